//! From one observation, the features of all 64 trajectories and the collision mask.
//!
//! # Features (paper, section 6), and why these scales
//!
//! For trajectory `a` with footprint-centre samples `c_1 … c_10` (see
//! [`Trajectory::centers`](crate::lattice::Trajectory::centers)) and end pose `e`:
//!
//! | feature | value | range |
//! |---|---|---|
//! | [`Feature::Obstacles`] | `Σ_k min(d_scan(c_k), 0.5 m) / 0.5 m` | 0 … 10 |
//! | [`Feature::Door`], [`Feature::Stairs`], [`Feature::Chair`] | `Σ_k min(d_class(c_k), 2 m) / 2 m` | 0 … 10 |
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
//! 1. the 640 samples of the lattice are only 415 distinct points (trajectories share their first
//!    segments), evaluated once each;
//! 2. for a sample at range `ρ` and bearing `α`, a scan point on the beam at bearing `β` is at least
//!    `ρ·sin|α − β|` away (at least `ρ` beyond 90°), so only the beams within
//!    `asin(0.5 m / ρ)` of `α` can come within the 0.5 m clip; these windows are computed at
//!    compile time (`build.rs`) as one 64-bit beam mask per sample, 11 518 (sample, beam) pairs
//!    in all ([`WINDOW_PAIRS`](crate::lattice::WINDOW_PAIRS)), with a 0.01 rad margin;
//! 3. a beam whose range exceeds `ρ + 0.5 m` cannot come within the clip either: each tick
//!    builds the mask of beams shorter than the farthest sample's `ρ` + 0.5 m, ANDs it with each
//!    window, and checks the sample's own `ρ + 0.5 m` for the rest. In open space no beam is
//!    near and the obstacle pass costs nothing.
//!
//! Every skipped beam is provably farther than the clip, so the minimum of the kept ones, once
//! clipped, equals the brute-force minimum: the features and the mask are bit-identical to a
//! brute-force evaluator given the same sample points and beam directions (tested against a
//! naive std implementation in `tests/evaluator.rs`). The error bound is zero.
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
    BEAM_COS, BEAM_SIN, MAX_SAMPLE_RHO, OBSTACLE_CLIP, SAMPLE_OF, SAMPLE_POINTS, SAMPLE_RHO,
    SAMPLE_WINDOW, SAMPLES, SCAN_BEAMS, TRAJECTORIES, UNIQUE_SAMPLES,
};
use crate::observation::{Observation, ObservationError, SemanticClass};

/// Clearances to semantic objects are clipped at this distance (m).
pub const SEMANTIC_CLIP: f32 = 2.0;

/// A sample closer than this to a scan point collides (m): the car's half-width 0.15 m plus a
/// 0.10 m margin.
pub const COLLISION_RADIUS: f32 = 0.25;

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

const COLLIDE_WORDS: usize = UNIQUE_SAMPLES.div_ceil(64);

/// Slack added to "range beyond ρ + clip" before a beam is skipped: 1 mm, far above f32
/// rounding at these magnitudes, so a skipped beam is provably beyond the clip.
const REACH_MARGIN: f32 = 1.0e-3;

/// The evaluator and its scratch memory (about 3.5 KiB), reused from tick to tick.
///
/// Keep one per agent, in a `static` on the car, so the linker accounts for it.
#[derive(Clone, Debug)]
pub struct Evaluator {
    /// Scan points in the car frame.
    points: [[f32; 2]; SCAN_BEAMS],
    /// Per distinct sample: clipped clearance (obstacles, then one class at a time).
    clearance: [f32; UNIQUE_SAMPLES],
    /// Per distinct sample: whether it collides.
    collides: [u64; COLLIDE_WORDS],
}

impl Default for Evaluator {
    fn default() -> Self {
        Self::new()
    }
}

/// Distance from `p` to the disc `(cx, cy, r)`, 0 inside.
#[inline]
fn disc_distance(p: [f32; 2], cx: f32, cy: f32, r: f32) -> f32 {
    let dx = p[0] - cx;
    let dy = p[1] - cy;
    let d = libm::sqrtf(dx * dx + dy * dy) - r;
    if d > 0.0 { d } else { 0.0 }
}

impl Evaluator {
    /// A fresh evaluator.
    pub const fn new() -> Self {
        Self {
            points: [[0.0; 2]; SCAN_BEAMS],
            clearance: [0.0; UNIQUE_SAMPLES],
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
            let mut sum = 0.0f32;
            let mut hit = false;
            for &u in &SAMPLE_OF[a] {
                let u = u as usize;
                sum += self.clearance[u];
                hit |= self.collides[u / 64] >> (u % 64) & 1 == 1;
            }
            row[Feature::Obstacles.index()] = sum / OBSTACLE_CLIP;
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
        // Beams that may come within the clip of some sample: range below the farthest sample's
        // distance plus the clip. In open space this is empty and the loop below does nothing.
        let mut near = 0u64;
        for j in 0..SCAN_BEAMS {
            let r = obs.scan.ranges[j];
            self.points[j] = [r * BEAM_COS[j], r * BEAM_SIN[j]];
            if r < MAX_SAMPLE_RHO + OBSTACLE_CLIP + REACH_MARGIN {
                near |= 1 << j;
            }
        }
        self.collides = [0; COLLIDE_WORDS];
        let clip2 = OBSTACLE_CLIP * OBSTACLE_CLIP;
        let collide2 = COLLISION_RADIUS * COLLISION_RADIUS;
        for u in 0..UNIQUE_SAMPLES {
            let [sx, sy] = SAMPLE_POINTS[u];
            // Beams beyond ρ + clip cannot come within the clip either.
            let reach = SAMPLE_RHO[u] + OBSTACLE_CLIP + REACH_MARGIN;
            let mut best = clip2;
            let mut beams = SAMPLE_WINDOW[u] & near;
            while beams != 0 {
                let j = beams.trailing_zeros() as usize;
                beams &= beams - 1;
                if obs.scan.ranges[j] < reach {
                    let dx = self.points[j][0] - sx;
                    let dy = self.points[j][1] - sy;
                    let d2 = dx * dx + dy * dy;
                    if d2 < best {
                        best = d2;
                    }
                }
            }
            self.clearance[u] = if best < clip2 {
                libm::sqrtf(best)
            } else {
                OBSTACLE_CLIP
            };
            if best < collide2 {
                self.collides[u / 64] |= 1 << (u % 64);
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
        let mut any = false;
        for u in 0..UNIQUE_SAMPLES {
            let mut best = SEMANTIC_CLIP;
            for o in obs.objects.iter().filter(|o| o.class == class) {
                any = true;
                let d = disc_distance(SAMPLE_POINTS[u], o.x, o.y, o.radius);
                if d < best {
                    best = d;
                }
            }
            self.clearance[u] = best;
            if !any {
                break;
            }
        }
        for (a, row) in rows.iter_mut().enumerate() {
            row[f] = if any {
                let mut sum = 0.0f32;
                for &u in &SAMPLE_OF[a] {
                    sum += self.clearance[u as usize];
                }
                sum / SEMANTIC_CLIP
            } else {
                SAMPLES as f32
            };
        }
    }
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
