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
