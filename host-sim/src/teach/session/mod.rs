//! A person teaching: the session behind `host-sim teach`, its files, and its replay.
//!
//! A [`Session`] is the loop of [`crate::teach::experiment`] with the programmatic teacher's
//! feedback replaced by a person's ([`Teaching`]), which arrives whenever the person acts rather
//! than once per tick. It advances only when told ([`Session::step`]); the console decides when
//! (10 Hz times the chosen speed, paused, single steps). Nothing here reads a clock: the wall
//! time of each teaching is given by the caller and only recorded.
//!
//! # Ticks
//!
//! The session is always *at* a tick `t`: the world was sensed and the learner chose its
//! trajectory for `t`, which is not driven yet. A teaching names the tick it is about, `t` or one
//! of the [`TICK_HISTORY`]` − 1` ticks before it that had a choice (the ticks the learner, in
//! process or on the car, still remembers: a page at 8× shows a tick a little after the session
//! left it); it is judged against that tick's round and applied at once, *during* tick `t`.
//! [`Session::step`] then drives `t`'s trajectory, records the tick, and senses and decides
//! `t + 1`. The E-stop is always about the current tick.
//!
//! The record of tick `t` (a `steps.csv` row, the same columns as `host-sim run`) says whether
//! feedback reached the learner during `t` (`corrected`; the feedback may be about a tick
//! before), and `corrections` counts every feedback that reached it so far (an E-stop is one:
//! the intervention, about the current tick, unless that tick had no choice to judge). `latent_loss` and `teacher_action` are the scenario's
//! programmatic teacher's view of the tick, as in `run`: the person can compare themselves with
//! it, the learner never sees it.
//!
//! # Files ([`SessionFiles`])
//!
//! | file | what |
//! |---|---|
//! | `steps.csv` | one row per tick driven, as `host-sim run` writes it |
//! | `summary.json` | as `host-sim run` writes it (`config.feedback` is `person`), plus `session`: what replaying needs (the scenario as given, the seed, the learner's parameters, the ticks) and what happened (teachings by kind, E-stops, the link) |
//! | `feedback.jsonl` | one line per teaching that was taken: `tick` (what it is about), `applied` (the tick the session was at), `kind`, `content` (see [`Teaching`]), `wall_time_ms` (milliseconds since the session started) |
//! | `snapshots.jsonl` | the learner's snapshot after every feedback: `tick`, `applied`, `snapshot` |
//! | `candump.log` | with a link: every CAN frame, candump format |
//!
//! `feedback.jsonl` and `snapshots.jsonl` are appended and flushed as the person teaches;
//! `steps.csv` and `summary.json` are written (each whole, through a temporary file) whenever
//! the console pauses, every few hundred ticks, and when the session ends.
//!
//! # Replay ([`replay`])
//!
//! `host-sim replay-session DIR` runs a fresh learner in this process through the same ticks,
//! applying each line of `feedback.jsonl` at its `applied` tick, and checks that `steps.csv`,
//! `snapshots.jsonl` and the final weights come out byte for byte the same. Wall time is data,
//! not input: the replay keys on ticks only.

use anyhow::{Result, bail, ensure};
use firmware_core::agent::{Decision, TICK_HISTORY};
use firmware_core::{ActionIndex, LearnerSnapshot, policy};
use serde::{Deserialize, Serialize};

use super::config::{Mode, RunConfig};
use super::experiment::{CarLink, InProcessLink, learner_with};
use super::person::{Effect, Teaching, TeachingError, TickRound};
use super::record::{RunReport, StepRecord};
use super::remote::{RemoteCar, RemoteStats};
use crate::world::car::Pose;
use crate::world::sim::{Episode, ResetReason};
use crate::world::teacher::{FeedbackKind, Judgement, Teacher};

mod files;
mod replay;

pub use files::{SessionAbout, SessionFiles, names};
pub use replay::{Recorded, Replayed, replay};

/// Version of the session files' layout (`summary.json`'s `session.format`). 2: the E-stop
/// teaches (the intervention feedback, issue 15), where in 1 it taught nothing, so a format-1
/// session with an E-stop would replay differently and is refused; reward, correctness and
/// span teachings are new.
pub const SESSION_FORMAT: u32 = 2;

/// The learner's link as a session sees it: a [`CarLink`] that may say how the link is doing.
pub trait SessionLink: CarLink + Send {
    /// The link's state, `None` in process.
    fn link_state(&self) -> Option<LinkState> {
        None
    }
}

