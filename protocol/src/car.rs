//! The car's side of the link: one [`CarNode`] per controller, shared by the `hil_mock` process
//! and the `no_std` firmware.
//!
//! A node holds the `firmware-core` [`Agent`], the car's [`Inbox`], the [`FeedbackReceiver`]
//! (dedupe window), the host's configuration session, the watchdog and counters. The caller owns
//! the bus, the clock and the flash: it hands every received frame to [`CarNode::on_frame`] and
//! calls [`CarNode::poll`] often (every few milliseconds) for the watchdog and the reassembly
//! timeouts. No heap, no clock, no `unsafe`. A node is about 11.5 KiB (the agent and the
//! inbox's six reassembly buffers); [`CarNode::new`] is a `const fn` and [`CarNode::load`]
//! restores in place, so firmware can keep it in a `static`.
//!
//! | received | the car does | answers |
//! |---|---|---|
//! | observation of tick `t` | `agent.act(t, obs)`; clears a stop; feeds the watchdog | [`Message::Action`] of `t` with the collision mask, or [`ErrorCode::Observation`] |
//! | feedback `id` about tick `t` | applies it once ([`FeedbackReceiver`]); a fresh one is persisted *before* the ack | [`Message::Ack`] / [`Message::Nack`], the same for every copy; [`ErrorCode::Internal`] when persisting failed (no ack: the host retransmits) |
//! | configure `(session, snapshot)` | a new session: `Learner::restore(snapshot)`, forgets its ticks and dedupe window, persists; the current session: nothing (a copy) | [`Message::Weights`] (current), or [`ErrorCode::Params`] |
//! | weights request | nothing | [`Message::Weights`] |
//! | heartbeat | nothing | [`Message::Heartbeat`] with the car's own counter |
//! | reset | stops, forgets its ticks and dedupe window, disarms the watchdog, keeps the learner | nothing |
//! | a lost message (reassembly, decode, wrong stream) | nothing | [`Message::Error`] with its code |
//!
//! **Watchdog.** Once observations have been coming, a gap of [`CarConfig::watchdog_ms`] without
//! one makes [`CarNode::poll`] transmit one stop ([`ActionCommand`] with no track, empty mask)
//! for the last tick and mark the node [`stopped`](CarNode::stopped); the next accepted
//! observation resumes.
//!
//! **Persistence.** After every applied feedback and every new configuration, the node hands
//! [`Persisted`] (session, learner snapshot, feedback receiver) to the caller's [`Persist`]
//! before it answers, so an ack always means "in flash". [`CarNode::restore`] starts a node from
//! it: the restored receiver acks copies of feedback applied before the restart instead of
//! applying them again. A failed write is counted and reported with [`ErrorCode::Internal`]; the
//! state is written again before the next ack or weights report of a configuration.
//!
//! ```
//! use firmware_core::{Learner, LearnerParams};
//! use firmware_core::observation::Observation;
//! use protocol::can::{CanBus, CanFrame};
//! use protocol::car::{CarConfig, CarNode, Persist, Persisted};
//! use protocol::isotp::FrameMode;
//! use protocol::link::{Inbox, Received, transmit};
//! use protocol::message::{Message, ObservationMessage};
//! use protocol::stream::Direction;
//!
//! #[derive(Default)]
//! struct Wire(Vec<CanFrame>);
//! impl CanBus for Wire {
//!     type Error = ();
//!     fn transmit(&mut self, f: &CanFrame) -> Result<(), ()> { self.0.push(*f); Ok(()) }
//!     fn receive(&mut self) -> Result<Option<CanFrame>, ()> { Ok(None) }
//! }
//! struct NoFlash;
//! impl Persist for NoFlash {
//!     type Error = ();
//!     fn persist(&mut self, _: &Persisted) -> Result<(), ()> { Ok(()) }
//! }
//!
//! let learner = Learner::new(LearnerParams::default().check().unwrap());
//! let mut car = CarNode::new(CarConfig::default(), learner);
//! let (mut to_car, mut to_host) = (Wire::default(), Wire::default());
//! let obs = Message::Observation(ObservationMessage { tick: 1, observation: Observation::open_space() });
//! transmit(&mut to_car, &obs, Direction::HostToCar, FrameMode::Fd).unwrap();
//! for f in &to_car.0 {
//!     car.on_frame(f, 0, &mut to_host, &mut NoFlash).unwrap();
//! }
//! let mut host = Inbox::new(Direction::CarToHost);
//! let answer = to_host.0.iter().map(|f| host.feed(f, 0)).last().unwrap();
//! let Received::Message(Message::Action(cmd)) = answer else { panic!() };
//! assert_eq!((cmd.tick, car.stats().actions), (1, 1));
//! ```

