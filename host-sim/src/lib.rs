//! # host-sim: the world the learner is taught in
//!
//! The std side of the project (DESIGN section 6). It drives the `firmware-core` learner with
//! programmatic teachers and records what happens.
//!
//! * [`synthetic`]: a seeded synthetic stream (random features for 64 actions, a hidden teacher)
//!   for watching the learner learn without a world around it: the `host-sim demo` command.
//!
//! Every random choice takes a seed; the same seed gives bit-identical results.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod synthetic;
