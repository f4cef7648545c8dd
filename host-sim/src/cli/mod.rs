//! The commands of `host-sim` other than `run`, and what they share: standard output, the
//! output folder, the worker threads, the progress bar.

use std::io::{IsTerminal, Write};
use std::path::Path;

use anyhow::{Context, Result};
use firmware_core::LearnerKind;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

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

pub(crate) fn parse_kind(s: &str) -> Result<LearnerKind, String> {
    LearnerKind::from_name(s).ok_or_else(|| {
        let names: Vec<_> = LearnerKind::ALL.iter().map(|k| k.name()).collect();
        format!(
            "unknown learner '{s}', expected one of {}",
            names.join(", ")
        )
    })
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
