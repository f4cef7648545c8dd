//! A [`CanBus`] over UART0 speaking slcan: the car as a serial-line CAN node.
//!
//! Receiving is non-blocking: [`SlcanBus::receive`] takes the bytes already waiting in the UART,
//! one at a time, through a [`LineReader`], and returns as soon as a line completes a frame or no
//! byte is waiting. What the host may send besides frames is handled without ever failing:
//!
//! * commands (`C`, `S8`, `O`, … as a host opens an adapter) are answered like an adapter
//!   answers them: `\r` for the ones it knows, BEL for the others; `V` and `N` with a version and
//!   a serial number;
//! * `\r` replies, BEL and `z`/`Z` acknowledgements are ignored;
//! * malformed lines and lines longer than [`protocol::slcan::MAX_LINE`] are dropped and
//!   counted;
//! * a receiver overrun drops the line in progress up to its terminator, counted.
//!
//! A frame lost this way is the reassembler's business: it sees a gap or a timeout and drops
//! the message, as it would on a CAN bus. Frames are transmitted as `t`/`T` lines (`b`/`B` for
//! CAN FD frames, which the car does not send in classic mode).

use core::convert::Infallible;

use protocol::can::{CanBus, CanFrame};
use protocol::slcan::{BEL, Feed, Line, LineReader, MAX_LINE, encode, parse_line};

use crate::uart::Uart0;

/// What the bus has seen, for diagnostics.
#[derive(Clone, Copy, Default, Debug, PartialEq, Eq)]
pub struct BusStats {
    /// Frames received.
    pub frames_in: u32,
    /// Frames transmitted.
    pub frames_out: u32,
    /// Commands answered.
    pub commands: u32,
    /// Lines that did not parse.
    pub bad_lines: u32,
    /// Lines longer than the longest slcan line.
    pub overflows: u32,
    /// Receiver overruns.
    pub overruns: u32,
}

/// slcan over the board's UART0.
pub struct SlcanBus {
    uart: Uart0,
    reader: LineReader,
    /// Dropping bytes up to the next terminator after an overrun.
    resync: bool,
    stats: BusStats,
}

impl SlcanBus {
    /// The bus on `uart`.
    pub const fn new(uart: Uart0) -> Self {
        Self {
            uart,
            reader: LineReader::new(),
            resync: false,
            stats: BusStats {
                frames_in: 0,
                frames_out: 0,
                commands: 0,
                bad_lines: 0,
                overflows: 0,
                overruns: 0,
            },
        }
    }

    /// The counters so far.
    #[cfg_attr(
        not(feature = "cli"),
        expect(
            dead_code,
            reason = "read by the echo diagnostic of the command-line images"
        )
    )]
    pub fn stats(&self) -> BusStats {
        self.stats
    }
}

/// An adapter's reply to command `letter`.
fn reply(letter: u8) -> &'static [u8] {
    match letter {
        b'V' => b"V1013\r",
        b'N' => b"NCAR0\r",
        b'O' | b'C' | b'L' | b'S' | b's' | b'F' | b'X' | b'Z' | b'M' | b'm' | b'W' | b'Q' => b"\r",
        _ => &[BEL],
    }
}

impl CanBus for SlcanBus {
    type Error = Infallible;

    fn transmit(&mut self, frame: &CanFrame) -> Result<(), Infallible> {
        let mut buf = [0u8; MAX_LINE];
        self.uart.write_all(encode(frame, &mut buf));
        self.stats.frames_out = self.stats.frames_out.wrapping_add(1);
        Ok(())
    }

    fn receive(&mut self) -> Result<Option<CanFrame>, Infallible> {
        loop {
            if self.uart.take_overrun() {
                self.stats.overruns = self.stats.overruns.wrapping_add(1);
                // The line in progress lost a byte: empty the reader, skip to the next terminator.
                let _ = self.reader.push(b'\r');
                self.resync = true;
            }
            let Some(byte) = self.uart.try_read() else {
                return Ok(None);
            };
            if self.resync {
                self.resync = !matches!(byte, b'\r' | b'\n');
                continue;
            }
            match self.reader.push(byte) {
                Feed::Pending | Feed::Bell => {}
                Feed::Overflow => self.stats.overflows = self.stats.overflows.wrapping_add(1),
                Feed::Line(line) => match parse_line(line) {
                    Ok(Line::Frame(frame)) => {
                        self.stats.frames_in = self.stats.frames_in.wrapping_add(1);
                        return Ok(Some(frame));
                    }
                    Ok(Line::Command(letter, _)) => {
                        self.stats.commands = self.stats.commands.wrapping_add(1);
                        self.uart.write_all(reply(letter));
                    }
                    Ok(Line::Ok | Line::TransmitAck) => {}
                    Err(_) => self.stats.bad_lines = self.stats.bad_lines.wrapping_add(1),
                },
            }
        }
    }
}
