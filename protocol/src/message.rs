//! The messages between the host and the car, their wire encoding and their size bounds.
//!
//! A [`Message`] is the typed representation. On the wire it travels as a *secured* PDU
//! ([`crate::secure`]: version byte, postcard payload, freshness byte, truncated AES-CMAC);
//! in storage (flash pages, recorded ticks) as a plain [`envelope`](crate::envelope) (version
//! byte, postcard payload, CRC-16), written by [`Message::emit`] and read by [`Message::parse`].
//! The payload is the same in both.
//!
//! | # | variant | direction | payload |
//! |---|---|---|---|
//! | 0 | [`Message::Observation`] | host → car | [`ObservationMessage`]: tick number and [`Observation`] (quantized, [`crate::quantize`]) |
//! | 1 | [`Message::Action`] | car → host | [`ActionCommand`]: tick number, the trajectory to track or a stop and its reason, the collision mask |
//! | 2 | [`Message::Feedback`] | host → car | [`FeedbackMessage`]: delivery id, tick number, [`Feedback`] of any kind (table below) |
//! | 3 | [`Message::Ack`] | car → host | [`Ack`]: the delivery id of an applied feedback |
//! | 4 | [`Message::Nack`] | car → host | [`Nack`]: the delivery id of a refused feedback and why |
//! | 5 | [`Message::Heartbeat`] | both | nothing (the freshness counter of its PDU counts) |
//! | 6 | [`Message::Weights`] | car → host | [`WeightsReport`]: the car's status and its [`LearnerSnapshot`] |
//! | 7 | [`Message::Configure`] | host → car | [`ConfigureMessage`]: a session number and the [`LearnerSnapshot`] to start from |
//! | 8 | [`Message::Reset`] | host → car | nothing |
//! | 9 | [`Message::Error`] | both | [`ErrorReport`] |
//! | 10 | [`Message::WeightsRequest`] | host → car | nothing; answered with [`Message::Weights`] |
//! | 11 | [`Message::Hello`] | host → car | [`Hello`]: a nonce and the host's freshness; answered with [`Message::Welcome`] |
//! | 12 | [`Message::Welcome`] | car → host | [`Welcome`]: the nonce, the car's freshness and [`CarStatus`] |
//!
//! The [`Feedback`] is itself a variant number and its fields:
//!
//! | # | kind | fields | payload bytes |
//! |---|---|---|---|
//! | 0 | action | the teacher's action | 1 |
//! | 1 | preference | preferred, other | 2 |
//! | 2 | semantic | six optional polarities, in feature order | 6–12 |
//! | 3 | perturbation | the corrected trajectory's six features, fixed-width `i16` thousandths | 12 |
//! | 4 | reward | `i8` hundredths in −100…100 | 1 |
//! | 5 | correctness | correct (a bool) | 1 |
//! | 6 | span | ticks (`u8`, up to 50), good (a bool) | 2 |
//! | 7 | ranking | the shown actions best first (a length, then one byte each, up to 8), ordered | 3–10 |
//! | 8 | E-stop | nothing | 0 |
//!
//! Decoding checks the layout (action indices, the ranking's length); the numbers' ranges are
//! checked by `firmware-core` when the car learns from them, and refused with a
//! [`Nack`] ([`NackCode::Rejected`]).
//!
//! The variant number is the first payload byte (a postcard varint); variants and fields are
//! never reordered within a protocol version (the golden-bytes tests pin them). The largest
//! secured message of each kind is [`MessageKind::max_encoded_size`], a compile-time constant
//! derived from postcard's `MaxSize`; [`MAX_MESSAGE_SIZE`] bounds them all and sizes every
//! buffer.
//!
//! # Checked view, typed representation, panic contract
//!
//! [`Message::parse`] and [`crate::secure`]'s `open` are total: any byte string gives a
//! [`Message`] or an error, never a panic. They decode the payload with postcard (which
//! range-checks action indices, enum tags and list lengths), require every byte to be used, and
//! check the numbers the *protocol* defines (the [`Track`] of an action command: within the
//! car's limits). The values of `firmware-core` types (observation, feedback, snapshot) are
//! checked by `firmware-core` when they are used ([`Observation::validate`],
//! `Learner::restore`), so they are not checked twice.
//!
//! ```
//! use protocol::message::{ActionCommand, Message, MAX_MESSAGE_SIZE};
//! use firmware_core::ActionIndex;
//!
//! let cmd = Message::Action(ActionCommand::new(42, ActionIndex::new(0)));
//! let mut buf = [0u8; MAX_MESSAGE_SIZE];
//! let bytes = cmd.emit(&mut buf).unwrap();
//! assert_eq!(Message::parse(bytes), Ok(cmd));
//! assert!(Message::parse(&bytes[1..]).is_err());
//! ```

use core::fmt;

use firmware_core::agent::FeedbackError;
use firmware_core::lattice::{self, MAX_PLANNING_STEERING};
use firmware_core::observation::MAX_SPEED;
use firmware_core::{ActionIndex, ActionMask, Feedback, FeedbackKind, LearnerSnapshot};
use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

pub use firmware_core::observation::Observation;

use crate::envelope::{ENVELOPE_OVERHEAD, Envelope, EnvelopeError, seal};
use crate::quantize::{I16, U16, WireObservation, track};
use crate::secure::SECURED_OVERHEAD;

/// Largest steering angle an action command may carry (rad): the car's mechanical limit.
pub const MAX_STEERING: f32 = 0.34;

/// Largest length of one segment of an action command (m).
pub const MAX_SEGMENT_LENGTH: f32 = 1.0;

const _: () = assert!(
    MAX_PLANNING_STEERING <= MAX_STEERING,
    "the lattice steers within reach"
);
const _: () = assert!(
    lattice::CRUISE_SEGMENT_LENGTH <= MAX_SEGMENT_LENGTH
        && lattice::CREEP_LENGTH <= MAX_SEGMENT_LENGTH,
    "lattice segments fit an action command"
);
const _: () = assert!(
    lattice::CRUISE_SPEED <= MAX_SPEED && lattice::CREEP_SPEED <= MAX_SPEED,
    "lattice speeds fit an action command"
);

/// The observation of one tick, host → car.
///
/// On the wire the observation is quantized ([`crate::quantize`]): a decoded message holds the
/// quantized numbers, so a message round-trips exactly when its observation is the output of
/// [`crate::quantize::quantize`].
#[derive(Clone, PartialEq, Debug, Serialize, Deserialize)]
pub struct ObservationMessage {
    /// The tick number; the car's action command and any feedback name it.
    pub tick: u32,
    /// What the car observes.
    #[serde(with = "crate::quantize::observation")]
    pub observation: Observation,
}

impl MaxSize for ObservationMessage {
    const POSTCARD_MAX_SIZE: usize = u32::POSTCARD_MAX_SIZE + WireObservation::POSTCARD_MAX_SIZE;
}

/// One segment of the trajectory to track.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct SegmentCommand {
    /// Steering angle (rad, positive left), within ±[`MAX_STEERING`]; 10⁻⁴ rad steps on the
    /// wire.
    pub steering: f32,
    /// Arc length (m), in `[0, MAX_SEGMENT_LENGTH]`; millimetres on the wire.
    pub length: f32,
}

/// What the tracking controller needs to follow one trajectory of the lattice.
///
/// On the wire: the action (one byte), each segment's steering as an `i16` in 10⁻⁴ rad and its
/// length as a `u16` in millimetres, the speed as a `u16` in mm/s (11 bytes). [`Track::of`]
/// gives those rounded numbers, so a track round-trips exactly.
#[derive(Clone, Copy, PartialEq, Debug, Serialize, Deserialize)]
#[serde(into = "WireTrack", from = "WireTrack")]
pub struct Track {
    /// The action (trajectory) chosen.
    pub action: ActionIndex,
    /// Its two constant-curvature segments, in order.
    pub segments: [SegmentCommand; 2],
    /// The speed to drive it at (m/s), in `(0, MAX_SPEED]`; mm/s on the wire.
    pub speed: f32,
}

#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize, MaxSize)]
struct WireSegment {
    steering: I16,
    length: U16,
}

#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize, MaxSize)]
struct WireTrack {
    action: ActionIndex,
    segments: [WireSegment; 2],
    speed: U16,
}

