//! From one observation, the collision mask and the features of the 64 trajectories.
//!
//! # Features (paper, section 6), and why these scales
//!
//! For trajectory `a` with footprint-centre samples `c_1 … c_n` every 0.1 m of arc (see
//! [`Trajectory::samples`](crate::lattice::Trajectory::samples); `n` = 10 for cruise, 5 for creep)
//! and end pose `e`, with `k = 10 / n` so that every trajectory counts as ten samples:
//!
//! | feature | value | range |
//! |---|---|---|
//! | [`Feature::Obstacles`] | `k · Σ_i min(d_scan(c_i), 0.5 m) / 0.5 m` | 0 … 10 |
//! | [`Feature::Door`], [`Feature::Stairs`], [`Feature::Chair`] | `k · Σ_i min(d_class(c_i), 2 m) / 2 m` | 0 … 10 |
//! | [`Feature::Path`] | `min(|along| + |cross|, 4 m)`, in metres, of `e` against the path reference | 0 … 4 |
//! | [`Feature::Right`] | `−10 · e.y` (decimetres, right positive) | −4.9 … 4.9 |
//!
//! `d_scan` is the distance to the nearest scan point, `d_class` to the nearest object of the class
//! (0 inside its disc). A class with no detected object reads 10 for every trajectory, so it
//! does not move the argmax.
//!
//! The scales make every feature a number of order 1–10 whose spread across the 64 actions is a
//! few units: a teacher's weights of order 1 then give latent losses of order 1–10, the scale of
//! the paper's correction threshold (1.0) and of its plots, and one step of `η = 0.01` moves a
//! score by a few hundredths, so the hinge's margin of 100 is reached only after many consistent
//! corrections, as in the paper. The clips say what matters: an obstacle beyond 0.5 m of the
//! footprint's centre (0.35 m of its side) no longer changes a trajectory's worth; a door two
//! metres away still does, since the teacher wants it avoided before it is close.
//!
//! # Collisions
//!
//! A trajectory collides, and is cleared from the mask, when any of its samples lies closer than
//! [`COLLISION_RADIUS`] = half the car's width (0.15 m) + a 0.10 m margin to a scan point. The
//! margin covers the footprint's corners near the sample (0.29 m from its centre) in part, the
//! gaps between beams and the tracking error of the controller.
//!
//! A colliding trajectory is never chosen and never judged (the policy, the pseudo-losses and
//! [`Round`](crate::Round) read the rows of allowed actions only), so its features are not
//! computed: **its row is all zeros.** Every other row is complete.
//!
//! # Cost: exact, not brute force
//!
//! A brute-force evaluator measures every (trajectory, sample, beam): 64 × 10 × 64 = 40 960
//! distances. This one gives the same mask and the same features (bit for bit, whatever the
//! pruning) with a small fraction of that:
//!
//! 1. the 565 samples of the lattice are only 351 distinct points (trajectories share their
//!    starts), measured once each, and sums along trajectories share their common heads;
//! 2. `build.rs` groups nearby samples into clusters (every member within 0.15 m of the
//!    cluster's centre; the samples at the same arc length of trajectories that start
//!    together lie on a short arc). For a centre at range `ρ` and bearing `α`, a scan point on the
//!    beam at bearing `β` is at least `ρ·sin|α − β|` away (at least `ρ` beyond 90°), and at least
//!    `|r − ρ|` for a range `r`: at compile time each cluster gets the window of beams within
//!    `asin(d/ρ)` of `α` (with a 0.01 rad margin) and the band of range bins within `d` of `ρ`,
//!    for `d` = the 0.5 m clip + the spread. Each tick sorts the beams into range bins (0.15 m
//!    wide) once, leaving out every beam longer than its own reach (`build.rs`: the farthest
//!    range at which that beam's point comes within the clip of some sample), which is never
//!    looked at again, and a cluster's candidates are its window ANDed with its band: two 32-bit
//!    masks. In open space no beam is within reach and the obstacle pass ends there;
//! 3. from the cluster's centre, with `m` the distance to its nearest candidate and `s` the
//!    spread, every member is within `m + s` of that point, so a point farther than `m + 2s`
//!    from the centre is nobody's nearest: the members measure only the candidates within
//!    `m + 2s` (the near set), usually one to three;
//! 4. clusters are visited farthest first: a sample's nearest distance decides its collision,
//!    and the samples whose trajectories all collide already are skipped, and so are the
//!    members of a cluster with no candidate within the clip plus its spread (and a
//!    millimetre); then the semantic features run over the clusters some trajectory that does not
//!    collide uses (every member of such a cluster: measuring a member that no such trajectory
//!    uses costs less than testing it; a cluster near no object writes the clip, so no sample is
//!    filled beforehand), and the sums over the trajectories that do not collide only; every
//!    clearance feature of an allowed row starts as ten clips, in one pass with the path and
//!    side features, and only a trajectory with a sample within a clip takes a sum. Semantic objects are
//!    pruned per cluster the same way (reach, and an object that is farther than another for
//!    every member), and where the centre's distance settles a test for every member at once
//!    (outside the disc, within the clip, inside the disc), a loop without it runs. The whole
//!    lattice is such a cluster too (`LATTICE`, tested first): an object that another is
//!    farther than for every sample is left out of every cluster's tests, and where one object
//!    alone is within the clip and outside its disc for every sample, no cluster is tested at
//!    all; a cluster whose centre's squared distance from a lone object lies in a band set once
//!    per object for the largest spread takes that loop without the centre's root. Between the
//!    two, `build.rs` groups nearby clusters into eight regions (k-means on their centres; the
//!    samples are numbered region by region, so a region's members are consecutive too), each
//!    with a centre and a spread, tested before its clusters with the same tests and margins: a
//!    region out of every object's reach writes the clip into its clusters; where one object
//!    alone is within reach (or the other is farther for every member, told by the side of
//!    their bisector, with a bound for the regions' largest spread), and the region is within
//!    its clip and outside its disc, its clusters take the roots without a test each (one loop
//!    over the region's samples when every trajectory through it is allowed), and where it is
//!    outside the disc only, and every trajectory through it allowed, one loop of the cluster's
//!    outside-the-disc kind runs over its samples; any other region tests its clusters one by
//!    one.
//!
//! Every skipped beam, object or test is provably irrelevant (each decision keeps a 1 mm margin,
//! far above the rounding of these distances), so pruning changes no result.
//!
//! Square roots use [`sqrt`], a seed and two Newton steps with relative error at most
//! [`SQRT_RELATIVE_ERROR`] (a Cortex-M4 spends about 70 instructions on `libm`'s correctly
//! rounded one, 8 on this). Collisions are decided on squared distances, without any root. So,
//! against a brute-force evaluator with exact square roots (the naive std implementation in
//! `tests/integration/support/naive.rs`), the collision mask is identical and every feature is
//! within [`FEATURE_ERROR_BOUND`]:
//!
//! * an obstacle clearance is at most 0.5 m, off by at most 0.5 × 3e-7; ten of them and the
//!   rounding of their sum stay below 1e-5 after the division by 0.5;
//! * a semantic clearance below its 2 m clip comes from a centre distance below 7 m (clip + the
//!   largest radius), off by at most 7 × 3e-7; ten of them stay below 2e-5 after the division by 2;
//! * path and side features take no root and are exact.
//!
//! The bound below leaves a factor of five. Host and car run the same operations, so they agree
//! bit for bit regardless.
//!
//! # On the host
//!
//! The pruning above is tuned for the car's instruction counts (cheap branches, one `f32` at a
//! time). A host that computes several `f32`s side by side (`policy::WIDE`: every target but
//! `arm`) takes other exact algorithms, without the branches and the bookkeeping that only skip
//! work, on the samples sixteen at a time (`LANES`, one array per coordinate; the lanes past the
//! last sample lie far from everything):
//!
//! * the obstacle pass takes every scan point within reach (the beams the car's pass bins: 6.8
//!   a tick on average on `doors`), one after the other, to each chunk of samples a table made
//!   by `build.rs` does not leave out for it (`BEAM_CHUNKS`: per beam and range bin, the chunks
//!   some sample of which a point of that beam and bin may come within the clip of), each lane
//!   keeping its least squared distance in its clearance slot: no clusters, windows, bands or
//!   near sets. The least
//!   over those points is the car's least over the cluster's near set whenever it is below the
//!   clip's square (that point is in both sets), and both read the clip's square otherwise, so
//!   every collision test and clearance comes from the same number; what the car's pass skips
//!   (a cluster beyond the clip, one within the collision radius of its centre's nearest point,
//!   the members whose trajectories all collide already) is what these give too, or is never
//!   read;
//! * the semantic pass takes, object by object, every lane of the chunks whose bounding box is
//!   within the object's reach to the least of the clip and its clearance, by one formula
//!   without a branch (no per-cluster loops, cases or dominance test);
//! * the rows start from the path and side features of every action (the car's
//!   `PathFrame::path_and_side_of`), then are written whole (and the colliding ones zeroed).
//!
//! Each value comes from the same operations as on the car, so the masks and rows are the same
//! bits (tested on random observations against the car's paths, run on the host).
//!
//! ```
//! use firmware_core::evaluator::Evaluator;
//! use firmware_core::observation::Observation;
//! use firmware_core::{FeatureTable, ActionMask};
//!
//! let mut evaluator = Evaluator::new();
//! let mut table = FeatureTable::ZERO;
//! let obs = Observation::open_space();
//! let allowed = evaluator.evaluate(obs.check().unwrap(), &mut table);
//! assert_eq!(allowed, ActionMask::ALL); // nothing to hit
//! ```

use nalgebra::{Isometry2, Point2, Translation2, UnitComplex};

use crate::action::{ActionMask, MAX_ACTIONS};
use crate::feature::{FEATURE_COUNT, Feature, FeatureTable, Features};
use crate::lattice::{
    BEAM_COS, BEAM_REACH, BEAM_SIN, CLUSTERS, Cluster, END_POINTS, HEAD_COUNT, HEAD_LEN, HEAD_OF,
    HEADS, LATTICE, MAX_CLUSTER_SPREAD, MAX_REGION_SPREAD, MAX_SAMPLE_RHO, OBSTACLE_CLIP,
    PAD_SAMPLE, RANGE_BIN_WIDTH, RANGE_BINS, REACH_MARGIN, REGION_CLUSTERS, REGIONS, ROW_SCALE,
    Reach, Region, SAMPLE_POINTS, SAMPLE_TRAJECTORIES, SAMPLES, SCAN_BEAMS, TAIL_LEN, TAIL_OF,
    UNIQUE_SAMPLES,
};
use crate::observation::{
    MAX_OBJECTS, Observation, PathReference, SemanticClass, ValidObservation,
};
use crate::policy::WIDE;
use crate::trig::sincosf;

#[cfg(not(target_arch = "arm"))]
use crate::lattice::{BEAM_CHUNKS, LANES};

pub use crate::lattice::COLLISION_RADIUS;

/// Clearances to semantic objects are clipped at this distance (m).
pub const SEMANTIC_CLIP: f32 = 2.0;

/// Largest difference between a feature of this evaluator and the same feature computed with
/// exact square roots (see the module documentation for the derivation; tested).
pub const FEATURE_ERROR_BOUND: f32 = 1.0e-4;

/// The path error is clipped at this value (m).
pub const PATH_CLIP: f32 = 4.0;

/// [`Feature::Right`] is the end's lateral offset in these units per metre (decimetres).
pub const RIGHT_SCALE: f32 = 10.0;

const _: () = assert!(
    OBSTACLE_CLIP <= 1.0,
    "the clip is not below its square (a wide target's obstacle pass tells them apart)"
);
const _: () = assert!(
    COLLISION_RADIUS < OBSTACLE_CLIP,
    "collisions are decided inside the windows"
);
const _: () = assert!(UNIQUE_SAMPLES <= u16::MAX as usize);
const _: () = assert!(crate::observation::SCAN_BEAMS == SCAN_BEAMS);
const _: () = assert!(SCAN_BEAMS == 64, "beam masks are two u32 words");
const _: () = assert!(
    PAD_SAMPLE == SCRATCH - 1 && UNIQUE_SAMPLES.next_multiple_of(4) <= PAD_SAMPLE,
    "the last slot pads heads and tails, and no fill reaches it"
);
const _: () = assert!(HEAD_COUNT.is_power_of_two());

/// Length of the per-sample clearance array: the next power of two above the distinct samples, so
/// that indexing with a mask needs no bounds check.
const SCRATCH: usize = UNIQUE_SAMPLES.next_power_of_two();

/// A set of beams, one bit each: beams 0–31, then 32–63.
type Beams = [u32; 2];

/// One observation evaluated: the features of every action (all zeros for those that collide)
/// and the actions that do not collide. Made only by [`Evaluator::evaluation`] (and written
/// over only by [`Evaluator::evaluation_into`]), so an agent can act on it as on its own
/// evaluation.
#[derive(Clone, PartialEq, Debug)]
pub struct Evaluation {
    table: FeatureTable,
    allowed: ActionMask,
    reference: PathReference,
}

impl Evaluation {
    /// The features of every action.
    pub fn table(&self) -> &FeatureTable {
        &self.table
    }

    /// The actions that do not collide.
    pub fn allowed(&self) -> ActionMask {
        self.allowed
    }

    /// The observation's path reference (what a statement about the path is judged against).
    pub fn reference(&self) -> PathReference {
        self.reference
    }
}

