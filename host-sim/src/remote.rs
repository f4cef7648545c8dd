//! The learner on the car's controller: [`RemoteCar`], a [`CarLink`] over a CAN link.
//!
//! Every call is a stop-and-wait exchange: send the request, wait up to
//! [`RemoteConfig::try_timeout`] for its answer, send it again, until the answer comes or
//! [`RemoteConfig::deadline`] has passed since the call began (long enough to outlive a restart
//! of the car's controller). Answers to other requests (late copies, duplicates) are ignored, so
//! lost, corrupted, duplicated, reordered or delayed frames cost time, never a different result:
//! a run over a link gives the same records, bit for bit, as a run in process.
//!
//! | call | sends | until |
//! |---|---|---|
//! | `restore(snapshot)` | configure (session `s`, snapshot) | a weights report equal to `snapshot` (else: another session) |
//! | `act(t, obs)` | observation of `t` | the action command of `t` (error `observation` → error) |
//! | `feedback(t, fb)` | feedback `(s, seq)` | its ack; nack `unknown tick` → the observation of `t` again, then the feedback with a new `seq`; nack `rejected` → error |
//! | `snapshot()` | weights request | a weights report |
//!
//! The car answers an observation with a stop whose mask is empty in two cases: every trajectory
//! collides, or its watchdog fired (the observation or its answer took more than its watchdog
//! time to get through). The two are the same bytes; [`RemoteCar`] tells them apart by evaluating
//! the observation itself when a stop comes (the same `firmware-core` evaluator, so the same mask): a stop for an
//! observation that leaves some trajectory free is the watchdog's, and is ignored.
//!
//! ```
//! use firmware_core::{Learner, LearnerParams};
//! use firmware_core::observation::Observation;
//! use hil_mock::server::Server;
//! use hil_mock::transport::memory::MemoryLink;
//! use host_sim::experiment::CarLink;
//! use host_sim::remote::{RemoteCar, RemoteConfig};
//! use protocol::car::CarConfig;
//! use std::sync::{Arc, atomic::{AtomicBool, Ordering}};
//!
//! let (host, mut car) = MemoryLink::pair();
//! let stop = Arc::new(AtomicBool::new(false));
//! let flag = stop.clone();
//! let server = std::thread::spawn(move || {
//!     let mut s = Server::in_memory(CarConfig::default());
//!     s.run(&mut car, &flag)
//! });
//! let mut remote = RemoteCar::new(host, RemoteConfig::default());
//! let learner = Learner::new(LearnerParams::default().check().unwrap());
//! remote.restore(&learner.snapshot()).unwrap();
//! let d = remote.act(0, &Observation::open_space()).unwrap();
//! assert!(d.action.is_some());
//! assert_eq!(remote.snapshot().unwrap(), learner.snapshot());
//! stop.store(true, Ordering::Relaxed);
//! server.join().unwrap().unwrap();
//! ```

use std::time::{Duration, Instant};

use anyhow::{Result, anyhow, bail};
use firmware_core::agent::Decision;
use firmware_core::evaluator::Evaluator;
use firmware_core::observation::Observation;
use firmware_core::{FeatureTable, Feedback, LearnerSnapshot};
use hil_mock::server::LinkBus;
use hil_mock::transport::{Link, LinkError};
use protocol::isotp::FrameMode;
use protocol::link::{Inbox, Received, transmit};
use protocol::message::{
    ConfigureMessage, DeliveryId, ErrorCode, FeedbackMessage, Message, NackCode, ObservationMessage,
};
use protocol::stream::Direction;

use crate::experiment::CarLink;

/// How a [`RemoteCar`] talks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RemoteConfig {
    /// The frames it transmits.
    pub mode: FrameMode,
    /// Wait this long for an answer before sending the request again.
    pub try_timeout: Duration,
    /// Give a call up after this long.
    pub deadline: Duration,
    /// The first configuration session to try (`None`: from the clock).
    pub session: Option<u8>,
}

