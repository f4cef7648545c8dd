//! The car's side of a control tick: observe, act, and learn from feedback about a recent tick.
//!
//! An [`Agent`] owns the [`Learner`] and the features and path reference of the last
//! [`TICK_HISTORY`] ticks, so that feedback arriving after the next observation (a slow link, a
//! retransmission) is still judged against the tick it refers to.
//!
//! [`Agent::act`] checks the observation once and evaluates the checked one with the
//! [`Evaluator`] it keeps (2 944 bytes of scratch, reused from tick to tick: a fresh one gives
//! the same bits, and a kept one is not zeroed at every act). In a process where
//! someone else evaluated the same observation already (the host's teacher),
//! [`Agent::act_evaluated`] takes that [`Evaluation`] instead.
//!
//! ```
//! use firmware_core::agent::Agent;
//! use firmware_core::observation::Observation;
//! use firmware_core::{ActionFeedback, ActionIndex, Feedback, Learner, LearnerParams};
//!
//! let mut agent = Agent::new(Learner::new(LearnerParams::default().check().unwrap()));
//! let decision = agent.act(1, &Observation::open_space()).unwrap();
//! assert_eq!(decision.action, Some(ActionIndex::new(0).unwrap())); // zero weights: straight
//! let fb = Feedback::Action(ActionFeedback { action: ActionIndex::new(3).unwrap() });
//! agent.feedback(1, &fb).unwrap();
//! assert!(agent.feedback(7, &fb).is_err()); // no such tick
//! ```

use core::fmt;

use crate::action::{ActionIndex, ActionMask};
use crate::error::LearnError;
use crate::evaluator::{Evaluation, Evaluator, PathFrame};
use crate::feature::FeatureTable;
use crate::feedback::{Feedback, Round, SpanFeedback};
use crate::learner::{Learner, OnlineLearner, Outcome};
use crate::observation::{Observation, ObservationError, PathReference, ValidObservation};

/// Number of past ticks feedback may refer to.
pub const TICK_HISTORY: usize = 4;

/// What the agent decided in one tick.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Decision {
    /// The tick this decides.
    pub tick: u32,
    /// The chosen trajectory; `None` when every trajectory collides: the car must stop.
    pub action: Option<ActionIndex>,
    /// The trajectories that do not collide.
    pub allowed: ActionMask,
}

/// Why feedback was refused. The learner is unchanged.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum FeedbackError {
    /// The tick is not among the last [`TICK_HISTORY`] ticks the agent acted in, or the agent had
    /// no action in it (everything collided).
    UnknownTick(u32),
    /// The learning step refused the feedback.
    Learn(LearnError),
}

impl fmt::Display for FeedbackError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FeedbackError::UnknownTick(t) => write!(f, "no recent tick {t} to apply feedback to"),
            FeedbackError::Learn(e) => write!(f, "{e}"),
        }
    }
}

impl core::error::Error for FeedbackError {}

/// The features of one remembered tick. Slots are reused in place: the evaluator writes straight
/// into a slot's table, so no 1.5 KiB table ever travels on the stack.
#[derive(Clone, Debug)]
struct TickRecord {
    /// `Some(tick)` when the slot holds a tick the agent acted in.
    tick: Option<u32>,
    features: FeatureTable,
    allowed: ActionMask,
    chosen: ActionIndex,
    /// The tick's path reference: statements about the path are judged by the cross-track
    /// error of each trajectory's end against it (12 bytes, where a second feature table
    /// would take 1.5 KiB).
    reference: PathReference,
    /// Select's scores in the tick, off the car.
    #[cfg(not(target_arch = "arm"))]
    scored: Scored,
}

/// Select's scores of every allowed action in a tick and the weights they are of: a feedback
/// about the tick learned at weights of the same bits (relative feedback, while no other
/// feedback has moved the learner) takes them instead of scoring the table again
/// ([`Round::with_scores`]). Kept on the host (its simulated cars); the car
/// (`target_arch = "arm"`) keeps no room for them (1 KiB of RAM for four ticks, and a store per
/// action in every tick's select) and scores the table again.
#[cfg(not(target_arch = "arm"))]
#[derive(Clone, Debug)]
struct Scored {
    weights: crate::feature::Weights,
    scores: [f32; crate::action::MAX_ACTIONS],
}

impl TickRecord {
    const EMPTY: Self = Self {
        tick: None,
        features: FeatureTable::ZERO,
        allowed: ActionMask::NONE,
        chosen: ActionIndex::FIRST,
        reference: PathReference {
            x: 0.0,
            y: 0.0,
            heading: 0.0,
        },
        #[cfg(not(target_arch = "arm"))]
        scored: Scored {
            weights: [0.0; crate::feature::FEATURE_COUNT],
            scores: [0.0; crate::action::MAX_ACTIONS],
        },
    };
}

