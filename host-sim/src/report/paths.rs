//! The laps drawn on the maps: a frozen learner (the teacher's weights, or a trained learner's)
//! driven from the start.

use std::sync::Arc;

use anyhow::Result;
use firmware_core::LearnerSnapshot;
use nalgebra::Point2;

use crate::teach::experiment::{CarLink, InProcessLink};
use crate::world::check;
use crate::world::scenario::Scenario;
use crate::world::teacher::{Teacher, TeacherSpec};

/// A lap driven for a path figure.
#[derive(Clone, Debug, PartialEq)]
pub struct PathTrace {
    /// Positions of the rear axle, the start first.
    pub points: Vec<Point2<f64>>,
    /// Why it ended: `lap`, a reset reason (`collision`, `stuck`, `lost`, `blocked`) or `ticks`.
    pub end: String,
    /// Mean true latent loss of the actions along it (the setting's teacher, without noise).
    pub mean_latent_loss: f64,
}

impl PathTrace {
    /// Its loss with how it ended, so a short lap that ended in a reset does not read as the
    /// best: "0.010 (lost after 197 ticks)", "0.027 (a lap in 382 ticks)".
    pub fn loss_and_end(&self) -> String {
        let ticks = self.points.len().saturating_sub(1);
        let how = match self.end.as_str() {
            "lap" => format!("a lap in {ticks} ticks"),
            "ticks" => format!("no lap in {ticks} ticks"),
            reset => format!("{reset} after {ticks} ticks"),
        };
        format!("{:.3} ({how})", self.mean_latent_loss)
    }
}

/// Drives `snapshot`'s learner, frozen, from the scenario's start for at most `max_ticks`
/// ([`check::drive_lap`]); `teacher`, without noise, judges every action.
pub fn learner_lap(
    scenario: &Arc<Scenario>,
    snapshot: &LearnerSnapshot,
    teacher: TeacherSpec,
    max_ticks: u32,
) -> Result<PathTrace> {
    let mut link = InProcessLink::new(snapshot.params)?;
    link.restore(snapshot)?;
    let mut judge = Teacher::new(
        TeacherSpec {
            noise: 0.0,
            ..teacher
        },
        0,
    );
    let mut loss = 0.0f64;
    let mut acted = 0u32;
    let drive = check::drive_lap(scenario, max_ticks, |tick, obs| -> Result<_> {
        let checked = obs
            .check()
            .map_err(|e| anyhow::anyhow!("tick {tick}: observation refused: {e}"))?;
        let j = judge.judge_checked(checked);
        let decision = link.act_evaluated(tick, obs, &j.evaluation)?;
        if let Some(a) = decision.action {
            loss += j.latent_loss(a) as f64;
            acted += 1;
        }
        Ok(decision.action)
    })?;
    Ok(PathTrace {
        points: drive.trace,
        end: drive.end.name().to_string(),
        mean_latent_loss: if acted > 0 { loss / acted as f64 } else { 0.0 },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_s_loss_is_shown_with_how_it_ended() {
        let p = |end: &str, n: usize| PathTrace {
            points: vec![Point2::origin(); n + 1],
            end: end.into(),
            mean_latent_loss: 0.0104,
        };
        assert_eq!(
            p("lost", 197).loss_and_end(),
            "0.010 (lost after 197 ticks)"
        );
        assert_eq!(p("lap", 382).loss_and_end(), "0.010 (a lap in 382 ticks)");
        assert_eq!(
            p("ticks", 1500).loss_and_end(),
            "0.010 (no lap in 1500 ticks)"
        );
    }
}
