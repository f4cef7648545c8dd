//! Claim 4: the noise experiment.

use std::fmt::Write as _;

use super::{Verdict, breaks_increase, join, pm, pm1, where_they_got};
use crate::report::aggregate::Aggregate;
use crate::report::statistics::spearman;

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
    let mut text = format!(
        "Doors, action feedback, threshold 1.0; σ = {}: final loss {}; corrections {}. Over the \
         whole sweep (σ 0 to 2 in steps of 0.125) the Spearman rank correlation with σ is \
         {rho_l:.2} for the final loss and {rho_c:.2} for the corrections.",
        join(curves, ", ", |a| a.setting.noise.to_string()),
        join(curves, ", ", |a| pm(a.final_loss)),
        join(curves, ", ", |a| pm1(a.total_corrections)),
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
    text.push_str(&where_they_got(curves, |a| {
        format!("σ {}", a.setting.noise)
    }));
    Verdict { holds, text }
}
