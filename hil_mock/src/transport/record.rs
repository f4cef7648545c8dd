//! candump logs: a recorder around any link, a parser, and replay.
//!
//! The format is can-utils' `candump -l` log, which `canplayer`, `log2asc` and python-can's
//! `CanutilsLogReader` read: one frame per line,
//!
//! ```text
//! (1700000000.123456) can0 123#DEADBEEF        classic, 11-bit id (3 hex digits)
//! (1700000000.123789) can0 1ABCDEF0#           classic, 29-bit id (8 hex digits), no data
//! (1700000000.124001) can0 123##1DEADBEEF      CAN FD: '##', one hex digit of flags (1 = BRS), data
//! ```
//!
//! A [`RecordingLink`] logs every frame it sends and receives, as a candump on the bus would see
//! them, with the wall-clock time of the event.

use std::fmt::Write as _;
use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use protocol::can::{CanFrame, CanId};

use super::{Link, LinkError};

/// The frame in candump's `ID#DATA` / `ID##FDATA` notation.
pub fn format_frame(frame: &CanFrame) -> String {
    let mut s = match frame.id() {
        CanId::Standard(id) => format!("{id:03X}"),
        CanId::Extended(id) => format!("{id:08X}"),
    };
    s.push_str(if frame.is_fd() { "##1" } else { "#" });
    for b in frame.data() {
        let _ = write!(s, "{b:02X}");
    }
    s
}

/// Parses candump's `ID#DATA` / `ID##FDATA` notation. Remote frames (`ID#R`) are refused.
/// Total: any text gives a frame or a message saying what is wrong, never a panic.
pub fn parse_frame(s: &str) -> Result<CanFrame, String> {
    let (id, rest) = s
        .split_once('#')
        .ok_or_else(|| format!("no '#' in {s:?}"))?;
    if id.is_empty() || !id.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!("bad id {id:?}: not hexadecimal digits"));
    }
    let raw = u32::from_str_radix(id, 16).map_err(|_| format!("bad id {id:?}"))?;
    let can_id = match id.len() {
        3 => CanId::standard(raw as u16),
        8 => CanId::extended(raw),
        _ => None,
    }
    .ok_or_else(|| format!("id {id:?} is neither 3 nor 8 hex digits in range"))?;
    let (fd, hex) = match rest.strip_prefix('#') {
        Some(r) => {
            let mut chars = r.chars();
            chars
                .next()
                .filter(|c| c.is_ascii_hexdigit())
                .ok_or_else(|| format!("missing CAN FD flags in {s:?}"))?;
            (true, chars.as_str())
        }
        None => (false, rest),
    };
    if hex.starts_with('R') {
        return Err("remote frames are not supported".into());
    }
    if let Some(bad) = hex.chars().find(|c| !c.is_ascii_hexdigit()) {
        return Err(format!(
            "bad data {hex:?}: {bad:?} is not a hexadecimal digit"
        ));
    }
    if hex.len() % 2 != 0 {
        return Err(format!("odd number of hex digits in {hex:?}"));
    }
    let data = (0..hex.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).map_err(|_| format!("bad data {hex:?}")))
        .collect::<Result<Vec<u8>, _>>()?;
    let frame = if fd {
        CanFrame::new_fd(can_id, &data)
    } else {
        CanFrame::new(can_id, &data)
    };
    frame.map_err(|e| e.to_string())
}

/// One log line.
pub fn format_line(time: SystemTime, iface: &str, frame: &CanFrame) -> String {
    let t = time.duration_since(UNIX_EPOCH).unwrap_or_default();
    format!(
        "({}.{:06}) {iface} {}",
        t.as_secs(),
        t.subsec_micros(),
        format_frame(frame)
    )
}

/// One logged frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Logged {
    /// Seconds since the Unix epoch.
    pub time: f64,
    /// Interface name.
    pub iface: String,
    /// The frame.
    pub frame: CanFrame,
}

/// Parses one line of a candump log, `(TIME) IFACE FRAME`. Total: any text gives a frame or a
/// message saying what is wrong, never a panic.
pub fn parse_line(line: &str) -> Result<Logged, String> {
    let mut parts = line.split_whitespace();
    let (Some(time), Some(iface), Some(frame)) = (parts.next(), parts.next(), parts.next()) else {
        return Err("expected '(TIME) IFACE FRAME'".into());
    };
    let time: f64 = time
        .strip_prefix('(')
        .and_then(|t| t.strip_suffix(')'))
        .and_then(|t| t.parse().ok())
        .filter(|t: &f64| t.is_finite())
        .ok_or_else(|| format!("bad timestamp {time:?}"))?;
    let frame = parse_frame(frame)?;
    Ok(Logged {
        time,
        iface: iface.to_string(),
        frame,
    })
}

/// Reads a candump log. Blank lines and lines starting with `#` are skipped; any other line that
/// does not parse (bytes that are not UTF-8 included) is an error naming the file and the line.
pub fn read_log(path: &Path) -> Result<Vec<Logged>, LinkError> {
    let file =
        File::open(path).map_err(|e| LinkError::io(format!("open {}", path.display()), e))?;
    let mut out = Vec::new();
    for (n, line) in BufReader::new(file).split(b'\n').enumerate() {
        let line = line.map_err(|e| LinkError::io(format!("read {}", path.display()), e))?;
        let bad = |d: String| {
            LinkError::malformed("candump", format!("{}:{}: {d}", path.display(), n + 1))
        };
        let line = std::str::from_utf8(&line).map_err(|e| bad(format!("not UTF-8 text: {e}")))?;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        out.push(parse_line(line).map_err(bad)?);
    }
    Ok(out)
}

