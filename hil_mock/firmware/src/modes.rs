//! The measurement modes (cargo feature `bench`, on by default): fixed workloads for instruction
//! counting (`bench-act`, `bench-learn`, `bench-node`, `bench-host`, `bench-mac`, and `replay`
//! with feature `replay`) and the worst-case stack by painting (`stack`).
//!
//! The car node only accepts authenticated messages from a configured session, so the node
//! modes first configure it (the same work for N and for 0 ticks) and seal every message as a
//! host would ([`HostSecurity`] with the built-in key). `bench-host N` does the host's part
//! alone (sealing and segmenting the same messages), so that the node's own work per tick is
//! `(bench-node N − bench-host N) / N`.

use core::convert::Infallible;

use firmware_core::agent::Agent;
use firmware_core::observation::Observation;
use firmware_core::{ActionFeedback, ActionIndex, Feedback, Learner, LearnerParams};
use protocol::MAX_MESSAGE_SIZE;
use protocol::can::{CanBus, CanFrame};
use protocol::car::CarNode;
use protocol::isotp::{FrameMode, Segmenter};
use protocol::message::{
    ConfigureMessage, DeliveryId, FeedbackMessage, Message, ObservationMessage,
};
use protocol::secure::{Authenticator, Endpoint, Freshness, HostSecurity};
use protocol::stream::{Direction, Stream};
use semihosting::{println, process};

use crate::serve::RamStore;
use crate::{EPOCH, bench, car_key, stack};

fn learner() -> Learner {
    let params = LearnerParams::default().with_initial([1.0, 2.0, 1.0, 1.0, -3.0, 0.5]);
    match params.check() {
        Ok(p) => Learner::new(p),
        Err(_) => process::exit(2),
    }
}

fn number(arg: Option<&str>) -> u32 {
    arg.and_then(|s| s.parse().ok()).unwrap_or(0)
}

/// A bus that drops what the node transmits and never receives.
struct NullBus;

impl CanBus for NullBus {
    type Error = Infallible;
    fn transmit(&mut self, _: &CanFrame) -> Result<(), Infallible> {
        Ok(())
    }
    fn receive(&mut self) -> Result<Option<CanFrame>, Infallible> {
        Ok(None)
    }
}

/// The host's side of the node modes: a host in step with a car that just started in
/// [`EPOCH`] with the built-in key.
fn host() -> HostSecurity {
    HostSecurity::assume_fresh_car(&car_key(), EPOCH)
}

/// Seals `msg` as the host and hands it to `node` frame by frame (classic CAN, as on the UART);
/// without a node, only seals and segments it. Returns the deepest stack below the painted mark
/// across the frames, and the deepest from the top of the stack.
fn to_node(
    host: &mut HostSecurity,
    mut node: Option<&mut CarNode>,
    msg: &Message,
    store: &mut RamStore,
    measure: bool,
) -> (usize, usize) {
    let mut buf = [0u8; MAX_MESSAGE_SIZE];
    let Some(stream) = Stream::for_kind(msg.kind(), Direction::HostToCar) else {
        return (0, 0);
    };
    let Ok(bytes) = host.seal(msg, stream, &mut buf) else {
        return (0, 0);
    };
    let Ok(frames) = Segmenter::new(stream.id(), bytes, FrameMode::Classic) else {
        return (0, 0);
    };
    let (mut below, mut top) = (0, 0);
    for frame in frames {
        let Some(node) = node.as_deref_mut() else {
            core::hint::black_box(&frame);
            continue;
        };
        let at = if measure { stack::paint() } else { 0 };
        let _ = node.on_frame(&frame, 0, &mut NullBus, store);
        if measure {
            below = below.max(stack::depth_below(at));
            top = top.max(stack::high_water());
        }
    }
    (below, top)
}

/// Configures `node` (session 1) with the measurement learner, as a host would.
fn configure(host: &mut HostSecurity, node: &mut CarNode, store: &mut RamStore) {
    let msg = Message::Configure(ConfigureMessage {
        session: 1,
        snapshot: learner().snapshot(),
    });
    to_node(host, Some(node), &msg, store, false);
}

fn observation(tick: u32, observation: Observation) -> Message {
    Message::Observation(ObservationMessage { tick, observation })
}

fn feedback(seq: u8, tick: u32, feedback: Feedback) -> Message {
    Message::Feedback(FeedbackMessage {
        id: DeliveryId { session: 1, seq },
        tick,
        feedback,
    })
}

