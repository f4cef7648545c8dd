//! Hand-computed cases of every pseudo-loss, of both surrogates and of one step of every learner,
//! from the paper's formulas (sections 5 and 6). The expected numbers are worked out in f64 in
//! the comments and compared with a tolerance where a square root is involved.

use firmware_core::evaluator::cross_track_errors;
use firmware_core::observation::PathReference;
use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, FEATURE_COUNT, Feature, FeatureTable, LearnError,
    Learner, LearnerKind, LearnerParams, OnlineLearner, PreferenceFeedback, Round,
    SemanticFeedback, lattice, learn, pseudo_loss, surrogate,
};

fn a(i: usize) -> ActionIndex {
    ActionIndex::new(i).unwrap()
}

/// Three allowed actions (0, 1, 2) and one forbidden (3) whose features are absurd on purpose:
/// they must never be read.
///
/// φ0 = (1, 0, 0, 0, 0, 0), φ1 = (0, 2, 0, 0, 0, 0), φ2 = (0, 0, 0, 0, 3, 4).
fn scene() -> (FeatureTable, ActionMask) {
    let mut t = FeatureTable::ZERO;
    t[a(0)] = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    t[a(1)] = [0.0, 2.0, 0.0, 0.0, 0.0, 0.0];
    t[a(2)] = [0.0, 0.0, 0.0, 0.0, 3.0, 4.0];
    t[a(3)] = [f32::NAN; FEATURE_COUNT];
    let mask: ActionMask = [a(0), a(1), a(2)].into_iter().collect();
    (t, mask)
}

fn close(x: f32, y: f64) -> bool {
    (x as f64 - y).abs() < 1e-5
}

#[test]
fn action_feedback_is_zero_for_the_teacher_and_100_elsewhere() {
    let (t, m) = scene();
    let round = Round::new(&t, m, a(1)).unwrap();
    let d = pseudo_loss(&ActionFeedback { action: a(2) }, &round).unwrap();
    assert_eq!(&d.values()[..4], &[100.0, 100.0, 0.0, 0.0]);
}

/// Action feedback builds its pseudo-loss directly, without the raw values and their shift:
/// the same values, bit for bit, as the general path, for every mask and every teacher's action.
#[test]
fn action_feedback_shortcut_equals_the_raw_values_shifted() {
    use firmware_core::{PseudoLoss, PseudoLossSource};
    let t = FeatureTable::ZERO;
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    for _ in 0..2000 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let mask = ActionMask::from_bits(state | 1 << (state % 64));
        let allowed: Vec<ActionIndex> = mask.into_iter().collect();
        let chosen = allowed[(state >> 8) as usize % allowed.len()];
        let teacher = allowed[(state >> 20) as usize % allowed.len()];
        let round = Round::new(&t, mask, chosen).unwrap();
        let fb = ActionFeedback { action: teacher };
        let mut raw = [0.0f32; 64];
        fb.write_pseudo_loss(&round, &mut raw).unwrap();
        let general = PseudoLoss::from_raw(raw, mask).unwrap().with_absolute(true);
        assert_eq!(fb.to_pseudo_loss(&round).unwrap(), general);
        let bits = |d: &PseudoLoss| d.values().map(f32::to_bits);
        assert_eq!(bits(&pseudo_loss(&fb, &round).unwrap()), bits(&general));
    }
    // A teacher's action the round does not allow is refused the same way.
    let (t, m) = scene();
    let round = Round::new(&t, m, a(0)).unwrap();
    assert_eq!(
        ActionFeedback { action: a(3) }.to_pseudo_loss(&round),
        Err(LearnError::ActionNotAllowed(a(3)))
    );
}

