//! Acknowledged feedback: no correction lost, none applied twice.
//!
//! The host's [`FeedbackSender`] numbers each feedback with a [`DeliveryId`] (its session and a
//! wrapping 8-bit sequence number), keeps it until the car answers, and retransmits it every
//! [`RetryPolicy::timeout_ms`] up to [`RetryPolicy::max_retries`] times. The car's
//! [`FeedbackReceiver`] applies a feedback the first time its id arrives and answers every copy
//! with the same [`Ack`] or [`Nack`], so a lost ack costs a retransmission, never a second update.
//! Both are plain state machines: the caller passes the time in milliseconds (wrapping `u32`)
//! and moves the messages; there is no clock, thread or allocation inside.
//!
//! ```text
//!  host (FeedbackSender)                         car (FeedbackReceiver)
//!  send(now, tick, fb) ──Feedback{id 7/12}──X   (lost)
//!  poll(now + timeout) → Retransmit ──────────▶  new id: apply once ── Ack{7/12} ──X (lost)
//!  poll(now + 2·timeout) → Retransmit ────────▶  duplicate: not applied, Ack{7/12} again
//!  on_reply(Ack) → Delivered  ◀──────────────────┘
//! ```
//!
//! # Sequence numbers, wraparound and restarts
//!
//! * **Window.** The receiver remembers the verdicts of the last [`DEDUPE_WINDOW`] sequence
//!   numbers at or below the highest one it has seen (serial-number arithmetic, RFC 1982, so the
//!   8-bit numbers wrap freely). The sender never numbers a feedback more than
//!   `DEDUPE_WINDOW − 1` ahead of one still outstanding ([`SendError::Full`] until the old one
//!   is settled), so every copy it can still send falls inside the receiver's window. A number
//!   older than the window is answered [`NackCode::Stale`] and not applied (it cannot come from a
//!   sender that keeps that rule).
//! * **Sessions.** The sequence numbers count within a configuration session (the car's
//!   [`crate::car::CarNode`] applies feedback of its configured session only). The receiver
//!   keeps a window per session for the last [`SESSIONS`] sessions, so a change of session
//!   forgets nothing: a copy of a feedback applied in an earlier session is still answered with
//!   its ack, never applied again.
//! * **Receiver restart.** The receiver is persisted with the weights after every applied
//!   feedback ([`crate::car::Persisted`]), so a car restarted from flash still answers copies of
//!   feedback it applied before the restart with their [`Ack`], without applying them again.
//!
//! ```
//! use firmware_core::{ActionFeedback, ActionIndex, Feedback};
//! use protocol::delivery::{FeedbackReceiver, FeedbackSender, RetryPolicy, SenderEvent, Verdict};
//!
//! let mut host = FeedbackSender::new(7, RetryPolicy::default());
//! let mut car = FeedbackReceiver::new();
//! let fb = Feedback::Action(ActionFeedback { action: ActionIndex::new(5).unwrap() });
//! let msg = host.send(0, 41, fb).unwrap();
//! let mut applied = 0;
//! let reply = car.receive(&msg, |_| { applied += 1; Verdict::Applied });
//! let again = car.receive(&msg, |_| { applied += 1; Verdict::Applied }); // a retransmission
//! assert_eq!((applied, reply), (1, again));
//! assert!(matches!(host.on_reply(&reply.into()), Some(SenderEvent::Delivered { tick: 41, .. })));
//! ```

use core::fmt;

use firmware_core::Feedback;
use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

use crate::message::{Ack, DeliveryId, FeedbackMessage, Message, Nack, NackCode};

/// Number of recent sequence numbers the receiver remembers.
pub const DEDUPE_WINDOW: usize = 32;

/// Number of feedbacks a sender keeps outstanding at once.
pub const MAX_IN_FLIGHT: usize = 4;

const HALF: u8 = 128;

const _: () = assert!(
    DEDUPE_WINDOW <= HALF as usize,
    "the window is within half the sequence space (serial-number arithmetic)"
);
const _: () = assert!(
    MAX_IN_FLIGHT <= DEDUPE_WINDOW,
    "every outstanding feedback fits the window"
);

/// How long the sender waits for an answer and how often it retries.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub struct RetryPolicy {
    /// Wait for an ack or nack this long after each transmission (ms).
    pub timeout_ms: u32,
    /// Retransmit at most this many times; then report [`SenderEvent::Failed`].
    pub max_retries: u16,
}

impl Default for RetryPolicy {
    /// 50 ms and 5 retries: a feedback is given up after 300 ms, within the car's memory of its
    /// last 4 ticks at 10 Hz (`firmware_core::agent::TICK_HISTORY`).
    fn default() -> Self {
        Self {
            timeout_ms: 50,
            max_retries: 5,
        }
    }
}

/// A feedback could not be queued; it is handed back.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum SendError {
    /// [`MAX_IN_FLIGHT`] feedbacks are outstanding, or the next sequence number would be
    /// [`DEDUPE_WINDOW`] or more ahead of an outstanding one: retry after an answer or a
    /// failure.
    Full(Feedback),
}

impl fmt::Display for SendError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SendError::Full(_) => f.write_str("too many feedbacks awaiting an answer"),
        }
    }
}

impl core::error::Error for SendError {}

