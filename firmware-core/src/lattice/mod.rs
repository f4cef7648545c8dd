//! The 64 candidate trajectories, fixed at compile time.
//!
//! Every trajectory starts at the car frame's origin (the rear axle), heading along `x`, and is
//! made of two constant-curvature segments that a kinematic bicycle (wheelbase [`WHEELBASE`])
//! follows exactly with the segment's steering angle. Two families:
//!
//! * **Cruise** (actions 0–48): two 0.5 m segments at [`CRUISE_SPEED`], each with a curvature
//!   among `κ_max · {0, ±1/3, ±2/3, ±1}` (7 × 7 = 49 shapes). Equal curvatures make arcs
//!   (straight included); opposite curvatures make **lane shifts** that move sideways and end
//!   parallel to the start (up to ±0.26 m); the rest turn then hold, or hold then turn.
//! * **Creep** (actions 49–63): one 0.5 m arc at [`CREEP_SPEED`], curvature among
//!   `κ_max · {0, ±1/7, …, ±1}`: slow, finely graded moves for tight spots.
//!
//! `κ_max = tan(0.30 rad) / 0.29 m ≈ 1.067 /m` (see [`MAX_PLANNING_STEERING`]). Each trajectory is
//! sampled at [`SAMPLES`] poses evenly spaced along its length (every 0.1 m for cruise, every
//! 0.05 m for creep), the last one at its end, for the tracking controller; clearances are measured
//! every 0.1 m of arc ([`Trajectory::samples`]).
//!
//! Indices are ordered gentlest first, each left-turning shape followed by its mirror image:
//! action 0 is the straight cruise trajectory, so a zero weight vector (all scores tie, the
//! lowest index wins) drives straight. [`Trajectory::mirror`] gives the mirror image of every
//! action; [`mirror_action`] maps indices.
//!
//! ```text
//!   y (left)                 cruise shapes, seen from above (x forward):
//!   ▲     ╭──      arc  (κ, κ)          ╭─── lane shift (κ, −κ): ends parallel, offset
//!   │   ╭─╯                           ╭─╯
//!   ●───────▶ x  straight (0, 0)   ●──╯        turn-and-hold (κ, 0), hold-and-turn (0, κ)
//! ```
//!
//! `host-sim lattice` draws the whole lattice to an SVG.
//!
//! ```
//! use firmware_core::lattice::{trajectory, Family, SAMPLES};
//! use firmware_core::ActionIndex;
//!
//! let straight = trajectory(ActionIndex::new(0).unwrap());
//! assert_eq!(straight.family, Family::Cruise);
//! let end = straight.end();
//! assert!((end.x - 1.0).abs() < 1e-6 && end.y == 0.0);
//! assert_eq!(straight.poses().len(), SAMPLES);
//! ```

mod params;

pub use params::*;

use nalgebra::{Isometry2, Point2, Translation2, UnitComplex};

use crate::action::{ActionIndex, MAX_ACTIONS};

/// A pose in the car frame, as the generated tables hold it: position and heading angle. The
/// geometry is [`Pose::isometry`]'s.
#[derive(Clone, Copy, PartialEq, Debug, Default)]
pub struct Pose {
    /// Forward (m).
    pub x: f32,
    /// Left (m).
    pub y: f32,
    /// Heading (rad, counter-clockwise).
    pub theta: f32,
}

impl Pose {
    /// Where the rear axle is.
    pub fn position(&self) -> Point2<f32> {
        Point2::new(self.x, self.y)
    }

    /// The heading as a rotation (cosine and sine from `libm`, the same bits on every target).
    pub fn rotation(&self) -> UnitComplex<f32> {
        UnitComplex::from_cos_sin_unchecked(libm::cosf(self.theta), libm::sinf(self.theta))
    }

    /// The pose as an isometry: from the frame of the car at this pose to the car frame.
    pub fn isometry(&self) -> Isometry2<f32> {
        Isometry2::from_parts(Translation2::new(self.x, self.y), self.rotation())
    }
}

