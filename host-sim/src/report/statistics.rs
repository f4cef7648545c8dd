//! The statistics of the report: means and sample standard deviations, Spearman's rank
//! correlation, the standard normal's upper tail, and the smoothing of the charts' curves.

/// Latent-loss curves are smoothed by a centred moving mean over this fraction of the run.
pub const SMOOTHING: f64 = 0.05;

/// Mean and sample standard deviation (0 for one value).
pub fn mean_std(xs: &[f64]) -> (f64, f64) {
    let n = xs.len();
    if n == 0 {
        return (0.0, 0.0);
    }
    let m = xs.iter().sum::<f64>() / n as f64;
    if n == 1 {
        return (m, 0.0);
    }
    let v = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1) as f64;
    (m, v.sqrt())
}

/// Steps in a tenth of `steps` (at least one).
pub fn tenth(steps: usize) -> usize {
    ((steps as f64 / 10.0).round() as usize).max(1)
}

/// Steps in the smoothing window of a run of `steps` steps ([`SMOOTHING`] of it, at least 1).
pub fn smoothing_window(steps: usize) -> usize {
    ((steps as f64 * SMOOTHING).round() as usize).max(1)
}

/// A per-step curve for a chart: at most 100 points, each the centred moving mean over
/// `window` steps (shorter at the ends) of the mean and of the standard deviation.
pub fn smoothed(v: &[(f64, f64)], window: usize) -> Vec<(f64, f64, f64)> {
    let n = v.len();
    if n == 0 {
        return Vec::new();
    }
    let mut sm = vec![0.0; n + 1];
    let mut ss = vec![0.0; n + 1];
    for (i, (m, s)) in v.iter().enumerate() {
        sm[i + 1] = sm[i] + m;
        ss[i + 1] = ss[i] + s;
    }
    let b = n.min(100);
    let half = window / 2;
    (0..b)
        .map(|k| {
            let c = (2 * k + 1) * n / (2 * b);
            let (lo, hi) = (c.saturating_sub(half), (c + window - half).min(n));
            let len = (hi - lo) as f64;
            (c as f64, (sm[hi] - sm[lo]) / len, (ss[hi] - ss[lo]) / len)
        })
        .collect()
}

/// A cumulative per-step curve for a chart: its value at the end of each of at most 100 blocks.
pub fn sampled(v: &[(f64, f64)]) -> Vec<(f64, f64, f64)> {
    let n = v.len();
    let b = n.min(100);
    (0..b)
        .map(|k| {
            let hi = ((k + 1) * n / b).max(1);
            let (m, s) = v[hi - 1];
            (hi as f64, m, s)
        })
        .collect()
}

/// Spearman rank correlation (average ranks for ties; 0 when either side is constant).
pub fn spearman(x: &[f64], y: &[f64]) -> f64 {
    fn ranks(v: &[f64]) -> Vec<f64> {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
        let mut r = vec![0.0; v.len()];
        let mut i = 0;
        while i < idx.len() {
            let mut j = i;
            while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
                j += 1;
            }
            for k in i..=j {
                r[idx[k]] = (i + j) as f64 / 2.0 + 1.0;
            }
            i = j + 1;
        }
        r
    }
    let (rx, ry) = (ranks(x), ranks(y));
    let (mx, _) = mean_std(&rx);
    let (my, _) = mean_std(&ry);
    let cov: f64 = rx.iter().zip(&ry).map(|(a, b)| (a - mx) * (b - my)).sum();
    let vx: f64 = rx.iter().map(|a| (a - mx) * (a - mx)).sum();
    let vy: f64 = ry.iter().map(|b| (b - my) * (b - my)).sum();
    if vx == 0.0 || vy == 0.0 {
        0.0
    } else {
        cov / (vx * vy).sqrt()
    }
}

/// `P(N > z)` for a standard normal `N`: `erfc(z / √2) / 2` (`libm::erfc`).
pub fn upper_tail(z: f64) -> f64 {
    libm::erfc(z / std::f64::consts::SQRT_2) / 2.0
}

/// Resamples of [`bootstrap_mean`].
pub const BOOTSTRAP_RESAMPLES: usize = 10_000;

