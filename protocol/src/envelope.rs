//! The checked envelope: `[version: u8][postcard payload][CRC-16 little-endian]`: the storage
//! form of the protocol's values (the car's flash pages, recorded ticks). On the wire messages
//! travel authenticated instead ([`crate::secure`]), with a MAC in the place of the CRC.
//!
//! The CRC is CRC-16/IBM-3740 (polynomial 0x1021, initial value 0xFFFF, no reflection; also
//! known as CRC-16/CCITT-FALSE), computed over the version byte and the payload. A receiver
//! checks the length, then the CRC, then the version, then decodes the payload and requires it
//! to use every byte.
//!
//! ```
//! use protocol::{open, seal};
//! let mut buf = [0u8; 16];
//! let bytes = seal(&(7u8, -1i16), &mut buf).unwrap();
//! assert_eq!(open::<(u8, i16)>(bytes), Ok((7, -1)));
//! ```
//!
//! # Checked view and panic contract
//!
//! [`Envelope`] is a view of raw bytes (smoltcp style): [`Envelope::new_checked`] checks the
//! length, the CRC and the version, and after it no accessor panics. [`Envelope::new_unchecked`]
//! only wraps the buffer; its accessors panic on a buffer shorter than [`ENVELOPE_OVERHEAD`].
//! Bytes from outside must go through [`Envelope::new_checked`] (or [`open`], which uses it).
//!
//! ```
//! use protocol::envelope::{Envelope, EnvelopeError};
//! let mut buf = [0u8; 8];
//! let sealed = protocol::seal(&300u16, &mut buf).unwrap();
//! let env = Envelope::new_checked(sealed).unwrap();
//! assert_eq!((env.version(), env.payload()), (4, &[0xAC, 0x02][..]));
//! assert_eq!(Envelope::new_checked(&sealed[..2]).unwrap_err(), EnvelopeError::Truncated);
//! ```

use core::fmt;

use serde::{Deserialize, Serialize};

/// The protocol version this build speaks. A frame of another version is refused.
///
/// History: 1, the first; 2, the action command carries the collision mask, the configure
/// carries a session and a learner snapshot, the weights request is appended; 3, authenticated
/// PDUs on the wire (AES-128-CMAC and freshness, [`crate::secure`]), the observation and the
/// track quantized, stop reasons, the heartbeat without a counter, the car's status in the
/// weights report, the hello/welcome handshake, new nack and error codes; 4, every kind of
/// feedback of the paper's Table 1 (perturbation, reward, correct/incorrect, good/bad spans,
/// rankings, E-stop: variants 3 to 8 of the feedback) and the E-stop's stop reason.
pub const PROTOCOL_VERSION: u8 = 4;

/// Bytes the envelope adds to a payload: the version byte and the CRC.
pub const ENVELOPE_OVERHEAD: usize = 3;

/// The CRC of every envelope.
pub const CRC16: crc::Crc<u16> = crc::Crc::<u16>::new(&crc::CRC_16_IBM_3740);

/// Why an envelope could not be written or read.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum EnvelopeError {
    /// The output buffer is too small for the encoded value.
    BufferTooSmall,
    /// The input is shorter than an empty envelope.
    Truncated,
    /// The CRC does not match.
    Crc,
    /// The frame was written by another protocol version.
    Version(u8),
    /// The payload is not a valid encoding of the expected type.
    Decode,
    /// The payload decoded with bytes left over.
    TrailingBytes,
}

impl fmt::Display for EnvelopeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EnvelopeError::BufferTooSmall => f.write_str("buffer too small for the message"),
            EnvelopeError::Truncated => f.write_str("frame shorter than an envelope"),
            EnvelopeError::Crc => f.write_str("CRC mismatch"),
            EnvelopeError::Version(v) => {
                write!(f, "protocol version {v}, expected {PROTOCOL_VERSION}")
            }
            EnvelopeError::Decode => f.write_str("payload does not decode"),
            EnvelopeError::TrailingBytes => f.write_str("payload has trailing bytes"),
        }
    }
}

impl core::error::Error for EnvelopeError {}

/// Writes `value` into `buf` as an envelope and returns the bytes written.
pub fn seal<'b, T: Serialize + ?Sized>(
    value: &T,
    buf: &'b mut [u8],
) -> Result<&'b [u8], EnvelopeError> {
    if buf.len() < ENVELOPE_OVERHEAD {
        return Err(EnvelopeError::BufferTooSmall);
    }
    buf[0] = PROTOCOL_VERSION;
    let payload_room = buf.len() - ENVELOPE_OVERHEAD;
    let n = postcard::to_slice(value, &mut buf[1..1 + payload_room])
        .map_err(|_| EnvelopeError::BufferTooSmall)?
        .len();
    let crc = CRC16.checksum(&buf[..1 + n]);
    buf[1 + n..3 + n].copy_from_slice(&crc.to_le_bytes());
    Ok(&buf[..3 + n])
}

/// Reads a value from an envelope: [`Envelope::new_checked`], then the payload must decode as
/// a `T` using every byte.
pub fn open<'a, T: Deserialize<'a>>(bytes: &'a [u8]) -> Result<T, EnvelopeError> {
    let payload = Envelope::new_checked(bytes)?.into_payload();
    let (value, rest) = postcard::take_from_bytes(payload).map_err(|_| EnvelopeError::Decode)?;
    if !rest.is_empty() {
        return Err(EnvelopeError::TrailingBytes);
    }
    Ok(value)
}

