//! Segmentation of a message onto CAN frames and reassembly in a fixed buffer, ISO-TP style
//! (ISO 15765-2), for classic CAN (8-byte frames) and CAN FD (64-byte frames).
//!
//! # Frames (protocol control information, PCI)
//!
//! The first byte's high nibble is the frame type:
//!
//! | frame | bytes | payload bytes per frame (classic / FD) |
//! |---|---|---|
//! | single frame (SF) | `0x0L` (L = 1..=7, then L bytes) | 1–7 / 1–7 |
//! | single frame, FD escape | `0x00 LL` (LL = 8..=62, then LL bytes) | – / 8–62 |
//! | first frame (FF) | `0x1H LL` (12-bit length `HLL`, 8..=4095), then data | 6 / 62 |
//! | consecutive frame (CF) | `0x2N` (sequence number N = 1, 2, …, 15, 0, 1, …), then data | 7 / 63 |
//!
//! A classic frame is as long as its content (no padding: classic CAN allows any length 0–8).
//! An FD frame must have one of the lengths of [`FD_LENGTHS`]; the SF
//! and the last CF are padded with [`PADDING`] up to the next one. A first frame and every
//! consecutive frame but the last are full (8 or 64 bytes).
//!
//! # Deviations from ISO 15765-2
//!
//! * **No flow control.** ISO-TP's receiver answers a first frame with a flow-control frame
//!   (`0x3…`: continue, wait, overflow; block size; separation time). Here the sender sends all
//!   frames back to back and the receiver never answers: every receiver keeps a fixed buffer per
//!   stream sized for the largest message of the stream (an [`Inbox`](crate::link::Inbox): by
//!   [`STREAM_BUFFERS`](crate::link::STREAM_BUFFERS)) or of the protocol (a [`Reassembler`]:
//!   [`MAX_MESSAGE_SIZE`]), so there is
//!   nothing to negotiate, and each stream has one sender. A frame with a flow-control PCI is an
//!   error ([`ReassemblyError::InvalidPci`]). This halves the latency of a multi-frame message
//!   and needs no reverse identifier per stream.
//! * **Bounded length.** The 32-bit first-frame length escape is not supported: a message is at
//!   most [`MAX_ISOTP_LEN`] = 4095 bytes, far above [`MAX_MESSAGE_SIZE`].
//! * **Timeout.** Only the receiver's timeout between consecutive frames (ISO's N_Cr) exists,
//!   [`DEFAULT_TIMEOUT_MS`] by default; the caller passes the time in milliseconds.
//!
//! # Reassembly
//!
//! A [`Reassembler`] serves one stream (one CAN identifier) and is fed one frame at a time.
//! [`Reassembler::feed`] answers like postcard's `CobsAccumulator`: [`FeedResult::Consumed`]
//! (more frames needed), [`FeedResult::Complete`] (a whole message, borrowed from the buffer
//! until the next call), or [`FeedResult::Error`]. An error ends the message in progress on
//! *this* stream only: a wrong sequence number ([`ReassemblyError::Gap`]), a consecutive frame
//! with no message in progress ([`ReassemblyError::UnexpectedConsecutive`]), a declared length
//! beyond the buffer ([`ReassemblyError::TooLong`]), a frame arriving after the timeout
//! ([`ReassemblyError::Timeout`]), or a malformed frame. The next single or first frame starts
//! afresh. As in ISO-TP, a single or first frame arriving while a message is in progress
//! abandons that message and starts the new one; [`Reassembler::abandoned`] counts these.
//!
//! Any frame, whatever its bytes, gives one of the three results: `feed` never panics.
//!
//! ```
//! use protocol::can::CanId;
//! use protocol::isotp::{FeedResult, FrameMode, Reassembler, Segmenter};
//!
//! let id = CanId::standard(0x104).unwrap();
//! let message = [7u8; 20];
//! let mut rx = Reassembler::<64>::new();
//! let mut got = None;
//! for frame in Segmenter::new(id, &message, FrameMode::Classic).unwrap() {
//!     match rx.feed(&frame, 0) {
//!         FeedResult::Consumed => {}
//!         FeedResult::Complete(bytes) => got = Some(bytes.to_vec()),
//!         FeedResult::Error(e) => panic!("{e}"),
//!     }
//! }
//! assert_eq!(got.as_deref(), Some(&message[..]));
//! ```
//!
//! [`MAX_MESSAGE_SIZE`]: crate::message::MAX_MESSAGE_SIZE

use core::fmt;

use crate::can::{CLASSIC_MAX_DATA, CanFrame, CanId, FD_LENGTHS, FD_MAX_DATA};
use crate::message::MAX_MESSAGE_SIZE;