/// Learner, recent ticks and the evaluator's scratch: everything the car keeps between ticks,
/// 9 336 bytes (the learner and the last ticks 6 392, the scratch 2 944; off the car each tick
/// also keeps select's scores, 1 KiB more, and its table's columns, 1.5 KiB more: see
/// [`FeatureTable`]).
///
/// [`Agent::new`] is a `const fn`, so firmware can place an agent in a `static` (for example a
/// `static_cell::ConstStaticCell`) without building it on the stack first.
#[derive(Clone)]
pub struct Agent {
    learner: Learner,
    history: [TickRecord; TICK_HISTORY],
    next: usize,
    /// The evaluator's scratch, reused from tick to tick (a fresh one gives the same bits).
    evaluator: Evaluator,
}

impl fmt::Debug for Agent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // The evaluator's scratch is left out: nothing in it outlives an evaluation.
        f.debug_struct("Agent")
            .field("learner", &self.learner)
            .field("history", &self.history)
            .field("next", &self.next)
            .finish_non_exhaustive()
    }
}

impl Agent {
    /// An agent with `learner`, no history.
    pub const fn new(learner: Learner) -> Self {
        Self {
            learner,
            history: [TickRecord::EMPTY; TICK_HISTORY],
            next: 0,
            evaluator: Evaluator::new(),
        }
    }

    /// An agent whose every byte is zero, so that a `static` holding it lands in `.bss` and
    /// costs no flash (a `const` agent with any other learner is a 6 KiB initial value in
    /// `.data`, copied from flash at start). Its learner is a placeholder that never moves (step
    /// 0; not valid parameters): give it its learner with [`Agent::set_learner`] before it acts.
    pub const BLANK: Self = Self::new(Learner::PLACEHOLDER);

    /// The learner.
    pub fn learner(&self) -> &Learner {
        &self.learner
    }

    /// Replaces the learner (a new configuration, a restored snapshot); the history is kept.
    pub fn set_learner(&mut self, learner: Learner) {
        self.learner = learner;
    }

    /// Validates `obs` (once: the evaluator takes the checked observation), evaluates it,
    /// chooses the action and remembers the tick. On `Err` nothing changed.
    ///
    /// Acting again in a tick already remembered replaces that record.
    pub fn act(&mut self, tick: u32, obs: &Observation) -> Result<Decision, ObservationError> {
        Ok(self.act_checked(tick, obs.check()?))
    }

    /// [`Agent::act`] on an observation already checked.
    ///
    /// The agent's evaluator is reused: nothing it holds outlives an evaluation, and a fresh
    /// one gives the same bits as a reused one.
    pub fn act_checked(&mut self, tick: u32, obs: ValidObservation<'_>) -> Decision {
        let slot = self.slot_for(tick);
        let features = &mut self.history[slot].features;
        let frame = PathFrame::new(&obs.reference);
        let allowed = ActionMask::from_bits(clearances(&mut self.evaluator, obs, &frame, features));
        self.decide(tick, slot, allowed, obs.reference)
    }

    /// [`Agent::act`] on an observation someone else in the process evaluated already (the
    /// host's teacher judges the same observation): the agent takes that evaluation instead of
    /// making its own, bit for bit the same.
    pub fn act_evaluated(&mut self, tick: u32, evaluation: &Evaluation) -> Decision {
        let slot = self.slot_for(tick);
        self.history[slot].features.clone_from(evaluation.table());
        self.decide(tick, slot, evaluation.allowed(), evaluation.reference())
    }

    /// Chooses the action from the features in `slot` and remembers the tick there.
    fn decide(
        &mut self,
        tick: u32,
        slot: usize,
        allowed: ActionMask,
        reference: PathReference,
    ) -> Decision {
        let Self {
            learner,
            history,
            next,
            ..
        } = self;
        let record = &mut history[slot];
        #[cfg(not(target_arch = "arm"))]
        let action = {
            let scored = &mut record.scored;
            scored.weights = *learner.weights();
            crate::policy::select_scored(
                &scored.weights,
                &record.features,
                allowed,
                &mut scored.scores,
            )
        };
        #[cfg(target_arch = "arm")]
        let action = learner.select(&record.features, allowed);
        match action {
            Some(chosen) => {
                record.tick = Some(tick);
                record.allowed = allowed;
                record.chosen = chosen;
                record.reference = reference;
                if slot == *next {
                    *next = (*next + 1) % TICK_HISTORY;
                }
            }
            // Nothing to learn about a tick without an action: the slot is free again.
            None => record.tick = None,
        }
        Decision {
            tick,
            action,
            allowed,
        }
    }

    /// The slot to (re)use for `tick`: its own if remembered, else the oldest.
    fn slot_for(&self, tick: u32) -> usize {
        self.history
            .iter()
            .position(|r| r.tick == Some(tick))
            .unwrap_or(self.next)
    }

