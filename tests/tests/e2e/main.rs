//! The end-to-end tests across the workspace's crates that run by default, one binary
//! (`cargo test -p tests --test e2e`): each file of this folder is a module, so a test is named
//! `FILE::TEST` (for example `cargo test -p tests --test e2e link::` runs `link.rs`). One binary
//! instead of one per file: each test binary links the whole crate graph, which a fresh clone's
//! `cargo test` paid once per file (issue 17, build time). A new test file goes here as a module.
//! The QEMU tests (`firmware_qemu.rs`, `firmware_budget.rs`, all ignored by default) stay binaries
//! of their own, so that `.ci/run` names them as targets (a missing target is an error, where a
//! filter that matches nothing would pass).

mod attack;
mod common;
mod determinism;
mod link;
mod persistence;
