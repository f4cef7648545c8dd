//! The simulated MuSHR car: a kinematic bicycle with steering-rate and acceleration limits, its
//! rectangular footprint, and a pure-pursuit tracking controller for a lattice trajectory.
//!
//! # Model
//!
//! State `(x, y, θ)` of the rear-axle midpoint, speed `v`, steering angle `δ`. Each physics step
//! of `dt` first moves `δ` towards the command by at most `steer_rate · dt` and `v` towards the
//! command by at most `max_accel · dt`, then advances the pose exactly along the arc of curvature
//! `tan δ / L` (closed form, no Euler error). Constants ([`CarParams::MUSHR`]): wheelbase
//! `L` = 0.33 m, steering ±0.34 rad, 4 rad/s steering rate, 2 m/s² acceleration, footprint
//! 0.5 m × 0.3 m centred 0.15 m ahead of the rear axle, physics at 100 Hz.
//!
//! # Tracking
//!
//! A chosen trajectory (car frame, from the lattice) is fixed in the world at the pose where it
//! was chosen. [`Tracker`] steers by pure pursuit towards the point of that polyline (extended
//! straight past its end) [`Tracker::LOOKAHEAD`] ahead of the car's projection onto it, and
//! drives at the trajectory's speed. On a constant-curvature arc pure pursuit commands exactly
//! the arc's curvature, so the plant's longer wheelbase (0.33 m vs the lattice's 0.29 m) costs
//! nothing: steering is computed for the plant.
//!
//! Transforms are nalgebra's ([`Pose::isometry`]: an `Isometry2` of the position and the
//! heading's `UnitComplex`, built from libm's cosine and sine as firmware-core's lattice does);
//! all transcendental functions go through `libm`, so results are the same on every host.

use std::cell::Cell;

use firmware_core::lattice::{SAMPLES, Trajectory};
use nalgebra::{Isometry2, Point2, UnitComplex, Vector2};

use crate::world::map::OccupancyGrid;

/// A pose in the world frame (rear-axle midpoint, heading counter-clockwise from +x).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Pose {
    /// x (m).
    pub x: f64,
    /// y (m).
    pub y: f64,
    /// Heading (rad).
    pub theta: f64,
}

impl Pose {
    /// The pose at `position` facing `theta`.
    pub fn at(position: Point2<f64>, theta: f64) -> Self {
        Self {
            x: position.x,
            y: position.y,
            theta,
        }
    }

    /// The position (m).
    #[inline]
    pub fn position(&self) -> Point2<f64> {
        Point2::new(self.x, self.y)
    }

    /// The heading as a rotation.
    #[inline]
    pub fn rotation(&self) -> UnitComplex<f64> {
        rotation(self.theta)
    }

    /// The transform from this pose's frame (x forward, y left) to the world's.
    #[inline]
    pub fn isometry(&self) -> Isometry2<f64> {
        self.isometry_turned(self.rotation())
    }

    /// [`Pose::isometry`] with the heading's rotation given (`self.rotation()`, computed once
    /// by a caller that needs it more than once).
    #[inline]
    pub fn isometry_turned(&self, rotation: UnitComplex<f64>) -> Isometry2<f64> {
        Isometry2::from_parts(self.position().coords.into(), rotation)
    }

    /// The world point of a point given in this pose's frame.
    #[inline]
    pub fn to_world(&self, p: Point2<f64>) -> Point2<f64> {
        self.isometry() * p
    }

    /// A world point in this pose's frame.
    #[inline]
    pub fn to_local(&self, p: Point2<f64>) -> Point2<f64> {
        self.isometry().inverse_transform_point(&p)
    }
}

/// The rotation by `angle` (rad), from libm's cosine and sine (not simba's, which follow the
/// features a build unifies).
#[inline]
pub fn rotation(angle: f64) -> UnitComplex<f64> {
    let (sin, cos) = sin_cos(angle);
    UnitComplex::from_cos_sin_unchecked(cos, sin)
}

/// `(libm::sin(angle), libm::cos(angle))`, bit for bit, with one argument reduction for both:
/// libm's `sincos` runs the same kernels on the same reduced argument as its `sin` and `cos`
/// (`sin_cos_is_libms_sin_and_cos` checks it).
#[inline]
pub fn sin_cos(angle: f64) -> (f64, f64) {
    libm::sincos(angle)
}

/// Wraps an angle into `[−π, π]`.
pub fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::PI;
    let q = (a + PI) / (2.0 * PI);
    // `a − 2π·⌊q⌋`, whose floor is 0 for `q` in `[0, 1)` (most angles, already wrapped): then
    // it is `a − (+0)`, which is `a` bit for bit (−0 included), without the call to `floor`.
    let mut w = if (0.0..1.0).contains(&q) {
        a
    } else {
        a - 2.0 * PI * libm::floor(q)
    };
    if w > PI {
        w -= 2.0 * PI;
    }
    if w < -PI {
        w += 2.0 * PI;
    }
    w
}

