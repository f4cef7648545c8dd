//! Records the car's side of short simulator runs as protocol messages, for the firmware's
//! replay benchmark (`scripts/measure-firmware`).
//!
//! ```text
//! cargo run -p tests --example record_ticks -- OUT [STEPS]
//! ```
//!
//! Runs the `doors` scenario, seed 0, once per kind of feedback, in `FeedbackKind` order
//! (action, preference, semantic, perturbation, reward, correctness, span, ranking, E-stop),
//! `STEPS` ticks each (default 40), with the firmware agent in this process, and writes every call
//! the experiment made to the agent, in order, to `OUT`. Each item is a little-endian `u16`
//! length followed by one sealed [`Message`] (versioned postcard envelope with its CRC):
//!
//! * `Weights(report)`: start of a run: restore the report's learner, forget the ticks;
//! * `Observation { tick, observation }`: act on it;
//! * `Feedback { tick, feedback, .. }`: learn from it.
//!
//! The replay of the same items on the firmware gives the same decisions (the bit-identical test
//! checks that for whole runs), so the instructions counted there are the simulator's real ticks.

use std::sync::Arc;

use anyhow::{Context, Result, bail};
use firmware_core::agent::Decision;
use firmware_core::observation::Observation;
use firmware_core::{Feedback, LearnerKind, LearnerParams, LearnerSnapshot};
use host_sim::teach::experiment::{CarLink, InProcessLink, Mode, RunConfig, run_with};
use host_sim::world::registry;
use host_sim::world::teacher::FeedbackKind;
use protocol::MAX_MESSAGE_SIZE;
use protocol::message::{
    CarStatus, DeliveryId, FeedbackMessage, Message, ObservationMessage, WeightsReport,
};

/// Forwards to the in-process agent and appends every call to `out`.
struct Recorder {
    inner: InProcessLink,
    out: Vec<u8>,
    seq: u8,
}

impl Recorder {
    fn push(&mut self, msg: &Message) -> Result<()> {
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        let bytes = msg.emit(&mut buf).map_err(anyhow::Error::msg)?;
        let len = u16::try_from(bytes.len()).context("message longer than 64 KiB")?;
        self.out.extend_from_slice(&len.to_le_bytes());
        self.out.extend_from_slice(bytes);
        Ok(())
    }
}

impl CarLink for Recorder {
    fn restore(&mut self, snapshot: &LearnerSnapshot) -> Result<()> {
        self.push(&Message::Weights(WeightsReport {
            status: CarStatus::default(),
            snapshot: *snapshot,
        }))?;
        self.inner.restore(snapshot)
    }

    fn act(&mut self, tick: u32, obs: &Observation) -> Result<Decision> {
        self.push(&Message::Observation(ObservationMessage {
            tick,
            observation: obs.clone(),
        }))?;
        self.inner.act(tick, obs)
    }

    fn feedback(&mut self, tick: u32, feedback: &Feedback) -> Result<()> {
        let id = DeliveryId {
            session: 0,
            seq: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        self.push(&Message::Feedback(FeedbackMessage {
            id,
            tick,
            feedback: *feedback,
        }))?;
        self.inner.feedback(tick, feedback)
    }

    fn snapshot(&mut self) -> Result<LearnerSnapshot> {
        self.inner.snapshot()
    }
}

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let Some(out) = args.next() else {
        bail!("usage: record_ticks OUT [STEPS]");
    };
    let steps: u32 = match args.next() {
        Some(s) => s.parse().context("STEPS: not a number")?,
        None => 40,
    };
    let scenario = Arc::new(registry::load_scenario("doors")?);
    let params = LearnerParams::new(LearnerKind::AveragedOgd);
    let mut rec = Recorder {
        inner: InProcessLink::new(params)?,
        out: Vec::new(),
        seq: 0,
    };
    let (mut ticks, mut feedbacks) = (0, 0);
    for kind in FeedbackKind::ALL {
        let config = RunConfig {
            mode: Mode::Online(kind),
            steps,
            seed: 0,
            learner: params,
            ..RunConfig::new(scenario.clone())
        };
        let report = run_with(&config, &mut rec, &mut |_| {})?;
        ticks += report.records.len();
        feedbacks += report.corrections();
    }
    std::fs::write(&out, &rec.out).with_context(|| format!("{out}: cannot write"))?;
    println!(
        "{out}: {ticks} observations and {feedbacks} feedbacks of doors runs (one per kind of feedback, in FeedbackKind order; seed 0), {} bytes",
        rec.out.len()
    );
    Ok(())
}