/// The evaluator's scratch memory (2 944 bytes). Nothing in it outlives an evaluation: a fresh
/// evaluator gives the same bits as one reused from tick to tick. The
/// [`Agent`](crate::agent::Agent) keeps one and reuses it (on the car a fresh one on the stack
/// cost about 1 450 instructions an act to zero, `__aeabi_memclr4`, and the deepest stack
/// path went through it).
#[derive(Clone, Debug)]
pub struct Evaluator {
    /// `shorter[b]`: the beams within reach whose range bin is below `b`, i.e. (up to rounding,
    /// which the margins absorb) whose range is below `b · RANGE_BIN_WIDTH`.
    shorter: [Beams; SHORTER],
    /// The scan points of one cluster's candidates within its reach, side by side (then its
    /// near set, compacted into the front), so that its members' loop reads them in order.
    near: [[f32; 2]; SCAN_BEAMS],
    /// Their squared distances from the cluster's centre.
    near_d2: [f32; SCAN_BEAMS],
    /// Per distinct sample: clipped clearance (obstacles, then one class at a time); slot
    /// `PAD_SAMPLE` stays 0. The scan points in the car frame (of the beams within reach; the
    /// others are stale) live in the unused slots from `POINTS_AT` (see [`split_points`]).
    clearance: [f32; SCRATCH],
}

/// Where the scan points start in `Evaluator::clearance`: after the samples' slots (and the
/// fill's), before the padding slot. The scratch's length is a power of two so that indexing it
/// with a mask needs no bounds check; the points take 512 of its 644 spare bytes (and
/// `sum_rows` keeps the cruise heads' sums in 28 more, from `HEADS_AT`).
const POINTS_AT: usize = UNIQUE_SAMPLES.next_multiple_of(FILL);
const _: () = assert!(POINTS_AT + 2 * SCAN_BEAMS <= PAD_SAMPLE);

/// The samples' slots of the scratch, and its scan points, one `[x, y]` per beam.
#[inline(always)]
fn split_points(clearance: &mut [f32; SCRATCH]) -> (&mut [f32], &mut [[f32; 2]]) {
    let (samples, tail) = clearance.split_at_mut(POINTS_AT);
    (samples, tail[..2 * SCAN_BEAMS].as_chunks_mut::<2>().0)
}

impl Default for Evaluator {
    fn default() -> Self {
        Self::new()
    }
}

/// Largest relative error of [`sqrt`] on the squared distances the evaluator takes (all `f32` in
/// `[f32::MIN_POSITIVE, 1e4]`, checked exhaustively by `cargo test -p firmware-core --release --
/// --ignored sqrt_exhaustive`; measured 2.8e-7).
pub const SQRT_RELATIVE_ERROR: f32 = 3.0e-7;

/// Square root of a squared distance: a bit-level seed and two Newton steps, 8 FPU instructions
/// where `libm`'s correctly rounded `sqrtf` takes about 70 integer ones on a Cortex-M4 (whose
/// `vsqrt` stable Rust cannot reach without `unsafe`). Relative error at most
/// [`SQRT_RELATIVE_ERROR`]; the same operations, so the same bits, on the host and the car.
#[inline]
pub fn sqrt(x: f32) -> f32 {
    // One float comparison, false for NaN: LLVM turns `x.is_nan() || x < MIN_POSITIVE` into an
    // integer classification of the bits, about 15 instructions more on a Cortex-M4.
    if x >= f32::MIN_POSITIVE {
        return newton_sqrt(x);
    }
    // 0, subnormals (never produced by the geometry here), negatives and NaN take the exact path.
    libm::sqrtf(x)
}

/// [`sqrt`] of an `x` known to be at least `f32::MIN_POSITIVE` (a distance known to exceed a
/// millimetre): the same bits, without the test.
#[inline(always)]
fn newton_sqrt(x: f32) -> f32 {
    let mut y = f32::from_bits(0x1fbb_4f2e_u32.wrapping_add(x.to_bits() >> 1));
    y = 0.5 * (y + x / y);
    0.5 * (y + x / y)
}

/// `x` if it is below `clip`, else `clip` (`f32::min` without the NaN handling, which is a call
/// to `fminf` on a Cortex-M4; the evaluator's values are never NaN).
#[inline]
fn clipped(x: f32, clip: f32) -> f32 {
    if x < clip { x } else { clip }
}

impl Evaluator {
    /// A fresh evaluator.
    pub const fn new() -> Self {
        Self {
            shorter: [[0; 2]; SHORTER],
            near: [[0.0; 2]; SCAN_BEAMS],
            near_d2: [0.0; SCAN_BEAMS],
            clearance: [0.0; SCRATCH],
        }
    }

    /// Writes the features of every trajectory that does not collide into `out` (the rows of
    /// the colliding ones are zero), and returns the trajectories that do not collide.
    ///
    /// The observation was validated once, by [`Observation::check`].
    pub fn evaluate(&mut self, obs: ValidObservation<'_>, out: &mut FeatureTable) -> ActionMask {
        let frame = PathFrame::new(&obs.reference);
        ActionMask::from_bits(self.clearances(obs, &frame, out))
    }

    /// [`Evaluator::evaluate`] with the path's frame made already: the collisions and every
    /// feature of the trajectories that do not collide (the rows of the others zeroed), one bit
    /// per action that does not collide. The frame is made apart, so that a caller with a fresh
    /// evaluator on its stack (the agent) holds the scratch only here, not during the path's
    /// `sincosf` too (768 bytes of frame on the car while that was `libm`'s, with its
    /// large-argument reduction; [`sincosf`] has none).
    pub(crate) fn clearances(
        &mut self,
        obs: ValidObservation<'_>,
        frame: &PathFrame,
        out: &mut FeatureTable,
    ) -> u64 {
        let allowed = self.clearances_with::<WIDE>(obs, frame, out);
        // On a host, the table's copy feature by feature for the learner's passes (nothing on
        // the car).
        out.seal();
        allowed
    }

    /// [`Evaluator::clearances`] on the car's paths (`W` false) or the host's (`W` true, see
    /// `policy::WIDE`): the same bits either way (tested).
    fn clearances_with<const W: bool>(
        &mut self,
        obs: ValidObservation<'_>,
        frame: &PathFrame,
        out: &mut FeatureTable,
    ) -> u64 {
        let obstacles = self.obstacles::<W>(&obs.scan.ranges);
        let rows = out.rows_mut();
        let allowed = match obstacles {
            Obstacles::Clear => u64::MAX,
            Obstacles::Measured { allowed, .. } => allowed,
        };
        if W {
            #[cfg(not(target_arch = "arm"))]
            start_rows_wide(allowed, frame, rows);
        } else {
            start_rows(allowed, frame, rows);
        }
        if let Obstacles::Measured { allowed, touched } = obstacles {
            let f = Feature::Obstacles.index();
            self.sum_rows(allowed, touched, f, OBSTACLE_CLIP, rows);
        }
        if allowed != 0 {
            for class in SemanticClass::ALL {
                self.semantic::<W>(&obs, class, allowed, rows);
            }
        }
        allowed
    }

    /// [`Evaluator::evaluate`] into an [`Evaluation`] of its own, which an
    /// [`Agent`](crate::agent::Agent) can act on without evaluating again
    /// ([`Agent::act_evaluated`](crate::agent::Agent::act_evaluated)).
    pub fn evaluation(&mut self, obs: ValidObservation<'_>) -> Evaluation {
        let mut table = FeatureTable::ZERO;
        let allowed = self.evaluate(obs, &mut table);
        Evaluation {
            table,
            allowed,
            reference: obs.reference,
        }
    }

    /// [`Evaluator::evaluation`] of `obs` written over `into` (an evaluation of another
    /// observation), the same bits: every row of the table is written (the colliding ones
    /// zeroed) and the table sealed, so nothing of the old evaluation is left. A host that
    /// evaluates an observation a tick reuses one evaluation instead of zeroing and moving a
    /// table (3 KiB on a host) each time.
    pub fn evaluation_into(&mut self, obs: ValidObservation<'_>, into: &mut Evaluation) {
        into.allowed = self.evaluate(obs, &mut into.table);
        into.reference = obs.reference;
    }

    /// Decides which trajectories collide, then measures the clipped obstacle clearance of every
    /// sample of the others (into `clearance`). Returns the trajectories that do not collide, and
    /// those with a sample nearer than the clip to a scan point, one bit per action.
    fn obstacles<const W: bool>(&mut self, ranges: &[f32; SCAN_BEAMS]) -> Obstacles {
        #[cfg(not(target_arch = "arm"))]
        if W {
            return self.obstacles_wide(ranges);
        }
        let Self {
            shorter,
            near,
            near_d2,
            clearance,
        } = self;
        let (clearance, points) = split_points(clearance);
        if !bin_beams(ranges, shorter, clearance, points) {
            // No beam within reach of any sample: nothing collides, every clearance is the clip.
            return Obstacles::Clear;
        }
        // Beams shorter than the clip plus the largest spread, and some more (whole bins):
        // candidates for the clusters near the sensor whatever their bearing (their windows
        // cover only bearings within 90° of the centre's).
        let close = shorter[CLOSE_BINS];

        // Farthest clusters first (their samples collide most often): a sample whose trajectories
        // all collide already is skipped. The nearest scan point of a sample within the clip is
        // in its cluster's near set, so its distance decides both the clearance and the collision.
        let (mut alive, mut touched) = (u64::MAX, 0u64);
        for cluster in CLUSTERS.iter().rev() {
            if cluster.trajectories & alive == 0 {
                continue;
            }
            let beams = candidates(shorter, &cluster.clip, close);
            if beams[0] | beams[1] == 0 {
                continue;
            }
            // The candidates within reach of some member (the clip plus the spread), side by
            // side, and the nearest of them to the centre.
            let [cx, cy] = cluster.centre;
            let spread = cluster.spread;
            let reach = OBSTACLE_CLIP + spread + REACH_MARGIN;
            let reach2 = reach * reach;
            let mut n = 0usize;
            let mut m2 = reach2;
            let mut gather = |mut bits: u32, base: usize| {
                while bits != 0 {
                    let j = (bits.trailing_zeros() as usize + base) & (SCAN_BEAMS - 1);
                    bits &= bits - 1;
                    let [px, py] = points[j];
                    let dx = px - cx;
                    let dy = py - cy;
                    let d2 = dx * dx + dy * dy;
                    if d2 < reach2 {
                        near[n & (SCAN_BEAMS - 1)] = [px, py];
                        near_d2[n & (SCAN_BEAMS - 1)] = d2;
                        n += 1;
                        if d2 < m2 {
                            m2 = d2;
                        }
                    }
                }
            };
            gather(beams[0], 0);
            gather(beams[1], 32);
            if n == 0 {
                // Every candidate is beyond the clip of every member.
                continue;
            }
            // With `m` the distance from the centre to its nearest candidate and `s` the spread,
            // every member is within `m + s` of that point, and a point farther than `m + 2s`
            // from the centre is farther than `m + s` from every member: only the points within
            // `m + 2s` of the centre can be a member's nearest (the near set).
            let m = sqrt(m2);
            if (m + spread) * (1.0 + 1.0e-5) + REACH_MARGIN < COLLISION_RADIUS {
                // Every member is within the collision radius of the centre's nearest point.
                alive &= !cluster.trajectories;
                continue;
            }
            // No test of `m` against the clip: the centre's nearest candidate is within its reach
            // (`m < reach = clip + s + 1 mm`, up to the root's rounding), so `m − s` is never
            // beyond the clip with the margins such a test needs; and the members measured
            // against the near set settle nothing beyond the clip anyway.
            // Generous against rounding: a relative 1e-5 and the 1 mm margin.
            let limit = clipped((m + 2.0 * spread) * (1.0 + 1.0e-5) + REACH_MARGIN, reach);
            let limit2 = limit * limit;
            let n = n.min(SCAN_BEAMS);
            // The points kept before the first one left out stay where they are (found by
            // `position`: fewer counters than an index loop; no distance is NaN).
            let kept = near_d2[..n]
                .iter()
                .position(|&d2| d2 >= limit2)
                .unwrap_or(n);
            let mut k = kept;
            for i in kept..n {
                if near_d2[i] < limit2 {
                    near[k & (SCAN_BEAMS - 1)] = near[i];
                    k += 1;
                }
            }
            // The set holds the centre's nearest candidate: never empty. Each member's least
            // starts from its first point rather than the clip's square: the same least when it
            // is below the clip's square, and at least that square (no clearance, no collision)
            // otherwise.
            let Some((&[fx, fy], set)) = near[..k.min(n)].split_first() else {
                continue;
            };
            let start = usize::from(cluster.samples[0]);
            let end = usize::from(cluster.samples[1]);
            let (Some(samples), Some(trajectories), Some(clearance)) = (
                SAMPLE_POINTS.get(start..end),
                SAMPLE_TRAJECTORIES.get(start..end),
                clearance.get_mut(start..end),
            ) else {
                continue;
            };
            // Two members at a time where two are left to measure: each point of the near set
            // loaded once for both. The second's result is taken only if its trajectories do
            // not all collide after the first's (as when they are measured one after the other).
            let len = samples.len().min(trajectories.len()).min(clearance.len());
            let mut i = 0;
            while i < len {
                if trajectories[i] & alive == 0 {
                    i += 1;
                    continue;
                }
                let mut j = i + 1;
                while j < len && trajectories[j] & alive == 0 {
                    j += 1;
                }
                let [ax, ay] = samples[i];
                if j < len {
                    let [bx, by] = samples[j];
                    let d2 = |x: f32, y: f32| {
                        let (dx, dy) = (fx - x, fy - y);
                        dx * dx + dy * dy
                    };
                    let (mut best_a, mut best_b) = (d2(ax, ay), d2(bx, by));
                    for &[px, py] in set {
                        let dx = px - ax;
                        let dy = py - ay;
                        let d2 = dx * dx + dy * dy;
                        if d2 < best_a {
                            best_a = d2;
                        }
                        let dx = px - bx;
                        let dy = py - by;
                        let d2 = dx * dx + dy * dy;
                        if d2 < best_b {
                            best_b = d2;
                        }
                    }
                    settle(
                        best_a,
                        trajectories[i],
                        &mut clearance[i],
                        &mut alive,
                        &mut touched,
                    );
                    let of = trajectories[j];
                    if of & alive != 0 {
                        settle(best_b, of, &mut clearance[j], &mut alive, &mut touched);
                    }
                } else {
                    let (dx, dy) = (fx - ax, fy - ay);
                    let mut best = dx * dx + dy * dy;
                    for &[px, py] in set {
                        let dx = px - ax;
                        let dy = py - ay;
                        let d2 = dx * dx + dy * dy;
                        if d2 < best {
                            best = d2;
                        }
                    }
                    settle(
                        best,
                        trajectories[i],
                        &mut clearance[i],
                        &mut alive,
                        &mut touched,
                    );
                }
                i = j + 1;
            }
        }
        Obstacles::Measured {
            allowed: alive,
            touched,
        }
    }

