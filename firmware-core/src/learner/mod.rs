//! Online learners behind one trait, and the learning step that feeds them.
//!
//! A learning step is: feedback → [`pseudo_loss`] → surrogate at the learner's
//! [`OnlineLearner::linearization_point`] → [`OnlineLearner::step`] along the subgradient.
//! [`learn`] does all of it and changes nothing when any part is refused.
//!
//! | type | rule (`g` = surrogate subgradient) |
//! |---|---|
//! | [`Ogd`] | `w ← Π(w − η_t g)`, `η_t = η` or `η/√t` |
//! | [`AveragedOgd`] | constant-step OGD; the policy uses `w̄ = mean(w_0 … w_t)` |
//! | [`AdaGrad`] | `G ← G + g²`, `w ← Π(w − η g / (√G + ε))` per feature |
//! | [`Coactive`] | `w ← Π(w − η g)` on the perceptron surrogate (`η = 1`: the preference perceptron) |
//!
//! `Π` is the optional projection onto the L2 ball of [`LearnerParams::radius`]. [`Learner`]
//! holds any of them, chosen at run time from [`LearnerParams`], and is what the agent keeps.
//!
//! Every step is checked before it is committed: a non-finite or oversized subgradient, or a
//! result beyond [`WEIGHT_BOUND`], is refused with an [`UpdateError`] and the learner keeps its
//! previous state, so its weights are always finite.
//!
//! ```
//! use firmware_core::{learn, ActionFeedback, ActionIndex, ActionMask, FeatureTable, Learner,
//!                     LearnerParams, OnlineLearner, Round};
//!
//! let mut table = FeatureTable::ZERO;
//! let (a, b) = (ActionIndex::new(0).unwrap(), ActionIndex::new(1).unwrap());
//! table[b][3] = 1.0;
//! let mut learner = Learner::new(LearnerParams::paper().check().unwrap());
//! let chosen = learner.select(&table, ActionMask::ALL).unwrap();
//! assert_eq!(chosen, a); // zero weights: all tie, lowest index
//! let round = Round::new(&table, ActionMask::ALL, chosen).unwrap();
//! learn(&mut learner, &round, &ActionFeedback { action: b }).unwrap();
//! assert_eq!(learner.select(&table, ActionMask::ALL), Some(b));
//! ```

mod params;
mod snapshot;

pub use params::{LearnerKind, LearnerParams, MAX_STEP, PAPER_STEP, ValidLearnerParams};
pub use snapshot::{LearnerSnapshot, LearnerState, SNAPSHOT_VERSION};

use crate::action::{ActionIndex, ActionMask};
use crate::error::{LearnError, UpdateError};
use crate::feature::{
    FEATURE_BOUND, FEATURE_COUNT, FeatureTable, Features, WEIGHT_BOUND, Weights, ieee_sqrt, within,
};
use crate::feedback::{PseudoLoss, PseudoLossSource, Round, pseudo_loss};
use crate::surrogate::{self, Surrogate, SurrogateEval};

/// Largest magnitude of a subgradient entry a learner accepts: the largest difference of two
/// in-bound features.
pub const GRADIENT_BOUND: f32 = 2.0 * FEATURE_BOUND;

/// `ε` of [`AdaGrad`]'s denominator.
pub const ADAGRAD_EPSILON: f32 = 1.0e-6;

/// An online learner of linear policy weights.
///
/// Implementors provide the state and the step rule; [`learn`] provides the rest.
pub trait OnlineLearner {
    /// The weights the policy acts with.
    fn weights(&self) -> &Weights;

    /// The weights at which the surrogate's subgradient is taken; by default the acting weights,
    /// so the learner is corrected for what it did.
    fn linearization_point(&self, delta: &PseudoLoss) -> &Weights {
        let _ = delta;
        self.weights()
    }

    /// The surrogate this learner minimises.
    fn surrogate(&self) -> Surrogate {
        Surrogate::GeneralizedHinge
    }

