//! The commands of `host-sim` other than `run`, and what they share: standard output, the
//! output folder, the worker threads, the progress bar.

use std::io::{IsTerminal, Write};
use std::path::Path;

use anyhow::{Context, Result};
use clap::ValueEnum;
use clap::builder::PossibleValue;
use firmware_core::{LearnerKind, LearnerParams};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use protocol::isotp::FrameMode;

/// `println!` that returns the error instead of panicking: `outln!(...)?` in every command, so a
/// closed pipe (`host-sim list | head -1`) ends the command quietly ([`closed_stdout`]).
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::cli::write_stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` that returns the error instead of panicking (see [`outln!`]).
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::cli::write_stdout(format_args!($($arg)*))
    };
}

pub(crate) use {out, outln};

/// Writes to standard output, with the error of a closed pipe returned, not a panic.
pub(crate) fn write_stdout(args: std::fmt::Arguments<'_>) -> std::io::Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_fmt(args)?;
    out.flush()
}

/// Whether `e` is standard output's reader gone (a broken pipe): the command then ends quietly
/// with success, as `head` and `grep -q` expect of what they read from.
pub(crate) fn closed_stdout(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

pub(crate) mod demo;
pub(crate) mod generate;
pub(crate) mod inspect;
pub(crate) mod learners;
pub(crate) mod link;
pub(crate) mod reproduce;
pub(crate) mod teach;

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
    /// Step size, in (0, 1000] (default: the learner's own: 0.01 for the OGD family, 0.1
    /// AdaGrad, 1 coactive).
    #[arg(long, allow_negative_numbers = true,
          value_parser = host_sim::checks::flag(host_sim::checks::step_size))]
    step: Option<f64>,
}

impl LearnerArgs {
    /// The learner asked for, `default` when none was.
    pub(crate) fn params(&self, default: impl FnOnce() -> LearnerKind) -> LearnerParams {
        let kind = self.learner.map_or_else(default, |l| l.0);
        let params = LearnerParams::new(kind);
        match self.step {
            Some(step) => params.with_step(step as f32),
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
    /// Control ticks per trial, 10 to 10 000 000.
    #[arg(long, default_value_t = 5_000, allow_negative_numbers = true,
          value_parser = host_sim::checks::count_flag(host_sim::report::grid::GRID_STEPS))]
    pub(crate) steps: u32,
    /// Seed of trial 0 (trial t has seed SEED + t).
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    /// Worker threads (default: one per core). The outputs do not depend on it.
    #[arg(long, allow_negative_numbers = true, value_parser = host_sim::checks::count_flag(JOBS))]
    pub(crate) jobs: Option<u32>,
}

/// Creates the output folder `dir` (and its missing parents) and checks that it is writable.
/// The guard it returns removes again, when dropped without [`OutDir::keep`], the folders this
/// made that are still empty: a command that fails (a bad map, a refused link) leaves no empty
/// folder behind, and never removes a file or a folder that was there before.
pub(crate) fn prepare_out(dir: &Path) -> Result<OutDir> {
    let mut created = Vec::new();
    let mut missing = Some(dir);
    while let Some(d) = missing.filter(|d| !d.as_os_str().is_empty() && !d.exists()) {
        created.push(d.to_path_buf());
        missing = d.parent();
    }
    let guard = OutDir {
        created,
        keep: false,
    };
    std::fs::create_dir_all(dir)
        .with_context(|| format!("output folder {}: cannot create", dir.display()))?;
    let probe = dir.join(".host-sim-write-test");
    std::fs::write(&probe, b"")
        .with_context(|| format!("output folder {}: not writable", dir.display()))?;
    let _ = std::fs::remove_file(probe);
    Ok(guard)
}

/// The folders [`prepare_out`] made, removed when dropped unless kept (see there).
#[must_use = "dropping the guard removes the folders it made (if still empty)"]
#[derive(Debug)]
pub(crate) struct OutDir {
    /// The folders made, deepest first.
    created: Vec<std::path::PathBuf>,
    keep: bool,
}

impl OutDir {
    /// The command succeeded: keep the folders.
    pub(crate) fn keep(mut self) {
        self.keep = true;
    }
}

impl Drop for OutDir {
    fn drop(&mut self) {
        if !self.keep {
            for d in &self.created {
                // Only an empty folder can be removed: nothing written is lost.
                let _ = std::fs::remove_dir(d);
            }
        }
    }
}

/// The worker threads `--jobs` accepts.
pub(crate) const JOBS: std::ops::RangeInclusive<u32> = 1..=1024;

/// The rayon pool of `--jobs` threads (default: one per core).
pub(crate) fn worker_pool(jobs: Option<u32>) -> Result<rayon::ThreadPool> {
    if let Some(n) = jobs {
        host_sim::checks::count(n.into(), JOBS).map_err(host_sim::checks::named("--jobs"))?;
    }
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = jobs {
        pool = pool.num_threads(n as usize);
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
