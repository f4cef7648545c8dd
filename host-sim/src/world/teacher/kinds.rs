//! The feedback of the kinds beyond the paper's three (issue 15), from the same latent weights,
//! threshold and noise model: every decision goes through the perceived latent loss `L̃` and the
//! teacher's choice `ã = argmin L̃` (or, for a random answer, a uniformly drawn action or a
//! coin), exactly as for action, preference and semantic feedback.
//!
//! | kind | what the teacher says when it corrects `a_t` | random answer |
//! |---|---|---|
//! | perturbation | it pushes `a_t`'s trajectory [`PUSH`] (half) of the way towards `ã`'s ([`DeformedTrajectory::between`]) and sends the pushed trajectory's features, measured in the tick's observation | the push goes towards a random action |
//! | ranking | it is shown `a_t` and [`RANKED_SHOWN`] − 1 other allowed actions drawn uniformly without replacement, and orders all of them by `L̃` (lowest first; equal `L̃` in index order; all equal: nothing) | the shown actions in a random order |
//! | reward | `r = −min(1, L̃(a_t) / REWARD_FULL_SCALE)`, at least −0.01 in size | `r` uniform over the hundredths −1…1 but 0 |
//! | correctness | "incorrect" | a coin: correct or incorrect |
//! | span | "bad" about the tick (the loop's [`crate::teach::kinds::Tutor`] widens it to the whole stretch of bad ticks) | a coin: good or bad |
//! | E-stop | it stops the car | — (nothing to draw: it pressed the button) |
//!
//! Like the paper's semantic and action teachers, it says nothing when its own choice `ã` is the
//! learner's action (with σ > 0 every perceived loss may exceed the threshold). The teacher
//! speaks only when it corrects (the paper's user model: no feedback when the action is good
//! enough), so its labels and rewards are never the positive ones; the car takes those too.

use firmware_core::feedback::perturbation::{CORRECTED_RANGES, DeformedTrajectory, PUSH};
use firmware_core::{
    ActionIndex, CorrectnessFeedback, EStopFeedback, FEATURE_COUNT, Feedback, FeedbackKind,
    PerturbationFeedback, RankingFeedback, RewardFeedback, SpanFeedback,
};
use rand::RngExt;
use rand::seq::SliceRandom;

use super::{Judgement, Teacher};

/// How many actions a ranking teacher is shown: the learner's and three others.
pub const RANKED_SHOWN: usize = 4;

/// The perceived latent loss a reward of −1 stands for: larger losses also get −1, smaller
/// ones a proportionally smaller penalty (the size does not change what the learner learns:
/// see [`firmware_core::feedback::executed`]).
pub const REWARD_FULL_SCALE: f32 = 10.0;

impl Teacher {
    /// The feedback of `kind` (one of the kinds beyond the paper's three) about `chosen`, with
    /// the teacher's choice `choice` (already a random action when `random` and the kind
    /// answers with an action).
    pub(super) fn other_kind(
        &mut self,
        kind: FeedbackKind,
        j: &Judgement,
        chosen: ActionIndex,
        choice: ActionIndex,
        random: bool,
    ) -> Option<Feedback> {
        match kind {
            FeedbackKind::Perturbation => {
                if choice == chosen {
                    return None;
                }
                let pushed = DeformedTrajectory::between(chosen, choice, PUSH);
                let valid = j.observation.as_ref()?.check().ok()?;
                let mut phi = pushed.features(valid);
                for (x, (lo, hi)) in phi.iter_mut().zip(CORRECTED_RANGES).take(FEATURE_COUNT) {
                    *x = x.clamp(lo, hi);
                }
                PerturbationFeedback::new(&phi).map(Feedback::Perturbation)
            }
            FeedbackKind::Ranking => {
                let mut others = j.allowed();
                others.remove(chosen);
                let mut pool: Vec<ActionIndex> = others.iter().collect();
                let mut shown = vec![chosen];
                while shown.len() < RANKED_SHOWN && !pool.is_empty() {
                    let k = self.rng.random_range(0..pool.len());
                    shown.push(pool.swap_remove(k));
                }
                if shown.len() < 2 {
                    return None;
                }
                if random {
                    shown.shuffle(&mut self.rng);
                } else {
                    let l = &j.perceived;
                    shown.sort_by(|x, y| l[x.get()].total_cmp(&l[y.get()]).then(x.cmp(y)));
                    let first = l[shown[0].get()];
                    if shown.iter().all(|x| l[x.get()] == first) {
                        return None;
                    }
                }
                RankingFeedback::new(&shown, true).map(Feedback::Ranking)
            }
            FeedbackKind::Reward => {
                let r = if random {
                    let h = self.rng.random_range(1..=200i16);
                    (if h > 100 { h - 201 } else { h }) as f32 / 100.0
                } else {
                    let size = (j.perceived[chosen.get()] / REWARD_FULL_SCALE).clamp(0.01, 1.0);
                    -size
                };
                RewardFeedback::new(r).map(Feedback::Reward)
            }
            FeedbackKind::Correctness => Some(Feedback::Correctness(CorrectnessFeedback {
                correct: random && self.rng.random::<bool>(),
            })),
            FeedbackKind::Span => Some(Feedback::Span(SpanFeedback {
                ticks: 1,
                good: random && self.rng.random::<bool>(),
            })),
            FeedbackKind::EStop => Some(Feedback::EStop(EStopFeedback)),
            FeedbackKind::Action | FeedbackKind::Preference | FeedbackKind::Semantic => None,
        }
    }
}
