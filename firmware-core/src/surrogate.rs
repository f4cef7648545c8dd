//! Convex surrogates of a pseudo-loss, their values and subgradients.
//!
//! # Sign convention
//!
//! The policy *maximises* `w · φ`; the surrogates are losses to *minimise* in `w`. With
//! `s_i = w · φ_i` (computed by [`crate::dot`]) and `â` the target action (below):
//!
//! * **Generalized hinge** (paper eq. for `ℓ(w)`, DESIGN section 4):
//!   `ℓ(w) = max over allowed i of [Δ_i + (s_i − s_â)] ≥ Δ(a_t) ≥ 0`.
//!   Its subgradient is `g = φ_sel − φ_â`, with `a_sel` the maximiser, and online gradient
//!   descent steps `w ← w − η g = w + η (φ_â − φ_sel)`. The paper writes the bracket with the
//!   opposite sign because its policy is an argmin; this is the same rule.
//! * **Perceptron** (Coactive learning, paper section 5.2):
//!   `ℓ(w) = s_{a_t} − s_â`, subgradient `φ_{a_t} − φ_â`: the preference perceptron's update.
//!
//! # The target action `â`
//!
//! `â = argmin Δ`. When several actions share the minimum (the semantic pseudo-loss is flat on
//! purpose), `â` is the one the current weights score highest, lowest index on ties: the
//! minimiser that makes the surrogate smallest. A pseudo-loss that is flat everywhere therefore
//! gives `â = a_t`, a zero surrogate and no update.
//!
//! The maximiser `a_sel` prefers `â` on ties (a zero subgradient is a valid one), then the
//! lowest index.
//!
//! ```
//! use firmware_core::{surrogate, ActionFeedback, ActionIndex, ActionMask, FeatureTable, Round, pseudo_loss};
//!
//! let mut table = FeatureTable::ZERO;
//! let (a0, a1) = (ActionIndex::new(0).unwrap(), ActionIndex::new(1).unwrap());
//! table[a0] = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
//! table[a1] = [0.0, 1.0, 0.0, 0.0, 0.0, 0.0];
//! let mask: ActionMask = [a0, a1].into_iter().collect();
//! let w = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
//! let round = Round::new(&table, mask, a0).unwrap();
//! let delta = pseudo_loss(&ActionFeedback { action: a1 }, &round).unwrap();
//! let eval = surrogate::generalized_hinge(&w, &round, &delta);
//! // ℓ = max(Δ_0 + s_0 − s_1, Δ_1 + s_1 − s_1) = max(100 + 1 − 0, 0) = 101
//! assert_eq!(eval.value, 101.0);
//! assert_eq!(eval.maximiser, a0);
//! assert_eq!(eval.subgradient, [1.0, -1.0, 0.0, 0.0, 0.0, 0.0]);
//! ```

use serde::{Deserialize, Serialize};

use crate::action::{ActionIndex, ActionMask, MAX_ACTIONS};
use crate::feature::{FEATURE_COUNT, Features, Weights, column_dot, dot};
use crate::feedback::{PseudoLoss, Round};
use crate::policy;

/// Which convex surrogate a learner minimises.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub enum Surrogate {
    /// The generalized hinge of the paper's section 5.1.
    GeneralizedHinge,
    /// The perceptron loss of Coactive learning (section 5.2).
    Perceptron,
}

/// A surrogate evaluated at some weights.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct SurrogateEval {
    /// `ℓ(w)`, at least 0.
    pub value: f32,
    /// `â`, the action the pseudo-loss points to.
    pub target: ActionIndex,
    /// The action whose term attains the maximum (`a_sel`; the learner's choice for the
    /// perceptron).
    pub maximiser: ActionIndex,
    /// A subgradient of `ℓ` at `w`: `φ_maximiser − φ_target`.
    pub subgradient: Features,
}

impl SurrogateEval {
    /// Whether the subgradient is zero (nothing to learn from this feedback at these weights).
    pub fn is_flat(&self) -> bool {
        self.maximiser == self.target
    }
}

/// `â`: the minimiser of `Δ` over the allowed actions, ties to the highest score then the lowest
/// index.
pub fn target(w: &Weights, round: &Round<'_>, delta: &PseudoLoss) -> ActionIndex {
    let zeros = delta.zeros() & round.allowed().bits();
    if zeros != 0 {
        // The minimum is 0 (always, for a pseudo-loss of this round): `â` is the best scored of
        // the zeros, without a score anywhere else; alone, without a score at all.
        let table = round.features();
        return best_among(ActionMask::from_bits(zeros), |a| dot(w, &table[a]));
    }
    match round.scores_at(w) {
        Some(scores) => target_of(scores, round, delta),
        None => target_of(&scores(w, round), round, delta),
    }
}

