//! `host-sim list`, `draw` and `bench`: what is built in, a scenario's picture, the speed.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Result, anyhow, bail};
use host_sim::report::animation::{self, AnimateOptions};
use host_sim::report::run_folder::RunFolder;
use host_sim::teach::calibrate::median;
use host_sim::teach::experiment::{self, RunConfig};
use host_sim::world::registry;
use host_sim::world::scenario::Scenario;
use nalgebra::Point2;

use crate::load_scenario;

pub(crate) fn list() -> Result<()> {
    outln!("scenarios (--scenario NAME, or a path to your own .toml):")?;
    for s in registry::SCENARIOS {
        let length = load_scenario(s.name)
            .map(|scn| format!("{:6.1} m path", scn.path.length()))
            .unwrap_or_else(|e| format!("(cannot load: {e})"));
        outln!("  {:<14} {length}  {}", s.name, s.description)?;
    }
    outln!("teacher presets (weights: obstacles, door, stairs, chair, path, right):")?;
    for p in host_sim::world::teacher::PRESETS {
        outln!("  {:<14} {:?}  {}", p.name, p.weights, p.description)?;
    }
    outln!("experiments:")?;
    for e in host_sim::report::registry::EXPERIMENTS {
        outln!("  {:<14} {}", e.name, e.description)?;
    }
    Ok(())
}

#[derive(clap::Args, Debug)]
pub(crate) struct DrawArgs {
    /// Scenario name or file. Default: with --run, the run's own (a run is drawn only on its
    /// own scenario); without, doors.
    #[arg(long)]
    scenario: Option<String>,
    /// A `host-sim run` folder (or its steps.csv) whose poses to draw.
    #[arg(long, value_name = "DIR")]
    run: Option<PathBuf>,
    /// The PNG file to write (default scenario.png; with --animate, only if given).
    #[arg(long)]
    out: Option<PathBuf>,
    /// With --run: write the run as an animated PNG (APNG) to this file: the map, the car's
    /// footprint, the 64 trajectories with the chosen one, corrections flashed, a tick counter
    /// and a latent-loss strip.
    #[arg(long, value_name = "OUT", requires = "run")]
    animate: Option<PathBuf>,
    /// With --animate: the first tick.
    #[arg(long, default_value_t = 0, requires = "animate")]
    from: u32,
    /// With --animate: one past the last tick (default: the run's end).
    #[arg(long, requires = "animate")]
    to: Option<u32>,
    /// With --animate: ticks per frame (default: the fewest that keep it at 300 frames or
    /// fewer).
    #[arg(long, requires = "animate")]
    every: Option<u32>,
    /// With --animate: frames per second, 1 to 50 (10 with --every 1 is the car's own pace).
    #[arg(long, default_value_t = 10, requires = "animate")]
    fps: u32,
}

/// The scenario to draw a run on: the run's own, or `--scenario` if it is the same; another is
/// refused.
fn scenario_of_run(run: &RunFolder, given: Option<&str>) -> Result<Scenario> {
    let Some(name) = &run.scenario else {
        // A steps.csv without its summary.json: nothing to check against.
        let given = given.ok_or_else(|| {
            anyhow!(
                "{}: no summary.json beside it to say which scenario the run was in: give \
                 --scenario",
                run.steps_csv.display()
            )
        })?;
        return load_scenario(given);
    };
    let own = || -> Result<Scenario> {
        match &run.scenario_file {
            Some(f) if f.is_file() => load_scenario(&f.to_string_lossy()),
            Some(f) if !registry::SCENARIOS.iter().any(|b| b.name == *name) => bail!(
                "the run's scenario {name} was {}, which is gone: give --scenario FILE",
                f.display()
            ),
            _ => load_scenario(name),
        }
    };
    let Some(given) = given else {
        return own();
    };
    let s = load_scenario(given)?;
    let same_file = match &run.scenario_file {
        Some(f) => std::fs::canonicalize(&s.source).is_ok_and(|g| &g == f),
        None => true,
    };
    if s.name != *name || !same_file {
        let file = run
            .scenario_file
            .as_ref()
            .map(|f| format!(" ({})", f.display()))
            .unwrap_or_default();
        bail!(
            "the run in {} is of scenario {name}{file}, not {} ({}): leave --scenario out to draw \
             it on its own",
            run.steps_csv.parent().unwrap_or(Path::new(".")).display(),
            s.name,
            s.source.display()
        );
    }
    Ok(s)
}

