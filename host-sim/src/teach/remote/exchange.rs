//! The stop-and-wait exchange of [`RemoteCar`] (see the module above): sending, receiving and
//! authenticating, the hello and the welcome, and the calls' exchanges (configure, observe,
//! deliver).

use std::time::{Duration, Instant};

use anyhow::{Result, anyhow, bail};
use firmware_core::agent::Decision;
use firmware_core::observation::Observation;
use firmware_core::{Feedback, LearnerSnapshot};
use hil_mock::server::BatchBus;
use hil_mock::transport::{Link, LinkError};
use protocol::delivery::{FeedbackSender, RetryPolicy, SenderEvent};
use protocol::link::{Received, transmit};
use protocol::message::{
    CarStatus, ConfigureMessage, ErrorCode, Message, NackCode, ObservationMessage, Welcome,
};
use protocol::stream::Direction;

use super::{Answer, HELLO_AFTER, Held, MAX_RESTORES, RemoteCar, RemoteStats};

impl<L: Link> RemoteCar<L> {
    /// Milliseconds since this host started (wrapping): the time the protocol sees.
    pub(super) fn now_ms(&self) -> u32 {
        self.start.elapsed().as_millis() as u32
    }

    /// Sends `msg`, its frames together (one packet on UDP); transient link errors are counted
    /// (the request is sent again later).
    pub(super) fn send(&mut self, msg: &Message) -> Result<()> {
        let mut bus = BatchBus::new(&mut self.link);
        let sealed = transmit(
            &mut bus,
            msg,
            Direction::HostToCar,
            self.config.mode,
            &mut self.security,
        );
        // The bus only holds frames, so a failed transmit is the message's own (sealing,
        // segmenting) and nothing was sent; the link's errors come from the flush.
        if let Err(e) = sealed {
            return Err(anyhow!("{}: {e}", self.link.describe()));
        }
        match bus.flush() {
            Ok(()) => Ok(()),
            Err(LinkError::Io { .. }) => {
                self.stats.link_errors += 1;
                Ok(())
            }
            Err(e) => Err(anyhow!("{}: {e}", self.link.describe())),
        }
    }

    pub(super) fn say_hello(&mut self) -> Result<()> {
        let nonce = hil_mock::key::random_nonce()?;
        let hello = self.security.hello(nonce);
        self.stats.hellos += 1;
        self.send(&hello)
    }

    /// The next authenticated message from the car before `until`, if any. A welcome is taken
    /// here ([`RemoteCar::on_welcome`]) and not returned.
    pub(super) fn receive(&mut self, until: Instant) -> Result<Option<Message>> {
        loop {
            let now = Instant::now();
            if now >= until {
                return Ok(None);
            }
            let got = match self.link.recv(until - now) {
                Ok(f) => f,
                Err(LinkError::Malformed { .. }) | Err(LinkError::Io { .. }) => {
                    self.stats.link_errors += 1;
                    // Do not spin on a link that fails at once.
                    std::thread::sleep(Duration::from_millis(1));
                    continue;
                }
                Err(e) => return Err(anyhow!("{}: {e}", self.link.describe())),
            };
            let now_ms = self.now_ms();
            while self.inbox.poll(now_ms).is_some() {}
            let Some(frame) = got else { continue };
            if let Received::Message(m) = self.inbox.feed(&frame, now_ms, &mut self.security) {
                self.silent_tries = 0;
                if let Message::Welcome(w) = m {
                    self.on_welcome(&w)?;
                    continue;
                }
                if let Message::Weights(_) = m
                    && !self.security.opened_newest()
                {
                    // A weights report that messages the car sent after it overtook on the
                    // way: its status is older than theirs (an answer to an earlier request,
                    // delayed), and compared with what the host expects now it would read as a
                    // car that lost what it was taught. The request is sent again and answered
                    // afresh. (A welcome overtaken so is refused by `HostSecurity` itself.)
                    self.stats.out_of_date += 1;
                    continue;
                }
                return Ok(Some(m));
            }
        }
    }

