//! Fault injection: a middleware link that drops, corrupts, duplicates, reorders and delays the
//! frames sent through it, with a seeded generator (smoltcp's `FaultInjector` in spirit).
//!
//! The same firmware-facing code runs over a clean or a hostile link: wrap each end of a link to
//! disturb both directions. Decisions are drawn per sent frame, in order, from a ChaCha8 generator
//! seeded by [`FaultConfig::seed`]: the same sequence of frames meets the same faults.
//!
//! * **drop**: the frame is not sent;
//! * **corrupt**: one random bit of the payload is flipped (a bridge or a buffer gone wrong; a
//!   real bus's CRC would have dropped it instead);
//! * **duplicate**: the frame is sent twice;
//! * **reorder**: the frame is held back and sent after the next one (or at the next receive);
//! * **delay**: the frame is held back for a random time up to `max_delay`, then sent.

use std::time::{Duration, Instant};

use protocol::can::CanFrame;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{Link, LinkError};

/// Probabilities of each fault, per frame, and the generator's seed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultConfig {
    /// Probability that a frame is dropped.
    pub drop: f64,
    /// Probability that one payload bit is flipped.
    pub corrupt: f64,
    /// Probability that a frame is sent twice.
    pub duplicate: f64,
    /// Probability that a frame swaps places with the next.
    pub reorder: f64,
    /// Probability that a frame is delayed.
    pub delay: f64,
    /// Longest delay.
    pub max_delay: Duration,
    /// Seed of the fault generator.
    pub seed: u64,
}

impl FaultConfig {
    /// No faults.
    pub const NONE: Self = Self {
        drop: 0.0,
        corrupt: 0.0,
        duplicate: 0.0,
        reorder: 0.0,
        delay: 0.0,
        max_delay: Duration::ZERO,
        seed: 0,
    };
}

impl std::str::FromStr for FaultConfig {
    type Err = String;

    /// `drop=0.1,corrupt=0.01,duplicate=0.01,reorder=0.01,delay=0.01,max-delay-ms=5,seed=7`:
    /// any subset, probabilities in `[0, 1]`; what is not given is 0 (`max-delay-ms` 0).
    fn from_str(s: &str) -> Result<Self, String> {
        let mut c = FaultConfig::NONE;
        for item in s.split(',').map(str::trim).filter(|i| !i.is_empty()) {
            let (key, value) = item
                .split_once('=')
                .ok_or_else(|| format!("fault '{item}': expected KEY=VALUE"))?;
            let p = || -> Result<f64, String> {
                let p: f64 = value
                    .parse()
                    .map_err(|_| format!("fault {key}: '{value}' is not a number"))?;
                if (0.0..=1.0).contains(&p) {
                    Ok(p)
                } else {
                    Err(format!("fault {key}: probability {value} is not in [0, 1]"))
                }
            };
            let int = || -> Result<u64, String> {
                value
                    .parse()
                    .map_err(|_| format!("fault {key}: '{value}' is not a whole number"))
            };
            match key {
                "drop" => c.drop = p()?,
                "corrupt" => c.corrupt = p()?,
                "duplicate" => c.duplicate = p()?,
                "reorder" => c.reorder = p()?,
                "delay" => c.delay = p()?,
                "max-delay-ms" => c.max_delay = Duration::from_millis(int()?.min(60_000)),
                "seed" => c.seed = int()?,
                _ => {
                    return Err(format!(
                        "unknown fault '{key}'; use drop, corrupt, duplicate, reorder, delay, \
                         max-delay-ms, seed"
                    ));
                }
            }
        }
        if c.delay > 0.0 && c.max_delay.is_zero() {
            c.max_delay = Duration::from_millis(5);
        }
        Ok(c)
    }
}

/// What the injector did so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultStats {
    /// Frames handed to the injector.
    pub frames: u64,
    /// Dropped.
    pub dropped: u64,
    /// Corrupted.
    pub corrupted: u64,
    /// Duplicated.
    pub duplicated: u64,
    /// Reordered.
    pub reordered: u64,
    /// Delayed.
    pub delayed: u64,
}

