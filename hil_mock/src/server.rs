//! The car's controller over a [`Link`]: a [`CarNode`], its key and flash, and the poll loop.
//!
//! [`Server`] owns the node and the store; [`Server::run`] receives frames with a short timeout,
//! hands each to [`CarNode::on_frame`] and calls [`CarNode::poll`] between them (watchdog,
//! reassembly timeouts), until asked to stop or the link fails. The clock is the milliseconds
//! since the server started.
//!
//! What goes wrong on the link (malformed packets, lost messages, refused messages, answers the
//! OS could not send) is counted and written to stderr at a bounded rate ([`Reports`]): the
//! first few in full, then one summary line at most every [`SUMMARY_INTERVAL`] while anything
//! new happened, so a flood cannot flood the log.
//!
//! What happens to the car is written to stderr too, one line each ([`Server::step`]): a
//! session starts (an authenticated configuration of the next session: the learner it holds),
//! and the car stops (its watchdog, or a reset by the host; the stop of a new configuration is
//! its session's line). What the car restored from its flash when it started is the line of
//! [`StartState`].

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use firmware_core::{Learner, ValidLearnerParams};
use protocol::can::{CanBus, CanFrame};
use protocol::car::{CarConfig, CarNode, Outcome, Persist, Persisted};
use protocol::secure::{Key, Refusal};

use crate::flash::{FlashError, FlashStore, Open, PageStatus};
use crate::transport::{Link, LinkError};

/// A [`Link`] seen as the protocol's [`CanBus`].
#[derive(Debug)]
pub struct LinkBus<'a, L: Link + ?Sized>(pub &'a mut L);

impl<L: Link + ?Sized> CanBus for LinkBus<'_, L> {
    type Error = LinkError;

    fn transmit(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        self.0.send(frame)
    }

    fn receive(&mut self) -> Result<Option<CanFrame>, LinkError> {
        self.0.recv(Duration::ZERO)
    }

    fn authenticated(&mut self, fresh: bool) {
        self.0.authenticated(fresh)
    }
}

/// A [`Link`] seen as the protocol's [`CanBus`] that holds the frames transmitted until
/// [`BatchBus::flush`] sends them together ([`Link::send_all`]: on UDP, the frames of a message
/// in one packet). Receiving and [`CanBus::authenticated`] go to the link at once.
#[derive(Debug)]
pub struct BatchBus<'a, L: Link + ?Sized> {
    link: &'a mut L,
    frames: Vec<CanFrame>,
}

impl<'a, L: Link + ?Sized> BatchBus<'a, L> {
    /// A bus holding nothing yet.
    pub fn new(link: &'a mut L) -> Self {
        Self {
            link,
            frames: Vec::new(),
        }
    }

    /// Sends what was transmitted since the last flush, in order; holds nothing after it,
    /// whatever the result.
    pub fn flush(&mut self) -> Result<(), LinkError> {
        if self.frames.is_empty() {
            return Ok(());
        }
        let result = self.link.send_all(&self.frames);
        self.frames.clear();
        result
    }
}

impl<L: Link + ?Sized> CanBus for BatchBus<'_, L> {
    type Error = LinkError;

    fn transmit(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        self.frames.push(*frame);
        Ok(())
    }

    fn receive(&mut self) -> Result<Option<CanFrame>, LinkError> {
        self.link.recv(Duration::ZERO)
    }

    fn authenticated(&mut self, fresh: bool) {
        self.link.authenticated(fresh)
    }
}

/// Where the server persists: a flash file, or RAM (lost when the process ends).
#[derive(Debug)]
pub enum Store {
    /// The two-page flash file.
    Flash(FlashStore),
    /// In memory: the last state written.
    Memory(Option<Persisted>),
}

impl Persist for Store {
    type Error = FlashError;

    fn persist(&mut self, state: &Persisted) -> Result<(), FlashError> {
        match self {
            Store::Flash(f) => f.persist(state),
            Store::Memory(m) => {
                *m = Some(state.clone());
                Ok(())
            }
        }
    }
}

