//! Learning on a seeded synthetic realizable stream (DESIGN section 4, issue 2).
//!
//! The stream: every round draws fresh features for 64 actions, uniform in [-1, 1]^6, with a
//! random eighth of the actions forbidden (as colliding trajectories would be); the hidden teacher
//! weights are uniform in [-1, 1]^6, drawn once per seed. The teacher's latent loss of action `a`
//! is `L(a) = w*·(φ(a*) − φ(a))`; it corrects, with the action it wants, whenever `L(a_t)` exceeds
//! a threshold of 0.05 (about 3% of a random action's mean loss of ~1.6). The noisy teacher
//! replaces 20% of its answers by a uniformly random allowed action.
//!
//! Measured (T = 20 000; `cargo test -p firmware-core --release --test integration learning::
//! -- --nocapture` prints the table): every learner's regret fits a log-log slope of 0.12–0.33 on the clean
//! stream (seeds 0–1); with the noisy teacher (seeds 0–3) plain OGD's last-1000-round loss is
//! 0.7–5.7% of a random policy's (2.98%, 1.22%, 5.70%, 0.73%) and the averaged OGD default's at
//! most 0.011%. [`the_quoted_noise_figures_are_the_measured_ones`] re-measures the last two and
//! checks that this file, the README, `lib.rs` and `learner/mod.rs` quote them.

use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, FEATURE_COUNT, FeatureTable, Learner, LearnerKind,
    LearnerParams, OnlineLearner, Round, Weights, dot, policy,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const T: usize = 20_000;
const THRESHOLD: f32 = 0.05;
const TAIL: usize = 1_000;

struct Run {
    /// Cumulative latent regret after each round (`L(a*) = 0`, so regret = Σ L(a_t)).
    regret: Vec<f64>,
    /// Mean latent loss of the learner over the last `TAIL` rounds.
    tail_loss: f64,
    /// Mean latent loss of a uniformly random allowed action over the same rounds.
    tail_random: f64,
    corrections: usize,
}

fn run(params: LearnerParams, noise: f64, seed: u64) -> Run {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut w_star: Weights = [0.0; FEATURE_COUNT];
    for x in &mut w_star {
        *x = rng.random_range(-1.0f32..1.0);
    }
    let mut learner = Learner::new(params.check().unwrap());
    let mut out = Run {
        regret: Vec::with_capacity(T),
        tail_loss: 0.0,
        tail_random: 0.0,
        corrections: 0,
    };
    let mut cumulative = 0.0f64;
    let mut table = FeatureTable::ZERO;
    for t in 0..T {
        for row in table.rows_mut() {
            for x in row.iter_mut() {
                *x = rng.random_range(-1.0f32..1.0);
            }
        }
        let mut mask = ActionMask::ALL;
        for a in ActionIndex::all() {
            if rng.random_range(0..8) == 0 {
                mask.remove(a);
            }
        }
        if mask.is_empty() {
            mask = ActionMask::ALL;
        }
        let best = policy::select(&w_star, &table, mask).unwrap();
        let best_score = dot(&w_star, &table[best]);
        let loss = |a: ActionIndex| best_score - dot(&w_star, &table[a]);

        let chosen = learner.select(&table, mask).unwrap();
        let l = loss(chosen);
        cumulative += l as f64;
        out.regret.push(cumulative);
        if t >= T - TAIL {
            out.tail_loss += l as f64 / TAIL as f64;
            let mean_random: f64 =
                mask.iter().map(|a| loss(a) as f64).sum::<f64>() / mask.count() as f64;
            out.tail_random += mean_random / TAIL as f64;
        }
        if l > THRESHOLD {
            out.corrections += 1;
            let answer = if rng.random::<f64>() < noise {
                mask.iter()
                    .nth(rng.random_range(0..mask.count() as usize))
                    .unwrap()
            } else {
                best
            };
            let round = Round::new(&table, mask, chosen).unwrap();
            learner
                .learn(&round, &ActionFeedback { action: answer })
                .unwrap();
        }
    }
    out
}

/// Least-squares slope of log R(t) against log t at 21 log-spaced t from 100 to T.
fn loglog_slope(regret: &[f64]) -> f64 {
    let pts: Vec<(f64, f64)> = (0..=20)
        .map(|k| {
            let t = (100.0 * (regret.len() as f64 / 100.0).powf(k as f64 / 20.0)).round() as usize;
            ((t as f64).ln(), regret[t - 1].max(1e-9).ln())
        })
        .collect();
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let num: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let den: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    num / den
}

