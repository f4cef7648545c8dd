//! The learner learns in the world, over several seeds: each test runs [`SEEDS`] seeds with the
//! reproduction's start jitter (so that the seeds differ even with a noiseless teacher) and
//! asserts on the median seed and on the worst one, each with a margin stated beside it
//! against what was measured.

use std::sync::Arc;

use firmware_core::LearnerParams;
use host_sim::teach::bc;
use host_sim::teach::experiment::{self, Mode, RunConfig, StartJitter};
use host_sim::teach::record::RunReport;
use host_sim::world::registry;
use host_sim::world::teacher::{FeedbackKind, PAPER_KINDS};

/// Seeds per test.
const SEEDS: u64 = 8;

/// Runs `config` at seeds 0..SEEDS with the reproduction's start jitter, in parallel.
fn over_seeds(config: RunConfig) -> Vec<RunReport> {
    let configs: Vec<RunConfig> = (0..SEEDS)
        .map(|seed| RunConfig {
            seed,
            start_jitter: Some(StartJitter::REPRODUCE),
            ..config.clone()
        })
        .collect();
    experiment::run_all(&configs)
        .into_iter()
        .map(|r| r.unwrap())
        .collect()
}

/// The median and the largest of `xs`.
fn median_and_worst(mut xs: Vec<f64>) -> (f64, f64) {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    let median = if n % 2 == 1 {
        xs[n / 2]
    } else {
        (xs[n / 2 - 1] + xs[n / 2]) / 2.0
    };
    (median, xs[n - 1])
}

/// Last-tenth over first-tenth mean latent loss of every seed's run.
fn ratios(name: &str, runs: &[RunReport]) -> Vec<f64> {
    runs.iter()
        .map(|r| {
            let (first, last) = r.first_last(0.1);
            println!(
                "{name} seed {}: first {first:.4}, last {last:.4}, ratio {:.3}, {} corrections, {} laps, resets {:?}",
                r.seed,
                last / first,
                r.corrections(),
                r.laps(),
                r.resets
            );
            last / first
        })
        .collect()
}

fn doors(kind: FeedbackKind, learner: LearnerParams) -> RunConfig {
    let s = Arc::new(registry::load_scenario("doors").unwrap());
    RunConfig {
        mode: Mode::Online(kind),
        steps: 5_000,
        learner,
        ..RunConfig::new(s)
    }
}

/// Action feedback with the paper's learner on doors. Measured (seeds 0–7): last-tenth over
/// first-tenth loss, median 0.031, worst 0.216 (seed 3). Asserted: median below 0.1 and worst
/// below 0.5, margins of about 3 and 2.3 times; and every seed's corrections slow down.
#[test]
fn action_feedback_on_doors_cuts_the_latent_loss_over_seeds() {
    let runs = over_seeds(doors(FeedbackKind::Action, LearnerParams::paper()));
    let (median, worst) = median_and_worst(ratios("doors/action/ogd", &runs));
    println!("median {median:.3}, worst {worst:.3}");
    assert!(median < 0.1, "median ratio {median}");
    assert!(worst < 0.5, "worst ratio {worst}");
    // Corrections stop growing: fewer in the second half than in the first, on every seed.
    for r in &runs {
        let half = r.records[2_499].corrections;
        assert!(
            r.corrections() - half < half,
            "seed {}: {half} then {}",
            r.seed,
            r.corrections() - half
        );
    }
}

/// Preference and semantic feedback with the paper's learner on doors. Measured (seeds 0–7):
/// preference median 0.228, worst 0.797 (seed 7); semantic median 0.038, worst 0.419 (seed 6).
/// Asserted: preference median below 0.5 and every seed below 1 (it lowers its loss; the
/// narrowest margin here, 1.25 times); semantic median below 0.15 and worst below 0.8.
#[test]
fn preference_and_semantic_feedback_teach_the_paper_learner_over_seeds() {
    for (kind, median_max, worst_max) in [
        (FeedbackKind::Preference, 0.5, 1.0),
        (FeedbackKind::Semantic, 0.15, 0.8),
    ] {
        let runs = over_seeds(doors(kind, LearnerParams::paper()));
        let (median, worst) =
            median_and_worst(ratios(&format!("doors/{}/ogd", kind.name()), &runs));
        println!("{}: median {median:.3}, worst {worst:.3}", kind.name());
        assert!(
            median < median_max,
            "{}: median ratio {median}",
            kind.name()
        );
        assert!(worst < worst_max, "{}: worst ratio {worst}", kind.name());
    }
}