/// What the server found in its flash when it started.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StartState {
    /// No flash file given: a fresh learner, nothing persisted.
    NoFlash,
    /// The flash held nothing good: a fresh learner.
    Fresh {
        /// What each page held.
        pages: [PageStatus; 2],
    },
    /// Restored from a page.
    Restored {
        /// The page used.
        page: usize,
        /// Its write count.
        generation: u32,
        /// What each page held (the other may be corrupt: a fallback).
        pages: [PageStatus; 2],
    },
}

impl std::fmt::Display for StartState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let describe = |p: &PageStatus| match p {
            PageStatus::Empty => "empty".to_string(),
            PageStatus::Good(g) => format!("good (write {g})"),
            PageStatus::Corrupt => "corrupt".to_string(),
        };
        match self {
            StartState::NoFlash => {
                f.write_str("no flash file: no configured learner, nothing persisted")
            }
            StartState::Fresh { pages } => write!(
                f,
                "flash holds no good page (page 0 {}, page 1 {}): no configured learner",
                describe(&pages[0]),
                describe(&pages[1])
            ),
            StartState::Restored {
                page,
                generation,
                pages,
            } => {
                write!(
                    f,
                    "restored write {generation} from page {page} (page 0 {}, page 1 {})",
                    describe(&pages[0]),
                    describe(&pages[1])
                )?;
                if pages[1 - page] == PageStatus::Corrupt {
                    write!(f, "; fell back from corrupt page {}", 1 - page)?;
                }
                Ok(())
            }
        }
    }
}

/// The least time between two summary lines on stderr.
pub const SUMMARY_INTERVAL: Duration = Duration::from_secs(10);

/// How many problems are written out in full before only summaries follow.
pub const FIRST_LINES: u32 = 5;

/// What went wrong once, for [`Reports`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Problem {
    /// The transport received bytes that are not a packet or line of its format.
    Malformed(String),
    /// A message was lost (reassembly, decoding, wrong stream).
    Lost,
    /// A message was refused (authentication or freshness).
    Refused(Refusal),
    /// The OS refused to send an answer (the host's port closed while it restarts, ...).
    AnswerLost(String),
}

/// Counters of [`Problem`]s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProblemCounts {
    /// Malformed transport input.
    pub malformed: u64,
    /// Lost messages.
    pub lost: u64,
    /// Refused messages: MAC failures.
    pub refused_mac: u64,
    /// Refused messages: copies and messages older than the replay window.
    pub refused_stale: u64,
    /// Answers the OS did not send.
    pub answers_lost: u64,
}

impl ProblemCounts {
    fn total(&self) -> u64 {
        self.malformed + self.lost + self.refused_mac + self.refused_stale + self.answers_lost
    }

    fn minus(&self, o: &Self) -> Self {
        Self {
            malformed: self.malformed - o.malformed,
            lost: self.lost - o.lost,
            refused_mac: self.refused_mac - o.refused_mac,
            refused_stale: self.refused_stale - o.refused_stale,
            answers_lost: self.answers_lost - o.answers_lost,
        }
    }
}

impl std::fmt::Display for ProblemCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} malformed packets or lines, {} messages lost, {} refused (MAC {}, replayed or stale {}), {} answers not sent",
            self.malformed,
            self.lost,
            self.refused_mac + self.refused_stale,
            self.refused_mac,
            self.refused_stale,
            self.answers_lost
        )
    }
}

/// Counts problems and says what to write on stderr, at a bounded rate (time passed in).
#[derive(Debug)]
pub struct Reports {
    counts: ProblemCounts,
    at_last_summary: ProblemCounts,
    printed: u32,
    last_summary: Option<Instant>,
}

impl Reports {
    /// No problem yet; the first summary comes [`SUMMARY_INTERVAL`] after `now`.
    pub fn new(now: Instant) -> Self {
        Self {
            counts: ProblemCounts::default(),
            at_last_summary: ProblemCounts::default(),
            printed: 0,
            last_summary: Some(now),
        }
    }

    /// Everything counted so far.
    pub fn counts(&self) -> ProblemCounts {
        self.counts
    }

