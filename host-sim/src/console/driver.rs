//! The session's own thread: it owns the [`Session`] (and the learner's link, which blocks), runs
//! the ticks at 10 Hz times the speed, takes the page's commands, writes the session's files and
//! publishes the state for every page.

use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tokio::sync::watch;

use super::wire::{self, Command, Notice, Pace, SPEEDS};
use crate::teach::session::{Session, SessionAbout, SessionFiles, TeachError};
use crate::world::sim::TICK_SECONDS;

/// Ticks between two writes of `steps.csv` and `summary.json` while running.
pub const CHECKPOINT_TICKS: u32 = 300;

/// What reaches the session's thread.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Control {
    /// A page's command.
    Command(Command),
    /// Ctrl-C: end the session as the person's finish would.
    Interrupt,
}

/// Where the car has been, for pages that connect late: `[x, y]` points, `None` where the car
/// was put back at the start.
pub type Trace = Arc<Mutex<Vec<Option<[f64; 2]>>>>;

/// How the session ended.
#[derive(Debug)]
pub struct Outcome {
    /// Ticks driven.
    pub ticks: usize,
    /// Feedback that reached the learner.
    pub corrections: u32,
    /// Why it ended.
    pub ended_by: String,
    /// Whether it ended because the learner's link failed.
    pub failed: bool,
    /// Whether the files were written completely; the error if not.
    pub written: anyhow::Result<()>,
}

/// The session's thread: see the module documentation.
pub struct Driver {
    session: Session,
    files: SessionFiles,
    about: SessionAbout,
    started: Instant,
    pace: Pace,
    notice: Option<Notice>,
    notices: u64,
    last_checkpoint: u32,
    failed: bool,
    written: anyhow::Result<()>,
    state: watch::Sender<Arc<str>>,
    trace: Trace,
}

impl std::fmt::Debug for Driver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Driver")
            .field("session", &self.session)
            .field("pace", &self.pace)
            .finish()
    }
}

impl Driver {
    /// A driver of `session`, paused at 1×, writing into `files`.
    pub fn new(
        session: Session,
        files: SessionFiles,
        about: SessionAbout,
        state: watch::Sender<Arc<str>>,
        trace: Trace,
    ) -> Self {
        let pose = session.view().pose;
        if let Ok(mut t) = trace.lock() {
            t.push(Some([pose.x, pose.y]));
        }
        let dir = files.dir().display().to_string();
        let mut d = Self {
            session,
            files,
            about,
            started: Instant::now(),
            pace: Pace {
                running: false,
                speed: 1.0,
                dir,
                ..Pace::default()
            },
            notice: None,
            notices: 0,
            last_checkpoint: 0,
            failed: false,
            written: Ok(()),
            state,
            trace,
        };
        d.checkpoint();
        d.publish();
        d
    }

    /// Runs until the person finishes, Ctrl-C, the tick limit or a link failure; every change
    /// is published. The files are written last.
    pub fn run(mut self, controls: Receiver<Control>) -> Outcome {
        let mut due = Instant::now();
        while !self.pace.finished {
            let control = if self.pace.running {
                let now = Instant::now();
                if due <= now {
                    None
                } else {
                    match controls.recv_timeout(due - now) {
                        Ok(c) => Some(c),
                        Err(RecvTimeoutError::Timeout) => None,
                        Err(RecvTimeoutError::Disconnected) => Some(Control::Interrupt),
                    }
                }
            } else {
                Some(controls.recv().unwrap_or(Control::Interrupt))
            };
            match control {
                None => {
                    self.advance();
                    let period = Duration::from_secs_f64(TICK_SECONDS / self.pace.speed as f64);
                    // Late (a slow link, a busy machine): go on from now, no burst of ticks.
                    due = (due + period).max(Instant::now());
                }
                Some(Control::Interrupt) => self.finish("interrupted (Ctrl-C)".into()),
                Some(Control::Command(c)) => {
                    if matches!(c, Command::Play) && !self.pace.running {
                        due = Instant::now();
                    }
                    self.command(c);
                }
            }
            self.publish();
        }
        Outcome {
            ticks: self.session.records().len(),
            corrections: self.session.corrections(),
            ended_by: self.pace.ended_by.clone().unwrap_or_default(),
            failed: self.failed,
            written: self.written,
        }
    }

