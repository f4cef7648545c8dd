//! From one observation, the features of all 64 trajectories and the collision mask.
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
//! # Cost: exact, not brute force
//!
//! A brute-force evaluator measures every (trajectory, sample, beam): 64 × 10 × 64 = 40 960
//! distances. This one is exact with a fraction of that:
//!
//! 1. the 565 samples of the lattice are only 340 distinct points (trajectories share their first
//!    segments), evaluated once each;
//! 2. for a sample at range `ρ` and bearing `α`, a scan point on the beam at bearing `β` is at least
//!    `ρ·sin|α − β|` away (at least `ρ` beyond 90°), so only the beams within
//!    `asin(0.5 m / ρ)` of `α` can come within the 0.5 m clip, and for a sample nearer than the
//!    clip, a beam more than 90° away comes no nearer than its own range, so only those shorter
//!    than the clip (found each tick) need testing; these windows are computed at
//!    compile time (`build.rs`) as one 64-bit beam mask per sample, 11 518 (sample, beam) pairs
//!    in all ([`WINDOW_PAIRS`](crate::lattice::WINDOW_PAIRS)), with a 0.01 rad margin;
//! 3. a beam whose range exceeds `ρ + 0.5 m` cannot come within the clip either: each tick
//!    builds the mask of beams shorter than the farthest sample's `ρ` + 0.5 m, ANDs it with each
//!    window, and checks the sample's own `ρ + 0.5 m` for the rest. In open space no beam is
//!    near and the obstacle pass costs nothing.
//!
//! Every skipped beam is provably farther than the clip, so pruning changes no result.
//!
//! Square roots use [`sqrt`], a seed and two Newton steps with relative error at most
//! [`SQRT_RELATIVE_ERROR`] (a Cortex-M4 spends about 70 instructions on `libm`'s correctly
//! rounded one, 8 on this). Collisions are decided on squared distances, without any root. So,
//! against a brute-force evaluator with exact square roots (the naive std implementation in
//! `tests/support/naive.rs`), the collision mask is identical and every feature is within
//! [`FEATURE_ERROR_BOUND`]:
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
//! ```
//! use firmware_core::evaluator::Evaluator;
//! use firmware_core::observation::Observation;
//! use firmware_core::{FeatureTable, ActionMask};
//!
//! let mut evaluator = Evaluator::new();
//! let mut table = FeatureTable::ZERO;
//! let allowed = evaluator.evaluate(&Observation::open_space(), &mut table).unwrap();
//! assert_eq!(allowed, ActionMask::ALL); // nothing to hit
//! ```

use crate::action::{ActionIndex, ActionMask, MAX_ACTIONS};
use crate::feature::{Feature, FeatureTable, Features};
use crate::lattice::{
    BEAM_COS, BEAM_SIN, MAX_SAMPLE_RHO, OBSTACLE_CLIP, SAMPLE_COUNT, SAMPLE_OF, SAMPLE_POINTS,
    SAMPLE_RHO, SAMPLE_WINDOW, SAMPLES, SAMPLES_BY_RHO, SCAN_BEAMS, TRAJECTORIES, UNIQUE_SAMPLES,
};
use crate::observation::{Observation, ObservationError, PathReference, SemanticClass};

/// Clearances to semantic objects are clipped at this distance (m).
pub const SEMANTIC_CLIP: f32 = 2.0;

/// A sample closer than this to a scan point collides (m): the car's half-width 0.15 m plus a
/// 0.10 m margin.
pub const COLLISION_RADIUS: f32 = 0.25;

/// Largest difference between a feature of this evaluator and the same feature computed with
/// exact square roots (see the module documentation for the derivation; tested).
pub const FEATURE_ERROR_BOUND: f32 = 1.0e-4;

/// The path error is clipped at this value (m).
pub const PATH_CLIP: f32 = 4.0;

/// [`Feature::Right`] is the end's lateral offset in these units per metre (decimetres).
pub const RIGHT_SCALE: f32 = 10.0;

const _: () = assert!(
    COLLISION_RADIUS < OBSTACLE_CLIP,
    "collisions are decided inside the windows"
);
const _: () = assert!(UNIQUE_SAMPLES <= u16::MAX as usize);
const _: () = assert!(crate::observation::SCAN_BEAMS == SCAN_BEAMS);

const COLLIDE_WORDS: usize = SCRATCH / 32;