/// A link that disturbs what is sent through it.
#[derive(Debug)]
pub struct FaultyLink<L: Link> {
    inner: L,
    config: FaultConfig,
    rng: ChaCha8Rng,
    held: Option<CanFrame>,
    delayed: Vec<(Instant, CanFrame)>,
    stats: FaultStats,
}

impl<L: Link> FaultyLink<L> {
    /// Wraps `inner`.
    pub fn new(inner: L, config: FaultConfig) -> Self {
        Self {
            inner,
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            config,
            held: None,
            delayed: Vec::new(),
            stats: FaultStats::default(),
        }
    }

    /// What was done so far.
    pub fn stats(&self) -> FaultStats {
        self.stats
    }

    fn release(&mut self, flush_all: bool) -> Result<(), LinkError> {
        if let Some(f) = self.held.take() {
            self.inner.send(&f)?;
        }
        let now = Instant::now();
        self.delayed.sort_by_key(|(t, _)| *t);
        while let Some((t, _)) = self.delayed.first() {
            if !flush_all && *t > now {
                break;
            }
            let (_, f) = self.delayed.remove(0);
            self.inner.send(&f)?;
        }
        Ok(())
    }
}

impl<L: Link> Link for FaultyLink<L> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        self.stats.frames += 1;
        // Draw every decision for this frame up front, so the stream of draws does not depend
        // on which faults fired.
        let c = self.config;
        let roll: [f64; 5] = std::array::from_fn(|_| self.rng.random::<f64>());
        let bit = self.rng.random_range(0..8 * frame.data().len().max(1));
        let wait = self.rng.random_range(0.0..=1.0) * c.max_delay.as_secs_f64();

        let now = Instant::now();
        let due: Vec<CanFrame> = {
            self.delayed.sort_by_key(|(t, _)| *t);
            let n = self.delayed.iter().take_while(|(t, _)| *t <= now).count();
            self.delayed.drain(..n).map(|(_, f)| f).collect()
        };
        for f in due {
            self.inner.send(&f)?;
        }
        if roll[0] < c.drop {
            self.stats.dropped += 1;
            return Ok(());
        }
        let mut frame = *frame;
        if roll[1] < c.corrupt && !frame.data().is_empty() {
            let mut data = frame.data().to_vec();
            data[bit / 8] ^= 1 << (bit % 8);
            frame = if frame.is_fd() {
                CanFrame::new_fd(frame.id(), &data)
            } else {
                CanFrame::new(frame.id(), &data)
            }
            .expect("same length as a valid frame");
            self.stats.corrupted += 1;
        }
        if roll[4] < c.delay {
            self.stats.delayed += 1;
            self.delayed
                .push((now + Duration::from_secs_f64(wait), frame));
            return Ok(());
        }
        if roll[3] < c.reorder && self.held.is_none() {
            self.stats.reordered += 1;
            self.held = Some(frame);
            return Ok(());
        }
        self.inner.send(&frame)?;
        if let Some(h) = self.held.take() {
            self.inner.send(&h)?;
        }
        if roll[2] < c.duplicate {
            self.stats.duplicated += 1;
            self.inner.send(&frame)?;
        }
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        // Nothing stays held while we wait: a held frame goes out now, a delayed one when due.
        let deadline = Instant::now() + timeout;
        loop {
            self.release(false)?;
            let now = Instant::now();
            let next_due = self.delayed.iter().map(|(t, _)| *t).min();
            let wait = match next_due {
                Some(t) => deadline.min(t).saturating_duration_since(now),
                None => deadline.saturating_duration_since(now),
            };
            if let Some(f) = self.inner.recv(wait)? {
                return Ok(Some(f));
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
        }
    }

    fn authenticated(&mut self, fresh: bool) {
        self.inner.authenticated(fresh)
    }

    fn describe(&self) -> String {
        format!("{} with faults {:?}", self.inner.describe(), self.config)
    }
}