impl SessionLink for InProcessLink {}

impl<L: hil_mock::transport::Link + Send> SessionLink for RemoteCar<L> {
    fn link_state(&self) -> Option<LinkState> {
        Some(LinkState {
            address: self.link().describe(),
            connected: self.session().is_some(),
            stats: self.stats(),
        })
    }
}

/// How a link to the car is doing.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkState {
    /// The link, as its transport describes it.
    pub address: String,
    /// Whether the car took the host's configuration (its session is open).
    pub connected: bool,
    /// Retransmissions, stops, restarts, refusals so far.
    pub stats: RemoteStats,
}

/// One line of `feedback.jsonl`: a teaching that was taken.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// The tick it is about.
    pub tick: u32,
    /// The tick the session was at when it was applied.
    pub applied: u32,
    /// What the person did.
    #[serde(flatten)]
    pub teaching: Teaching,
    /// Milliseconds since the session started (data, not input: the replay ignores it).
    pub wall_time_ms: u64,
}

/// One line of `snapshots.jsonl`: the learner after a feedback.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SnapshotEntry {
    /// The tick the feedback was about.
    pub tick: u32,
    /// The tick the session was at.
    pub applied: u32,
    /// The learner after it.
    pub snapshot: LearnerSnapshot,
}

/// Why a teaching was not taken.
#[derive(Debug, thiserror::Error)]
pub enum TeachError {
    /// The person's teaching does not fit the tick; nothing reached the learner.
    #[error("tick {tick}: {reason}")]
    Refused {
        /// The tick it was about.
        tick: u32,
        /// Why.
        reason: TeachingError,
    },
    /// The tick is no longer remembered, or had no choice.
    #[error(
        "tick {tick} is gone: the learner remembers the last {TICK_HISTORY} ticks that had a \
         choice and the session is at tick {current} (pause to teach at leisure)"
    )]
    Gone {
        /// The tick it was about.
        tick: u32,
        /// The session's tick.
        current: u32,
    },
    /// A tick the session has not reached.
    #[error("tick {tick} has not happened: the session is at tick {current}")]
    Future {
        /// The tick it was about.
        tick: u32,
        /// The session's tick.
        current: u32,
    },
    /// The learner could not be reached or refused: the session cannot go on.
    #[error(transparent)]
    Link(#[from] anyhow::Error),
}

impl TeachError {
    /// Whether the session can go on (everything but a link failure).
    pub fn is_refusal(&self) -> bool {
        !matches!(self, TeachError::Link(_))
    }
}

/// The tick the session is at: sensed and decided, not driven.
#[derive(Clone, Debug)]
pub struct TickView {
    /// The tick.
    pub tick: u32,
    /// The car's pose, where the learner chose.
    pub pose: Pose,
    /// The learner's decision.
    pub decision: Decision,
    /// The scenario's programmatic teacher's view of the tick (features, latent losses).
    pub judgement: Judgement,
}

/// A person teaching a learner in a household, one tick at a time. See the module documentation.
pub struct Session {
    config: RunConfig,
    link: Box<dyn SessionLink>,
    episode: Episode,
    teacher: Teacher,
    current: TickView,
    /// The last ticks that had a choice (current included when it has one), oldest first: the
    /// ticks the learner still remembers.
    recent: Vec<(u32, TickRound)>,
    records: Vec<StepRecord>,
    corrections: u32,
    corrected_now: bool,
    /// The kind of the last feedback that reached the learner during the current tick, and the
    /// effort of all of it ([`super::kinds::effort`], the stated guesses `run` records too).
    given_now: Option<FeedbackKind>,
    effort_now: f32,
    resets: [u32; 4],
    entries: Vec<Entry>,
    snapshots: Vec<SnapshotEntry>,
    snapshot: LearnerSnapshot,
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("scenario", &self.config.scenario.name)
            .field("tick", &self.current.tick)
            .field("corrections", &self.corrections)
            .field("entries", &self.entries.len())
            .finish()
    }
}

