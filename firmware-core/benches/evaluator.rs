//! `cargo bench -p firmware-core --features bench --bench evaluator`: one full tick on the car
//! (evaluate the 64 trajectories + select) against the brute-force reference evaluator of the tests
//! (+ select), on three scenes.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use firmware_core::evaluator::{Evaluator, beam_direction};
use firmware_core::lattice::SCAN_BEAMS;
use firmware_core::observation::{
    Observation, PathReference, SCAN_MAX_RANGE, SemanticClass, SemanticObject,
};
use firmware_core::{ActionMask, FeatureTable, Learner, LearnerParams, OnlineLearner, policy};

#[path = "../tests/integration/support/naive.rs"]
mod naive;

fn scenes() -> Vec<(&'static str, Observation)> {
    let open = Observation::open_space();
    let mut corridor = Observation::open_space();
    for j in 0..SCAN_BEAMS {
        let (_, s) = beam_direction(j).unwrap();
        corridor.scan.ranges[j] = (0.75 / s.abs()).min(SCAN_MAX_RANGE);
    }
    corridor
        .objects
        .push(SemanticObject {
            class: SemanticClass::Door,
            x: 1.5,
            y: 0.9,
            radius: 0.45,
        })
        .unwrap();
    let mut cluttered = corridor.clone();
    for j in (0..SCAN_BEAMS).step_by(3) {
        cluttered.scan.ranges[j] = 0.6 + 0.02 * j as f32;
    }
    cluttered
        .objects
        .push(SemanticObject {
            class: SemanticClass::Chair,
            x: 1.0,
            y: -0.5,
            radius: 0.3,
        })
        .unwrap();
    cluttered
        .objects
        .push(SemanticObject {
            class: SemanticClass::Stairs,
            x: 2.5,
            y: 0.0,
            radius: 1.0,
        })
        .unwrap();
    cluttered.reference = PathReference {
        x: 0.95,
        y: 0.2,
        heading: 0.3,
    };
    vec![
        ("open", open),
        ("corridor", corridor),
        ("cluttered", cluttered),
    ]
}

fn bench(c: &mut Criterion) {
    let learner = Learner::new(
        LearnerParams::default()
            .with_initial([1.0, 2.0, 1.0, 1.0, -3.0, 0.5])
            .check()
            .unwrap(),
    );
    let mut group = c.benchmark_group("tick");
    for (name, obs) in scenes() {
        let mut evaluator = Evaluator::new();
        let mut table = FeatureTable::ZERO;
        group.bench_with_input(BenchmarkId::new("evaluate+select", name), &obs, |b, obs| {
            b.iter(|| {
                let obs = black_box(obs).check().unwrap();
                let mask = evaluator.evaluate(obs, &mut table);
                learner.select(&table, mask)
            })
        });
        group.bench_with_input(
            BenchmarkId::new("brute-force+select", name),
            &obs,
            |b, obs| {
                b.iter(|| {
                    let out = naive::evaluate(black_box(obs)).unwrap();
                    let mut t = FeatureTable::ZERO;
                    let mut mask = ActionMask::NONE;
                    for (a, row) in t.rows_mut().iter_mut().enumerate() {
                        *row = out.features[a];
                        if !out.collides[a] {
                            mask.insert(firmware_core::ActionIndex::new(a).unwrap());
                        }
                    }
                    policy::select(learner.weights(), &t, mask)
                })
            },
        );
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
