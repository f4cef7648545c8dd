//! The trial grid: settings, options, shards, and the jobs that run them.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::Arc;

use anyhow::{Context, Result};
use firmware_core::{LearnerParams, PAPER_STEP};
use rayon::prelude::*;

use super::paths::{PathTrace, learner_lap};
use super::worlds::{self, WorldTrial};
use crate::teach::experiment::{self, MAX_STEPS, Mode, RunConfig, StartJitter};
use crate::teach::record::{RESET_CAUSES, RunReport};
use crate::world::registry;
use crate::world::scenario::Scenario;
use crate::world::sim::ResetReason;
use crate::world::teacher::{FeedbackKind, PAPER_KINDS};

/// The households of the variety experiment (the paper's three).
pub const HOUSEHOLDS: [&str; 3] = ["doors", "stairs-right", "stairs-chairs"];
/// Teacher noise levels of the noise experiment: 0 to 2.0 in steps of 0.125.
pub const NOISE_SWEEP: [f32; 17] = [
    0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.0, 1.125, 1.25, 1.375, 1.5, 1.625, 1.75,
    1.875, 2.0,
];
/// The noise levels drawn as curves (the paper's four).
pub const NOISE_CURVES: [f32; 4] = [0.0, 0.25, 0.5, 1.0];
/// The noise levels whose trained learner's path is drawn.
pub const NOISE_PATHS: [f32; 3] = [0.0, 1.0, 2.0];
/// The thresholds of the threshold experiment: the paper's five and 2, 4, 8.
pub const THRESHOLDS: [f32; 8] = [0.0, 0.25, 0.5, 0.75, 1.0, 2.0, 4.0, 8.0];
/// The paper's thresholds: claim 5 is decided on these.
pub const PAPER_THRESHOLDS: [f32; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];
/// Longest drive of a path figure (ticks).
pub const PATH_TICKS: u32 = 1_500;
/// Largest number of trials per setting.
pub const MAX_TRIALS: u32 = 10_000;
/// The trials per setting a grid accepts (`--trials`).
pub const TRIALS: std::ops::RangeInclusive<u32> = 1..=MAX_TRIALS;
/// The steps per trial a grid accepts (`--steps`): at least ten, so that a tenth is a step.
pub const GRID_STEPS: std::ops::RangeInclusive<u32> = 10..=MAX_STEPS;
/// Version of the shard files (3: the worlds' trials in `worlds.csv` and the kinds experiment's runs).
pub const SHARD_FORMAT: u32 = 3;
/// Generated worlds per teacher by default (`--worlds`): with the paper's grid and the kinds
/// experiment, what a full reproduction runs in a minute on two idle cores, with room to spare.
/// Measured on this project's 2-core machine, idle (README, "Reproducing the paper"): 60.6 s of
/// wall time with 16 (114.2 s of CPU), 54.1 s with 14 (102.8 s of CPU).
pub const DEFAULT_WORLDS: u32 = 14;
/// Trials per setting in each world by default (`--world-trials`).
pub const DEFAULT_WORLD_TRIALS: u32 = 2;
/// Most generated worlds per teacher.
pub const MAX_WORLDS: u32 = 100_000;
/// The generated worlds per teacher a grid accepts (`--worlds`; 0: none).
pub const WORLDS: std::ops::RangeInclusive<u32> = 0..=MAX_WORLDS;
/// The trials per setting in a world a grid accepts (`--world-trials`).
pub const WORLD_TRIALS: std::ops::RangeInclusive<u32> = 1..=100;
/// The factors of the teachers' scale the scale sweep runs the claims at.
pub const SWEEP_FACTORS: [f32; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];

/// The paper's learner: plain OGD, constant step 0.01.
pub fn paper_learner() -> LearnerParams {
    LearnerParams::paper().with_step(PAPER_STEP)
}

/// Which experiment a setting belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Group {
    /// Feedback types and behaviour cloning in three households.
    Variety,
    /// Teacher noise σ.
    Noise,
    /// Correction thresholds.
    Thresholds,
}

impl Group {
    /// Its name (the CSV's and figures' stem).
    pub const fn name(self) -> &'static str {
        match self {
            Group::Variety => "variety",
            Group::Noise => "noise",
            Group::Thresholds => "thresholds",
        }
    }
}

