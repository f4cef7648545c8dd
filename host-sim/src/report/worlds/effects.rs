//! Each claim in one world: its verdict, by the same function of [`crate::report::claims`] as in
//! the paper's grid, applied to the world's own aggregates, and its **effect size** in that world
//! ([`EFFECTS`]), a number whose side of a boundary is the verdict (checked by the tests below).

use anyhow::{Result, ensure};

use super::{World, WorldTrial, world_settings};
use crate::report::aggregate::{Aggregate, TrialSummary, aggregate_summaries};
use crate::report::claims::{self, BC_FLAT};
use crate::report::grid::Options;
use crate::report::statistics::{spearman, tenth};
use crate::teach::experiment::Mode;

/// Each claim's effect size in a world, in words (the report's table and `worlds.csv`).
pub const EFFECTS: [&str; 6] = [
    "the smallest relative fall of the latent loss over action, preference and semantic \
     feedback, min (first − final) / first; the claim holds when it is above 0",
    "behaviour cloning's relative change of the latent loss, |final − first| / max(first, \
     final); the claim holds at 0.25 or below",
    "action feedback's smallest relative saving of corrections against preference and semantic \
     feedback, min (other − action) / max(other, action); the claim holds when it is above 0",
    "the smaller of the Spearman rank correlations with σ (0, 0.25, 0.5, 1) of the final loss \
     and of the corrections; 1 when both rise strictly, which is when the claim holds",
    "the smaller of the Spearman rank correlation with the threshold (0, 0.25, 0.5, 0.75, 1) of \
     the final loss and minus that of the corrections; 1 when the loss rises and the \
     corrections fall strictly, which is when the claim holds",
    "the share of the world's ten online settings whose corrections flattened (fewer in the \
     last tenth than in the first, or none); 1 when the claim holds",
];

/// Indices into [`world_settings`]: action, preference and semantic feedback, behaviour
/// cloning; the noise curves σ = 0, 0.25, 0.5, 1; the thresholds 0 … 1.
const ONLINE: [usize; 3] = [0, 1, 2];
const BC: usize = 3;
const NOISE: [usize; 4] = [0, 4, 5, 6];
const THRESHOLDS: [usize; 5] = [7, 8, 9, 10, 0];

/// The claims in one world.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// The world.
    pub world: World,
    /// Whether each claim holds there.
    pub holds: [bool; 6],
    /// Each claim's effect size there ([`EFFECTS`]).
    pub effects: [f64; 6],
    /// Laps of action feedback's trials (σ 0, threshold 1), mean.
    pub action_laps: f64,
    /// Resets of action feedback's trials, mean (every cause).
    pub action_resets: f64,
    /// The orders behind claims 4 and 5, Spearman rank correlations: of the final loss with σ,
    /// of the corrections with σ, of the final loss with the threshold, of the corrections with
    /// the threshold (claim 4 wants the first two at 1, claim 5 the third at 1 and the fourth
    /// at −1).
    pub orders: [f64; 4],
}

/// `a` relative to the larger of `a` and `b` (0 when both are 0).
fn relative(d: f64, a: f64, b: f64) -> f64 {
    let m = a.max(b);
    if m > 0.0 { d / m } else { 0.0 }
}