impl<L: Link> Drop for FaultyLink<L> {
    fn drop(&mut self) {
        let _ = self.release(true);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_specs_parse_and_bad_ones_say_why() {
        let c: FaultConfig = "drop=0.1,corrupt=0.01,duplicate=0.02,reorder=0.03,delay=0.04,seed=9"
            .parse()
            .unwrap();
        assert_eq!(
            (c.drop, c.corrupt, c.duplicate, c.reorder, c.delay, c.seed),
            (0.1, 0.01, 0.02, 0.03, 0.04, 9)
        );
        assert_eq!(c.max_delay, Duration::from_millis(5), "default delay bound");
        assert_eq!("".parse::<FaultConfig>().unwrap(), FaultConfig::NONE);
        for (bad, why) in [
            ("drop=2", "not in [0, 1]"),
            ("drop=x", "not a number"),
            ("seed=-1", "whole number"),
            ("jitter=0.1", "unknown fault"),
            ("drop", "KEY=VALUE"),
        ] {
            let e = bad.parse::<FaultConfig>().unwrap_err();
            assert!(e.contains(why), "{bad}: {e}");
        }
    }
    use crate::transport::memory::MemoryLink;
    use protocol::can::CanId;

    fn frame(i: u16) -> CanFrame {
        CanFrame::new(CanId::standard(i & 0x7FF).unwrap(), &i.to_le_bytes()).unwrap()
    }

    fn received(b: &mut MemoryLink) -> Vec<CanFrame> {
        let mut out = Vec::new();
        while let Some(f) = b.recv(Duration::from_millis(20)).unwrap() {
            out.push(f);
        }
        out
    }

    #[test]
    fn rates_are_as_configured_and_seeded() {
        let config = FaultConfig {
            drop: 0.1,
            corrupt: 0.05,
            duplicate: 0.05,
            reorder: 0.05,
            ..FaultConfig::NONE
        };
        let run = |seed| {
            let (a, mut b) = MemoryLink::pair();
            let mut f = FaultyLink::new(a, FaultConfig { seed, ..config });
            for i in 0..4000 {
                f.send(&frame(i)).unwrap();
            }
            f.release(true).unwrap();
            (f.stats(), received(&mut b))
        };
        let (stats, got) = run(7);
        assert_eq!(stats.frames, 4000);
        for (n, p) in [
            (stats.dropped, 0.1),
            (stats.corrupted, 0.05 * 0.9),
            (stats.duplicated, 0.05 * 0.9 * 0.95),
        ] {
            let expected = 4000.0 * p;
            assert!(
                (n as f64 - expected).abs() < 4.0 * expected.sqrt() + 5.0,
                "{n} vs {expected}"
            );
        }
        assert_eq!(got.len() as u64, 4000 - stats.dropped + stats.duplicated);
        assert_eq!(run(7), (stats, got.clone()), "same seed, same faults");
        assert_ne!(run(8).1, got);
    }

    #[test]
    fn reordering_swaps_neighbours_and_delays_release() {
        let (a, mut b) = MemoryLink::pair();
        let mut f = FaultyLink::new(
            a,
            FaultConfig {
                reorder: 1.0,
                ..FaultConfig::NONE
            },
        );
        f.send(&frame(1)).unwrap();
        f.send(&frame(2)).unwrap();
        assert_eq!(received(&mut b), [frame(2), frame(1)]);

        let (a, mut b) = MemoryLink::pair();
        let mut f = FaultyLink::new(
            a,
            FaultConfig {
                delay: 1.0,
                max_delay: Duration::from_millis(30),
                ..FaultConfig::NONE
            },
        );
        f.send(&frame(3)).unwrap();
        assert_eq!(b.recv(Duration::ZERO).unwrap(), None, "held back");
        let _ = f.recv(Duration::from_millis(40)).unwrap();
        assert_eq!(b.recv(Duration::from_millis(10)).unwrap(), Some(frame(3)));
    }

    #[test]
    fn corruption_flips_exactly_one_bit() {
        let (a, mut b) = MemoryLink::pair();
        let mut f = FaultyLink::new(
            a,
            FaultConfig {
                corrupt: 1.0,
                seed: 3,
                ..FaultConfig::NONE
            },
        );
        for i in 0..100 {
            f.send(&frame(i)).unwrap();
        }
        for (i, g) in received(&mut b).iter().enumerate() {
            let diff: u32 = g
                .data()
                .iter()
                .zip(frame(i as u16).data())
                .map(|(x, y)| (x ^ y).count_ones())
                .sum();
            assert_eq!(diff, 1);
        }
    }
}
