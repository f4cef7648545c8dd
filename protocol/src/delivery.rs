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
//! * **Sender restart.** A new sender must use a new session number (a boot counter kept in
//!   flash, or a random byte) and should send [`Message::Reset`] first.
//!   The receiver starts a fresh window whenever the session changes, so the new sender's
//!   sequence numbers are not mistaken for the old one's.
//! * **Receiver restart.** The receiver is persisted with the weights after every applied
//!   feedback ([`crate::car::Persisted`]), so a car restarted from flash still answers copies of
//!   feedback it applied before the restart with their [`Ack`], without applying them again. A
//!   receiver that lost its window would hand such copies to `apply` again, where the car's agent
//!   refuses them with [`NackCode::UnknownTick`] (its recent ticks are forgotten on a restart).
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
    pub max_retries: u8,
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
    retries: u8,
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
    fn new(id: DeliveryId, verdict: Verdict) -> Self {
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

/// The car's side: applies each feedback once and answers every copy.
///
/// It is `Serialize`/`Deserialize` so that a car can persist it with its weights
/// ([`crate::car::Persisted`]): a car restarted from flash then still recognises copies of the
/// feedback it applied before the restart. Every field value is a valid state, so a decoded
/// receiver needs no further check.
#[derive(Clone, PartialEq, Eq, Debug, Serialize, Deserialize, MaxSize)]
pub struct FeedbackReceiver {
    session: Option<u8>,
    highest: u8,
    /// Verdict of sequence number `s` at `s % DEDUPE_WINDOW`, for `s` in
    /// `(highest − DEDUPE_WINDOW, highest]`; `None`: not received.
    verdicts: [Option<Verdict>; DEDUPE_WINDOW],
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
            session: None,
            highest: 0,
            verdicts: [None; DEDUPE_WINDOW],
        }
    }

    /// Forgets everything (on a [`Message::Reset`]).
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// Handles a feedback: calls `apply` if its id is new (and records the verdict), and
    /// returns the answer to send, the same for every copy.
    pub fn receive<F>(&mut self, msg: &FeedbackMessage, apply: F) -> Reply
    where
        F: FnOnce(&FeedbackMessage) -> Verdict,
    {
        let id = msg.id;
        let seq = id.seq;
        if self.session != Some(id.session) {
            *self = Self::new();
            self.session = Some(id.session);
            self.highest = seq;
            return self.apply(msg, apply);
        }
        let ahead = seq.wrapping_sub(self.highest);
        if ahead != 0 && ahead < HALF {
            // Newer than anything seen: slide the window, clearing the numbers it enters.
            for k in 1..=(ahead as usize).min(DEDUPE_WINDOW) {
                let s = self.highest.wrapping_add(k as u8);
                self.verdicts[s as usize % DEDUPE_WINDOW] = None;
            }
            self.highest = seq;
            return self.apply(msg, apply);
        }
        let behind = self.highest.wrapping_sub(seq) as usize;
        if behind >= DEDUPE_WINDOW {
            return Reply::new(id, Verdict::Refused(NackCode::Stale));
        }
        match self.verdicts[seq as usize % DEDUPE_WINDOW] {
            Some(v) => Reply::new(id, v),
            None => self.apply(msg, apply),
        }
    }

    fn apply<F>(&mut self, msg: &FeedbackMessage, apply: F) -> Reply
    where
        F: FnOnce(&FeedbackMessage) -> Verdict,
    {
        let v = apply(msg);
        self.verdicts[msg.id.seq as usize % DEDUPE_WINDOW] = Some(v);
        Reply::new(msg.id, v)
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
    fn restarts_of_either_side() {
        let mut car = FeedbackReceiver::new();
        for seq in 0..10 {
            assert!(applied(&mut car, 1, seq).0);
        }
        // The host restarts with a new session and numbers from 0 again: all new.
        for seq in 0..10 {
            assert!(applied(&mut car, 2, seq).0, "new session, seq {seq}");
        }
        assert!(!applied(&mut car, 2, 9).0);
        // A reset (or a restart of the car) forgets the window: copies are handed to `apply`
        // again, where the car's agent refuses them (its ticks are forgotten too).
        car.reset();
        assert!(applied(&mut car, 2, 9).0);
        // A restarted sender in session 2 starts again from seq 0.
        let host = FeedbackSender::new(2, POLICY);
        assert_eq!(host.in_flight(), 0);
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
}
