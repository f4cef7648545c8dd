//! # hil_mock: the car's controller, stood in for
//!
//! A process that runs the `firmware-core` learner behind the `protocol` crate, as the car's
//! Cortex-M4F would (DESIGN section 2).
//!
//! * [`flash`]: a file-backed emulation of two flash pages holding the learner's snapshot, with
//!   a CRC and a generation counter, so that a torn or corrupt write never loses the last good
//!   weights.
//! * [`transport`]: CAN links (in-memory, cannelloni over UDP, slcan over TCP or a serial port,
//!   SocketCAN), fault injection and candump recording.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod flash;
pub mod transport;
