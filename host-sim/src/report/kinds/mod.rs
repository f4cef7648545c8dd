//! The experiment of issue 15: every kind of feedback, and mixes of them, in every world.
//!
//! A **kind setting** is a world and a way of teaching ([`teachings`]): each of the nine kinds
//! alone, the mix of the paper's three (`mix:action=0.2,preference=0.3,semantic=0.5`), the nine
//! in equal parts (`mix:all`) and the cost-aware teacher (`cheapest`), in the three households and
//! the MIT basement ([`KIND_WORLDS`]). Every run has the calibrated teacher of its world at the
//! paper's threshold 1.0 without noise, the reproduction's start jitter, and **the car's default
//! learner, averaged OGD with a step of 0.01** (`LearnerParams::default()`): one learner for
//! every kind, since a mixed stream needs one that applies each kind at its right iterate (the
//! paper's plain OGD is the reproduction's learner for its own three kinds).
//!
//! Trial `t` has seed `seed + t` like the paper's grid, and a setting runs
//! `min(trials, KIND_TRIALS)` trials, so that the whole reproduction stays within a minute on the
//! project's machine. Jobs are numbered setting-major and sharded like the paper's grid
//! (`--shard i/n` takes every job whose number modulo `n` is `i`); a shard writes its raw results
//! under `kinds/` beside the grid's `trials/`, and `host-sim merge` reads them back.
//!
//! What a trial records ([`KindTrial`]): per step the latent loss, the cumulative corrections,
//! a person's cumulative effort (seconds, [`crate::teach::kinds::EFFORT_SECONDS`]) and the
//! progress along the path; at the end its laps, resets, the feedback of each kind and, per kind,
//! the informativeness of its corrections ([`crate::teach::kinds::Informativeness`]).

mod outputs;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result, ensure};
use firmware_core::{FeedbackKind, LearnerParams};
use rayon::prelude::*;

pub use outputs::write_outputs;

use super::files::{read_text, write_file};
use super::grid::{Options, Shard};
use super::statistics::{mean_std, tenth};
use crate::teach::experiment::{self, Mode, RunConfig, StartJitter};
use crate::teach::kinds::Mix;
use crate::teach::record::RESET_CAUSES;
use crate::world::registry;
use crate::world::scenario::Scenario;
use crate::world::teacher::StatementSet;

/// The worlds of the experiment: the three households and the MIT basement.
pub const KIND_WORLDS: [&str; 4] = ["doors", "stairs-right", "stairs-chairs", "basement"];

/// The most trials a kind setting runs.
pub const KIND_TRIALS: u32 = 3;

/// The mix of the paper's three kinds in the example proportions.
pub const PAPER_MIX: &str = "action=0.2,preference=0.3,semantic=0.5";

/// Every way of teaching of the experiment, in its order: the nine kinds, the paper's mix, all
/// nine in equal parts, the cost-aware teacher.
pub fn teachings() -> Vec<Mode> {
    let mut v: Vec<Mode> = FeedbackKind::ALL.into_iter().map(Mode::Online).collect();
    // The mixes are constants of this file: they parse.
    if let Ok(m) = Mix::parse(PAPER_MIX) {
        v.push(Mode::Mix(m));
    }
    v.push(Mode::Mix(Mix::ALL));
    v.push(Mode::Cheapest);
    v
}

/// One world and one way of teaching.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KindSetting {
    /// The world (a built-in scenario).
    pub world: &'static str,
    /// How the learner is taught.
    pub mode: Mode,
}

impl KindSetting {
    /// A unique folder name: `kinds-doors-ranking`, `kinds-basement-mix-all`.
    pub fn key(&self) -> String {
        let slug: String = self
            .mode
            .name()
            .chars()
            .map(|c| match c {
                ':' | '=' | ',' => '-',
                c => c,
            })
            .collect();
        format!("kinds-{}-{slug}", self.world)
    }

    /// The run of trial `trial`.
    pub fn config(&self, scenario: Arc<Scenario>, trial: u32, o: &Options) -> RunConfig {
        RunConfig {
            mode: self.mode,
            steps: o.steps,
            seed: o.seed.wrapping_add(trial as u64),
            threshold: Some(1.0),
            noise: Some(0.0),
            learner: LearnerParams::default(),
            start_jitter: Some(StartJitter::REPRODUCE),
            statements: Some(StatementSet::Paper),
            random_answers: Some(0.0),
            teacher_scale: (o.teacher_scale != 1.0).then_some(o.teacher_scale),
            ..RunConfig::new(scenario)
        }
    }
}

