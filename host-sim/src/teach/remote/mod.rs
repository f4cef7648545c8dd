//! The learner on the car's controller: [`RemoteCar`], a [`CarLink`] over a CAN link.
//!
//! Every message is authenticated with the car's key ([`RemoteConfig::key`]) and fresh
//! (`protocol::secure`): the host first says hello and takes the car's epoch, counters and
//! status from its welcome. Every call is then a stop-and-wait exchange: send the request, wait
//! up to [`RemoteConfig::try_timeout`] for its answer, send it again, until the answer comes or
//! [`RemoteConfig::deadline`] has passed since the call began (long enough to outlive a restart
//! of the car's controller). Answers to other requests (late copies, duplicates) are ignored,
//! and messages that fail authentication or freshness are counted and dropped, so lost,
//! corrupted, duplicated, reordered, delayed, forged or replayed frames cost time, never a
//! different result: a run over a link gives the same records, bit for bit, as a run in
//! process. The time is the milliseconds since the [`RemoteCar`] was made, passed to the
//! protocol's state machines ([`FeedbackSender`]).
//!
//! | call | sends | until |
//! |---|---|---|
//! | `restore(snapshot)` | hello (if not welcomed yet), configure (the session after the car's, the snapshot) | a weights report of that session equal to `snapshot` |
//! | `act(t, obs)` | observation of `t` | the answer of `t`: a track, or a stop because every trajectory collides (error `observation` → error) |
//! | `feedback(t, fb)` | feedback `(s, seq)` through a [`FeedbackSender`] | its ack; nack `unknown tick` → the observation of `t` again, then the feedback with a new `seq`; other nacks → error |
//! | `snapshot()` | weights request | a weights report |
//!
//! The car says why it stops ([`protocol::message::StopReason`]): a stop for its watchdog, a reset or a new
//! configuration answers no observation and is ignored; the host evaluates nothing itself.
//!
//! # Restarts of the car
//!
//! A restarted car takes a new epoch, so it refuses everything the host sends in the old one
//! and nothing it sends verifies under the old one: after [`HELLO_AFTER`] tries without an
//! authenticated answer, the host says hello again, and the welcome says what the car holds.
//! The host keeps the last snapshot the car reported (the configuration's, or a weights
//! report's) and counts the feedback the car acknowledged since:
//!
//! * the car holds the session and generation the host expects: the run goes on (a feedback in
//!   flight is acknowledged from the car's restored dedupe window, never applied twice);
//! * it holds less, and the host's snapshot is the one the car should hold: the host configures
//!   it again with that snapshot, and the run goes on, bit-identical;
//! * it holds less, and the host's snapshot is older: the call fails, naming what was lost, and
//!   `host-sim run` exits non-zero. Never a silent fresh learner.
//!
//! ```
//! use firmware_core::{Learner, LearnerParams};
//! use firmware_core::observation::Observation;
//! use hil_mock::server::Server;
//! use hil_mock::transport::memory::MemoryLink;
//! use host_sim::teach::experiment::CarLink;
//! use host_sim::teach::remote::{RemoteCar, RemoteConfig};
//! use protocol::car::CarConfig;
//! use protocol::secure::Key;
//! use std::sync::{Arc, atomic::{AtomicBool, Ordering}};
//!
//! let key = Key::new([0x5A; 16]);
//! let (host, mut car) = MemoryLink::pair();
//! let stop = Arc::new(AtomicBool::new(false));
//! let flag = stop.clone();
//! let car_key = key.clone();
//! let server = std::thread::spawn(move || {
//!     let mut s = Server::in_memory(CarConfig::default(), &car_key, 77);
//!     s.run(&mut car, &flag)
//! });
//! let mut remote = RemoteCar::new(host, RemoteConfig::new(key));
//! let learner = Learner::new(LearnerParams::default().check().unwrap());
//! remote.restore(&learner.snapshot()).unwrap();
//! let d = remote.act(0, &Observation::open_space()).unwrap();
//! assert!(d.action.is_some());
//! assert_eq!(remote.snapshot().unwrap(), learner.snapshot());
//! stop.store(true, Ordering::Relaxed);
//! server.join().unwrap().unwrap();
//! ```

mod exchange;

use std::time::{Duration, Instant};

