//! Writes the seed corpus of `hil_mock`'s fuzz targets: `fuzz/corpus/cannelloni/*.bin`
//! (datagrams), `fuzz/corpus/flash_page/*.bin` (flash images: empty, one page, two pages, one
//! corrupt) and `fuzz/corpus/candump/*.bin` (log lines). The protocol's targets get theirs from
//! `cargo run -p protocol --example fuzz_seeds`.
//!
//! ```text
//! cargo run -p hil_mock --example transport_fuzz_seeds [-- OUT_DIR]     # default: fuzz/corpus
//! ```

use std::path::PathBuf;

use firmware_core::{Learner, LearnerParams, OnlineLearner};
use hil_mock::flash::{FlashStore, HEADER_SIZE, Open};
use hil_mock::transport::record::format_line;
use hil_mock::transport::udp::encode_packet;
use protocol::can::{CanFrame, CanId};
use protocol::car::Persisted;
use protocol::delivery::FeedbackReceiver;

fn main() -> anyhow::Result<()> {
    let out = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("fuzz/corpus"), PathBuf::from);
    let dir = |name: &str| -> std::io::Result<PathBuf> {
        let d = out.join(name);
        std::fs::create_dir_all(&d)?;
        Ok(d)
    };
    let mut count = 0;

    let frames = [
        CanFrame::new(CanId::Standard(0x104), &[0x10, 0x61, 3, 0, 1, 2, 3, 4])?,
        CanFrame::new(CanId::Extended(0x1ABC_DEF0), &[])?,
        CanFrame::new_fd(CanId::Standard(0x10A), &[0x5A; 24])?,
    ];
    let cannelloni = dir("cannelloni")?;
    for (i, set) in [&frames[..1], &frames[1..2], &frames[2..], &frames[..]]
        .into_iter()
        .enumerate()
    {
        let mut packet = Vec::new();
        encode_packet(i as u8, set, &mut packet);
        std::fs::write(cannelloni.join(format!("packet_{i}.bin")), packet)?;
        count += 1;
    }

    let candump = dir("candump")?;
    let t = std::time::UNIX_EPOCH + std::time::Duration::from_micros(1_700_000_000_123_456);
    for (i, f) in frames.iter().enumerate() {
        std::fs::write(
            candump.join(format!("line_{i}.bin")),
            format_line(t, "can0", f),
        )?;
        count += 1;
    }

    // Flash images: written through the store, so every byte is what the car writes.
    let flash_dir = dir("flash_page")?;
    let tmp = tempfile::tempdir()?;
    let path = tmp.path().join("car.flash");
    let mut learner = Learner::new(
        LearnerParams::default()
            .check()
            .map_err(anyhow::Error::msg)?,
    );
    let (mut store, _) = FlashStore::open(&path, Open::Existing)?;
    std::fs::write(flash_dir.join("erased.bin"), std::fs::read(&path)?)?;
    for generation in 0..2u32 {
        learner
            .step(&[0.5, -0.25, 0.0, 1.0, 0.0, 0.25])
            .map_err(anyhow::Error::msg)?;
        store.save(&Persisted {
            session: Some(4),
            generation,
            snapshot: learner.snapshot(),
            receiver: FeedbackReceiver::new(),
        })?;
        std::fs::write(
            flash_dir.join(format!("pages_{}.bin", generation + 1)),
            std::fs::read(&path)?,
        )?;
    }
    let mut corrupt = std::fs::read(&path)?;
    corrupt[HEADER_SIZE + 40] ^= 1;
    std::fs::write(flash_dir.join("one_corrupt.bin"), corrupt)?;
    count += 4;
    println!("wrote {count} seeds under {}", out.display());
    Ok(())
}
