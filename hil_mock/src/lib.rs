//! # hil_mock: the car's controller, stood in for
//!
//! A process that runs the `firmware-core` learner behind the `protocol` crate, as the car's
//! Cortex-M4F would (DESIGN section 2).
//!
//! * [`server`]: the car's controller over a link: a `protocol::car::CarNode` (the same state
//!   machine the firmware runs), its flash, the poll loop.
//! * `cli` (feature `cli`, on by default): the `hil_mock` program: `keygen`, `serve`, `replay`,
//!   `bench-latency`.
//! * [`key`]: key files (`hil_mock keygen`), and the rule that a program talking to the car
//!   refuses to start without a key unless told `--insecure`.
//! * [`flash`]: a file-backed emulation of two flash pages holding the car's persisted state
//!   (learner snapshot, session, generation and feedback dedupe windows), with a CRC and a write
//!   counter, so that a torn or corrupt write never loses the last good state; a file that is
//!   not a flash image is refused.
//! * [`transport`]: CAN links (in-memory, cannelloni over UDP, slcan over TCP or a serial port,
//!   SocketCAN), fault injection and candump recording.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

#[cfg(feature = "cli")]
pub mod cli;
pub mod flash;
pub mod key;
pub mod server;
pub mod transport;
