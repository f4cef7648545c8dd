//! Helpers shared by the end-to-end tests over a link (`link.rs`, `attack.rs`): the test key,
//! runs in process and over a link, a car node in a thread, `hil_mock` as a child process.
//!
//! Each test file uses a part of them.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use firmware_core::observation::Observation;
use hil_mock::server::Server;
use hil_mock::transport::Link;
use hil_mock::transport::udp::UdpLink;
use host_sim::teach::experiment::{self, CarLink, RunConfig};
use host_sim::teach::record::RunReport;
use host_sim::teach::remote::{RemoteCar, RemoteConfig, RemoteStats};
use protocol::car::{CarConfig, CarStats};
use protocol::isotp::FrameMode;
use protocol::secure::Key;

pub(crate) const SEED: u64 = 11;

/// The key of every car and host in these tests.
pub(crate) const KEY: Key = Key::new([0x4B; 16]);

/// Writes [`KEY`] to a key file in `dir` (as `hil_mock keygen` would, with a known key).
pub(crate) fn key_file(dir: &Path) -> std::path::PathBuf {
    let path = dir.join("car.key");
    let mut text = KEY.to_hex().to_vec();
    text.push(b'\n');
    std::fs::write(&path, text).unwrap();
    path
}

pub(crate) fn config(steps: u32) -> RunConfig {
    let scenario = host_sim::world::registry::load_scenario("doors").unwrap();
    RunConfig {
        steps,
        seed: SEED,
        ..RunConfig::new(Arc::new(scenario))
    }
}

pub(crate) fn remote_config(mode: FrameMode) -> RemoteConfig {
    RemoteConfig {
        mode,
        try_timeout: Duration::from_millis(3),
        deadline: Duration::from_secs(30),
        ..RemoteConfig::new(KEY)
    }
}

/// A `CarNode` serving `link` in a thread until stopped; gives back its counters.
pub(crate) struct ServerThread {
    stop: Arc<AtomicBool>,
    handle: JoinHandle<CarStats>,
}

impl ServerThread {
    /// A car in epoch 7 with [`KEY`], never configured.
    pub(crate) fn spawn<L: Link + 'static>(
        open: impl FnOnce() -> L + Send + 'static,
        car: CarConfig,
    ) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let handle = std::thread::spawn(move || {
            let mut link = open();
            let mut server = Server::in_memory(car, &KEY, 7);
            match server.run(&mut link, &flag) {
                // The host hung up (a memory link's other end dropped): the end of the test.
                Ok(()) | Err(hil_mock::transport::LinkError::Closed(_)) => {}
                Err(e) => panic!("the server's link: {e}"),
            }
            server.node().stats()
        });
        Self { stop, handle }
    }

    pub(crate) fn stop(self) -> CarStats {
        self.stop.store(true, Ordering::Relaxed);
        self.handle.join().expect("the server thread")
    }
}

pub(crate) fn car(mode: FrameMode) -> CarConfig {
    CarConfig {
        mode,
        ..CarConfig::default()
    }
}

pub(crate) fn remote_run<L: Link>(
    config: &RunConfig,
    link: L,
    mode: FrameMode,
) -> (RunReport, RemoteStats) {
    let mut remote = RemoteCar::new(link, remote_config(mode));
    let report = experiment::run_with(config, &mut remote, &mut |_| {}).unwrap();
    (report, remote.stats())
}

#[track_caller]
pub(crate) fn assert_same(a: &RunReport, b: &RunReport, what: &str) {
    assert!(
        a.csv_bytes() == b.csv_bytes(),
        "{what}: per-step CSV differs"
    );
    assert_eq!(
        tests::weight_bits(&a.final_snapshot.state.iterate),
        tests::weight_bits(&b.final_snapshot.state.iterate),
        "{what}: final iterate"
    );
    assert_eq!(
        tests::weight_bits(&a.final_snapshot.state.average),
        tests::weight_bits(&b.final_snapshot.state.average),
        "{what}: final weights"
    );
    assert_eq!(a.final_snapshot, b.final_snapshot, "{what}: final snapshot");
}