/// The action of highest score among `among` (not empty), lowest index on ties: `target_of`'s
/// comparisons over the actions whose `Δ` is the minimum. A single action is not scored.
#[inline(always)]
fn best_among(among: ActionMask, score: impl Fn(ActionIndex) -> f32) -> ActionIndex {
    let mut it = among.iter();
    let Some(first) = it.next() else {
        return ActionIndex::FIRST;
    };
    if it.len() == 0 {
        return first;
    }
    let (mut best, mut best_score) = (first, score(first));
    for a in it {
        let s = score(a);
        if s > best_score {
            best = a;
            best_score = s;
        }
    }
    best
}

/// The score `w · φ(a)` of every allowed action (forbidden ones are never read): every action's
/// in one pass on a `policy::WIDE` target, else the allowed actions' one by one.
fn scores(w: &Weights, round: &Round<'_>) -> [f32; MAX_ACTIONS] {
    if policy::WIDE {
        return policy::all_scores(w, round.features());
    }
    let mut out = [0.0f32; MAX_ACTIONS];
    policy::scores(w, round.features(), round.allowed(), &mut out);
    out
}

/// [`target`] from the scores, for any `Δ`: the minimum of `Δ` first, then the highest score.
fn target_of(scores: &[f32; MAX_ACTIONS], round: &Round<'_>, delta: &PseudoLoss) -> ActionIndex {
    let mut best = round.chosen();
    let mut best_delta = f32::INFINITY;
    let mut best_score = f32::NEG_INFINITY;
    for a in round.allowed() {
        let (d, s) = (delta[a], scores[a.get()]);
        if d <= best_delta && (d < best_delta || s > best_score) {
            best = a;
            best_delta = d;
            best_score = s;
        }
    }
    best
}

fn difference(a: &Features, b: &Features) -> Features {
    let mut g = [0.0f32; FEATURE_COUNT];
    for i in 0..FEATURE_COUNT {
        g[i] = a[i] - b[i];
    }
    g
}

/// The generalized hinge `max_i [Δ_i + (s_i − s_â)]` and its subgradient at `w`.
///
/// One pass of scores over the allowed actions, none when the round carries its scores at `w`
/// ([`Round::with_scores`]: select's, for feedback linearized at the weights that chose). On a
/// `policy::WIDE` target the pass scores every action, then the terms of all of them side by
/// side give the maximum. On the car, when a single action holds the minimum of `Δ` (action
/// feedback always, most others) `â` is known before any score and each score is used where it
/// is computed; otherwise `â` is the best scored of the minimum's actions, read from the pass.
pub fn generalized_hinge(w: &Weights, round: &Round<'_>, delta: &PseudoLoss) -> SurrogateEval {
    let zeros = ActionMask::from_bits(delta.zeros() & round.allowed().bits());
    let table = round.features();
    let (hat, value, sel) = match round.scores_at(w) {
        Some(scores) => hinge_of(scores, round, delta),
        None if policy::WIDE => {
            let mut it = zeros.iter();
            match (it.next(), it.len()) {
                // `â` known before any score (action feedback always): each action's term as
                // its score is computed, no array of scores.
                (Some(hat), 0) => {
                    let s_hat = dot(w, &table[hat]);
                    match table.columns() {
                        Some(columns) => {
                            hinge_terms(hat, s_hat, round, delta, |i| column_dot(w, columns, i))
                        }
                        None => {
                            let rows = table.rows();
                            hinge_terms(hat, s_hat, round, delta, |i| dot(w, &rows[i]))
                        }
                    }
                }
                _ => hinge_of(&policy::all_scores(w, table), round, delta),
            }
        }
        None => {
            let mut it = zeros.iter();
            match (it.next(), it.len()) {
                (Some(hat), 0) => hinge_one_by_one(hat, dot(w, &table[hat]), round, delta, |a| {
                    dot(w, &table[a])
                }),
                _ => {
                    let scores = scores(w, round);
                    let hat = target_scored(&scores, zeros, round, delta);
                    hinge_one_by_one(hat, scores[hat.get()], round, delta, |a| scores[a.get()])
                }
            }
        }
    };
    SurrogateEval {
        value,
        target: hat,
        maximiser: sel,
        subgradient: difference(round.phi(sel), round.phi(hat)),
    }
}

