//! slcan over a TCP socket or a serial device.
//!
//! The line format is `protocol::slcan` (also used by the car's firmware over its UART). Two
//! roles:
//!
//! * **host** (we opened the connection, as a PC opens a USB-CAN adapter): on open it sends
//!   `C\r S8\r O\r` (close, 1 Mbit/s, open) and ignores the adapter's `\r`/BEL replies;
//! * **device** (we accepted the connection, standing in for the adapter or the car): it answers
//!   every command with `\r` (`V` and `N` with a version and serial number), and BEL for a
//!   command it does not know.
//!
//! Both roles send and receive frames as `t`/`T`/`b`/`B` lines.
//!
//! A car listening on TCP ([`SlcanListener`], `slcan+tcp-listen://`) serves connections one
//! after another, one at a time. A connection that brings no authenticated message with the
//! highest counter yet for the idle timeout is closed and the next one waiting is accepted, so a process that connects
//! first and stays (silent, or sending garbage or replays) cannot lock the host out; when a
//! connection ends, the car serves the next.

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, SocketAddrV4, TcpListener, TcpStream};
#[cfg(feature = "serial")]
use std::path::Path;
use std::time::{Duration, Instant};

use protocol::can::CanFrame;
use protocol::slcan::{Feed, Line, LineReader, MAX_LINE, encode, parse_line};

use super::{Link, LinkError};

/// A byte stream an slcan link runs over.
pub trait Stream: Read + Write + Send {
    /// Sets how long a read may block (`None`: forever).
    fn set_read_timeout(&mut self, timeout: Option<Duration>) -> std::io::Result<()>;
}

impl Stream for TcpStream {
    fn set_read_timeout(&mut self, timeout: Option<Duration>) -> std::io::Result<()> {
        TcpStream::set_read_timeout(self, timeout)
    }
}

impl Stream for Box<dyn Stream> {
    fn set_read_timeout(&mut self, timeout: Option<Duration>) -> std::io::Result<()> {
        (**self).set_read_timeout(timeout)
    }
}

#[cfg(feature = "serial")]
impl Stream for Box<dyn serialport::SerialPort> {
    fn set_read_timeout(&mut self, timeout: Option<Duration>) -> std::io::Result<()> {
        // serialport needs a positive timeout; "forever" becomes a long one.
        self.set_timeout(
            timeout
                .unwrap_or(Duration::from_secs(3600))
                .max(Duration::from_millis(1)),
        )
        .map_err(std::io::Error::other)
    }
}

/// Which end of the line we are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// We drive an adapter.
    Host,
    /// We are the adapter (or the car behind it).
    Device,
}

/// An slcan link over any [`Stream`].
pub struct SlcanLink<S: Stream = Box<dyn Stream>> {
    stream: S,
    role: Role,
    reader: LineReader,
    pending: VecDeque<CanFrame>,
    name: String,
    buf: [u8; 512],
    buffered: VecDeque<u8>,
}

impl<S: Stream> std::fmt::Debug for SlcanLink<S> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SlcanLink")
            .field("name", &self.name)
            .field("role", &self.role)
            .finish()
    }
}

impl SlcanLink<Box<dyn Stream>> {
    /// Connects to `addr` (127.0.0.1) as the host, retrying until `timeout` (the server, QEMU for
    /// example, may still be starting).
    pub fn connect_tcp(addr: SocketAddrV4, timeout: Duration) -> Result<Self, LinkError> {
        let deadline = Instant::now() + timeout;
        let stream = loop {
            match TcpStream::connect_timeout(&addr.into(), Duration::from_millis(500)) {
                Ok(s) => break s,
                Err(e) if Instant::now() < deadline => {
                    let _ = e;
                    std::thread::sleep(Duration::from_millis(50));
                }
                Err(e) => return Err(LinkError::io(format!("connect to {addr}"), e)),
            }
        };
        stream
            .set_nodelay(true)
            .map_err(|e| LinkError::io("TCP_NODELAY", e))?;
        SlcanLink::new(Box::new(stream), Role::Host, format!("slcan/tcp {addr}"))
    }