    /// [`Evaluator::obstacles`] on a wide target: every scan point within reach, beam by beam,
    /// measured against each chunk of samples that `BEAM_CHUNKS` does not leave out for it,
    /// [`LANES`] samples side by side, without the clusters' pruning (see "On the host" in the
    /// module documentation). The same mask, the same clearance for every sample of a
    /// trajectory that does not collide, and `touched` the same on those trajectories.
    ///
    /// The least squared distance of a sample over the points within reach its chunk keeps is
    /// the least over its cluster's near set whenever it is below the clip's square (that point
    /// is in both: `BEAM_CHUNKS` leaves out only points a millimetre beyond the clip of every
    /// lane, tested; and the least of the same values is the same whatever the order: none is
    /// NaN or −0), and at least the clip's square otherwise, where both read the clip's square. So
    /// every sample's collision test and clearance come from the same number as on the car;
    /// what the car's pass skips (a cluster beyond the clip, one within the collision radius
    /// of its centre's nearest point, the members whose trajectories all collide already) is
    /// what these give them too, or is never read.
    #[cfg(not(target_arch = "arm"))]
    fn obstacles_wide(&mut self, ranges: &[f32; SCAN_BEAMS]) -> Obstacles {
        // The beams within reach, one bit each: those the car's pass bins (`beams_within_reach`,
        // the car's own test; every beam within reach is within the bins, asserted).
        let [low, high] = beams_within_reach(ranges);
        let within = u64::from(low) | u64::from(high) << 32;
        if within == 0 {
            return Obstacles::Clear;
        }
        // The chunks some beam within reach may come within the clip of (`BEAM_CHUNKS`, by the
        // beam's range bin, the one the car's pass puts it in).
        let chunks_of = |j: usize| {
            let b = (ranges[j] * (1.0 / RANGE_BIN_WIDTH)) as usize;
            BEAM_CHUNKS[j].get(b).copied().unwrap_or(u32::MAX) & ALL_CHUNKS
        };
        let mut visited = 0u32;
        let mut bits = within;
        while bits != 0 {
            visited |= chunks_of(bits.trailing_zeros() as usize & (SCAN_BEAMS - 1));
            bits &= bits - 1;
        }
        // Each lane of a visited chunk keeps its least squared distance in its clearance slot,
        // from the clip's square; the others read the clip.
        let collide2 = COLLISION_RADIUS * COLLISION_RADIUS;
        let clip2 = OBSTACLE_CLIP * OBSTACLE_CLIP;
        let (lanes, []) = self.clearance[..LANE_CHUNKS * LANES].as_chunks_mut::<LANES>() else {
            unreachable!("whole chunks")
        };
        for (k, c) in lanes.iter_mut().enumerate() {
            *c = [if visited >> k & 1 != 0 {
                clip2
            } else {
                OBSTACLE_CLIP
            }; LANES];
        }
        // Beam by beam (its scan point as the car's pass computes it), each chunk it may come
        // within the clip of. `sx − px` is `−(px − sx)` exactly (a rounding to nearest is
        // symmetric), so its square is the car's.
        let mut bits = within;
        while bits != 0 {
            let j = bits.trailing_zeros() as usize & (SCAN_BEAMS - 1);
            bits &= bits - 1;
            let r = ranges[j];
            let (px, py) = (r * BEAM_COS[j], r * BEAM_SIN[j]);
            let mut chunks = chunks_of(j);
            while chunks != 0 {
                let k = chunks.trailing_zeros() as usize;
                chunks &= chunks - 1;
                let (Some([sx, sy]), Some(best)) = (SAMPLE_LANES.get(k), lanes.get_mut(k)) else {
                    continue;
                };
                for l in 0..LANES {
                    let dx = sx[l] - px;
                    let dy = sy[l] - py;
                    best[l] = clipped(dx * dx + dy * dy, best[l]);
                }
            }
        }
        let (mut collided, mut touched) = (0u64, 0u64);
        let mut bits = visited;
        while bits != 0 {
            let k = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let (Some(best), Some(of)) = (lanes.get_mut(k), LANE_HALVES.0.get(k)) else {
                continue;
            };
            // The trajectories of the lanes within the clip: none when no lane is (every
            // sample belongs to some trajectory).
            if !any_below(best, clip2) {
                *best = [OBSTACLE_CLIP; LANES];
                continue;
            }
            touched |= trajectories_below(best, clip2, of);
            if any_below(best, collide2) {
                collided |= trajectories_below(best, collide2, of);
            }
            for b in best.iter_mut() {
                let root = clipped(newton_sqrt(*b), OBSTACLE_CLIP);
                *b = if *b < clip2 { root } else { OBSTACLE_CLIP };
            }
        }
        Obstacles::Measured {
            allowed: !collided,
            touched,
        }
    }

    /// Sums the per-sample clearance (`self.clearance`) along every allowed trajectory, scaled
    /// to ten samples and divided by `clip`, into feature `f`: the shared heads once (into the
    /// scratch's slots from `HEADS_AT`), then each trajectory's head and tail, in order along it
    /// (the same sum, bit for bit, as one pass: the creep trajectories' empty head and padding
    /// added only `PAD_SAMPLE`'s 0, which changes no sum of clearances, none of them −0). A
    /// trajectory not in `touched` has the clip at every sample: its sum is exactly ten clips,
    /// and it keeps the [`SAMPLES`] that [`Evaluator::clearances`] wrote (a sum of clips, a
    /// power of two, is exact).
    ///
    /// `sum * ROW_SCALE[a] / clip` is `sum * (ROW_SCALE[a] / clip)` bit for bit: both factors are
    /// powers of two (asserted) and no sum is subnormal; so each family takes one factor.
    fn sum_rows(
        &mut self,
        allowed: u64,
        touched: u64,
        f: usize,
        clip: f32,
        rows: &mut [Features; MAX_ACTIONS],
    ) {
        let todo = allowed & touched;
        if todo == 0 {
            return;
        }
        let c = &mut self.clearance;
        // The cruise heads, written out (constant slots: a load and an add a sample), into the
        // slots the cruise sums read them from. From the first sample rather than from 0.0: the
        // same sum, no clearance being −0.
        macro_rules! heads {
            ($($h:literal)*) => {$({
                const U: [usize; HEAD_LEN] = head_slots($h);
                c[HEADS_AT + $h] = c[U[0]] + c[U[1]] + c[U[2]] + c[U[3]];
            })*};
        }
        const _: () = assert!(
            CRUISE_HEADS == 7 && HEAD_LEN == 4,
            "the heads are written out"
        );
        heads!(0 1 2 3 4 5 6);
        let c = &*c;
        let far = |u: u16| c[usize::from(u) & (SCRATCH - 1)];
        let cruise = 1.0 / clip;
        let low = todo as u32;
        let high = (todo >> 32) as u32;
        // Each half of the mask with its halves of the table and the rows (no action number to
        // make from a bit's position and a base).
        let ([sums_low, sums_high], []) = CRUISE_SUMS.as_chunks::<32>() else {
            unreachable!("64 actions")
        };
        let ([rows_low, rows_high], []) = rows.as_chunks_mut::<32>() else {
            unreachable!("64 actions")
        };
        for (bits, sums, rows) in [
            (low, sums_low, rows_low),
            (high & CRUISE_HIGH, sums_high, rows_high),
        ] {
            for_each_bit(bits, |a| {
                let a = a & 31;
                let CruiseSum {
                    near: [_, h, t0, t1, t2, t3],
                    far: [t4, t5],
                } = sums[a];
                let mut sum = c[NEAR_BASE[0] + usize::from(h)];
                sum += c[NEAR_BASE[1] + usize::from(t0)];
                sum += c[NEAR_BASE[2] + usize::from(t1)];
                sum += c[NEAR_BASE[3] + usize::from(t2)];
                sum += c[NEAR_BASE[4] + usize::from(t3)];
                sum += far(t4);
                sum += far(t5);
                rows[a][f] = sum * cruise;
            });
        }
        let creep = CREEP_SCALE / clip;
        let ([_, rows], []) = rows.as_chunks_mut::<32>() else {
            unreachable!("64 actions")
        };
        for_each_bit(high >> (CRUISE - 32), |i| {
            let [_, t0, t1, t2, t3, t4, _, _] = CREEP_SUMS[i & (CREEP_SLOTS - 1)];
            let mut sum = c[usize::from(t0)];
            sum += c[usize::from(t1)];
            sum += c[usize::from(t2)];
            sum += c[usize::from(t3)];
            sum += c[usize::from(t4)];
            rows[(i + CRUISE - 32) & 31][f] = sum * creep;
        });
    }

    /// The clearance feature of one semantic class, for every allowed trajectory.
    #[inline(never)]
    fn semantic<const W: bool>(
        &mut self,
        obs: &Observation,
        class: SemanticClass,
        allowed: u64,
        rows: &mut [Features; MAX_ACTIONS],
    ) {
        let f = class.feature().index();
        // No object of the class: every clearance is the clip, as below (and no array of
        // objects to fill first).
        if !obs.objects.iter().any(|o| o.class == class) {
            return;
        }
        // The objects of the class. A sample farther than clip + r from the centre reads the clip
        // for that object (tested on squares, so the root is taken only where it matters).
        let mut objects = [Disc::FAR; MAX_OBJECTS];
        let mut n = 0;
        for o in obs.objects.iter().filter(|o| o.class == class) {
            let reach = SEMANTIC_CLIP + o.radius + REACH_MARGIN;
            // An object whose reach misses every sample is left out.
            let whole = MAX_SAMPLE_RHO + reach;
            if o.x * o.x + o.y * o.y >= whole * whole {
                continue;
            }
            if let Some(slot) = objects.get_mut(n) {
                *slot = Disc::new(o.x, o.y, o.radius);
                n += 1;
            }
        }
        if n == 0 {
            // No object of the class, or none within reach: every clearance is the clip, and
            // every sum ten clips (an absent class reads the same), as the rows hold already.
            return;
        }
        let objects = &objects[..n];
        // A disc wider than the margin holds every point whose squared distance to its centre
        // is below `f32::MIN_POSITIVE` (where `sqrt` is not `newton_sqrt`) by far: such a member
        // reads 0 either way, so the host's loop may take `newton_sqrt` for every member.
        #[cfg(not(target_arch = "arm"))]
        if W && objects.iter().all(|o| o.radius >= REACH_MARGIN) {
            self.semantic_lanes(objects, allowed, f, rows);
            return;
        }
        // The objects that may be the nearest of the class to some sample: the dominance test
        // over the whole lattice as one cluster ([`LATTICE`]). When one alone is left, the
        // others are left out of every cluster's tests (each cluster's own test would leave
        // them out too: its members are within the lattice's spread of its centre), and where
        // the lattice is within its clip and outside its disc, every sample an allowed
        // trajectory has reads its root less the radius, without a test per cluster.
        let (near, centre) = if n == 1 {
            let o = &objects[0];
            let (dx, dy) = (LATTICE.centre[0] - o.x, LATTICE.centre[1] - o.y);
            (1, sqrt(dx * dx + dy * dy))
        } else {
            dominant(objects, (1 << n) - 1, &LATTICE)
        };
        let objects = if near & (near - 1) == 0 {
            let o = &objects[near.trailing_zeros() as usize & (MAX_OBJECTS - 1)];
            if self.settled(o, centre, allowed) {
                self.sum_rows(allowed, allowed, f, SEMANTIC_CLIP, rows);
                return;
            }
            core::slice::from_ref(o)
        } else {
            objects
        };
        // Two objects: which of them is the nearest to every member of a cluster, told by the
        // cluster's side of their bisector where it can be (no root per object and cluster).
        let pair = match objects {
            [a, b] => Bisector::new(a, b),
            _ => None,
        };
        let mut touched = 0u64;
        for region in &REGIONS {
            // A region no allowed trajectory uses is skipped, as its clusters would be.
            if region.trajectories & allowed == 0 {
                continue;
            }
            let clusters = REGION_CLUSTERS
                .get(usize::from(region.clusters[0])..usize::from(region.clusters[1]))
                .unwrap_or(&[]);
            // The objects within reach of some member of the region, and the one nearest to
            // every member where two are and their bisector tells, as for a cluster below.
            let (near, last2) = within_reach(objects, region.centre, region.spread, || {
                pair.as_ref().and_then(|p| p.side_of_region(region))
            });
            if near == 0 {
                // No object within reach of any member: every member of a cluster an allowed
                // trajectory uses reads the clip (as a cluster near no object below).
                for &i in clusters {
                    let Some(cluster) = CLUSTERS.get(usize::from(i)) else {
                        continue;
                    };
                    if cluster.trajectories & allowed == 0 {
                        continue;
                    }
                    self.clip_members(cluster);
                }
                continue;
            }
            if near & (near - 1) == 0 {
                // One object alone may be the nearest to some member: where the region is within
                // its clip and outside its disc, every member reads its root less the radius.
                let o = &objects[near.trailing_zeros() as usize & (MAX_OBJECTS - 1)];
                let centre = sqrt(last2);
                if o.settles(centre, region.spread) {
                    touched |= region.trajectories;
                    self.region_roots(region, o, allowed);
                    continue;
                }
                if region.trajectories & !allowed == 0
                    && centre - (region.spread + REACH_MARGIN) > o.radius
                {
                    // Every member outside the disc by more than a millimetre, some maybe
                    // beyond the clip, and every trajectory through the region allowed: one
                    // loop over its samples, as `one_object`'s for a cluster.
                    touched |= region.trajectories;
                    self.outside(region.samples, o);
                    continue;
                }
            }
            for &i in clusters {
                let Some(cluster) = CLUSTERS.get(usize::from(i)) else {
                    continue;
                };
                // A cluster no allowed trajectory uses is skipped (the sums read no member of
                // it); in the others every member is written: the clip, or measured (a member
                // only colliding trajectories use is written and never read: measuring it costs
                // less than testing it). So every sample an allowed trajectory has is written,
                // without a fill of every sample.
                if cluster.trajectories & allowed == 0 {
                    continue;
                }
                // The objects within reach of some member of the cluster.
                let (mut near, last2) =
                    within_reach(objects, cluster.centre, cluster.spread, || {
                        pair.as_ref().and_then(|p| p.side(cluster))
                    });
                if near == 0 {
                    self.clip_members(cluster);
                    continue;
                }
                touched |= cluster.trajectories;
                if near & (near - 1) == 0 {
                    let o = &objects[near.trailing_zeros() as usize & (MAX_OBJECTS - 1)];
                    if o.inner2 < last2 && last2 < o.outer2 {
                        self.roots(cluster.samples, o);
                        continue;
                    }
                }
                let centre;
                (near, centre) = if near & (near - 1) == 0 {
                    (near, sqrt(last2))
                } else {
                    dominant(objects, near, cluster)
                };
                if near & (near - 1) == 0 {
                    let k = near.trailing_zeros() as usize & (MAX_OBJECTS - 1);
                    self.one_object(cluster, &objects[k], centre);
                    continue;
                }
                for u in members(cluster) {
                    let [sx, sy] = SAMPLE_POINTS[u];
                    let mut c = SEMANTIC_CLIP;
                    let mut bits = near;
                    while bits != 0 {
                        let o = &objects[bits.trailing_zeros() as usize & (MAX_OBJECTS - 1)];
                        bits &= bits - 1;
                        let (dx, dy) = (sx - o.x, sy - o.y);
                        let d2 = dx * dx + dy * dy;
                        if d2 < o.reach2 {
                            let d = sqrt(d2) - o.radius;
                            let d = if d > 0.0 { d } else { 0.0 };
                            if d < c {
                                c = d;
                            }
                        }
                    }
                    self.clearance[u] = c;
                }
            }
        }
        self.sum_rows(allowed, touched, f, SEMANTIC_CLIP, rows);
    }