/// A view of an envelope in a byte buffer: the checked counterpart of [`seal`]'s output.
///
/// See the module documentation for the panic contract.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Envelope<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Envelope<T> {
    /// Wraps `buffer` without checking it: accessors panic if it is shorter than
    /// [`ENVELOPE_OVERHEAD`]. Use [`Envelope::new_checked`] for bytes from outside.
    pub const fn new_unchecked(buffer: T) -> Self {
        Self { buffer }
    }

    /// Wraps `buffer` after checking its length, CRC and version, in that order.
    pub fn new_checked(buffer: T) -> Result<Self, EnvelopeError> {
        let env = Self::new_unchecked(buffer);
        env.check_len()?;
        if env.crc() != env.computed_crc() {
            return Err(EnvelopeError::Crc);
        }
        if env.version() != PROTOCOL_VERSION {
            return Err(EnvelopeError::Version(env.version()));
        }
        Ok(env)
    }

    /// Whether the buffer is long enough for the accessors not to panic.
    pub fn check_len(&self) -> Result<(), EnvelopeError> {
        if self.buffer.as_ref().len() < ENVELOPE_OVERHEAD {
            Err(EnvelopeError::Truncated)
        } else {
            Ok(())
        }
    }

    /// The version byte.
    pub fn version(&self) -> u8 {
        self.buffer.as_ref()[0]
    }

    /// The postcard payload between the version byte and the CRC.
    pub fn payload(&self) -> &[u8] {
        let b = self.buffer.as_ref();
        &b[1..b.len() - 2]
    }

    /// The CRC as written in the last two bytes (little-endian).
    pub fn crc(&self) -> u16 {
        let b = self.buffer.as_ref();
        u16::from_le_bytes([b[b.len() - 2], b[b.len() - 1]])
    }

    /// The CRC of the version byte and the payload.
    pub fn computed_crc(&self) -> u16 {
        let b = self.buffer.as_ref();
        CRC16.checksum(&b[..b.len() - 2])
    }

    /// The underlying buffer.
    pub fn into_inner(self) -> T {
        self.buffer
    }
}

impl<'a> Envelope<&'a [u8]> {
    /// The payload, borrowed for as long as the buffer (not just the view).
    pub fn into_payload(self) -> &'a [u8] {
        let b = self.buffer;
        &b[1..b.len() - 2]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware_core::{ActionFeedback, ActionIndex, Feedback};
    use proptest::prelude::*;

    #[test]
    fn golden_bytes_of_an_action_feedback() {
        let fb = Feedback::Action(ActionFeedback {
            action: ActionIndex::new(17).unwrap(),
        });
        let mut buf = [0u8; 16];
        let bytes = seal(&fb, &mut buf).unwrap();
        // version 4, variant 0 (Action), action 17, then the CRC (computed independently).
        assert_eq!(CRC16.checksum(&[4, 0, 17]).to_le_bytes(), [0x4C, 0x12]);
        assert_eq!(bytes, &[4, 0, 17, 0x4C, 0x12]);
        assert_eq!(
            CRC16.checksum(b"123456789"),
            0x29B1,
            "CRC-16/IBM-3740 check value"
        );
    }

    #[test]
    fn every_corruption_is_caught() {
        let fb = Feedback::Action(ActionFeedback {
            action: ActionIndex::new(3).unwrap(),
        });
        let mut buf = [0u8; 16];
        let good = seal(&fb, &mut buf).unwrap().to_vec();
        assert_eq!(open::<Feedback>(&good), Ok(fb));
        for i in 0..good.len() {
            for bit in 0..8 {
                let mut bad = good.clone();
                bad[i] ^= 1 << bit;
                assert!(
                    open::<Feedback>(&bad).is_err(),
                    "flip of byte {i} bit {bit} accepted"
                );
            }
        }
        assert_eq!(open::<Feedback>(&good[..2]), Err(EnvelopeError::Truncated));
    }

    #[test]
    fn versions_and_sizes_are_checked() {
        let mut buf = [0u8; 8];
        let bytes = seal(&5u32, &mut buf).unwrap().to_vec();
        let mut other = bytes.clone();
        other[0] = 1;
        let crc = CRC16.checksum(&other[..other.len() - 2]).to_le_bytes();
        let n = other.len();
        other[n - 2..].copy_from_slice(&crc);
        assert_eq!(open::<u32>(&other), Err(EnvelopeError::Version(1)));
        assert_eq!(open::<u8>(&bytes), Ok(5));
        assert_eq!(
            seal(&[0u8; 10], &mut buf),
            Err(EnvelopeError::BufferTooSmall)
        );
        assert_eq!(open::<(u8, u8)>(&bytes), Err(EnvelopeError::Decode));
    }

    proptest! {
        #[test]
        fn any_bytes_give_a_value_or_an_error(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            let _ = open::<Feedback>(&bytes);
            let _ = open::<firmware_core::LearnerSnapshot>(&bytes);
        }
    }
}