#[test]
fn slope_fit_is_right_on_known_curves() {
    let sqrt: Vec<f64> = (1..=T).map(|t| (t as f64).sqrt()).collect();
    assert!((loglog_slope(&sqrt) - 0.5).abs() < 1e-9);
    let linear: Vec<f64> = (1..=T).map(|t| 3.0 * t as f64).collect();
    assert!((loglog_slope(&linear) - 1.0).abs() < 1e-9);
}

#[test]
fn regret_grows_sublinearly_for_every_learner() {
    for kind in LearnerKind::ALL {
        for seed in 0..2 {
            let r = run(LearnerParams::new(kind), 0.0, seed);
            let slope = loglog_slope(&r.regret);
            println!(
                "clean  {:>13} seed {seed}: slope {slope:.3}, regret {:.1}, corrections {}, tail {:.5} (random {:.3})",
                kind.name(),
                r.regret[T - 1],
                r.corrections,
                r.tail_loss,
                r.tail_random
            );
            assert!(slope < 0.6, "{kind:?} seed {seed}: log-log slope {slope}");
        }
    }
}

#[test]
fn default_learner_survives_a_noisy_teacher() {
    let default = LearnerParams::default();
    assert_eq!(default.kind, LearnerKind::AveragedOgd);
    for seed in 0..4 {
        let r = run(default, 0.2, seed);
        let ratio = r.tail_loss / r.tail_random;
        println!(
            "noisy  {:>13} seed {seed}: tail {:.5} = {:.3}% of random, corrections {}",
            default.kind.name(),
            r.tail_loss,
            100.0 * ratio,
            r.corrections
        );
        assert!(
            ratio < 0.02,
            "seed {seed}: last-{TAIL} loss is {:.2}% of random",
            100.0 * ratio
        );
    }
}

/// Not a pass/fail claim about plain OGD, a record of why it is not the default: printed with
/// `--nocapture`. It asserts only that the noisy stream is hard enough to matter (plain OGD
/// does measurably worse than the default on it).
#[test]
fn plain_ogd_is_worse_under_noise() {
    let mut plain = 0.0;
    let mut averaged = 0.0;
    for seed in 0..4 {
        let p = run(LearnerParams::paper(), 0.2, seed);
        let a = run(LearnerParams::default(), 0.2, seed);
        println!(
            "noisy seed {seed}: ogd {:.3}% vs averaged {:.3}% of random; corrections {} vs {}",
            100.0 * p.tail_loss / p.tail_random,
            100.0 * a.tail_loss / a.tail_random,
            p.corrections,
            a.corrections
        );
        plain += p.tail_loss;
        averaged += a.tail_loss;
    }
    assert!(plain > 5.0 * averaged, "ogd {plain} vs averaged {averaged}");
}

/// The noisy-teacher figures the documentation quotes: plain OGD's last-1000-round loss as a
/// range over seeds 0–3 ("0.7–5.7%", one decimal) and averaged OGD's largest ("0.011%", three
/// decimals), re-measured and looked for in every file that quotes them, so a change of the
/// learner that moves them fails here until the text is updated.
#[test]
fn the_quoted_noise_figures_are_the_measured_ones() {
    let (mut lo, mut hi, mut averaged) = (f64::INFINITY, 0.0f64, 0.0f64);
    for seed in 0..4 {
        let p = run(LearnerParams::paper(), 0.2, seed);
        let a = run(LearnerParams::default(), 0.2, seed);
        let pct = |r: &Run| 100.0 * r.tail_loss / r.tail_random;
        lo = lo.min(pct(&p));
        hi = hi.max(pct(&p));
        averaged = averaged.max(pct(&a));
    }
    let range = format!("{lo:.1}–{hi:.1}%");
    let top = format!("{averaged:.3}%");
    println!("plain OGD {range}, averaged OGD at most {top}");
    let root = env!("CARGO_MANIFEST_DIR");
    for file in [
        "../README.md",
        "src/lib.rs",
        "src/learner/mod.rs",
        "tests/integration/learning.rs",
    ] {
        let text = std::fs::read_to_string(format!("{root}/{file}")).unwrap();
        assert!(
            text.contains(&range) && text.contains(&top),
            "{file} should quote {range} (plain OGD) and {top} (averaged OGD)"
        );
    }
}