    /// [`Evaluator::semantic`] on a wide target, every disc wider than the margin: the same
    /// values, [`LANES`] samples side by side. Each lane starts at the clip and takes the least
    /// of that and its clearance to each object whose reach comes within the lanes' bounding
    /// box, by one formula without a branch ([`least_with`]: the general member loop's value, the
    /// clip beyond the reach, else the root less the radius, at least 0 and at most the clip,
    /// taken into the least without its clip and reach test, which change no least; `newton_sqrt`
    /// for every lane, the same bits as `sqrt` for a disc wider than the margin, since a sample
    /// within `f32::MIN_POSITIVE`'s root of the centre reads 0 either way). A sample no allowed trajectory has is
    /// written and never read; every other reads the least over the objects of the class
    /// within reach of its cluster, as the car's paths give it: an object out of a sample's
    /// reach (its squared distance at least the reach's square, as the formula computes it)
    /// gives the clip, which the least leaves as it is; a box whose nearest point's squared
    /// distance to the object is at least the reach's square has every lane out of reach (the
    /// differences, squares and sums are rounded monotonically, and no lane's difference is
    /// smaller than the box's); and the least does not depend on the order it is taken in (no
    /// value is NaN or −0). `touched` holds the trajectories of every chunk within some object's
    /// reach, every one with a lane below the clip among them (a trajectory whose samples all
    /// read the clip sums them to ten clips, exactly: summing one more changes no bit).
    #[cfg(not(target_arch = "arm"))]
    fn semantic_lanes(
        &mut self,
        objects: &[Disc],
        allowed: u64,
        f: usize,
        rows: &mut [Features; MAX_ACTIONS],
    ) {
        // Which chunks each object's reach comes within: whether the box's nearest point, by
        // coordinate, is nearer than the reach (every chunk side by side).
        let mut near = [[false; LANE_CHUNKS]; MAX_OBJECTS];
        let [[x0, x1], [y0, y1]] = &BOX_LANES;
        for (o, near) in objects.iter().zip(near.iter_mut()) {
            for (k, near) in near.iter_mut().enumerate() {
                let dx = at_least(at_least(x0[k] - o.x, o.x - x1[k]), 0.0);
                let dy = at_least(at_least(y0[k] - o.y, o.y - y1[k]), 0.0);
                *near = dx * dx + dy * dy < o.reach2;
            }
        }
        // Every lane from the clip, then each object over the chunks within its reach.
        let (lanes, []) = self.clearance[..LANE_CHUNKS * LANES].as_chunks_mut::<LANES>() else {
            unreachable!("whole chunks")
        };
        lanes.fill([SEMANTIC_CLIP; LANES]);
        let mut touched = 0u64;
        for (o, near) in objects.iter().zip(&near) {
            let (ox, oy, radius) = (o.x, o.y, o.radius);
            for (k, (least, &near)) in lanes.iter_mut().zip(near).enumerate() {
                if !near {
                    continue;
                }
                // Some lane may be below the clip: the chunk's trajectories may sum less than
                // ten clips (a trajectory whose samples all read the clip sums exactly ten).
                touched |= LANE_UNION[k];
                let [sx, sy] = &SAMPLE_LANES[k];
                for l in 0..LANES {
                    let (dx, dy) = (sx[l] - ox, sy[l] - oy);
                    least[l] = least_with(newton_sqrt(dx * dx + dy * dy) - radius, least[l]);
                }
            }
        }
        if touched == 0 {
            // No sample within the clip of an object: the rows hold ten clips already.
            return;
        }
        self.sum_rows(allowed, touched, f, SEMANTIC_CLIP, rows);
    }

    /// Whether the whole lattice ([`LATTICE`]) is within the clip of `o` and outside its disc
    /// (`centre` the distance from the lattice's centre to the object's; the same tests, with
    /// the same margin, as [`Evaluator::one_object`]'s loop without tests); if so, writes the
    /// clearance of every member of every cluster an allowed trajectory uses (and of the other
    /// members of a region whose trajectories are all allowed), as that loop does (the same
    /// values, bit for bit, as the general loop: every member is within reach, outside the disc
    /// and nearer than the clip beyond it).
    fn settled(&mut self, o: &Disc, centre: f32, allowed: u64) -> bool {
        if !o.settles(centre, LATTICE.spread) {
            return false;
        }
        for region in &REGIONS {
            self.region_roots(region, o, allowed);
        }
        true
    }

    /// Every member of every cluster of `region` an allowed trajectory uses (or of every
    /// cluster, when every trajectory through the region is allowed: one loop over its
    /// samples) reads its root less the radius of `o` ([`Evaluator::roots`]).
    #[inline(always)]
    fn region_roots(&mut self, region: &Region, o: &Disc, allowed: u64) {
        if region.trajectories & !allowed == 0 {
            self.roots(region.samples, o);
            return;
        }
        let clusters = REGION_CLUSTERS
            .get(usize::from(region.clusters[0])..usize::from(region.clusters[1]))
            .unwrap_or(&[]);
        for &i in clusters {
            let Some(cluster) = CLUSTERS.get(usize::from(i)) else {
                continue;
            };
            if cluster.trajectories & allowed != 0 {
                self.roots(cluster.samples, o);
            }
        }
    }

    /// Every member of `cluster` reads the semantic clip (no object of the class within reach).
    #[inline(always)]
    fn clip_members(&mut self, cluster: &Cluster) {
        let start = usize::from(cluster.samples[0]);
        let end = usize::from(cluster.samples[1]);
        if let Some(clearance) = self.clearance.get_mut(start..end) {
            for c in clearance {
                *c = SEMANTIC_CLIP;
            }
        }
    }

    /// The points of the samples `samples[0]..samples[1]` (a cluster's or a region's members)
    /// and their clearances.
    #[inline(always)]
    fn members_mut(&mut self, samples: [u16; 2]) -> Option<(&'static [[f32; 2]], &mut [f32])> {
        let start = usize::from(samples[0]);
        let end = usize::from(samples[1]).min(UNIQUE_SAMPLES);
        Some((
            SAMPLE_POINTS.get(start..end)?,
            self.clearance.get_mut(start..end)?,
        ))
    }

    /// Every sample of `samples[0]..samples[1]` (a cluster's or a region's members) reads its
    /// root less the radius of `o`: the general loop's value where every member is within
    /// reach, outside the disc by more than a millimetre and nearer than the clip beyond it.
    #[inline]
    fn roots(&mut self, samples: [u16; 2], o: &Disc) {
        let (ox, oy, radius) = (o.x, o.y, o.radius);
        let Some((points, clearance)) = self.members_mut(samples) else {
            return;
        };
        for (c, &[sx, sy]) in clearance.iter_mut().zip(points) {
            let (dx, dy) = (sx - ox, sy - oy);
            *c = newton_sqrt(dx * dx + dy * dy) - radius;
        }
    }

    /// Every sample of `samples[0]..samples[1]` (a cluster's or a region's members, all outside
    /// the disc of `o` by more than a millimetre, some maybe beyond the clip) reads the general
    /// loop's value: no test of the root's sign; a member beyond the reach reads the clip
    /// without a root (a compare costs less than the root it saves).
    #[inline(always)]
    fn outside(&mut self, samples: [u16; 2], o: &Disc) {
        let (ox, oy, radius, reach2) = (o.x, o.y, o.radius, o.reach2);
        let Some((points, clearance)) = self.members_mut(samples) else {
            return;
        };
        for (c, &[sx, sy]) in clearance.iter_mut().zip(points) {
            let (dx, dy) = (sx - ox, sy - oy);
            let d2 = dx * dx + dy * dy;
            // Beyond the reach is beyond the clip by a millimetre: the clip, without a root.
            *c = if d2 < reach2 {
                clipped(newton_sqrt(d2) - radius, SEMANTIC_CLIP)
            } else {
                SEMANTIC_CLIP
            };
        }
    }

    /// The semantic clearance of every member of `cluster` when one object `o` alone can be the
    /// nearest of its class to them. The same values, bit for bit, as the general loop: where the
    /// centre's distance and the spread decide a test for every member at once (each with a 1 mm
    /// margin, far above the rounding of these distances), a loop without it runs: every member
    /// outside the disc (no test of the root's sign; a member beyond the reach reads the clip
    /// without a root), and within the clip as well (no clip nor reach),
    /// or every member inside the disc (0). `centre` is the distance from the cluster's centre to
    /// the object's.
    fn one_object(&mut self, cluster: &Cluster, o: &Disc, centre: f32) {
        if o.settles(centre, cluster.spread) {
            self.roots(cluster.samples, o);
            return;
        }
        let spread = cluster.spread + REACH_MARGIN;
        if centre - spread > o.radius {
            self.outside(cluster.samples, o);
            return;
        }
        let (ox, oy, radius, reach2) = (o.x, o.y, o.radius, o.reach2);
        let Some((points, clearance)) = self.members_mut(cluster.samples) else {
            return;
        };
        if centre + spread < radius {
            // Inside the disc by more than a millimetre: every clearance is 0 (a zero the
            // compiler cannot see, `black_box`: a loop of stores, not a call to `memclr`).
            let zero = core::hint::black_box(0.0f32);
            for c in clearance.iter_mut() {
                *c = zero;
            }
            return;
        }
        for (c, &[sx, sy]) in clearance.iter_mut().zip(points) {
            let (dx, dy) = (sx - ox, sy - oy);
            let d2 = dx * dx + dy * dy;
            *c = if d2 < reach2 {
                let d = sqrt(d2) - radius;
                clipped(if d > 0.0 { d } else { 0.0 }, SEMANTIC_CLIP)
            } else {
                SEMANTIC_CLIP
            };
        }
    }
}