    /// One step against the subgradient `g` (minimisation convention). On `Err` nothing changed.
    fn step(&mut self, g: &Features) -> Result<(), UpdateError>;

    /// Number of steps taken.
    fn steps(&self) -> u32;

    /// The policy's action for a tick's features: `argmax` of `weights() · φ` over `allowed`.
    fn select(&self, table: &FeatureTable, allowed: ActionMask) -> Option<ActionIndex> {
        crate::policy::select(self.weights(), table, allowed)
    }
}

/// What one call to [`learn`] did.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Outcome {
    /// The surrogate at the linearization point, before the step.
    pub eval: SurrogateEval,
    /// Whether a step was taken (false when the subgradient was zero).
    pub stepped: bool,
}

/// Learns from one feedback about `round`: builds the pseudo-loss, evaluates the learner's
/// surrogate and steps along its subgradient. A zero subgradient takes no step.
///
/// On `Err` the learner is unchanged.
pub fn learn<L, S>(learner: &mut L, round: &Round<'_>, feedback: &S) -> Result<Outcome, LearnError>
where
    L: OnlineLearner + ?Sized,
    S: PseudoLossSource + ?Sized,
{
    if crate::policy::WIDE {
        // The pseudo-loss read where the call left it, inside its `Result`: not moved out of it
        // first (the compiler copied its 264 bytes).
        return match &pseudo_loss(feedback, round) {
            Ok(delta) => learn_from_loss(learner, round, delta),
            Err(e) => Err(*e),
        };
    }
    let delta = pseudo_loss(feedback, round)?;
    learn_from_loss(learner, round, &delta)
}

/// [`learn`] from a pseudo-loss already built.
pub fn learn_from_loss<L>(
    learner: &mut L,
    round: &Round<'_>,
    delta: &PseudoLoss,
) -> Result<Outcome, LearnError>
where
    L: OnlineLearner + ?Sized,
{
    let eval = surrogate::evaluate(
        learner.surrogate(),
        learner.linearization_point(delta),
        round,
        delta,
    );
    if eval.is_flat() {
        return Ok(Outcome {
            eval,
            stepped: false,
        });
    }
    learner.step(&eval.subgradient)?;
    Ok(Outcome {
        eval,
        stepped: true,
    })
}

/// `‖w‖₂`, summed from index 0.
#[inline]
pub(crate) fn norm(w: &Weights) -> f32 {
    let mut s = 0.0f32;
    for x in w {
        s += x * x;
    }
    ieee_sqrt(s)
}

/// Whether every entry is finite with magnitude at most `bound` ([`within`]): one comparison per
/// entry (false for NaN and both infinities) without an early exit, which the compiler does four
/// entries at a time on a `policy::WIDE` target where [`within`]'s tests, one branch each, stay
/// scalar.
#[inline(always)]
fn all_within(v: &Features, bound: f32) -> bool {
    v.iter().fold(true, |good, x| good & (x.abs() <= bound))
}

fn check_gradient(g: &Features) -> Result<(), UpdateError> {
    if crate::policy::WIDE && all_within(g, GRADIENT_BOUND) {
        return Ok(());
    }
    if g.iter().any(|x| !x.is_finite()) {
        return Err(UpdateError::NotFinite);
    }
    if !within(g, GRADIENT_BOUND) {
        return Err(UpdateError::OutOfBounds);
    }
    Ok(())
}

/// Scales `w` back onto the ball of `radius` when it lies outside.
fn project(w: &mut Weights, radius: Option<f32>) {
    if let Some(r) = radius {
        let n = norm(w);
        if n > r {
            let k = r / n;
            for x in w.iter_mut() {
                *x *= k;
            }
        }
    }
}

fn check_weights(w: &Weights) -> Result<(), UpdateError> {
    let good = if crate::policy::WIDE {
        all_within(w, WEIGHT_BOUND)
    } else {
        within(w, WEIGHT_BOUND)
    };
    if good {
        Ok(())
    } else {
        Err(UpdateError::OutOfBounds)
    }
}

/// Online gradient descent, constant or `1/√t` steps, optional projection.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Ogd {
    w: Weights,
    step: f32,
    decaying: bool,
    radius: Option<f32>,
    t: u32,
}