/// Sends the frames of a log through `link`, in order; with `realtime`, spaced as they were
/// logged. Returns the number of frames sent.
pub fn replay(log: &[Logged], link: &mut dyn Link, realtime: bool) -> Result<usize, LinkError> {
    let start = Instant::now();
    let t0 = log.first().map(|l| l.time).unwrap_or(0.0);
    for l in log {
        if realtime {
            let at = Duration::try_from_secs_f64((l.time - t0).max(0.0)).map_err(|_| {
                LinkError::malformed(
                    "candump",
                    format!("timestamp {} is too far from the first, {t0}", l.time),
                )
            })?;
            if let Some(wait) = at.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        link.send(&l.frame)?;
    }
    Ok(log.len())
}

/// A link that writes every frame it sends or receives to a candump log.
#[derive(Debug)]
pub struct RecordingLink<L: Link> {
    inner: L,
    log: BufWriter<File>,
    path: PathBuf,
    iface: String,
}

impl<L: Link> RecordingLink<L> {
    /// Wraps `inner`, logging to a new file at `path` under the interface name `iface`.
    pub fn new(inner: L, path: &Path, iface: &str) -> Result<Self, LinkError> {
        let file = File::create(path)
            .map_err(|e| LinkError::io(format!("create {}", path.display()), e))?;
        Ok(Self {
            inner,
            log: BufWriter::new(file),
            path: path.to_path_buf(),
            iface: iface.to_string(),
        })
    }

    fn write(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        let line = format_line(SystemTime::now(), &self.iface, frame);
        writeln!(self.log, "{line}")
            .and_then(|()| self.log.flush())
            .map_err(|e| LinkError::io(format!("write {}", self.path.display()), e))
    }
}

impl<L: Link> Link for RecordingLink<L> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        self.inner.send(frame)?;
        self.write(frame)
    }

    fn send_all(&mut self, frames: &[CanFrame]) -> Result<(), LinkError> {
        self.inner.send_all(frames)?;
        frames.iter().try_for_each(|f| self.write(f))
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        let got = self.inner.recv(timeout)?;
        if let Some(f) = &got {
            self.write(f)?;
        }
        Ok(got)
    }

    fn authenticated(&mut self, fresh: bool) {
        self.inner.authenticated(fresh)
    }

    fn describe(&self) -> String {
        format!(
            "{} recorded to {}",
            self.inner.describe(),
            self.path.display()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::memory::MemoryLink;

    #[test]
    fn notation_matches_candump() {
        let std =
            CanFrame::new(CanId::standard(0x123).unwrap(), &[0xDE, 0xAD, 0xBE, 0xEF]).unwrap();
        let ext = CanFrame::new(CanId::extended(0x1ABC_DEF0).unwrap(), &[]).unwrap();
        let fd = CanFrame::new_fd(CanId::standard(0x7FF).unwrap(), &[0x11; 12]).unwrap();
        assert_eq!(format_frame(&std), "123#DEADBEEF");
        assert_eq!(format_frame(&ext), "1ABCDEF0#");
        assert_eq!(format_frame(&fd), "7FF##1111111111111111111111111");
        for f in [std, ext, fd] {
            assert_eq!(parse_frame(&format_frame(&f)), Ok(f));
        }
        let t = UNIX_EPOCH + Duration::from_micros(1_700_000_000_123_456);
        assert_eq!(
            format_line(t, "can0", &std),
            "(1700000000.123456) can0 123#DEADBEEF"
        );
        for bad in [
            "123",
            "12#00",
            "123#0",
            "123#R",
            "800#",
            "123##",
            "123#GG",
            "123#000000000000000000",
            // Issue 14: a non-ASCII byte in the data used to panic (slicing inside a character).
            "123#0é",
            "123#é0",
            "123##1é",
            "+12#00",
            "12 #00",
            "123#+1",
        ] {
            assert!(parse_frame(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn record_then_read_then_replay() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bus.log");
        let (a, mut b) = MemoryLink::pair();
        let mut rec = RecordingLink::new(a, &path, "can0").unwrap();
        let f1 = CanFrame::new(CanId::standard(0x10).unwrap(), &[1]).unwrap();
        let f2 = CanFrame::new(CanId::standard(0x20).unwrap(), &[2]).unwrap();
        rec.send(&f1).unwrap();
        b.send(&f2).unwrap();
        assert_eq!(rec.recv(Duration::from_secs(1)).unwrap(), Some(f2));
        drop(rec);
        let log = read_log(&path).unwrap();
        assert_eq!(log.iter().map(|l| l.frame).collect::<Vec<_>>(), [f1, f2]);
        assert!(log.iter().all(|l| l.iface == "can0" && l.time > 1.6e9));
        let (mut c, mut d) = MemoryLink::pair();
        assert_eq!(replay(&log, &mut c, false).unwrap(), 2);
        assert_eq!(d.recv(Duration::ZERO).unwrap(), Some(f1));

        std::fs::write(&path, "(1.0) can0 123#00\nnot a line\n").unwrap();
        let e = read_log(&path).unwrap_err().to_string();
        assert!(e.contains("bus.log:2"), "{e}");
        std::fs::write(&path, "(1.0) can0 123#0\u{e9}\n").unwrap();
        let e = read_log(&path).unwrap_err().to_string();
        assert!(e.contains("bus.log:1") && e.contains("hexadecimal"), "{e}");
        std::fs::write(&path, b"(1.0) can0 123#00\n(2.0) can0 123#\xff\xfe\n").unwrap();
        let e = read_log(&path).unwrap_err().to_string();
        assert!(e.contains("bus.log:2") && e.contains("UTF-8"), "{e}");
    }
}