use core::fmt;

use firmware_core::agent::Agent;
use firmware_core::{Learner, LearnerSnapshot, SnapshotError, ValidLearnerParams};
use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

use crate::can::{CanBus, CanFrame};
use crate::delivery::{FeedbackReceiver, Reply, Verdict};
use crate::envelope::ENVELOPE_OVERHEAD;
use crate::isotp::FrameMode;
use crate::link::{Inbox, LinkError, Received, TransmitError, transmit};
use crate::message::{
    ActionCommand, ConfigureMessage, ErrorCode, ErrorReport, FeedbackMessage, Heartbeat, Message,
    NackCode, ObservationMessage,
};
use crate::stream::Direction;

/// What the car keeps in flash: enough to continue exactly where it was.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, MaxSize)]
pub struct Persisted {
    /// The host's configuration session the learner belongs to (`None`: never configured).
    pub session: Option<u8>,
    /// The learner.
    pub snapshot: LearnerSnapshot,
    /// The feedback dedupe window, with the verdict of the last feedback applied.
    pub receiver: FeedbackReceiver,
}

/// The largest [`Persisted`] sealed in a protocol envelope ([`crate::seal`]), in bytes.
pub const PERSISTED_MAX_SIZE: usize = ENVELOPE_OVERHEAD + Persisted::POSTCARD_MAX_SIZE;

/// Where the car writes its [`Persisted`] state (flash pages, a file).
pub trait Persist {
    /// Why a write failed.
    type Error: fmt::Debug;

    /// Writes `state` durably; returns only when a restart would find it.
    fn persist(&mut self, state: &Persisted) -> Result<(), Self::Error>;
}

/// How a node behaves.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct CarConfig {
    /// Stop when no observation came for this long after observations had been coming (ms).
    pub watchdog_ms: u32,
    /// The frames the node transmits (classic CAN or CAN FD). It receives both.
    pub mode: FrameMode,
}

/// The default watchdog: two ticks at 10 Hz.
pub const DEFAULT_WATCHDOG_MS: u32 = 200;

impl CarConfig {
    /// 200 ms watchdog, classic CAN frames.
    pub const DEFAULT: Self = Self {
        watchdog_ms: DEFAULT_WATCHDOG_MS,
        mode: FrameMode::Classic,
    };
}

impl Default for CarConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// What a node has done since it started (not persisted).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct CarStats {
    /// Observations received (accepted or refused).
    pub observations: u32,
    /// Action commands sent in answer to observations (watchdog stops not included).
    pub actions: u32,
    /// Stops commanded by the watchdog.
    pub watchdog_stops: u32,
    /// Feedback applied to the learner (each delivery once).
    pub feedback_applied: u32,
    /// Copies of feedback already answered: acked or nacked again, not applied.
    pub feedback_duplicates: u32,
    /// Feedback refused (nacked) the first time it came.
    pub feedback_refused: u32,
    /// Error reports sent (lost messages, refused observations or configurations, failed writes).
    pub errors: u32,
    /// Writes of the persisted state that failed.
    pub persist_failures: u32,
}

impl CarStats {
    const ZERO: Self = Self {
        observations: 0,
        actions: 0,
        watchdog_stops: 0,
        feedback_applied: 0,
        feedback_duplicates: 0,
        feedback_refused: 0,
        errors: 0,
        persist_failures: 0,
    };
}

/// Counters saturate instead of overflowing (a car may run for years).
fn bump(counter: &mut u32) {
    *counter = counter.saturating_add(1);
}

/// Why a node could not be restored.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum RestoreError {
    /// The persisted learner snapshot is refused by `Learner::restore`.
    Snapshot(SnapshotError),
}

impl fmt::Display for RestoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RestoreError::Snapshot(e) => write!(f, "persisted learner refused: {e}"),
        }
    }
}

impl core::error::Error for RestoreError {}

/// The car's controller: agent, inbox, dedupe window, session, watchdog, counters.
#[derive(Clone, Debug)]
pub struct CarNode {
    config: CarConfig,
    agent: Agent,
    inbox: Inbox,
    receiver: FeedbackReceiver,
    session: Option<u8>,
    /// The last tick acted in, and when its observation came (ms); `None`: watchdog disarmed.
    watched: Option<(u32, u32)>,
    stopped: bool,
    /// The state in RAM is newer than the last successful write.
    dirty: bool,
    heartbeat: u16,
    stats: CarStats,
}

