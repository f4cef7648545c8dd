//! # protocol: the wire between the host and the car
//!
//! `no_std`, no heap, no `unsafe` (DESIGN section 7).
//!
//! * [`can`]: checked CAN / CAN FD frames and the [`can::CanBus`] trait transports implement.
//! * [`envelope`]: the versioned, CRC-checked postcard envelope.
//!
//! Every message travels inside an
//! [`envelope`]: a protocol version byte, the postcard encoding of the value, and a CRC-16 over
//! both. Decoding is total: any byte sequence gives a value or an [`EnvelopeError`], never a
//! panic.

#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod can;
pub mod delivery;
pub mod envelope;
pub mod isotp;
pub mod link;
pub mod message;
pub mod stream;

pub use envelope::{ENVELOPE_OVERHEAD, EnvelopeError, PROTOCOL_VERSION, open, seal};