/// The car's constants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CarParams {
    /// Wheelbase (m).
    pub wheelbase: f64,
    /// Largest steering angle (rad).
    pub max_steering: f64,
    /// Largest steering rate (rad/s).
    pub steering_rate: f64,
    /// Largest acceleration and deceleration (m/s²).
    pub max_accel: f64,
    /// Footprint length (m).
    pub length: f64,
    /// Footprint width (m).
    pub width: f64,
    /// Distance from the rear axle forward to the footprint's centre (m).
    pub center_offset: f64,
    /// Physics steps per second.
    pub physics_hz: u32,
}

impl CarParams {
    /// The MuSHR racecar.
    pub const MUSHR: Self = Self {
        wheelbase: 0.33,
        max_steering: 0.34,
        steering_rate: 4.0,
        max_accel: 2.0,
        length: 0.5,
        width: 0.3,
        center_offset: 0.15,
        physics_hz: 100,
    };

    /// Whether the footprint at `pose` overlaps a cell that is not free. Samples the rectangle
    /// on a grid no coarser than half a cell (edges included).
    pub fn footprint_hits(&self, map: &OccupancyGrid, pose: Pose) -> bool {
        self.footprint_on(map).hits(map, pose, pose.rotation())
    }

    /// What [`CarParams::footprint_hits`] computes from the car's size and `map`'s resolution
    /// alone, once for many poses.
    pub fn footprint_on(&self, map: &OccupancyGrid) -> Footprint {
        let step = map.resolution() / 2.0;
        // Every sample is within the half-diagonal of the centre, so its cell is at most
        // ⌊half-diagonal / resolution⌋ + 1 cells from the centre's along each axis (one more for
        // rounding). If all cells that near are free, no sample can hit: the same answer as the
        // loop over the samples, without it.
        let reach = libm::sqrt(self.length * self.length + self.width * self.width) / 2.0;
        // The same for each quarter of the rectangle (halves of the samples along each side),
        // around its own centre: half the diagonal.
        let quarter = reach / 2.0;
        Footprint {
            car: *self,
            nx: libm::ceil(self.length / step) as usize,
            ny: libm::ceil(self.width / step) as usize,
            near: (reach / map.resolution()).floor() + 2.0,
            near_quarter: (quarter / map.resolution()).floor() + 2.0,
            reach,
            resolution: map.resolution(),
            swing: 1.0 + self.center_offset.abs() * libm::tan(self.max_steering) / self.wheelbase,
        }
    }
}

/// The footprint test of [`CarParams::footprint_hits`] for one car on maps of one resolution
/// ([`CarParams::footprint_on`]).
#[derive(Clone, Copy, Debug)]
pub struct Footprint {
    car: CarParams,
    /// Sample intervals along the length and the width.
    nx: usize,
    ny: usize,
    /// A centre with a clearance above this many cells is clear.
    near: f64,
    /// The same for a quarter's centre and its samples.
    near_quarter: f64,
    /// Half the footprint's diagonal (m), and the map's resolution.
    reach: f64,
    resolution: f64,
    /// How far the footprint's centre moves, at most, per metre the rear axle drives
    /// ([`Footprint::travel`]).
    swing: f64,
}

impl Footprint {
    /// Whether the footprint touches no blocked cell at any pose within `travel` metres of `pose`
    /// (rotation given, `pose.rotation()`) as its centre moves: every sample of such a pose lies
    /// within half the diagonal plus `travel` of the centre at `pose`, so, as for one pose, a
    /// centre whose clearance exceeds ⌊(half-diagonal + travel) / resolution⌋ + 2 cells shows
    /// them all clear. `true` means [`Footprint::hits`] is `false` at every such pose; `false`
    /// settles nothing.
    pub fn clear_within(
        &self,
        map: &OccupancyGrid,
        pose: Pose,
        rotation: UnitComplex<f64>,
        travel: f64,
    ) -> bool {
        let near = ((self.reach + travel) / self.resolution).floor() + 2.0;
        let centre = pose.isometry_turned(rotation) * Point2::new(self.car.center_offset, 0.0);
        map.clearance_cells(centre.x, centre.y) as f64 > near
    }

