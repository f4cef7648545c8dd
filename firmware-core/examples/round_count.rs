//! `cargo build --release -p firmware-core --features bench --example round_count`, then
//! `target/release/examples/round_count KIND N`: the round of the learner bench
//! (`benches/learner.rs`, group `round`) done N times, for counting its instructions with callgrind
//! (`valgrind --tool=callgrind`: the count at N minus the count at 0, over N). KIND: dots (the
//! 64 × 6 dot products), select (select alone, its scores kept), action, preference or semantic,
//! or seal (`FeatureTable::seal`, which the evaluator does once per table it writes: on the host
//! the table's copy feature by feature that the round's passes read, and its bound check).

use std::hint::black_box;

use firmware_core::{ActionMask, MAX_ACTIONS, OnlineLearner, dot, policy};

#[path = "../benches/support/round.rs"]
mod fixture;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let kind = args.get(1).map_or("action", String::as_str);
    let n: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(20_000);
    let t = fixture::table(3);
    let mut resealed = t.clone();
    let learner = fixture::warmed_learner();
    let feedbacks = fixture::feedbacks();
    let fb = feedbacks
        .iter()
        .find(|(name, _)| *name == kind)
        .map(|(_, fb)| fb);
    for _ in 0..n {
        match (kind, fb) {
            ("dots", _) => {
                let w = black_box(learner.weights());
                let mut sum = 0.0f32;
                for row in black_box(&t).rows() {
                    sum += dot(w, row);
                }
                black_box(sum);
            }
            ("select", _) => {
                let mut scores = [0.0f32; MAX_ACTIONS];
                let chosen = policy::select_scored(
                    black_box(learner.weights()),
                    black_box(&t),
                    ActionMask::ALL,
                    &mut scores,
                );
                black_box((chosen, &scores));
            }
            ("seal", _) => {
                let t = black_box(&mut resealed);
                t.seal();
                black_box(t);
            }
            (_, Some(fb)) => {
                black_box(fixture::round(&learner, &t, fb));
            }
            _ => panic!("KIND: dots, select, action, preference, semantic or seal"),
        }
    }
}