/// Length of the per-sample scratch arrays: the next power of two above the distinct samples.
const SCRATCH: usize = UNIQUE_SAMPLES.next_power_of_two();

/// Slack added to "range beyond ρ + clip" before a beam is skipped: 1 mm, far above f32
/// rounding at these magnitudes, so a skipped beam is provably beyond the clip.
const REACH_MARGIN: f32 = 1.0e-3;

/// Width of the range bins of the obstacle pass (m).
const BIN_WIDTH: f32 = 0.05;

/// Number of range bins: enough to cover the farthest sample's ρ + clip.
const RANGE_BINS: usize =
    ((MAX_SAMPLE_RHO + OBSTACLE_CLIP + REACH_MARGIN) / BIN_WIDTH) as usize + 1;

/// `BIN_EDGES[b] = b · BIN_WIDTH`, the lower edge of bin `b` (and the upper edge of bin `b − 1`).
const BIN_EDGES: [f32; RANGE_BINS + 1] = {
    let mut e = [0.0f32; RANGE_BINS + 1];
    let mut b = 0;
    while b <= RANGE_BINS {
        e[b] = b as f32 * BIN_WIDTH;
        b += 1;
    }
    e
};

/// The evaluator and its scratch memory (about 2.6 KiB), reused from tick to tick.
///
/// Keep one per agent, in a `static` on the car, so the linker accounts for it.
#[derive(Clone, Debug)]
pub struct Evaluator {
    /// Scan points in the car frame.
    points: [[f32; 2]; SCAN_BEAMS],
    /// Per distinct sample: clipped clearance (obstacles, then one class at a time). A power of
    /// two long, so that indexing with a mask needs no bounds check.
    clearance: [f32; SCRATCH],
    /// Per distinct sample: whether it collides.
    collides: [u32; COLLIDE_WORDS],
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
        let mut y = f32::from_bits(0x1fbb_4f2e_u32.wrapping_add(x.to_bits() >> 1));
        y = 0.5 * (y + x / y);
        return 0.5 * (y + x / y);
    }
    // 0, subnormals (never produced by the geometry here), negatives and NaN take the exact path.
    libm::sqrtf(x)
}

impl Evaluator {
    /// A fresh evaluator.
    pub const fn new() -> Self {
        Self {
            points: [[0.0; 2]; SCAN_BEAMS],
            clearance: [0.0; SCRATCH],
            collides: [0; COLLIDE_WORDS],
        }
    }

    /// Validates `obs`, writes the features of every trajectory into `out`, and returns the
    /// trajectories that do not collide. On `Err`, `out` is untouched.
    pub fn evaluate(
        &mut self,
        obs: &Observation,
        out: &mut FeatureTable,
    ) -> Result<ActionMask, ObservationError> {
        obs.validate()?;
        self.obstacles(obs);
        let mut allowed = ActionMask::NONE;
        let rows = out.rows_mut();
        for (a, row) in rows.iter_mut().enumerate() {
            let (samples, scale) = samples_of(a);
            let mut sum = 0.0f32;
            let mut hit = false;
            for &u in samples {
                let u = u as usize & (SCRATCH - 1);
                sum += self.clearance[u];
                hit |= self.collides[u >> 5] >> (u & 31) & 1 == 1;
            }
            row[Feature::Obstacles.index()] = sum * scale / OBSTACLE_CLIP;
            if !hit && let Some(action) = ActionIndex::new(a) {
                allowed.insert(action);
            }
        }
        for class in SemanticClass::ALL {
            self.semantic(obs, class, rows);
        }
        path_and_side(obs, rows);
        Ok(allowed)
    }

