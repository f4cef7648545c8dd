//! A `host-sim run` folder read back: its `steps.csv` rows and, from `summary.json`, which
//! scenario it ran (`host-sim draw --run DIR`, the animation).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};

/// One row of `steps.csv`: what the animation and the drawings need.
#[derive(Clone, Debug, PartialEq)]
pub struct StepRow {
    /// Step index.
    pub step: u32,
    /// The learner's action (None: every trajectory collided).
    pub action: Option<u8>,
    /// The teacher's action.
    pub teacher_action: Option<u8>,
    /// The latent loss of the learner's action.
    pub latent_loss: f64,
    /// Whether feedback reached the learner this step.
    pub corrected: bool,
    /// Corrections so far.
    pub corrections: u32,
    /// Why the car was put back at the start after this step, if it was (`collision`, `stuck`,
    /// `lost`, `blocked`, `path-end`).
    pub reset: Option<String>,
    /// Laps so far.
    pub lap: u32,
    /// Pose where the action was chosen: x (m).
    pub x: f64,
    /// y (m).
    pub y: f64,
    /// Heading (rad).
    pub theta: f64,
}

/// A run's folder: where its files are and which scenario it ran.
#[derive(Clone, Debug)]
pub struct RunFolder {
    /// Its `steps.csv`.
    pub steps_csv: PathBuf,
    /// The scenario's name, from `summary.json` (None without one).
    pub scenario: Option<String>,
    /// The scenario's file, from `summary.json` (runs before it was recorded have none).
    pub scenario_file: Option<PathBuf>,
    /// What the run was, in words: "doors, action feedback, seed 0" from `summary.json`, or
    /// the folder's name without one.
    pub title: String,
}

impl RunFolder {
    /// The run in `path`: a folder holding `steps.csv` (and `summary.json`), or a `steps.csv`
    /// whose folder holds the `summary.json`.
    pub fn open(path: &Path) -> Result<Self> {
        let (dir, steps_csv) = if path.is_dir() {
            (path.to_path_buf(), path.join("steps.csv"))
        } else {
            let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
            (dir, path.to_path_buf())
        };
        if !steps_csv.is_file() {
            bail!(
                "{}: no steps.csv (give the folder of a `host-sim run --out DIR`)",
                path.display()
            );
        }
        let summary = dir.join("summary.json");
        let folder = dir
            .canonicalize()
            .ok()
            .and_then(|d| d.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| "run".into());
        let (scenario, scenario_file, title) = if summary.is_file() {
            let text = std::fs::read_to_string(&summary)
                .with_context(|| format!("{}: cannot read", summary.display()))?;
            let v: serde_json::Value = serde_json::from_str(&text)
                .with_context(|| format!("{}: not a run's summary", summary.display()))?;
            let config = &v["config"];
            let name = config["scenario"]
                .as_str()
                .ok_or_else(|| anyhow!("{}: no config.scenario", summary.display()))?;
            let title = match (config["feedback"].as_str(), config["seed"].as_u64()) {
                (Some(f @ ("action" | "preference" | "semantic")), Some(seed)) => {
                    format!("{name}, {f} feedback, seed {seed}")
                }
                (Some(f), Some(seed)) => format!("{name}, {f}, seed {seed}"),
                _ => name.to_string(),
            };
            (
                Some(name.to_string()),
                config["scenario_file"].as_str().map(PathBuf::from),
                title,
            )
        } else {
            (None, None, folder)
        };
        Ok(Self {
            steps_csv,
            scenario,
            scenario_file,
            title,
        })
    }

    /// The rows of its `steps.csv`.
    pub fn rows(&self) -> Result<Vec<StepRow>> {
        read_steps(&self.steps_csv)
    }
}

/// Reads a `steps.csv` written by `host-sim run`, its columns found by their names.
pub fn read_steps(csv: &Path) -> Result<Vec<StepRow>> {
    let text =
        std::fs::read_to_string(csv).with_context(|| format!("{}: cannot read", csv.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| anyhow!("{}: empty", csv.display()))?
        .split(',')
        .collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| anyhow!("{}: no column {name:?}", csv.display()))
    };
    let c = [
        col("step")?,
        col("action")?,
        col("teacher_action")?,
        col("latent_loss")?,
        col("corrected")?,
        col("corrections")?,
        col("reset")?,
        col("lap")?,
        col("x")?,
        col("y")?,
        col("theta")?,
    ];
    let mut rows = Vec::new();
    for (i, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let bad = |what: &str| anyhow!("{}: line {}: bad {what}", csv.display(), i + 2);
        let field = |k: usize| f.get(c[k]).copied().unwrap_or("");
        let number = |k: usize, what: &str| -> Result<f64> {
            field(k)
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(what))
        };
        let count = |k: usize, what: &str| field(k).parse::<u32>().map_err(|_| bad(what));
        let action = |k: usize, what: &str| -> Result<Option<u8>> {
            match field(k) {
                "" => Ok(None),
                s => s
                    .parse::<u8>()
                    .ok()
                    .filter(|&a| (a as usize) < firmware_core::MAX_ACTIONS)
                    .map(Some)
                    .ok_or_else(|| bad(what)),
            }
        };
        rows.push(StepRow {
            step: count(0, "step")?,
            action: action(1, "action")?,
            teacher_action: action(2, "teacher_action")?,
            latent_loss: number(3, "latent_loss")?,
            corrected: match field(4) {
                "0" => false,
                "1" => true,
                _ => return Err(bad("corrected")),
            },
            corrections: count(5, "corrections")?,
            reset: Some(field(6)).filter(|s| !s.is_empty()).map(str::to_string),
            lap: count(7, "lap")?,
            x: number(8, "x")?,
            y: number(9, "y")?,
            theta: number(10, "theta")?,
        });
    }
    Ok(rows)
}