/// Every kind setting, world-major.
pub fn settings() -> Vec<KindSetting> {
    let mut out = Vec::new();
    for world in KIND_WORLDS {
        for mode in teachings() {
            out.push(KindSetting { world, mode });
        }
    }
    out
}

/// Trials per kind setting.
pub fn trials(o: &Options) -> u32 {
    o.trials.min(KIND_TRIALS)
}

/// The kind jobs of `shard`: (setting, trial), in order.
pub fn jobs(o: &Options, shard: Shard) -> Vec<(usize, u32)> {
    let n = settings().len();
    let t = trials(o);
    (0..n)
        .flat_map(|s| (0..t).map(move |k| (s, k)))
        .enumerate()
        .filter(|(k, _)| shard.has(*k))
        .map(|(_, j)| j)
        .collect()
}

/// The informativeness of one kind's corrections in a trial: how many could be measured, the
/// sums of α and of the worst-minimiser α, how many had α > 0.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AlphaSums {
    /// Corrections measured (the judged action's latent loss above 0).
    pub n: u32,
    /// Σ α.
    pub sum: f64,
    /// Σ α over the worst minimiser.
    pub sum_worst: f64,
    /// Corrections with α > 0 (pointing at better actions than the learner's, on average).
    pub positive: u32,
}

impl AlphaSums {
    fn add(&mut self, o: &AlphaSums) {
        self.n += o.n;
        self.sum += o.sum;
        self.sum_worst += o.sum_worst;
        self.positive += o.positive;
    }

    /// Mean α, mean worst α, share with α > 0; `None` without a measured correction.
    pub fn means(&self) -> Option<(f64, f64, f64)> {
        (self.n > 0).then(|| {
            let n = self.n as f64;
            (self.sum / n, self.sum_worst / n, self.positive as f64 / n)
        })
    }
}

/// What one kind trial produced.
#[derive(Clone, Debug, PartialEq)]
pub struct KindTrial {
    /// Index into [`settings`].
    pub setting: usize,
    /// The trial.
    pub trial: u32,
    /// Latent loss per step.
    pub latent: Vec<f32>,
    /// Cumulative corrections (feedback messages) per step.
    pub corrections: Vec<u32>,
    /// Cumulative effort per step (s).
    pub effort: Vec<f64>,
    /// Progress along the path per step (m).
    pub progress: Vec<f64>,
    /// Laps at the end.
    pub laps: u32,
    /// Resets by cause: collision, stuck, lost, blocked.
    pub resets: [u32; 4],
    /// Feedback messages of each kind, in [`FeedbackKind`] order.
    pub kinds: [u32; 9],
    /// The informativeness of each kind's corrections, in [`FeedbackKind`] order.
    pub alpha: [AlphaSums; 9],
}

/// Runs kind job (`setting`, `trial`).
pub fn run_job(
    worlds: &BTreeMap<&'static str, Arc<Scenario>>,
    all: &[KindSetting],
    setting: usize,
    trial: u32,
    o: &Options,
) -> Result<KindTrial> {
    let s = all
        .get(setting)
        .with_context(|| format!("no kind setting {setting}"))?;
    let scenario = worlds
        .get(s.world)
        .with_context(|| format!("world {} not loaded", s.world))?
        .clone();
    let config = s.config(scenario, trial, o);
    let report = experiment::run(&config).with_context(|| format!("{} trial {trial}", s.key()))?;
    let mut effort = Vec::with_capacity(report.records.len());
    let mut total = 0.0f64;
    for r in &report.records {
        total += r.effort as f64;
        effort.push(total);
    }
    let mut alpha = [AlphaSums::default(); 9];
    for i in &report.informativeness {
        if let (Some(a), Some(w)) = (i.alpha(), i.alpha_worst()) {
            let s = &mut alpha[i.kind as usize];
            s.n += 1;
            s.sum += a;
            s.sum_worst += w;
            s.positive += u32::from(a > 0.0);
        }
    }
    Ok(KindTrial {
        setting,
        trial,
        latent: report.records.iter().map(|r| r.latent_loss).collect(),
        corrections: report.records.iter().map(|r| r.corrections).collect(),
        effort,
        progress: report.records.iter().map(|r| r.progress).collect(),
        laps: report.laps(),
        resets: report.resets,
        kinds: report.kind_counts(),
        alpha,
    })
}

