//! What the test modules share: running the `host-sim` binary and reading what it said, and a
//! plain HTTP GET of the console.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::{Command, Output};

/// Runs the `host-sim` binary Cargo built for these tests with `args`, to completion.
pub(crate) fn host_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// The run's standard error as text (lossy: the assertions only look for words).
pub(crate) fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Status line and body of a GET of `path` on `authority` with extra header lines.
pub(crate) fn get(authority: &str, path: &str, headers: &str) -> (String, String) {
    let mut s = TcpStream::connect(authority).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {authority}\r\n{headers}Connection: close\r\n\r\n"
    )
    .unwrap();
    let mut bytes = Vec::new();
    s.read_to_end(&mut bytes).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    let status = text.lines().next().unwrap_or_default().to_string();
    let body = text
        .split("\r\n\r\n")
        .nth(1)
        .unwrap_or_default()
        .to_string();
    (status, body)
}