    /// Learns from feedback about a recent `tick`.
    ///
    /// A [`SpanFeedback`] (good or bad over the last ticks up to `tick`) is learned from once for
    /// every tick of its span the agent still holds, oldest first, all or none: the outcome is
    /// the last step's, `stepped` if any step was taken. Ticks of the span older than the
    /// agent's [`TICK_HISTORY`] are dropped ([`crate::feedback::span`]); a span none of whose
    /// ticks is held is [`FeedbackError::UnknownTick`].
    pub fn feedback(&mut self, tick: u32, feedback: &Feedback) -> Result<Outcome, FeedbackError> {
        if let Feedback::Span(span) = feedback {
            return self.feedback_span(tick, span);
        }
        let record = self
            .history
            .iter()
            .find(|r| r.tick == Some(tick))
            .ok_or(FeedbackError::UnknownTick(tick))?;
        learn_at(&mut self.learner, record, feedback)
    }

    /// The ticks of a span ending at `tick` that the agent holds, as slots, oldest first.
    fn span_slots(&self, tick: u32, span: &SpanFeedback) -> ([usize; TICK_HISTORY], usize) {
        let mut slots = [0usize; TICK_HISTORY];
        let mut n = 0;
        for (i, r) in self.history.iter().enumerate() {
            if let Some(t) = r.tick
                && span.covers(tick, t)
            {
                slots[n] = i;
                n += 1;
            }
        }
        // Oldest first: by distance back from `tick`, largest first (an insertion sort of at
        // most four entries).
        let age = |i: usize| self.history[i].tick.map_or(0, |t| tick.wrapping_sub(t));
        for k in 1..n {
            let mut j = k;
            while j > 0 && age(slots[j - 1]) < age(slots[j]) {
                slots.swap(j - 1, j);
                j -= 1;
            }
        }
        (slots, n)
    }

    /// How many ticks of a span ending at `tick` the agent holds (what a
    /// [`SpanFeedback`] would be applied to).
    pub fn held_in_span(&self, tick: u32, span: &SpanFeedback) -> usize {
        self.span_slots(tick, span).1
    }

    fn feedback_span(&mut self, tick: u32, span: &SpanFeedback) -> Result<Outcome, FeedbackError> {
        span.check().map_err(FeedbackError::Learn)?;
        let (slots, n) = self.span_slots(tick, span);
        if n == 0 {
            return Err(FeedbackError::UnknownTick(tick));
        }
        // On a copy, committed only when every step was taken.
        let mut learner = self.learner;
        let mut last = None;
        let mut stepped = false;
        // As a `Feedback`: the same learning path as every other kind (one copy of it).
        let label = Feedback::Span(*span);
        for &slot in &slots[..n] {
            let outcome = learn_at(&mut learner, &self.history[slot], &label)?;
            stepped |= outcome.stepped;
            last = Some(outcome);
        }
        self.learner = learner;
        Ok(Outcome {
            stepped,
            ..last.ok_or(FeedbackError::UnknownTick(tick))?
        })
    }

    /// Forgets every remembered tick (a reset of the car), keeping the learner.
    pub fn forget_ticks(&mut self) {
        for r in &mut self.history {
            r.tick = None;
        }
        self.next = 0;
    }
}

/// The collisions and features of `obs` into `out` (what [`Evaluator::evaluate`] does once the
/// path's frame is made), with the agent's `evaluator`. Never inlined: the evaluation's code
/// and frame stay apart from its callers' (on the car, the node's handling of a message).
#[inline(never)]
fn clearances(
    evaluator: &mut Evaluator,
    obs: ValidObservation<'_>,
    frame: &PathFrame,
    out: &mut FeatureTable,
) -> u64 {
    evaluator.clearances(obs, frame, out)
}