/// One curve of the paper: what every trial of it runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setting {
    /// The experiment.
    pub group: Group,
    /// The household (built-in scenario name).
    pub household: &'static str,
    /// How the learner is taught.
    pub mode: Mode,
    /// Teacher noise σ.
    pub noise: f32,
    /// Teacher threshold.
    pub threshold: f32,
    /// Whether trial 0's trained learner drives a lap for the path figures.
    pub draw_path: bool,
}

impl Setting {
    /// A unique name, usable as a folder name: `variety-doors-action`, `noise-0.125`,
    /// `thresholds-0.25`.
    pub fn key(&self) -> String {
        match self.group {
            Group::Variety => format!("variety-{}-{}", self.household, self.mode.name()),
            Group::Noise => format!("noise-{}", self.noise),
            Group::Thresholds => format!("thresholds-{}", self.threshold),
        }
    }

    /// The run of trial `trial`.
    pub fn config(&self, scenario: Arc<Scenario>, trial: u32, o: &Options) -> RunConfig {
        RunConfig {
            mode: self.mode,
            steps: o.steps,
            seed: o.seed.wrapping_add(trial as u64),
            threshold: Some(self.threshold),
            noise: Some(self.noise),
            learner: paper_learner(),
            start_jitter: Some(StartJitter::REPRODUCE),
            statements: Some(crate::world::teacher::StatementSet::Paper),
            random_answers: Some(0.0),
            teacher_scale: (o.teacher_scale != 1.0).then_some(o.teacher_scale),
            ..RunConfig::new(scenario)
        }
    }
}

/// Every setting, in the grid's order.
pub fn settings() -> Vec<Setting> {
    let mut out = Vec::new();
    for household in HOUSEHOLDS {
        let mut modes: Vec<Mode> = PAPER_KINDS.into_iter().map(Mode::Online).collect();
        modes.push(Mode::BehaviourCloning);
        for mode in modes {
            out.push(Setting {
                group: Group::Variety,
                household,
                mode,
                noise: 0.0,
                threshold: 1.0,
                draw_path: false,
            });
        }
    }
    for noise in NOISE_SWEEP {
        out.push(Setting {
            group: Group::Noise,
            household: "doors",
            mode: Mode::Online(FeedbackKind::Action),
            noise,
            threshold: 1.0,
            draw_path: NOISE_PATHS.contains(&noise),
        });
    }
    for threshold in THRESHOLDS {
        out.push(Setting {
            group: Group::Thresholds,
            household: "stairs-chairs",
            mode: Mode::Online(FeedbackKind::Action),
            noise: 0.0,
            threshold,
            draw_path: true,
        });
    }
    out
}

/// The size of the grid, the worlds, and the teachers' scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Trials per setting.
    pub trials: u32,
    /// Steps per trial.
    pub steps: u32,
    /// Seed of trial 0 (trial `t` has `seed + t`).
    pub seed: u64,
    /// Every teacher's weights times this (1: the calibrated teachers).
    pub teacher_scale: f32,
    /// Generated worlds per teacher ([`crate::report::worlds`]; 0: the paper's grid only).
    pub worlds: u32,
    /// Trials per setting in each world.
    pub world_trials: u32,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            trials: 10,
            steps: 5_000,
            seed: 0,
            teacher_scale: 1.0,
            worlds: DEFAULT_WORLDS,
            world_trials: DEFAULT_WORLD_TRIALS,
        }
    }
}

impl Options {
    /// The grid in words: "10 trials × 5000 steps, seed 0, 14 worlds per teacher × 2 trials" (and
    /// the teachers' scale if not 1).
    pub fn describe(&self) -> String {
        let mut d = format!(
            "{} trials × {} steps, seed {}",
            self.trials, self.steps, self.seed
        );
        if self.worlds > 0 {
            let _ = write!(
                d,
                ", {} worlds per teacher × {} trials",
                self.worlds, self.world_trials
            );
        }
        if self.teacher_scale != 1.0 {
            let _ = write!(d, ", teachers' scale × {}", self.teacher_scale);
        }
        d
    }

    /// The command-line options that make this grid: `--trials 10 --steps 5000 --seed 0
    /// --worlds 14 --world-trials 2` (and `--teacher-scale F` if not 1).
    pub fn flags(&self) -> String {
        let mut f = format!(
            "--trials {} --steps {} --seed {} --worlds {} --world-trials {}",
            self.trials, self.steps, self.seed, self.worlds, self.world_trials
        );
        if self.teacher_scale != 1.0 {
            let _ = write!(f, " --teacher-scale {}", self.teacher_scale);
        }
        f
    }

