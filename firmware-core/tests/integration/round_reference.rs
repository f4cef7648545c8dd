//! The learner's round bit for bit as its first, straightforward code (kept here as the
//! reference): the pseudo-loss's check and shift, the semantic pseudo-loss, the target `â` and both
//! surrogates, on random rounds built to tie (features and weights on a coarse grid, few allowed
//! actions or all of them, every kind of feedback). Every `f32` is compared by its bits. Each
//! round is played on its table as written (the rows) and on the same table sealed
//! (`FeatureTable::seal`: on a host its columns, which the passes then read).

use firmware_core::evaluator::cross_track_errors;
use firmware_core::feedback::{PseudoLoss, PseudoLossSource};
use firmware_core::observation::PathReference;
use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, CorrectnessFeedback, EStopFeedback, FEATURE_COUNT,
    Feature, FeatureTable, Feedback, MAX_ACTIONS, PSEUDO_LOSS_BOUND, PreferenceFeedback,
    RankingFeedback, RewardFeedback, Round, SEMANTIC_LOSS, SemanticFeedback, SurrogateEval, dot,
    policy, pseudo_loss, surrogate,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The check and shift as first written: one running minimum in index order.
fn reference_shift(raw: &[f32; MAX_ACTIONS], allowed: ActionMask) -> Option<[f32; MAX_ACTIONS]> {
    let bits = allowed.bits();
    let (mut good, mut min) = (true, f32::INFINITY);
    for (i, &v) in raw.iter().enumerate() {
        let here = bits >> i & 1 == 1;
        good &= !here | (v.abs() <= PSEUDO_LOSS_BOUND);
        min = if here && v < min { v } else { min };
    }
    if !good || allowed.is_empty() {
        return None;
    }
    let mut out = *raw;
    for (i, v) in out.iter_mut().enumerate() {
        *v = if bits >> i & 1 == 1 { *v - min } else { 0.0 };
    }
    Some(out)
}

/// The semantic pseudo-loss as first written: `SEMANTIC_LOSS` added per failed statement.
fn reference_semantic(said: &SemanticFeedback, round: &Round<'_>) -> [f32; MAX_ACTIONS] {
    let cross = round.reference().map(cross_track_errors);
    let mut out = [0.0f32; MAX_ACTIONS];
    for s in said.statements() {
        let f = s.subject.index();
        let quantity = |a: ActionIndex| match (&cross, s.subject) {
            (Some(cross), Feature::Path) => cross[a.get()],
            _ => round.phi(a)[f],
        };
        let reference = quantity(round.chosen());
        let higher = s.wants_higher();
        for a in round.allowed() {
            let v = quantity(a);
            let better = if higher { v > reference } else { v < reference };
            if !better {
                out[a.get()] += SEMANTIC_LOSS;
            }
        }
    }
    out
}

/// The preference pseudo-loss as first written: `‖φ_p − φ_a‖ − ‖φ_np − φ_a‖` over the allowed
/// actions, each distance summed from index 0 (`f32::sqrt`: the bits of `libm::sqrtf`).
fn reference_preference(said: &PreferenceFeedback, round: &Round<'_>) -> [f32; MAX_ACTIONS] {
    let distance = |x: &[f32; FEATURE_COUNT], y: &[f32; FEATURE_COUNT]| {
        let mut s = 0.0f32;
        for i in 0..FEATURE_COUNT {
            let d = x[i] - y[i];
            s += d * d;
        }
        s.sqrt()
    };
    let (p, np) = (round.phi(said.preferred), round.phi(said.other));
    let mut out = [0.0f32; MAX_ACTIONS];
    for a in round.allowed() {
        let phi = round.phi(a);
        out[a.get()] = distance(p, phi) - distance(np, phi);
    }
    out
}

fn reference_scores(w: &[f32; FEATURE_COUNT], round: &Round<'_>) -> [f32; MAX_ACTIONS] {
    let mut out = [0.0f32; MAX_ACTIONS];
    for (s, row) in out.iter_mut().zip(round.features().rows()) {
        *s = dot(w, row);
    }
    out
}