/// Learns from `feedback` about the tick `record` holds.
fn learn_at(
    learner: &mut Learner,
    record: &TickRecord,
    feedback: &Feedback,
) -> Result<Outcome, FeedbackError> {
    let round = Round::new(&record.features, record.allowed, record.chosen)
        .and_then(|r| r.with_reference(record.reference))
        .map_err(FeedbackError::Learn)?;
    #[cfg(not(target_arch = "arm"))]
    let round = round.with_scores(&record.scored.weights, &record.scored.scores);
    learner
        .learn(&round, feedback)
        .map_err(FeedbackError::Learn)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::feedback::ActionFeedback;
    use crate::learner::LearnerParams;

    fn agent() -> Agent {
        Agent::new(Learner::new(LearnerParams::paper().check().unwrap()))
    }

    fn fb(a: usize) -> Feedback {
        Feedback::Action(ActionFeedback {
            action: ActionIndex::new(a).unwrap(),
        })
    }

    #[test]
    fn feedback_reaches_back_tick_history_ticks() {
        let mut ag = agent();
        let obs = Observation::open_space();
        for t in 0..10 {
            ag.act(t, &obs).unwrap();
        }
        for t in 10 - TICK_HISTORY as u32..10 {
            assert!(ag.feedback(t, &fb(3)).is_ok(), "tick {t}");
        }
        assert_eq!(
            ag.feedback(5, &fb(3)).unwrap_err(),
            FeedbackError::UnknownTick(5)
        );
    }

    #[test]
    fn a_path_statement_is_judged_against_its_own_tick_s_path_reference() {
        use crate::feature::Feature;
        use crate::feedback::SemanticFeedback;
        let mut ag = agent();
        let ahead = Observation::open_space();
        let mut left = ahead.clone();
        left.reference.y = 0.5;
        // Zero weights drive straight. With the path straight ahead, straight is already on it:
        // "stay on the path" has nothing better to point to. With the path half a metre to the
        // left, the left turns are better: the learner steps.
        ag.act(1, &ahead).unwrap();
        ag.act(2, &left).unwrap();
        let stay = Feedback::Semantic(SemanticFeedback::new().prefer(Feature::Path));
        assert!(!ag.feedback(1, &stay).unwrap().stepped);
        assert!(ag.feedback(2, &stay).unwrap().stepped);
        assert!(ag.learner().weights() != &[0.0; crate::FEATURE_COUNT]);
    }

    #[test]
    fn acting_on_an_evaluation_equals_acting_on_the_observation() {
        let mut obs = Observation::open_space();
        for j in 0..crate::observation::SCAN_BEAMS {
            let (c, _) = crate::evaluator::beam_direction(j).unwrap();
            if c > 0.2 {
                obs.scan.ranges[j] = 1.2 / c;
            }
        }
        let (mut own, mut taking) = (agent(), agent());
        let evaluation = Evaluator::new().evaluation(obs.check().unwrap());
        let d = own.act(1, &obs).unwrap();
        assert_eq!(taking.act_evaluated(1, &evaluation), d);
        assert_eq!(d.allowed, evaluation.allowed());
        // The same record behind the tick: the same learning step.
        assert_eq!(own.feedback(1, &fb(3)), taking.feedback(1, &fb(3)));
        assert_eq!(own.learner(), taking.learner());
    }

    #[test]
    fn a_blank_agent_given_its_learner_is_a_new_one() {
        let mut blank = Agent::BLANK;
        assert_eq!(blank.learner().params().get().step, 0.0, "a placeholder");
        let learner = Learner::new(LearnerParams::default().check().unwrap());
        blank.set_learner(learner);
        let mut new = Agent::new(learner);
        assert_eq!(format!("{blank:?}"), format!("{new:?}"));
        let obs = Observation::open_space();
        assert_eq!(blank.act(1, &obs), new.act(1, &obs));
        assert_eq!(blank.feedback(1, &fb(3)), new.feedback(1, &fb(3)));
        assert_eq!(blank.learner(), new.learner());
    }

    #[test]
    fn a_bad_observation_changes_nothing() {
        let mut ag = agent();
        let obs = Observation::open_space();
        ag.act(1, &obs).unwrap();
        let mut bad = obs.clone();
        bad.scan.ranges[0] = f32::NAN;
        assert!(ag.act(2, &bad).is_err());
        assert!(ag.feedback(1, &fb(3)).is_ok(), "tick 1 still remembered");
        assert!(ag.feedback(2, &fb(3)).is_err());
    }

    #[test]
    fn everything_blocked_means_stop() {
        let mut ag = agent();
        let mut obs = Observation::open_space();
        obs.scan.ranges = [0.1; crate::observation::SCAN_BEAMS];
        let d = ag.act(1, &obs).unwrap();
        assert_eq!((d.action, d.allowed), (None, ActionMask::NONE));
        assert_eq!(
            ag.feedback(1, &fb(0)).unwrap_err(),
            FeedbackError::UnknownTick(1)
        );
    }

    #[test]
    fn a_forbidden_teacher_action_is_refused() {
        let mut ag = agent();
        let mut obs = Observation::open_space();
        // A wall 1.2 m ahead blocks the straight cruise trajectory.
        for j in 0..crate::observation::SCAN_BEAMS {
            let (c, _) = crate::evaluator::beam_direction(j).unwrap();
            if c > 0.2 {
                obs.scan.ranges[j] = 1.2 / c;
            }
        }
        let d = ag.act(1, &obs).unwrap();
        assert!(!d.allowed.contains(ActionIndex::FIRST));
        let before = *ag.learner();
        assert!(matches!(
            ag.feedback(1, &fb(0)),
            Err(FeedbackError::Learn(LearnError::ActionNotAllowed(_)))
        ));
        assert_eq!(*ag.learner(), before);
    }
}