    /// Listens on `addr` (127.0.0.1) and accepts one connection as the device, waiting up to
    /// `timeout`.
    pub fn accept_tcp(addr: SocketAddrV4, timeout: Duration) -> Result<Self, LinkError> {
        let listener =
            TcpListener::bind(addr).map_err(|e| LinkError::io(format!("bind {addr}"), e))?;
        Self::accept_from(&listener, timeout)
    }

    /// Accepts one connection on an already bound listener as the device.
    pub fn accept_from(listener: &TcpListener, timeout: Duration) -> Result<Self, LinkError> {
        let local = listener
            .local_addr()
            .map_err(|e| LinkError::io("listener address", e))?;
        listener
            .set_nonblocking(true)
            .map_err(|e| LinkError::io("listener nonblocking", e))?;
        let deadline = Instant::now() + timeout;
        let stream = loop {
            match listener.accept() {
                Ok((s, _)) => break s,
                Err(e) if e.kind() == ErrorKind::WouldBlock && Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(10));
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    return Err(LinkError::Closed(format!(
                        "nobody connected to {local} within {timeout:?}"
                    )));
                }
                Err(e) => return Err(LinkError::io(format!("accept on {local}"), e)),
            }
        };
        Self::device(stream, local)
    }

    /// The device's side of an accepted connection (blocking reads with timeouts, no Nagle).
    fn device(stream: TcpStream, local: SocketAddr) -> Result<Self, LinkError> {
        stream
            .set_nonblocking(false)
            .map_err(|e| LinkError::io("stream blocking", e))?;
        stream
            .set_nodelay(true)
            .map_err(|e| LinkError::io("TCP_NODELAY", e))?;
        SlcanLink::new(Box::new(stream), Role::Device, format!("slcan/tcp {local}"))
    }

    /// Opens a serial device as the host (feature `serial`, on by default).
    #[cfg(feature = "serial")]
    pub fn open_serial(path: &Path, baud: u32) -> Result<Self, LinkError> {
        let port = serialport::new(path.to_string_lossy(), baud)
            .timeout(Duration::from_millis(10))
            .open()
            .map_err(|e| {
                LinkError::io(
                    format!("open serial device {}", path.display()),
                    std::io::Error::other(e),
                )
            })?;
        SlcanLink::new(
            Box::new(port),
            Role::Host,
            format!("slcan/serial {}", path.display()),
        )
    }
}

impl<S: Stream> SlcanLink<S> {
    /// An slcan link over `stream` in `role`; the host role sends its opening commands.
    pub fn new(stream: S, role: Role, name: String) -> Result<Self, LinkError> {
        let mut link = Self {
            stream,
            role,
            reader: LineReader::new(),
            pending: VecDeque::new(),
            name,
            buf: [0; 512],
            buffered: VecDeque::new(),
        };
        if role == Role::Host {
            link.write(b"C\rS8\rO\r")?;
        }
        Ok(link)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        match self
            .stream
            .write_all(bytes)
            .and_then(|()| self.stream.flush())
        {
            Ok(()) => Ok(()),
            Err(e) if matches!(e.kind(), ErrorKind::BrokenPipe | ErrorKind::ConnectionReset) => {
                Err(LinkError::Closed(format!("{}: {e}", self.name)))
            }
            Err(e) => Err(LinkError::io(format!("{} write", self.name), e)),
        }
    }