fn reference_target(
    scores: &[f32; MAX_ACTIONS],
    round: &Round<'_>,
    delta: &[f32; MAX_ACTIONS],
) -> ActionIndex {
    let mut best = round.chosen();
    let mut best_delta = f32::INFINITY;
    let mut best_score = f32::NEG_INFINITY;
    for a in round.allowed() {
        let (d, s) = (delta[a.get()], scores[a.get()]);
        if d <= best_delta && (d < best_delta || s > best_score) {
            best = a;
            best_delta = d;
            best_score = s;
        }
    }
    best
}

fn difference(x: &[f32; FEATURE_COUNT], y: &[f32; FEATURE_COUNT]) -> [f32; FEATURE_COUNT] {
    core::array::from_fn(|i| x[i] - y[i])
}

fn reference_hinge(
    w: &[f32; FEATURE_COUNT],
    round: &Round<'_>,
    delta: &[f32; MAX_ACTIONS],
) -> SurrogateEval {
    let scores = reference_scores(w, round);
    let hat = reference_target(&scores, round, delta);
    let s_hat = scores[hat.get()];
    let mut sel = hat;
    let mut value = delta[hat.get()];
    for a in round.allowed() {
        let v = delta[a.get()] + (scores[a.get()] - s_hat);
        if a != hat && v > value {
            value = v;
            sel = a;
        }
    }
    SurrogateEval {
        value,
        target: hat,
        maximiser: sel,
        subgradient: difference(round.phi(sel), round.phi(hat)),
    }
}

fn reference_perceptron(
    w: &[f32; FEATURE_COUNT],
    round: &Round<'_>,
    delta: &[f32; MAX_ACTIONS],
) -> SurrogateEval {
    let hat = reference_target(&reference_scores(w, round), round, delta);
    let chosen = round.chosen();
    let value = dot(w, round.phi(chosen)) - dot(w, round.phi(hat));
    SurrogateEval {
        value: if value > 0.0 { value } else { 0.0 },
        target: hat,
        maximiser: chosen,
        subgradient: difference(round.phi(chosen), round.phi(hat)),
    }
}

fn bits<const N: usize>(v: &[f32; N]) -> [u32; N] {
    v.map(f32::to_bits)
}

fn same(x: &SurrogateEval, y: &SurrogateEval) -> bool {
    x.value.to_bits() == y.value.to_bits()
        && x.target == y.target
        && x.maximiser == y.maximiser
        && bits(&x.subgradient) == bits(&y.subgradient)
}

/// A value on a coarse grid (ties between actions are common), sometimes −0.
fn grid(rng: &mut ChaCha8Rng) -> f32 {
    match rng.random_range(0..16u32) {
        0 => -0.0,
        1 => 0.0,
        _ => rng.random_range(-4i32..=4) as f32 * 0.5,
    }
}

/// A table of [`grid`] values (written through `rows_mut`: not sealed).
fn grid_table(rng: &mut ChaCha8Rng) -> FeatureTable {
    let mut table = FeatureTable::ZERO;
    for row in table.rows_mut() {
        for x in row.iter_mut() {
            *x = grid(rng);
        }
    }
    assert!(!table.is_sealed());
    table
}

/// `table` as written and sealed: on a host the second one's passes read its columns, the
/// first one's its rows (on a target without the columns, the same table twice).
fn both(table: FeatureTable) -> [FeatureTable; 2] {
    let mut sealed = table.clone();
    sealed.seal();
    assert_eq!(sealed.is_sealed(), !cfg!(target_arch = "arm"));
    let bits = |t: &FeatureTable| t.rows().map(|row| row.map(f32::to_bits));
    assert_eq!(bits(&sealed), bits(&table));
    [table, sealed]
}