/// The rows before the sums: zeros for the trajectories that collide; for the others ten clips
/// in every clearance feature, in one pass with the path and side features (the sums then
/// overwrite the clearances of the trajectories with a sample nearer than a clip). Not inlined:
/// apart from the passes over the clusters, it keeps its own registers.
#[inline(never)]
fn start_rows(allowed: u64, frame: &PathFrame, rows: &mut [Features; MAX_ACTIONS]) {
    // Six stores a row, written out: a zero the compiler cannot see (`black_box`) keeps it from
    // making each row a call to `memclr` (about 30 instructions on a Cortex-M4), and a loop of
    // six stores cost five instructions a store.
    let zero = core::hint::black_box(0.0f32);
    const _: () = assert!(FEATURE_COUNT == 6);
    let ([low, high], []) = rows.as_chunks_mut::<32>() else {
        unreachable!("64 actions")
    };
    for (bits, rows) in [(!allowed as u32, low), (!(allowed >> 32) as u32, high)] {
        for_each_bit(bits, |a| {
            let row = &mut rows[a & 31];
            row[0] = zero;
            row[1] = zero;
            row[2] = zero;
            row[3] = zero;
            row[4] = zero;
            row[5] = zero;
        });
    }
    const CLIPS: f32 = SAMPLES as f32;
    const _: () = assert!(
        Feature::Obstacles.index() == 0
            && Feature::Door.index() == 1
            && Feature::Stairs.index() == 2
            && Feature::Chair.index() == 3,
        "the clearance features are the first four"
    );
    // Each half of the mask with its halves of the rows and the end points (no action number
    // to make from a bit's position and a base).
    let ([ends_low, ends_high], []) = END_POINTS.as_chunks::<32>() else {
        unreachable!("64 actions")
    };
    let ([rows_low, rows_high], []) = rows.as_chunks_mut::<32>() else {
        unreachable!("64 actions")
    };
    for (bits, ends, rows) in [
        (allowed as u32, ends_low, rows_low),
        ((allowed >> 32) as u32, ends_high, rows_high),
    ] {
        for_each_bit(bits, |a| {
            let a = a & 31;
            let row = &mut rows[a];
            row[0] = CLIPS;
            row[1] = CLIPS;
            row[2] = CLIPS;
            row[3] = CLIPS;
            [row[Feature::Path.index()], row[Feature::Right.index()]] =
                frame.path_and_side_of(ends[a]);
        });
    }
}

/// [`start_rows`] on a wide target: the path and side features of every action first (the same
/// [`PathFrame::path_and_side_of`], on the end points one array per coordinate, which the
/// compiler takes four actions at a time), then every row written whole, and the rows of the
/// trajectories that collide zeroed.
#[cfg(not(target_arch = "arm"))]
fn start_rows_wide(allowed: u64, frame: &PathFrame, rows: &mut [Features; MAX_ACTIONS]) {
    const CLIPS: f32 = SAMPLES as f32;
    let [xs, ys] = &END_LANES;
    let mut path = [0.0f32; MAX_ACTIONS];
    let mut side = [0.0f32; MAX_ACTIONS];
    for (a, (p, s)) in path.iter_mut().zip(side.iter_mut()).enumerate() {
        [*p, *s] = frame.path_and_side_of([xs[a], ys[a]]);
    }
    for ((row, &p), &s) in rows.iter_mut().zip(&path).zip(&side) {
        *row = [CLIPS, CLIPS, CLIPS, CLIPS, p, s];
    }
    let mut collided = !allowed;
    while collided != 0 {
        rows[collided.trailing_zeros() as usize & (MAX_ACTIONS - 1)] = [0.0; FEATURE_COUNT];
        collided &= collided - 1;
    }
}

/// The trajectories' end points, one array per coordinate (`[x, y]`), for [`start_rows_wide`].
#[cfg(not(target_arch = "arm"))]
static END_LANES: [[f32; MAX_ACTIONS]; 2] = {
    let mut out = [[0.0; MAX_ACTIONS]; 2];
    let mut a = 0;
    while a < MAX_ACTIONS {
        out[0][a] = END_POINTS[a][0];
        out[1][a] = END_POINTS[a][1];
        a += 1;
    }
    out
};

/// The objects within reach of some point within `spread` of `centre` (a region's or a
/// cluster's), one bit each, and the squared distance from the centre to the last of them (the
/// only one's, when one alone is: its root is the centre's distance). Where both objects of a
/// pair are within reach, `side` (the centre's side of their bisector, when it tells) leaves
/// out the one that is nowhere the nearest, as `dominant` would leave it out.
#[inline(always)]
fn within_reach(
    objects: &[Disc],
    [cx, cy]: [f32; 2],
    spread: f32,
    side: impl FnOnce() -> Option<u32>,
) -> (u32, f32) {
    let mut near = 0u32;
    let mut last2 = 0.0;
    // The first object's, when it is within reach.
    let mut first2 = 0.0;
    for (k, o) in objects.iter().enumerate() {
        let (dx, dy) = (cx - o.x, cy - o.y);
        let limit = o.reach + spread;
        let d2 = dx * dx + dy * dy;
        if d2 < limit * limit {
            near |= 1 << k;
            last2 = d2;
            if k == 0 {
                first2 = d2;
            }
        }
    }
    if near == 0b11
        && let Some(side) = side()
    {
        return if side == 0 {
            (0b01, first2)
        } else {
            (0b10, last2)
        };
    }
    (near, last2)
}

/// The obstacle pass's verdict on one member whose least squared distance to its cluster's near
/// set is `best`: its trajectories `of` collide, or its clearance is that distance (those
/// trajectories touched) when it is within the clip; nothing at or beyond the clip.
#[inline(always)]
fn settle(best: f32, of: u64, c: &mut f32, alive: &mut u64, touched: &mut u64) {
    // Most members are beyond the clip: that test first.
    if best < OBSTACLE_CLIP * OBSTACLE_CLIP {
        if best < COLLISION_RADIUS * COLLISION_RADIUS {
            // Its trajectories collide: its clearance is never read.
            *alive &= !of;
        } else {
            // At least the collision radius squared: the root's test is not needed.
            *c = clipped(newton_sqrt(best), OBSTACLE_CLIP);
            *touched |= of;
        }
    }
}

/// How many slots [`fill`] writes at a time.
const FILL: usize = 16;

/// Sets the clearance of every sample to `value` (`clearance`: the samples' slots, up to
/// `POINTS_AT`).
#[inline]
fn fill(clearance: &mut [f32], value: f32) {
    // Sixteen at a time, written out (eight double-word stores on a Cortex-M4): a store-and-count
    // loop spends three instructions per slot. Four at a time, the fill cost 616 instructions a
    // tick, 286 now. (`copy_from_slice` of an array of sixteen costs more than either.)
    for c in clearance[..POINTS_AT].chunks_exact_mut(FILL) {
        c[0] = value;
        c[1] = value;
        c[2] = value;
        c[3] = value;
        c[4] = value;
        c[5] = value;
        c[6] = value;
        c[7] = value;
        c[8] = value;
        c[9] = value;
        c[10] = value;
        c[11] = value;
        c[12] = value;
        c[13] = value;
        c[14] = value;
        c[15] = value;
    }
}

/// The beams that may come within `reach`'s distance of a cluster's samples: its window (with
/// the beams shorter than the distance, whatever their bearing, for a cluster near the sensor)
/// within its band of range bins.
#[inline]
fn candidates(shorter: &[Beams; SHORTER], reach: &Reach, close: Beams) -> Beams {
    let lo = shorter[usize::from(reach.bins[0]) & (SHORTER - 1)];
    let hi = shorter[usize::from(reach.bins[1]) & (SHORTER - 1)];
    let (w0, w1) = if reach.behind {
        (reach.window[0] | close[0], reach.window[1] | close[1])
    } else {
        (reach.window[0], reach.window[1])
    };
    [w0 & hi[0] & !lo[0], w1 & hi[1] & !lo[1]]
}

/// A semantic object for the evaluator: its disc, its reach (the semantic clip beyond its
/// radius, and the margin) and the reach squared.
#[derive(Clone, Copy)]
struct Disc {
    x: f32,
    y: f32,
    radius: f32,
    reach: f32,
    reach2: f32,
    /// A cluster whose centre's squared distance from the object's is between these two has
    /// every member outside the disc and nearer than the clip beyond it, whatever its spread
    /// (at most [`MAX_CLUSTER_SPREAD`]), with a 2 mm margin: its members read their roots less
    /// the radius, without the centre's root.
    inner2: f32,
    outer2: f32,
}

impl Disc {
    /// A placeholder, out of every sample's reach.
    const FAR: Self = Self {
        x: 1.0e6,
        y: 1.0e6,
        radius: 0.0,
        reach: 0.0,
        reach2: 0.0,
        inner2: 0.0,
        outer2: 0.0,
    };

    /// Whether every point within `spread` of a point `centre` metres from the object's centre
    /// is within reach, outside the disc by more than a millimetre (its clearance, the root less
    /// the radius, is positive, with no test of the root's argument) and nearer than the clip
    /// beyond the disc: its clearance is then its root less the radius ([`Evaluator::roots`]).
    #[inline(always)]
    fn settles(&self, centre: f32, spread: f32) -> bool {
        let spread = spread + REACH_MARGIN;
        centre + spread < self.reach
            && centre - spread > self.radius
            && centre + spread < SEMANTIC_CLIP + self.radius
    }

    /// The disc of an object within reach of some sample.
    fn new(x: f32, y: f32, radius: f32) -> Self {
        let reach = SEMANTIC_CLIP + radius + REACH_MARGIN;
        let slack = MAX_CLUSTER_SPREAD + 2.0 * REACH_MARGIN;
        let inner = radius + slack;
        let outer = SEMANTIC_CLIP + radius - slack;
        Self {
            x,
            y,
            radius,
            reach,
            reach2: reach * reach,
            inner2: inner * inner,
            outer2: outer * outer,
        }
    }
}

/// The bisector of two objects' centres, to tell on which side of it a cluster lies: every
/// member of a cluster far enough on `a`'s side has its clearance to `a` below its clearance to
/// `b` by more than 2 mm, so `b` is left out of its least (as [`dominant`] leaves out an object
/// another is nearer than for every member), and the other way round.
///
/// For a point `x` at signed distance `t` from the bisector towards `a`, with `h` half the
/// distance between the centres, `|x − b|² − |x − a|² = 4ht`, so `|x − b| − |x − a| = 4ht /
/// (|x − b| + |x − a|)`. Both objects are within reach of the cluster (`reach + spread` of its
/// centre), so every member is within `reach + 2 · MAX_CLUSTER_SPREAD` of `a` and, by the
/// triangle inequality, that plus `2h` of `b`: the sum is below `bound = 2 (reach + 2 ·
/// MAX_CLUSTER_SPREAD) + 2h`. So `t ≥ need · bound / 4h` gives `|x − b| − |x − a| ≥ need`, with
/// `need` the difference of radii plus the margin: `(|x − b| − r_b) − (|x − a| − r_a) ≥ 2 mm`.
/// Every member is within the cluster's spread of its centre, whose `t` is taken once; the
/// thresholds have a millimetre of slack against rounding. A region's side is told the same
/// way, with thresholds of their own: the bound with [`MAX_REGION_SPREAD`] for
/// `MAX_CLUSTER_SPREAD`.
struct Bisector {
    /// The midpoint of the centres.
    mid: [f32; 2],
    /// The unit vector from `b`'s centre to `a`'s.
    normal: [f32; 2],
    /// The least `t` of every member for `a` alone.
    a_wins: f32,
    /// The least `−t` of every member for `b` alone.
    b_wins: f32,
    /// `a_wins` for a region (the bound with [`MAX_REGION_SPREAD`]).
    a_wins_region: f32,
    /// `b_wins` for a region.
    b_wins_region: f32,
}

impl Bisector {
    /// The bisector of `a` and `b`, or `None` where their centres are within a centimetre
    /// (the bound is of no use there).
    fn new(a: &Disc, b: &Disc) -> Option<Self> {
        let (dx, dy) = (a.x - b.x, a.y - b.y);
        let d = sqrt(dx * dx + dy * dy);
        if d <= 0.01 {
            return None;
        }
        let h = 0.5 * d;
        let margin = 2.0 * REACH_MARGIN;
        let threshold = |near: &Disc, far: &Disc, spread: f32| {
            let need = far.radius - near.radius + margin;
            let bound = 2.0 * (near.reach + 2.0 * spread) + 2.0 * h;
            let t = if need > 0.0 {
                need * bound / (4.0 * h)
            } else {
                0.0
            };
            // Slack against the rounding of `t` and of the cluster's spread.
            t * (1.0 + 1.0e-4) + REACH_MARGIN
        };
        Some(Self {
            mid: [0.5 * (a.x + b.x), 0.5 * (a.y + b.y)],
            normal: [dx / d, dy / d],
            a_wins: threshold(a, b, MAX_CLUSTER_SPREAD),
            b_wins: threshold(b, a, MAX_CLUSTER_SPREAD),
            a_wins_region: threshold(a, b, MAX_REGION_SPREAD),
            b_wins_region: threshold(b, a, MAX_REGION_SPREAD),
        })
    }

    /// 0 if `a` is the nearest to every member of `cluster` by the margin, 1 if `b` is, `None`
    /// if the bound cannot tell.
    #[inline(always)]
    fn side(&self, cluster: &Cluster) -> Option<u32> {
        self.side_at(cluster.centre, cluster.spread, self.a_wins, self.b_wins)
    }

    /// [`Bisector::side`] for every member of `region` (both objects within reach of it).
    #[inline(always)]
    fn side_of_region(&self, region: &Region) -> Option<u32> {
        self.side_at(
            region.centre,
            region.spread,
            self.a_wins_region,
            self.b_wins_region,
        )
    }

    /// [`Bisector::side`] for the points within `spread` of `centre`, with the thresholds
    /// `a_wins` and `b_wins` made for that spread.
    #[inline(always)]
    fn side_at(&self, centre: [f32; 2], spread: f32, a_wins: f32, b_wins: f32) -> Option<u32> {
        let [cx, cy] = centre;
        let t = (cx - self.mid[0]) * self.normal[0] + (cy - self.mid[1]) * self.normal[1];
        if t - spread >= a_wins {
            Some(0)
        } else if -t - spread >= b_wins {
            Some(1)
        } else {
            None
        }
    }
}

