//! What a run records: one [`StepRecord`] per tick, the [`RunReport`] with its CSV and summary,
//! and the task's success beside the latent loss.

use std::io::Write;

use firmware_core::{ActionIndex, Feature, LearnerParams, LearnerSnapshot, Weights};

use super::bc::BcFit;
use super::config::Mode;
use crate::world::sim::ResetReason;
use crate::world::teacher::TeacherSpec;

/// One step of a run: one CSV row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepRecord {
    /// Step index, from 0.
    pub step: u32,
    /// The learner's action (None: nothing was allowed).
    pub action: Option<ActionIndex>,
    /// The teacher's (perceived-best) action.
    pub teacher_action: Option<ActionIndex>,
    /// True latent loss of the learner's action (0 when there was none).
    pub latent_loss: f32,
    /// Whether feedback reached the learner this step.
    pub corrected: bool,
    /// Corrections so far, this one included.
    pub corrections: u32,
    /// Whether the car collided this step.
    pub collision: bool,
    /// Why the car was put back at the start, if it was.
    pub reset: Option<ResetReason>,
    /// Laps completed so far.
    pub lap: u32,
    /// How far along the path the car has come so far (m; laps times the path's length plus the
    /// current lap's progress, see [`Episode::path_progress`](crate::world::sim::Episode::path_progress)).
    pub progress: f64,
    /// Pose where the action was chosen.
    pub x: f64,
    /// Pose where the action was chosen.
    pub y: f64,
    /// Pose where the action was chosen.
    pub theta: f64,
}

/// Everything a run produced.
#[derive(Clone, Debug)]
pub struct RunReport {
    /// The scenario's name.
    pub scenario: String,
    /// The mode.
    pub mode: Mode,
    /// The seed.
    pub seed: u64,
    /// The teacher (after overrides).
    pub teacher: TeacherSpec,
    /// The learner's parameters.
    pub learner: LearnerParams,
    /// One record per step.
    pub records: Vec<StepRecord>,
    /// The learner at the end.
    pub final_snapshot: LearnerSnapshot,
    /// The behaviour-cloning fit, for `bc`.
    pub bc: Option<BcFit>,
    /// Resets by reason: collision, stuck, lost, blocked.
    pub resets: [u32; 4],
}

impl RunReport {
    /// Corrections in all.
    pub fn corrections(&self) -> u32 {
        self.records.last().map_or(0, |r| r.corrections)
    }

    /// Laps in all.
    pub fn laps(&self) -> u32 {
        self.records.last().map_or(0, |r| r.lap)
    }

    /// Collisions in all.
    pub fn collisions(&self) -> u32 {
        self.resets[0]
    }

    /// How far along the path the car came over the run (m; see [`Episode::path_progress`](crate::world::sim::Episode::path_progress)).
    pub fn progress(&self) -> f64 {
        self.records.last().map_or(0.0, |r| r.progress)
    }

    /// The task's outcome in words: laps, progress and resets by cause.
    pub fn task_success(&self) -> TaskSuccess {
        TaskSuccess {
            laps: self.laps(),
            progress: self.progress(),
            resets: self.resets,
        }
    }

    /// Mean latent loss over steps `range`.
    pub fn mean_loss(&self, range: std::ops::Range<usize>) -> f64 {
        let rows =
            &self.records[range.start.min(self.records.len())..range.end.min(self.records.len())];
        if rows.is_empty() {
            return 0.0;
        }
        rows.iter().map(|r| r.latent_loss as f64).sum::<f64>() / rows.len() as f64
    }

    /// Mean latent loss of the first and the last `fraction` of the steps.
    pub fn first_last(&self, fraction: f64) -> (f64, f64) {
        let n = self.records.len();
        let k = ((n as f64 * fraction).round() as usize).max(1);
        (self.mean_loss(0..k), self.mean_loss(n.saturating_sub(k)..n))
    }

    /// Writes the per-step CSV (through the `csv` crate; numbers as Rust prints them, the
    /// progress to the millimetre).
    pub fn write_csv<W: Write>(&self, w: W) -> std::io::Result<()> {
        let mut w = csv::Writer::from_writer(w);
        w.write_record([
            "step",
            "action",
            "teacher_action",
            "latent_loss",
            "corrected",
            "corrections",
            "collision",
            "reset",
            "lap",
            "progress",
            "x",
            "y",
            "theta",
        ])?;
        let idx = |a: Option<ActionIndex>| a.map(|a| a.get().to_string()).unwrap_or_default();
        for r in &self.records {
            w.write_record([
                r.step.to_string(),
                idx(r.action),
                idx(r.teacher_action),
                r.latent_loss.to_string(),
                u8::from(r.corrected).to_string(),
                r.corrections.to_string(),
                u8::from(r.collision).to_string(),
                r.reset.map_or("", |x| x.name()).to_string(),
                r.lap.to_string(),
                format!("{:.3}", r.progress),
                r.x.to_string(),
                r.y.to_string(),
                r.theta.to_string(),
            ])?;
        }
        w.flush()
    }

