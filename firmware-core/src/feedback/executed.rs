//! Feedback about the executed action only: a scalar reward (COACH, TAMER), a correct/incorrect
//! label (Hao et al.'s binary feedback), an intervention (E-stop).
//!
//! All three judge one action, the one the learner executed, `a_t`, and say nothing about any
//! other. Their pseudo-losses therefore cannot point at a better action: they can only say "not
//! this one" (every other action becomes a minimiser) or "this one" (`a_t` becomes the only
//! minimiser).
//!
//! | feedback | `Δ(a_t)` | `Δ(a)`, `a ≠ a_t` |
//! |---|---|---|
//! | [`CorrectnessFeedback`] incorrect, [`EStopFeedback`] | [`EXECUTED_LOSS`] | 0 |
//! | [`CorrectnessFeedback`] correct | 0 | [`EXECUTED_LOSS`] |
//! | [`RewardFeedback`] `r < 0` | [`EXECUTED_LOSS`] · `|r|` | 0 |
//! | [`RewardFeedback`] `r > 0` | 0 | [`EXECUTED_LOSS`] · `r` |
//!
//! # What the generalized hinge makes of them
//!
//! With "not this one", every other allowed action ties at 0, so the surrogate's target `â` is
//! the one the weights score highest among them ([`crate::surrogate`]: ties go to the best
//! scored): the learner's runner-up. The learner chose `a_t` as its argmax, so the hinge's
//! maximiser is `a_t` and the step is `w ← w + η (φ(runner-up) − φ(a_t))`: it lowers `a_t` and
//! raises the runner-up, whether or not the runner-up is any better for the teacher. The
//! paper's assumption 1 holds in its weak form (the teacher's best is *among* the minimisers
//! whenever `a_t` is not it), but assumption 2 (α-informativeness: the minimiser the learner
//! moves towards is at least a fraction α of the way from `a_t` to the teacher's best) holds
//! only when the runner-up happens to be better than `a_t`; `host-sim reproduce` measures how
//! often along real runs.
//!
//! **The size of a reward does not change the step.** A negative reward sets `Δ(a_t)`; the
//! hinge's maximiser is `a_t` whatever its size, and the subgradient `φ(a_t) − φ(â)` does not
//! contain `Δ`, so with the learners of [`crate::learner`] a reward of −0.1 teaches exactly what
//! −1 does, and what "incorrect" does. COACH uses the reward as the step's multiplier (an
//! advantage in an actor-critic update) and TAMER regresses a model of it; the meta-algorithm's
//! hinge keeps the ordering the reward implies and drops its size. The reward's size still
//! travels and is recorded, so a learner that used it could.
//!
//! **E-stop** has the pseudo-loss of "incorrect": the teacher stopped the car, so the executed
//! action was unacceptable. What else it does is the car's: the car stands until its next
//! observation (`protocol::car::CarNode`), and the simulator holds the car still for the tick.

use serde::{Deserialize, Serialize};

use super::Round;
use crate::action::MAX_ACTIONS;
use crate::error::LearnError;

/// `Δ` of the executed action when it was judged wrong (and of every other action when it was
/// judged right): the paper's 100 of action feedback.
pub const EXECUTED_LOSS: f32 = 100.0;

/// A reward's steps per unit: the wire carries hundredths.
pub const REWARD_STEPS: i8 = 100;

/// Writes "not `a_t`, by `loss`" (`judged_good` false) or "`a_t`, by `loss`" (true).
fn judge_executed(
    round: &Round<'_>,
    judged_good: bool,
    loss: f32,
    out: &mut [f32; MAX_ACTIONS],
) -> Result<(), LearnError> {
    let chosen = round.chosen();
    for a in round.allowed() {
        let is_chosen = a == chosen;
        out[a.get()] = if is_chosen != judged_good { loss } else { 0.0 };
    }
    Ok(())
}

/// A scalar reward for the executed action (COACH, MacGlashan et al. 2017; TAMER, Knox and
/// Stone 2009): `r ∈ [−1, 1]` in hundredths, −1 the worst the teacher can say, +1 the best, 0
/// refused as saying nothing.
///
/// COACH and TAMER take `r` as a number to learn a value or an advantage from; here it becomes a
/// pseudo-loss over the actions (see the module documentation): its sign decides which actions
/// minimise it, its size scales `Δ` and, with the generalized hinge, does not change the step.
///
/// ```
/// use firmware_core::RewardFeedback;
/// let r = RewardFeedback::new(-0.25).unwrap();
/// assert_eq!(r.hundredths, -25);
/// assert_eq!(r.value(), -0.25);
/// assert!(RewardFeedback::new(1.5).is_none());
/// ```
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct RewardFeedback {
    /// The reward in hundredths: −100 to 100, not 0.
    pub hundredths: i8,
}

impl RewardFeedback {
    /// The reward `r`, rounded to hundredths; `None` when `r` is not finite or beyond ±1.
    pub fn new(r: f32) -> Option<Self> {
        if !(r.is_finite() && libm::fabsf(r) <= 1.0) {
            return None;
        }
        let h = libm::roundf(r * REWARD_STEPS as f32) as i8;
        Some(Self { hundredths: h })
    }

    /// The reward as a number in `[−1, 1]`.
    pub fn value(self) -> f32 {
        self.hundredths as f32 / REWARD_STEPS as f32
    }

    /// Whether the reward is one the pseudo-loss takes: `0 < |hundredths| ≤ 100`.
    pub fn check(self) -> Result<(), LearnError> {
        match self.hundredths {
            0 => Err(LearnError::DegenerateFeedback),
            h if h.unsigned_abs() > REWARD_STEPS as u8 => Err(LearnError::OutOfRange),
            _ => Ok(()),
        }
    }
}

impl super::PseudoLossSource for RewardFeedback {
    fn write_pseudo_loss(
        &self,
        round: &Round<'_>,
        out: &mut [f32; MAX_ACTIONS],
    ) -> Result<(), LearnError> {
        self.check()?;
        let r = self.value();
        judge_executed(round, r > 0.0, EXECUTED_LOSS * libm::fabsf(r), out)
    }
}

/// The executed action was correct or incorrect (binary feedback: Hao et al., Table 1's
/// "binary correct/incorrect feedback"). The paper's teacher speaks only when it corrects, so
/// its labels are "incorrect"; "correct" is taken too, for a person who says so.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct CorrectnessFeedback {
    /// Whether the executed action was correct.
    pub correct: bool,
}

impl super::PseudoLossSource for CorrectnessFeedback {
    fn write_pseudo_loss(
        &self,
        round: &Round<'_>,
        out: &mut [f32; MAX_ACTIONS],
    ) -> Result<(), LearnError> {
        judge_executed(round, self.correct, EXECUTED_LOSS, out)
    }
}

/// The teacher stopped the car (an intervention, an emergency stop): the executed action was
/// unacceptable. The pseudo-loss is "incorrect"'s; the car also stands until its next
/// observation (see the module documentation).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Default, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct EStopFeedback;

impl super::PseudoLossSource for EStopFeedback {
    fn write_pseudo_loss(
        &self,
        round: &Round<'_>,
        out: &mut [f32; MAX_ACTIONS],
    ) -> Result<(), LearnError> {
        judge_executed(round, false, EXECUTED_LOSS, out)
    }
}