/// Of the objects `near` (bits into `objects`), those whose clearance may be the least of the
/// class for some member of `cluster`, and the distance from the centre to the last of them: an
/// object whose clearance exceeds, for every member, another's largest possible one is left out
/// (with a 1 mm margin, far above the rounding of these distances). Inlined in both its callers
/// (a call of its own costs the worst real ticks about 1 K instructions on the car).
#[inline(always)]
fn dominant(objects: &[Disc], near: u32, cluster: &Cluster) -> (u32, f32) {
    let spread = cluster.spread + REACH_MARGIN;
    let [cx, cy] = cluster.centre;
    let mut distance = [0.0f32; MAX_OBJECTS];
    let mut least_highest = f32::MAX;
    let mut bits = near;
    while bits != 0 {
        let k = bits.trailing_zeros() as usize & (MAX_OBJECTS - 1);
        bits &= bits - 1;
        if let Some(o) = objects.get(k) {
            let (dx, dy) = (cx - o.x, cy - o.y);
            distance[k] = sqrt(dx * dx + dy * dy);
            let highest = distance[k] - o.radius + spread;
            if highest < least_highest {
                least_highest = highest;
            }
        }
    }
    let (mut kept, mut last) = (0, 0.0);
    let mut bits = near;
    while bits != 0 {
        let k = bits.trailing_zeros() as usize & (MAX_OBJECTS - 1);
        bits &= bits - 1;
        if let Some(o) = objects.get(k)
            && distance[k] - o.radius - spread <= least_highest
        {
            kept |= 1 << k;
            last = distance[k];
        }
    }
    (kept, last)
}

/// Calls `f` with the position of every bit set in `bits`, lowest first. A mask of actions
/// goes through it in two 32-bit halves (a 64-bit shift or count is several instructions on a
/// Cortex-M4), each with its halves of the tables and rows it indexes.
#[inline(always)]
fn for_each_bit(mut bits: u32, mut f: impl FnMut(usize)) {
    while bits != 0 {
        f(bits.trailing_zeros() as usize);
        bits &= bits - 1;
    }
}

/// The obstacle pass's first step: the beams within reach of some sample binned by range into
/// `shorter` (see `Evaluator::shorter`), their scan points into `points`, and the clip into
/// every sample's `clearance` (see [`fill`]); false when no beam is within reach (then nothing
/// reads what it wrote). Not inlined: the passes over the clusters then keep their registers
/// as they were (on the real ticks, mean / worst: this out of line −305 / −313 instructions
/// against the loop over every beam it replaced inline; the same mask inline −80 / +366, the
/// clusters' loops taking other registers).
#[inline(never)]
fn bin_beams(
    ranges: &[f32; SCAN_BEAMS],
    shorter: &mut [Beams; SHORTER],
    clearance: &mut [f32],
    points: &mut [[f32; 2]],
) -> bool {
    // Beams within reach of some sample, binned by range (bin b holding [b·w, (b+1)·w)) into
    // `shorter[b + 1]`, then accumulated in place: `shorter[b]` holds the bins below b.
    // Longer beams are never looked at. (In place rather than in a local array of bins:
    // `RANGE_BINS` × 8 bytes less on the stack of the evaluation.)
    let within = beams_within_reach(ranges);
    if within == [0; 2] {
        return false;
    }
    // Every entry zeroed, four at a time written out, with a zero the compiler cannot see
    // (`black_box`): a call to `memclr` otherwise.
    let zero = core::hint::black_box(0u32);
    for c in shorter.as_chunks_mut::<4>().0 {
        c[0] = [zero; 2];
        c[1] = [zero; 2];
        c[2] = [zero; 2];
        c[3] = [zero; 2];
    }
    let bins = &mut shorter[1..=RANGE_BINS];
    let mut any = false;
    for (half, base) in [(within[0], 0), (within[1], 32)] {
        for_each_bit(half, |j| {
            let j = (j + base) & (SCAN_BEAMS - 1);
            let r = ranges[j];
            let b = (r * (1.0 / RANGE_BIN_WIDTH)) as usize;
            if let Some(bin) = bins.get_mut(b) {
                bin[j >> 5] |= 1 << (j & 31);
                any = true;
                points[j] = [r * BEAM_COS[j], r * BEAM_SIN[j]];
            }
        });
    }
    if !any {
        return false;
    }
    let mut acc = [0u32; 2];
    for bin in bins.iter_mut() {
        acc = [acc[0] | bin[0], acc[1] | bin[1]];
        *bin = acc;
    }
    fill(clearance, OBSTACLE_CLIP);
    true
}

/// The beams within reach (`r < reach`, `BEAM_REACH`), one bit each, four beams at a time
/// without a branch: on the bits, as `i32`s, which are in the order of the values for a
/// validated range (+0 … the scan's maximum, or −0, whose bits are the least) and a positive
/// reach.
#[inline(always)]
fn beams_within_reach(ranges: &[f32; SCAN_BEAMS]) -> Beams {
    let mut within = [0u32; 2];
    for (w, (r, q)) in within.iter_mut().zip(
        ranges
            .as_chunks::<32>()
            .0
            .iter()
            .zip(REACH_BITS.as_chunks::<32>().0),
    ) {
        let mut m = 0u32;
        for (r, q) in r.as_chunks::<4>().0.iter().zip(q.as_chunks::<4>().0).rev() {
            let lt = |k: usize| u32::from((r[k].to_bits() as i32) < q[k]);
            m = m << 4 | lt(3) << 3 | lt(2) << 2 | lt(1) << 1 | lt(0);
        }
        *w = m;
    }
    within
}

/// `BEAM_REACH`'s bits, as `i32`s: for a positive reach and a validated range `r` (+0 … the
/// scan's maximum, or −0), `r < reach` exactly when `r.to_bits() as i32` is below.
static REACH_BITS: [i32; SCAN_BEAMS] = {
    let mut out = [0; SCAN_BEAMS];
    let mut j = 0;
    while j < SCAN_BEAMS {
        let q = BEAM_REACH[j];
        assert!(q > 0.0 && q < f32::INFINITY);
        out[j] = q.to_bits() as i32;
        j += 1;
    }
    out
};

/// The first creep trajectory: the cruise ones come first (each with a head of `HEADS`), then
/// the creep ones (the empty head, padding only), all in the upper half of a mask.
const CRUISE: usize = {
    let mut a = 0;
    while a < MAX_ACTIONS && (HEAD_OF[a] as usize) < HEAD_COUNT - 1 {
        a += 1;
    }
    let mut b = a;
    while b < MAX_ACTIONS {
        assert!(
            HEAD_OF[b] as usize == HEAD_COUNT - 1,
            "the creep trajectories come last"
        );
        b += 1;
    }
    assert!(32 <= a && a < MAX_ACTIONS && MAX_ACTIONS - a <= CREEP_SLOTS);
    a
};

/// The cruise trajectories' bits in the upper half of a mask.
const CRUISE_HIGH: u32 = (1 << (CRUISE - 32)) - 1;

/// The cruise heads: every head but the last (empty) one.
const CRUISE_HEADS: usize = HEAD_COUNT - 1;

/// The slots of head `h`'s samples.
const fn head_slots(h: usize) -> [usize; HEAD_LEN] {
    let mut out = [0; HEAD_LEN];
    let mut k = 0;
    while k < HEAD_LEN {
        out[k] = HEADS[h][k] as usize;
        assert!(out[k] < UNIQUE_SAMPLES);
        k += 1;
    }
    out
}

/// Where [`Evaluator::sum_rows`] keeps the cruise heads' sums in the scratch: after the scan
/// points (which the sums outlive), before the padding slot.
const HEADS_AT: usize = POINTS_AT + 2 * SCAN_BEAMS;
const _: () = assert!(HEADS_AT + CRUISE_HEADS <= PAD_SAMPLE);

/// Samples of a creep trajectory (its tail's; the rest of it padding).
const CREEP_SAMPLES: usize = 5;

/// Entries of `CREEP_SUMS`: a power of two, so that indexing it with a mask needs no bounds
/// check.
const CREEP_SLOTS: usize = 16;

/// A creep trajectory's `ROW_SCALE` (and a cruise one's is 1).
const CREEP_SCALE: f32 = (SAMPLES / CREEP_SAMPLES) as f32;

/// Whether `x` is a power of two (a normal `f32` with no mantissa bit): a product by it or a
/// quotient by it is exact.
const fn power_of_two(x: f32) -> bool {
    let bits = x.to_bits();
    bits & 0x807f_ffff == 0 && bits >> 23 != 0 && bits >> 23 != 0xff
}

const _: () = {
    assert!(power_of_two(OBSTACLE_CLIP) && power_of_two(SEMANTIC_CLIP));
    assert!(power_of_two(CREEP_SCALE));
    let mut a = 0;
    while a < MAX_ACTIONS {
        assert!(ROW_SCALE[a] == if a < CRUISE { 1.0 } else { CREEP_SCALE });
        a += 1;
    }
};

/// The smallest slot that sample position `k` of a cruise trajectory (0: its head's sum, in
/// the slots from `HEADS_AT`; then its first four tail samples) reads, or 255 when that is
/// more (a `vldr`'s largest offset): `CruiseSum::near` is the offset from it.
const NEAR_BASE: [usize; 5] = {
    let mut base = [255; 5];
    let mut a = 0;
    while a < CRUISE {
        let mut k = 0;
        while k < 5 {
            let u = near_slot(a, k);
            if u < base[k] {
                base[k] = u;
            }
            k += 1;
        }
        a += 1;
    }
    base
};

/// The slot that position `k` of cruise trajectory `a` reads (see `NEAR_BASE`).
const fn near_slot(a: usize, k: usize) -> usize {
    if k == 0 {
        HEADS_AT + HEAD_OF[a] as usize
    } else {
        TAIL_OF[a][k - 1] as usize
    }
}

/// Where a cruise trajectory's sum reads its samples: its head's sum and its first four tail
/// samples as offsets from `NEAR_BASE` (one byte each: no mask is needed to stay within the
/// scratch), its last two tail samples (whose slots span more than 255) as indices. Nothing at
/// offset 0: every field is then read at an offset from the entry's address, which the
/// compiler computes once (it read a field at offset 0 at an index, and computed the address
/// apart).
#[derive(Clone, Copy)]
#[repr(C, align(16))]
struct CruiseSum {
    near: [u8; 6],
    far: [u16; 2],
}

/// Per action, where its sum reads its samples when it is a cruise trajectory (and nothing of
/// use for a creep one: 64 entries, so that indexing needs no bounds check).
static CRUISE_SUMS: [CruiseSum; MAX_ACTIONS] = {
    let mut out = [CruiseSum {
        near: [0; 6],
        far: [0; 2],
    }; MAX_ACTIONS];
    let mut a = 0;
    while a < CRUISE {
        let mut k = 0;
        while k < 5 {
            let off = near_slot(a, k) - NEAR_BASE[k];
            assert!(off <= 255 && NEAR_BASE[k] + 255 < SCRATCH);
            out[a].near[k + 1] = off as u8;
            k += 1;
        }
        assert!(HEAD_LEN + TAIL_LEN == SAMPLES && TAIL_LEN == 6);
        out[a].far = [TAIL_OF[a][4], TAIL_OF[a][5]];
        a += 1;
    }
    out
};

/// Per creep trajectory (from `CRUISE`), its samples (each below 256: no mask is needed to
/// stay within the scratch), from offset 1 (as `CruiseSum`, nothing at offset 0); the rest of
/// its tail is padding.
static CREEP_SUMS: [[u8; 8]; CREEP_SLOTS] = {
    let mut out = [[0; 8]; CREEP_SLOTS];
    let mut a = CRUISE;
    while a < MAX_ACTIONS {
        let mut k = 0;
        while k < TAIL_LEN {
            let u = TAIL_OF[a][k] as usize;
            if k < CREEP_SAMPLES {
                assert!(u < 256 && u != PAD_SAMPLE);
                out[a - CRUISE][k + 1] = u as u8;
            } else {
                assert!(u == PAD_SAMPLE, "a creep trajectory has five samples");
            }
            k += 1;
        }
        a += 1;
    }
    out
};

/// What the obstacle pass found.
#[derive(Clone, Copy)]
enum Obstacles {
    /// No scan point within reach of any sample: nothing collides, every clearance is the clip.
    Clear,
    /// The trajectories that do not collide (one bit per action); the clearances of their
    /// samples are in `Evaluator::clearance`, and `touched` has the trajectories with a sample
    /// nearer than the clip to a scan point.
    Measured { allowed: u64, touched: u64 },
}

/// The sample indices of a cluster's members, masked into the scratch arrays' range.
#[inline]
fn members(cluster: &Cluster) -> impl Iterator<Item = usize> {
    (usize::from(cluster.samples[0])..usize::from(cluster.samples[1])).map(|u| u & (SCRATCH - 1))
}

/// Chunks of [`LANES`] samples that cover every sample.
#[cfg(not(target_arch = "arm"))]
const LANE_CHUNKS: usize = UNIQUE_SAMPLES.div_ceil(LANES);

#[cfg(not(target_arch = "arm"))]
const _: () = assert!(LANE_CHUNKS * LANES <= POINTS_AT && LANE_CHUNKS <= 32);

/// Where no sample is: a lane past the last sample, farther than any scan point's reach.
#[cfg(not(target_arch = "arm"))]
const NOWHERE: f32 = 1.0e3;

/// The samples' coordinates, [`LANES`] at a time: `[x, y]` of chunk `k`, samples
/// `k · LANES ..` (the lanes past the last sample [`NOWHERE`]).
#[cfg(not(target_arch = "arm"))]
static SAMPLE_LANES: [[[f32; LANES]; 2]; LANE_CHUNKS] = {
    let mut out = [[[NOWHERE; LANES]; 2]; LANE_CHUNKS];
    let mut u = 0;
    while u < UNIQUE_SAMPLES {
        out[u / LANES][0][u % LANES] = SAMPLE_POINTS[u][0];
        out[u / LANES][1][u % LANES] = SAMPLE_POINTS[u][1];
        u += 1;
    }
    out
};

