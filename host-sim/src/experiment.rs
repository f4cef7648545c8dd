//! One run of the paper's experiment: a car in a household, a learner behind a [`CarLink`], a
//! programmatic teacher, and the per-step record.
//!
//! # One step (one control tick)
//!
//! 1. The world is sensed into an [`Observation`] (see [`crate::sim`]).
//! 2. The learner acts on it through the link: `link.act(tick, &obs)`.
//! 3. The teacher judges the same observation with the same evaluator; the **latent loss** of the
//!    learner's action is recorded. If the perceived loss exceeds the threshold and the run
//!    learns online, the teacher's feedback goes to the learner: `link.feedback(tick, &fb)`.
//! 4. The car tracks the learner's trajectory for one tick; collisions, stuck and lost cars are
//!    put back at the start, keeping the learner.
//!
//! The learner sits behind [`CarLink`], so the same loop runs the in-process agent
//! ([`InProcessLink`]) or one in another process over a CAN link; both must give bit-identical
//! records. Nothing here reads a clock: the only randomness is the teacher's, seeded from the
//! run's seed, so the same configuration gives the same CSV bytes.
//!
//! # Modes
//!
//! * online learning from `action`, `preference` or `semantic` feedback;
//! * `bc`: behaviour cloning. The teacher drives one lap of its own policy (at most
//!   [`BC_ROLLOUT_TICKS`] ticks) from the start; [`BC_SAMPLES`] ticks evenly spaced over that
//!   rollout become action-feedback samples (features, mask, the teacher's choice). They are
//!   fitted offline with the same generalized hinge and learner: epochs over the samples in their
//!   order until an epoch leaves the weights unchanged or [`BC_MAX_EPOCHS`] epochs. The fitted
//!   learner is then frozen for the run (no feedback reaches it) and scored like the others;
//! * `teacher`: the teacher's own policy drives (learner weights = teacher weights, frozen): the
//!   reference the learners are measured against, and the lap test of every household.
//!
//! # Measured (5000 steps, seed 0, threshold 1.0, noise 0)
//!
//! Mean latent loss of the first → last 500 steps (corrections in all), with the firmware's
//! default learner (averaged OGD, η = 0.01) and the paper's (plain OGD, η = 0.01):
//!
//! | household | action, avg | action, OGD | preference, avg | preference, OGD | semantic, avg | semantic, OGD | bc |
//! |---|---|---|---|---|---|---|---|
//! | doors | 0.301 → 0.056 (51) | 0.403 → 0.019 (74) | 1.414 → 0.499 (1297) | 0.557 → 0.028 (207) | 3.678 → 2.775 (1978) | 0.572 → 0.032 (62) | 0.004 → 0.003 |
//! | stairs-right | 0.429 → 0.164 (45) | 0.233 → 0.054 (20) | 0.577 → 0.019 (40) | 0.645 → 0.025 (62) | 1.882 → 0.033 (216) | 0.215 → 0.036 (28) | 0.009 → 0.019 |
//! | stairs-chairs | 0.392 → 0.083 (66) | 0.385 → 0.095 (64) | 1.236 → 0.033 (341) | 1.000 → 0.062 (192) | 2.795 → 3.929 (3647) | 0.648 → 0.023 (94) | 0.014 → 0.011 |
//! | basement | 0.122 → 0.005 (22) | 0.274 → 0.001 (41) | 1.405 → 0.139 (430) | 0.373 → 0.072 (96) | 1.029 → 3.851 (1391) | 0.160 → 0.040 (102) | 0.000 → 0.001 |
//!
//! Plain OGD learns from every kind of feedback on every household. Averaged OGD learns from
//! action and preference feedback (with more corrections for preference) but **not from semantic
//! feedback** on three of the four: its subgradient is taken at the raw iterate, and the semantic
//! pseudo-loss is flat over every action that beats the learner's on the stated features, so `â`
//! is the raw iterate's own favourite among them; the step then reinforces the iterate's biases
//! (on doors it grew a weight on `right`, a feature the teacher never mentions) rather than
//! correcting the averaged policy that acted. Under noise the order flips: on doors with action
//! feedback and σ = 1 (seed 1), averaged OGD reaches 0.393 → 0.020 (906 corrections), plain OGD
//! 0.557 → 0.213 (1219). BC fits the teacher's lap almost exactly: 50 samples of a noiseless
//! teacher in a world this regular pin its policy down.

