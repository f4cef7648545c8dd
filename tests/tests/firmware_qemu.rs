//! The learner as firmware: a fixed-seed simulator run through the thumbv7em image under QEMU,
//! over slcan on the emulated UART, driven by host-sim's [`RemoteCar`] (what
//! `host-sim run --link slcan+tcp://…` uses), gives the same per-step CSV and the same final
//! weights, bit for bit, as the same run with the agent in this process.
//!
//! Ignored by default: it needs `qemu-system-arm` and the firmware image. `.ci/run` runs it after
//! `scripts/setup-qemu` and the image's build:
//!
//! ```text
//! scripts/setup-qemu
//! export CAR_KEY_FILE=$PWD/target/car.key; [ -f $CAR_KEY_FILE ] || cargo run -p hil_mock -- keygen $CAR_KEY_FILE
//! (cd hil_mock/firmware && cargo build --release)
//! cargo test -p tests --test firmware_qemu -- --ignored
//! ```
//!
//! The image holds the car's key from build time (`CAR_KEY_FILE=FILE` when it is built); the
//! test reads the same file from the same variable. `CAR_FIRMWARE_IMAGE` overrides the image's
//! path. QEMU listens on a port of 127.0.0.1 it picks
//! itself and is killed when the test ends, however it ends. No assertion depends on time: the
//! client waits for each answer up to a generous deadline only so that a broken image fails
//! instead of hanging, and a late answer costs a retransmission, never a different result.

use std::io::{BufRead, BufReader};
use std::net::{Ipv4Addr, SocketAddrV4};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use firmware_core::{LearnerKind, LearnerParams, LearnerSnapshot};
use hil_mock::transport::slcan::SlcanLink;
use host_sim::teach::experiment::{Mode, RunConfig, run, run_with};
use host_sim::teach::record::RunReport;
use host_sim::teach::remote::{RemoteCar, RemoteConfig};
use host_sim::world::registry;
use host_sim::world::teacher::FeedbackKind;
use protocol::isotp::FrameMode;

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

/// Starts QEMU with UART0 on a TCP server of 127.0.0.1 at a port QEMU picks (port 0, no race);
/// returns it and the port, read from QEMU's "waiting for connection" line.
fn start_qemu(mode: &str) -> Result<(Qemu, u16)> {
    let image = image();
    if !image.is_file() {
        bail!(
            "{}: no firmware image; build it with (cd hil_mock/firmware && cargo build --release)",
            image.display()
        );
    }
    let mut child = Command::new("qemu-system-arm")
        .args(["-machine", "mps2-an386", "-cpu", "cortex-m4", "-nographic"])
        .args(["-monitor", "none"])
        // nodelay: every byte the UART sends goes out at once (Nagle's algorithm would hold the
        // small writes back for the peer's delayed acks, tens of ms per answer).
        .args(["-serial", "tcp:127.0.0.1:0,server,nodelay=on"])
        .arg("-semihosting-config")
        .arg(format!(
            "enable=on,target=native,arg=car-firmware,arg={mode}"
        ))
        .arg("-kernel")
        .arg(&image)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .context("qemu-system-arm: not installed? (scripts/setup-qemu)")?;
    let stderr = child.stderr.take().context("QEMU's stderr")?;
    let qemu = Qemu(child);
    let mut lines = BufReader::new(stderr).lines();
    let marker = "waiting for connection on: disconnected:tcp:127.0.0.1:";
    let port = loop {
        let Some(line) = lines.next() else {
            bail!("QEMU ended without opening its serial port");
        };
        let line = line?;
        if let Some(rest) = line.split(marker).nth(1) {
            let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
            break digits
                .parse::<u16>()
                .with_context(|| format!("port in {line:?}"))?;
        }
    };
    // Keep draining QEMU's stderr so that it never blocks on a full pipe.
    std::thread::spawn(move || lines.for_each(drop));
    Ok((qemu, port))
}

/// The snapshot's exact bytes (postcard keeps every f32's bit pattern).
fn bytes_of(snapshot: &LearnerSnapshot) -> Vec<u8> {
    let mut buf = [0u8; protocol::MAX_MESSAGE_SIZE];
    protocol::seal(snapshot, &mut buf).unwrap().to_vec()
}

