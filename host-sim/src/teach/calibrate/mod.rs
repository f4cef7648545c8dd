//! `host-sim calibrate`: the procedure of `docs/reproduction/CALIBRATION.md` that picks the
//! teachers' scale from the regimes the paper describes, and the statistics it rests on.
//!
//! # The procedure (CALIBRATION.md, restated)
//!
//! A teacher's weights are `s · r`: its ratios `r` (the task, path weight −1, in
//! [`crate::world::teacher::PRESETS`]) times a scale `s` (the magnitude of its path weight). For each of
//! the paper's households, along the teacher's own noiseless lap from the scenario's start:
//!
//! * the **path follower** is the teacher with every semantic class (door, stairs, chair) and
//!   `right` set to 0 (obstacles and path kept); at every tick it chooses with the same
//!   evaluator, mask and tie rule as the car, and its latent loss under the teacher's full
//!   weights is `s · ℓ_t`, `ℓ_t = r·(φ(a*) − φ(a_pf))`;
//! * a **passage** is a tick where the path follower and the teacher choose differently;
//! * `S(h, s, τ) = Σ_{s·ℓ_t > τ} ℓ_t / Σ ℓ_t`, the share of what ignoring the semantic objects
//!   costs that a teacher of threshold `τ` sees; `m(h, s) = s · median of ℓ_t over the passages`.
//!
//! The targets: **T1** `S(doors, s, 1) ≥ 0.75`; **T2** `S(h, s, 1) ≤ 0.5` for both stairs
//! households; **T3** `S(h, s, 0.25) ≥ 0.75` for both; **T4** `√2 ≤ m(doors, s) ≤ 2√2`. Each holds
//! on an interval of `s`, computed exactly from the lap ([`Interval`]): `S(h, s, τ)` depends on
//! `τ/s` only and is a non-increasing step function of it, so `S ≥ q` holds exactly for
//! `τ/s < v` with `v` the largest loss value such that the losses of at least `v` make a share
//! `q`, and `S ≤ q` exactly for `τ/s ≥ u` with `u` the smallest loss value such that the losses
//! above `u` make at most a share `q`.
//!
//! The rule: if the targets of every teacher share an interval, the scale is its geometric
//! middle rounded to two significant digits, for every teacher. Otherwise each teacher gets the
//! geometric middle of the interval its own targets allow (doors: T1 and T4; each stairs
//! household: T2 and T3), and a teacher whose own targets conflict gets the middle of the
//! interval that fails the fewest of them; the command prints which targets conflict and why.
//!
//! The command also prints what issue 12 asks the procedure to rest on, at the chosen scale: per
//! household, the distribution of the latent loss of the allowed non-teacher actions along the
//! teacher's lap, and how often the initial policy (zero weights: straight ahead, the lowest
//! allowed index) would exceed each threshold there.

use std::sync::Arc;

use anyhow::{Result, bail};
use firmware_core::{Weights, policy};

use crate::world::check::{self, LapEnd};
use crate::world::registry;
use crate::world::scenario::Scenario;
use crate::world::teacher::{Preset, Teacher, TeacherSpec, path_follower};

/// The households calibrated: the paper's three.
pub const HOUSEHOLDS: [&str; 3] = ["doors", "stairs-right", "stairs-chairs"];

/// Thresholds at which the initial policy's corrections are counted (the threshold experiment's).
pub const THRESHOLDS: [f64; 8] = [0.0, 0.25, 0.5, 0.75, 1.0, 2.0, 4.0, 8.0];

/// Longest teacher lap (ticks).
pub const LAP_TICKS: u32 = 3_000;

/// An interval of scales with open or closed ends; `hi = ∞` for none above.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// Whether `lo` belongs to it.
    pub lo_closed: bool,
    /// Upper end (may be infinite).
    pub hi: f64,
    /// Whether `hi` belongs to it.
    pub hi_closed: bool,
}

impl Interval {
    /// Every positive scale.
    pub const ALL: Interval = Interval {
        lo: 0.0,
        lo_closed: false,
        hi: f64::INFINITY,
        hi_closed: false,
    };

    /// The scales in both.
    pub fn intersect(&self, o: &Interval) -> Interval {
        let (lo, lo_closed) = if self.lo > o.lo {
            (self.lo, self.lo_closed)
        } else if o.lo > self.lo {
            (o.lo, o.lo_closed)
        } else {
            (self.lo, self.lo_closed && o.lo_closed)
        };
        let (hi, hi_closed) = if self.hi < o.hi {
            (self.hi, self.hi_closed)
        } else if o.hi < self.hi {
            (o.hi, o.hi_closed)
        } else {
            (self.hi, self.hi_closed && o.hi_closed)
        };
        Interval {
            lo,
            lo_closed,
            hi,
            hi_closed,
        }
    }

