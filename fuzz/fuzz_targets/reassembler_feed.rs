//! Any sequence of CAN frames fed to the reassemblers gives `Consumed`, `Complete` or `Error`,
//! never a panic, and a completed message never exceeds its buffer; the car's inbox opens
//! every completed PDU with its endpoint (key 0x42…, epoch 3).
//!
//! Input: a sequence of records `[ctrl][len][data...]` (the format `fuzz_seeds` writes):
//! * `ctrl` bits 0–2: the stream: 0–5 the host → car identifier of class 0–5, 6 the car → host
//!   heartbeat identifier (not for the car's inbox), 7 a foreign identifier (0x7FF);
//!   bit 3: CAN FD; bits 4–7: milliseconds since the previous frame, in steps of 4 (0–60 ms,
//!   across the 50 ms reassembly timeout);
//! * `len` low nibble: the data length code (classic: 0–8, larger codes mean 8; FD: 0–15 →
//!   0–64 bytes);
//! * the data bytes; missing ones at the end of the input are zeros.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::can::{CanFrame, CanId, FD_LENGTHS};
use protocol::isotp::{FeedResult, Reassembler};
use protocol::link::{Inbox, Received};
use protocol::message::MAX_MESSAGE_SIZE;
use protocol::secure::{CarSecurity, Key};
use protocol::stream::{Class, Direction, Stream};

fn id(selector: u8) -> CanId {
    match selector {
        0..=5 => Stream::new(Class::ALL[selector as usize], Direction::HostToCar).id(),
        6 => Stream::new(Class::Heartbeat, Direction::CarToHost).id(),
        _ => CanId::Standard(0x7FF),
    }
}

fuzz_target!(|data: &[u8]| {
    let mut inbox = Inbox::new(Direction::HostToCar);
    let mut car = CarSecurity::new(&Key::new([0x42; 16]), 3);
    let mut small = Reassembler::<32>::new();
    let mut big: Reassembler = Reassembler::new();
    let mut now = 0u32;
    let mut rest = data;
    while let [ctrl, len, tail @ ..] = rest {
        let fd = ctrl & 0x08 != 0;
        let n = if fd {
            FD_LENGTHS[(len & 0x0F) as usize]
        } else {
            ((len & 0x0F) as usize).min(8)
        };
        let mut bytes = [0u8; 64];
        let take = n.min(tail.len());
        bytes[..take].copy_from_slice(&tail[..take]);
        rest = &tail[take..];
        now = now.wrapping_add(4 * (ctrl >> 4) as u32);
        let id = id(ctrl & 0x07);
        let frame = if fd {
            CanFrame::new_fd(id, &bytes[..n])
        } else {
            CanFrame::new(id, &bytes[..n])
        }
        .expect("valid lengths by construction");

        match inbox.feed(&frame, now, &mut car) {
            Received::Message(m) => {
                let stream = Stream::from_id(frame.id()).expect("a message came on a stream");
                assert!(stream.carries(m.kind()));
            }
            Received::Nothing | Received::Error(_) => {}
        }
        let _ = inbox.poll(now);
        if let FeedResult::Complete(b) = small.feed(&frame, now) {
            assert!(!b.is_empty() && b.len() <= 32);
        }
        if let FeedResult::Complete(b) = big.feed(&frame, now) {
            assert!(!b.is_empty() && b.len() <= MAX_MESSAGE_SIZE);
        }
        let _ = big.poll(now);
    }
});
