//! The kinds of feedback beyond the paper's three (issue 15): perturbation, reward,
//! correct/incorrect, good/bad spans, rankings, E-stops. For each: hand-computed values, the
//! paper's assumption 1 for a noiseless teacher where the kind carries that information (the
//! pseudo-loss is minimised by actions of minimal latent loss), bounds, and refusals that change
//! nothing.

use firmware_core::agent::{Agent, FeedbackError, TICK_HISTORY};
use firmware_core::evaluator::{Evaluator, FEATURE_ERROR_BOUND, beam_direction};
use firmware_core::feedback::executed::EXECUTED_LOSS;
use firmware_core::feedback::perturbation::{CORRECTED_RANGES, DeformedTrajectory, Milli};
use firmware_core::lattice::{SCAN_BEAMS, trajectory};
use firmware_core::observation::{
    MAX_OBJECTS, Observation, PathReference, SCAN_MAX_RANGE, SemanticClass, SemanticObject,
};
use firmware_core::{
    ActionIndex, ActionMask, CorrectnessFeedback, EStopFeedback, FEATURE_BOUND, FEATURE_COUNT,
    FeatureTable, Feedback, FeedbackKind, LearnError, Learner, LearnerParams, MAX_RANKED, MAX_SPAN,
    OnlineLearner, PSEUDO_LOSS_BOUND, PerturbationFeedback, PreferenceFeedback, PseudoLoss,
    PseudoLossSource, RankingFeedback, RewardFeedback, Round, SpanFeedback, Weights, dot,
    pseudo_loss,
};
use proptest::prelude::*;

fn a(i: usize) -> ActionIndex {
    ActionIndex::new(i).unwrap()
}

/// φ0 = (1, 0, …), φ1 = (0, 2, 0, …), φ2 = (0, 0, 0, 0, 3, 4); action 3 forbidden.
fn scene() -> (FeatureTable, ActionMask) {
    let mut t = FeatureTable::ZERO;
    t[a(0)] = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    t[a(1)] = [0.0, 2.0, 0.0, 0.0, 0.0, 0.0];
    t[a(2)] = [0.0, 0.0, 0.0, 0.0, 3.0, 4.0];
    t[a(3)] = [f32::NAN; FEATURE_COUNT];
    (t, [a(0), a(1), a(2)].into_iter().collect())
}

fn values(fb: &dyn PseudoLossSource, chosen: usize) -> Result<[f32; 3], LearnError> {
    let (t, m) = scene();
    let round = Round::new(&t, m, a(chosen)).unwrap();
    let d = fb.to_pseudo_loss(&round)?;
    Ok([d[a(0)], d[a(1)], d[a(2)]])
}

fn close(x: f32, y: f64) -> bool {
    (x as f64 - y).abs() < 1e-5
}

#[test]
fn executed_action_kinds_by_hand() {
    let bad = EXECUTED_LOSS;
    // Incorrect, E-stop, a negative reward: "not a_t" (a_t = 1).
    assert_eq!(
        values(&CorrectnessFeedback { correct: false }, 1),
        Ok([0.0, bad, 0.0])
    );
    assert_eq!(values(&EStopFeedback, 1), Ok([0.0, bad, 0.0]));
    let r = RewardFeedback::new(-0.25).unwrap();
    assert_eq!(values(&r, 1), Ok([0.0, 25.0, 0.0]));
    // Correct, a positive reward: "a_t".
    assert_eq!(
        values(&CorrectnessFeedback { correct: true }, 2),
        Ok([bad, bad, 0.0])
    );
    let r = RewardFeedback::new(0.5).unwrap();
    assert_eq!(values(&r, 2), Ok([50.0, 50.0, 0.0]));
    // A span's pseudo-loss on one tick is correct/incorrect's.
    let span = SpanFeedback {
        ticks: 3,
        good: false,
    };
    assert_eq!(values(&span, 0), Ok([bad, 0.0, 0.0]));
    // None of them is absolute.
    for k in [
        Feedback::Reward(r),
        Feedback::Correctness(CorrectnessFeedback { correct: true }),
        Feedback::Span(span),
        Feedback::EStop(EStopFeedback),
    ] {
        assert!(!k.is_absolute(), "{k:?}");
        assert!(!k.kind().points_at_better());
    }
}

