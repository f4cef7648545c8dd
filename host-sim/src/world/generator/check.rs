//! What a generated world must pass, and what is measured on it.
//!
//! * [`teacher_lap`]: the teacher's own policy (its weights in a frozen learner, driven by
//!   [`crate::report::paths::drive_lap`]) drives one lap from the start without a reset.
//! * [`unreachable_objects`]: every semantic object is within the detector's range
//!   ([`SENSOR_RANGE`]) of some point of the path, in line of sight (the test of
//!   [`crate::world::sim::detect`]).
//! * [`contrast`] (measured, not required): a **path follower**, the teacher with its class and
//!   keep-right weights set to zero, drives a lap; at each tick the teacher judges the follower's
//!   action. Where the two differ, the teacher's preferences matter on this path.

use std::sync::Arc;

use anyhow::Result;
use firmware_core::Feature;

use crate::report::{grid, paths};
use crate::teach::experiment;
use crate::world::scenario::Scenario;
use crate::world::sim::{Episode, LOS_SLACK_CELLS, SENSOR_RANGE};
use crate::world::teacher::{Teacher, TeacherSpec};

/// Spacing of the path points the reachability test looks from (m).
pub const REACH_STEP: f64 = 0.1;

/// One lap of a policy from the start.
#[derive(Clone, Debug, PartialEq)]
pub struct Lap {
    /// The teacher (preset name).
    pub teacher: &'static str,
    /// Ticks driven.
    pub ticks: u32,
    /// `lap`, a reset reason (`collision`, `stuck`, `lost`, `blocked`) or `ticks` (no lap within
    /// the budget).
    pub end: String,
    /// Positions of the rear axle, the start first.
    pub trace: Vec<(f64, f64)>,
}

impl Lap {
    /// Whether it completed the lap.
    pub fn lapped(&self) -> bool {
        self.end == "lap"
    }

    /// Where it ended (the last position before a reset).
    pub fn last(&self) -> (f64, f64) {
        self.trace.last().copied().unwrap_or_default()
    }
}

/// The most ticks a lap may take: three times the path at cruise speed (1 m/s, 0.1 s ticks),
/// at least 600.
pub fn lap_budget(scenario: &Scenario) -> u32 {
    let ticks = libm::ceil(3.0 * scenario.path.length() / 0.1);
    (ticks as u32).max(600)
}

/// The teacher `spec`'s own policy drives `scenario` from its start for at most
/// [`lap_budget`] ticks.
pub fn teacher_lap(scenario: &Arc<Scenario>, name: &'static str, spec: TeacherSpec) -> Result<Lap> {
    let snapshot = experiment::learner_with(grid::paper_learner(), spec.weights)?;
    let trace = paths::drive_lap(scenario, &snapshot, spec, lap_budget(scenario))?;
    let ticks = if trace.end == "lap" || trace.end == "ticks" {
        trace.points.len() as u32 - 1
    } else {
        // The resetting tick's pose is not recorded.
        trace.points.len() as u32
    };
    Ok(Lap {
        teacher: name,
        ticks,
        end: trace.end,
        trace: trace.points,
    })
}

/// The objects (indices into `scenario.objects`) that no point of the path, sampled every
/// [`REACH_STEP`], detects: farther than [`SENSOR_RANGE`] or out of line of sight.
pub fn unreachable_objects(scenario: &Scenario) -> Vec<usize> {
    let path = &scenario.path;
    let n = libm::ceil(path.length() / REACH_STEP) as usize;
    let points: Vec<(f64, f64)> = (0..n)
        .map(|k| {
            let (x, y, _) = path.point_at(k as f64 * REACH_STEP);
            (x, y)
        })
        .collect();
    let slack = LOS_SLACK_CELLS * scenario.map.resolution();
    scenario
        .objects
        .iter()
        .enumerate()
        .filter(|(_, o)| {
            !points.iter().any(|&p| {
                let (q, d) = o.nearest_point(p);
                d <= SENSOR_RANGE && scenario.map.line_of_sight(p, q, slack)
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
    /// Ticks the follower drove (until its lap, a reset, or [`lap_budget`]).
    pub ticks: u32,
    /// How the follower's drive ended (as [`Lap::end`]).
    pub end: String,
    /// Ticks where the teacher's best action is not the follower's.
    pub differs: u32,
    /// Ticks where the teacher's latent loss of the follower's action exceeds its threshold:
    /// a teacher would correct the path follower there.
    pub over_threshold: u32,
    /// The follower's positions, the start first.
    pub trace: Vec<(f64, f64)>,
}

/// The path follower of `spec`: its weights with doors, stairs, chairs and keep-right at zero.
pub fn path_follower(spec: TeacherSpec) -> TeacherSpec {
    let mut weights = spec.weights;
    for f in [
        Feature::Door,
        Feature::Stairs,
        Feature::Chair,
        Feature::Right,
    ] {
        weights[f.index()] = 0.0;
    }
    TeacherSpec {
        preset: None,
        weights,
        ..spec
    }
}

/// Drives the path follower of `spec` for one lap and counts where the teacher disagrees.
pub fn contrast(
    scenario: &Arc<Scenario>,
    name: &'static str,
    spec: TeacherSpec,
) -> Result<Contrast> {
    let quiet = TeacherSpec { noise: 0.0, ..spec };
    let mut follower = Teacher::new(path_follower(quiet), 0);
    let mut teacher = Teacher::new(quiet, 0);
    let mut episode = Episode::new(scenario.clone());
    let start = episode.car().pose;
    let mut c = Contrast {
        teacher: name,
        ticks: 0,
        end: "ticks".into(),
        differs: 0,
        over_threshold: 0,
        trace: vec![(start.x, start.y)],
    };
    for tick in 0..lap_budget(scenario) {
        let obs = episode.observe();
        let f = follower
            .judge(&obs)
            .map_err(|e| anyhow::anyhow!("tick {tick}: observation refused: {e}"))?;
        let t = teacher
            .judge(&obs)
            .map_err(|e| anyhow::anyhow!("tick {tick}: observation refused: {e}"))?;
        if let Some(a) = f.best {
            c.differs += u32::from(t.best != Some(a));
            c.over_threshold += u32::from(t.latent_loss(a) > quiet.threshold);
        }
        let r = episode.drive(f.best);
        c.ticks += 1;
        if let Some(reason) = r.reset {
            c.end = if r.lap { "lap" } else { reason.name() }.into();
            break;
        }
        let p = episode.car().pose;
        c.trace.push((p.x, p.y));
        if r.lap {
            c.end = "lap".into();
            break;
        }
    }
    Ok(c)
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

    /// A 12 m × 10 m room (5 cm cells) with a wall across x = 6 m from y = 0 to 4 m, a path
    /// from (1, 1) to (5, 1), and chairs: in sight, behind the wall, beyond the range.
    #[test]
    fn objects_out_of_range_or_behind_a_wall_are_unreachable() {
        let map = OccupancyGrid::from_fn(240, 200, 0.05, [0.0, 0.0, 0.0], |c, r| {
            c == 0 || r == 0 || c == 239 || r == 199 || (c == 120 && r < 80)
        });
        let chair = |x, y| WorldObject {
            class: SemanticClass::Chair,
            x,
            y,
            shape: Shape::Disc { radius: 0.2 },
        };
        let stairs = WorldObject {
            class: SemanticClass::Stairs,
            x: 9.0,
            y: 6.0,
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
            path: RefPath::new(vec![(1.0, 1.0), (5.0, 1.0)], false).unwrap(),
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