    /// Clipped obstacle clearance and collision of every distinct sample.
    fn obstacles(&mut self, obs: &Observation) {
        let ranges = &obs.scan.ranges;
        for j in 0..SCAN_BEAMS {
            self.points[j] = [ranges[j] * BEAM_COS[j], ranges[j] * BEAM_SIN[j]];
        }
        self.collides = [0; COLLIDE_WORDS];
        let clip2 = OBSTACLE_CLIP * OBSTACLE_CLIP;
        let collide2 = COLLISION_RADIUS * COLLISION_RADIUS;
        // Beams binned by range: bin b holds the beams with range in [b·w, (b+1)·w), w = BIN_WIDTH.
        // Only ranges below the farthest sample's ρ + clip can matter; longer beams are left out.
        let mut bins = [[0u32; 2]; RANGE_BINS];
        // Beams shorter than the clip: candidates for every sample, whatever their bearing (the
        // compile-time windows cover only bearings within 90° of a sample's).
        let (mut close_lo, mut close_hi) = (0u32, 0u32);
        for (j, &r) in ranges.iter().enumerate() {
            let b = (r * (1.0 / BIN_WIDTH)) as usize;
            if b < RANGE_BINS {
                bins[b][j >> 5] |= 1 << (j & 31);
            }
            if r < OBSTACLE_CLIP + REACH_MARGIN {
                if j < 32 {
                    close_lo |= 1 << j;
                } else {
                    close_hi |= 1 << (j & 31);
                }
            }
        }
        if bins.iter().all(|b| b[0] | b[1] == 0) {
            // No beam within reach of any sample: every clearance is the clip.
            self.clearance = [OBSTACLE_CLIP; SCRATCH];
            return;
        }
        // Samples by increasing ρ: `upper` holds the bins that may hold a beam shorter than
        // ρ + clip, `lower` the bins whose beams are all at most ρ − clip; both only grow. A bin
        // joins `upper` as soon as its lower edge is below ρ + clip and `lower` only once its upper
        // edge is at most ρ − clip, so the candidates are a superset of the beams that can matter:
        // the binning costs some extra distance tests, never a wrong result.
        let (mut upper_lo, mut upper_hi, mut lower_lo, mut lower_hi) = (0u32, 0u32, 0u32, 0u32);
        let (mut hi, mut lo) = (0usize, 0usize);
        for &u in &SAMPLES_BY_RHO {
            let u = u as usize;
            let rho = SAMPLE_RHO[u];
            let far = rho + OBSTACLE_CLIP + REACH_MARGIN;
            while hi < RANGE_BINS && BIN_EDGES[hi] < far {
                upper_lo |= bins[hi][0];
                upper_hi |= bins[hi][1];
                hi += 1;
            }
            let near = rho - OBSTACLE_CLIP - REACH_MARGIN;
            while lo < RANGE_BINS && BIN_EDGES[lo + 1] <= near {
                lower_lo |= bins[lo][0];
                lower_hi |= bins[lo][1];
                lo += 1;
            }
            let window = SAMPLE_WINDOW[u];
            let cand_lo = (window as u32 | close_lo) & upper_lo & !lower_lo;
            let cand_hi = ((window >> 32) as u32 | close_hi) & upper_hi & !lower_hi;
            if cand_lo | cand_hi == 0 {
                self.clearance[u & (SCRATCH - 1)] = OBSTACLE_CLIP;
                continue;
            }
            let [sx, sy] = SAMPLE_POINTS[u];
            let mut best = clip2;
            // The two halves of the candidate mask, written out: a loop over a two-element array
            // of (mask, base) pairs costs stack traffic per sample on a Cortex-M4.
            let points = &self.points;
            let mut nearest = |mut beams: u32, base: usize| {
                while beams != 0 {
                    let j = (beams.trailing_zeros() as usize + base) & (SCAN_BEAMS - 1);
                    beams &= beams - 1;
                    let dx = points[j][0] - sx;
                    let dy = points[j][1] - sy;
                    let d2 = dx * dx + dy * dy;
                    if d2 < best {
                        best = d2;
                    }
                }
            };
            nearest(cand_lo, 0);
            nearest(cand_hi, 32);
            self.clearance[u & (SCRATCH - 1)] = if best < clip2 {
                sqrt(best).min(OBSTACLE_CLIP)
            } else {
                OBSTACLE_CLIP
            };
            if best < collide2 {
                self.collides[(u >> 5) & (COLLIDE_WORDS - 1)] |= 1 << (u & 31);
            }
        }
    }

