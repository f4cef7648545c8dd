//! The scenario check: before a scenario is used, its teacher's own policy must drive a lap.
//!
//! A scenario whose teacher cannot lap it measures nothing: a learner taught there is compared
//! with a policy that itself collides, gets stuck or leaves the path, and the run's latent loss
//! cannot show it (the teacher's own actions have a latent loss of zero wherever they go).
//! [`teacher_lap`] drives the teacher's noiseless policy (the same evaluator, mask and tie rule
//! as the car, no learner) from the scenario's start until it completes a lap, and says where
//! and why it could not: the tick, the position, the station along the path and the reset cause
//! ([`ResetReason`]), or that no lap came within [`lap_tick_limit`] ticks.
//!
//! [`crate::world::registry::load_scenario`] runs it on every scenario it loads, built-in or a user's
//! file; `host-sim --no-scenario-check` skips it and says so on standard error. A lap costs a few
//! hundred to about 1 500 ticks, some 10–30 ms of a release build.

use std::sync::Arc;

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

/// The teacher's lap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TeacherLap {
    /// Ticks it took.
    pub ticks: u32,
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
    let spec = TeacherSpec {
        noise: 0.0,
        random_answers: 0.0,
        ..scenario.teacher
    };
    let mut teacher = Teacher::new(spec, 0);
    let mut episode = Episode::new(scenario.clone());
    let limit = lap_tick_limit(scenario);
    let fail = |tick, e: &Episode, failure| {
        let pose = e.car().pose;
        ScenarioUnusable {
            scenario: scenario.name.clone(),
            tick,
            x: pose.x,
            y: pose.y,
            station: e.station(),
            length: scenario.path.length(),
            failure,
        }
    };
    for tick in 0..limit {
        // The observation of a scenario that loaded is always valid; a refusal would be a bug
        // of the sensing, reported as a blocked car rather than a panic.
        let best = match teacher.judge(&episode.observe()) {
            Ok(j) => j.best,
            Err(_) => None,
        };
        let before = episode.clone();
        let r = episode.drive(best);
        if r.lap {
            return Ok(TeacherLap { ticks: tick + 1 });
        }
        if let Some(reason) = r.reset {
            return Err(fail(tick, &before, LapFailure::Reset(reason)));
        }
    }
    Err(fail(
        limit,
        &episode,
        LapFailure::TooSlow {
            ticks: limit,
            progress: episode.progress(),
        },
    ))
}