fn random_mask(rng: &mut ChaCha8Rng) -> ActionMask {
    let bits = match rng.random_range(0..4u32) {
        0 => u64::MAX,
        1 => 1u64 << rng.random_range(0..64u32),
        _ => rng.random::<u64>() & rng.random::<u64>(),
    };
    if bits == 0 {
        ActionMask::ALL
    } else {
        ActionMask::from_bits(bits)
    }
}

fn pick(rng: &mut ChaCha8Rng, mask: ActionMask) -> ActionIndex {
    let n = mask.iter().len();
    mask.iter().nth(rng.random_range(0..n)).unwrap()
}

fn random_feedback(rng: &mut ChaCha8Rng, mask: ActionMask) -> Feedback {
    match rng.random_range(0..7u32) {
        0 => ActionFeedback {
            action: pick(rng, mask),
        }
        .into(),
        1 => PreferenceFeedback {
            preferred: pick(rng, mask),
            other: pick(rng, mask),
        }
        .into(),
        2 => {
            let mut said = SemanticFeedback::new();
            for f in Feature::ALL {
                match rng.random_range(0..3u32) {
                    0 => said = said.avoid(f),
                    1 => said = said.prefer(f),
                    _ => {}
                }
            }
            said.into()
        }
        3 => RewardFeedback::new(rng.random_range(-4i32..=4) as f32 * 0.25)
            .map_or(EStopFeedback.into(), Feedback::from),
        4 => CorrectnessFeedback {
            correct: rng.random(),
        }
        .into(),
        5 => {
            let shown: Vec<ActionIndex> = (0..3).map(|_| pick(rng, mask)).collect();
            RankingFeedback::new(&shown, rng.random()).map_or(EStopFeedback.into(), Feedback::from)
        }
        _ => EStopFeedback.into(),
    }
}

#[test]
fn the_round_is_bit_for_bit_its_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let (mut checked, mut refused) = (0, 0);
    for _ in 0..40_000 {
        let tables = both(grid_table(&mut rng));
        let mask = random_mask(&mut rng);
        let chosen = pick(&mut rng, mask);
        let w: [f32; FEATURE_COUNT] = core::array::from_fn(|_| grid(&mut rng));
        let reference = PathReference {
            x: grid(&mut rng),
            y: grid(&mut rng),
            heading: rng.random_range(-3.0f32..3.0),
        };
        let fb = random_feedback(&mut rng, mask);
        for table in &tables {
            let round = Round::new(table, mask, chosen)
                .unwrap()
                .with_reference(reference)
                .unwrap();
            let got = pseudo_loss(&fb, &round);
            let mut raw = [0.0f32; MAX_ACTIONS];
            let written = match &fb {
                Feedback::Semantic(said) if !said.is_empty() => {
                    raw = reference_semantic(said, &round);
                    Ok(())
                }
                Feedback::Preference(said) if said.preferred != said.other => {
                    raw = reference_preference(said, &round);
                    Ok(())
                }
                _ => fb.write_pseudo_loss(&round, &mut raw),
            };
            let delta = match (written, got) {
                (Err(e), Err(f)) => {
                    assert_eq!(e, f);
                    refused += 1;
                    continue;
                }
                (Ok(()), Ok(delta)) => delta,
                (w, g) => panic!("{fb:?}: reference {w:?}, got {g:?}"),
            };
            let expected = reference_shift(&raw, mask).expect("a valid pseudo-loss");
            assert_eq!(bits(delta.values()), bits(&expected), "{fb:?}");
            assert!(
                same(
                    &surrogate::generalized_hinge(&w, &round, &delta),
                    &reference_hinge(&w, &round, &expected)
                ),
                "{fb:?} {mask:?} {w:?}"
            );
            assert!(
                same(
                    &surrogate::perceptron(&w, &round, &delta),
                    &reference_perceptron(&w, &round, &expected)
                ),
                "{fb:?}"
            );
            checked += 1;
        }
    }
    assert!(checked > 60_000, "{checked} checked, {refused} refused");
}

