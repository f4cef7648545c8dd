//! Behaviour cloning, the paper's baseline: the teacher's demonstration of a run's first
//! [`BC_SAMPLES`] ticks, fitted offline with the same hinge and learner, then frozen (see
//! [`crate::teach::experiment`]'s "Modes").

use anyhow::{Context, Result, ensure};
use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, FeatureTable, Learner, LearnerSnapshot, OnlineLearner,
    Round, Weights,
};

use super::config::RunConfig;
use crate::world::car::Pose;
use crate::world::sim::Episode;
use crate::world::teacher::{Teacher, TeacherSpec};

/// Number of behaviour-cloning samples: the teacher's demonstration of ticks 0–49.
pub const BC_SAMPLES: usize = 50;
/// Epoch cap of the behaviour-cloning fit.
pub const BC_MAX_EPOCHS: u32 = 200;

/// One behaviour-cloning sample: a tick of the teacher's demonstration.
#[derive(Clone, Debug, PartialEq)]
pub struct BcSample {
    /// The tick of the demonstration (from 0).
    pub tick: u32,
    /// Where the car was.
    pub pose: Pose,
    /// The features of every action.
    pub table: FeatureTable,
    /// The allowed actions.
    pub mask: ActionMask,
    /// The teacher's action: the label.
    pub label: ActionIndex,
}

/// What behaviour cloning did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BcFit {
    /// Samples fitted.
    pub samples: usize,
    /// Ticks of the teacher's demonstration they came from (ticks `0..ticks`).
    pub ticks: u32,
    /// Epochs run.
    pub epochs: u32,
    /// Whether the weights stopped changing before the cap.
    pub converged: bool,
    /// The fitted weights.
    pub weights: Weights,
}

/// The behaviour-cloning samples of `config`'s run: the teacher's own (noiseless) policy drives
/// ticks 0–49 from the run's start pose; every tick with an allowed action is a sample labelled
/// with the teacher's action. A reset (none happens to the households' teachers) puts the car
/// back at the start, and the demonstration goes on from there.
pub fn bc_samples(config: &RunConfig) -> Result<Vec<BcSample>> {
    let spec = TeacherSpec {
        noise: 0.0,
        random_answers: 0.0,
        ..config.teacher()
    };
    // The noiseless teacher draws nothing: the seed changes nothing here.
    let mut teacher = Teacher::new(spec, config.seed);
    let mut episode = Episode::starting_at(config.scenario.clone(), config.start_pose());
    let mut samples = Vec::with_capacity(BC_SAMPLES);
    for tick in 0..BC_SAMPLES as u32 {
        let obs = episode.observe();
        let pose = episode.car().pose;
        let j = teacher
            .judge(&obs)
            .map_err(|e| anyhow::anyhow!("tick {tick}: observation refused: {e}"))?;
        if let Some(label) = j.best {
            samples.push(BcSample {
                tick,
                pose,
                table: j.table().clone(),
                mask: j.allowed(),
                label,
            });
        }
        episode.drive(j.best);
    }
    ensure!(
        !samples.is_empty(),
        "behaviour cloning: the teacher had no allowed action in its first {BC_SAMPLES} ticks"
    );
    Ok(samples)
}

/// Behaviour cloning: the samples of [`bc_samples`], fitted offline.
pub fn behaviour_cloning(config: &RunConfig) -> Result<(LearnerSnapshot, BcFit)> {
    let samples = bc_samples(config)?;
    let params = config
        .learner
        .check()
        .map_err(|e| anyhow::anyhow!("learner parameters: {e}"))?;
    let mut learner = Learner::new(params);
    let mut epochs = 0;
    let mut converged = false;
    while epochs < BC_MAX_EPOCHS {
        let before = learner.snapshot();
        for s in &samples {
            let chosen = learner
                .select(&s.table, s.mask)
                .context("behaviour cloning: empty mask")?;
            let round = Round::new(&s.table, s.mask, chosen).map_err(anyhow::Error::msg)?;
            learner
                .learn(&round, &ActionFeedback { action: s.label })
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
        ticks: BC_SAMPLES as u32,
        epochs,
        converged,
        weights: *learner.weights(),
    };
    Ok((learner.snapshot(), fit))
}