#[test]
fn preference_feedback_follows_the_norm_difference_shifted_to_zero() {
    // Δ(a) = ‖φ_p − φ_a‖ − ‖φ_np − φ_a‖ with p = 1, np = 2:
    //   Δ0 = √5 − √26, Δ1 = 0 − √29, Δ2 = √29 − 0; min = −√29, so after the shift
    //   Δ0 = √5 − √26 + √29, Δ1 = 0, Δ2 = 2√29.
    let (t, m) = scene();
    let round = Round::new(&t, m, a(0)).unwrap();
    let d = pseudo_loss(
        &PreferenceFeedback {
            preferred: a(1),
            other: a(2),
        },
        &round,
    )
    .unwrap();
    let (s5, s26, s29) = (5f64.sqrt(), 26f64.sqrt(), 29f64.sqrt());
    assert!(close(d[a(0)], s5 - s26 + s29), "{}", d[a(0)]);
    assert_eq!(d[a(1)], 0.0);
    assert!(close(d[a(2)], 2.0 * s29), "{}", d[a(2)]);
    assert_eq!(d[a(3)], 0.0, "forbidden entries stay 0");
}

/// The path straight ahead along the car's axis: the cross-track error of a trajectory is the
/// magnitude of its end's `y` (0 for the straight action 0, positive for actions 1 and 2, the
/// gentlest left turn and its mirror image, whose ends are equally far from the axis).
const AHEAD: PathReference = PathReference {
    x: 1.0,
    y: 0.0,
    heading: 0.0,
};

#[test]
fn semantic_statements_add_up() {
    // Chosen a0. "Avoid doors": door clearance higher than φ0's 0 is better → a1 gets 0,
    // a0 and a2 get 100. "Stay on the path": cross-track error below a0's 0 → nobody; all 100.
    // Sum (200, 100, 200) → shifted (100, 0, 100).
    let (t, m) = scene();
    let round = Round::new(&t, m, a(0))
        .unwrap()
        .with_reference(AHEAD)
        .unwrap();
    let said = SemanticFeedback::new()
        .avoid(Feature::Door)
        .prefer(Feature::Path);
    let d = pseudo_loss(&said, &round).unwrap();
    assert_eq!(&d.values()[..3], &[100.0, 0.0, 100.0]);

    // "Keep right" (prefer Right): a higher right offset is better → a2 (4 > 0).
    let d = pseudo_loss(&SemanticFeedback::new().prefer(Feature::Right), &round).unwrap();
    assert_eq!(&d.values()[..3], &[100.0, 100.0, 0.0]);
    // "Avoid the right" is "keep left": lower is better → nobody beats 0 → flat.
    let d = pseudo_loss(&SemanticFeedback::new().avoid(Feature::Right), &round).unwrap();
    assert_eq!(&d.values()[..3], &[0.0, 0.0, 0.0]);
    // "Avoid the path" wants a higher cross-track error than a0's 0: a1 and a2 (the Path
    // feature, 0 for a1, would have said a2 only).
    let d = pseudo_loss(&SemanticFeedback::new().avoid(Feature::Path), &round).unwrap();
    assert_eq!(&d.values()[..3], &[100.0, 0.0, 0.0]);
}

#[test]
fn the_path_statement_is_judged_by_cross_track_error_not_the_path_feature() {
    let (t, m) = scene();
    let cross = cross_track_errors(&AHEAD);
    let end = |i: usize| lattice::trajectory(a(i)).end();
    assert_eq!(cross[0], 0.0);
    assert_eq!(cross[1], end(1).y.abs());
    assert!(
        cross[1] > 0.0 && cross[1] == cross[2],
        "mirror images: {cross:?}"
    );
    // The Path feature says a0 (0) beats a2 (3); cross-track says a0 (0) beats a1 and a2. From
    // a1, "stay on the path" points to a0 alone: a2's end is as far off as a1's.
    let round = Round::new(&t, m, a(1))
        .unwrap()
        .with_reference(AHEAD)
        .unwrap();
    let d = pseudo_loss(&SemanticFeedback::new().prefer(Feature::Path), &round).unwrap();
    assert_eq!(&d.values()[..3], &[0.0, 100.0, 100.0]);
    // A path seen 0.3 m to the left, heading along the axis: cross-track |y_end − 0.3|.
    let left = PathReference { y: 0.3, ..AHEAD };
    let cross = cross_track_errors(&left);
    for i in 0..3 {
        assert!((cross[i] - (end(i).y - 0.3).abs()).abs() < 1e-6, "{i}");
    }
    // A path at right angles (heading π/2, through (1, 0)): cross-track is |x_end − 1|.
    let across = PathReference {
        heading: core::f32::consts::FRAC_PI_2,
        ..AHEAD
    };
    let cross = cross_track_errors(&across);
    for i in 0..3 {
        assert!((cross[i] - (end(i).x - 1.0).abs()).abs() < 1e-6, "{i}");
    }
}