use std::io::Write;
use std::sync::Arc;

use anyhow::{Context, Result, bail, ensure};
use firmware_core::agent::{Agent, Decision};
use firmware_core::observation::Observation;
use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, FeatureTable, Feedback, Learner, LearnerParams,
    LearnerSnapshot, OnlineLearner, Round, Weights,
};

use crate::scenario::Scenario;
use crate::sim::{Episode, ResetReason};
use crate::teacher::{FeedbackKind, Teacher, TeacherSpec};

/// The learner as the experiment sees it: on this machine or on the car's controller.
///
/// Implementations must be deterministic: the same calls give the same answers.
pub trait CarLink {
    /// Replaces the learner by the one `snapshot` describes (parameters and state).
    fn restore(&mut self, snapshot: &LearnerSnapshot) -> Result<()>;
    /// Evaluates the observation and chooses an action for `tick`.
    fn act(&mut self, tick: u32, obs: &Observation) -> Result<Decision>;
    /// Learns from feedback about a recent `tick`.
    fn feedback(&mut self, tick: u32, feedback: &Feedback) -> Result<()>;
    /// The learner's current parameters and state.
    fn snapshot(&mut self) -> Result<LearnerSnapshot>;
}

/// The firmware's [`Agent`], called directly.
#[derive(Clone, Debug)]
pub struct InProcessLink {
    agent: Agent,
}

impl InProcessLink {
    /// An agent with a fresh learner of `params`.
    pub fn new(params: LearnerParams) -> Result<Self> {
        let valid = params.check().map_err(anyhow::Error::msg)?;
        Ok(Self {
            agent: Agent::new(Learner::new(valid)),
        })
    }

    /// The agent.
    pub fn agent(&self) -> &Agent {
        &self.agent
    }
}

impl CarLink for InProcessLink {
    fn restore(&mut self, snapshot: &LearnerSnapshot) -> Result<()> {
        let learner = Learner::restore(snapshot).map_err(anyhow::Error::msg)?;
        self.agent.set_learner(learner);
        self.agent.forget_ticks();
        Ok(())
    }

    fn act(&mut self, tick: u32, obs: &Observation) -> Result<Decision> {
        self.agent
            .act(tick, obs)
            .map_err(|e| anyhow::anyhow!("tick {tick}: observation refused: {e}"))
    }

    fn feedback(&mut self, tick: u32, feedback: &Feedback) -> Result<()> {
        self.agent
            .feedback(tick, feedback)
            .map(|_| ())
            .map_err(|e| anyhow::anyhow!("tick {tick}: feedback refused: {e}"))
    }

    fn snapshot(&mut self) -> Result<LearnerSnapshot> {
        Ok(self.agent.learner().snapshot())
    }
}

/// How the learner is taught.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Online, from this kind of feedback.
    Online(FeedbackKind),
    /// Behaviour cloning on [`BC_SAMPLES`] action samples, then frozen.
    BehaviourCloning,
    /// The teacher's own policy, frozen.
    Teacher,
}

impl Mode {
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
        match name {
            "bc" => Some(Mode::BehaviourCloning),
            "teacher" => Some(Mode::Teacher),
            _ => FeedbackKind::ALL
                .into_iter()
                .find(|k| k.name() == name)
                .map(Mode::Online),
        }
    }
}

