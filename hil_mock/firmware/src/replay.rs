//! Replays ticks recorded from simulator runs (`cargo run -p tests --example record_ticks`), for
//! counting the instructions of real observation → action and feedback → update steps.
//!
//! The record is built into the image (cargo feature `replay`, file named by `REPLAY_TICKS` at
//! build time; see `build.rs`). It is a sequence of items, each a little-endian `u16` length and a
//! sealed protocol message: `Weights` (restore this learner), `Observation` (act) or `Feedback`
//! (learn). `replay I do` runs items 0 to I; `replay I skip` runs items 0 to I-1 and only decodes
//! item I. The difference of the two instruction counts is item I's act or update alone.

use firmware_core::Learner;
use firmware_core::agent::Agent;
use protocol::message::Message;

static TICKS: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/ticks.bin"));

/// The items of the record, in order; stops at the first that does not decode.
fn items() -> impl Iterator<Item = Message> {
    let mut rest = TICKS;
    core::iter::from_fn(move || {
        let (len, tail) = rest.split_first_chunk::<2>()?;
        let len = u16::from_le_bytes(*len) as usize;
        let bytes = tail.get(..len)?;
        rest = &tail[len..];
        Message::parse(bytes).ok()
    })
}

/// Number of items.
pub fn count() -> usize {
    items().count()
}

/// What the last item replayed was.
pub enum Last {
    /// A learner restored.
    Restore,
    /// An observation acted on: its tick and the action (99 for none, 98 refused).
    Act(u32, u32),
    /// Feedback learned from: its tick and whether it was applied.
    Feedback(u32, bool),
    /// Not an item this replay knows.
    Other,
}

/// Replays items 0..=`last`; item `last` itself only if `run_last`. Returns what item `last` was
/// and a checksum of every action chosen.
pub fn replay(agent: &mut Agent, last: usize, run_last: bool) -> (Last, u32) {
    let mut sum = 0u32;
    let mut what = Last::Other;
    for (i, msg) in items().enumerate().take(last + 1) {
        let run = i < last || run_last;
        what = match msg {
            Message::Weights(report) => {
                if run && let Ok(learner) = Learner::restore(&report.snapshot) {
                    agent.set_learner(learner);
                    agent.forget_ticks();
                }
                Last::Restore
            }
            Message::Observation(o) => {
                let mut action = 0;
                if run {
                    action = match agent.act(o.tick, &o.observation) {
                        Ok(d) => d.action.map_or(99, |a| a.get() as u32),
                        Err(_) => 98,
                    };
                    sum = sum.wrapping_mul(31).wrapping_add(action);
                }
                Last::Act(o.tick, action)
            }
            Message::Feedback(f) => {
                let ok = run && agent.feedback(f.tick, &f.feedback).is_ok();
                Last::Feedback(f.tick, ok)
            }
            _ => Last::Other,
        };
    }
    (what, sum)
}
