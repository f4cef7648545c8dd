//! Good/bad labels of a part of the recent trajectory (ARC: Cui and Niekum, *Active reward
//! learning from critiques*, ICRA 2018).
//!
//! ARC's teacher watches a trajectory and marks segments of it good or bad; the critiques become
//! labelled state-action pairs from which a reward is learned, with a confidence factor for the
//! teacher's accuracy. Here a [`SpanFeedback`] labels the last `ticks` ticks up to and including
//! the tick its message names, all good or all bad, and every labelled tick the car still holds
//! gets the correct/incorrect pseudo-loss of its own executed action
//! ([`crate::CorrectnessFeedback`]): one learning step per tick, oldest first, all or none (a
//! refused step leaves the learner as it was before the first).
//!
//! **Older ticks.** The car remembers the features of its last
//! [`TICK_HISTORY`](crate::agent::TICK_HISTORY) (= 4) ticks only. Labelled ticks older than that
//! are dropped: their features are gone, and the teacher's label says nothing about the ticks
//! the car holds. A span is refused ([`crate::agent::FeedbackError::UnknownTick`]) only when the
//! car holds none of its ticks. ARC has no such limit because it learns offline from whole
//! trajectories; a car with more memory would apply more of a long span. ARC's confidence factor
//! is not modelled: every label counts fully, as every other kind of feedback does here.
//!
//! A span covers at most [`MAX_SPAN`] ticks (5 s at 10 Hz); longer, or 0, is refused.
//!
//! ```
//! use firmware_core::SpanFeedback;
//! let bad = SpanFeedback { ticks: 3, good: false };
//! assert_eq!(bad.first_tick(10), 8);
//! assert!(SpanFeedback { ticks: 0, good: false }.check().is_err());
//! ```

use serde::{Deserialize, Serialize};

use super::Round;
use crate::action::MAX_ACTIONS;
use crate::error::LearnError;

/// The longest span a label may cover (ticks): 5 s at 10 Hz.
pub const MAX_SPAN: u8 = 50;

/// A good or bad label of the last `ticks` ticks, ending with the tick of its message.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct SpanFeedback {
    /// How many ticks the label covers, 1 to [`MAX_SPAN`].
    pub ticks: u8,
    /// Good (every labelled action was right) or bad (every one was wrong).
    pub good: bool,
}

impl SpanFeedback {
    /// Whether the span's length is one the car takes.
    pub fn check(self) -> Result<(), LearnError> {
        match self.ticks {
            0 => Err(LearnError::DegenerateFeedback),
            n if n > MAX_SPAN => Err(LearnError::OutOfRange),
            _ => Ok(()),
        }
    }

    /// The first tick of a span that ends at `last` (tick numbers wrap like the protocol's).
    pub fn first_tick(self, last: u32) -> u32 {
        last.wrapping_sub(u32::from(self.ticks.max(1)) - 1)
    }

    /// Whether `tick` is one of the span's when it ends at `last`.
    pub fn covers(self, last: u32, tick: u32) -> bool {
        last.wrapping_sub(tick) < u32::from(self.ticks)
    }
}

/// One labelled tick's pseudo-loss: correct/incorrect of the tick's executed action.
impl super::PseudoLossSource for SpanFeedback {
    fn write_pseudo_loss(
        &self,
        round: &Round<'_>,
        out: &mut [f32; MAX_ACTIONS],
    ) -> Result<(), LearnError> {
        self.check()?;
        super::CorrectnessFeedback { correct: self.good }.write_pseudo_loss(round, out)
    }
}