impl CarNode {
    /// A node with `learner`, never configured, stopped, with an empty dedupe window.
    pub const fn new(config: CarConfig, learner: Learner) -> Self {
        Self {
            config,
            agent: Agent::new(learner),
            inbox: Inbox::new(Direction::HostToCar),
            receiver: FeedbackReceiver::new(),
            session: None,
            watched: None,
            stopped: true,
            dirty: false,
            heartbeat: 0,
            stats: CarStats::ZERO,
        }
    }

    /// A node continuing from `state` (read back from flash): its learner, session and dedupe
    /// window; no recent ticks; stopped.
    pub fn restore(config: CarConfig, state: &Persisted) -> Result<Self, RestoreError> {
        let mut node = Self::new(config, Learner::new(ValidLearnerParams::DEFAULT));
        node.load(state)?;
        Ok(node)
    }

    /// [`CarNode::restore`] in place, for a node that lives in a `static` (a node is about
    /// 11.5 KiB; this moves none of it). Counters and configuration are kept; on `Err` nothing
    /// changed.
    pub fn load(&mut self, state: &Persisted) -> Result<(), RestoreError> {
        let learner = Learner::restore(&state.snapshot).map_err(RestoreError::Snapshot)?;
        self.agent.set_learner(learner);
        self.stand();
        self.inbox.reset();
        self.receiver = state.receiver.clone();
        self.session = state.session;
        self.dirty = false;
        Ok(())
    }

    /// Forgets the recent ticks and disarms the watchdog: stopped until the next observation.
    fn stand(&mut self) {
        self.agent.forget_ticks();
        self.watched = None;
        self.stopped = true;
    }

    /// The state to persist now.
    pub fn persisted(&self) -> Persisted {
        Persisted {
            session: self.session,
            snapshot: self.agent.learner().snapshot(),
            receiver: self.receiver.clone(),
        }
    }

    /// The counters.
    pub fn stats(&self) -> CarStats {
        self.stats
    }

    /// The agent (learner and recent ticks).
    pub fn agent(&self) -> &Agent {
        &self.agent
    }

    /// The configuration.
    pub fn config(&self) -> CarConfig {
        self.config
    }

    /// The host's configuration session, if configured.
    pub fn session(&self) -> Option<u8> {
        self.session
    }

    /// Whether the car is standing: before its first action, after a watchdog stop or a reset,
    /// and while every trajectory collides.
    pub fn stopped(&self) -> bool {
        self.stopped
    }

    /// Handles one received frame at `now_ms`, transmitting any answer on `bus` and persisting
    /// through `store`. Frames of other nodes and of the car's own direction are ignored.
    ///
    /// An `Err` is the bus refusing a frame of the answer: the message is lost (the host
    /// retransmits), the node's state is consistent.
    pub fn on_frame<B: CanBus, P: Persist>(
        &mut self,
        frame: &CanFrame,
        now_ms: u32,
        bus: &mut B,
        store: &mut P,
    ) -> Result<(), B::Error> {
        match self.inbox.feed(frame, now_ms) {
            Received::Nothing => Ok(()),
            Received::Error(e) => self.report_link_error(e, bus),
            Received::Message(msg) => self.on_message(msg, now_ms, bus, store),
        }
    }

    /// The watchdog and the reassembly timeouts at `now_ms`; call every few milliseconds.
    pub fn poll<B: CanBus>(&mut self, now_ms: u32, bus: &mut B) -> Result<(), B::Error> {
        while let Some(e) = self.inbox.poll(now_ms) {
            self.report_link_error(e, bus)?;
        }
        if let Some((tick, since)) = self.watched
            && !self.stopped
            && now_ms.wrapping_sub(since) >= self.config.watchdog_ms
        {
            self.stopped = true;
            bump(&mut self.stats.watchdog_stops);
            self.send(bus, &Message::Action(ActionCommand::stop(tick)))?;
        }
        Ok(())
    }

    fn on_message<B: CanBus, P: Persist>(
        &mut self,
        msg: Message,
        now_ms: u32,
        bus: &mut B,
        store: &mut P,
    ) -> Result<(), B::Error> {
        match msg {
            Message::Observation(o) => self.on_observation(&o, now_ms, bus),
            Message::Feedback(f) => self.on_feedback(&f, bus, store),
            Message::Configure(c) => self.on_configure(&c, bus, store),
            Message::WeightsRequest => self.send_weights(bus),
            Message::Heartbeat(_) => {
                let counter = self.heartbeat;
                self.heartbeat = self.heartbeat.wrapping_add(1);
                self.send(bus, &Message::Heartbeat(Heartbeat { counter }))
            }
            Message::Reset => {
                self.stand();
                self.receiver.reset();
                Ok(())
            }
            // The host's error reports and anything else the inbox lets through: nothing to do.
            _ => Ok(()),
        }
    }

