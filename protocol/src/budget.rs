//! Bus-load arithmetic: the bits one frame, one message and one control tick put on the wire.
//!
//! # Classic CAN (ISO 11898-1, base format, 11-bit identifier)
//!
//! A data frame with `n` data bytes has these fields (bits): start of frame 1, identifier 11,
//! RTR 1, IDE 1, r0 1, DLC 4, data `8n`, CRC 15, CRC delimiter 1, ACK slot 1, ACK delimiter 1,
//! end of frame 7, and the interframe space 3 before the next frame. Bit stuffing (a complement
//! bit after five equal bits) covers start of frame through CRC, `34 + 8n` bits; in the worst case
//! the first stuff bit comes after 5 bits and each further one after 4 more, so at most
//! `⌊(34 + 8n − 1) / 4⌋` stuff bits. Hence (Davis, Burns, Bril, Lukkien, *Controller Area Network
//! (CAN) schedulability analysis: refuted, revisited and revised*, Real-Time Systems 35, 2007):
//!
//! ```text
//! bits(n) = 8n + 47 + ⌊(34 + 8n − 1) / 4⌋        (55 bits for n = 0, 135 for n = 8)
//! ```
//!
//! # CAN FD (ISO 11898-1:2015, base format, 11-bit identifier, ISO CRC)
//!
//! * Arbitration phase, nominal rate: start of frame 1, identifier 11, RRS 1, IDE 1, FDF 1, res 1,
//!   BRS 1 (17 bits), then after the data phase CRC delimiter 1, ACK slot 1, ACK delimiter 1,
//!   end of frame 7, interframe space 3 (13 bits). The bit rate switches at the sample points of
//!   BRS and of the CRC delimiter; both are counted at the (slower) nominal rate.
//! * Data phase, data rate: ESI 1, DLC 4, data `8n`, then the CRC field: stuff count 4 (3-bit
//!   Gray code and parity) and CRC 17 (`n ≤ 16`) or 21 (`n > 16`).
//! * Dynamic stuffing covers start of frame through the data field, `22 + 8n` bits: at most
//!   `⌊(22 + 8n − 1) / 4⌋` stuff bits, of which at most `⌊(17 − 1) / 4⌋ = 4` fall in the
//!   arbitration phase; the worst case for time puts those 4 at the nominal rate and the rest in
//!   the data phase.
//! * Fixed stuff bits in the CRC field: one before the stuff count and one after every 4 bits
//!   of stuff count and CRC: `1 + ⌊(4 + crc − 1) / 4⌋`, i.e. 6 with CRC-17 and 7 with CRC-21.
//!
//! Assumptions: no error frames, no overload frames, no remote frames, no bus idle time between
//! frames, and every frame of a message sent back to back. Frame sizes come from
//! [`crate::isotp::frame_len`], so the arithmetic follows the segmentation exactly.
//!
//! ```
//! use protocol::budget::{Bus, classic_frame_bits, tick_load_percent};
//! assert_eq!(classic_frame_bits(8), 135);
//! let load = tick_load_percent(Bus::CLASSIC_1M, 10);
//! assert!(load < 5.0, "{load}");
//! ```

use crate::isotp::{FrameMode, frame_count, frame_len};
use crate::message::MessageKind;

/// The control rate of the car (ticks per second).
pub const CONTROL_RATE_HZ: u32 = 10;

/// Largest share of a 1 Mbit/s classic CAN bus one tick's traffic may take, MACs included
/// (DESIGN section 7).
pub const MAX_TICK_LOAD_PERCENT: f64 = 5.0;

/// The messages of one control tick with a correction, in the worst case: the observation
/// (host → car), the action command (car → host), one feedback (host → car), its ack
/// (car → host) and one heartbeat each way. Every one at its largest secured size (freshness
/// byte and MAC included).
pub const TICK_TRAFFIC: [MessageKind; 6] = [
    MessageKind::Observation,
    MessageKind::Action,
    MessageKind::Feedback,
    MessageKind::Ack,
    MessageKind::Heartbeat,
    MessageKind::Heartbeat,
];

/// Bits of a classic CAN data frame with `n` data bytes (`n <= 8`), worst-case stuffing,
/// interframe space included.
pub const fn classic_frame_bits(n: usize) -> u32 {
    let stuffed = 34 + 8 * n as u32;
    stuffed + 13 + (stuffed - 1) / 4
}