    /// How far (m) the footprint's centre can move from where it is in `steps` physics steps of
    /// `dt` at speeds of at most `speed` (m/s, the larger of the car's and the command's: a step
    /// moves the speed towards the command), with a millimetre for rounding: each step moves the
    /// rear axle along an arc of `|v|·dt` (its chord is shorter) and turns the heading by
    /// `|k|·|v|·dt` with `|k| ≤ tan(max_steering) / wheelbase`, which moves the centre, ahead of
    /// the axle by the centre offset, by at most the offset times that angle.
    pub fn travel(&self, steps: u32, dt: f64, speed: f64) -> f64 {
        f64::from(steps) * dt * libm::fabs(speed) * self.swing + 1e-3
    }

    /// [`CarParams::footprint_hits`] with the heading's rotation given (`pose.rotation()`), on a
    /// map of the resolution this was made for.
    pub fn hits(&self, map: &OccupancyGrid, pose: Pose, rotation: UnitComplex<f64>) -> bool {
        let Self {
            car,
            nx,
            ny,
            near,
            near_quarter,
            ..
        } = *self;
        let iso = pose.isometry_turned(rotation);
        let centre = iso * Point2::new(car.center_offset, 0.0);
        if (map.clearance_cells(centre.x, centre.y) as f64) > near {
            return false;
        }
        let u = |i: usize| -car.length / 2.0 + car.length * i as f64 / nx as f64;
        let v = |j: usize| -car.width / 2.0 + car.width * j as f64 / ny as f64;
        // Near a wall: the samples by quarters (indices `0..=n/2` and `n/2 + 1..=n` along each
        // side), each skipped when its own centre's clearance shows it clear, as above (its
        // samples lie within half its diagonal of that centre, at most a quarter's).
        let halves = |n: usize| [(0, n / 2), (n / 2 + 1, n)];
        for (i0, i1) in halves(nx) {
            for (j0, j1) in halves(ny) {
                let middle = Vector2::new((u(i0) + u(i1)) / 2.0, (v(j0) + v(j1)) / 2.0);
                let m = centre + iso.rotation * middle;
                if (map.clearance_cells(m.x, m.y) as f64) > near_quarter {
                    continue;
                }
                for i in i0..=i1 {
                    for j in j0..=j1 {
                        let p = centre + iso.rotation * Vector2::new(u(i), v(j));
                        if map.is_blocked(p.x, p.y) {
                            return true;
                        }
                    }
                }
            }
        }
        false
    }
}

/// The car's state.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct CarState {
    /// Pose of the rear axle.
    pub pose: Pose,
    /// Forward speed (m/s).
    pub speed: f64,
    /// Steering angle (rad).
    pub steering: f64,
}

impl CarState {
    /// Standing at `pose`, wheels straight.
    pub fn at(pose: Pose) -> Self {
        Self {
            pose,
            speed: 0.0,
            steering: 0.0,
        }
    }

    /// One physics step of `dt` towards the commanded steering and speed.
    pub fn step(&mut self, p: &CarParams, steering_cmd: f64, speed_cmd: f64, dt: f64) {
        let rotation = self.pose.rotation();
        self.step_turned(p, steering_cmd, speed_cmd, dt, rotation);
    }

    /// [`CarState::step`] with the heading's rotation given (`self.pose.rotation()`); returns
    /// the new heading's (the same bits as `self.pose.rotation()` after the step: the arc's end
    /// heading is the new heading unless it had to be wrapped).
    pub fn step_turned(
        &mut self,
        p: &CarParams,
        steering_cmd: f64,
        speed_cmd: f64,
        dt: f64,
        rotation: UnitComplex<f64>,
    ) -> UnitComplex<f64> {
        let (cos_th, sin_th) = (rotation.cos_angle(), rotation.sin_angle());
        let target = steering_cmd.clamp(-p.max_steering, p.max_steering);
        let ds = p.steering_rate * dt;
        self.steering += (target - self.steering).clamp(-ds, ds);
        let dv = p.max_accel * dt;
        self.speed += (speed_cmd - self.speed).clamp(-dv, dv);
        let s = self.speed * dt;
        let k = libm::tan(self.steering) / p.wheelbase;
        let th = self.pose.theta;
        if libm::fabs(k * s) < 1e-9 {
            self.pose.x += s * cos_th;
            self.pose.y += s * sin_th;
            rotation
        } else {
            let th2 = th + k * s;
            let (sin2, cos2) = sin_cos(th2);
            self.pose.x += (sin2 - sin_th) / k;
            self.pose.y -= (cos2 - cos_th) / k;
            self.pose.theta = wrap_angle(th2);
            if self.pose.theta.to_bits() == th2.to_bits() {
                UnitComplex::from_cos_sin_unchecked(cos2, sin2)
            } else {
                self.pose.rotation()
            }
        }
    }
}

