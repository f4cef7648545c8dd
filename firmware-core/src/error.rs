//! Error types of the learning path. All are small `Copy` enums: no allocation, no strings.
//!
//! A call that returns one of these changed nothing: validation always runs before any state is
//! written.

use core::fmt;

use crate::action::ActionIndex;
use crate::feature::FeatureError;

/// Why a learning step (feedback → pseudo-loss → surrogate → update) was refused.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum LearnError {
    /// The round allows no action at all.
    NoAllowedAction,
    /// An action the round or the feedback names is forbidden by the mask (for example a
    /// colliding trajectory).
    ActionNotAllowed(ActionIndex),
    /// The feature table failed its check.
    Features(FeatureError),
    /// The feedback carries no information: a preference between an action and itself, or a
    /// semantic feedback without a statement.
    DegenerateFeedback,
    /// A pseudo-loss was NaN, infinite or beyond [`crate::PSEUDO_LOSS_BOUND`].
    BadPseudoLoss,
    /// The update itself was refused.
    Update(UpdateError),
    /// A statement about the path came for a round without a path reference (see
    /// [`crate::Round::with_reference`]): the cross-track error it is judged by is unknown.
    NoPathReference,
    /// A round's path reference is not finite or out of its bounds.
    BadPathReference,
}

impl fmt::Display for LearnError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LearnError::NoAllowedAction => f.write_str("no action is allowed in this round"),
            LearnError::ActionNotAllowed(a) => write!(f, "action {a} is not allowed in this round"),
            LearnError::Features(e) => write!(f, "bad features: {e}"),
            LearnError::DegenerateFeedback => f.write_str("the feedback carries no information"),
            LearnError::BadPseudoLoss => f.write_str("pseudo-loss not finite or out of bounds"),
            LearnError::Update(e) => write!(f, "update refused: {e}"),
            LearnError::NoPathReference => {
                f.write_str("a statement about the path needs the round's path reference")
            }
            LearnError::BadPathReference => {
                f.write_str("path reference not finite or out of bounds")
            }
        }
    }
}

impl core::error::Error for LearnError {}

impl From<FeatureError> for LearnError {
    fn from(e: FeatureError) -> Self {
        LearnError::Features(e)
    }
}

impl From<UpdateError> for LearnError {
    fn from(e: UpdateError) -> Self {
        LearnError::Update(e)
    }
}

/// Why an online learner refused a step. Its state is unchanged.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum UpdateError {
    /// The subgradient holds NaN or an infinity.
    NotFinite,
    /// The subgradient or the resulting weights exceed their bounds
    /// ([`crate::GRADIENT_BOUND`], [`crate::WEIGHT_BOUND`]).
    OutOfBounds,
    /// The learner has taken `u32::MAX` steps.
    Exhausted,
}

impl fmt::Display for UpdateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UpdateError::NotFinite => f.write_str("subgradient is not finite"),
            UpdateError::OutOfBounds => f.write_str("step would leave the weight bounds"),
            UpdateError::Exhausted => f.write_str("step counter exhausted"),
        }
    }
}

impl core::error::Error for UpdateError {}

/// Why learner parameters failed [`crate::LearnerParams::check`].
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum ParamError {
    /// The step size is NaN, infinite, not positive, or above [`crate::MAX_STEP`].
    Step,
    /// The projection radius is NaN, infinite, not positive, or above [`crate::WEIGHT_BOUND`].
    Radius,
    /// The initial weights are not finite, exceed [`crate::WEIGHT_BOUND`], or lie outside the
    /// projection ball.
    Initial,
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            // The bounds are written out (a test checks them against the constants), so a user
            // reads the number, not the constant's name.
            ParamError::Step => {
                f.write_str("step size must be finite, positive and at most 1000 (MAX_STEP)")
            }
            ParamError::Radius => f.write_str(
                "projection radius must be finite, positive and at most 1000000 (WEIGHT_BOUND)",
            ),
            ParamError::Initial => f.write_str(
                "initial weights must be finite, within ±1000000 (WEIGHT_BOUND) and inside the \
                 projection ball",
            ),
        }
    }
}

impl core::error::Error for ParamError {}

/// Why a learner snapshot could not be restored.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum SnapshotError {
    /// The snapshot was written by an unknown format version.
    Version(u16),
    /// Its parameters fail [`crate::LearnerParams::check`].
    Params(ParamError),
    /// Its state holds non-finite or out-of-bound numbers.
    State,
}

impl fmt::Display for SnapshotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SnapshotError::Version(v) => write!(f, "unknown snapshot version {v}"),
            SnapshotError::Params(e) => write!(f, "snapshot parameters invalid: {e}"),
            SnapshotError::State => f.write_str("snapshot state not finite or out of bounds"),
        }
    }
}

impl core::error::Error for SnapshotError {}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

    #[test]
    fn parameter_errors_name_their_bounds() {
        let step = std::format!("at most {} (MAX_STEP)", crate::MAX_STEP);
        assert!(ParamError::Step.to_string().contains(&step));
        let radius = std::format!("at most {} (WEIGHT_BOUND)", crate::WEIGHT_BOUND);
        assert!(ParamError::Radius.to_string().contains(&radius));
        let initial = std::format!("within ±{} (WEIGHT_BOUND)", crate::WEIGHT_BOUND);
        assert!(ParamError::Initial.to_string().contains(&initial));
    }
}