impl Default for RemoteConfig {
    /// CAN FD, 20 ms per try, 30 s per call, a session from the clock.
    fn default() -> Self {
        Self {
            mode: FrameMode::Fd,
            try_timeout: Duration::from_millis(20),
            deadline: Duration::from_secs(30),
            session: None,
        }
    }
}

/// What a [`RemoteCar`] has done.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RemoteStats {
    /// Requests sent again after a try timed out.
    pub retransmissions: u64,
    /// Feedbacks acknowledged (one per `feedback` call that succeeded).
    pub feedback_acked: u64,
    /// Feedback deliveries (sequence numbers) used, including those nacked `unknown tick`.
    pub feedback_deliveries: u64,
    /// Ticks observed again because the car had forgotten them (it restarted).
    pub reobserved: u64,
    /// Watchdog stops received and ignored.
    pub watchdog_stops: u64,
    /// Frames that could not be sent or were malformed on receipt (transient link trouble).
    pub link_errors: u64,
}

/// The learner on the car's controller, behind a [`Link`].
pub struct RemoteCar<L: Link> {
    link: L,
    config: RemoteConfig,
    inbox: Inbox,
    start: Instant,
    session: u8,
    next_seq: u8,
    /// The last tick acted in: its observation and the decision.
    last: Option<(u32, Observation, Decision)>,
    /// Tells a watchdog stop from a real one; taken out while an observation is exchanged.
    stops: Option<Box<StopCheck>>,
    stats: RemoteStats,
}

/// The car's evaluator on the host, run only when the car answers with a stop.
struct StopCheck {
    evaluator: Evaluator,
    table: FeatureTable,
}

impl StopCheck {
    fn new() -> Box<Self> {
        Box::new(Self {
            evaluator: Evaluator::new(),
            table: FeatureTable::ZERO,
        })
    }

    /// Whether a stop for `obs` is the car's watchdog: the observation leaves some trajectory
    /// free, so the car's own answer would not be a stop (the same evaluator, the same mask).
    fn is_watchdog(&mut self, obs: &Observation) -> bool {
        obs.check()
            .is_ok_and(|obs| !self.evaluator.evaluate(obs, &mut self.table).is_empty())
    }
}

impl<L: Link> std::fmt::Debug for RemoteCar<L> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RemoteCar")
            .field("link", &self.link.describe())
            .field("session", &self.session)
            .field("stats", &self.stats)
            .finish()
    }
}

/// What to do with a received message.
enum Answer<T> {
    /// Not the answer: keep waiting.
    Ignore,
    /// The answer.
    Done(T),
}