impl Ogd {
    /// Constant steps `η`.
    pub const fn constant(params: &ValidLearnerParams) -> Self {
        let p = params.get();
        Self {
            w: p.initial,
            step: p.step,
            decaying: false,
            radius: p.radius,
            t: 0,
        }
    }

    /// Steps `η / √t`.
    pub const fn decaying(params: &ValidLearnerParams) -> Self {
        Self {
            decaying: true,
            ..Self::constant(params)
        }
    }

    /// The step size of the next step.
    pub fn next_step_size(&self) -> f32 {
        if self.decaying {
            self.step / ieee_sqrt(self.t.saturating_add(1) as f32)
        } else {
            self.step
        }
    }

    /// The iterate after a step along `g`, not committed.
    fn stepped(&self, g: &Features) -> Result<Self, UpdateError> {
        check_gradient(g)?;
        let t = self.t.checked_add(1).ok_or(UpdateError::Exhausted)?;
        let eta = self.next_step_size();
        let mut w = self.w;
        for i in 0..FEATURE_COUNT {
            w[i] -= eta * g[i];
        }
        project(&mut w, self.radius);
        check_weights(&w)?;
        Ok(Self { w, t, ..*self })
    }

    fn state(&self) -> LearnerState {
        LearnerState {
            iterate: self.w,
            average: self.w,
            accumulator: [0.0; FEATURE_COUNT],
            steps: self.t,
        }
    }
}

impl OnlineLearner for Ogd {
    fn weights(&self) -> &Weights {
        &self.w
    }

    fn step(&mut self, g: &Features) -> Result<(), UpdateError> {
        *self = self.stepped(g)?;
        Ok(())
    }

    fn steps(&self) -> u32 {
        self.t
    }
}

/// Constant-step OGD acting on the running mean of its iterates `w̄ = mean(w_0, …, w_t)`
/// (Polyak–Ruppert averaging over updates; rounds without feedback change nothing).
///
/// Where the surrogate is evaluated depends on what the feedback says:
///
/// * **Absolute feedback** (the teacher names its best action, [`ActionFeedback`](crate::ActionFeedback)):
///   at the raw iterate `w_t`, plain OGD, the policy playing `w̄`. The pseudo-loss ranks the
///   named action above every other, so it is a valid loss for any iterate, and a wrong answer
///   moves `w_t` once, by one step, and `w̄` by `1/t` of that. This is what survives noisy
///   teachers: on the synthetic stream of `tests/integration/learning.rs`, with 20% of the
///   answers random, the mean latent loss of the last 1000 rounds stays at most 0.011% of a random
///   policy's (seeds 0–3), where plain OGD's is 0.7–5.7%. Evaluating at `w̄` instead was
///   measured at 4–10%: `w̄` moves slowly, so the same mistake is corrected again and again and
///   the raw iterate overshoots.
/// * **Relative feedback** (a preference, semantic statements): at `w̄`, the weights that chose
///   the judged action. Such a pseudo-loss only ranks actions relative to the ones it compared;
///   evaluated at `w_t`, its maximiser is the raw iterate's own favourite, about which the
///   feedback says nothing. Measured in the households of `host-sim` (5000 steps, threshold 1,
///   with the teachers and statements before their calibration): evaluated at `w_t`, semantic
///   feedback did not learn at all (doors: latent loss 3.8 → 3.6 over 2992 corrections);
///   evaluated at `w̄`, it learns like plain OGD (2.3 → 0.05).
///
/// The step always moves `w_t`; `w̄` follows by `(w_{t+1} − w̄)/(t + 2)`.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct AveragedOgd {
    ogd: Ogd,
    average: Weights,
}