/// The worlds of the experiment, loaded once.
pub fn load_worlds() -> Result<BTreeMap<&'static str, Arc<Scenario>>> {
    let mut m = BTreeMap::new();
    for w in KIND_WORLDS {
        m.insert(w, Arc::new(registry::load_scenario(w)?));
    }
    Ok(m)
}

/// Runs the kind jobs of `shard` on the current rayon pool; `done` is called after each job.
pub fn run_shard(o: &Options, shard: Shard, done: &(dyn Fn() + Sync)) -> Result<Vec<KindTrial>> {
    o.check()?;
    let worlds = load_worlds()?;
    let all = settings();
    let results: Vec<Result<KindTrial>> = jobs(o, shard)
        .par_iter()
        .map(|&(s, t)| {
            let r = run_job(&worlds, &all, s, t, o);
            done();
            r
        })
        .collect();
    results.into_iter().collect()
}

const STEP_HEADER: &str = "latent_loss,corrections,effort_s,progress";
const END_HEADER: &str = "laps,resets_collision,resets_stuck,resets_lost,resets_blocked";

/// Writes a shard's kind results under `dir/kinds/` (floats in Rust's shortest round-trip form).
pub fn write_shard(dir: &Path, results: &[KindTrial]) -> Result<()> {
    let all = settings();
    for r in results {
        let base = dir.join("kinds").join(all[r.setting].key());
        let mut csv = format!("{STEP_HEADER}\n");
        for i in 0..r.latent.len() {
            let _ = writeln!(
                csv,
                "{},{},{},{}",
                r.latent[i], r.corrections[i], r.effort[i], r.progress[i]
            );
        }
        write_file(&base.join(format!("{}.csv", r.trial)), csv.as_bytes())?;
        let mut end = format!("{END_HEADER}\n{}", r.laps);
        for x in r.resets {
            let _ = write!(end, ",{x}");
        }
        end.push_str("\nkind,feedback,alpha_n,alpha_sum,alpha_worst_sum,alpha_positive\n");
        for k in FeedbackKind::ALL {
            let a = &r.alpha[k as usize];
            let _ = writeln!(
                end,
                "{},{},{},{},{},{}",
                k.name(),
                r.kinds[k as usize],
                a.n,
                a.sum,
                a.sum_worst,
                a.positive
            );
        }
        write_file(&base.join(format!("{}-end.csv", r.trial)), end.as_bytes())?;
    }
    Ok(())
}

fn parse<T: std::str::FromStr>(s: &str, what: &dyn Fn() -> String) -> Result<T> {
    s.parse().ok().with_context(what)
}

fn read_trial(dir: &Path, setting: usize, trial: u32, steps: u32) -> Result<KindTrial> {
    let path = dir.join(format!("{trial}.csv"));
    let text = read_text(&path)?;
    let mut lines = text.lines();
    ensure!(
        lines.next() == Some(STEP_HEADER),
        "{}: bad header",
        path.display()
    );
    let (mut latent, mut corrections, mut effort, mut progress) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (i, line) in lines.enumerate() {
        let bad = || format!("{}: line {}: bad row {line:?}", path.display(), i + 2);
        let f: Vec<&str> = line.split(',').collect();
        ensure!(f.len() == 4, "{}", bad());
        let l: f32 = parse(f[0], &bad)?;
        let e: f64 = parse(f[2], &bad)?;
        let p: f64 = parse(f[3], &bad)?;
        ensure!(l.is_finite() && e.is_finite() && p.is_finite(), "{}", bad());
        latent.push(l);
        corrections.push(parse(f[1], &bad)?);
        effort.push(e);
        progress.push(p);
    }
    ensure!(
        latent.len() == steps as usize,
        "{}: {} rows, expected {steps}",
        path.display(),
        latent.len()
    );
    let end_path = dir.join(format!("{trial}-end.csv"));
    let text = read_text(&end_path)?;
    let lines: Vec<&str> = text.lines().collect();
    let bad = || format!("{}: bad file", end_path.display());
    ensure!(lines.len() == 3 + 9 && lines[0] == END_HEADER, "{}", bad());
    let f: Vec<&str> = lines[1].split(',').collect();
    ensure!(f.len() == 5, "{}", bad());
    let laps = parse(f[0], &bad)?;
    let mut resets = [0u32; 4];
    for (r, x) in resets.iter_mut().zip(&f[1..]) {
        *r = parse(x, &bad)?;
    }
    let mut kinds = [0u32; 9];
    let mut alpha = [AlphaSums::default(); 9];
    for (k, line) in FeedbackKind::ALL.iter().zip(&lines[3..]) {
        let f: Vec<&str> = line.split(',').collect();
        ensure!(f.len() == 6 && f[0] == k.name(), "{}", bad());
        kinds[*k as usize] = parse(f[1], &bad)?;
        alpha[*k as usize] = AlphaSums {
            n: parse(f[2], &bad)?,
            sum: parse(f[3], &bad)?,
            sum_worst: parse(f[4], &bad)?,
            positive: parse(f[5], &bad)?,
        };
    }
    Ok(KindTrial {
        setting,
        trial,
        latent,
        corrections,
        effort,
        progress,
        laps,
        resets,
        kinds,
        alpha,
    })
}