impl From<Track> for WireTrack {
    fn from(t: Track) -> Self {
        let seg = |s: &SegmentCommand| WireSegment {
            steering: I16::new(track::signed(s.steering, track::STEERING_STEPS)),
            length: U16::new(track::unsigned(s.length, track::MM)),
        };
        Self {
            action: t.action,
            segments: [seg(&t.segments[0]), seg(&t.segments[1])],
            speed: U16::new(track::unsigned(t.speed, track::MM)),
        }
    }
}

impl From<WireTrack> for Track {
    fn from(w: WireTrack) -> Self {
        let seg = |s: &WireSegment| SegmentCommand {
            steering: s.steering.get() as f32 / track::STEERING_STEPS,
            length: s.length.get() as f32 / track::MM,
        };
        Self {
            action: w.action,
            segments: [seg(&w.segments[0]), seg(&w.segments[1])],
            speed: w.speed.get() as f32 / track::MM,
        }
    }
}

impl MaxSize for Track {
    const POSTCARD_MAX_SIZE: usize = WireTrack::POSTCARD_MAX_SIZE;
}

impl Track {
    /// The lattice's trajectory of `action` (`firmware_core::lattice::trajectory`), its numbers
    /// rounded to their wire steps.
    pub fn of(action: ActionIndex) -> Self {
        let t = lattice::trajectory(action);
        let seg = |i: usize| SegmentCommand {
            steering: t.segments[i].steering,
            length: t.segments[i].length,
        };
        Track::from(WireTrack::from(Self {
            action,
            segments: [seg(0), seg(1)],
            speed: t.speed,
        }))
    }

    /// Whether every number is finite and within the car's limits.
    pub fn check(&self) -> Result<(), DecodeError> {
        let segment_ok = |s: &SegmentCommand| {
            s.steering.is_finite()
                && s.steering.abs() <= MAX_STEERING
                && s.length.is_finite()
                && (0.0..=MAX_SEGMENT_LENGTH).contains(&s.length)
        };
        let speed_ok = self.speed.is_finite() && self.speed > 0.0 && self.speed <= MAX_SPEED;
        if self.segments.iter().all(segment_ok) && speed_ok {
            Ok(())
        } else {
            Err(DecodeError::InvalidTrack)
        }
    }
}

/// Why the car stands.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize, MaxSize)]
#[non_exhaustive]
pub enum StopReason {
    /// Every trajectory collides in this tick: the car's answer to the observation.
    Blocked,
    /// No observation came for the watchdog's time.
    Watchdog,
    /// The host reset the car.
    Reset,
    /// A new learner was configured.
    Reconfigured,
    /// The teacher stopped the car ([`firmware_core::EStopFeedback`]): it stands until its next
    /// observation.
    EStop,
}

impl fmt::Display for StopReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            StopReason::Blocked => "every trajectory collides",
            StopReason::Watchdog => "watchdog: no observation in time",
            StopReason::Reset => "reset by the host",
            StopReason::Reconfigured => "a new learner was configured",
            StopReason::EStop => "stopped by the teacher (E-stop)",
        })
    }
}

/// Drive or stand.
#[derive(Clone, Copy, PartialEq, Debug, Serialize, Deserialize, MaxSize)]
pub enum Command {
    /// Track this trajectory.
    Track(Track),
    /// Stand, for this reason.
    Stop(StopReason),
}

/// The car's decision for a tick, car → host.
#[derive(Clone, Copy, PartialEq, Debug, Serialize, Deserialize, MaxSize)]
pub struct ActionCommand {
    /// The tick of the observation this answers (for a stop that answers none, the last tick
    /// the car acted in, 0 before any).
    pub tick: u32,
    /// The trajectory to track, or a stop and why.
    pub command: Command,
    /// The trajectories the car found collision-free in this tick (the evaluator's mask), so the
    /// host can check that both sides see the same world. Empty in a stop that answers no
    /// observation.
    pub allowed: ActionMask,
}

impl ActionCommand {
    /// The command for `action` in `tick`: its lattice trajectory, or for `None` a stop because
    /// every trajectory collides, with an empty mask (see [`ActionCommand::with_allowed`]).
    pub fn new(tick: u32, action: Option<ActionIndex>) -> Self {
        Self {
            tick,
            command: match action {
                Some(a) => Command::Track(Track::of(a)),
                None => Command::Stop(StopReason::Blocked),
            },
            allowed: ActionMask::NONE,
        }
    }

    /// The same command with the collision mask `allowed`.
    pub const fn with_allowed(mut self, allowed: ActionMask) -> Self {
        self.allowed = allowed;
        self
    }

    /// A stop in `tick` for `reason`, with an empty mask.
    pub const fn stop(tick: u32, reason: StopReason) -> Self {
        Self {
            tick,
            command: Command::Stop(reason),
            allowed: ActionMask::NONE,
        }
    }

    /// The track, if the car drives.
    pub const fn track(&self) -> Option<&Track> {
        match &self.command {
            Command::Track(t) => Some(t),
            Command::Stop(_) => None,
        }
    }

    /// The action of the track, if any.
    pub fn action(&self) -> Option<ActionIndex> {
        self.track().map(|t| t.action)
    }

    /// Why the car stands, if it does.
    pub const fn stop_reason(&self) -> Option<StopReason> {
        match self.command {
            Command::Track(_) => None,
            Command::Stop(r) => Some(r),
        }
    }

    /// Whether this is the car's answer to the observation of its tick (a track, or a stop
    /// because every trajectory collides) rather than a stop for another reason.
    pub const fn answers_observation(&self) -> bool {
        !matches!(self.command, Command::Stop(r) if !matches!(r, StopReason::Blocked))
    }
}

impl From<&firmware_core::agent::Decision> for ActionCommand {
    fn from(d: &firmware_core::agent::Decision) -> Self {
        Self::new(d.tick, d.action).with_allowed(d.allowed)
    }
}

/// What the car holds: its configuration session and how far its learner went in it.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Default, Serialize, Deserialize, MaxSize)]
pub struct CarStatus {
    /// The host's configuration session the learner belongs to; `None`: the car holds no
    /// configured learner (never configured, or its state was lost).
    pub session: Option<u8>,
    /// The snapshot generation: 0 after the configuration, one more per applied feedback.
    pub generation: u32,
}

impl fmt::Display for CarStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.session {
            Some(s) => write!(f, "session {s}, generation {}", self.generation),
            None => f.write_str("no configured learner"),
        }
    }
}

/// A learner report, car → host: the car's status and its learner.
#[derive(Clone, Copy, PartialEq, Debug, Serialize, Deserialize, MaxSize)]
pub struct WeightsReport {
    /// The session and generation the snapshot belongs to.
    pub status: CarStatus,
    /// The learner.
    pub snapshot: LearnerSnapshot,
}

/// A learner configuration, host → car: the car replaces its learner by the one `snapshot`
/// describes and remembers `session`. A fresh learner is `Learner::new(params).snapshot()`.
///
/// A configure whose `session` equals the car's current one is a copy (a retransmission, a
/// delayed frame): the car answers with its current weights and changes nothing, so a duplicated
/// configure never resets a running learner. A new configuration takes the session after the
/// car's current one (`current + 1`, wrapping; any session if the car holds none), so no
/// session number comes back while frames of its previous use may still be on their way.
#[derive(Clone, Copy, PartialEq, Debug, Serialize, Deserialize, MaxSize)]
pub struct ConfigureMessage {
    /// The host's configuration session.
    pub session: u8,
    /// The learner to start from (parameters and state).
    pub snapshot: LearnerSnapshot,
}

/// Identifies one feedback delivery: the sender's session and its sequence number in it.
///
/// A sender numbers its feedback `seq = 0, 1, 2, …` wrapping at 256 within the configuration
/// session. See [`crate::delivery`].
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize, MaxSize)]
pub struct DeliveryId {
    /// The configuration session.
    pub session: u8,
    /// The sequence number within the session (wrapping).
    pub seq: u8,
}

/// Feedback about one tick, host → car; acknowledged by an [`Ack`] or a [`Nack`].
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize, MaxSize)]
pub struct FeedbackMessage {
    /// The delivery this is (retransmissions repeat it).
    pub id: DeliveryId,
    /// The tick the feedback refers to.
    pub tick: u32,
    /// The teacher's feedback.
    pub feedback: Feedback,
}

