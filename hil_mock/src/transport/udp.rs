//! CAN frames over UDP in cannelloni's packet format (version 2), on 127.0.0.1.
//!
//! [cannelloni](https://github.com/mguentner/cannelloni) tunnels a SocketCAN bus over UDP; a
//! cannelloni instance on a machine with a real bus could bridge this link onto it. Its format
//! (`doc/udp_format.md` in that repository), everything big-endian:
//!
//! | bytes | field |
//! |---|---|
//! | 1 | version, 2 |
//! | 1 | op code, 0 = DATA |
//! | 1 | sequence number (wraps) |
//! | 2 | number of CAN frames |
//!
//! then per frame: `can_id` (4 bytes, Linux `canid_t`: bit 31 = extended, bit 30 = remote,
//! bit 29 = error frame), `len` (the payload length; bit 7 set marks a CAN FD frame, which is then
//! followed by a `flags` byte: 0x01 bit-rate switch, 0x04 FD frame), and the payload.
//!
//! This link sends a frame, or the frames of a message ([`Link::send_all`]), in one packet at once
//! (no batching delay), and takes a packet the moment it arrives: its socket never blocks. Within a
//! busy-poll window of its last send or receive (an exchange under way: the answer to what it just
//! sent, the next frame of a message, the next tick of a host driving it back to back) `recv` reads
//! the socket again without sleeping; after that it waits for the next datagram in `poll(2)` with
//! the time left (a timeout ends on the kernel's high-resolution timer, within its 50 µs slack).
//! The busy poll is for the wake-up: a thread asleep in `poll` is woken by the sender's kernel,
//! which on this machine's virtual CPUs costs several times the datagram's own trip (issue 17: back
//! to back, the round trip's p50 went 78–90 → 11–15 µs, docs/performance.md, "The link"). The
//! window adapts: a poll that catches a datagram doubles it, up to [`DEFAULT_BUSY_POLL`]; one that
//! runs out halves it, down to [`MIN_BUSY_POLL`]. So a link whose peer answers at once keeps
//! polling, and one whose answers come late (a car at a real tick rate, a machine whose cores are
//! busy, where polling keeps the peer from a core) polls only briefly. It never stops altogether: a
//! link that slept cannot tell from the time its datagram came whether a longer poll would have
//! caught it, since that time includes its own wake-up (tens of microseconds here), so a window
//! that fell to nothing would stay there. An idle link takes no CPU time.
//! [`UdpLink::set_busy_poll`] sets the limit ([`Duration::ZERO`]: never).
//!
//! Both ends busy polling on one CPU wait for each other: each holds the CPU its peer needs until
//! its window runs out, and a wake-up over loopback tends to pull the woken thread onto the
//! waker's CPU. A car's server is best on a CPU of its own (`taskset -c 1 hil_mock serve …`), as
//! `hil_mock bench-latency` places it (docs/performance.md, "The link").
//!
//! Remote and error frames received are skipped; a packet that is truncated or inconsistent is
//! reported as malformed and dropped whole.
//!
//! **Whom a listening link answers.** Anyone on 127.0.0.1 can send it a datagram. A listening
//! link answers only the sender of the last packet that completed an authenticated message with
//! the highest counter yet ([`Link::authenticated`], called by the car's node after the MAC and
//! freshness checks): garbage, forgeries and replays from another port never redirect its
//! answers, nor does a genuine message that was lost and is replayed late by another node. The
//! answer to a hello (authenticated but replayable) or to such a late message goes to its
//! sender alone, without trusting it. Before the first authenticated message it answers nobody (its frames are
//! dropped, as on a bus without a listener).

use std::collections::VecDeque;
use std::io::ErrorKind;
use std::net::{SocketAddr, SocketAddrV4, UdpSocket};
use std::time::{Duration, Instant};

use protocol::can::{CLASSIC_MAX_DATA, CanFrame, CanId, FD_LENGTHS};

use super::{Link, LinkError};

/// The cannelloni format version this codec speaks.
pub const VERSION: u8 = 2;
/// The DATA op code.
pub const OP_DATA: u8 = 0;
/// Size of the packet header.
pub const HEADER_LEN: usize = 5;