/// Pure pursuit along one lattice trajectory fixed in the world.
#[derive(Clone, Debug)]
pub struct Tracker {
    /// The polyline's segments: from the start pose through the trajectory's poses, world
    /// frame, one array per quantity (the projection onto every segment is then one loop the
    /// compiler vectorizes).
    segments: Segments,
    /// The polyline's last point.
    last: Point2<f64>,
    /// Its length (the segments' lengths summed in order).
    total: f64,
    /// The heading at the end, for the straight extension (rad), and its rotation, computed
    /// the first time the extension is needed (most ticks never reach it).
    end_theta: f64,
    end_rotation: std::cell::OnceCell<UnitComplex<f64>>,
    speed: f64,
    /// How many segments, from the first, a projection looks at: all of them unless
    /// [`Tracker::narrow_within`] showed the later ones too far to be the nearest.
    near: Cell<usize>,
    /// The travel of a [`Tracker::narrow_within`] the next projection narrows by.
    narrow_by: Cell<Option<f64>>,
}

/// A [`Tracker`]'s segments, with what every projection onto them needs: segment `i` starts at
/// `(ax[i], ay[i])` and ends at that plus `(dx[i], dy[i])`.
#[derive(Clone, Copy, Debug, Default)]
struct Segments {
    ax: [f64; SAMPLES],
    ay: [f64; SAMPLES],
    dx: [f64; SAMPLES],
    dy: [f64; SAMPLES],
    /// The squared length and the length of `(dx, dy)`.
    len2: [f64; SAMPLES],
    len: [f64; SAMPLES],
    /// The arc length at the segment's start (the lengths before it summed in order).
    s0: [f64; SAMPLES],
}

impl Tracker {
    /// Look-ahead distance of pure pursuit (m).
    pub const LOOKAHEAD: f64 = 0.3;

    /// Fixes `trajectory` in the world at `origin` (the pose where it was chosen).
    pub fn new(origin: Pose, trajectory: &Trajectory) -> Self {
        Self::new_turned(origin, origin.rotation(), trajectory)
    }

    /// [`Tracker::new`] with the origin's rotation given (`origin.rotation()`).
    pub fn new_turned(origin: Pose, rotation: UnitComplex<f64>, trajectory: &Trajectory) -> Self {
        let iso = origin.isometry_turned(rotation);
        let mut g = Segments::default();
        let mut a = origin.position();
        let mut s0 = 0.0;
        for (i, p) in trajectory.poses().iter().enumerate() {
            let b = iso * Point2::new(p.x as f64, p.y as f64);
            let d = b - a;
            let len = d.norm();
            g.ax[i] = a.x;
            g.ay[i] = a.y;
            g.dx[i] = d.x;
            g.dy[i] = d.y;
            g.len2[i] = d.norm_squared();
            g.len[i] = len;
            g.s0[i] = s0;
            s0 += len;
            a = b;
        }
        Self {
            segments: g,
            last: a,
            total: s0,
            end_theta: origin.theta + trajectory.end().theta as f64,
            end_rotation: std::cell::OnceCell::new(),
            speed: trajectory.speed as f64,
            near: Cell::new(SAMPLES),
            narrow_by: Cell::new(None),
        }
    }

    /// The commanded speed (m/s).
    pub fn speed(&self) -> f64 {
        self.speed
    }

    /// The arc length of `at`'s projection onto the polyline: of the first segment nearest to
    /// it. The parameter along every segment and the squared distance to its point (each the
    /// operations of nalgebra's `dot` and `norm_squared` written out, `x0·y0 + x1·y1`) are
    /// computed in one loop without branches, which the compiler vectorizes; then the nearest.
    fn station(&self, at: Point2<f64>) -> f64 {
        if let Some(travel) = self.narrow_by.take() {
            let (s, best, d2) = self.nearest::<SAMPLES>(at);
            self.narrow(&d2, best, travel);
            return s;
        }
        // A constant number of segments each (an even one: the loop vectorized by pairs without
        // a remainder); the segments past `near` that it takes are never the first nearest.
        match self.near.get() {
            0..=2 => self.nearest::<2>(at).0,
            3..=4 => self.nearest::<4>(at).0,
            5..=6 => self.nearest::<6>(at).0,
            7..=8 => self.nearest::<8>(at).0,
            _ => self.nearest::<SAMPLES>(at).0,
        }
    }

    /// The station of `at`'s projection onto the first nearest of the first `N` segments, its
    /// squared distance, and every one's squared distance (the rest 0).
    #[inline(always)]
    fn nearest<const N: usize>(&self, at: Point2<f64>) -> (f64, f64, [f64; SAMPLES]) {
        let (t, d2) = self.projections(at, N);
        let g = &self.segments;
        let (mut s, mut best) = (0.0f64, f64::INFINITY);
        for i in 0..N.min(SAMPLES) {
            if d2[i] < best {
                (s, best) = (g.s0[i] + t[i] * g.len[i], d2[i]);
            }
        }
        (s, best, d2)
    }