impl FeedbackMessage {
    /// The largest secured feedback message carrying a feedback of `kind` (version, payload,
    /// freshness byte and MAC), in bytes: the bus budget of each kind
    /// (`cargo run -p protocol --example bus_budget`). The largest of them is
    /// [`MessageKind::Feedback`]'s [`MessageKind::max_encoded_size`].
    pub const fn max_encoded_size_of(kind: FeedbackKind) -> usize {
        use firmware_core::{
            ActionFeedback, CorrectnessFeedback, EStopFeedback, PerturbationFeedback,
            PreferenceFeedback, RankingFeedback, RewardFeedback, SemanticFeedback, SpanFeedback,
        };
        let content = match kind {
            FeedbackKind::Action => ActionFeedback::POSTCARD_MAX_SIZE,
            FeedbackKind::Preference => PreferenceFeedback::POSTCARD_MAX_SIZE,
            FeedbackKind::Semantic => SemanticFeedback::POSTCARD_MAX_SIZE,
            FeedbackKind::Perturbation => PerturbationFeedback::POSTCARD_MAX_SIZE,
            FeedbackKind::Reward => RewardFeedback::POSTCARD_MAX_SIZE,
            FeedbackKind::Correctness => CorrectnessFeedback::POSTCARD_MAX_SIZE,
            FeedbackKind::Span => SpanFeedback::POSTCARD_MAX_SIZE,
            FeedbackKind::Ranking => RankingFeedback::POSTCARD_MAX_SIZE,
            FeedbackKind::EStop => EStopFeedback::POSTCARD_MAX_SIZE,
        };
        SECURED_OVERHEAD
            + TAG
            + DeliveryId::POSTCARD_MAX_SIZE
            + u32::POSTCARD_MAX_SIZE
            + TAG
            + content
    }
}

/// The feedback `id` was applied (now or the first time it arrived).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize, MaxSize)]
pub struct Ack {
    /// The delivery acknowledged.
    pub id: DeliveryId,
}

/// Why a feedback was refused. The sender does not retransmit it.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize, MaxSize)]
#[non_exhaustive]
pub enum NackCode {
    /// The tick is not among the car's recent ticks (or it had no action then).
    UnknownTick,
    /// The learner refused the feedback (degenerate, not allowed, bad numbers).
    Rejected,
    /// The sequence number is older than the receiver's dedupe window: it cannot tell whether
    /// it was applied, so it is not applied again.
    Stale,
    /// The feedback belongs to another session than the car's configured one (or the car holds
    /// none).
    WrongSession,
}

impl fmt::Display for NackCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            NackCode::UnknownTick => "unknown tick",
            NackCode::Rejected => "feedback rejected by the learner",
            NackCode::Stale => "sequence number older than the dedupe window",
            NackCode::WrongSession => "feedback of another session than the car's",
        })
    }
}

impl From<&FeedbackError> for NackCode {
    fn from(e: &FeedbackError) -> Self {
        match e {
            FeedbackError::UnknownTick(_) => NackCode::UnknownTick,
            _ => NackCode::Rejected,
        }
    }
}

/// The feedback `id` was not applied, because of `code`.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize, MaxSize)]
pub struct Nack {
    /// The delivery refused.
    pub id: DeliveryId,
    /// Why.
    pub code: NackCode,
}

/// What went wrong, in an [`ErrorReport`].
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize, MaxSize)]
#[non_exhaustive]
pub enum ErrorCode {
    /// A message did not decode (encoding, trailing bytes, invalid track).
    Decode,
    /// A message came with another protocol version.
    Version,
    /// A CAN stream could not be reassembled (gap, timeout, overlong, unexpected frame).
    Reassembly,
    /// A message came on a stream that does not carry it.
    WrongStream,
    /// The observation of the tick was refused (`Observation::validate`).
    Observation,
    /// The learner configuration was refused (`LearnerParams::check`).
    Params,
    /// The receiver could not do what the message asked for another reason.
    Internal,
    /// The car holds no configured learner: it does not act until configured.
    NotConfigured,
    /// A configure with a session that is neither the car's current one nor the next.
    Session,
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ErrorCode::Decode => "message does not decode",
            ErrorCode::Version => "other protocol version",
            ErrorCode::Reassembly => "CAN reassembly failed",
            ErrorCode::WrongStream => "message on the wrong CAN stream",
            ErrorCode::Observation => "observation refused",
            ErrorCode::Params => "learner configuration refused",
            ErrorCode::Internal => "internal error",
            ErrorCode::NotConfigured => "no configured learner",
            ErrorCode::Session => "configure session is neither the current nor the next",
        })
    }
}

/// A report of something that went wrong at the sender.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize, MaxSize)]
pub struct ErrorReport {
    /// What went wrong.
    pub code: ErrorCode,
    /// The tick concerned, if any.
    pub tick: Option<u32>,
}

/// Bytes of a handshake nonce.
pub const NONCE_LEN: usize = 8;

/// Host → car: "tell me your freshness and your status". Answered with a [`Welcome`] carrying
/// the same nonce. See [`crate::secure`] for how it resynchronises the freshness counters.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize, MaxSize)]
pub struct Hello {
    /// A number the host never used before (random): the welcome must repeat it.
    pub nonce: [u8; NONCE_LEN],
    /// The car's epoch as the host believes it (0: none yet).
    pub epoch: u32,
    /// The host's next freshness counter in that epoch.
    pub counter: u32,
}

/// Car → host, the answer to a [`Hello`].
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize, MaxSize)]
pub struct Welcome {
    /// The hello's nonce.
    pub nonce: [u8; NONCE_LEN],
    /// The car's epoch (new at every start of the car).
    pub epoch: u32,
    /// The freshness counter of this very message.
    pub counter: u32,
    /// The next host → car counter the car accepts.
    pub host_next: u32,
    /// What the car holds.
    pub status: CarStatus,
    /// Messages the car refused since it started (authentication or freshness failed).
    pub refused: u32,
}

/// Every message of the protocol. See the module documentation for the table.
///
/// The observation makes it about 200 bytes; without a heap there is no boxing it, and a
/// message lives in one place (a static or the stack of the loop that handles it).
#[expect(
    clippy::large_enum_variant,
    reason = "no heap: the observation is stored inline"
)]
#[derive(Clone, PartialEq, Debug, Serialize, Deserialize)]
pub enum Message {
    /// An observation, host → car.
    Observation(ObservationMessage),
    /// An action command (or stop), car → host.
    Action(ActionCommand),
    /// Feedback, host → car.
    Feedback(FeedbackMessage),
    /// Feedback applied, car → host.
    Ack(Ack),
    /// Feedback refused, car → host.
    Nack(Nack),
    /// Alive, both ways.
    Heartbeat,
    /// The car's status and learner, car → host.
    Weights(WeightsReport),
    /// A learner to start from, host → car (the car answers with a weights report or an error).
    Configure(ConfigureMessage),
    /// Host → car: stop, forget the recent ticks; keep the learner and the dedupe windows.
    Reset,
    /// Something went wrong, both ways.
    Error(ErrorReport),
    /// Host → car: report the learner (the car answers with [`Message::Weights`]).
    WeightsRequest,
    /// Host → car: the freshness handshake (answered with [`Message::Welcome`]).
    Hello(Hello),
    /// Car → host: the answer to a hello.
    Welcome(Welcome),
}

impl MaxSize for Message {
    const POSTCARD_MAX_SIZE: usize = TAG + max_payload();
}

const fn max_payload() -> usize {
    let mut max = 0;
    let mut i = 0;
    while i < MessageKind::ALL.len() {
        let n = MessageKind::ALL[i].max_payload_size();
        if n > max {
            max = n;
        }
        i += 1;
    }
    max
}

/// The kind of a [`Message`], without its payload: the variant, in the same order.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
#[repr(u8)]
pub enum MessageKind {
    /// [`Message::Observation`].
    Observation = 0,
    /// [`Message::Action`].
    Action = 1,
    /// [`Message::Feedback`].
    Feedback = 2,
    /// [`Message::Ack`].
    Ack = 3,
    /// [`Message::Nack`].
    Nack = 4,
    /// [`Message::Heartbeat`].
    Heartbeat = 5,
    /// [`Message::Weights`].
    Weights = 6,
    /// [`Message::Configure`].
    Configure = 7,
    /// [`Message::Reset`].
    Reset = 8,
    /// [`Message::Error`].
    Error = 9,
    /// [`Message::WeightsRequest`].
    WeightsRequest = 10,
    /// [`Message::Hello`].
    Hello = 11,
    /// [`Message::Welcome`].
    Welcome = 12,
}

