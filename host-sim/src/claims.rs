//! The paper's claims, each checked by one pure function of the reproduction's aggregates.
//!
//! Every function here takes [`Aggregate`]s (means and standard deviations across trials; see
//! [`crate::reproduce`]) and returns a [`Verdict`]: whether the claim holds by its rule, and a
//! paragraph with the numbers and, when it does not hold, the reason. Nothing here runs a
//! simulation, so each rule is tested on synthetic aggregates on both sides of it and on its
//! boundary (`tests` below).
//!
//! | # | claim | rule |
//! |---|---|---|
//! | 1 | every feedback type lowers the latent loss in `doors` | each kind's final loss (mean over trials) is below its first-tenth loss |
//! | 2 | behaviour cloning stays about flat | in each household, the first- and last-tenth losses differ by at most a quarter of the larger |
//! | 3 | action feedback needs the fewest corrections in each household | action's mean corrections are below each other kind's, in every household |
//! | 4 | more noise gives a higher final loss and more corrections | both rise strictly over σ = 0, 0.25, 0.5, 1.0 |
//! | 5 | a lower threshold gives a lower final loss and more corrections | over the paper's thresholds 0 … 1, the final loss rises strictly and the corrections fall strictly |
//! | 6 | the corrections flatten out | every online setting has fewer corrections in its last tenth than in its first, or none in its last tenth |
//!
//! Claim 2's rule before this version was "within 25% of the larger, or within 0.05": at the
//! losses of a behaviour-cloned policy (0.006–0.015 then) the absolute 0.05 made it impossible
//! to fail. It is now relative to the two quantities it compares, and the report says so.
//!
//! Claim 6's rule was "fewer in the last tenth than in the first". The thresholds 4 and 8, added
//! with this version, give teachers that never correct at all (0 and 0): their count does not
//! grow, which is what "flatten out" means, but "fewer" counted them as failing. A setting with
//! no correction in its last tenth now counts as flattened; the report says so and counts them.
//!
//! The claims about learning (1, 3, 4, 5) also say whether the car got anywhere: laps, progress
//! and resets beside the latent loss, which cannot see a car that circles where the teacher
//! would circle too.

use std::fmt::Write as _;

use crate::experiment::RESET_CAUSES;
use crate::reproduce::{Aggregate, spearman, upper_tail};

/// The claims, in the report's order.
pub const CLAIMS: [&str; 6] = [
    "Every feedback type lowers the latent loss in the doors household",
    "Behaviour cloning stays about flat",
    "Action feedback needs the fewest corrections in each household",
    "More noise gives a higher final latent loss and more corrections",
    "A lower threshold gives a lower final loss and more corrections",
    "The corrections flatten out (fewer in the last tenth of a run than in the first, or none)",
];

/// The largest relative change of behaviour cloning's loss that still counts as flat.
pub const BC_FLAT: f64 = 0.25;

/// A claim's outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    /// Whether the claim holds by its rule.
    pub holds: bool,
    /// The numbers, and the reason when it does not hold.
    pub text: String,
}

impl Verdict {
    /// `**holds**` or `**does not hold**`.
    pub fn word(&self) -> &'static str {
        if self.holds {
            "**holds**"
        } else {
            "**does not hold**"
        }
    }

    /// `holds` or `does not hold`.
    pub fn plain(&self) -> &'static str {
        if self.holds { "holds" } else { "does not hold" }
    }
}

/// `0.123 ± 0.045`.
pub fn pm(x: (f64, f64)) -> String {
    format!("{:.3} ± {:.3}", x.0, x.1)
}

/// `12.3 ± 4.5`.
pub fn pm1(x: (f64, f64)) -> String {
    format!("{:.1} ± {:.1}", x.0, x.1)
}