/// The claims in `world` from its aggregates, in [`world_settings`] order (`trials` per
/// setting, `steps` per trial).
pub fn outcome(world: World, aggs: &[Aggregate], trials: usize, steps: u32) -> Outcome {
    let pick = |ix: &[usize]| -> Vec<&Aggregate> { ix.iter().map(|&i| &aggs[i]).collect() };
    let online = pick(&ONLINE);
    let bc = &aggs[BC];
    let curves = pick(&NOISE);
    let thresholds = pick(&THRESHOLDS);
    let every_online: Vec<&Aggregate> = aggs
        .iter()
        .filter(|a| matches!(a.setting.mode, Mode::Online(_)))
        .collect();
    let name = world.name();
    let verdicts = [
        claims::feedback_lowers_loss(&online),
        claims::bc_flat(&[bc]),
        claims::action_fewest(&[(name.as_str(), online.clone())], trials),
        claims::noise_raises(&curves, &curves),
        claims::threshold_lowers(&thresholds, &thresholds),
        claims::corrections_flatten(&every_online, tenth(steps as usize)),
    ];
    let corrections = |a: &Aggregate| a.total_corrections.0;
    let action = corrections(online[0]);
    let rho = |v: &[&Aggregate], x: &dyn Fn(&Aggregate) -> f64, y: &dyn Fn(&Aggregate) -> f64| {
        let xs: Vec<f64> = v.iter().map(|a| x(a)).collect();
        let ys: Vec<f64> = v.iter().map(|a| y(a)).collect();
        spearman(&xs, &ys)
    };
    let sigma = |a: &Aggregate| a.setting.noise as f64;
    let tau = |a: &Aggregate| a.setting.threshold as f64;
    let loss = |a: &Aggregate| a.final_loss.0;
    let orders = [
        rho(&curves, &sigma, &loss),
        rho(&curves, &sigma, &corrections),
        rho(&thresholds, &tau, &loss),
        rho(&thresholds, &tau, &corrections),
    ];
    let effects = [
        online
            .iter()
            .map(|a| {
                let (first, last) = (a.first_loss.0, a.final_loss.0);
                if first > 0.0 {
                    (first - last) / first
                } else {
                    0.0
                }
            })
            .fold(f64::INFINITY, f64::min),
        relative(
            (bc.final_loss.0 - bc.first_loss.0).abs(),
            bc.first_loss.0,
            bc.final_loss.0,
        ),
        online[1..]
            .iter()
            .map(|a| relative(corrections(a) - action, corrections(a), action))
            .fold(f64::INFINITY, f64::min),
        orders[0].min(orders[1]),
        orders[2].min(-orders[3]),
        every_online.iter().filter(|a| claims::flattened(a)).count() as f64
            / every_online.len().max(1) as f64,
    ];
    Outcome {
        world,
        holds: verdicts.map(|v| v.holds),
        effects,
        action_laps: online[0].laps.0,
        action_resets: online[0].resets.iter().sum(),
        orders,
    }
}

/// Every world's outcome from its trials (`None` for a world the generator did not give), in
/// world order; checks that the trials are the whole grid of every world.
pub fn outcomes(
    o: &Options,
    worlds: &[World],
    trials: &[WorldTrial],
) -> Result<Vec<Option<Outcome>>> {
    let settings = world_settings();
    let n = o.world_trials as usize;
    // Per world, setting and trial: not given yet, or given (`None` when the world was not made).
    type Slot = Option<Option<TrialSummary>>;
    let mut by: Vec<Vec<Vec<Slot>>> = vec![vec![vec![None; n]; settings.len()]; worlds.len()];
    for t in trials {
        ensure!(
            t.world < worlds.len() && t.setting < settings.len() && (t.trial as usize) < n,
            "a world's trial of another grid"
        );
        let slot = &mut by[t.world][t.setting][t.trial as usize];
        ensure!(
            slot.is_none(),
            "{}: a trial given twice",
            worlds[t.world].name()
        );
        *slot = Some(t.summary);
    }
    let mut out = Vec::with_capacity(worlds.len());
    for (w, per_setting) in worlds.iter().zip(by) {
        let mut aggs = Vec::with_capacity(settings.len());
        let mut generated = true;
        for (s, slots) in settings.iter().zip(per_setting) {
            let mut summaries = Vec::with_capacity(n);
            for slot in slots {
                let Some(summary) = slot else {
                    anyhow::bail!("{}: a trial is missing", w.name());
                };
                match summary {
                    Some(x) => summaries.push(x),
                    None => generated = false,
                }
            }
            let setting = crate::report::grid::Setting {
                household: w.teacher(),
                ..*s
            };
            aggs.push(aggregate_summaries(setting, &summaries));
        }
        out.push(generated.then(|| outcome(*w, &aggs, n, o.steps)));
    }
    Ok(out)
}

