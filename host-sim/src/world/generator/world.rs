//! The attempts, and the world the generator hands back: the bytes of its files, the scenario in
//! memory, the checks and measurements.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

use super::check::{self, Contrast};
use super::draft::{Draft, Summary, Why};
use super::options::{Options, OptionsError, ValidOptions};
use super::plan::{self, Ranges};
use crate::world::check::TeacherLap;
use crate::world::scenario::Scenario;
use crate::world::teacher::{self, Preset, TeacherSpec};

/// An attempt that failed its checks, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Refusal {
    /// The attempt (the stream of the seed's generator).
    pub attempt: u32,
    /// Why it was refused.
    pub why: Why,
}

/// Why no world came out.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum GenerateError {
    /// The options were refused.
    #[error(transparent)]
    Options(#[from] OptionsError),
    /// Every attempt failed its checks.
    #[error("no world for seed {seed} passed its checks in {} attempts: {}", .refusals.len(), list(.refusals))]
    NoWorld {
        /// The seed.
        seed: u64,
        /// Every attempt's reason.
        refusals: Vec<Refusal>,
    },
    /// The simulator failed while checking (a bug, not the world's fault).
    #[error("seed {seed}, attempt {attempt}: {message}")]
    Check {
        /// The seed.
        seed: u64,
        /// The attempt.
        attempt: u32,
        /// What failed.
        message: String,
    },
}

fn list(r: &[Refusal]) -> String {
    r.iter()
        .map(|r| format!("attempt {}: {}", r.attempt, r.why))
        .collect::<Vec<_>>()
        .join("; ")
}

/// A generated world that passed its checks.
#[derive(Clone, Debug)]
pub struct World {
    /// The options it was made with.
    pub options: ValidOptions,
    /// The attempt that passed.
    pub attempt: u32,
    /// The attempts before it, and why they failed.
    pub refused: Vec<Refusal>,
    /// `NAME.pgm`.
    pub pgm: Vec<u8>,
    /// `NAME.yaml`.
    pub yaml: String,
    /// `NAME.toml`.
    pub toml: String,
    /// The scenario, in memory (what loading the files gives, but for the map's unknown cells,
    /// here occupied: the car and its sensor treat both alike).
    pub scenario: Arc<Scenario>,
    /// Every preset teacher's lap (the scenario check's), in [`teacher::PRESETS`] order.
    pub laps: Vec<TeacherLap>,
    /// Every preset teacher against its path follower, in the same order.
    pub contrasts: Vec<Contrast>,
    /// Its numbers.
    pub summary: Summary,
}

impl World {
    /// The files: name and bytes (`NAME.pgm`, `NAME.yaml`, `NAME.toml`).
    pub fn files(&self) -> [(String, &[u8]); 3] {
        let n = &self.options.name;
        [
            (format!("{n}.pgm"), &self.pgm[..]),
            (format!("{n}.yaml"), self.yaml.as_bytes()),
            (format!("{n}.toml"), self.toml.as_bytes()),
        ]
    }

    /// Writes the files into `dir` (created if missing; files of the same name are replaced).
    /// Returns the scenario file's path.
    pub fn write(&self, dir: &Path) -> anyhow::Result<PathBuf> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
        for (name, bytes) in self.files() {
            let p = dir.join(&name);
            std::fs::write(&p, bytes).with_context(|| format!("{}: cannot write", p.display()))?;
        }
        Ok(dir.join(format!("{}.toml", self.options.name)))
    }

    /// The lap of the scenario's teacher.
    pub fn lap(&self) -> &TeacherLap {
        let i = preset_index(self.options.teacher);
        &self.laps[i]
    }

    /// The scenario's teacher against its path follower.
    pub fn contrast(&self) -> &Contrast {
        let i = preset_index(self.options.teacher);
        &self.contrasts[i]
    }
}

fn preset_index(p: &Preset) -> usize {
    teacher::PRESETS
        .iter()
        .position(|q| q.name == p.name)
        .unwrap_or(0)
}

/// A generated plan taught by the calibrated teacher `preset` instead of its own, named `name`
/// (the worlds `gen-SEED/TEACHER` of the reproduction's claims across worlds and of the learner
/// table).
pub fn with_teacher(plan: &Scenario, name: String, preset: &'static Preset) -> Scenario {
    Scenario {
        name,
        teacher: TeacherSpec::from_preset(preset),
        ..plan.clone()
    }
}

/// Generates a world: draws plans until one passes its checks (see the module documentation).
pub fn generate(options: &Options) -> Result<World, GenerateError> {
    let options = options.check()?;
    let mut refused = Vec::new();
    for attempt in 0..options.attempts {
        let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
        rng.set_stream(u64::from(attempt));
        let plan = plan::plan(
            &mut rng,
            Ranges {
                hallway: options.hallway_mm,
            },
        );
        let internal = |e: anyhow::Error| GenerateError::Check {
            seed: options.seed,
            attempt,
            message: format!("{e:#}"),
        };
        let draft = Draft::new(&plan, &options, attempt).map_err(internal)?;
        match draft.accept() {
            Err(why) => refused.push(Refusal { attempt, why }),
            Ok(laps) => {
                let mut contrasts = Vec::new();
                for p in &teacher::PRESETS {
                    let c = check::contrast(&draft.scenario, p.name, TeacherSpec::from_preset(p))
                        .map_err(internal)?;
                    contrasts.push(c);
                }
                let summary = draft.summary(&plan);
                return Ok(World {
                    options,
                    attempt,
                    refused,
                    pgm: draft.pgm,
                    yaml: draft.yaml,
                    toml: draft.toml,
                    scenario: draft.scenario,
                    laps,
                    contrasts,
                    summary,
                });
            }
        }
    }
    Err(GenerateError::NoWorld {
        seed: options.seed,
        refusals: refused,
    })
}