    fn on_observation<B: CanBus>(
        &mut self,
        o: &ObservationMessage,
        now_ms: u32,
        bus: &mut B,
    ) -> Result<(), B::Error> {
        bump(&mut self.stats.observations);
        match self.agent.act(o.tick, &o.observation) {
            Ok(decision) => {
                bump(&mut self.stats.actions);
                self.stopped = decision.action.is_none();
                self.watched = Some((o.tick, now_ms));
                self.send(bus, &Message::Action(ActionCommand::from(&decision)))
            }
            Err(_) => self.report(ErrorCode::Observation, Some(o.tick), bus),
        }
    }

    fn on_feedback<B: CanBus, P: Persist>(
        &mut self,
        f: &FeedbackMessage,
        bus: &mut B,
        store: &mut P,
    ) -> Result<(), B::Error> {
        let agent = &mut self.agent;
        let mut fresh = false;
        let reply = self.receiver.receive(f, |m| {
            fresh = true;
            match agent.feedback(m.tick, &m.feedback) {
                Ok(_) => Verdict::Applied,
                Err(e) => Verdict::Refused(NackCode::from(&e)),
            }
        });
        match (fresh, reply) {
            (true, Reply::Ack(_)) => {
                bump(&mut self.stats.feedback_applied);
                self.dirty = true;
            }
            (true, Reply::Nack(_)) => bump(&mut self.stats.feedback_refused),
            (false, _) => bump(&mut self.stats.feedback_duplicates),
        }
        // An ack means "in flash": write first (again, if an earlier write failed).
        if matches!(reply, Reply::Ack(_)) && !self.commit(store) {
            return self.report(ErrorCode::Internal, Some(f.tick), bus);
        }
        self.send(bus, &reply.into())
    }

    fn on_configure<B: CanBus, P: Persist>(
        &mut self,
        c: &ConfigureMessage,
        bus: &mut B,
        store: &mut P,
    ) -> Result<(), B::Error> {
        if self.session != Some(c.session) {
            let Ok(learner) = Learner::restore(&c.snapshot) else {
                return self.report(ErrorCode::Params, None, bus);
            };
            self.agent.set_learner(learner);
            self.stand();
            self.receiver.reset();
            self.session = Some(c.session);
            self.dirty = true;
        }
        if !self.commit(store) {
            return self.report(ErrorCode::Internal, None, bus);
        }
        self.send_weights(bus)
    }

    /// Writes the state if it changed since the last successful write; false if that failed.
    fn commit<P: Persist>(&mut self, store: &mut P) -> bool {
        if !self.dirty {
            return true;
        }
        match store.persist(&self.persisted()) {
            Ok(()) => {
                self.dirty = false;
                true
            }
            Err(_) => {
                bump(&mut self.stats.persist_failures);
                false
            }
        }
    }

    fn send_weights<B: CanBus>(&mut self, bus: &mut B) -> Result<(), B::Error> {
        let snapshot = self.agent.learner().snapshot();
        self.send(bus, &Message::Weights(snapshot))
    }

    fn report_link_error<B: CanBus>(&mut self, e: LinkError, bus: &mut B) -> Result<(), B::Error> {
        self.report(e.code(), None, bus)
    }

    fn report<B: CanBus>(
        &mut self,
        code: ErrorCode,
        tick: Option<u32>,
        bus: &mut B,
    ) -> Result<(), B::Error> {
        bump(&mut self.stats.errors);
        self.send(bus, &Message::Error(ErrorReport { code, tick }))
    }