    /// Handles one completed line; returns an error for a malformed one.
    fn handle_line(&mut self, line: &[u8]) -> Result<(), LinkError> {
        let parsed = parse_line(line).map_err(|e| {
            LinkError::malformed(
                "slcan",
                format!("{e} in {:?}", String::from_utf8_lossy(line)),
            )
        })?;
        match parsed {
            Line::Frame(f) => self.pending.push_back(f),
            Line::Ok | Line::TransmitAck => {}
            Line::Command(c, _) if self.role == Role::Device => {
                let reply: &[u8] = match c {
                    b'V' => b"V1013\r",
                    b'N' => b"NHILM\r",
                    b'O' | b'C' | b'L' | b'S' | b's' | b'F' | b'X' | b'Z' | b'M' | b'm' | b'W'
                    | b'Q' => b"\r",
                    _ => &[protocol::slcan::BEL],
                };
                self.write(reply)?;
            }
            Line::Command(c, _) => {
                return Err(LinkError::malformed(
                    "slcan",
                    format!("the adapter sent a command '{}'", c as char),
                ));
            }
        }
        Ok(())
    }
}

impl<S: Stream> Link for SlcanLink<S> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        let mut line = [0u8; MAX_LINE];
        let bytes = encode(frame, &mut line).to_vec();
        self.write(&bytes)
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(f) = self.pending.pop_front() {
                return Ok(Some(f));
            }
            // Parse what is already buffered, one line at a time.
            let mut error = None;
            while let Some(b) = self.buffered.pop_front() {
                let mut completed: Option<Vec<u8>> = None;
                match self.reader.push(b) {
                    Feed::Line(l) => completed = Some(l.to_vec()),
                    Feed::Overflow => {
                        error = Some(LinkError::malformed(
                            "slcan",
                            format!("line longer than {MAX_LINE} bytes"),
                        ));
                    }
                    Feed::Bell | Feed::Pending => {}
                }
                if let Some(l) = completed
                    && let Err(e) = self.handle_line(&l)
                {
                    error = Some(e);
                }
                if error.is_some() || !self.pending.is_empty() {
                    break;
                }
            }
            if let Some(e) = error {
                return Err(e);
            }
            if !self.pending.is_empty() {
                continue;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            self.stream
                .set_read_timeout(Some(left.max(Duration::from_micros(100))))
                .map_err(|e| LinkError::io(format!("{} timeout", self.name), e))?;
            match self.stream.read(&mut self.buf) {
                Ok(0) => return Err(LinkError::Closed(format!("{}: end of stream", self.name))),
                Ok(n) => self.buffered.extend(&self.buf[..n]),
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    if Instant::now() >= deadline {
                        return Ok(None);
                    }
                }
                Err(e) if e.kind() == ErrorKind::ConnectionReset => {
                    return Err(LinkError::Closed(format!("{}: {e}", self.name)));
                }
                Err(e) => return Err(LinkError::io(format!("{} read", self.name), e)),
            }
        }
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

/// The default idle timeout of a listening car: a connection that brought no authenticated
/// message for this long is closed.
pub const DEFAULT_IDLE_TIMEOUT: Duration = Duration::from_secs(10);

/// slcan over TCP as the listening device (the car): connections are served one after another,
/// one at a time (see the module documentation).
pub struct SlcanListener {
    listener: TcpListener,
    local: SocketAddr,
    current: Option<SlcanLink>,
    idle_timeout: Duration,
    /// When the current connection was accepted or last brought an authenticated message.
    trusted_at: Instant,
    accepted: u64,
    idle_closed: u64,
}

impl std::fmt::Debug for SlcanListener {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

impl SlcanListener {
    /// Binds `addr` (127.0.0.1).
    pub fn bind(addr: SocketAddrV4, idle_timeout: Duration) -> Result<Self, LinkError> {
        let listener =
            TcpListener::bind(addr).map_err(|e| LinkError::io(format!("bind {addr}"), e))?;
        Self::from_listener(listener, idle_timeout)
    }

    /// Serves an already bound listener.
    pub fn from_listener(listener: TcpListener, idle_timeout: Duration) -> Result<Self, LinkError> {
        let local = listener
            .local_addr()
            .map_err(|e| LinkError::io("listener address", e))?;
        listener
            .set_nonblocking(true)
            .map_err(|e| LinkError::io("listener nonblocking", e))?;
        Ok(Self {
            listener,
            local,
            current: None,
            idle_timeout,
            trusted_at: Instant::now(),
            accepted: 0,
            idle_closed: 0,
        })
    }