/// Whether the car got anywhere, in a few words: "4.2 laps (10 of 10 trials lapped), 0.3
/// resets (0.3 lost)".
pub fn task(a: &Aggregate) -> String {
    let total: f64 = a.resets.iter().sum();
    let causes: Vec<String> = RESET_CAUSES
        .iter()
        .zip(&a.resets)
        .filter(|(_, n)| **n > 0.0)
        .map(|(c, n)| format!("{n:.1} {c}"))
        .collect();
    format!(
        "{:.1} laps ({} of {} trials lapped), {:.0} m of progress, {:.1} resets{}",
        a.laps.0,
        a.lapped,
        a.trials,
        a.progress.0,
        total,
        if causes.is_empty() {
            String::new()
        } else {
            format!(" ({})", causes.join(", "))
        }
    )
}

/// The pairs `(i, i+1)` where `v` does not strictly increase.
pub fn breaks_increase(v: &[f64]) -> Vec<usize> {
    (0..v.len().saturating_sub(1))
        .filter(|&i| v[i + 1] <= v[i])
        .collect()
}

/// Claim 1 over the doors household's online settings (action, preference, semantic).
pub fn feedback_lowers_loss(doors: &[&Aggregate]) -> Verdict {
    let mut holds = !doors.is_empty();
    let mut parts = Vec::new();
    let mut tasks = Vec::new();
    for a in doors {
        let lowered = a.final_loss.0 < a.first_loss.0;
        holds &= lowered;
        let m = a.setting.mode.name();
        parts.push(format!(
            "{m}: {} → {} ({})",
            pm(a.first_loss),
            pm(a.final_loss),
            if lowered {
                format!(
                    "{:.0}% lower",
                    100.0 * (1.0 - a.final_loss.0 / a.first_loss.0.max(1e-12))
                )
            } else {
                "not lower".into()
            }
        ));
        tasks.push(format!("{m}: {}", task(a)));
    }
    let mut text = format!(
        "Mean latent loss, first tenth → last tenth, in `doors`: {}.",
        parts.join("; ")
    );
    if !holds {
        text.push_str(
            " Where it is not lower, the learner did not improve within this run; its corrections \
             are in the variety table below.",
        );
    }
    let _ = write!(text, " Where the cars got: {}.", tasks.join("; "));
    Verdict { holds, text }
}

/// Claim 2 over the behaviour-cloning settings of each household.
pub fn bc_flat(bc: &[&Aggregate]) -> Verdict {
    let mut holds = !bc.is_empty();
    let mut parts = Vec::new();
    for a in bc {
        let (first, last) = (a.first_loss.0, a.final_loss.0);
        let d = (last - first).abs();
        let larger = first.max(last);
        let flat = d <= BC_FLAT * larger;
        holds &= flat;
        parts.push(format!(
            "{}: {} → {} ({}{}); {}",
            a.setting.household,
            pm(a.first_loss),
            pm(a.final_loss),
            if larger > 0.0 {
                format!("{:+.0}%", 100.0 * (last - first) / larger)
            } else {
                "both 0".into()
            },
            if flat { "" } else { ", not flat" },
            task(a)
        ));
    }
    let mut text = format!(
        "Behaviour cloning is fitted on the teacher's demonstration of the run's first 50 ticks and \
         then frozen, so its loss can only change with where the car drives. \"About flat\" is \
         taken as: the first- and last-tenth losses differ by at most {:.0}% of the larger (the \
         rule is relative to the two losses it compares; an earlier version also accepted any \
         difference below 0.05, which could not fail at the losses behaviour cloning had then). \
         {}.",
        100.0 * BC_FLAT,
        parts.join("; ")
    );
    if !holds {
        text.push_str(
            " Where it is not flat, the frozen policy drives into states (after resets, on later \
             laps) whose loss differs from the first tenth's; nothing is learned either way.",
        );
    }
    Verdict { holds, text }
}