    /// Counts `p`; returns the line to write if it is among the first [`FIRST_LINES`].
    pub fn note(&mut self, p: &Problem) -> Option<String> {
        let c = &mut self.counts;
        match p {
            Problem::Malformed(_) => c.malformed += 1,
            Problem::Lost => c.lost += 1,
            Problem::Refused(Refusal::Mac | Refusal::Unkeyed) => c.refused_mac += 1,
            Problem::Refused(_) => c.refused_stale += 1,
            Problem::AnswerLost(_) => c.answers_lost += 1,
        }
        if self.printed >= FIRST_LINES {
            return None;
        }
        self.printed += 1;
        let more = if self.printed == FIRST_LINES {
            format!(
                "; from now on a summary at most every {} s",
                SUMMARY_INTERVAL.as_secs()
            )
        } else {
            String::new()
        };
        Some(match p {
            Problem::Malformed(d) => format!("skipped: {d}{more}"),
            Problem::Lost => format!("a message was lost on the way{more}"),
            Problem::Refused(r) => format!("refused a message: {r}{more}"),
            Problem::AnswerLost(d) => format!("an answer was lost: {d}{more}"),
        })
    }

    /// The summary line to write at `now`, if one is due and anything happened since the last.
    pub fn summary(&mut self, now: Instant) -> Option<String> {
        let due = self
            .last_summary
            .is_none_or(|t| now.duration_since(t) >= SUMMARY_INTERVAL);
        if !due || self.counts == self.at_last_summary {
            return None;
        }
        let since = self.counts.minus(&self.at_last_summary);
        self.at_last_summary = self.counts;
        self.last_summary = Some(now);
        (since.total() > 0).then(|| {
            format!(
                "in the last {} s: {since} (in all: {})",
                SUMMARY_INTERVAL.as_secs(),
                self.counts
            )
        })
    }
}

/// The car's controller: node, store, clock, reports.
#[derive(Debug)]
pub struct Server {
    node: CarNode,
    store: Store,
    start: Instant,
    reports: Reports,
    /// Write a line to stderr when a session starts or the car stops.
    log_events: bool,
}

/// The state `Server::events` compares: the session and the stops so far.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Watched {
    session: Option<u8>,
    watchdog_stops: u32,
    commanded_stops: u32,
}

/// How long one receive waits before the server polls the node again.
pub const POLL_INTERVAL: Duration = Duration::from_millis(2);

impl Server {
    /// A server with a fresh default learner, never configured, persisting in RAM, with `key`
    /// in `epoch`.
    pub fn in_memory(config: CarConfig, key: &Key, epoch: u32) -> Self {
        let mut node = CarNode::new(config, fresh_learner());
        node.install_key(key, epoch);
        Self::with_node(node, Store::Memory(None))
    }

    fn with_node(node: CarNode, store: Store) -> Self {
        let start = Instant::now();
        Self {
            node,
            store,
            start,
            reports: Reports::new(start),
            log_events: true,
        }
    }

    /// Without the lines of sessions and stops on stderr (a benchmark's car).
    pub fn without_event_lines(mut self) -> Self {
        self.log_events = false;
        self
    }

    /// A server persisting to the flash file at `path` (see [`FlashStore::open`] for `open`),
    /// restored from it when it holds a good page, with `key` in `epoch`.
    pub fn with_flash(
        config: CarConfig,
        path: &Path,
        open: Open,
        key: &Key,
        epoch: u32,
    ) -> Result<(Self, StartState), FlashError> {
        let (store, restored) = FlashStore::open(path, open)?;
        let pages = store.pages();
        let (mut node, state) = match restored {
            Some(r) => {
                // The page's snapshot passed `Learner::restore` already.
                let node = CarNode::restore(config, &r.state)
                    .unwrap_or_else(|_| CarNode::new(config, r.learner));
                let state = StartState::Restored {
                    page: r.page,
                    generation: r.generation,
                    pages,
                };
                (node, state)
            }
            None => (
                CarNode::new(config, fresh_learner()),
                StartState::Fresh { pages },
            ),
        };
        node.install_key(key, epoch);
        Ok((Self::with_node(node, Store::Flash(store)), state))
    }

    /// The node.
    pub fn node(&self) -> &CarNode {
        &self.node
    }

    /// The problems counted so far.
    pub fn problems(&self) -> ProblemCounts {
        self.reports.counts()
    }

    /// Milliseconds since the server started (wrapping).
    fn now_ms(&self) -> u32 {
        self.start.elapsed().as_millis() as u32
    }

    fn report(&mut self, p: Problem) {
        if let Some(line) = self.reports.note(&p) {
            eprintln!("hil_mock: {line}");
        }
    }