impl Session {
    /// Starts a session of `config` (its scenario, seed, learner and teacher; `steps` is the most
    /// ticks it may run) with the learner behind `link`: configures the learner and decides tick 0.
    pub fn start(config: RunConfig, mut link: Box<dyn SessionLink>) -> Result<Self> {
        config.check()?;
        let initial = learner_with(config.learner, config.learner.initial)?;
        link.restore(&initial)?;
        let mut teacher = Teacher::new(config.teacher(), config.seed);
        let episode = Episode::starting_at(config.scenario.clone(), config.start_pose());
        let current = sense(&mut *link, &mut teacher, &episode, 0)?;
        let mut s = Self {
            config,
            link,
            episode,
            teacher,
            current,
            recent: Vec::new(),
            records: Vec::new(),
            corrections: 0,
            corrected_now: false,
            given_now: None,
            effort_now: 0.0,
            resets: [0; 4],
            entries: Vec::new(),
            snapshots: Vec::new(),
            snapshot: initial,
        };
        s.remember();
        Ok(s)
    }

    /// Senses the world and lets the learner decide `tick`.
    fn decide(&mut self, tick: u32) -> Result<()> {
        self.current = sense(&mut *self.link, &mut self.teacher, &self.episode, tick)?;
        self.remember();
        Ok(())
    }

    /// Remembers the current tick's round if it had a choice (the learner does the same).
    fn remember(&mut self) {
        let d = self.current.decision;
        if d.action.is_some() {
            self.recent.push((
                d.tick,
                TickRound {
                    allowed: d.allowed,
                    chosen: d.action,
                },
            ));
            if self.recent.len() > TICK_HISTORY {
                self.recent.remove(0);
            }
        }
    }

    /// The configuration.
    pub fn config(&self) -> &RunConfig {
        &self.config
    }

    /// The tick the session is at.
    pub fn tick(&self) -> u32 {
        self.current.tick
    }

    /// The tick the session is at: pose, decision, the teacher's view.
    pub fn view(&self) -> &TickView {
        &self.current
    }

    /// The learner's current snapshot (after the last feedback).
    pub fn snapshot(&self) -> &LearnerSnapshot {
        &self.snapshot
    }

    /// The trajectory the learner would choose in the current tick with its current weights
    /// (its choice in the tick, until feedback changes the weights).
    pub fn choice_now(&self) -> Option<ActionIndex> {
        let j = &self.current.judgement;
        policy::select(&self.snapshot.state.average, j.table(), j.allowed())
    }

    /// The ticks driven so far.
    pub fn records(&self) -> &[StepRecord] {
        &self.records
    }

    /// Feedback that reached the learner so far.
    pub fn corrections(&self) -> u32 {
        self.corrections
    }

    /// Every teaching taken, in order.
    pub fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// The learner's snapshot after every feedback, in order.
    pub fn snapshots(&self) -> &[SnapshotEntry] {
        &self.snapshots
    }

    /// The link's state (`None` in process).
    pub fn link_state(&self) -> Option<LinkState> {
        self.link.link_state()
    }

    /// Whether the session ran the most ticks its configuration allows.
    pub fn is_done(&self) -> bool {
        self.records.len() >= self.config.steps as usize
    }

    /// The round of `tick`, if the learner still remembers it.
    fn round(&self, tick: u32) -> Result<TickRound, TeachError> {
        let current = self.current.tick;
        if tick > current {
            return Err(TeachError::Future { tick, current });
        }
        if tick == current && self.current.decision.action.is_none() {
            return Ok(TickRound {
                allowed: self.current.decision.allowed,
                chosen: None,
            });
        }
        self.recent
            .iter()
            .find(|(t, _)| *t == tick)
            .map(|&(_, r)| r)
            .ok_or(TeachError::Gone { tick, current })
    }

    /// Takes `teaching` about `tick`, given `wall_time_ms` milliseconds into the session
    /// (recorded only). A refusal changes nothing; a link failure ends the session.
    pub fn teach(
        &mut self,
        tick: u32,
        teaching: Teaching,
        wall_time_ms: u64,
    ) -> Result<Effect, TeachError> {
        let current = self.current.tick;
        // The E-stop is about now, whatever the page showed.
        let tick = if matches!(teaching, Teaching::Estop {}) {
            current
        } else {
            tick
        };
        let round = match self.round(tick) {
            Ok(r) => r,
            Err(_) if matches!(teaching, Teaching::Estop {}) => TickRound {
                allowed: self.current.decision.allowed,
                chosen: self.current.decision.action,
            },
            Err(e) => return Err(e),
        };
        let effect = teaching
            .effect(round)
            .map_err(|reason| TeachError::Refused { tick, reason })?;
        if let Some(fb) = &effect.feedback {
            self.link.feedback(tick, fb)?;
            self.corrections += 1;
            self.corrected_now = true;
            self.given_now = Some(fb.kind());
            self.effort_now += super::kinds::effort(fb.kind());
        }
        // Taken: recorded even if the snapshot below fails (the learner has it).
        self.entries.push(Entry {
            tick,
            applied: current,
            teaching,
            wall_time_ms,
        });
        if effect.feedback.is_some() {
            self.snapshot = self.link.snapshot()?;
            self.snapshots.push(SnapshotEntry {
                tick,
                applied: current,
                snapshot: self.snapshot,
            });
        }
        Ok(effect)
    }

