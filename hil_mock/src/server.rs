//! The car's controller over a [`Link`]: a [`CarNode`], its flash, and the poll loop.
//!
//! [`Server`] owns the node and the store; [`Server::run`] receives frames with a short timeout,
//! hands each to [`CarNode::on_frame`] and calls [`CarNode::poll`] between them (watchdog,
//! reassembly timeouts), until asked to stop or the link fails. The clock is the milliseconds
//! since the server started.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use firmware_core::{Learner, ValidLearnerParams};
use protocol::can::{CanBus, CanFrame};
use protocol::car::{CarConfig, CarNode, Persist, Persisted};

use crate::flash::{FlashError, FlashStore, PageStatus};
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
        /// Its generation.
        generation: u32,
        /// What each page held (the other may be corrupt: a fallback).
        pages: [PageStatus; 2],
    },
}

impl std::fmt::Display for StartState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let describe = |p: &PageStatus| match p {
            PageStatus::Empty => "empty".to_string(),
            PageStatus::Good(g) => format!("good (generation {g})"),
            PageStatus::Corrupt => "corrupt".to_string(),
        };
        match self {
            StartState::NoFlash => f.write_str("no flash file: fresh learner, nothing persisted"),
            StartState::Fresh { pages } => write!(
                f,
                "flash holds no good page (page 0 {}, page 1 {}): fresh learner",
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
                    "restored generation {generation} from page {page} (page 0 {}, page 1 {})",
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

/// The car's controller: node, store, clock.
#[derive(Debug)]
pub struct Server {
    node: CarNode,
    store: Store,
    start: Instant,
}

/// How long one receive waits before the server polls the node again.
pub const POLL_INTERVAL: Duration = Duration::from_millis(2);

impl Server {
    /// A server with a fresh default learner persisting in RAM.
    pub fn in_memory(config: CarConfig) -> Self {
        Self {
            node: CarNode::new(config, fresh_learner()),
            store: Store::Memory(None),
            start: Instant::now(),
        }
    }

    /// A server persisting to the flash file at `path`, restored from it when it holds a good
    /// page.
    pub fn with_flash(config: CarConfig, path: &Path) -> Result<(Self, StartState), FlashError> {
        let (store, restored) = FlashStore::open(path)?;
        let pages = store.pages();
        let (node, state) = match restored {
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
        let server = Self {
            node,
            store: Store::Flash(store),
            start: Instant::now(),
        };
        Ok((server, state))
    }

    /// The node.
    pub fn node(&self) -> &CarNode {
        &self.node
    }

    /// Milliseconds since the server started (wrapping).
    fn now_ms(&self) -> u32 {
        self.start.elapsed().as_millis() as u32
    }

    /// Waits up to `timeout` for one frame and handles it, then polls the node. Malformed input
    /// is reported on stderr and skipped; other link failures are returned.
    pub fn step(&mut self, link: &mut dyn Link, timeout: Duration) -> Result<(), LinkError> {
        let got = match link.recv(timeout) {
            Ok(f) => f,
            Err(e @ LinkError::Malformed { .. }) => {
                eprintln!("hil_mock: skipped: {e}");
                None
            }
            Err(e) => return Err(e),
        };
        let mut bus = LinkBus(link);
        if let Some(frame) = got {
            let now = self.now_ms();
            let sent = self.node.on_frame(&frame, now, &mut bus, &mut self.store);
            transient(sent)?;
        }
        let now = self.now_ms();
        transient(self.node.poll(now, &mut bus))
    }

    /// Serves until `stop` is set or the link fails.
    pub fn run(&mut self, link: &mut dyn Link, stop: &AtomicBool) -> Result<(), LinkError> {
        while !stop.load(Ordering::Relaxed) {
            self.step(link, POLL_INTERVAL)?;
        }
        Ok(())
    }
}

/// A send the OS refused (the host's port closed while it restarts, a full buffer) loses one
/// answer, which the host asks for again: reported, not fatal.
fn transient(r: Result<(), LinkError>) -> Result<(), LinkError> {
    match r {
        Err(e @ LinkError::Io { .. }) => {
            eprintln!("hil_mock: an answer was lost: {e}");
            Ok(())
        }
        other => other,
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
    use protocol::message::{Message, ObservationMessage};
    use protocol::stream::Direction;
    use std::sync::Arc;

    #[test]
    fn a_server_thread_answers_observations_over_a_memory_link() {
        let (mut host, mut car) = MemoryLink::pair();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let handle = std::thread::spawn(move || {
            let mut server = Server::in_memory(CarConfig {
                mode: FrameMode::Fd,
                ..CarConfig::default()
            });
            server.run(&mut car, &flag).map(|()| server.node().stats())
        });
        let mut inbox = Inbox::new(Direction::CarToHost);
        for tick in 0..3 {
            let obs = Message::Observation(ObservationMessage {
                tick,
                observation: Observation::open_space(),
            });
            transmit(
                &mut LinkBus(&mut host),
                &obs,
                Direction::HostToCar,
                FrameMode::Fd,
            )
            .unwrap();
            let answer = loop {
                let f = host
                    .recv(Duration::from_secs(10))
                    .unwrap()
                    .expect("an answer");
                if let Received::Message(m) = inbox.feed(&f, 0) {
                    break m;
                }
            };
            assert!(matches!(answer, Message::Action(a) if a.tick == tick));
        }
        stop.store(true, Ordering::Relaxed);
        let stats = handle.join().unwrap().unwrap();
        assert_eq!((stats.observations, stats.actions), (3, 3));
    }

    #[test]
    fn start_states_say_where_the_learner_came_from() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("car.flash");
        let (_, s) = Server::with_flash(CarConfig::default(), &path).unwrap();
        assert!(matches!(s, StartState::Fresh { .. }));
        let mut store = FlashStore::open(&path).unwrap().0;
        let state = CarNode::new(CarConfig::default(), fresh_learner()).persisted();
        store.save(&state).unwrap();
        store.save(&state).unwrap();
        drop(store);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[crate::flash::PAGE_SIZE + 20] ^= 0xFF;
        std::fs::write(&path, &bytes).unwrap();
        let (server, s) = Server::with_flash(CarConfig::default(), &path).unwrap();
        assert_eq!(
            s.to_string(),
            "restored generation 1 from page 0 (page 0 good (generation 1), page 1 corrupt); \
             fell back from corrupt page 1"
        );
        assert_eq!(server.node().persisted(), state);
    }
}