/// Number of behaviour-cloning samples.
pub const BC_SAMPLES: usize = 50;
/// Longest teacher rollout the samples are drawn from (ticks).
pub const BC_ROLLOUT_TICKS: u32 = 3_000;
/// Epoch cap of the behaviour-cloning fit.
pub const BC_MAX_EPOCHS: u32 = 200;
/// Largest number of steps of one run.
pub const MAX_STEPS: u32 = 10_000_000;

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
        t
    }

    /// Checks the numbers.
    pub fn check(&self) -> Result<()> {
        ensure!(
            self.steps > 0 && self.steps <= MAX_STEPS,
            "steps must be in 1..={MAX_STEPS}, got {}",
            self.steps
        );
        let t = self.teacher();
        ensure!(
            t.threshold.is_finite() && t.threshold >= 0.0,
            "threshold must be finite and >= 0, got {}",
            t.threshold
        );
        ensure!(
            t.noise.is_finite() && t.noise >= 0.0,
            "noise must be finite and >= 0, got {}",
            t.noise
        );
        self.learner
            .check()
            .map_err(|e| anyhow::anyhow!("learner parameters: {e}"))?;
        Ok(())
    }
}

/// One step of a run: one CSV row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepRecord {
    /// Step index, from 0.
    pub step: u32,
    /// The learner's action (None: nothing was allowed).
    pub action: Option<ActionIndex>,
    /// The teacher's (perceived-best) action.
    pub teacher_action: Option<ActionIndex>,
    /// True latent loss of the learner's action (0 when there was none).
    pub latent_loss: f32,
    /// Whether feedback reached the learner this step.
    pub corrected: bool,
    /// Corrections so far, this one included.
    pub corrections: u32,
    /// Whether the car collided this step.
    pub collision: bool,
    /// Why the car was put back at the start, if it was.
    pub reset: Option<ResetReason>,
    /// Laps completed so far.
    pub lap: u32,
    /// Pose where the action was chosen.
    pub x: f64,
    /// Pose where the action was chosen.
    pub y: f64,
    /// Pose where the action was chosen.
    pub theta: f64,
}

/// What behaviour cloning did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BcFit {
    /// Samples fitted.
    pub samples: usize,
    /// Ticks of the teacher's rollout they were drawn from.
    pub rollout_ticks: u32,
    /// Epochs run.
    pub epochs: u32,
    /// Whether the weights stopped changing before the cap.
    pub converged: bool,
    /// The fitted weights.
    pub weights: Weights,
}

/// Everything a run produced.
#[derive(Clone, Debug)]
pub struct RunReport {
    /// The scenario's name.
    pub scenario: String,
    /// The mode.
    pub mode: Mode,
    /// The seed.
    pub seed: u64,
    /// The teacher (after overrides).
    pub teacher: TeacherSpec,
    /// The learner's parameters.
    pub learner: LearnerParams,
    /// One record per step.
    pub records: Vec<StepRecord>,
    /// The learner at the end.
    pub final_snapshot: LearnerSnapshot,
    /// The behaviour-cloning fit, for `bc`.
    pub bc: Option<BcFit>,
    /// Resets by reason: collision, stuck, lost, blocked.
    pub resets: [u32; 4],
}

impl RunReport {
    /// Corrections in all.
    pub fn corrections(&self) -> u32 {
        self.records.last().map_or(0, |r| r.corrections)
    }

    /// Laps in all.
    pub fn laps(&self) -> u32 {
        self.records.last().map_or(0, |r| r.lap)
    }

    /// Collisions in all.
    pub fn collisions(&self) -> u32 {
        self.resets[0]
    }

    /// Mean latent loss over steps `range`.
    pub fn mean_loss(&self, range: std::ops::Range<usize>) -> f64 {
        let rows =
            &self.records[range.start.min(self.records.len())..range.end.min(self.records.len())];
        if rows.is_empty() {
            return 0.0;
        }
        rows.iter().map(|r| r.latent_loss as f64).sum::<f64>() / rows.len() as f64
    }

    /// Mean latent loss of the first and the last `fraction` of the steps.
    pub fn first_last(&self, fraction: f64) -> (f64, f64) {
        let n = self.records.len();
        let k = ((n as f64 * fraction).round() as usize).max(1);
        (self.mean_loss(0..k), self.mean_loss(n.saturating_sub(k)..n))
    }

