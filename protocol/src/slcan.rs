//! slcan: the Lawicel serial-line CAN protocol that common USB-CAN adapters speak, `no_std`.
//!
//! Every message is one line of ASCII ended by a carriage return (`\r`):
//!
//! | line | meaning |
//! |---|---|
//! | `tIIILDD…` | classic data frame, 11-bit id `III` (3 hex), length `L` (0–8), data bytes in hex |
//! | `TIIIIIIIILDD…` | the same with a 29-bit id (8 hex) |
//! | `bIIILDD…`, `BIIIIIIIILDD…` | CAN FD frame with bit-rate switch, `L` the DLC code (0–F) |
//! | `dIIILDD…`, `DIIIIIIIILDD…` | CAN FD frame without bit-rate switch (read; written as `b`/`B`) |
//! | `O`, `C`, `S0`–`S8`, `V`, `N`, … | commands from the host to the adapter |
//! | empty line | "OK" from the adapter; the BEL byte `0x07` is its "error" |
//! | `z`, `Z` | "transmitted" acknowledgements some adapters send; ignored |
//!
//! The FD lines are the extension used by CANable-class adapters; the Linux `slcan` driver and the
//! original Lawicel adapters know only the classic ones. Hex digits are accepted in either case
//! and written in upper case.
//!
//! ```
//! use protocol::can::{CanFrame, CanId};
//! use protocol::slcan::{encode, parse_line, Line, MAX_LINE};
//!
//! let f = CanFrame::new(CanId::standard(0x123).unwrap(), &[0xAB, 0x01]).unwrap();
//! let mut buf = [0u8; MAX_LINE];
//! let line = encode(&f, &mut buf);
//! assert_eq!(line, b"t1232AB01\r");
//! assert_eq!(parse_line(&line[..line.len() - 1]), Ok(Line::Frame(f)));
//! ```

use core::fmt;

use crate::can::{CanFrame, CanId, FD_LENGTHS};

/// Longest line, terminator included: `B` + 8 id digits + DLC + 64 bytes in hex + `\r`.
pub const MAX_LINE: usize = 1 + 8 + 1 + 2 * 64 + 1;

/// The adapter's error reply.
pub const BEL: u8 = 0x07;

/// Why a line was refused.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum SlcanError {
    /// A character that is not a hex digit where one is expected.
    NotHex,
    /// The line is shorter or longer than its header announces.
    Length,
    /// The identifier is out of range for its format.
    Identifier,
    /// The length code is out of range (above 8 for classic frames).
    Dlc,
    /// The line grew beyond [`MAX_LINE`] without a terminator.
    TooLong,
}

impl fmt::Display for SlcanError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SlcanError::NotHex => "not a hex digit",
            SlcanError::Length => "line length does not match its header",
            SlcanError::Identifier => "identifier out of range",
            SlcanError::Dlc => "length code out of range",
            SlcanError::TooLong => "line too long",
        })
    }
}

impl core::error::Error for SlcanError {}

/// One parsed line.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Line<'a> {
    /// A data frame.
    Frame(CanFrame),
    /// A command: its letter and the rest of the line.
    Command(u8, &'a [u8]),
    /// The empty line: "OK".
    Ok,
    /// A `z`/`Z` transmit acknowledgement.
    TransmitAck,
}

const HEX: &[u8; 16] = b"0123456789ABCDEF";

fn hex_value(c: u8) -> Result<u8, SlcanError> {
    match c {
        b'0'..=b'9' => Ok(c - b'0'),
        b'A'..=b'F' => Ok(c - b'A' + 10),
        b'a'..=b'f' => Ok(c - b'a' + 10),
        _ => Err(SlcanError::NotHex),
    }
}

fn hex_number(digits: &[u8]) -> Result<u32, SlcanError> {
    digits
        .iter()
        .try_fold(0u32, |acc, &c| Ok(acc << 4 | hex_value(c)? as u32))
}

