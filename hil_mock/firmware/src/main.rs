//! The car's firmware on a Cortex-M4F (QEMU `mps2-an386`).
//!
//! Modes, chosen by the semihosting command line (`-semihosting-config ...,arg=MODE,arg=N`):
//!
//! * `serve` (the default, also with no arguments): the car. A [`protocol::car::CarNode`] on
//!   UART0 speaking slcan (classic CAN frames), with a SysTick millisecond clock and its persisted
//!   state in RAM; see [`serve`]. QEMU connects UART0 to its first `-serial`, e.g.
//!   `-serial tcp:127.0.0.1:PORT,server`, and `host-sim run --link slcan+tcp://127.0.0.1:PORT
//!   --key FILE` drives it;
//! * `echo`: a diagnostic of the slcan link (every frame is answered with the bus's counters);
//!
//! and with the cargo feature `bench` (on by default; see `modes`):
//!
//! * `bench-act N [SCENE]`: N ticks of observation → action (evaluate 64 trajectories + select),
//!   on the three bench scenes in turn or on scene 0 (open), 1 (corridor) or 2 (cluttered);
//! * `bench-learn N`: N feedback → update steps;
//! * `bench-node N`: N observations through the car node, frame by frame (reassembly, decoding,
//!   act, the answer encoded and segmented);
//! * `stack`: the worst-case stack of act, of every feedback kind and of the car node, by painting;
//! * `replay-count`, `replay I 1|0`, `replay-all` (feature `replay`): ticks recorded from the
//!   simulator.
//!
//! The measurement modes print their result on the semihosting console and exit with status 0.
//! Reading the command line is a semihosting call, so an image with the feature `cli` (implied by
//! `bench`, on by default) expects a debugger or QEMU's `-semihosting-config enable=on`; without
//! one the call raises a HardFault and the image stops. The car's own image
//! (`--no-default-features`) has no command line and no semihosting: it serves at once, and a
//! panic resets the controller (the car would restore its state from flash).
//! No allocator is linked: the node (and the bench agent) live in `ConstStaticCell`s whose
//! initial values are all zeros (`.bss`, no flash), completed in place at start.
//!
//! **The key** is built into the image: `build.rs` reads the key file named by `CAR_KEY_FILE`
//! (`hil_mock keygen FILE`; the hosts use the same file) and refuses to build without one
//! unless the feature `insecure` asks for the public all-zero key. The node installs it at
//! start with the epoch [`EPOCH`].

#![no_std]
#![no_main]
#![deny(unsafe_code)]

#[cfg(feature = "bench")]
mod bench;
mod clock;
#[cfg(feature = "bench")]
mod modes;
#[cfg(feature = "replay")]
mod replay;
mod serve;
mod slcan_bus;
#[cfg(feature = "bench")]
mod stack;
mod uart;

use cortex_m_rt::entry;
use firmware_core::{Learner, ValidLearnerParams};
use protocol::car::{CarConfig, CarNode, CarNodeSlot};
use protocol::secure::Key;
#[cfg(feature = "cli")]
use semihosting::{println, process};
use static_cell::ConstStaticCell;

mod key {
    include!(concat!(env!("OUT_DIR"), "/key.rs"));
}

/// The car's epoch. This image has no flash and no entropy source under QEMU, so every start is
/// epoch 1 and a restart forgets everything anyway (its state is in RAM); a car's controller
/// takes a boot counter kept in flash (incremented and written before it serves) or a number
/// from its TRNG, so that frames recorded before a restart are refused after it
/// (docs/protocol.md, threat model).
pub const EPOCH: u32 = 1;

/// The car's key, as built in.
pub fn car_key() -> Key {
    Key::new(key::KEY)
}

/// The car node, completed at start: the default learner (the host configures its own), the
/// default configuration and the built-in key.
fn node() -> &'static mut CarNode {
    let node = NODE.take().init(
        CarConfig::DEFAULT,
        Learner::new(ValidLearnerParams::DEFAULT),
    );
    node.install_key(&car_key(), EPOCH);
    node
}

/// The car node's storage: every byte zero, so it lands in `.bss` (no initial value in flash)
/// and is completed in place at start ([`CarNodeSlot::init`]), never built on the stack.
static NODE: ConstStaticCell<CarNodeSlot> = ConstStaticCell::new(CarNodeSlot::EMPTY);

/// The agent of the measurement modes (in `.bss` too; `modes::run` gives it its learner).
#[cfg(feature = "bench")]
static AGENT: ConstStaticCell<firmware_core::agent::Agent> =
    ConstStaticCell::new(firmware_core::agent::Agent::BLANK);

#[cfg(feature = "cli")]
#[entry]
fn main() -> ! {
    let node = node();
    if car_key().is_insecure() {
        println!(
            "WARNING: built with --features insecure: the public all-zero key; anyone who can \
             send a frame can drive and teach this car"
        );
    }
    let args = match semihosting::experimental::env::args::<256>() {
        Ok(a) => a,
        Err(_) => {
            println!("error: no semihosting command line");
            process::exit(2)
        }
    };
    let mut args = args.map(|a| a.unwrap_or(""));
    let _program = args.next();
    match args.next() {
        None | Some("serve") => {
            let _ = serve::serve(node);
            println!("error: UART0 or the core peripherals already taken");
            process::exit(3)
        }
        Some("echo") => echo(),
        #[cfg(feature = "bench")]
        Some(mode) => modes::run(mode, args, AGENT.take(), node),
        #[cfg(not(feature = "bench"))]
        Some(other) => {
            println!(
                "error: unknown mode {other:?}; expected serve or echo (others: feature bench)"
            );
            process::exit(2)
        }
    }
}

/// The car's image: no command line, serve at once.
#[cfg(not(feature = "cli"))]
#[entry]
fn main() -> ! {
    let node = node();
    let _ = serve::serve(node);
    // UART0 or the core peripherals were already taken: nothing to serve with.
    cortex_m::peripheral::SCB::sys_reset()
}

#[cfg(feature = "cli")]
/// Diagnostic of the slcan link: every frame received on UART0 is answered with a frame whose
/// identifier is one more and whose data are four little-endian `u16` counters of the bus: frames
/// received, malformed lines, overlong lines, commands answered.
fn echo() -> ! {
    use protocol::can::{CanBus, CanFrame, CanId};
    let Some(uart) = uart::Uart0::take() else {
        process::exit(3)
    };
    let mut bus = slcan_bus::SlcanBus::new(uart);
    loop {
        if let Ok(Some(f)) = bus.receive() {
            let id = CanId::standard(((f.id().raw() + 1) & 0x7FF) as u16).unwrap_or(f.id());
            let s = bus.stats();
            let mut data = [0u8; 8];
            for (i, v) in [s.frames_in, s.bad_lines, s.overflows, s.commands]
                .into_iter()
                .enumerate()
            {
                data[2 * i..2 * i + 2].copy_from_slice(&(v as u16).to_le_bytes());
            }
            if let Ok(back) = CanFrame::new(id, &data) {
                let _ = bus.transmit(&back);
            }
        }
    }
}

#[cfg(feature = "cli")]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    println!("panic: {}", info);
    process::exit(101)
}

/// Without a console, a panic resets the controller.
#[cfg(not(feature = "cli"))]
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo<'_>) -> ! {
    cortex_m::peripheral::SCB::sys_reset()
}