/// Reads the kind results of shard `shard` from `dir` (written by [`write_shard`]).
pub fn read_shard(dir: &Path, o: &Options, shard: Shard) -> Result<Vec<KindTrial>> {
    let all = settings();
    jobs(o, shard)
        .into_iter()
        .map(|(s, t)| read_trial(&dir.join("kinds").join(all[s].key()), s, t, o.steps))
        .collect()
}

/// One kind setting across its trials.
#[derive(Clone, Debug)]
pub struct KindAggregate {
    /// The setting.
    pub setting: KindSetting,
    /// Trials.
    pub trials: usize,
    /// Per step: mean and std of the latent loss.
    pub loss: Vec<(f64, f64)>,
    /// Per step: mean and std of the cumulative corrections.
    pub corrections: Vec<(f64, f64)>,
    /// Per step: mean and std of the cumulative effort (s).
    pub effort: Vec<(f64, f64)>,
    /// Per step: mean and std of the progress (m).
    pub progress_curve: Vec<(f64, f64)>,
    /// Mean latent loss of the first tenth: mean and std across trials.
    pub first_loss: (f64, f64),
    /// Mean latent loss of the last tenth.
    pub final_loss: (f64, f64),
    /// Corrections in all.
    pub total_corrections: (f64, f64),
    /// Effort in all (s).
    pub total_effort: (f64, f64),
    /// Laps in all.
    pub laps: (f64, f64),
    /// Trials with at least one lap.
    pub lapped: usize,
    /// Progress at the end (m).
    pub progress: (f64, f64),
    /// Resets per trial by cause (means).
    pub resets: [f64; 4],
    /// Feedback of each kind per trial (means).
    pub kinds: [f64; 9],
    /// The informativeness of each kind, over every trial.
    pub alpha: [AlphaSums; 9],
}

fn aggregate(setting: KindSetting, trials: &[&KindTrial]) -> KindAggregate {
    let steps = trials.first().map_or(0, |t| t.latent.len());
    let k = tenth(steps.max(1));
    let per_step = |f: &dyn Fn(&KindTrial, usize) -> f64| -> Vec<(f64, f64)> {
        (0..steps)
            .map(|i| mean_std(&trials.iter().map(|t| f(t, i)).collect::<Vec<_>>()))
            .collect()
    };
    let over = |f: &dyn Fn(&KindTrial) -> f64| -> (f64, f64) {
        mean_std(&trials.iter().map(|t| f(t)).collect::<Vec<_>>())
    };
    let mean_of = |xs: &[f32]| xs.iter().map(|&x| x as f64).sum::<f64>() / xs.len().max(1) as f64;
    let n = trials.len().max(1) as f64;
    let (mut resets, mut kinds, mut alpha) = ([0.0; 4], [0.0; 9], [AlphaSums::default(); 9]);
    for t in trials {
        for (r, c) in resets.iter_mut().zip(t.resets) {
            *r += c as f64 / n;
        }
        for (r, c) in kinds.iter_mut().zip(t.kinds) {
            *r += c as f64 / n;
        }
        for (a, b) in alpha.iter_mut().zip(&t.alpha) {
            a.add(b);
        }
    }
    let last = steps.saturating_sub(1);
    KindAggregate {
        setting,
        trials: trials.len(),
        loss: per_step(&|t, i| t.latent[i] as f64),
        corrections: per_step(&|t, i| t.corrections[i] as f64),
        effort: per_step(&|t, i| t.effort[i]),
        progress_curve: per_step(&|t, i| t.progress[i]),
        first_loss: over(&|t| mean_of(&t.latent[..k.min(steps)])),
        final_loss: over(&|t| mean_of(&t.latent[steps.saturating_sub(k)..])),
        total_corrections: over(&|t| t.corrections.get(last).map_or(0.0, |&c| c as f64)),
        total_effort: over(&|t| t.effort.get(last).copied().unwrap_or(0.0)),
        laps: over(&|t| t.laps as f64),
        lapped: trials.iter().filter(|t| t.laps > 0).count(),
        progress: over(&|t| t.progress.get(last).copied().unwrap_or(0.0)),
        resets,
        kinds,
        alpha,
    }
}