/// What the sender tells its caller.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum SenderEvent {
    /// No answer in time: send this copy again now.
    Retransmit(FeedbackMessage),
    /// The car applied the feedback (acked).
    Delivered {
        /// The delivery.
        id: DeliveryId,
        /// The tick it referred to.
        tick: u32,
    },
    /// The car refused the feedback (nacked); it is not retransmitted.
    Refused {
        /// The delivery.
        id: DeliveryId,
        /// The tick it referred to.
        tick: u32,
        /// Why.
        code: NackCode,
    },
    /// No answer after [`RetryPolicy::max_retries`] retransmissions: the feedback is given up
    /// and handed back.
    Failed {
        /// The delivery.
        id: DeliveryId,
        /// The tick it referred to.
        tick: u32,
        /// The feedback.
        feedback: Feedback,
    },
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct Pending {
    msg: FeedbackMessage,
    sent_ms: u32,
    retries: u16,
}

/// The host's side: numbers, keeps and retransmits feedback until answered.
#[derive(Clone, Debug)]
pub struct FeedbackSender {
    session: u8,
    next_seq: u8,
    policy: RetryPolicy,
    pending: [Option<Pending>; MAX_IN_FLIGHT],
}

impl FeedbackSender {
    /// A sender in `session` (new at every start of the sender), numbering from 0.
    pub const fn new(session: u8, policy: RetryPolicy) -> Self {
        Self {
            session,
            next_seq: 0,
            policy,
            pending: [None; MAX_IN_FLIGHT],
        }
    }

    /// The session.
    pub const fn session(&self) -> u8 {
        self.session
    }

    /// The retry policy.
    pub const fn policy(&self) -> RetryPolicy {
        self.policy
    }

    /// Number of feedbacks awaiting an answer.
    pub fn in_flight(&self) -> usize {
        self.pending.iter().flatten().count()
    }

    /// Numbers `feedback` about `tick` and keeps it; returns the message to transmit now.
    pub fn send(
        &mut self,
        now: u32,
        tick: u32,
        feedback: Feedback,
    ) -> Result<FeedbackMessage, SendError> {
        let behind = self
            .pending
            .iter()
            .flatten()
            .map(|p| self.next_seq.wrapping_sub(p.msg.id.seq) as usize)
            .max()
            .unwrap_or(0);
        // The new number may be at most DEDUPE_WINDOW - 1 ahead of every outstanding one.
        if behind >= DEDUPE_WINDOW {
            return Err(SendError::Full(feedback));
        }
        let Some(slot) = self.pending.iter_mut().find(|p| p.is_none()) else {
            return Err(SendError::Full(feedback));
        };
        let msg = FeedbackMessage {
            id: DeliveryId {
                session: self.session,
                seq: self.next_seq,
            },
            tick,
            feedback,
        };
        *slot = Some(Pending {
            msg,
            sent_ms: now,
            retries: 0,
        });
        self.next_seq = self.next_seq.wrapping_add(1);
        Ok(msg)
    }

    /// Takes an answer from the car: an [`Ack`] or [`Nack`] of an outstanding feedback settles
    /// it; anything else (duplicates, other sessions, other messages) is ignored.
    pub fn on_reply(&mut self, reply: &Message) -> Option<SenderEvent> {
        let (id, code) = match reply {
            Message::Ack(a) => (a.id, None),
            Message::Nack(n) => (n.id, Some(n.code)),
            _ => return None,
        };
        let slot = self
            .pending
            .iter_mut()
            .find(|p| p.is_some_and(|p| p.msg.id == id))?;
        let p = slot.take()?;
        let tick = p.msg.tick;
        Some(match code {
            None => SenderEvent::Delivered { id, tick },
            Some(code) => SenderEvent::Refused { id, tick, code },
        })
    }

    /// The next thing to do at `now`: a retransmission or a failure. Call until `None`; each
    /// call does a bounded amount of work.
    pub fn poll(&mut self, now: u32) -> Option<SenderEvent> {
        let timeout = self.policy.timeout_ms;
        let max_retries = self.policy.max_retries;
        // The oldest sequence number first, so that retransmissions keep their order.
        let next_seq = self.next_seq;
        let slot = self
            .pending
            .iter_mut()
            .filter(|p| p.is_some_and(|p| now.wrapping_sub(p.sent_ms) >= timeout))
            .max_by_key(|p| p.map_or(0, |p| next_seq.wrapping_sub(p.msg.id.seq)))?;
        let p = slot.as_mut()?;
        if p.retries >= max_retries {
            let msg = p.msg;
            *slot = None;
            return Some(SenderEvent::Failed {
                id: msg.id,
                tick: msg.tick,
                feedback: msg.feedback,
            });
        }
        p.retries += 1;
        p.sent_ms = now;
        Some(SenderEvent::Retransmit(p.msg))
    }
}

/// What applying a feedback came to; the receiver remembers it per sequence number.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize, MaxSize)]
pub enum Verdict {
    /// Applied: answered with an [`Ack`].
    Applied,
    /// Refused: answered with a [`Nack`].
    Refused(NackCode),
}

/// The answer to a feedback: an [`Ack`] or a [`Nack`].
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum Reply {
    /// Applied (now or before).
    Ack(Ack),
    /// Not applied.
    Nack(Nack),
}

impl Reply {
    /// The answer that `verdict` gives `id`.
    pub fn new(id: DeliveryId, verdict: Verdict) -> Self {
        match verdict {
            Verdict::Applied => Reply::Ack(Ack { id }),
            Verdict::Refused(code) => Reply::Nack(Nack { id, code }),
        }
    }
}

impl From<Reply> for Message {
    fn from(r: Reply) -> Self {
        match r {
            Reply::Ack(a) => Message::Ack(a),
            Reply::Nack(n) => Message::Nack(n),
        }
    }
}

/// Sessions whose dedupe windows a [`FeedbackReceiver`] keeps.
pub const SESSIONS: usize = 4;