/// A pseudo-loss judged against a round of other allowed actions (`learn_from_loss` takes any):
/// its minimum over them need not be 0, and the target falls back to the full comparison.
#[test]
fn a_pseudo_loss_of_another_round_finds_the_same_target() {
    let mut rng = ChaCha8Rng::seed_from_u64(18);
    for _ in 0..5_000 {
        let tables = both(grid_table(&mut rng));
        let (m1, m2) = (random_mask(&mut rng), random_mask(&mut rng));
        let w: [f32; FEATURE_COUNT] = core::array::from_fn(|_| grid(&mut rng));
        let (c1, c2) = (pick(&mut rng, m1), pick(&mut rng, m2));
        let fb = random_feedback(&mut rng, m1);
        for table in &tables {
            let first = Round::new(table, m1, c1).unwrap();
            let Ok(delta) = pseudo_loss(&fb, &first) else {
                continue;
            };
            let other = Round::new(table, m2, c2).unwrap();
            assert!(same(
                &surrogate::generalized_hinge(&w, &other, &delta),
                &reference_hinge(&w, &other, delta.values())
            ));
            assert_eq!(
                surrogate::target(&w, &other, &delta),
                reference_target(&reference_scores(&w, &other), &other, delta.values())
            );
        }
    }
}

/// The check and shift of raw values with zeros of both signs, ties and out-of-bound entries,
/// against the single running minimum.
#[test]
fn the_shift_is_bit_for_bit_its_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(19);
    for _ in 0..20_000 {
        let mask = random_mask(&mut rng);
        let raw: [f32; MAX_ACTIONS] = core::array::from_fn(|_| match rng.random_range(0..40u32) {
            0 => f32::NAN,
            1 => 2.0 * PSEUDO_LOSS_BOUND,
            _ => grid(&mut rng),
        });
        let got = PseudoLoss::from_raw(raw, mask);
        match reference_shift(&raw, mask) {
            Some(expected) => {
                let got = got.expect("accepted by the reference");
                assert_eq!(bits(got.values()), bits(&expected), "{raw:?}");
                let zeros = (0..MAX_ACTIONS)
                    .filter(|&i| expected[i] == 0.0)
                    .fold(0u64, |z, i| z | 1 << i);
                assert_eq!(got.zeros(), zeros);
            }
            None => assert!(got.is_err()),
        }
    }
}

/// The shift with every action allowed (on a host its own second pass, `subtract_all`), on raw
/// values that are nearly always accepted and tie often, the minimum often a zero of either sign:
/// the same values and zero bits as the reference.
#[test]
fn the_shift_of_every_action_is_bit_for_bit_its_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    for case in 0..20_000 {
        let raw: [f32; MAX_ACTIONS] = core::array::from_fn(|_| match case % 4 {
            // Zeros of both signs and a few values above them.
            0 => [-0.0, 0.0, 0.5, 1.0][rng.random_range(0..4usize)],
            1 => grid(&mut rng),
            2 => rng.random_range(-3i32..=3) as f32 * 0.25,
            _ => match rng.random_range(0..2000u32) {
                0 => f32::NAN,
                1 => -2.0 * PSEUDO_LOSS_BOUND,
                _ => grid(&mut rng),
            },
        });
        let got = PseudoLoss::from_raw(raw, ActionMask::ALL);
        match reference_shift(&raw, ActionMask::ALL) {
            Some(expected) => {
                let got = got.expect("accepted by the reference");
                assert_eq!(bits(got.values()), bits(&expected), "{raw:?}");
                let zeros = (0..MAX_ACTIONS)
                    .filter(|&i| expected[i] == 0.0)
                    .fold(0u64, |z, i| z | 1 << i);
                assert_eq!(got.zeros(), zeros, "{raw:?}");
            }
            None => assert!(got.is_err()),
        }
    }
}

