//! The learner as firmware: a fixed-seed simulator run through the thumbv7em image under QEMU,
//! over slcan on the emulated UART, gives the same per-step CSV and the same final weights, bit
//! for bit, as the same run with the agent in this process.
//!
//! Ignored by default: it needs `qemu-system-arm` and the firmware image. `.ci/run` runs it after
//! `scripts/setup-qemu` and the image's build:
//!
//! ```text
//! scripts/setup-qemu
//! (cd hil_mock/firmware && cargo build --release)
//! cargo test -p tests --test firmware_qemu -- --ignored
//! ```
//!
//! `CAR_FIRMWARE_IMAGE` overrides the image's path. QEMU listens on a free port of 127.0.0.1 and
//! is killed when the test ends, however it ends. No assertion depends on time: the client waits
//! for each answer up to a generous deadline only so that a broken image fails instead of hanging.

use std::net::{Ipv4Addr, SocketAddrV4, TcpListener};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use firmware_core::agent::Decision;
use firmware_core::observation::Observation;
use firmware_core::{Feedback, LearnerKind, LearnerParams, LearnerSnapshot};
use hil_mock::transport::Link;
use hil_mock::transport::slcan::SlcanLink;
use host_sim::experiment::{CarLink, Mode, RunConfig, run, run_with};
use host_sim::registry;
use host_sim::teacher::FeedbackKind;
use protocol::can::{CanBus, CanFrame};
use protocol::isotp::FrameMode;
use protocol::link::{Inbox, Received, transmit};
use protocol::message::{
    ConfigureMessage, DeliveryId, FeedbackMessage, Message, ObservationMessage,
};
use protocol::stream::Direction;

/// How long one answer may take before the test gives up (QEMU on a loaded CI machine is slow;
/// a healthy answer takes milliseconds).
const ANSWER_DEADLINE: Duration = Duration::from_secs(30);

/// QEMU running the image, killed on drop.
struct Qemu(Child);

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn image() -> PathBuf {
    std::env::var_os("CAR_FIRMWARE_IMAGE")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../hil_mock/firmware/target/thumbv7em-none-eabihf/release/car-firmware")
        })
}

fn free_port() -> Result<u16> {
    let l = TcpListener::bind((Ipv4Addr::LOCALHOST, 0))?;
    Ok(l.local_addr()?.port())
}

/// Starts QEMU with UART0 on a TCP server at a free port of 127.0.0.1; returns it and the port.
fn start_qemu() -> Result<(Qemu, u16)> {
    let image = image();
    if !image.is_file() {
        bail!(
            "{}: no firmware image; build it with (cd hil_mock/firmware && cargo build --release)",
            image.display()
        );
    }
    let port = free_port()?;
    let child = Command::new("qemu-system-arm")
        .args(["-machine", "mps2-an386", "-cpu", "cortex-m4", "-nographic"])
        .args(["-monitor", "none"])
        .arg("-serial")
        // nodelay: every byte the UART sends goes out at once (Nagle's algorithm would hold the
        // small writes back for the peer's delayed acks, tens of ms per answer).
        .arg(format!("tcp:127.0.0.1:{port},server,nodelay=on"))
        .args(["-semihosting-config", "enable=on,target=native"])
        .arg("-kernel")
        .arg(&image)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .spawn()
        .context("qemu-system-arm: not installed? (scripts/setup-qemu)")?;
    Ok((Qemu(child), port))
}

/// A hil_mock link as the protocol's bus.
struct Bus<'a>(&'a mut dyn Link);

impl CanBus for Bus<'_> {
    type Error = hil_mock::transport::LinkError;
    fn transmit(&mut self, frame: &CanFrame) -> Result<(), Self::Error> {
        self.0.send(frame)
    }
    fn receive(&mut self) -> Result<Option<CanFrame>, Self::Error> {
        self.0.recv(Duration::ZERO)
    }
}

/// The learner on the firmware, as the experiment sees it: every call one request and its
/// answer over the link.
struct FirmwareCar {
    link: SlcanLink,
    inbox: Inbox,
    started: Instant,
    session: u8,
    seq: u8,
}

impl FirmwareCar {
    fn send(&mut self, msg: &Message) -> Result<()> {
        transmit(
            &mut Bus(&mut self.link),
            msg,
            Direction::HostToCar,
            FrameMode::Classic,
        )
        .map_err(|e| anyhow::anyhow!("sending {:?}: {e}", msg.kind()))?;
        Ok(())
    }