#[test]
fn a_path_statement_needs_a_valid_path_reference() {
    let (t, m) = scene();
    let bare = Round::new(&t, m, a(0)).unwrap();
    assert_eq!(
        pseudo_loss(&SemanticFeedback::new().prefer(Feature::Path), &bare),
        Err(LearnError::NoPathReference)
    );
    // Other statements need none.
    assert!(pseudo_loss(&SemanticFeedback::new().avoid(Feature::Door), &bare).is_ok());
    for bad in [
        PathReference {
            x: f32::NAN,
            ..AHEAD
        },
        PathReference { y: 6.0, ..AHEAD },
        PathReference {
            heading: 4.0,
            ..AHEAD
        },
    ] {
        assert_eq!(
            bare.with_reference(bad).err(),
            Some(LearnError::BadPathReference),
            "{bad:?}"
        );
    }
    // The learner is unchanged by a refused statement.
    let mut l = Learner::new(LearnerParams::paper().check().unwrap());
    let before = *l.weights();
    assert_eq!(
        learn(
            &mut l,
            &bare,
            &SemanticFeedback::new().prefer(Feature::Path)
        ),
        Err(LearnError::NoPathReference)
    );
    assert_eq!(*l.weights(), before);
}

#[test]
fn bad_feedback_is_refused() {
    let (t, m) = scene();
    let round = Round::new(&t, m, a(0)).unwrap();
    assert_eq!(
        pseudo_loss(&ActionFeedback { action: a(3) }, &round),
        Err(LearnError::ActionNotAllowed(a(3)))
    );
    assert_eq!(
        pseudo_loss(
            &PreferenceFeedback {
                preferred: a(1),
                other: a(1)
            },
            &round
        ),
        Err(LearnError::DegenerateFeedback)
    );
    assert_eq!(
        pseudo_loss(&SemanticFeedback::new(), &round),
        Err(LearnError::DegenerateFeedback)
    );
    assert_eq!(
        Round::new(&t, m, a(3)).err(),
        Some(LearnError::ActionNotAllowed(a(3)))
    );
    assert_eq!(
        Round::new(&t, ActionMask::NONE, a(0)).err(),
        Some(LearnError::NoAllowedAction)
    );
    assert!(matches!(
        Round::new(&t, ActionMask::ALL, a(0)),
        Err(LearnError::Features(_))
    ));
}

#[test]
fn generalized_hinge_matches_the_paper() {
    // w = (1, 1, 0, 0, 0, 0): scores s = (1, 2, 0); the learner chose a1.
    // Action feedback a2: Δ = (100, 100, 0), â = a2,
    // ℓ = max(100 + 1 − 0, 100 + 2 − 0, 0) = 102 ≥ Δ(a_t) = 100, a_sel = a1,
    // g = φ1 − φ2 = (0, 2, 0, 0, −3, −4).
    let (t, m) = scene();
    let w = [1.0, 1.0, 0.0, 0.0, 0.0, 0.0];
    let round = Round::new(&t, m, a(1)).unwrap();
    let d = pseudo_loss(&ActionFeedback { action: a(2) }, &round).unwrap();
    let e = surrogate::generalized_hinge(&w, &round, &d);
    assert_eq!(e.value, 102.0);
    assert!(e.value >= d[round.chosen()]);
    assert_eq!((e.target, e.maximiser), (a(2), a(1)));
    assert_eq!(e.subgradient, [0.0, 2.0, 0.0, 0.0, -3.0, -4.0]);

    // Preference a1 over a2: Δ = (√5 − √26 + √29, 0, 2√29), â = a1,
    // ℓ = max(Δ0 + 1 − 2, 0, Δ2 + 0 − 2) = 2√29 − 2 ≈ 8.7703, a_sel = a2, g = φ2 − φ1.
    let d = pseudo_loss(
        &PreferenceFeedback {
            preferred: a(1),
            other: a(2),
        },
        &round,
    )
    .unwrap();
    let e = surrogate::generalized_hinge(&w, &round, &d);
    assert!(close(e.value, 2.0 * 29f64.sqrt() - 2.0), "{}", e.value);
    assert_eq!((e.target, e.maximiser), (a(1), a(2)));
    assert_eq!(e.subgradient, [0.0, -2.0, 0.0, 0.0, 3.0, 4.0]);
}

