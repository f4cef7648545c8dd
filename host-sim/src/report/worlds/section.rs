//! The report's section on the claims across worlds, the pictures of the worlds where a claim
//! fails, and `worlds.csv`.
//!
//! # Intervals
//!
//! * The share of the generated worlds where a claim holds gets a 95% **Wilson score**
//!   interval ([`wilson`]): a binomial proportion, often near 0 or 1, where the normal
//!   approximation's interval leaves [0, 1] or covers too little.
//! * A claim's mean effect size over the generated worlds gets a 95% **percentile bootstrap**
//!   interval ([`bootstrap_mean`], 10 000 resamples from a ChaCha8 generator seeded with
//!   [`BOOTSTRAP_SEED`] + the claim's number, so the report is the same bytes every time): the
//!   effect sizes are bounded and skewed (rank correlations pile up at 1, shares at 1, relative
//!   changes have long tails), and a t interval's normal sampling distribution of the mean is
//!   not to be assumed at a few dozen worlds; the bootstrap assumes only that the worlds are
//!   independent draws, which the generator's seeds make them.
//!
//! The fixed worlds (the paper's households and the basement) are reported one by one and kept
//! out of both intervals: they were drawn by hand, not drawn from the generator.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;

use super::effects::{EFFECTS, Outcome, outcomes};
use super::{FIXED, Scenarios, World, WorldTrial, world_settings, worlds};
use crate::report::claims::SHORT;
use crate::report::figure::{self, Picture};
use crate::report::files::write_csv;
use crate::report::grid::Options;
use crate::report::plot::MapDrawing;
use crate::report::statistics::{BOOTSTRAP_RESAMPLES, bootstrap_mean, mean_std, wilson};
use crate::world::check;
use crate::world::teacher::{self, TeacherSpec};

/// Seed of claim `i`'s bootstrap is this plus `i` (1 … 6).
pub const BOOTSTRAP_SEED: u64 = 0xB007_5742_A1D5_0000;
/// Most pictures of failing worlds per claim.
pub const FAILURE_PICTURES: usize = 6;
/// Most failing worlds named per claim.
pub const FAILURES_NAMED: usize = 40;
/// The teacher's lap in the pictures.
const LAP_COLOUR: [u8; 3] = [150, 0, 200];