pub(crate) fn udp_pair() -> (UdpLink, UdpLink) {
    let car = UdpLink::listen(SocketAddrV4::new(Ipv4Addr::LOCALHOST, 0)).unwrap();
    let SocketAddr::V4(addr) = car.local_addr().unwrap() else {
        unreachable!("bound on 127.0.0.1")
    };
    let host = UdpLink::connect(addr).unwrap();
    (host, car)
}

/// The `hil_mock` program as a child process, serving with a flash file and [`KEY`].
pub(crate) struct Child9 {
    pub(crate) child: Child,
    pub(crate) port: u16,
    pub(crate) stderr: Arc<Mutex<String>>,
    reader: Option<JoinHandle<()>>,
}

pub(crate) fn spawn_server(flash: &Path, port: u16) -> Child9 {
    spawn_server_on(flash, "udp-listen", port)
}

/// The same, listening with `scheme` (`udp-listen`, `slcan+tcp-listen`).
pub(crate) fn spawn_server_on(flash: &Path, scheme: &str, port: u16) -> Child9 {
    let key = key_file(flash.parent().expect("the flash file is in a folder"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_hil_mock_server"))
        .args(["serve", "--link"])
        .arg(format!("{scheme}://127.0.0.1:{port}"))
        .arg("--key")
        .arg(key)
        .arg("--flash")
        .arg(flash)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start hil_mock");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let port = line
        .trim()
        .rsplit(':')
        .next()
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("hil_mock said {line:?}"));
    let stderr = Arc::new(Mutex::new(String::new()));
    let sink = stderr.clone();
    let err = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        for l in BufReader::new(err).lines().map_while(Result::ok) {
            sink.lock().unwrap().push_str(&(l + "\n"));
        }
    });
    Child9 {
        child,
        port,
        stderr,
        reader: Some(reader),
    }
}

impl Child9 {
    /// The child's stderr so far, once `ready` holds for it (or after 30 s).
    pub(crate) fn stderr_when(&self, ready: impl Fn(&str) -> bool) -> String {
        for _ in 0..30_000 {
            let log = self.stderr.lock().unwrap().clone();
            if ready(&log) {
                return log;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        self.stderr.lock().unwrap().clone()
    }

    pub(crate) fn kill9(&mut self) {
        // `Child::kill` is SIGKILL on Unix.
        self.child.kill().unwrap();
        self.child.wait().unwrap();
        // Its stderr is complete once the reader has seen the end of the pipe.
        if let Some(r) = self.reader.take() {
            let _ = r.join();
        }
    }
}

impl Drop for Child9 {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Waits until `ready` (the supervisor restarted the server); a generous bound turns a stuck
/// supervisor into a failure instead of a hang.
pub(crate) fn wait_for(ready: impl Fn() -> bool) {
    for _ in 0..60_000 {
        if ready() {
            return;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    panic!("the supervisor did not restart hil_mock within a minute");
}

/// A [`CarLink`] that has the car killed (and restarted) before some feedbacks.
pub(crate) struct KillBeforeFeedback<'a, C: CarLink> {
    pub(crate) inner: C,
    pub(crate) feedbacks: u32,
    pub(crate) at: &'a [u32],
    pub(crate) kill: &'a dyn Fn(bool),
}

impl<C: CarLink> CarLink for KillBeforeFeedback<'_, C> {
    fn restore(&mut self, snapshot: &firmware_core::LearnerSnapshot) -> anyhow::Result<()> {
        self.inner.restore(snapshot)
    }
    fn act(
        &mut self,
        tick: u32,
        obs: &Observation,
    ) -> anyhow::Result<firmware_core::agent::Decision> {
        self.inner.act(tick, obs)
    }
    fn feedback(&mut self, tick: u32, feedback: &firmware_core::Feedback) -> anyhow::Result<()> {
        self.feedbacks += 1;
        if self.at.contains(&self.feedbacks) {
            (self.kill)(true);
        }
        self.inner.feedback(tick, feedback)
    }
    fn snapshot(&mut self) -> anyhow::Result<firmware_core::LearnerSnapshot> {
        self.inner.snapshot()
    }
}