impl AveragedOgd {
    /// From checked parameters.
    pub const fn new(params: &ValidLearnerParams) -> Self {
        let ogd = Ogd::constant(params);
        Self {
            average: ogd.w,
            ogd,
        }
    }

    /// The raw OGD iterate `w_t`.
    pub fn iterate(&self) -> &Weights {
        &self.ogd.w
    }
}

impl OnlineLearner for AveragedOgd {
    fn weights(&self) -> &Weights {
        &self.average
    }

    fn linearization_point(&self, delta: &PseudoLoss) -> &Weights {
        if delta.is_absolute() {
            &self.ogd.w
        } else {
            &self.average
        }
    }

    fn step(&mut self, g: &Features) -> Result<(), UpdateError> {
        let ogd = self.ogd.stepped(g)?;
        let n = ogd.t as f32 + 1.0;
        let mut average = self.average;
        for i in 0..FEATURE_COUNT {
            average[i] += (ogd.w[i] - average[i]) / n;
        }
        check_weights(&average)?;
        *self = Self { ogd, average };
        Ok(())
    }

    fn steps(&self) -> u32 {
        self.ogd.t
    }
}

/// Diagonal AdaGrad with optional projection (Euclidean, onto the L2 ball).
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct AdaGrad {
    w: Weights,
    squares: Features,
    step: f32,
    radius: Option<f32>,
    t: u32,
}

impl AdaGrad {
    /// From checked parameters.
    pub const fn new(params: &ValidLearnerParams) -> Self {
        let p = params.get();
        Self {
            w: p.initial,
            squares: [0.0; FEATURE_COUNT],
            step: p.step,
            radius: p.radius,
            t: 0,
        }
    }

    /// The accumulated squared subgradients `G`.
    pub fn accumulator(&self) -> &Features {
        &self.squares
    }
}

impl OnlineLearner for AdaGrad {
    fn weights(&self) -> &Weights {
        &self.w
    }

    fn step(&mut self, g: &Features) -> Result<(), UpdateError> {
        check_gradient(g)?;
        let t = self.t.checked_add(1).ok_or(UpdateError::Exhausted)?;
        let mut squares = self.squares;
        let mut w = self.w;
        for i in 0..FEATURE_COUNT {
            squares[i] += g[i] * g[i];
            w[i] -= self.step * g[i] / (ieee_sqrt(squares[i]) + ADAGRAD_EPSILON);
        }
        if squares.iter().any(|x| !x.is_finite()) {
            return Err(UpdateError::OutOfBounds);
        }
        project(&mut w, self.radius);
        check_weights(&w)?;
        *self = Self {
            w,
            squares,
            t,
            ..*self
        };
        Ok(())
    }

    fn steps(&self) -> u32 {
        self.t
    }
}

/// The preference perceptron of Coactive learning: constant steps on the perceptron surrogate,
/// `w ← w + η (φ(â) − φ(a_t))`.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Coactive {
    ogd: Ogd,
}

impl Coactive {
    /// From checked parameters.
    pub const fn new(params: &ValidLearnerParams) -> Self {
        Self {
            ogd: Ogd::constant(params),
        }
    }
}

impl OnlineLearner for Coactive {
    fn weights(&self) -> &Weights {
        &self.ogd.w
    }

    fn surrogate(&self) -> Surrogate {
        Surrogate::Perceptron
    }

    fn step(&mut self, g: &Features) -> Result<(), UpdateError> {
        self.ogd.step(g)
    }

    fn steps(&self) -> u32 {
        self.ogd.t
    }
}