    fn send<B: CanBus>(&mut self, bus: &mut B, msg: &Message) -> Result<(), B::Error> {
        match transmit(bus, msg, Direction::CarToHost, self.config.mode) {
            Ok(_) => Ok(()),
            Err(TransmitError::Bus { error, .. }) => Err(error),
            // Every message the node sends travels car → host and fits the buffers.
            Err(_) => {
                bump(&mut self.stats.errors);
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::delivery::DEDUPE_WINDOW;
    use crate::message::{Ack, DeliveryId, Nack};
    use firmware_core::observation::Observation;
    use firmware_core::{ActionFeedback, ActionIndex, Feedback, LearnerParams, OnlineLearner};
    use std::vec::Vec;

    /// Frames one way.
    #[derive(Default)]
    struct Wire(Vec<CanFrame>);

    impl CanBus for Wire {
        type Error = &'static str;
        fn transmit(&mut self, f: &CanFrame) -> Result<(), &'static str> {
            self.0.push(*f);
            Ok(())
        }
        fn receive(&mut self) -> Result<Option<CanFrame>, &'static str> {
            Ok((!self.0.is_empty()).then(|| self.0.remove(0)))
        }
    }

    /// A RAM flash that can be made to fail.
    #[derive(Default)]
    struct Ram {
        stored: Option<Persisted>,
        writes: u32,
        broken: bool,
    }

    impl Persist for Ram {
        type Error = &'static str;
        fn persist(&mut self, state: &Persisted) -> Result<(), &'static str> {
            if self.broken {
                return Err("flash worn out");
            }
            self.writes += 1;
            self.stored = Some(state.clone());
            Ok(())
        }
    }

    fn learner() -> Learner {
        Learner::new(LearnerParams::paper().check().unwrap())
    }

    fn node() -> CarNode {
        CarNode::new(CarConfig::default(), learner())
    }

    /// The car with its flash, and the host's inbox.
    struct Bench {
        car: CarNode,
        flash: Ram,
        host: Inbox,
    }

    impl Bench {
        fn new(car: CarNode) -> Self {
            Self {
                car,
                flash: Ram::default(),
                host: Inbox::new(Direction::CarToHost),
            }
        }

        /// Sends `msg` (in CAN FD frames) at `now`; returns what the car answered.
        fn send(&mut self, msg: &Message, now: u32) -> Vec<Message> {
            let mut to_car = Wire::default();
            transmit(&mut to_car, msg, Direction::HostToCar, FrameMode::Fd).unwrap();
            let mut frames = Vec::new();
            for f in &to_car.0 {
                self.frames_in(f, now, &mut frames);
            }
            frames
        }

        fn frames_in(&mut self, f: &CanFrame, now: u32, out: &mut Vec<Message>) {
            let mut to_host = Wire::default();
            self.car
                .on_frame(f, now, &mut to_host, &mut self.flash)
                .unwrap();
            out.extend(self.decode(&to_host));
        }

        fn poll(&mut self, now: u32) -> Vec<Message> {
            let mut to_host = Wire::default();
            self.car.poll(now, &mut to_host).unwrap();
            self.decode(&to_host)
        }

        fn decode(&mut self, wire: &Wire) -> Vec<Message> {
            let mut out = Vec::new();
            for f in &wire.0 {
                match self.host.feed(f, 0) {
                    Received::Message(m) => out.push(m),
                    Received::Nothing => {}
                    Received::Error(e) => panic!("the car sent a bad message: {e}"),
                }
            }
            out
        }

        fn observe(&mut self, tick: u32, now: u32) -> Vec<Message> {
            self.send(&observation(tick), now)
        }
    }

    fn observation(tick: u32) -> Message {
        Message::Observation(ObservationMessage {
            tick,
            observation: Observation::open_space(),
        })
    }

    fn feedback(seq: u8, tick: u32, action: usize) -> Message {
        Message::Feedback(FeedbackMessage {
            id: DeliveryId { session: 4, seq },
            tick,
            feedback: Feedback::Action(ActionFeedback {
                action: ActionIndex::new(action).unwrap(),
            }),
        })
    }

    fn ack(seq: u8) -> Message {
        Message::Ack(Ack {
            id: DeliveryId { session: 4, seq },
        })
    }

    fn error(code: ErrorCode, tick: Option<u32>) -> Message {
        Message::Error(ErrorReport { code, tick })
    }

    #[test]
    fn an_observation_is_answered_with_the_agent_s_action_and_mask() {
        let mut b = Bench::new(node());
        let mut reference = Agent::new(learner());
        let d = reference.act(5, &Observation::open_space()).unwrap();
        assert!(b.car.stopped(), "standing before the first action");
        let got = b.observe(5, 0);
        assert_eq!(got, [Message::Action(ActionCommand::from(&d))]);
        let Message::Action(cmd) = &got[0] else {
            unreachable!()
        };
        assert_eq!((cmd.action(), cmd.allowed), (d.action, d.allowed));
        assert!(!cmd.allowed.is_empty());
        assert!(!b.car.stopped());
        let s = b.car.stats();
        assert_eq!((s.observations, s.actions, s.errors), (1, 1, 0));
    }

