//! Claim 5: the threshold experiment.

use std::fmt::Write as _;

use super::{Verdict, breaks_increase, join, pm, pm1, where_they_got};
use crate::report::aggregate::Aggregate;
use crate::report::statistics::spearman;

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
    let thresholds = |v: &[&Aggregate]| join(v, ", ", |a| a.setting.threshold.to_string());
    let mut text = format!(
        "Stairs-chairs, action feedback; the paper's thresholds {}: final loss {}; corrections {}.",
        thresholds(paper),
        join(paper, ", ", |a| pm(a.final_loss)),
        join(paper, ", ", |a| pm1(a.total_corrections)),
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
    let extra: Vec<&Aggregate> = all
        .iter()
        .copied()
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
            thresholds(&extra),
            join(&extra, ", ", |a| pm(a.final_loss)),
            join(&extra, ", ", |a| pm1(a.total_corrections)),
            all.len()
        );
    }
    text.push_str(&where_they_got(all, |a| {
        format!("threshold {}", a.setting.threshold)
    }));
    Verdict { holds, text }
}
