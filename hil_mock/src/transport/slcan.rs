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

use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddrV4, TcpListener, TcpStream};
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
        stream
            .set_nonblocking(false)
            .map_err(|e| LinkError::io("stream blocking", e))?;
        stream
            .set_nodelay(true)
            .map_err(|e| LinkError::io("TCP_NODELAY", e))?;
        SlcanLink::new(Box::new(stream), Role::Device, format!("slcan/tcp {local}"))
    }

    /// Opens a serial device as the host.
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
}
