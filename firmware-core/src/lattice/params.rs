//! Constants of the lattice and of the evaluator's geometry.
//!
//! This file is also compiled into `build.rs` (which generates the lattice tables from it), so
//! it holds plain constants only.

/// Wheelbase of the controller's kinematic bicycle model (m). MuSHR's is 0.29–0.33 m; the
/// lattice is planned with 0.29 m.
pub const WHEELBASE: f32 = 0.29;

/// Largest steering angle the lattice plans with (rad). The car steers to ±0.34 rad; planning
/// to 0.30 rad keeps the sharpest trajectory (curvature 1.067 /m) within reach of a plant whose
/// wheelbase is as long as 0.33 m (`tan(0.34)/0.33 = 1.073 /m`), so a tracking controller can
/// follow every trajectory of the lattice.
pub const MAX_PLANNING_STEERING: f32 = 0.30;

/// Number of poses sampled along every trajectory (every 0.1 m of a cruise trajectory, every
/// 0.05 m of a creep one), for the tracking controller; also the largest number of clearance
/// samples of a trajectory.
pub const SAMPLES: usize = 10;

/// Clearances are measured every this much arc length (m), at the footprint's centre: 10 samples
/// on a cruise trajectory, 5 on a creep one.
pub const SAMPLE_SPACING: f32 = 0.1;

/// Length of each of the two constant-curvature segments of a cruise trajectory (m).
pub const CRUISE_SEGMENT_LENGTH: f32 = 0.5;

/// Number of curvature levels per cruise segment: `κ_max · {0, ±1/3, ±2/3, ±1}`.
pub const CRUISE_LEVELS: usize = 7;

/// Length of a creep trajectory, a single arc (m).
pub const CREEP_LENGTH: f32 = 0.5;

/// Number of creep curvature levels: `κ_max · {0, ±1/7, …, ±7/7}`.
pub const CREEP_LEVELS: usize = 15;

/// Speed of the cruise trajectories (m/s).
pub const CRUISE_SPEED: f32 = 1.0;

/// Speed of the creep trajectories (m/s).
pub const CREEP_SPEED: f32 = 0.5;

/// Distance from the rear axle (the car frame's origin) forward to the centre of the car's
/// footprint (m). Clearances and collisions are measured from the footprint's centre.
pub const FOOTPRINT_CENTER_OFFSET: f32 = 0.15;

/// Number of beams of the downsampled range scan.
pub const SCAN_BEAMS: usize = 64;

/// Obstacle clearances are clipped at this distance (m): a trajectory that stays this far from
/// every scan point is as good as any other as far as obstacles go.
pub const OBSTACLE_CLIP: f32 = 0.5;

/// A sample closer than this to a scan point collides (m): the car's half-width 0.15 m plus a
/// 0.10 m margin. (Re-exported as [`crate::evaluator::COLLISION_RADIUS`].)
pub const COLLISION_RADIUS: f32 = 0.25;

/// Width of the range bins the evaluator sorts the beams into each tick (m). Only a cost, never a
/// value (the pruning is exact): swept on the car's recorded ticks (docs/firmware.md,
/// "Measurements"), 0.15 m (12 bins) costs less than 0.05 m (36 bins): fewer bins to clear and
/// accumulate each tick, for a band hardly less tight than the clusters' windows make it.
pub(crate) const RANGE_BIN_WIDTH: f32 = 0.15;

/// Slack added to every "farther than" decision of the evaluator's pruning: 1 mm, far above f32
/// rounding at these magnitudes, so a pruned beam is provably out of reach.
pub(crate) const REACH_MARGIN: f32 = 1.0e-3;

/// Largest distance of a sample point from the centre of its cluster (m): the evaluator prunes
/// the beams of a cluster's samples together (see `build.rs`). Only a cost, never a value: swept
/// on the car's recorded ticks (docs/firmware.md, "Measurements"): every value from 0.106 to
/// 0.146 gives the same 56 clusters, 0.147 to 0.2 the same 48, 0.1 gave 65. With the semantic
/// pass's regions (grouped from the clusters' centres), 48 clusters give the least worst tick
/// (53 711 against 55 096 with 56, the mean 33 013 against 32 929; 40 clusters, 0.3 m: 33 657 /
/// 56 741).
pub(crate) const CLUSTER_SPREAD: f32 = 0.15;