    /// What the lines of `events` are about.
    fn watched(&self) -> Watched {
        let s = self.node.stats();
        Watched {
            session: self.node.session(),
            watchdog_stops: s.watchdog_stops,
            commanded_stops: s.commanded_stops,
        }
    }

    /// One line for each thing that happened to the car since `before`: a session started, the
    /// car stopped.
    fn events(&self, before: Watched) -> Vec<String> {
        let now = self.watched();
        let mut lines = Vec::new();
        if now.session != before.session
            && let Some(session) = now.session
        {
            let learner = self.node.agent().learner();
            lines.push(format!(
                "session {session} started: the host configured a learner ({}, {} steps in)",
                learner.kind().name(),
                learner.state().steps
            ));
        }
        if now.watchdog_stops > before.watchdog_stops {
            lines.push(format!(
                "stopped: the watchdog (no observation for {} ms)",
                self.node.config().watchdog_ms
            ));
        }
        // A new configuration stops the car too: its line is the session's.
        let commanded = now.commanded_stops - before.commanded_stops;
        let reconfigured = u32::from(now.session != before.session);
        if commanded > reconfigured {
            lines.push("stopped: the host reset the car".to_string());
        }
        lines
    }

    /// Waits up to `timeout` for one frame and handles it, then polls the node. Malformed input,
    /// lost and refused messages and answers the OS did not send are counted and reported at a
    /// bounded rate; other link failures are returned. A session's start and the car's stops
    /// are written to stderr, one line each.
    pub fn step(&mut self, link: &mut dyn Link, timeout: Duration) -> Result<(), LinkError> {
        let before = self.watched();
        let result = self.handle(link, timeout);
        if self.log_events {
            for line in self.events(before) {
                eprintln!("hil_mock: {line}");
            }
        }
        result
    }

    fn handle(&mut self, link: &mut dyn Link, timeout: Duration) -> Result<(), LinkError> {
        let got = match link.recv(timeout) {
            Ok(f) => f,
            Err(e @ LinkError::Malformed { .. }) => {
                self.report(Problem::Malformed(e.to_string()));
                None
            }
            Err(e) => return Err(e),
        };
        // Each answer's frames leave together (one packet on UDP).
        if let Some(frame) = got {
            let now = self.now_ms();
            let mut bus = BatchBus::new(&mut *link);
            let handled = self.node.on_frame(&frame, now, &mut bus, &mut self.store);
            let sent = bus.flush();
            match self.transient(handled)? {
                Some(Outcome::Lost) => self.report(Problem::Lost),
                Some(Outcome::Refused(r)) => self.report(Problem::Refused(r)),
                _ => {}
            }
            self.transient(sent)?;
        }
        let now = self.now_ms();
        let mut bus = BatchBus::new(&mut *link);
        let polled = self.node.poll(now, &mut bus);
        let sent = bus.flush();
        self.transient(polled)?;
        self.transient(sent)?;
        if let Some(line) = self.reports.summary(Instant::now()) {
            eprintln!("hil_mock: {line}");
        }
        Ok(())
    }

