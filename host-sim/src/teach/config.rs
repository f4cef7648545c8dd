//! A run's configuration: how the learner is taught ([`Mode`]), the scenario, the learner, the
//! overrides of the scenario's teacher, and the seeded jitter of the start pose.

use std::sync::Arc;

use anyhow::{Result, ensure};
use firmware_core::{LearnerParams, LearnerSnapshot};
use nalgebra::Point2;

use crate::world::car::Pose;
use crate::world::scenario::Scenario;
use crate::world::teacher::{FeedbackKind, StatementSet, TeacherSpec};

/// How the learner is taught.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Online, from this kind of feedback.
    Online(FeedbackKind),
    /// Behaviour cloning on [`BC_SAMPLES`](super::bc::BC_SAMPLES) action samples, then frozen.
    BehaviourCloning,
    /// The teacher's own policy, frozen.
    Teacher,
}

impl Mode {
    /// Every mode, in the order of the command line's list.
    pub const ALL: [Mode; 5] = [
        Mode::Online(FeedbackKind::Action),
        Mode::Online(FeedbackKind::Preference),
        Mode::Online(FeedbackKind::Semantic),
        Mode::BehaviourCloning,
        Mode::Teacher,
    ];

    /// The name used on the command line: action, preference, semantic, bc, teacher.
    pub const fn name(self) -> &'static str {
        match self {
            Mode::Online(k) => k.name(),
            Mode::BehaviourCloning => "bc",
            Mode::Teacher => "teacher",
        }
    }

    /// The mode called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }
}

/// `--feedback NAME` on the command line.
impl clap::ValueEnum for Mode {
    fn value_variants<'a>() -> &'a [Self] {
        &Self::ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.name()))
    }
}

pub use crate::checks::MAX_STEPS;

/// One run's configuration.
#[derive(Clone, Debug)]
pub struct RunConfig {
    /// The household.
    pub scenario: Arc<Scenario>,
    /// How the learner is taught.
    pub mode: Mode,
    /// Number of control ticks.
    pub steps: u32,
    /// Seed of the teacher's noise and random queries.
    pub seed: u64,
    /// Overrides the scenario teacher's threshold.
    pub threshold: Option<f32>,
    /// Overrides the scenario teacher's noise σ.
    pub noise: Option<f32>,
    /// The learner's parameters.
    pub learner: LearnerParams,
    /// A seeded random offset of the start pose (None: the scenario's start, as `host-sim run`).
    pub start_jitter: Option<StartJitter>,
    /// Overrides the statements of the scenario teacher's semantic feedback.
    pub statements: Option<StatementSet>,
    /// Overrides the scenario teacher's probability of a random answer.
    pub random_answers: Option<f32>,
    /// Multiplies the scenario teacher's weights (its scale; the reproduction's scale sweep).
    pub teacher_scale: Option<f32>,
    /// Start from this learner, parameters and state (`run --load-learner`), instead of a fresh
    /// one of `learner`; online modes only. Its parameters must be `learner`.
    pub initial: Option<LearnerSnapshot>,
}

/// A small random offset of the start pose, drawn once per run from the run's seed, so that
/// trials of the same setting differ even with a noiseless teacher (with σ = 0 and action
/// feedback nothing else in a run is random). Every reset of the run returns to the same
/// jittered pose.
///
/// The offset is `u·lateral` metres across the start's heading (left positive) and `v·heading`
/// radians of heading, `u, v` uniform in [−1, 1] drawn in that order from a ChaCha8 generator
/// seeded with `seed ^ JITTER_SALT` (independent of the teacher's generator). If the car's
/// footprint at the offset pose would touch the map, the offset is halved, up to four times, and
/// then dropped (the scenario's start, which loading checked, is used).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StartJitter {
    /// Largest lateral offset (m).
    pub lateral: f64,
    /// Largest heading offset (rad).
    pub heading: f64,
}

impl StartJitter {
    /// The reproduction's jitter: up to 0.15 m sideways and 0.1 rad (5.7°) of heading, small
    /// against the 1.6–2 m hallways and the 1 m trajectories.
    pub const REPRODUCE: StartJitter = StartJitter {
        lateral: 0.15,
        heading: 0.1,
    };

    /// Salt of the jitter's generator seed.
    pub const JITTER_SALT: u64 = 0x5EED_0F57_A27C_0DE5;