/// Claim 3: per household, its online settings (action, preference, semantic); `trials` is the
/// number of trials per setting (for the standard error of a difference of means).
pub fn action_fewest(households: &[(&str, Vec<&Aggregate>)], trials: usize) -> Verdict {
    let mut holds = !households.is_empty();
    let mut parts = Vec::new();
    let mut why = Vec::new();
    for (h, c) in households {
        let Some(action) = c.iter().find(|a| a.setting.mode.name() == "action") else {
            holds = false;
            parts.push(format!("{h}: no action feedback setting"));
            continue;
        };
        let mut fewest = true;
        for other in c.iter().filter(|a| a.setting.mode.name() != "action") {
            if action.total_corrections.0 >= other.total_corrections.0 {
                fewest = false;
                let n = trials.max(1) as f64;
                let se = ((action.total_corrections.1.powi(2) + other.total_corrections.1.powi(2))
                    / n)
                    .sqrt();
                let d = action.total_corrections.0 - other.total_corrections.0;
                why.push(format!(
                    "in {h}, {} needed {:.1} corrections against action's {:.1} (difference {d:.1}, \
                     {} standard errors of the difference of means), and ended at a final loss \
                     of {} against action's {}",
                    other.setting.mode.name(),
                    other.total_corrections.0,
                    action.total_corrections.0,
                    if se > 0.0 {
                        format!("{:.1}", d / se)
                    } else {
                        "∞".into()
                    },
                    pm(other.final_loss),
                    pm(action.final_loss)
                ));
            }
        }
        holds &= fewest;
        parts.push(format!(
            "{h}: {}{}",
            c.iter()
                .map(|a| format!(
                    "{} {} ({:.1} laps)",
                    a.setting.mode.name(),
                    pm1(a.total_corrections),
                    a.laps.0
                ))
                .collect::<Vec<_>>()
                .join(", "),
            if fewest {
                ""
            } else {
                " (action is not the fewest)"
            }
        ));
    }
    let mut text = format!("Corrections in all (mean ± std): {}.", parts.join("; "));
    if !holds && !why.is_empty() {
        let _ = write!(
            text,
            " It fails because {}. A teacher stops correcting once the perceived loss of the \
             learner's actions stays below its threshold, so the count measures how soon that \
             happens in this household's geometry, not only how informative one correction is; \
             the households were not changed to make the claim hold.",
            why.join("; ")
        );
    }
    Verdict { holds, text }
}

