//! A recorded session read back from its folder, and its replay against a fresh learner (see
//! the module documentation of [`super`]).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail, ensure};
use firmware_core::{Feature, LearnerParams};

use super::files::names;
use super::{Entry, SESSION_FORMAT, Session};
use crate::teach::config::RunConfig;
use crate::teach::experiment::InProcessLink;

/// A recorded session, read back from its folder.
#[derive(Clone, Debug)]
pub struct Recorded {
    /// The folder.
    pub dir: PathBuf,
    /// The scenario as given.
    pub scenario: String,
    /// The seed.
    pub seed: u64,
    /// The learner's parameters.
    pub learner: LearnerParams,
    /// Ticks driven.
    pub ticks: u32,
    /// The tick the session was at when it ended.
    pub at_tick: u32,
    /// The teachings.
    pub entries: Vec<Entry>,
    /// `steps.csv`, as written.
    pub steps_csv: Vec<u8>,
    /// `snapshots.jsonl`, as written.
    pub snapshots: Vec<u8>,
    /// `summary.json`.
    pub summary: serde_json::Value,
}

impl Recorded {
    /// Reads the session in `dir`.
    pub fn read(dir: &Path) -> Result<Self> {
        let read = |name: &str| {
            std::fs::read(dir.join(name))
                .with_context(|| format!("{}: cannot read", dir.join(name).display()))
        };
        let summary: serde_json::Value = serde_json::from_slice(&read(names::SUMMARY)?)
            .with_context(|| format!("{}: not JSON", names::SUMMARY))?;
        let session = summary
            .get("session")
            .with_context(|| format!("{}: no `session` section: not a session", names::SUMMARY))?;
        let field = |name: &str| {
            session
                .get(name)
                .with_context(|| format!("{}: session.{name} is missing", names::SUMMARY))
        };
        let format = field("format")?.as_u64();
        ensure!(
            format == Some(SESSION_FORMAT as u64),
            "{}: session format {:?}, this build reads {SESSION_FORMAT}",
            names::SUMMARY,
            format
        );
        let number = |name: &str| -> Result<u64> {
            field(name)?
                .as_u64()
                .with_context(|| format!("{}: session.{name} is not a count", names::SUMMARY))
        };
        let ticks = u32::try_from(number("ticks")?).context("session.ticks")?;
        let at_tick = u32::try_from(number("at_tick")?).context("session.at_tick")?;
        ensure!(
            at_tick == ticks,
            "{}: session.at_tick {at_tick} is not session.ticks {ticks}",
            names::SUMMARY
        );
        let scenario = field("scenario")?
            .as_str()
            .with_context(|| format!("{}: session.scenario is not text", names::SUMMARY))?
            .to_string();
        let learner: LearnerParams = serde_json::from_value(field("learner")?.clone())
            .with_context(|| format!("{}: session.learner", names::SUMMARY))?;
        let mut entries = Vec::new();
        let feedback = read(names::FEEDBACK)?;
        let text = std::str::from_utf8(&feedback)
            .with_context(|| format!("{}: not UTF-8", names::FEEDBACK))?;
        for (i, line) in text.lines().enumerate() {
            let e: Entry = serde_json::from_str(line)
                .with_context(|| format!("{} line {}", names::FEEDBACK, i + 1))?;
            if let Some(last) = entries.last().map(|l: &Entry| l.applied) {
                ensure!(
                    e.applied >= last,
                    "{} line {}: applied at tick {} after tick {last}",
                    names::FEEDBACK,
                    i + 1,
                    e.applied
                );
            }
            ensure!(
                e.applied <= ticks,
                "{} line {}: applied at tick {}, after the session's last tick {ticks}",
                names::FEEDBACK,
                i + 1,
                e.applied
            );
            entries.push(e);
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            scenario,
            seed: number("seed")?,
            learner,
            ticks,
            at_tick,
            entries,
            steps_csv: read(names::STEPS)?,
            snapshots: read(names::SNAPSHOTS)?,
            summary,
        })
    }
}