    /// Writes the per-step CSV.
    pub fn write_csv<W: Write>(&self, mut w: W) -> std::io::Result<()> {
        writeln!(
            w,
            "step,action,teacher_action,latent_loss,corrected,corrections,collision,reset,lap,x,y,theta"
        )?;
        let idx = |a: Option<ActionIndex>| a.map(|a| a.get().to_string()).unwrap_or_default();
        for r in &self.records {
            writeln!(
                w,
                "{},{},{},{},{},{},{},{},{},{},{},{}",
                r.step,
                idx(r.action),
                idx(r.teacher_action),
                r.latent_loss,
                u8::from(r.corrected),
                r.corrections,
                u8::from(r.collision),
                r.reset.map_or("", |x| x.name()),
                r.lap,
                r.x,
                r.y,
                r.theta
            )?;
        }
        Ok(())
    }

    /// The CSV as bytes.
    pub fn csv_bytes(&self) -> Vec<u8> {
        let mut v = Vec::new();
        // Writing to a Vec cannot fail.
        let _ = self.write_csv(&mut v);
        v
    }

    /// The summary (everything but the wall time, which the caller adds).
    pub fn summary(&self) -> serde_json::Value {
        let (first, last) = self.first_last(0.1);
        let t = &self.teacher;
        let s = &self.final_snapshot;
        serde_json::json!({
            "config": {
                "scenario": self.scenario,
                "feedback": self.mode.name(),
                "steps": self.records.len(),
                "seed": self.seed,
                "threshold": t.threshold,
                "noise": t.noise,
                "teacher_preset": t.preset,
                "teacher_weights": t.weights,
                "learner": self.learner.kind.name(),
                "step_size": self.learner.step,
            },
            "seed": self.seed,
            "final_weights": s.state.average,
            "final_iterate": s.state.iterate,
            "learner_steps": s.state.steps,
            "totals": {
                "corrections": self.corrections(),
                "collisions": self.resets[0],
                "stuck": self.resets[1],
                "lost": self.resets[2],
                "blocked": self.resets[3],
                "laps": self.laps(),
            },
            "mean_latent_loss_first_10pct": first,
            "mean_latent_loss_last_10pct": last,
            "corrections": self.corrections(),
            "collisions": self.resets[0],
            "laps": self.laps(),
            "bc": self.bc.map(|b| serde_json::json!({
                "samples": b.samples,
                "rollout_ticks": b.rollout_ticks,
                "epochs": b.epochs,
                "converged": b.converged,
                "weights": b.weights,
            })),
        })
    }
}

/// FNV-1a (64-bit) of `bytes`: the digest the determinism goldens pin.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The learner with `weights` as its initial (and, frozen, final) weights.
fn learner_with(params: LearnerParams, weights: Weights) -> Result<LearnerSnapshot> {
    let p = params
        .with_initial(weights)
        .check()
        .map_err(|e| anyhow::anyhow!("learner parameters: {e}"))?;
    Ok(Learner::new(p).snapshot())
}

/// Behaviour cloning: the teacher's rollout, the samples, the offline fit.
pub fn behaviour_cloning(config: &RunConfig) -> Result<(LearnerSnapshot, BcFit)> {
    let spec = config.teacher();
    let mut teacher = Teacher::new(spec, config.seed ^ 0xB0C0_B0C0_B0C0_B0C0);
    let mut episode = Episode::new(config.scenario.clone());
    let mut rollout: Vec<(FeatureTable, ActionMask, ActionIndex)> = Vec::new();
    let mut ticks = 0;
    while ticks < BC_ROLLOUT_TICKS && episode.laps() == 0 {
        let obs = episode.observe();
        let j = teacher
            .judge(&obs)
            .map_err(|e| anyhow::anyhow!("tick {ticks}: observation refused: {e}"))?;
        if let Some(label) = j.choice {
            rollout.push((j.table.clone(), j.allowed, label));
        }
        episode.drive(j.best);
        ticks += 1;
    }
    ensure!(
        rollout.len() >= BC_SAMPLES,
        "behaviour cloning: the teacher's rollout gave only {} samples",
        rollout.len()
    );
    let samples: Vec<_> = (0..BC_SAMPLES)
        .map(|k| &rollout[k * rollout.len() / BC_SAMPLES])
        .collect();
    let params = config
        .learner
        .check()
        .map_err(|e| anyhow::anyhow!("learner parameters: {e}"))?;
    let mut learner = Learner::new(params);
    let mut epochs = 0;
    let mut converged = false;
    while epochs < BC_MAX_EPOCHS {
        let before = learner.snapshot();
        for (table, mask, label) in &samples {
            let chosen = learner
                .select(table, *mask)
                .context("behaviour cloning: empty mask")?;
            let round = Round::new(table, *mask, chosen).map_err(anyhow::Error::msg)?;
            learner
                .learn(&round, &ActionFeedback { action: *label })
                .map_err(anyhow::Error::msg)?;
        }
        epochs += 1;
        if learner.snapshot() == before {
            converged = true;
            break;
        }
    }
    let fit = BcFit {
        samples: samples.len(),
        rollout_ticks: ticks,
        epochs,
        converged,
        weights: *learner.weights(),
    };
    Ok((learner.snapshot(), fit))
}

