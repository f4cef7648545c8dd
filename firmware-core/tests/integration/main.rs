//! firmware-core's integration tests, one binary (`cargo test -p firmware-core --test
//! integration`): each file of this folder is a module, so a test is named `FILE::TEST` (for
//! example `cargo test -p firmware-core --test integration learning::` runs `learning.rs`). One
//! binary instead of six: each was compiled and linked on its own with proptest and the rest of
//! the graph (issue 17, item 6). A new test file goes here as a module. Proptest keeps the
//! failing cases it found in `../proptest-regressions/FILE.txt` and replays them first.

mod evaluator;
mod kinds;
mod learning;
mod pseudo_loss;
mod reference;
mod round_reference;
mod support;
