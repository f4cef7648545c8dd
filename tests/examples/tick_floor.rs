//! The least work an exact evaluator must do on each recorded tick, to set beside what the car's
//! evaluator does (`scripts/measure-firmware`, docs/firmware.md).
//!
//! ```text
//! cargo run -p tests --example record_ticks -- TICKS 30
//! cargo run -p tests --example tick_floor -- TICKS
//! ```
//!
//! For every observation in `TICKS` (the format `record_ticks` writes) it counts, with the
//! evaluator's own mask of the trajectories that do not collide:
//!
//! * `samples`: the distinct lattice samples those trajectories have (the feature sums read each
//!   of them);
//! * `roots`: the (sample, feature) pairs among them whose clearance is below its clip, for
//!   obstacles and for each semantic class the observation holds. Each such clearance is one
//!   root of one exact squared distance (the features stay bit for bit as they are, so no table
//!   or bound can stand in for it); a clearance at the clip needs none;
//! * `floor`: a lower bound on the instructions of those roots and sums on the Cortex-M4F:
//!   [`ROOT`] per root (load the sample, its squared distance to the nearest point or object, the
//!   evaluator's Newton root, store) and [`SUM`] per sample for each feature with any root (load,
//!   add). It leaves out everything else an evaluator does: finding the nearest scan point,
//!   deciding the collisions, writing the rows, the path features, validation and selection.
//!
//! Distances here are in `f64` over every scan point and object (brute force), so a clearance
//! within a rounding of its clip may be counted on the other side: a few roots either way.

use anyhow::{Context, Result, bail};
use firmware_core::evaluator::{Evaluator, SEMANTIC_CLIP, beam_direction};
use firmware_core::lattice::{OBSTACLE_CLIP, trajectory};
use firmware_core::observation::{Observation, SCAN_BEAMS, SemanticClass};
use protocol::message::Message;

/// Instructions per root at the least: two loads of the sample, two subtractions, a multiply
/// and a multiply-add for the squared distance, nine for the root (`evaluator::sqrt`'s seed and
/// two Newton steps, its constant already in a register) and one store.
const ROOT: u64 = 16;
/// Instructions per sample and feature summed, at the least: one load, one add.
const SUM: u64 = 2;

struct Floor {
    allowed: u32,
    samples: u32,
    roots: [u32; 4],
    floor: u64,
}

fn floor(obs: &Observation, evaluator: &mut Evaluator) -> Result<Floor> {
    let valid = obs.check().map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let allowed = evaluator.evaluation(valid).allowed();
    // The distinct samples of the allowed trajectories (by their bits).
    let mut samples: Vec<[f32; 2]> = Vec::new();
    for a in allowed.iter() {
        for s in trajectory(a).samples() {
            if !samples
                .iter()
                .any(|t| t[0].to_bits() == s[0].to_bits() && t[1].to_bits() == s[1].to_bits())
            {
                samples.push(*s);
            }
        }
    }
    let points: Vec<(f64, f64)> = (0..SCAN_BEAMS)
        .filter_map(|j| {
            let (c, s) = beam_direction(j)?;
            let r = f64::from(obs.scan.ranges[j]);
            Some((r * f64::from(c), r * f64::from(s)))
        })
        .collect();
    let mut roots = [0u32; 4];
    for &[sx, sy] in &samples {
        let (sx, sy) = (f64::from(sx), f64::from(sy));
        let nearest = points
            .iter()
            .map(|&(px, py)| ((px - sx).powi(2) + (py - sy).powi(2)).sqrt())
            .fold(f64::INFINITY, f64::min);
        if nearest < f64::from(OBSTACLE_CLIP) {
            roots[0] += 1;
        }
        for (k, class) in SemanticClass::ALL.iter().enumerate() {
            let clearance = obs
                .objects
                .iter()
                .filter(|o| o.class == *class)
                .map(|o| {
                    ((f64::from(o.x) - sx).powi(2) + (f64::from(o.y) - sy).powi(2)).sqrt()
                        - f64::from(o.radius)
                })
                .fold(f64::INFINITY, f64::min);
            if clearance < f64::from(SEMANTIC_CLIP) {
                roots[k + 1] += 1;
            }
        }
    }
    let n = samples.len() as u64;
    let touched = roots.iter().filter(|&&r| r > 0).count() as u64;
    let all: u64 = roots.iter().map(|&r| u64::from(r)).sum();
    Ok(Floor {
        allowed: allowed.iter().count() as u32,
        samples: n as u32,
        roots,
        floor: ROOT * all + SUM * n * touched,
    })
}

fn main() -> Result<()> {
    let Some(path) = std::env::args().nth(1) else {
        bail!("usage: tick_floor TICKS (written by the record_ticks example)");
    };
    let bytes = std::fs::read(&path).with_context(|| format!("{path}: cannot read"))?;
    let mut evaluator = Evaluator::new();
    let (mut rest, mut item, mut floors) = (&bytes[..], 0usize, Vec::new());
    println!("item allowed samples roots(obstacles door stairs chair) floor");
    while !rest.is_empty() {
        let Some((len, tail)) = rest.split_first_chunk::<2>() else {
            bail!("{path}: truncated length at item {item}");
        };
        let len = usize::from(u16::from_le_bytes(*len));
        let Some((msg, tail)) = tail.split_at_checked(len) else {
            bail!("{path}: truncated message at item {item}");
        };
        rest = tail;
        let msg = Message::parse(msg).map_err(|e| anyhow::anyhow!("item {item}: {e:?}"))?;
        if let Message::Observation(o) = msg {
            let f = floor(&o.observation, &mut evaluator)?;
            println!(
                "{item} {} {} {} {} {} {} {}",
                f.allowed, f.samples, f.roots[0], f.roots[1], f.roots[2], f.roots[3], f.floor
            );
            floors.push(f.floor);
        }
        item += 1;
    }
    if floors.is_empty() {
        bail!("{path}: no observation");
    }
    let mean = floors.iter().sum::<u64>() as f64 / floors.len() as f64;
    let max = floors.iter().max().copied().unwrap_or(0);
    println!(
        "{} observations: floor mean {mean:.0}, max {max} instructions",
        floors.len()
    );
    Ok(())
}