    /// Whether no scale is in it.
    pub fn is_empty(&self) -> bool {
        self.lo > self.hi || (self.lo == self.hi && !(self.lo_closed && self.hi_closed))
    }

    /// Whether `s` is in it.
    pub fn contains(&self, s: f64) -> bool {
        (s > self.lo || (self.lo_closed && s == self.lo))
            && (s < self.hi || (self.hi_closed && s == self.hi))
    }

    /// `√(lo · hi)`, when both ends are positive and finite.
    pub fn geometric_middle(&self) -> Option<f64> {
        (self.lo > 0.0 && self.hi.is_finite() && !self.is_empty())
            .then(|| (self.lo * self.hi).sqrt())
    }

    /// `[a, b)`-style text.
    pub fn describe(&self) -> String {
        if self.is_empty() {
            return "empty".into();
        }
        let hi = if self.hi.is_finite() {
            format!("{:.4}", self.hi)
        } else {
            "∞".into()
        };
        format!(
            "{}{:.4}, {hi}{}",
            if self.lo_closed { "[" } else { "(" },
            self.lo,
            if self.hi_closed { "]" } else { ")" }
        )
    }
}

/// `x` rounded to two significant digits.
pub fn two_significant(x: f64) -> f64 {
    if x <= 0.0 || !x.is_finite() {
        return x;
    }
    let e = x.log10().floor() as i32 - 1;
    let f = 10f64.powi(e);
    (x / f).round() * f
}

/// The share `S` of the losses `l` (all ≥ 0) from the values above `x`.
pub fn share_above(l: &[f64], x: f64) -> f64 {
    let total: f64 = l.iter().sum();
    if total <= 0.0 {
        return 0.0;
    }
    l.iter().filter(|&&v| v > x).fold(0.0, |a, v| a + v) / total
}

/// The largest loss value `v` with `Σ_{l ≥ v} l ≥ q · Σ l`: `S(x) ≥ q` exactly for `x < v`.
/// None when the losses are all zero.
pub fn share_at_least_below(l: &[f64], q: f64) -> Option<f64> {
    let total: f64 = l.iter().sum();
    if total <= 0.0 {
        return None;
    }
    let mut v: Vec<f64> = l.iter().copied().filter(|&x| x > 0.0).collect();
    v.sort_by(|a, b| b.total_cmp(a));
    let mut sum = 0.0;
    let mut i = 0;
    while i < v.len() {
        // Every loss equal to v[i] joins at once.
        let x = v[i];
        while i < v.len() && v[i] == x {
            sum += v[i];
            i += 1;
        }
        if sum >= q * total {
            return Some(x);
        }
    }
    None
}

/// The smallest loss value `u` (or 0) with `Σ_{l > u} l ≤ q · Σ l`: `S(x) ≤ q` exactly for
/// `x ≥ u`.
pub fn share_at_most_from(l: &[f64], q: f64) -> f64 {
    let total: f64 = l.iter().sum();
    let mut v: Vec<f64> = l.iter().copied().filter(|&x| x > 0.0).collect();
    v.sort_by(|a, b| a.total_cmp(b));
    v.dedup();
    let mut candidates = vec![0.0];
    candidates.extend(v);
    for u in candidates {
        if l.iter().filter(|&&x| x > u).sum::<f64>() <= q * total {
            return u;
        }
    }
    f64::INFINITY
}

