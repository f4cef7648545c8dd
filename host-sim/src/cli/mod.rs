//! The commands of `host-sim` other than `run`, and what they share: the output folder, the
//! worker threads, the progress bar.

use std::io::IsTerminal;
use std::path::Path;

use anyhow::{Context, Result, bail};
use clap::ValueEnum;
use clap::builder::PossibleValue;
use firmware_core::{LearnerKind, LearnerParams};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use protocol::isotp::FrameMode;

pub(crate) mod demo;
pub(crate) mod generate;
pub(crate) mod inspect;
pub(crate) mod learners;
pub(crate) mod reproduce;

/// An online learner on the command line (`--learner NAME`: the names of
/// [`LearnerKind::name`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Learner(pub(crate) LearnerKind);

const LEARNERS: [Learner; LearnerKind::ALL.len()] = {
    let mut out = [Learner(LearnerKind::ALL[0]); LearnerKind::ALL.len()];
    let mut i = 0;
    while i < out.len() {
        out[i] = Learner(LearnerKind::ALL[i]);
        i += 1;
    }
    out
};

impl ValueEnum for Learner {
    fn value_variants<'a>() -> &'a [Self] {
        &LEARNERS
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(self.0.name()))
    }
}

/// The learner of `run` and `demo`.
#[derive(clap::Args, Debug)]
pub(crate) struct LearnerArgs {
    /// Online learner. Default: for `run`, the one docs/learners.md chose for the kind of
    /// feedback (`host-sim learners`); for `demo`, averaged-ogd.
    #[arg(long)]
    learner: Option<Learner>,
    /// Step size (default: the learner's own: 0.01 for the OGD family, 0.1 AdaGrad, 1 coactive).
    #[arg(long, allow_negative_numbers = true)]
    step: Option<f32>,
}

impl LearnerArgs {
    /// The learner asked for, `default` when none was.
    pub(crate) fn params(&self, default: impl FnOnce() -> LearnerKind) -> LearnerParams {
        let kind = self.learner.map_or_else(default, |l| l.0);
        let params = LearnerParams::new(kind);
        match self.step {
            Some(step) => params.with_step(step),
            None => params,
        }
    }
}

/// CAN frames on the command line (`--frame-mode classic|fd`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frames(pub(crate) FrameMode);

impl ValueEnum for Frames {
    fn value_variants<'a>() -> &'a [Self] {
        &[Frames(FrameMode::Classic), Frames(FrameMode::Fd)]
    }

    fn to_possible_value(&self) -> Option<PossibleValue> {
        Some(PossibleValue::new(match self.0 {
            FrameMode::Classic => "classic",
            FrameMode::Fd => "fd",
        }))
    }
}

/// The size of a trial grid, shared by `reproduce` and `scale-sweep`.
#[derive(clap::Args, Debug)]
pub(crate) struct GridArgs {
    /// Control ticks per trial.
    #[arg(long, default_value_t = 5_000)]
    pub(crate) steps: u32,
    /// Seed of trial 0 (trial t has seed SEED + t).
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    /// Worker threads (default: one per core). The outputs do not depend on it.
    #[arg(long)]
    pub(crate) jobs: Option<usize>,
}

pub(crate) fn prepare_out(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("output folder {}: cannot create", dir.display()))?;
    let probe = dir.join(".host-sim-write-test");
    std::fs::write(&probe, b"")
        .with_context(|| format!("output folder {}: not writable", dir.display()))?;
    let _ = std::fs::remove_file(probe);
    Ok(())
}

/// The rayon pool of `--jobs` threads (default: one per core).
pub(crate) fn worker_pool(jobs: Option<usize>) -> Result<rayon::ThreadPool> {
    if jobs == Some(0) {
        bail!("--jobs must be positive");
    }
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = jobs {
        pool = pool.num_threads(n);
    }
    pool.build().context("cannot start the worker threads")
}

/// A progress bar of `len` units on standard error, hidden when that is not a terminal.
pub(crate) fn progress_bar(len: u64, template: &str) -> ProgressBar {
    let target = if std::io::stderr().is_terminal() {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    };
    let bar = ProgressBar::with_draw_target(Some(len), target);
    bar.set_style(
        ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}
