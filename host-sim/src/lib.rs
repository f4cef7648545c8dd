//! # host-sim: the world the learner is taught in
//!
//! The std side of the project (DESIGN section 6): simulated households, the MuSHR car, the
//! programmatic teachers of the paper's section 6, the experiment loop that drives the
//! `firmware-core` learner through them, and the reproduction of the paper's section 6.
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
//! # Three layers, one folder each
//!
//! Each layer uses only the layers below it (and `firmware-core`, `protocol`, `hil_mock`):
//!
//! 1. [`world`]: the household and everything in it. Maps in ROS `map_server` format, the
//!    reference path, the car, scenario files, sensing and the episode (one control tick,
//!    resets, laps), the programmatic teacher who lives there (it sees what the car sees and
//!    judges it with the same evaluator), the scenario check (the teacher must lap before a
//!    scenario is used), the built-in households and the seeded generator of new ones.
//! 2. [`teach`]: a learner taught in a world. The run loop behind the [`teach::experiment::CarLink`]
//!    trait (the learner in this process, or on the car's controller over CAN:
//!    [`teach::remote`]), behaviour cloning, what a run records, the synthetic stream of
//!    `host-sim demo`, the learner table that picks `host-sim run`'s default learner, and the
//!    calibration of the teachers' scale.
//! 3. [`report`]: the reproduction of the paper's section 6. The trial grid and its shards,
//!    statistics and aggregates, the paper's claims (one pure function each) in the paper's
//!    households and across many generated worlds, the figures and drawings, and the report's
//!    sections.
//!
//! On top of them, [`console`]: the teaching console of `host-sim teach`, a web page on
//! 127.0.0.1 from which a person teaches the car ([`teach::session`]). The `host-sim` command
//! (`src/main.rs`, its commands in `src/cli/`) sits on top of all of it. Beside them, [`checks`]
//! checks the numbers a user gives, the same way and in the same words wherever they come from:
//! a flag, a scenario file, a configuration built in code.
//!
//! Every random choice takes a seed and no clock is read: the same configuration gives
//! bit-identical records.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod checks;
pub mod console;
pub mod report;
pub mod teach;
pub mod world;
