//! The car's node as a whole: any sequence of frames (raw, or messages sealed with the car's key
//! so that they pass authentication), polls and restarts gives no panic; everything the node
//! sends opens at the host as an authentic message; the state it persists always reopens, and a
//! node restored from it persists the same state.
//!
//! Input: records, each starting with a byte `op`:
//! * `op & 3 == 0`: a raw frame: `[ctrl][len][data…]` as in `reassembler_feed`;
//! * `op & 3 == 1`: a message: `[n][n bytes]` decoded as a postcard payload
//!   (`Message::decode_payload`); if it decodes and travels host → car it is sealed by the host
//!   and its frames (CAN FD if `op & 4`, else classic) go to the node;
//! * `op & 3 == 2`: time passes (`op >> 2` × 8 ms) and the node is polled;
//! * `op & 3 == 3`: the car restarts from what it persisted, in a new epoch, and the host
//!   follows it.
#![no_main]

use firmware_core::{Learner, ValidLearnerParams};
use libfuzzer_sys::fuzz_target;
use protocol::can::{CanBus, CanFrame, CanId, FD_LENGTHS};
use protocol::car::{CarConfig, CarNode, Persist, Persisted, PERSISTED_MAX_SIZE};
use protocol::isotp::FrameMode;
use protocol::link::{Inbox, LinkError, Received, transmit};
use protocol::message::Message;
use protocol::secure::{HostSecurity, Key};
use protocol::stream::{Class, Direction, Stream};

const KEY: Key = Key::new([0x42; 16]);

#[derive(Default)]
struct Wire(Vec<CanFrame>);

impl CanBus for Wire {
    type Error = ();
    fn transmit(&mut self, f: &CanFrame) -> Result<(), ()> {
        self.0.push(*f);
        Ok(())
    }
    fn receive(&mut self) -> Result<Option<CanFrame>, ()> {
        Ok(None)
    }
}

#[derive(Default)]
struct Ram(Option<Persisted>);

impl Persist for Ram {
    type Error = ();
    fn persist(&mut self, state: &Persisted) -> Result<(), ()> {
        self.0 = Some(state.clone());
        Ok(())
    }
}

/// The host's side, in step with the node's epoch; checks what the node sends.
struct Host {
    security: HostSecurity,
    inbox: Inbox,
}

impl Host {
    fn new(epoch: u32) -> Self {
        Self {
            security: HostSecurity::assume_fresh_car(&KEY, epoch),
            inbox: Inbox::new(Direction::CarToHost),
        }
    }

    fn check(&mut self, out: &Wire) {
        for f in &out.0 {
            match self.inbox.feed(f, 0, &mut self.security) {
                Received::Error(LinkError::Refused(..) | LinkError::Decode(..)) => {
                    panic!("the node sent a message the host cannot open")
                }
                _ => {}
            }
        }
    }
}

fn id(selector: u8) -> CanId {
    match selector {
        0..=5 => Stream::new(Class::ALL[selector as usize], Direction::HostToCar).id(),
        6 => Stream::new(Class::Heartbeat, Direction::CarToHost).id(),
        _ => CanId::Standard(0x7FF),
    }
}

fn node(epoch: u32) -> CarNode {
    let mut n = CarNode::new(CarConfig::DEFAULT, Learner::new(ValidLearnerParams::DEFAULT));
    n.install_key(&KEY, epoch);
    n
}

fuzz_target!(|data: &[u8]| {
    let mut epoch = 1;
    let mut car = node(epoch);
    let mut host = Host::new(epoch);
    let mut flash = Ram::default();
    let mut now = 0u32;
    let mut rest = data;
    while let [op, tail @ ..] = rest {
        rest = tail;
        let mut frames = Vec::new();
        match op & 3 {
            0 => {
                let [ctrl, len, tail @ ..] = rest else { break };
                let fd = ctrl & 0x08 != 0;
                let n = if fd {
                    FD_LENGTHS[(len & 0x0F) as usize]
                } else {
                    ((len & 0x0F) as usize).min(8)
                };
                let mut bytes = [0u8; 64];
                let take = n.min(tail.len());
                bytes[..take].copy_from_slice(&tail[..take]);
                rest = &tail[take..];
                now = now.wrapping_add(4 * (ctrl >> 4) as u32);
                let id = id(ctrl & 0x07);
                let f = if fd {
                    CanFrame::new_fd(id, &bytes[..n])
                } else {
                    CanFrame::new(id, &bytes[..n])
                };
                frames.push(f.expect("valid lengths by construction"));
            }
            1 => {
                let [n, tail @ ..] = rest else { break };
                let n = (*n as usize).min(tail.len());
                let (payload, tail) = tail.split_at(n);
                rest = tail;
                if let Ok(msg) = Message::decode_payload(payload) {
                    // The host expects the welcome to its hello.
                    if let Message::Hello(h) = &msg {
                        let _ = host.security.hello(h.nonce);
                    }
                    let mode = if op & 4 != 0 { FrameMode::Fd } else { FrameMode::Classic };
                    let mut wire = Wire::default();
                    let _ = transmit(&mut wire, &msg, Direction::HostToCar, mode, &mut host.security);
                    frames = wire.0;
                }
            }
            2 => {
                now = now.wrapping_add(8 * (op >> 2) as u32);
                let mut out = Wire::default();
                let _ = car.poll(now, &mut out);
                host.check(&out);
            }
            _ => {
                // A restart: the node from its flash (a fresh one if nothing was written).
                epoch += 1;
                car = match &flash.0 {
                    Some(state) => {
                        let mut n = CarNode::restore(CarConfig::DEFAULT, state)
                            .expect("a persisted state restores");
                        n.install_key(&KEY, epoch);
                        n
                    }
                    None => node(epoch),
                };
                host = Host::new(epoch);
            }
        }
        for f in &frames {
            let mut out = Wire::default();
            let _ = car.on_frame(f, now, &mut out, &mut flash);
            host.check(&out);
        }
    }
    // What the node persists reopens, through the envelope the flash uses, and restores to a node
    // that persists the same state.
    let state = car.persisted();
    let mut buf = [0u8; PERSISTED_MAX_SIZE];
    let bytes = protocol::seal(&state, &mut buf).expect("the persisted state fits");
    let back: Persisted = protocol::open(bytes).expect("a sealed state opens");
    assert_eq!(back, state);
    let again = CarNode::restore(CarConfig::DEFAULT, &back).expect("a persisted state restores");
    assert_eq!(again.persisted(), state);
});
