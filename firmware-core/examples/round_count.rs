//! `cargo run --release -p firmware-core --features bench --example round_count -- KIND N`: the
//! bench's round (benches/learner.rs, group `round`) done N times, for counting instructions
//! under callgrind (`valgrind --tool=callgrind`, the count at N minus the count at 0, over N).
//! KIND: dots (the 64 × 6 dot products), select, action, preference or semantic.

use std::hint::black_box;

use firmware_core::observation::PathReference;
use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, Feature, FeatureTable, Feedback, Learner,
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

const AHEAD: PathReference = PathReference {
    x: 1.0,
    y: 0.0,
    heading: 0.0,
};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let kind = args.get(1).map(String::as_str).unwrap_or("action");
    let n: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(20_000);
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
    let fb: Feedback = match kind {
        "preference" => PreferenceFeedback {
            preferred: a(17),
            other: a(40),
        }
        .into(),
        "semantic" => SemanticFeedback::new()
            .avoid(Feature::Door)
            .prefer(Feature::Path)
            .into(),
        _ => ActionFeedback { action: a(17) }.into(),
    };
    let mut acc = 0.0f32;
    for _ in 0..n {
        match kind {
            "dots" => {
                let w = black_box(learner.weights());
                let mut sum = 0.0f32;
                for row in black_box(&t).rows() {
                    sum += dot(w, row);
                }
                acc += black_box(sum);
            }
            "select" => {
                let mut scores = [0.0f32; MAX_ACTIONS];
                let c = policy::select_scored(
                    black_box(learner.weights()),
                    black_box(&t),
                    ActionMask::ALL,
                    &mut scores,
                );
                black_box((c, &scores));
            }
            _ => {
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
                l.learn(&round, black_box(&fb)).unwrap();
                black_box(l);
            }
        }
    }
    black_box(acc);
}