/// Bytes of a variant number (postcard varint of values below 128).
const TAG: usize = 1;

impl MessageKind {
    /// Every kind, in variant order.
    pub const ALL: [MessageKind; 13] = [
        MessageKind::Observation,
        MessageKind::Action,
        MessageKind::Feedback,
        MessageKind::Ack,
        MessageKind::Nack,
        MessageKind::Heartbeat,
        MessageKind::Weights,
        MessageKind::Configure,
        MessageKind::Reset,
        MessageKind::Error,
        MessageKind::WeightsRequest,
        MessageKind::Hello,
        MessageKind::Welcome,
    ];

    /// The kind whose variant number is `tag`.
    pub const fn from_tag(tag: u8) -> Option<Self> {
        if (tag as usize) < Self::ALL.len() {
            Some(Self::ALL[tag as usize])
        } else {
            None
        }
    }

    /// The largest payload after the variant number (bytes).
    const fn max_payload_size(self) -> usize {
        match self {
            MessageKind::Observation => ObservationMessage::POSTCARD_MAX_SIZE,
            MessageKind::Action => ActionCommand::POSTCARD_MAX_SIZE,
            MessageKind::Feedback => FeedbackMessage::POSTCARD_MAX_SIZE,
            MessageKind::Ack => Ack::POSTCARD_MAX_SIZE,
            MessageKind::Nack => Nack::POSTCARD_MAX_SIZE,
            MessageKind::Heartbeat => 0,
            MessageKind::Weights => WeightsReport::POSTCARD_MAX_SIZE,
            MessageKind::Configure => ConfigureMessage::POSTCARD_MAX_SIZE,
            MessageKind::Reset => 0,
            MessageKind::Error => ErrorReport::POSTCARD_MAX_SIZE,
            MessageKind::WeightsRequest => 0,
            MessageKind::Hello => Hello::POSTCARD_MAX_SIZE,
            MessageKind::Welcome => Welcome::POSTCARD_MAX_SIZE,
        }
    }

    /// The largest secured message of this kind on the wire (version, payload, freshness byte
    /// and MAC), in bytes.
    pub const fn max_encoded_size(self) -> usize {
        SECURED_OVERHEAD + TAG + self.max_payload_size()
    }

    /// The largest plain envelope of this kind ([`Message::emit`]: version, payload, CRC).
    pub const fn max_stored_size(self) -> usize {
        ENVELOPE_OVERHEAD + TAG + self.max_payload_size()
    }

    /// A short name ("observation", "action", …).
    pub const fn name(self) -> &'static str {
        match self {
            MessageKind::Observation => "observation",
            MessageKind::Action => "action",
            MessageKind::Feedback => "feedback",
            MessageKind::Ack => "ack",
            MessageKind::Nack => "nack",
            MessageKind::Heartbeat => "heartbeat",
            MessageKind::Weights => "weights",
            MessageKind::Configure => "configure",
            MessageKind::Reset => "reset",
            MessageKind::Error => "error",
            MessageKind::WeightsRequest => "weights request",
            MessageKind::Hello => "hello",
            MessageKind::Welcome => "welcome",
        }
    }
}

impl fmt::Display for MessageKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The largest secured message of any kind: the size of every message buffer.
pub const MAX_MESSAGE_SIZE: usize = SECURED_OVERHEAD + Message::POSTCARD_MAX_SIZE;

const _: () = assert!(
    MessageKind::ALL.len() < 128,
    "variant numbers are one-byte varints"
);
const _: () = assert!(
    MessageKind::Observation.max_encoded_size() == MAX_MESSAGE_SIZE,
    "the observation is the largest message"
);
const _: () = assert!(
    ENVELOPE_OVERHEAD <= SECURED_OVERHEAD,
    "a stored message fits a wire buffer"
);

/// Why bytes did not decode as a [`Message`].
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum DecodeError {
    /// The envelope or its payload is bad (length, CRC, version, encoding, trailing bytes).
    Envelope(EnvelopeError),
    /// An action command's track has a non-finite or out-of-range number.
    InvalidTrack,
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::Envelope(e) => e.fmt(f),
            DecodeError::InvalidTrack => f.write_str("action command out of the car's limits"),
        }
    }
}

impl core::error::Error for DecodeError {}

impl From<EnvelopeError> for DecodeError {
    fn from(e: EnvelopeError) -> Self {
        DecodeError::Envelope(e)
    }
}

impl DecodeError {
    /// The [`ErrorCode`] to report this error with.
    pub const fn code(self) -> ErrorCode {
        match self {
            DecodeError::Envelope(EnvelopeError::Version(_)) => ErrorCode::Version,
            _ => ErrorCode::Decode,
        }
    }
}

impl Message {
    /// The kind of this message.
    pub const fn kind(&self) -> MessageKind {
        match self {
            Message::Observation(_) => MessageKind::Observation,
            Message::Action(_) => MessageKind::Action,
            Message::Feedback(_) => MessageKind::Feedback,
            Message::Ack(_) => MessageKind::Ack,
            Message::Nack(_) => MessageKind::Nack,
            Message::Heartbeat => MessageKind::Heartbeat,
            Message::Weights(_) => MessageKind::Weights,
            Message::Configure(_) => MessageKind::Configure,
            Message::Reset => MessageKind::Reset,
            Message::Error(_) => MessageKind::Error,
            Message::WeightsRequest => MessageKind::WeightsRequest,
            Message::Hello(_) => MessageKind::Hello,
            Message::Welcome(_) => MessageKind::Welcome,
        }
    }

    /// Writes the message as a plain envelope (version, postcard, CRC-16) into `buf` and returns
    /// the bytes written: the storage form (recorded ticks, tests), not the wire's, which is
    /// authenticated ([`crate::secure`]). A buffer of [`MAX_MESSAGE_SIZE`] bytes always suffices.
    pub fn emit<'b>(&self, buf: &'b mut [u8]) -> Result<&'b [u8], EnvelopeError> {
        seal(self, buf)
    }

    /// Reads a plain envelope written by [`Message::emit`]. Total: any bytes give a message or
    /// an error.
    pub fn parse(bytes: &[u8]) -> Result<Message, DecodeError> {
        Self::decode_payload(Envelope::new_checked(bytes)?.into_payload())
    }

    /// Decodes a postcard payload (the variant number and its fields), requiring every byte to
    /// be used, and checks the numbers the protocol defines. Total.
    pub fn decode_payload(payload: &[u8]) -> Result<Message, DecodeError> {
        let (msg, rest) = postcard::take_from_bytes::<Message>(payload)
            .map_err(|_| DecodeError::Envelope(EnvelopeError::Decode))?;
        if !rest.is_empty() {
            return Err(DecodeError::Envelope(EnvelopeError::TrailingBytes));
        }
        if let Message::Action(ActionCommand {
            command: Command::Track(track),
            ..
        }) = &msg
        {
            track.check()?;
        }
        Ok(msg)
    }
}

impl From<Ack> for Message {
    fn from(a: Ack) -> Self {
        Message::Ack(a)
    }
}

impl From<Nack> for Message {
    fn from(n: Nack) -> Self {
        Message::Nack(n)
    }
}

impl From<FeedbackMessage> for Message {
    fn from(f: FeedbackMessage) -> Self {
        Message::Feedback(f)
    }
}

impl From<ActionCommand> for Message {
    fn from(a: ActionCommand) -> Self {
        Message::Action(a)
    }
}

/// Proptest strategies for messages, shared by the tests of this crate.
#[cfg(test)]
pub(crate) mod strategies {
    use super::*;
    use firmware_core::feature::Feature;
    use firmware_core::feedback::perturbation::Milli;
    use firmware_core::observation::{MAX_OBJECTS, PathReference, SemanticClass, SemanticObject};
    use firmware_core::{
        ActionFeedback, CorrectnessFeedback, EStopFeedback, LearnerKind, LearnerParams,
        LearnerState, MAX_RANKED, PerturbationFeedback, Polarity, PreferenceFeedback,
        RankingFeedback, RewardFeedback, SemanticFeedback, SpanFeedback,
    };
    use proptest::prelude::*;

