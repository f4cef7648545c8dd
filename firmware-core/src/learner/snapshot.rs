//! The versioned learner snapshot: what persists in flash and travels in a weights report.
//!
//! A snapshot holds the parameters and the *whole* learner state (iterate, average, AdaGrad
//! accumulator, step count), so a learner restored from it continues bit-identically. The
//! encoding is the caller's choice; the project uses postcard (fixed little-endian `f32`s,
//! varint integers), framed with a CRC by the flash store and the link.
//!
//! Format history: version 1 is the first.
//!
//! ```
//! use firmware_core::{Learner, LearnerParams};
//! let learner = Learner::new(LearnerParams::default().check().unwrap());
//! let snap = learner.snapshot();
//! assert_eq!(Learner::restore(&snap).unwrap(), learner);
//! ```

use serde::{Deserialize, Serialize};

use crate::feature::{Features, Weights};
use crate::learner::LearnerParams;

/// The snapshot format this build writes and reads.
pub const SNAPSHOT_VERSION: u16 = 1;

/// A learner's state. Fields a learner does not use hold copies of the iterate (`average`) or
/// zeros (`accumulator`).
#[derive(Clone, Copy, PartialEq, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct LearnerState {
    /// The raw iterate `w_t`.
    pub iterate: Weights,
    /// The averaged iterate `w̄_t` (the acting weights of averaged OGD).
    pub average: Weights,
    /// AdaGrad's accumulated squared subgradients.
    pub accumulator: Features,
    /// Number of steps taken.
    pub steps: u32,
}

/// Parameters and state of a learner, with a format version.
#[derive(Clone, Copy, PartialEq, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct LearnerSnapshot {
    /// [`SNAPSHOT_VERSION`] when written by this build.
    pub version: u16,
    /// The learner's parameters.
    pub params: LearnerParams,
    /// The learner's state.
    pub state: LearnerState,
}
