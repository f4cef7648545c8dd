//! The car's side of the link: one [`CarNode`] per controller, shared by the `hil_mock` process
//! and the `no_std` firmware.
//!
//! A node holds the `firmware-core` [`Agent`], the car's [`Inbox`], its [`CarSecurity`] (key,
//! epoch, freshness counters), the [`FeedbackReceiver`] (dedupe windows per session), the
//! configuration session and its generation, the watchdog and counters. The caller owns the bus,
//! the clock and the flash: it hands every received frame to [`CarNode::on_frame`] and calls
//! [`CarNode::poll`] often (every few milliseconds) for the watchdog and the reassembly
//! timeouts. No heap, no clock, no `unsafe`. [`CarNode::new`] is a `const fn` and
//! [`CarNode::load`] restores in place, so firmware can keep the node in a `static`; the key is
//! installed at start ([`CarNode::install_key`]): a node without one accepts nothing.
//!
//! Nothing below happens for a message whose MAC or freshness fails ([`crate::secure`]): it is
//! counted ([`CarStats::refused`]) and not answered.
//!
//! | received | the car does | answers |
//! |---|---|---|
//! | observation of tick `t` | configured: `agent.act(t, obs)`, drives (or stands if every trajectory collides), feeds the watchdog | [`Message::Action`] of `t` with the collision mask; [`ErrorCode::Observation`] if refused; [`ErrorCode::NotConfigured`] without a configured learner |
//! | feedback `id` about tick `t` | of the configured session: applies it once ([`FeedbackReceiver`]), one generation more, persisted *before* the ack | [`Message::Ack`] / [`Message::Nack`], the same for every copy; [`ErrorCode::Internal`] when persisting failed (no ack: the host retransmits) |
//! | feedback of another session | a copy of one applied then: nothing | its recorded answer; otherwise [`NackCode::WrongSession`] |
//! | an E-stop ([`firmware_core::EStopFeedback`]), any session, every copy | first stands (keeping its ticks, so later feedback about them still applies), then as any feedback | a stop ([`StopReason::EStop`]), then the feedback's answer |
//! | configure `(s, snapshot)` | `s` = the next session (any, if none): `Learner::restore(snapshot)`, generation 0, forgets its ticks, stops, persists; `s` = the current session: nothing (a copy) | [`Message::Weights`]; [`ErrorCode::Params`] / [`ErrorCode::Session`] if refused |
//! | weights request | nothing | [`Message::Weights`] |
//! | heartbeat | nothing | [`Message::Heartbeat`] |
//! | reset | stops, forgets its ticks; keeps the learner and the dedupe windows | a stop ([`StopReason::Reset`]) |
//! | hello | moves its freshness window to the host's counter (same epoch) | [`Message::Welcome`]: epoch, counters, [`CarStatus`] |
//! | a lost message (reassembly, decode, wrong stream) | nothing | [`Message::Error`] with its code, at most one per [`ERROR_REPORT_INTERVAL_MS`] |
//!
//! **Safe state.** The car stands before its first action, after a watchdog stop, a reset, a
//! new configuration or an E-stop, and while every trajectory collides; only an accepted observation of a
//! configured learner makes it drive. A reset or a new configuration commands a stop at once.
//! No message disarms the watchdog: once observations have been coming, a gap of
//! [`CarConfig::watchdog_ms`] while driving makes [`CarNode::poll`] command a stop
//! ([`StopReason::Watchdog`]).
//!
//! **Persistence.** After every applied feedback and every new configuration, the node hands
//! [`Persisted`] (session, generation, learner, dedupe windows) to the caller's [`Persist`]
//! before it answers, so an ack always means "in flash". [`CarNode::restore`] starts a node from
//! it: the restored windows ack copies of feedback applied before the restart instead of
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
//! use protocol::message::{ConfigureMessage, Message, ObservationMessage};
//! use protocol::secure::{HostSecurity, Key};
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
//! let key = Key::new([3; 16]);
//! let learner = Learner::new(LearnerParams::default().check().unwrap());
//! let mut car = CarNode::new(CarConfig::default(), learner);
//! car.install_key(&key, 9);
//! let mut host = HostSecurity::assume_fresh_car(&key, 9);
//! let mut host_inbox = Inbox::new(Direction::CarToHost);
//! let mut exchange = |car: &mut CarNode, msg: &Message| {
//!     let (mut to_car, mut to_host) = (Wire::default(), Wire::default());
//!     transmit(&mut to_car, msg, Direction::HostToCar, FrameMode::Fd, &mut host).unwrap();
//!     for f in &to_car.0 {
//!         car.on_frame(f, 0, &mut to_host, &mut NoFlash).unwrap();
//!     }
//!     to_host.0.iter().map(|f| host_inbox.feed(f, 0, &mut host)).last()
//! };
//! let configure = Message::Configure(ConfigureMessage { session: 1, snapshot: learner.snapshot() });
//! exchange(&mut car, &configure);
//! let obs = Message::Observation(ObservationMessage { tick: 1, observation: Observation::open_space() });
//! let Some(Received::Message(Message::Action(cmd))) = exchange(&mut car, &obs) else { panic!() };
//! assert_eq!((cmd.tick, car.stats().actions), (1, 1));
//! ```

use core::fmt;

use firmware_core::agent::Agent;
use firmware_core::{Feedback, Learner, LearnerSnapshot, SnapshotError, ValidLearnerParams};
use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

use crate::can::{CanBus, CanFrame};
use crate::delivery::{FeedbackReceiver, Reply, Verdict};
use crate::envelope::ENVELOPE_OVERHEAD;
use crate::isotp::{DEFAULT_TIMEOUT_MS, FrameMode};
use crate::link::{Inbox, LinkError, Received, TransmitError, transmit};
use crate::message::{
    ActionCommand, CarStatus, ConfigureMessage, ErrorCode, ErrorReport, FeedbackMessage, Hello,
    Message, MessageKind, Nack, NackCode, ObservationMessage, StopReason, WeightsReport,
};
use crate::secure::{CarSecurity, Key, Refusal, RefusalStats};
use crate::stream::Direction;

/// What the car keeps in flash: enough to continue exactly where it was.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, MaxSize)]
pub struct Persisted {
    /// The host's configuration session the learner belongs to (`None`: never configured).
    pub session: Option<u8>,
    /// The snapshot generation: 0 after the configuration, one more per applied feedback.
    pub generation: u32,
    /// The learner.
    pub snapshot: LearnerSnapshot,
    /// The feedback dedupe windows, with the verdict of the last feedback applied.
    pub receiver: FeedbackReceiver,
}

impl Persisted {
    /// The status this state gives the car.
    pub fn status(&self) -> CarStatus {
        CarStatus {
            session: self.session,
            generation: self.generation,
        }
    }
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
    /// Stop when no observation came for this long while driving (ms).
    pub watchdog_ms: u32,
    /// The frames the node transmits (classic CAN or CAN FD). It receives both.
    pub mode: FrameMode,
}

