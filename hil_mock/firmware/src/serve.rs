//! The car: a [`CarNode`] behind slcan on UART0, with a millisecond clock and the persisted
//! state in RAM.
//!
//! The loop takes the frames waiting on the UART (up to 64 in a round) to [`CarNode::on_frame`]
//! (stamped with the clock), then calls [`CarNode::poll`] for the watchdog and the reassembly
//! timeouts, and starts again; it never blocks on the UART and never ends.
//!
//! **Persistence.** [`RamStore`] keeps the last [`Persisted`] state (session, generation,
//! learner, dedupe windows) in RAM: enough for QEMU, where a restart loses everything anyway
//! (the host's welcome then says the car holds no configured learner). The car's controller writes it to flash instead, in
//! the two-page scheme `hil_mock::flash` emulates (CRC and generation counter, so a torn write
//! never loses the last good state) and starts with [`CarNode::restore`] from what it reads
//! back. The node persists before it acknowledges, so only the store changes.

use core::convert::Infallible;

use protocol::can::CanBus;
use protocol::car::{CarNode, Persist, Persisted};

use crate::clock;
use crate::slcan_bus::SlcanBus;
use crate::uart::Uart0;

/// Frames handled between two polls of the node: an observation in classic frames is 40.
const FRAMES_PER_ROUND: usize = 64;

/// The persisted state, in RAM (see the module documentation).
#[derive(Debug, Default)]
pub struct RamStore {
    last: Option<Persisted>,
    writes: u32,
}

impl RamStore {
    /// Number of writes so far.
    #[allow(dead_code)]
    pub fn writes(&self) -> u32 {
        self.writes
    }
}

impl Persist for RamStore {
    type Error = Infallible;

    fn persist(&mut self, state: &Persisted) -> Result<(), Infallible> {
        self.last = Some(state.clone());
        self.writes = self.writes.wrapping_add(1);
        Ok(())
    }
}

/// Runs the car forever. `None` if the UART or the core peripherals were already taken.
pub fn serve(node: &mut CarNode) -> Option<Infallible> {
    let uart = Uart0::take()?;
    let peripherals = cortex_m::Peripherals::take()?;
    clock::start(peripherals.SYST);
    let mut bus = SlcanBus::new(uart);
    let mut store = RamStore::default();
    loop {
        // The bus never fails (`Infallible`). At most a burst of frames per round, so that a
        // host that never pauses cannot keep the watchdog and the timeouts from running.
        for _ in 0..FRAMES_PER_ROUND {
            let Ok(Some(frame)) = bus.receive() else {
                break;
            };
            let _ = node.on_frame(&frame, clock::now_ms(), &mut bus, &mut store);
        }
        let _ = node.poll(clock::now_ms(), &mut bus);
    }
}
