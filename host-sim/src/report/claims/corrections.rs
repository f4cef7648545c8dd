//! Claim 6: the corrections flatten out, over every online setting.

use std::fmt::Write as _;

use super::Verdict;
use crate::report::aggregate::Aggregate;
use crate::report::statistics::upper_tail;

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
