//! `host-sim reproduce` and `host-sim merge`: the paper's section 6, end to end.
//!
//! # The trial grid
//!
//! A **setting** is one curve of the paper: a household, a way of teaching, a teacher noise σ and
//! threshold. [`settings`] lists them in a fixed order:
//!
//! * **variety**: action, preference and semantic feedback, and behaviour cloning, in each of
//!   `doors`, `stairs-right` and `stairs-chairs` (σ = 0, threshold 1.0);
//! * **noise**: action feedback in `doors`, threshold 1.0, σ from 0 to 2.0 in steps of 0.125
//!   ([`NOISE_SWEEP`]); the curves of σ = 0, 0.25, 0.5, 1.0 are the paper's figure, the whole
//!   sweep gives the final latent loss against σ;
//! * **thresholds**: action feedback in `stairs-chairs`, σ = 0, the paper's thresholds 0, 0.25,
//!   0.5, 0.75, 1.0 and, so that the whole regime is visible, 2, 4 and 8 ([`THRESHOLDS`]).
//!
//! Each setting runs `trials` trials; trial `t` has seed `seed + t` (the same seeds in every
//! setting: common random numbers make the comparisons between settings less noisy). A seed
//! drives the teacher's noise and random preference queries and the start-pose jitter
//! ([`StartJitter::REPRODUCE`]), so trials differ even with a noiseless teacher. Every run uses
//! **the paper's learner, plain OGD with a constant step of 0.01** ([`paper_learner`]), not the
//! crate's default averaged OGD, the paper's semantic teacher (doors, stairs, chairs and the path
//! by cross-track error; [`crate::teacher::StatementSet::Paper`]) and the teachers calibrated by
//! `host-sim calibrate` ([`crate::calibrate`]), optionally all multiplied by
//! [`Options::teacher_scale`] (the scale sweep, [`scale_sweep`]).
//!
//! A **job** is one (setting, trial); jobs are numbered setting-major. Job `k` belongs to shard
//! `k mod n` of `--shard i/n` (round robin, so each shard gets a share of every experiment).
//!
//! # Paths
//!
//! For the path figures, trial 0 of the noise settings σ = 0, 1, 2 and of every threshold drives
//! one more lap after training: its final learner, frozen, from the scenario's own start (no
//! jitter), until a lap is done, the car is reset, or [`PATH_TICKS`] ticks. The teacher's own
//! policy drives the same way on each household. The mean true latent loss along the drawn lap
//! is reported beside it, with how the lap ended.
//!
//! # Outputs (`finalize`)
//!
//! `variety.csv`, `noise.csv`, `thresholds.csv` (per step: mean and sample standard deviation
//! across trials of the latent loss, of the cumulative corrections and of the progress along the
//! path), `noise_sweep.csv` (final latent loss and corrections against σ), `summary.csv` (one
//! row per setting, task success included), `paths.csv`, `figures/*.png` and `figures/*.svg`,
//! and `REPORT.md`: the calibration of the teachers, then the paper's claims
//! ([`crate::claims::CLAIMS`]) checked with these numbers, then the tables and figures. The
//! **final latent loss** of a trial is its mean latent loss over the last tenth of the steps (one
//! step's loss depends on where the car happens to be); the report gives its mean and standard
//! deviation across trials. **Task success** is reported beside it: laps, progress along the path
//! (metres: laps times the path's length plus the current lap's progress; a reset takes back its
//! lap's progress) and resets by cause. Nothing in these files depends on the
//! machine, the number of threads or the sharding: a merged result is byte-identical to a
//! one-machine run. The wall time is printed, never written into them.
//!
//! # Shards
//!
//! `--shard i/n` writes only its jobs' raw results: `manifest.json` and
//! `trials/KEY/TRIAL.csv` (`latent_loss,corrections,progress,lap,reset` per step; floats in
//! Rust's shortest round-trip form, so nothing is lost), plus `trials/KEY/path.csv` and
//! `path-end.csv` for the path runs. `host-sim merge DIR... --out DIR` checks that the shards
//! belong to one grid and cover it exactly once, reads them and writes the outputs above.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Context, Result, bail, ensure};
use firmware_core::{LearnerParams, LearnerSnapshot, PAPER_STEP};
use rayon::prelude::*;

use crate::claims::{self, Verdict};
use crate::experiment::{
    self, CarLink, InProcessLink, MAX_STEPS, Mode, RESET_CAUSES, RunConfig, StartJitter,
};
use crate::figure::{self, PALETTE, Panel, Picture, Series};
use crate::registry;
use crate::scenario::Scenario;
use crate::sim::{Episode, ResetReason};
use crate::teacher::{FeedbackKind, Teacher};

pub use crate::claims::CLAIMS;

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
/// Version of the shard files.
pub const SHARD_FORMAT: u32 = 2;
/// The factors of the teachers' scale the scale sweep runs the claims at.
pub const SWEEP_FACTORS: [f32; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];
/// Latent-loss curves are smoothed by a centred moving mean over this fraction of the run.
pub const SMOOTHING: f64 = 0.05;

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
            statements: Some(crate::teacher::StatementSet::Paper),
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
        let mut modes: Vec<Mode> = FeedbackKind::ALL.into_iter().map(Mode::Online).collect();
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

/// The size of the grid, and the teachers' scale.
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
}

impl Default for Options {
    fn default() -> Self {
        Self {
            trials: 10,
            steps: 5_000,
            seed: 0,
            teacher_scale: 1.0,
        }
    }
}

impl Options {
    /// The grid in words: "10 trials × 5000 steps, seed 0" (and the teachers' scale if not 1).
    pub fn describe(&self) -> String {
        let mut d = format!(
            "{} trials × {} steps, seed {}",
            self.trials, self.steps, self.seed
        );
        if self.teacher_scale != 1.0 {
            let _ = write!(d, ", teachers' scale × {}", self.teacher_scale);
        }
        d
    }

    /// Checks the numbers.
    pub fn check(&self) -> Result<()> {
        ensure!(
            self.teacher_scale.is_finite()
                && self.teacher_scale > 0.0
                && self.teacher_scale <= 1.0e3,
            "--teacher-scale must be in (0, 1000], got {}",
            self.teacher_scale
        );
        ensure!(
            (1..=MAX_TRIALS).contains(&self.trials),
            "--trials must be in 1..={MAX_TRIALS}, got {}",
            self.trials
        );
        ensure!(
            (10..=MAX_STEPS).contains(&self.steps),
            "--steps must be in 10..={MAX_STEPS}, got {}",
            self.steps
        );
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

/// A lap driven for a path figure.
#[derive(Clone, Debug, PartialEq)]
pub struct PathTrace {
    /// Positions of the rear axle, the start first.
    pub points: Vec<(f64, f64)>,
    /// Why it ended: `lap`, a reset reason (`collision`, `stuck`, `lost`, `blocked`) or `ticks`.
    pub end: String,
    /// Mean true latent loss of the actions along it (the setting's teacher, without noise).
    pub mean_latent_loss: f64,
}

impl PathTrace {
    /// Its loss with how it ended, so a short lap that ended in a reset does not read as the
    /// best: "0.010 (lost after 197 ticks)", "0.027 (a lap in 382 ticks)".
    pub fn loss_and_end(&self) -> String {
        let ticks = self.points.len().saturating_sub(1);
        let how = match self.end.as_str() {
            "lap" => format!("a lap in {ticks} ticks"),
            "ticks" => format!("no lap in {ticks} ticks"),
            reset => format!("{reset} after {ticks} ticks"),
        };
        format!("{:.3} ({how})", self.mean_latent_loss)
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
    /// Progress along the path per step (m; see [`crate::sim::Episode::path_progress`]).
    pub progress: Vec<f64>,
    /// Laps completed so far, per step.
    pub laps: Vec<u32>,
    /// The reset of each step, if any.
    pub resets: Vec<Option<ResetReason>>,
    /// The trained learner's lap (trial 0 of a setting that draws paths).
    pub path: Option<PathTrace>,
}

impl TrialResult {
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

/// Drives `snapshot`'s learner, frozen, from the scenario's start for at most `max_ticks`.
pub fn drive_lap(
    scenario: &Arc<Scenario>,
    snapshot: &LearnerSnapshot,
    teacher: crate::teacher::TeacherSpec,
    max_ticks: u32,
) -> Result<PathTrace> {
    let mut link = InProcessLink::new(snapshot.params)?;
    link.restore(snapshot)?;
    let mut judge = Teacher::new(
        crate::teacher::TeacherSpec {
            noise: 0.0,
            ..teacher
        },
        0,
    );
    let mut episode = Episode::new(scenario.clone());
    let start = episode.car().pose;
    let mut points = vec![(start.x, start.y)];
    let mut loss = 0.0f64;
    let mut acted = 0u32;
    let mut end = "ticks".to_string();
    for tick in 0..max_ticks {
        let obs = episode.observe();
        let decision = link.act(tick, &obs)?;
        let j = judge
            .judge(&obs)
            .map_err(|e| anyhow::anyhow!("tick {tick}: observation refused: {e}"))?;
        if let Some(a) = decision.action {
            loss += j.latent_loss(a) as f64;
            acted += 1;
        }
        let r = episode.drive(decision.action);
        if let Some(reason) = r.reset {
            end = if r.lap { "lap" } else { reason.name() }.to_string();
            break;
        }
        let p = episode.car().pose;
        points.push((p.x, p.y));
        if r.lap {
            end = "lap".into();
            break;
        }
    }
    Ok(PathTrace {
        points,
        end,
        mean_latent_loss: if acted > 0 { loss / acted as f64 } else { 0.0 },
    })
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
        Some(drive_lap(
            &scenario,
            &report.final_snapshot,
            config.teacher(),
            PATH_TICKS,
        )?)
    } else {
        None
    };
    Ok(TrialResult {
        setting,
        trial,
        latent: report.records.iter().map(|r| r.latent_loss).collect(),
        corrections: report.records.iter().map(|r| r.corrections).collect(),
        progress: report.records.iter().map(|r| r.progress).collect(),
        laps: report.records.iter().map(|r| r.lap).collect(),
        resets: report.records.iter().map(|r| r.reset).collect(),
        path,
    })
}

/// The jobs of `shard`: (setting, trial), in grid order.
pub fn jobs(o: &Options, shard: Shard) -> Vec<(usize, u32)> {
    let n = settings().len();
    (0..n)
        .flat_map(|s| (0..o.trials).map(move |t| (s, t)))
        .enumerate()
        .filter(|(k, _)| shard.has(*k))
        .map(|(_, j)| j)
        .collect()
}

/// Runs the jobs of `shard` on the current rayon pool; `done` is called after each job.
pub fn run_shard(o: &Options, shard: Shard, done: &(dyn Fn() + Sync)) -> Result<Vec<TrialResult>> {
    o.check()?;
    let households = load_households()?;
    let all = settings();
    let jobs = jobs(o, shard);
    let results: Vec<Result<TrialResult>> = jobs
        .par_iter()
        .map(|&(s, t)| {
            let r = run_job(&households, &all, s, t, o);
            done();
            r
        })
        .collect();
    results.into_iter().collect()
}

// ---------------------------------------------------------------------------------------------
// Shard files.

fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("{}: cannot create", parent.display()))?;
    }
    std::fs::write(path, bytes).with_context(|| format!("{}: cannot write", path.display()))
}

fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))
}

/// Writes a shard's raw results and its manifest into `dir`.
pub fn write_shard(dir: &Path, o: &Options, shard: Shard, results: &[TrialResult]) -> Result<()> {
    let all = settings();
    for r in results {
        let key = all[r.setting].key();
        let mut csv = String::from("latent_loss,corrections,progress,lap,reset\n");
        for i in 0..r.latent.len() {
            let _ = writeln!(
                csv,
                "{},{},{},{},{}",
                r.latent[i],
                r.corrections[i],
                r.progress[i],
                r.laps[i],
                r.resets[i].map_or("", |x| x.name())
            );
        }
        write_file(
            &dir.join("trials")
                .join(&key)
                .join(format!("{}.csv", r.trial)),
            csv.as_bytes(),
        )?;
        if let Some(p) = &r.path {
            let mut csv = String::from("x,y\n");
            for (x, y) in &p.points {
                let _ = writeln!(csv, "{x},{y}");
            }
            write_file(
                &dir.join("trials").join(&key).join("path.csv"),
                csv.as_bytes(),
            )?;
            write_file(
                &dir.join("trials").join(&key).join("path-end.csv"),
                format!("end,mean_latent_loss\n{},{}\n", p.end, p.mean_latent_loss).as_bytes(),
            )?;
        }
    }
    let manifest = serde_json::json!({
        "format": SHARD_FORMAT,
        "trials": o.trials,
        "steps": o.steps,
        "seed": o.seed,
        "teacher_scale": o.teacher_scale,
        "shard": shard.index,
        "shards": shard.count,
        "jobs": results.len(),
        "settings": all.iter().map(Setting::key).collect::<Vec<_>>(),
    });
    write_file(
        &dir.join("manifest.json"),
        (serde_json::to_string_pretty(&manifest)? + "\n").as_bytes(),
    )
}

fn read_manifest(dir: &Path) -> Result<(Options, Shard)> {
    let path = dir.join("manifest.json");
    let v: serde_json::Value = serde_json::from_str(&read_text(&path)?)
        .with_context(|| format!("{}: not JSON", path.display()))?;
    let num = |k: &str| {
        v.get(k)
            .and_then(serde_json::Value::as_u64)
            .with_context(|| format!("{}: no number {k:?}", path.display()))
    };
    ensure!(
        num("format")? == SHARD_FORMAT as u64,
        "{}: shard format {} (this build reads {SHARD_FORMAT})",
        path.display(),
        num("format")?
    );
    let keys: Vec<String> = settings().iter().map(Setting::key).collect();
    ensure!(
        v.get("settings") == Some(&serde_json::json!(keys)),
        "{}: written by a build with other settings",
        path.display()
    );
    let small = |k: &str| -> Result<u32> {
        u32::try_from(num(k)?).with_context(|| format!("{}: {k} too large", path.display()))
    };
    let teacher_scale = v
        .get("teacher_scale")
        .and_then(serde_json::Value::as_f64)
        .with_context(|| format!("{}: no number \"teacher_scale\"", path.display()))?
        as f32;
    let o = Options {
        trials: small("trials")?,
        steps: small("steps")?,
        seed: num("seed")?,
        teacher_scale,
    };
    o.check()
        .with_context(|| format!("{}: bad grid", path.display()))?;
    let (index, count) = (small("shard")?, small("shards")?);
    ensure!(
        count > 0 && index < count,
        "{}: bad shard {index}/{count}",
        path.display()
    );
    Ok((o, Shard { index, count }))
}

/// The per-step columns of one trial's file.
type TrialColumns = (
    Vec<f32>,
    Vec<u32>,
    Vec<f64>,
    Vec<u32>,
    Vec<Option<ResetReason>>,
);

fn parse_trial(path: &Path, steps: u32) -> Result<TrialColumns> {
    let text = read_text(path)?;
    let mut lines = text.lines();
    ensure!(
        lines.next() == Some("latent_loss,corrections,progress,lap,reset"),
        "{}: bad header",
        path.display()
    );
    let mut out: TrialColumns = Default::default();
    for (i, line) in lines.enumerate() {
        let bad = || format!("{}: line {}: bad row {line:?}", path.display(), i + 2);
        let f: Vec<&str> = line.split(',').collect();
        ensure!(f.len() == 5, "{}", bad());
        let l: f32 = f[0]
            .parse()
            .ok()
            .filter(|v: &f32| v.is_finite())
            .with_context(bad)?;
        let p: f64 = f[2]
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .with_context(bad)?;
        let reset = match f[4] {
            "" => None,
            name => Some(ResetReason::from_name(name).with_context(bad)?),
        };
        out.0.push(l);
        out.1.push(f[1].parse().ok().with_context(bad)?);
        out.2.push(p);
        out.3.push(f[3].parse().ok().with_context(bad)?);
        out.4.push(reset);
    }
    ensure!(
        out.0.len() == steps as usize,
        "{}: {} rows, expected {steps}",
        path.display(),
        out.0.len()
    );
    Ok(out)
}

fn parse_path(dir: &Path) -> Result<PathTrace> {
    let path = dir.join("path.csv");
    let text = read_text(&path)?;
    let mut points = Vec::new();
    for (i, line) in text.lines().skip(1).enumerate() {
        let bad = || format!("{}: line {}: bad row {line:?}", path.display(), i + 2);
        let (x, y) = line.split_once(',').with_context(bad)?;
        let x: f64 = x
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .with_context(bad)?;
        let y: f64 = y
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .with_context(bad)?;
        points.push((x, y));
    }
    let end_path = dir.join("path-end.csv");
    let end_text = read_text(&end_path)?;
    let row = end_text
        .lines()
        .nth(1)
        .with_context(|| format!("{}: no row", end_path.display()))?;
    let (end, loss) = row
        .split_once(',')
        .with_context(|| format!("{}: bad row", end_path.display()))?;
    let mean_latent_loss: f64 = loss
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite())
        .with_context(|| format!("{}: bad loss", end_path.display()))?;
    Ok(PathTrace {
        points,
        end: end.to_string(),
        mean_latent_loss,
    })
}

