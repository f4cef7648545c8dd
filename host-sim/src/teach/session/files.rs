//! A session's files: what `summary.json` says of it beyond its ticks, and the files written as
//! the person teaches (see the module documentation of [`super`]).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, ensure};
use serde::Serialize;

use super::Session;

/// What `summary.json` says of a session beyond its ticks.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SessionAbout {
    /// The scenario as given (a built-in name or a path), to load it again.
    pub scenario: String,
    /// The link's address, if the learner was the car's.
    pub link: Option<String>,
    /// When it started (seconds since 1970).
    pub started_unix_s: u64,
    /// Seconds since it started.
    pub wall_time_s: f64,
    /// Whether it has ended.
    pub finished: bool,
    /// Why it ended: the person, the tick limit, an interrupt, a link failure.
    pub ended_by: Option<String>,
}

/// The files of a session being recorded (see the module documentation).
#[derive(Debug)]
pub struct SessionFiles {
    dir: PathBuf,
    feedback: std::fs::File,
    snapshots: std::fs::File,
    /// Entries and snapshots already written.
    written: (usize, usize),
}

/// The names of a session's files.
pub mod names {
    /// Per tick, as `host-sim run`.
    pub const STEPS: &str = "steps.csv";
    /// Summary, as `host-sim run`, plus the session.
    pub const SUMMARY: &str = "summary.json";
    /// The teachings.
    pub const FEEDBACK: &str = "feedback.jsonl";
    /// The learner after each feedback.
    pub const SNAPSHOTS: &str = "snapshots.jsonl";
    /// The CAN frames, with a link.
    pub const CANDUMP: &str = "candump.log";
}

impl SessionFiles {
    /// Creates `dir` for a new session; refuses a folder that holds one already.
    pub fn create(dir: &Path) -> Result<Self> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("session folder {}: cannot create", dir.display()))?;
        for name in [names::FEEDBACK, names::STEPS, names::SUMMARY] {
            ensure!(
                !dir.join(name).exists(),
                "session folder {} holds a session already ({name}): choose another folder",
                dir.display()
            );
        }
        let open = |name: &str| {
            std::fs::OpenOptions::new()
                .create_new(true)
                .append(true)
                .open(dir.join(name))
                .with_context(|| format!("{}: cannot create", dir.join(name).display()))
        };
        Ok(Self {
            feedback: open(names::FEEDBACK)?,
            snapshots: open(names::SNAPSHOTS)?,
            dir: dir.to_path_buf(),
            written: (0, 0),
        })
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Appends the teachings and snapshots `session` took since the last call, flushed.
    pub fn append(&mut self, session: &Session) -> Result<()> {
        let (e, s) = self.written;
        append_lines(&mut self.feedback, &session.entries()[e..])
            .with_context(|| format!("{}: cannot write", names::FEEDBACK))?;
        self.written.0 = session.entries().len();
        append_lines(&mut self.snapshots, &session.snapshots()[s..])
            .with_context(|| format!("{}: cannot write", names::SNAPSHOTS))?;
        self.written.1 = session.snapshots().len();
        Ok(())
    }

    /// Writes everything: the new lines, `steps.csv` and `summary.json` (each through a
    /// temporary file, so a reader never sees half of one).
    pub fn checkpoint(&mut self, session: &Session, about: &SessionAbout) -> Result<()> {
        self.append(session)?;
        write_atomically(&self.dir.join(names::STEPS), &session.report().csv_bytes())?;
        let text = serde_json::to_string_pretty(&session.summary(about))? + "\n";
        write_atomically(&self.dir.join(names::SUMMARY), text.as_bytes())
    }
}

fn append_lines<T: Serialize>(file: &mut std::fs::File, items: &[T]) -> Result<()> {
    let mut text = String::new();
    for item in items {
        text += &serde_json::to_string(item)?;
        text.push('\n');
    }
    file.write_all(text.as_bytes())?;
    file.flush()?;
    Ok(())
}

fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, bytes).with_context(|| format!("{}: cannot write", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("{}: cannot write", path.display()))
}