    #[test]
    fn a_refused_observation_is_an_error_report_of_its_tick() {
        let mut b = Bench::new(node());
        let mut obs = Observation::open_space();
        obs.scan.ranges[3] = f32::NAN;
        let msg = Message::Observation(ObservationMessage {
            tick: 9,
            observation: obs,
        });
        assert_eq!(b.send(&msg, 0), [error(ErrorCode::Observation, Some(9))]);
        let s = b.car.stats();
        assert_eq!((s.observations, s.actions, s.errors), (1, 0, 1));
        // Nothing was remembered: feedback about tick 9 is refused.
        assert_eq!(
            b.send(&feedback(0, 9, 3), 1),
            [Message::Nack(Nack {
                id: DeliveryId { session: 4, seq: 0 },
                code: NackCode::UnknownTick
            })]
        );
    }

    #[test]
    fn feedback_is_applied_once_persisted_before_its_ack_and_every_copy_is_acked() {
        let mut b = Bench::new(node());
        b.observe(1, 0);
        let before = *b.car.agent().learner();
        assert_eq!(b.send(&feedback(0, 1, 3), 1), [ack(0)]);
        let after = *b.car.agent().learner();
        assert_ne!(after, before, "the feedback moved the weights");
        // Persisted before the ack went out: the flash holds the new learner and the verdict.
        assert_eq!(b.flash.writes, 1);
        assert_eq!(b.flash.stored.as_ref(), Some(&b.car.persisted()));
        assert_eq!(b.flash.stored.as_ref().unwrap().snapshot, after.snapshot());
        for now in 2..5 {
            assert_eq!(b.send(&feedback(0, 1, 3), now), [ack(0)]);
        }
        assert_eq!(*b.car.agent().learner(), after, "copies are not applied");
        assert_eq!(b.flash.writes, 1, "nor written");
        let s = b.car.stats();
        assert_eq!((s.feedback_applied, s.feedback_duplicates), (1, 3));
        // The same, learned by a bare agent: one step.
        let mut reference = Agent::new(learner());
        reference.act(1, &Observation::open_space()).unwrap();
        reference
            .feedback(
                1,
                &Feedback::Action(ActionFeedback {
                    action: ActionIndex::new(3).unwrap(),
                }),
            )
            .unwrap();
        assert_eq!(*reference.learner(), after);
    }

    #[test]
    fn refused_feedback_is_nacked_every_time_and_not_persisted() {
        let mut b = Bench::new(node());
        let nack = Message::Nack(Nack {
            id: DeliveryId { session: 4, seq: 7 },
            code: NackCode::UnknownTick,
        });
        assert_eq!(b.send(&feedback(7, 77, 1), 0), core::slice::from_ref(&nack));
        assert_eq!(b.send(&feedback(7, 77, 1), 0), [nack]);
        let s = b.car.stats();
        assert_eq!((s.feedback_refused, s.feedback_duplicates), (1, 1));
        assert_eq!(b.flash.writes, 0);
    }

    #[test]
    fn a_failed_write_withholds_the_ack_until_a_retransmission_finds_the_flash_working() {
        let mut b = Bench::new(node());
        b.observe(1, 0);
        b.flash.broken = true;
        assert_eq!(
            b.send(&feedback(0, 1, 3), 1),
            [error(ErrorCode::Internal, Some(1))]
        );
        let applied = *b.car.agent().learner();
        // Still broken: the copy is not applied again, and still not acked.
        assert_eq!(
            b.send(&feedback(0, 1, 3), 2),
            [error(ErrorCode::Internal, Some(1))]
        );
        b.flash.broken = false;
        assert_eq!(b.send(&feedback(0, 1, 3), 3), [ack(0)]);
        assert_eq!(*b.car.agent().learner(), applied);
        assert_eq!(
            b.flash.stored.as_ref().unwrap().snapshot,
            applied.snapshot()
        );
        let s = b.car.stats();
        assert_eq!(
            (s.feedback_applied, s.persist_failures, s.errors),
            (1, 2, 2)
        );
    }