/// A 95% percentile-bootstrap interval of the mean of `xs`: the 2.5th and 97.5th percentiles of
/// the means of [`BOOTSTRAP_RESAMPLES`] resamples of `xs` with replacement, drawn from a ChaCha8
/// generator seeded with `seed` (so the interval is the same bytes on every machine). Percentile
/// `p` of the sorted means `m` is `m[⌊p·(B − 1)⌉]`. `None` for no values; a single value's
/// interval is the value itself.
pub fn bootstrap_mean(xs: &[f64], seed: u64) -> Option<(f64, f64)> {
    use rand::{RngExt, SeedableRng};
    if xs.is_empty() {
        return None;
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let n = xs.len();
    let mut means: Vec<f64> = (0..BOOTSTRAP_RESAMPLES)
        .map(|_| (0..n).map(|_| xs[rng.random_range(0..n)]).sum::<f64>() / n as f64)
        .collect();
    means.sort_by(f64::total_cmp);
    let at = |p: f64| means[(p * (BOOTSTRAP_RESAMPLES - 1) as f64).round() as usize];
    Some((at(0.025), at(0.975)))
}

/// The 95% Wilson score interval of a proportion: `k` successes in `n` trials (`z` = 1.96).
/// Unlike `p̂ ± z·√(p̂(1 − p̂)/n)` it keeps its coverage near 0 and 1 and never leaves [0, 1].
pub fn wilson(k: usize, n: usize) -> (f64, f64) {
    if n == 0 {
        return (0.0, 1.0);
    }
    let z = 1.96f64;
    let (n, p) = (n as f64, k as f64 / n as f64);
    let centre = p + z * z / (2.0 * n);
    let half = z * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt();
    let d = 1.0 + z * z / n;
    (
        ((centre - half) / d).max(0.0),
        ((centre + half) / d).min(1.0),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chart_s_latent_loss_is_a_centred_moving_mean() {
        // 200 steps of loss i (std 1): 100 points, at the centre of each block of 2 steps; a
        // window of 10 around step c averages steps c − 5 … c + 4, a mean of c − 0.5.
        let v: Vec<(f64, f64)> = (0..200).map(|i| (i as f64, 1.0)).collect();
        let p = smoothed(&v, 10);
        assert_eq!(p.len(), 100);
        assert_eq!(p[50], (101.0, 100.5, 1.0));
        // At the ends the window is cut: step 1 averages steps 0 … 5.
        assert_eq!(p[0], (1.0, 2.5, 1.0));
        assert_eq!(smoothing_window(5_000), 250);
        assert_eq!(smoothing_window(10), 1);
    }

    #[test]
    fn intervals() {
        // Wilson: 0 of 10 is [0, 0.278], 10 of 10 [0.722, 1], 5 of 10 [0.237, 0.763].
        let r = |x: f64| (x * 1000.0).round() / 1000.0;
        let w = |k, n| {
            let (a, b) = wilson(k, n);
            (r(a), r(b))
        };
        assert_eq!(w(0, 10), (0.0, 0.278));
        assert_eq!(w(10, 10), (0.722, 1.0));
        assert_eq!(w(5, 10), (0.237, 0.763));
        assert_eq!(wilson(0, 0), (0.0, 1.0));
        // The bootstrap is seeded, brackets the mean, and is a point for one value or for
        // equal values.
        let xs: Vec<f64> = (0..40)
            .map(|i| libm::sin(i as f64 * 1.7) + i as f64 * 0.01)
            .collect();
        let (lo, hi) = bootstrap_mean(&xs, 1).unwrap();
        let (m, s) = mean_std(&xs);
        assert_eq!(bootstrap_mean(&xs, 1), Some((lo, hi)));
        assert_ne!(bootstrap_mean(&xs, 2), Some((lo, hi)));
        assert!(lo < m && m < hi, "{lo} {m} {hi}");
        // About the normal interval's half-width, 1.96·s/√n.
        let half = 1.96 * s / (xs.len() as f64).sqrt();
        assert!(
            ((hi - lo) / 2.0 - half).abs() < 0.15 * half,
            "{lo} {hi} {half}"
        );
        assert_eq!(bootstrap_mean(&[3.0], 1), Some((3.0, 3.0)));
        assert_eq!(bootstrap_mean(&[2.0; 5], 1), Some((2.0, 2.0)));
        assert_eq!(bootstrap_mean(&[], 1), None);
    }

    #[test]
    fn statistics() {
        assert_eq!(mean_std(&[1.0, 3.0]), (2.0, std::f64::consts::SQRT_2));
        assert_eq!(mean_std(&[4.0]), (4.0, 0.0));
        assert!((spearman(&[1.0, 2.0, 3.0], &[10.0, 20.0, 30.0]) - 1.0).abs() < 1e-12);
        assert!((spearman(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        // With ties: y = (1, 1, 2, 3) has ranks (1.5, 1.5, 3, 4); x ranks (1, 2, 3, 4). Both
        // mean 2.5; deviations x (−1.5, −0.5, 0.5, 1.5), y (−1, −1, 0.5, 1.5): covariance sum
        // 1.5 + 0.5 + 0.25 + 2.25 = 4.5, x's sum of squares 5, y's 4.5: ρ = 4.5 / √22.5 = √0.9.
        let rho = spearman(&[1.0, 2.0, 3.0, 4.0], &[1.0, 1.0, 2.0, 3.0]);
        assert!((rho - 0.9f64.sqrt()).abs() < 1e-12, "{rho}");
        // x = (1, 2, 3, 4), y = (2, 1, 4, 3): d = (−1, 1, −1, 1), ρ = 1 − 6·4 / (4·15) = 0.6.
        assert!((spearman(&[1.0, 2.0, 3.0, 4.0], &[2.0, 1.0, 4.0, 3.0]) - 0.6).abs() < 1e-12);
        assert_eq!(spearman(&[1.0, 2.0], &[5.0, 5.0]), 0.0, "a constant side");
        assert_eq!(
            mean_std(&[2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]),
            (5.0, (32.0f64 / 7.0).sqrt())
        );
        // libm's erfc, exact to the last digits of the tables: Φ(−1) = 0.158 655 253 931 457 1.
        assert_eq!(upper_tail(0.0), 0.5);
        assert!((upper_tail(1.0) - 0.158_655_253_931_457_1).abs() < 1e-15);
        assert!((upper_tail(-1.0) - 0.841_344_746_068_542_9).abs() < 1e-15);
        assert!((upper_tail(3.0) - 0.001_349_898_031_630_094_6).abs() < 1e-17);
        assert_eq!(tenth(5000), 500);
        assert_eq!(tenth(3), 1);
    }
}
