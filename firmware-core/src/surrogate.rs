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

use crate::action::{ActionIndex, MAX_ACTIONS};
use crate::feature::{FEATURE_COUNT, Features, Weights, dot};
use crate::feedback::{PseudoLoss, Round};

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
    target_of(&scores(w, round), round, delta)
}

/// The score `w · φ(a)` of every action (forbidden ones too, never read): one pass without a
/// branch, shared by the target and the hinge.
fn scores(w: &Weights, round: &Round<'_>) -> [f32; MAX_ACTIONS] {
    let mut out = [0.0f32; MAX_ACTIONS];
    for (s, row) in out.iter_mut().zip(round.features().rows()) {
        *s = dot(w, row);
    }
    out
}

/// [`target`] from the scores: the same comparisons in the same order.
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
pub fn generalized_hinge(w: &Weights, round: &Round<'_>, delta: &PseudoLoss) -> SurrogateEval {
    let scores = scores(w, round);
    let hat = target_of(&scores, round, delta);
    let s_hat = scores[hat.get()];
    // The target's own term is Δ_â + 0 = 0: start there so that ties keep the zero subgradient.
    let mut sel = hat;
    let mut value = delta[hat];
    for a in round.allowed() {
        let v = delta[a] + (scores[a.get()] - s_hat);
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