/// Reads shard folders; checks that they are one grid, each shard exactly once.
pub fn read_shards(dirs: &[PathBuf]) -> Result<(Options, Vec<TrialResult>)> {
    ensure!(!dirs.is_empty(), "merge needs at least one shard folder");
    let mut grid: Option<(Options, u32)> = None;
    let mut seen = BTreeMap::new();
    // Folders without a manifest: a shard writes it last, so these did not finish (a failed or
    // cancelled job); they are named with the missing shards below.
    let mut unfinished: Vec<String> = Vec::new();
    for d in dirs {
        if d.is_dir() && !d.join("manifest.json").exists() {
            unfinished.push(d.display().to_string());
            continue;
        }
        let (o, shard) = read_manifest(d)?;
        match grid {
            None => grid = Some((o, shard.count)),
            Some((g, n)) => ensure!(
                g == o && n == shard.count,
                "{}: a different grid ({}, {} shards) from the first folder's ({}, {n} shards)",
                d.display(),
                o.describe(),
                shard.count,
                g.describe()
            ),
        }
        if let Some(other) = seen.insert(shard.index, d.clone()) {
            bail!(
                "shard {} given twice: {} and {}",
                shard.index,
                other.display(),
                d.display()
            );
        }
    }
    let unfinished_note = if unfinished.is_empty() {
        String::new()
    } else {
        format!(
            "; {} has no manifest.json (a shard writes it last, so it did not finish)",
            unfinished.join(", ")
        )
    };
    let Some((o, n)) = grid else {
        bail!("no finished shard among the folders{unfinished_note}");
    };
    let missing: Vec<u32> = (0..n).filter(|i| !seen.contains_key(i)).collect();
    ensure!(
        missing.is_empty(),
        "shards {missing:?} of {n} are missing{unfinished_note}: run `host-sim reproduce --trials {} \
         --steps {} --seed {}{} --shard INDEX/{n}` again for each missing INDEX, then merge again",
        o.trials,
        o.steps,
        o.seed,
        if o.teacher_scale != 1.0 {
            format!(" --teacher-scale {}", o.teacher_scale)
        } else {
            String::new()
        }
    );
    let all = settings();
    let mut results = Vec::new();
    for (index, dir) in &seen {
        for (s, t) in jobs(
            &o,
            Shard {
                index: *index,
                count: n,
            },
        ) {
            let sdir = dir.join("trials").join(all[s].key());
            let (latent, corrections, progress, laps, resets) =
                parse_trial(&sdir.join(format!("{t}.csv")), o.steps)?;
            let path = if all[s].draw_path && t == 0 {
                Some(parse_path(&sdir)?)
            } else {
                None
            };
            results.push(TrialResult {
                setting: s,
                trial: t,
                latent,
                corrections,
                progress,
                laps,
                resets,
                path,
            });
        }
    }
    results.sort_by_key(|r| (r.setting, r.trial));
    Ok((o, results))
}

// ---------------------------------------------------------------------------------------------
// Aggregates.

/// Mean and sample standard deviation (0 for one value).
pub fn mean_std(xs: &[f64]) -> (f64, f64) {
    let n = xs.len();
    if n == 0 {
        return (0.0, 0.0);
    }
    let m = xs.iter().sum::<f64>() / n as f64;
    if n == 1 {
        return (m, 0.0);
    }
    let v = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1) as f64;
    (m, v.sqrt())
}

/// One setting across its trials.
#[derive(Clone, Debug)]
pub struct Aggregate {
    /// The setting.
    pub setting: Setting,
    /// Trials.
    pub trials: usize,
    /// Per step: mean and std of the latent loss.
    pub loss: Vec<(f64, f64)>,
    /// Per step: mean and std of the cumulative corrections.
    pub corrections: Vec<(f64, f64)>,
    /// Per step: mean and std of the progress along the path (m).
    pub progress_curve: Vec<(f64, f64)>,
    /// Mean latent loss of the first tenth of the steps: mean and std across trials.
    pub first_loss: (f64, f64),
    /// Final latent loss (mean of the last tenth): mean and std across trials.
    pub final_loss: (f64, f64),
    /// Corrections in all.
    pub total_corrections: (f64, f64),
    /// Corrections in the first tenth.
    pub first_tenth_corrections: (f64, f64),
    /// Corrections in the last tenth.
    pub last_tenth_corrections: (f64, f64),
    /// Laps in all.
    pub laps: (f64, f64),
    /// Trials with at least one lap.
    pub lapped: usize,
    /// Progress along the path at the end (m).
    pub progress: (f64, f64),
    /// Resets per trial by cause (means): collision, stuck, lost, blocked.
    pub resets: [f64; 4],
    /// Trial 0's trained learner's lap.
    pub path: Option<PathTrace>,
}

impl Aggregate {
    /// An aggregate of `setting` over `trials` trials with every number 0 and no curve (for
    /// tests and for filling in by hand).
    pub fn empty(setting: Setting, trials: usize) -> Self {
        Self {
            setting,
            trials,
            loss: Vec::new(),
            corrections: Vec::new(),
            progress_curve: Vec::new(),
            first_loss: (0.0, 0.0),
            final_loss: (0.0, 0.0),
            total_corrections: (0.0, 0.0),
            first_tenth_corrections: (0.0, 0.0),
            last_tenth_corrections: (0.0, 0.0),
            laps: (0.0, 0.0),
            lapped: 0,
            progress: (0.0, 0.0),
            resets: [0.0; 4],
            path: None,
        }
    }
}

/// Steps in a tenth of `steps` (at least one).
pub fn tenth(steps: usize) -> usize {
    ((steps as f64 / 10.0).round() as usize).max(1)
}

/// The aggregate of `setting` over `trials` (all of the same length).
pub fn aggregate(setting: Setting, trials: &[&TrialResult]) -> Aggregate {
    let steps = trials.first().map_or(0, |t| t.latent.len());
    if steps == 0 {
        return Aggregate::empty(setting, trials.len());
    }
    let k = tenth(steps);
    let per_step = |f: &dyn Fn(&TrialResult, usize) -> f64| -> Vec<(f64, f64)> {
        (0..steps)
            .map(|i| mean_std(&trials.iter().map(|t| f(t, i)).collect::<Vec<_>>()))
            .collect()
    };
    let over = |f: &dyn Fn(&TrialResult) -> f64| -> (f64, f64) {
        mean_std(&trials.iter().map(|t| f(t)).collect::<Vec<_>>())
    };
    let mean_of = |xs: &[f32]| xs.iter().map(|&x| x as f64).sum::<f64>() / xs.len().max(1) as f64;
    let at = |t: &TrialResult, i: usize| t.corrections[i] as f64;
    let n = trials.len().max(1) as f64;
    let mut resets = [0.0; 4];
    for t in trials {
        for (r, c) in resets.iter_mut().zip(t.reset_counts()) {
            *r += c as f64 / n;
        }
    }
    let last = |t: &TrialResult| t.laps[steps - 1];
    Aggregate {
        setting,
        trials: trials.len(),
        first_loss: over(&|t| mean_of(&t.latent[..k])),
        final_loss: over(&|t| mean_of(&t.latent[steps - k..])),
        total_corrections: over(&|t| at(t, steps - 1)),
        first_tenth_corrections: over(&|t| at(t, k - 1)),
        last_tenth_corrections: over(&|t| {
            at(t, steps - 1) - if steps > k { at(t, steps - k - 1) } else { 0.0 }
        }),
        laps: over(&|t| last(t) as f64),
        lapped: trials.iter().filter(|t| last(t) > 0).count(),
        progress: over(&|t| t.progress[steps - 1]),
        resets,
        path: trials
            .iter()
            .find(|t| t.trial == 0)
            .and_then(|t| t.path.clone()),
        loss: per_step(&|t, i| t.latent[i] as f64),
        corrections: per_step(&|t, i| t.corrections[i] as f64),
        progress_curve: per_step(&|t, i| t.progress[i]),
    }
}

/// Aggregates every setting; checks the results are the whole grid.
pub fn aggregate_all(o: &Options, results: &[TrialResult]) -> Result<Vec<Aggregate>> {
    let all = settings();
    let mut by: Vec<Vec<&TrialResult>> = vec![Vec::new(); all.len()];
    for r in results {
        ensure!(
            r.setting < all.len() && r.latent.len() == o.steps as usize,
            "a result of another grid"
        );
        by[r.setting].push(r);
    }
    for (s, rs) in by.iter_mut().enumerate() {
        rs.sort_by_key(|r| r.trial);
        let trials: Vec<u32> = rs.iter().map(|r| r.trial).collect();
        ensure!(
            trials == (0..o.trials).collect::<Vec<_>>(),
            "{}: trials {trials:?}, expected 0..{}",
            all[s].key(),
            o.trials
        );
    }
    Ok(all
        .iter()
        .zip(&by)
        .map(|(s, rs)| aggregate(*s, rs))
        .collect())
}