/// Largest message length a first frame can declare (12 bits).
pub const MAX_ISOTP_LEN: usize = 0xFFF;

/// The byte that pads CAN FD frames up to a valid length (ISO 15765-2's recommended value).
pub const PADDING: u8 = 0xCC;

/// Default longest wait between two frames of one message (ms).
pub const DEFAULT_TIMEOUT_MS: u32 = 50;

const PCI_SF: u8 = 0x0;
const PCI_FF: u8 = 0x1;
const PCI_CF: u8 = 0x2;

const _: () = assert!(
    MAX_MESSAGE_SIZE <= MAX_ISOTP_LEN,
    "every message fits a first frame"
);

/// Classic CAN or CAN FD frames.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum FrameMode {
    /// Classic CAN: at most 8 data bytes per frame.
    Classic,
    /// CAN FD: at most 64 data bytes per frame.
    Fd,
}

impl FrameMode {
    /// The largest frame of this mode (bytes).
    pub const fn max_frame(self) -> usize {
        match self {
            FrameMode::Classic => CLASSIC_MAX_DATA,
            FrameMode::Fd => FD_MAX_DATA,
        }
    }

    /// The largest message a single frame carries.
    pub const fn single_frame_capacity(self) -> usize {
        match self {
            FrameMode::Classic => CLASSIC_MAX_DATA - 1,
            FrameMode::Fd => FD_MAX_DATA - 2,
        }
    }

    /// Message bytes in a first frame.
    pub const fn first_frame_data(self) -> usize {
        self.max_frame() - 2
    }

    /// Message bytes in a full consecutive frame.
    pub const fn consecutive_frame_data(self) -> usize {
        self.max_frame() - 1
    }

    const fn of(frame: &CanFrame) -> Self {
        if frame.is_fd() {
            FrameMode::Fd
        } else {
            FrameMode::Classic
        }
    }
}

/// The smallest valid CAN FD length that holds `n` bytes (`n <= 64`).
const fn fd_padded(n: usize) -> usize {
    let mut i = 0;
    while i < FD_LENGTHS.len() {
        if FD_LENGTHS[i] >= n {
            return FD_LENGTHS[i];
        }
        i += 1;
    }
    FD_MAX_DATA
}

/// The CAN data length of a frame carrying `n` bytes (PCI included) in `mode`.
const fn frame_size(n: usize, mode: FrameMode) -> usize {
    match mode {
        FrameMode::Classic => n,
        FrameMode::Fd => fd_padded(n),
    }
}

/// Number of frames a message of `len` bytes (1..=[`MAX_ISOTP_LEN`]) takes in `mode`.
pub const fn frame_count(len: usize, mode: FrameMode) -> usize {
    if len <= mode.single_frame_capacity() {
        1
    } else {
        let rest = len - mode.first_frame_data();
        let cf = mode.consecutive_frame_data();
        1 + rest.div_ceil(cf)
    }
}

/// The CAN data length (PCI and padding included) of frame `index` of a message of `len` bytes
/// in `mode`; 0 if there is no such frame.
pub const fn frame_len(len: usize, mode: FrameMode, index: usize) -> usize {
    if index >= frame_count(len, mode) {
        return 0;
    }
    if len <= mode.single_frame_capacity() {
        let pci = if len < CLASSIC_MAX_DATA { 1 } else { 2 };
        return frame_size(pci + len, mode);
    }
    if index == 0 {
        return mode.max_frame();
    }
    let cf = mode.consecutive_frame_data();
    let rest = len - mode.first_frame_data() - (index - 1) * cf;
    if rest >= cf {
        mode.max_frame()
    } else {
        frame_size(1 + rest, mode)
    }
}

/// Why a message cannot be segmented.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum SegmentError {
    /// An empty message (ISO-TP has no zero-length message).
    Empty,
    /// Longer than [`MAX_ISOTP_LEN`].
    TooLong(usize),
}

impl fmt::Display for SegmentError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SegmentError::Empty => f.write_str("empty message"),
            SegmentError::TooLong(n) => write!(f, "message of {n} bytes exceeds {MAX_ISOTP_LEN}"),
        }
    }
}

impl core::error::Error for SegmentError {}

/// The frames of one message, in order: an iterator that borrows the message.
///
/// Resumable: if the bus refuses a frame, keep the frame and the iterator and try again later.
#[derive(Clone, Debug)]
pub struct Segmenter<'a> {
    id: CanId,
    data: &'a [u8],
    mode: FrameMode,
    index: usize,
    offset: usize,
}

