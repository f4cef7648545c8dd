//! Simulated steps per second of one run on one core, and its parts.
//!
//! `cargo bench -p host-sim --features bench --bench sim`. `host-sim bench` prints the same figure
//! for a whole run.

use std::hint::black_box;
use std::sync::Arc;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use host_sim::teach::experiment::{self, RunConfig};
use host_sim::world::registry;
use host_sim::world::sim::Episode;

fn bench(c: &mut Criterion) {
    let scenario = Arc::new(registry::load_scenario("doors").unwrap());
    let mut g = c.benchmark_group("sim");
    g.sample_size(10);
    let steps = 500u32;
    g.throughput(Throughput::Elements(steps as u64));
    g.bench_function("run_500_steps_action_feedback", |b| {
        let config = RunConfig {
            steps,
            ..RunConfig::new(scenario.clone())
        };
        b.iter(|| black_box(experiment::run(&config).unwrap().corrections()))
    });
    g.throughput(Throughput::Elements(1));
    let episode = Episode::new(scenario.clone());
    g.bench_function("observe", |b| b.iter(|| black_box(episode.observe())));
    // What an in-process run senses: the beams only as far as an evaluation can see.
    g.bench_function("observe_near", |b| {
        b.iter(|| black_box(episode.observe_near()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
