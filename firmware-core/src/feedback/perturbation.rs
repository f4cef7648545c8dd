//! A trajectory perturbation: the teacher nudges the executed trajectory, and the corrected
//! trajectory, which need not be one of the lattice's, arrives as its feature vector (Bajcsy et
//! al. 2017, physical corrections; Losey and O'Malley 2018, trajectory deformations; Coactive
//! Learning's improved object, Shivaswamy and Joachims 2015).
//!
//! Coactive Learning's teacher answers the learner's object `y` with an improved one `ȳ` of
//! higher utility, and the preference perceptron steps `w ← w + φ(ȳ) − φ(y)`: the update uses
//! only the corrected object's features. Bajcsy et al. arrive at the same rule from a physical
//! push, the deformed trajectory's features against the planned one's. Here the corrected
//! trajectory's features `φ̄` become a pseudo-loss over the lattice's actions, ranking each by
//! its feature distance to the correction:
//!
//! ```text
//! Δ(a) = ‖φ(a) − φ̄‖
//! ```
//!
//! Its minimiser `â` is the lattice action nearest the corrected trajectory in feature space,
//! and the generalized hinge steps `w ← w + η (φ(â) − φ(a_sel))`. Where ours differs from
//! Coactive Learning: the step moves towards the nearest *lattice* action, not towards `φ̄`
//! itself (the meta-algorithm's surrogate is a loss over the actions the car can take); when
//! the correction is a lattice action's own trajectory, `φ̄` is its features and `â` is that
//! action (assumption 1), and a partial nudge points to whichever action is nearest it.
//!
//! The pseudo-loss ranks every action on its own, like the teacher's action, but it is taken as
//! *relative* ([`super::PseudoLossSource::is_absolute`] false: an averaged learner evaluates it
//! at the weights that acted). Its margins are feature distances, a few units, not action
//! feedback's 100: at [`crate::AveragedOgd`]'s raw iterate the hinge goes flat as soon as that
//! iterate scores the target a few units above its neighbours, while the average that acts
//! still lags behind, and the teacher keeps correcting to no effect. Measured in `host-sim`'s
//! doors household (seed 0, averaged OGD, 5000 steps, first → last tenth of the latent loss):
//! taken as absolute 8.0 → 3.3, 3812 corrections, no lap; as relative 8.6 → 1.3, 2070
//! corrections, 9 laps.
//!
//! # On the wire and on the car
//!
//! The car keeps the features of its recent ticks, not their observations, so it cannot
//! evaluate a trajectory it never planned: the sender (which holds the observation) computes
//! `φ̄` with [`DeformedTrajectory::features`], the evaluator's definitions applied to any
//! sampled path, and sends it in thousandths, fixed-width ([`Milli`]: 12 bytes). The car refuses
//! a vector no trajectory of at most 1 m could have ([`LearnError::OutOfRange`]): obstacle and
//! class clearances outside `[0, 10]`, a path error outside `[0, 4]`, a lateral end beyond
//! ±10 dm.
//!
//! # The deformation the programmatic teacher makes
//!
//! [`DeformedTrajectory::between`] moves every sample of the executed trajectory a fraction
//! `λ` of the way towards the same sample of the trajectory the teacher wanted (samples at the
//! same fraction of each one's length; the end pose likewise), which is what a push of
//! strength `λ` does to the trajectory in Losey and O'Malley's deformation model, without its
//! smoothing. `λ = 1` is the teacher's own trajectory; `host-sim` uses
//! [`PUSH`] = 0.5.

use serde::{Deserialize, Serialize};

use super::{Round, distance};
use crate::action::{ActionIndex, MAX_ACTIONS};
use crate::error::LearnError;
use crate::evaluator::{PATH_CLIP, RIGHT_SCALE, SEMANTIC_CLIP};
use crate::feature::{FEATURE_COUNT, Feature, Features, ieee_sqrt};
use crate::lattice::{FOOTPRINT_CENTER_OFFSET, OBSTACLE_CLIP, Pose, SAMPLES, trajectory};
use crate::observation::{SemanticClass, ValidObservation};

/// How far a programmatic teacher's push moves the executed trajectory towards the one it
/// wanted (a fraction of the way; see the module documentation).
pub const PUSH: f32 = 0.5;

