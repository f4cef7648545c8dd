//! The scenario check, and the one lap driver of the crate.
//!
//! A scenario whose teacher cannot lap it measures nothing: a learner taught there is compared
//! with a policy that itself collides, gets stuck or leaves the path, and the run's latent loss
//! cannot show it (the teacher's own actions have a latent loss of zero wherever they go).
//! [`teacher_lap`] drives the teacher's noiseless policy (the same evaluator, mask and tie rule
//! as the car, no learner) from the scenario's start until it completes a lap, and says where
//! and why it could not: the tick, the position, the station along the path and the reset cause
//! ([`ResetReason`]), or that no lap came within [`lap_tick_limit`] ticks.
//!
//! [`crate::world::registry::load_scenario`] runs it on every scenario it loads, built-in or a
//! user's file; `host-sim --no-scenario-check` skips it and says so on standard error. The
//! generator runs the same check with every teacher preset ([`lap_of`]) before it keeps a world.
//! A lap costs a few hundred to about 1 500 ticks, some 10–30 ms of a release build.
//!
//! Every lap of the crate is driven by [`drive_lap`]: a policy (the teacher's, a trained
//! learner's, a path follower's) from the scenario's start until a lap, a reset or a tick limit,
//! with the positions it drove through.

use std::sync::Arc;

use firmware_core::ActionIndex;
use firmware_core::observation::Observation;
use nalgebra::Point2;
use thiserror::Error;

use crate::world::scenario::Scenario;
use crate::world::sim::{Episode, LOST_DISTANCE, ResetReason, STUCK_TICKS, TICK_SECONDS};
use crate::world::teacher::{Teacher, TeacherSpec};

/// Ticks allowed per metre of path before a lap counts as not coming: thirty, three times what
/// the lattice's 1 m/s cruise speed needs.
pub const TICKS_PER_METRE: f64 = 30.0;

/// The longest a lap of `scenario` may take (ticks): [`TICKS_PER_METRE`] per metre of its path,
/// and at least 100.
pub fn lap_tick_limit(scenario: &Scenario) -> u32 {
    ((scenario.path.length() * TICKS_PER_METRE).ceil() as u32).max(100)
}

/// How a drive from the start ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LapEnd {
    /// It completed a lap.
    Lap,
    /// It was put back at the start.
    Reset(ResetReason),
    /// No lap within the tick limit.
    Ticks,
}

impl LapEnd {
    /// `lap`, the reset reason's name (`collision`, `stuck`, `lost`, `blocked`) or `ticks`.
    pub fn name(self) -> &'static str {
        match self {
            LapEnd::Lap => "lap",
            LapEnd::Reset(r) => r.name(),
            LapEnd::Ticks => "ticks",
        }
    }
}

/// Where the car stood.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Place {
    /// Position of the rear axle (m).
    pub x: f64,
    /// Position of the rear axle (m).
    pub y: f64,
    /// Its projection onto the path (m of arc length from the path's start).
    pub station: f64,
}

/// One drive from the scenario's start ([`drive_lap`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Drive {
    /// Control ticks driven, the one that ended the drive included.
    pub ticks: u32,
    /// How it ended.
    pub end: LapEnd,
    /// Positions of the rear axle: the start, then after every tick but one that reset the car
    /// (which puts it back at the start).
    pub trace: Vec<Point2<f64>>,
    /// Where the car stood at the start of the tick that reset it, or at the end of the drive.
    pub last: Place,
    /// Progress along the path at the end (m; see [`Episode::progress`]).
    pub progress: f64,
}

/// Drives `policy` (the action for each tick's observation, `None` for none allowed) from the
/// scenario's start until a lap, a reset or `max_ticks` ticks.
pub fn drive_lap<E>(
    scenario: &Arc<Scenario>,
    max_ticks: u32,
    mut policy: impl FnMut(u32, &Observation) -> Result<Option<ActionIndex>, E>,
) -> Result<Drive, E> {
    let mut episode = Episode::new(scenario.clone());
    let place = |e: &Episode| {
        let p = e.car().pose;
        Place {
            x: p.x,
            y: p.y,
            station: e.station(),
        }
    };
    let mut trace = vec![episode.car().pose.position()];
    for tick in 0..max_ticks {
        let action = policy(tick, &episode.observe())?;
        let before = place(&episode);
        let r = episode.drive(action);
        let end = match r.reset {
            Some(_) if r.lap => Some(LapEnd::Lap),
            Some(reason) => Some(LapEnd::Reset(reason)),
            None => {
                trace.push(episode.car().pose.position());
                r.lap.then_some(LapEnd::Lap)
            }
        };
        if let Some(end) = end {
            return Ok(Drive {
                ticks: tick + 1,
                end,
                trace,
                last: before,
                progress: episode.progress(),
            });
        }
    }
    Ok(Drive {
        ticks: max_ticks,
        end: LapEnd::Ticks,
        trace,
        last: place(&episode),
        progress: episode.progress(),
    })
}