/// Writes `frame` as an slcan line (with its `\r`) into `out` and returns it.
pub fn encode<'o>(frame: &CanFrame, out: &'o mut [u8; MAX_LINE]) -> &'o [u8] {
    let (letter, id_digits) = match (frame.id(), frame.is_fd()) {
        (CanId::Standard(_), false) => (b't', 3),
        (CanId::Extended(_), false) => (b'T', 8),
        (CanId::Standard(_), true) => (b'b', 3),
        (CanId::Extended(_), true) => (b'B', 8),
    };
    out[0] = letter;
    let id = frame.id().raw();
    for i in 0..id_digits {
        out[1 + i] = HEX[(id >> (4 * (id_digits - 1 - i)) & 0xF) as usize];
    }
    let mut n = 1 + id_digits;
    out[n] = HEX[frame.dlc() as usize & 0xF];
    n += 1;
    for &b in frame.data() {
        out[n] = HEX[(b >> 4) as usize];
        out[n + 1] = HEX[(b & 0xF) as usize];
        n += 2;
    }
    out[n] = b'\r';
    &out[..n + 1]
}

/// Parses one line, without its terminator.
pub fn parse_line(line: &[u8]) -> Result<Line<'_>, SlcanError> {
    let Some((&letter, rest)) = line.split_first() else {
        return Ok(Line::Ok);
    };
    let (id_digits, fd) = match letter {
        b't' => (3, false),
        b'T' => (8, false),
        b'b' | b'd' => (3, true),
        b'B' | b'D' => (8, true),
        b'z' | b'Z' if rest.is_empty() => return Ok(Line::TransmitAck),
        _ => return Ok(Line::Command(letter, rest)),
    };
    if rest.len() < id_digits + 1 {
        return Err(SlcanError::Length);
    }
    let raw = hex_number(&rest[..id_digits])?;
    let id = if id_digits == 3 {
        CanId::standard(raw as u16)
    } else {
        CanId::extended(raw)
    }
    .ok_or(SlcanError::Identifier)?;
    let dlc = hex_value(rest[id_digits])? as usize;
    let len = if fd {
        FD_LENGTHS[dlc]
    } else if dlc <= 8 {
        dlc
    } else {
        return Err(SlcanError::Dlc);
    };
    let hex = &rest[id_digits + 1..];
    if hex.len() != 2 * len {
        return Err(SlcanError::Length);
    }
    let mut data = [0u8; 64];
    for i in 0..len {
        data[i] = hex_value(hex[2 * i])? << 4 | hex_value(hex[2 * i + 1])?;
    }
    let frame = if fd {
        CanFrame::new_fd(id, &data[..len])
    } else {
        CanFrame::new(id, &data[..len])
    };
    frame.map(Line::Frame).map_err(|_| SlcanError::Length)
}

/// What one byte fed to a [`LineReader`] completed.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Feed<'a> {
    /// Nothing yet.
    Pending,
    /// A line (without its terminator).
    Line(&'a [u8]),
    /// The BEL error reply.
    Bell,
    /// A line overflowed [`MAX_LINE`]; it is dropped up to its terminator.
    Overflow,
}

/// Splits a byte stream into lines in a fixed buffer.
#[derive(Clone, Debug)]
pub struct LineReader {
    buf: [u8; MAX_LINE],
    len: usize,
    discarding: bool,
}

impl Default for LineReader {
    fn default() -> Self {
        Self::new()
    }
}