use anyhow::{Result, bail};
use firmware_core::agent::Decision;
use firmware_core::observation::Observation;
use firmware_core::{Feedback, LearnerSnapshot};
use hil_mock::transport::Link;
use protocol::delivery::FeedbackSender;
use protocol::isotp::FrameMode;
use protocol::link::Inbox;
use protocol::message::{CarStatus, Message};
use protocol::secure::{HostSecurity, Key, RefusalStats};
use protocol::stream::Direction;

use crate::teach::experiment::CarLink;

/// Tries without an authenticated answer after which the host says hello again.
pub const HELLO_AFTER: u32 = 3;

/// How many times in one call the car may come back without its state and be configured
/// again before the host gives up.
const MAX_RESTORES: u32 = 8;

/// How a [`RemoteCar`] talks.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RemoteConfig {
    /// The frames it transmits.
    pub mode: FrameMode,
    /// Wait this long for an answer before sending the request again.
    pub try_timeout: Duration,
    /// Give a call up after this long.
    pub deadline: Duration,
    /// The car's key (`Key::INSECURE` with `--insecure`).
    pub key: Key,
}

impl RemoteConfig {
    /// CAN FD, 20 ms per try, 30 s per call, with `key`.
    pub fn new(key: Key) -> Self {
        Self {
            mode: FrameMode::Fd,
            try_timeout: Duration::from_millis(20),
            deadline: Duration::from_secs(30),
            key,
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
    /// Stops that answered no observation (watchdog, reset, new configuration), ignored.
    pub stops_ignored: u64,
    /// Hellos sent.
    pub hellos: u64,
    /// Welcomes that showed a new epoch: the car restarted.
    pub car_restarts: u64,
    /// Times the car was configured again with the host's snapshot after losing its state.
    pub restores: u64,
    /// Frames that could not be sent or were malformed on receipt (transient link trouble).
    pub link_errors: u64,
    /// Messages from the car refused (authentication or freshness).
    pub refused: RefusalStats,
    /// Weights reports dropped as out of date: messages the car sent after them arrived first.
    pub out_of_date: u64,
}

/// The last learner the car reported, and where it stood.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Held {
    status: CarStatus,
    snapshot: LearnerSnapshot,
}

/// The learner on the car's controller, behind a [`Link`].
pub struct RemoteCar<L: Link> {
    link: L,
    config: RemoteConfig,
    inbox: Inbox,
    security: HostSecurity,
    start: Instant,
    /// The car's epoch and status as the last welcome said.
    epoch: Option<u32>,
    car: Option<CarStatus>,
    /// What the car holds as far as this host knows: the session it configured and the
    /// generation (feedback acknowledged since).
    expected: Option<CarStatus>,
    /// The last snapshot the car reported.
    held: Option<Held>,
    sender: Option<FeedbackSender>,
    /// The last tick acted in: its observation and the decision.
    last: Option<(u32, Observation, Decision)>,
    /// Tries since the last authenticated message.
    silent_tries: u32,
    /// Set by a welcome that required configuring the car again.
    restored: bool,
    restores_in_call: u32,
    stats: RemoteStats,
}

impl<L: Link> std::fmt::Debug for RemoteCar<L> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RemoteCar")
            .field("link", &self.link.describe())
            .field("epoch", &self.epoch)
            .field("expected", &self.expected)
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
        let security = HostSecurity::new(&config.key);
        Self {
            link,
            config,
            inbox: Inbox::new(Direction::CarToHost),
            security,
            start: Instant::now(),
            epoch: None,
            car: None,
            expected: None,
            held: None,
            sender: None,
            last: None,
            silent_tries: 0,
            restored: false,
            restores_in_call: 0,
            stats: RemoteStats::default(),
        }
    }

    /// What it has done.
    pub fn stats(&self) -> RemoteStats {
        RemoteStats {
            refused: self.security.refusals(),
            ..self.stats
        }
    }

    /// The configured session, if any.
    pub fn session(&self) -> Option<u8> {
        self.expected.and_then(|s| s.session)
    }

    /// The car's status as the last welcome said (it may have moved on since).
    pub fn car_status(&self) -> Option<CarStatus> {
        self.car
    }

    /// The link.
    pub fn link(&self) -> &L {
        &self.link
    }

    /// The link, mutably.
    pub fn link_mut(&mut self) -> &mut L {
        &mut self.link
    }
}

/// How many times one feedback may meet a car that forgot its tick (restarted) in a row.
const MAX_REOBSERVE: u32 = 16;

