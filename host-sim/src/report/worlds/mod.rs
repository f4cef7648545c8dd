//! The paper's claims across worlds (`host-sim reproduce --worlds K`).
//!
//! Three households cannot tell a property of the method from a property of one floor plan.
//! Beside the paper's grid, every claim is checked again **in each of many worlds**, each with a
//! small grid of its own, and the report says in how many worlds each claim holds and how large
//! its effect is across them, with 95% intervals.
//!
//! # The worlds
//!
//! [`worlds`]: the three households and the basement scenario ([`FIXED`], each with its own
//! teacher), then, for each teacher preset (doors, stairs-right, stairs-chairs), the generated
//! households of seeds 0 … K − 1 ([`crate::world::generator`], default options). A generated
//! world is the same floor plan for the three teachers (the generator keeps a world only if
//! every preset's own policy laps it), so the three teachers are compared on the same plans.
//! The teachers are the calibrated presets, never recalibrated per world, and the worlds are
//! the generator's, never chosen for a claim.
//!
//! # The grid of a world
//!
//! [`world_settings`]: the paper's experiments in miniature, with the world's teacher: action,
//! preference and semantic feedback and behaviour cloning (σ = 0, threshold 1.0); action
//! feedback at σ = 0.25, 0.5, 1.0 (threshold 1.0; with σ = 0 the paper's four noise levels);
//! action feedback at thresholds 0, 0.25, 0.5, 0.75 (σ = 0; with 1.0 the paper's five). Each runs
//! `--world-trials` trials (trial `t` has seed `seed + t`, as in the paper's grid) of `--steps`
//! steps, with the paper's learner and the start jitter of the paper's grid.
//!
//! # Per-world claims and effect sizes
//!
//! [`effects`]: each claim's verdict in a world is the same function of [`crate::report::claims`]
//! applied to the world's own aggregates, and each claim has a per-world effect size, defined
//! there ([`effects::EFFECTS`]) and in the report. [`section`] writes the report's section, the
//! pictures of the worlds where a claim fails and `worlds.csv`.
//!
//! A world's trials keep only their summaries ([`TrialSummary`]): at K = 1 000 the curves of every
//! trial would not fit in memory, and no figure draws them.

pub mod effects;
pub mod section;

use std::collections::BTreeMap;
use std::sync::Arc;

use anyhow::{Context, Result};
use rayon::prelude::*;

use super::aggregate::TrialSummary;
use super::grid::{Group, Options, Setting, TrialResult};
use crate::teach::experiment::{self, Mode};
use crate::world::generator;
use crate::world::registry;
use crate::world::scenario::Scenario;
use crate::world::teacher::{self, FeedbackKind, PAPER_KINDS};

/// The fixed worlds: the paper's three households and the basement scenario.
pub const FIXED: [&str; 4] = ["doors", "stairs-right", "stairs-chairs", "basement"];

/// A world of the across-worlds experiment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum World {
    /// A built-in scenario, with its own teacher.
    Fixed(&'static str),
    /// The generated household of `seed`, with the teacher preset `teacher`.
    Generated {
        /// The generator's seed.
        seed: u64,
        /// The teacher preset.
        teacher: &'static str,
    },
}

impl World {
    /// `doors`, `basement`, `gen-12/stairs-right`.
    pub fn name(&self) -> String {
        match self {
            World::Fixed(h) => (*h).to_string(),
            World::Generated { seed, teacher } => format!("gen-{seed}/{teacher}"),
        }
    }

    /// The teacher preset's name (a fixed world's own: the basement's is `doors`).
    pub fn teacher(&self) -> &'static str {
        match self {
            World::Fixed("basement") => "doors",
            World::Fixed(h) => h,
            World::Generated { teacher, .. } => teacher,
        }
    }

    /// Whether it is a generated world.
    pub fn generated(&self) -> bool {
        matches!(self, World::Generated { .. })
    }
}

/// The worlds of `--worlds k`: [`FIXED`], then `k` generated worlds for each teacher preset.
pub fn worlds(k: u32) -> Vec<World> {
    if k == 0 {
        return Vec::new();
    }
    let mut out: Vec<World> = FIXED.iter().map(|h| World::Fixed(h)).collect();
    for p in &teacher::PRESETS {
        out.extend((0..u64::from(k)).map(|seed| World::Generated {
            seed,
            teacher: p.name,
        }));
    }
    out
}

/// The noise levels of a world's grid (the paper's four).
pub const WORLD_NOISE: [f32; 4] = [0.0, 0.25, 0.5, 1.0];
/// The thresholds of a world's grid (the paper's five).
pub const WORLD_THRESHOLDS: [f32; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];

