//! The `hil_mock` program as a user meets it: a closed pipe ends a command quietly, and an error
//! says its cause once.

use std::process::{Command, Output, Stdio};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs `hil_mock args` with its standard output a pipe whose reader has gone.
fn into_closed_pipe(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_hil_mock"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary runs");
    drop(child.stdout.take());
    child.wait_with_output().expect("the binary ends")
}

/// `hil_mock bench-latency | head -1`: exit 0, nothing on stderr.
#[test]
fn a_closed_pipe_ends_a_command_quietly() {
    let tmp = tempfile::tempdir().unwrap();
    let key = tmp.path().join("car.key");
    for args in [
        &["bench-latency", "--count", "50"][..],
        &["keygen", key.to_str().unwrap()],
    ] {
        let o = into_closed_pipe(args);
        assert!(
            o.status.success(),
            "{args:?}: {:?} {}",
            o.status,
            stderr(&o)
        );
        assert_eq!(stderr(&o), "", "{args:?}");
    }
    assert!(
        key.is_file(),
        "keygen wrote its key before it found nobody reading"
    );
}

/// A refused connection is said once ("Connection refused (os error 111)"), not once per layer.
#[test]
fn a_refused_connection_is_said_once() {
    let tmp = tempfile::tempdir().unwrap();
    let log = tmp.path().join("bus.log");
    let frame = "(1700000000.000000) can0 104#0102\n";
    std::fs::write(&log, frame.repeat(3)).unwrap();
    // A port that was free a moment ago: nothing listens on it, and the second datagram sent
    // there meets the refusal the first one brought back.
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let o = Command::new(env!("CARGO_BIN_EXE_hil_mock"))
        .args([
            "replay",
            log.to_str().unwrap(),
            "--link",
            &format!("udp://127.0.0.1:{port}"),
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let e = stderr(&o);
    assert_eq!(e.matches("Connection refused").count(), 1, "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
}
