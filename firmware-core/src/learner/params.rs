//! Learner parameters, validated once into [`ValidLearnerParams`].

use serde::{Deserialize, Serialize};

use crate::error::ParamError;
use crate::feature::{FEATURE_COUNT, WEIGHT_BOUND, Weights, within};
use crate::learner::norm;

/// Largest step size accepted by [`LearnerParams::check`].
pub const MAX_STEP: f32 = 1.0e3;

/// The paper's OGD step size.
pub const PAPER_STEP: f32 = 0.01;

/// Which online learner to run.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub enum LearnerKind {
    /// Online gradient descent with a constant step `η` (the paper's learner, `η = 0.01`).
    Ogd,
    /// Online gradient descent with steps `η / √t` (`t` = number of updates so far, from 1).
    OgdDecaying,
    /// Constant-step OGD whose policy acts on the running average of its iterates
    /// (Polyak–Ruppert averaging). The default: see [`LearnerParams::default`].
    AveragedOgd,
    /// Diagonal AdaGrad: per-feature steps `η / (√(Σ g²) + ε)`.
    AdaGrad,
    /// The preference perceptron of Coactive learning: steps of `η` (1 in the paper) along
    /// `φ(â) − φ(a_t)`, the perceptron surrogate's negative subgradient.
    Coactive,
}

impl LearnerKind {
    /// All kinds, for sweeps and CLIs.
    pub const ALL: [LearnerKind; 5] = [
        LearnerKind::Ogd,
        LearnerKind::OgdDecaying,
        LearnerKind::AveragedOgd,
        LearnerKind::AdaGrad,
        LearnerKind::Coactive,
    ];

    /// The step size used when none is given: 0.01 (the paper's) for the OGD family, 0.1 for
    /// AdaGrad, 1 for the perceptron.
    ///
    /// From zero initial weights the policy is invariant to the step's scale for OGD, AdaGrad
    /// and the perceptron (`argmax` ignores a positive factor); the step matters against non-zero
    /// initial weights and against a projection radius.
    pub const fn default_step(self) -> f32 {
        match self {
            LearnerKind::Ogd | LearnerKind::OgdDecaying | LearnerKind::AveragedOgd => PAPER_STEP,
            LearnerKind::AdaGrad => 0.1,
            LearnerKind::Coactive => 1.0,
        }
    }

    /// A short name ("ogd", "ogd-decaying", "averaged-ogd", "adagrad", "coactive").
    pub const fn name(self) -> &'static str {
        match self {
            LearnerKind::Ogd => "ogd",
            LearnerKind::OgdDecaying => "ogd-decaying",
            LearnerKind::AveragedOgd => "averaged-ogd",
            LearnerKind::AdaGrad => "adagrad",
            LearnerKind::Coactive => "coactive",
        }
    }

    /// The kind named `name` (see [`LearnerKind::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// Parameters of an online learner, as a user or the wire gives them.
///
/// They become usable only through [`LearnerParams::check`], so the learners never re-validate
/// a step size or a radius per update.
///
/// ```
/// use firmware_core::{LearnerKind, LearnerParams, Learner};
/// let params = LearnerParams::new(LearnerKind::Ogd).with_step(0.01).check().unwrap();
/// let learner = Learner::new(params);
/// assert_eq!(learner.kind(), LearnerKind::Ogd);
/// assert!(LearnerParams::new(LearnerKind::Ogd).with_step(f32::NAN).check().is_err());
/// ```
#[derive(Clone, Copy, PartialEq, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct LearnerParams {
    /// Which learner.
    pub kind: LearnerKind,
    /// The step size `η`.
    pub step: f32,
    /// Radius of the L2 ball the iterate is projected onto after every step; `None`: no
    /// projection.
    pub radius: Option<f32>,
    /// The weights before any feedback.
    pub initial: Weights,
}

impl LearnerParams {
    /// `kind` with its default step, no projection, zero initial weights.
    pub const fn new(kind: LearnerKind) -> Self {
        Self {
            kind,
            step: kind.default_step(),
            radius: None,
            initial: [0.0; FEATURE_COUNT],
        }
    }

    /// The paper's learner: constant-step OGD with `η = 0.01`.
    pub const fn paper() -> Self {
        Self::new(LearnerKind::Ogd)
    }

    /// With step size `step`.
    pub const fn with_step(mut self, step: f32) -> Self {
        self.step = step;
        self
    }

    /// With projection onto the L2 ball of `radius`.
    pub const fn with_radius(mut self, radius: f32) -> Self {
        self.radius = Some(radius);
        self
    }

    /// With initial weights.
    pub const fn with_initial(mut self, initial: Weights) -> Self {
        self.initial = initial;
        self
    }

    /// Validates the parameters: step in `(0, MAX_STEP]`, radius in `(0, WEIGHT_BOUND]`, initial
    /// weights finite, within [`WEIGHT_BOUND`] and inside the ball.
    pub fn check(&self) -> Result<ValidLearnerParams, ParamError> {
        if !(self.step.is_finite() && self.step > 0.0 && self.step <= MAX_STEP) {
            return Err(ParamError::Step);
        }
        if let Some(r) = self.radius
            && !(r.is_finite() && r > 0.0 && r <= WEIGHT_BOUND)
        {
            return Err(ParamError::Radius);
        }
        if !within(&self.initial, WEIGHT_BOUND) {
            return Err(ParamError::Initial);
        }
        if let Some(r) = self.radius
            && norm(&self.initial) > r
        {
            return Err(ParamError::Initial);
        }
        Ok(ValidLearnerParams(*self))
    }
}

impl Default for LearnerParams {
    /// Constant-step OGD acting on its averaged iterate, `η = 0.01`, from zero weights.
    ///
    /// Why this default: a real teacher is noisy. On the seeded synthetic stream of the test
    /// suite (64 actions, 20% of the teacher's answers replaced by random actions), plain OGD's
    /// iterate keeps being knocked about by every wrong answer, while the averaged iterate (the
    /// mean of all iterates, Polyak–Ruppert) moves by `1/t` of each step and settles near the
    /// teacher's policy; in the simulated households it is also the better learner from noisy
    /// action feedback, and it learns from preferences and spoken rules as well (see
    /// [`AveragedOgd`](crate::AveragedOgd) for how it treats each kind of feedback). The figures
    /// are in `firmware-core/tests/integration/learning.rs` and `host-sim`'s `experiment` module.
    fn default() -> Self {
        Self::new(LearnerKind::AveragedOgd)
    }
}

/// Learner parameters that passed [`LearnerParams::check`]. The default is
/// [`LearnerParams::default`], valid by construction (checked in the tests).
#[derive(Clone, Copy, PartialEq, Debug, Default)]
pub struct ValidLearnerParams(LearnerParams);

impl ValidLearnerParams {
    /// [`LearnerParams::default`], valid by construction (checked in the tests); usable in
    /// `const` and `static` initialisers.
    pub const DEFAULT: Self = Self(LearnerParams::new(LearnerKind::AveragedOgd));

    /// All zeros (OGD, step 0): not valid parameters; only [`crate::Learner::PLACEHOLDER`]'s.
    pub(crate) const PLACEHOLDER: Self = Self(LearnerParams {
        kind: LearnerKind::Ogd,
        step: 0.0,
        radius: None,
        initial: [0.0; FEATURE_COUNT],
    });

    /// The checked parameters.
    #[inline]
    pub const fn get(&self) -> &LearnerParams {
        &self.0
    }
}
