//! Milliseconds since boot, counted by the SysTick interrupt.
//!
//! SysTick runs from the core clock, 25 MHz on the MPS2 AN386 image (QEMU models the same
//! frequency), and interrupts once per millisecond. Without `-icount`, QEMU's virtual clock follows
//! the host's wall clock, so a millisecond here is a millisecond of real time, which is what the
//! car's watchdog and the reassembly timeouts need when a host drives the image over a socket.
//! With `-icount shift=0` (the benchmarks) one instruction takes one virtual nanosecond instead.
//! The counter wraps after 49 days; its users compare times with wrapping arithmetic.

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m_rt::exception;

/// The core clock of the MPS2 AN386 image.
pub const CORE_HZ: u32 = 25_000_000;

static MILLIS: AtomicU32 = AtomicU32::new(0);

/// Starts the millisecond interrupt.
pub fn start(mut syst: SYST) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(CORE_HZ / 1_000 - 1);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// Milliseconds since [`start`].
pub fn now_ms() -> u32 {
    MILLIS.load(Ordering::Relaxed)
}

#[exception]
fn SysTick() {
    MILLIS.fetch_add(1, Ordering::Relaxed);
}
