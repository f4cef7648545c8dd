//! `host-sim run --link`: the same CSV as in process, with the learner in a `hil_mock` server
//! (here a thread on UDP 127.0.0.1) sharing its key, and clear errors for bad link arguments
//! and a missing key.

use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::support::host_sim;
use hil_mock::server::Server;
use hil_mock::transport::udp::UdpLink;
use protocol::car::CarConfig;
use protocol::isotp::FrameMode;

#[test]
fn run_over_udp_writes_the_same_csv_as_in_process() {
    let mut car = UdpLink::listen(SocketAddrV4::new(Ipv4Addr::LOCALHOST, 0)).unwrap();
    let SocketAddr::V4(addr) = car.local_addr().unwrap() else {
        unreachable!("bound on 127.0.0.1")
    };
    let tmp = tempfile::tempdir().unwrap();
    let dir = |name: &str| tmp.path().join(name).to_str().unwrap().to_string();
    let key_file = dir("car.key");
    let key = hil_mock::key::keygen(std::path::Path::new(&key_file)).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let server = std::thread::spawn(move || {
        let mut s = Server::in_memory(
            CarConfig {
                mode: FrameMode::Fd,
                ..CarConfig::default()
            },
            &key,
            42,
        );
        s.run(&mut car, &flag).unwrap();
        s.node().stats()
    });
    let common = [
        "run",
        "--scenario",
        "doors",
        "--steps",
        "200",
        "--seed",
        "5",
    ];
    let local = host_sim(&[&common[..], &["--out", &dir("local")]].concat());
    assert!(local.status.success(), "{local:?}");
    let link = format!("udp://{addr}");
    let log = dir("host.log");
    let remote = host_sim(
        &[
            &common[..],
            &[
                "--out",
                &dir("remote"),
                "--link",
                &link,
                "--key",
                &key_file,
                "--record",
                &log,
            ],
        ]
        .concat(),
    );
    stop.store(true, Ordering::Relaxed);
    let stats = server.join().unwrap();
    assert!(remote.status.success(), "{remote:?}");
    let csv = |d: &str| std::fs::read(tmp.path().join(d).join("steps.csv")).unwrap();
    assert!(csv("local") == csv("remote"), "the CSVs differ");
    assert_eq!(stats.observations as usize, 200);
    assert!(
        std::fs::read_to_string(&log)
            .unwrap()
            .contains(" can0 104##")
    );
}

#[test]
fn bad_link_arguments_are_clear_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().to_str().unwrap();
    for (args, why) in [
        (
            vec![
                "run",
                "--out",
                out,
                "--insecure",
                "--link",
                "udp://10.0.0.1:4000",
            ],
            "127.0.0.1",
        ),
        (
            vec!["run", "--out", out, "--insecure", "--link", "pigeon://x"],
            "scheme",
        ),
        // No key: the host refuses to start, and says how to get one.
        (
            vec!["run", "--out", out, "--link", "udp://127.0.0.1:9"],
            "hil_mock keygen",
        ),
        (
            vec![
                "run",
                "--out",
                out,
                "--link",
                "udp://127.0.0.1:9",
                "--key",
                "/nonexistent/car.key",
            ],
            "/nonexistent/car.key",
        ),
        (vec!["run", "--out", out, "--record", "x.log"], "--link"),
        (
            vec![
                "run",
                "--out",
                out,
                "--insecure",
                "--link",
                "udp://127.0.0.1:9",
                "--faults",
                "drop=3",
            ],
            "not in [0, 1]",
        ),
        (
            vec![
                "run",
                "--out",
                out,
                "--insecure",
                "--link",
                "udp://127.0.0.1:9",
                "--frame-mode",
                "x",
            ],
            "[possible values: classic, fd]",
        ),
    ] {
        let o = host_sim(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}");
        assert!(err.contains(why), "{args:?}: {err}");
    }
}

/// Issue 14, item 3: a car restarted on a flash that lost what it learned used to serve a fresh
/// learner while `host-sim` finished with exit 0. Now the run stops with a non-zero exit that
/// names the loss. (The car runs in a thread here; a restart is a new server on the same socket
/// and flash file, with a new epoch.)
#[test]
fn run_over_a_link_fails_naming_the_loss_when_the_car_loses_its_flash() {
    use hil_mock::flash::{HEADER_SIZE, Open, PAGE_SIZE, decode_pages};
    use std::time::{Duration, Instant};
    let tmp = tempfile::tempdir().unwrap();
    let key_file = tmp.path().join("car.key");
    let key = hil_mock::key::keygen(&key_file).unwrap();
    let flash = tmp.path().join("car.flash");
    // The car's socket outlives a restart (the thread hands it back): a restart that bound the
    // port again could find it taken by another process on a busy machine.
    let serve = |mut link: UdpLink, epoch: u32, stop: Arc<AtomicBool>| {
        let (key, flash) = (key.clone(), flash.clone());
        std::thread::spawn(move || {
            let config = CarConfig {
                mode: FrameMode::Fd,
                ..CarConfig::default()
            };
            let (mut s, _) =
                Server::with_flash(config, &flash, Open::Existing, &key, epoch).expect("the flash");
            s.run(&mut link, &stop).unwrap();
            link
        })
    };
    let link = UdpLink::listen(SocketAddrV4::new(Ipv4Addr::LOCALHOST, 0)).expect("a port");
    let SocketAddr::V4(addr) = link.local_addr().unwrap() else {
        unreachable!("bound on 127.0.0.1")
    };
    let stop = Arc::new(AtomicBool::new(false));
    let first = serve(link, 1, stop.clone());
    let child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args([
            "run",
            "--scenario",
            "doors",
            "--steps",
            "5000",
            "--seed",
            "5",
        ])
        .arg("--out")
        .arg(tmp.path().join("out"))
        .args(["--link", &format!("udp://{addr}"), "--key"])
        .arg(&key_file)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Once the car has applied three corrections: a power cut that garbles both flash pages.
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let bytes = std::fs::read(&flash).unwrap_or_default();
        let (_, restored) = decode_pages(&bytes);
        if restored.is_some_and(|r| r.state.generation >= 3) {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "no three corrections within a minute"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    stop.store(true, Ordering::Relaxed);
    let link = first.join().unwrap();
    let mut bytes = std::fs::read(&flash).unwrap();
    for page in 0..2 {
        bytes[HEADER_SIZE + page * PAGE_SIZE + 40] ^= 0x01;
    }
    std::fs::write(&flash, bytes).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let second = serve(link, 2, stop.clone());
    let out = child.wait_with_output().unwrap();
    stop.store(true, Ordering::Relaxed);
    second.join().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "host-sim must fail: {err}");
    assert!(
        err.contains("the car lost what it was taught") && err.contains("unreadable or erased"),
        "{err}"
    );
}