impl<'a> Segmenter<'a> {
    /// The frames of `data` on identifier `id` in `mode`.
    pub fn new(id: CanId, data: &'a [u8], mode: FrameMode) -> Result<Self, SegmentError> {
        if data.is_empty() {
            return Err(SegmentError::Empty);
        }
        if data.len() > MAX_ISOTP_LEN {
            return Err(SegmentError::TooLong(data.len()));
        }
        Ok(Self {
            id,
            data,
            mode,
            index: 0,
            offset: 0,
        })
    }

    /// Number of frames in all.
    pub fn frame_count(&self) -> usize {
        frame_count(self.data.len(), self.mode)
    }

    fn build(&self, bytes: &[u8]) -> Option<CanFrame> {
        // Lengths come from `frame_len`, which only yields valid lengths (tested).
        match self.mode {
            FrameMode::Classic => CanFrame::new(self.id, bytes).ok(),
            FrameMode::Fd => CanFrame::new_fd(self.id, bytes).ok(),
        }
    }
}

impl Iterator for Segmenter<'_> {
    type Item = CanFrame;

    fn next(&mut self) -> Option<CanFrame> {
        let len = self.data.len();
        let size = frame_len(len, self.mode, self.index);
        if size == 0 {
            return None;
        }
        let mut buf = [PADDING; FD_MAX_DATA];
        let pci = if len <= self.mode.single_frame_capacity() {
            if len < CLASSIC_MAX_DATA {
                buf[0] = (PCI_SF << 4) | len as u8;
                1
            } else {
                buf[0] = PCI_SF << 4;
                buf[1] = len as u8;
                2
            }
        } else if self.index == 0 {
            buf[0] = (PCI_FF << 4) | (len >> 8) as u8;
            buf[1] = len as u8;
            2
        } else {
            buf[0] = (PCI_CF << 4) | (self.index % 16) as u8;
            1
        };
        let take = (size - pci).min(len - self.offset);
        buf[pci..pci + take].copy_from_slice(&self.data[self.offset..self.offset + take]);
        self.offset += take;
        self.index += 1;
        self.build(&buf[..size])
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = self.frame_count() - self.index.min(self.frame_count());
        (n, Some(n))
    }
}

/// Why a frame could not be used. The message in progress on the stream (if any) is dropped.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum ReassemblyError {
    /// A frame without data.
    EmptyFrame,
    /// A frame type this protocol does not use (flow control `0x3`, reserved `0x4`–`0xF`).
    InvalidPci(u8),
    /// The PCI does not fit the frame: a single frame's length is 0 or beyond the frame, a first
    /// frame is not full or declares a length a single frame would carry, a consecutive frame
    /// is shorter than it must be or of the other frame mode.
    InvalidFrame,
    /// A consecutive frame with no message in progress.
    UnexpectedConsecutive,
    /// A consecutive frame with the wrong sequence number (a frame was lost).
    Gap {
        /// The sequence number expected.
        expected: u8,
        /// The one received.
        got: u8,
    },
    /// A first frame declares more bytes than the buffer holds.
    TooLong(u16),
    /// The next frame of a message came later than the timeout (or never, see
    /// [`Reassembler::poll`]).
    Timeout,
}

impl fmt::Display for ReassemblyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReassemblyError::EmptyFrame => f.write_str("empty frame"),
            ReassemblyError::InvalidPci(p) => write!(f, "unsupported frame type {p:#x}"),
            ReassemblyError::InvalidFrame => f.write_str("frame inconsistent with its header"),
            ReassemblyError::UnexpectedConsecutive => {
                f.write_str("consecutive frame without a message in progress")
            }
            ReassemblyError::Gap { expected, got } => {
                write!(f, "sequence number {got}, expected {expected}")
            }
            ReassemblyError::TooLong(n) => write!(f, "declared length {n} exceeds the buffer"),
            ReassemblyError::Timeout => f.write_str("timed out between frames"),
        }
    }
}

impl core::error::Error for ReassemblyError {}