/// Units per feature unit on the wire: thousandths.
pub const MILLI: f32 = 1000.0;

/// A fixed-width little-endian `i16` of thousandths (postcard would write a zigzag varint of 1
/// to 3 bytes).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Default, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct Milli([u8; 2]);

impl Milli {
    /// From thousandths.
    pub const fn new(thousandths: i16) -> Self {
        Self(thousandths.to_le_bytes())
    }

    /// `x` rounded to thousandths; `None` when `x` is not finite or beyond ±32.767.
    pub fn from_f32(x: f32) -> Option<Self> {
        let t = libm::roundf(x * MILLI);
        (t.is_finite() && t >= i16::MIN as f32 && t <= i16::MAX as f32).then(|| Self::new(t as i16))
    }

    /// The thousandths.
    pub const fn get(self) -> i16 {
        i16::from_le_bytes(self.0)
    }

    /// The value.
    pub fn to_f32(self) -> f32 {
        self.get() as f32 / MILLI
    }
}

/// The feature vector of the corrected trajectory, in thousandths.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct PerturbationFeedback {
    /// `φ̄`, in [`Feature`] order.
    pub corrected: [Milli; FEATURE_COUNT],
}

/// The range each feature of a corrected trajectory may take (see the module documentation).
pub const CORRECTED_RANGES: [(f32, f32); FEATURE_COUNT] = [
    (0.0, SAMPLES as f32),
    (0.0, SAMPLES as f32),
    (0.0, SAMPLES as f32),
    (0.0, SAMPLES as f32),
    (0.0, PATH_CLIP),
    (-RIGHT_SCALE, RIGHT_SCALE),
];

impl PerturbationFeedback {
    /// The feedback for the corrected features `phi`, rounded to thousandths; `None` when a
    /// feature is outside [`CORRECTED_RANGES`] (or not finite).
    pub fn new(phi: &Features) -> Option<Self> {
        let mut corrected = [Milli::default(); FEATURE_COUNT];
        for (i, (m, &x)) in corrected.iter_mut().zip(phi).enumerate() {
            let (lo, hi) = CORRECTED_RANGES[i];
            if !(x >= lo && x <= hi) {
                return None;
            }
            *m = Milli::from_f32(x)?;
        }
        Some(Self { corrected })
    }

    /// `φ̄`, checked against [`CORRECTED_RANGES`].
    pub fn features(&self) -> Result<Features, LearnError> {
        let mut phi = [0.0f32; FEATURE_COUNT];
        for (i, (x, m)) in phi.iter_mut().zip(&self.corrected).enumerate() {
            *x = m.to_f32();
            let (lo, hi) = CORRECTED_RANGES[i];
            if !(*x >= lo && *x <= hi) {
                return Err(LearnError::OutOfRange);
            }
        }
        Ok(phi)
    }
}

impl super::PseudoLossSource for PerturbationFeedback {
    fn write_pseudo_loss(
        &self,
        round: &Round<'_>,
        out: &mut [f32; MAX_ACTIONS],
    ) -> Result<(), LearnError> {
        let target = self.features()?;
        for a in round.allowed() {
            out[a.get()] = distance(round.phi(a), &target);
        }
        Ok(())
    }
}

/// A trajectory off the lattice: footprint-centre samples and the end pose, in the car frame.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct DeformedTrajectory {
    samples: [[f32; 2]; SAMPLES],
    count: u8,
    /// The end pose (rear axle).
    pub end: Pose,
}

/// The footprint centre of a rear-axle pose.
fn centre(p: &Pose) -> [f32; 2] {
    [
        p.x + FOOTPRINT_CENTER_OFFSET * libm::cosf(p.theta),
        p.y + FOOTPRINT_CENTER_OFFSET * libm::sinf(p.theta),
    ]
}

/// `(1 − t)·a + t·b`: exactly `a` at 0 and `b` at 1.
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    (1.0 - t) * a + t * b
}

impl DeformedTrajectory {
    /// The trajectory of action `a` as it is.
    pub fn of(a: ActionIndex) -> Self {
        let t = trajectory(a);
        let mut samples = [[0.0; 2]; SAMPLES];
        samples[..t.samples().len()].copy_from_slice(t.samples());
        Self {
            samples,
            count: t.samples().len() as u8,
            end: t.end(),
        }
    }

