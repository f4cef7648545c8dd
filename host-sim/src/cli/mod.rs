//! The commands of `host-sim` other than `run`, and what they share: the output folder, the
//! worker threads, the progress bar.

use std::io::IsTerminal;
use std::path::Path;

use anyhow::{Context, Result, bail};
use firmware_core::LearnerKind;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

pub(crate) mod demo;
pub(crate) mod generate;
pub(crate) mod inspect;
pub(crate) mod learners;
pub(crate) mod link;
pub(crate) mod reproduce;
pub(crate) mod teach;

pub(crate) fn parse_kind(s: &str) -> Result<LearnerKind, String> {
    LearnerKind::from_name(s).ok_or_else(|| {
        let names: Vec<_> = LearnerKind::ALL.iter().map(|k| k.name()).collect();
        format!(
            "unknown learner '{s}', expected one of {}",
            names.join(", ")
        )
    })
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