    /// The address listened on.
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }

    /// Connections accepted so far.
    pub fn accepted(&self) -> u64 {
        self.accepted
    }

    /// Connections closed because they brought no authenticated message in time.
    pub fn idle_closed(&self) -> u64 {
        self.idle_closed
    }

    /// Whether a connection is being served.
    pub fn connected(&self) -> bool {
        self.current.is_some()
    }

    /// Accepts the next waiting connection, if any.
    fn accept_next(&mut self) -> Result<(), LinkError> {
        match self.listener.accept() {
            Ok((stream, _)) => {
                self.current = Some(SlcanLink::device(stream, self.local)?);
                self.accepted += 1;
                self.trusted_at = Instant::now();
                Ok(())
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => Ok(()),
            Err(e) => Err(LinkError::io(format!("accept on {}", self.local), e)),
        }
    }
}

impl Link for SlcanListener {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        let Some(link) = self.current.as_mut() else {
            // Nobody connected: the frame is lost, as on a bus without a listener.
            return Ok(());
        };
        match link.send(frame) {
            Err(LinkError::Closed(_)) | Err(LinkError::Io { .. }) => {
                self.current = None;
                Ok(())
            }
            r => r,
        }
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        let deadline = Instant::now() + timeout;
        loop {
            if self.current.is_some() && self.trusted_at.elapsed() >= self.idle_timeout {
                self.current = None;
                self.idle_closed += 1;
            }
            if self.current.is_none() {
                self.accept_next()?;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            let Some(link) = self.current.as_mut() else {
                if left.is_zero() {
                    return Ok(None);
                }
                std::thread::sleep(left.min(Duration::from_millis(5)));
                continue;
            };
            // Wait no longer than the connection may stay idle.
            let wait = left.min(
                self.idle_timeout
                    .saturating_sub(self.trusted_at.elapsed())
                    .max(Duration::from_millis(1)),
            );
            match link.recv(wait) {
                Ok(Some(f)) => return Ok(Some(f)),
                Ok(None) if Instant::now() >= deadline => return Ok(None),
                Ok(None) => {}
                Err(LinkError::Closed(_)) | Err(LinkError::Io { .. }) => self.current = None,
                Err(e) => return Err(e),
            }
        }
    }

    fn describe(&self) -> String {
        format!(
            "slcan/tcp listening on {} ({} connections accepted, {} closed idle{})",
            self.local,
            self.accepted,
            self.idle_closed,
            if self.current.is_some() {
                ", one connected"
            } else {
                ""
            }
        )
    }