#[test]
fn the_size_of_a_reward_does_not_change_the_step() {
    let (t, m) = scene();
    let round = Round::new(&t, m, a(1)).unwrap();
    let step = |fb: &dyn PseudoLossSource| {
        let mut l = Learner::new(LearnerParams::paper().check().unwrap());
        let delta = fb.to_pseudo_loss(&round).unwrap();
        firmware_core::learn_from_loss(&mut l, &round, &delta).unwrap();
        *l.weights()
    };
    let small = step(&RewardFeedback::new(-0.01).unwrap());
    assert_eq!(small, step(&RewardFeedback::new(-1.0).unwrap()));
    assert_eq!(small, step(&CorrectnessFeedback { correct: false }));
    assert_eq!(small, step(&EStopFeedback));
}

#[test]
fn ranking_by_hand_and_two_actions_are_a_preference() {
    // Best of three, ordered 1 ≻ 0 ≻ 2: c = (1, 2), Δ(a) = (1·(d1 − d0) + 2·(d1 − d2)) / 3.
    let r = RankingFeedback::new(&[a(1), a(0), a(2)], true).unwrap();
    let [d0, d1, d2] = values(&r, 0).unwrap();
    let (s5, s29, s26) = (5f64.sqrt(), 29f64.sqrt(), 26f64.sqrt());
    let raw = [
        ((s5 - 0.0) + 2.0 * (s5 - s26)) / 3.0,
        ((0.0 - s5) + 2.0 * (0.0 - s29)) / 3.0,
        ((s29 - s26) + 2.0 * (s29 - 0.0)) / 3.0,
    ];
    let min = raw[1];
    assert!(close(d0, raw[0] - min) && close(d1, 0.0) && close(d2, raw[2] - min));
    // Best of three (not ordered): c = (1, 1).
    let b = RankingFeedback::new(&[a(1), a(0), a(2)], false).unwrap();
    let [e0, e1, _] = values(&b, 0).unwrap();
    assert!(close(e1, 0.0) && e0 > 0.0);
    // K = 2 is the paper's preference, bit for bit.
    let (t, m) = scene();
    for chosen in 0..3 {
        let round = Round::new(&t, m, a(chosen)).unwrap();
        for (p, q) in [(0, 1), (1, 2), (2, 0)] {
            let rank = RankingFeedback::new(&[a(p), a(q)], true).unwrap();
            let pref = PreferenceFeedback {
                preferred: a(p),
                other: a(q),
            };
            let bits = |d: PseudoLoss| d.values().map(f32::to_bits);
            assert_eq!(
                bits(pseudo_loss(&rank, &round).unwrap()),
                bits(pseudo_loss(&pref, &round).unwrap())
            );
        }
    }
}

#[test]
fn perturbation_by_hand() {
    // φ̄ = (0, 2, 0, 0, 0, 1): distances √(1+4+1) = √6 to φ0, 1 to φ1, √(4+9+9) = √22 to φ2.
    let fb = PerturbationFeedback::new(&[0.0, 2.0, 0.0, 0.0, 0.0, 1.0]).unwrap();
    let [d0, d1, d2] = values(&fb, 0).unwrap();
    assert!(close(d0, 6f64.sqrt() - 1.0) && close(d1, 0.0) && close(d2, 22f64.sqrt() - 1.0));
    assert!(
        !fb.is_absolute(),
        "taken at the weights that acted (see its documentation)"
    );
    // Thousandths, fixed width.
    assert_eq!(Milli::from_f32(1.2345).unwrap().get(), 1235);
    assert_eq!(Milli::new(-7).to_f32(), -0.007);
    let bytes = postcard::to_allocvec(&fb).unwrap();
    assert_eq!(bytes.len(), 12);
}