/// Bits of a CAN FD frame, by bit rate.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Default)]
pub struct FdBits {
    /// Bits at the nominal (arbitration) rate.
    pub nominal: u32,
    /// Bits at the data rate.
    pub data: u32,
}

impl FdBits {
    const fn add(self, other: FdBits) -> FdBits {
        FdBits {
            nominal: self.nominal + other.nominal,
            data: self.data + other.data,
        }
    }
}

/// Bits of a CAN FD data frame with `n` data bytes (one of the FD lengths), worst-case dynamic
/// stuffing, bit-rate switching on.
pub const fn fd_frame_bits(n: usize) -> FdBits {
    const ARBITRATION: u32 = 17;
    const TAIL: u32 = 13;
    const STUFF_COUNT: u32 = 4;
    let data_fields = 1 + 4 + 8 * n as u32;
    let dynamic_stuff = (ARBITRATION + data_fields - 1) / 4;
    let arbitration_stuff = (ARBITRATION - 1) / 4;
    let crc = if n <= 16 { 17 } else { 21 };
    let fixed_stuff = 1 + (STUFF_COUNT + crc - 1) / 4;
    FdBits {
        nominal: ARBITRATION + arbitration_stuff + TAIL,
        data: data_fields + (dynamic_stuff - arbitration_stuff) + STUFF_COUNT + crc + fixed_stuff,
    }
}

/// Bits of all classic frames of a message of `len` bytes.
pub const fn classic_message_bits(len: usize) -> u32 {
    let mut bits = 0;
    let mut i = 0;
    while i < frame_count(len, FrameMode::Classic) {
        bits += classic_frame_bits(frame_len(len, FrameMode::Classic, i));
        i += 1;
    }
    bits
}

/// Bits of all CAN FD frames of a message of `len` bytes.
pub const fn fd_message_bits(len: usize) -> FdBits {
    let mut bits = FdBits {
        nominal: 0,
        data: 0,
    };
    let mut i = 0;
    while i < frame_count(len, FrameMode::Fd) {
        bits = bits.add(fd_frame_bits(frame_len(len, FrameMode::Fd, i)));
        i += 1;
    }
    bits
}

/// A bus and its bit rates (bit/s).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum Bus {
    /// Classic CAN.
    Classic {
        /// The bit rate.
        bitrate: u32,
    },
    /// CAN FD with bit-rate switching.
    Fd {
        /// The arbitration-phase bit rate.
        nominal: u32,
        /// The data-phase bit rate.
        data: u32,
    },
}

impl Bus {
    /// Classic CAN at 1 Mbit/s.
    pub const CLASSIC_1M: Bus = Bus::Classic { bitrate: 1_000_000 };
    /// Classic CAN at 500 kbit/s.
    pub const CLASSIC_500K: Bus = Bus::Classic { bitrate: 500_000 };
    /// CAN FD, 1 Mbit/s arbitration, 5 Mbit/s data.
    pub const FD_1M_5M: Bus = Bus::Fd {
        nominal: 1_000_000,
        data: 5_000_000,
    };

    /// The frames this bus carries.
    pub const fn mode(self) -> FrameMode {
        match self {
            Bus::Classic { .. } => FrameMode::Classic,
            Bus::Fd { .. } => FrameMode::Fd,
        }
    }

    /// Time on the wire of a message of `len` bytes (ns, rounded up).
    pub const fn message_time_ns(self, len: usize) -> u64 {
        match self {
            Bus::Classic { bitrate } => ns(classic_message_bits(len), bitrate),
            Bus::Fd { nominal, data } => {
                let bits = fd_message_bits(len);
                ns(bits.nominal, nominal) + ns(bits.data, data)
            }
        }
    }
}

const fn ns(bits: u32, bitrate: u32) -> u64 {
    (bits as u64 * 1_000_000_000).div_ceil(bitrate as u64)
}

/// Time on the wire of one tick's [`TICK_TRAFFIC`], every message at its largest (ns).
pub const fn tick_time_ns(bus: Bus) -> u64 {
    let mut t = 0;
    let mut i = 0;
    while i < TICK_TRAFFIC.len() {
        t += bus.message_time_ns(TICK_TRAFFIC[i].max_encoded_size());
        i += 1;
    }
    t
}

