//! CAN frames and the bus trait every transport implements.
//!
//! A [`CanFrame`] is checked when it is built: the identifier fits its format and the payload
//! length is one a classic CAN (0–8 bytes) or CAN FD (0–8, 12, 16, 20, 24, 32, 48, 64 bytes)
//! frame can carry. After that no accessor panics.
//!
//! [`CanBus`] is the interface between the protocol and a link: non-blocking, no allocation, so
//! the car's firmware can implement it over its CAN peripheral (or a UART speaking slcan) and the
//! host over UDP, a serial port or SocketCAN.
//!
//! ```
//! use protocol::can::{CanFrame, CanId};
//! let f = CanFrame::new(CanId::standard(0x123).unwrap(), &[1, 2, 3]).unwrap();
//! assert_eq!(f.data(), &[1, 2, 3]);
//! assert!(!f.is_fd());
//! assert!(CanFrame::new(CanId::standard(0x123).unwrap(), &[0; 9]).is_err());
//! assert!(CanFrame::new_fd(CanId::standard(0x123).unwrap(), &[0; 12]).is_ok());
//! assert!(CanFrame::new_fd(CanId::standard(0x123).unwrap(), &[0; 13]).is_err());
//! ```

use core::fmt;

/// Largest payload of a classic CAN frame.
pub const CLASSIC_MAX_DATA: usize = 8;

/// Largest payload of a CAN FD frame.
pub const FD_MAX_DATA: usize = 64;

/// The payload lengths a CAN FD frame may have (its DLC codes 0–15).
pub const FD_LENGTHS: [usize; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];

/// A CAN identifier: 11-bit standard or 29-bit extended. Lower values win arbitration.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, PartialOrd, Ord)]
pub enum CanId {
    /// An 11-bit identifier (0..=0x7FF).
    Standard(u16),
    /// A 29-bit identifier (0..=0x1FFF_FFFF).
    Extended(u32),
}

impl CanId {
    /// A standard identifier, if `id <= 0x7FF`.
    pub const fn standard(id: u16) -> Option<Self> {
        if id <= 0x7FF {
            Some(Self::Standard(id))
        } else {
            None
        }
    }

    /// An extended identifier, if `id <= 0x1FFF_FFFF`.
    pub const fn extended(id: u32) -> Option<Self> {
        if id <= 0x1FFF_FFFF {
            Some(Self::Extended(id))
        } else {
            None
        }
    }

    /// The raw identifier bits.
    pub const fn raw(self) -> u32 {
        match self {
            Self::Standard(id) => id as u32,
            Self::Extended(id) => id,
        }
    }

    /// Whether this is an extended (29-bit) identifier.
    pub const fn is_extended(self) -> bool {
        matches!(self, Self::Extended(_))
    }
}

impl fmt::Display for CanId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Standard(id) => write!(f, "{id:03X}"),
            Self::Extended(id) => write!(f, "{id:08X}"),
        }
    }
}

/// Why a frame could not be built.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum FrameError {
    /// The payload is longer than the frame kind allows, or not a valid CAN FD length.
    InvalidLength(usize),
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameError::InvalidLength(n) => write!(f, "invalid CAN payload length {n}"),
        }
    }
}

impl core::error::Error for FrameError {}

/// One CAN or CAN FD data frame.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: CanId,
    fd: bool,
    len: u8,
    data: [u8; FD_MAX_DATA],
}

impl CanFrame {
    /// A classic CAN frame with 0–8 bytes.
    pub fn new(id: CanId, data: &[u8]) -> Result<Self, FrameError> {
        if data.len() > CLASSIC_MAX_DATA {
            return Err(FrameError::InvalidLength(data.len()));
        }
        Ok(Self::raw(id, false, data))
    }

    /// A CAN FD frame; `data.len()` must be one of [`FD_LENGTHS`].
    pub fn new_fd(id: CanId, data: &[u8]) -> Result<Self, FrameError> {
        if !FD_LENGTHS.contains(&data.len()) {
            return Err(FrameError::InvalidLength(data.len()));
        }
        Ok(Self::raw(id, true, data))
    }

    fn raw(id: CanId, fd: bool, data: &[u8]) -> Self {
        let mut buf = [0u8; FD_MAX_DATA];
        buf[..data.len()].copy_from_slice(data);
        Self {
            id,
            fd,
            len: data.len() as u8,
            data: buf,
        }
    }

    /// The identifier.
    pub const fn id(&self) -> CanId {
        self.id
    }

    /// Whether this is a CAN FD frame.
    pub const fn is_fd(&self) -> bool {
        self.fd
    }

    /// The payload.
    pub fn data(&self) -> &[u8] {
        &self.data[..self.len as usize]
    }

    /// The data length code of the payload length (0–8 classic; 0–15 FD).
    pub fn dlc(&self) -> u8 {
        let n = self.len as usize;
        FD_LENGTHS.iter().position(|&l| l == n).unwrap_or(0) as u8
    }
}

impl fmt::Debug for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}{}#", self.id, if self.fd { "#" } else { "" })?;
        for b in self.data() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

/// The smallest CAN FD payload length that holds `n` bytes, if any.
pub fn fd_length_for(n: usize) -> Option<usize> {
    FD_LENGTHS.iter().copied().find(|&l| l >= n)
}

/// A CAN bus as the protocol sees it: send a frame, poll for a received one. Non-blocking: a
/// transport that cannot send now returns an error of its own kind, and `receive` returns
/// `Ok(None)` when nothing is waiting. Time and retries are the caller's.
pub trait CanBus {
    /// The transport's error.
    type Error: fmt::Debug;

    /// Queues `frame` for transmission.
    fn transmit(&mut self, frame: &CanFrame) -> Result<(), Self::Error>;

    /// The next received frame, if one is waiting.
    fn receive(&mut self) -> Result<Option<CanFrame>, Self::Error>;

    /// The frame received last completed an authenticated message, called before the answer is
    /// transmitted. A transport that has a notion of peers (UDP, a TCP connection) answers its
    /// sender; if the message was also `fresh` (it carried the highest counter yet: not a hello,
    /// which may be replayed by design, nor a late message, which another node may have
    /// recorded and replayed) it may trust that sender from now on (answer it, keep its
    /// connection). Does nothing by default (a bus has no peers).
    fn authenticated(&mut self, fresh: bool) {
        let _ = fresh;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identifiers_are_range_checked() {
        assert!(CanId::standard(0x7FF).is_some());
        assert!(CanId::standard(0x800).is_none());
        assert!(CanId::extended(0x1FFF_FFFF).is_some());
        assert!(CanId::extended(0x2000_0000).is_none());
    }

    #[test]
    fn lengths_and_dlc() {
        let id = CanId::standard(1).unwrap();
        for n in 0..=8 {
            assert_eq!(CanFrame::new(id, &[0; 64][..n]).unwrap().dlc() as usize, n);
        }
        let f = CanFrame::new_fd(id, &[7; 48]).unwrap();
        assert_eq!((f.dlc(), f.data().len()), (14, 48));
        assert_eq!(fd_length_for(9), Some(12));
        assert_eq!(fd_length_for(65), None);
        assert_eq!(
            format!("{:?}", CanFrame::new(id, &[0xAB]).unwrap()),
            "001#AB"
        );
    }
}
