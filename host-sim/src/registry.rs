//! Scenarios and experiments registered by name, in the manner of rapier's example registry:
//! the CLI lists them, and [`run_all`] runs any list of runs in parallel. `host-sim reproduce`
//! runs the paper's full grid, with the paper's learner, through [`crate::reproduce`].
//!
//! Built-in scenarios live in `host-sim/scenarios/` (located at build time through
//! `CARGO_MANIFEST_DIR`). An experiment is a name and a function that expands options into run
//! configurations; [`run_all`] runs any list of configurations on rayon's pool. Runs share
//! nothing mutable: each owns its episode, teacher, generator (seeded from its own seed) and
//! learner, and scenarios are shared read-only through `Arc`.
//!
//! ```no_run
//! use host_sim::registry;
//! let scenario = registry::load_scenario("doors").unwrap();
//! assert_eq!(scenario.name, "doors");
//! ```

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Result, bail};
use rayon::prelude::*;

use crate::experiment::{Mode, RunConfig, RunReport};
use crate::scenario::Scenario;
use crate::teacher::FeedbackKind;

/// A built-in scenario.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BuiltinScenario {
    /// Its name (`--scenario NAME`).
    pub name: &'static str,
    /// The file in `scenarios/`.
    pub file: &'static str,
    /// One line about it.
    pub description: &'static str,
}

/// The built-in scenarios.
pub const SCENARIOS: &[BuiltinScenario] = &[
    BuiltinScenario {
        name: "doors",
        file: "doors.toml",
        description: "a flat with bedroom doors along 2 m hallways; the teacher avoids doors",
    },
    BuiltinScenario {
        name: "stairs-right",
        file: "stairs-right.toml",
        description: "1.6 m hallways and two staircases; the teacher avoids stairs and keeps right",
    },
    BuiltinScenario {
        name: "stairs-chairs",
        file: "stairs-chairs.toml",
        description: "a stairwell, a dining room and a living room; the teacher avoids stairs and chairs",
    },
    BuiltinScenario {
        name: "basement",
        file: "basement.toml",
        description: "the MIT basement hallways of MuSHR's map set, with doors placed on it",
    },
];

/// The folder of the built-in scenarios.
pub fn scenario_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios")
}

/// The file of a built-in scenario name, or `name_or_path` itself when it is not one.
pub fn resolve(name_or_path: &str) -> PathBuf {
    match SCENARIOS.iter().find(|s| s.name == name_or_path) {
        Some(s) => scenario_dir().join(s.file),
        None => PathBuf::from(name_or_path),
    }
}

/// Loads a built-in scenario by name, or a scenario file by path, and checks that its teacher's
/// own policy drives a lap of it ([`crate::check::teacher_lap`]); a scenario that fails is
/// refused with where and why.
pub fn load_scenario(name_or_path: &str) -> Result<Scenario> {
    let s = load_scenario_unchecked(name_or_path)?;
    crate::check::teacher_lap(&Arc::new(s.clone()))?;
    Ok(s)
}

/// [`load_scenario`] without the teacher's lap (`host-sim --no-scenario-check`).
pub fn load_scenario_unchecked(name_or_path: &str) -> Result<Scenario> {
    let path = resolve(name_or_path);
    if !path.exists() && !name_or_path.contains(['/', '.']) {
        let names: Vec<_> = SCENARIOS.iter().map(|s| s.name).collect();
        bail!(
            "unknown scenario {name_or_path:?}: a built-in name ({}) or a path to a .toml file",
            names.join(", ")
        );
    }
    Ok(Scenario::load(&path)?)
}

/// Options an experiment expands into runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExperimentOptions {
    /// Trials per setting (seeds `seed`, `seed + 1`, …).
    pub trials: u32,
    /// First seed.
    pub seed: u64,
    /// Steps per run.
    pub steps: u32,
}

impl Default for ExperimentOptions {
    fn default() -> Self {
        Self {
            trials: 10,
            seed: 0,
            steps: 5_000,
        }
    }
}

/// A registered experiment.
#[derive(Clone, Copy, Debug)]
pub struct Experiment {
    /// Its name.
    pub name: &'static str,
    /// What it measures (the paper's section 6).
    pub description: &'static str,
    /// Its runs.
    pub configs: fn(&ExperimentOptions) -> Result<Vec<RunConfig>>,
}

fn trials(base: RunConfig, o: &ExperimentOptions) -> impl Iterator<Item = RunConfig> {
    (0..o.trials).map(move |t| RunConfig {
        seed: o.seed + t as u64,
        steps: o.steps,
        ..base.clone()
    })
}

fn variety(o: &ExperimentOptions) -> Result<Vec<RunConfig>> {
    let mut out = Vec::new();
    for name in ["doors", "stairs-right", "stairs-chairs"] {
        let s = Arc::new(load_scenario(name)?);
        let mut modes: Vec<Mode> = FeedbackKind::ALL.into_iter().map(Mode::Online).collect();
        modes.push(Mode::BehaviourCloning);
        for mode in modes {
            let base = RunConfig {
                mode,
                ..RunConfig::new(s.clone())
            };
            out.extend(trials(base, o));
        }
    }
    Ok(out)
}

fn noise(o: &ExperimentOptions) -> Result<Vec<RunConfig>> {
    let s = Arc::new(load_scenario("doors")?);
    let mut out = Vec::new();
    for sigma in [0.0, 0.25, 0.5, 1.0, 1.5, 2.0] {
        let base = RunConfig {
            noise: Some(sigma),
            ..RunConfig::new(s.clone())
        };
        out.extend(trials(base, o));
    }
    Ok(out)
}

fn thresholds(o: &ExperimentOptions) -> Result<Vec<RunConfig>> {
    let s = Arc::new(load_scenario("stairs-chairs")?);
    let mut out = Vec::new();
    for t in crate::reproduce::THRESHOLDS {
        let base = RunConfig {
            threshold: Some(t),
            ..RunConfig::new(s.clone())
        };
        out.extend(trials(base, o));
    }
    Ok(out)
}

/// The registered experiments (paper, section 6).
pub const EXPERIMENTS: &[Experiment] = &[
    Experiment {
        name: "variety",
        description: "action, preference and semantic feedback and behaviour cloning on the three households",
        configs: variety,
    },
    Experiment {
        name: "noise",
        description: "action feedback on doors with teacher noise sigma 0 to 2",
        configs: noise,
    },
    Experiment {
        name: "thresholds",
        description: "action feedback on stairs-chairs with correction thresholds 0 to 8",
        configs: thresholds,
    },
];

/// The experiment called `name`.
pub fn experiment(name: &str) -> Option<&'static Experiment> {
    EXPERIMENTS.iter().find(|e| e.name == name)
}

/// Runs every configuration in parallel (rayon); results come back in the input order.
pub fn run_all(configs: &[RunConfig]) -> Vec<Result<RunReport>> {
    configs.par_iter().map(crate::experiment::run).collect()
}
