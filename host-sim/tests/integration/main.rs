//! host-sim's integration tests, one binary (`cargo test -p host-sim --test integration`): each
//! file of this folder is a module, so a test is named `FILE::TEST` (for example
//! `cargo test -p host-sim --test integration kinds::` runs `kinds.rs`). One binary instead of one
//! per file: each test binary links the whole crate graph (axum, tokio, rayon, plotters, ...),
//! which a fresh clone's `cargo test` paid fourteen times (issue 17, build time). A new test
//! file goes here as a module. `console.rs` holds the browser tests, ignored unless asked for
//! (`-- --ignored console::`; they need chromium and chromedriver).

mod calibration;
mod cli;
mod cli_kinds;
mod console;
mod determinism;
mod generator;
mod households;
mod kinds;
mod learning;
mod maps;
mod reproduce;
mod run_files;
mod run_link;
mod scenarios;
mod support;
mod teach;