/// Claim 4: the paper's curves (σ = 0, 0.25, 0.5, 1.0, in order) and the whole sweep.
pub fn noise_raises(curves: &[&Aggregate], sweep: &[&Aggregate]) -> Verdict {
    let fl: Vec<f64> = curves.iter().map(|a| a.final_loss.0).collect();
    let co: Vec<f64> = curves.iter().map(|a| a.total_corrections.0).collect();
    let (bl, bc) = (breaks_increase(&fl), breaks_increase(&co));
    let holds = curves.len() >= 2 && bl.is_empty() && bc.is_empty();
    let sx: Vec<f64> = sweep.iter().map(|a| a.setting.noise as f64).collect();
    let rho_l = spearman(
        &sx,
        &sweep.iter().map(|a| a.final_loss.0).collect::<Vec<_>>(),
    );
    let rho_c = spearman(
        &sx,
        &sweep
            .iter()
            .map(|a| a.total_corrections.0)
            .collect::<Vec<_>>(),
    );
    let desc = |v: &[usize]| {
        v.iter()
            .map(|&i| {
                format!(
                    "σ {} → {}",
                    curves[i].setting.noise,
                    curves[i + 1].setting.noise
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    let sigmas: Vec<String> = curves.iter().map(|a| a.setting.noise.to_string()).collect();
    let mut text = format!(
        "Doors, action feedback, threshold 1.0; σ = {}: final loss {}; corrections {}. Over the \
         whole sweep (σ 0 to 2 in steps of 0.125) the Spearman rank correlation with σ is \
         {rho_l:.2} for the final loss and {rho_c:.2} for the corrections.",
        sigmas.join(", "),
        curves
            .iter()
            .map(|a| pm(a.final_loss))
            .collect::<Vec<_>>()
            .join(", "),
        curves
            .iter()
            .map(|a| pm1(a.total_corrections))
            .collect::<Vec<_>>()
            .join(", "),
    );
    if !bl.is_empty() {
        let _ = write!(text, " The final loss does not rise at {}.", desc(&bl));
    }
    if !bc.is_empty() {
        let _ = write!(text, " The corrections do not rise at {}.", desc(&bc));
    }
    if !holds {
        text.push_str(
            " Differences smaller than the standard deviations across trials are not resolved by \
             this many trials.",
        );
    }
    let _ = write!(
        text,
        " Where the cars got: {}.",
        curves
            .iter()
            .map(|a| format!("σ {}: {}", a.setting.noise, task(a)))
            .collect::<Vec<_>>()
            .join("; ")
    );
    Verdict { holds, text }
}

/// Claim 5: the paper's thresholds (0, 0.25, 0.5, 0.75, 1.0, in order) decide; `all` (the same
/// and the larger ones, in order) is described beside them.
pub fn threshold_lowers(paper: &[&Aggregate], all: &[&Aggregate]) -> Verdict {
    let fl: Vec<f64> = paper.iter().map(|a| a.final_loss.0).collect();
    let neg_co: Vec<f64> = paper.iter().map(|a| -a.total_corrections.0).collect();
    let (bl, bc) = (breaks_increase(&fl), breaks_increase(&neg_co));
    let holds = paper.len() >= 2 && bl.is_empty() && bc.is_empty();
    let th = |i: usize| paper[i].setting.threshold;
    let desc = |v: &[usize]| {
        v.iter()
            .map(|&i| format!("{} → {}", th(i), th(i + 1)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let list = |v: &[&Aggregate]| {
        v.iter()
            .map(|a| a.setting.threshold.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut text = format!(
        "Stairs-chairs, action feedback; the paper's thresholds {}: final loss {}; corrections {}.",
        list(paper),
        paper
            .iter()
            .map(|a| pm(a.final_loss))
            .collect::<Vec<_>>()
            .join(", "),
        paper
            .iter()
            .map(|a| pm1(a.total_corrections))
            .collect::<Vec<_>>()
            .join(", "),
    );
    if !bl.is_empty() {
        let inversions: Vec<String> = bl
            .iter()
            .map(|&i| {
                let d = fl[i] - fl[i + 1];
                let sd = paper[i].final_loss.1.max(paper[i + 1].final_loss.1);
                format!(
                    "{d:.3} at {} → {} ({} the larger standard deviation across trials, {sd:.3})",
                    th(i),
                    th(i + 1),
                    if d < sd {
                        "smaller than"
                    } else {
                        "not smaller than"
                    }
                )
            })
            .collect();
        let _ = write!(
            text,
            " The final loss does not rise with the threshold at {}: it falls by {}.",
            desc(&bl),
            inversions.join("; ")
        );
    }
    if !bc.is_empty() {
        let _ = write!(
            text,
            " The corrections do not fall with the threshold at {}.",
            desc(&bc)
        );
    }
    let extra: Vec<&&Aggregate> = all
        .iter()
        .filter(|a| {
            !paper
                .iter()
                .any(|p| p.setting.threshold == a.setting.threshold)
        })
        .collect();
    if !extra.is_empty() {
        let tx: Vec<f64> = all.iter().map(|a| a.setting.threshold as f64).collect();
        let rho_l = spearman(&tx, &all.iter().map(|a| a.final_loss.0).collect::<Vec<_>>());
        let rho_c = spearman(
            &tx,
            &all.iter()
                .map(|a| a.total_corrections.0)
                .collect::<Vec<_>>(),
        );
        let _ = write!(
            text,
            " Beyond the paper's range, thresholds {}: final loss {}; corrections {}. Over all {} \
             thresholds the Spearman rank correlation with the threshold is {rho_l:.2} for the \
             final loss and {rho_c:.2} for the corrections.",
            extra
                .iter()
                .map(|a| a.setting.threshold.to_string())
                .collect::<Vec<_>>()
                .join(", "),
            extra
                .iter()
                .map(|a| pm(a.final_loss))
                .collect::<Vec<_>>()
                .join(", "),
            extra
                .iter()
                .map(|a| pm1(a.total_corrections))
                .collect::<Vec<_>>()
                .join(", "),
            all.len()
        );
    }
    let _ = write!(
        text,
        " Where the cars got: {}.",
        all.iter()
            .map(|a| format!("threshold {}: {}", a.setting.threshold, task(a)))
            .collect::<Vec<_>>()
            .join("; ")
    );
    Verdict { holds, text }
}

/// Whether a setting's corrections flattened: fewer in its last tenth than in its first, or
/// none in its last tenth (claim 6's rule).
pub fn flattened(a: &Aggregate) -> bool {
    a.last_tenth_corrections.0 < a.first_tenth_corrections.0 || a.last_tenth_corrections.0 == 0.0
}

/// Claim 6 over every online setting; `tenth` is the number of steps in a tenth of a run.
pub fn corrections_flatten(online: &[&Aggregate], tenth: usize) -> Verdict {
    let bad: Vec<&&Aggregate> = online.iter().filter(|a| !flattened(a)).collect();
    let holds = !online.is_empty() && bad.is_empty();
    let n = online.len().max(1) as f64;
    let first: f64 = online
        .iter()
        .map(|a| a.first_tenth_corrections.0)
        .sum::<f64>()
        / n;
    let last: f64 = online
        .iter()
        .map(|a| a.last_tenth_corrections.0)
        .sum::<f64>()
        / n;
    let never: Vec<String> = online
        .iter()
        .filter(|a| a.total_corrections.0 == 0.0)
        .map(|a| format!("`{}`", a.setting.key()))
        .collect();
    let mut text = format!(
        "Corrections in the first tenth → last tenth, mean over the {} online settings: {first:.1} \
         → {last:.1}. A setting counts as flattened when it has fewer corrections in its last tenth \
         than in its first, or none in its last tenth (its count has stopped growing).",
        online.len()
    );
    if !never.is_empty() {
        let _ = write!(
            text,
            " {} of them never corrected at all ({}): the threshold is above every loss the \
             teacher perceives, so the count is flat from the start; the rule was \"fewer in the \
             last tenth\" before these settings existed, and would count them as failing.",
            never.len(),
            never.join(", ")
        );
    }
    if !bad.is_empty() {
        let _ = write!(
            text,
            " It fails in {} of {} settings: {}.",
            bad.len(),
            online.len(),
            bad.iter()
                .map(|a| {
                    let s = &a.setting;
                    let p = if s.noise > 0.0 {
                        // P(σ·N > threshold) for a standard normal N: the teacher's rate of
                        // corrections of an action it would not correct without noise.
                        let z = s.threshold as f64 / s.noise as f64;
                        format!(
                            "; a teacher with this σ corrects even a perfect action with \
                             probability {:.0}%, {:.0} corrections per tenth",
                            100.0 * upper_tail(z),
                            upper_tail(z) * tenth as f64
                        )
                    } else {
                        String::new()
                    };
                    format!(
                        "`{}` ({:.1} → {:.1}{p})",
                        s.key(),
                        a.first_tenth_corrections.0,
                        a.last_tenth_corrections.0
                    )
                })
                .collect::<Vec<_>>()
                .join("; ")
        );
        if bad.iter().any(|a| a.setting.noise > 0.0) {
            text.push_str(
                " A noisy teacher perceives a loss above its threshold by chance, so its \
                 corrections never stop.",
            );
        }
        if bad.iter().any(|a| a.setting.noise == 0.0) {
            text.push_str(
                " A noiseless teacher keeps correcting a learner that has not yet settled on a \
                 policy the teacher accepts (with threshold 0, every action other than its own).",
            );
        }
    }
    Verdict { holds, text }
}

/// The claims' table and sections of the report.
pub fn render(verdicts: &[Verdict]) -> String {
    let mut r = String::from("| # | claim | verdict |\n|---|---|---|\n");
    for (i, (c, v)) in CLAIMS.iter().zip(verdicts).enumerate() {
        let _ = writeln!(r, "| {} | {c} | {} |", i + 1, v.word());
    }
    let _ = writeln!(r);
    for (i, (c, v)) in CLAIMS.iter().zip(verdicts).enumerate() {
        let _ = writeln!(r, "### {}. {c}: {}\n\n{}\n", i + 1, v.word(), v.text);
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::Mode;
    use crate::reproduce::{Group, Setting};
    use crate::teacher::FeedbackKind;

    fn setting(
        group: Group,
        household: &'static str,
        mode: Mode,
        noise: f32,
        threshold: f32,
    ) -> Setting {
        Setting {
            group,
            household,
            mode,
            noise,
            threshold,
            draw_path: false,
        }
    }

    /// An aggregate of `mode` in `household` with the given first-tenth and final losses and
    /// corrections.
    fn agg(
        household: &'static str,
        mode: Mode,
        first: f64,
        last: f64,
        corrections: f64,
    ) -> Aggregate {
        let mut a = Aggregate::empty(setting(Group::Variety, household, mode, 0.0, 1.0), 10);
        a.first_loss = (first, 0.01);
        a.final_loss = (last, 0.01);
        a.total_corrections = (corrections, 1.0);
        a
    }

    const ACTION: Mode = Mode::Online(FeedbackKind::Action);
    const PREFERENCE: Mode = Mode::Online(FeedbackKind::Preference);
    const SEMANTIC: Mode = Mode::Online(FeedbackKind::Semantic);

    #[test]
    fn claim_1_holds_only_when_every_kind_lowers_its_loss() {
        let a = agg("doors", ACTION, 1.0, 0.1, 10.0);
        let p = agg("doors", PREFERENCE, 1.0, 0.5, 10.0);
        let s = agg("doors", SEMANTIC, 1.0, 0.9, 10.0);
        let v = feedback_lowers_loss(&[&a, &p, &s]);
        assert!(v.holds, "{}", v.text);
        assert!(
            v.text
                .contains("action: 1.000 ± 0.010 → 0.100 ± 0.010 (90% lower)"),
            "{}",
            v.text
        );
        assert!(v.text.contains("Where the cars got"), "{}", v.text);
        // The boundary: a final loss equal to the first is not lower.
        let flat = agg("doors", SEMANTIC, 1.0, 1.0, 10.0);
        let v = feedback_lowers_loss(&[&a, &p, &flat]);
        assert!(!v.holds);
        assert!(
            v.text
                .contains("semantic: 1.000 ± 0.010 → 1.000 ± 0.010 (not lower)"),
            "{}",
            v.text
        );
        let worse = agg("doors", PREFERENCE, 1.0, 1.2, 10.0);
        assert!(!feedback_lowers_loss(&[&a, &worse, &s]).holds);
        assert!(!feedback_lowers_loss(&[]).holds, "no numbers, no claim");
    }

    #[test]
    fn claim_2_flat_means_within_a_quarter_of_the_larger_loss() {
        let bc = |first, last| agg("doors", Mode::BehaviourCloning, first, last, 0.0);
        // 0.75 → 1.0: a difference of 0.25, exactly a quarter of the larger: flat (the
        // boundary), either way round.
        let (a, b) = (bc(0.75, 1.0), bc(1.0, 0.75));
        let v = bc_flat(&[&a, &b]);
        assert!(v.holds, "{}", v.text);
        assert!(
            v.text.contains("+25%") && v.text.contains("-25%"),
            "{}",
            v.text
        );
        // 0.74 → 1.0: more than a quarter: not flat, whatever the scale of the losses.
        for k in [1.0, 0.01] {
            let c = bc(0.74 * k, 1.0 * k);
            let v = bc_flat(&[&a, &c]);
            assert!(!v.holds, "scale {k}: {}", v.text);
            assert!(v.text.contains("not flat"), "{}", v.text);
        }
        // Small absolute differences count relative to the losses (the old rule's 0.05 floor is
        // gone): 0.006 → 0.015 is not flat.
        assert!(!bc_flat(&[&bc(0.006, 0.015)]).holds);
        assert!(bc_flat(&[&bc(0.0, 0.0)]).holds, "a zero loss stays flat");
    }

    #[test]
    fn claim_3_needs_action_strictly_fewest_everywhere() {
        let house = |h: &'static str, a: f64, p: f64, s: f64| {
            (
                h,
                vec![
                    agg(h, ACTION, 1.0, 0.1, a),
                    agg(h, PREFERENCE, 1.0, 0.1, p),
                    agg(h, SEMANTIC, 1.0, 0.1, s),
                ],
            )
        };
        let refs = |v: &[(&'static str, Vec<Aggregate>)]| -> Vec<(&'static str, Vec<Aggregate>)> {
            v.to_vec()
        };
        let run = |v: Vec<(&'static str, Vec<Aggregate>)>| {
            let owned = refs(&v);
            let borrowed: Vec<(&str, Vec<&Aggregate>)> = owned
                .iter()
                .map(|(h, a)| (*h, a.iter().collect()))
                .collect();
            action_fewest(&borrowed, 10)
        };
        let v = run(vec![
            house("doors", 40.0, 200.0, 100.0),
            house("stairs-right", 30.0, 60.0, 31.0),
        ]);
        assert!(v.holds, "{}", v.text);
        // The boundary: a tie is not "fewest".
        let v = run(vec![
            house("doors", 40.0, 200.0, 100.0),
            house("stairs-right", 30.0, 60.0, 30.0),
        ]);
        assert!(!v.holds);
        assert!(
            v.text.contains("stairs-right: action 30.0 ± 1.0"),
            "{}",
            v.text
        );
        assert!(v.text.contains("(action is not the fewest)"), "{}", v.text);
        assert!(v.text.contains("in stairs-right, semantic needed 30.0 corrections against action's 30.0 (difference 0.0, 0.0 standard errors"), "{}", v.text);
        let v = run(vec![house("doors", 40.0, 39.0, 100.0)]);
        assert!(
            !v.holds && v.text.contains("in doors, preference needed 39.0"),
            "{}",
            v.text
        );
    }

    fn curve(group: Group, noise: f32, threshold: f32, loss: f64, corrections: f64) -> Aggregate {
        let mut a = Aggregate::empty(setting(group, "doors", ACTION, noise, threshold), 10);
        a.final_loss = (loss, 0.02);
        a.total_corrections = (corrections, 3.0);
        a
    }

    #[test]
    fn claim_4_needs_both_to_rise_strictly() {
        let mk = |l: [f64; 4], c: [f64; 4]| -> Vec<Aggregate> {
            [0.0, 0.25, 0.5, 1.0]
                .iter()
                .enumerate()
                .map(|(i, &s)| curve(Group::Noise, s, 1.0, l[i], c[i]))
                .collect()
        };
        let rising = mk([0.1, 0.2, 0.3, 0.4], [10.0, 20.0, 30.0, 40.0]);
        let r: Vec<&Aggregate> = rising.iter().collect();
        let v = noise_raises(&r, &r);
        assert!(v.holds, "{}", v.text);
        assert!(
            v.text
                .contains("Spearman rank correlation with σ is 1.00 for the final loss and 1.00"),
            "{}",
            v.text
        );
        // The boundary: equal neighbours break the rise.
        let tie = mk([0.1, 0.2, 0.2, 0.4], [10.0, 20.0, 30.0, 40.0]);
        let t: Vec<&Aggregate> = tie.iter().collect();
        let v = noise_raises(&t, &t);
        assert!(!v.holds);
        assert!(
            v.text
                .contains("The final loss does not rise at σ 0.25 → 0.5."),
            "{}",
            v.text
        );
        let fewer = mk([0.1, 0.2, 0.3, 0.4], [10.0, 20.0, 30.0, 29.0]);
        let f: Vec<&Aggregate> = fewer.iter().collect();
        let v = noise_raises(&f, &f);
        assert!(
            !v.holds && v.text.contains("The corrections do not rise at σ 0.5 → 1."),
            "{}",
            v.text
        );
    }

    #[test]
    fn claim_5_is_decided_on_the_paper_s_thresholds() {
        let ths = [0.0, 0.25, 0.5, 0.75, 1.0];
        let mk = |l: [f64; 5], c: [f64; 5]| -> Vec<Aggregate> {
            ths.iter()
                .enumerate()
                .map(|(i, &t)| curve(Group::Thresholds, 0.0, t, l[i], c[i]))
                .collect()
        };
        let good = mk([0.1, 0.2, 0.3, 0.4, 0.5], [500.0, 200.0, 100.0, 60.0, 50.0]);
        let mut all = good.clone();
        // Beyond the paper's range the loss may do anything: it is described, not decided.
        all.push(curve(Group::Thresholds, 0.0, 2.0, 0.3, 45.0));
        let p: Vec<&Aggregate> = good.iter().collect();
        let a: Vec<&Aggregate> = all.iter().collect();
        let v = threshold_lowers(&p, &a);
        assert!(v.holds, "{}", v.text);
        assert!(
            v.text
                .contains("Beyond the paper's range, thresholds 2: final loss 0.300 ± 0.020"),
            "{}",
            v.text
        );
        // The boundary: equal corrections at two thresholds are not "more".
        let tie = mk(
            [0.1, 0.2, 0.3, 0.4, 0.5],
            [500.0, 200.0, 100.0, 100.0, 50.0],
        );
        let t: Vec<&Aggregate> = tie.iter().collect();
        let v = threshold_lowers(&t, &t);
        assert!(
            !v.holds
                && v.text
                    .contains("The corrections do not fall with the threshold at 0.5 → 0.75."),
            "{}",
            v.text
        );
        let dip = mk(
            [0.1, 0.05, 0.3, 0.4, 0.5],
            [500.0, 200.0, 100.0, 60.0, 50.0],
        );
        let d: Vec<&Aggregate> = dip.iter().collect();
        let v = threshold_lowers(&d, &d);
        assert!(!v.holds);
        assert!(v.text.contains("The final loss does not rise with the threshold at 0 → 0.25: it falls by 0.050 at 0 → 0.25 (not smaller than the larger standard deviation across trials, 0.020)"), "{}", v.text);
    }

    #[test]
    fn claim_6_needs_fewer_corrections_late_in_every_setting() {
        let mk = |noise: f32, first: f64, last: f64| {
            let mut a = curve(Group::Noise, noise, 1.0, 0.1, 10.0);
            a.first_tenth_corrections = (first, 1.0);
            a.last_tenth_corrections = (last, 1.0);
            a
        };
        let (a, b) = (mk(0.0, 40.0, 0.0), mk(0.5, 70.0, 69.0));
        let v = corrections_flatten(&[&a, &b], 500);
        assert!(v.holds, "{}", v.text);
        assert!(v.text.contains("55.0 → 34.5"), "{}", v.text);
        // None at all is flat; so is none late after some early; but one late after none early
        // is rising.
        let mut never = mk(0.0, 0.0, 0.0);
        never.total_corrections = (0.0, 0.0);
        let v = corrections_flatten(&[&a, &never], 500);
        assert!(v.holds, "{}", v.text);
        assert!(
            v.text
                .contains("1 of them never corrected at all (`noise-0`)"),
            "{}",
            v.text
        );
        let rising = mk(0.0, 0.0, 1.0);
        assert!(!corrections_flatten(&[&a, &rising], 500).holds);
        // The boundary: as many late as early (and some) is not flattening.
        let c = mk(2.0, 200.0, 200.0);
        let v = corrections_flatten(&[&a, &c], 500);
        assert!(!v.holds);
        assert!(v.text.contains("`noise-2` (200.0 → 200.0; a teacher with this σ corrects even a perfect action with probability 31%, 154 corrections per tenth)"), "{}", v.text);
    }

    #[test]
    fn the_table_marks_each_claim_by_its_own_verdict() {
        let v = |holds| Verdict {
            holds,
            text: "numbers".into(),
        };
        let verdicts = [v(true), v(false), v(true), v(false), v(false), v(true)];
        let r = render(&verdicts);
        for (i, c) in CLAIMS.iter().enumerate() {
            let word = if verdicts[i].holds {
                "**holds**"
            } else {
                "**does not hold**"
            };
            assert!(r.contains(&format!("| {} | {c} | {word} |", i + 1)), "{r}");
            assert!(r.contains(&format!("### {}. {c}: {word}", i + 1)), "{r}");
        }
    }
}
