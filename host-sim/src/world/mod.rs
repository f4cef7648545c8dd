//! The household and everything in it: what the learner is taught in.
//!
//! * [`map`]: occupancy grids in ROS `map_server` format, DDA ray casting.
//! * [`path`]: the reference path (polyline, loop or open), projection and look-ahead.
//! * [`car`]: kinematic bicycle with MuSHR constants, footprint, pure-pursuit tracker.
//! * [`scenario`]: scenario files (map, semantic objects, path, start, teacher), validated.
//! * [`sim`]: sensing (range scan, detections, path reference) and the episode (resets, laps).
//! * [`teacher`]: the programmatic teachers (presets, threshold, noise) and their feedback. From
//!   the learner's side the teacher is part of the world: it sees the observation the car sees
//!   and judges it with the same evaluator; a scenario file names its teacher.
//! * [`check`]: the scenario check: the teacher's own policy must drive a lap before a scenario
//!   is used.
//! * [`registry`]: the built-in scenarios by name, loaded and checked.
//! * [`households`]: the drawing of the built-in household maps.
//! * [`generator`]: seeded households (floor plan, path, objects) as map and scenario files.

pub mod car;
pub mod check;
pub mod generator;
pub mod households;
pub mod map;
pub mod path;
pub mod registry;
pub mod scenario;
pub mod sim;
pub mod teacher;

/// The tests' uniform numbers in `[0, 1)`: xorshift64 from `seed` (not zero), 53 bits a number.
#[cfg(test)]
pub(crate) fn test_uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}
