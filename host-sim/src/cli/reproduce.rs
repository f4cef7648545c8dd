//! `host-sim reproduce`, `merge` and `scale-sweep`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};

use host_sim::checks;
use host_sim::report::grid::{TRIALS, WORLD_TRIALS, WORLDS};

use super::{GridArgs, prepare_out, progress_bar, worker_pool};

#[derive(clap::Args, Debug)]
pub(crate) struct ReproduceArgs {
    /// Trials per setting (trial t has seed SEED + t), 1 to 10 000.
    #[arg(long, default_value_t = 10, allow_negative_numbers = true,
          value_parser = checks::count_flag(TRIALS))]
    trials: u32,
    #[command(flatten)]
    grid: GridArgs,
    /// Output folder (created if missing).
    #[arg(long, default_value = "out/reproduce")]
    out: PathBuf,
    /// Run only slice INDEX of COUNT of the trial grid (INDEX from 0, e.g. a SLURM array task id
    /// or a Kubernetes JOB_COMPLETION_INDEX) and write its raw results for `host-sim merge`.
    #[arg(long, value_name = "INDEX/COUNT")]
    shard: Option<host_sim::report::Shard>,
    /// Multiply every teacher's weights by this factor, in (0, 1000] (default 1: the calibrated
    /// teachers of docs/reproduction/CALIBRATION.md).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true,
          value_parser = checks::flag(checks::teacher_scale))]
    teacher_scale: f64,
    /// Generated worlds per teacher for the claims across worlds (seeds 0..K, each with each
    /// teacher, beside the households and the basement), 0 to 100 000; 0 runs the paper's grid
    /// only.
    #[arg(long, value_name = "K", default_value_t = host_sim::report::grid::DEFAULT_WORLDS,
          allow_negative_numbers = true, value_parser = checks::count_flag(WORLDS))]
    worlds: u32,
    /// Trials per setting in each world, 1 to 100.
    #[arg(long, default_value_t = host_sim::report::grid::DEFAULT_WORLD_TRIALS,
          allow_negative_numbers = true, value_parser = checks::count_flag(WORLD_TRIALS))]
    world_trials: u32,
}

#[derive(clap::Args, Debug)]
pub(crate) struct ScaleSweepArgs {
    /// Trials per setting (fewer than the report's 10 keeps the five grids quick; the output
    /// says how many), 1 to 10 000.
    #[arg(long, default_value_t = 5, allow_negative_numbers = true,
          value_parser = checks::count_flag(TRIALS))]
    trials: u32,
    #[command(flatten)]
    grid: GridArgs,
    /// The Markdown file to write.
    #[arg(long, default_value = "out/SCALE_SWEEP.md")]
    out: PathBuf,
}

pub(crate) fn reproduce(args: &ReproduceArgs) -> Result<()> {
    use host_sim::report::{self, Options, Shard};
    let o = Options {
        trials: args.trials,
        steps: args.grid.steps,
        seed: args.grid.seed,
        teacher_scale: args.teacher_scale as f32,
        worlds: args.worlds,
        world_trials: args.world_trials,
    };
    o.check()?;
    let shard = args.shard.unwrap_or(Shard::WHOLE);
    let out_dir = prepare_out(&args.out)?;
    let pool = worker_pool(args.grid.jobs)?;
    let jobs = report::jobs(&o, shard).len();
    let bar = progress_bar(
        jobs as u64,
        "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} trials, {eta} left {msg}",
    );
    bar.set_message(format!("({} threads)", pool.current_num_threads()));
    let started = Instant::now();
    let results = pool.install(|| report::run_shard(&o, shard, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let ran = started.elapsed().as_secs_f64();
    outln!(
        "ran {jobs} trials of {} steps on {} threads in {ran:.1} s",
        o.steps,
        pool.current_num_threads()
    )?;
    if shard.count > 1 {
        report::write_shard(&args.out, &o, shard, &results)?;
        out_dir.keep();
        outln!(
            "wrote shard {}/{} into {}; combine every shard with `host-sim merge DIR... --out DIR`",
            shard.index,
            shard.count,
            args.out.display()
        )?;
        return Ok(());
    }
    let report = report::finalize(&args.out, &o, &results)?;
    out_dir.keep();
    print_outcome(&args.out, &report)?;
    outln!(
        "wall time {:.1} s ({ran:.1} s of trials)",
        started.elapsed().as_secs_f64()
    )?;
    Ok(())
}

pub(crate) fn scale_sweep(args: &ScaleSweepArgs) -> Result<()> {
    use host_sim::report::grid::SWEEP_FACTORS;
    use host_sim::report::{self, Options, Shard};
    let o = Options {
        trials: args.trials,
        steps: args.grid.steps,
        seed: args.grid.seed,
        teacher_scale: 1.0,
        worlds: 0,
        world_trials: 1,
    };
    o.check()?;
    let pool = worker_pool(args.grid.jobs)?;
    let out_dir = match args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(parent) => Some(prepare_out(parent)?),
        None => None,
    };
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
    if let Some(d) = out_dir {
        d.keep();
    }
    for line in text.lines().filter(|l| l.starts_with("| ")) {
        outln!("{line}")?;
    }
    outln!(
        "wrote {} ({jobs} trials on {} threads in {:.1} s)",
        args.out.display(),
        pool.current_num_threads(),
        started.elapsed().as_secs_f64()
    )?;
    Ok(())
}

pub(crate) fn print_outcome(out: &Path, report: &str) -> Result<()> {
    for line in report
        .lines()
        .filter(|l| l.starts_with("| ") && l.ends_with("hold** |") || l.ends_with("holds** |"))
    {
        outln!("{line}")?;
    }
    outln!("report:  {}", out.join("REPORT.md").display())?;
    outln!("figures: {}", out.join("figures").display())?;
    Ok(())
}

pub(crate) fn merge(dirs: &[PathBuf], out: &Path) -> Result<()> {
    let started = Instant::now();
    let (o, results) = host_sim::report::read_shards(dirs)?;
    let out_dir = prepare_out(out)?;
    let report = host_sim::report::finalize(out, &o, &results)?;
    out_dir.keep();
    outln!(
        "merged {} shard folders ({}) in {:.1} s",
        dirs.len(),
        o.describe(),
        started.elapsed().as_secs_f64()
    )?;
    print_outcome(out, &report)?;
    Ok(())
}