/// The median (the mean of the two middle values for an even count; 0 for none).
pub fn median(xs: &[f64]) -> f64 {
    if xs.is_empty() {
        return 0.0;
    }
    let mut v = xs.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// The `p`-quantile (nearest rank) of sorted values.
pub fn quantile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let k = ((p * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[k - 1]
}

/// What one household's lap measured, in the units of its ratios (scale 1).
#[derive(Clone, Debug, PartialEq)]
pub struct HouseholdLap {
    /// The household.
    pub household: &'static str,
    /// The teacher's ratios.
    pub ratios: Weights,
    /// Ticks of the lap.
    pub ticks: u32,
    /// `ℓ_t` of the path follower at every tick (0 where it agrees with the teacher).
    pub follower: Vec<f64>,
    /// `ℓ_t` of the passages only.
    pub passages: Vec<f64>,
    /// Latent losses (scale 1) of every allowed non-teacher action at every tick, pooled.
    pub others: Vec<f64>,
    /// Latent loss (scale 1) of the initial policy at every tick.
    pub initial: Vec<f64>,
}

/// Drives `preset`'s noiseless teacher for a lap of `scenario` and measures along it.
pub fn measure_lap(scenario: &Arc<Scenario>, preset: &'static Preset) -> Result<HouseholdLap> {
    // The teacher at scale 1 (its ratios): the choices do not depend on the scale, so neither
    // does anything measured here, before or after the scale is frozen.
    let spec = TeacherSpec::with_weights(Some(preset.name), preset.ratios);
    let mut teacher = Teacher::new(spec, 0);
    let follower_w = path_follower(&preset.ratios);
    let r = &preset.ratios;
    let mut out = HouseholdLap {
        household: preset.name,
        ratios: preset.ratios,
        ticks: 0,
        follower: Vec::new(),
        passages: Vec::new(),
        others: Vec::new(),
        initial: Vec::new(),
    };
    // Latent loss in ratio units, in f64 (the choices are the car's, in f32).
    let loss = |t: &firmware_core::FeatureTable, best, a| {
        let (pb, pa) = (&t[best], &t[a]);
        (0..pb.len())
            .map(|i| r[i] as f64 * (pb[i] as f64 - pa[i] as f64))
            .sum::<f64>()
            .max(0.0)
    };
    let drive = check::drive_lap(scenario, LAP_TICKS, |tick, obs| -> Result<_> {
        let j = teacher
            .judge(obs)
            .map_err(|e| anyhow::anyhow!("{}: tick {tick}: {e}", preset.name))?;
        let Some(best) = j.best else {
            bail!(
                "{}: tick {tick}: nothing allowed on the teacher's lap",
                preset.name
            );
        };
        let pf = policy::select(&follower_w, j.table(), j.allowed()).unwrap_or(best);
        let l = loss(j.table(), best, pf);
        out.follower.push(if pf == best { 0.0 } else { l });
        if pf != best {
            out.passages.push(l);
        }
        for a in j.allowed().iter().filter(|&a| a != best) {
            out.others.push(loss(j.table(), best, a));
        }
        let init = policy::select(&[0.0; 6], j.table(), j.allowed()).unwrap_or(best);
        out.initial.push(loss(j.table(), best, init));
        Ok(Some(best))
    })?;
    out.ticks = drive.ticks;
    match drive.end {
        LapEnd::Lap => Ok(out),
        LapEnd::Reset(reason) => bail!(
            "{}: the teacher's lap was cut short at tick {} ({})",
            preset.name,
            drive.ticks - 1,
            reason.name()
        ),
        LapEnd::Ticks => bail!("{}: no lap in {LAP_TICKS} ticks", preset.name),
    }
}

/// One target, its interval of scales, and the numbers it comes from.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetInterval {
    /// T1 … T4.
    pub target: &'static str,
    /// The household.
    pub household: &'static str,
    /// The condition in words.
    pub condition: String,
    /// Where it holds.
    pub interval: Interval,
    /// The loss value (ratio units) the interval's end comes from.
    pub pivot: f64,
}

/// The whole calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// Per household.
    pub laps: Vec<HouseholdLap>,
    /// Per target and household.
    pub targets: Vec<TargetInterval>,
    /// Whether one scale serves every teacher.
    pub common: Option<Interval>,
    /// The scale of each household's teacher.
    pub scales: Vec<(&'static str, f64)>,
    /// What the rule said, in words (the conflicts, if any).
    pub notes: Vec<String>,
}

const SQRT2: f64 = std::f64::consts::SQRT_2;

/// The targets' intervals from the laps.
pub fn target_intervals(laps: &[HouseholdLap]) -> Vec<TargetInterval> {
    let mut out = Vec::new();
    for lap in laps {
        let l = &lap.follower;
        if lap.household == "doors" {
            let v = share_at_least_below(l, 0.75).unwrap_or(f64::INFINITY);
            out.push(TargetInterval {
                target: "T1",
                household: lap.household,
                condition: "S(doors, s, 1.0) ≥ 0.75".into(),
                interval: Interval {
                    lo: 1.0 / v,
                    lo_closed: false,
                    ..Interval::ALL
                },
                pivot: v,
            });
            let m = median(&lap.passages);
            out.push(TargetInterval {
                target: "T4",
                household: lap.household,
                condition: "√2 ≤ m(doors, s) ≤ 2√2".into(),
                interval: Interval {
                    lo: SQRT2 / m,
                    lo_closed: true,
                    hi: 2.0 * SQRT2 / m,
                    hi_closed: true,
                },
                pivot: m,
            });
        } else {
            let u = share_at_most_from(l, 0.5);
            out.push(TargetInterval {
                target: "T2",
                household: lap.household,
                condition: format!("S({}, s, 1.0) ≤ 0.5", lap.household),
                interval: Interval {
                    hi: 1.0 / u,
                    hi_closed: u > 0.0,
                    ..Interval::ALL
                },
                pivot: u,
            });
            let v = share_at_least_below(l, 0.75).unwrap_or(f64::INFINITY);
            out.push(TargetInterval {
                target: "T3",
                household: lap.household,
                condition: format!("S({}, s, 0.25) ≥ 0.75", lap.household),
                interval: Interval {
                    lo: 0.25 / v,
                    lo_closed: false,
                    ..Interval::ALL
                },
                pivot: v,
            });
        }
    }
    out
}

/// The scale of the interval that fails the fewest of `targets` (ties: the first in target
/// order), and the targets it fails.
fn fewest_failures(targets: &[&TargetInterval]) -> (Option<f64>, Vec<&'static str>) {
    // Every non-empty intersection of a subset, largest subsets first.
    let n = targets.len();
    let mut best: Option<(usize, Interval, Vec<&'static str>)> = None;
    for mask in (1u32..(1 << n)).rev() {
        let mut i = Interval::ALL;
        let mut failed = Vec::new();
        for (k, t) in targets.iter().enumerate() {
            if mask >> k & 1 == 1 {
                i = i.intersect(&t.interval);
            } else {
                failed.push(t.target);
            }
        }
        if i.is_empty() || i.geometric_middle().is_none() {
            continue;
        }
        let kept = mask.count_ones() as usize;
        if best.as_ref().is_none_or(|b| kept > b.0) {
            best = Some((kept, i, failed));
        }
    }
    match best {
        Some((_, i, failed)) => (i.geometric_middle().map(two_significant), failed),
        None => (None, targets.iter().map(|t| t.target).collect()),
    }
}

/// Applies the rule to the measured laps.
pub fn calibrate(laps: Vec<HouseholdLap>) -> Calibration {
    let targets = target_intervals(&laps);
    let mut notes = Vec::new();
    let all = targets
        .iter()
        .fold(Interval::ALL, |i, t| i.intersect(&t.interval));
    let (common, scales) = match all.geometric_middle() {
        Some(g) => {
            let s = two_significant(g);
            notes.push(format!(
                "One interval of s satisfies T1–T4 for every teacher: {}; its geometric middle is \
                 {g:.4}, rounded to two significant digits s = {s}, for every teacher.",
                all.describe()
            ));
            (Some(all), laps.iter().map(|l| (l.household, s)).collect())
        }
        None => {
            notes.push(format!(
                "No single s satisfies T1–T4 for every teacher (their intersection is {}); each \
                 teacher gets the geometric middle of the interval its own targets allow.",
                all.describe()
            ));
            // Which pairs conflict.
            for (i, a) in targets.iter().enumerate() {
                for b in &targets[i + 1..] {
                    if a.interval.intersect(&b.interval).is_empty() {
                        notes.push(format!(
                            "{} in {} needs s in {} while {} in {} needs s in {}.",
                            a.target,
                            a.household,
                            a.interval.describe(),
                            b.target,
                            b.household,
                            b.interval.describe()
                        ));
                    }
                }
            }
            let mut scales = Vec::new();
            for lap in &laps {
                let own: Vec<&TargetInterval> = targets
                    .iter()
                    .filter(|t| t.household == lap.household)
                    .collect();
                let (s, failed) = fewest_failures(&own);
                if !failed.is_empty() {
                    notes.push(format!(
                        "{}: its own targets conflict; the scale fails {} (the middle of the \
                         interval that fails the fewest).",
                        lap.household,
                        failed.join(", ")
                    ));
                }
                match s {
                    Some(s) => scales.push((lap.household, s)),
                    None => notes.push(format!("{}: no bounded interval at all", lap.household)),
                }
            }
            (None, scales)
        }
    };
    Calibration {
        laps,
        targets,
        common,
        scales,
        notes,
    }
}

/// Measures the three households' laps with the current presets' ratios and applies the rule.
pub fn run() -> Result<Calibration> {
    let mut laps = Vec::new();
    for h in HOUSEHOLDS {
        let scenario = Arc::new(registry::load_scenario(h)?);
        let preset = crate::world::teacher::preset(h)
            .ok_or_else(|| anyhow::anyhow!("no teacher preset {h}"))?;
        laps.push(measure_lap(&scenario, preset)?);
    }
    Ok(calibrate(laps))
}

mod markdown;

pub use markdown::{markdown, two_digits};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shares_and_their_exact_thresholds() {
        // Losses 4, 3, 2, 1 (total 10) and zeros.
        let l = [0.0, 4.0, 1.0, 0.0, 3.0, 2.0];
        assert_eq!(share_above(&l, 0.0), 1.0);
        assert_eq!(share_above(&l, 1.0), 0.9);
        assert_eq!(share_above(&l, 2.5), 0.7);
        assert_eq!(share_above(&l, 4.0), 0.0);
        // S ≥ 0.75: 4 + 3 = 7 < 7.5, 4 + 3 + 2 = 9 ≥ 7.5: holds exactly for x < 2.
        assert_eq!(share_at_least_below(&l, 0.75), Some(2.0));
        assert!(share_above(&l, 1.999) >= 0.75 && share_above(&l, 2.0) < 0.75);
        // S ≤ 0.5: above 3 is 4 (0.4 ≤ 0.5), above 2 is 7: holds exactly for x ≥ 3.
        assert_eq!(share_at_most_from(&l, 0.5), 3.0);
        assert!(share_above(&l, 3.0) <= 0.5 && share_above(&l, 2.999) > 0.5);
        // Ties join at once: 5, 5 (total 10): S ≥ 0.75 needs both, so x < 5.
        assert_eq!(share_at_least_below(&[5.0, 5.0], 0.75), Some(5.0));
        assert_eq!(share_at_least_below(&[0.0], 0.75), None);
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert_eq!(two_significant(0.36789), 0.37);
        assert_eq!(two_significant(12.49), 12.0);
        assert_eq!(quantile(&[1.0, 2.0, 3.0, 4.0], 0.5), 2.0);
    }

    #[test]
    fn intervals_intersect_with_their_ends() {
        let a = Interval {
            lo: 1.0,
            lo_closed: false,
            ..Interval::ALL
        };
        let b = Interval {
            hi: 1.0,
            hi_closed: true,
            ..Interval::ALL
        };
        assert!(a.intersect(&b).is_empty());
        let c = Interval {
            lo: 0.5,
            lo_closed: true,
            hi: 4.0,
            hi_closed: true,
        };
        let i = a.intersect(&c);
        assert!(!i.contains(1.0) && i.contains(4.0) && i.contains(2.0));
        assert_eq!(i.geometric_middle(), Some(2.0));
        assert_eq!(a.geometric_middle(), None, "unbounded above");
    }

    fn lap(household: &'static str, follower: Vec<f64>) -> HouseholdLap {
        HouseholdLap {
            household,
            ratios: [0.0; 6],
            ticks: follower.len() as u32,
            passages: follower.iter().copied().filter(|&x| x > 0.0).collect(),
            follower,
            others: vec![],
            initial: vec![],
        }
    }

    #[test]
    fn the_rule_takes_the_common_interval_s_geometric_middle() {
        // doors: T1 needs 1/s < 2 (s > 0.5); median passage 2 → T4: s in [0.707, 1.414].
        // stairs: losses 4, 3, 2, 1: T2 needs 1/s ≥ 3 (s ≤ 1/3)... too small for T4: conflict.
        let laps = vec![
            lap("doors", vec![2.0, 2.0, 2.0, 0.5]),
            lap("stairs-right", vec![4.0, 3.0, 2.0, 1.0]),
        ];
        let c = calibrate(laps);
        assert!(c.common.is_none());
        assert!(
            c.notes.iter().any(|n| n.contains("No single s")),
            "{:?}",
            c.notes
        );
        // doors alone: (0.5, ∞) ∩ [0.707, 1.414] → √(0.707 · 1.414) = 1.0.
        assert_eq!(c.scales[0], ("doors", 1.0));
        // stairs alone: T2 s ≤ 1/3, T3 0.25/s < 2 → s > 0.125: middle √(0.125/3) ≈ 0.204 → 0.2.
        assert_eq!(c.scales[1], ("stairs-right", 0.2));
        // A stairs household whose losses allow the doors' interval: one common scale.
        let laps = vec![
            lap("doors", vec![2.0, 2.0, 2.0, 0.5]),
            lap("stairs-right", vec![0.5, 0.5, 0.4, 0.1, 0.1, 0.1, 0.1]),
        ];
        let c = calibrate(laps);
        let common = c.common.expect("one interval");
        assert!(common.contains(c.scales[0].1) && c.scales[0].1 == c.scales[1].1);
    }
}