    /// Checks the numbers.
    pub fn check(&self) -> Result<()> {
        use crate::checks;
        use crate::checks::named;
        checks::teacher_scale(self.teacher_scale.into()).map_err(named("--teacher-scale"))?;
        checks::count(self.trials.into(), TRIALS).map_err(named("--trials"))?;
        checks::count(self.steps.into(), GRID_STEPS).map_err(named("--steps"))?;
        checks::count(self.worlds.into(), WORLDS).map_err(named("--worlds"))?;
        checks::count(self.world_trials.into(), WORLD_TRIALS).map_err(named("--world-trials"))?;
        Ok(())
    }
}

/// Slice `index` of `count` of the grid (`--shard index/count`, `index` from 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard, `0..count`.
    pub index: u32,
    /// Number of shards.
    pub count: u32,
}

impl Shard {
    /// The whole grid.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Whether job `job` is in this shard.
    pub fn has(&self, job: usize) -> bool {
        job % self.count as usize == self.index as usize
    }
}

impl std::str::FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("shard must be INDEX/COUNT with 0 <= INDEX < COUNT, got {s:?}");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let index: u32 = i.trim().parse().map_err(|_| bad())?;
        let count: u32 = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

/// What one job produced.
#[derive(Clone, Debug, PartialEq)]
pub struct TrialResult {
    /// Index into [`settings`].
    pub setting: usize,
    /// The trial.
    pub trial: u32,
    /// True latent loss per step.
    pub latent: Vec<f32>,
    /// Cumulative corrections per step.
    pub corrections: Vec<u32>,
    /// Progress along the path per step (m; see [`crate::world::sim::Episode::path_progress`]).
    pub progress: Vec<f64>,
    /// Laps completed so far, per step.
    pub laps: Vec<u32>,
    /// The reset of each step, if any.
    pub resets: Vec<Option<ResetReason>>,
    /// The trained learner's lap (trial 0 of a setting that draws paths).
    pub path: Option<PathTrace>,
}

impl TrialResult {
    /// The columns of `report`, a run of trial `trial` of setting `setting`.
    pub fn of_report(
        setting: usize,
        trial: u32,
        report: &RunReport,
        path: Option<PathTrace>,
    ) -> Self {
        Self {
            setting,
            trial,
            latent: report.records.iter().map(|r| r.latent_loss).collect(),
            corrections: report.records.iter().map(|r| r.corrections).collect(),
            progress: report.records.iter().map(|r| r.progress).collect(),
            laps: report.records.iter().map(|r| r.lap).collect(),
            resets: report.records.iter().map(|r| r.reset).collect(),
            path,
        }
    }

    /// Resets by cause: collision, stuck, lost, blocked ([`RESET_CAUSES`]).
    pub fn reset_counts(&self) -> [u32; 4] {
        let mut n = [0u32; 4];
        for r in self.resets.iter().flatten() {
            if let Some(i) = RESET_CAUSES.iter().position(|c| *c == r.name()) {
                n[i] += 1;
            }
        }
        n
    }
}

/// The built-in households, loaded once and shared.
pub fn load_households() -> Result<BTreeMap<&'static str, Arc<Scenario>>> {
    let mut m = BTreeMap::new();
    for h in HOUSEHOLDS {
        m.insert(h, Arc::new(registry::load_scenario(h)?));
    }
    Ok(m)
}

/// Runs job (`setting`, `trial`).
pub fn run_job(
    households: &BTreeMap<&'static str, Arc<Scenario>>,
    all: &[Setting],
    setting: usize,
    trial: u32,
    o: &Options,
) -> Result<TrialResult> {
    let s = all
        .get(setting)
        .with_context(|| format!("no setting {setting}"))?;
    let scenario = households
        .get(s.household)
        .with_context(|| format!("household {} not loaded", s.household))?
        .clone();
    let config = s.config(scenario.clone(), trial, o);
    let report = experiment::run(&config).with_context(|| format!("{} trial {trial}", s.key()))?;
    let path = if s.draw_path && trial == 0 {
        Some(learner_lap(
            &scenario,
            &report.final_snapshot,
            config.teacher(),
            PATH_TICKS,
        )?)
    } else {
        None
    };
    Ok(TrialResult::of_report(setting, trial, &report, path))
}

