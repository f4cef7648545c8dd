//! The numbers a user gives, checked once: the same function checks a value whether it comes
//! from a flag of the command line (through [`flag`], before the command does anything), from a
//! scenario file or from a configuration built in code, and says what is wrong in the same words
//! (`must be in [0, 1000], got 1e30`). The caller names the value (`--threshold`,
//! `FILE: teacher.threshold: …`, `threshold: …`).
//!
//! Numbers are written as the shortest decimal that reads back as the same number (`-1`, `0.5`,
//! `NaN`), and in exponent form when that would spell out many zeros (`1e30`, `1e-9`).

use std::ops::RangeInclusive;

/// Largest correction threshold, noise σ, teacher weight or teacher scale (latent-loss units):
/// far above anything meaningful (the calibrated teachers' latent losses are of order 1-10),
/// small enough that nothing overflows.
pub const TEACHER_BOUND: f64 = 1.0e3;

/// Largest number of steps of one run.
pub const MAX_STEPS: u32 = 10_000_000;

/// `v` as a message writes it (see the module documentation).
pub fn number(v: f64) -> String {
    let a = v.abs();
    if a.is_finite() && a != 0.0 && !(1e-4..1e16).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

fn within(v: f64, lo: f64, hi: f64) -> Result<f64, String> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(format!("must be in [{lo}, {hi}], got {}", number(v)))
    }
}

/// The teacher's correction threshold on the perceived latent loss: in [0, 1000].
pub fn threshold(v: f64) -> Result<f64, String> {
    within(v, 0.0, TEACHER_BOUND)
}

/// The standard deviation σ of the teacher's noise on every latent loss it perceives: in
/// [0, 1000].
pub fn noise(v: f64) -> Result<f64, String> {
    within(v, 0.0, TEACHER_BOUND)
}

/// A probability (of a random answer): in [0, 1].
pub fn probability(v: f64) -> Result<f64, String> {
    within(v, 0.0, 1.0)
}

/// One weight of a teacher: within ±1000.
pub fn teacher_weight(v: f64) -> Result<f64, String> {
    within(v, -TEACHER_BOUND, TEACHER_BOUND)
}

/// A factor on the teacher's weights: in (0, 1000].
pub fn teacher_scale(v: f64) -> Result<f64, String> {
    if v.is_finite() && v > 0.0 && v <= TEACHER_BOUND {
        Ok(v)
    } else {
        Err(format!(
            "must be in (0, {TEACHER_BOUND}], got {}",
            number(v)
        ))
    }
}

/// A learner's step size: in (0, [`firmware_core::MAX_STEP`]], what the learner accepts.
pub fn step_size(v: f64) -> Result<f64, String> {
    let max = firmware_core::MAX_STEP as f64;
    if v.is_finite() && v > 0.0 && v <= max {
        Ok(v)
    } else {
        Err(format!("must be in (0, {max}], got {}", number(v)))
    }
}

/// A whole number in `range` (steps, trials, seeds, threads…).
pub fn count(v: i128, range: RangeInclusive<u32>) -> Result<u32, String> {
    if (*range.start() as i128..=*range.end() as i128).contains(&v) {
        Ok(v as u32)
    } else {
        Err(format!(
            "must be in {}..={}, got {v}",
            range.start(),
            range.end()
        ))
    }
}

/// The steps of one run: in 1..=[`MAX_STEPS`].
pub fn steps(v: i128) -> Result<u32, String> {
    count(v, 1..=MAX_STEPS)
}

/// For `map_err`: the check's words after the value's name (`steps: must be in …`).
pub fn named(name: &'static str) -> impl Fn(String) -> anyhow::Error {
    move |m| anyhow::anyhow!("{name}: {m}")
}

/// The parser of a flag whose number (`f64`) `check` checks: text that is not a number is
/// refused as such, a number `check` refuses with its words. For clap's `value_parser`.
pub fn flag(
    check: fn(f64) -> Result<f64, String>,
) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    move |text: &str| {
        let v: f64 = text
            .trim()
            .parse()
            .map_err(|_| "not a number".to_string())?;
        check(v)
    }
}

/// The parser of a flag with a whole number in `range`: a number outside it is refused with the
/// range, not with the limits of the type that holds it.
pub fn count_flag(
    range: RangeInclusive<u32>,
) -> impl Fn(&str) -> Result<u32, String> + Clone + Send + Sync + 'static {
    move |text: &str| {
        let v: i128 = text
            .trim()
            .parse()
            .map_err(|_| "not a whole number".to_string())?;
        count(v, range.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_wording_for_every_value() {
        assert_eq!(threshold(1.0), Ok(1.0));
        assert_eq!(
            threshold(1e30),
            Err("must be in [0, 1000], got 1e30".to_string())
        );
        assert_eq!(noise(-1.0), Err("must be in [0, 1000], got -1".into()));
        assert_eq!(noise(f64::NAN), Err("must be in [0, 1000], got NaN".into()));
        assert_eq!(probability(1.5), Err("must be in [0, 1], got 1.5".into()));
        assert_eq!(teacher_weight(-1000.0), Ok(-1000.0));
        assert_eq!(
            step_size(f64::NAN),
            Err("must be in (0, 1000], got NaN".into())
        );
        assert_eq!(step_size(0.0), Err("must be in (0, 1000], got 0".into()));
        assert_eq!(number(1e-9), "1e-9");
        assert_eq!(number(0.25), "0.25");
        assert_eq!(number(f64::INFINITY), "inf");
        assert_eq!(teacher_scale(0.25), Ok(0.25));
        assert_eq!(
            steps(99_999_999_999),
            Err("must be in 1..=10000000, got 99999999999".into())
        );
        assert_eq!(steps(0), Err("must be in 1..=10000000, got 0".into()));
        assert_eq!(steps(5000), Ok(5000));
    }

    #[test]
    fn a_flag_s_text_is_read_then_checked() {
        let t = flag(threshold);
        assert_eq!(t("0.5"), Ok(0.5));
        assert_eq!(t("nan"), Err("must be in [0, 1000], got NaN".into()));
        assert_eq!(t("-1"), Err("must be in [0, 1000], got -1".into()));
        assert_eq!(t("lots"), Err("not a number".into()));
        let s = count_flag(1..=MAX_STEPS);
        assert_eq!(s("2000"), Ok(2000));
        assert_eq!(s("-5"), Err("must be in 1..=10000000, got -5".into()));
        assert_eq!(s("many"), Err("not a whole number".into()));
        assert_eq!(s("1.5"), Err("not a whole number".into()));
    }
}