    /// Takes a welcome: the car's epoch and status. A car that lost what this host taught it
    /// is configured again from the host's snapshot when that snapshot is current; otherwise
    /// the loss is an error.
    pub(super) fn on_welcome(&mut self, w: &Welcome) -> Result<()> {
        if self.epoch.is_some_and(|e| e != w.epoch) {
            self.stats.car_restarts += 1;
        }
        self.epoch = Some(w.epoch);
        self.car = Some(w.status);
        let Some(expected) = self.expected else {
            return Ok(());
        };
        let in_flight = self.sender.as_ref().map_or(0, |s| s.in_flight() as u32);
        let holds = w.status.session == expected.session
            && (expected.generation..=expected.generation + in_flight)
                .contains(&w.status.generation);
        if holds {
            return Ok(());
        }
        match self.held {
            Some(h) if h.status == expected => {
                self.restores_in_call += 1;
                if self.restores_in_call > MAX_RESTORES {
                    bail!(
                        "the car keeps losing its learner: configured again {MAX_RESTORES} times in one call"
                    );
                }
                self.stats.restores += 1;
                eprintln!(
                    "host-sim: the car came back holding {} instead of {}; configuring it \
                     again with the snapshot of {}",
                    w.status, expected, h.status
                );
                self.configure(&h.snapshot)?;
                self.restored = true;
                Ok(())
            }
            held => {
                let held_generation = held.map_or(0, |h| h.status.generation);
                let lost = if w.status.session == expected.session {
                    expected.generation.saturating_sub(w.status.generation)
                } else {
                    expected.generation
                };
                bail!(
                    "the car lost what it was taught: it came back holding {} ({}) where the \
                     host expected {}; {lost} acknowledged corrections are gone from the car, \
                     and the host holds {}, so restoring it would undo {} of them: the run \
                     cannot go on bit-identical",
                    w.status,
                    if w.status.session.is_none() {
                        "its flash was unreadable or erased"
                    } else {
                        "it restored an older state"
                    },
                    expected,
                    held.map_or("no snapshot of the car's learner".to_string(), |h| {
                        format!("only the snapshot of {}", h.status)
                    }),
                    expected.generation.saturating_sub(held_generation)
                )
            }
        }
    }

    /// Sends `request` until `accept` takes an answer, within the deadline; says hello first
    /// when not welcomed yet and after [`HELLO_AFTER`] silent tries.
    pub(super) fn exchange<T>(
        &mut self,
        what: &str,
        request: &Message,
        mut accept: impl FnMut(&Message, &mut RemoteStats) -> Result<Answer<T>>,
    ) -> Result<T> {
        let deadline = Instant::now() + self.config.deadline;
        loop {
            if self.epoch.is_none() || self.silent_tries >= HELLO_AFTER {
                self.silent_tries = 0;
                self.say_hello()?;
            }
            if self.epoch.is_some() {
                self.send(request)?;
            }
            let until = (Instant::now() + self.config.try_timeout).min(deadline);
            while let Some(m) = self.receive(until)? {
                if let Answer::Done(t) = accept(&m, &mut self.stats)? {
                    return Ok(t);
                }
            }
            if Instant::now() >= deadline {
                return Err(self.silence(what));
            }
            self.silent_tries += 1;
            self.stats.retransmissions += 1;
        }
    }

    /// The error of a call the car did not answer in time.
    pub(super) fn silence(&self, what: &str) -> anyhow::Error {
        anyhow!(
            "{what}: no authenticated answer from the car within {:?} over {} ({} messages from \
             it refused): is the car running, and does it have the same key?",
            self.config.deadline,
            self.link.describe(),
            self.security.refusals().total(),
        )
    }

    /// Makes sure a welcome gave the car's epoch and status.
    pub(super) fn welcomed(&mut self) -> Result<CarStatus> {
        let deadline = Instant::now() + self.config.deadline;
        while self.epoch.is_none() {
            self.say_hello()?;
            let until = (Instant::now() + self.config.try_timeout).min(deadline);
            while self.epoch.is_none() && self.receive(until)?.is_some() {}
            if self.epoch.is_none() && Instant::now() >= deadline {
                return Err(self.silence("hello"));
            }
        }
        Ok(self.car.unwrap_or_default())
    }

    /// Configures the car with `snapshot` in the session after its current one.
    pub(super) fn configure(&mut self, snapshot: &LearnerSnapshot) -> Result<()> {
        let car = self.welcomed()?;
        let session = car.session.map_or(1, |s| s.wrapping_add(1));
        let request = Message::Configure(ConfigureMessage {
            session,
            snapshot: *snapshot,
        });
        let report = self.exchange("configure", &request, |m, _| match m {
            Message::Weights(w) if w.status.session == Some(session) => Ok(Answer::Done(*w)),
            Message::Error(e) if e.code == ErrorCode::Params => {
                bail!("the car refused the learner configuration")
            }
            Message::Error(e) if e.code == ErrorCode::Session => {
                bail!("the car refused session {session}: another host configured it meanwhile?")
            }
            _ => Ok(Answer::Ignore),
        })?;
        if report.snapshot != *snapshot || report.status.generation != 0 {
            bail!("configure: the car reported another learner than the one it was given");
        }
        let status = CarStatus {
            session: Some(session),
            generation: 0,
        };
        self.car = Some(status);
        self.expected = Some(status);
        self.held = Some(Held {
            status,
            snapshot: *snapshot,
        });
        let tries = self.config.deadline.as_millis() / self.config.try_timeout.as_millis().max(1);
        self.sender = Some(FeedbackSender::new(
            session,
            RetryPolicy {
                timeout_ms: self.config.try_timeout.as_millis().max(1) as u32,
                max_retries: tries.min(u16::MAX as u128) as u16,
            },
        ));
        Ok(())
    }