    fn real() -> impl Strategy<Value = f32> {
        -1.0e3f32..1.0e3
    }

    fn action() -> impl Strategy<Value = ActionIndex> {
        (0usize..64).prop_map(|a| ActionIndex::new(a).unwrap())
    }

    fn observation() -> impl Strategy<Value = Observation> {
        let object =
            (0usize..3, real(), real(), real()).prop_map(|(c, x, y, radius)| SemanticObject {
                class: SemanticClass::ALL[c],
                x,
                y,
                radius,
            });
        (
            proptest::collection::vec(0.0f32..10.0, 64),
            proptest::collection::vec(object, 0..=MAX_OBJECTS),
            (real(), real(), real(), real()),
        )
            .prop_map(|(ranges, objects, (x, y, heading, speed))| {
                let mut obs = Observation::open_space();
                obs.scan.ranges.copy_from_slice(&ranges);
                for o in objects {
                    obs.objects.push(o).unwrap();
                }
                obs.reference = PathReference { x, y, heading };
                obs.speed = speed;
                // What goes on the wire: the decoded message equals it.
                crate::quantize::quantize(&obs)
            })
    }

    pub(crate) fn feedback() -> impl Strategy<Value = Feedback> {
        prop_oneof![
            action().prop_map(|action| Feedback::Action(ActionFeedback { action })),
            (action(), action()).prop_map(|(preferred, other)| Feedback::Preference(
                PreferenceFeedback { preferred, other }
            )),
            proptest::collection::vec(proptest::option::of(any::<bool>()), 6).prop_map(|ps| {
                let mut s = SemanticFeedback::new();
                for (f, p) in Feature::ALL.iter().zip(ps) {
                    if let Some(prefer) = p {
                        s = if prefer { s.prefer(*f) } else { s.avoid(*f) };
                    }
                }
                Feedback::Semantic(s)
            }),
            // Any bytes: the car checks the ranges when it learns, not when it decodes.
            proptest::array::uniform6(any::<i16>()).prop_map(|t| Feedback::Perturbation(
                PerturbationFeedback {
                    corrected: t.map(Milli::new)
                }
            )),
            any::<i8>().prop_map(|hundredths| Feedback::Reward(RewardFeedback { hundredths })),
            any::<bool>()
                .prop_map(|correct| Feedback::Correctness(CorrectnessFeedback { correct })),
            (any::<u8>(), any::<bool>())
                .prop_map(|(ticks, good)| Feedback::Span(SpanFeedback { ticks, good })),
            (
                proptest::collection::vec(action(), 0..=MAX_RANKED),
                any::<bool>()
            )
                .prop_map(|(actions, ordered)| Feedback::Ranking(
                    RankingFeedback::new(&actions, ordered).unwrap()
                )),
            Just(Feedback::EStop(EStopFeedback)),
        ]
    }

    fn params() -> impl Strategy<Value = LearnerParams> {
        (
            0usize..5,
            real(),
            proptest::option::of(real()),
            proptest::array::uniform6(real()),
        )
            .prop_map(|(k, step, radius, initial)| LearnerParams {
                kind: LearnerKind::ALL[k],
                step,
                radius,
                initial,
            })
    }

    fn id() -> impl Strategy<Value = DeliveryId> {
        (any::<u8>(), any::<u8>()).prop_map(|(session, seq)| DeliveryId { session, seq })
    }

    fn nack_code() -> impl Strategy<Value = NackCode> {
        prop_oneof![
            Just(NackCode::UnknownTick),
            Just(NackCode::Rejected),
            Just(NackCode::Stale),
            Just(NackCode::WrongSession),
        ]
    }

    fn stop_reason() -> impl Strategy<Value = StopReason> {
        prop_oneof![
            Just(StopReason::Blocked),
            Just(StopReason::Watchdog),
            Just(StopReason::Reset),
            Just(StopReason::Reconfigured),
            Just(StopReason::EStop),
        ]
    }

    pub(crate) fn status() -> impl Strategy<Value = CarStatus> {
        (proptest::option::of(any::<u8>()), any::<u32>()).prop_map(|(session, generation)| {
            CarStatus {
                session,
                generation,
            }
        })
    }

    /// Any message `Message::parse` accepts.
    pub(crate) fn message() -> impl Strategy<Value = Message> {
        prop_oneof![
            (any::<u32>(), observation()).prop_map(|(tick, observation)| Message::Observation(
                ObservationMessage { tick, observation }
            )),
            (any::<u32>(), proptest::option::of(action()), any::<u64>()).prop_map(
                |(tick, a, bits)| Message::Action(
                    ActionCommand::new(tick, a).with_allowed(ActionMask::from_bits(bits))
                )
            ),
            (any::<u32>(), stop_reason())
                .prop_map(|(tick, r)| Message::Action(ActionCommand::stop(tick, r))),
            (id(), any::<u32>(), feedback()).prop_map(|(id, tick, feedback)| {
                Message::Feedback(FeedbackMessage { id, tick, feedback })
            }),
            id().prop_map(|id| Message::Ack(Ack { id })),
            (id(), nack_code()).prop_map(|(id, code)| Message::Nack(Nack { id, code })),
            Just(Message::Heartbeat),
            (status(), snapshot()).prop_map(|(status, snapshot)| Message::Weights(WeightsReport {
                status,
                snapshot
            })),
            (any::<u8>(), snapshot()).prop_map(|(session, snapshot)| Message::Configure(
                ConfigureMessage { session, snapshot }
            )),
            Just(Message::Reset),
            (
                0usize..ERROR_CODES.len(),
                proptest::option::of(any::<u32>())
            )
                .prop_map(|(c, tick)| {
                    Message::Error(ErrorReport {
                        code: ERROR_CODES[c],
                        tick,
                    })
                }),
            Just(Message::WeightsRequest),
            (any::<[u8; NONCE_LEN]>(), any::<u32>(), any::<u32>()).prop_map(
                |(nonce, epoch, counter)| Message::Hello(Hello {
                    nonce,
                    epoch,
                    counter
                })
            ),
            (
                any::<[u8; NONCE_LEN]>(),
                (any::<u32>(), any::<u32>(), any::<u32>()),
                status(),
                any::<u32>()
            )
                .prop_map(|(nonce, (epoch, counter, host_next), status, refused)| {
                    Message::Welcome(Welcome {
                        nonce,
                        epoch,
                        counter,
                        host_next,
                        status,
                        refused,
                    })
                }),
        ]
    }

    fn snapshot() -> impl Strategy<Value = LearnerSnapshot> {
        (
            params(),
            proptest::array::uniform6(real()),
            proptest::array::uniform6(real()),
            any::<u32>(),
        )
            .prop_map(|(params, iterate, average, steps)| LearnerSnapshot {
                version: firmware_core::SNAPSHOT_VERSION,
                params,
                state: LearnerState {
                    iterate,
                    average,
                    accumulator: [0.0; 6],
                    steps,
                },
            })
    }

    /// Polarity is re-exported here so the tests below can name it.
    pub(crate) type Pol = Polarity;

    /// Every error code, in variant order.
    pub(crate) const ERROR_CODES: [ErrorCode; 9] = [
        ErrorCode::Decode,
        ErrorCode::Version,
        ErrorCode::Reassembly,
        ErrorCode::WrongStream,
        ErrorCode::Observation,
        ErrorCode::Params,
        ErrorCode::Internal,
        ErrorCode::NotConfigured,
        ErrorCode::Session,
    ];
}

#[cfg(test)]
mod tests {
    use super::strategies::{ERROR_CODES, Pol, message};
    use super::*;
    use crate::envelope::{CRC16, PROTOCOL_VERSION};
    use firmware_core::feature::Feature;
    use firmware_core::observation::{PathReference, SemanticClass, SemanticObject};
    use firmware_core::{
        ActionFeedback, CorrectnessFeedback, EStopFeedback, LearnerKind, LearnerParams,
        LearnerState, PerturbationFeedback, PreferenceFeedback, RankingFeedback, RewardFeedback,
        SemanticFeedback, SpanFeedback,
    };
    use proptest::prelude::*;

    fn a(i: usize) -> ActionIndex {
        ActionIndex::new(i).unwrap()
    }

