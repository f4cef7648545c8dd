//! `host-sim demo`: the learner against a synthetic teacher, no world.

use anyhow::Result;
use firmware_core::LearnerKind;
use host_sim::teach::synthetic::{self, SyntheticConfig};

use host_sim::checks;

use super::LearnerArgs;

#[derive(clap::Args, Debug)]
pub(crate) struct DemoArgs {
    /// Number of rounds, 1 to 10 000 000.
    #[arg(long, default_value_t = 5_000, allow_negative_numbers = true,
          value_parser = checks::count_flag(1..=checks::MAX_STEPS))]
    steps: u32,
    /// Seed of the teacher and of every random draw; the same seed gives the same run.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The teacher corrects when the latent loss of the learner's action exceeds this, 0 to
    /// 1000.
    #[arg(long, default_value_t = 0.05, allow_negative_numbers = true,
          value_parser = checks::flag(checks::threshold))]
    threshold: f64,
    /// Probability that a correction names a random action instead of the teacher's best, 0 to
    /// 1 (`run --random-answers`).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true,
          value_parser = checks::flag(checks::probability))]
    noise: f64,
    #[command(flatten)]
    learner: LearnerArgs,
    /// Number of lines of the printed curve (rows cover geometrically growing spans of
    /// rounds), 1 to 1000.
    #[arg(long, default_value_t = 16, allow_negative_numbers = true,
          value_parser = checks::count_flag(1..=1000))]
    rows: u32,
}

pub(crate) fn demo(args: &DemoArgs) -> Result<()> {
    let (steps, rows) = (args.steps as usize, args.rows as usize);
    let learner = args.learner.params(|| LearnerKind::AveragedOgd);
    let config = SyntheticConfig {
        steps,
        seed: args.seed,
        threshold: args.threshold as f32,
        noise: args.noise,
        learner,
        ..SyntheticConfig::default()
    };
    outln!(
        "synthetic teacher: {} rounds, seed {}, threshold {}, {:.0}% random answers, learner {}",
        config.steps,
        config.seed,
        config.threshold,
        100.0 * config.noise,
        learner.kind.name()
    )?;
    let report = synthetic::run(&config)?;
    // Row boundaries spaced geometrically, so the fast early learning gets rows of its own.
    let mut bounds = vec![0usize];
    for k in 1..=rows {
        let b = ((steps as f64).powf(k as f64 / rows as f64)).round() as usize;
        if b > *bounds.last().unwrap_or(&0) {
            bounds.push(b.min(steps));
        }
    }
    let random_mean = report.random_loss.iter().map(|&x| x as f64).sum::<f64>() / steps as f64;
    outln!(
        "{:>13}  {:>11}  {:>11}  latent loss (40 marks = a random policy's)",
        "rounds",
        "mean loss",
        "corrections"
    )?;
    let mut corrections = 0;
    for w in bounds.windows(2) {
        let (start, end) = (w[0], w[1]);
        let chunk = &report.latent_loss[start..end];
        let mean = chunk.iter().map(|&x| x as f64).sum::<f64>() / chunk.len() as f64;
        corrections += report.corrected[start..end].iter().filter(|&&c| c).count();
        let bar = ((40.0 * mean / random_mean).round() as usize).min(60);
        outln!(
            "{:>6}-{:<6}  {:>11.5}  {:>11}  {}",
            start,
            end - 1,
            mean,
            corrections,
            "#".repeat(bar)
        )?;
    }
    let tail = (steps / 10).max(1);
    let tail_mean = report.latent_loss[steps - tail..]
        .iter()
        .map(|&x| x as f64)
        .sum::<f64>()
        / tail as f64;
    outln!(
        "last {tail} rounds: mean latent loss {tail_mean:.5} ({:.3}% of a random policy's {random_mean:.3}); {} corrections in all",
        100.0 * tail_mean / random_mean,
        report.corrections()
    )?;
    outln!("teacher weights {:?}", report.teacher)?;
    outln!("learned weights {:?}", report.weights)?;
    Ok(())
}