/// `â` from every allowed action's score, `zeros` the allowed ones where `Δ` is 0.
#[inline(always)]
fn target_scored(
    scores: &[f32; MAX_ACTIONS],
    zeros: ActionMask,
    round: &Round<'_>,
    delta: &PseudoLoss,
) -> ActionIndex {
    match zeros.first() {
        Some(_) => best_among(zeros, |a| scores[a.get()]),
        None => target_of(scores, round, delta),
    }
}

/// `â`, the hinge's maximum and its maximiser from every allowed action's score: the terms
/// `Δ_a + (s_a − s_â)` of all 64 actions side by side, then [`policy::first_max`] of the allowed
/// ones. The target's own term is `Δ_â + 0 = Δ_â`, where the running maximum of
/// [`hinge_one_by_one`] starts: the maximiser is the first allowed action whose term exceeds it
/// (a NaN term never does), else `â` (ties keep the zero subgradient).
#[inline(always)]
fn hinge_of(
    scores: &[f32; MAX_ACTIONS],
    round: &Round<'_>,
    delta: &PseudoLoss,
) -> (ActionIndex, f32, ActionIndex) {
    let zeros = ActionMask::from_bits(delta.zeros() & round.allowed().bits());
    let hat = target_scored(scores, zeros, round, delta);
    hinge_terms(hat, scores[hat.get()], round, delta, |i| scores[i])
}

/// [`hinge_of`] given `â`, its score and every action's (`score(i)`, the same bits as
/// `dot(w, φ_i)`): the terms side by side, then their first maximum.
#[inline(always)]
fn hinge_terms(
    hat: ActionIndex,
    s_hat: f32,
    round: &Round<'_>,
    delta: &PseudoLoss,
    score: impl Fn(usize) -> f32,
) -> (ActionIndex, f32, ActionIndex) {
    let values = delta.values();
    let mut terms = [0.0f32; MAX_ACTIONS];
    for i in 0..MAX_ACTIONS {
        terms[i] = values[i] + (score(i) - s_hat);
    }
    let start = delta[hat];
    match policy::first_max(&terms, round.allowed()).0 {
        Some((sel, value)) if value > start => (hat, value, sel),
        _ => (hat, start, hat),
    }
}

/// The hinge's maximum and maximiser given `â`, its score and every allowed action's, one action
/// at a time.
#[inline(always)]
fn hinge_one_by_one(
    hat: ActionIndex,
    s_hat: f32,
    round: &Round<'_>,
    delta: &PseudoLoss,
    score: impl Fn(ActionIndex) -> f32,
) -> (ActionIndex, f32, ActionIndex) {
    // The target's own term is Δ_â + 0 = 0: start there so that ties keep the zero subgradient
    // (the term of `â` in the loop, Δ_â + (s_â − s_â) = Δ_â, never exceeds the running value,
    // which starts at Δ_â and only grows: no test of `a ≠ â`).
    let mut sel = hat;
    let mut value = delta[hat];
    for a in round.allowed() {
        let v = delta[a] + (score(a) - s_hat);
        if v > value {
            value = v;
            sel = a;
        }
    }
    (hat, value, sel)
}

/// The perceptron loss `s_{a_t} − s_â` (never below 0 since `a_t` is the argmax) and its
/// subgradient `φ_{a_t} − φ_â`.
pub fn perceptron(w: &Weights, round: &Round<'_>, delta: &PseudoLoss) -> SurrogateEval {
    let hat = target(w, round, delta);
    let chosen = round.chosen();
    let value = dot(w, round.phi(chosen)) - dot(w, round.phi(hat));
    SurrogateEval {
        value: if value > 0.0 { value } else { 0.0 },
        target: hat,
        maximiser: chosen,
        subgradient: difference(round.phi(chosen), round.phi(hat)),
    }
}

/// Evaluates `kind` at `w`.
pub fn evaluate(
    kind: Surrogate,
    w: &Weights,
    round: &Round<'_>,
    delta: &PseudoLoss,
) -> SurrogateEval {
    match kind {
        Surrogate::GeneralizedHinge => generalized_hinge(w, round, delta),
        Surrogate::Perceptron => perceptron(w, round, delta),
    }
}