    /// Narrows the projections (`Tracker::station`) after the next one to the segments that
    /// can be the nearest to a point within `travel` metres of the next point projected (the
    /// car's rear axle over a tick, projected first where it starts: [`Footprint::travel`]
    /// bounds how far it moves). See `Tracker::narrow`.
    pub fn narrow_within(&mut self, travel: f64) {
        self.narrow_by.set(Some(travel));
    }

    /// With `dᵢ` segment `i`'s distance from a point (`d2`: its square) and `m` the least
    /// (`least`: its square), a point within `travel` of it is at least `dᵢ − travel` from
    /// segment `i` and at most `m + travel` from the nearest, so a segment with
    /// `dᵢ > m + 2·travel` (and a micrometre for rounding, far above the squared distances'
    /// relative 10⁻¹⁶) is never the first nearest: the segments after the last one within that
    /// bound are left out. The nearest among the rest is the same segment, its station the same
    /// bits.
    fn narrow(&self, d2: &[f64; SAMPLES], least: f64, travel: f64) {
        // Compared squared (the micrometre is far above the squares' rounding).
        let bound = libm::sqrt(least) + 2.0 * travel + 1e-6;
        let bound2 = bound * bound;
        // NaN (never: finite poses) keeps every segment.
        let mut near = 0;
        for (i, &d2) in d2.iter().enumerate() {
            if d2 <= bound2 || d2.is_nan() {
                near = i + 1;
            }
        }
        if near > 0 {
            self.near.set(near);
        }
    }

    /// The parameter along each of the first `n` segments of `at`'s projection and the
    /// squared distance to it (the rest 0).
    #[inline(always)]
    fn projections(&self, at: Point2<f64>, n: usize) -> ([f64; SAMPLES], [f64; SAMPLES]) {
        let g = &self.segments;
        let mut t = [0.0f64; SAMPLES];
        let mut d2 = [0.0f64; SAMPLES];
        for i in 0..n.min(SAMPLES) {
            let (rx, ry) = (at.x - g.ax[i], at.y - g.ay[i]);
            let q = (rx * g.dx[i] + ry * g.dy[i]) / g.len2[i];
            // `q.clamp(0.0, 1.0)` written out: the same values (NaN included), but with
            // `clamp` the loop is not vectorized (measured: 58 020 against 56 220 instructions
            // a step of `host-sim bench`, callgrind).
            #[allow(clippy::manual_clamp)]
            let clamped = if q < 0.0 {
                0.0
            } else if q > 1.0 {
                1.0
            } else {
                q
            };
            let ti = if g.len2[i] > 0.0 { clamped } else { 0.0 };
            let ex = at.x - (g.ax[i] + g.dx[i] * ti);
            let ey = at.y - (g.ay[i] + g.dy[i] * ti);
            t[i] = ti;
            d2[i] = ex * ex + ey * ey;
        }
        (t, d2)
    }

    /// Steering command for the car at `pose`.
    pub fn steering(&self, pose: Pose, p: &CarParams) -> f64 {
        self.steering_turned(pose, pose.rotation(), p)
    }

