//! What the test modules share: running the `host-sim` binary and reading what it said.

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
