//! The paper's section 6 experiments registered by name, in the manner of rapier's example
//! registry: `host-sim list` lists them, and each expands options into run configurations
//! ([`crate::teach::experiment::run_all`] runs them in parallel). `host-sim reproduce` runs the
//! paper's full grid, with the paper's learner, through [`crate::report::grid`].

use std::sync::Arc;

use anyhow::Result;

use crate::teach::experiment::{Mode, RunConfig};
use crate::world::registry::load_scenario;
use crate::world::teacher::FeedbackKind;

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
    for t in super::grid::THRESHOLDS {
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
        description: "action feedback on doors with teacher noise σ 0 to 2",
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