impl<L: Link> CarLink for RemoteCar<L> {
    fn restore(&mut self, snapshot: &LearnerSnapshot) -> Result<()> {
        self.restores_in_call = 0;
        self.last = None;
        self.configure(snapshot)
    }

    fn act(&mut self, tick: u32, obs: &Observation) -> Result<Decision> {
        self.restores_in_call = 0;
        let d = self.observe(tick, obs)?;
        self.last = Some((tick, obs.clone(), d));
        Ok(d)
    }

    fn feedback(&mut self, tick: u32, feedback: &Feedback) -> Result<()> {
        self.restores_in_call = 0;
        let mut reobserved = 0;
        loop {
            if self.deliver(tick, feedback)? {
                self.stats.feedback_acked += 1;
                return Ok(());
            }
            // The car restarted and forgot the tick (or was configured again): show it again,
            // then send the feedback under a new number (the old one was not applied).
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
                    "tick {tick}: the car decided differently after a restart ({:?} before, {:?} \
                     now): its learner was not restored",
                    d.action,
                    again.action
                );
            }
            self.last = Some((t, obs, d));
        }
    }

    fn snapshot(&mut self) -> Result<LearnerSnapshot> {
        self.restores_in_call = 0;
        let report = self.exchange("weights request", &Message::WeightsRequest, |m, _| {
            Ok(match m {
                Message::Weights(w) => Answer::Done(*w),
                _ => Answer::Ignore,
            })
        })?;
        if let Some(e) = self.expected
            && report.status != e
        {
            bail!(
                "weights request: the car reports {}, the host expected {e}",
                report.status
            );
        }
        self.held = Some(Held {
            status: report.status,
            snapshot: report.snapshot,
        });
        Ok(report.snapshot)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hil_mock::server::LinkBus;
    use hil_mock::server::Server;
    use hil_mock::transport::memory::MemoryLink;
    use protocol::car::CarConfig;
    use protocol::link::{Received, transmit};
    use protocol::message::{ActionCommand, StopReason, WeightsReport};
    use protocol::secure::CarSecurity;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};

    const KEY: Key = Key::new([0x21; 16]);

    fn quick() -> RemoteConfig {
        RemoteConfig {
            try_timeout: Duration::from_millis(5),
            deadline: Duration::from_secs(2),
            ..RemoteConfig::new(KEY)
        }
    }

    /// A car that answers every observation first with a watchdog stop, then with its real
    /// action (a stand-in speaking the protocol directly, without a configuration).
    fn stubborn_car(mut link: MemoryLink) {
        let mut inbox = Inbox::new(Direction::HostToCar);
        let mut sec = CarSecurity::new(&KEY, 5);
        let mut agent = firmware_core::agent::Agent::new(firmware_core::Learner::new(
            firmware_core::LearnerParams::default().check().unwrap(),
        ));
        while let Ok(got) = link.recv(Duration::from_secs(5)) {
            let Some(frame) = got else { return };
            let answers = match inbox.feed(&frame, 0, &mut sec) {
                Received::Message(Message::Observation(o)) => {
                    let d = agent.act(o.tick, &o.observation).unwrap();
                    std::vec![
                        Message::Action(ActionCommand::stop(o.tick, StopReason::Watchdog)),
                        Message::Action(ActionCommand::from(&d)),
                    ]
                }
                Received::Message(Message::Hello(h)) => {
                    std::vec![Message::Welcome(sec.welcome(&h, CarStatus::default()))]
                }
                _ => continue,
            };
            for msg in answers {
                if transmit(
                    &mut LinkBus(&mut link),
                    &msg,
                    Direction::CarToHost,
                    FrameMode::Fd,
                    &mut sec,
                )
                .is_err()
                {
                    return;
                }
            }
        }
    }

    #[test]
    fn stops_that_answer_no_observation_are_ignored_without_evaluating() {
        let (host, car) = MemoryLink::pair();
        let handle = std::thread::spawn(move || stubborn_car(car));
        let mut remote = RemoteCar::new(host, quick());
        let d = remote.act(3, &Observation::open_space()).unwrap();
        assert!(d.action.is_some() && !d.allowed.is_empty());
        assert_eq!(remote.stats().stops_ignored, 1);
        // Everything blocked: the stop is the answer.
        let mut walled = Observation::open_space();
        walled.scan.ranges = [0.1; firmware_core::observation::SCAN_BEAMS];
        let d = remote.act(4, &walled).unwrap();
        assert_eq!((d.action, d.allowed.is_empty()), (None, true));
        drop(remote);
        handle.join().unwrap();
    }

    /// A car that answers the first weights request with a report of an earlier state (no
    /// learner) which a message it sent after it overtakes on the way, as a delayed frame would;
    /// every other request in order.
    fn car_with_a_late_report(mut link: MemoryLink) {
        let mut inbox = Inbox::new(Direction::HostToCar);
        let mut sec = CarSecurity::new(&KEY, 6);
        let mut held: Option<WeightsReport> = None;
        let mut late_sent = false;
        let send = |link: &mut MemoryLink, sec: &mut CarSecurity, msg: &Message| {
            transmit(
                &mut LinkBus(link),
                msg,
                Direction::CarToHost,
                FrameMode::Fd,
                sec,
            )
            .is_ok()
        };
        while let Ok(got) = link.recv(Duration::from_secs(5)) {
            let Some(frame) = got else { return };
            let status = held.map_or(CarStatus::default(), |r| r.status);
            let ok = match inbox.feed(&frame, 0, &mut sec) {
                Received::Message(Message::Hello(h)) => {
                    let welcome = Message::Welcome(sec.welcome(&h, status));
                    send(&mut link, &mut sec, &welcome)
                }
                Received::Message(Message::Configure(c)) => {
                    let report = WeightsReport {
                        status: CarStatus {
                            session: Some(c.session),
                            generation: 0,
                        },
                        snapshot: c.snapshot,
                    };
                    held = Some(report);
                    send(&mut link, &mut sec, &Message::Weights(report))
                }
                Received::Message(Message::WeightsRequest) if !late_sent => {
                    late_sent = true;
                    // Sealed first, delivered after the heartbeat sealed next.
                    let (mut into, mut out) = MemoryLink::pair();
                    let late = Message::Weights(WeightsReport {
                        status: CarStatus::default(),
                        snapshot: held.unwrap().snapshot,
                    });
                    let mut ok = send(&mut into, &mut sec, &late);
                    ok &= send(&mut link, &mut sec, &Message::Heartbeat);
                    while let Ok(Some(f)) = out.recv(Duration::ZERO) {
                        ok &= link.send(&f).is_ok();
                    }
                    ok
                }
                Received::Message(Message::WeightsRequest) => {
                    send(&mut link, &mut sec, &Message::Weights(held.unwrap()))
                }
                _ => continue,
            };
            if !ok {
                return;
            }
        }
    }

    #[test]
    fn a_weights_report_that_a_later_message_overtook_is_not_taken_as_the_cars_state() {
        let (host, car) = MemoryLink::pair();
        let handle = std::thread::spawn(move || car_with_a_late_report(car));
        let mut remote = RemoteCar::new(host, quick());
        let learner =
            firmware_core::Learner::new(firmware_core::LearnerParams::default().check().unwrap());
        remote.restore(&learner.snapshot()).unwrap();
        // Taken as the answer, the late report (no learner) would read as a car that lost it.
        assert_eq!(remote.snapshot().unwrap(), learner.snapshot());
        let stats = remote.stats();
        assert_eq!(
            (stats.out_of_date, stats.retransmissions),
            (1, 1),
            "{stats:?}"
        );
        drop(remote);
        handle.join().unwrap();
    }

    #[test]
    fn a_host_with_another_key_gets_no_answer_and_says_so() {
        let (host, mut car) = MemoryLink::pair();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let server = std::thread::spawn(move || {
            let mut s = Server::in_memory(CarConfig::default(), &KEY, 3);
            s.run(&mut car, &flag).map(|()| s.node().stats())
        });
        let mut remote = RemoteCar::new(
            host,
            RemoteConfig {
                key: Key::new([0x22; 16]),
                deadline: Duration::from_millis(300),
                ..quick()
            },
        );
        let learner =
            firmware_core::Learner::new(firmware_core::LearnerParams::default().check().unwrap());
        let e = remote.restore(&learner.snapshot()).unwrap_err().to_string();
        assert!(e.contains("hello: no authenticated answer"), "{e}");
        assert!(e.contains("same key"), "{e}");
        stop.store(true, Ordering::Relaxed);
        let stats = server.join().unwrap().unwrap();
        assert!(stats.refused.mac > 0, "{stats:?}");
        assert_eq!(stats.actions, 0);
    }
}
