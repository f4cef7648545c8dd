//! A naive std reference evaluator: every (trajectory, sample, beam), no windows, no sharing,
//! Vec-based, written from the formulas of `firmware_core::evaluator`'s documentation. It reads the
//! lattice's sample points and the beam directions (inputs, not evaluator code) so that its
//! arithmetic sees the same numbers; its constants are its own, written from the documented
//! feature definitions, and `evaluator.rs` beside this folder checks that the crate's equal them.
#![allow(dead_code)]

use firmware_core::evaluator::beam_direction;
use firmware_core::lattice::{SCAN_BEAMS, trajectory};

/// A sample collides within this distance of a scan point: the car's half-width 0.15 m plus a
/// 0.10 m margin ("Collisions" in the evaluator's documentation).
pub(crate) const COLLISION_RADIUS: f32 = 0.15 + 0.10;

/// Obstacle clearances are clipped at 0.5 m (the features table: `min(d_scan, 0.5 m) / 0.5 m`).
pub(crate) const OBSTACLE_CLIP: f32 = 0.5;

/// Semantic clearances are clipped at 2 m (`min(d_class, 2 m) / 2 m`).
pub(crate) const SEMANTIC_CLIP: f32 = 2.0;

/// The path error is clipped at 4 m (`min(|along| + |cross|, 4 m)`).
pub(crate) const PATH_CLIP: f32 = 4.0;

/// The lateral feature is in decimetres, right positive (`−10 · e.y`).
pub(crate) const RIGHT_SCALE: f32 = 10.0;

/// Every trajectory counts as ten samples (`k = 10 / n`).
pub(crate) const COUNTED_SAMPLES: usize = 10;

/// A class with no detected object reads this for every trajectory.
pub(crate) const ABSENT_CLASS: f32 = 10.0;
use firmware_core::observation::{Observation, SemanticClass};
use firmware_core::{ActionIndex, FEATURE_COUNT, Feature, MAX_ACTIONS};

pub(crate) struct NaiveOutput {
    pub(crate) features: Vec<[f32; FEATURE_COUNT]>,
    pub(crate) collides: Vec<bool>,
}

pub(crate) fn evaluate(obs: &Observation) -> Option<NaiveOutput> {
    obs.validate().ok()?;
    let points: Vec<(f32, f32)> = (0..SCAN_BEAMS)
        .map(|j| {
            let (c, s) = beam_direction(j).unwrap();
            (obs.scan.ranges[j] * c, obs.scan.ranges[j] * s)
        })
        .collect();
    let mut features = vec![[0.0f32; FEATURE_COUNT]; MAX_ACTIONS];
    let mut collides = vec![false; MAX_ACTIONS];
    for a in 0..MAX_ACTIONS {
        let t = trajectory(ActionIndex::new(a).unwrap());
        let mut obstacle_sum = 0.0f32;
        let mut class_sum = [0.0f32; 3];
        let scale = (COUNTED_SAMPLES / t.samples().len()) as f32;
        for c in t.samples() {
            // Nearest scan point, brute force.
            let mut d2min = f32::INFINITY;
            for p in &points {
                let d2 = (p.0 - c[0]) * (p.0 - c[0]) + (p.1 - c[1]) * (p.1 - c[1]);
                d2min = d2min.min(d2);
            }
            if d2min < COLLISION_RADIUS * COLLISION_RADIUS {
                collides[a] = true;
            }
            obstacle_sum += d2min.sqrt().min(OBSTACLE_CLIP);
            for (k, class) in SemanticClass::ALL.iter().enumerate() {
                let mut best = SEMANTIC_CLIP;
                for o in obs.objects.iter().filter(|o| o.class == *class) {
                    let d = (((c[0] - o.x) * (c[0] - o.x) + (c[1] - o.y) * (c[1] - o.y)).sqrt()
                        - o.radius)
                        .max(0.0);
                    best = best.min(d);
                }
                class_sum[k] += best;
            }
        }
        let f = &mut features[a];
        f[Feature::Obstacles.index()] = obstacle_sum * scale / OBSTACLE_CLIP;
        for (k, class) in SemanticClass::ALL.iter().enumerate() {
            let any = obs.objects.iter().any(|o| o.class == *class);
            f[class.feature().index()] = if any {
                class_sum[k] * scale / SEMANTIC_CLIP
            } else {
                ABSENT_CLASS
            };
        }
        let e = t.end();
        let r = &obs.reference;
        let (s, co) = (libm::sinf(r.heading), libm::cosf(r.heading));
        let (dx, dy) = (e.x - r.x, e.y - r.y);
        let err = (dx * co + dy * s).abs() + (dy * co - dx * s).abs();
        f[Feature::Path.index()] = err.min(PATH_CLIP);
        f[Feature::Right.index()] = -RIGHT_SCALE * e.y;
    }
    Some(NaiveOutput { features, collides })
}