#[test]
fn malformed_feedback_is_refused() {
    let refused = |fb: &dyn PseudoLossSource| values(fb, 0).unwrap_err();
    assert_eq!(
        refused(&RewardFeedback { hundredths: 0 }),
        LearnError::DegenerateFeedback
    );
    for h in [101, -101, i8::MIN, i8::MAX] {
        assert_eq!(
            refused(&RewardFeedback { hundredths: h }),
            LearnError::OutOfRange
        );
    }
    assert!(RewardFeedback::new(1.01).is_none() && RewardFeedback::new(f32::NAN).is_none());
    assert_eq!(
        refused(&SpanFeedback {
            ticks: 0,
            good: false
        }),
        LearnError::DegenerateFeedback
    );
    assert_eq!(
        refused(&SpanFeedback {
            ticks: MAX_SPAN + 1,
            good: false
        }),
        LearnError::OutOfRange
    );
    for r in [
        RankingFeedback::new(&[], true).unwrap(),
        RankingFeedback::new(&[a(1)], true).unwrap(),
        RankingFeedback::new(&[a(1), a(2), a(1)], false).unwrap(),
    ] {
        assert_eq!(refused(&r), LearnError::DegenerateFeedback, "{r:?}");
    }
    assert_eq!(
        refused(&RankingFeedback::new(&[a(1), a(3)], true).unwrap()),
        LearnError::ActionNotAllowed(a(3))
    );
    assert!(RankingFeedback::new(&[a(0); MAX_RANKED + 1], true).is_none());
    // A corrected feature vector no trajectory could have.
    let mut phi = [1.0, 1.0, 1.0, 1.0, 1.0, 0.0];
    assert!(PerturbationFeedback::new(&phi).is_some());
    for (i, (lo, hi)) in CORRECTED_RANGES.iter().enumerate() {
        for x in [lo - 0.001, hi + 0.001] {
            let saved = phi[i];
            phi[i] = x;
            assert!(
                PerturbationFeedback::new(&phi).is_none(),
                "feature {i} = {x}"
            );
            // From the wire, where nothing checked it.
            let mut fb = PerturbationFeedback::new(&[1.0, 1.0, 1.0, 1.0, 1.0, 0.0]).unwrap();
            fb.corrected[i] = Milli::new((x * 1000.0).round() as i16);
            assert_eq!(refused(&fb), LearnError::OutOfRange, "feature {i} = {x}");
            phi[i] = saved;
        }
    }
    assert!(PerturbationFeedback::new(&[f32::NAN, 1.0, 1.0, 1.0, 1.0, 0.0]).is_none());
}

#[test]
fn every_kind_travels_and_comes_back() {
    let all = [
        Feedback::Perturbation(
            PerturbationFeedback::new(&[9.5, 0.0, 10.0, 3.25, 4.0, -9.9]).unwrap(),
        ),
        Feedback::Reward(RewardFeedback::new(-1.0).unwrap()),
        Feedback::Correctness(CorrectnessFeedback { correct: true }),
        Feedback::Span(SpanFeedback {
            ticks: 4,
            good: false,
        }),
        Feedback::Ranking(RankingFeedback::new(&[a(63), a(0), a(7), a(8)], false).unwrap()),
        Feedback::EStop(EStopFeedback),
    ];
    for fb in all {
        let bytes = postcard::to_allocvec(&fb).unwrap();
        assert_eq!(bytes[0], fb.kind() as u8);
        assert_eq!(postcard::from_bytes::<Feedback>(&bytes).unwrap(), fb);
        assert_eq!(FeedbackKind::from_name(fb.kind().name()), Some(fb.kind()));
    }
    // Nine actions do not decode as a ranking; two equal rankings compare equal whatever the
    // unused slots hold.
    let mut nine = vec![7u8, 9];
    nine.extend(0..9u8);
    nine.push(1);
    assert!(postcard::from_bytes::<Feedback>(&nine).is_err());
    let r = RankingFeedback::new(&[a(1), a(2)], true).unwrap();
    let back: RankingFeedback = postcard::from_bytes(&postcard::to_allocvec(&r).unwrap()).unwrap();
    assert_eq!(back, r);
}

