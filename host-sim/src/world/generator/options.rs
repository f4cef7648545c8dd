//! The generator's options, checked once ([`Options::check`] → [`ValidOptions`]).

use std::fmt::Write as _;

use thiserror::Error;

use crate::world::teacher::{self, Preset};

/// Hallway widths a user may ask for (m): below 1.2 m the car's lane (the width less 0.25 m of
/// collision margin on each side) is under 0.7 m.
pub const HALLWAY_LIMITS: (f64, f64) = (1.2, 3.0);
/// Attempts by default.
pub const DEFAULT_ATTEMPTS: u32 = 16;
/// Most attempts a user may ask for.
pub const MAX_ATTEMPTS: u32 = 64;

/// What to generate.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// The seed: the same options give the same bytes.
    pub seed: u64,
    /// The scenario's teacher: a preset name (`doors`, `stairs-right`, `stairs-chairs`).
    pub teacher: String,
    /// The files' and scenario's name (default `gen-SEED`): letters, digits, `-`, `_`, `.`.
    pub name: Option<String>,
    /// Narrowest hallway (m).
    pub hallway_min: f64,
    /// Widest hallway (m).
    pub hallway_max: f64,
    /// Worlds drawn at most before giving up.
    pub attempts: u32,
}

impl Options {
    /// The defaults for `seed`: teacher `doors`, name `gen-SEED`, hallways 1.4–2.5 m, 8 attempts.
    pub fn new(seed: u64) -> Self {
        Self {
            seed,
            teacher: "doors".into(),
            name: None,
            hallway_min: 1.4,
            hallway_max: 2.5,
            attempts: DEFAULT_ATTEMPTS,
        }
    }

    /// Validates the options.
    pub fn check(&self) -> Result<ValidOptions, OptionsError> {
        let preset = teacher::preset(&self.teacher).ok_or_else(|| {
            let names: Vec<_> = teacher::PRESETS.iter().map(|p| p.name).collect();
            OptionsError::Teacher {
                given: self.teacher.clone(),
                known: names.join(", "),
            }
        })?;
        let name = match &self.name {
            None => format!("gen-{}", self.seed),
            Some(n) => {
                let bad = |problem| OptionsError::Name {
                    name: n.clone(),
                    problem,
                };
                if n.is_empty() || n.len() > 64 {
                    return Err(bad("must have 1 to 64 characters"));
                }
                if n.starts_with('.') {
                    return Err(bad("must not start with '.'"));
                }
                if !n
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
                {
                    return Err(bad(
                        "may hold only letters, digits, '-', '_' and '.' (it names files)",
                    ));
                }
                n.clone()
            }
        };
        let (min, max) = (self.hallway_min, self.hallway_max);
        let bad = |problem: String| OptionsError::Hallway { min, max, problem };
        if !(min.is_finite() && max.is_finite()) {
            return Err(bad("must be finite numbers".into()));
        }
        let (lo, hi) = HALLWAY_LIMITS;
        if min < lo || max > hi {
            return Err(bad(format!("must lie within {lo}–{hi} m")));
        }
        if min > max {
            return Err(bad("the narrowest exceeds the widest".into()));
        }
        // On the 5 cm grid, inward.
        let min_mm = (libm::ceil(min * 20.0 - 1e-9) as i32) * 50;
        let max_mm = (libm::floor(max * 20.0 + 1e-9) as i32) * 50;
        if min_mm > max_mm {
            return Err(bad(
                "no width on the map's 5 cm grid lies between them".into()
            ));
        }
        if self.attempts == 0 || self.attempts > MAX_ATTEMPTS {
            return Err(OptionsError::Attempts(self.attempts));
        }
        let defaults = Options::new(self.seed);
        let mut command = format!("host-sim generate --seed {}", self.seed);
        if self.teacher != defaults.teacher {
            let _ = write!(command, " --teacher {}", self.teacher);
        }
        if let Some(n) = &self.name {
            let _ = write!(command, " --name {n}");
        }
        if min != defaults.hallway_min {
            let _ = write!(command, " --hallway-min {min}");
        }
        if max != defaults.hallway_max {
            let _ = write!(command, " --hallway-max {max}");
        }
        Ok(ValidOptions {
            seed: self.seed,
            teacher: preset,
            name,
            hallway_mm: (min_mm, max_mm),
            attempts: self.attempts,
            command,
        })
    }
}

/// Options that passed [`Options::check`].
#[derive(Clone, Debug, PartialEq)]
pub struct ValidOptions {
    /// The seed.
    pub seed: u64,
    /// The scenario's teacher.
    pub teacher: &'static Preset,
    /// The name of the files and the scenario.
    pub name: String,
    /// Hallway widths (mm, on the 5 cm grid).
    pub hallway_mm: (i32, i32),
    /// Attempts at most.
    pub attempts: u32,
    /// The command line that makes this world (for the scenario file's header).
    pub command: String,
}

/// A refused option, with what is wrong.
#[derive(Clone, Debug, PartialEq, Error)]
#[non_exhaustive]
pub enum OptionsError {
    /// Not a teacher preset.
    #[error("unknown teacher {given:?}: one of {known}")]
    Teacher {
        /// What was given.
        given: String,
        /// The presets.
        known: String,
    },
    /// A name that cannot name files.
    #[error("name {name:?}: {problem}")]
    Name {
        /// What was given.
        name: String,
        /// What is wrong.
        problem: &'static str,
    },
    /// Bad hallway widths.
    #[error("hallway widths {min}–{max} m: {problem}")]
    Hallway {
        /// The narrowest given.
        min: f64,
        /// The widest given.
        max: f64,
        /// What is wrong.
        problem: String,
    },
    /// Attempts out of range.
    #[error("attempts must be in 1..={MAX_ATTEMPTS}, got {0}")]
    Attempts(u32),
}
