//! The `hil_mock` program, built in this package so the end-to-end tests can run it as a child
//! process (`CARGO_BIN_EXE_hil_mock_server`) and kill it with SIGKILL.

fn main() -> std::process::ExitCode {
    hil_mock::cli::main()
}