/// An explicit tag (`repr(u8)`, `Ogd` = 0) rather than a niche in a field: a zero byte is OGD, so
/// [`Learner::PLACEHOLDER`] is all zeros.
#[derive(Clone, Copy, PartialEq, Debug)]
#[repr(u8)]
enum Inner {
    Ogd(Ogd),
    Averaged(AveragedOgd),
    AdaGrad(AdaGrad),
    Coactive(Coactive),
}

/// Any of the learners, chosen at run time by [`LearnerParams::kind`]. No allocation, no
/// dynamic dispatch: 80 bytes or so, `Copy`.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Learner {
    params: ValidLearnerParams,
    inner: Inner,
}

impl Learner {
    /// A fresh learner at its initial weights.
    pub const fn new(params: ValidLearnerParams) -> Self {
        let inner = match params.get().kind {
            LearnerKind::Ogd => Inner::Ogd(Ogd::constant(&params)),
            LearnerKind::OgdDecaying => Inner::Ogd(Ogd::decaying(&params)),
            LearnerKind::AveragedOgd => Inner::Averaged(AveragedOgd::new(&params)),
            LearnerKind::AdaGrad => Inner::AdaGrad(AdaGrad::new(&params)),
            LearnerKind::Coactive => Inner::Coactive(Coactive::new(&params)),
        };
        Self { params, inner }
    }

    /// A stand-in whose every byte is zero (OGD, step 0, zero weights: it never moves), for
    /// storage that must be all zeros to land in `.bss` ([`crate::agent::Agent::BLANK`]). Its
    /// parameters are not valid ones (the step is 0): it is replaced before anything learns.
    pub(crate) const PLACEHOLDER: Self = Self {
        params: ValidLearnerParams::PLACEHOLDER,
        inner: Inner::Ogd(Ogd {
            w: [0.0; FEATURE_COUNT],
            step: 0.0,
            decaying: false,
            radius: None,
            t: 0,
        }),
    };

    /// The parameters it was built from.
    pub fn params(&self) -> &ValidLearnerParams {
        &self.params
    }

    /// Which learner this is.
    pub fn kind(&self) -> LearnerKind {
        self.params.get().kind
    }

    /// Back to the initial weights, parameters kept.
    pub fn reset(&mut self) {
        *self = Self::new(self.params);
    }

    /// Learns from one feedback about `round` (see [`learn`]).
    pub fn learn<S: PseudoLossSource + ?Sized>(
        &mut self,
        round: &Round<'_>,
        feedback: &S,
    ) -> Result<Outcome, LearnError> {
        learn(self, round, feedback)
    }

    fn as_dyn(&self) -> &dyn OnlineLearner {
        match &self.inner {
            Inner::Ogd(l) => l,
            Inner::Averaged(l) => l,
            Inner::AdaGrad(l) => l,
            Inner::Coactive(l) => l,
        }
    }

    fn as_dyn_mut(&mut self) -> &mut dyn OnlineLearner {
        match &mut self.inner {
            Inner::Ogd(l) => l,
            Inner::Averaged(l) => l,
            Inner::AdaGrad(l) => l,
            Inner::Coactive(l) => l,
        }
    }

    /// The full state, enough to continue bit-identically after [`Learner::restore`].
    pub fn state(&self) -> LearnerState {
        match &self.inner {
            Inner::Ogd(l) => l.state(),
            Inner::Coactive(l) => l.ogd.state(),
            Inner::Averaged(l) => LearnerState {
                average: l.average,
                ..l.ogd.state()
            },
            Inner::AdaGrad(l) => LearnerState {
                iterate: l.w,
                average: l.w,
                accumulator: l.squares,
                steps: l.t,
            },
        }
    }

    /// A versioned snapshot of parameters and state, for persistence and the weights report.
    pub fn snapshot(&self) -> LearnerSnapshot {
        LearnerSnapshot {
            version: SNAPSHOT_VERSION,
            params: *self.params.get(),
            state: self.state(),
        }
    }