const EFF_FLAG: u32 = 0x8000_0000;
const RTR_FLAG: u32 = 0x4000_0000;
const ERR_FLAG: u32 = 0x2000_0000;
const FD_LEN_FLAG: u8 = 0x80;
const CANFD_BRS: u8 = 0x01;
const CANFD_FDF: u8 = 0x04;

/// The longest a link polls its socket without sleeping after its last send or receive (see the
/// module documentation).
pub const DEFAULT_BUSY_POLL: Duration = Duration::from_micros(50);

/// The shortest window the busy poll shrinks to (or the limit, if that is shorter).
pub const MIN_BUSY_POLL: Duration = Duration::from_micros(20);

/// Largest packet [`Link::send_all`] sends: an Ethernet MTU's UDP payload, as cannelloni's own
/// packets.
pub const MAX_PACKET: usize = 1472;

/// Bytes a frame takes in a packet.
fn packed_len(frame: &CanFrame) -> usize {
    4 + 1 + usize::from(frame.is_fd()) + frame.data().len()
}

/// Largest datagram read (cannelloni's default MTU-sized packets fit with room to spare).
const MAX_DATAGRAM: usize = 2048;

/// Appends one DATA packet holding `frames` to `out`.
pub fn encode_packet(seq: u8, frames: &[CanFrame], out: &mut Vec<u8>) {
    out.extend_from_slice(&[VERSION, OP_DATA, seq]);
    out.extend_from_slice(&(frames.len() as u16).to_be_bytes());
    for f in frames {
        let word = match f.id() {
            CanId::Standard(id) => id as u32,
            CanId::Extended(id) => id | EFF_FLAG,
        };
        out.extend_from_slice(&word.to_be_bytes());
        let len = f.data().len() as u8;
        if f.is_fd() {
            out.push(len | FD_LEN_FLAG);
            out.push(CANFD_BRS | CANFD_FDF);
        } else {
            out.push(len);
        }
        out.extend_from_slice(f.data());
    }
}

/// Decodes a packet, appending its data frames to `out`; returns the packet's sequence number.
/// On error nothing is appended.
pub fn decode_packet(bytes: &[u8], out: &mut Vec<CanFrame>) -> Result<u8, LinkError> {
    let bad = |d: String| LinkError::malformed("cannelloni", d);
    if bytes.len() < HEADER_LEN {
        return Err(bad(format!(
            "packet of {} bytes is shorter than the header",
            bytes.len()
        )));
    }
    if bytes[0] != VERSION {
        return Err(bad(format!("version {}, expected {VERSION}", bytes[0])));
    }
    if bytes[1] != OP_DATA {
        return Err(bad(format!("op code {}, expected DATA", bytes[1])));
    }
    let seq = bytes[2];
    let count = u16::from_be_bytes([bytes[3], bytes[4]]) as usize;
    let mut frames = Vec::with_capacity(count.min(64));
    let mut rest = &bytes[HEADER_LEN..];
    for i in 0..count {
        if rest.len() < 5 {
            return Err(bad(format!("frame {i} of {count}: truncated header")));
        }
        let word = u32::from_be_bytes([rest[0], rest[1], rest[2], rest[3]]);
        let raw_len = rest[4];
        rest = &rest[5..];
        let fd = raw_len & FD_LEN_FLAG != 0;
        let len = (raw_len & !FD_LEN_FLAG) as usize;
        if fd {
            if rest.is_empty() {
                return Err(bad(format!("frame {i}: missing CAN FD flags")));
            }
            rest = &rest[1..];
        }
        let remote = word & RTR_FLAG != 0;
        let data_len = if remote { 0 } else { len };
        if rest.len() < data_len {
            return Err(bad(format!(
                "frame {i}: {data_len} payload bytes announced, {} left",
                rest.len()
            )));
        }
        let data = &rest[..data_len];
        rest = &rest[data_len..];
        if remote || word & ERR_FLAG != 0 {
            continue; // valid on a bus, meaningless to this protocol
        }
        let id = if word & EFF_FLAG != 0 {
            CanId::extended(word & 0x1FFF_FFFF)
        } else {
            CanId::standard((word & 0x7FF) as u16).filter(|_| word & 0x1FFF_F800 == 0)
        }
        .ok_or_else(|| bad(format!("frame {i}: identifier {word:#x} out of range")))?;
        let frame = if fd {
            if !FD_LENGTHS.contains(&len) {
                return Err(bad(format!("frame {i}: {len} is not a CAN FD length")));
            }
            CanFrame::new_fd(id, data)
        } else {
            if len > CLASSIC_MAX_DATA {
                return Err(bad(format!("frame {i}: classic frame of {len} bytes")));
            }
            CanFrame::new(id, data)
        }
        .map_err(|e| bad(format!("frame {i}: {e}")))?;
        frames.push(frame);
    }
    if !rest.is_empty() {
        return Err(bad(format!("{} bytes after the last frame", rest.len())));
    }
    out.extend(frames);
    Ok(seq)
}