/// The settings of every world, in order: action, preference, semantic, bc (σ 0, threshold 1);
/// action at σ 0.25, 0.5, 1; action at thresholds 0, 0.25, 0.5, 0.75. Their `household` is a
/// placeholder: [`effects`] names the world's teacher there.
pub fn world_settings() -> Vec<Setting> {
    let action = Mode::Online(FeedbackKind::Action);
    let at = |group, mode, noise, threshold| Setting {
        group,
        household: "world",
        mode,
        noise,
        threshold,
        draw_path: false,
    };
    let mut out: Vec<Setting> = PAPER_KINDS
        .into_iter()
        .map(|k| at(Group::Variety, Mode::Online(k), 0.0, 1.0))
        .collect();
    out.push(at(Group::Variety, Mode::BehaviourCloning, 0.0, 1.0));
    out.extend(
        WORLD_NOISE[1..]
            .iter()
            .map(|&s| at(Group::Noise, action, s, 1.0)),
    );
    out.extend(
        WORLD_THRESHOLDS[..4]
            .iter()
            .map(|&t| at(Group::Thresholds, action, 0.0, t)),
    );
    out
}

/// A key of a world setting, for the shard files: `action`, `bc`, `noise-0.25`, `threshold-0`.
pub fn world_setting_key(s: &Setting) -> String {
    match s.group {
        Group::Variety => s.mode.name().to_string(),
        Group::Noise => format!("noise-{}", s.noise),
        Group::Thresholds => format!("threshold-{}", s.threshold),
    }
}

/// One trial of a world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldTrial {
    /// Index into [`worlds`].
    pub world: usize,
    /// Index into [`world_settings`].
    pub setting: usize,
    /// The trial.
    pub trial: u32,
    /// Its summary; `None` when the generator gave no world for the seed.
    pub summary: Option<TrialSummary>,
}

/// The scenarios of the worlds a shard runs: the fixed ones loaded (and checked), the generated
/// ones generated once per seed (the same plan for every teacher).
#[derive(Debug, Default)]
pub struct Scenarios {
    fixed: BTreeMap<&'static str, Arc<Scenario>>,
    generated: BTreeMap<u64, Option<Arc<Scenario>>>,
}

impl Scenarios {
    /// The scenarios of `needed` (indices into `all`), generated worlds in parallel.
    pub fn load(all: &[World], needed: &[usize]) -> Result<Self> {
        let mut s = Self::default();
        let mut seeds = Vec::new();
        for &i in needed {
            match all.get(i).context("no such world")? {
                World::Fixed(h) => {
                    if !s.fixed.contains_key(h) {
                        s.fixed.insert(h, Arc::new(registry::load_scenario(h)?));
                    }
                }
                World::Generated { seed, .. } => seeds.push(*seed),
            }
        }
        seeds.sort_unstable();
        seeds.dedup();
        let made: Vec<(u64, Option<Arc<Scenario>>)> = seeds
            .par_iter()
            .map(|&seed| (seed, generate(seed)))
            .collect();
        s.generated.extend(made);
        Ok(s)
    }

    /// The scenario of `world`, with its teacher; `None` for a seed that gave no world.
    pub fn scenario(&self, world: &World) -> Option<Arc<Scenario>> {
        match world {
            World::Fixed(h) => self.fixed.get(h).cloned(),
            World::Generated { seed, teacher } => {
                let plan = self.generated.get(seed)?.as_ref()?;
                let preset = teacher::preset(teacher)?;
                Some(Arc::new(generator::with_teacher(
                    plan,
                    world.name(),
                    preset,
                )))
            }
        }
    }
}

/// The generated household of `seed` (default options), or `None` when the generator gives
/// none (every attempt failed its checks).
pub fn generate(seed: u64) -> Option<Arc<Scenario>> {
    generator::generate(&generator::Options::new(seed))
        .ok()
        .map(|w| w.scenario)
}

/// Runs trial `trial` of `settings[setting]` in `worlds[world]`.
pub fn run_world_job(
    scenarios: &Scenarios,
    worlds: &[World],
    settings: &[Setting],
    (world, setting, trial): (usize, usize, u32),
    o: &Options,
) -> Result<WorldTrial> {
    let w = worlds.get(world).context("no such world")?;
    let s = settings.get(setting).context("no such world setting")?;
    let Some(scenario) = scenarios.scenario(w) else {
        return Ok(WorldTrial {
            world,
            setting,
            trial,
            summary: None,
        });
    };
    let report = experiment::run(&s.config(scenario, trial, o))
        .with_context(|| format!("{} {} trial {trial}", w.name(), world_setting_key(s)))?;
    Ok(WorldTrial {
        world,
        setting,
        trial,
        summary: Some(TrialSummary::of(&TrialResult::of_report(
            setting, trial, &report, None,
        ))),
    })
}