    #[test]
    fn a_restored_node_acks_a_retransmitted_feedback_without_applying_it() {
        let mut b = Bench::new(node());
        b.observe(1, 0);
        b.observe(2, 100);
        assert_eq!(b.send(&feedback(0, 1, 3), 101), [ack(0)]);
        assert_eq!(b.send(&feedback(1, 2, 5), 102), [ack(1)]);
        // Power cut: the ack of seq 1 never reached the host. The car restarts from flash.
        let state = b.flash.stored.clone().unwrap();
        let restored = CarNode::restore(CarConfig::default(), &state).unwrap();
        assert_eq!(*restored.agent().learner(), *b.car.agent().learner());
        assert!(restored.stopped());
        let mut b2 = Bench::new(restored);
        let learner = *b2.car.agent().learner();
        assert_eq!(b2.send(&feedback(1, 2, 5), 0), [ack(1)]);
        assert_eq!(*b2.car.agent().learner(), learner, "not applied twice");
        let s = b2.car.stats();
        assert_eq!((s.feedback_applied, s.feedback_duplicates), (0, 1));
        // New feedback about a tick from before the restart: refused, the ticks are gone.
        assert!(matches!(
            b2.send(&feedback(2, 2, 5), 1)[..],
            [Message::Nack(Nack {
                code: NackCode::UnknownTick,
                ..
            })]
        ));
        // The restored state round-trips through the envelope the flash uses.
        let mut buf = [0u8; PERSISTED_MAX_SIZE];
        let bytes = crate::seal(&state, &mut buf).unwrap();
        assert!(bytes.len() <= PERSISTED_MAX_SIZE);
        assert_eq!(crate::open::<Persisted>(bytes).unwrap(), state);
    }

    #[test]
    fn load_restores_in_place() {
        let mut b = Bench::new(node());
        b.observe(1, 0);
        b.send(&feedback(0, 1, 3), 1);
        let state = b.flash.stored.clone().unwrap();
        let mut other = node();
        other.load(&state).unwrap();
        assert_eq!(other.persisted(), state);
        assert!(other.stopped());
        let mut bad = state.clone();
        bad.snapshot.state.average[0] = f32::INFINITY;
        assert!(other.load(&bad).is_err());
        assert_eq!(other.persisted(), state, "unchanged on Err");
        // The loaded node dedupes like the restored one.
        let mut b2 = Bench::new(other);
        assert_eq!(b2.send(&feedback(0, 1, 3), 0), [ack(0)]);
        assert_eq!(b2.car.stats().feedback_applied, 0);
    }

    #[test]
    fn a_bad_persisted_snapshot_is_refused() {
        let mut state = node().persisted();
        state.snapshot.version = 99;
        assert!(matches!(
            CarNode::restore(CarConfig::default(), &state),
            Err(RestoreError::Snapshot(SnapshotError::Version(99)))
        ));
    }

    fn configure(session: u8, learner: &Learner) -> Message {
        Message::Configure(ConfigureMessage {
            session,
            snapshot: learner.snapshot(),
        })
    }

    #[test]
    fn configure_replaces_the_learner_once_per_session() {
        let mut b = Bench::new(node());
        b.observe(1, 0);
        b.send(&feedback(0, 1, 3), 1);
        let mut fresh = Learner::new(LearnerParams::default().check().unwrap());
        fresh.step(&[0.5, 0.0, 0.0, -0.25, 0.0, 1.0]).unwrap();
        assert_eq!(
            b.send(&configure(1, &fresh), 2),
            [Message::Weights(fresh.snapshot())]
        );
        assert_eq!(*b.car.agent().learner(), fresh);
        assert_eq!(b.car.session(), Some(1));
        let stored = b.flash.stored.clone().unwrap();
        assert_eq!(
            (stored.session, stored.snapshot),
            (Some(1), fresh.snapshot())
        );
        assert_eq!(stored.receiver, FeedbackReceiver::new(), "window reset");
        // The old tick is forgotten.
        assert!(matches!(
            b.send(&feedback(1, 1, 3), 3)[..],
            [Message::Nack(Nack {
                code: NackCode::UnknownTick,
                ..
            })]
        ));
        // The learner moves on; a late copy of the configure does not reset it.
        b.observe(2, 4);
        assert_eq!(b.send(&feedback(2, 2, 9), 5), [ack(2)]);
        let learned = *b.car.agent().learner();
        assert_ne!(learned, fresh);
        let writes = b.flash.writes;
        assert_eq!(
            b.send(&configure(1, &fresh), 6),
            [Message::Weights(learned.snapshot())]
        );
        assert_eq!(*b.car.agent().learner(), learned);
        assert_eq!(b.flash.writes, writes);
        // And it still knows tick 2.
        assert_eq!(b.send(&feedback(2, 2, 9), 7), [ack(2)]);
        // A new session applies again; an invalid snapshot is refused and changes nothing.
        assert_eq!(
            b.send(&configure(2, &fresh), 8),
            [Message::Weights(fresh.snapshot())]
        );
        let mut bad = fresh.snapshot();
        bad.state.iterate[0] = f32::NAN;
        let msg = Message::Configure(ConfigureMessage {
            session: 3,
            snapshot: bad,
        });
        assert_eq!(b.send(&msg, 9), [error(ErrorCode::Params, None)]);
        assert_eq!(
            (b.car.session(), *b.car.agent().learner()),
            (Some(2), fresh)
        );
    }

