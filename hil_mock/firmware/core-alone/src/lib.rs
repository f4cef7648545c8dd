//! firmware-core for `thumbv7em-none-eabihf` with no feature on (no `max-size`, no `std`): built
//! by CI as the car's image is (see this crate's `Cargo.toml`). A failure here is code of
//! firmware-core that compiles only with a feature some other crate turns on.
#![no_std]

pub use firmware_core;