// ---------------------------------------------------------------------------------------------
// Assumption 1 and bounds, on random rounds with a noiseless teacher.

/// A random round: features in ±`scale`, at least two allowed actions, a chosen one, the
/// teacher's weights.
fn round_parts() -> impl Strategy<Value = (FeatureTable, ActionMask, usize, Weights)> {
    (
        proptest::collection::vec(proptest::array::uniform6(-10.0f32..10.0), 64),
        any::<u64>(),
        0usize..64,
        proptest::array::uniform6(-3.0f32..3.0),
    )
        .prop_map(|(rows, bits, pick, w)| {
            let mut t = FeatureTable::ZERO;
            for (i, r) in rows.into_iter().enumerate() {
                t[a(i)] = r;
            }
            let mask = ActionMask::from_bits(bits | 0b11);
            let allowed: Vec<ActionIndex> = mask.into_iter().collect();
            (t, mask, allowed[pick % allowed.len()].get(), w)
        })
}

/// Latent losses `w*·(φ(a*) − φ(a))` and the teacher's best.
fn latent(t: &FeatureTable, mask: ActionMask, w: &Weights) -> ([f32; 64], ActionIndex) {
    let best = firmware_core::policy::select(w, t, mask).unwrap();
    let top = dot(w, &t[best]);
    let mut l = [0.0; 64];
    for x in mask {
        l[x.get()] = top - dot(w, &t[x]);
    }
    (l, best)
}

/// The minimisers of `delta` over the allowed actions.
fn minimisers(delta: &PseudoLoss, mask: ActionMask) -> Vec<ActionIndex> {
    mask.into_iter().filter(|&x| delta[x] == 0.0).collect()
}