/// What one frame did to a [`Reassembler`].
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum FeedResult<'a> {
    /// The frame was taken; the message needs more frames.
    Consumed,
    /// A whole message; valid until the next call on the reassembler.
    Complete(&'a [u8]),
    /// The frame could not be used; the stream is reset.
    Error(ReassemblyError),
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum State {
    Idle,
    Receiving {
        len: usize,
        filled: usize,
        next_sn: u8,
        mode: FrameMode,
        last_ms: u32,
    },
}

/// Reassembles the messages of one stream in a buffer of `N` bytes (`N <= MAX_ISOTP_LEN`).
#[derive(Clone, Debug)]
pub struct Reassembler<const N: usize = MAX_MESSAGE_SIZE> {
    buf: [u8; N],
    core: Reassembly,
}

impl<const N: usize> Default for Reassembler<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Reassembler<N> {
    /// An idle reassembler with the [`DEFAULT_TIMEOUT_MS`].
    pub const fn new() -> Self {
        Self::with_timeout(DEFAULT_TIMEOUT_MS)
    }

    /// An idle reassembler that gives up on a message when its next frame is more than
    /// `timeout_ms` late.
    pub const fn with_timeout(timeout_ms: u32) -> Self {
        const {
            assert!(
                N >= 1 && N <= MAX_ISOTP_LEN,
                "buffer within ISO-TP's 12-bit length"
            )
        };
        Self {
            buf: [0; N],
            core: Reassembly::with_timeout(timeout_ms),
        }
    }

    /// Whether a message is in progress.
    pub fn is_receiving(&self) -> bool {
        self.core.is_receiving()
    }

    /// Number of messages abandoned because a single or first frame arrived before they were
    /// complete (ISO-TP's "unexpected PDU"), since the reassembler was made.
    pub fn abandoned(&self) -> u32 {
        self.core.abandoned
    }

    /// Drops the message in progress, if any.
    pub fn reset(&mut self) {
        self.core.reset();
    }

    /// Ends a message in progress whose next frame is overdue at `now` (ms).
    pub fn poll(&mut self, now: u32) -> Option<ReassemblyError> {
        self.core.poll(now)
    }

    /// Takes one frame of the stream, received at `now` (ms, wrapping).
    pub fn feed(&mut self, frame: &CanFrame, now: u32) -> FeedResult<'_> {
        self.core.feed(&mut self.buf, frame, now)
    }
}

/// The state of one stream's reassembly, apart from its buffer: a [`Reassembler`] holds its
/// own, an [`Inbox`](crate::link::Inbox) lends each stream its part of one buffer (sized per
/// stream by the largest message the stream carries).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Reassembly {
    state: State,
    timeout_ms: u32,
    abandoned: u32,
}

impl Reassembly {
    /// Idle, giving up on a message whose next frame is more than `timeout_ms` late.
    pub(crate) const fn with_timeout(timeout_ms: u32) -> Self {
        Self {
            state: State::Idle,
            timeout_ms,
            abandoned: 0,
        }
    }

    /// Sets the timeout between consecutive frames of a message (ms).
    pub(crate) fn set_timeout(&mut self, timeout_ms: u32) {
        self.timeout_ms = timeout_ms;
    }

    fn is_receiving(&self) -> bool {
        matches!(self.state, State::Receiving { .. })
    }

    /// Drops the message in progress, if any.
    pub(crate) fn reset(&mut self) {
        self.state = State::Idle;
    }

    /// Ends a message in progress whose next frame is overdue at `now` (ms).
    pub(crate) fn poll(&mut self, now: u32) -> Option<ReassemblyError> {
        match self.state {
            State::Receiving { last_ms, .. } if now.wrapping_sub(last_ms) > self.timeout_ms => {
                self.state = State::Idle;
                Some(ReassemblyError::Timeout)
            }
            _ => None,
        }
    }

