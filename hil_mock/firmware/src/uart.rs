//! The CMSDK APB UART0 of the MPS2 AN386 board, which QEMU connects to its first `-serial`.
//!
//! Register map (ARM CMSDK APB UART, offsets from 0x4000_4000): DATA 0x00, STATE 0x04 (bit 0
//! TX buffer full, bit 1 RX buffer full), CTRL 0x08 (bit 0 TX enable, bit 1 RX enable),
//! INTSTATUS 0x0C, BAUDDIV 0x10. STATE bit 3 is the receive overrun flag (a byte arrived while the
//! buffer was still full; written with 1 to clear). Volatile accesses to these five registers are
//! the firmware's `unsafe`, with the stack painting of `stack.rs`.
//!
//! Under QEMU the receiver never overruns: QEMU hands the UART the next byte from its character
//! device only once the guest has read the previous one, so a socket simply waits. A real UART at
//! 1 Mbit/s does overrun when the loop is busy for longer than a character time; the slcan bus
//! above counts that and drops the line that lost a byte.
#![allow(unsafe_code)]

use core::sync::atomic::{AtomicBool, Ordering};

const BASE: usize = 0x4000_4000;
const DATA: *mut u32 = BASE as *mut u32;
const STATE: *mut u32 = (BASE + 0x04) as *mut u32;
const CTRL: *mut u32 = (BASE + 0x08) as *mut u32;
const BAUDDIV: *mut u32 = (BASE + 0x10) as *mut u32;

const TX_FULL: u32 = 1 << 0;
const RX_FULL: u32 = 1 << 1;
const RX_OVERRUN: u32 = 1 << 3;

static TAKEN: AtomicBool = AtomicBool::new(false);

/// The UART, owned once.
pub struct Uart0 {
    _private: (),
}

impl Uart0 {
    /// The UART, the first time; `None` afterwards.
    pub fn take() -> Option<Self> {
        if TAKEN.swap(true, Ordering::AcqRel) {
            return None;
        }
        // SAFETY: BASE is the UART0 block of this board; these are its documented registers, and
        // `TAKEN` makes this the only owner.
        unsafe {
            BAUDDIV.write_volatile(16);
            CTRL.write_volatile(0b11);
        }
        Some(Self { _private: () })
    }

    /// A received byte, if one is waiting.
    pub fn try_read(&mut self) -> Option<u8> {
        // SAFETY: see `take`.
        unsafe {
            if STATE.read_volatile() & RX_FULL != 0 {
                Some(DATA.read_volatile() as u8)
            } else {
                None
            }
        }
    }

    /// Whether the receiver overran since the last call (a byte was lost); clears the flag.
    pub fn take_overrun(&mut self) -> bool {
        // SAFETY: see `take`.
        unsafe {
            let overrun = STATE.read_volatile() & RX_OVERRUN != 0;
            if overrun {
                STATE.write_volatile(RX_OVERRUN);
            }
            overrun
        }
    }

    /// Sends bytes, waiting while the transmit buffer is full.
    pub fn write_all(&mut self, bytes: &[u8]) {
        for &b in bytes {
            // SAFETY: see `take`.
            unsafe {
                while STATE.read_volatile() & TX_FULL != 0 {}
                DATA.write_volatile(b as u32);
            }
        }
    }
}