    const ID: DeliveryId = DeliveryId {
        session: 7,
        seq: 200,
    };

    /// Emits `value` as a plain envelope, checks that the payload is exactly `payload` and the
    /// envelope is `[3, payload.., crc_lo, crc_hi]`, and that it parses back to `value`.
    #[track_caller]
    fn test_one(value: Message, payload: &[u8]) {
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        let bytes = value.emit(&mut buf).unwrap();
        let mut expected = std::vec![PROTOCOL_VERSION_BYTE];
        expected.extend_from_slice(payload);
        let crc = CRC16.checksum(&expected).to_le_bytes();
        expected.extend_from_slice(&crc);
        assert_eq!(bytes, &expected[..], "{value:?}");
        assert_eq!(
            payload[0],
            value.kind() as u8,
            "variant number of {value:?}"
        );
        assert!(bytes.len() <= value.kind().max_stored_size());
        assert!(payload.len() + SECURED_OVERHEAD <= value.kind().max_encoded_size());
        assert_eq!(Message::parse(bytes), Ok(value));
    }

    const PROTOCOL_VERSION_BYTE: u8 = 4;

    #[test]
    fn the_version_byte_is_the_protocol_version() {
        assert_eq!(PROTOCOL_VERSION, PROTOCOL_VERSION_BYTE);
    }

    /// The 80 bytes of 64 ten-bit codes, written bit by bit (independently of the codec).
    fn packed(codes: &[u16; 64]) -> std::vec::Vec<u8> {
        let mut out = std::vec![0u8; 80];
        for (j, &c) in codes.iter().enumerate() {
            for b in 0..10 {
                if c >> b & 1 == 1 {
                    let bit = 10 * j + b;
                    out[bit / 8] |= 1 << (bit % 8);
                }
            }
        }
        out
    }

    #[test]
    fn golden_observation() {
        let mut obs = Observation::open_space();
        obs.scan.ranges[0] = 0.5;
        obs.scan.ranges[1] = 1.234; // 123 cm
        obs.objects
            .push(SemanticObject {
                class: SemanticClass::Stairs,
                x: 2.0,
                y: -1.0,
                radius: 0.25,
            })
            .unwrap();
        obs.reference = PathReference {
            x: 1.0,
            y: 0.0,
            heading: -0.5,
        };
        obs.speed = 1.0;
        let obs = crate::quantize::quantize(&obs);
        assert_eq!(obs.scan.ranges[1], 1.23);
        let mut codes = [1000u16; 64];
        codes[0] = 50;
        codes[1] = 123;
        let mut payload = std::vec![0u8, 0xAC, 0x02]; // variant 0, tick 300 (varint)
        payload.extend_from_slice(&packed(&codes));
        payload.extend_from_slice(&[
            1, // one object
            1, // Stairs
            0xD0, 0x07, // x 2000 mm
            0x18, 0xFC, // y -1000 mm
            0xFA, 0x00, // radius 250 mm
            0xE8, 0x03, // reference x 1000 mm
            0, 0, // reference y
            0x78, 0xEC, // heading -5000e-4 rad
            0xE8, 0x03, // speed 1000 mm/s
        ]);
        test_one(
            Message::Observation(ObservationMessage {
                tick: 300,
                observation: obs,
            }),
            &payload,
        );
    }

    #[test]
    fn golden_action_and_stop() {
        #[rustfmt::skip]
        let straight = [
            1, 0xAC, 0x02, // variant 1, tick 300
            0, 0,          // Track, action 0
            0, 0,  0xF4, 0x01, // segment 1: steering 0, length 500 mm
            0, 0,  0xF4, 0x01, // segment 2: steering 0, length 500 mm
            0xE8, 0x03,        // speed 1000 mm/s
            0x80, 0x01,        // allowed: action 7 alone (a u64 varint)
        ];
        let mask = ActionMask::from_bits(1 << 7);
        test_one(
            Message::Action(ActionCommand::new(300, Some(a(0))).with_allowed(mask)),
            &straight,
        );
        let reasons = [
            StopReason::Blocked,
            StopReason::Watchdog,
            StopReason::Reset,
            StopReason::Reconfigured,
            StopReason::EStop,
        ];
        for (i, r) in reasons.into_iter().enumerate() {
            test_one(
                Message::Action(ActionCommand::stop(7, r)),
                &[1, 7, 1, i as u8, 0],
            );
        }
        assert_eq!(
            ActionCommand::new(7, None),
            ActionCommand::stop(7, StopReason::Blocked)
        );
        // Every action allowed: 64 one bits, a ten-byte varint.
        let mut all = std::vec![1, 7, 1, 0];
        all.extend_from_slice(&[0xFF; 9]);
        all.push(0x01);
        test_one(
            Message::Action(ActionCommand::new(7, None).with_allowed(ActionMask::ALL)),
            &all,
        );
        // A curved one: the lattice's numbers, rounded to their steps.
        let t = Track::of(a(1));
        let lattice = lattice::trajectory(a(1));
        let mut payload = std::vec![1, 9, 0, 1];
        for (s, l) in t.segments.iter().zip(lattice.segments.iter()) {
            let steering = (l.steering * 10_000.0).round() as i16;
            let length = (l.length * 1000.0).round() as u16;
            assert_eq!(s.steering, steering as f32 / 10_000.0);
            payload.extend_from_slice(&steering.to_le_bytes());
            payload.extend_from_slice(&length.to_le_bytes());
        }
        payload.extend_from_slice(&((lattice.speed * 1000.0).round() as u16).to_le_bytes());
        payload.push(0); // empty mask
        assert!(
            t.segments[1].steering > 0.1,
            "action 1 turns left in its second half"
        );
        test_one(Message::Action(ActionCommand::new(9, Some(a(1)))), &payload);
        // Which commands answer an observation.
        assert!(ActionCommand::new(1, Some(a(1))).answers_observation());
        assert!(ActionCommand::new(1, None).answers_observation());
        for r in &reasons[1..] {
            assert!(!ActionCommand::stop(1, *r).answers_observation());
        }
    }

    #[test]
    fn golden_feedback_of_every_kind() {
        let fb = |feedback| {
            Message::Feedback(FeedbackMessage {
                id: ID,
                tick: 1,
                feedback,
            })
        };
        // variant 2, session 7, seq 200, tick 1, then the Feedback enum.
        test_one(
            fb(Feedback::Action(ActionFeedback { action: a(17) })),
            &[2, 7, 200, 1, 0, 17],
        );
        test_one(
            fb(Feedback::Preference(PreferenceFeedback {
                preferred: a(3),
                other: a(63),
            })),
            &[2, 7, 200, 1, 1, 3, 63],
        );
        let said = SemanticFeedback::new()
            .avoid(Feature::Door)
            .prefer(Feature::Path);
        assert_eq!(said.get(Feature::Path), Some(Pol::Prefer));
        // Six Option<Polarity>, in feature order: None, Some(Avoid), None, None, Some(Prefer), None.
        test_one(
            fb(Feedback::Semantic(said)),
            &[2, 7, 200, 1, 2, 0, 1, 0, 0, 0, 1, 1, 0],
        );
        // Perturbation: six fixed-width i16 thousandths, little-endian.
        let corrected = [10.0, 0.5, 2.0, 10.0, 0.25, -1.5];
        #[rustfmt::skip]
        test_one(
            fb(Feedback::Perturbation(PerturbationFeedback::new(&corrected).unwrap())),
            &[2, 7, 200, 1, 3,
              0x10, 0x27, 0xF4, 0x01, 0xD0, 0x07, 0x10, 0x27, 0xFA, 0x00, 0x24, 0xFA],
        );
        // Reward: one i8 of hundredths (-35 is 0xDD).
        test_one(
            fb(Feedback::Reward(RewardFeedback::new(-0.35).unwrap())),
            &[2, 7, 200, 1, 4, 0xDD],
        );
        // Correct / incorrect: one bool.
        test_one(
            fb(Feedback::Correctness(CorrectnessFeedback {
                correct: false,
            })),
            &[2, 7, 200, 1, 5, 0],
        );
        test_one(
            fb(Feedback::Correctness(CorrectnessFeedback { correct: true })),
            &[2, 7, 200, 1, 5, 1],
        );
        // Span: ticks, good.
        test_one(
            fb(Feedback::Span(SpanFeedback {
                ticks: 4,
                good: false,
            })),
            &[2, 7, 200, 1, 6, 4, 0],
        );
        // Ranking: the number of actions, the actions best first, ordered.
        test_one(
            fb(Feedback::Ranking(
                RankingFeedback::new(&[a(9), a(0), a(63)], true).unwrap(),
            )),
            &[2, 7, 200, 1, 7, 3, 9, 0, 63, 1],
        );
        // E-stop: the variant alone.
        test_one(fb(Feedback::EStop(EStopFeedback)), &[2, 7, 200, 1, 8]);
    }