/// Waits for `socket` to hold a datagram (or an error), at most `timeout`: `poll(2)` on the
/// socket, which the kernel ends as soon as a datagram arrives, or on its high-resolution timer
/// when the time is up (a socket's receive timeout would be rounded up to the scheduler's tick,
/// 4–8 ms here, and short naps between non-blocking reads add their own length to every
/// answer). An interrupted wait returns early; the caller reads and waits again.
#[cfg(unix)]
fn wait_readable(socket: &UdpSocket, timeout: Duration) -> Result<(), LinkError> {
    use rustix::event::{PollFd, PollFlags, Timespec, poll};
    let mut fds = [PollFd::new(socket, PollFlags::IN)];
    // A wait too long for a timespec is as good as forever.
    let limit = Timespec::try_from(timeout).unwrap_or(Timespec {
        tv_sec: i64::MAX,
        tv_nsec: 0,
    });
    match poll(&mut fds, Some(&limit)) {
        Ok(_) | Err(rustix::io::Errno::INTR) => Ok(()),
        Err(e) => Err(LinkError::io("udp wait", e.into())),
    }
}

/// Elsewhere: short naps between non-blocking reads.
#[cfg(not(unix))]
fn wait_readable(_socket: &UdpSocket, timeout: Duration) -> Result<(), LinkError> {
    std::thread::sleep(timeout.min(Duration::from_micros(50)));
    Ok(())
}

/// A cannelloni UDP link on 127.0.0.1.
#[derive(Debug)]
pub struct UdpLink {
    socket: UdpSocket,
    /// Where frames go: the remote (connected), or the sender of the last authenticated, fresh
    /// message (listening).
    peer: Option<SocketAddr>,
    /// Listening: where the answer to the frame received last goes, when it is not `peer` (the
    /// sender of a hello); cleared by the next receive.
    answer_to: Option<SocketAddr>,
    connected: bool,
    seq: u8,
    /// Received frames with the address they came from.
    pending: VecDeque<(CanFrame, Option<SocketAddr>)>,
    /// The sender of the frame `recv` returned last.
    last_from: Option<SocketAddr>,
    /// Frames not sent because no authenticated peer has spoken yet (listening).
    unanswered: u64,
    /// The datagram received last.
    buf: Vec<u8>,
    /// The packet being sent.
    out: Vec<u8>,
    /// The busy poll's limit.
    busy_poll: Duration,
    /// How long after `active` `recv` polls without sleeping now (adapted, at most `busy_poll`).
    window: Duration,
    /// The last send or receive of a datagram.
    active: Instant,
    /// The frames of the packet received last.
    decoded: Vec<CanFrame>,
}

impl UdpLink {
    /// Binds an ephemeral port on 127.0.0.1 and sends to `remote`.
    pub fn connect(remote: SocketAddrV4) -> Result<Self, LinkError> {
        let socket =
            UdpSocket::bind("127.0.0.1:0").map_err(|e| LinkError::io("bind 127.0.0.1:0", e))?;
        socket
            .connect(remote)
            .map_err(|e| LinkError::io(format!("connect to {remote}"), e))?;
        Self::new(socket, Some(SocketAddr::V4(remote)), true)
    }

