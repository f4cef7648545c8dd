//! # host-sim: the world the learner is taught in
//!
//! The std side of the project (DESIGN section 6): simulated households, the MuSHR car, the
//! programmatic teachers of the paper's section 6, and the experiment loop that drives the
//! `firmware-core` learner through them and records what happens.
//!
//! ```text
//!  scenario (TOML) ──▶ map (map_server YAML + PGM/PNG), objects, path, start, teacher
//!        │
//!  Episode ──sense──▶ Observation ──CarLink::act──▶ Decision (learner's action)
//!        ▲                 │
//!        │                 └──Teacher::judge (same evaluator)──▶ latent loss, feedback?
//!        │                                                  └──CarLink::feedback
//!        └── drive one tick (bicycle + pure pursuit), collisions, resets, laps ──▶ StepRecord
//! ```
//!
//! * [`map`]: occupancy grids in ROS `map_server` format, DDA ray casting.
//! * [`path`]: the reference path (polyline, loop or open), projection and look-ahead.
//! * [`scenario`]: scenario files (map, semantic objects, path, start, teacher), validated.
//! * [`check`]: the scenario check: the teacher's own policy must drive a lap before a scenario
//!   is used.
//! * [`car`]: kinematic bicycle with MuSHR constants, footprint, pure-pursuit tracker.
//! * [`sim`]: sensing (range scan, detections, path reference) and the episode (resets, laps).
//! * [`teacher`]: programmatic teachers (presets, threshold, noise) and their feedback.
//! * [`experiment`]: the run loop behind the [`experiment::CarLink`] trait, behaviour cloning,
//!   per-step records, CSV and summary.
//! * [`registry`]: built-in scenarios and experiments by name; parallel runs.
//! * [`remote`]: [`remote::RemoteCar`], the [`experiment::CarLink`] to a learner on the car's
//!   controller (`hil_mock`, the firmware) over a CAN link.
//! * [`learners`]: `host-sim learners`, every learner × feedback × noise × world, and the rule
//!   that picks `host-sim run`'s default learner from it (`docs/learners.md`).
//! * [`households`]: the generator of the built-in household maps.
//! * [`generator`]: seeded households (floor plan, path, objects) as map and scenario files.
//! * [`plot`]: drawings: the lattice (SVG), a scenario and a run's poses (PNG).
//! * [`figure`]: the reproduction's charts (mean ± std bands) and map panels, as PNG and SVG.
//! * [`calibrate`]: `host-sim calibrate`, the procedure that fixes the teachers' scale from the
//!   paper's words (`docs/reproduction/CALIBRATION.md`).
//! * [`claims`]: the paper's claims, each checked by one pure function of the aggregates.
//! * [`reproduce`]: `host-sim reproduce` and `host-sim merge`: the paper's section 6 end to end,
//!   sharded or not, with CSVs, figures and a report that checks the paper's claims.
//! * [`synthetic`]: a seeded synthetic stream (no world) for the `demo` command.
//!
//! Every random choice takes a seed and no clock is read: the same configuration gives
//! bit-identical records.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod calibrate;
pub mod car;
pub mod check;
pub mod claims;
pub mod experiment;
pub mod figure;
pub mod generator;
pub mod households;
pub mod learners;
pub mod map;
pub mod path;
pub mod plot;
pub mod registry;
pub mod remote;
pub mod reproduce;
pub mod scenario;
pub mod sim;
pub mod synthetic;
pub mod teacher;