#[test]
fn behaviour_cloning_is_fitted_on_ticks_0_to_49_then_frozen() {
    let s = Arc::new(registry::load_scenario("doors").unwrap());
    for seed in [0, 7] {
        let config = RunConfig {
            mode: Mode::BehaviourCloning,
            steps: 300,
            seed,
            learner: LearnerParams::paper(),
            start_jitter: Some(StartJitter::REPRODUCE),
            ..RunConfig::new(s.clone())
        };
        // The samples are the teacher's demonstration of the run's ticks 0–49: the poses, the
        // labels and the masks of a run in which the teacher's own policy drives from the same
        // (jittered) start.
        let samples = bc::bc_samples(&config).unwrap();
        let ticks: Vec<u32> = samples.iter().map(|x| x.tick).collect();
        assert_eq!(ticks, (0..bc::BC_SAMPLES as u32).collect::<Vec<_>>());
        let teacher = experiment::run(&RunConfig {
            mode: Mode::Teacher,
            steps: 60,
            ..config.clone()
        })
        .unwrap();
        for (x, r) in samples.iter().zip(&teacher.records) {
            assert_eq!((x.pose.x, x.pose.y, x.pose.theta), (r.x, r.y, r.theta));
            assert_eq!(Some(x.label), r.teacher_action, "tick {}", x.tick);
        }
        let r = experiment::run(&config).unwrap();
        let bc = r.bc.expect("a bc run reports its fit");
        println!("seed {seed}: bc fit {bc:?}");
        assert_eq!((bc.samples, bc.ticks), (bc::BC_SAMPLES, 50));
        assert!(bc.epochs >= 1 && bc.epochs <= bc::BC_MAX_EPOCHS);
        assert_eq!(r.corrections(), 0, "no feedback reaches a frozen learner");
        assert_eq!(r.final_snapshot.state.average, bc.weights, "frozen");
        assert!(bc.weights.iter().any(|&w| w != 0.0));
        // The run starts where the demonstration started.
        assert_eq!(
            (r.records[0].x, r.records[0].y),
            (samples[0].pose.x, samples[0].pose.y)
        );
    }
}

/// `host-sim run`'s default learner for each kind of feedback (docs/learners.md) learns on
/// doors over seeds. Measured (seeds 0–7), last-tenth over first-tenth loss: action (Coactive)
/// median 0.071, worst 0.201; preference (plain OGD) median 0.195, worst 0.361; semantic
/// (AdaGrad) median 0.058, worst 0.180. Asserted: for action and semantic feedback median below 0.15 and worst
/// below 0.5; for preferences, which say less per correction, the bounds of the paper learner's
/// preference test above (median below 0.5, every seed below 1): margins of at least 2 times.
/// (The defaults were AdaGrad / Coactive / AdaGrad, with median 0.047 / 0.032 / 0.042, until the
/// regenerated table chose otherwise under the same rule.)
#[test]
fn run_s_default_learners_learn_over_seeds() {
    for kind in PAPER_KINDS {
        let learner = LearnerParams::new(host_sim::teach::learners::default_learner(Mode::Online(
            kind,
        )));
        let runs = over_seeds(doors(kind, learner));
        let name = format!("doors/{}/{}", kind.name(), learner.kind.name());
        let (median, worst) = median_and_worst(ratios(&name, &runs));
        println!("{name}: median {median:.3}, worst {worst:.3}");
        let (median_bound, worst_bound) = match kind {
            FeedbackKind::Preference => (0.5, 1.0),
            _ => (0.15, 0.5),
        };
        assert!(median < median_bound, "{name}: median ratio {median}");
        assert!(worst < worst_bound, "{name}: worst ratio {worst}");
    }
}