pub(crate) fn draw(args: &DrawArgs) -> Result<()> {
    let run = args.run.as_deref().map(RunFolder::open).transpose()?;
    let s = match &run {
        Some(r) => scenario_of_run(r, args.scenario.as_deref())?,
        None => load_scenario(args.scenario.as_deref().unwrap_or("doors"))?,
    };
    let rows = run.as_ref().map(RunFolder::rows).transpose()?;
    let out = match (&args.out, &args.animate) {
        (Some(out), _) => Some(out.clone()),
        (None, None) => Some(PathBuf::from("scenario.png")),
        (None, Some(_)) => None,
    };
    if let Some(out) = out {
        let mut raster = host_sim::report::plot::MapDrawing::of_scenario(&s);
        if let Some(rows) = &rows {
            let trace: Vec<Point2<f64>> = rows.iter().map(|r| Point2::new(r.x, r.y)).collect();
            raster.trace(&trace);
        }
        raster.write_png(&out)?;
        outln!("wrote {}", out.display())?;
    }
    if let (Some(file), Some(rows), Some(run)) = (&args.animate, &rows, &run) {
        let o = AnimateOptions {
            from: args.from,
            to: args.to,
            every: args.every,
            fps: args.fps,
            ..AnimateOptions::default()
        };
        let a = animation::animate(&s, rows, &run.title, &o, file)?;
        outln!(
            "wrote {}: {} frames of {} × {} pixels, one per {} tick{} at {} frames/s, {} bytes",
            file.display(),
            a.frames,
            a.width,
            a.height,
            a.every,
            if a.every == 1 { "" } else { "s" },
            o.fps,
            a.bytes
        )?;
    }
    Ok(())
}

pub(crate) fn bench(scenario: &str, steps: u32, runs: u32) -> Result<()> {
    let s = Arc::new(load_scenario(scenario)?);
    let config = RunConfig {
        steps,
        ..RunConfig::new(s)
    };
    let mut rates = Vec::with_capacity(runs as usize);
    // Whether every run's rate is of CPU time (else, some of wall time: no CPU clock).
    let mut of_cpu = true;
    let mut first = None;
    for run in 1..=runs {
        // The wall clock around the CPU clock's two readings, so that the CPU time is within it.
        let started = Instant::now();
        let on_cpu = thread_cpu_time();
        let report = experiment::run(&config)?;
        let cpu = on_cpu.zip(thread_cpu_time()).map(|(a, b)| b - a);
        let wall = started.elapsed().as_secs_f64();
        // Every run is the same seeded run: one that ends elsewhere (its corrections, its resets,
        // its learner) is a bug, not the machine's noise.
        let outcome = (report.corrections(), report.resets, report.final_snapshot);
        match &first {
            None => {
                outln!(
                    "{}: {steps} simulated steps (action feedback, {} corrections), {runs} run{}",
                    report.scenario,
                    report.corrections(),
                    if runs == 1 { "" } else { "s" }
                )?;
                first = Some(outcome);
            }
            Some(f) if *f != outcome => {
                bail!("run {run} ended elsewhere than the first: {outcome:?} against {f:?}")
            }
            Some(_) => {}
        }
        let per_second = |t: f64| steps as f64 / t;
        match cpu.filter(|c| *c > 0.0) {
            Some(cpu) => {
                outln!(
                    "  run {run}: {wall:.4} s, of which {cpu:.4} s on the CPU (the rest waiting \
                     for it): {:.0} steps per second of CPU time",
                    per_second(cpu)
                )?;
                rates.push(per_second(cpu));
            }
            None => {
                outln!(
                    "  run {run}: {wall:.4} s: {:.0} steps/s on one core",
                    per_second(wall)
                )?;
                rates.push(per_second(wall));
                of_cpu = false;
            }
        }
    }
    if rates.len() > 1 {
        let (best, worst) = rates
            .iter()
            .fold((f64::MIN, f64::MAX), |(b, w), &r| (b.max(r), w.min(r)));
        outln!(
            "steps per second{} over the {runs} runs: best {best:.0}, median {:.0}, worst {worst:.0}",
            if of_cpu { " of CPU time" } else { "" },
            median(&rates)
        )?;
    }
    Ok(())
}

/// The time this thread has spent on a CPU (s), from Linux's `/proc/thread-self/schedstat`
/// (nanoseconds, first field); `None` elsewhere.
///
/// The kernel brings that sum up to date when the thread leaves the CPU or at its scheduler's
/// tick, not when the file is read: read as it runs, it lags by up to a tick (4 ms here, 5 % of
/// a 20 000-step run). The yield first makes the kernel account the time run so far (a yield
/// is a trip through the scheduler, which updates it), so that the reading is current to within
/// microseconds (Python's `os.sched_yield()` then the file, against `time.thread_time_ns()`,
/// which reads the same clock through `clock_gettime`: 0.1 ms apart at most over 18 ms, against
/// 1–3 ms without the yield; 2026-12-04).
fn thread_cpu_time() -> Option<f64> {
    std::thread::yield_now();
    let stat = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: u64 = stat.split_whitespace().next()?.parse().ok()?;
    Some(ns as f64 * 1e-9)
}
