//! What a generated world must pass, and what is measured on it.
//!
//! * The scenario check of every scenario ([`crate::world::check::lap_of`]), once per teacher
//!   preset: its own policy drives one lap from the start without a reset.
//! * [`unreachable_objects`]: every semantic object is within the detector's range
//!   ([`SENSOR_RANGE`]) of some point of the path, in line of sight (the test of
//!   [`crate::world::sim::detect`]).
//! * [`contrast`] (measured, not required): a **path follower**, the teacher with its class and
//!   keep-right weights set to zero ([`teacher::path_follower`]), drives a lap; at each tick the
//!   teacher judges the follower's action. Where the two differ, the teacher's preferences
//!   matter on this path.

use std::sync::Arc;

use anyhow::Result;

use nalgebra::Point2;

use crate::world::check::{self, lap_tick_limit};
use crate::world::scenario::Scenario;
use crate::world::sim::{LOS_SLACK_CELLS, SENSOR_RANGE};
use crate::world::teacher::{self, Teacher, TeacherSpec};

/// Spacing of the path points the reachability test looks from (m).
pub const REACH_STEP: f64 = 0.1;

/// The objects (indices into `scenario.objects`) that no point of the path, sampled every
/// [`REACH_STEP`], detects: farther than [`SENSOR_RANGE`] or out of line of sight.
pub fn unreachable_objects(scenario: &Scenario) -> Vec<usize> {
    let path = &scenario.path;
    let n = libm::ceil(path.length() / REACH_STEP) as usize;
    let points: Vec<Point2<f64>> = (0..n)
        .map(|k| path.point_at(k as f64 * REACH_STEP).0)
        .collect();
    let slack = LOS_SLACK_CELLS * scenario.map.resolution();
    scenario
        .objects
        .iter()
        .enumerate()
        .filter(|(_, o)| {
            !points.iter().any(|p| {
                let (q, d) = o.nearest_point(p);
                d <= SENSOR_RANGE && scenario.map.line_of_sight((p.x, p.y), (q.x, q.y), slack)
            })
        })
        .map(|(i, _)| i)
        .collect()
}

/// A teacher against the path follower of the same weights without its preferences.
#[derive(Clone, Debug, PartialEq)]
pub struct Contrast {
    /// The teacher (preset name).
    pub teacher: &'static str,
    /// Ticks the follower drove (until its lap, a reset, or [`lap_tick_limit`]).
    pub ticks: u32,
    /// How the follower's drive ended: `lap`, a reset reason or `ticks`.
    pub end: &'static str,
    /// Ticks where the teacher's best action is not the follower's.
    pub differs: u32,
    /// Ticks where the teacher's latent loss of the follower's action exceeds its threshold:
    /// a teacher would correct the path follower there.
    pub over_threshold: u32,
    /// The follower's positions, the start first.
    pub trace: Vec<Point2<f64>>,
}

/// Drives the path follower of `spec` for one lap ([`check::drive_lap`], the scenario check's
/// tick limit) and counts where the teacher disagrees.
pub fn contrast(
    scenario: &Arc<Scenario>,
    name: &'static str,
    spec: TeacherSpec,
) -> Result<Contrast> {
    let quiet = TeacherSpec { noise: 0.0, ..spec };
    let mut follower = Teacher::new(
        TeacherSpec {
            preset: None,
            weights: teacher::path_follower(&quiet.weights),
            ..quiet
        },
        0,
    );
    let mut judge = Teacher::new(quiet, 0);
    let (mut differs, mut over_threshold) = (0, 0);
    let drive = check::drive_lap(
        scenario,
        lap_tick_limit(scenario),
        |tick, obs| -> Result<_> {
            let refused = |e| anyhow::anyhow!("tick {tick}: observation refused: {e}");
            // One evaluation, judged by both.
            let f = follower.judge(obs).map_err(refused)?;
            let t = judge.judge_evaluation(f.evaluation.clone());
            if let Some(a) = f.best {
                differs += u32::from(t.best != Some(a));
                over_threshold += u32::from(t.latent_loss(a) > quiet.threshold);
            }
            Ok(f.best)
        },
    )?;
    Ok(Contrast {
        teacher: name,
        ticks: drive.ticks,
        end: drive.end.name(),
        differs,
        over_threshold,
        trace: drive.trace,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::car::Pose;
    use crate::world::map::OccupancyGrid;
    use crate::world::path::RefPath;
    use crate::world::scenario::{Shape, WorldObject};
    use crate::world::teacher::{PRESETS, TeacherSpec};
    use firmware_core::observation::SemanticClass;
    use nalgebra::Point2;

    /// A 12 m × 10 m room (5 cm cells) with a wall across x = 6 m from y = 0 to 4 m, a path
    /// from (1, 1) to (5, 1), and chairs: in sight, behind the wall, beyond the range.
    #[test]
    fn objects_out_of_range_or_behind_a_wall_are_unreachable() {
        let map = OccupancyGrid::from_fn(240, 200, 0.05, [0.0, 0.0, 0.0], |c, r| {
            c == 0 || r == 0 || c == 239 || r == 199 || (c == 120 && r < 80)
        });
        let chair = |x, y| WorldObject {
            class: SemanticClass::Chair,
            centre: Point2::new(x, y),
            shape: Shape::Disc { radius: 0.2 },
        };
        let stairs = WorldObject {
            class: SemanticClass::Stairs,
            centre: Point2::new(9.0, 6.0),
            shape: Shape::Rect {
                width: 4.0,
                height: 1.0,
                yaw: 0.0,
            },
        };
        let s = Scenario {
            name: "room".into(),
            description: String::new(),
            source: Default::default(),
            map: Arc::new(map),
            path: RefPath::new(vec![Point2::new(1.0, 1.0), Point2::new(5.0, 1.0)], false).unwrap(),
            start: Pose {
                x: 1.0,
                y: 1.0,
                theta: 0.0,
            },
            objects: vec![
                chair(3.0, 3.0),
                chair(7.5, 1.0),
                chair(1.0, 7.0),
                // 4.4 m from (5, 1), this side of the wall: in reach.
                chair(5.5, 5.6),
                // Its nearest end, (7.5, 6), is 5.7 m from (5, 1): out of reach.
                stairs,
            ],
            teacher: TeacherSpec::from_preset(&PRESETS[0]),
        };
        assert_eq!(unreachable_objects(&s), vec![1, 2, 4]);
    }
}