/// One run of the grid: a trial of a setting of the paper's grid, or of a setting of a world.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Job {
    /// Trial `trial` of [`settings`]`[setting]`.
    Grid {
        /// Index into [`settings`].
        setting: usize,
        /// The trial.
        trial: u32,
    },
    /// Trial `trial` of [`worlds::world_settings`]`[setting]` in [`worlds::worlds`]`[world]`.
    World {
        /// Index into the worlds.
        world: usize,
        /// Index into the worlds' settings.
        setting: usize,
        /// The trial.
        trial: u32,
    },
}

/// The jobs of `shard`, in grid order: the paper's grid setting-major, then the worlds
/// world-major, setting, trial. Job `k` of the whole list is in shard `k mod n`.
pub fn jobs(o: &Options, shard: Shard) -> Vec<Job> {
    let grid = (0..settings().len())
        .flat_map(|setting| (0..o.trials).map(move |trial| Job::Grid { setting, trial }));
    let per_world = worlds::world_settings().len();
    let world_jobs = (0..worlds::worlds(o.worlds).len()).flat_map(move |world| {
        (0..per_world).flat_map(move |setting| {
            (0..o.world_trials).map(move |trial| Job::World {
                world,
                setting,
                trial,
            })
        })
    });
    grid.chain(world_jobs)
        .enumerate()
        .filter(|(k, _)| shard.has(*k))
        .map(|(_, j)| j)
        .collect()
}

/// What a shard (or the whole grid) produced.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Results {
    /// The paper's grid's trials, in job order.
    pub grid: Vec<TrialResult>,
    /// The worlds' trials, in job order.
    pub worlds: Vec<WorldTrial>,
}

/// Runs the jobs of `shard` on the current rayon pool; `done` is called after each job.
pub fn run_shard(o: &Options, shard: Shard, done: &(dyn Fn() + Sync)) -> Result<Results> {
    o.check()?;
    let households = load_households()?;
    let all = settings();
    let jobs = jobs(o, shard);
    let world_list = worlds::worlds(o.worlds);
    let needed: Vec<usize> = {
        let mut v: Vec<usize> = jobs
            .iter()
            .filter_map(|j| match j {
                Job::World { world, .. } => Some(*world),
                Job::Grid { .. } => None,
            })
            .collect();
        v.dedup();
        v
    };
    let scenarios = worlds::Scenarios::load(&world_list, &needed)?;
    let world_settings = worlds::world_settings();
    enum Done {
        Grid(TrialResult),
        World(WorldTrial),
    }
    let results: Vec<Result<Done>> = jobs
        .par_iter()
        .map(|&job| {
            let r = match job {
                Job::Grid { setting, trial } => {
                    run_job(&households, &all, setting, trial, o).map(Done::Grid)
                }
                Job::World {
                    world,
                    setting,
                    trial,
                } => worlds::run_world_job(
                    &scenarios,
                    &world_list,
                    &world_settings,
                    (world, setting, trial),
                    o,
                )
                .map(Done::World),
            };
            done();
            r
        })
        .collect();
    let mut out = Results::default();
    for r in results {
        match r? {
            Done::Grid(t) => out.grid.push(t),
            Done::World(w) => out.worlds.push(w),
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse_and_partition_the_grid() {
        assert_eq!("2/5".parse::<Shard>(), Ok(Shard { index: 2, count: 5 }));
        for bad in ["5/5", "1/0", "x/2", "3", "-1/2", ""] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        let o = Options {
            trials: 3,
            steps: 10,
            worlds: 2,
            world_trials: 2,
            ..Options::default()
        };
        let whole = jobs(&o, Shard::WHOLE);
        let world_jobs = worlds::worlds(2).len() * worlds::world_settings().len() * 2;
        assert_eq!(whole.len(), settings().len() * 3 + world_jobs);
        let mut union: Vec<_> = (0..4)
            .flat_map(|i| jobs(&o, Shard { index: i, count: 4 }))
            .collect();
        union.sort();
        assert_eq!(union, whole);
    }

    #[test]
    fn setting_keys_are_unique() {
        let keys: std::collections::BTreeSet<_> = settings().iter().map(Setting::key).collect();
        assert_eq!(keys.len(), settings().len());
    }
}