/// Runs `config` with the learner behind `link`; `on_step` sees every record as it is made.
pub fn run_with(
    config: &RunConfig,
    link: &mut dyn CarLink,
    on_step: &mut dyn FnMut(&StepRecord),
) -> Result<RunReport> {
    config.check()?;
    let spec = config.teacher();
    let (initial, bc) = match config.mode {
        Mode::Online(_) => (learner_with(config.learner, config.learner.initial)?, None),
        Mode::Teacher => (learner_with(config.learner, spec.weights)?, None),
        Mode::BehaviourCloning => {
            let (snap, fit) = behaviour_cloning(config)?;
            (snap, Some(fit))
        }
    };
    link.restore(&initial)?;
    let mut teacher = Teacher::new(spec, config.seed);
    let mut episode = Episode::new(config.scenario.clone());
    let mut records = Vec::with_capacity(config.steps as usize);
    let mut corrections = 0u32;
    let mut resets = [0u32; 4];
    for step in 0..config.steps {
        let obs = episode.observe();
        let pose = episode.car().pose;
        let decision = link.act(step, &obs)?;
        let j = teacher
            .judge(&obs)
            .map_err(|e| anyhow::anyhow!("step {step}: teacher: observation refused: {e}"))?;
        if decision.allowed != j.allowed {
            bail!("step {step}: the learner's and the teacher's collision masks differ");
        }
        let mut corrected = false;
        let latent_loss = match decision.action {
            Some(a) => {
                if let Mode::Online(kind) = config.mode
                    && teacher.corrects(&j, a)
                    && let Some(fb) = teacher.feedback(kind, &j, a)
                {
                    link.feedback(step, &fb)?;
                    corrected = true;
                    corrections += 1;
                }
                j.latent_loss(a)
            }
            None => 0.0,
        };
        let result = episode.drive(decision.action);
        match result.reset {
            Some(ResetReason::Collision) => resets[0] += 1,
            Some(ResetReason::Stuck) => resets[1] += 1,
            Some(ResetReason::Lost) => resets[2] += 1,
            Some(ResetReason::Blocked) => resets[3] += 1,
            Some(ResetReason::PathEnd) | None => {}
        }
        let record = StepRecord {
            step,
            action: decision.action,
            teacher_action: j.choice,
            latent_loss,
            corrected,
            corrections,
            collision: result.reset == Some(ResetReason::Collision),
            reset: result.reset,
            lap: episode.laps(),
            x: pose.x,
            y: pose.y,
            theta: pose.theta,
        };
        on_step(&record);
        records.push(record);
    }
    Ok(RunReport {
        scenario: config.scenario.name.clone(),
        mode: config.mode,
        seed: config.seed,
        teacher: spec,
        learner: config.learner,
        records,
        final_snapshot: link.snapshot()?,
        bc,
        resets,
    })
}

/// Runs `config` with the firmware agent in this process.
pub fn run(config: &RunConfig) -> Result<RunReport> {
    let mut link = InProcessLink::new(config.learner)?;
    run_with(config, &mut link, &mut |_| {})
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_the_reference_vectors() {
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(b"foobar"), 0x8594_4171_f739_67e8);
    }

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
}
