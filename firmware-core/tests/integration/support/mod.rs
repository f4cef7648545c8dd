//! Shared helpers of the integration tests (and of the benchmark, through `#[path]`).
pub(crate) mod naive;