    /// The CSV as bytes.
    pub fn csv_bytes(&self) -> Vec<u8> {
        let mut v = Vec::new();
        // Writing to a Vec cannot fail.
        let _ = self.write_csv(&mut v);
        v
    }

    /// The summary (everything but the wall time, which the caller adds).
    pub fn summary(&self) -> serde_json::Value {
        let (first, last) = self.first_last(0.1);
        let t = &self.teacher;
        let s = &self.final_snapshot;
        serde_json::json!({
            "config": {
                "scenario": self.scenario,
                "feedback": self.mode.name(),
                "steps": self.records.len(),
                "seed": self.seed,
                "threshold": t.threshold,
                "noise": t.noise,
                "statements": t.statements.name(),
                "random_answers": t.random_answers,
                "teacher_preset": t.preset,
                "teacher_weights": weights_by_name(&t.weights),
                "learner": self.learner.kind.name(),
                "step_size": self.learner.step,
            },
            "seed": self.seed,
            "final_weights": weights_by_name(&s.state.average),
            "final_iterate": weights_by_name(&s.state.iterate),
            "learner_steps": s.state.steps,
            "totals": {
                "corrections": self.corrections(),
                "collisions": self.resets[0],
                "stuck": self.resets[1],
                "lost": self.resets[2],
                "blocked": self.resets[3],
                "laps": self.laps(),
                "progress_m": self.progress(),
            },
            "resets": {
                "collision": self.resets[0],
                "stuck": self.resets[1],
                "lost": self.resets[2],
                "blocked": self.resets[3],
            },
            "mean_latent_loss_first_10pct": first,
            "mean_latent_loss_last_10pct": last,
            "corrections": self.corrections(),
            "collisions": self.resets[0],
            "laps": self.laps(),
            "bc": self.bc.map(|b| serde_json::json!({
                "samples": b.samples,
                "ticks": b.ticks,
                "epochs": b.epochs,
                "converged": b.converged,
                "weights": weights_by_name(&b.weights),
            })),
        })
    }
}

/// Weights by feature name, as `summary.json` holds them: `{"obstacles": 0.2, "door": 0.0, …}`.
pub fn weights_by_name(w: &Weights) -> serde_json::Value {
    Feature::ALL
        .iter()
        .map(|f| (f.name().to_string(), serde_json::json!(w[f.index()])))
        .collect::<serde_json::Map<_, _>>()
        .into()
}

/// Weights by feature name, in the features' order, as `run` prints them: "obstacles 0.2,
/// door 0, stairs 0, chair 0.06, path -0.32, right 0.018" (each number the shortest that reads
/// back as the same `f32`).
pub fn describe_weights(w: &Weights) -> String {
    Feature::ALL
        .iter()
        .map(|f| format!("{} {}", f.name(), w[f.index()]))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The names of the reset causes, in the order of [`RunReport::resets`].
pub const RESET_CAUSES: [&str; 4] = ["collision", "stuck", "lost", "blocked"];

/// Whether a run got anywhere: what latent loss alone cannot see (a car that circles where the
/// teacher would circle too has a latent loss of zero).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TaskSuccess {
    /// Laps completed.
    pub laps: u32,
    /// How far along the path the car came (m): laps times the path's length plus the last
    /// lap's progress; resets take back the progress of their lap.
    pub progress: f64,
    /// Resets by cause: collision, stuck, lost, blocked ([`RESET_CAUSES`]).
    pub resets: [u32; 4],
}

impl TaskSuccess {
    /// Resets of every cause.
    pub fn total_resets(&self) -> u32 {
        self.resets.iter().sum()
    }

    /// "3 laps, 152.3 m of progress, resets: 0 collision, 2 stuck, 11 lost, 0 blocked".
    pub fn describe(&self) -> String {
        format!(
            "{} laps, {:.1} m of progress, resets: {}",
            self.laps,
            self.progress,
            describe_resets(&self.resets)
        )
    }
}

/// "0 collision, 2 stuck, 11 lost, 0 blocked".
pub fn describe_resets(resets: &[u32; 4]) -> String {
    RESET_CAUSES
        .iter()
        .zip(resets)
        .map(|(c, n)| format!("{n} {c}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// FNV-1a (64-bit) of `bytes`: the digest the determinism goldens pin.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_named_by_their_feature() {
        let w = [0.5, 0.0, -1.25, 2.0, -0.125, 1.0e-3];
        assert_eq!(
            describe_weights(&w),
            "obstacles 0.5, door 0, stairs -1.25, chair 2, path -0.125, right 0.001"
        );
        let j = weights_by_name(&w);
        assert_eq!(j["stairs"], -1.25);
        assert_eq!(j["right"], 1.0e-3f32 as f64);
        assert_eq!(j.as_object().unwrap().len(), 6);
    }

    #[test]
    fn fnv1a_matches_the_reference_vectors() {
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(b"foobar"), 0x8594_4171_f739_67e8);
    }
}