    /// Drives the current tick's trajectory, records the tick, and decides the next one.
    pub fn step(&mut self) -> Result<&StepRecord> {
        ensure!(
            !self.is_done(),
            "the session ran its {} ticks",
            self.config.steps
        );
        let TickView {
            tick,
            pose,
            decision,
            ref judgement,
        } = self.current;
        let latent_loss = decision.action.map_or(0.0, |a| judgement.latent_loss(a));
        let teacher_action = judgement.choice;
        let result = self.episode.drive(decision.action);
        match result.reset {
            Some(ResetReason::Collision) => self.resets[0] += 1,
            Some(ResetReason::Stuck) => self.resets[1] += 1,
            Some(ResetReason::Lost) => self.resets[2] += 1,
            Some(ResetReason::Blocked) => self.resets[3] += 1,
            Some(ResetReason::PathEnd) | None => {}
        }
        self.records.push(StepRecord {
            step: tick,
            action: decision.action,
            teacher_action,
            latent_loss,
            corrected: self.corrected_now,
            corrections: self.corrections,
            collision: result.reset == Some(ResetReason::Collision),
            reset: result.reset,
            lap: self.episode.laps(),
            progress: self.episode.path_progress(),
            x: pose.x,
            y: pose.y,
            theta: pose.theta,
            feedback: self.given_now.take(),
            effort: std::mem::take(&mut self.effort_now),
        });
        self.corrected_now = false;
        self.decide(tick + 1)?;
        Ok(self.records.last().expect("a record was just pushed"))
    }

    /// The ticks driven so far as a run's report (its CSV and summary are `run`'s).
    pub fn report(&self) -> RunReport {
        RunReport {
            scenario: self.config.scenario.name.clone(),
            // A person's feedback is of every kind; the summary says `person`.
            mode: Mode::Online(FeedbackKind::Action),
            seed: self.config.seed,
            teacher: self.config.teacher(),
            learner: self.config.learner,
            records: self.records.clone(),
            final_snapshot: self.snapshot,
            bc: None,
            resets: self.resets,
            // A person's feedback is not measured against the programmatic teacher's losses.
            informativeness: Vec::new(),
        }
    }

    /// How many teachings of each kind were taken, by [`Teaching::KINDS`].
    pub fn counts(&self) -> serde_json::Map<String, serde_json::Value> {
        Teaching::KINDS
            .iter()
            .map(|k| {
                let n = self
                    .entries
                    .iter()
                    .filter(|e| e.teaching.kind() == *k)
                    .count();
                (k.to_string(), serde_json::json!(n))
            })
            .collect()
    }

    /// `summary.json`: `run`'s summary with `config.feedback` = `person` and the `session`
    /// section (see the module documentation).
    pub fn summary(&self, about: &SessionAbout) -> serde_json::Value {
        let mut s = self.report().summary();
        s["config"]["feedback"] = serde_json::json!("person");
        s["session"] = serde_json::json!({
            "format": SESSION_FORMAT,
            "scenario": about.scenario,
            "seed": self.config.seed,
            "learner": self.config.learner,
            "max_ticks": self.config.steps,
            "ticks": self.records.len(),
            "at_tick": self.current.tick,
            "teachings": self.counts(),
            "link": about.link,
            "started_unix_s": about.started_unix_s,
            "finished": about.finished,
            "ended_by": about.ended_by,
        });
        s["wall_time_s"] = serde_json::json!(about.wall_time_s);
        s
    }
}