    /// Waits for the first message `pick` accepts; others (heartbeats, watchdog stops) are
    /// skipped, error reports fail.
    fn wait<T>(&mut self, what: &str, mut pick: impl FnMut(&Message) -> Option<T>) -> Result<T> {
        let deadline = Instant::now() + ANSWER_DEADLINE;
        while Instant::now() < deadline {
            let Some(frame) = self.link.recv(Duration::from_millis(100))? else {
                continue;
            };
            let now = self.started.elapsed().as_millis() as u32;
            match self.inbox.feed(&frame, now) {
                Received::Nothing => {}
                Received::Error(e) => bail!("waiting for {what}: lost a message from the car: {e}"),
                Received::Message(Message::Error(e)) => {
                    bail!("waiting for {what}: the car reported {e:?}")
                }
                Received::Message(m) => {
                    if let Some(t) = pick(&m) {
                        return Ok(t);
                    }
                }
            }
        }
        bail!("no {what} from the car within {ANSWER_DEADLINE:?}")
    }
}

impl CarLink for FirmwareCar {
    fn restore(&mut self, snapshot: &LearnerSnapshot) -> Result<()> {
        self.session = self.session.wrapping_add(1);
        let session = self.session;
        self.send(&Message::Configure(ConfigureMessage {
            session,
            snapshot: *snapshot,
        }))?;
        let got = self.wait("weights", |m| match m {
            Message::Weights(s) => Some(*s),
            _ => None,
        })?;
        if got != *snapshot {
            bail!("the car restored {got:?}, not {snapshot:?}");
        }
        Ok(())
    }

    fn act(&mut self, tick: u32, obs: &Observation) -> Result<Decision> {
        self.send(&Message::Observation(ObservationMessage {
            tick,
            observation: obs.clone(),
        }))?;
        self.wait("action", |m| match m {
            Message::Action(a) if a.tick == tick => Some(Decision {
                tick,
                action: a.action(),
                allowed: a.allowed,
            }),
            _ => None,
        })
    }

    fn feedback(&mut self, tick: u32, feedback: &Feedback) -> Result<()> {
        let id = DeliveryId {
            session: self.session,
            seq: self.seq,
        };
        self.seq = self.seq.wrapping_add(1);
        self.send(&Message::Feedback(FeedbackMessage {
            id,
            tick,
            feedback: *feedback,
        }))?;
        let acked = self.wait("ack", |m| match m {
            Message::Ack(a) if a.id == id => Some(true),
            Message::Nack(n) if n.id == id => Some(false),
            _ => None,
        })?;
        if !acked {
            bail!("tick {tick}: the car refused the feedback");
        }
        Ok(())
    }

    fn snapshot(&mut self) -> Result<LearnerSnapshot> {
        self.send(&Message::WeightsRequest)?;
        self.wait("weights", |m| match m {
            Message::Weights(s) => Some(*s),
            _ => None,
        })
    }
}

/// The snapshot's exact bytes (postcard keeps every f32's bit pattern).
fn bytes_of(snapshot: &LearnerSnapshot) -> Vec<u8> {
    let mut buf = [0u8; protocol::MAX_MESSAGE_SIZE];
    Message::Weights(*snapshot).emit(&mut buf).unwrap().to_vec()
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware image; .ci/run runs it"]
fn qemu_firmware_run_is_bit_identical_to_the_in_process_run() -> Result<()> {
    let scenario = Arc::new(registry::load_scenario("doors")?);
    let config = RunConfig {
        mode: Mode::Online(FeedbackKind::Action),
        steps: 150,
        seed: 3,
        learner: LearnerParams::new(LearnerKind::AveragedOgd),
        ..RunConfig::new(scenario)
    };
    let here = run(&config)?;
    assert!(here.corrections() > 0, "the run must exercise learning");

    let (_qemu, port) = start_qemu()?;
    let addr = SocketAddrV4::new(Ipv4Addr::LOCALHOST, port);
    let link = SlcanLink::connect_tcp(addr, Duration::from_secs(30))?;
    let mut car = FirmwareCar {
        link,
        inbox: Inbox::new(Direction::CarToHost),
        started: Instant::now(),
        session: 0,
        seq: 0,
    };
    let there = run_with(&config, &mut car, &mut |_| {})?;

    assert_eq!(
        String::from_utf8_lossy(&there.csv_bytes()),
        String::from_utf8_lossy(&here.csv_bytes()),
        "per-step CSV through the QEMU firmware"
    );
    assert_eq!(
        bytes_of(&there.final_snapshot),
        bytes_of(&here.final_snapshot),
        "final learner state through the QEMU firmware: {:?} vs {:?}",
        there.final_snapshot,
        here.final_snapshot
    );
    assert_eq!(
        tests::weight_bits(&there.final_snapshot.state.average),
        tests::weight_bits(&here.final_snapshot.state.average)
    );
    Ok(())
}