    /// Binds `local` (on 127.0.0.1) and answers the sender of the last authenticated message.
    pub fn listen(local: SocketAddrV4) -> Result<Self, LinkError> {
        let socket =
            UdpSocket::bind(local).map_err(|e| LinkError::io(format!("bind {local}"), e))?;
        Self::new(socket, None, false)
    }

    /// The socket never blocks: `recv` reads what is there and waits in `wait_readable`.
    fn new(
        socket: UdpSocket,
        peer: Option<SocketAddr>,
        connected: bool,
    ) -> Result<Self, LinkError> {
        socket
            .set_nonblocking(true)
            .map_err(|e| LinkError::io("udp nonblocking", e))?;
        Ok(Self {
            socket,
            peer,
            connected,
            seq: 0,
            pending: VecDeque::new(),
            answer_to: None,
            last_from: None,
            unanswered: 0,
            buf: vec![0; MAX_DATAGRAM],
            out: Vec::with_capacity(HEADER_LEN + 6 + 64),
            busy_poll: DEFAULT_BUSY_POLL,
            window: DEFAULT_BUSY_POLL,
            active: Instant::now(),
            decoded: Vec::new(),
        })
    }

    /// The longest `recv` polls the socket without sleeping after the link's last send or
    /// receive ([`DEFAULT_BUSY_POLL`] unless set; [`Duration::ZERO`] turns it off). The window
    /// adapts below it (module documentation); setting it starts the window at the limit.
    pub fn set_busy_poll(&mut self, busy_poll: Duration) {
        self.busy_poll = busy_poll;
        self.window = busy_poll;
    }

    /// The busy poll's window now (at most the limit [`UdpLink::set_busy_poll`] set).
    pub fn busy_poll_window(&self) -> Duration {
        self.window
    }

    /// A busy poll caught a datagram (double the window, up to the limit) or ran out (halve it,
    /// down to [`MIN_BUSY_POLL`]).
    fn adapt(&mut self, caught: bool) {
        let floor = MIN_BUSY_POLL.min(self.busy_poll);
        self.window = if caught {
            (self.window * 2).min(self.busy_poll)
        } else {
            (self.window / 2).max(floor)
        };
    }

    /// Sends `frames` in one packet (to the peer, or counted as unanswered while there is none).
    fn send_packet(&mut self, frames: &[CanFrame]) -> Result<(), LinkError> {
        self.out.clear();
        encode_packet(self.seq, frames, &mut self.out);
        self.seq = self.seq.wrapping_add(1);
        let result = if self.connected {
            self.socket.send(&self.out)
        } else {
            let Some(peer) = self.answer_to.or(self.peer) else {
                self.unanswered += frames.len() as u64;
                return Ok(());
            };
            self.socket.send_to(&self.out, peer)
        };
        self.active = Instant::now();
        result.map(|_| ()).map_err(|e| LinkError::io("udp send", e))
    }

    /// The address answers go to (listening: the sender of the last authenticated message).
    pub fn peer(&self) -> Option<SocketAddr> {
        self.peer
    }

    /// Frames a listening link dropped because no authenticated peer had spoken yet.
    pub fn unanswered(&self) -> u64 {
        self.unanswered
    }

    /// The local address (the port to give the peer when listening on port 0).
    pub fn local_addr(&self) -> Result<SocketAddr, LinkError> {
        self.socket
            .local_addr()
            .map_err(|e| LinkError::io("local address", e))
    }
}

