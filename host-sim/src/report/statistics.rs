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

/// `P(N > z)` for a standard normal `N` (Abramowitz–Stegun 7.1.26 for erfc; error < 1.5e-7).
pub fn upper_tail(z: f64) -> f64 {
    let x = z / std::f64::consts::SQRT_2;
    let sign = x < 0.0;
    let x = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let y = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let erfc = y * (-x * x).exp();
    let erfc = if sign { 2.0 - erfc } else { erfc };
    erfc / 2.0
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
        assert!((upper_tail(0.0) - 0.5).abs() < 1e-6);
        assert!((upper_tail(1.0) - 0.158_655).abs() < 1e-5);
        assert!((upper_tail(-1.0) - 0.841_345).abs() < 1e-5);
        assert_eq!(tenth(5000), 500);
        assert_eq!(tenth(3), 1);
    }
}