/// Runs measurement mode `mode` with its arguments and exits.
pub fn run<'a>(
    mode: &str,
    mut args: impl Iterator<Item = &'a str>,
    agent: &mut Agent,
    node: &mut CarNode,
) -> ! {
    agent.set_learner(learner());
    match mode {
        "bench-act" => {
            let n = number(args.next());
            let only = args.next().and_then(|s| s.parse().ok());
            let sum = bench::act(agent, n, only);
            println!("bench-act {n} checksum {sum}");
        }
        "bench-learn" => {
            let n = number(args.next());
            let ok = bench::learn(agent, n);
            println!("bench-learn {n} accepted {ok}");
        }
        "bench-node" | "bench-host" => {
            // N ticks through the car node: observation frames in, action frames out; or the
            // host's part alone (sealing, segmenting).
            let n = number(args.next());
            let scenes = bench::scenes();
            let mut store = RamStore::default();
            let mut host = host();
            configure(&mut host, node, &mut store);
            let with_node = mode == "bench-node";
            for t in 0..n {
                let scene = scenes[t as usize % 3].clone();
                let car = with_node.then_some(&mut *node);
                to_node(&mut host, car, &observation(t, scene), &mut store, false);
            }
            println!("{mode} {n} actions {}", node.stats().actions);
        }
        "bench-mac" => {
            // N truncated AES-128-CMACs of a body of LEN bytes (the MAC covers 2 + LEN + 8).
            let n = number(args.next());
            let len = (number(args.next()) as usize).min(MAX_MESSAGE_SIZE);
            let auth = Authenticator::new(&car_key());
            let stream = Stream::for_kind(
                protocol::message::MessageKind::Observation,
                Direction::HostToCar,
            );
            let Some(stream) = stream else {
                process::exit(2)
            };
            let body = [0x5Au8; MAX_MESSAGE_SIZE];
            let mut sum = 0u32;
            for i in 0..n {
                let fv = Freshness {
                    epoch: EPOCH,
                    counter: i,
                };
                let tag = auth.tag(stream, core::hint::black_box(&body[..len]), fv);
                sum = sum.wrapping_add(u32::from_le_bytes(tag));
            }
            println!("bench-mac {n} {len} checksum {sum}");
        }
        "stack" => {
            // Depth of each workload below its caller's frame, and the worst from the top of the
            // stack (every frame above included) over all of them.
            let scenes = bench::scenes();
            let (mut act, mut worst) = (0, 0);
            for (t, scene) in scenes.iter().enumerate() {
                let at = stack::paint();
                let _ = agent.act(t as u32, scene);
                act = act.max(stack::depth_below(at));
                worst = worst.max(stack::high_water());
            }
            let mut learn = 0;
            for i in 0..bench::KINDS {
                let fb = bench::feedback(i);
                let at = stack::paint();
                let _ = agent.feedback(2, &fb);
                learn = learn.max(stack::depth_below(at));
                worst = worst.max(stack::high_water());
            }
            // The car node, frame by frame: a configuration, observations, then each kind of
            // feedback.
            let mut store = RamStore::default();
            let mut host = host();
            let mut car = 0;
            let mut take = |(below, top): (usize, usize)| {
                car = car.max(below);
                worst = worst.max(top);
            };
            let configure = Message::Configure(ConfigureMessage {
                session: 1,
                snapshot: learner().snapshot(),
            });
            take(to_node(&mut host, Some(node), &configure, &mut store, true));
            for (t, scene) in scenes.iter().enumerate() {
                take(to_node(
                    &mut host,
                    Some(node),
                    &observation(t as u32, scene.clone()),
                    &mut store,
                    true,
                ));
            }
            for i in 0..bench::KINDS as u8 {
                let fb = bench::feedback(i as u32);
                take(to_node(
                    &mut host,
                    Some(node),
                    &feedback(i, 2, fb),
                    &mut store,
                    true,
                ));
            }
            let a = ActionIndex::new(5).unwrap_or(ActionIndex::FIRST);
            let fb = Feedback::Action(ActionFeedback { action: a });
            take(to_node(
                &mut host,
                Some(node),
                &feedback(3, 1, fb),
                &mut store,
                true,
            ));
            println!(
                "stack act {act} learn {learn} car-node {car} worst {worst} region {}",
                stack::region()
            );
        }
        #[cfg(feature = "replay")]
        "replay-count" => println!("replay-count {}", crate::replay::count()),
        #[cfg(feature = "replay")]
        "replay" => {
            let last = number(args.next()) as usize;
            // 1 or 0, parsed alike: the two runs of an item differ in nothing but that digit.
            let run_last = number(args.next()) != 0;
            let (what, sum) = crate::replay::replay(agent, last, run_last);
            replay_report(last, what, sum);
        }
        #[cfg(feature = "replay")]
        "replay-all" => crate::replay::replay_all(agent, replay_report),
        other => {
            println!(
                "error: unknown mode {other:?}; expected serve, echo, bench-act N [SCENE], \
                 bench-learn N, bench-node N, bench-host N, bench-mac N LEN, stack, \
                 replay-count, replay I 1|0 or replay-all"
            );
            process::exit(2)
        }
    }
    process::exit(0)
}

/// The line `replay I 1|0` ends with, and `replay-all` prints after each piece (the same
/// instructions in both, never inlined: see [`crate::replay::step`]).
#[cfg(feature = "replay")]
#[inline(never)]
fn replay_report(last: usize, what: crate::replay::Last, sum: u32) {
    use crate::replay::Last;
    match what {
        Last::Restore => println!("replay {last} restore checksum {sum}"),
        Last::Act(t, a) => println!("replay {last} act tick {t} action {a} checksum {sum}"),
        Last::Feedback(t, ok) => {
            println!("replay {last} feedback tick {t} applied {ok} checksum {sum}")
        }
        Last::Other => println!("replay {last} other checksum {sum}"),
    }
}
