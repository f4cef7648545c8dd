//! Replays ticks recorded from simulator runs (`cargo run -p tests --example record_ticks`), for
//! counting the instructions of real observation → action and feedback → update steps.
//!
//! The record is built into the image (cargo feature `replay`, file named by `REPLAY_TICKS` at
//! build time; see `build.rs`). It is a sequence of items, each a little-endian `u16` length and a
//! sealed protocol message: `Weights` (restore this learner), `Observation` (act) or `Feedback`
//! (learn). `replay I 1` runs items 0 to I; `replay I 0` runs items 0 to I-1 and only decodes
//! item I. The difference of the two instruction counts is item I's act or update alone (the two
//! command lines differ in one digit, parsed alike: a longer word for the skip cost the skip run
//! some 35 to 50 instructions of parsing more, taken off the item until 2026-12). `replay-all`
//! gives every item's two counts in one run (between marks; see [`replay_all`]), linear in the
//! record where the two runs per item are quadratic; scripts/measure-firmware uses it and checks
//! it against the two runs on the worst items.

use firmware_core::Learner;
use firmware_core::agent::Agent;
use protocol::message::Message;

static TICKS: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/ticks.bin"));

/// The items of the record, in order, each as its bytes; stops at the first that is cut short.
fn items() -> impl Iterator<Item = &'static [u8]> {
    let mut rest = TICKS;
    core::iter::from_fn(move || {
        let (len, tail) = rest.split_first_chunk::<2>()?;
        let len = u16::from_le_bytes(*len) as usize;
        let bytes = tail.get(..len)?;
        rest = &tail[len..];
        Some(bytes)
    })
}

/// Number of items (up to the first that does not decode).
pub fn count() -> usize {
    items().take_while(|b| Message::parse(b).is_ok()).count()
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

/// Decodes item `bytes` and replays it on `agent` if `run`; otherwise only says what it is (`None`
/// if it does not decode). `sum` is the checksum of every action chosen so far (an act run adds
/// its action). Never inlined: the two-run measurement ([`replay`]) and the one-run measurement
/// ([`replay_all`]) execute the same instructions for an item, the message decoded into this
/// function's own frame (the stack pointer is 8-byte aligned at every call, so the data it copies
/// are aligned alike in both), so that both count the same.
#[inline(never)]
pub fn step(agent: &mut Agent, bytes: &[u8], run: bool, sum: &mut u32) -> Option<Last> {
    Some(match Message::parse(bytes).ok()? {
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
                *sum = sum.wrapping_mul(31).wrapping_add(action);
            }
            Last::Act(o.tick, action)
        }
        Message::Feedback(f) => {
            let ok = run && agent.feedback(f.tick, &f.feedback).is_ok();
            Last::Feedback(f.tick, ok)
        }
        _ => Last::Other,
    })
}

/// Replays items 0..=`last`; item `last` itself only if `run_last`. Returns what item `last` was
/// and a checksum of every action chosen.
pub fn replay(agent: &mut Agent, last: usize, run_last: bool) -> (Last, u32) {
    let mut sum = 0u32;
    let mut what = Last::Other;
    for (i, bytes) in items().enumerate().take(last + 1) {
        let run = i < last || run_last;
        match step(agent, bytes, run, &mut sum) {
            Some(w) => what = w,
            None => break,
        }
    }
    (what, sum)
}

/// A point between measured pieces: the instruction counter plugin of scripts/measure-firmware
/// (`hil_mock/firmware/tools/insn_marks.c`) writes down its running count whenever this
/// function starts. Never inlined, so that it has an address of its own.
#[inline(never)]
pub fn mark() {
    core::hint::black_box(());
}

/// Every item in one run: for item I, from the state that items 0 to I-1 left, the item skipped
/// (only decoded) and then run, each followed by `report` (as `replay I 0` and `replay I 1` end)
/// and each between two [`mark`]s. The instructions between the marks of the run less those
/// between the marks of the skip are item I's act or update: what the difference of the two runs
/// `replay I 1` and `replay I 0` gives, since both replay items 0 to I-1 alike and the skip
/// changes nothing. Linear in the number of items where the two runs per item are quadratic.
pub fn replay_all(agent: &mut Agent, mut report: impl FnMut(usize, Last, u32)) {
    let mut sum = 0u32;
    for (i, bytes) in items().enumerate() {
        // Not run, the item changes neither the agent nor the checksum.
        if !piece(agent, i, bytes, false, &mut sum, &mut report)
            || !piece(agent, i, bytes, true, &mut sum, &mut report)
        {
            break;
        }
    }
}

/// One measured piece of [`replay_all`]: item `i` skipped or run and reported, between two marks.
/// Never inlined, and `run` opaque to the compiler, so that the skip and the run execute the same
/// instructions around [`step`] and `report` (the loop's own bookkeeping stays outside the marks).
#[inline(never)]
fn piece(
    agent: &mut Agent,
    i: usize,
    bytes: &[u8],
    run: bool,
    sum: &mut u32,
    report: &mut impl FnMut(usize, Last, u32),
) -> bool {
    mark();
    let what = step(agent, bytes, core::hint::black_box(run), sum);
    let decoded = what.is_some();
    if let Some(what) = what {
        report(i, what, *sum);
    }
    mark();
    decoded
}
