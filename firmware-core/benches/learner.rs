//! `cargo bench -p firmware-core --features bench --bench learner`: the policy's select over 64
//! actions, one learning step (pseudo-loss + surrogate + update) per feedback kind and learner, and
//! the learner's round (select + update, 64 actions, the default learner) beside its own floor, the
//! 64 × 6 dot products of the weights with the table, in the same run (group `round`).

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use firmware_core::{
    ActionMask, Learner, LearnerKind, LearnerParams, OnlineLearner, Round, dot, policy,
};

#[path = "support/round.rs"]
mod fixture;
use fixture::{AHEAD, table};

fn bench_select(c: &mut Criterion) {
    let t = table(1);
    let w = [0.3, -0.2, 0.9, 0.1, -0.7, 0.4];
    let mut group = c.benchmark_group("select");
    for allowed in [64u32, 32, 8] {
        let mask = ActionMask::from_bits(if allowed == 64 {
            u64::MAX
        } else {
            (1u64 << allowed) - 1
        });
        group.bench_with_input(BenchmarkId::from_parameter(allowed), &mask, |b, &mask| {
            b.iter(|| policy::select(black_box(&w), black_box(&t), black_box(mask)))
        });
    }
    group.finish();
}

fn bench_update(c: &mut Criterion) {
    let t = table(2);
    let feedbacks = fixture::feedbacks();
    let mut group = c.benchmark_group("update");
    for kind in [
        LearnerKind::Ogd,
        LearnerKind::AveragedOgd,
        LearnerKind::AdaGrad,
    ] {
        for (name, fb) in &feedbacks {
            let learner = Learner::new(
                LearnerParams::new(kind)
                    .with_initial([0.1; 6])
                    .check()
                    .unwrap(),
            );
            let chosen = learner.select(&t, ActionMask::ALL).unwrap();
            group.bench_function(BenchmarkId::new(kind.name(), name), |b| {
                b.iter_batched_ref(
                    || learner,
                    |l| {
                        let round = Round::new(black_box(&t), ActionMask::ALL, chosen)
                            .and_then(|r| r.with_reference(AHEAD))
                            .unwrap();
                        l.learn(&round, black_box(fb)).unwrap()
                    },
                    criterion::BatchSize::SmallInput,
                )
            });
        }
    }
    group.finish();
}

/// The round the car runs when a correction arrives for the tick it just acted in
/// ([`fixture::round`]: select over 64 actions keeping their scores, then one update, with the
/// default learner warmed so that its raw iterate is not its average), and in the same group the
/// 64 × 6 dot products of the acting weights with the table that any round must do once.
fn bench_round(c: &mut Criterion) {
    let t = table(3);
    let learner = fixture::warmed_learner();
    let mut group = c.benchmark_group("round");
    group.bench_function("dot-products", |b| {
        b.iter(|| {
            let w = black_box(learner.weights());
            let mut sum = 0.0f32;
            for row in black_box(&t).rows() {
                sum += dot(w, row);
            }
            sum
        })
    });
    for (name, fb) in &fixture::feedbacks() {
        // Each iteration starts from a copy of the same learner (about 100 bytes on the stack):
        // `iter_batched_ref` would time its batch's vector of outputs too, page faults included.
        group.bench_function(BenchmarkId::new("select+update", name), |b| {
            b.iter(|| fixture::round(&learner, &t, fb))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_select, bench_update, bench_round);
criterion_main!(benches);