/// One remembered verdict in a byte: 0 nothing received, 1 applied, 2 + the nack code refused.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize, MaxSize)]
#[serde(into = "u8", try_from = "u8")]
struct Slot(u8);

impl Slot {
    const EMPTY: Slot = Slot(0);

    const fn of(v: Verdict) -> Self {
        Slot(match v {
            Verdict::Applied => 1,
            Verdict::Refused(NackCode::UnknownTick) => 2,
            Verdict::Refused(NackCode::Rejected) => 3,
            Verdict::Refused(NackCode::Stale) => 4,
            Verdict::Refused(NackCode::WrongSession) => 5,
        })
    }

    const fn verdict(self) -> Option<Verdict> {
        match self.0 {
            1 => Some(Verdict::Applied),
            2 => Some(Verdict::Refused(NackCode::UnknownTick)),
            3 => Some(Verdict::Refused(NackCode::Rejected)),
            4 => Some(Verdict::Refused(NackCode::Stale)),
            5 => Some(Verdict::Refused(NackCode::WrongSession)),
            _ => None,
        }
    }
}

impl From<Slot> for u8 {
    fn from(s: Slot) -> u8 {
        s.0
    }
}

impl TryFrom<u8> for Slot {
    type Error = &'static str;
    fn try_from(v: u8) -> Result<Self, &'static str> {
        if v <= 5 {
            Ok(Slot(v))
        } else {
            Err("not a verdict")
        }
    }
}

/// The verdicts of one session's last [`DEDUPE_WINDOW`] sequence numbers.
#[derive(Clone, PartialEq, Eq, Debug, Serialize, Deserialize, MaxSize)]
struct SessionWindow {
    session: u8,
    highest: u8,
    /// Verdict of sequence number `s` at `s % DEDUPE_WINDOW`, for `s` in
    /// `(highest − DEDUPE_WINDOW, highest]`.
    slots: [Slot; DEDUPE_WINDOW],
}

impl SessionWindow {
    const fn new(session: u8, first: u8) -> Self {
        Self {
            session,
            highest: first,
            slots: [Slot::EMPTY; DEDUPE_WINDOW],
        }
    }

    /// The verdict recorded for `seq`: `Err(())` if it is older than the window.
    fn recorded(&self, seq: u8) -> Result<Option<Verdict>, ()> {
        let ahead = seq.wrapping_sub(self.highest);
        if ahead != 0 && ahead < HALF {
            return Ok(None);
        }
        if self.highest.wrapping_sub(seq) as usize >= DEDUPE_WINDOW {
            return Err(());
        }
        Ok(self.slots[seq as usize % DEDUPE_WINDOW].verdict())
    }

    fn receive<F>(&mut self, msg: &FeedbackMessage, apply: F) -> Reply
    where
        F: FnOnce(&FeedbackMessage) -> Verdict,
    {
        let id = msg.id;
        let seq = id.seq;
        let ahead = seq.wrapping_sub(self.highest);
        if ahead != 0 && ahead < HALF {
            // Newer than anything seen: slide the window, clearing the numbers it enters.
            for k in 1..=(ahead as usize).min(DEDUPE_WINDOW) {
                let s = self.highest.wrapping_add(k as u8);
                self.slots[s as usize % DEDUPE_WINDOW] = Slot::EMPTY;
            }
            self.highest = seq;
        } else if self.highest.wrapping_sub(seq) as usize >= DEDUPE_WINDOW {
            return Reply::new(id, Verdict::Refused(NackCode::Stale));
        } else if let Some(v) = self.slots[seq as usize % DEDUPE_WINDOW].verdict() {
            return Reply::new(id, v);
        }
        let v = apply(msg);
        self.slots[seq as usize % DEDUPE_WINDOW] = Slot::of(v);
        Reply::new(id, v)
    }
}

/// The car's side: applies each feedback once and answers every copy.
///
/// It keeps a dedupe window per session for the last [`SESSIONS`] sessions it saw (the most
/// recently used first), so a change of session never forgets which feedback was applied: a
/// copy of a feedback of an earlier session is still recognised ([`FeedbackReceiver::recorded`])
/// and a session that comes back finds its window.
///
/// It is `Serialize`/`Deserialize` so that a car can persist it with its weights
/// ([`crate::car::Persisted`]): a car restarted from flash then still recognises copies of the
/// feedback it applied before the restart. Every decodable value is a valid state, so a decoded
/// receiver needs no further check.
#[derive(Clone, PartialEq, Eq, Debug, Serialize, Deserialize, MaxSize)]
pub struct FeedbackReceiver {
    windows: [Option<SessionWindow>; SESSIONS],
}

impl Default for FeedbackReceiver {
    fn default() -> Self {
        Self::new()
    }
}

impl FeedbackReceiver {
    /// A receiver that has seen nothing.
    pub const fn new() -> Self {
        Self {
            windows: [const { None }; SESSIONS],
        }
    }

    fn find(&self, session: u8) -> Option<usize> {
        self.windows
            .iter()
            .position(|w| w.as_ref().is_some_and(|w| w.session == session))
    }