    /// The executed trajectory `from` pushed a fraction `lambda` (in `[0, 1]`) of the way
    /// towards `to`: each sample moved towards `to`'s sample at the same fraction of its length.
    /// Two trajectories with as many samples blend sample by sample (so `lambda` 0 and 1 give
    /// `from` and `to` exactly); a creep and a cruise trajectory blend the footprint centres of
    /// their [`SAMPLES`] evenly spaced poses.
    pub fn between(from: ActionIndex, to: ActionIndex, lambda: f32) -> Self {
        let (f, t) = (trajectory(from), trajectory(to));
        let mut samples = [[0.0; 2]; SAMPLES];
        let count = if f.samples().len() == t.samples().len() {
            for (s, (p, q)) in samples.iter_mut().zip(f.samples().iter().zip(t.samples())) {
                *s = [lerp(p[0], q[0], lambda), lerp(p[1], q[1], lambda)];
            }
            f.samples().len()
        } else {
            for (s, (p, q)) in samples.iter_mut().zip(f.poses().iter().zip(t.poses())) {
                let (p, q) = (centre(p), centre(q));
                *s = [lerp(p[0], q[0], lambda), lerp(p[1], q[1], lambda)];
            }
            SAMPLES
        };
        let (e, g) = (f.end(), t.end());
        Self {
            samples,
            count: count as u8,
            end: Pose {
                x: lerp(e.x, g.x, lambda),
                y: lerp(e.y, g.y, lambda),
                theta: lerp(e.theta, g.theta, lambda),
            },
        }
    }

    /// The samples clearances are measured from.
    pub fn samples(&self) -> &[[f32; 2]] {
        &self.samples[..usize::from(self.count).clamp(1, SAMPLES)]
    }

    /// The features of this trajectory in `obs`, by the evaluator's definitions
    /// ([`crate::evaluator`]), measured by brute force with correctly rounded roots: for a
    /// lattice trajectory they equal the evaluator's within
    /// [`FEATURE_ERROR_BOUND`](crate::evaluator::FEATURE_ERROR_BOUND) (tested). Whether the
    /// trajectory collides is not asked: a teacher's correction is taken as it is.
    pub fn features(&self, obs: ValidObservation<'_>) -> Features {
        let samples = self.samples();
        let k = (SAMPLES / samples.len()) as f32;
        let mut phi = [0.0f32; FEATURE_COUNT];
        let mut obstacles = 0.0f32;
        for c in samples {
            let mut d2 = f32::INFINITY;
            for (j, &r) in obs.scan.ranges.iter().enumerate() {
                let (cos, sin) = crate::evaluator::beam_direction(j).unwrap_or((1.0, 0.0));
                let (dx, dy) = (r * cos - c[0], r * sin - c[1]);
                let d = dx * dx + dy * dy;
                if d < d2 {
                    d2 = d;
                }
            }
            obstacles += ieee_sqrt(d2).min(OBSTACLE_CLIP);
        }
        phi[Feature::Obstacles.index()] = k * obstacles / OBSTACLE_CLIP;
        for class in SemanticClass::ALL {
            let mut any = false;
            let mut sum = 0.0f32;
            for c in samples {
                let mut best = SEMANTIC_CLIP;
                for o in obs.objects.iter().filter(|o| o.class == class) {
                    any = true;
                    let (dx, dy) = (c[0] - o.x, c[1] - o.y);
                    let d = (ieee_sqrt(dx * dx + dy * dy) - o.radius).max(0.0);
                    best = best.min(d);
                }
                sum += best;
            }
            phi[class.feature().index()] = if any {
                k * sum / SEMANTIC_CLIP
            } else {
                SAMPLES as f32
            };
        }
        let reference = &obs.reference;
        let iso = Pose {
            x: reference.x,
            y: reference.y,
            theta: reference.heading,
        }
        .isometry();
        let local = iso.inverse_transform_point(&self.end.position());
        let error = libm::fabsf(local.x) + libm::fabsf(local.y);
        phi[Feature::Path.index()] = error.min(PATH_CLIP);
        phi[Feature::Right.index()] = -RIGHT_SCALE * self.end.y;
        phi
    }
}
