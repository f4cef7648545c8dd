//! The car's firmware on a Cortex-M4F (QEMU `mps2-an386`).
//!
//! Modes, chosen by the semihosting command line (`-semihosting-config ...,arg=MODE,arg=N`):
//!
//! * `bench-act N [SCENE]`: N ticks of observation → action (evaluate 64 trajectories + select),
//!   on the three bench scenes in turn or on scene 0 (open), 1 (corridor) or 2 (cluttered);
//! * `bench-learn N`: N feedback → update steps;
//! * `stack`: the worst-case stack of act and of every feedback kind, by painting.
//!
//! Every mode prints its result on the semihosting console and exits with status 0.
//! No allocator is linked: the agent lives in a `StaticCell`, counted by the linker.

#![no_std]
#![no_main]
#![deny(unsafe_code)]

mod bench;
#[cfg(feature = "replay")]
mod replay;
mod slcan_bus;
mod stack;
mod uart;

use cortex_m_rt::entry;
use firmware_core::agent::Agent;
use firmware_core::{Learner, LearnerParams, ValidLearnerParams};
use semihosting::{println, process};
use static_cell::ConstStaticCell;

/// The agent, built at compile time into .bss/.data: never on the stack.
static AGENT: ConstStaticCell<Agent> =
    ConstStaticCell::new(Agent::new(Learner::new(ValidLearnerParams::DEFAULT)));

fn learner() -> Learner {
    let params = LearnerParams::default().with_initial([1.0, 2.0, 1.0, 1.0, -3.0, 0.5]);
    match params.check() {
        Ok(p) => Learner::new(p),
        Err(_) => process::exit(2),
    }
}

fn number(arg: Option<&str>) -> u32 {
    arg.and_then(|s| s.parse().ok()).unwrap_or(0)
}

#[entry]
fn main() -> ! {
    let agent = AGENT.take();
    agent.set_learner(learner());
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
        Some("bench-act") => {
            let n = number(args.next());
            let only = args.next().and_then(|s| s.parse().ok());
            let sum = bench::act(agent, n, only);
            println!("bench-act {n} checksum {sum}");
        }
        Some("bench-learn") => {
            let n = number(args.next());
            let ok = bench::learn(agent, n);
            println!("bench-learn {n} accepted {ok}");
        }
        Some("stack") => {
            let scenes = bench::scenes();
            let mut act = 0;
            for (t, scene) in scenes.iter().enumerate() {
                let at = stack::paint();
                let _ = agent.act(t as u32, scene);
                act = act.max(stack::depth_below(at));
            }
            let mut learn = 0;
            for i in 0..3 {
                let fb = bench::feedback(i);
                let at = stack::paint();
                let _ = agent.feedback(2, &fb);
                learn = learn.max(stack::depth_below(at));
            }
            println!(
                "stack act {act} learn {learn} main {} deepest {} region {}",
                stack::used_above(stack::paint()),
                stack::high_water(),
                stack::region()
            );
        }
        #[cfg(feature = "replay")]
        Some("replay-count") => println!("replay-count {}", replay::count()),
        #[cfg(feature = "replay")]
        Some("replay") => {
            let last = number(args.next()) as usize;
            let run_last = args.next() == Some("do");
            let (what, sum) = replay::replay(agent, last, run_last);
            match what {
                replay::Last::Restore => println!("replay {last} restore checksum {sum}"),
                replay::Last::Act(t, a) => {
                    println!("replay {last} act tick {t} action {a} checksum {sum}")
                }
                replay::Last::Feedback(t, ok) => {
                    println!("replay {last} feedback tick {t} applied {ok} checksum {sum}")
                }
                replay::Last::Other => println!("replay {last} other checksum {sum}"),
            }
        }
        Some("echo") => echo(),
        other => {
            println!(
                "error: unknown mode {:?}; expected bench-act N, bench-learn N or stack",
                other
            );
            process::exit(2)
        }
    }
    process::exit(0)
}

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

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    println!("panic: {}", info);
    process::exit(101)
}
