//! `cargo bench -p firmware-core --features bench --bench learner`: the policy's select over 64
//! actions, one learning step (pseudo-loss + surrogate + update) per feedback kind and learner, and
//! the learner's round (select + update, 64 actions, the default learner) beside its own floor, the
//! 64 × 6 dot products of the weights with the table, in the same run (group `round`).

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use firmware_core::observation::PathReference;
use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, Feature, FeatureTable, Feedback, Learner, LearnerKind,
    LearnerParams, MAX_ACTIONS, OnlineLearner, PreferenceFeedback, Round, SemanticFeedback, dot,
    policy,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn table(seed: u64) -> FeatureTable {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut t = FeatureTable::ZERO;
    for row in t.rows_mut() {
        for x in row.iter_mut() {
            *x = rng.random_range(-1.0f32..1.0);
        }
    }
    t
}

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

/// The path 1 m straight ahead: statements about the path are judged against it.
const AHEAD: PathReference = PathReference {
    x: 1.0,
    y: 0.0,
    heading: 0.0,
};

fn bench_update(c: &mut Criterion) {
    let t = table(2);
    let a = |i| ActionIndex::new(i).unwrap();
    let feedbacks: [(&str, Feedback); 3] = [
        ("action", ActionFeedback { action: a(17) }.into()),
        (
            "preference",
            PreferenceFeedback {
                preferred: a(17),
                other: a(40),
            }
            .into(),
        ),
        (
            "semantic",
            SemanticFeedback::new()
                .avoid(Feature::Door)
                .prefer(Feature::Path)
                .into(),
        ),
    ];
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

/// The round the car runs when a correction arrives for the tick it just acted in: select over
/// 64 actions keeping their scores, then one update, with the default learner (averaged OGD),
/// the round carrying its path reference as the agent's do (a statement about the path needs it)
/// and select's scores (`Round::with_scores`, as the agent's do off the car); and in the same
/// group, the 64 × 6 dot products of the acting weights with the table that any round must do
/// once. The learner has taken a few steps first, so that its raw iterate (where action
/// feedback is linearized) is not its average (where it acts): a fresh learner's are the same
/// weights, and select's scores would serve action feedback too.
fn bench_round(c: &mut Criterion) {
    let t = table(3);
    let a = |i| ActionIndex::new(i).unwrap();
    let mut learner = Learner::new(
        LearnerParams::default()
            .with_initial([0.3, -0.2, 0.9, 0.1, -0.7, 0.4])
            .check()
            .unwrap(),
    );
    let warm = table(4);
    for i in [5, 23, 41] {
        let chosen = learner.select(&warm, ActionMask::ALL).unwrap();
        let round = Round::new(&warm, ActionMask::ALL, chosen).unwrap();
        learner
            .learn(&round, &ActionFeedback { action: a(i) })
            .unwrap();
    }
    assert_ne!(learner.state().iterate, learner.state().average);
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
    let feedbacks: [(&str, Feedback); 3] = [
        ("action", ActionFeedback { action: a(17) }.into()),
        (
            "preference",
            PreferenceFeedback {
                preferred: a(17),
                other: a(40),
            }
            .into(),
        ),
        (
            "semantic",
            SemanticFeedback::new()
                .avoid(Feature::Door)
                .prefer(Feature::Path)
                .into(),
        ),
    ];
    for (name, fb) in &feedbacks {
        // Each iteration starts from a copy of the same learner (about 100 bytes on the stack):
        // `iter_batched_ref` would time its batch's vector of outputs too, page faults included.
        group.bench_function(BenchmarkId::new("select+update", name), |b| {
            b.iter(|| {
                let mut l = black_box(learner);
                let table = black_box(&t);
                let mut scores = [0.0f32; MAX_ACTIONS];
                let chosen =
                    policy::select_scored(l.weights(), table, ActionMask::ALL, &mut scores)
                        .unwrap();
                let round = Round::new(table, ActionMask::ALL, chosen)
                    .and_then(|r| r.with_reference(AHEAD))
                    .unwrap()
                    .with_scores(l.weights(), &scores);
                l.learn(&round, black_box(fb)).unwrap();
                l
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_select, bench_update, bench_round);
criterion_main!(benches);