    fn command(&mut self, c: Command) {
        match c {
            Command::Play => {
                if self.session.is_done() {
                    self.say("info", "the session ran its ticks: finish it".into());
                } else {
                    self.pace.running = true;
                    self.pace.estopped = false;
                }
            }
            Command::Pause => {
                self.pace.running = false;
                self.checkpoint();
            }
            Command::Step => {
                self.pace.running = false;
                self.advance();
                self.checkpoint();
            }
            Command::Speed { value } => {
                if SPEEDS.contains(&value) {
                    self.pace.speed = value;
                } else {
                    self.say(
                        "warn",
                        format!("speed {value} refused: one of {SPEEDS:?} times 10 Hz"),
                    );
                }
            }
            Command::Teach { tick, teaching } => {
                let wall_ms = self.started.elapsed().as_millis() as u64;
                match self.session.teach(tick, teaching, wall_ms) {
                    Ok(effect) => {
                        if effect.stop {
                            self.pace.running = false;
                            self.pace.estopped = true;
                            self.say(
                                "warn",
                                format!(
                                    "E-stop at tick {}: the car stopped; play to go on",
                                    self.session.tick()
                                ),
                            );
                            self.checkpoint();
                        } else {
                            self.append();
                        }
                    }
                    Err(e) if e.is_refusal() => self.say("warn", e.to_string()),
                    Err(e) => self.fail(&e),
                }
            }
            Command::Finish => self.finish("the person finished it".into()),
        }
    }

    /// One tick, if the session may go on.
    fn advance(&mut self) {
        if self.session.is_done() {
            self.pace.running = false;
            return;
        }
        match self.session.step() {
            Ok(r) => {
                let reset = r.reset.is_some();
                let pose = self.session.view().pose;
                if let Ok(mut t) = self.trace.lock() {
                    if reset {
                        t.push(None);
                    }
                    t.push(Some([pose.x, pose.y]));
                }
                if self.session.tick() >= self.last_checkpoint + CHECKPOINT_TICKS {
                    self.checkpoint();
                }
                if self.session.is_done() {
                    self.finish(format!("it ran its {} ticks", self.session.config().steps));
                }
            }
            Err(e) => self.fail(&TeachError::Link(e)),
        }
    }

    fn fail(&mut self, e: &TeachError) {
        self.failed = true;
        self.finish(format!("the learner's link failed: {e:#}"));
    }

    fn finish(&mut self, why: String) {
        self.pace.running = false;
        self.pace.finished = true;
        self.pace.ended_by = Some(why.clone());
        self.about.finished = true;
        self.about.ended_by = Some(why.clone());
        self.checkpoint();
        let level = if self.failed { "error" } else { "info" };
        let written = match &self.written {
            Ok(()) => format!("written to {}", self.pace.dir),
            Err(e) => format!("could not be written completely: {e:#}"),
        };
        self.say(level, format!("session ended ({why}); {written}"));
    }

    /// Appends the new teachings; a failure to write is said and kept for the end.
    fn append(&mut self) {
        if let Err(e) = self.files.append(&self.session) {
            self.say("error", format!("{e:#}"));
            self.written = Err(e);
        }
    }

    fn checkpoint(&mut self) {
        self.about.wall_time_s = self.started.elapsed().as_secs_f64();
        self.last_checkpoint = self.session.tick();
        if let Err(e) = self.files.checkpoint(&self.session, &self.about) {
            self.say("error", format!("{e:#}"));
            self.written = Err(e);
        }
    }

    fn say(&mut self, level: &'static str, text: String) {
        self.notices += 1;
        self.notice = Some(Notice {
            seq: self.notices,
            level,
            text,
        });
    }

    fn publish(&self) {
        let state = wire::state(&self.session, &self.pace, self.notice.as_ref());
        self.state.send_replace(Arc::from(state.to_string()));
    }
}