#[test]
fn hinge_is_zero_when_the_margins_already_hold() {
    // w = (0, 100, 0, 0, 0, 0): s = (0, 200, 0). Action feedback a1 (the learner's own choice):
    // ℓ = max(100 + 0 − 200, 0, 100 + 0 − 200) = 0 → flat, no step.
    let (t, m) = scene();
    let w = [0.0, 100.0, 0.0, 0.0, 0.0, 0.0];
    let round = Round::new(&t, m, a(1)).unwrap();
    let d = pseudo_loss(&ActionFeedback { action: a(1) }, &round).unwrap();
    let e = surrogate::generalized_hinge(&w, &round, &d);
    assert_eq!(e.value, 0.0);
    assert!(e.is_flat());
    assert_eq!(e.subgradient, [0.0; FEATURE_COUNT]);
}

#[test]
fn target_ties_go_to_the_best_scored_action() {
    // Semantic feedback flat on {a0, a2}? "Avoid doors" with chosen a1 (door 2): nobody is
    // better → Δ ≡ 0 → â is the best-scored action, the learner's own: no update.
    let (t, m) = scene();
    let w = [0.0, 1.0, 0.0, 0.0, 0.0, 0.0];
    let round = Round::new(&t, m, a(1)).unwrap();
    let d = pseudo_loss(&SemanticFeedback::new().avoid(Feature::Door), &round).unwrap();
    let e = surrogate::generalized_hinge(&w, &round, &d);
    assert_eq!(e.target, a(1));
    assert!(e.is_flat());
}

#[test]
fn perceptron_surrogate_is_the_coactive_update() {
    // Chosen a1, teacher a2: g = φ1 − φ2; Coactive (η = 1): w' = w − g = w + φ2 − φ1.
    let (t, m) = scene();
    let mut l = Learner::new(LearnerParams::new(LearnerKind::Coactive).check().unwrap());
    let round = Round::new(&t, m, a(1)).unwrap();
    let out = learn(&mut l, &round, &ActionFeedback { action: a(2) }).unwrap();
    assert!(out.stepped);
    assert_eq!(out.eval.maximiser, a(1));
    assert_eq!(l.weights(), &[0.0, -2.0, 0.0, 0.0, 3.0, 4.0]);
}

#[test]
fn one_step_of_each_learner_by_hand() {
    // From w0 = (1, 1, 0, 0, 0, 0), chosen a1, teacher a2 → g = (0, 2, 0, 0, −3, −4).
    let (t, m) = scene();
    let w0 = [1.0, 1.0, 0.0, 0.0, 0.0, 0.0];
    let round = Round::new(&t, m, a(1)).unwrap();
    let fb = ActionFeedback { action: a(2) };
    let make =
        |k: LearnerKind| Learner::new(LearnerParams::new(k).with_initial(w0).check().unwrap());

    // OGD, η = 0.01: w = w0 − 0.01 g = (1, 0.98, 0, 0, 0.03, 0.04).
    let mut l = make(LearnerKind::Ogd);
    l.learn(&round, &fb).unwrap();
    assert_eq!(
        l.weights(),
        &[1.0, 1.0 - 0.01 * 2.0, 0.0, 0.0, 0.01 * 3.0, 0.01 * 4.0]
    );

    // OGD with η/√t: the first step is η/√1 = η, the second η/√2.
    let mut l = make(LearnerKind::OgdDecaying);
    l.learn(&round, &fb).unwrap();
    assert_eq!(l.weights(), &[1.0, 0.98, 0.0, 0.0, 0.03, 0.04]);
    assert_eq!(l.steps(), 1);

    // Averaged OGD: raw w1 = (1, 0.98, 0, 0, 0.03, 0.04), acting w̄ = (w0 + w1)/2.
    let mut l = make(LearnerKind::AveragedOgd);
    l.learn(&round, &fb).unwrap();
    let avg = l.weights();
    assert!(
        close(avg[1], 0.99) && close(avg[4], 0.015) && close(avg[5], 0.02),
        "{avg:?}"
    );
    assert_eq!(avg[0], 1.0);

    // AdaGrad, η = 0.1: G = g² = (0, 4, 0, 0, 9, 16); w −= η g / (√G + ε)
    //   → (1, 1 − 0.1, 0, 0, 0.1, 0.1) up to ε = 1e-6.
    let mut l = make(LearnerKind::AdaGrad);
    l.learn(&round, &fb).unwrap();
    let w = l.weights();
    assert!(
        close(w[1], 0.9) && close(w[4], 0.1) && close(w[5], 0.1) && w[0] == 1.0,
        "{w:?}"
    );
}