/// Senses the world of `episode` and lets the learner behind `link` and the teacher judge `tick`.
fn sense(
    link: &mut dyn SessionLink,
    teacher: &mut Teacher,
    episode: &Episode,
    tick: u32,
) -> Result<TickView> {
    let obs = episode.observe();
    let pose = episode.car().pose;
    // As `run` does: one evaluation of the observation, the teacher's and (in process) the
    // learner's; a car evaluates on its own.
    let checked = obs
        .check()
        .map_err(|e| anyhow::anyhow!("tick {tick}: observation refused: {e}"))?;
    let judgement = teacher.judge_checked(checked);
    let decision = link.act_evaluated(tick, &obs, &judgement.evaluation)?;
    if decision.allowed != judgement.allowed() {
        bail!("tick {tick}: the learner's and the teacher's collision masks differ");
    }
    Ok(TickView {
        tick,
        pose,
        decision,
        judgement,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::teach::person::Spoken;
    use firmware_core::LearnerParams;
    use std::path::Path;
    use std::sync::Arc;

    fn config(steps: u32) -> RunConfig {
        let scenario = crate::world::registry::load_scenario_unchecked("doors").unwrap();
        RunConfig {
            steps,
            seed: 3,
            learner: LearnerParams::new(firmware_core::LearnerKind::AdaGrad),
            ..RunConfig::new(Arc::new(scenario))
        }
    }

    fn start(steps: u32) -> Session {
        let c = config(steps);
        let link = InProcessLink::new(c.learner).unwrap();
        Session::start(c, Box::new(link)).unwrap()
    }

    /// An allowed trajectory other than the learner's choice in the current tick.
    fn another(s: &Session) -> ActionIndex {
        let d = s.view().decision;
        d.allowed.iter().find(|&a| Some(a) != d.action).unwrap()
    }

    #[test]
    fn without_teaching_a_session_is_the_run_of_a_learner_never_corrected() {
        let mut s = start(60);
        for _ in 0..60 {
            s.step().unwrap();
        }
        assert!(s.is_done());
        assert!(s.step().is_err());
        // The teacher's threshold so high that it never corrects: the same ticks.
        let c = RunConfig {
            threshold: Some(1000.0),
            ..config(60)
        };
        let run = crate::teach::experiment::run(&c).unwrap();
        assert_eq!(run.corrections(), 0);
        assert!(s.report().csv_bytes() == run.csv_bytes());
    }

    #[test]
    fn a_click_teaches_the_learner_and_is_counted_and_recorded() {
        let mut s = start(100);
        s.step().unwrap();
        let before = *s.snapshot();
        let target = another(&s);
        let tick = s.tick();
        let e = s
            .teach(tick, Teaching::Action { action: target }, 1500)
            .unwrap();
        assert!(e.feedback.is_some() && !e.stop);
        assert_ne!(s.snapshot().state, before.state, "the weights moved");
        assert_eq!(s.corrections(), 1);
        assert_eq!(
            s.entries(),
            &[Entry {
                tick,
                applied: tick,
                teaching: Teaching::Action { action: target },
                wall_time_ms: 1500
            }]
        );
        assert_eq!(s.snapshots().len(), 1);
        assert_eq!(s.snapshots()[0].snapshot, *s.snapshot());
        let r = *s.step().unwrap();
        assert!(r.corrected && r.corrections == 1 && r.step == tick);
        assert!(!s.step().unwrap().corrected);
    }

    #[test]
    fn recent_ticks_are_taught_old_and_future_ones_refused_without_a_trace() {
        let mut s = start(100);
        for _ in 0..10 {
            s.step().unwrap();
        }
        let now = s.tick();
        let before = (*s.snapshot(), s.entries().len());
        // The page showed a tick a little before: still remembered.
        let say = Teaching::Statement {
            statement: Spoken::StayOnPath,
        };
        s.teach(now - 2, say, 0).unwrap();
        assert_eq!(s.entries().last().unwrap().tick, now - 2);
        assert_eq!(s.entries().last().unwrap().applied, now);
        let mid = (*s.snapshot(), s.entries().len());
        assert_ne!(mid.1, before.1);
        // Too old, from the future, a collision, the same trajectory twice: refused, no trace.
        let gone = s.teach(now - TICK_HISTORY as u32, say, 0).unwrap_err();
        assert!(matches!(gone, TeachError::Gone { .. }), "{gone}");
        assert!(gone.is_refusal());
        let future = s.teach(now + 1, say, 0).unwrap_err();
        assert!(matches!(future, TeachError::Future { .. }), "{future}");
        let d = s.view().decision;
        if let Some(blocked) = firmware_core::ActionIndex::all().find(|&a| !d.allowed.contains(a)) {
            let e = s
                .teach(now, Teaching::Action { action: blocked }, 0)
                .unwrap_err();
            assert!(matches!(e, TeachError::Refused { .. }), "{e}");
        }
        let chosen = d.action.unwrap();
        let e = s
            .teach(
                now,
                Teaching::Preference {
                    preferred: chosen,
                    other: chosen,
                },
                0,
            )
            .unwrap_err();
        assert!(e.to_string().contains("two different"), "{e}");
        assert_eq!((*s.snapshot(), s.entries().len()), mid);
        assert_eq!(s.corrections(), 1);
    }

    #[test]
    fn the_estop_is_about_now_and_teaches_the_intervention() {
        let mut s = start(100);
        s.step().unwrap();
        let before = *s.snapshot();
        let chosen = s.view().decision.action;
        assert!(chosen.is_some());
        // The page may send any tick: the E-stop is about the current one.
        let e = s.teach(0, Teaching::Estop {}, 2000).unwrap();
        assert!(e.stop);
        assert_eq!(
            e.feedback,
            Some(firmware_core::Feedback::EStop(firmware_core::EStopFeedback))
        );
        assert_eq!(s.entries()[0].tick, s.tick());
        assert_ne!(*s.snapshot(), before);
        assert_eq!(s.corrections(), 1);
        assert_eq!(s.snapshots().len(), 1);
        assert_eq!(s.snapshots()[0].tick, s.tick());
        assert_eq!(s.counts()["estop"], 1);
    }

    #[test]
    fn a_span_teaches_about_the_ticks_the_learner_holds() {
        let mut s = start(100);
        for _ in 0..6 {
            s.step().unwrap();
        }
        let before = *s.snapshot();
        let t = s.tick();
        let span = Teaching::Span {
            ticks: TICK_HISTORY as u8,
            good: false,
        };
        let e = s.teach(t, span, 10).unwrap();
        assert!(matches!(e.feedback, Some(firmware_core::Feedback::Span(_))));
        assert_ne!(*s.snapshot(), before);
        assert_eq!((s.corrections(), s.entries().len()), (1, 1));
        assert_eq!(s.counts()["span"], 1);
        // Too long a span is refused and changes nothing.
        let long = Teaching::Span {
            ticks: firmware_core::MAX_SPAN + 1,
            good: false,
        };
        let e = s.teach(t, long, 20).unwrap_err();
        assert!(e.to_string().contains("a span is 1 to"), "{e}");
        assert_eq!((s.corrections(), s.entries().len()), (1, 1));
    }

    #[test]
    fn a_reward_and_a_mark_reach_the_learner_about_their_tick() {
        let mut s = start(100);
        s.step().unwrap();
        s.step().unwrap();
        let before = *s.snapshot();
        let t = s.tick();
        s.teach(t - 1, Teaching::Reward { hundredths: -100 }, 10)
            .unwrap();
        let after_reward = *s.snapshot();
        assert_ne!(after_reward, before);
        s.teach(t, Teaching::Correctness { correct: false }, 20)
            .unwrap();
        assert_ne!(*s.snapshot(), after_reward);
        assert_eq!(s.corrections(), 2);
        assert_eq!((s.entries()[0].tick, s.entries()[1].tick), (t - 1, t));
        assert_eq!(s.counts()["reward"], 1);
        assert_eq!(s.counts()["correctness"], 1);
        // A reward of 0 is refused and changes nothing.
        let e = s
            .teach(t, Teaching::Reward { hundredths: 0 }, 30)
            .unwrap_err();
        assert!(matches!(e, TeachError::Refused { .. }), "{e}");
        assert_eq!(s.corrections(), 2);
        assert_eq!(s.entries().len(), 2);
    }

    /// The in-process learner, with a snapshot that fails once `broken` is set.
    struct BrokenSnapshot {
        inner: InProcessLink,
        broken: Arc<std::sync::atomic::AtomicBool>,
    }

    impl CarLink for BrokenSnapshot {
        fn restore(&mut self, snapshot: &LearnerSnapshot) -> Result<()> {
            self.inner.restore(snapshot)
        }
        fn act(
            &mut self,
            tick: u32,
            obs: &firmware_core::observation::Observation,
        ) -> Result<Decision> {
            self.inner.act(tick, obs)
        }
        fn feedback(&mut self, tick: u32, feedback: &firmware_core::Feedback) -> Result<()> {
            self.inner.feedback(tick, feedback)
        }
        fn snapshot(&mut self) -> Result<LearnerSnapshot> {
            ensure!(
                !self.broken.load(std::sync::atomic::Ordering::Relaxed),
                "the link went down"
            );
            self.inner.snapshot()
        }
    }

    impl SessionLink for BrokenSnapshot {}

    #[test]
    fn feedback_the_learner_took_is_recorded_even_when_the_snapshot_after_it_fails() {
        let c = config(100);
        let broken = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let link = BrokenSnapshot {
            inner: InProcessLink::new(c.learner).unwrap(),
            broken: broken.clone(),
        };
        let mut s = Session::start(c, Box::new(link)).unwrap();
        s.step().unwrap();
        let target = another(&s);
        let tick = s.tick();
        broken.store(true, std::sync::atomic::Ordering::Relaxed);
        let e = s.teach(tick, Teaching::Action { action: target }, 700);
        assert!(matches!(e, Err(TeachError::Link(_))), "{e:?}");
        // The learner has it: the session's record says so, so that a replay gives it too.
        assert_eq!(s.corrections(), 1);
        assert_eq!(s.entries().len(), 1);
        assert_eq!(s.entries()[0].teaching, Teaching::Action { action: target });
        assert!(s.snapshots().is_empty());
    }

    /// A session with every kind of teaching, written to `dir`.
    fn record(dir: &Path) -> Session {
        let mut files = SessionFiles::create(dir).unwrap();
        let mut s = start(200);
        let about = SessionAbout {
            scenario: "doors".into(),
            started_unix_s: 1,
            ..SessionAbout::default()
        };
        let mut wall = 0;
        for i in 0..120u32 {
            wall += 100;
            let now = s.tick();
            let d = s.view().decision;
            let chosen = d.action;
            // An allowed trajectory other than the learner's, if there is one.
            let other = d.allowed.iter().find(|&a| Some(a) != chosen);
            let t = match (i % 20, other, chosen) {
                (3, Some(other), _) => Some((now, Teaching::Action { action: other })),
                (7, Some(other), Some(chosen)) => Some((
                    now,
                    Teaching::Preference {
                        preferred: other,
                        other: chosen,
                    },
                )),
                (11, _, _) => Some((
                    now.saturating_sub(1),
                    Teaching::Statement {
                        statement: Spoken::ALL[(i as usize / 20) % Spoken::ALL.len()],
                    },
                )),
                (13, _, _) => Some((now, Teaching::Estop {})),
                (15, _, _) => Some((
                    now.saturating_sub(1),
                    Teaching::Reward {
                        hundredths: [-100, -50, 50, 100][(i as usize / 20) % 4],
                    },
                )),
                (17, _, _) => Some((
                    now,
                    Teaching::Correctness {
                        correct: i % 40 == 17,
                    },
                )),
                (19, _, _) => Some((
                    now,
                    Teaching::Span {
                        ticks: TICK_HISTORY as u8 + 2,
                        good: i % 40 == 19,
                    },
                )),
                _ => None,
            };
            if let Some((tick, t)) = t {
                s.teach(tick, t, wall).unwrap();
                // Two in one tick, now and then.
                if i % 40 == 3 {
                    s.teach(
                        now,
                        Teaching::Statement {
                            statement: Spoken::AvoidDoors,
                        },
                        wall,
                    )
                    .unwrap();
                }
            }
            if i % 50 == 0 {
                files.checkpoint(&s, &about).unwrap();
            }
            s.step().unwrap();
        }
        // Feedback at the last tick, which is decided but never driven.
        let other = another(&s);
        s.teach(s.tick(), Teaching::Action { action: other }, wall)
            .unwrap();
        files
            .checkpoint(
                &s,
                &SessionAbout {
                    finished: true,
                    ..about
                },
            )
            .unwrap();
        s
    }

    #[test]
    fn a_recorded_session_replays_byte_for_byte() {
        let tmp = tempfile::tempdir().unwrap();
        let s = record(tmp.path());
        assert!(s.counts().values().all(|n| n.as_u64().unwrap() > 0));
        let rec = Recorded::read(tmp.path()).unwrap();
        assert_eq!(rec.entries, s.entries());
        assert_eq!(rec.ticks, 120);
        let summary = &rec.summary;
        assert_eq!(summary["config"]["feedback"], "person");
        assert_eq!(summary["session"]["teachings"]["estop"], 6);
        // `run`'s totals count the ticks driven; the click in the last tick, decided but not
        // driven, is in the session's counts and the final weights.
        assert_eq!(summary["corrections"], s.corrections() - 1);
        assert_eq!(summary["session"]["teachings"]["action"], 7);
        let r = replay(&rec, config(1)).unwrap();
        assert!(r.differences.is_empty(), "{:?}", r.differences);
        assert!(r.steps_csv == rec.steps_csv);
        assert_eq!(r.session.snapshot(), s.snapshot());
        // The wall time is not input: other times replay the same.
        let mut later = rec.clone();
        for e in &mut later.entries {
            e.wall_time_ms = e.wall_time_ms * 3 + 1;
        }
        assert!(replay(&later, config(1)).unwrap().differences.is_empty());
    }

    #[test]
    fn a_changed_recording_is_caught() {
        let tmp = tempfile::tempdir().unwrap();
        record(tmp.path());
        let rec = Recorded::read(tmp.path()).unwrap();
        // One click a tick later (alone in its tick, with room before the next): the weights
        // after it differ.
        let mut moved = rec.clone();
        let i = (0..moved.entries.len() - 1)
            .find(|&i| {
                let (e, next) = (&moved.entries[i], &moved.entries[i + 1]);
                e.teaching.kind() == "action"
                    && next.applied > e.applied + 1
                    && (i == 0 || moved.entries[i - 1].applied < e.applied)
            })
            .unwrap();
        moved.entries[i].applied += 1;
        moved.entries[i].tick += 1;
        caught(replay(&moved, config(1)));
        // The last teaching dropped: only the final weights and the snapshots differ.
        let mut dropped = rec.clone();
        dropped.entries.pop();
        let r = replay(&dropped, config(1)).unwrap();
        assert!(
            r.differences.iter().any(|d| d.contains(names::SNAPSHOTS))
                && r.differences.iter().any(|d| d.contains("final_weights")),
            "{:?}",
            r.differences
        );
        // Another learner.
        caught(replay(
            &Recorded {
                learner: LearnerParams::new(firmware_core::LearnerKind::Ogd),
                ..rec.clone()
            },
            config(1),
        ));
    }

    /// A replay that differs, or in which a teaching no longer fits its tick (the car went
    /// elsewhere).
    fn caught(r: Result<Replayed>) {
        match r {
            Ok(r) => assert!(!r.differences.is_empty()),
            Err(e) => assert!(e.to_string().contains("replaying"), "{e}"),
        }
    }

    #[test]
    fn a_folder_with_a_session_is_not_overwritten_and_bad_files_are_named() {
        let tmp = tempfile::tempdir().unwrap();
        record(tmp.path());
        let e = SessionFiles::create(tmp.path()).unwrap_err().to_string();
        assert!(e.contains("holds a session already"), "{e}");
        let feedback = tmp.path().join(names::FEEDBACK);
        let mut text = std::fs::read_to_string(&feedback).unwrap();
        text.push_str("{\"tick\":1,\"applied\":1,\"kind\":\"action\",\"content\":{\"action\":99},\"wall_time_ms\":0}\n");
        std::fs::write(&feedback, text).unwrap();
        let e = format!("{:#}", Recorded::read(tmp.path()).unwrap_err());
        assert!(e.contains("feedback.jsonl line"), "{e}");
        let e = format!(
            "{:#}",
            Recorded::read(&tmp.path().join("nowhere")).unwrap_err()
        );
        assert!(e.contains("cannot read"), "{e}");
    }

    #[test]
    fn a_session_of_format_1_is_refused_naming_both_formats() {
        // Format 1's E-stop taught nothing; replaying it with this build's would not be the
        // same session.
        let tmp = tempfile::tempdir().unwrap();
        record(tmp.path());
        let path = tmp.path().join(names::SUMMARY);
        let mut summary: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        summary["session"]["format"] = 1.into();
        std::fs::write(&path, serde_json::to_vec(&summary).unwrap()).unwrap();
        let e = format!("{:#}", Recorded::read(tmp.path()).unwrap_err());
        assert!(
            e.contains("session format Some(1), this build reads 2"),
            "{e}"
        );
    }
}