fn in_bounds(delta: &PseudoLoss, mask: ActionMask) -> bool {
    mask.into_iter()
        .all(|x| delta[x].is_finite() && delta[x] >= 0.0 && delta[x] <= 2.0 * PSEUDO_LOSS_BOUND)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    /// A ranking of K shown actions, ordered by a noiseless teacher, with the teacher's best
    /// among them: its only minimisers have the least latent loss (the best, or an action with
    /// the same features). Best of K likewise.
    #[test]
    fn a_noiseless_ranking_is_minimised_by_the_teachers_best(
        (t, mask, chosen, w) in round_parts(),
        picks in proptest::collection::vec(0usize..64, 1..MAX_RANKED),
        ordered in any::<bool>(),
    ) {
        let (l, best) = latent(&t, mask, &w);
        let allowed: Vec<ActionIndex> = mask.into_iter().collect();
        let mut shown = vec![best];
        for p in picks {
            let x = allowed[p % allowed.len()];
            if !shown.contains(&x) { shown.push(x); }
        }
        prop_assume!(shown.len() >= 2);
        shown.sort_by(|x, y| l[x.get()].total_cmp(&l[y.get()]).then(x.cmp(y)));
        prop_assume!(shown[0] == best);
        let fb = RankingFeedback::new(&shown, ordered).unwrap();
        let round = Round::new(&t, mask, a(chosen)).unwrap();
        let delta = pseudo_loss(&fb, &round).unwrap();
        prop_assert!(in_bounds(&delta, mask));
        for m in minimisers(&delta, mask) {
            prop_assert!(l[m.get()] <= l[best.get()] + 1e-3, "minimiser {m} latent {} vs best {}", l[m.get()], l[best.get()]);
        }
    }

    /// A full push (the teacher's own trajectory's features as the correction) is minimised by
    /// the teacher's best; any correction is minimised by the action nearest it.
    #[test]
    fn a_perturbation_is_minimised_by_the_action_nearest_the_correction(
        (t, mask, chosen, w) in round_parts(),
        target in proptest::array::uniform6(0.0f32..4.0),
    ) {
        let (l, best) = latent(&t, mask, &w);
        let round = Round::new(&t, mask, a(chosen)).unwrap();
        // The teacher's best's features, where they fit the wire's ranges.
        let row = t[best];
        if let Some(fb) = PerturbationFeedback::new(&row) {
            let delta = pseudo_loss(&fb, &round).unwrap();
            let corrected = fb.features().unwrap();
            for m in minimisers(&delta, mask) {
                // Rounded to thousandths on the wire: the nearest is the best or within that.
                let d: f32 = t[m].iter().zip(&corrected).map(|(x, y)| (x - y) * (x - y)).sum::<f32>().sqrt();
                prop_assert!(m == best || d < 0.01 || l[m.get()] <= 1e-3, "{m}");
            }
        }
        let fb = PerturbationFeedback::new(&target).unwrap();
        let delta = pseudo_loss(&fb, &round).unwrap();
        prop_assert!(in_bounds(&delta, mask));
        let phi = fb.features().unwrap();
        let dist = |x: ActionIndex| t[x].iter().zip(&phi).map(|(p, q)| ((p - q) as f64).powi(2)).sum::<f64>().sqrt();
        let nearest = mask.into_iter().map(dist).fold(f64::INFINITY, f64::min);
        for m in minimisers(&delta, mask) {
            prop_assert!((dist(m) - nearest).abs() < 1e-3);
        }
    }

    /// The kinds that judge the executed action only: when the teacher says "not a_t" (a_t is
    /// not its best), its best is among the minimisers, which are every other action; when it
    /// says "a_t" (a_t is its best), a_t is the only one.
    #[test]
    fn executed_action_kinds_keep_the_teachers_best_among_the_minimisers(
        (t, mask, chosen, w) in round_parts(),
        size in 1i8..=100,
    ) {
        let (l, best) = latent(&t, mask, &w);
        let round = Round::new(&t, mask, a(chosen)).unwrap();
        let wrong = l[chosen] > 0.0;
        let said: Vec<Feedback> = if wrong {
            vec![
                CorrectnessFeedback { correct: false }.into(),
                RewardFeedback { hundredths: -size }.into(),
                EStopFeedback.into(),
                SpanFeedback { ticks: 1, good: false }.into(),
            ]
        } else {
            vec![
                CorrectnessFeedback { correct: true }.into(),
                RewardFeedback { hundredths: size }.into(),
                SpanFeedback { ticks: 1, good: true }.into(),
            ]
        };
        for fb in said {
            let delta = pseudo_loss(&fb, &round).unwrap();
            prop_assert!(in_bounds(&delta, mask));
            let mins = minimisers(&delta, mask);
            if wrong {
                prop_assert!(mins.contains(&best));
                prop_assert_eq!(mins.len() as u32, mask.count() - 1);
                prop_assert!(!mins.contains(&a(chosen)));
            } else {
                prop_assert_eq!(mins, vec![a(chosen)]);
            }
        }
    }

    /// Features at the bound: every kind's pseudo-loss stays finite and within its bound.
    #[test]
    fn pseudo_losses_stay_bounded_at_the_feature_bound(
        rows in proptest::collection::vec(proptest::array::uniform6(prop_oneof![Just(-FEATURE_BOUND), Just(FEATURE_BOUND), -1.0f32..1.0]), 64),
        chosen in 0usize..64,
    ) {
        let mut t = FeatureTable::ZERO;
        for (i, r) in rows.into_iter().enumerate() { t[a(i)] = r; }
        let round = Round::new(&t, ActionMask::ALL, a(chosen)).unwrap();
        let kinds: Vec<Feedback> = vec![
            PerturbationFeedback::new(&[0.0, 10.0, 10.0, 0.0, 4.0, -10.0]).unwrap().into(),
            RankingFeedback::new(&[a(0), a(1), a(2), a(3), a(4), a(5), a(6), a(7)], true).unwrap().into(),
            RewardFeedback { hundredths: -100 }.into(),
            CorrectnessFeedback { correct: true }.into(),
            SpanFeedback { ticks: MAX_SPAN, good: false }.into(),
            EStopFeedback.into(),
        ];
        for fb in kinds {
            let delta = pseudo_loss(&fb, &round).unwrap();
            prop_assert!(in_bounds(&delta, ActionMask::ALL), "{fb:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Spans on the agent.

fn agent() -> Agent {
    Agent::new(Learner::new(LearnerParams::paper().check().unwrap()))
}

/// An observation that varies with `k`: the path reference moves, so every tick's features do.
fn obs(k: u32) -> Observation {
    let mut o = Observation::open_space();
    o.reference = PathReference {
        x: 1.0,
        y: -0.3 + 0.1 * k as f32,
        heading: 0.0,
    };
    o
}

#[test]
fn a_span_is_applied_to_each_held_tick_oldest_first_and_older_ticks_are_dropped() {
    let mut ag = agent();
    for t in 1..=6 {
        ag.act(t, &obs(t)).unwrap();
    }
    // Ticks 3..6 are held (TICK_HISTORY = 4): a span of 6 ending at 6 covers 1..6.
    assert_eq!(TICK_HISTORY, 4);
    let span = SpanFeedback {
        ticks: 6,
        good: false,
    };
    assert_eq!(ag.held_in_span(6, &span), 4);
    assert_eq!(
        ag.held_in_span(
            5,
            &SpanFeedback {
                ticks: 2,
                good: false
            }
        ),
        2
    );
    // The same as incorrect on 3, 4, 5, 6 in turn.
    let mut reference = ag.clone();
    let mut applied = 0;
    for t in 3..=6 {
        if reference
            .feedback(t, &CorrectnessFeedback { correct: false }.into())
            .unwrap()
            .stepped
        {
            applied += 1;
        }
    }
    assert!(applied > 0);
    let out = ag.feedback(6, &span.into()).unwrap();
    assert!(out.stepped);
    assert_eq!(ag.learner(), reference.learner());
    // Ending at a tick the agent never saw, but covering held ones: applied to those.
    let mut other = agent();
    for t in 1..=3 {
        other.act(t, &obs(t)).unwrap();
    }
    let late = SpanFeedback {
        ticks: 3,
        good: false,
    };
    assert!(other.feedback(4, &late.into()).is_ok());
    // Covering none: unknown tick, nothing changes.
    let before = *other.learner();
    assert_eq!(
        other.feedback(
            40,
            &SpanFeedback {
                ticks: 3,
                good: false
            }
            .into()
        ),
        Err(FeedbackError::UnknownTick(40))
    );
    assert_eq!(
        other.feedback(
            3,
            &SpanFeedback {
                ticks: 0,
                good: false
            }
            .into()
        ),
        Err(FeedbackError::Learn(LearnError::DegenerateFeedback))
    );
    assert_eq!(*other.learner(), before);
}

#[test]
fn a_span_is_all_or_nothing() {
    // A learner one step short of its step counter's end: the span's first tick is learned,
    // its second is refused (exhausted), and the agent keeps the learner it had before both.
    let mut snapshot = Learner::new(LearnerParams::paper().check().unwrap()).snapshot();
    snapshot.state.steps = u32::MAX - 1;
    let mut ag = Agent::new(Learner::restore(&snapshot).unwrap());
    for t in 1..=2 {
        ag.act(t, &obs(t)).unwrap();
    }
    let before = *ag.learner();
    let incorrect: Feedback = CorrectnessFeedback { correct: false }.into();
    // One tick alone is learned.
    let mut one = ag.clone();
    assert!(one.feedback(1, &incorrect).unwrap().stepped);
    assert_eq!(one.learner().steps(), u32::MAX);
    // Both in one span: refused, nothing learned.
    let span = SpanFeedback {
        ticks: 2,
        good: false,
    };
    assert_eq!(
        ag.feedback(2, &span.into()),
        Err(FeedbackError::Learn(LearnError::Update(
            firmware_core::UpdateError::Exhausted
        )))
    );
    assert_eq!(*ag.learner(), before);
}

// ---------------------------------------------------------------------------------------------
// The corrected trajectory's features.

fn random_obs() -> impl Strategy<Value = Observation> {
    (
        proptest::collection::vec(prop_oneof![0.3f32..3.0, Just(SCAN_MAX_RANGE)], SCAN_BEAMS),
        proptest::collection::vec(
            (0usize..3, -3.0f32..3.0, -3.0f32..3.0, 0.05f32..1.0),
            0..=MAX_OBJECTS,
        ),
        (
            -1.0f32..3.0,
            -2.0f32..2.0,
            -std::f32::consts::PI..=std::f32::consts::PI,
        ),
    )
        .prop_map(|(ranges, objects, (x, y, heading))| {
            let mut o = Observation::open_space();
            o.scan.ranges.copy_from_slice(&ranges);
            for (c, x, y, radius) in objects {
                o.objects
                    .push(SemanticObject {
                        class: SemanticClass::ALL[c],
                        x,
                        y,
                        radius,
                    })
                    .unwrap();
            }
            o.reference = PathReference { x, y, heading };
            o
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 60, ..ProptestConfig::default() })]

    /// The lattice's own trajectories, measured as deformed ones, have the evaluator's features;
    /// a deformation's features stay in the wire's ranges.
    #[test]
    fn deformed_trajectories_are_measured_like_the_lattice(o in random_obs(), from in 0usize..64, to in 0usize..64, lambda in 0.0f32..=1.0) {
        let mut table = FeatureTable::ZERO;
        let valid = o.check().unwrap();
        let mask = Evaluator::new().evaluate(valid, &mut table);
        for x in mask {
            let phi = DeformedTrajectory::of(x).features(valid);
            for (i, (p, q)) in phi.iter().zip(&table[x]).enumerate() {
                prop_assert!((p - q).abs() <= FEATURE_ERROR_BOUND, "action {x} feature {i}: {p} vs {q}");
            }
        }
        let d = DeformedTrajectory::between(a(from), a(to), lambda);
        let phi = d.features(valid);
        prop_assert!(PerturbationFeedback::new(&phi).is_some(), "{phi:?}");
    }
}

#[test]
fn a_full_push_is_the_teachers_trajectory_and_none_is_the_learners() {
    for (from, to) in [(0, 5), (3, 60), (50, 55), (10, 10)] {
        let (f, t) = (a(from), a(to));
        let same = trajectory(f).samples().len() == trajectory(t).samples().len();
        let none = DeformedTrajectory::between(f, t, 0.0);
        let full = DeformedTrajectory::between(f, t, 1.0);
        assert_eq!(none.end, trajectory(f).end());
        assert_eq!(full.end, trajectory(t).end());
        if same {
            assert_eq!(none.samples(), trajectory(f).samples());
            assert_eq!(full.samples(), trajectory(t).samples());
        } else {
            assert_eq!(full.samples().len(), 10);
        }
    }
    // A wall on the right: pushing a right turn half way to a left turn gains clearance.
    let mut o = Observation::open_space();
    for j in 0..SCAN_BEAMS {
        let (_, s) = beam_direction(j).unwrap();
        if s < -0.05 {
            o.scan.ranges[j] = (0.5 / -s).min(SCAN_MAX_RANGE);
        }
    }
    let valid = o.check().unwrap();
    let right = (0..49)
        .map(a)
        .min_by(|x, y| trajectory(*x).end().y.total_cmp(&trajectory(*y).end().y))
        .unwrap();
    let left = trajectory(right).mirror();
    let c = |l| DeformedTrajectory::between(right, left, l).features(valid)[0];
    assert!(c(0.0) < c(0.5) && c(0.5) <= c(1.0) + 1e-4);
}