    /// The start pose of a run of `scenario` with `seed`.
    pub fn start(&self, scenario: &Scenario, seed: u64) -> Pose {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ Self::JITTER_SALT);
        let u: f64 = rng.random_range(-1.0..=1.0);
        let v: f64 = rng.random_range(-1.0..=1.0);
        let st = scenario.start;
        let car = crate::world::car::CarParams::MUSHR;
        let mut scale = 1.0;
        for _ in 0..5 {
            // Sideways in the start's frame (y left), then turned.
            let d = u * self.lateral * scale;
            let pose = Pose::at(
                st.to_world(Point2::new(0.0, d)),
                st.theta + v * self.heading * scale,
            );
            if !car.footprint_hits(&scenario.map, pose) {
                return pose;
            }
            scale /= 2.0;
        }
        st
    }
}

impl RunConfig {
    /// A run of `scenario` with default settings: action feedback, 5000 steps, seed 0, the
    /// scenario's teacher, the default learner.
    pub fn new(scenario: Arc<Scenario>) -> Self {
        Self {
            scenario,
            mode: Mode::Online(FeedbackKind::Action),
            steps: 5_000,
            seed: 0,
            threshold: None,
            noise: None,
            learner: LearnerParams::default(),
            start_jitter: None,
            statements: None,
            random_answers: None,
            teacher_scale: None,
            initial: None,
        }
    }

    /// Where the run's car starts: the scenario's start, or jittered by the seed.
    pub fn start_pose(&self) -> Pose {
        match self.start_jitter {
            Some(j) => j.start(&self.scenario, self.seed),
            None => self.scenario.start,
        }
    }

    /// The teacher after the overrides.
    pub fn teacher(&self) -> TeacherSpec {
        let mut t = self.scenario.teacher;
        if let Some(th) = self.threshold {
            t.threshold = th;
        }
        if let Some(n) = self.noise {
            t.noise = n;
        }
        if let Some(s) = self.statements {
            t.statements = s;
        }
        if let Some(p) = self.random_answers {
            t.random_answers = p;
        }
        if let Some(f) = self.teacher_scale {
            t.weights = crate::world::teacher::scaled(&t.weights, f);
        }
        t
    }

    /// Checks the numbers, with the checks (and the words) of [`crate::checks`] that the
    /// command line and the scenario files use.
    pub fn check(&self) -> Result<()> {
        use crate::checks;
        use crate::checks::named;
        checks::steps(self.steps.into()).map_err(named("steps"))?;
        let t = self.teacher();
        checks::threshold(t.threshold.into()).map_err(named("threshold"))?;
        checks::noise(t.noise.into()).map_err(named("noise"))?;
        if let Some(f) = self.teacher_scale {
            checks::teacher_scale(f.into()).map_err(named("the teacher's scale"))?;
        }
        checks::probability(t.random_answers.into())
            .map_err(named("the probability of a random answer"))?;
        if let Some(j) = self.start_jitter {
            ensure!(
                j.lateral.is_finite()
                    && j.lateral >= 0.0
                    && j.heading.is_finite()
                    && j.heading >= 0.0,
                "start jitter must be finite and >= 0, got {j:?}"
            );
        }
        checks::step_size(self.learner.step.into()).map_err(named("step size"))?;
        self.learner
            .check()
            .map_err(|e| anyhow::anyhow!("learner parameters: {e}"))?;
        if let Some(s) = &self.initial {
            ensure!(
                matches!(self.mode, Mode::Online(_)),
                "a loaded learner is taught online (action, preference or semantic feedback), not {}",
                self.mode.name()
            );
            ensure!(
                s.params == self.learner,
                "the loaded learner's parameters differ from the run's learner"
            );
            firmware_core::Learner::restore(s)
                .map_err(|e| anyhow::anyhow!("the loaded learner: {e}"))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_round_trip_their_names() {
        for m in [
            Mode::Online(FeedbackKind::Action),
            Mode::Online(FeedbackKind::Preference),
            Mode::Online(FeedbackKind::Semantic),
            Mode::BehaviourCloning,
            Mode::Teacher,
        ] {
            assert_eq!(Mode::from_name(m.name()), Some(m));
        }
        assert_eq!(Mode::from_name("shouting"), None);
    }

    #[test]
    fn start_jitter_is_seeded_small_and_free() {
        let s = crate::world::registry::load_scenario("doors").unwrap();
        let j = StartJitter::REPRODUCE;
        let a = j.start(&s, 1);
        assert_eq!(a, j.start(&s, 1));
        assert_ne!(a, j.start(&s, 2));
        for seed in 0..20 {
            let p = j.start(&s, seed);
            let d = ((p.x - s.start.x).powi(2) + (p.y - s.start.y).powi(2)).sqrt();
            assert!(d <= j.lateral + 1e-9 && (p.theta - s.start.theta).abs() <= j.heading + 1e-9);
            assert!(!crate::world::car::CarParams::MUSHR.footprint_hits(&s.map, p));
        }
    }
}
