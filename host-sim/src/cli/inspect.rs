//! `host-sim list`, `draw` and `bench`: what is built in, a scenario's picture, the speed.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Result, bail};
use host_sim::teach::experiment::{self, RunConfig};
use host_sim::world::registry;

use crate::load_scenario;

pub(crate) fn list() {
    println!("scenarios (--scenario NAME, or a path to your own .toml):");
    for s in registry::SCENARIOS {
        let length = load_scenario(s.name)
            .map(|scn| format!("{:6.1} m path", scn.path.length()))
            .unwrap_or_else(|e| format!("(cannot load: {e})"));
        println!("  {:<14} {length}  {}", s.name, s.description);
    }
    println!("teacher presets (weights: obstacles, door, stairs, chair, path, right):");
    for p in host_sim::world::teacher::PRESETS {
        println!("  {:<14} {:?}  {}", p.name, p.weights, p.description);
    }
    println!("experiments:");
    for e in host_sim::report::registry::EXPERIMENTS {
        println!("  {:<14} {}", e.name, e.description);
    }
}

pub(crate) fn draw(scenario: &str, run: Option<&Path>, out: &Path) -> Result<()> {
    let s = load_scenario(scenario)?;
    let mut raster = host_sim::report::plot::Raster::of_scenario(&s);
    if let Some(csv) = run {
        raster.trace(&host_sim::report::plot::read_trace(csv)?);
    }
    raster.write_png(out)?;
    println!("wrote {}", out.display());
    Ok(())
}

pub(crate) fn bench(scenario: &str, steps: u32) -> Result<()> {
    if steps == 0 {
        bail!("--steps must be positive");
    }
    let s = Arc::new(load_scenario(scenario)?);
    let config = RunConfig {
        steps,
        ..RunConfig::new(s)
    };
    let on_cpu = thread_cpu_time();
    let started = Instant::now();
    let report = experiment::run(&config)?;
    let wall = started.elapsed().as_secs_f64();
    let cpu = on_cpu.zip(thread_cpu_time()).map(|(a, b)| b - a);
    println!(
        "{}: {} simulated steps (action feedback, {} corrections) in {:.3} s: {:.0} steps/s on one core",
        report.scenario,
        steps,
        report.corrections(),
        wall,
        steps as f64 / wall
    );
    if let Some(cpu) = cpu.filter(|c| *c > 0.0) {
        println!(
            "  of which {cpu:.3} s on the CPU (the rest waiting for it: other work shares the \
             machine): {:.0} steps per second of CPU time",
            steps as f64 / cpu
        );
    }
    Ok(())
}

/// The time this thread has spent on a CPU (s), from Linux's `/proc/thread-self/schedstat`
/// (nanoseconds, first field); `None` elsewhere.
fn thread_cpu_time() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: u64 = stat.split_whitespace().next()?.parse().ok()?;
    Some(ns as f64 * 1e-9)
}
