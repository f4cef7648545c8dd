//! Every kind of feedback, the mixes and the cost-aware teacher teach the car's default learner
//! (averaged OGD, step 0.01) in `doors` (issue 15): over [`SEEDS`] seeds with the
//! reproduction's start jitter, the median run's mean latent loss of its last 500 steps (of
//! 5000) is below half that of its first 500, or, for the two kinds that do not get there, the
//! measured reason is asserted.
//!
//! Measured (seeds 0–7, last 500 over first 500, sorted):
//!
//! | teaching | ratios | median |
//! |---|---|---|
//! | action | 0.041 0.095 0.107 0.109 0.122 0.134 0.137 0.151 | 0.115 |
//! | preference | 0.020 0.020 0.025 0.092 0.113 0.143 0.572 0.637 | 0.102 |
//! | semantic | 0.004 0.007 0.008 0.011 0.016 0.019 0.062 0.502 | 0.013 |
//! | perturbation | 0.013 0.185 0.202 0.224 0.230 0.245 0.288 0.436 | 0.227 |
//! | reward | 0.006 0.007 0.013 0.027 0.747 1.177 1.287 1.424 | 0.387 |
//! | correctness | the same runs as reward, bit for bit | 0.387 |
//! | span | 0.144 0.320 0.389 0.643 0.951 1.012 1.171 1.668 | 0.797 |
//! | ranking | 0.027 0.036 0.045 0.048 0.132 0.188 0.217 0.364 | 0.090 |
//! | estop | 0.979 0.981 0.987 1.010 1.146 1.310 1.340 2.998 | 1.078 |
//! | mix:action=0.2,preference=0.3,semantic=0.5 | 0.039 0.049 0.056 0.061 0.066 0.111 0.113 0.113 | 0.063 |
//! | mix:all | 0.014 0.023 0.028 0.033 0.047 0.049 0.074 0.126 | 0.040 |
//! | cheapest | 0.032 0.055 0.063 0.072 0.074 0.090 0.093 0.096 | 0.073 |
//!
//! Reward and correct/incorrect halve the loss on the median run but not on half the seeds: "not
//! this action" moves the learner towards its own runner-up, which in doors is on average worse
//! than its choice (the report's α of these kinds in doors is negative). Span and E-stop do not
//! get there, for the reasons their tests state.

use std::sync::Arc;

use firmware_core::LearnerParams;
use host_sim::teach::experiment::{self, Mode, RunConfig, StartJitter};
use host_sim::teach::record::RunReport;
use host_sim::world::registry;

/// Seeds per teaching.
const SEEDS: u64 = 8;

/// The runs of `mode` in doors, seeds 0..SEEDS, the car's default learner, the reproduction's
/// start jitter.
fn runs(mode: &str) -> Vec<RunReport> {
    let s = Arc::new(registry::load_scenario("doors").unwrap());
    let mode = Mode::parse(mode).unwrap();
    let configs: Vec<RunConfig> = (0..SEEDS)
        .map(|seed| RunConfig {
            mode,
            steps: 5_000,
            seed,
            learner: LearnerParams::default(),
            start_jitter: Some(StartJitter::REPRODUCE),
            ..RunConfig::new(s.clone())
        })
        .collect();
    experiment::run_all(&configs)
        .into_iter()
        .map(|r| r.unwrap())
        .collect()
}

/// Last 500 over first 500 of every run, and their median.
fn ratios(name: &str, runs: &[RunReport]) -> (Vec<f64>, f64) {
    let mut r: Vec<f64> = runs
        .iter()
        .map(|r| {
            let n = r.records.len();
            r.mean_loss(n - 500..n) / r.mean_loss(0..500)
        })
        .collect();
    r.sort_by(f64::total_cmp);
    let median = (r[r.len() / 2 - 1] + r[r.len() / 2]) / 2.0;
    println!(
        "{name}: {} (median {median:.3})",
        r.iter()
            .map(|x| format!("{x:.3}"))
            .collect::<Vec<_>>()
            .join(" ")
    );
    (r, median)
}

#[test]
fn every_kind_that_points_somewhere_halves_the_latent_loss_in_doors() {
    for name in [
        "action",
        "preference",
        "semantic",
        "perturbation",
        "ranking",
        "mix:action=0.2,preference=0.3,semantic=0.5",
        "mix:all",
        "cheapest",
    ] {
        let (_, median) = ratios(name, &runs(name));
        assert!(median < 0.5, "{name}: median ratio {median}");
    }
}

/// Reward and correct/incorrect say the same thing ("not this action") and their pseudo-losses
/// have the same minimisers, so the generalized hinge takes the same steps: the runs are the
/// same, bit for bit (the reward's size does not change the step). The median run halves its
/// loss; the other half of the seeds do not (see the module documentation).
#[test]
fn reward_and_correctness_teach_the_same_and_halve_the_median_run() {
    let reward = runs("reward");
    let correctness = runs("correctness");
    for (r, c) in reward.iter().zip(&correctness) {
        let loss = |x: &RunReport| x.records.iter().map(|s| s.latent_loss).collect::<Vec<_>>();
        assert_eq!(loss(r), loss(c), "seed {}", r.seed);
        assert_eq!(r.final_snapshot, c.final_snapshot);
        assert!(r.effort() > c.effort(), "a reward costs more than a label");
    }
    let (_, median) = ratios("reward", &reward);
    assert!(median < 0.5, "reward: median ratio {median}");
}

/// Spans do not halve it in doors (median 0.80; three seeds of eight do). The span teacher
/// lets a stretch of bad ticks go by before it labels it (up to four), so the first tenth's
/// loss is higher than correct/incorrect's and each label carries what four "incorrect"s
/// would, late. What is asserted is what was measured: the median does not get below half,
/// and at least one seed does (if spans come to halve the median run, this test fails: move
/// them to the test above and update the documentation and the report's text).
#[test]
fn spans_do_not_halve_it_in_doors_and_say_why() {
    let r = runs("span");
    let (ratios, median) = ratios("span", &r);
    assert!(median >= 0.5, "span: median ratio {median}");
    assert!(ratios[0] < 0.5, "span: no seed halves it: {ratios:?}");
    // Each label covers one to four ticks, all still held by the car.
    for run in &r {
        let labels = run.kind_counts()[firmware_core::FeedbackKind::Span as usize] as usize;
        let labelled = run.informativeness.len();
        assert!(labels > 0 && labelled >= labels && labelled <= 4 * labels);
    }
}

/// E-stops do not teach in doors: the teacher stops the car at every correction, so the car
/// stands where it was, and in that one state "not this action" makes the learner swap between
/// its two best-scored actions, each stopped in turn, until the car is reset for making no
/// progress (measured by `host-sim run --feedback estop --learner averaged-ogd`, seed 0, no
/// jitter: actions 42 and 34 on 2384 and 2382 of the 5000 ticks, the teacher's best 28; 98
/// resets). Asserted: no run laps or makes more than a few metres of
/// progress, most of its ticks are stopped, and the median ratio stays above half.
#[test]
fn e_stops_do_not_teach_in_doors_because_the_car_stands_where_it_was_wrong() {
    let r = runs("estop");
    let (_, median) = ratios("estop", &r);
    assert!(median >= 0.5, "estop: median ratio {median}");
    for run in &r {
        assert_eq!(run.laps(), 0, "seed {}", run.seed);
        assert!(run.corrections() as usize > run.records.len() / 2);
        // Stuck resets: the held car made no progress.
        assert!(run.resets[1] > 10, "seed {}: {:?}", run.seed, run.resets);
    }
}