/// The default watchdog: two ticks at 10 Hz.
pub const DEFAULT_WATCHDOG_MS: u32 = 200;

/// The least time between two error reports about lost messages (ms): garbage on the bus is
/// counted, not echoed frame for frame.
pub const ERROR_REPORT_INTERVAL_MS: u32 = 100;

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
    /// Action commands sent in answer to observations (stops for other reasons not included).
    pub actions: u32,
    /// Stops commanded by the watchdog.
    pub watchdog_stops: u32,
    /// Stops commanded because of a reset or a new configuration.
    pub commanded_stops: u32,
    /// Stops commanded by the teacher's E-stops (every copy).
    pub estops: u32,
    /// Feedback applied to the learner (each delivery once).
    pub feedback_applied: u32,
    /// Copies of feedback already answered: acked or nacked again, not applied.
    pub feedback_duplicates: u32,
    /// Feedback refused (nacked) the first time it came, feedback of other sessions included.
    pub feedback_refused: u32,
    /// Messages lost on the way (reassembly, decoding, wrong stream).
    pub lost: u32,
    /// Messages refused by authentication or freshness (forged, replayed, of another epoch).
    pub refused: RefusalStats,
    /// Error reports sent (lost messages, refused observations or configurations, failed writes).
    pub errors: u32,
    /// Writes of the persisted state that failed.
    pub persist_failures: u32,
    /// Observations not acted on because a host message sent after them came first (a copy
    /// the host retransmitted, delayed on the way): counted in `observations` too.
    pub stale_observations: u32,
}

impl CarStats {
    const ZERO: Self = Self {
        observations: 0,
        actions: 0,
        watchdog_stops: 0,
        commanded_stops: 0,
        estops: 0,
        feedback_applied: 0,
        feedback_duplicates: 0,
        feedback_refused: 0,
        lost: 0,
        refused: RefusalStats {
            mac: 0,
            replayed: 0,
            stale: 0,
            unsynced: 0,
        },
        errors: 0,
        persist_failures: 0,
        stale_observations: 0,
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

/// What one frame came to (for the caller's counters and logs).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Outcome {
    /// Nothing complete yet, or not a frame for the car.
    Pending,
    /// An authenticated, fresh message of this kind was handled.
    Accepted(MessageKind),
    /// A message was lost (reassembly, decoding, wrong stream).
    Lost,
    /// A message was refused (authentication or freshness).
    Refused(Refusal),
}

/// The car's controller: agent, inbox, security, dedupe windows, session, watchdog, counters.
#[derive(Clone, Debug)]
pub struct CarNode {
    config: CarConfig,
    agent: Agent,
    inbox: Inbox,
    security: CarSecurity,
    receiver: FeedbackReceiver,
    session: Option<u8>,
    generation: u32,
    /// The last tick acted in, and when its observation came (ms); `None` before the first.
    watched: Option<(u32, u32)>,
    stopped: bool,
    /// The state in RAM is newer than the last successful write.
    dirty: bool,
    /// When the last error report about a lost message went out (ms).
    last_report: Option<u32>,
    stats: CarStats,
}

/// Storage for a [`CarNode`] whose every byte is zero, so that a `static` holding it lands in
/// `.bss`: no flash for an initial value (a `static` [`CarNode::new`] was 11.6 KiB of `.data`
/// when this came, copied from flash at start, of which 19 bytes were not zero), and never built on the stack.
/// The node inside is reached only through [`CarNodeSlot::init`], which completes it in place
/// into what [`CarNode::new`] makes.
///
/// ```
/// use firmware_core::{Learner, ValidLearnerParams};
/// use protocol::car::{CarConfig, CarNodeSlot};
///
/// let mut slot = CarNodeSlot::EMPTY;
/// let node = slot.init(CarConfig::DEFAULT, Learner::new(ValidLearnerParams::DEFAULT));
/// assert!(node.stopped() && node.session().is_none());
/// ```
#[derive(Debug)]
pub struct CarNodeSlot(CarNode);

impl CarNodeSlot {
    /// The blank node: a placeholder learner, no configuration, zero timeouts, no key.
    pub const EMPTY: Self = Self(CarNode {
        config: CarConfig {
            watchdog_ms: 0,
            mode: FrameMode::Classic,
        },
        agent: Agent::BLANK,
        inbox: Inbox::with_timeout(Direction::HostToCar, 0),
        security: CarSecurity::BLANK,
        receiver: FeedbackReceiver::new(),
        session: None,
        generation: 0,
        watched: None,
        stopped: false,
        dirty: false,
        last_report: None,
        stats: CarStats::ZERO,
    });

    /// Completes the blank node in place, field by field (nothing the size of the node passes
    /// through the stack), into `CarNode::new(config, learner)`, and hands it out. Called again,
    /// it starts the node afresh the same way (the reassemblers' counters kept).
    pub fn init(&mut self, config: CarConfig, learner: Learner) -> &mut CarNode {
        let node = &mut self.0;
        node.config = config;
        node.agent.set_learner(learner);
        node.agent.forget_ticks();
        node.inbox.reset();
        node.inbox.set_timeout(DEFAULT_TIMEOUT_MS);
        node.security = CarSecurity::unkeyed();
        node.receiver = FeedbackReceiver::new();
        node.session = None;
        node.generation = 0;
        node.watched = None;
        node.stopped = true;
        node.dirty = false;
        node.last_report = None;
        node.stats = CarStats::ZERO;
        node
    }
}

impl CarNode {
    /// A node with `learner`, never configured, standing, with empty dedupe windows and no key
    /// (it accepts nothing until [`CarNode::install_key`]).
    pub const fn new(config: CarConfig, learner: Learner) -> Self {
        Self {
            config,
            agent: Agent::new(learner),
            inbox: Inbox::new(Direction::HostToCar),
            security: CarSecurity::unkeyed(),
            receiver: FeedbackReceiver::new(),
            session: None,
            generation: 0,
            watched: None,
            stopped: true,
            dirty: false,
            last_report: None,
            stats: CarStats::ZERO,
        }
    }

    /// Installs the car's `key` and starts `epoch`: a number never used before with this key
    /// (a random number, or a boot counter kept in flash), not 0. Call once at start.
    pub fn install_key(&mut self, key: &Key, epoch: u32) {
        self.security.install(key, epoch);
    }

    /// A node continuing from `state` (read back from flash): its learner, session, generation
    /// and dedupe windows; no recent ticks; standing; no key yet.
    pub fn restore(config: CarConfig, state: &Persisted) -> Result<Self, RestoreError> {
        let mut node = Self::new(config, Learner::new(ValidLearnerParams::DEFAULT));
        node.load(state)?;
        Ok(node)
    }