// ---------------------------------------------------------------------------------------------
// Outputs.

fn per_step_csv(head: &str, rows: &[(String, &Aggregate)]) -> String {
    let mut out = format!(
        "{head},step,latent_loss_mean,latent_loss_std,corrections_mean,corrections_std,progress_mean,progress_std\n"
    );
    for (label, a) in rows {
        for (i, ((l, c), p)) in a
            .loss
            .iter()
            .zip(&a.corrections)
            .zip(&a.progress_curve)
            .enumerate()
        {
            let _ = writeln!(
                out,
                "{label},{i},{:.6},{:.6},{:.6},{:.6},{:.3},{:.3}",
                l.0, l.1, c.0, c.1, p.0, p.1
            );
        }
    }
    out
}

/// One experiment's per-step CSV (`NAME.csv`, keyed by `key`) and its figure (`figures/NAME`):
/// latent loss and corrections of the settings `on_figure` picks, labelled "KEY VALUE".
#[expect(
    clippy::too_many_arguments,
    reason = "one call per experiment, every argument named"
)]
fn write_curves(
    out: &Path,
    figs: &Path,
    name: &str,
    title: &str,
    aggs: &[&Aggregate],
    key: &str,
    value: impl Fn(&Aggregate) -> String,
    on_figure: impl Fn(&Aggregate) -> bool,
) -> Result<()> {
    let rows: Vec<(String, &Aggregate)> = aggs.iter().map(|a| (value(a), *a)).collect();
    write_file(
        &out.join(format!("{name}.csv")),
        per_step_csv(key, &rows).as_bytes(),
    )?;
    let curves: Vec<(String, &Aggregate)> = aggs
        .iter()
        .filter(|a| on_figure(a))
        .map(|a| (format!("{key} {}", value(a)), *a))
        .collect();
    figure::write_chart(
        &figs.join(name),
        title,
        &[
            loss_panel("latent loss", &curves),
            corrections_panel("corrections", &curves),
        ],
        2,
        (600, 420),
    )
}

/// `a ± b` of the laps and progress, and the mean resets by cause, for the tables.
fn task_cells(a: &Aggregate) -> String {
    format!(
        "{} ({}/{}) | {:.0} ± {:.0} | {}",
        claims::pm1(a.laps),
        a.lapped,
        a.trials,
        a.progress.0,
        a.progress.1,
        a.resets
            .iter()
            .map(|r| format!("{r:.1}"))
            .collect::<Vec<_>>()
            .join(" / ")
    )
}

const TASK_HEAD: &str =
    "laps (trials that lapped) | progress (m) | resets: collision / stuck / lost / blocked";

fn summary_csv(aggs: &[Aggregate]) -> String {
    let mut out = String::from(
        "experiment,household,feedback,sigma,threshold,trials,first_tenth_loss_mean,first_tenth_loss_std,final_loss_mean,final_loss_std,corrections_mean,corrections_std,first_tenth_corrections_mean,last_tenth_corrections_mean,laps_mean,laps_std,trials_lapped,progress_m_mean,progress_m_std,resets_collision_mean,resets_stuck_mean,resets_lost_mean,resets_blocked_mean\n",
    );
    for a in aggs {
        let s = &a.setting;
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{:.6},{:.6},{:.6},{:.6},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3}",
            s.group.name(),
            s.household,
            s.mode.name(),
            s.noise,
            s.threshold,
            a.trials,
            a.first_loss.0,
            a.first_loss.1,
            a.final_loss.0,
            a.final_loss.1,
            a.total_corrections.0,
            a.total_corrections.1,
            a.first_tenth_corrections.0,
            a.last_tenth_corrections.0,
            a.laps.0,
            a.laps.1,
            a.lapped,
            a.progress.0,
            a.progress.1,
            a.resets[0],
            a.resets[1],
            a.resets[2],
            a.resets[3],
        );
    }
    out
}

/// Steps in the smoothing window of a run of `steps` steps ([`SMOOTHING`] of it, at least 1).
pub fn smoothing_window(steps: usize) -> usize {
    ((steps as f64 * SMOOTHING).round() as usize).max(1)
}

/// A per-step curve for a chart: at most 100 points, each the centred moving mean over
/// `window` steps (shorter at the ends) of the mean and of the standard deviation.
pub fn smoothed(v: &[(f64, f64)], window: usize) -> Vec<(f64, f64, f64)> {
    let n = v.len();
    if n == 0 {
        return Vec::new();
    }
    let mut sm = vec![0.0; n + 1];
    let mut ss = vec![0.0; n + 1];
    for (i, (m, s)) in v.iter().enumerate() {
        sm[i + 1] = sm[i] + m;
        ss[i + 1] = ss[i] + s;
    }
    let b = n.min(100);
    let half = window / 2;
    (0..b)
        .map(|k| {
            let c = (2 * k + 1) * n / (2 * b);
            let (lo, hi) = (c.saturating_sub(half), (c + window - half).min(n));
            let len = (hi - lo) as f64;
            (c as f64, (sm[hi] - sm[lo]) / len, (ss[hi] - ss[lo]) / len)
        })
        .collect()
}

/// A cumulative per-step curve for a chart: its value at the end of each of at most 100 blocks.
fn sampled(v: &[(f64, f64)]) -> Vec<(f64, f64, f64)> {
    let n = v.len();
    let b = n.min(100);
    (0..b)
        .map(|k| {
            let hi = ((k + 1) * n / b).max(1);
            let (m, s) = v[hi - 1];
            (hi as f64, m, s)
        })
        .collect()
}

fn loss_panel(title: &str, rows: &[(String, &Aggregate)]) -> Panel {
    Panel {
        title: title.to_string(),
        x_label: "step".into(),
        y_label: "latent loss".into(),
        band: true,
        legend_left: false,
        series: rows
            .iter()
            .enumerate()
            .map(|(i, (label, a))| Series {
                label: label.clone(),
                colour: PALETTE[i % PALETTE.len()],
                points: smoothed(&a.loss, smoothing_window(a.loss.len())),
            })
            .collect(),
    }
}

fn corrections_panel(title: &str, rows: &[(String, &Aggregate)]) -> Panel {
    Panel {
        title: title.to_string(),
        x_label: "step".into(),
        y_label: "corrections".into(),
        band: true,
        legend_left: true,
        series: rows
            .iter()
            .enumerate()
            .map(|(i, (label, a))| Series {
                label: label.clone(),
                colour: PALETTE[i % PALETTE.len()],
                points: sampled(&a.corrections),
            })
            .collect(),
    }
}

/// Progress along the path against the step, and the teacher's own pace (`pace` metres per
/// tick) as a reference line.
fn progress_panel(title: &str, rows: &[(String, &Aggregate)], pace: Option<f64>) -> Panel {
    let mut series: Vec<Series> = rows
        .iter()
        .enumerate()
        .map(|(i, (label, a))| Series {
            label: label.clone(),
            colour: PALETTE[i % PALETTE.len()],
            points: sampled(&a.progress_curve),
        })
        .collect();
    let steps = rows.first().map_or(0, |(_, a)| a.progress_curve.len()) as f64;
    if let Some(p) = pace {
        series.push(Series {
            label: "teacher's pace".into(),
            colour: plotters::style::RGBColor(0, 0, 0),
            points: vec![(0.0, 0.0, 0.0), (steps, p * steps, 0.0)],
        });
    }
    Panel {
        title: title.to_string(),
        x_label: "step".into(),
        y_label: "progress along the path (m)".into(),
        band: true,
        legend_left: true,
        series,
    }
}

const TEACHER_COLOUR: [u8; 3] = [150, 0, 200];
const LEARNER_COLOUR: [u8; 3] = [255, 140, 0];

fn map_picture(
    scenario: &Scenario,
    scale: usize,
    caption: String,
    teacher: &PathTrace,
    learner: Option<&PathTrace>,
) -> Picture {
    let mut r = crate::plot::Raster::of_scenario_scaled(scenario, scale);
    r.polyline(&teacher.points, TEACHER_COLOUR);
    if let Some(l) = learner {
        r.polyline(&l.points, LEARNER_COLOUR);
    }
    let (width, height) = r.size();
    Picture {
        caption,
        width,
        height,
        rgb: r.rgb().to_vec(),
    }
}

/// One row per setting of `group`: its key column, the losses, the corrections, the task.
fn summary_table(
    r: &mut String,
    aggs: &[Aggregate],
    group: Group,
    key: &str,
    key_of: impl Fn(&Aggregate) -> String,
) {
    let _ = writeln!(
        r,
        "| {key} | first-tenth loss | final loss | corrections | first → last tenth corrections | {TASK_HEAD} |\n|---|---|---|---|---|---|---|---|"
    );
    for a in aggs.iter().filter(|a| a.setting.group == group) {
        let _ = writeln!(
            r,
            "| {} | {} | {} | {} | {:.1} → {:.1} | {} |",
            key_of(a),
            claims::pm(a.first_loss),
            claims::pm(a.final_loss),
            claims::pm1(a.total_corrections),
            a.first_tenth_corrections.0,
            a.last_tenth_corrections.0,
            task_cells(a)
        );
    }
}