/// Writes `worlds.csv` and the pictures of failing worlds into `out`, and returns the report's
/// section.
pub fn write(out: &Path, figs: &Path, o: &Options, trials: &[WorldTrial]) -> Result<String> {
    let all = worlds(o.worlds);
    let results = outcomes(o, &all, trials)?;
    write_table(&out.join("worlds.csv"), &all, &results)?;
    let generated: Vec<&Outcome> = results
        .iter()
        .flatten()
        .filter(|x| x.world.generated())
        .collect();
    let missing: Vec<String> = all
        .iter()
        .zip(&results)
        .filter(|(_, r)| r.is_none())
        .map(|(w, _)| w.name())
        .collect();
    let fixed: Vec<Option<&Outcome>> = FIXED
        .iter()
        .map(|h| {
            results
                .iter()
                .flatten()
                .find(|x| x.world == World::Fixed(h))
        })
        .collect();

    let mut r = String::new();
    let n_settings = world_settings().len();
    let _ = writeln!(
        r,
        "## The claims across worlds\n\n\
         Three households cannot tell a property of the method from a property of one floor \
         plan. So every claim is checked again in each of {} worlds: the three households and \
         the basement scenario, each with its own teacher, and the generated households of seeds \
         0 to {} (`host-sim generate`, default options), each with each of the three calibrated \
         teachers: {} generated worlds{}. The generator keeps a plan only if every teacher's own \
         policy laps it, so the three teachers meet the same plans; no world and no teacher was \
         chosen or tuned for a claim.\n\n\
         Each world runs its own grid, the paper's experiments in miniature with the world's \
         teacher: action, preference and semantic feedback and behaviour cloning (σ = 0, \
         threshold 1.0); action feedback at σ = 0.25, 0.5, 1.0; action feedback at thresholds \
         0, 0.25, 0.5, 0.75: {n_settings} settings × {} trials (seeds {} + t, as above) × {} \
         steps, the paper's learner. A claim's verdict in a world is the rule of the claim above \
         (the same function), applied to the world's own numbers; claim 1, about the doors \
         household in the paper, is asked of every world, and claims 4 and 5 of every world's \
         noise levels (0, 0.25, 0.5, 1) and thresholds (0 to 1).\n",
        all.len(),
        o.worlds.saturating_sub(1),
        3 * o.worlds,
        if missing.is_empty() {
            String::new()
        } else {
            format!(
                " ({} of them could not be made: the generator found no plan that passes its \
                 checks: {})",
                missing.len(),
                missing.join(", ")
            )
        },
        o.world_trials,
        o.seed,
        o.steps,
    );
    let _ = writeln!(
        r,
        "Intervals: the share of generated worlds where a claim holds has a 95% Wilson score \
         interval (a proportion, often near 0 or 1, where the normal approximation's interval \
         misbehaves); a claim's mean effect size over the generated worlds has a 95% percentile \
         bootstrap interval ({} resamples of the worlds, seeded, so this file \
         is the same bytes every time): the effect sizes are bounded and skewed, and the worlds \
         are independent draws of the generator. The four fixed worlds are shown one by one and \
         kept out of both intervals.\n",
        BOOTSTRAP_RESAMPLES
    );
    let _ = writeln!(
        r,
        "| # | claim | doors | stairs-right | stairs-chairs | basement | generated worlds where it \
         holds (95% interval) | by teacher: doors / stairs-right / stairs-chairs | effect size, \
         mean over generated worlds (95% interval) |\n|---|---|---|---|---|---|---|---|---|"
    );
    for (i, claim) in SHORT.iter().enumerate() {
        let mark = |x: &Option<&Outcome>| match x {
            Some(x) => format!(
                "{} ({:.3})",
                if x.holds[i] { "holds" } else { "fails" },
                x.effects[i]
            ),
            None => "-".into(),
        };
        let n = generated.len();
        let k = generated.iter().filter(|x| x.holds[i]).count();
        let (lo, hi) = wilson(k, n);
        let by_teacher: Vec<String> = teacher::PRESETS
            .iter()
            .map(|p| {
                let of: Vec<&&Outcome> = generated
                    .iter()
                    .filter(|x| x.world.teacher() == p.name)
                    .collect();
                format!("{}/{}", of.iter().filter(|x| x.holds[i]).count(), of.len())
            })
            .collect();
        let effects: Vec<f64> = generated.iter().map(|x| x.effects[i]).collect();
        let effect = match bootstrap_mean(&effects, BOOTSTRAP_SEED + i as u64 + 1) {
            Some((a, b)) => format!("{:.3} ({a:.3} to {b:.3})", mean_std(&effects).0),
            None => "-".into(),
        };
        let _ = writeln!(
            r,
            "| {} | {claim} | {} | {} | {} | {} | {k} of {n} ({:.0}% to {:.0}%) | {} | {effect} |",
            i + 1,
            mark(&fixed[0]),
            mark(&fixed[1]),
            mark(&fixed[2]),
            mark(&fixed[3]),
            100.0 * lo,
            100.0 * hi,
            by_teacher.join(" / "),
        );
    }
    let _ = writeln!(
        r,
        "\nThe effect size of each claim in a world (in brackets after each fixed world's \
         verdict):\n"
    );
    for (i, e) in EFFECTS.iter().enumerate() {
        let _ = writeln!(r, "{}. {e}.", i + 1);
    }
    let _ = writeln!(
        r,
        "\nClaims 4 and 5 ask a world for a strict order over four noise levels and five \
         thresholds, each the mean of {} trials: one pair of neighbouring settings out of order \
         fails them, so their counts are severe and their effect sizes (rank correlations: 1 is \
         the claimed order, 0 none, −1 the reverse) say how close the world came.",
        o.world_trials
    );
    if !generated.is_empty() {
        let part = |k: usize, want: f64| {
            let v: Vec<f64> = generated.iter().map(|x| x.orders[k]).collect();
            (v.iter().filter(|&&r| r == want).count(), mean_std(&v).0)
        };
        let (a, b, c, d) = (part(0, 1.0), part(1, 1.0), part(2, 1.0), part(3, -1.0));
        let n = generated.len();
        let _ = writeln!(
            r,
            "Which order breaks, over the {n} generated worlds: the final loss rises strictly \
             with σ in {} (mean rank correlation {:.3}), the corrections in {} ({:.3}); the \
             final loss rises strictly with the threshold in {} ({:.3}), the corrections fall \
             strictly in {} ({:.3}) (`worlds.csv` has each world's four correlations).",
            a.0, a.1, b.0, b.1, c.0, c.1, d.0, d.1
        );
    }
    let laps: Vec<f64> = generated.iter().map(|x| x.action_laps).collect();
    let never = generated.iter().filter(|x| x.action_laps == 0.0).count();
    if let Some((a, b)) = bootstrap_mean(&laps, BOOTSTRAP_SEED) {
        let resets: Vec<f64> = generated.iter().map(|x| x.action_resets).collect();
        let _ = writeln!(
            r,
            "\nWhere the cars got, with action feedback (σ = 0, threshold 1.0): {:.1} laps per \
             trial, mean over the generated worlds ({a:.1} to {b:.1}), {:.1} resets per trial; \
             worlds where no such trial completed a lap: {never} of {}.\n",
            mean_std(&laps).0,
            mean_std(&resets).0,
            generated.len()
        );
    }
    failures(&mut r, figs, &all, &generated)?;
    let _ = writeln!(
        r,
        "Every world's verdicts, effect sizes and action feedback's laps are in `worlds.csv`.\n"
    );
    Ok(r)
}