/// The share of `bus` that [`TICK_TRAFFIC`] takes at `rate_hz` ticks per second (percent).
pub fn tick_load_percent(bus: Bus, rate_hz: u32) -> f64 {
    tick_time_ns(bus) as f64 * rate_hz as f64 / 1.0e7
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::can::FD_LENGTHS;

    #[test]
    fn classic_frames_match_the_literature() {
        // Davis et al. 2007: 55 bits for 0 bytes, 135 bits for 8 bytes (11-bit identifiers).
        assert_eq!(classic_frame_bits(0), 55);
        assert_eq!(classic_frame_bits(8), 135);
        // Without stuffing an 8-byte frame is 111 bits; stuffing adds at most 24.
        assert_eq!(classic_frame_bits(8) - (8 * 8 + 47), 24);
        assert_eq!(classic_frame_bits(1), 65);
    }

    #[test]
    fn fd_frames_by_hand() {
        // 64 bytes: nominal 17 + 4 + 13 = 34; data 1 + 4 + 512 = 517 plus
        // (⌊(17 + 517 − 1)/4⌋ − 4 = 129) dynamic stuff bits, 4 stuff count, 21 CRC, 7 fixed.
        assert_eq!(
            fd_frame_bits(64),
            FdBits {
                nominal: 34,
                data: 517 + 129 + 4 + 21 + 7
            }
        );
        // 8 bytes: data 69 + (⌊85/4⌋ − 4 = 17) + 4 + 17 + 6.
        assert_eq!(
            fd_frame_bits(8),
            FdBits {
                nominal: 34,
                data: 69 + 17 + 4 + 17 + 6
            }
        );
        // The CRC grows from 17 to 21 bits between 16 and 20 bytes.
        assert_eq!(
            fd_frame_bits(20).data - fd_frame_bits(16).data,
            32 + 8 + 4 + 1
        );
        for w in FD_LENGTHS.windows(2) {
            assert!(fd_frame_bits(w[1]).data > fd_frame_bits(w[0]).data);
        }
    }

    #[test]
    fn messages_sum_their_frames() {
        // 19 bytes classic: FF (6 data) + CF (7 data) + CF (6 data in a 7-byte frame).
        assert_eq!(classic_message_bits(19), 135 + 135 + classic_frame_bits(7));
        assert_eq!(classic_message_bits(20), 3 * 135);
        // 7 bytes: one single frame of 8 bytes.
        assert_eq!(classic_message_bits(7), 135);
        // 100 bytes FD: FF 64 (62 data) + CF with 38 data → 39 bytes padded to 48.
        assert_eq!(
            fd_message_bits(100),
            fd_frame_bits(64).add(fd_frame_bits(48))
        );
    }

    #[test]
    fn one_tick_stays_under_five_percent_of_classic_can_at_1_mbit() {
        let load = tick_load_percent(Bus::CLASSIC_1M, CONTROL_RATE_HZ);
        assert_eq!(MAX_TICK_LOAD_PERCENT, 5.0, "DESIGN section 7");
        assert!(
            load < MAX_TICK_LOAD_PERCENT,
            "one tick takes {load:.2}% of a 1 Mbit/s classic CAN bus"
        );
        // The MAC and the freshness byte are in every message of the tick.
        for kind in TICK_TRAFFIC {
            assert!(kind.max_encoded_size() > crate::secure::SECURED_OVERHEAD);
        }
        // The figure is what the frames add up to (docs/protocol.md quotes 4.79%): the
        // observation is 3.08% of the bus, so a larger scan or object list would break the
        // budget.
        assert_eq!(tick_time_ns(Bus::CLASSIC_1M), 4_790_000);
        let obs = tick_load_percent(Bus::CLASSIC_1M, CONTROL_RATE_HZ)
            - (tick_time_ns(Bus::CLASSIC_1M)
                - Bus::CLASSIC_1M.message_time_ns(MessageKind::Observation.max_encoded_size()))
                as f64
                * CONTROL_RATE_HZ as f64
                / 1.0e7;
        assert!(obs > 3.0, "{obs}");
        assert!(tick_load_percent(Bus::CLASSIC_500K, CONTROL_RATE_HZ) > load * 1.99);
        assert!(tick_load_percent(Bus::FD_1M_5M, CONTROL_RATE_HZ) < load);
    }
}
