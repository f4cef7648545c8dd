//! A naive std reference evaluator: every (trajectory, sample, beam), no windows, no sharing,
//! Vec-based, written from the formulas of `firmware_core::evaluator`'s documentation. It reads the
//! lattice's sample points and the beam directions (inputs, not evaluator code) so that its
//! arithmetic sees the same numbers.
#![allow(dead_code)]

use firmware_core::evaluator::{
    COLLISION_RADIUS, PATH_CLIP, RIGHT_SCALE, SEMANTIC_CLIP, beam_direction,
};
use firmware_core::lattice::{OBSTACLE_CLIP, SCAN_BEAMS, trajectory};
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
        let scale = (10 / t.samples().len()) as f32;
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
                10.0
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