    #[test]
    fn golden_ack_nack_heartbeat_reset_error() {
        test_one(Message::Ack(Ack { id: ID }), &[3, 7, 200]);
        let nack = |code| Message::Nack(Nack { id: ID, code });
        test_one(nack(NackCode::UnknownTick), &[4, 7, 200, 0]);
        test_one(nack(NackCode::Rejected), &[4, 7, 200, 1]);
        test_one(nack(NackCode::Stale), &[4, 7, 200, 2]);
        test_one(nack(NackCode::WrongSession), &[4, 7, 200, 3]);
        test_one(Message::Heartbeat, &[5]);
        test_one(Message::Reset, &[8]);
        test_one(
            Message::Error(ErrorReport {
                code: ErrorCode::Observation,
                tick: Some(9),
            }),
            &[9, 4, 1, 9],
        );
        for (i, code) in ERROR_CODES.into_iter().enumerate() {
            let m = Message::Error(ErrorReport { code, tick: None });
            test_one(m, &[9, i as u8, 0]);
        }
    }

    #[test]
    fn golden_weights_and_configure() {
        let params = LearnerParams::paper();
        let snap = LearnerSnapshot {
            version: 1,
            params,
            state: LearnerState {
                iterate: [0.0; 6],
                average: [0.0; 6],
                accumulator: [0.0; 6],
                steps: 3,
            },
        };
        // variant 6, status: Some(session 9), generation 300; snapshot: version 1, kind Ogd
        let mut payload = std::vec![6, 1, 9, 0xAC, 0x02, 1, 0];
        payload.extend_from_slice(&[0x0A, 0xD7, 0x23, 0x3C]); // step 0.01
        payload.push(0); // no radius
        payload.extend_from_slice(&[0; 24]); // initial weights
        payload.extend_from_slice(&[0; 72]); // iterate, average, accumulator
        payload.push(3); // steps
        let status = CarStatus {
            session: Some(9),
            generation: 300,
        };
        test_one(
            Message::Weights(WeightsReport {
                status,
                snapshot: snap,
            }),
            &payload,
        );

        let mut cfg = LearnerParams::new(LearnerKind::AdaGrad).with_radius(2.0);
        cfg.initial[5] = -1.0;
        let fresh = LearnerSnapshot {
            version: 1,
            params: cfg,
            state: LearnerState {
                iterate: cfg.initial,
                average: cfg.initial,
                accumulator: [0.0; 6],
                steps: 0,
            },
        };
        let weights = |payload: &mut std::vec::Vec<u8>| {
            payload.extend_from_slice(&[0; 20]);
            payload.extend_from_slice(&[0x00, 0x00, 0x80, 0xBF]); // [5] = -1.0
        };
        let mut payload = std::vec![7, 200, 1, 3]; // variant 7, session 200, version 1, AdaGrad
        payload.extend_from_slice(&[0xCD, 0xCC, 0xCC, 0x3D]); // step 0.1
        payload.extend_from_slice(&[1, 0x00, 0x00, 0x00, 0x40]); // Some(2.0)
        weights(&mut payload); // initial
        weights(&mut payload); // iterate
        weights(&mut payload); // average
        payload.extend_from_slice(&[0; 24]); // accumulator
        payload.push(0); // steps
        test_one(
            Message::Configure(ConfigureMessage {
                session: 200,
                snapshot: fresh,
            }),
            &payload,
        );
        test_one(Message::WeightsRequest, &[10]);
    }

    #[test]
    fn golden_hello_and_welcome() {
        let nonce = [1, 2, 3, 4, 5, 6, 7, 8];
        test_one(
            Message::Hello(Hello {
                nonce,
                epoch: 300,
                counter: 5,
            }),
            &[11, 1, 2, 3, 4, 5, 6, 7, 8, 0xAC, 0x02, 5],
        );
        test_one(
            Message::Welcome(Welcome {
                nonce,
                epoch: 300,
                counter: 7,
                host_next: 6,
                status: CarStatus {
                    session: None,
                    generation: 0,
                },
                refused: 2,
            }),
            &[12, 1, 2, 3, 4, 5, 6, 7, 8, 0xAC, 0x02, 7, 6, 0, 0, 2],
        );
    }

    #[test]
    fn maximum_sizes_are_reached_by_the_worst_case_values() {
        let mut obs = Observation::open_space();
        while obs
            .objects
            .push(SemanticObject {
                class: SemanticClass::Chair,
                x: 1.0,
                y: 1.0,
                radius: 0.3,
            })
            .is_ok()
        {}
        let every = SemanticFeedback::new()
            .avoid(Feature::Obstacles)
            .avoid(Feature::Door)
            .avoid(Feature::Stairs)
            .avoid(Feature::Chair)
            .prefer(Feature::Path)
            .prefer(Feature::Right);
        let params = LearnerParams::paper().with_radius(1.0);
        // The largest snapshot: every varint at its longest.
        let snapshot = LearnerSnapshot {
            version: u16::MAX,
            params,
            state: LearnerState {
                iterate: [1.0; 6],
                average: [1.0; 6],
                accumulator: [1.0; 6],
                steps: u32::MAX,
            },
        };
        let status = CarStatus {
            session: Some(u8::MAX),
            generation: u32::MAX,
        };
        let worst = [
            (
                Message::Observation(ObservationMessage {
                    tick: u32::MAX,
                    observation: obs,
                }),
                157,
            ),
            (
                Message::Action(
                    ActionCommand::new(u32::MAX, Some(a(63))).with_allowed(ActionMask::ALL),
                ),
                34,
            ),
            (
                Message::Feedback(FeedbackMessage {
                    id: ID,
                    tick: u32::MAX,
                    feedback: Feedback::Semantic(every),
                }),
                27,
            ),
            (Message::Ack(Ack { id: ID }), 9),
            (
                Message::Nack(Nack {
                    id: ID,
                    code: NackCode::Stale,
                }),
                10,
            ),
            (Message::Heartbeat, 7),
            (Message::Weights(WeightsReport { status, snapshot }), 128),
            (
                Message::Configure(ConfigureMessage {
                    session: u8::MAX,
                    snapshot,
                }),
                122,
            ),
            (Message::Reset, 7),
            (
                Message::Error(ErrorReport {
                    code: ErrorCode::Internal,
                    tick: Some(u32::MAX),
                }),
                14,
            ),
            (Message::WeightsRequest, 7),
            (
                Message::Hello(Hello {
                    nonce: [0xFF; NONCE_LEN],
                    epoch: u32::MAX,
                    counter: u32::MAX,
                }),
                25,
            ),
            (
                Message::Welcome(Welcome {
                    nonce: [0xFF; NONCE_LEN],
                    epoch: u32::MAX,
                    counter: u32::MAX,
                    host_next: u32::MAX,
                    status,
                    refused: u32::MAX,
                }),
                42,
            ),
        ];
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        for (i, (msg, size)) in worst.into_iter().enumerate() {
            let kind = msg.kind();
            assert_eq!(
                kind,
                MessageKind::ALL[i],
                "the table follows the variant order"
            );
            assert_eq!(kind.max_encoded_size(), size, "{kind}");
            assert_eq!(
                msg.emit(&mut buf).unwrap().len() - ENVELOPE_OVERHEAD + SECURED_OVERHEAD,
                size,
                "{kind} reaches its bound"
            );
            assert_eq!(MessageKind::from_tag(i as u8), Some(kind));
        }
        assert_eq!(MessageKind::from_tag(13), None);
        assert_eq!(MAX_MESSAGE_SIZE, 157);
    }