/// The teacher's lap.
#[derive(Clone, Debug, PartialEq)]
pub struct TeacherLap {
    /// Ticks it took.
    pub ticks: u32,
    /// The positions it drove through, the start first.
    pub trace: Vec<Point2<f64>>,
}

/// Why the teacher's policy did not complete a lap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LapFailure {
    /// It was put back at the start.
    Reset(ResetReason),
    /// No lap within the tick limit.
    TooSlow {
        /// The limit.
        ticks: u32,
        /// Progress along the path by then (m).
        progress: f64,
    },
}

impl LapFailure {
    /// The reset reason's name, or `ticks`.
    pub fn name(&self) -> &'static str {
        match self {
            LapFailure::Reset(r) => r.name(),
            LapFailure::TooSlow { .. } => "ticks",
        }
    }
}

/// The scenario cannot be used: its teacher cannot drive a lap.
#[derive(Clone, Debug, PartialEq, Error)]
#[error(
    "{scenario}: the teacher's own policy cannot drive a lap of this scenario: at tick {tick}, at \
     ({x:.2}, {y:.2}) m, {station:.1} m along the path ({length:.1} m long), {}; change the \
     scenario (map, path, objects, start or teacher), or run with --no-scenario-check to use it \
     anyway",
    why(.failure)
)]
pub struct ScenarioUnusable {
    /// The scenario's name.
    pub scenario: String,
    /// The tick where it failed.
    pub tick: u32,
    /// Where the car was at the start of that tick (m).
    pub x: f64,
    /// Where the car was at the start of that tick (m).
    pub y: f64,
    /// The car's projection onto the path there (m of arc length from the path's start).
    pub station: f64,
    /// The path's length (m).
    pub length: f64,
    /// What happened.
    pub failure: LapFailure,
}

fn why(f: &LapFailure) -> String {
    match f {
        LapFailure::Reset(ResetReason::Collision) => {
            "its footprint touched an occupied or unknown cell (collision)".into()
        }
        LapFailure::Reset(ResetReason::Stuck) => format!(
            "it made no progress along the path for {:.0} s (stuck)",
            STUCK_TICKS as f64 * TICK_SECONDS
        ),
        LapFailure::Reset(ResetReason::Lost) => {
            format!("it was more than {LOST_DISTANCE} m from the path (lost)")
        }
        LapFailure::Reset(ResetReason::Blocked) => {
            "every trajectory of the lattice collided (blocked)".into()
        }
        LapFailure::Reset(ResetReason::PathEnd) => "the path ended".into(),
        LapFailure::TooSlow { ticks, progress } => {
            format!("no lap came within {ticks} ticks ({progress:.1} m of progress)")
        }
    }
}

/// Drives the noiseless teacher of `scenario` from its start until a lap, a reset or
/// [`lap_tick_limit`] ticks.
pub fn teacher_lap(scenario: &Arc<Scenario>) -> Result<TeacherLap, ScenarioUnusable> {
    lap_of(scenario, scenario.teacher)
}

/// [`teacher_lap`] with the teacher `spec` in place of the scenario's.
pub fn lap_of(scenario: &Arc<Scenario>, spec: TeacherSpec) -> Result<TeacherLap, ScenarioUnusable> {
    let spec = TeacherSpec {
        noise: 0.0,
        random_answers: 0.0,
        ..spec
    };
    let mut teacher = Teacher::new(spec, 0);
    let limit = lap_tick_limit(scenario);
    // The observation of a scenario that loaded is always valid; a refusal would be a bug of
    // the sensing, reported as a blocked car rather than a panic.
    let Ok(drive) = drive_lap::<std::convert::Infallible>(scenario, limit, |_, obs| {
        Ok(teacher.judge(obs).ok().and_then(|j| j.best))
    });
    let (tick, failure) = match drive.end {
        LapEnd::Lap => {
            return Ok(TeacherLap {
                ticks: drive.ticks,
                trace: drive.trace,
            });
        }
        LapEnd::Reset(reason) => (drive.ticks - 1, LapFailure::Reset(reason)),
        LapEnd::Ticks => (
            limit,
            LapFailure::TooSlow {
                ticks: limit,
                progress: drive.progress,
            },
        ),
    };
    Err(ScenarioUnusable {
        scenario: scenario.name.clone(),
        tick,
        x: drive.last.x,
        y: drive.last.y,
        station: drive.last.station,
        length: scenario.path.length(),
        failure,
    })
}