    /// Takes one frame of the stream, received at `now` (ms, wrapping), into `buf` (the same
    /// buffer for every frame of the stream; a message longer than it is
    /// [`ReassemblyError::TooLong`]).
    pub(crate) fn feed<'b>(
        &mut self,
        buf: &'b mut [u8],
        frame: &CanFrame,
        now: u32,
    ) -> FeedResult<'b> {
        match self.step(buf, frame, now) {
            Ok(Some(len)) => FeedResult::Complete(&buf[..len]),
            Ok(None) => FeedResult::Consumed,
            Err(e) => {
                self.state = State::Idle;
                FeedResult::Error(e)
            }
        }
    }

    /// `Ok(Some(len))`: a message of `len` bytes is in the buffer.
    fn step(
        &mut self,
        buf: &mut [u8],
        frame: &CanFrame,
        now: u32,
    ) -> Result<Option<usize>, ReassemblyError> {
        let data = frame.data();
        let mode = FrameMode::of(frame);
        let Some(&pci) = data.first() else {
            return Err(ReassemblyError::EmptyFrame);
        };
        match pci >> 4 {
            PCI_SF => {
                self.abandon();
                let (len, body) = if data.len() <= CLASSIC_MAX_DATA {
                    ((pci & 0x0F) as usize, &data[1..])
                } else if pci == PCI_SF << 4 {
                    (data[1] as usize, &data[2..])
                } else {
                    return Err(ReassemblyError::InvalidFrame);
                };
                if len == 0 || len > body.len() {
                    return Err(ReassemblyError::InvalidFrame);
                }
                let Some(to) = buf.get_mut(..len) else {
                    return Err(ReassemblyError::TooLong(len as u16));
                };
                to.copy_from_slice(&body[..len]);
                Ok(Some(len))
            }
            PCI_FF => {
                self.abandon();
                if data.len() != mode.max_frame() {
                    return Err(ReassemblyError::InvalidFrame);
                }
                let len = (((pci & 0x0F) as usize) << 8) | data[1] as usize;
                if len <= mode.single_frame_capacity() {
                    return Err(ReassemblyError::InvalidFrame);
                }
                if len > buf.len() {
                    return Err(ReassemblyError::TooLong(len as u16));
                }
                let body = &data[2..];
                buf[..body.len()].copy_from_slice(body);
                self.state = State::Receiving {
                    len,
                    filled: body.len(),
                    next_sn: 1,
                    mode,
                    last_ms: now,
                };
                Ok(None)
            }
            PCI_CF => {
                let State::Receiving {
                    len,
                    filled,
                    next_sn,
                    mode: expected_mode,
                    last_ms,
                } = self.state
                else {
                    return Err(ReassemblyError::UnexpectedConsecutive);
                };
                if now.wrapping_sub(last_ms) > self.timeout_ms {
                    return Err(ReassemblyError::Timeout);
                }
                let sn = pci & 0x0F;
                if sn != next_sn {
                    return Err(ReassemblyError::Gap {
                        expected: next_sn,
                        got: sn,
                    });
                }
                let body = &data[1..];
                let rest = len - filled;
                // A frame short of the rest must be full; a frame of the other mode never fits.
                if mode != expected_mode || (body.len() < rest && data.len() != mode.max_frame()) {
                    return Err(ReassemblyError::InvalidFrame);
                }
                let take = body.len().min(rest);
                buf[filled..filled + take].copy_from_slice(&body[..take]);
                if filled + take == len {
                    self.state = State::Idle;
                    Ok(Some(len))
                } else {
                    self.state = State::Receiving {
                        len,
                        filled: filled + take,
                        next_sn: (next_sn + 1) % 16,
                        mode,
                        last_ms: now,
                    };
                    Ok(None)
                }
            }
            other => Err(ReassemblyError::InvalidPci(other)),
        }
    }

    fn abandon(&mut self) {
        if self.is_receiving() {
            self.abandoned = self.abandoned.wrapping_add(1);
            self.state = State::Idle;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec;

    const ID: CanId = CanId::Standard(0x104);

    fn frames(data: &[u8], mode: FrameMode) -> Vec<CanFrame> {
        Segmenter::new(ID, data, mode).unwrap().collect()
    }

    fn bytes(n: usize) -> Vec<u8> {
        (0..n).map(|i| i as u8).collect()
    }

    /// Feeds every frame; returns the messages completed and the errors.
    fn feed_all<const N: usize>(
        rx: &mut Reassembler<N>,
        frames: &[CanFrame],
        now: u32,
    ) -> (Vec<Vec<u8>>, Vec<ReassemblyError>) {
        let (mut done, mut errors) = (Vec::new(), Vec::new());
        for f in frames {
            match rx.feed(f, now) {
                FeedResult::Consumed => {}
                FeedResult::Complete(b) => done.push(b.to_vec()),
                FeedResult::Error(e) => errors.push(e),
            }
        }
        (done, errors)
    }

    fn classic(data: &[u8]) -> CanFrame {
        CanFrame::new(ID, data).unwrap()
    }

    #[test]
    fn golden_classic_frames() {
        assert_eq!(
            frames(&[0xA, 0xB, 0xC], FrameMode::Classic),
            [classic(&[0x03, 0xA, 0xB, 0xC])]
        );
        let f = frames(&bytes(20), FrameMode::Classic);
        assert_eq!(
            f,
            [
                classic(&[0x10, 20, 0, 1, 2, 3, 4, 5]),
                classic(&[0x21, 6, 7, 8, 9, 10, 11, 12]),
                classic(&[0x22, 13, 14, 15, 16, 17, 18, 19]),
            ]
        );
        // The last consecutive frame is not padded on classic CAN.
        let f = frames(&bytes(15), FrameMode::Classic);
        assert_eq!(f[2], classic(&[0x22, 13, 14]));
    }

    #[test]
    fn golden_fd_frames() {
        let fd = |d: &[u8]| CanFrame::new_fd(ID, d).unwrap();
        assert_eq!(
            frames(&[9; 7], FrameMode::Fd),
            [fd(&[0x07, 9, 9, 9, 9, 9, 9, 9])]
        );
        // 20 bytes: single frame with the length escape, padded to 24.
        let mut sf = std::vec![0x00, 20];
        sf.extend(bytes(20));
        sf.extend([PADDING; 2]);
        assert_eq!(frames(&bytes(20), FrameMode::Fd), [fd(&sf)]);
        // 100 bytes: a first frame of 62 and a consecutive frame of 38, padded to 48.
        let data = bytes(100);
        let mut ff = std::vec![0x10, 100];
        ff.extend_from_slice(&data[..62]);
        let mut cf = std::vec![0x21];
        cf.extend_from_slice(&data[62..]);
        cf.extend([PADDING; 9]);
        assert_eq!(frames(&data, FrameMode::Fd), [fd(&ff), fd(&cf)]);
        // A 12-bit length: 0x182 = 386 bytes.
        let f = frames(&bytes(386), FrameMode::Fd);
        assert_eq!(&f[0].data()[..2], &[0x11, 0x82]);
    }

    #[test]
    fn sequence_numbers_wrap_after_15() {
        let f = frames(&bytes(6 + 7 * 20), FrameMode::Classic);
        let sn: Vec<u8> = f[1..].iter().map(|f| f.data()[0]).collect();
        let expected: Vec<u8> = (1..=20).map(|i| 0x20 | (i % 16) as u8).collect();
        assert_eq!(sn, expected);
        let mut rx = Reassembler::<400>::new();
        assert_eq!(
            feed_all(&mut rx, &f, 0),
            (std::vec![bytes(146)], Vec::new())
        );
    }

    #[test]
    fn frame_arithmetic_matches_the_segmenter() {
        for mode in [FrameMode::Classic, FrameMode::Fd] {
            for len in 1..=MAX_MESSAGE_SIZE {
                let f = frames(&bytes(len), mode);
                assert_eq!(f.len(), frame_count(len, mode), "{len} {mode:?}");
                for (i, frame) in f.iter().enumerate() {
                    assert_eq!(
                        frame.data().len(),
                        frame_len(len, mode, i),
                        "{len} {mode:?} {i}"
                    );
                    if mode == FrameMode::Fd {
                        assert!(FD_LENGTHS.contains(&frame.data().len()));
                    } else {
                        assert!(frame.data().len() <= CLASSIC_MAX_DATA);
                    }
                }
                assert_eq!(frame_len(len, mode, f.len()), 0);
            }
        }
        assert_eq!(frame_count(MAX_MESSAGE_SIZE, FrameMode::Classic), 23);
        assert_eq!(frame_count(MAX_MESSAGE_SIZE, FrameMode::Fd), 3);
    }

    #[test]
    fn segmentation_refuses_empty_and_overlong_messages() {
        assert_eq!(
            Segmenter::new(ID, &[], FrameMode::Classic).unwrap_err(),
            SegmentError::Empty
        );
        let big = [0u8; MAX_ISOTP_LEN + 1];
        assert_eq!(
            Segmenter::new(ID, &big, FrameMode::Fd).unwrap_err(),
            SegmentError::TooLong(4096)
        );
        assert_eq!(
            Segmenter::new(ID, &big[1..], FrameMode::Fd)
                .unwrap()
                .count(),
            66
        );
    }

    #[test]
    fn a_gap_ends_the_message_and_the_next_one_is_received() {
        let data = bytes(30);
        let mut f = frames(&data, FrameMode::Classic);
        f.remove(2);
        let mut rx = Reassembler::<64>::new();
        let (done, errors) = feed_all(&mut rx, &f, 0);
        assert!(done.is_empty());
        // Frame 3 is the gap; frame 4 then has no message to belong to.
        assert_eq!(
            errors,
            [
                ReassemblyError::Gap {
                    expected: 2,
                    got: 3
                },
                ReassemblyError::UnexpectedConsecutive
            ]
        );
        let again = frames(&data, FrameMode::Classic);
        assert_eq!(feed_all(&mut rx, &again, 0), (std::vec![data], Vec::new()));
    }

    #[test]
    fn timeouts_end_the_message() {
        let data = bytes(30);
        let f = frames(&data, FrameMode::Classic);
        let mut rx = Reassembler::<64>::with_timeout(10);
        assert_eq!(rx.feed(&f[0], 100), FeedResult::Consumed);
        assert_eq!(rx.feed(&f[1], 110), FeedResult::Consumed); // exactly on time
        assert_eq!(
            rx.feed(&f[2], 121),
            FeedResult::Error(ReassemblyError::Timeout)
        );
        assert!(!rx.is_receiving());
        // Through poll, across the wrap of the millisecond counter.
        let t0 = u32::MAX - 3;
        assert_eq!(rx.feed(&f[0], t0), FeedResult::Consumed);
        assert_eq!(rx.poll(t0.wrapping_add(10)), None);
        assert_eq!(rx.poll(t0.wrapping_add(11)), Some(ReassemblyError::Timeout));
        assert_eq!(rx.poll(t0.wrapping_add(50)), None);
        assert_eq!(
            rx.feed(&f[1], t0.wrapping_add(12)),
            FeedResult::Error(ReassemblyError::UnexpectedConsecutive)
        );
    }

    #[test]
    fn overlong_declarations_are_refused_before_any_copy() {
        let f = frames(&bytes(65), FrameMode::Classic);
        let mut rx = Reassembler::<64>::new();
        assert_eq!(
            rx.feed(&f[0], 0),
            FeedResult::Error(ReassemblyError::TooLong(65))
        );
        assert_eq!(
            rx.feed(&f[1], 0),
            FeedResult::Error(ReassemblyError::UnexpectedConsecutive)
        );
        // An FD single frame longer than a small buffer.
        let mut small = Reassembler::<8>::new();
        let sf = frames(&bytes(9), FrameMode::Fd);
        assert_eq!(
            small.feed(&sf[0], 0),
            FeedResult::Error(ReassemblyError::TooLong(9))
        );
        // The largest declaration, 4095, against the protocol's buffer.
        let mut rx = Reassembler::<MAX_MESSAGE_SIZE>::new();
        let ff = classic(&[0x1F, 0xFF, 0, 0, 0, 0, 0, 0]);
        assert_eq!(
            rx.feed(&ff, 0),
            FeedResult::Error(ReassemblyError::TooLong(4095))
        );
    }

    #[test]
    fn malformed_frames_are_errors() {
        let mut rx = Reassembler::<64>::new();
        let mut check = |d: &[u8], fd: bool, e: ReassemblyError| {
            let frame = if fd {
                CanFrame::new_fd(ID, d)
            } else {
                CanFrame::new(ID, d)
            }
            .unwrap();
            assert_eq!(rx.feed(&frame, 0), FeedResult::Error(e), "{frame:?}");
        };
        check(&[], false, ReassemblyError::EmptyFrame);
        check(&[0x30, 0, 0], false, ReassemblyError::InvalidPci(3)); // flow control
        check(&[0xF0], false, ReassemblyError::InvalidPci(0xF));
        check(&[0x00, 1], false, ReassemblyError::InvalidFrame); // SF of length 0
        check(&[0x05, 1, 2], false, ReassemblyError::InvalidFrame); // SF longer than the frame
        check(&[0x10, 20, 1, 2], false, ReassemblyError::InvalidFrame); // FF not full
        check(
            &[0x10, 7, 1, 2, 3, 4, 5, 6],
            false,
            ReassemblyError::InvalidFrame,
        ); // FF for an SF
        check(&[0x21, 1], false, ReassemblyError::UnexpectedConsecutive);
        let mut esc = [0u8; 12];
        esc[0] = 0x01; // an FD frame above 8 bytes must use the escape
        check(&esc, true, ReassemblyError::InvalidFrame);
        esc[0] = 0x00;
        esc[1] = 11; // escape length beyond the frame's 10 bytes
        check(&esc, true, ReassemblyError::InvalidFrame);
        // A consecutive frame that is neither full nor the last.
        let data = bytes(30);
        let f = frames(&data, FrameMode::Classic);
        assert_eq!(rx.feed(&f[0], 0), FeedResult::Consumed);
        let short = classic(&f[1].data()[..5]);
        assert_eq!(
            rx.feed(&short, 0),
            FeedResult::Error(ReassemblyError::InvalidFrame)
        );
        // A consecutive frame of the other mode.
        assert_eq!(rx.feed(&f[0], 0), FeedResult::Consumed);
        let fd_cf = CanFrame::new_fd(ID, f[1].data()).unwrap();
        assert_eq!(
            rx.feed(&fd_cf, 0),
            FeedResult::Error(ReassemblyError::InvalidFrame)
        );
        // After all that, a good message still goes through.
        assert_eq!(feed_all(&mut rx, &f, 0), (std::vec![data], Vec::new()));
    }

    #[test]
    fn a_new_message_abandons_an_unfinished_one() {
        let long = frames(&bytes(30), FrameMode::Classic);
        let short = frames(&[1, 2], FrameMode::Classic);
        let mut rx = Reassembler::<64>::new();
        assert_eq!(rx.feed(&long[0], 0), FeedResult::Consumed);
        assert_eq!(rx.feed(&short[0], 0), FeedResult::Complete(&[1, 2]));
        assert_eq!(rx.abandoned(), 1);
        assert_eq!(
            rx.feed(&long[1], 0),
            FeedResult::Error(ReassemblyError::UnexpectedConsecutive)
        );
        // A first frame in the middle restarts the message.
        assert_eq!(rx.feed(&long[0], 0), FeedResult::Consumed);
        assert_eq!(
            feed_all(&mut rx, &long, 0),
            (std::vec![bytes(30)], Vec::new())
        );
        assert_eq!(rx.abandoned(), 2);
    }

    /// Frames of several streams, each in order, interleaved by `order` (stream picks).
    fn interleave(streams: &[Vec<CanFrame>], order: &[usize]) -> Vec<CanFrame> {
        let mut next = std::vec![0; streams.len()];
        let mut out = Vec::new();
        let mut picks = order.iter().cycle();
        while out.len() < streams.iter().map(Vec::len).sum() {
            let s = *picks.next().unwrap() % streams.len();
            if next[s] < streams[s].len() {
                out.push(streams[s][next[s]]);
                next[s] += 1;
            } else if let Some(s) = (0..streams.len()).find(|&s| next[s] < streams[s].len()) {
                out.push(streams[s][next[s]]);
                next[s] += 1;
            }
        }
        out
    }

    fn any_mode() -> impl Strategy<Value = FrameMode> {
        prop_oneof![Just(FrameMode::Classic), Just(FrameMode::Fd)]
    }

    proptest! {
        #[test]
        fn segmentation_round_trips(
            data in proptest::collection::vec(any::<u8>(), 1..=MAX_MESSAGE_SIZE),
            mode in any_mode(),
        ) {
            let f = frames(&data, mode);
            prop_assert_eq!(f.len(), frame_count(data.len(), mode));
            let mut rx = Reassembler::<MAX_MESSAGE_SIZE>::new();
            prop_assert_eq!(feed_all(&mut rx, &f, 0), (std::vec![data], Vec::new()));
        }

        #[test]
        fn interleaved_streams_reassemble_independently(
            payloads in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 1..200), 2..5),
            modes in proptest::collection::vec(any_mode(), 5),
            order in proptest::collection::vec(0usize..5, 1..50),
            drop in proptest::option::of((0usize..5, any::<prop::sample::Index>())),
        ) {
            let ids: Vec<CanId> = (0..payloads.len()).map(|i| CanId::Standard(0x100 + i as u16)).collect();
            let mut streams: Vec<Vec<CanFrame>> = payloads
                .iter()
                .zip(&ids)
                .zip(&modes)
                .map(|((p, &id), &mode)| Segmenter::new(id, p, mode).unwrap().collect())
                .collect();
            // Optionally lose one frame of one multi-frame stream: only that stream may fail.
            let damaged = drop.and_then(|(s, i)| {
                let s = s % streams.len();
                (streams[s].len() > 1).then(|| {
                    let at = i.index(streams[s].len());
                    streams[s].remove(at);
                    s
                })
            });
            let wire = interleave(&streams, &order);
            let mut rx: Vec<Reassembler<256>> = (0..payloads.len()).map(|_| Reassembler::new()).collect();
            let mut got: Vec<Vec<Vec<u8>>> = std::vec![Vec::new(); payloads.len()];
            for f in &wire {
                let s = ids.iter().position(|&id| id == f.id()).unwrap();
                match rx[s].feed(f, 0) {
                    FeedResult::Complete(b) => got[s].push(b.to_vec()),
                    FeedResult::Error(_) => prop_assert_eq!(Some(s), damaged),
                    FeedResult::Consumed => {}
                }
            }
            for (s, p) in payloads.iter().enumerate() {
                if Some(s) == damaged {
                    prop_assert!(got[s].is_empty(), "a damaged message must not complete");
                } else {
                    prop_assert_eq!(&got[s], &std::vec![p.clone()]);
                }
            }
        }

        #[test]
        fn any_frames_give_a_result_never_a_panic(
            raw in proptest::collection::vec((any::<bool>(), 0usize..16, proptest::collection::vec(any::<u8>(), 64), 0u32..30), 0..40),
        ) {
            let mut small = Reassembler::<16>::with_timeout(20);
            let mut big = Reassembler::<MAX_MESSAGE_SIZE>::with_timeout(20);
            let mut now = 0u32;
            for (fd, dlc, data, dt) in raw {
                now = now.wrapping_add(dt);
                let frame = if fd {
                    CanFrame::new_fd(ID, &data[..FD_LENGTHS[dlc]]).unwrap()
                } else {
                    CanFrame::new(ID, &data[..dlc.min(8)]).unwrap()
                };
                if let FeedResult::Complete(b) = small.feed(&frame, now) {
                    prop_assert!(!b.is_empty() && b.len() <= 16);
                }
                if let FeedResult::Complete(b) = big.feed(&frame, now) {
                    prop_assert!(!b.is_empty() && b.len() <= MAX_MESSAGE_SIZE);
                }
                let _ = big.poll(now);
            }
        }
    }
}