/// The box around chunk `k`'s samples, `[[x_min, x_max], [y_min, y_max]]` (the lanes past the
/// last sample left out).
#[cfg(not(target_arch = "arm"))]
static LANE_BOXES: [[[f32; 2]; 2]; LANE_CHUNKS] = {
    let mut out = [[[f32::MAX, f32::MIN]; 2]; LANE_CHUNKS];
    let mut u = 0;
    while u < UNIQUE_SAMPLES {
        let b = &mut out[u / LANES];
        let mut i = 0;
        while i < 2 {
            let v = SAMPLE_POINTS[u][i];
            if v < b[i][0] {
                b[i][0] = v;
            }
            if v > b[i][1] {
                b[i][1] = v;
            }
            i += 1;
        }
        u += 1;
    }
    out
};

/// The least of `least` (at most [`SEMANTIC_CLIP`]) and the semantic clearance of a lane whose
/// root less the object's radius is `d`: `d` at least 0, then the least. The same bits as the
/// general member loop's value (the clip beyond the reach, else `d` at least 0 and at most the
/// clip) taken into the least, without its clip and its test of the reach: where that value is
/// the clip, `d` is at least the clip (beyond the reach, the root is at least the reach less
/// rounding far below its millimetre of margin: `d` exceeds the clip), so the least is `least`
/// either way (it is at most the clip); elsewhere both are the least of `d` at least 0 and
/// `least` (tested on every case, `the_lane_formula_is_the_general_loops`).
#[cfg(not(target_arch = "arm"))]
#[inline(always)]
fn least_with(d: f32, least: f32) -> f32 {
    clipped(if d > 0.0 { d } else { 0.0 }, least)
}

/// [`LANE_BOXES`] one array per bound, for every chunk side by side: `[[x_min, x_max], [y_min,
/// y_max]]`.
#[cfg(not(target_arch = "arm"))]
static BOX_LANES: [[[f32; LANE_CHUNKS]; 2]; 2] = {
    let mut out = [[[0.0; LANE_CHUNKS]; 2]; 2];
    let mut k = 0;
    while k < LANE_CHUNKS {
        let mut i = 0;
        while i < 2 {
            out[i][0][k] = LANE_BOXES[k][i][0];
            out[i][1][k] = LANE_BOXES[k][i][1];
            i += 1;
        }
        k += 1;
    }
    out
};

