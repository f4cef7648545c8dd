//! `hil_mock`: the car's controller, stood in for. See `hil_mock::cli`.

fn main() -> std::process::ExitCode {
    hil_mock::cli::main()
}
