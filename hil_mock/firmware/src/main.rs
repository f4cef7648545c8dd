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
mod stack;
#[allow(dead_code)]
mod uart;

use cortex_m_rt::entry;
use firmware_core::agent::Agent;
use firmware_core::{Learner, LearnerParams, ValidLearnerParams};
use semihosting::{println, process};
use static_cell::ConstStaticCell;

/// The agent, built at compile time into .bss/.data: never on the stack.
static AGENT: ConstStaticCell<Agent> = ConstStaticCell::new(Agent::new(Learner::new(ValidLearnerParams::DEFAULT)));

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
        other => {
            println!("error: unknown mode {:?}; expected bench-act N, bench-learn N or stack", other);
            process::exit(2)
        }
    }
    process::exit(0)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    println!("panic: {}", info);
    process::exit(101)
}