impl<L: Link> RemoteCar<L> {
    /// A remote car over `link`. Call [`CarLink::restore`] first.
    pub fn new(link: L, config: RemoteConfig) -> Self {
        let session = config.session.unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(1, |d| (d.subsec_nanos() >> 10) as u8)
        });
        Self {
            link,
            config,
            inbox: Inbox::new(Direction::CarToHost),
            start: Instant::now(),
            session,
            next_seq: 0,
            last: None,
            stops: Some(StopCheck::new()),
            stats: RemoteStats::default(),
        }
    }

    /// What it has done.
    pub fn stats(&self) -> RemoteStats {
        self.stats
    }

    /// The configuration session in use.
    pub fn session(&self) -> u8 {
        self.session
    }

    /// The link.
    pub fn link(&self) -> &L {
        &self.link
    }

    /// The link, mutably.
    pub fn link_mut(&mut self) -> &mut L {
        &mut self.link
    }

    fn now_ms(&self) -> u32 {
        self.start.elapsed().as_millis() as u32
    }

    /// Sends `msg`; transient link errors are counted (the request is sent again later).
    fn send(&mut self, msg: &Message) -> Result<()> {
        match transmit(
            &mut LinkBus(&mut self.link),
            msg,
            Direction::HostToCar,
            self.config.mode,
        ) {
            Ok(_) => Ok(()),
            Err(protocol::link::TransmitError::Bus {
                error: LinkError::Io { .. },
                ..
            }) => {
                self.stats.link_errors += 1;
                Ok(())
            }
            Err(e) => Err(anyhow!("{}: {e}", self.link.describe())),
        }
    }

    /// The next message from the car before `until`, if any.
    fn receive(&mut self, until: Instant) -> Result<Option<Message>> {
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
            if let Some(frame) = got
                && let Received::Message(m) = self.inbox.feed(&frame, now_ms)
            {
                return Ok(Some(m));
            }
        }
    }

    /// Sends `request` until `accept` takes an answer, within the deadline.
    fn exchange<T>(
        &mut self,
        what: &str,
        request: &Message,
        mut accept: impl FnMut(&Message, &mut RemoteStats) -> Result<Answer<T>>,
    ) -> Result<T> {
        let deadline = Instant::now() + self.config.deadline;
        loop {
            self.send(request)?;
            let until = (Instant::now() + self.config.try_timeout).min(deadline);
            while let Some(m) = self.receive(until)? {
                if let Answer::Done(t) = accept(&m, &mut self.stats)? {
                    return Ok(t);
                }
            }
            if Instant::now() >= deadline {
                bail!(
                    "{what}: no answer from the car within {:?} over {}",
                    self.config.deadline,
                    self.link.describe()
                );
            }
            self.stats.retransmissions += 1;
        }
    }

    fn observe(&mut self, tick: u32, obs: &Observation) -> Result<Decision> {
        let request = Message::Observation(ObservationMessage {
            tick,
            observation: obs.clone(),
        });
        let mut stops = self.stops.take().unwrap_or_else(StopCheck::new);
        let decision = self.exchange(&format!("tick {tick}"), &request, |m, stats| match m {
            Message::Action(a) if a.tick == tick => {
                // A stop despite a free trajectory is the car's watchdog, not its answer.
                if a.track.is_none() && stops.is_watchdog(obs) {
                    stats.watchdog_stops += 1;
                    return Ok(Answer::Ignore);
                }
                Ok(Answer::Done(Decision {
                    tick,
                    action: a.action(),
                    allowed: a.allowed,
                }))
            }
            Message::Error(e) if e.code == ErrorCode::Observation && e.tick == Some(tick) => {
                bail!("tick {tick}: observation refused by the car")
            }
            _ => Ok(Answer::Ignore),
        });
        self.stops = Some(stops);
        decision
    }
}

/// How many times one feedback may meet a car that forgot its tick (restarted) in a row.
const MAX_REOBSERVE: u32 = 16;

impl<L: Link> CarLink for RemoteCar<L> {
    fn restore(&mut self, snapshot: &LearnerSnapshot) -> Result<()> {
        for _ in 0..8 {
            let session = self.session;
            let request = Message::Configure(ConfigureMessage {
                session,
                snapshot: *snapshot,
            });
            let got = self.exchange("configure", &request, |m, _| match m {
                Message::Weights(w) => Ok(Answer::Done(*w)),
                Message::Error(e) if e.code == ErrorCode::Params => {
                    bail!("the car refused the learner configuration")
                }
                _ => Ok(Answer::Ignore),
            })?;
            if got == *snapshot {
                self.next_seq = 0;
                self.last = None;
                return Ok(());
            }
            // The car already had this session (from an earlier run): take another.
            self.session = session.wrapping_add(1);
        }
        bail!("configure: the car never reported the learner it was given")
    }

    fn act(&mut self, tick: u32, obs: &Observation) -> Result<Decision> {
        let d = self.observe(tick, obs)?;
        self.last = Some((tick, obs.clone(), d));
        Ok(d)
    }

