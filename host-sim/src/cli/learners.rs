//! `host-sim learners`: every learner against every kind of feedback (docs/learners.md).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};

use super::{prepare_out, progress_bar, worker_pool};

pub(crate) fn learners(seeds: u32, steps: u32, jobs: Option<u32>, out: &Path) -> Result<()> {
    use host_sim::teach::learners::{self, Options};
    let o = Options { seeds, steps };
    let pool = worker_pool(jobs)?;
    let out_dir = match out.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(parent) => Some(prepare_out(parent)?),
        None => None,
    };
    let runs = learners::cells().len() * seeds as usize;
    let bar = progress_bar(
        runs as u64,
        "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} runs, {eta} left",
    );
    let started = Instant::now();
    let cells = pool.install(|| learners::run_table(&o, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let text = learners::markdown(&o, &cells);
    std::fs::write(out, &text).with_context(|| format!("{}: cannot write", out.display()))?;
    if let Some(d) = out_dir {
        d.keep();
    }
    for line in text.lines().filter(|l| l.starts_with("**Chosen")) {
        outln!("{line}")?;
    }
    outln!(
        "wrote {} ({runs} runs on {} threads in {:.1} s)",
        out.display(),
        pool.current_num_threads(),
        started.elapsed().as_secs_f64()
    )?;
    Ok(())
}