    #[test]
    fn weights_requests_heartbeats_and_reset() {
        let mut b = Bench::new(node());
        let snap = b.car.agent().learner().snapshot();
        assert_eq!(
            b.send(&Message::WeightsRequest, 0),
            [Message::Weights(snap)]
        );
        let hb = |counter| Message::Heartbeat(Heartbeat { counter });
        assert_eq!(b.send(&hb(100), 0), [hb(0)]);
        assert_eq!(b.send(&hb(101), 0), [hb(1)]);
        b.observe(1, 0);
        assert!(!b.car.stopped());
        assert_eq!(b.send(&Message::Reset, 1), []);
        assert!(b.car.stopped());
        assert!(matches!(
            b.send(&feedback(0, 1, 3), 2)[..],
            [Message::Nack(Nack {
                code: NackCode::UnknownTick,
                ..
            })]
        ));
        assert_eq!(b.poll(10_000), [], "the watchdog is disarmed by a reset");
        assert_eq!(b.car.agent().learner().snapshot(), snap, "learner kept");
    }

    #[test]
    fn the_watchdog_stops_once_and_the_next_observation_resumes() {
        let mut b = Bench::new(node());
        assert_eq!(b.poll(1_000), [], "no observation yet: nothing to watch");
        b.observe(1, 1_000);
        b.observe(2, 1_100);
        assert_eq!(b.poll(1_299), []);
        assert_eq!(b.poll(1_300), [Message::Action(ActionCommand::stop(2))]);
        assert!(b.car.stopped());
        assert_eq!(b.poll(1_500), [], "one stop, not one per poll");
        assert_eq!(b.car.stats().watchdog_stops, 1);
        // Observations return: the car drives again, and can stop again.
        let got = b.observe(3, 2_000);
        assert!(matches!(
            got[..],
            [Message::Action(ActionCommand {
                tick: 3,
                track: Some(_),
                ..
            })]
        ));
        assert!(!b.car.stopped());
        assert_eq!(b.poll(2_199), []);
        assert_eq!(b.poll(2_200), [Message::Action(ActionCommand::stop(3))]);
        let s = b.car.stats();
        assert_eq!((s.watchdog_stops, s.actions), (2, 3));
        // Wrapping milliseconds.
        let mut b = Bench::new(node());
        b.observe(1, u32::MAX - 50);
        assert_eq!(b.poll(100), []);
        assert_eq!(b.poll(150), [Message::Action(ActionCommand::stop(1))]);
    }

    #[test]
    fn lost_messages_are_reported() {
        let mut b = Bench::new(node());
        // A corrupted single-frame message.
        let mut to_car = Wire::default();
        transmit(
            &mut to_car,
            &Message::WeightsRequest,
            Direction::HostToCar,
            FrameMode::Fd,
        )
        .unwrap();
        let f = to_car.0[0];
        let mut data = [0u8; 64];
        data[..f.data().len()].copy_from_slice(f.data());
        data[2] ^= 0x01;
        let bad = CanFrame::new_fd(f.id(), &data[..f.data().len()]).unwrap();
        let mut got = Vec::new();
        b.frames_in(&bad, 0, &mut got);
        assert_eq!(got, [error(ErrorCode::Decode, None)]);
        // Half an observation, then silence: a reassembly timeout.
        let mut to_car = Wire::default();
        transmit(
            &mut to_car,
            &observation(1),
            Direction::HostToCar,
            FrameMode::Fd,
        )
        .unwrap();
        got.clear();
        b.frames_in(&to_car.0[0], 10, &mut got);
        assert_eq!(got, []);
        assert_eq!(b.poll(10), []);
        assert_eq!(b.poll(1_000), [error(ErrorCode::Reassembly, None)]);
        assert_eq!(b.car.stats().errors, 2);
    }

    #[test]
    fn the_persisted_state_size_is_what_its_fields_add_up_to() {
        // Session 2, snapshot 114 (a weights report less its tag and envelope), receiver
        // 3 + 3 per window slot, envelope 3.
        assert_eq!(PERSISTED_MAX_SIZE, 2 + 114 + 3 + 3 * DEDUPE_WINDOW + 3);
    }
}