#[test]
fn no_feedback_means_no_change() {
    // Acting many times without feedback leaves every learner exactly where it was: the crate
    // has no per-tick state. A flat pseudo-loss (feedback that does not tell the chosen action
    // from the best) takes no step either.
    let (t, m) = scene();
    for k in LearnerKind::ALL {
        let mut l = Learner::new(
            LearnerParams::new(k)
                .with_initial([0.5; 6])
                .check()
                .unwrap(),
        );
        let before = l;
        for _ in 0..100 {
            let chosen = l.select(&t, m).unwrap();
            assert_eq!(chosen, a(2));
        }
        assert_eq!(l, before);
        let round = Round::new(&t, m, a(2)).unwrap();
        let out = l
            .learn(&round, &SemanticFeedback::new().prefer(Feature::Right))
            .unwrap();
        assert!(!out.stepped, "{k:?}");
        assert_eq!(l, before, "{k:?}");
    }
}

#[test]
fn a_refused_call_changes_nothing() {
    let (t, m) = scene();
    let mut l = Learner::new(
        LearnerParams::default()
            .with_initial([0.5; 6])
            .check()
            .unwrap(),
    );
    let before = l;
    let round = Round::new(&t, m, a(0)).unwrap();
    assert!(l.learn(&round, &ActionFeedback { action: a(3) }).is_err());
    assert!(
        l.learn(
            &round,
            &PreferenceFeedback {
                preferred: a(0),
                other: a(0)
            }
        )
        .is_err()
    );
    assert_eq!(l, before);
}

#[test]
fn averaged_ogd_takes_absolute_feedback_at_its_iterate_and_relative_feedback_at_its_average() {
    use firmware_core::{AveragedOgd, LearnerParams, ValidLearnerParams};
    let (t, m) = scene();
    let params: ValidLearnerParams = LearnerParams::default().check().unwrap();
    let mut l = AveragedOgd::new(&params);
    // Two action corrections make the raw iterate and the average differ.
    let round = Round::new(&t, m, a(0)).unwrap();
    learn(&mut l, &round, &ActionFeedback { action: a(2) }).unwrap();
    learn(&mut l, &round, &ActionFeedback { action: a(1) }).unwrap();
    assert_ne!(l.iterate(), l.weights());
    let chosen = l.select(&t, m).unwrap();
    let round = Round::new(&t, m, chosen).unwrap();

    let absolute = ActionFeedback { action: a(0) };
    let delta = pseudo_loss(&absolute, &round).unwrap();
    assert!(delta.is_absolute());
    let at_iterate = surrogate::generalized_hinge(l.iterate(), &round, &delta);
    assert_eq!(
        learn(&mut l.clone(), &round, &absolute).unwrap().eval,
        at_iterate
    );

    let relative = SemanticFeedback::new().avoid(Feature::Door);
    let delta = pseudo_loss(&relative, &round).unwrap();
    assert!(!delta.is_absolute());
    let at_average = surrogate::generalized_hinge(l.weights(), &round, &delta);
    assert_eq!(
        learn(&mut l.clone(), &round, &relative).unwrap().eval,
        at_average
    );
    let preference = PreferenceFeedback {
        preferred: a(1),
        other: chosen,
    };
    assert!(!pseudo_loss(&preference, &round).unwrap().is_absolute());
}
