//! Prints the bus budget: every message at its largest, its frames and bits on classic CAN and
//! CAN FD, and the load of one control tick (`docs/protocol.md` quotes this output).
//!
//! ```text
//! cargo run -p protocol --example bus_budget
//! ```

use firmware_core::FeedbackKind;
use protocol::budget::{
    Bus, CONTROL_RATE_HZ, MAX_TICK_LOAD_PERCENT, TICK_TRAFFIC, classic_message_bits,
    fd_message_bits, tick_load_percent,
};
use protocol::isotp::{FrameMode, frame_count};
use protocol::message::{FeedbackMessage, MessageKind};

const BUSES: [(&str, Bus); 3] = [
    ("classic 1 Mbit/s", Bus::CLASSIC_1M),
    ("classic 500 kbit/s", Bus::CLASSIC_500K),
    ("CAN FD 1/5 Mbit/s", Bus::FD_1M_5M),
];

fn percent(ns: u64) -> f64 {
    ns as f64 * CONTROL_RATE_HZ as f64 / 1.0e7
}

fn main() {
    println!(
        "Every message at its largest (secured: version + postcard + freshness byte + 4-byte AES-CMAC), worst-case bit stuffing.\n"
    );
    println!(
        "| message | bytes | frames classic | frames FD | bits classic | bits FD (nominal + data) | µs classic 1M | µs FD 1/5M |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for kind in MessageKind::ALL {
        let n = kind.max_encoded_size();
        let fd = fd_message_bits(n);
        println!(
            "| {kind} | {n} | {} | {} | {} | {} + {} | {:.1} | {:.1} |",
            frame_count(n, FrameMode::Classic),
            frame_count(n, FrameMode::Fd),
            classic_message_bits(n),
            fd.nominal,
            fd.data,
            Bus::CLASSIC_1M.message_time_ns(n) as f64 / 1e3,
            Bus::FD_1M_5M.message_time_ns(n) as f64 / 1e3,
        );
    }

    println!(
        "\nThe feedback message by kind of feedback (the table's feedback row is the largest):\n"
    );
    println!(
        "| feedback kind | bytes | frames classic | µs classic 1M | tick load classic 1M (%) |"
    );
    println!("|---|---:|---:|---:|---:|");
    let largest = MessageKind::Feedback.max_encoded_size();
    let tick_ns = protocol::budget::tick_time_ns(Bus::CLASSIC_1M);
    for kind in FeedbackKind::ALL {
        let n = FeedbackMessage::max_encoded_size_of(kind);
        let ns = Bus::CLASSIC_1M.message_time_ns(n);
        let tick = tick_ns - Bus::CLASSIC_1M.message_time_ns(largest) + ns;
        println!(
            "| {kind} | {n} | {} | {:.1} | {:.2} |",
            frame_count(n, FrameMode::Classic),
            ns as f64 / 1e3,
            percent(tick)
        );
    }

    println!(
        "\nOne control tick with a correction at {CONTROL_RATE_HZ} Hz: load in % of the bus.\n"
    );
    print!("| message | bytes | bits classic | bits FD |");
    for (name, _) in BUSES {
        print!(" {name} |");
    }
    println!("\n|---|---:|---:|---:|---:|---:|---:|");
    for kind in TICK_TRAFFIC {
        let n = kind.max_encoded_size();
        let fd = fd_message_bits(n);
        print!(
            "| {kind} | {n} | {} | {} + {} |",
            classic_message_bits(n),
            fd.nominal,
            fd.data
        );
        for (_, bus) in BUSES {
            print!(" {:.2} |", percent(bus.message_time_ns(n)));
        }
        println!();
    }
    let bytes: usize = TICK_TRAFFIC.iter().map(|k| k.max_encoded_size()).sum();
    let classic: u32 = TICK_TRAFFIC
        .iter()
        .map(|k| classic_message_bits(k.max_encoded_size()))
        .sum();
    let (nominal, data) = TICK_TRAFFIC.iter().fold((0, 0), |(a, b), k| {
        let fd = fd_message_bits(k.max_encoded_size());
        (a + fd.nominal, b + fd.data)
    });
    print!("| **tick** | {bytes} | {classic} | {nominal} + {data} |");
    for (_, bus) in BUSES {
        print!(" **{:.2}** |", tick_load_percent(bus, CONTROL_RATE_HZ));
    }
    println!();
    let load = tick_load_percent(Bus::CLASSIC_1M, CONTROL_RATE_HZ);
    println!(
        "\nBudget (DESIGN section 7): under {MAX_TICK_LOAD_PERCENT}% of classic CAN at 1 Mbit/s: {load:.2}% — {}",
        if load < MAX_TICK_LOAD_PERCENT {
            "met"
        } else {
            "EXCEEDED"
        }
    );
}