/// One constant-curvature piece of a trajectory.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Segment {
    /// Curvature (1/m, positive turning left).
    pub curvature: f32,
    /// Arc length (m).
    pub length: f32,
    /// The bicycle model's steering angle for this curvature, `atan(κ · WHEELBASE)` (rad).
    pub steering: f32,
}

/// Which family a trajectory belongs to.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Family {
    /// 1 m, two segments, cruise speed.
    Cruise,
    /// 0.5 m, one arc, creep speed.
    Creep,
}

/// One candidate trajectory: what the tracking controller follows and what the evaluator scores.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Trajectory {
    /// Its family.
    pub family: Family,
    /// The two segments, in order.
    pub segments: [Segment; 2],
    /// The speed to drive it at (m/s).
    pub speed: f32,
    /// Its action's index, into the tables of its poses and samples.
    index: u8,
    sample_count: u8,
    mirror: u8,
}

impl Trajectory {
    /// Total length (m).
    pub fn length(&self) -> f32 {
        self.segments[0].length + self.segments[1].length
    }

    /// The points clearances and collisions are measured from, `[x, y]`: the centre of the car's
    /// footprint ([`FOOTPRINT_CENTER_OFFSET`] ahead of the rear axle) every [`SAMPLE_SPACING`] of
    /// arc, the last at the end. Ten on a cruise trajectory, five on a creep one.
    pub fn samples(&self) -> &[[f32; 2]] {
        let points = &TRAJECTORY_SAMPLES[usize::from(self.index) & (MAX_ACTIONS - 1)];
        &points[..(self.sample_count as usize).clamp(1, SAMPLES)]
    }

    /// [`SAMPLES`] poses evenly spaced along it, the last at its end (in a table of their own:
    /// the car's image, which reads only the segments, does not hold them).
    pub fn poses(&self) -> &'static [Pose; SAMPLES] {
        &TRAJECTORY_POSES[usize::from(self.index) & (MAX_ACTIONS - 1)]
    }

    /// The last pose.
    pub fn end(&self) -> Pose {
        self.poses()[SAMPLES - 1]
    }

    /// The action whose trajectory is this one mirrored along the car's axis.
    pub fn mirror(&self) -> ActionIndex {
        // Generated tables hold indices below MAX_ACTIONS (checked in the tests).
        ActionIndex::new(self.mirror as usize).unwrap_or(ActionIndex::FIRST)
    }

    /// The steering angle and the curvature at arc length `s` from the start (the second segment's
    /// beyond the end).
    pub fn segment_at(&self, s: f32) -> &Segment {
        if s < self.segments[0].length {
            &self.segments[0]
        } else {
            &self.segments[1]
        }
    }
}

/// The beams whose scan point may come within some distance of one sample point: those in a
/// window of bearings and in a band of range bins (see [`crate::evaluator`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Reach {
    /// The window, one bit per beam: beams 0–31, then 32–63.
    pub(crate) window: [u32; 2],
    /// The band: range bins `bins[0]..bins[1]` (each [`RANGE_BIN_WIDTH`] wide).
    pub(crate) bins: [u8; 2],
    /// The window is the half plane ahead of a centre nearer the sensor than the distance: the
    /// beams shorter than the distance may reach it from behind, whatever their bearing.
    pub(crate) behind: bool,
}

/// Nearby distinct samples, pruned together by the evaluator: the samples
/// `samples[0]..samples[1]`, all within `spread` of `centre`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cluster {
    /// The centre, `[x, y]` (m).
    pub(crate) centre: [f32; 2],
    /// Largest distance of a member from the centre (m), rounded up.
    pub(crate) spread: f32,
    /// The members: sample indices `samples[0]..samples[1]`.
    pub(crate) samples: [u16; 2],
    /// The trajectories some member belongs to, one bit per action.
    pub(crate) trajectories: u64,
    /// The beams that may come within [`OBSTACLE_CLIP`] of a member.
    pub(crate) clip: Reach,
}