impl Link for UdpLink {
    /// Sends one packet. The socket does not block: a send buffer that is full (it never is on
    /// loopback at these rates) loses the frame with an [`LinkError::Io`], which the protocol
    /// recovers like any lost frame.
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        self.send_packet(std::slice::from_ref(frame))
    }

    /// Sends the frames in as few packets as hold them, each at most [`MAX_PACKET`] bytes (the
    /// frames of one message: one packet).
    fn send_all(&mut self, frames: &[CanFrame]) -> Result<(), LinkError> {
        let mut rest = frames;
        while !rest.is_empty() {
            let mut bytes = HEADER_LEN;
            let n = rest
                .iter()
                .take_while(|f| {
                    bytes += packed_len(f);
                    bytes <= MAX_PACKET
                })
                .count()
                .max(1);
            self.send_packet(&rest[..n])?;
            rest = &rest[n..];
        }
        Ok(())
    }

    /// Returns a frame already received, else reads the socket, and while it is empty waits in
    /// `wait_readable` for the time left: a datagram is taken the moment it arrives.
    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        self.answer_to = None;
        let start = Instant::now();
        // This call polled without sleeping; its poll ran out.
        let (mut spun, mut missed) = (false, false);
        loop {
            if let Some((f, from)) = self.pending.pop_front() {
                self.last_from = from;
                return Ok(Some(f));
            }
            let got = if self.connected {
                self.socket.recv(&mut self.buf).map(|n| (n, None))
            } else {
                self.socket
                    .recv_from(&mut self.buf)
                    .map(|(n, a)| (n, Some(a)))
            };
            match got {
                Ok((n, from)) => {
                    let now = Instant::now();
                    if spun && !missed {
                        self.adapt(true);
                    }
                    (spun, missed) = (false, false);
                    self.active = now;
                    self.decoded.clear();
                    decode_packet(&self.buf[..n], &mut self.decoded)?;
                    self.pending
                        .extend(self.decoded.drain(..).map(|f| (f, from)));
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    let now = Instant::now();
                    let left = timeout.saturating_sub(now - start);
                    if left.is_zero() {
                        return Ok(None);
                    }
                    // An exchange under way: read again rather than sleep (module docs).
                    if now < self.active + self.window {
                        spun = true;
                        std::hint::spin_loop();
                        continue;
                    }
                    if spun && !missed {
                        missed = true;
                        self.adapt(false);
                    }
                    wait_readable(&self.socket, left)?;
                }
                // A previous send to a closed port on loopback comes back as ECONNREFUSED (once;
                // the next read goes on).
                Err(e) if e.kind() == ErrorKind::ConnectionRefused => {}
                Err(e) => return Err(LinkError::io("udp receive", e)),
            }
        }
    }

    fn authenticated(&mut self, fresh: bool) {
        if self.connected || self.last_from.is_none() {
            return;
        }
        if fresh {
            self.peer = self.last_from;
        } else {
            self.answer_to = self.last_from;
        }
    }

    fn describe(&self) -> String {
        match (self.socket.local_addr(), self.peer) {
            (Ok(l), Some(p)) => format!("cannelloni/udp {l} <-> {p}"),
            (Ok(l), None) => format!("cannelloni/udp listening on {l}"),
            _ => "cannelloni/udp".into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames() -> Vec<CanFrame> {
        vec![
            CanFrame::new(CanId::standard(0x123).unwrap(), &[0xDE, 0xAD, 0xBE, 0xEF]).unwrap(),
            CanFrame::new(CanId::extended(0x1ABC_DEF0).unwrap(), &[]).unwrap(),
            CanFrame::new_fd(CanId::standard(0x7FF).unwrap(), &[7; 12]).unwrap(),
        ]
    }

    /// The busy poll's window: halved by each poll that runs out, down to its floor; doubled by
    /// each that catches a datagram, up to the limit; off stays off.
    #[test]
    fn the_busy_poll_window_adapts_within_its_limit() {
        let mut link = UdpLink::listen("127.0.0.1:0".parse().unwrap()).unwrap();
        assert_eq!(link.busy_poll_window(), DEFAULT_BUSY_POLL);
        let windows = |link: &mut UdpLink, caught: bool| {
            (0..3)
                .map(|_| {
                    link.adapt(caught);
                    link.busy_poll_window().as_micros()
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(windows(&mut link, false), [25, 20, 20]);
        assert_eq!(windows(&mut link, true), [40, 50, 50]);
        link.set_busy_poll(Duration::from_micros(8));
        assert_eq!(
            windows(&mut link, false),
            [8, 8, 8],
            "a limit under the floor"
        );
        link.set_busy_poll(Duration::ZERO);
        assert_eq!(windows(&mut link, true), [0, 0, 0], "off stays off");
        assert_eq!(windows(&mut link, false), [0, 0, 0]);
    }

    #[test]
    fn golden_bytes_of_a_packet() {
        let mut out = Vec::new();
        encode_packet(9, &frames()[..1], &mut out);
        assert_eq!(
            out,
            [2, 0, 9, 0, 1, 0, 0, 0x01, 0x23, 4, 0xDE, 0xAD, 0xBE, 0xEF]
        );
        let mut out = Vec::new();
        encode_packet(0, &frames()[2..], &mut out);
        assert_eq!(&out[5..12], &[0, 0, 0x07, 0xFF, 12 | 0x80, 0x05, 7]);
    }

    #[test]
    fn packets_round_trip() {
        let mut out = Vec::new();
        encode_packet(200, &frames(), &mut out);
        let mut back = Vec::new();
        assert_eq!(decode_packet(&out, &mut back).unwrap(), 200);
        assert_eq!(back, frames());
    }

    #[test]
    fn remote_frames_are_skipped_and_bad_packets_refused() {
        // One remote frame with dlc 8 and no payload, then a data frame.
        let mut p = vec![2, 0, 0, 0, 2];
        p.extend_from_slice(&(0x100u32 | RTR_FLAG).to_be_bytes());
        p.push(8);
        p.extend_from_slice(&0x101u32.to_be_bytes());
        p.extend_from_slice(&[1, 0xAA]);
        let mut out = Vec::new();
        decode_packet(&p, &mut out).unwrap();
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].data(), &[0xAA]);

        let mut good = Vec::new();
        encode_packet(1, &frames(), &mut good);
        for cut in 0..good.len() {
            let mut out = Vec::new();
            assert!(
                decode_packet(&good[..cut], &mut out).is_err(),
                "cut at {cut}"
            );
            assert!(out.is_empty());
        }
        let mut bad = good.clone();
        bad[0] = 3;
        assert!(
            decode_packet(&bad, &mut Vec::new())
                .unwrap_err()
                .to_string()
                .contains("version 3")
        );
        let mut bad = vec![2, 0, 0, 0, 1, 0, 0, 1, 0, 9];
        bad.extend_from_slice(&[0; 9]);
        assert!(
            decode_packet(&bad, &mut Vec::new())
                .unwrap_err()
                .to_string()
                .contains("classic frame of 9")
        );
        let mut bad = vec![2, 0, 0, 0, 1, 0, 0, 1, 0, 13 | 0x80, 0];
        bad.extend_from_slice(&[0; 13]);
        assert!(
            decode_packet(&bad, &mut Vec::new())
                .unwrap_err()
                .to_string()
                .contains("not a CAN FD length")
        );
        let mut bad = good;
        bad.push(0);
        assert!(decode_packet(&bad, &mut Vec::new()).is_err());
    }

    #[test]
    fn arbitrary_bytes_never_panic() {
        let mut state = 0x1234_5678u32;
        for n in 0..2000 {
            let bytes: Vec<u8> = (0..n % 80)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 17;
                    state ^= state << 5;
                    state as u8
                })
                .collect();
            let mut prefixed = vec![2, 0, 0];
            prefixed.extend_from_slice(&bytes);
            let _ = decode_packet(&bytes, &mut Vec::new());
            let _ = decode_packet(&prefixed, &mut Vec::new());
        }
    }

    /// `send_all` puts a message's frames in one packet, and as many frames as a packet of at
    /// most `MAX_PACKET` bytes holds when they are more, in order; a listening link counts each
    /// frame it could not send.
    #[test]
    fn send_all_packs_frames_into_as_few_packets_as_hold_them() {
        let raw = UdpSocket::bind("127.0.0.1:0").unwrap();
        raw.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        let SocketAddr::V4(at) = raw.local_addr().unwrap() else {
            unreachable!()
        };
        let mut link = UdpLink::connect(at).unwrap();
        let mut buf = [0u8; MAX_DATAGRAM];
        let mut packets = |link: &mut UdpLink, frames: &[CanFrame]| {
            link.send_all(frames).unwrap();
            let mut got = Vec::new();
            let mut sizes = Vec::new();
            while got.len() < frames.len() {
                let n = raw.recv(&mut buf).unwrap();
                sizes.push(n);
                decode_packet(&buf[..n], &mut got).unwrap();
            }
            assert_eq!(got, frames);
            sizes
        };
        assert_eq!(packets(&mut link, &frames()), [HEADER_LEN + 9 + 5 + 18]);
        // 40 FD frames of 64 bytes, 70 bytes each in a packet: 20 fit in 1 472 bytes.
        let many: Vec<CanFrame> = (0..40u8)
            .map(|i| CanFrame::new_fd(CanId::standard(0x100).unwrap(), &[i; 64]).unwrap())
            .collect();
        assert_eq!(packets(&mut link, &many), [1405, 1405]);
        assert_eq!(packets(&mut link, &many[..1]), [HEADER_LEN + 70]);
        link.send_all(&[]).unwrap();
        raw.set_nonblocking(true).unwrap();
        assert!(raw.recv(&mut buf).is_err(), "no packet for no frames");

        let mut server = UdpLink::listen("127.0.0.1:0".parse().unwrap()).unwrap();
        server.send_all(&frames()).unwrap();
        assert_eq!(server.unanswered(), 3);
    }

    #[test]
    fn loopback_exchange() {
        let mut server = UdpLink::listen("127.0.0.1:0".parse().unwrap()).unwrap();
        let port = server.local_addr().unwrap().port();
        let mut client =
            UdpLink::connect(SocketAddrV4::new(std::net::Ipv4Addr::LOCALHOST, port)).unwrap();
        // No authenticated peer yet: nothing goes out.
        server.send(&frames()[0]).unwrap();
        assert_eq!(server.unanswered(), 1);
        for f in frames() {
            client.send(&f).unwrap();
        }
        for f in frames() {
            assert_eq!(server.recv(Duration::from_secs(2)).unwrap(), Some(f));
        }
        assert_eq!(server.peer(), None, "receiving alone trusts nobody");
        server.authenticated(true);
        server.send(&frames()[1]).unwrap();
        assert_eq!(
            client.recv(Duration::from_secs(2)).unwrap(),
            Some(frames()[1])
        );
        assert_eq!(client.recv(Duration::from_millis(5)).unwrap(), None);
        assert_eq!(client.recv(Duration::ZERO).unwrap(), None);
    }

    #[test]
    fn a_stranger_does_not_redirect_the_answers() {
        let mut server = UdpLink::listen("127.0.0.1:0".parse().unwrap()).unwrap();
        let port = server.local_addr().unwrap().port();
        let addr = SocketAddrV4::new(std::net::Ipv4Addr::LOCALHOST, port);
        let mut host = UdpLink::connect(addr).unwrap();
        let mut stranger = UdpLink::connect(addr).unwrap();
        host.send(&frames()[0]).unwrap();
        assert!(server.recv(Duration::from_secs(2)).unwrap().is_some());
        server.authenticated(true);
        // The stranger's packet arrives (garbage or a forgery: never authenticated).
        stranger.send(&frames()[1]).unwrap();
        assert!(server.recv(Duration::from_secs(2)).unwrap().is_some());
        server.send(&frames()[2]).unwrap();
        assert_eq!(
            host.recv(Duration::from_secs(2)).unwrap(),
            Some(frames()[2])
        );
        assert_eq!(stranger.recv(Duration::from_millis(20)).unwrap(), None);
        // A malformed datagram does not either.
        let raw = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        raw.send_to(b"\x02\x00", addr).unwrap();
        assert!(server.recv(Duration::from_secs(2)).is_err());
        server.send(&frames()[0]).unwrap();
        assert_eq!(
            host.recv(Duration::from_secs(2)).unwrap(),
            Some(frames()[0])
        );
    }
}