    /// The sessions whose windows are kept, the most recently used first.
    pub fn sessions(&self) -> impl Iterator<Item = u8> + '_ {
        self.windows.iter().flatten().map(|w| w.session)
    }

    /// The verdict recorded for `id`, without applying anything: `None` if its session has no
    /// window here, or its number was never received or is older than the window.
    pub fn recorded(&self, id: DeliveryId) -> Option<Verdict> {
        let w = self.windows[self.find(id.session)?].as_ref()?;
        w.recorded(id.seq).ok().flatten()
    }

    /// Handles a feedback: calls `apply` if its id is new in its session's window (and records
    /// the verdict), and returns the answer to send, the same for every copy. A session without
    /// a window gets a fresh one; the least recently used of [`SESSIONS`] is forgotten.
    pub fn receive<F>(&mut self, msg: &FeedbackMessage, apply: F) -> Reply
    where
        F: FnOnce(&FeedbackMessage) -> Verdict,
    {
        let session = msg.id.session;
        let window = match self.find(session).and_then(|i| self.windows[i].take()) {
            Some(w) => w,
            None => {
                if self.windows.iter().all(Option::is_some) {
                    self.windows[SESSIONS - 1] = None;
                }
                // Just below the first number: it enters the window as new.
                SessionWindow::new(session, msg.id.seq.wrapping_sub(1))
            }
        };
        // Most recently used first: shift the ones before the freed slot down by one.
        let free = self
            .windows
            .iter()
            .position(Option::is_none)
            .unwrap_or(SESSIONS - 1);
        self.windows[..=free].rotate_right(1);
        self.windows[0].insert(window).receive(msg, apply)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware_core::{ActionFeedback, ActionIndex};
    use proptest::prelude::*;
    use std::vec::Vec;

    fn fb(a: usize) -> Feedback {
        Feedback::Action(ActionFeedback {
            action: ActionIndex::new(a % 64).unwrap(),
        })
    }

    const POLICY: RetryPolicy = RetryPolicy {
        timeout_ms: 10,
        max_retries: 3,
    };

    #[test]
    fn lost_feedback_and_lost_ack_cost_retransmissions_not_double_updates() {
        let mut host = FeedbackSender::new(1, POLICY);
        let mut car = FeedbackReceiver::new();
        let mut applied = Vec::new();
        let first = host.send(0, 5, fb(3)).unwrap();
        assert_eq!(first.id, DeliveryId { session: 1, seq: 0 });
        // The first copy is lost. Nothing is due before the timeout.
        assert_eq!(host.poll(9), None);
        let Some(SenderEvent::Retransmit(copy)) = host.poll(10) else {
            panic!("expected a retransmission")
        };
        assert_eq!(copy, first);
        // The car applies it; the ack is lost.
        let ack = car.receive(&copy, |m| {
            applied.push(m.tick);
            Verdict::Applied
        });
        assert_eq!(ack, Reply::Ack(Ack { id: first.id }));
        let Some(SenderEvent::Retransmit(copy)) = host.poll(20) else {
            panic!("expected a second retransmission")
        };
        // The duplicate is acked again and not applied.
        let again = car.receive(&copy, |m| {
            applied.push(m.tick);
            Verdict::Applied
        });
        assert_eq!(again, ack);
        assert_eq!(applied, [5]);
        assert_eq!(
            host.on_reply(&again.into()),
            Some(SenderEvent::Delivered {
                id: first.id,
                tick: 5
            })
        );
        // A late copy of the same ack changes nothing.
        assert_eq!(host.on_reply(&ack.into()), None);
        assert_eq!((host.in_flight(), host.poll(1000)), (0, None));
    }

    #[test]
    fn retries_are_bounded_and_failure_hands_the_feedback_back() {
        let mut host = FeedbackSender::new(1, POLICY);
        let sent = host.send(100, 9, fb(4)).unwrap();
        let mut retransmissions = 0;
        let mut now = 100;
        let failed = loop {
            now += 1;
            match host.poll(now) {
                None => {}
                Some(SenderEvent::Retransmit(m)) => {
                    assert_eq!(m, sent);
                    assert_eq!(now, 100 + 10 * (retransmissions + 1), "one per timeout");
                    retransmissions += 1;
                }
                Some(other) => break other,
            }
        };
        assert_eq!(retransmissions, 3);
        assert_eq!(now, 140);
        assert_eq!(
            failed,
            SenderEvent::Failed {
                id: sent.id,
                tick: 9,
                feedback: fb(4)
            }
        );
        assert_eq!(host.in_flight(), 0);
    }

    #[test]
    fn a_nack_settles_the_feedback_and_is_repeated_for_duplicates() {
        let mut host = FeedbackSender::new(2, POLICY);
        let mut car = FeedbackReceiver::new();
        let m = host.send(0, 3, fb(1)).unwrap();
        let mut calls = 0;
        let mut refuse = |_: &FeedbackMessage| {
            calls += 1;
            Verdict::Refused(NackCode::UnknownTick)
        };
        let r1 = car.receive(&m, &mut refuse);
        let r2 = car.receive(&m, &mut refuse);
        assert_eq!(r1, r2);
        assert_eq!(calls, 1);
        assert_eq!(
            host.on_reply(&r1.into()),
            Some(SenderEvent::Refused {
                id: m.id,
                tick: 3,
                code: NackCode::UnknownTick
            })
        );
        assert_eq!(host.poll(1000), None, "no retransmission after a nack");
    }

    #[test]
    fn the_sender_hands_feedback_back_when_full() {
        let mut host = FeedbackSender::new(0, POLICY);
        for i in 0..MAX_IN_FLIGHT {
            host.send(0, i as u32, fb(i)).unwrap();
        }
        assert_eq!(host.send(0, 99, fb(9)), Err(SendError::Full(fb(9))));
        // Replies from another session or for unknown numbers do not free a slot.
        let foreign = Message::Ack(Ack {
            id: DeliveryId { session: 1, seq: 0 },
        });
        assert_eq!(host.on_reply(&foreign), None);
        assert_eq!(host.on_reply(&Message::Reset), None);
        let ours = Message::Ack(Ack {
            id: DeliveryId { session: 0, seq: 2 },
        });
        assert!(host.on_reply(&ours).is_some());
        assert!(host.send(0, 99, fb(9)).is_ok());
    }

    #[test]
    fn the_sender_stays_within_the_receiver_s_window() {
        // Feedback 0 is never answered; the others are acked at once.
        let mut host = FeedbackSender::new(
            0,
            RetryPolicy {
                timeout_ms: 1000,
                max_retries: 1,
            },
        );
        let stuck = host.send(0, 0, fb(0)).unwrap();
        let mut seqs = Vec::new();
        loop {
            match host.send(0, 1, fb(1)) {
                Ok(m) => {
                    seqs.push(m.id.seq);
                    host.on_reply(&Message::Ack(Ack { id: m.id })).unwrap();
                }
                Err(SendError::Full(f)) => {
                    assert_eq!(f, fb(1));
                    break;
                }
            }
        }
        // Numbers 1..=31 went out: the newest is DEDUPE_WINDOW - 1 ahead of the stuck one.
        assert_eq!(seqs, (1..DEDUPE_WINDOW as u8).collect::<Vec<_>>());
        // The receiver still recognises a copy of the stuck one.
        let mut car = FeedbackReceiver::new();
        car.receive(&stuck, |_| Verdict::Applied);
        for s in &seqs {
            let m = FeedbackMessage {
                id: DeliveryId {
                    session: 0,
                    seq: *s,
                },
                ..stuck
            };
            car.receive(&m, |_| Verdict::Applied);
        }
        let mut applied_again = false;
        car.receive(&stuck, |_| {
            applied_again = true;
            Verdict::Applied
        });
        assert!(!applied_again);
        // Once the stuck one is settled, numbering goes on.
        host.on_reply(&Message::Ack(Ack { id: stuck.id })).unwrap();
        assert_eq!(host.send(0, 2, fb(2)).unwrap().id.seq, DEDUPE_WINDOW as u8);
    }

    fn msg(session: u8, seq: u8) -> FeedbackMessage {
        FeedbackMessage {
            id: DeliveryId { session, seq },
            tick: 0,
            feedback: fb(0),
        }
    }

    /// Delivers `seq` and says whether `apply` ran.
    fn applied(car: &mut FeedbackReceiver, session: u8, seq: u8) -> (bool, Reply) {
        let mut ran = false;
        let r = car.receive(&msg(session, seq), |_| {
            ran = true;
            Verdict::Applied
        });
        (ran, r)
    }

    #[test]
    fn the_window_slides_across_the_wrap_of_the_sequence_numbers() {
        let mut car = FeedbackReceiver::new();
        for seq in (200..=255).chain(0..=40) {
            assert!(applied(&mut car, 3, seq).0, "{seq} is new");
        }
        // The last DEDUPE_WINDOW numbers are remembered; older ones are stale.
        for back in 0..DEDUPE_WINDOW as u8 {
            assert!(
                !applied(&mut car, 3, 40u8.wrapping_sub(back)).0,
                "{back} back is a duplicate"
            );
        }
        let (ran, r) = applied(&mut car, 3, 40u8.wrapping_sub(DEDUPE_WINDOW as u8));
        assert!(!ran);
        assert_eq!(
            r,
            Reply::Nack(Nack {
                id: DeliveryId { session: 3, seq: 8 },
                code: NackCode::Stale
            })
        );
        // Out of order within the window: a number never seen is applied once.
        assert!(applied(&mut car, 3, 45).0);
        assert!(applied(&mut car, 3, 43).0);
        assert!(!applied(&mut car, 3, 43).0);
        assert!(applied(&mut car, 3, 44).0);
        // A jump of more than the window clears it.
        assert!(applied(&mut car, 3, 100).0);
        assert!(!applied(&mut car, 3, 45).0, "45 is now stale");
        assert!(applied(&mut car, 3, 99).0);
    }

    #[test]
    fn sessions_keep_their_own_windows() {
        let mut car = FeedbackReceiver::new();
        for seq in 0..10 {
            assert!(applied(&mut car, 1, seq).0);
        }
        // Another session numbers from 0 again: all new, in its own window.
        for seq in 0..10 {
            assert!(applied(&mut car, 2, seq).0, "new session, seq {seq}");
        }
        assert!(!applied(&mut car, 2, 9).0);
        // The first session's window survived the change: its copies are not applied again.
        for seq in 0..10 {
            assert!(!applied(&mut car, 1, seq).0, "session 1, seq {seq} again");
        }
        assert_eq!(
            car.recorded(DeliveryId { session: 1, seq: 3 }),
            Some(Verdict::Applied)
        );
        assert_eq!(
            car.recorded(DeliveryId {
                session: 1,
                seq: 30
            }),
            None
        );
        assert_eq!(car.recorded(DeliveryId { session: 9, seq: 3 }), None);
        assert_eq!(car.sessions().collect::<Vec<_>>(), [1, 2]);
        // Up to SESSIONS sessions are kept, the least recently used is forgotten first.
        for s in 3..=5 {
            assert!(applied(&mut car, s, 0).0);
        }
        assert_eq!(car.sessions().collect::<Vec<_>>(), [5, 4, 3, 1]);
        assert_eq!(car.recorded(DeliveryId { session: 2, seq: 0 }), None);
        // A persisted receiver decodes to the same windows.
        let mut buf = [0u8; FeedbackReceiver::POSTCARD_MAX_SIZE];
        let bytes = postcard::to_slice(&car, &mut buf).unwrap();
        assert_eq!(
            postcard::from_bytes::<FeedbackReceiver>(bytes).unwrap(),
            car
        );
        // A verdict byte that is no verdict is refused.
        let mut bad = bytes.to_vec();
        bad[3] = 6;
        assert!(postcard::from_bytes::<FeedbackReceiver>(&bad).is_err());
    }

    /// Delivers `seq` with `verdict` and says whether `apply` ran.
    fn answered(car: &mut FeedbackReceiver, seq: u8, verdict: Verdict) -> bool {
        let mut ran = false;
        car.receive(&msg(3, seq), |_| {
            ran = true;
            verdict
        });
        ran
    }

    /// Applied for even numbers, refused for odd ones: neighbouring slots differ.
    fn verdict_of(seq: u8) -> Verdict {
        if seq.is_multiple_of(2) {
            Verdict::Applied
        } else {
            Verdict::Refused(NackCode::Rejected)
        }
    }

    #[test]
    fn recorded_answers_exactly_the_window_across_the_wrap() {
        let mut car = FeedbackReceiver::new();
        for seq in (200..=255).chain(0..=10) {
            assert!(answered(&mut car, seq, verdict_of(seq)), "{seq} is new");
        }
        // The window is 235 ..= 10, across the wrap: each number's own verdict.
        for back in 0..DEDUPE_WINDOW as u8 {
            let seq = 10u8.wrapping_sub(back);
            assert_eq!(
                car.recorded(DeliveryId { session: 3, seq }),
                Some(verdict_of(seq)),
                "{seq}"
            );
        }
        // 234 is DEDUPE_WINDOW behind: its slot now holds 10's verdict, but 234 is stale.
        let stale = DeliveryId {
            session: 3,
            seq: 10u8.wrapping_sub(DEDUPE_WINDOW as u8),
        };
        assert_eq!(car.recorded(stale), None);
        assert!(!answered(&mut car, stale.seq, Verdict::Applied));
        // Numbers not yet received, just ahead of the window, have no verdict.
        for seq in 11..=20 {
            assert_eq!(car.recorded(DeliveryId { session: 3, seq }), None, "{seq}");
        }
    }

    #[test]
    fn a_jump_past_the_window_forgets_every_old_verdict() {
        for start in [0u8, 240] {
            let mut car = FeedbackReceiver::new();
            for k in 0..DEDUPE_WINDOW as u8 {
                let seq = start.wrapping_add(k);
                assert!(answered(&mut car, seq, verdict_of(seq)));
            }
            // A jump of 40 (the sender gave up on the numbers between): the new window holds
            // only the new number; every other number in it is new, including the one whose
            // slot the old highest number used.
            let high = start.wrapping_add(DEDUPE_WINDOW as u8 - 1);
            let jump = high.wrapping_add(40);
            assert!(answered(&mut car, jump, Verdict::Applied));
            for back in 1..DEDUPE_WINDOW as u8 {
                let seq = jump.wrapping_sub(back);
                assert_eq!(
                    car.recorded(DeliveryId { session: 3, seq }),
                    None,
                    "start {start}: {seq} was never received"
                );
                assert!(
                    answered(&mut car, seq, Verdict::Applied),
                    "start {start}: {seq} is new"
                );
            }
        }
    }

    #[test]
    fn retransmissions_go_oldest_first_across_the_wrap() {
        let mut host = FeedbackSender::new(1, POLICY);
        // 254 feedbacks delivered: the next number is 254.
        for i in 0..254 {
            let m = host.send(0, i, fb(i as usize)).unwrap();
            assert!(host.on_reply(&Message::Ack(Ack { id: m.id })).is_some());
        }
        // MAX_IN_FLIGHT outstanding, 254, 255, 0, 1, all lost: they come back in that order.
        let sent: Vec<u8> = (0..MAX_IN_FLIGHT as u32)
            .map(|i| host.send(100, 300 + i, fb(i as usize)).unwrap().id.seq)
            .collect();
        assert_eq!(sent, [254, 255, 0, 1]);
        let mut again = Vec::new();
        while let Some(SenderEvent::Retransmit(m)) = host.poll(100 + POLICY.timeout_ms) {
            again.push(m.id.seq);
        }
        assert_eq!(again, sent);
    }

    #[derive(Debug, Clone)]
    struct Step {
        give: bool,
        lose_feedback: bool,
        lose_reply: bool,
        duplicate: bool,
        dt: u32,
    }

    fn step() -> impl Strategy<Value = Step> {
        (any::<bool>(), 0u8..100, 0u8..100, 0u8..100, 0u32..25).prop_map(|(give, lf, lr, d, dt)| {
            Step {
                give,
                lose_feedback: lf < 30,
                lose_reply: lr < 30,
                duplicate: d < 10,
                dt,
            }
        })
    }

    /// Host and car over a lossy, duplicating link, with the bookkeeping of the test.
    struct Sim {
        host: FeedbackSender,
        car: FeedbackReceiver,
        applied: std::collections::HashMap<u32, u32>,
        delivered: Vec<u32>,
        failed: Vec<u32>,
    }

    impl Sim {
        fn transmit(&mut self, m: FeedbackMessage, s: &Step) {
            if s.lose_feedback {
                return;
            }
            for _ in 0..if s.duplicate { 2 } else { 1 } {
                let applied = &mut self.applied;
                let r = self.car.receive(&m, |m| {
                    *applied.entry(m.tick).or_default() += 1;
                    Verdict::Applied
                });
                if s.lose_reply {
                    continue;
                }
                if let Some(SenderEvent::Delivered { tick, .. }) = self.host.on_reply(&r.into()) {
                    self.delivered.push(tick);
                }
            }
        }

        fn drain(&mut self, now: u32, s: &Step) {
            while let Some(e) = self.host.poll(now) {
                match e {
                    SenderEvent::Retransmit(m) => self.transmit(m, s),
                    SenderEvent::Failed { tick, .. } => self.failed.push(tick),
                    other => panic!("poll gave {other:?}"),
                }
            }
        }
    }

    proptest! {
        /// A lossy, duplicating link: every feedback is applied at most once; a delivered one
        /// exactly once; every one is settled (delivered or failed) in the end.
        #[test]
        fn each_feedback_is_applied_at_most_once(steps in proptest::collection::vec(step(), 1..400)) {
            let mut sim = Sim {
                host: FeedbackSender::new(5, RetryPolicy { timeout_ms: 10, max_retries: 4 }),
                car: FeedbackReceiver::new(),
                applied: Default::default(),
                delivered: Vec::new(),
                failed: Vec::new(),
            };
            let mut given = 0u32;
            let mut now = 0u32;
            for s in &steps {
                now += s.dt;
                if s.give && let Ok(m) = sim.host.send(now, given, fb(given as usize)) {
                    given += 1;
                    sim.transmit(m, s);
                }
                sim.drain(now, s);
            }
            // The link goes quiet: every outstanding feedback runs out of retries.
            let quiet = Step { give: false, lose_feedback: true, lose_reply: true, duplicate: false, dt: 0 };
            for _ in 0..=4 {
                now += 10;
                sim.drain(now, &quiet);
            }
            prop_assert_eq!(sim.host.in_flight(), 0);
            prop_assert_eq!(sim.delivered.len() + sim.failed.len(), given as usize);
            for (tick, n) in &sim.applied {
                prop_assert!(*n == 1, "tick {} applied {} times", tick, n);
            }
            for tick in &sim.delivered {
                prop_assert_eq!(sim.applied.get(tick), Some(&1));
            }
            // Nothing is applied that was not given.
            prop_assert!(sim.applied.keys().all(|&t| t < given));
        }
    }

    /// One step of [`Net`]: what happens to the link in it.
    #[derive(Debug, Clone)]
    struct Event {
        /// Which sender gives a new feedback, if any.
        give: Option<usize>,
        /// Milliseconds that pass.
        dt: u32,
        /// Rolls (0..100) for a loss, a duplicate, a held-up feedback, a lost reply.
        lose: u8,
        duplicate: u8,
        stubborn: u8,
        lose_reply: u8,
        /// Delays (ms) of this step's transmissions: copies overtake each other.
        delay: u32,
        reply_delay: u32,
    }

    fn event(senders: usize) -> impl Strategy<Value = Event> {
        (
            0usize..senders + 1,
            0u32..5,
            (0u8..100, 0u8..100, 0u8..100, 0u8..100),
            (0u32..15, 0u32..15),
        )
            .prop_map(
                move |(g, dt, (lose, duplicate, stubborn, lose_reply), (delay, reply_delay))| {
                    Event {
                        // A give most of the time.
                        give: (g < senders || dt > 0).then_some(g % senders),
                        dt,
                        lose,
                        duplicate,
                        stubborn,
                        lose_reply,
                        delay,
                        reply_delay,
                    }
                },
            )
    }

    /// Copies a held-up feedback loses before one gets through: more than the window's worth of
    /// other feedback is settled meanwhile.
    const HELD_UP: u32 = 40;

    /// Senders and one receiver over a link that loses (10%), duplicates (10%), delays and so
    /// reorders copies both ways, and holds some feedback up (3%) for [`HELD_UP`]
    /// transmissions. A feedback is `(sender, its count)`.
    struct Net {
        senders: Vec<FeedbackSender>,
        car: FeedbackReceiver,
        /// In flight: (due ms, order, sender, message) and (due, order, sender, reply).
        to_car: Vec<(u32, u64, usize, FeedbackMessage)>,
        to_host: Vec<(u32, u64, usize, Reply)>,
        order: u64,
        given: Vec<u32>,
        held_up: std::collections::HashMap<(usize, u32), u32>,
        applied: std::collections::HashMap<(usize, u32), u32>,
        delivered: Vec<(usize, u32)>,
        refused: Vec<(usize, u32, NackCode)>,
        failed: Vec<(usize, u32)>,
        /// Times each sender's sequence number wrapped from 255 to 0.
        wraps: Vec<u32>,
    }

    impl Net {
        fn new(sessions: &[u8]) -> Self {
            let policy = RetryPolicy {
                timeout_ms: 10,
                max_retries: 4 * HELD_UP as u16,
            };
            Self {
                senders: sessions
                    .iter()
                    .map(|&s| FeedbackSender::new(s, policy))
                    .collect(),
                car: FeedbackReceiver::new(),
                to_car: Vec::new(),
                to_host: Vec::new(),
                order: 0,
                given: std::vec![0; sessions.len()],
                held_up: Default::default(),
                applied: Default::default(),
                delivered: Vec::new(),
                refused: Vec::new(),
                failed: Vec::new(),
                wraps: std::vec![0; sessions.len()],
            }
        }

        fn transmit(&mut self, now: u32, sender: usize, m: FeedbackMessage, e: &Event) {
            let key = (sender, m.tick);
            if let Some(n) = self.held_up.get_mut(&key)
                && *n > 0
            {
                *n -= 1;
                return;
            }
            if e.lose < 10 {
                return;
            }
            let copies = if e.duplicate < 10 { 2 } else { 1 };
            for c in 0..copies {
                self.order += 1;
                self.to_car
                    .push((now + e.delay * (c + 1), self.order, sender, m));
            }
        }

        /// Delivers everything due at `now`, in order of arrival.
        fn deliver(&mut self, now: u32, e: &Event) {
            self.to_car.sort_by_key(|(due, order, ..)| (*due, *order));
            let due = self.to_car.iter().take_while(|(d, ..)| *d <= now).count();
            for (_, _, sender, m) in self.to_car.drain(..due).collect::<Vec<_>>() {
                let applied = &mut self.applied;
                let r = self.car.receive(&m, |m| {
                    *applied.entry((sender, m.tick)).or_default() += 1;
                    Verdict::Applied
                });
                if e.lose_reply >= 10 {
                    self.order += 1;
                    self.to_host
                        .push((now + e.reply_delay, self.order, sender, r));
                }
            }
            self.to_host.sort_by_key(|(due, order, ..)| (*due, *order));
            let due = self.to_host.iter().take_while(|(d, ..)| *d <= now).count();
            for (_, _, sender, r) in self.to_host.drain(..due).collect::<Vec<_>>() {
                match self.senders[sender].on_reply(&r.into()) {
                    Some(SenderEvent::Delivered { tick, .. }) => {
                        self.delivered.push((sender, tick))
                    }
                    Some(SenderEvent::Refused { tick, code, .. }) => {
                        self.refused.push((sender, tick, code))
                    }
                    _ => {}
                }
            }
        }

        fn poll(&mut self, now: u32, e: &Event) {
            for k in 0..self.senders.len() {
                while let Some(ev) = self.senders[k].poll(now) {
                    match ev {
                        SenderEvent::Retransmit(m) => self.transmit(now, k, m, e),
                        SenderEvent::Failed { tick, .. } => self.failed.push((k, tick)),
                        other => panic!("poll gave {other:?}"),
                    }
                }
            }
        }

        fn step(&mut self, now: u32, e: &Event) {
            self.deliver(now, e);
            self.poll(now, e);
            if let Some(k) = e.give {
                let tick = self.given[k];
                if let Ok(m) = self.senders[k].send(now, tick, fb(tick as usize)) {
                    if m.id.seq == 255 {
                        self.wraps[k] += 1;
                    }
                    self.given[k] += 1;
                    if e.stubborn < 3 {
                        self.held_up.insert((k, tick), HELD_UP);
                    }
                    self.transmit(now, k, m, e);
                }
            }
        }

        /// Runs `events`, then lets the link go quiet until every feedback is settled.
        fn run(&mut self, events: &[Event]) {
            let mut now = 0;
            for e in events {
                now += e.dt;
                self.step(now, e);
            }
            let quiet = Event {
                give: None,
                dt: 1,
                lose: 99,
                duplicate: 99,
                stubborn: 99,
                lose_reply: 99,
                delay: 1,
                reply_delay: 1,
            };
            for _ in 0..100_000 {
                if self.senders.iter().all(|s| s.in_flight() == 0) && self.to_car.is_empty() {
                    break;
                }
                now += 1;
                self.step(now, &quiet);
            }
        }

        /// Every feedback settled; none applied twice; a delivered one applied exactly once;
        /// none refused (every verdict here is "applied": a nack can only be `Stale`, which a
        /// sender keeping its window rule never meets).
        fn check(&self) -> Result<(), TestCaseError> {
            prop_assert!(self.senders.iter().all(|s| s.in_flight() == 0));
            let settled = self.delivered.len() + self.refused.len() + self.failed.len();
            prop_assert_eq!(settled as u32, self.given.iter().sum::<u32>());
            for (f, n) in &self.applied {
                prop_assert!(*n == 1, "feedback {:?} applied {} times", f, n);
            }
            for f in &self.delivered {
                prop_assert_eq!(self.applied.get(f), Some(&1), "delivered {:?}", f);
            }
            prop_assert!(
                self.refused.is_empty(),
                "refused (applied {:?}): {:?}",
                self.refused
                    .iter()
                    .map(|(s, t, _)| self.applied.get(&(*s, *t)))
                    .collect::<Vec<_>>(),
                self.refused
            );
            Ok(())
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

        /// Issue 19: well past 256 feedbacks (the sequence numbers of both ends wrap at least
        /// three times) over a link that loses, duplicates and reorders both ways, with some
        /// feedback held up while more than the window's worth of others is settled. Fails if
        /// the sender's window rule ignores the wrap (`saturating_sub` for `wrapping_sub`).
        #[test]
        fn the_sender_and_the_receiver_cross_the_sequence_wrap_many_times(
            events in proptest::collection::vec(event(1), 5000)
        ) {
            let mut net = Net::new(&[5]);
            net.run(&events);
            prop_assert!(net.wraps[0] >= 3, "only {} wraps in {} feedbacks", net.wraps[0], net.given[0]);
            net.check()?;
        }

        /// Several senders, each in its own session, their feedback interleaved on one lossy,
        /// duplicating, reordering link to one receiver: each session's feedback is applied once.
        #[test]
        fn interleaved_sessions_apply_each_feedback_once(
            events in proptest::collection::vec(event(3), 1500),
            first in any::<u8>(),
        ) {
            let sessions = [first, first.wrapping_add(1), first.wrapping_add(100)];
            let mut net = Net::new(&sessions);
            net.run(&events);
            net.check()?;
            prop_assert!(net.car.sessions().count() == 3);
        }
    }
}