/// What a replay found.
#[derive(Debug)]
pub struct Replayed {
    /// The replayed session, at the recorded one's last tick.
    pub session: Session,
    /// Its `steps.csv`.
    pub steps_csv: Vec<u8>,
    /// Its `snapshots.jsonl`.
    pub snapshots: Vec<u8>,
    /// Differences from the recording, in words (empty: byte for byte the same).
    pub differences: Vec<String>,
}

/// Replays `recorded` against a fresh learner in this process, in `config`'s world (its
/// scenario; seed, learner and ticks are the recording's), and compares.
pub fn replay(recorded: &Recorded, config: RunConfig) -> Result<Replayed> {
    let config = RunConfig {
        seed: recorded.seed,
        learner: recorded.learner,
        steps: recorded.ticks.max(1),
        ..config
    };
    let link = InProcessLink::new(config.learner)?;
    let mut session = Session::start(config, Box::new(link))?;
    let mut entries = recorded.entries.iter().peekable();
    loop {
        while let Some(e) = entries.next_if(|e| e.applied == session.tick()) {
            session
                .teach(e.tick, e.teaching, e.wall_time_ms)
                .map_err(|err| anyhow::anyhow!("replaying {e:?}: {err}"))?;
        }
        if session.records().len() as u32 >= recorded.ticks {
            break;
        }
        session.step()?;
    }
    if let Some(e) = entries.next() {
        bail!(
            "{}: a teaching applied at tick {} never came up in the replay",
            names::FEEDBACK,
            e.applied
        );
    }
    let steps_csv = session.report().csv_bytes();
    let mut snapshots = Vec::new();
    for s in session.snapshots() {
        snapshots.extend(serde_json::to_vec(s)?);
        snapshots.push(b'\n');
    }
    let mut differences = Vec::new();
    if steps_csv != recorded.steps_csv {
        differences.push(first_difference(
            names::STEPS,
            &recorded.steps_csv,
            &steps_csv,
        ));
    }
    if snapshots != recorded.snapshots {
        differences.push(first_difference(
            names::SNAPSHOTS,
            &recorded.snapshots,
            &snapshots,
        ));
    }
    // The final weights by feature name as f32 bits (each number in summary.json is an f32
    // written exactly).
    let state = session.snapshot().state;
    for (key, replayed) in [
        ("final_weights", state.average),
        ("final_iterate", state.iterate),
    ] {
        let written = Feature::ALL.map(|f| {
            recorded.summary[key][f.name()]
                .as_f64()
                .map(|v| (v as f32).to_bits())
        });
        if written != replayed.map(|v| Some(v.to_bits())) {
            differences.push(format!(
                "{}: {key} recorded {}, replayed {replayed:?}",
                names::SUMMARY,
                recorded.summary[key]
            ));
        }
    }
    if recorded.summary["learner_steps"].as_u64() != Some(state.steps as u64) {
        differences.push(format!(
            "{}: learner_steps recorded {}, replayed {}",
            names::SUMMARY,
            recorded.summary["learner_steps"],
            state.steps
        ));
    }
    Ok(Replayed {
        session,
        steps_csv,
        snapshots,
        differences,
    })
}

/// "steps.csv line 12: recorded `…`, replayed `…`".
fn first_difference(name: &str, recorded: &[u8], replayed: &[u8]) -> String {
    let a = String::from_utf8_lossy(recorded);
    let b = String::from_utf8_lossy(replayed);
    let (mut la, mut lb) = (a.lines(), b.lines());
    let mut line = 1;
    loop {
        match (la.next(), lb.next()) {
            (Some(x), Some(y)) if x == y => line += 1,
            (x, y) => {
                return format!(
                    "{name} line {line}: recorded {:?}, replayed {:?}",
                    x.unwrap_or("(end)"),
                    y.unwrap_or("(end)")
                );
            }
        }
    }
}
