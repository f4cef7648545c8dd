//! Worst-case stack by painting: fill the free stack with a pattern, run the workload, find
//! the deepest word that changed.
#![allow(unsafe_code)]

const PAINT: u32 = 0xC0DE_F00D;

unsafe extern "C" {
    static mut _stack_end: u32;
    static _stack_start: u32;
}

fn bounds() -> (usize, usize) {
    // Only the addresses of the linker symbols are taken, which is safe.
    (
        core::ptr::addr_of!(_stack_end) as usize,
        core::ptr::addr_of!(_stack_start) as usize,
    )
}

/// Paints from the bottom of the stack region to 64 bytes below the current stack pointer, and
/// returns the address painting stopped at.
#[inline(never)]
pub fn paint() -> usize {
    let (bottom, _) = bounds();
    let sp = cortex_m::register::msp::read() as usize;
    let mut p = bottom;
    while p + 64 < sp {
        // SAFETY: [bottom, sp - 64) is stack memory not in use by any frame.
        unsafe { (p as *mut u32).write_volatile(PAINT) };
        p += 4;
    }
    p
}

/// The lowest address whose paint was overwritten.
fn lowest_used() -> usize {
    let (bottom, top) = bounds();
    let mut p = bottom;
    // SAFETY: reads within the stack region.
    while p < top && unsafe { (p as *const u32).read_volatile() } == PAINT {
        p += 4;
    }
    p
}

/// Bytes used below `painted_to` (what [`paint`] returned) since that call: the depth of the
/// calls made in between, plus at most 64 bytes of the caller's frame.
pub fn depth_below(painted_to: usize) -> usize {
    painted_to.saturating_sub(lowest_used())
}

/// Bytes of stack used at the deepest point since the last [`paint`].
pub fn high_water() -> usize {
    bounds().1 - lowest_used()
}

/// Size of the stack region (RAM not taken by statics).
pub fn region() -> usize {
    let (bottom, top) = bounds();
    top - bottom
}