    /// [`Tracker::steering`] with the pose's rotation given (`pose.rotation()`).
    pub fn steering_turned(&self, pose: Pose, turn: UnitComplex<f64>, p: &CarParams) -> f64 {
        let g = &self.segments;
        let target_s = self.station(pose.position()) + Self::LOOKAHEAD;
        let goal = if target_s >= self.total {
            let end = *self
                .end_rotation
                .get_or_init(|| crate::world::car::rotation(self.end_theta));
            self.last + end * Vector2::new(target_s - self.total, 0.0)
        } else {
            (0..SAMPLES)
                .find(|&i| g.s0[i] + g.len[i] >= target_s)
                .map_or(self.last, |i| {
                    let t = if g.len[i] > 0.0 {
                        (target_s - g.s0[i]) / g.len[i]
                    } else {
                        0.0
                    };
                    Point2::new(g.ax[i] + g.dx[i] * t, g.ay[i] + g.dy[i] * t)
                })
        };
        let local = pose.isometry_turned(turn).inverse_transform_point(&goal);
        let d2 = local.coords.norm_squared();
        if d2 < 1e-12 {
            return 0.0;
        }
        // Pure pursuit: curvature 2·y / d².
        let k = 2.0 * local.y / d2;
        libm::atan(k * p.wheelbase)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware_core::lattice::trajectory;
    use firmware_core::{ActionIndex, MAX_ACTIONS};

    #[test]
    fn a_footprint_clear_within_its_travel_hits_nothing_for_a_tick() {
        // Ticks of ten physics steps from random free poses of every built-in map, with random
        // speeds (up to 4 m/s, twice the lattice's fastest) and random trajectories: when the
        // start says the tick's travel is clear, no step's footprint may hit.
        use crate::world::registry::{SCENARIOS, load_scenario_unchecked};
        use firmware_core::{ActionIndex, MAX_ACTIONS};
        let p = CarParams::MUSHR;
        let mut uniform = crate::world::test_uniform(0x9E37_79B9_7F4A_7C15);
        let (mut clear, mut unclear, mut hit) = (0u32, 0u32, 0u32);
        for s in SCENARIOS {
            let map = load_scenario_unchecked(s.name).unwrap().map;
            let footprint = p.footprint_on(&map);
            let (w, h, o) = (
                map.width() as f64 * map.resolution(),
                map.height() as f64 * map.resolution(),
                map.origin(),
            );
            for _ in 0..4000 {
                let pose = Pose {
                    x: o[0] + uniform() * w,
                    y: o[1] + uniform() * h,
                    theta: (uniform() - 0.5) * 7.0,
                };
                if map.is_blocked(pose.x, pose.y) {
                    continue;
                }
                let action = ActionIndex::new((uniform() * MAX_ACTIONS as f64) as usize).unwrap();
                let mut car = CarState {
                    pose,
                    speed: uniform() * 4.0,
                    steering: (uniform() - 0.5) * 2.0 * p.max_steering,
                };
                let command = uniform() * 4.0;
                let tracker = Tracker::new(pose, firmware_core::lattice::trajectory(action));
                let dt = 0.01;
                let travel = footprint.travel(10, dt, car.speed.max(command));
                let is_clear = footprint.clear_within(&map, pose, pose.rotation(), travel);
                let mut any = false;
                for _ in 0..10 {
                    let steer = tracker.steering(car.pose, &p);
                    car.step(&p, steer, command, dt);
                    any |= p.footprint_hits(&map, car.pose);
                }
                assert!(!(is_clear && any), "{}: {pose:?}", s.name);
                if is_clear {
                    clear += 1;
                } else {
                    unclear += 1;
                    hit += u32::from(any);
                }
            }
        }
        assert!(
            clear > 2000 && unclear > 2000 && hit > 200,
            "{clear} {unclear} {hit}"
        );
    }

    #[test]
    fn sin_cos_is_libms_sin_and_cos() {
        // Every branch of libm's reduction: tiny, below π/4, medium and huge arguments, both
        // signs, the binade edges of its thresholds, the infinities and NaN, and many random
        // bit patterns.
        let mut xs = vec![
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            5e-324,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MAX,
            std::f64::consts::FRAC_PI_4,
            std::f64::consts::PI,
            1e22,
        ];
        for high in [
            0x3e46a09e_u64,
            0x3e500000,
            0x3fe921fb,
            0x4002d97c,
            0x400f6a7a,
            0x413921fb,
        ] {
            for low in [0u64, 1, 0x7fff_ffff, 0xffff_ffff] {
                for delta in [-1i64, 0, 1] {
                    let bits = ((high << 32) | low).wrapping_add_signed(delta);
                    xs.push(f64::from_bits(bits));
                }
            }
        }
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for i in 0..400_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            xs.push(if i % 2 == 0 {
                f64::from_bits(state)
            } else {
                // Headings, as the car has them.
                ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 20.0
            });
        }
        for x in xs {
            for x in [x, -x] {
                let (s, c) = sin_cos(x);
                assert_eq!(s.to_bits(), libm::sin(x).to_bits(), "sin {x:e}");
                assert_eq!(c.to_bits(), libm::cos(x).to_bits(), "cos {x:e}");
            }
        }
    }

    #[test]
    fn step_turned_returns_the_new_headings_rotation_bit_for_bit() {
        // Circles both ways (the heading wraps at ±π), straight runs and a stop, from a few
        // headings: the rotation handed on is the one the new pose gives.
        let p = CarParams::MUSHR;
        let (mut wrapped, mut arcs) = (0, 0);
        for theta in [0.0, 3.1, -3.1, 1.0] {
            let mut car = CarState::at(Pose {
                x: 0.0,
                y: 0.0,
                theta,
            });
            let mut rotation = car.pose.rotation();
            for i in 0..3000 {
                let (cmd, speed) = match i / 500 {
                    0 | 3 => (0.34, 1.0),
                    1 | 4 => (-0.34, 1.5),
                    2 => (0.0, 1.0),
                    _ => (0.0, 0.0),
                };
                let before = car.pose.theta;
                let mut plain = car;
                plain.step(&p, cmd, speed, 0.01);
                rotation = car.step_turned(&p, cmd, speed, 0.01, rotation);
                assert_eq!(plain, car, "step and step_turned agree");
                let want = car.pose.rotation();
                assert_eq!(rotation.cos_angle().to_bits(), want.cos_angle().to_bits());
                assert_eq!(rotation.sin_angle().to_bits(), want.sin_angle().to_bits());
                arcs += usize::from(before != car.pose.theta);
                wrapped += usize::from((before - car.pose.theta).abs() > 3.0);
            }
        }
        assert!(arcs > 1000 && wrapped > 4, "{arcs} arcs, {wrapped} wraps");
    }