    /// A send the OS refused (the host's port closed while it restarts, a full buffer) loses one
    /// answer, which the host asks for again: counted, not fatal.
    fn transient<T>(&mut self, r: Result<T, LinkError>) -> Result<Option<T>, LinkError> {
        match r {
            Ok(t) => Ok(Some(t)),
            Err(e @ LinkError::Io { .. }) => {
                self.report(Problem::AnswerLost(e.to_string()));
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    /// Serves until `stop` is set or the link fails.
    pub fn run(&mut self, link: &mut dyn Link, stop: &AtomicBool) -> Result<(), LinkError> {
        while !stop.load(Ordering::Relaxed) {
            self.step(link, POLL_INTERVAL)?;
        }
        Ok(())
    }

    /// One line with the node's counters and the problems, for the end of a session.
    pub fn summary(&self) -> String {
        let s = self.node.stats();
        format!(
            "{} observations ({} late copies not acted on), {} actions, {} feedback applied ({} \
             copies, {} refused), {} stops (watchdog {}, commanded {}), refused messages {} (MAC \
             {}, replayed {}, stale {}), {} lost, {} error reports, {} failed writes; {}",
            s.observations,
            s.stale_observations,
            s.actions,
            s.feedback_applied,
            s.feedback_duplicates,
            s.feedback_refused,
            s.watchdog_stops + s.commanded_stops,
            s.watchdog_stops,
            s.commanded_stops,
            s.refused.total(),
            s.refused.mac,
            s.refused.replayed,
            s.refused.stale,
            s.lost,
            s.errors,
            s.persist_failures,
            self.reports.counts()
        )
    }
}

/// The learner a server starts with when nothing is persisted (the host configures its own).
pub fn fresh_learner() -> Learner {
    Learner::new(ValidLearnerParams::DEFAULT)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::memory::MemoryLink;
    use firmware_core::observation::Observation;
    use protocol::isotp::FrameMode;
    use protocol::link::{Inbox, Received, transmit};
    use protocol::message::{ConfigureMessage, Message, ObservationMessage};
    use protocol::secure::HostSecurity;
    use protocol::stream::Direction;
    use std::sync::Arc;

    const KEY: Key = Key::new([9; 16]);

    /// A batch bus holds what is transmitted until it is flushed, then sends it in order; it
    /// receives from the link at once.
    #[test]
    fn a_batch_bus_sends_on_flush_in_order() {
        let (mut a, mut b) = MemoryLink::pair();
        let id = protocol::can::CanId::standard(0x10).unwrap();
        let frames: Vec<CanFrame> = (0..3u8).map(|i| CanFrame::new(id, &[i]).unwrap()).collect();
        b.send(&frames[2]).unwrap();
        let mut bus = BatchBus::new(&mut a);
        for f in &frames {
            bus.transmit(f).unwrap();
        }
        assert_eq!(bus.receive().unwrap(), Some(frames[2]));
        assert_eq!(
            b.recv(Duration::ZERO).unwrap(),
            None,
            "nothing before the flush"
        );
        bus.flush().unwrap();
        bus.flush().unwrap();
        for f in &frames {
            assert_eq!(b.recv(Duration::from_secs(1)).unwrap(), Some(*f));
        }
        assert_eq!(
            b.recv(Duration::ZERO).unwrap(),
            None,
            "each frame sent once"
        );
    }

    #[test]
    fn a_server_thread_answers_observations_over_a_memory_link() {
        let (mut host, mut car) = MemoryLink::pair();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let handle = std::thread::spawn(move || {
            let mut server = Server::in_memory(
                CarConfig {
                    mode: FrameMode::Fd,
                    ..CarConfig::default()
                },
                &KEY,
                5,
            );
            server.run(&mut car, &flag).map(|()| server.node().stats())
        });
        let mut sec = HostSecurity::assume_fresh_car(&KEY, 5);
        let mut inbox = Inbox::new(Direction::CarToHost);
        let mut exchange = |msg: &Message, want: &dyn Fn(&Message) -> bool| {
            transmit(
                &mut LinkBus(&mut host),
                msg,
                Direction::HostToCar,
                FrameMode::Fd,
                &mut sec,
            )
            .unwrap();
            loop {
                let f = host
                    .recv(Duration::from_secs(10))
                    .unwrap()
                    .expect("an answer");
                if let Received::Message(m) = inbox.feed(&f, 0, &mut sec)
                    && want(&m)
                {
                    break m;
                }
            }
        };
        let configure = Message::Configure(ConfigureMessage {
            session: 1,
            snapshot: fresh_learner().snapshot(),
        });
        exchange(&configure, &|m| matches!(m, Message::Weights(_)));
        for tick in 0..3 {
            let obs = Message::Observation(ObservationMessage {
                tick,
                observation: Observation::open_space(),
            });
            let answer = exchange(&obs, &|m| matches!(m, Message::Action(_)));
            assert!(matches!(answer, Message::Action(a) if a.tick == tick));
        }
        stop.store(true, Ordering::Relaxed);
        let stats = handle.join().unwrap().unwrap();
        assert_eq!((stats.observations, stats.actions), (3, 3));
    }

    /// One line per session start and stop, and no line for the stop a configuration implies.
    #[test]
    fn a_session_s_start_and_the_car_s_stops_are_one_line_each() {
        let (mut host, mut car) = MemoryLink::pair();
        let config = CarConfig {
            mode: FrameMode::Fd,
            watchdog_ms: 200,
        };
        let mut server = Server::in_memory(config, &KEY, 5);
        let mut sec = HostSecurity::assume_fresh_car(&KEY, 5);
        let mut send_and_serve = |server: &mut Server, msg: Option<&Message>| {
            if let Some(m) = msg {
                transmit(
                    &mut LinkBus(&mut host),
                    m,
                    Direction::HostToCar,
                    FrameMode::Fd,
                    &mut sec,
                )
                .unwrap();
            }
            let before = server.watched();
            for _ in 0..5 {
                server.handle(&mut car, Duration::from_millis(2)).unwrap();
            }
            server.events(before)
        };
        let configure = |session| {
            Message::Configure(ConfigureMessage {
                session,
                snapshot: fresh_learner().snapshot(),
            })
        };
        assert_eq!(
            send_and_serve(&mut server, Some(&configure(1))),
            ["session 1 started: the host configured a learner (averaged-ogd, 0 steps in)"]
        );
        assert_eq!(
            send_and_serve(&mut server, Some(&configure(1))),
            Vec::<String>::new(),
            "a copy starts nothing"
        );
        let obs = Message::Observation(ObservationMessage {
            tick: 0,
            observation: Observation::open_space(),
        });
        assert_eq!(
            send_and_serve(&mut server, Some(&obs)),
            Vec::<String>::new()
        );
        std::thread::sleep(Duration::from_millis(300));
        assert_eq!(
            send_and_serve(&mut server, None),
            ["stopped: the watchdog (no observation for 200 ms)"]
        );
        assert_eq!(
            send_and_serve(&mut server, Some(&Message::Reset)),
            ["stopped: the host reset the car"]
        );
        assert_eq!(
            send_and_serve(&mut server, Some(&configure(2))),
            ["session 2 started: the host configured a learner (averaged-ogd, 0 steps in)"]
        );
    }

    #[test]
    fn start_states_say_where_the_learner_came_from() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("car.flash");
        let open = |p: &Path| Server::with_flash(CarConfig::default(), p, Open::Existing, &KEY, 1);
        let (_, s) = open(&path).unwrap();
        assert!(matches!(s, StartState::Fresh { .. }));
        let mut store = FlashStore::open(&path, Open::Existing).unwrap().0;
        let state = CarNode::new(CarConfig::default(), fresh_learner()).persisted();
        store.save(&state).unwrap();
        store.save(&state).unwrap();
        drop(store);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[crate::flash::HEADER_SIZE + crate::flash::PAGE_SIZE + 20] ^= 0xFF;
        std::fs::write(&path, &bytes).unwrap();
        let (server, s) = open(&path).unwrap();
        assert_eq!(
            s.to_string(),
            "restored write 1 from page 0 (page 0 good (write 1), page 1 corrupt); \
             fell back from corrupt page 1"
        );
        assert_eq!(server.node().persisted(), state);
        // Not an image: refused.
        std::fs::write(&path, b"important notes").unwrap();
        assert!(open(&path).is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"important notes");
    }

    #[test]
    fn reports_are_rate_limited() {
        let t0 = Instant::now();
        let mut r = Reports::new(t0);
        let mut lines = 0;
        for i in 0..20_000 {
            let p = if i % 2 == 0 {
                Problem::Malformed(format!("packet {i}"))
            } else {
                Problem::Refused(Refusal::Mac)
            };
            lines += r.note(&p).is_some() as u32;
            lines += r.summary(t0 + Duration::from_millis(i)).is_some() as u32;
        }
        // Five in full, then one summary at 10 s.
        assert_eq!(lines, FIRST_LINES + 1);
        assert_eq!(r.counts().malformed, 10_000);
        assert_eq!(r.counts().refused_mac, 10_000);
        // The rest at the next summary; then nothing new, nothing written.
        assert!(r.summary(t0 + Duration::from_secs(30)).is_some());
        assert_eq!(r.summary(t0 + Duration::from_secs(60)), None, "nothing new");
        r.note(&Problem::Lost);
        let line = r.summary(t0 + Duration::from_secs(70)).unwrap();
        assert!(line.contains("1 messages lost"), "{line}");
    }
}