/// Aggregates every kind setting; checks that the results are the whole experiment.
pub fn aggregate_all(o: &Options, results: &[KindTrial]) -> Result<Vec<KindAggregate>> {
    let all = settings();
    let t = trials(o);
    let mut by: Vec<Vec<&KindTrial>> = vec![Vec::new(); all.len()];
    for r in results {
        ensure!(
            r.setting < all.len() && r.latent.len() == o.steps as usize,
            "a kind result of another experiment"
        );
        by[r.setting].push(r);
    }
    for (s, rs) in by.iter_mut().enumerate() {
        rs.sort_by_key(|r| r.trial);
        let got: Vec<u32> = rs.iter().map(|r| r.trial).collect();
        ensure!(
            got == (0..t).collect::<Vec<_>>(),
            "{}: trials {got:?}, expected 0..{t}",
            all[s].key()
        );
    }
    Ok(all
        .iter()
        .zip(&by)
        .map(|(s, rs)| aggregate(*s, rs))
        .collect())
}

/// The resets' names and mean counts: "0.0 / 1.3 / 0.0 / 2.0".
fn resets_cell(r: &[f64; 4]) -> String {
    debug_assert_eq!(RESET_CAUSES.len(), r.len());
    r.iter()
        .map(|x| format!("{x:.1}"))
        .collect::<Vec<_>>()
        .join(" / ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_unique_folder_names_and_jobs_partition() {
        let keys: std::collections::BTreeSet<String> = settings().iter().map(|s| s.key()).collect();
        assert_eq!(keys.len(), settings().len());
        assert_eq!(settings().len(), KIND_WORLDS.len() * 12);
        for k in &keys {
            assert!(
                k.chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '.'),
                "{k}"
            );
        }
        assert!(keys.contains("kinds-doors-mix-action-0.2-preference-0.3-semantic-0.5"));
        let o = Options {
            trials: 10,
            steps: 10,
            seed: 0,
            teacher_scale: 1.0,
            worlds: 0,
            world_trials: 2,
        };
        let whole = jobs(&o, Shard::WHOLE);
        assert_eq!(whole.len(), settings().len() * KIND_TRIALS as usize);
        let mut union: Vec<_> = (0..3)
            .flat_map(|i| jobs(&o, Shard { index: i, count: 3 }))
            .collect();
        union.sort();
        assert_eq!(union, whole);
    }

    #[test]
    fn a_trial_survives_its_files() {
        let tmp = tempfile::tempdir().unwrap();
        let mut alpha = [AlphaSums::default(); 9];
        alpha[3] = AlphaSums {
            n: 4,
            sum: 1.25,
            sum_worst: -0.1,
            positive: 3,
        };
        let t = KindTrial {
            setting: 5,
            trial: 1,
            latent: vec![0.1, 2.0 / 3.0, 0.0],
            corrections: vec![1, 1, 2],
            effort: vec![1.5, 1.5, 3.5],
            progress: vec![0.01, 0.123456789, 1.0 / 7.0],
            laps: 2,
            resets: [0, 1, 2, 3],
            kinds: [0, 0, 0, 2, 0, 0, 0, 0, 0],
            alpha,
        };
        write_shard(tmp.path(), std::slice::from_ref(&t)).unwrap();
        let dir = tmp.path().join("kinds").join(settings()[5].key());
        assert_eq!(read_trial(&dir, 5, 1, 3).unwrap(), t);
        assert!(read_trial(&dir, 5, 1, 4).is_err());
    }
}