    #[test]
    fn the_clearance_shortcut_gives_the_sampled_answer() {
        let s = crate::world::registry::load_scenario("stairs-chairs").unwrap();
        let car = CarParams::MUSHR;
        let map = &s.map;
        let step = map.resolution() / 2.0;
        let nx = libm::ceil(car.length / step) as usize;
        let ny = libm::ceil(car.width / step) as usize;
        let sampled = |pose: Pose| {
            let (sn, c) = (libm::sin(pose.theta), libm::cos(pose.theta));
            let cx = pose.x + car.center_offset * c;
            let cy = pose.y + car.center_offset * sn;
            (0..=nx).any(|i| {
                let u = -car.length / 2.0 + car.length * i as f64 / nx as f64;
                (0..=ny).any(|j| {
                    let v = -car.width / 2.0 + car.width * j as f64 / ny as f64;
                    map.is_blocked(cx + u * c - v * sn, cy + u * sn + v * c)
                })
            })
        };
        let (mut hits, mut misses) = (0, 0);
        for i in 0..170 {
            for j in 0..120 {
                for k in 0..3 {
                    let pose = Pose {
                        x: 0.1 * i as f64 + 0.013,
                        y: 0.1 * j as f64 + 0.007,
                        theta: 0.7 * k as f64,
                    };
                    let want = sampled(pose);
                    assert_eq!(car.footprint_hits(map, pose), want, "{pose:?}");
                    if want { hits += 1 } else { misses += 1 }
                }
            }
        }
        assert!(hits > 1000 && misses > 1000, "{hits} {misses}");
    }