/// Nearby clusters, which the semantic pass tests as one where it can: the clusters
/// `REGION_CLUSTERS[clusters[0]..clusters[1]]`, whose members are the samples
/// `samples[0]..samples[1]`, all within `spread` of `centre`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Region {
    /// The centre, `[x, y]` (m).
    pub(crate) centre: [f32; 2],
    /// Largest distance of a member from the centre (m), rounded up.
    pub(crate) spread: f32,
    /// The members of its clusters: sample indices `samples[0]..samples[1]`.
    pub(crate) samples: [u16; 2],
    /// Its clusters: `REGION_CLUSTERS[clusters[0]..clusters[1]]`.
    pub(crate) clusters: [u8; 2],
    /// The trajectories some member belongs to, one bit per action.
    pub(crate) trajectories: u64,
}

include!(concat!(env!("OUT_DIR"), "/lattice_tables.rs"));

/// The trajectory of action `a`.
#[inline]
pub fn trajectory(a: ActionIndex) -> &'static Trajectory {
    &TRAJECTORIES[a.get()]
}

/// The mirror image of action `a`.
#[inline]
pub fn mirror_action(a: ActionIndex) -> ActionIndex {
    trajectory(a).mirror()
}

const _: () = assert!(MAX_ACTIONS == 64, "the lattice has 64 trajectories");
const _: () = assert!(
    MAX_CLUSTER_SPREAD <= CLUSTER_SPREAD * 1.001,
    "build.rs halves clusters down to CLUSTER_SPREAD"
);
const _: () = assert!(
    (CRUISE_LEVELS * CRUISE_LEVELS + CREEP_LEVELS) == MAX_ACTIONS,
    "cruise and creep families fill the 64 actions"
);

#[cfg(test)]
mod tests {
    use super::*;

    fn all() -> impl Iterator<Item = (ActionIndex, &'static Trajectory)> {
        ActionIndex::all().map(|a| (a, trajectory(a)))
    }

    #[test]
    fn families_and_lengths() {
        for (a, t) in all() {
            let expected = if a.get() < 49 {
                Family::Cruise
            } else {
                Family::Creep
            };
            assert_eq!(t.family, expected, "{a}");
            let len = if t.family == Family::Cruise { 1.0 } else { 0.5 };
            assert!((t.length() - len).abs() < 1e-6);
            // Consecutive samples are one step of arc length apart (chords of gentle arcs).
            let mut prev = Pose::default();
            for p in t.poses() {
                let d = (p.position() - prev.position()).norm();
                assert!((d - len / SAMPLES as f32).abs() < 2e-3, "{a}: step {d}");
                prev = *p;
            }
        }
    }

    #[test]
    fn steering_and_curvature_are_within_the_car_s_limits() {
        for (_, t) in all() {
            for s in &t.segments {
                assert!(s.steering.abs() <= MAX_PLANNING_STEERING + 1e-6);
                assert!((s.curvature - libm::tanf(s.steering) / WHEELBASE).abs() < 1e-5);
                assert!(s.curvature.abs() <= MAX_CURVATURE + 1e-6);
            }
        }
    }

    #[test]
    fn straight_first_and_mirrors_pair_up() {
        let t0 = trajectory(ActionIndex::FIRST);
        // Mirror images are neighbours: the left-turning one first.
        for (a, t) in all() {
            let m = t.mirror().get();
            assert!(m == a.get() || m.abs_diff(a.get()) == 1, "{a} <-> {m}");
        }
        assert!(t0.poses().iter().all(|p| p.y == 0.0 && p.theta == 0.0));
        for (a, t) in all() {
            let m = trajectory(t.mirror());
            assert_eq!(m.mirror(), a, "mirror is an involution");
            for (p, q) in t.poses().iter().zip(m.poses().iter()) {
                assert_eq!((p.x, p.y, p.theta), (q.x, -q.y, -q.theta), "{a}");
            }
        }
    }

    #[test]
    fn lane_shifts_end_parallel_and_offset() {
        let mut shifts = 0;
        for (_, t) in all() {
            let [s1, s2] = t.segments;
            if t.family == Family::Cruise && s1.curvature != 0.0 && s1.curvature == -s2.curvature {
                shifts += 1;
                let end = t.end();
                assert!(end.theta.abs() < 1e-6, "ends parallel");
                assert!(end.y.abs() > 0.05, "moved sideways");
            }
        }
        assert_eq!(shifts, 6, "three offsets each side");
    }