    pub(super) fn observe(&mut self, tick: u32, obs: &Observation) -> Result<Decision> {
        self.restored = false;
        let request = Message::Observation(ObservationMessage {
            tick,
            observation: obs.clone(),
        });
        let mut not_configured = false;
        let d = self.exchange(&format!("tick {tick}"), &request, |m, stats| match m {
            Message::Action(a) if a.tick == tick => {
                if !a.answers_observation() {
                    // The car's watchdog, a reset or a new configuration, not its answer.
                    stats.stops_ignored += 1;
                    return Ok(Answer::Ignore);
                }
                Ok(Answer::Done(Some(Decision {
                    tick,
                    action: a.action(),
                    allowed: a.allowed,
                })))
            }
            Message::Action(a) if a.stop_reason().is_some() => {
                stats.stops_ignored += 1;
                Ok(Answer::Ignore)
            }
            Message::Error(e) if e.code == ErrorCode::Observation && e.tick == Some(tick) => {
                bail!("tick {tick}: observation refused by the car")
            }
            Message::Error(e) if e.code == ErrorCode::NotConfigured && e.tick == Some(tick) => {
                not_configured = true;
                Ok(Answer::Done(None))
            }
            _ => Ok(Answer::Ignore),
        })?;
        match d {
            Some(d) => {
                // A restore during the exchange gave the same learner: the answer stands.
                self.restored = false;
                Ok(d)
            }
            None => {
                // The car holds no learner: it lost its state. Ask what it holds.
                debug_assert!(not_configured);
                self.epoch = None;
                self.welcomed()?;
                if !self.restored {
                    bail!("tick {tick}: the car holds no configured learner");
                }
                self.restored = false;
                self.observe(tick, obs)
            }
        }
    }

    /// Sends `feedback` about `tick` until the car acknowledges it; `Ok(false)` if it was
    /// nacked `unknown tick` (the tick must be shown again).
    pub(super) fn deliver(&mut self, tick: u32, feedback: &Feedback) -> Result<bool> {
        self.restored = false;
        let deadline = Instant::now() + self.config.deadline;
        let now = self.now_ms();
        let sender = self
            .sender
            .as_mut()
            .ok_or_else(|| anyhow!("feedback before the car was configured"))?;
        let session = sender.session();
        let msg = sender
            .send(now, tick, *feedback)
            .map_err(|e| anyhow!("tick {tick}: {e}"))?;
        self.stats.feedback_deliveries += 1;
        self.send(&Message::Feedback(msg))?;
        loop {
            let until = (Instant::now() + self.config.try_timeout).min(deadline);
            while let Some(m) = self.receive(until)? {
                if self.restored {
                    // The car was configured again: a new session; this delivery is void (the
                    // restored learner never had it).
                    self.restored = false;
                    return Ok(false);
                }
                let event = self.sender.as_mut().and_then(|s| s.on_reply(&m));
                match event {
                    Some(SenderEvent::Delivered { .. }) => {
                        if let Some(e) = &mut self.expected {
                            e.generation = e.generation.wrapping_add(1);
                        }
                        return Ok(true);
                    }
                    Some(SenderEvent::Refused {
                        code: NackCode::UnknownTick,
                        ..
                    }) => return Ok(false),
                    Some(SenderEvent::Refused {
                        code: NackCode::WrongSession,
                        ..
                    }) => {
                        // The car is in another session than ours: it lost its state.
                        self.epoch = None;
                        self.welcomed()?;
                        self.restored = false;
                        return Ok(false);
                    }
                    Some(SenderEvent::Refused { code, .. }) => {
                        bail!("tick {tick}: feedback refused by the car: {code}")
                    }
                    _ => {}
                }
            }
            if self.restored {
                self.restored = false;
                return Ok(false);
            }
            if self.silent_tries >= HELLO_AFTER {
                self.silent_tries = 0;
                self.say_hello()?;
            }
            self.silent_tries += 1;
            let now = self.now_ms();
            while let Some(e) = self.sender.as_mut().and_then(|s| s.poll(now)) {
                match e {
                    SenderEvent::Retransmit(m) if m.id.session == session => {
                        self.stats.retransmissions += 1;
                        self.send(&Message::Feedback(m))?;
                    }
                    SenderEvent::Failed { .. } => {
                        return Err(self.silence(&format!("feedback on tick {tick}")));
                    }
                    _ => {}
                }
            }
        }
    }
}