    /// [`CarNode::restore`] in place, for a node that lives in a `static` (this moves none of
    /// it). Counters, key and configuration are kept; on `Err` nothing changed.
    pub fn load(&mut self, state: &Persisted) -> Result<(), RestoreError> {
        let learner = Learner::restore(&state.snapshot).map_err(RestoreError::Snapshot)?;
        self.agent.set_learner(learner);
        self.stand();
        self.inbox.reset();
        self.receiver = state.receiver.clone();
        self.session = state.session;
        self.generation = state.generation;
        self.dirty = false;
        Ok(())
    }

    /// Forgets the recent ticks: standing until the next accepted observation.
    fn stand(&mut self) {
        self.agent.forget_ticks();
        self.stopped = true;
    }

    /// The state to persist now.
    pub fn persisted(&self) -> Persisted {
        Persisted {
            session: self.session,
            generation: self.generation,
            snapshot: self.agent.learner().snapshot(),
            receiver: self.receiver.clone(),
        }
    }

    /// The counters (refusals included).
    pub fn stats(&self) -> CarStats {
        CarStats {
            refused: self.security.refusals(),
            ..self.stats
        }
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

    /// Whether the car holds a configured learner, and its generation.
    pub fn status(&self) -> CarStatus {
        CarStatus {
            session: self.session,
            generation: self.generation,
        }
    }

    /// The security state (epoch, counters, refusals).
    pub fn security(&self) -> &CarSecurity {
        &self.security
    }

    /// Whether the car is standing: before its first action, after a watchdog stop, a reset or
    /// a new configuration, and while every trajectory collides.
    pub fn stopped(&self) -> bool {
        self.stopped
    }

    /// The last tick acted in (0 before any).
    fn last_tick(&self) -> u32 {
        self.watched.map_or(0, |(t, _)| t)
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
    ) -> Result<Outcome, B::Error> {
        match self.inbox.feed(frame, now_ms, &mut self.security) {
            Received::Nothing => Ok(Outcome::Pending),
            Received::Error(LinkError::Refused(_, r)) => Ok(Outcome::Refused(r)),
            Received::Error(e) => {
                self.report_link_error(e, now_ms, bus)?;
                Ok(Outcome::Lost)
            }
            Received::Message(msg) => {
                let kind = msg.kind();
                // Trusted: the newest host message (a hello may be a replay, and a late message
                // may be a genuine one another node recorded and replays).
                bus.authenticated(self.security.opened_newest());
                self.on_message(&msg, now_ms, bus, store)?;
                Ok(Outcome::Accepted(kind))
            }
        }
    }

    /// The watchdog and the reassembly timeouts at `now_ms`; call every few milliseconds.
    pub fn poll<B: CanBus>(&mut self, now_ms: u32, bus: &mut B) -> Result<(), B::Error> {
        while let Some(e) = self.inbox.poll(now_ms) {
            self.report_link_error(e, now_ms, bus)?;
        }
        if let Some((tick, since)) = self.watched
            && !self.stopped
            && now_ms.wrapping_sub(since) >= self.config.watchdog_ms
        {
            self.stopped = true;
            bump(&mut self.stats.watchdog_stops);
            self.send(
                bus,
                &Message::Action(ActionCommand::stop(tick, StopReason::Watchdog)),
            )?;
        }
        Ok(())
    }

    // Not inlined into `on_frame` (and on into the caller's loop): the locals of handling a
    // message then share no frame with the decoding of the next one, which is the deepest call
    // (`CarSecurity::open` and the observation's decoding). Measured on the car image's served
    // session: see docs/firmware.md.
    #[inline(never)]
    fn on_message<B: CanBus, P: Persist>(
        &mut self,
        msg: &Message,
        now_ms: u32,
        bus: &mut B,
        store: &mut P,
    ) -> Result<(), B::Error> {
        match msg {
            Message::Observation(_) if !self.security.opened_newest() => {
                // Sent before a host message that came first: a copy the host retransmitted
                // while it waited for the action, delayed on the way, arriving after the host
                // moved on (it sends a tick's feedback only once it has the tick's action).
                // Acting on it would drive on an old scan, and would replace the tick's record
                // with the decision of a learner that the tick's own feedback may have moved
                // since: a later feedback about the tick (a span) would then read another
                // action than the one the car executed. Nothing is done; a host still waiting
                // sends the observation again, and that copy is the newest.
                bump(&mut self.stats.observations);
                bump(&mut self.stats.stale_observations);
                Ok(())
            }
            Message::Observation(o) => self.on_observation(o, now_ms, bus),
            Message::Feedback(f) => self.on_feedback(f, bus, store),
            Message::Configure(c) => self.on_configure(c, bus, store),
            Message::WeightsRequest => self.send_weights(bus),
            Message::Heartbeat => self.send(bus, &Message::Heartbeat),
            Message::Reset => self.stop_now(StopReason::Reset, bus),
            Message::Hello(h) => self.on_hello(h, bus),
            // The host's error reports and anything else the inbox lets through: nothing to do.
            _ => Ok(()),
        }
    }

    /// Stands and commands a stop at once.
    fn stop_now<B: CanBus>(&mut self, reason: StopReason, bus: &mut B) -> Result<(), B::Error> {
        self.stand();
        bump(&mut self.stats.commanded_stops);
        let tick = self.last_tick();
        self.send(bus, &Message::Action(ActionCommand::stop(tick, reason)))
    }

    fn on_hello<B: CanBus>(&mut self, hello: &Hello, bus: &mut B) -> Result<(), B::Error> {
        self.security.on_hello(hello);
        let welcome = self.security.welcome(hello, self.status());
        self.send(bus, &Message::Welcome(welcome))
    }

    fn on_observation<B: CanBus>(
        &mut self,
        o: &ObservationMessage,
        now_ms: u32,
        bus: &mut B,
    ) -> Result<(), B::Error> {
        bump(&mut self.stats.observations);
        if self.session.is_none() {
            return self.report(ErrorCode::NotConfigured, Some(o.tick), bus);
        }
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
        if matches!(f.feedback, Feedback::EStop(_)) {
            // The teacher stopped the car: stand at once, whatever becomes of the learning, and
            // keep the ticks (feedback about them may follow). Every copy stops it again: an
            // E-stop is never lost to the dedupe window, and standing is always safe.
            self.stopped = true;
            bump(&mut self.stats.estops);
            let tick = self.last_tick();
            self.send(
                bus,
                &Message::Action(ActionCommand::stop(tick, StopReason::EStop)),
            )?;
        }
        if self.session != Some(f.id.session) {
            // Never applied here; a copy of one applied in an earlier session gets its answer.
            let reply = match self.receiver.recorded(f.id) {
                Some(v) => {
                    bump(&mut self.stats.feedback_duplicates);
                    Reply::new(f.id, v)
                }
                None => {
                    bump(&mut self.stats.feedback_refused);
                    Reply::Nack(Nack {
                        id: f.id,
                        code: NackCode::WrongSession,
                    })
                }
            };
            return self.send(bus, &reply.into());
        }
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
                self.generation = self.generation.wrapping_add(1);
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
            if let Some(s) = self.session
                && c.session != s.wrapping_add(1)
            {
                return self.report(ErrorCode::Session, None, bus);
            }
            let Ok(learner) = Learner::restore(&c.snapshot) else {
                return self.report(ErrorCode::Params, None, bus);
            };
            self.agent.set_learner(learner);
            self.session = Some(c.session);
            self.generation = 0;
            self.dirty = true;
            self.stop_now(StopReason::Reconfigured, bus)?;
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
        let report = WeightsReport {
            status: self.status(),
            snapshot: self.agent.learner().snapshot(),
        };
        self.send(bus, &Message::Weights(report))
    }

    /// Counts a lost message and reports it, at most once per [`ERROR_REPORT_INTERVAL_MS`].
    fn report_link_error<B: CanBus>(
        &mut self,
        e: LinkError,
        now_ms: u32,
        bus: &mut B,
    ) -> Result<(), B::Error> {
        bump(&mut self.stats.lost);
        let Some(code) = e.code() else {
            return Ok(());
        };
        let due = self
            .last_report
            .is_none_or(|t| now_ms.wrapping_sub(t) >= ERROR_REPORT_INTERVAL_MS);
        if !due {
            return Ok(());
        }
        self.last_report = Some(now_ms);
        self.report(code, None, bus)
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
        match transmit(
            bus,
            msg,
            Direction::CarToHost,
            self.config.mode,
            &mut self.security,
        ) {
            Ok(_) => Ok(()),
            Err(TransmitError::Bus { error, .. }) => Err(error),
            // No key (nothing was accepted either), or the epoch's counter used up: silent.
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
    use crate::delivery::{DEDUPE_WINDOW, FeedbackSender, RetryPolicy, SESSIONS, SenderEvent};
    use crate::message::{Ack, DeliveryId, Nack};
    use crate::secure::{Endpoint, HostSecurity};
    use firmware_core::observation::Observation;
    use firmware_core::{ActionFeedback, ActionIndex, Feedback, LearnerParams, OnlineLearner};
    use proptest::prelude::*;
    use std::vec::Vec;

    const KEY: Key = Key::new([0x77; 16]);
    const EPOCH: u32 = 1000;

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

    /// A keyed node in `EPOCH`, never configured.
    fn node() -> CarNode {
        let mut n = CarNode::new(CarConfig::default(), learner());
        n.install_key(&KEY, EPOCH);
        n
    }

    /// The car with its flash, and the host's side of the link.
    struct Bench {
        car: CarNode,
        flash: Ram,
        host: HostSecurity,
        inbox: Inbox,
    }

    impl Bench {
        /// A bench whose host is in step with `car`'s epoch (as after a welcome).
        fn new(car: CarNode) -> Self {
            let host = HostSecurity::assume_fresh_car(&KEY, car.security().epoch());
            Self {
                car,
                flash: Ram::default(),
                host,
                inbox: Inbox::new(Direction::CarToHost),
            }
        }

        /// A bench with a node configured in session 4 with the paper's fresh learner.
        fn configured() -> Self {
            let mut b = Bench::new(node());
            let got = b.send(&configure(4, &learner()), 0);
            assert!(
                matches!(got[..], [Message::Action(_), Message::Weights(_)]),
                "{got:?}"
            );
            b
        }

        /// The frames of `msg` sealed by `sealer` (CAN FD).
        fn frames(msg: &Message, sealer: &mut impl Endpoint) -> Vec<CanFrame> {
            let mut to_car = Wire::default();
            transmit(
                &mut to_car,
                msg,
                Direction::HostToCar,
                FrameMode::Fd,
                sealer,
            )
            .unwrap();
            to_car.0
        }

        /// Sends `msg` (in CAN FD frames) at `now`; returns what the car answered.
        fn send(&mut self, msg: &Message, now: u32) -> Vec<Message> {
            let frames = Self::frames(msg, &mut self.host);
            let mut out = Vec::new();
            for f in &frames {
                self.frames_in(f, now, &mut out);
            }
            out
        }

        fn frames_in(&mut self, f: &CanFrame, now: u32, out: &mut Vec<Message>) -> Outcome {
            let mut to_host = Wire::default();
            let outcome = self
                .car
                .on_frame(f, now, &mut to_host, &mut self.flash)
                .unwrap();
            out.extend(self.decode(&to_host));
            outcome
        }

        fn poll(&mut self, now: u32) -> Vec<Message> {
            let mut to_host = Wire::default();
            self.car.poll(now, &mut to_host).unwrap();
            self.decode(&to_host)
        }

        fn decode(&mut self, wire: &Wire) -> Vec<Message> {
            let mut out = Vec::new();
            for f in &wire.0 {
                match self.inbox.feed(f, 0, &mut self.host) {
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

    fn feedback_in(session: u8, seq: u8, tick: u32, action: usize) -> Message {
        Message::Feedback(FeedbackMessage {
            id: DeliveryId { session, seq },
            tick,
            feedback: Feedback::Action(ActionFeedback {
                action: ActionIndex::new(action).unwrap(),
            }),
        })
    }

    fn feedback(seq: u8, tick: u32, action: usize) -> Message {
        feedback_in(4, seq, tick, action)
    }

    fn ack(seq: u8) -> Message {
        Message::Ack(Ack {
            id: DeliveryId { session: 4, seq },
        })
    }

    fn nack(session: u8, seq: u8, code: NackCode) -> Message {
        Message::Nack(Nack {
            id: DeliveryId { session, seq },
            code,
        })
    }

    fn error(code: ErrorCode, tick: Option<u32>) -> Message {
        Message::Error(ErrorReport { code, tick })
    }

    fn stop(tick: u32, reason: StopReason) -> Message {
        Message::Action(ActionCommand::stop(tick, reason))
    }

    fn configure(session: u8, learner: &Learner) -> Message {
        Message::Configure(ConfigureMessage {
            session,
            snapshot: learner.snapshot(),
        })
    }

    fn weights(session: u8, generation: u32, learner: &Learner) -> Message {
        Message::Weights(WeightsReport {
            status: CarStatus {
                session: Some(session),
                generation,
            },
            snapshot: learner.snapshot(),
        })
    }

    #[test]
    fn a_slot_completed_is_the_node_new_makes() {
        let config = CarConfig {
            watchdog_ms: 321,
            mode: FrameMode::Fd,
        };
        let learner = Learner::new(LearnerParams::paper().with_step(0.5).check().unwrap());
        let mut slot = CarNodeSlot::EMPTY;
        let node = slot.init(config, learner);
        assert_eq!(
            format!("{node:?}"),
            format!("{:?}", CarNode::new(config, learner))
        );
        // Used, then completed again: a fresh node (but for the reassemblers' counters).
        node.install_key(&KEY, EPOCH);
        let again = slot.init(CarConfig::DEFAULT, learner);
        assert!(!again.security().is_keyed() && again.stopped());
    }

    #[test]
    fn an_observation_is_answered_with_the_agent_s_action_and_mask() {
        let mut b = Bench::configured();
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
    fn a_car_without_a_configured_learner_does_not_drive() {
        let mut b = Bench::new(node());
        assert_eq!(b.observe(3, 0), [error(ErrorCode::NotConfigured, Some(3))]);
        assert!(b.car.stopped());
        assert_eq!(b.car.stats().actions, 0);
        // Nor does a car without a key: it accepts nothing and says nothing.
        let mut unkeyed = Bench::new(CarNode::new(CarConfig::default(), learner()));
        assert_eq!(unkeyed.send(&configure(1, &learner()), 0), []);
        assert_eq!(unkeyed.car.session(), None);
        assert_eq!(unkeyed.car.stats().refused.unsynced, 1);
    }

    #[test]
    fn a_refused_observation_is_an_error_report_of_its_tick() {
        let mut b = Bench::configured();
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
            [nack(4, 0, NackCode::UnknownTick)]
        );
    }

    #[test]
    fn feedback_is_applied_once_persisted_before_its_ack_and_every_copy_is_acked() {
        let mut b = Bench::configured();
        b.observe(1, 0);
        let before = *b.car.agent().learner();
        let writes = b.flash.writes;
        assert_eq!(b.send(&feedback(0, 1, 3), 1), [ack(0)]);
        let after = *b.car.agent().learner();
        assert_ne!(after, before, "the feedback moved the weights");
        assert_eq!(b.car.status().generation, 1);
        // Persisted before the ack went out: the flash holds the new learner and the verdict.
        assert_eq!(b.flash.writes, writes + 1);
        assert_eq!(b.flash.stored.as_ref(), Some(&b.car.persisted()));
        assert_eq!(b.flash.stored.as_ref().unwrap().snapshot, after.snapshot());
        assert_eq!(b.flash.stored.as_ref().unwrap().generation, 1);
        for now in 2..5 {
            assert_eq!(b.send(&feedback(0, 1, 3), now), [ack(0)]);
        }
        assert_eq!(*b.car.agent().learner(), after, "copies are not applied");
        assert_eq!(b.flash.writes, writes + 1, "nor written");
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
    fn an_e_stop_stops_the_car_first_keeps_its_ticks_and_is_learned_once() {
        let mut b = Bench::configured();
        b.observe(1, 0);
        b.observe(2, 1);
        assert!(!b.car.stopped());
        let before = *b.car.agent().learner();
        let estop = |seq| {
            Message::Feedback(FeedbackMessage {
                id: DeliveryId { session: 4, seq },
                tick: 2,
                feedback: Feedback::EStop(firmware_core::EStopFeedback),
            })
        };
        assert_eq!(b.send(&estop(0), 2), [stop(2, StopReason::EStop), ack(0)]);
        assert!(b.car.stopped());
        let after = *b.car.agent().learner();
        assert_ne!(
            after, before,
            "the executed action was learned as unacceptable"
        );
        // A copy: stops again, acked again, not learned again.
        assert_eq!(b.send(&estop(0), 3), [stop(2, StopReason::EStop), ack(0)]);
        assert_eq!(*b.car.agent().learner(), after);
        // The ticks are kept: feedback about tick 1 still applies.
        assert_eq!(b.send(&feedback(1, 1, 3), 4), [ack(1)]);
        // An E-stop of another session stops the car too, and is refused.
        let mut other = estop(9);
        if let Message::Feedback(f) = &mut other {
            f.id.session = 7;
        }
        assert_eq!(
            b.send(&other, 5),
            [
                stop(2, StopReason::EStop),
                nack(7, 9, NackCode::WrongSession)
            ]
        );
        let s = b.car.stats();
        assert_eq!((s.estops, s.feedback_applied), (3, 2));
        // The next observation drives again.
        b.observe(3, 6);
        assert!(!b.car.stopped());
    }

    #[test]
    fn refused_feedback_is_nacked_every_time_and_not_persisted() {
        let mut b = Bench::configured();
        let writes = b.flash.writes;
        let n = nack(4, 7, NackCode::UnknownTick);
        assert_eq!(b.send(&feedback(7, 77, 1), 0), core::slice::from_ref(&n));
        assert_eq!(b.send(&feedback(7, 77, 1), 0), [n]);
        let s = b.car.stats();
        assert_eq!((s.feedback_refused, s.feedback_duplicates), (1, 1));
        assert_eq!(b.flash.writes, writes);
        assert_eq!(b.car.status().generation, 0);
    }

    /// Issue 14, items 1 and 2: feedback of another session is never applied; a session change
    /// does not forget what was applied.
    #[test]
    fn feedback_binds_to_its_session_and_copies_survive_session_changes() {
        let mut b = Bench::configured();
        b.observe(1, 0);
        let learned = {
            assert_eq!(b.send(&feedback(0, 1, 3), 1), [ack(0)]);
            *b.car.agent().learner()
        };
        // Feedback of another session (a stale host, a confused one): refused, not applied.
        assert_eq!(
            b.send(&feedback_in(9, 0, 1, 5), 2),
            [nack(9, 0, NackCode::WrongSession)]
        );
        assert_eq!(*b.car.agent().learner(), learned);
        // A new configuration (session 5); the copy of session 4's feedback A still gets its
        // ack, and is not applied to the new learner.
        let fresh = learner();
        let got = b.send(&configure(5, &fresh), 3);
        assert_eq!(
            got,
            [stop(1, StopReason::Reconfigured), weights(5, 0, &fresh)]
        );
        b.observe(2, 4);
        assert_eq!(b.send(&feedback(0, 1, 3), 5), [ack(0)]);
        assert_eq!(*b.car.agent().learner(), fresh, "not applied again");
        // Session 4's unapplied numbers are refused now.
        assert_eq!(
            b.send(&feedback(1, 2, 3), 6),
            [nack(4, 1, NackCode::WrongSession)]
        );
        // Session 5 numbers from 0 in its own window.
        assert_eq!(
            b.send(&feedback_in(5, 0, 2, 3), 7),
            [Message::Ack(Ack {
                id: DeliveryId { session: 5, seq: 0 }
            })]
        );
        let s = b.car.stats();
        assert_eq!(
            (
                s.feedback_applied,
                s.feedback_duplicates,
                s.feedback_refused
            ),
            (2, 1, 2)
        );
    }

    #[test]
    fn a_failed_write_withholds_the_ack_until_a_retransmission_finds_the_flash_working() {
        let mut b = Bench::configured();
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

    /// A restart: the node restored from the flash, with a new epoch; the host says hello.
    fn restarted(b: &Bench, epoch: u32) -> Bench {
        let state = b.flash.stored.clone().unwrap();
        let mut n = CarNode::restore(CarConfig::default(), &state).unwrap();
        n.install_key(&KEY, epoch);
        let mut b2 = Bench::new(n);
        b2.flash.stored = Some(state);
        b2
    }

    #[test]
    fn a_restored_node_acks_a_retransmitted_feedback_without_applying_it() {
        let mut b = Bench::configured();
        b.observe(1, 0);
        b.observe(2, 100);
        assert_eq!(b.send(&feedback(0, 1, 3), 101), [ack(0)]);
        assert_eq!(b.send(&feedback(1, 2, 5), 102), [ack(1)]);
        // Power cut: the ack of seq 1 never reached the host. The car restarts from flash.
        let mut b2 = restarted(&b, EPOCH + 1);
        assert_eq!(*b2.car.agent().learner(), *b.car.agent().learner());
        assert_eq!(b2.car.status(), b.car.status());
        assert!(b2.car.stopped());
        // The host's frames of the old epoch are refused by the new one.
        let old = Bench::frames(&feedback(1, 2, 5), &mut b.host);
        let mut got = Vec::new();
        for f in &old {
            b2.frames_in(f, 0, &mut got);
        }
        assert_eq!(got, []);
        assert_eq!(b2.car.stats().refused.mac, 1);
        let learner = *b2.car.agent().learner();
        assert_eq!(b2.send(&feedback(1, 2, 5), 0), [ack(1)]);
        assert_eq!(*b2.car.agent().learner(), learner, "not applied twice");
        let s = b2.car.stats();
        assert_eq!((s.feedback_applied, s.feedback_duplicates), (0, 1));
        // New feedback about a tick from before the restart: refused, the ticks are gone.
        assert_eq!(
            b2.send(&feedback(2, 2, 5), 1),
            [nack(4, 2, NackCode::UnknownTick)]
        );
        // The restored state round-trips through the envelope the flash uses.
        let state = b.flash.stored.clone().unwrap();
        let mut buf = [0u8; PERSISTED_MAX_SIZE];
        let bytes = crate::seal(&state, &mut buf).unwrap();
        assert!(bytes.len() <= PERSISTED_MAX_SIZE);
        assert_eq!(crate::open::<Persisted>(bytes).unwrap(), state);
    }

    #[test]
    fn load_restores_in_place() {
        let mut b = Bench::configured();
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

    #[test]
    fn configure_replaces_the_learner_once_per_session_and_sessions_go_in_order() {
        let mut b = Bench::configured();
        b.observe(1, 0);
        b.send(&feedback(0, 1, 3), 1);
        let mut fresh = Learner::new(LearnerParams::default().check().unwrap());
        fresh.step(&[0.5, 0.0, 0.0, -0.25, 0.0, 1.0]).unwrap();
        // Not the next session: refused, nothing changes.
        assert_eq!(
            b.send(&configure(9, &fresh), 2),
            [error(ErrorCode::Session, None)]
        );
        assert_eq!(b.car.session(), Some(4));
        assert_eq!(
            b.send(&configure(5, &fresh), 2),
            [stop(1, StopReason::Reconfigured), weights(5, 0, &fresh)]
        );
        assert_eq!(*b.car.agent().learner(), fresh);
        assert_eq!(b.car.session(), Some(5));
        assert!(b.car.stopped());
        let stored = b.flash.stored.clone().unwrap();
        assert_eq!(
            (stored.session, stored.generation, stored.snapshot),
            (Some(5), 0, fresh.snapshot())
        );
        assert_eq!(
            stored.receiver.sessions().collect::<Vec<_>>(),
            [4],
            "session 4's window is kept"
        );
        // The old tick is forgotten.
        assert!(matches!(
            b.send(&feedback_in(5, 1, 1, 3), 3)[..],
            [Message::Nack(Nack {
                code: NackCode::UnknownTick,
                ..
            })]
        ));
        // The learner moves on; a late copy of the configure does not reset it.
        b.observe(2, 4);
        assert!(matches!(
            b.send(&feedback_in(5, 2, 2, 9), 5)[..],
            [Message::Ack(_)]
        ));
        let learned = *b.car.agent().learner();
        assert_ne!(learned, fresh);
        let writes = b.flash.writes;
        assert_eq!(b.send(&configure(5, &fresh), 6), [weights(5, 1, &learned)]);
        assert_eq!(*b.car.agent().learner(), learned);
        assert_eq!(b.flash.writes, writes);
        assert!(!b.car.stopped(), "a copy changes nothing");
        // An invalid snapshot is refused and changes nothing.
        let mut bad = fresh.snapshot();
        bad.state.iterate[0] = f32::NAN;
        let msg = Message::Configure(ConfigureMessage {
            session: 6,
            snapshot: bad,
        });
        assert_eq!(b.send(&msg, 9), [error(ErrorCode::Params, None)]);
        assert_eq!(
            (b.car.session(), *b.car.agent().learner()),
            (Some(5), learned)
        );
        // Sessions wrap.
        let mut b = Bench::new(node());
        b.send(&configure(255, &fresh), 0);
        assert!(matches!(
            b.send(&configure(0, &fresh), 1)[..],
            [Message::Action(_), Message::Weights(_)]
        ));
    }

    #[test]
    fn weights_requests_heartbeats_hello_and_reset() {
        let mut b = Bench::configured();
        let snap = *b.car.agent().learner();
        assert_eq!(b.send(&Message::WeightsRequest, 0), [weights(4, 0, &snap)]);
        assert_eq!(b.send(&Message::Heartbeat, 0), [Message::Heartbeat]);
        // A hello is answered with the car's epoch, counters and status.
        let mut fresh_host = HostSecurity::new(&KEY);
        let hello = fresh_host.hello([5; 8]);
        let frames = Bench::frames(&hello, &mut fresh_host);
        let mut to_host = Wire::default();
        for f in &frames {
            b.car.on_frame(f, 0, &mut to_host, &mut b.flash).unwrap();
        }
        let mut inbox = Inbox::new(Direction::CarToHost);
        let got: Vec<_> = to_host
            .0
            .iter()
            .map(|f| inbox.feed(f, 0, &mut fresh_host))
            .filter(|r| *r != Received::Nothing)
            .collect();
        let [Received::Message(Message::Welcome(w))] = &got[..] else {
            panic!("{got:?}")
        };
        assert_eq!((w.nonce, w.epoch), ([5; 8], EPOCH));
        assert_eq!(w.status, b.car.status());
        assert_eq!(fresh_host.epoch(), Some(EPOCH));
        // A reset stops the car at once and keeps the learner and the windows.
        b.observe(1, 0);
        assert!(!b.car.stopped());
        assert_eq!(b.send(&Message::Reset, 1), [stop(1, StopReason::Reset)]);
        assert!(b.car.stopped());
        assert!(matches!(
            b.send(&feedback(0, 1, 3), 2)[..],
            [Message::Nack(Nack {
                code: NackCode::UnknownTick,
                ..
            })]
        ));
        assert_eq!(*b.car.agent().learner(), snap, "learner kept");
        assert_eq!(b.car.stats().commanded_stops, 2);
    }

    #[test]
    fn an_observation_a_later_host_message_overtook_is_not_acted_on() {
        let mut b = Bench::configured();
        assert!(matches!(b.observe(1, 0)[..], [Message::Action(_)]));
        // A copy the host sent again while it waited, held back on the way; the host got the
        // action meanwhile and sends the tick's feedback, which arrives first.
        let late = Bench::frames(&observation(1), &mut b.host);
        assert_eq!(b.send(&feedback(0, 1, 3), 1), [ack(0)]);
        let before = b.car.stats();
        let mut out = Vec::new();
        for f in &late {
            b.frames_in(f, 2, &mut out);
        }
        assert_eq!(out, [], "no action for the late copy");
        let after = b.car.stats();
        assert_eq!(after.actions, before.actions, "not acted on");
        assert_eq!(after.stale_observations, 1);
        assert_eq!(after.observations, before.observations + 1);
        // The same tick observed anew (the newest message) is acted on.
        assert!(matches!(b.observe(1, 3)[..], [Message::Action(_)]));
        assert_eq!(b.car.stats().actions, before.actions + 1);
    }

    /// Issue 14, item 4: no message disarms the watchdog.
    #[test]
    fn the_watchdog_stops_once_and_is_never_disarmed_by_a_message() {
        let mut b = Bench::configured();
        assert_eq!(b.poll(1_000), [], "no observation yet: nothing to watch");
        b.observe(1, 1_000);
        b.observe(2, 1_100);
        assert_eq!(b.poll(1_299), []);
        assert_eq!(b.poll(1_300), [stop(2, StopReason::Watchdog)]);
        assert!(b.car.stopped());
        assert_eq!(b.poll(1_500), [], "one stop, not one per poll");
        assert_eq!(b.car.stats().watchdog_stops, 1);
        // Observations return: the car drives again, and can stop again.
        let got = b.observe(3, 2_000);
        assert!(matches!(
            got[..],
            [Message::Action(ActionCommand {
                tick: 3,
                command: crate::message::Command::Track(_),
                ..
            })]
        ));
        assert!(!b.car.stopped());
        assert_eq!(b.poll(2_199), []);
        assert_eq!(b.poll(2_200), [stop(3, StopReason::Watchdog)]);
        // A reset stops the car; when it drives again, silence still stops it.
        b.observe(4, 3_000);
        assert_eq!(b.send(&Message::Reset, 3_010), [stop(4, StopReason::Reset)]);
        b.observe(5, 3_020);
        assert_eq!(b.poll(3_219), []);
        assert_eq!(b.poll(3_220), [stop(5, StopReason::Watchdog)]);
        let s = b.car.stats();
        assert_eq!((s.watchdog_stops, s.actions), (3, 5));
        // Wrapping milliseconds.
        let mut b = Bench::configured();
        b.observe(1, u32::MAX - 50);
        assert_eq!(b.poll(100), []);
        assert_eq!(b.poll(150), [stop(1, StopReason::Watchdog)]);
    }

    /// Issue 14, item 1: a host without the key rewrites nothing, and replays change nothing.
    #[test]
    fn forged_and_replayed_messages_are_refused_and_counted() {
        let mut b = Bench::configured();
        b.observe(1, 0);
        // Recorded: a feedback, an observation and a configure as the real host sent them.
        let fb = Bench::frames(&feedback(0, 1, 3), &mut b.host);
        let obs = Bench::frames(&observation(2), &mut b.host);
        let mut out = Vec::new();
        for f in fb.iter().chain(obs.iter()) {
            b.frames_in(f, 1, &mut out);
        }
        assert!(matches!(out[..], [Message::Ack(_), Message::Action(_)]));
        let learned = *b.car.agent().learner();
        let status = b.car.status();
        let other = Learner::new(LearnerParams::default().check().unwrap());
        // Attackers: the wrong key and no key (the public all-zero key), in step with the epoch
        // (the epoch is no secret).
        for key in [Key::new([0x13; 16]), Key::INSECURE] {
            let mut forger = HostSecurity::assume_fresh_car(&key, EPOCH);
            for msg in [
                configure(5, &other),
                configure(4, &other),
                feedback(9, 1, 60),
                feedback_in(5, 0, 1, 60),
                Message::Reset,
                observation(3),
                Message::WeightsRequest,
            ] {
                let mut last = Outcome::Pending;
                for f in Bench::frames(&msg, &mut forger) {
                    last = b.frames_in(&f, 2, &mut out);
                }
                assert_eq!(last, Outcome::Refused(Refusal::Mac), "{msg:?}");
            }
        }
        // The real host's frames, replayed.
        for f in fb.iter().chain(obs.iter()) {
            b.frames_in(f, 3, &mut out);
        }
        assert_eq!(out.len(), 2, "no answer to any of it: {out:?}");
        assert_eq!(*b.car.agent().learner(), learned);
        assert_eq!(b.car.status(), status);
        assert!(
            !b.car.stopped(),
            "the forged reset did not stop the car either"
        );
        let s = b.car.stats();
        assert_eq!(s.refused.mac, 14);
        assert_eq!(s.refused.replayed, 2);
        assert_eq!((s.feedback_applied, s.actions), (1, 2));
    }

    #[test]
    fn lost_messages_are_reported_at_a_bounded_rate() {
        let mut b = Bench::configured();
        // Half an observation, then silence: a reassembly timeout.
        let frames = Bench::frames(&observation(1), &mut b.host);
        let mut got = Vec::new();
        b.frames_in(&frames[0], 10, &mut got);
        assert_eq!(got, []);
        assert_eq!(b.poll(10), []);
        assert_eq!(b.poll(1_000), [error(ErrorCode::Reassembly, None)]);
        // A flood of garbage within one interval: one report, every one counted.
        for i in 0..50u8 {
            let f = CanFrame::new_fd(frames[0].id(), &[0x03, 3, i, 0]).unwrap();
            b.frames_in(&f, 1_100 + u32::from(i), &mut got);
        }
        assert_eq!(got, [error(ErrorCode::Decode, None)]);
        let s = b.car.stats();
        assert_eq!((s.lost, s.errors), (51, 2));
    }

    #[test]
    fn the_persisted_state_size_is_what_its_fields_add_up_to() {
        // Session 2, generation 5, snapshot 114 (a weights report less its tag, status and
        // envelope), receiver SESSIONS × (1 + 2 + one byte per window slot), envelope 3.
        assert_eq!(
            PERSISTED_MAX_SIZE,
            2 + 5 + 114 + SESSIONS * (3 + DEDUPE_WINDOW) + 3
        );
    }

    #[derive(Debug, Clone)]
    enum Step {
        /// The current session's sender gives feedback about a new tick (observed first).
        Give,
        /// The sender of an earlier session (a host that missed the new configuration) gives
        /// feedback about a new tick: never applied.
        GiveStale,
        /// Time passes; senders retransmit what is due.
        Wait(u32),
        /// A new configuration (the next session, a new sender).
        Configure,
        /// The car restarts from its flash in a new epoch (the host says hello).
        Restart,
    }

    fn step() -> impl Strategy<Value = Step> {
        prop_oneof![
            6 => Just(Step::Give),
            2 => Just(Step::GiveStale),
            6 => (1u32..30).prop_map(Step::Wait),
            1 => Just(Step::Configure),
            1 => Just(Step::Restart),
        ]
    }

    /// The model of the property test: a car, its flash, senders of several sessions, and a
    /// link that loses and duplicates both ways.
    struct World {
        b: Bench,
        senders: Vec<FeedbackSender>,
        now: u32,
        tick: u32,
        epoch: u32,
        rolls: Vec<u8>,
        roll: usize,
        /// Applications of each delivery `(session, seq, tick)`.
        applied: std::collections::HashMap<(u8, u8, u32), u32>,
        /// Deliveries applied while the car was configured in another session.
        foreign: Vec<(u8, u8, u32)>,
        delivered: Vec<(u8, u8, u32)>,
        refused: Vec<(u8, u8, u32, NackCode)>,
    }

    impl World {
        fn next_roll(&mut self) -> u8 {
            self.roll += 1;
            self.rolls[self.roll % self.rolls.len()]
        }

        /// Sends one feedback message (maybe lost, maybe twice) and routes the answers.
        fn transmit(&mut self, m: FeedbackMessage) {
            if self.next_roll() < 15 {
                return;
            }
            let copies = if self.next_roll() < 15 { 2 } else { 1 };
            for _ in 0..copies {
                let before = self.b.car.stats().feedback_applied;
                let answers = self.b.send(&Message::Feedback(m), self.now);
                if self.b.car.stats().feedback_applied > before {
                    let id = (m.id.session, m.id.seq, m.tick);
                    *self.applied.entry(id).or_default() += 1;
                    if self.b.car.session() != Some(m.id.session) {
                        self.foreign.push(id);
                    }
                }
                for a in answers {
                    if self.next_roll() < 15 {
                        continue;
                    }
                    let id = match &a {
                        Message::Ack(x) => x.id,
                        Message::Nack(x) => x.id,
                        _ => continue,
                    };
                    let Some(s) = self.senders.iter_mut().find(|s| s.session() == id.session)
                    else {
                        continue;
                    };
                    match s.on_reply(&a) {
                        Some(SenderEvent::Delivered { id, tick }) => {
                            self.delivered.push((id.session, id.seq, tick))
                        }
                        Some(SenderEvent::Refused { id, tick, code }) => {
                            self.refused.push((id.session, id.seq, tick, code))
                        }
                        _ => {}
                    }
                }
            }
        }

        fn run(&mut self, s: &Step) {
            match s {
                Step::Give | Step::GiveStale => {
                    self.tick += 1;
                    self.b.observe(self.tick, self.now);
                    let tick = self.tick;
                    let fb = Feedback::Action(ActionFeedback {
                        action: ActionIndex::new(tick as usize % 64).unwrap(),
                    });
                    let n = self.senders.len();
                    let k = match s {
                        Step::GiveStale if n >= 2 => n - 2,
                        Step::GiveStale => return,
                        _ => n.wrapping_sub(1),
                    };
                    if let Some(sender) = self.senders.get_mut(k)
                        && let Ok(m) = sender.send(self.now, tick, fb)
                    {
                        self.transmit(m);
                    }
                }
                Step::Wait(dt) => {
                    self.now += dt;
                    for k in 0..self.senders.len() {
                        while let Some(e) = self.senders[k].poll(self.now) {
                            if let SenderEvent::Retransmit(m) = e {
                                self.transmit(m);
                            }
                        }
                    }
                }
                Step::Configure => {
                    // At most SESSIONS sessions: the car keeps that many windows.
                    if self.senders.len() < SESSIONS {
                        let session = self.b.car.session().map_or(0, |s| s.wrapping_add(1));
                        let got = self.b.send(&configure(session, &learner()), self.now);
                        assert!(got.iter().any(|m| matches!(m, Message::Weights(_))));
                        self.senders.push(FeedbackSender::new(
                            session,
                            RetryPolicy {
                                timeout_ms: 10,
                                max_retries: 8,
                            },
                        ));
                    }
                }
                Step::Restart => {
                    if self.b.flash.stored.is_some() {
                        self.epoch += 1;
                        self.b = restarted(&self.b, self.epoch);
                    }
                }
            }
        }
    }

    proptest! {
        /// Issue 14, item 3: feedback of several sessions interleaved, retransmitted, lost and
        /// duplicated both ways, the car restarting from its flash in between: every feedback
        /// is applied at most once, a delivered one exactly once, a refused one never; only the
        /// configured session's feedback is ever applied.
        #[test]
        fn interleaved_sessions_and_restarts_apply_each_feedback_at_most_once(
            steps in proptest::collection::vec(step(), 1..300),
            rolls in proptest::collection::vec(0u8..100, 64),
        ) {
            let mut w = World {
                b: Bench::new(node()),
                senders: Vec::new(),
                now: 0,
                tick: 0,
                epoch: EPOCH,
                rolls,
                roll: 0,
                applied: Default::default(),
                foreign: Vec::new(),
                delivered: Vec::new(),
                refused: Vec::new(),
            };
            w.run(&Step::Configure);
            for s in &steps {
                w.run(s);
            }
            for (f, n) in &w.applied {
                prop_assert!(*n == 1, "{:?} applied {} times", f, n);
            }
            prop_assert!(w.foreign.is_empty(), "applied in another session: {:?}", w.foreign);
            for f in &w.delivered {
                prop_assert_eq!(w.applied.get(f), Some(&1), "delivered {:?}", f);
            }
            for (s, q, t, code) in &w.refused {
                prop_assert_eq!(w.applied.get(&(*s, *q, *t)), None, "refused {:?} was applied", code);
            }
            // What the car holds is one generation per application in its session.
            let session = w.b.car.session().unwrap();
            let in_session = w.applied.keys().filter(|(s, ..)| *s == session).count() as u32;
            prop_assert!(w.b.car.status().generation <= in_session);
        }
    }
}