    #[test]
    fn every_feedback_kind_has_its_size_and_the_largest_is_the_message_s() {
        let sizes: std::vec::Vec<usize> = FeedbackKind::ALL
            .iter()
            .map(|&k| FeedbackMessage::max_encoded_size_of(k))
            .collect();
        // action, preference, semantic, perturbation, reward, correctness, span, ranking, E-stop.
        assert_eq!(sizes, [16, 17, 27, 27, 16, 16, 17, 25, 15]);
        assert_eq!(
            sizes.iter().max(),
            Some(&MessageKind::Feedback.max_encoded_size())
        );
        // Each reached by its largest value.
        let largest = [
            Feedback::Action(ActionFeedback { action: a(63) }),
            Feedback::Preference(PreferenceFeedback {
                preferred: a(1),
                other: a(2),
            }),
            Feedback::Semantic(
                SemanticFeedback::new()
                    .avoid(Feature::Obstacles)
                    .avoid(Feature::Door)
                    .avoid(Feature::Stairs)
                    .avoid(Feature::Chair)
                    .prefer(Feature::Path)
                    .prefer(Feature::Right),
            ),
            Feedback::Perturbation(
                PerturbationFeedback::new(&[5.0, 5.0, 5.0, 5.0, 3.0, -5.0]).unwrap(),
            ),
            Feedback::Reward(RewardFeedback { hundredths: -100 }),
            Feedback::Correctness(CorrectnessFeedback { correct: true }),
            Feedback::Span(SpanFeedback {
                ticks: 50,
                good: true,
            }),
            Feedback::Ranking(
                RankingFeedback::new(&[0, 1, 2, 3, 4, 5, 6, 7].map(a), true).unwrap(),
            ),
            Feedback::EStop(EStopFeedback),
        ];
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        for (fb, size) in largest.into_iter().zip(sizes) {
            let kind = fb.kind();
            let m = Message::Feedback(FeedbackMessage {
                id: ID,
                tick: u32::MAX,
                feedback: fb,
            });
            assert_eq!(
                m.emit(&mut buf).unwrap().len() - ENVELOPE_OVERHEAD + SECURED_OVERHEAD,
                size,
                "{kind}"
            );
        }
    }

    #[test]
    fn every_lattice_action_makes_a_valid_command() {
        for action in ActionIndex::all() {
            let track = Track::of(action);
            assert_eq!(track.check(), Ok(()), "{action}");
            let t = lattice::trajectory(action);
            assert!((track.segments[1].steering - t.segments[1].steering).abs() <= 0.5e-4);
            assert!((track.segments[0].length - t.segments[0].length).abs() <= 0.5e-3);
            assert!((track.speed - t.speed).abs() <= 0.5e-3);
            // What is sent is what arrives.
            assert_eq!(Track::from(WireTrack::from(track)), track);
        }
    }

    #[test]
    fn out_of_range_tracks_are_refused() {
        let bad = |edit: fn(&mut Track)| {
            let mut t = Track::of(a(0));
            edit(&mut t);
            let msg = Message::Action(ActionCommand {
                tick: 1,
                command: Command::Track(t),
                allowed: ActionMask::ALL,
            });
            let mut buf = [0u8; MAX_MESSAGE_SIZE];
            Message::parse(msg.emit(&mut buf).unwrap())
        };
        assert!(bad(|_| {}).is_ok());
        assert!(bad(|t| t.segments[0].steering = MAX_STEERING).is_ok());
        let refused: [fn(&mut Track); 7] = [
            |t| t.segments[0].steering = 0.3401,
            |t| t.segments[1].steering = -0.35,
            |t| t.segments[1].steering = f32::INFINITY,
            |t| t.segments[0].length = 1.001,
            |t| t.speed = 0.0,
            |t| t.speed = MAX_SPEED * 1.01,
            |t| t.speed = f32::NAN,
        ];
        for edit in refused {
            assert_eq!(bad(edit), Err(DecodeError::InvalidTrack));
        }
    }

    #[test]
    fn envelope_faults_are_decode_errors() {
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        let good = Message::Reset.emit(&mut buf).unwrap().to_vec();
        assert_eq!(
            Message::parse(&good[..2]),
            Err(DecodeError::Envelope(EnvelopeError::Truncated))
        );
        let mut crc_bad = good.clone();
        crc_bad[1] = 3;
        assert_eq!(
            Message::parse(&crc_bad),
            Err(DecodeError::Envelope(EnvelopeError::Crc))
        );
        // Re-seal by hand with version 2, then with a trailing byte, then an unknown variant.
        let reseal = |body: &[u8]| {
            let mut v = body.to_vec();
            let crc = CRC16.checksum(body).to_le_bytes();
            v.extend_from_slice(&crc);
            v
        };
        const V: u8 = PROTOCOL_VERSION_BYTE;
        let e = Message::parse(&reseal(&[2, 8])).unwrap_err();
        assert_eq!(e, DecodeError::Envelope(EnvelopeError::Version(2)));
        // Version 3 (before the kinds of issue 15) is refused too.
        assert_eq!(
            Message::parse(&reseal(&[3, 8])),
            Err(DecodeError::Envelope(EnvelopeError::Version(3)))
        );
        assert_eq!(e.code(), ErrorCode::Version);
        assert_eq!(
            Message::parse(&reseal(&[V, 8, 0])),
            Err(DecodeError::Envelope(EnvelopeError::TrailingBytes))
        );
        assert_eq!(
            Message::parse(&reseal(&[V, 13])),
            Err(DecodeError::Envelope(EnvelopeError::Decode))
        );
        // An action index of 64 is not an action.
        assert_eq!(
            Message::parse(&reseal(&[V, 2, 7, 200, 1, 0, 64])),
            Err(DecodeError::Envelope(EnvelopeError::Decode))
        );
        assert_eq!(
            Message::parse(&reseal(&[V, 2, 7, 200, 1, 0, 63])).map(|m| m.kind()),
            Ok(MessageKind::Feedback)
        );
        // A feedback variant beyond the E-stop, a ranking of nine actions.
        assert_eq!(
            Message::parse(&reseal(&[V, 2, 7, 200, 1, 9])),
            Err(DecodeError::Envelope(EnvelopeError::Decode))
        );
        assert_eq!(
            Message::parse(&reseal(&[
                V, 2, 7, 200, 1, 7, 9, 0, 1, 2, 3, 4, 5, 6, 7, 8, 1
            ])),
            Err(DecodeError::Envelope(EnvelopeError::Decode))
        );
    }

    #[test]
    fn nack_codes_follow_the_agent_s_errors() {
        use firmware_core::LearnError;
        assert_eq!(
            NackCode::from(&FeedbackError::UnknownTick(3)),
            NackCode::UnknownTick
        );
        assert_eq!(
            NackCode::from(&FeedbackError::Learn(LearnError::DegenerateFeedback)),
            NackCode::Rejected
        );
    }

    proptest! {
        #[test]
        fn messages_round_trip(msg in message()) {
            let mut buf = [0u8; MAX_MESSAGE_SIZE];
            let bytes = msg.emit(&mut buf).unwrap();
            prop_assert!(bytes.len() <= msg.kind().max_stored_size());
            prop_assert_eq!(bytes[1], msg.kind() as u8);
            prop_assert_eq!(Message::parse(bytes), Ok(msg));
        }

        #[test]
        fn any_bytes_give_a_message_or_an_error(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
            let _ = Message::parse(&bytes);
            let _ = Message::decode_payload(&bytes);
        }

        #[test]
        fn resealed_random_payloads_give_a_message_or_an_error(
            payload in proptest::collection::vec(any::<u8>(), 0..400),
            tag in 0u8..14,
        ) {
            // Past the CRC, so postcard's decoder and the track check see arbitrary bytes.
            let mut body = std::vec![PROTOCOL_VERSION_BYTE, tag];
            body.extend_from_slice(&payload);
            let crc = CRC16.checksum(&body).to_le_bytes();
            body.extend_from_slice(&crc);
            if let Ok(msg) = Message::parse(&body) {
                prop_assert_eq!(msg.kind() as u8, tag);
            }
        }

        #[test]
        fn any_corruption_of_a_message_is_caught(msg in message(), at in any::<usize>(), bit in 0u8..8) {
            let mut buf = [0u8; MAX_MESSAGE_SIZE];
            let mut bytes = msg.emit(&mut buf).unwrap().to_vec();
            let i = at % bytes.len();
            bytes[i] ^= 1 << bit;
            prop_assert!(Message::parse(&bytes).is_err());
        }
    }
}
