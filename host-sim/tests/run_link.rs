//! `host-sim run --link`: the same CSV as in process, with the learner in a `hil_mock` server
//! (here a thread on UDP 127.0.0.1) sharing its key, and clear errors for bad link arguments
//! and a missing key.

use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::process::{Command, Output};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use hil_mock::server::Server;
use hil_mock::transport::udp::UdpLink;
use protocol::car::CarConfig;
use protocol::isotp::FrameMode;

fn host_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .expect("the binary runs")
}

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
            "classic or fd",
        ),
    ] {
        let o = host_sim(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?}");
        assert!(err.contains(why), "{args:?}: {err}");
    }
}
