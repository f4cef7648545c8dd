//! The calibration as Markdown (`host-sim calibrate`, the report's calibration section).

use std::fmt::Write as _;

use super::{Calibration, THRESHOLDS, median, quantile, share_above};

fn fmt(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.3}")
    } else {
        "∞".into()
    }
}

/// The calibration as Markdown: the procedure's figures, the rule's outcome and the statistics
/// at the chosen scales.
pub fn markdown(c: &Calibration) -> String {
    let mut r = String::new();
    let _ = writeln!(
        r,
        "Along each teacher's own lap (ℓ in the units of its ratios, path weight −1; the latent \
         loss at scale s is s·ℓ):\n"
    );
    let _ = writeln!(
        r,
        "| household | lap (ticks) | passages | Σℓ of the path follower | median ℓ of a passage | largest ℓ |\n|---|---|---|---|---|---|"
    );
    for l in &c.laps {
        let max = l.passages.iter().copied().fold(0.0, f64::max);
        let _ = writeln!(
            r,
            "| {} | {} | {} | {} | {} | {} |",
            l.household,
            l.ticks,
            l.passages.len(),
            fmt(l.follower.iter().sum()),
            fmt(median(&l.passages)),
            fmt(max)
        );
    }
    let _ = writeln!(
        r,
        "\n| target | household | condition | from | holds for s in |\n|---|---|---|---|---|"
    );
    for t in &c.targets {
        let from = match t.target {
            "T1" | "T3" => format!("S ≥ 0.75 exactly while τ/s < {} (ℓ)", fmt(t.pivot)),
            "T2" => format!("S ≤ 0.5 exactly once τ/s ≥ {} (ℓ)", fmt(t.pivot)),
            _ => format!("median passage ℓ = {}", fmt(t.pivot)),
        };
        let _ = writeln!(
            r,
            "| {} | {} | {} | {from} | {} |",
            t.target,
            t.household,
            t.condition,
            t.interval.describe()
        );
    }
    let _ = writeln!(r);
    for n in &c.notes {
        let _ = writeln!(r, "{n}\n");
    }
    let _ = writeln!(
        r,
        "| household | scale s | weights (obstacles, door, stairs, chair, path, right) | S at τ = 0.25 / 0.5 / 1 / 2 | m |\n|---|---|---|---|---|"
    );
    for (l, (_, s)) in c.laps.iter().zip(&c.scales) {
        let w: Vec<String> = l
            .ratios
            .iter()
            .map(|r| format!("{}", two_decimals(*r as f64 * s)))
            .collect();
        let shares: Vec<String> = [0.25, 0.5, 1.0, 2.0]
            .iter()
            .map(|tau| format!("{:.2}", share_above(&l.follower, tau / s)))
            .collect();
        let _ = writeln!(
            r,
            "| {} | {} | [{}] | {} | {:.3} |",
            l.household,
            two_digits(*s),
            w.join(", "),
            shares.join(" / "),
            s * median(&l.passages)
        );
    }
    let _ = writeln!(
        r,
        "\nAt these scales, the latent loss of the allowed actions other than the teacher's, pooled \
         over the lap (quantiles), and how often the initial policy (zero weights: straight ahead, \
         else the lowest allowed index) has a latent loss above each threshold along the lap:\n"
    );
    let head: Vec<String> = THRESHOLDS.iter().map(|t| format!("> {t}")).collect();
    let _ = writeln!(
        r,
        "| household | others: 10% / 25% / 50% / 75% / 90% / 99% | initial policy: {} |\n|---|---|---|",
        head.join(" / ")
    );
    for (l, (_, s)) in c.laps.iter().zip(&c.scales) {
        let mut o: Vec<f64> = l.others.iter().map(|x| x * s).collect();
        o.sort_by(f64::total_cmp);
        let q: Vec<String> = [0.1, 0.25, 0.5, 0.75, 0.9, 0.99]
            .iter()
            .map(|&p| format!("{:.2}", quantile(&o, p)))
            .collect();
        let n = l.initial.len().max(1) as f64;
        let f: Vec<String> = THRESHOLDS
            .iter()
            .map(|&t| {
                format!(
                    "{:.0}%",
                    100.0 * l.initial.iter().filter(|&&x| x * s > t).count() as f64 / n
                )
            })
            .collect();
        let _ = writeln!(
            r,
            "| {} | {} | {} |",
            l.household,
            q.join(" / "),
            f.join(" / ")
        );
    }
    r
}

/// A scale with its two significant digits: 17, 2.6, 3.0, 0.45.
pub fn two_digits(s: f64) -> String {
    if s >= 10.0 {
        format!("{s:.0}")
    } else if s >= 1.0 {
        format!("{s:.1}")
    } else {
        format!("{s:.2}")
    }
}

/// `x` printed with at most two decimals (the weights are products of two-digit numbers).
fn two_decimals(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}