/// The greater of `a` and `b` (no NaN here).
#[cfg(not(target_arch = "arm"))]
#[inline(always)]
fn at_least(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// The trajectories some sample of chunk `k` belongs to.
#[cfg(not(target_arch = "arm"))]
static LANE_UNION: [u64; LANE_CHUNKS] = {
    let mut out = [0; LANE_CHUNKS];
    let mut u = 0;
    while u < UNIQUE_SAMPLES {
        out[u / LANES] |= SAMPLE_TRAJECTORIES[u];
        u += 1;
    }
    out
};

/// Every sample's trajectories, [`LANES`] at a time, as two halves (`[k][0]` the low 32 bits
/// of chunk `k`'s lanes, `[k][1]` the high ones; none for the lanes past the last sample),
/// aligned for whole vectors ([`trajectories_below`]).
#[cfg(not(target_arch = "arm"))]
#[repr(C, align(64))]
struct LaneHalves([[[u32; LANES]; 2]; LANE_CHUNKS]);

/// See [`LaneHalves`].
#[cfg(not(target_arch = "arm"))]
static LANE_HALVES: LaneHalves = {
    let mut out = [[[0; LANES]; 2]; LANE_CHUNKS];
    let mut u = 0;
    while u < UNIQUE_SAMPLES {
        assert!(SAMPLE_TRAJECTORIES[u] != 0, "every sample has a trajectory");
        let (k, l) = (u / LANES, u % LANES);
        out[k][0][l] = SAMPLE_TRAJECTORIES[u] as u32;
        out[k][1][l] = (SAMPLE_TRAJECTORIES[u] >> 32) as u32;
        u += 1;
    }
    LaneHalves(out)
};

/// The union of the trajectories (`of`: a chunk's [`LANE_HALVES`]) of the lanes whose value is
/// below `x`: each lane's halves under a mask of all ones or zeros, in four accumulators of
/// each half (the compiler keeps them in two vectors; inlined, it left them scalar).
#[cfg(not(target_arch = "arm"))]
#[inline(never)]
fn trajectories_below(values: &[f32; LANES], x: f32, of: &[[u32; LANES]; 2]) -> u64 {
    let (mut low, mut high) = ([0u32; 4], [0u32; 4]);
    for g in 0..LANES / 4 {
        for i in 0..4 {
            let l = 4 * g + i;
            let m = if values[l] < x { u32::MAX } else { 0 };
            low[i] |= m & of[0][l];
            high[i] |= m & of[1][l];
        }
    }
    let low = (low[0] | low[1]) | (low[2] | low[3]);
    let high = (high[0] | high[1]) | (high[2] | high[3]);
    u64::from(low) | u64::from(high) << 32
}

/// Whether some lane's value is below `x` (one comparison a lane, without an early exit: the
/// compiler tests them together).
#[cfg(not(target_arch = "arm"))]
#[inline(always)]
fn any_below(values: &[f32; LANES], x: f32) -> bool {
    values.iter().fold(false, |any, &v| any | (v < x))
}

/// Every chunk, one bit each.
#[cfg(not(target_arch = "arm"))]
const ALL_CHUNKS: u32 = if LANE_CHUNKS == 32 {
    u32::MAX
} else {
    (1 << LANE_CHUNKS) - 1
};

#[cfg(not(target_arch = "arm"))]
const _: () = assert!(LANES.is_multiple_of(4), "four lanes a vector");

/// Every beam within reach is within the range bins (the car's pass, which leaves out a beam
/// past the last bin, and the host's, which does not test it, take the same beams): the
/// longest reach's bin, as `r · (1 / RANGE_BIN_WIDTH)` rounds it, with room to spare.
const _: () = {
    let mut j = 0;
    while j < SCAN_BEAMS {
        assert!(BEAM_REACH[j] * (1.0 / RANGE_BIN_WIDTH) < RANGE_BINS as f32 - 0.5);
        j += 1;
    }
};

/// Range bins below the first that holds only beams at least the clip plus the largest spread
/// (and the margin) long: `shorter[CLOSE_BINS]` holds every beam shorter.
const CLOSE_BINS: usize = bins_below(OBSTACLE_CLIP + MAX_CLUSTER_SPREAD + REACH_MARGIN);

/// The number of whole bins that cover `[0, d)`.
const fn bins_below(d: f32) -> usize {
    let n = (d / RANGE_BIN_WIDTH) as usize + 1;
    assert!(n <= RANGE_BINS);
    n
}

/// Entries of `Evaluator::shorter`: `RANGE_BINS + 1` rounded up to a power of two, so that
/// indexing it with a mask needs no bounds check (the entries above `RANGE_BINS` stay empty and
/// are never read: the bands end at `RANGE_BINS`).
const SHORTER: usize = (RANGE_BINS + 1).next_power_of_two();

/// The cross-track error `|cross|` (m) of every trajectory's end against the path reference: the
/// distance from the end to the line through the reference point along the path's heading.
///
/// This is what a statement about the path ("stay on the path") judges (paper, section 6: the
/// path by cross-track error; see [`crate::SemanticFeedback`]). The teacher on the host calls the
/// same function, so both sides compare the same numbers. Exact (no root), not clipped. The
/// heading is a validated one (|heading| ≤ π, [`Observation::check`]); beyond ±5π/4 the car's
/// sine and cosine are no longer `libm`'s bits (see [`sincosf`]).
///
/// ```
/// use firmware_core::evaluator::cross_track_errors;
/// use firmware_core::observation::PathReference;
/// use firmware_core::ActionIndex;
///
/// // The path runs straight ahead along the car's axis: the straight trajectory is on it.
/// let cross = cross_track_errors(&PathReference { x: 1.0, y: 0.0, heading: 0.0 });
/// assert_eq!(cross[ActionIndex::FIRST.get()], 0.0);
/// assert!(cross.iter().all(|&d| d >= 0.0));
/// ```
pub fn cross_track_errors(reference: &PathReference) -> [f32; MAX_ACTIONS] {
    let p = reference;
    // `sincosf` (`libm`'s bits for a validated heading, without its large-argument reduction:
    // see `crate::trig`), as `PathFrame::new`. Host and car both reach this function, so they
    // compare the same numbers whatever the last bit of the heading's sine.
    let (s, c) = sincosf(p.heading);
    let mut out = [0.0f32; MAX_ACTIONS];
    for (d, &[x, y]) in out.iter_mut().zip(END_POINTS.iter()) {
        // The cross-track part of the end in the reference's frame (as `PathFrame::path_and_side_of`'s
        // `local.y`), written out with `sincosf`.
        let dx = x - p.x;
        let dy = y - p.y;
        let cross = dy * c - dx * s;
        *d = libm::fabsf(cross);
    }
    out
}

/// The path reference's frame, for the path and side features: made once per observation
/// (one `sincosf`), before the evaluator's scratch is in use.
pub(crate) struct PathFrame {
    reference: Isometry2<f32>,
}

impl PathFrame {
    /// The frame of `p`, whose heading [`Observation::check`] validated (|heading| ≤ π). Cosine
    /// and sine from [`sincosf`], `libm::sincosf`'s bits for such a heading (every one checked
    /// exhaustively) on the host and the car: one `sincosf` is the same bits as `sinf` and `cosf`
    /// apart (checked exhaustively too) and reduces the angle once.
    #[inline]
    pub(crate) fn new(p: &PathReference) -> Self {
        let (sin, cos) = sincosf(p.heading);
        Self {
            reference: Isometry2::from_parts(
                Translation2::new(p.x, p.y),
                UnitComplex::from_cos_sin_unchecked(cos, sin),
            ),
        }
    }

    /// Path error and lateral offset of the trajectory that ends at `[x, y]`: the end in the
    /// frame of the path reference (`along`, `cross`), and the end's `y`.
    #[inline(always)]
    fn path_and_side_of(&self, [x, y]: [f32; 2]) -> [f32; 2] {
        let local = self.reference.inverse_transform_point(&Point2::new(x, y));
        let error = libm::fabsf(local.x) + libm::fabsf(local.y);
        [
            if error < PATH_CLIP { error } else { PATH_CLIP },
            -RIGHT_SCALE * y,
        ]
    }
}

/// The directions of the scan's beams, `(cos, sin)` of [`beam_bearing`](crate::observation::beam_bearing),
/// exactly as the evaluator uses them.
pub fn beam_direction(j: usize) -> Option<(f32, f32)> {
    (j < SCAN_BEAMS).then(|| (BEAM_COS[j], BEAM_SIN[j]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::TRAJECTORIES;

    #[test]
    fn the_scratch_is_the_size_the_docs_give() {
        // The agent keeps one (its documentation, and docs/firmware.md's RAM figures).
        assert_eq!(core::mem::size_of::<Evaluator>(), 2944);
    }

    #[test]
    fn end_points_are_the_trajectories_ends() {
        for (t, &[x, y]) in TRAJECTORIES.iter().zip(END_POINTS.iter()) {
            assert_eq!([t.end().x, t.end().y], [x, y]);
        }
    }

    #[test]
    fn heads_and_tails_are_the_trajectories_samples() {
        use crate::lattice::{SAMPLE_COUNT, SAMPLE_OF};
        for a in 0..MAX_ACTIONS {
            let n = TRAJECTORIES[a].samples().len();
            assert_eq!(usize::from(SAMPLE_COUNT[a]), n, "trajectory {a}");
            let mut samples = HEADS[usize::from(HEAD_OF[a])].to_vec();
            samples.extend_from_slice(&TAIL_OF[a]);
            samples.retain(|&u| usize::from(u) != crate::lattice::PAD_SAMPLE);
            assert_eq!(samples, SAMPLE_OF[a][..n], "trajectory {a}");
            assert_eq!(ROW_SCALE[a], (SAMPLES / n) as f32, "trajectory {a}");
        }
    }

    #[test]
    fn the_beams_within_reach_are_those_below_their_reach() {
        // `beams_within_reach` compares bits as `i32`s: the float comparison's verdict on every
        // validated range, −0 and the values at and around each beam's reach included.
        use crate::observation::SCAN_MAX_RANGE;
        for j in 0..SCAN_BEAMS {
            let q = BEAM_REACH[j];
            let values = [
                -0.0,
                0.0,
                f32::from_bits(1),
                f32::MIN_POSITIVE,
                f32::from_bits(q.to_bits() - 1),
                q,
                f32::from_bits(q.to_bits() + 1),
                q * 0.5,
                SCAN_MAX_RANGE,
            ];
            for (k, &r) in values.iter().enumerate() {
                if !(0.0..=SCAN_MAX_RANGE).contains(&r) {
                    continue;
                }
                let mut ranges = [SCAN_MAX_RANGE; SCAN_BEAMS];
                ranges[j] = r;
                // And a neighbour with another value, so that the four beams of a step differ.
                ranges[j ^ 1] = values[(k + 3) % values.len()].min(SCAN_MAX_RANGE);
                let within = beams_within_reach(&ranges);
                for (i, &r) in ranges.iter().enumerate() {
                    let bit = within[i >> 5] >> (i & 31) & 1 != 0;
                    assert_eq!(bit, r < BEAM_REACH[i], "beam {i}, range {r:e}");
                }
            }
        }
    }

    /// A small deterministic generator (xorshift), for the paths' comparison below.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }

        fn unit(&mut self) -> f32 {
            (self.next() >> 40) as f32 / (1u64 << 24) as f32
        }

        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.unit()
        }
    }

    /// Scans of several kinds (uniform, near clutter, a corridor, a wall ahead, open space),
    /// objects anywhere near the lattice, some on a sample or of a tiny radius, and any path.
    fn random_observation(rng: &mut Rng) -> Observation {
        use crate::observation::{MAX_OBJECT_RADIUS, SCAN_MAX_RANGE, SemanticObject};
        let mut obs = Observation::open_space();
        let kind = rng.next() % 5;
        let (a, b) = (rng.range(0.2, 2.5), rng.range(0.2, 1.5));
        for j in 0..SCAN_BEAMS {
            let (c, s) = (BEAM_COS[j], BEAM_SIN[j]);
            obs.scan.ranges[j] = match kind {
                0 => rng.range(0.0, SCAN_MAX_RANGE),
                1 if rng.next().is_multiple_of(3) => SCAN_MAX_RANGE,
                1 => rng.range(0.05, 2.0),
                2 => (if s > 0.0 { a / s } else { b / -s }).min(SCAN_MAX_RANGE),
                3 if c > 0.05 => (a / c).min(SCAN_MAX_RANGE),
                _ => SCAN_MAX_RANGE,
            };
        }
        for _ in 0..rng.next() % (MAX_OBJECTS as u64 + 1) {
            let class = SemanticClass::ALL[(rng.next() % 3) as usize];
            let [x, y] = if rng.next().is_multiple_of(8) {
                SAMPLE_POINTS[(rng.next() % UNIQUE_SAMPLES as u64) as usize]
            } else {
                [rng.range(-4.0, 4.0), rng.range(-4.0, 4.0)]
            };
            let radius = match rng.next() % 10 {
                0 => 1.0e-30,
                1 => 5.0e-4,
                2 => MAX_OBJECT_RADIUS,
                _ => rng.range(0.05, 1.5),
            };
            let _ = obs.objects.push(SemanticObject {
                class,
                x,
                y,
                radius,
            });
        }
        obs.reference = PathReference {
            x: rng.range(-2.0, 3.0),
            y: rng.range(-2.0, 2.0),
            heading: rng.range(-3.0, 3.0),
        };
        obs
    }

    /// The host's paths (`WIDE`) and the car's give the same mask and the same feature bits, on
    /// a fresh evaluator and on one reused from observation to observation.
    #[test]
    fn the_wide_paths_are_the_cars_bit_for_bit() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let (mut narrow, mut wide) = (Evaluator::new(), Evaluator::new());
        for i in 0..20_000 {
            let obs = random_observation(&mut rng);
            let valid = obs.check().unwrap();
            let frame = PathFrame::new(&obs.reference);
            let mut tables = [FeatureTable::ZERO, FeatureTable::ZERO, FeatureTable::ZERO];
            let masks = [
                narrow.clearances_with::<false>(valid, &frame, &mut tables[0]),
                wide.clearances_with::<true>(valid, &frame, &mut tables[1]),
                Evaluator::new().clearances_with::<true>(valid, &frame, &mut tables[2]),
            ];
            let bits = |t: &FeatureTable| -> Vec<u32> {
                t.rows().iter().flatten().map(|v| v.to_bits()).collect()
            };
            assert_eq!(masks[0], masks[1], "observation {i}: {obs:?}");
            assert_eq!(masks[0], masks[2], "observation {i}: {obs:?}");
            assert_eq!(
                bits(&tables[0]),
                bits(&tables[1]),
                "observation {i}: {obs:?}"
            );
            assert_eq!(
                bits(&tables[0]),
                bits(&tables[2]),
                "observation {i}: {obs:?}"
            );
        }
    }

    /// The host's paths and the car's on scans at the edges the host's obstacle pass decides
    /// on: every beam at 0, at its reach and just below it, at each range bin's edges and their
    /// neighbours, at the range that puts its point nearest a sample (on it, for the samples on
    /// the beam's ray), and at the collision radius and the clip from a sample along the ray;
    /// with and without objects on samples.
    #[test]
    fn the_wide_paths_are_the_cars_at_the_edges() {
        let mut rng = Rng(0x510e_527f_ade6_82d1);
        let (mut narrow, mut wide) = (Evaluator::new(), Evaluator::new());
        let mut compare = |obs: &Observation| {
            let valid = obs.check().unwrap();
            let frame = PathFrame::new(&obs.reference);
            let mut tables = [FeatureTable::ZERO, FeatureTable::ZERO];
            let masks = [
                narrow.clearances_with::<false>(valid, &frame, &mut tables[0]),
                wide.clearances_with::<true>(valid, &frame, &mut tables[1]),
            ];
            let bits = |t: &FeatureTable| -> Vec<u32> {
                t.rows().iter().flatten().map(|v| v.to_bits()).collect()
            };
            assert_eq!(masks[0], masks[1], "{obs:?}");
            assert_eq!(bits(&tables[0]), bits(&tables[1]), "{obs:?}");
        };
        for case in 0..4_000 {
            let mut obs = random_observation(&mut rng);
            if case % 2 == 0 {
                obs.objects.clear();
            }
            for j in 0..SCAN_BEAMS {
                let (c, s) = (BEAM_COS[j], BEAM_SIN[j]);
                let [x, y] = SAMPLE_POINTS[(rng.next() % UNIQUE_SAMPLES as u64) as usize];
                let along = (x * c + y * s).max(0.0);
                let bin = (rng.next() % (RANGE_BINS as u64 + 1)) as f32 * RANGE_BIN_WIDTH;
                let r = match rng.next() % 12 {
                    0 => 0.0,
                    1 => BEAM_REACH[j],
                    2 => BEAM_REACH[j].next_down(),
                    3 => bin,
                    4 => bin.next_down(),
                    5 => bin.next_up(),
                    6 => along,
                    7 => along + COLLISION_RADIUS,
                    8 => (along - COLLISION_RADIUS).max(0.0),
                    9 => along + OBSTACLE_CLIP,
                    10 => (along - OBSTACLE_CLIP).max(0.0),
                    _ => obs.scan.ranges[j],
                };
                obs.scan.ranges[j] = r.clamp(0.0, crate::observation::SCAN_MAX_RANGE);
            }
            compare(&obs);
        }
    }

    /// `least_with` is the general member loop's value taken into the least, bit for bit: on
    /// random squared distances and radii, each reach's square and its neighbours, a sample on
    /// the centre, and every least from 0 to the clip.
    #[test]
    fn the_lane_formula_is_the_general_loops() {
        use crate::observation::MAX_OBJECT_RADIUS;
        let mut rng = Rng(0x3c6e_f372_fe94_f82b);
        let general = |d2: f32, o: &Disc, least: f32| {
            let d = newton_sqrt(d2) - o.radius;
            let d = clipped(if d > 0.0 { d } else { 0.0 }, SEMANTIC_CLIP);
            clipped(if d2 < o.reach2 { d } else { SEMANTIC_CLIP }, least)
        };
        for i in 0..2_000_000u32 {
            let radius = match i % 7 {
                0 => REACH_MARGIN,
                1 => MAX_OBJECT_RADIUS,
                2 => rng.range(REACH_MARGIN, 0.05),
                _ => rng.range(REACH_MARGIN, MAX_OBJECT_RADIUS),
            };
            let o = Disc::new(rng.range(-4.0, 4.0), rng.range(-4.0, 4.0), radius);
            let d2 = match i % 9 {
                0 => o.reach2,
                1 => o.reach2.next_down(),
                2 => o.reach2.next_up(),
                3 => 0.0,
                4 => rng.range(0.0, radius * radius),
                5 => rng.range(0.0, 2.0) * o.reach2,
                _ => {
                    let d = rng.range(0.0, o.reach + 1.0);
                    d * d
                }
            };
            let least = match i % 5 {
                0 => SEMANTIC_CLIP,
                1 => 0.0,
                _ => rng.range(0.0, SEMANTIC_CLIP),
            };
            let root = newton_sqrt(d2) - o.radius;
            assert_eq!(
                least_with(root, least).to_bits(),
                general(d2, &o, least).to_bits(),
                "d2 {d2}, radius {radius}, least {least}"
            );
        }
    }

    /// A chunk that `BEAM_CHUNKS` leaves out for a beam's range bin has no lane within the clip
    /// of that beam's scan point at any range of the bin (every 0.5 mm up to the beam's reach,
    /// and each bin's edges to the ulp), as the wide obstacle pass computes the points and the
    /// squared distances.
    #[test]
    fn a_chunk_left_out_of_a_bin_is_beyond_the_clip() {
        let clip2 = OBSTACLE_CLIP * OBSTACLE_CLIP;
        for j in 0..SCAN_BEAMS {
            let mut ranges = std::vec::Vec::new();
            let mut r = 0.0f32;
            while r < BEAM_REACH[j] {
                ranges.push(r);
                r += 5.0e-4;
            }
            for b in 0..=RANGE_BINS {
                let edge = b as f32 * RANGE_BIN_WIDTH;
                ranges.extend([edge.next_down(), edge, edge.next_up()]);
            }
            for r in ranges {
                let binned = r * (1.0 / RANGE_BIN_WIDTH) < RANGE_BINS as f32;
                if !(r >= 0.0 && r < BEAM_REACH[j] && binned) {
                    continue;
                }
                let b = (r * (1.0 / RANGE_BIN_WIDTH)) as usize;
                let (px, py) = (r * BEAM_COS[j], r * BEAM_SIN[j]);
                for (k, [sx, sy]) in SAMPLE_LANES.iter().enumerate() {
                    if BEAM_CHUNKS[j][b] >> k & 1 == 1 {
                        continue;
                    }
                    for l in 0..LANES {
                        let (dx, dy) = (px - sx[l], py - sy[l]);
                        assert!(
                            dx * dx + dy * dy >= clip2,
                            "beam {j} at {r} (bin {b}), chunk {k} lane {l}"
                        );
                    }
                }
            }
        }
    }

    /// An evaluation written over another is the evaluation made new: the same mask, reference,
    /// rows and (on a host) columns, bit for bit, whatever it held.
    #[test]
    fn an_evaluation_written_over_is_one_made_new() {
        let mut rng = Rng(0x6a09_e667_f3bc_c908);
        let mut evaluator = Evaluator::new();
        let mut reused = Evaluator::new().evaluation(Observation::open_space().check().unwrap());
        for i in 0..2_000 {
            let obs = random_observation(&mut rng);
            let valid = obs.check().unwrap();
            let new = Evaluator::new().evaluation(valid);
            evaluator.evaluation_into(valid, &mut reused);
            let bits = |e: &Evaluation| -> (u64, Vec<u32>, Option<Vec<u32>>) {
                let t = e.table();
                (
                    e.allowed().bits(),
                    t.rows().iter().flatten().map(|v| v.to_bits()).collect(),
                    t.columns()
                        .map(|c| c.iter().flatten().map(|v| v.to_bits()).collect()),
                )
            };
            assert_eq!(bits(&reused), bits(&new), "observation {i}: {obs:?}");
            assert_eq!(reused.reference(), new.reference());
        }
    }

    /// The evaluator seals what it writes (on a host: the table's columns, which the learner's
    /// passes read), whatever the table held.
    #[test]
    fn the_evaluation_is_sealed() {
        let mut rng = Rng(0x2545_f491_4f6c_dd1d);
        let mut table = FeatureTable::ZERO;
        for i in 0..200 {
            let obs = random_observation(&mut rng);
            table[crate::ActionIndex::new(i % 64).unwrap()][0] = f32::NAN;
            assert!(!table.is_sealed());
            let allowed = Evaluator::new().evaluate(obs.check().unwrap(), &mut table);
            assert_eq!(table.is_sealed(), WIDE);
            assert_eq!(
                table.check(allowed),
                FeatureTable::from_rows(*table.rows()).check(allowed)
            );
        }
    }

    fn check(x: f32) {
        let exact = (x as f64).sqrt();
        let err = ((sqrt(x) as f64 - exact) / exact).abs();
        assert!(
            err <= SQRT_RELATIVE_ERROR as f64,
            "sqrt({x:e}): relative error {err:e}"
        );
    }

    #[test]
    fn sqrt_is_within_its_bound_on_a_dense_sample() {
        let (first, last) = (f32::MIN_POSITIVE.to_bits(), 1.0e4f32.to_bits());
        let mut b = first;
        while b <= last {
            check(f32::from_bits(b));
            b += 997; // about 1.1 million points spread over every binade
        }
        for x in [
            f32::MIN_POSITIVE,
            1.0,
            2.0,
            0.25,
            0.0625,
            1.0e4,
            0.5 * 0.5,
            0.25 * 0.25,
        ] {
            check(x);
        }
        assert_eq!(sqrt(0.0), 0.0);
        assert_eq!(
            sqrt(1.0e-40),
            libm::sqrtf(1.0e-40),
            "subnormals take the exact path"
        );
    }

    /// Every f32 the evaluator can take a root of: `cargo test -p firmware-core --release --lib
    /// -- --ignored sqrt_exhaustive` (about ten seconds).
    #[test]
    #[ignore]
    fn sqrt_exhaustive() {
        let mut worst = 0.0f64;
        for b in f32::MIN_POSITIVE.to_bits()..=1.0e4f32.to_bits() {
            let x = f32::from_bits(b);
            let exact = (x as f64).sqrt();
            worst = worst.max(((sqrt(x) as f64 - exact) / exact).abs());
        }
        println!("largest relative error {worst:e}");
        assert!(worst <= SQRT_RELATIVE_ERROR as f64);
    }
}