    fn feedback(&mut self, tick: u32, feedback: &Feedback) -> Result<()> {
        let mut reobserved = 0;
        loop {
            let id = DeliveryId {
                session: self.session,
                seq: self.next_seq,
            };
            self.next_seq = self.next_seq.wrapping_add(1);
            self.stats.feedback_deliveries += 1;
            let request = Message::Feedback(FeedbackMessage {
                id,
                tick,
                feedback: *feedback,
            });
            let verdict =
                self.exchange(&format!("feedback on tick {tick}"), &request, |m, _| {
                    Ok(match m {
                        Message::Ack(a) if a.id == id => Answer::Done(None),
                        Message::Nack(n) if n.id == id => Answer::Done(Some(n.code)),
                        _ => Answer::Ignore,
                    })
                })?;
            match verdict {
                None => {
                    self.stats.feedback_acked += 1;
                    return Ok(());
                }
                Some(NackCode::UnknownTick) => {
                    // The car restarted and forgot the tick: show it again, then re-send the
                    // feedback under a new number (the old one is settled as refused).
                    let Some((t, obs, d)) = self.last.clone().filter(|(t, ..)| *t == tick) else {
                        bail!("tick {tick}: feedback refused: the car does not know the tick");
                    };
                    reobserved += 1;
                    if reobserved > MAX_REOBSERVE {
                        bail!("tick {tick}: the car keeps forgetting the tick");
                    }
                    self.stats.reobserved += 1;
                    let again = self.observe(t, &obs)?;
                    if again != d {
                        bail!(
                            "tick {tick}: the car decided differently after a restart \
                             ({:?} before, {:?} now): its learner was not restored",
                            d.action,
                            again.action
                        );
                    }
                }
                Some(code) => bail!("tick {tick}: feedback refused by the car: {code}"),
            }
        }
    }

    fn snapshot(&mut self) -> Result<LearnerSnapshot> {
        self.exchange("weights request", &Message::WeightsRequest, |m, _| {
            Ok(match m {
                Message::Weights(w) => Answer::Done(*w),
                _ => Answer::Ignore,
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hil_mock::transport::memory::MemoryLink;
    use protocol::message::ActionCommand;

    /// A car that answers every observation first with a watchdog-like stop, then with its
    /// real action.
    fn stubborn_car(mut link: MemoryLink) {
        let mut inbox = Inbox::new(Direction::HostToCar);
        let mut agent = firmware_core::agent::Agent::new(firmware_core::Learner::new(
            firmware_core::LearnerParams::default().check().unwrap(),
        ));
        while let Ok(got) = link.recv(Duration::from_secs(5)) {
            let Some(frame) = got else { return };
            if let Received::Message(Message::Observation(o)) = inbox.feed(&frame, 0) {
                let d = agent.act(o.tick, &o.observation).unwrap();
                for answer in [ActionCommand::stop(o.tick), ActionCommand::from(&d)] {
                    let msg = Message::Action(answer);
                    if transmit(
                        &mut LinkBus(&mut link),
                        &msg,
                        Direction::CarToHost,
                        FrameMode::Fd,
                    )
                    .is_err()
                    {
                        return;
                    }
                }
            }
        }
    }

    #[test]
    fn a_stop_for_an_observation_with_free_trajectories_is_the_watchdog_s() {
        let (host, car) = MemoryLink::pair();
        let handle = std::thread::spawn(move || stubborn_car(car));
        let mut remote = RemoteCar::new(host, RemoteConfig::default());
        let d = remote.act(3, &Observation::open_space()).unwrap();
        assert!(d.action.is_some() && !d.allowed.is_empty());
        assert_eq!(remote.stats().watchdog_stops, 1);
        // Everything blocked: the stop is the answer.
        let mut walled = Observation::open_space();
        walled.scan.ranges = [0.1; firmware_core::observation::SCAN_BEAMS];
        let d = remote.act(4, &walled).unwrap();
        assert_eq!((d.action, d.allowed.is_empty()), (None, true));
        drop(remote);
        handle.join().unwrap();
    }
}