/// The worlds where each claim fails: named, and the first of them drawn with the teacher's
/// lap.
fn failures(r: &mut String, figs: &Path, all: &[World], generated: &[&Outcome]) -> Result<()> {
    let _ = writeln!(r, "### Where the claims fail\n");
    let failing: Vec<Vec<&&Outcome>> = (0..SHORT.len())
        .map(|i| generated.iter().filter(|x| !x.holds[i]).collect())
        .collect();
    let needed: Vec<usize> = all
        .iter()
        .enumerate()
        .filter(|(_, w)| {
            failing
                .iter()
                .any(|f| f.iter().take(FAILURE_PICTURES).any(|x| x.world == **w))
        })
        .map(|(k, _)| k)
        .collect();
    let scenarios = Scenarios::load(all, &needed)?;
    for (i, (claim, fails)) in SHORT.iter().zip(&failing).enumerate() {
        let _ = write!(r, "**{}. {claim}**: ", i + 1);
        if fails.is_empty() {
            let _ = writeln!(r, "holds in every generated world.\n");
            continue;
        }
        let named: Vec<String> = fails
            .iter()
            .take(FAILURES_NAMED)
            .map(|x| format!("{} ({:.3})", x.world.name(), x.effects[i]))
            .collect();
        let _ = writeln!(
            r,
            "fails in {} of {} generated worlds: {}{}.\n",
            fails.len(),
            generated.len(),
            named.join(", "),
            if fails.len() > FAILURES_NAMED {
                format!(", and {} more", fails.len() - FAILURES_NAMED)
            } else {
                String::new()
            }
        );
        let shown: Vec<(&&Outcome, std::sync::Arc<crate::world::scenario::Scenario>)> = fails
            .iter()
            .take(FAILURE_PICTURES)
            .filter_map(|x| Some((*x, scenarios.scenario(&x.world)?)))
            .collect();
        let maps: Vec<&crate::world::scenario::Scenario> =
            shown.iter().map(|(_, s)| &**s).collect();
        let scale = MapDrawing::common_scale(&maps, 420);
        let cm = maps
            .first()
            .map_or(0.0, |s| 100.0 * MapDrawing::metres_per_pixel(s, scale));
        let mut pics = Vec::new();
        for (x, scenario) in &shown {
            let mut d = MapDrawing::of_scenario_scaled(scenario, scale);
            let lap = teacher::preset(x.world.teacher())
                .and_then(|p| check::lap_of(scenario, TeacherSpec::from_preset(p)).ok());
            if let Some(lap) = lap {
                d.polyline(&lap.trace, LAP_COLOUR);
            }
            pics.push(Picture {
                caption: format!("{}: {:.3}", x.world.name(), x.effects[i]),
                image: d.into_raster(),
            });
        }
        let stem = format!("worlds_claim{}", i + 1);
        figure::write_pictures(
            &figs.join(&stem),
            &format!("Claim {}: worlds where it fails", i + 1),
            &format!(
                "purple: the teacher's lap; blue: the path; doors brown, stairs red, chairs \
                 green; caption: world, effect size; 1 px = {cm:.1} cm"
            ),
            &pics,
            3,
        )?;
        let _ = writeln!(
            r,
            "![claim {} fails](figures/{stem}.png)\n\nThe first {} of them, each with its \
             teacher's own lap (purple) and the claim's effect size there.\n",
            i + 1,
            pics.len()
        );
    }
    Ok(())
}

/// `worlds.csv`: one row per world, its verdicts and effect sizes (empty for a world the
/// generator did not give).
fn write_table(path: &Path, all: &[World], results: &[Option<Outcome>]) -> Result<()> {
    let mut header = vec!["world", "teacher", "generated", "made"];
    let holds: Vec<String> = (1..=6).map(|i| format!("claim{i}_holds")).collect();
    let effects: Vec<String> = (1..=6).map(|i| format!("claim{i}_effect")).collect();
    header.extend(holds.iter().map(String::as_str));
    header.extend(effects.iter().map(String::as_str));
    header.extend([
        "action_laps",
        "action_resets",
        "rho_loss_sigma",
        "rho_corrections_sigma",
        "rho_loss_threshold",
        "rho_corrections_threshold",
    ]);
    write_csv(
        path,
        &header,
        all.iter().zip(results).map(|(w, x)| {
            let mut row = vec![
                w.name(),
                w.teacher().to_string(),
                u8::from(w.generated()).to_string(),
                u8::from(x.is_some()).to_string(),
            ];
            match x {
                Some(x) => {
                    row.extend(x.holds.iter().map(|&h| u8::from(h).to_string()));
                    row.extend(x.effects.iter().map(f64::to_string));
                    row.push(format!("{:.3}", x.action_laps));
                    row.push(format!("{:.3}", x.action_resets));
                    row.extend(x.orders.iter().map(f64::to_string));
                }
                None => row.extend(std::iter::repeat_n(String::new(), 18)),
            }
            row
        }),
    )
}