    #[test]
    fn sample_tables_are_consistent() {
        for (a, t) in all() {
            // Its samples are its own action's.
            assert_eq!(usize::from(t.index), a.get());
            let n = t.samples().len();
            assert_eq!(n, if t.family == Family::Cruise { 10 } else { 5 });
            for (k, &u) in SAMPLE_OF[a.get()][..n].iter().enumerate() {
                // Sample k sits (k + 1) · 0.1 m along the trajectory: pose 2k + 1 of a creep one.
                let p = if t.family == Family::Cruise {
                    t.poses()[k]
                } else {
                    t.poses()[2 * k + 1]
                };
                let [x, y] = SAMPLE_POINTS[u as usize];
                assert_eq!([x, y], t.samples()[k]);
                let centre = p
                    .isometry()
                    .transform_point(&Point2::new(FOOTPRINT_CENTER_OFFSET, 0.0));
                assert!((Point2::new(x, y) - centre).norm() < 1e-5, "{a}/{k}");
            }
        }
        // Every sample knows its trajectories, and belongs to one cluster, within its spread.
        for (a, t) in all() {
            let n = t.samples().len();
            for &u in &SAMPLE_OF[a.get()][..n] {
                assert!(SAMPLE_TRAJECTORIES[u as usize] >> a.get() & 1 == 1);
            }
        }
        let memberships: u32 = SAMPLE_TRAJECTORIES.iter().map(|m| m.count_ones()).sum();
        let samples: usize = all().map(|(_, t)| t.samples().len()).sum();
        assert_eq!(memberships as usize, samples);
        let mut pairs = 0;
        let beams = |r: &Reach| (r.window[0].count_ones() + r.window[1].count_ones()) as usize;
        // Regions tile the samples, and their clusters tile the region's samples, in
        // `REGION_CLUSTERS` order; every cluster is in one region.
        let mut next = 0;
        let mut seen = [false; CLUSTERS.len()];
        for r in &REGIONS {
            let [start, end] = r.samples.map(usize::from);
            assert!(start == next && start < end, "regions tile the samples");
            let mut member = start;
            let mut trajectories = 0;
            for &i in &REGION_CLUSTERS[usize::from(r.clusters[0])..usize::from(r.clusters[1])] {
                let c = &CLUSTERS[usize::from(i)];
                assert!(!seen[usize::from(i)]);
                seen[usize::from(i)] = true;
                let [s, e] = c.samples.map(usize::from);
                assert!(s == member && s < e, "clusters tile their region's samples");
                member = e;
                trajectories |= c.trajectories;
            }
            assert_eq!(member, end);
            assert_eq!(trajectories, r.trajectories);
            for u in start..end {
                let [x, y] = SAMPLE_POINTS[u];
                let d = libm::hypotf(x - r.centre[0], y - r.centre[1]);
                assert!(d <= r.spread && r.spread <= MAX_REGION_SPREAD, "{u}");
            }
            next = end;
        }
        assert_eq!(next, UNIQUE_SAMPLES);
        assert!(seen.iter().all(|&s| s));
        for c in &CLUSTERS {
            let [start, end] = c.samples.map(usize::from);
            let mut trajectories = 0;
            for u in start..end {
                let [x, y] = SAMPLE_POINTS[u];
                let d = libm::hypotf(x - c.centre[0], y - c.centre[1]);
                assert!(d <= c.spread && c.spread <= MAX_CLUSTER_SPREAD, "{u}");
                assert!(libm::hypotf(x, y) <= MAX_SAMPLE_RHO);
                trajectories |= SAMPLE_TRAJECTORIES[u];
            }
            assert_eq!(trajectories, c.trajectories);
            assert!(usize::from(c.clip.bins[1]) <= RANGE_BINS);
            pairs += beams(&c.clip) * (end - start);
        }
        assert_eq!(pairs, WINDOW_PAIRS);
    }
}