/// `policy::select` as first written: every allowed score in index order, the first taken and
/// each later one that is not at most the best so far.
fn reference_select(
    w: &[f32; FEATURE_COUNT],
    table: &FeatureTable,
    mask: ActionMask,
) -> Option<ActionIndex> {
    let mut best: Option<(ActionIndex, f32)> = None;
    for a in mask {
        let s = dot(w, &table[a]);
        match best {
            Some((_, b)) if s <= b => {}
            _ => best = Some((a, s)),
        }
    }
    best.map(|(a, _)| a)
}

/// Select, with and without keeping its scores, chooses as the reference does, on tables built
/// to tie, with NaNs and infinities in some rows (allowed or not) and in some weights; the scores
/// it keeps are the allowed actions' `dot`s, bit for bit.
#[test]
fn select_is_bit_for_bit_its_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(20);
    for _ in 0..20_000 {
        let mut table = FeatureTable::ZERO;
        for row in table.rows_mut() {
            for x in row.iter_mut() {
                *x = match rng.random_range(0..200u32) {
                    0 => f32::NAN,
                    1 => f32::INFINITY,
                    2 => f32::NEG_INFINITY,
                    _ => grid(&mut rng),
                };
            }
        }
        let mask = match rng.random_range(0..8u32) {
            0 => ActionMask::NONE,
            _ => random_mask(&mut rng),
        };
        let mut w: [f32; FEATURE_COUNT] = core::array::from_fn(|_| grid(&mut rng));
        if rng.random_range(0..50u32) == 0 {
            w[rng.random_range(0..FEATURE_COUNT)] = f32::NAN;
        }
        let expected = reference_select(&w, &table, mask);
        for table in &both(table) {
            assert_eq!(policy::select(&w, table, mask), expected);
            let mut scores = [0.0f32; MAX_ACTIONS];
            assert_eq!(
                policy::select_scored(&w, table, mask, &mut scores),
                expected
            );
            for a in mask {
                assert!(
                    same_score(scores[a.get()], dot(&w, &table[a])),
                    "{a}: {} against {}",
                    scores[a.get()],
                    dot(&w, &table[a])
                );
            }
        }
    }
}

/// The same bits, or both NaN: which NaN an operation on a NaN or an infinity gives (its sign)
/// depends on the order of a commutative operation's operands, which the optimiser may swap
/// (`cargo test --release` gave 0x7fc00000 against 0xffc00000), and no comparison, so no choice,
/// tells NaNs apart.
fn same_score(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

/// A round carrying select's scores evaluates both surrogates as the reference does at the
/// weights the scores are of, and ignores them at any other weights (the raw iterate, for action
/// feedback).
#[test]
fn a_round_with_its_scores_is_bit_for_bit_its_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let mut checked = 0;
    for _ in 0..20_000 {
        let tables = both(grid_table(&mut rng));
        let mask = random_mask(&mut rng);
        let w: [f32; FEATURE_COUNT] = core::array::from_fn(|_| grid(&mut rng));
        let other: [f32; FEATURE_COUNT] = core::array::from_fn(|_| grid(&mut rng));
        let fb = random_feedback(&mut rng, mask);
        for table in &tables {
            let mut scores = [0.0f32; MAX_ACTIONS];
            let chosen = policy::select_scored(&w, table, mask, &mut scores).unwrap();
            let round = Round::new(table, mask, chosen)
                .unwrap()
                .with_scores(&w, &scores);
            let Ok(delta) = pseudo_loss(&fb, &round) else {
                continue;
            };
            for at in [w, other] {
                assert!(same(
                    &surrogate::generalized_hinge(&at, &round, &delta),
                    &reference_hinge(&at, &round, delta.values())
                ));
                assert!(same(
                    &surrogate::perceptron(&at, &round, &delta),
                    &reference_perceptron(&at, &round, delta.values())
                ));
            }
            checked += 1;
        }
    }
    assert!(checked > 20_000, "{checked} checked");
}