    /// The projection as it was written before the segments were stored one array per
    /// quantity: one loop over the segments with nalgebra's `dot` and `norm_squared`, a division
    /// only for a segment of some length.
    fn station_one_segment_at_a_time(tr: &Tracker, at: Point2<f64>) -> f64 {
        let g = &tr.segments;
        let mut best = (0.0f64, f64::INFINITY);
        for i in 0..SAMPLES {
            let (a, d) = (
                Point2::new(g.ax[i], g.ay[i]),
                Vector2::new(g.dx[i], g.dy[i]),
            );
            let t = if g.len2[i] > 0.0 {
                ((at - a).dot(&d) / g.len2[i]).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let d2 = (at - (a + d * t)).norm_squared();
            if d2 < best.1 {
                best = (g.s0[i] + t * g.len[i], d2);
            }
        }
        best.0
    }

    #[test]
    fn the_projection_is_the_segment_by_segment_one_bit_for_bit() {
        let mut uniform = crate::world::test_uniform(17);
        let mut n = 0;
        for _ in 0..2_000 {
            for a in ActionIndex::all() {
                let origin = Pose {
                    x: 20.0 * uniform() - 10.0,
                    y: 20.0 * uniform() - 10.0,
                    theta: 7.0 * uniform() - 3.5,
                };
                let tr = Tracker::new(origin, trajectory(a));
                // Around the trajectory, and on its first point (a projection at its start).
                let pose = if n % 7 == 0 {
                    origin
                } else {
                    Pose {
                        x: origin.x + 2.4 * uniform() - 1.2,
                        y: origin.y + 2.4 * uniform() - 1.2,
                        theta: origin.theta + uniform() - 0.5,
                    }
                };
                n += 1;
                assert_eq!(
                    tr.station(pose.position()).to_bits(),
                    station_one_segment_at_a_time(&tr, pose.position()).to_bits(),
                    "{a}: {origin:?} {pose:?}"
                );
            }
        }
    }

    #[test]
    fn a_narrowed_projection_is_the_whole_one_bit_for_bit() {
        let mut uniform = crate::world::test_uniform(29);
        let mut narrowed = 0;
        for _ in 0..500 {
            for a in ActionIndex::all() {
                let origin = Pose {
                    x: 20.0 * uniform() - 10.0,
                    y: 20.0 * uniform() - 10.0,
                    theta: 7.0 * uniform() - 3.5,
                };
                let whole = Tracker::new(origin, trajectory(a));
                let mut tr = whole.clone();
                let travel = 0.3 * uniform();
                // From the start (as a tick narrows) or a point near the trajectory.
                let from = if uniform() < 0.5 {
                    origin.position()
                } else {
                    Point2::new(origin.x + uniform() - 0.5, origin.y + uniform() - 0.5)
                };
                tr.narrow_within(travel);
                assert_eq!(tr.station(from).to_bits(), whole.station(from).to_bits());
                narrowed += usize::from(tr.near.get() < SAMPLES);
                for _ in 0..8 {
                    // Within `travel` of `from` (up to its boundary).
                    let (r, phi) = (travel * uniform().sqrt(), 7.0 * uniform());
                    let at = Point2::new(from.x + r * phi.cos(), from.y + r * phi.sin());
                    assert_eq!(
                        tr.station(at).to_bits(),
                        whole.station(at).to_bits(),
                        "{a}: {origin:?} {from:?} {at:?} {travel}"
                    );
                }
            }
        }
        // The narrowing leaves segments out on most of these.
        assert!(narrowed > 500 * MAX_ACTIONS / 4, "{narrowed}");
    }

    #[test]
    fn the_car_follows_every_trajectory_closely() {
        let p = CarParams::MUSHR;
        let dt = 1.0 / p.physics_hz as f64;
        for a in ActionIndex::all() {
            let t = trajectory(a);
            // Start already moving at the trajectory's speed with the first segment's steering,
            // as in steady driving.
            let mut car = CarState::at(Pose::default());
            car.speed = t.speed as f64;
            car.steering = libm::atan(t.segments[0].curvature as f64 * p.wheelbase);
            let tr = Tracker::new(Pose::default(), t);
            let steps = (t.length() as f64 / t.speed as f64 / dt).round() as usize;
            for _ in 0..steps {
                let d = tr.steering(car.pose, &p);
                car.step(&p, d, tr.speed(), dt);
            }
            let e = t.end();
            let err =
                ((car.pose.x - e.x as f64).powi(2) + (car.pose.y - e.y as f64).powi(2)).sqrt();
            assert!(err < 0.06, "{a}: end error {err} m");
        }
    }

    #[test]
    fn wrap_angle_is_its_formula_bit_for_bit() {
        // The formula with `floor` for every angle, the shortcut where the floor is 0: random
        // angles, those near every multiple of π up to ±9π (a few ulps either side), ±0,
        // tiny ones and the non-finite.
        use std::f64::consts::PI;
        let formula = |a: f64| {
            let mut w = a - 2.0 * PI * libm::floor((a + PI) / (2.0 * PI));
            if w > PI {
                w -= 2.0 * PI;
            }
            if w < -PI {
                w += 2.0 * PI;
            }
            w
        };
        let mut angles = vec![
            0.0,
            -0.0,
            1e-300,
            -1e-300,
            f64::NAN,
            f64::INFINITY,
            -f64::INFINITY,
        ];
        for k in -9..=9 {
            let centre = f64::from(k) * PI;
            let mut up = centre;
            let mut down = centre;
            for _ in 0..40 {
                angles.extend([up, down]);
                up = up.next_up();
                down = down.next_down();
            }
        }
        let mut uniform = crate::world::test_uniform(0x0bad_5eed_1234_5678);
        angles.extend((0..200_000).map(|_| (uniform() - 0.5) * 40.0));
        angles.extend((0..200_000).map(|_| (uniform() - 0.5) * 2.0 * PI));
        for a in angles {
            assert_eq!(wrap_angle(a).to_bits(), formula(a).to_bits(), "{a:e}");
        }
    }

    #[test]
    fn footprint_and_frames() {
        let map = OccupancyGrid::from_fn(40, 40, 0.05, [0.0, 0.0, 0.0], |c, _| c >= 30);
        let p = CarParams::MUSHR;
        // Wall starts at x = 1.5; the footprint's front is 0.15 + 0.25 = 0.4 m ahead.
        assert!(!p.footprint_hits(
            &map,
            Pose {
                x: 1.05,
                y: 1.0,
                theta: 0.0
            }
        ));
        assert!(p.footprint_hits(
            &map,
            Pose {
                x: 1.12,
                y: 1.0,
                theta: 0.0
            }
        ));
        let pose = Pose {
            x: 1.0,
            y: 2.0,
            theta: 0.7,
        };
        let w = pose.to_world(Point2::new(0.3, -0.2));
        let l = pose.to_local(w);
        let (lx, ly) = (l.x, l.y);
        assert!((lx - 0.3).abs() < 1e-12 && (ly + 0.2).abs() < 1e-12);
        assert!(
            (wrap_angle(3.0 * std::f64::consts::PI).abs() - std::f64::consts::PI).abs() < 1e-12
        );
        assert!((wrap_angle(-7.0) - (-7.0 + 2.0 * std::f64::consts::PI)).abs() < 1e-12);
    }
}