    /// The learner a snapshot describes, after checking its version, parameters and numbers.
    pub fn restore(snapshot: &LearnerSnapshot) -> Result<Self, crate::error::SnapshotError> {
        use crate::error::SnapshotError;
        if snapshot.version != SNAPSHOT_VERSION {
            return Err(SnapshotError::Version(snapshot.version));
        }
        let params = snapshot.params.check().map_err(SnapshotError::Params)?;
        let s = &snapshot.state;
        if !(within(&s.iterate, WEIGHT_BOUND)
            && within(&s.average, WEIGHT_BOUND)
            && s.accumulator.iter().all(|x| x.is_finite() && *x >= 0.0))
        {
            return Err(SnapshotError::State);
        }
        let mut learner = Self::new(params);
        match &mut learner.inner {
            Inner::Ogd(l) => {
                l.w = s.iterate;
                l.t = s.steps;
            }
            Inner::Coactive(l) => {
                l.ogd.w = s.iterate;
                l.ogd.t = s.steps;
            }
            Inner::Averaged(l) => {
                l.ogd.w = s.iterate;
                l.ogd.t = s.steps;
                l.average = s.average;
            }
            Inner::AdaGrad(l) => {
                l.w = s.iterate;
                l.squares = s.accumulator;
                l.t = s.steps;
            }
        }
        Ok(learner)
    }
}

impl OnlineLearner for Learner {
    fn weights(&self) -> &Weights {
        self.as_dyn().weights()
    }

    fn linearization_point(&self, delta: &PseudoLoss) -> &Weights {
        self.as_dyn().linearization_point(delta)
    }

    fn surrogate(&self) -> Surrogate {
        self.as_dyn().surrogate()
    }

    fn step(&mut self, g: &Features) -> Result<(), UpdateError> {
        self.as_dyn_mut().step(g)
    }

    fn steps(&self) -> u32 {
        self.as_dyn().steps()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_params_are_valid() {
        assert_eq!(
            LearnerParams::default().check(),
            Ok(ValidLearnerParams::default())
        );
        for k in LearnerKind::ALL {
            assert!(LearnerParams::new(k).check().is_ok());
            assert_eq!(LearnerKind::from_name(k.name()), Some(k));
        }
    }

    #[test]
    fn projection_keeps_the_iterate_in_the_ball() {
        let p = LearnerParams::paper()
            .with_step(1.0)
            .with_radius(2.0)
            .check()
            .unwrap();
        let mut l = Ogd::constant(&p);
        l.step(&[-10.0, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap();
        assert_eq!(l.weights()[0], 2.0);
    }

    #[test]
    fn refused_steps_change_nothing() {
        for k in LearnerKind::ALL {
            let p = LearnerParams::new(k).with_step(MAX_STEP).check().unwrap();
            let mut l = Learner::new(p);
            l.step(&[1.0; FEATURE_COUNT]).unwrap();
            let before = l;
            assert_eq!(
                l.step(&[f32::NAN; FEATURE_COUNT]),
                Err(UpdateError::NotFinite)
            );
            assert_eq!(
                l.step(&[f32::INFINITY; FEATURE_COUNT]),
                Err(UpdateError::NotFinite)
            );
            assert_eq!(
                l.step(&[3.0e4; FEATURE_COUNT]),
                Err(UpdateError::OutOfBounds)
            );
            assert_eq!(l, before, "{k:?}");
        }
    }

    #[test]
    fn weights_never_cross_the_bound() {
        let p = LearnerParams::paper().with_step(MAX_STEP).check().unwrap();
        let mut l = Learner::new(p);
        let g = [-GRADIENT_BOUND; FEATURE_COUNT];
        let mut refused = false;
        for _ in 0..200 {
            match l.step(&g) {
                Ok(()) => {}
                Err(e) => {
                    assert_eq!(e, UpdateError::OutOfBounds);
                    refused = true;
                    break;
                }
            }
        }
        assert!(refused);
        assert!(within(l.weights(), WEIGHT_BOUND));
    }
}