/// Whether claim `i`'s effect size `e` is on the side of its boundary where the claim holds.
pub fn effect_holds(i: usize, e: f64) -> bool {
    match i {
        0 | 2 => e > 0.0,
        1 => e <= BC_FLAT,
        _ => e >= 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::grid::Setting;

    /// A world's aggregates: losses first → final per setting, corrections per setting, and the
    /// first- and last-tenth corrections.
    fn world(
        first: [f64; 11],
        last: [f64; 11],
        corrections: [f64; 11],
        tenths: [(f64, f64); 11],
    ) -> Vec<Aggregate> {
        world_settings()
            .into_iter()
            .enumerate()
            .map(|(i, s)| {
                let mut a = Aggregate::empty(
                    Setting {
                        household: "doors",
                        ..s
                    },
                    2,
                );
                a.first_loss = (first[i], 0.0);
                a.final_loss = (last[i], 0.0);
                a.total_corrections = (corrections[i], 0.0);
                a.first_tenth_corrections = (tenths[i].0, 0.0);
                a.last_tenth_corrections = (tenths[i].1, 0.0);
                a
            })
            .collect()
    }

    const W: World = World::Generated {
        seed: 3,
        teacher: "doors",
    };

    #[test]
    fn every_claim_holds_in_a_world_made_for_it_and_its_effects_say_so() {
        // Settings: action, preference, semantic, bc, σ .25 .5 1, thresholds 0 .25 .5 .75.
        // Final losses rise with σ and with the threshold (threshold 1 is action's 0.1);
        // corrections rise with σ and fall with the threshold.
        let first = [1.0, 1.0, 1.0, 0.5, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0];
        let last = [0.1, 0.2, 0.4, 0.55, 0.2, 0.3, 0.4, 0.01, 0.02, 0.03, 0.05];
        let corr = [
            10.0, 30.0, 20.0, 0.0, 12.0, 14.0, 16.0, 50.0, 40.0, 30.0, 20.0,
        ];
        let tenths = [(5.0, 1.0); 11];
        let o = outcome(W, &world(first, last, corr, tenths), 2, 100);
        assert_eq!(o.holds, [true; 6], "{o:?}");
        assert!((o.effects[0] - 0.6).abs() < 1e-12, "{o:?}");
        assert!((o.effects[1] - 0.05 / 0.55).abs() < 1e-12, "{o:?}");
        assert!((o.effects[2] - 0.5).abs() < 1e-12, "{o:?}");
        assert_eq!(&o.effects[3..], &[1.0, 1.0, 1.0]);
        assert_eq!(o.orders, [1.0, 1.0, 1.0, -1.0]);
        for i in 0..6 {
            assert!(effect_holds(i, o.effects[i]), "claim {}", i + 1);
        }
    }

    #[test]
    fn a_failing_claim_fails_by_its_effect_too() {
        let first = [1.0, 1.0, 1.0, 0.5, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0];
        // Semantic feedback does not lower the loss; bc rises by half; preference needs fewer
        // corrections than action; the loss falls at σ 1; the corrections rise at threshold
        // 0.75; one setting keeps correcting.
        let last = [0.1, 0.2, 1.0, 1.0, 0.2, 0.3, 0.15, 0.01, 0.02, 0.03, 0.05];
        let corr = [
            10.0, 8.0, 20.0, 0.0, 12.0, 14.0, 16.0, 50.0, 40.0, 30.0, 35.0,
        ];
        let mut tenths = [(5.0, 1.0); 11];
        tenths[5] = (2.0, 3.0);
        let o = outcome(W, &world(first, last, corr, tenths), 2, 100);
        assert_eq!(o.holds, [false; 6], "{o:?}");
        for i in 0..6 {
            assert!(
                !effect_holds(i, o.effects[i]),
                "claim {}: {}",
                i + 1,
                o.effects[i]
            );
        }
        assert_eq!(o.effects[0], 0.0);
        assert_eq!(o.effects[1], 0.5);
        assert!((o.effects[2] + 0.2).abs() < 1e-12);
        assert!((o.effects[5] - 0.9).abs() < 1e-12);
        // The loss is out of order with σ (ranks 1 3 4 2), the corrections with the threshold
        // (5 4 2 3 1 where 5 4 3 2 1 is claimed).
        let want = [0.4, 1.0, 1.0, -0.9];
        for (got, want) in o.orders.iter().zip(want) {
            assert!((got - want).abs() < 1e-12, "{:?}", o.orders);
        }
    }
}