    /// The clearance feature of one semantic class.
    fn semantic(
        &mut self,
        obs: &Observation,
        class: SemanticClass,
        rows: &mut [Features; MAX_ACTIONS],
    ) {
        let f = class.feature().index();
        if !obs.objects.iter().any(|o| o.class == class) {
            for row in rows.iter_mut() {
                row[f] = SAMPLES as f32;
            }
            return;
        }
        self.clearance = [SEMANTIC_CLIP; SCRATCH];
        for o in obs.objects.iter().filter(|o| o.class == class) {
            // A sample farther than clip + r from the centre reads the clip for this object:
            // tested on squares, so the root is taken only where it matters. An object whose
            // disc is farther than that from every sample is skipped whole.
            let reach = SEMANTIC_CLIP + o.radius + REACH_MARGIN;
            let reach2 = reach * reach;
            let whole = MAX_SAMPLE_RHO + reach;
            if o.x * o.x + o.y * o.y >= whole * whole {
                continue;
            }
            for (c, &[sx, sy]) in self.clearance.iter_mut().zip(SAMPLE_POINTS.iter()) {
                let (dx, dy) = (sx - o.x, sy - o.y);
                let d2 = dx * dx + dy * dy;
                if d2 < reach2 {
                    let d = sqrt(d2) - o.radius;
                    let d = if d > 0.0 { d } else { 0.0 };
                    if d < *c {
                        *c = d;
                    }
                }
            }
        }
        for (a, row) in rows.iter_mut().enumerate() {
            let (samples, scale) = samples_of(a);
            let mut sum = 0.0f32;
            for &u in samples {
                sum += self.clearance[u as usize & (SCRATCH - 1)];
            }
            row[f] = sum * scale / SEMANTIC_CLIP;
        }
    }
}

/// The distinct-sample indices of trajectory `a`, and the factor that scales their sum to ten
/// samples (1 for cruise, 2 for creep: exact in floating point). From a table of the counts, not
/// from the trajectory itself: no division and no large-struct indexing, 64 times per feature.
#[inline]
fn samples_of(a: usize) -> (&'static [u16], f32) {
    let n = (SAMPLE_COUNT[a] as usize).clamp(1, SAMPLES);
    (&SAMPLE_OF[a][..n], SAMPLE_SCALE[n])
}

/// `SAMPLE_SCALE[n] = SAMPLES / n` for the counts a trajectory can have (index 0 unused).
const SAMPLE_SCALE: [f32; SAMPLES + 1] = {
    let mut t = [0.0f32; SAMPLES + 1];
    let mut n = 1;
    while n <= SAMPLES {
        t[n] = (SAMPLES / n) as f32;
        n += 1;
    }
    t
};

/// The cross-track error `|cross|` (m) of every trajectory's end against the path reference: the
/// distance from the end to the line through the reference point along the path's heading.
///
/// This is what a statement about the path ("stay on the path") judges (paper, section 6: the
/// path by cross-track error; see [`crate::SemanticFeedback`]). The teacher on the host calls the
/// same function, so both sides compare the same numbers. Exact (no root), not clipped.
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
    // `sincosf`, not `sinf` and `cosf`: those two then keep a single caller, `path_and_side`,
    // and stay inlined in the tick's `act` (calling them out of line from there cost 440
    // instructions a tick on the Cortex-M4, measured). Host and car both reach this function,
    // so they compare the same numbers whatever the last bit of the heading's sine.
    let (s, c) = libm::sincosf(p.heading);
    let mut out = [0.0f32; MAX_ACTIONS];
    for (d, t) in out.iter_mut().zip(TRAJECTORIES.iter()) {
        let e = t.end();
        // The same operations as the cross-track part of `path_and_side`.
        let dx = e.x - p.x;
        let dy = e.y - p.y;
        let cross = dy * c - dx * s;
        *d = libm::fabsf(cross);
    }
    out
}

/// Path error and lateral offset of every trajectory's end.
fn path_and_side(obs: &Observation, rows: &mut [Features; MAX_ACTIONS]) {
    let p = &obs.reference;
    let (s, c) = (libm::sinf(p.heading), libm::cosf(p.heading));
    for (row, t) in rows.iter_mut().zip(TRAJECTORIES.iter()) {
        let e = t.end();
        let dx = e.x - p.x;
        let dy = e.y - p.y;
        let along = dx * c + dy * s;
        let cross = dy * c - dx * s;
        let error = libm::fabsf(along) + libm::fabsf(cross);
        row[Feature::Path.index()] = if error < PATH_CLIP { error } else { PATH_CLIP };
        row[Feature::Right.index()] = -RIGHT_SCALE * e.y;
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

    #[test]
    fn sample_counts_are_the_trajectories_own() {
        for a in 0..MAX_ACTIONS {
            let n = TRAJECTORIES[a].samples().len();
            assert_eq!(samples_of(a).0.len(), n, "trajectory {a}");
            assert_eq!(samples_of(a).1, (SAMPLES / n) as f32, "trajectory {a}");
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