impl LineReader {
    /// An empty reader.
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_LINE],
            len: 0,
            discarding: false,
        }
    }

    /// Feeds one byte. `\r` (and `\n`, for hand-typed input) end a line; a lone `\n` after `\r`
    /// yields an empty line, which callers treat as "OK".
    pub fn push(&mut self, byte: u8) -> Feed<'_> {
        match byte {
            b'\r' | b'\n' => {
                let n = self.len;
                self.len = 0;
                if core::mem::take(&mut self.discarding) {
                    return Feed::Pending;
                }
                Feed::Line(&self.buf[..n])
            }
            BEL => Feed::Bell,
            _ if self.discarding => Feed::Pending,
            _ if self.len == MAX_LINE - 1 => {
                self.len = 0;
                self.discarding = true;
                Feed::Overflow
            }
            _ => {
                self.buf[self.len] = byte;
                self.len += 1;
                Feed::Pending
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn line(f: &CanFrame) -> std::vec::Vec<u8> {
        let mut buf = [0u8; MAX_LINE];
        encode(f, &mut buf).to_vec()
    }

    #[test]
    fn golden_lines() {
        let ext = CanFrame::new(CanId::extended(0x1ABC_DEF0).unwrap(), &[]).unwrap();
        assert_eq!(line(&ext), b"T1ABCDEF00\r");
        let fd = CanFrame::new_fd(CanId::standard(0x7FF).unwrap(), &[0x5A; 12]).unwrap();
        assert_eq!(line(&fd), b"b7FF95A5A5A5A5A5A5A5A5A5A5A5A\r");
        assert_eq!(
            parse_line(b"t00a1ff"),
            Ok(Line::Frame(
                CanFrame::new(CanId::standard(10).unwrap(), &[0xFF]).unwrap()
            ))
        );
        assert_eq!(
            parse_line(b"d0010"),
            Ok(Line::Frame(
                CanFrame::new_fd(CanId::standard(1).unwrap(), &[]).unwrap()
            ))
        );
        assert_eq!(parse_line(b"S8"), Ok(Line::Command(b'S', b"8")));
        assert_eq!(parse_line(b""), Ok(Line::Ok));
        assert_eq!(parse_line(b"z"), Ok(Line::TransmitAck));
    }

    #[test]
    fn bad_lines_are_refused() {
        assert_eq!(parse_line(b"t12"), Err(SlcanError::Length));
        assert_eq!(parse_line(b"t8000"), Err(SlcanError::Identifier));
        assert_eq!(parse_line(b"t1239"), Err(SlcanError::Dlc));
        assert_eq!(parse_line(b"t1231A"), Err(SlcanError::Length));
        assert_eq!(parse_line(b"t1231GG"), Err(SlcanError::NotHex));
        assert_eq!(parse_line(b"T200000000"), Err(SlcanError::Identifier));
    }

    #[test]
    fn reader_splits_lines_and_survives_overflow() {
        let mut r = LineReader::new();
        let mut got = std::vec::Vec::new();
        let input = [&b"t1230\r"[..], &[b'x'; 300][..], b"\r", b"O\r", &[BEL]].concat();
        for b in input {
            match r.push(b) {
                Feed::Line(l) => got.push(std::format!("line {}", std::str::from_utf8(l).unwrap())),
                Feed::Bell => got.push("bell".into()),
                Feed::Overflow => got.push("overflow".into()),
                Feed::Pending => {}
            }
        }
        assert_eq!(got, ["line t1230", "overflow", "line O", "bell"]);
    }

    fn frame() -> impl Strategy<Value = CanFrame> {
        (
            any::<bool>(),
            any::<u32>(),
            any::<bool>(),
            proptest::collection::vec(any::<u8>(), 0..=64),
        )
            .prop_map(|(ext, id, fd, data)| {
                let id = if ext {
                    CanId::extended(id & 0x1FFF_FFFF)
                } else {
                    CanId::standard((id & 0x7FF) as u16)
                }
                .unwrap();
                if fd {
                    let n = crate::can::fd_length_for(data.len()).unwrap();
                    let mut d = data.clone();
                    d.resize(n, 0);
                    CanFrame::new_fd(id, &d).unwrap()
                } else {
                    CanFrame::new(id, &data[..data.len().min(8)]).unwrap()
                }
            })
    }

    proptest! {
        #[test]
        fn lines_round_trip(f in frame()) {
            let l = line(&f);
            prop_assert_eq!(parse_line(&l[..l.len() - 1]), Ok(Line::Frame(f)));
        }

        #[test]
        fn any_bytes_parse_or_fail(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            let _ = parse_line(&bytes);
            let mut r = LineReader::new();
            for b in bytes {
                if let Feed::Line(l) = r.push(b) {
                    let _ = parse_line(l);
                }
            }
        }
    }
}
