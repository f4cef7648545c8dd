//! The learner's round of `benches/learner.rs` (group `round`), shared with
//! `examples/round_count.rs`, which counts its instructions: the tables, the warmed learner, the
//! feedbacks and the round itself.

use std::hint::black_box;

use firmware_core::observation::PathReference;
use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, Feature, FeatureTable, Feedback, Learner,
    LearnerParams, MAX_ACTIONS, OnlineLearner, PreferenceFeedback, Round, SemanticFeedback, policy,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A table of features drawn uniformly from [−1, 1), sealed as the evaluator seals what it
/// writes (see `FeatureTable::seal`).
pub(crate) fn table(seed: u64) -> FeatureTable {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut t = FeatureTable::ZERO;
    for row in t.rows_mut() {
        for x in row.iter_mut() {
            *x = rng.random_range(-1.0f32..1.0);
        }
    }
    t.seal();
    t
}

/// The path 1 m straight ahead: statements about the path are judged against it.
pub(crate) const AHEAD: PathReference = PathReference {
    x: 1.0,
    y: 0.0,
    heading: 0.0,
};

fn a(i: usize) -> ActionIndex {
    ActionIndex::new(i).unwrap()
}

/// One feedback of each of the paper's kinds, by name.
pub(crate) fn feedbacks() -> [(&'static str, Feedback); 3] {
    [
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
    ]
}

/// The default learner (averaged OGD) after three steps of action feedback on another table, so
/// that its raw iterate (where action feedback is linearized) is not its average (where it acts):
/// a fresh learner's are the same weights, and select's scores would serve action feedback too.
pub(crate) fn warmed_learner() -> Learner {
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
    learner
}

/// The round the car runs when a correction arrives for the tick it just acted in: select over
/// 64 actions keeping their scores, then one update, the round carrying its path reference and
/// select's scores as the agent's do off the car. Starts from a copy of `learner` (about 100
/// bytes on the stack) and returns it.
#[inline(always)]
pub(crate) fn round(learner: &Learner, table: &FeatureTable, fb: &Feedback) -> Learner {
    let mut l = black_box(*learner);
    let table = black_box(table);
    let mut scores = [0.0f32; MAX_ACTIONS];
    let chosen = policy::select_scored(l.weights(), table, ActionMask::ALL, &mut scores).unwrap();
    let round = Round::new(table, ActionMask::ALL, chosen)
        .and_then(|r| r.with_reference(AHEAD))
        .unwrap()
        .with_scores(l.weights(), &scores);
    l.learn(&round, black_box(fb)).unwrap();
    l
}