/// Spearman rank correlation (average ranks for ties; 0 when either side is constant).
pub fn spearman(x: &[f64], y: &[f64]) -> f64 {
    fn ranks(v: &[f64]) -> Vec<f64> {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
        let mut r = vec![0.0; v.len()];
        let mut i = 0;
        while i < idx.len() {
            let mut j = i;
            while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
                j += 1;
            }
            for k in i..=j {
                r[idx[k]] = (i + j) as f64 / 2.0 + 1.0;
            }
            i = j + 1;
        }
        r
    }
    let (rx, ry) = (ranks(x), ranks(y));
    let (mx, _) = mean_std(&rx);
    let (my, _) = mean_std(&ry);
    let cov: f64 = rx.iter().zip(&ry).map(|(a, b)| (a - mx) * (b - my)).sum();
    let vx: f64 = rx.iter().map(|a| (a - mx) * (a - mx)).sum();
    let vy: f64 = ry.iter().map(|b| (b - my) * (b - my)).sum();
    if vx == 0.0 || vy == 0.0 {
        0.0
    } else {
        cov / (vx * vy).sqrt()
    }
}

/// Every claim's verdict from the aggregates of a whole grid.
pub fn verdicts(o: &Options, aggs: &[Aggregate]) -> Vec<Verdict> {
    let get = |g: Group, h: &str, m: &str, noise: f32, thr: f32| -> Option<&Aggregate> {
        aggs.iter().find(|a| {
            a.setting.group == g
                && a.setting.household == h
                && a.setting.mode.name() == m
                && a.setting.noise == noise
                && a.setting.threshold == thr
        })
    };
    let online = ["action", "preference", "semantic"];
    let doors: Vec<&Aggregate> = online
        .iter()
        .filter_map(|m| get(Group::Variety, "doors", m, 0.0, 1.0))
        .collect();
    let bc: Vec<&Aggregate> = HOUSEHOLDS
        .iter()
        .filter_map(|h| get(Group::Variety, h, "bc", 0.0, 1.0))
        .collect();
    let per_house: Vec<(&str, Vec<&Aggregate>)> = HOUSEHOLDS
        .iter()
        .map(|h| {
            (
                *h,
                online
                    .iter()
                    .filter_map(|m| get(Group::Variety, h, m, 0.0, 1.0))
                    .collect(),
            )
        })
        .collect();
    let curves: Vec<&Aggregate> = NOISE_CURVES
        .iter()
        .filter_map(|&s| get(Group::Noise, "doors", "action", s, 1.0))
        .collect();
    let sweep: Vec<&Aggregate> = aggs
        .iter()
        .filter(|a| a.setting.group == Group::Noise)
        .collect();
    let paper: Vec<&Aggregate> = PAPER_THRESHOLDS
        .iter()
        .filter_map(|&t| get(Group::Thresholds, "stairs-chairs", "action", 0.0, t))
        .collect();
    let all_thr: Vec<&Aggregate> = THRESHOLDS
        .iter()
        .filter_map(|&t| get(Group::Thresholds, "stairs-chairs", "action", 0.0, t))
        .collect();
    let online_settings: Vec<&Aggregate> = aggs
        .iter()
        .filter(|a| matches!(a.setting.mode, Mode::Online(_)))
        .collect();
    vec![
        claims::feedback_lowers_loss(&doors),
        claims::bc_flat(&bc),
        claims::action_fewest(&per_house, o.trials as usize),
        claims::noise_raises(&curves, &sweep),
        claims::threshold_lowers(&paper, &all_thr),
        claims::corrections_flatten(&online_settings, tenth(o.steps as usize)),
    ]
}

/// The teacher's own lap of every household (purple in the path figures).
fn teacher_laps(
    o: &Options,
    households: &BTreeMap<&'static str, Arc<Scenario>>,
) -> Result<BTreeMap<&'static str, PathTrace>> {
    let mut laps = BTreeMap::new();
    for h in HOUSEHOLDS {
        let s = &households[h];
        let teacher = crate::teacher::TeacherSpec {
            weights: crate::teacher::scaled(&s.teacher.weights, o.teacher_scale),
            ..s.teacher
        };
        let snap = experiment::learner_with(paper_learner(), teacher.weights)?;
        laps.insert(h, drive_lap(s, &snap, teacher, PATH_TICKS)?);
    }
    Ok(laps)
}

