//! A learner taught in a world: runs, links, baselines, and the choices they rest on.
//!
//! * [`config`]: a run's configuration: the mode, the learner, the teacher's overrides, the
//!   start jitter.
//! * [`experiment`]: the run loop behind the [`experiment::CarLink`] trait, parallel runs.
//! * [`bc`]: behaviour cloning, the paper's baseline.
//! * [`record`]: what a run records: per-step records, CSV, summary, task success.
//! * [`learner_file`]: the learner file of `run --save-learner` and `--load-learner`: the
//!   versioned snapshot the car persists.
//! * [`remote`]: [`remote::RemoteCar`], the [`experiment::CarLink`] to a learner on the car's
//!   controller (`hil_mock`, the firmware) over a CAN link.
//! * [`person`]: what a person at the teaching console can do, and the feedback each becomes.
//! * [`session`]: a person teaching (`host-sim teach`): the session, its files, its replay.
//! * [`synthetic`]: a seeded synthetic stream (no world) for the `demo` command.
//! * [`learners`]: `host-sim learners`, every learner × feedback × noise × world, and the rule
//!   that picks `host-sim run`'s default learner from it (`docs/learners.md`).
//! * [`calibrate`]: `host-sim calibrate`, the procedure that fixes the teachers' scale from the
//!   paper's words (`docs/reproduction/CALIBRATION.md`).

pub mod bc;
pub mod calibrate;
pub mod config;
pub mod experiment;
pub mod learner_file;
pub mod learners;
pub mod person;
pub mod record;
pub mod remote;
pub mod session;
pub mod synthetic;