    fn authenticated(&mut self, fresh: bool) {
        // A replayed hello must not keep a squatter's connection alive.
        if fresh {
            self.trusted_at = Instant::now();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::can::CanId;

    #[test]
    fn host_and_device_over_tcp() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let device = std::thread::spawn(move || {
            let mut d = SlcanLink::accept_from(&listener, Duration::from_secs(5)).unwrap();
            // Echo three frames back with the id plus one.
            for _ in 0..3 {
                let f = d.recv(Duration::from_secs(5)).unwrap().unwrap();
                let id = CanId::standard(f.id().raw() as u16 + 1).unwrap();
                d.send(&CanFrame::new(id, f.data()).unwrap()).unwrap();
            }
        });
        let mut host = SlcanLink::connect_tcp(
            SocketAddrV4::new(std::net::Ipv4Addr::LOCALHOST, port),
            Duration::from_secs(5),
        )
        .unwrap();
        for i in 0..3u8 {
            host.send(&CanFrame::new(CanId::standard(0x100).unwrap(), &[i, 0xFF]).unwrap())
                .unwrap();
            let back = host.recv(Duration::from_secs(5)).unwrap().unwrap();
            assert_eq!((back.id().raw(), back.data()), (0x101, &[i, 0xFF][..]));
        }
        device.join().unwrap();
        assert!(matches!(
            host.recv(Duration::from_secs(5)),
            Err(LinkError::Closed(_))
        ));
    }

    /// An in-memory stream for byte-level tests.
    struct Bytes {
        input: VecDeque<u8>,
        output: Vec<u8>,
    }
    impl Read for Bytes {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.input.is_empty() {
                return Err(ErrorKind::WouldBlock.into());
            }
            let n = buf.len().min(self.input.len()).min(7);
            for b in buf.iter_mut().take(n) {
                *b = self.input.pop_front().unwrap();
            }
            Ok(n)
        }
    }
    impl Write for Bytes {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.output.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    impl Stream for Bytes {
        fn set_read_timeout(&mut self, _: Option<Duration>) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn device_answers_commands_and_skips_bad_lines() {
        let input = b"C\rS8\rO\rV\rQ?\rk\rt12\rt1231AB\rz\r"
            .iter()
            .copied()
            .collect();
        let mut d = SlcanLink::new(
            Bytes {
                input,
                output: Vec::new(),
            },
            Role::Device,
            "test".into(),
        )
        .unwrap();
        let mut errors = 0;
        let mut frames = Vec::new();
        for _ in 0..10 {
            match d.recv(Duration::ZERO) {
                Ok(Some(f)) => frames.push(f),
                Ok(None) => break,
                Err(LinkError::Malformed { .. }) => errors += 1,
                Err(e) => panic!("{e}"),
            }
        }
        assert_eq!(errors, 1, "t12 is malformed");
        assert_eq!(
            frames,
            [CanFrame::new(CanId::standard(0x123).unwrap(), &[0xAB]).unwrap()]
        );
        assert_eq!(d.stream.output, b"\r\r\rV1013\r\r\x07");
    }

    #[test]
    fn host_opens_the_adapter() {
        let h = SlcanLink::new(
            Bytes {
                input: VecDeque::new(),
                output: Vec::new(),
            },
            Role::Host,
            "test".into(),
        )
        .unwrap();
        assert_eq!(h.stream.output, b"C\rS8\rO\r");
    }

    #[test]
    fn the_listener_serves_connections_one_after_another_and_drops_idle_ones() {
        let mut car = SlcanListener::bind(
            SocketAddrV4::new(std::net::Ipv4Addr::LOCALHOST, 0),
            Duration::from_millis(300),
        )
        .unwrap();
        let SocketAddr::V4(addr) = car.local_addr() else {
            unreachable!()
        };
        let frame = |b| CanFrame::new(CanId::standard(0x104).unwrap(), &[b]).unwrap();
        // A squatter connects first and says nothing; the host connects after it.
        let squatter = TcpStream::connect(addr).unwrap();
        assert_eq!(car.recv(Duration::from_millis(20)).unwrap(), None);
        assert!(car.connected());
        let mut host = SlcanLink::connect_tcp(addr, Duration::from_secs(5)).unwrap();
        host.send(&frame(1)).unwrap();
        // Nothing authenticated from the squatter: after the idle timeout the host is served.
        let got = car.recv(Duration::from_secs(5)).unwrap();
        assert_eq!(got, Some(frame(1)));
        assert_eq!((car.accepted(), car.idle_closed()), (2, 1));
        car.authenticated(true);
        car.send(&frame(2)).unwrap();
        assert_eq!(host.recv(Duration::from_secs(5)).unwrap(), Some(frame(2)));
        drop(squatter);
        // The host leaves: the car serves the next connection.
        drop(host);
        let mut next = SlcanLink::connect_tcp(addr, Duration::from_secs(5)).unwrap();
        next.send(&frame(3)).unwrap();
        assert_eq!(car.recv(Duration::from_secs(5)).unwrap(), Some(frame(3)));
        assert_eq!(car.accepted(), 3);
        assert!(
            car.describe().contains("3 connections accepted"),
            "{}",
            car.describe()
        );
    }
}