/// Writes every output of a finished grid into `out`; returns the report's text.
pub fn finalize(out: &Path, o: &Options, results: &[TrialResult]) -> Result<String> {
    let aggs = aggregate_all(o, results)?;
    let households = load_households()?;
    let figs = out.join("figures");
    std::fs::create_dir_all(&figs).with_context(|| format!("{}: cannot create", figs.display()))?;
    let find = |g: Group, pred: &dyn Fn(&Setting) -> bool| -> Vec<&Aggregate> {
        aggs.iter()
            .filter(|a| a.setting.group == g && pred(&a.setting))
            .collect()
    };
    let teacher_paths = teacher_laps(o, &households)?;
    // The teacher's pace in each household: metres of path per tick of its lap.
    let pace = |h: &str| {
        let t = &teacher_paths[h];
        (t.end == "lap" && t.points.len() > 1)
            .then(|| households[h].path.length() / (t.points.len() - 1) as f64)
    };

    // Variety.
    let variety = find(Group::Variety, &|_| true);
    let rows: Vec<(String, &Aggregate)> = variety
        .iter()
        .map(|a| {
            (
                format!("{},{}", a.setting.household, a.setting.mode.name()),
                *a,
            )
        })
        .collect();
    write_file(
        &out.join("variety.csv"),
        per_step_csv("household,feedback", &rows).as_bytes(),
    )?;
    let by_house = |h: &str, online_only: bool| -> Vec<(String, &Aggregate)> {
        variety
            .iter()
            .filter(|a| {
                a.setting.household == h
                    && (!online_only || matches!(a.setting.mode, Mode::Online(_)))
            })
            .map(|a| (a.setting.mode.name().to_string(), *a))
            .collect()
    };
    let mut panels = Vec::new();
    for h in HOUSEHOLDS {
        panels.push(loss_panel(
            &format!("{h}: latent loss"),
            &by_house(h, false),
        ));
    }
    for h in HOUSEHOLDS {
        panels.push(corrections_panel(
            &format!("{h}: corrections"),
            &by_house(h, true),
        ));
    }
    figure::write_chart(
        &figs.join("variety"),
        "Learning from a variety of feedback (mean ± std across trials)",
        &panels,
        3,
        (560, 400),
    )?;

    // Noise.
    let noise = find(Group::Noise, &|_| true);
    write_curves(
        out,
        &figs,
        "noise",
        "Learning under noisy feedback: doors, action feedback, threshold 1.0",
        &noise,
        "σ",
        |a| a.setting.noise.to_string(),
        |a| NOISE_CURVES.contains(&a.setting.noise),
    )?;
    let mut sweep = String::from(
        "sigma,trials,final_latent_loss_mean,final_latent_loss_std,corrections_mean,corrections_std\n",
    );
    for a in &noise {
        let _ = writeln!(
            sweep,
            "{},{},{:.6},{:.6},{:.3},{:.3}",
            a.setting.noise,
            a.trials,
            a.final_loss.0,
            a.final_loss.1,
            a.total_corrections.0,
            a.total_corrections.1
        );
    }
    write_file(&out.join("noise_sweep.csv"), sweep.as_bytes())?;
    let sweep_series = |label: &str, get: &dyn Fn(&Aggregate) -> (f64, f64), c| Series {
        label: label.to_string(),
        colour: c,
        points: noise
            .iter()
            .map(|a| {
                let (m, s) = get(a);
                (a.setting.noise as f64, m, s)
            })
            .collect(),
    };
    figure::write_chart(
        &figs.join("noise_sweep"),
        "Noise sweep: final latent loss and corrections against σ",
        &[
            Panel {
                title: "final latent loss".into(),
                x_label: "σ".into(),
                y_label: "latent loss".into(),
                band: false,
                legend_left: true,
                series: vec![sweep_series("final loss", &|a| a.final_loss, PALETTE[0])],
            },
            Panel {
                title: "corrections in all".into(),
                x_label: "σ".into(),
                y_label: "corrections".into(),
                band: false,
                legend_left: true,
                series: vec![sweep_series(
                    "corrections",
                    &|a| a.total_corrections,
                    PALETTE[1],
                )],
            },
        ],
        2,
        (600, 420),
    )?;

    // Thresholds.
    let thr = find(Group::Thresholds, &|_| true);
    write_curves(
        out,
        &figs,
        "thresholds",
        "Teacher thresholds: stairs-chairs, action feedback",
        &thr,
        "threshold",
        |a| a.setting.threshold.to_string(),
        |_| true,
    )?;
    write_file(&out.join("summary.csv"), summary_csv(&aggs).as_bytes())?;

    // Task success.
    let mut panels = Vec::new();
    for h in HOUSEHOLDS {
        panels.push(progress_panel(
            &format!("{h}: progress"),
            &by_house(h, false),
            pace(h),
        ));
    }
    fn labelled<'a>(
        v: &[&'a Aggregate],
        key: &str,
        value: &dyn Fn(&Aggregate) -> String,
    ) -> Vec<(String, &'a Aggregate)> {
        v.iter()
            .map(|a| (format!("{key} {}", value(a)), *a))
            .collect()
    }
    let noise_curves: Vec<&Aggregate> = noise
        .iter()
        .copied()
        .filter(|a| NOISE_CURVES.contains(&a.setting.noise))
        .collect();
    panels.push(progress_panel(
        "doors, noise: progress",
        &labelled(&noise_curves, "σ", &|a| a.setting.noise.to_string()),
        pace("doors"),
    ));
    panels.push(progress_panel(
        "stairs-chairs, thresholds: progress",
        &labelled(&thr, "threshold", &|a| a.setting.threshold.to_string()),
        pace("stairs-chairs"),
    ));
    figure::write_chart(
        &figs.join("task_success"),
        "Task success: progress along the path (m; a reset takes back its lap's; mean ± std across trials)",
        &panels,
        3,
        (560, 400),
    )?;

    // Paths, every map at one scale.
    let maps: Vec<&Scenario> = HOUSEHOLDS.iter().map(|h| &*households[h]).collect();
    let scale = crate::plot::Raster::common_scale(&maps, 720);
    let cm = 100.0 * crate::plot::Raster::metres_per_pixel(maps[0], scale);
    let mut paths_csv = String::from("figure,household,who,setting,point,x,y\n");
    let mut add_path = |fig: &str, h: &str, who: &str, key: &str, p: &PathTrace| {
        for (i, (x, y)) in p.points.iter().enumerate() {
            let _ = writeln!(paths_csv, "{fig},{h},{who},{key},{i},{x:.4},{y:.4}");
        }
    };
    let mut pics = Vec::new();
    for h in HOUSEHOLDS {
        let t = &teacher_paths[h];
        add_path("teachers", h, "teacher", "teacher", t);
        pics.push(map_picture(
            &households[h],
            scale,
            format!(
                "{h}: {} teacher, {}",
                households[h].teacher.preset.unwrap_or("its"),
                t.loss_and_end()
            ),
            t,
            None,
        ));
    }
    figure::write_pictures(
        &figs.join("paths_teachers"),
        "The teachers' paths",
        &format!(
            "purple: the teacher's own policy, one lap from the start; blue: the reference path; doors brown, stairs red, chairs green; every map at 1 px = {cm:.1} cm"
        ),
        &pics,
        3,
    )?;
    let mut path_rows = Vec::new();
    for (g, stem, title, house) in [
        (
            Group::Noise,
            "paths_noise",
            "Paths after training under noise (doors, action feedback)",
            "doors",
        ),
        (
            Group::Thresholds,
            "paths_thresholds",
            "Paths after training with different thresholds (stairs-chairs)",
            "stairs-chairs",
        ),
    ] {
        let mut pics = Vec::new();
        for a in find(g, &|s| s.draw_path) {
            let Some(p) = &a.path else { continue };
            let label = match g {
                Group::Noise => format!("σ {}", a.setting.noise),
                _ => format!("threshold {}", a.setting.threshold),
            };
            add_path(stem, house, "learner", &a.setting.key(), p);
            pics.push(map_picture(
                &households[house],
                scale,
                format!("{label}: latent loss {}", p.loss_and_end()),
                &teacher_paths[house],
                Some(p),
            ));
            path_rows.push((label, house, p.clone()));
        }
        figure::write_pictures(
            &figs.join(stem),
            title,
            &format!(
                "orange: trial 0's trained learner, frozen, one lap from the start; purple: the teacher; caption: mean latent loss along the drive (how it ended); 1 px = {cm:.1} cm"
            ),
            &pics,
            3,
        )?;
    }
    write_file(&out.join("paths.csv"), paths_csv.as_bytes())?;

    let calibration = crate::calibrate::run()?;
    let report = report(o, &aggs, &calibration, &teacher_paths, &path_rows, cm);
    write_file(&out.join("REPORT.md"), report.as_bytes())?;
    Ok(report)
}

/// The report's calibration section: the targets in one line each, the procedure's figures, the
/// rule's outcome and the frozen weights.
fn calibration_section(r: &mut String, o: &Options, c: &crate::calibrate::Calibration) {
    let _ = writeln!(
        r,
        "## Calibration of the teachers\n\n\
         The paper gives what each teacher wants but not the scale of its weights, and the scale \
         decides which regime a threshold lands in (the latent loss grows with it, the policy does \
         not). `docs/reproduction/CALIBRATION.md` wrote down, before any claim was checked, \
         targets from the paper's own words, stated on the *path follower* (the teacher without \
         its semantic weights, the learner that \"just focuses on following the line\") along \
         each teacher's own lap: `S(h, s, τ)` is the share of what the path follower's ignoring \
         the semantic objects costs that a teacher of threshold τ sees, `m` the median cost of a \
         passage where the two choose differently.\n\n\
         * **T1** (\"In Avoid Doors, all methods of feedback converge near zero\"): `S(doors, s, 1.0) ≥ 0.75`.\n\
         * **T2** (the stairs households: \"the teacher threshold being too high for the task\"): \
         `S(h, s, 1.0) ≤ 0.5`.\n\
         * **T3** (\"the middle ground, in our case, around 0.25 - 0.5\"): `S(h, s, 0.25) ≥ 0.75` in \
         both stairs households.\n\
         * **T4** (noise: \"a good job at the task with σ = 1.0. At σ = 2.0 the learner does not \
         care for the doors\"): `√2 ≤ m(doors, s) ≤ 2√2`.\n\n\
         `host-sim calibrate` computes each target's interval of the scale exactly from the laps \
         and applies the rule fixed with the targets:\n"
    );
    r.push_str(&crate::calibrate::markdown(c));
    let _ = writeln!(
        r,
        "\nThe frozen teachers (`host-sim/src/teacher.rs`), frozen in a commit of their own before \
         any claim was run with them:\n\n\
         | teacher | scale | weights (obstacles, door, stairs, chair, path, right) |\n|---|---|---|"
    );
    for p in crate::teacher::PRESETS {
        let _ = writeln!(
            r,
            "| {} | {} | {:?} |",
            p.name,
            crate::calibrate::two_digits(p.scale as f64),
            p.weights
        );
    }
    if o.teacher_scale != 1.0 {
        let _ = writeln!(
            r,
            "\n**This run multiplied every teacher's weights by {}** (a point of the scale sweep), \
             so its teachers are not the calibrated ones.",
            o.teacher_scale
        );
    }
    let _ = writeln!(
        r,
        "\nHow every claim's verdict depends on the scale (each teacher's at ×¼, ×½, ×1, ×2, ×4) is \
         in [`SCALE_SWEEP.md`](SCALE_SWEEP.md) (`host-sim scale-sweep`).\n"
    );
}

