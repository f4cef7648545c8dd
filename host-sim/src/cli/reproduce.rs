//! `host-sim reproduce`, `merge` and `scale-sweep`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};

use super::{prepare_out, progress_bar, worker_pool};

#[derive(clap::Args, Debug)]
pub(crate) struct ReproduceArgs {
    /// Trials per setting (trial t has seed SEED + t).
    #[arg(long, default_value_t = 10)]
    trials: u32,
    /// Control ticks per trial.
    #[arg(long, default_value_t = 5_000)]
    steps: u32,
    /// Seed of trial 0.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: one per core). The outputs do not depend on it.
    #[arg(long)]
    jobs: Option<usize>,
    /// Output folder (created if missing).
    #[arg(long, default_value = "out/reproduce")]
    out: PathBuf,
    /// Run only slice INDEX of COUNT of the trial grid (INDEX from 0, e.g. a SLURM array task id
    /// or a Kubernetes JOB_COMPLETION_INDEX) and write its raw results for `host-sim merge`.
    #[arg(long, value_name = "INDEX/COUNT")]
    shard: Option<host_sim::report::Shard>,
    /// Multiply every teacher's weights by this factor (default 1: the calibrated teachers of
    /// docs/reproduction/CALIBRATION.md).
    #[arg(long, default_value_t = 1.0)]
    teacher_scale: f32,
}

#[derive(clap::Args, Debug)]
pub(crate) struct ScaleSweepArgs {
    /// Trials per setting (fewer than the report's 10 keeps the five grids quick; the output
    /// says how many).
    #[arg(long, default_value_t = 5)]
    trials: u32,
    /// Control ticks per trial.
    #[arg(long, default_value_t = 5_000)]
    steps: u32,
    /// Seed of trial 0.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: one per core). The output does not depend on it.
    #[arg(long)]
    jobs: Option<usize>,
    /// The Markdown file to write.
    #[arg(long, default_value = "out/SCALE_SWEEP.md")]
    out: PathBuf,
}

pub(crate) fn reproduce(args: &ReproduceArgs) -> Result<()> {
    use host_sim::report::{self, Options, Shard};
    let o = Options {
        trials: args.trials,
        steps: args.steps,
        seed: args.seed,
        teacher_scale: args.teacher_scale,
    };
    o.check()?;
    let shard = args.shard.unwrap_or(Shard::WHOLE);
    prepare_out(&args.out)?;
    let pool = worker_pool(args.jobs)?;
    let jobs = report::jobs(&o, shard).len() + report::kinds::jobs(&o, shard).len();
    let bar = progress_bar(
        jobs as u64,
        "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} trials, {eta} left {msg}",
    );
    bar.set_message(format!("({} threads)", pool.current_num_threads()));
    let started = Instant::now();
    let results = pool.install(|| report::run_shard(&o, shard, &|| bar.inc(1)))?;
    let kinds = pool.install(|| report::kinds::run_shard(&o, shard, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let ran = started.elapsed().as_secs_f64();
    println!(
        "ran {jobs} trials of {} steps on {} threads in {ran:.1} s",
        o.steps,
        pool.current_num_threads()
    );
    if shard.count > 1 {
        report::write_shard(&args.out, &o, shard, &results, &kinds)?;
        println!(
            "wrote shard {}/{} into {}; combine every shard with `host-sim merge DIR... --out DIR`",
            shard.index,
            shard.count,
            args.out.display()
        );
        return Ok(());
    }
    let report = report::finalize(&args.out, &o, &results, &kinds)?;
    print_outcome(&args.out, &report);
    println!(
        "wall time {:.1} s ({ran:.1} s of trials)",
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

pub(crate) fn scale_sweep(args: &ScaleSweepArgs) -> Result<()> {
    use host_sim::report::grid::SWEEP_FACTORS;
    use host_sim::report::{self, Options, Shard};
    let o = Options {
        trials: args.trials,
        steps: args.steps,
        seed: args.seed,
        teacher_scale: 1.0,
    };
    o.check()?;
    let pool = worker_pool(args.jobs)?;
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        prepare_out(parent)?;
    }
    let jobs = report::jobs(&o, Shard::WHOLE).len() * SWEEP_FACTORS.len();
    let bar = progress_bar(
        jobs as u64,
        "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} trials, {eta} left {msg}",
    );
    let started = Instant::now();
    let rows = pool.install(|| report::scale_sweep(&o, &SWEEP_FACTORS, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let text = report::scale_sweep_markdown(&o, &rows);
    std::fs::write(&args.out, &text)
        .with_context(|| format!("{}: cannot write", args.out.display()))?;
    for line in text.lines().filter(|l| l.starts_with("| ")) {
        println!("{line}");
    }
    println!(
        "wrote {} ({jobs} trials on {} threads in {:.1} s)",
        args.out.display(),
        pool.current_num_threads(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

pub(crate) fn print_outcome(out: &Path, report: &str) {
    for line in report
        .lines()
        .filter(|l| l.starts_with("| ") && l.ends_with("hold** |") || l.ends_with("holds** |"))
    {
        println!("{line}");
    }
    println!("report:  {}", out.join("REPORT.md").display());
    println!("figures: {}", out.join("figures").display());
}

pub(crate) fn merge(dirs: &[PathBuf], out: &Path) -> Result<()> {
    let started = Instant::now();
    let (o, results, kinds) = host_sim::report::read_shards(dirs)?;
    prepare_out(out)?;
    let report = host_sim::report::finalize(out, &o, &results, &kinds)?;
    println!(
        "merged {} shard folders ({} trials x {} steps) in {:.1} s",
        dirs.len(),
        o.trials,
        o.steps,
        started.elapsed().as_secs_f64()
    );
    print_outcome(out, &report);
    Ok(())
}
