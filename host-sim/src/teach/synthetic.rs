//! A synthetic teacher on a seeded stream of random rounds.
//!
//! Each round draws features for the 64 actions uniformly in `[-1, 1]^F` and forbids a random
//! fraction of the actions (as colliding trajectories would be). The teacher has hidden weights
//! `w*` (uniform in `[-1, 1]^F`, drawn from the seed); its latent loss of action `a` is
//! `L(a) = w*·(φ(a*) − φ(a))`. When `L(a_t)` exceeds the threshold it answers with the action it
//! wants, or, with probability `noise`, with a uniformly random allowed action.
//!
//! ```
//! use host_sim::teach::synthetic::{SyntheticConfig, run};
//! let report = run(&SyntheticConfig { steps: 2_000, ..SyntheticConfig::default() }).unwrap();
//! assert_eq!(report.latent_loss.len(), 2_000);
//! ```

use anyhow::{Context, Result, ensure};
use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, FEATURE_COUNT, FeatureTable, Learner, LearnerParams,
    OnlineLearner, Round, Weights, dot, policy,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// How a synthetic run is set up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SyntheticConfig {
    /// Number of rounds.
    pub steps: usize,
    /// Seed of the teacher's weights and of every draw.
    pub seed: u64,
    /// The teacher corrects when the latent loss exceeds this.
    pub threshold: f32,
    /// Probability that a correction names a random allowed action instead of the best one.
    pub noise: f64,
    /// Probability that an action is forbidden in a round.
    pub forbidden: f64,
    /// The learner.
    pub learner: LearnerParams,
}

impl Default for SyntheticConfig {
    fn default() -> Self {
        Self {
            steps: 5_000,
            seed: 0,
            threshold: 0.05,
            noise: 0.0,
            forbidden: 0.125,
            learner: LearnerParams::default(),
        }
    }
}

/// What a synthetic run measured, one entry per round.
#[derive(Clone, Debug, PartialEq)]
pub struct SyntheticReport {
    /// The teacher's hidden weights.
    pub teacher: Weights,
    /// The learner's weights at the end.
    pub weights: Weights,
    /// Latent loss of the learner's action.
    pub latent_loss: Vec<f32>,
    /// Mean latent loss of a uniformly random allowed action.
    pub random_loss: Vec<f32>,
    /// Whether the teacher corrected.
    pub corrected: Vec<bool>,
}

impl SyntheticReport {
    /// Number of corrections.
    pub fn corrections(&self) -> usize {
        self.corrected.iter().filter(|&&c| c).count()
    }
}

/// Runs the stream.
pub fn run(config: &SyntheticConfig) -> Result<SyntheticReport> {
    crate::checks::probability(config.noise).map_err(|m| anyhow::anyhow!("noise: {m}"))?;
    ensure!(
        (0.0..1.0).contains(&config.forbidden),
        "forbidden must be in [0, 1), got {}",
        config.forbidden
    );
    crate::checks::threshold(config.threshold.into())
        .map_err(|m| anyhow::anyhow!("threshold: {m}"))?;
    let params = config
        .learner
        .check()
        .map_err(anyhow::Error::msg)
        .context("learner parameters")?;
    let mut learner = Learner::new(params);
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let mut teacher: Weights = [0.0; FEATURE_COUNT];
    for w in &mut teacher {
        *w = rng.random_range(-1.0f32..1.0);
    }
    let mut report = SyntheticReport {
        teacher,
        weights: *learner.weights(),
        latent_loss: Vec::with_capacity(config.steps),
        random_loss: Vec::with_capacity(config.steps),
        corrected: Vec::with_capacity(config.steps),
    };
    let mut table = FeatureTable::ZERO;
    for _ in 0..config.steps {
        for row in table.rows_mut() {
            for x in row.iter_mut() {
                *x = rng.random_range(-1.0f32..1.0);
            }
        }
        let mut mask = ActionMask::ALL;
        for a in ActionIndex::all() {
            if rng.random::<f64>() < config.forbidden {
                mask.remove(a);
            }
        }
        if mask.is_empty() {
            mask = ActionMask::ALL;
        }
        let best = policy::select(&teacher, &table, mask).context("no allowed action")?;
        let best_score = dot(&teacher, &table[best]);
        let loss = |a: ActionIndex| best_score - dot(&teacher, &table[a]);
        let chosen = learner.select(&table, mask).context("no allowed action")?;
        let l = loss(chosen);
        report.latent_loss.push(l);
        report
            .random_loss
            .push(mask.iter().map(loss).sum::<f32>() / mask.count() as f32);
        let corrects = l > config.threshold;
        report.corrected.push(corrects);
        if corrects {
            let answer = if rng.random::<f64>() < config.noise {
                mask.iter()
                    .nth(rng.random_range(0..mask.count() as usize))
                    .context("empty mask")?
            } else {
                best
            };
            let round = Round::new(&table, mask, chosen).map_err(anyhow::Error::msg)?;
            learner
                .learn(&round, &ActionFeedback { action: answer })
                .map_err(anyhow::Error::msg)?;
        }
    }
    report.weights = *learner.weights();
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_run() {
        let c = SyntheticConfig {
            steps: 500,
            noise: 0.2,
            ..SyntheticConfig::default()
        };
        assert_eq!(run(&c).unwrap(), run(&c).unwrap());
        let other = run(&SyntheticConfig { seed: 1, ..c }).unwrap();
        assert_ne!(run(&c).unwrap().teacher, other.teacher);
    }

    #[test]
    fn the_learner_learns() {
        let r = run(&SyntheticConfig {
            steps: 3_000,
            ..SyntheticConfig::default()
        })
        .unwrap();
        let first: f32 = r.latent_loss[..300].iter().sum();
        let last: f32 = r.latent_loss[2_700..].iter().sum();
        assert!(last < 0.05 * first, "first {first}, last {last}");
    }

    #[test]
    fn bad_configs_are_refused() {
        assert!(
            run(&SyntheticConfig {
                noise: 1.5,
                ..SyntheticConfig::default()
            })
            .is_err()
        );
        assert!(
            run(&SyntheticConfig {
                threshold: f32::NAN,
                ..SyntheticConfig::default()
            })
            .is_err()
        );
        let bad = SyntheticConfig {
            learner: LearnerParams::paper().with_step(-1.0),
            ..SyntheticConfig::default()
        };
        assert!(run(&bad).is_err());
    }
}