fn report(
    o: &Options,
    aggs: &[Aggregate],
    calibration: &crate::calibrate::Calibration,
    teacher_paths: &BTreeMap<&str, PathTrace>,
    path_rows: &[(String, &str, PathTrace)],
    cm_per_px: f64,
) -> String {
    let k = tenth(o.steps as usize);
    let w = smoothing_window(o.steps as usize);
    let mut r = String::new();
    let _ = writeln!(r, "# Reproduction of the paper's section 6\n");
    let scale_flag = if o.teacher_scale != 1.0 {
        format!(" --teacher-scale {}", o.teacher_scale)
    } else {
        String::new()
    };
    let _ = writeln!(
        r,
        "Generated by `host-sim reproduce --trials {} --steps {} --seed {}{scale_flag}` (or the merge of its shards: \
         the same bytes). {} settings × {} trials = {} runs of {} steps. Deterministic: the same grid gives \
         this file byte for byte; the wall time is printed by the command, not written here.\n",
        o.trials,
        o.steps,
        o.seed,
        aggs.len(),
        o.trials,
        aggs.len() * o.trials as usize,
        o.steps
    );
    let _ = writeln!(
        r,
        "* **Learner**: the paper's, plain online gradient descent with a constant step of {PAPER_STEP} \
         (`LearnerParams::paper()`), not the crate's default averaged OGD.\n\
         * **Teachers**: calibrated from the paper's words before any claim was checked (next section). \
         The semantic teacher is the paper's: statements about doors, stairs, chairs and the path, the \
         path judged by cross-track error, summed (the richer statements of `host-sim run --statements \
         rich` are not used here).\n\
         * **Behaviour cloning**: the paper's baseline was \"trained on 50 samples of action feedback\" \
         and \"does not receive additional training from the initial first 50 datapoints\". We read \
         the 50 datapoints as the first 50 ticks of a run: the teacher's own policy drives ticks 0–49 \
         from the run's start pose, each tick labelled with the teacher's action; the 50 samples are \
         fitted offline with the same generalized hinge and learner (epochs over them in tick order \
         until an epoch changes nothing, at most 200), and the fitted learner is frozen for the whole \
         run, from the same start. Behaviour cloning means imitating demonstrations, and the paper \
         gives its baseline no corrections of its own driving, hence the teacher's demonstration.\n\
         * **Trials**: trial t has seed {} + t, in every setting; the seed drives the teacher's noise and \
         random preference queries and a start-pose jitter (up to {} m sideways, {} rad of heading), so \
         that trials differ even with a noiseless teacher.\n\
         * **Households**: `doors`, `stairs-right`, `stairs-chairs`, look-alikes of the paper's Gibson \
         households (which could not be redistributed), with the teachers avoid doors; avoid stairs and \
         keep right; avoid stairs and chairs. Every scenario's teacher drives a lap of it before it is \
         used.\n\
         * **Final latent loss**: a trial's mean latent loss over its last tenth ({k} steps); the \
         first-tenth loss likewise. Numbers are mean ± sample standard deviation across trials.\n\
         * **Task success**, beside the latent loss: laps, progress along the path (metres: the laps \
         completed times the path's length plus the progress into the current lap; a reset puts the car \
         back at the start, so it takes back the progress of its lap) and resets by cause \
         (collision, stuck, lost, blocked), per trial, averaged. A latent loss of zero cannot tell a car \
         that laps from one that circles where the teacher would circle too.\n\
         * Figures: latent-loss curves are a centred moving mean over {w} steps ({:.0}% of the run) of \
         the per-step means across trials; the band is ± one standard deviation across trials, smoothed \
         the same way; corrections and progress are cumulative and drawn as they are. The CSVs hold \
         every step's raw mean and standard deviation.\n",
        o.seed,
        StartJitter::REPRODUCE.lateral,
        StartJitter::REPRODUCE.heading,
        100.0 * SMOOTHING,
    );

    calibration_section(&mut r, o, calibration);

    let _ = writeln!(r, "## Claims\n");
    r.push_str(&claims::render(&verdicts(o, aggs)));

    // Tables and figures.
    let _ = writeln!(
        r,
        "## Variety\n\n![variety](figures/variety.png)\n\n\
         The paper's figure has the same panels (latent loss, corrections; a column per household). \
         Its latent losses are in its own feature units (\"around 20\" in the stairs households); \
         ours are in this project's features and calibrated teachers, so compare the shapes and the \
         orders, not the values.\n"
    );
    let _ = writeln!(
        r,
        "| household | feedback | first-tenth loss | final loss | corrections | first → last tenth corrections | {TASK_HEAD} |\n|---|---|---|---|---|---|---|---|---|"
    );
    for a in aggs.iter().filter(|a| a.setting.group == Group::Variety) {
        let _ = writeln!(
            r,
            "| {} | {} | {} | {} | {} | {:.1} → {:.1} | {} |",
            a.setting.household,
            a.setting.mode.name(),
            claims::pm(a.first_loss),
            claims::pm(a.final_loss),
            claims::pm1(a.total_corrections),
            a.first_tenth_corrections.0,
            a.last_tenth_corrections.0,
            task_cells(a)
        );
    }
    let _ = writeln!(
        r,
        "\n## Task success\n\n![task success](figures/task_success.png)\n\n\
         The paper has no such figure: it measures learning by latent loss and corrections only. \
         Each panel shows the progress along the path (mean ± std across trials) against the step; \
         the black line is the teacher's own pace (its lap's length over its lap's ticks). Laps and \
         resets by cause are in the tables of each experiment.\n"
    );
    let _ = writeln!(
        r,
        "## Noise\n\n![noise](figures/noise.png)\n\n![noise sweep](figures/noise_sweep.png)\n\n\
         The paper's figure has the four curves σ = 0, 0.25, 0.5, 1.0; the sweep to σ = 2 (the \
         second figure) is ours.\n"
    );
    summary_table(&mut r, aggs, Group::Noise, "σ", |a| {
        a.setting.noise.to_string()
    });
    let _ = writeln!(
        r,
        "\n## Thresholds\n\n![thresholds](figures/thresholds.png)\n\n\
         The paper's figure has the thresholds 0 to 1; 2, 4 and 8 are ours, so that the whole \
         regime, up to where the teacher stops correcting, is visible.\n"
    );
    summary_table(&mut r, aggs, Group::Thresholds, "threshold", |a| {
        a.setting.threshold.to_string()
    });
    let _ = writeln!(
        r,
        "\n## Paths\n\nThe teacher's own policy (purple) and trial 0's trained learner, frozen (orange), each \
         driving one lap from the scenario's start (at most {PATH_TICKS} ticks; it ends early at a reset). \
         Every map is drawn at the same scale, 1 px = {cm_per_px:.1} cm. The paper draws its learners' \
         paths in its 3-D Gibson households; ours are 2-D maps, and a drive that ended in a reset is \
         short, so its mean latent loss is beside how it ended.\n\n\
         ![teachers](figures/paths_teachers.png)\n\n![paths under noise](figures/paths_noise.png)\n\n\
         ![paths by threshold](figures/paths_thresholds.png)\n"
    );
    let _ = writeln!(
        r,
        "| figure | household | points | ended | mean latent loss along it (how it ended) |\n|---|---|---|---|---|"
    );
    for (h, p) in teacher_paths {
        let _ = writeln!(
            r,
            "| teacher | {h} | {} | {} | {} |",
            p.points.len(),
            p.end,
            p.loss_and_end()
        );
    }
    for (label, h, p) in path_rows {
        let _ = writeln!(
            r,
            "| {label} | {h} | {} | {} | {} |",
            p.points.len(),
            p.end,
            p.loss_and_end()
        );
    }
    let _ = writeln!(
        r,
        "\n## Files\n\n* `variety.csv`, `noise.csv`, `thresholds.csv`: per step, mean and standard deviation \
         across trials of the latent loss, the cumulative corrections and the progress along the path (m).\n\
         * `noise_sweep.csv`: final latent loss and corrections against σ.\n\
         * `summary.csv`: one row per setting, laps, progress and resets by cause included.\n\
         * `paths.csv`: the drawn paths.\n\
         * `figures/`: every figure as PNG and SVG."
    );
    r
}

/// Runs the whole grid at each factor of the teachers' scale (`o.teacher_scale` is ignored)
/// and returns every claim's verdict at each; `done` is called after each job.
pub fn scale_sweep(
    o: &Options,
    factors: &[f32],
    done: &(dyn Fn() + Sync),
) -> Result<Vec<(f32, Vec<Verdict>)>> {
    let mut out = Vec::new();
    for &f in factors {
        let of = Options {
            teacher_scale: f,
            ..*o
        };
        let results = run_shard(&of, Shard::WHOLE, done)?;
        let aggs = aggregate_all(&of, &results)?;
        out.push((f, verdicts(&of, &aggs)));
    }
    Ok(out)
}

/// The scale sweep as Markdown (`SCALE_SWEEP.md`).
pub fn scale_sweep_markdown(o: &Options, rows: &[(f32, Vec<Verdict>)]) -> String {
    let mut r = String::from("# How the claims' verdicts depend on the teachers' scale\n\n");
    let factors: Vec<String> = rows.iter().map(|(f, _)| format!("×{f}")).collect();
    let _ = writeln!(
        r,
        "Generated by `host-sim scale-sweep --trials {} --steps {} --seed {}`: the whole reproduction \
         grid of `host-sim reproduce` run again with every teacher's weights multiplied by {}, and \
         every claim checked by the same rules (`host-sim/src/claims.rs`). ×1 is the calibrated \
         teachers of `docs/reproduction/CALIBRATION.md` (doors 17, stairs-right 2.6, stairs-chairs \
         3.0); at ×f a teacher's latent losses are f times larger against the same thresholds and \
         noise. {} trials per setting{}.\n",
        o.trials,
        o.steps,
        o.seed,
        factors.join(", "),
        o.trials,
        if o.trials < 10 {
            " (fewer than the report's 10, to keep the sweep's five grids quick; the ×1 column can \
             therefore differ from the report where a verdict is close)"
        } else {
            ""
        }
    );
    let _ = writeln!(
        r,
        "| # | claim | {} |\n|---|---|{}",
        factors.join(" | "),
        "---|".repeat(rows.len())
    );
    for (i, c) in CLAIMS.iter().enumerate() {
        let cells: Vec<&str> = rows.iter().map(|(_, v)| v[i].plain()).collect();
        let _ = writeln!(r, "| {} | {c} | {} |", i + 1, cells.join(" | "));
    }
    let _ = writeln!(
        r,
        "\nA verdict that is the same in every column is a property of the method in these \
         households; one that changes with the scale is a property of where the teachers' \
         latent losses fall against their thresholds. The numbers behind each verdict:\n"
    );
    for (f, v) in rows {
        let _ = writeln!(r, "## Teachers' scale ×{f}\n");
        for (i, (c, v)) in CLAIMS.iter().zip(v).enumerate() {
            let _ = writeln!(r, "* **{}. {c}**: {}. {}\n", i + 1, v.plain(), v.text);
        }
    }
    r
}