/// The key the image was built with: the file named by `CAR_KEY_FILE`.
fn car_key() -> Result<protocol::secure::Key> {
    let path = std::env::var_os("CAR_KEY_FILE").context(
        "CAR_KEY_FILE: the key file the firmware image was built with (hil_mock keygen FILE)",
    )?;
    Ok(hil_mock::key::read_key_file(std::path::Path::new(&path))?)
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
    bit_identical_through_qemu(&config, &here)
}

/// A mixed stream (issue 15): every kind of feedback in one run, the kind of each correction
/// drawn from the run's seed (`mix:all`), spans over several ticks and E-stops that hold the
/// car included.
#[test]
#[ignore = "needs qemu-system-arm and the firmware image; .ci/run runs it"]
fn qemu_firmware_mixed_stream_is_bit_identical_to_the_in_process_run() -> Result<()> {
    let scenario = Arc::new(registry::load_scenario("doors")?);
    let config = RunConfig {
        mode: Mode::parse("mix:all").map_err(anyhow::Error::msg)?,
        steps: 150,
        seed: 5,
        learner: LearnerParams::new(LearnerKind::AveragedOgd),
        ..RunConfig::new(scenario)
    };
    let here = run(&config)?;
    let kinds = here.kind_counts();
    assert!(
        kinds.iter().filter(|&&n| n > 0).count() >= 7,
        "the stream must mix most kinds: {kinds:?}"
    );
    bit_identical_through_qemu(&config, &here)
}

/// Runs `config` through the QEMU firmware; the per-step CSVs and the final learners must be
/// those of `here`, the same run in process, bit for bit.
fn bit_identical_through_qemu(config: &RunConfig, here: &RunReport) -> Result<()> {
    assert!(here.corrections() > 0, "the run must exercise learning");

    let (_qemu, port) = start_qemu("serve")?;
    let addr = SocketAddrV4::new(Ipv4Addr::LOCALHOST, port);
    let link = SlcanLink::connect_tcp(addr, Duration::from_secs(30))?;
    // Classic CAN both ways, as a Lawicel adapter carries; QEMU's UART moves about 25 KB/s, so
    // an observation (about 880 bytes of slcan lines) takes some 35 ms: wait a second per try.
    let mut car = RemoteCar::new(
        link,
        RemoteConfig {
            mode: FrameMode::Classic,
            try_timeout: Duration::from_secs(1),
            deadline: Duration::from_secs(60),
            key: car_key()?,
        },
    );
    let there = run_with(config, &mut car, &mut |_| {})?;

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

/// The image's slcan receiver survives what a serial line can bring: adapter commands, malformed
/// and overlong lines, stray bytes; the `echo` mode answers each frame with the bus's counters.
#[test]
#[ignore = "needs qemu-system-arm and the firmware image; .ci/run runs it"]
fn qemu_firmware_slcan_survives_garbage() -> Result<()> {
    use std::io::{Read, Write};
    let (_qemu, port) = start_qemu("echo")?;
    let mut s = std::net::TcpStream::connect((Ipv4Addr::LOCALHOST, port))?;
    s.set_read_timeout(Some(Duration::from_secs(30)))?;
    let mut input = Vec::new();
    input.extend_from_slice(b"C\rS8\rO\r"); // a host opening the adapter: three OKs
    input.extend_from_slice(b"t12\rt1239\rtXYZ0\rt1\xff30\r"); // four malformed lines
    input.extend_from_slice(b"\0\xff\r"); // a stray "command" 0x00: BEL
    input.extend_from_slice(&[b'7'; 1000]); // an overlong line, then its end
    input.extend_from_slice(b"\rq\r\x07z\r"); // an unknown command, BEL, a transmit ack
    input.extend_from_slice(b"t1232AB01\r"); // and a frame
    s.write_all(&input)?;
    let mut got = Vec::new();
    let mut buf = [0u8; 256];
    while !got.ends_with(b"\r") || !got.contains(&b't') {
        let n = s.read(&mut buf)?;
        if n == 0 {
            bail!(
                "QEMU closed the line; got {:?}",
                String::from_utf8_lossy(&got)
            );
        }
        got.extend_from_slice(&buf[..n]);
    }
    // Replies: \r to C, S8, O; BEL to 0x00 and to q; then the echo of the frame on id 0x124
    // with the counters frames 1, malformed 4, overlong 1, commands 5 (little-endian u16 each).
    assert_eq!(
        String::from_utf8_lossy(&got),
        "\r\r\r\x07\x07t12480100040001000500\r"
    );
    Ok(())
}