/// `P(N > z)` for a standard normal `N` (Abramowitz–Stegun 7.1.26 for erfc; error < 1.5e-7).
pub fn upper_tail(z: f64) -> f64 {
    let x = z / std::f64::consts::SQRT_2;
    let sign = x < 0.0;
    let x = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let y = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let erfc = y * (-x * x).exp();
    let erfc = if sign { 2.0 - erfc } else { erfc };
    erfc / 2.0
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
            seed: 0,
            teacher_scale: 1.0,
        };
        let whole = jobs(&o, Shard::WHOLE);
        assert_eq!(whole.len(), settings().len() * 3);
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

    /// A trial of 20 steps: latent loss `l[i]`, one correction at each step of `fixes`, progress
    /// 0.5 m a step, a lap at step 15, a `lost` reset at step 7.
    fn trial(t: u32, l: [f32; 20], fixes: &[usize]) -> TrialResult {
        let mut corrections = Vec::new();
        let mut c = 0;
        for i in 0..20 {
            if fixes.contains(&i) {
                c += 1;
            }
            corrections.push(c);
        }
        TrialResult {
            setting: 0,
            trial: t,
            latent: l.to_vec(),
            corrections,
            progress: (0..20).map(|i| 0.5 * (i + 1) as f64).collect(),
            laps: (0..20).map(|i| u32::from(i >= 15 && t == 0)).collect(),
            resets: (0..20)
                .map(|i| (i == 7).then_some(ResetReason::Lost))
                .collect(),
            path: None,
        }
    }

    #[test]
    fn aggregates_match_hand_computed_values() {
        // Two trials of 20 steps: a tenth is 2 steps.
        let mut a = [1.0f32; 20];
        a[0] = 4.0;
        a[1] = 2.0; // first tenth: (4 + 2) / 2 = 3
        a[18] = 0.5;
        a[19] = 0.25; // last tenth: (0.5 + 0.25) / 2 = 0.375
        let mut b = [2.0f32; 20];
        b[0] = 6.0; // first tenth: (6 + 2) / 2 = 4
        b[19] = 0.0; // last tenth: (2 + 0) / 2 = 1
        let ta = trial(0, a, &[0, 1, 5, 19]);
        let tb = trial(1, b, &[1, 2, 3, 18, 19]);
        let agg = aggregate(settings()[0], &[&ta, &tb]);
        assert_eq!(agg.trials, 2);
        // Means and sample standard deviations (n − 1) across the two trials.
        assert_eq!(agg.first_loss, (3.5, std::f64::consts::FRAC_1_SQRT_2));
        assert_eq!(agg.final_loss.0, 0.6875);
        assert!((agg.final_loss.1 - 0.625 * std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
        // Corrections: 4 and 5 in all; 2 and 1 in the first tenth (steps 0–1); 1 and 2 in the
        // last (steps 18–19).
        assert_eq!(agg.total_corrections.0, 4.5);
        assert_eq!(agg.first_tenth_corrections.0, 1.5);
        assert_eq!(agg.last_tenth_corrections.0, 1.5);
        // Task: one trial lapped once; 10 m of progress each; one `lost` reset each.
        assert_eq!((agg.laps.0, agg.lapped), (0.5, 1));
        assert_eq!(agg.progress, (10.0, 0.0));
        assert_eq!(agg.resets, [0.0, 0.0, 1.0, 0.0]);
        // Per step: step 0's loss is the mean of 4 and 6, std √2.
        assert_eq!(agg.loss[0], (5.0, std::f64::consts::SQRT_2));
        assert_eq!(agg.corrections[19], (4.5, std::f64::consts::FRAC_1_SQRT_2));
    }

    #[test]
    fn a_chart_s_latent_loss_is_a_centred_moving_mean() {
        // 200 steps of loss i (std 1): 100 points, at the centre of each block of 2 steps; a
        // window of 10 around step c averages steps c − 5 … c + 4, a mean of c − 0.5.
        let v: Vec<(f64, f64)> = (0..200).map(|i| (i as f64, 1.0)).collect();
        let p = smoothed(&v, 10);
        assert_eq!(p.len(), 100);
        assert_eq!(p[50], (101.0, 100.5, 1.0));
        // At the ends the window is cut: step 1 averages steps 0 … 5.
        assert_eq!(p[0], (1.0, 2.5, 1.0));
        assert_eq!(smoothing_window(5_000), 250);
        assert_eq!(smoothing_window(10), 1);
    }

    #[test]
    fn a_path_s_loss_is_shown_with_how_it_ended() {
        let p = |end: &str, n: usize| PathTrace {
            points: vec![(0.0, 0.0); n + 1],
            end: end.into(),
            mean_latent_loss: 0.0104,
        };
        assert_eq!(
            p("lost", 197).loss_and_end(),
            "0.010 (lost after 197 ticks)"
        );
        assert_eq!(p("lap", 382).loss_and_end(), "0.010 (a lap in 382 ticks)");
        assert_eq!(
            p("ticks", 1500).loss_and_end(),
            "0.010 (no lap in 1500 ticks)"
        );
    }

    #[test]
    fn statistics() {
        assert_eq!(mean_std(&[1.0, 3.0]), (2.0, std::f64::consts::SQRT_2));
        assert_eq!(mean_std(&[4.0]), (4.0, 0.0));
        assert!((spearman(&[1.0, 2.0, 3.0], &[10.0, 20.0, 30.0]) - 1.0).abs() < 1e-12);
        assert!((spearman(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        // With ties: y = (1, 1, 2, 3) has ranks (1.5, 1.5, 3, 4); x ranks (1, 2, 3, 4). Both
        // mean 2.5; deviations x (−1.5, −0.5, 0.5, 1.5), y (−1, −1, 0.5, 1.5): covariance sum
        // 1.5 + 0.5 + 0.25 + 2.25 = 4.5, x's sum of squares 5, y's 4.5: ρ = 4.5 / √22.5 = √0.9.
        let rho = spearman(&[1.0, 2.0, 3.0, 4.0], &[1.0, 1.0, 2.0, 3.0]);
        assert!((rho - 0.9f64.sqrt()).abs() < 1e-12, "{rho}");
        // x = (1, 2, 3, 4), y = (2, 1, 4, 3): d = (−1, 1, −1, 1), ρ = 1 − 6·4 / (4·15) = 0.6.
        assert!((spearman(&[1.0, 2.0, 3.0, 4.0], &[2.0, 1.0, 4.0, 3.0]) - 0.6).abs() < 1e-12);
        assert_eq!(spearman(&[1.0, 2.0], &[5.0, 5.0]), 0.0, "a constant side");
        assert_eq!(
            mean_std(&[2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]),
            (5.0, (32.0f64 / 7.0).sqrt())
        );
        assert!((upper_tail(0.0) - 0.5).abs() < 1e-6);
        assert!((upper_tail(1.0) - 0.158_655).abs() < 1e-5);
        assert!((upper_tail(-1.0) - 0.841_345).abs() < 1e-5);
        assert_eq!(tenth(5000), 500);
        assert_eq!(tenth(3), 1);
    }

    #[test]
    fn start_jitter_is_seeded_small_and_free() {
        let s = registry::load_scenario("doors").unwrap();
        let j = StartJitter::REPRODUCE;
        let a = j.start(&s, 1);
        assert_eq!(a, j.start(&s, 1));
        assert_ne!(a, j.start(&s, 2));
        for seed in 0..20 {
            let p = j.start(&s, seed);
            let d = ((p.x - s.start.x).powi(2) + (p.y - s.start.y).powi(2)).sqrt();
            assert!(d <= j.lateral + 1e-9 && (p.theta - s.start.theta).abs() <= j.heading + 1e-9);
            assert!(!crate::car::CarParams::MUSHR.footprint_hits(&s.map, p));
        }
    }
}
