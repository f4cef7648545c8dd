//! CAN transports: how frames travel between the host and the car.
//!
//! Every transport implements [`Link`]: send a frame, wait a bounded time for one. They are
//! chosen at run time from a [`LinkAddress`]:
//!
//! | address | transport |
//! |---|---|
//! | `udp://127.0.0.1:PORT` | [`udp::UdpLink`]: CAN frames in cannelloni's UDP packet format (connects to `PORT`) |
//! | `udp-listen://127.0.0.1:PORT` | the same, listening on `PORT`, answering only the sender of the last authenticated message |
//! | `slcan+tcp://127.0.0.1:PORT` | [`slcan::SlcanLink`] over TCP (connects; QEMU's `-serial tcp:…,server` is such a server) |
//! | `slcan+tcp-listen://127.0.0.1:PORT` | [`slcan::SlcanListener`]: accepts connections one after another, one at a time, dropping one idle (no authenticated message) for its idle timeout |
//! | `slcan+serial:///dev/ttyACM0?baud=115200` | slcan over a serial device (a USB-CAN adapter) |
//! | `socketcan://can0` | Linux SocketCAN (cargo feature `socketcan`) |
//!
//! [`memory::MemoryLink::pair`] gives two connected in-process ends for tests.
//! Middleware wraps any link: [`fault::FaultyLink`] (seeded drop, corruption, duplication,
//! reordering, delay), [`record::RecordingLink`] (a candump log of every frame) and
//! [`reconnect::ReconnectingLink`] (reopens a connection the peer closed, e.g. a restarted car).
//!
//! Every network transport binds or connects to 127.0.0.1 only: any other address is refused.

pub mod fault;
pub mod memory;
pub mod reconnect;
pub mod record;
pub mod slcan;
#[cfg(feature = "socketcan")]
pub mod socketcan;
pub mod udp;

use std::fmt;
use std::net::{Ipv4Addr, SocketAddrV4};
use std::path::PathBuf;
use std::str::FromStr;
use std::time::Duration;

use protocol::can::CanFrame;

/// Why a transport failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LinkError {
    /// The operating system refused (socket, device or file).
    #[error("{context}: {error}")]
    Io {
        /// What was being done.
        context: String,
        /// What the OS said (in the message, so not a `source`: a chain of causes prints it
        /// once).
        error: std::io::Error,
    },
    /// The peer sent bytes that are not a valid packet or line of the transport's format.
    #[error("malformed {format} input: {detail}")]
    Malformed {
        /// The format ("cannelloni", "slcan", "candump").
        format: &'static str,
        /// What was wrong.
        detail: String,
    },
    /// The other end went away.
    #[error("link closed: {0}")]
    Closed(String),
    /// The address is not one this build can open.
    #[error("bad link address '{address}': {reason}")]
    Address {
        /// The address as given.
        address: String,
        /// Why it was refused.
        reason: String,
    },
}

impl LinkError {
    pub(crate) fn io(context: impl Into<String>, error: std::io::Error) -> Self {
        LinkError::Io {
            context: context.into(),
            error,
        }
    }

    pub(crate) fn malformed(format: &'static str, detail: impl Into<String>) -> Self {
        LinkError::Malformed {
            format,
            detail: detail.into(),
        }
    }
}

/// A bidirectional CAN link.
pub trait Link: Send {
    /// Sends one frame.
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError>;

    /// Sends `frames` in order, together where the transport can: UDP puts them in one
    /// cannelloni packet (fewer system calls and wake-ups for the frames of one message). By
    /// default one [`Link::send`] each, so a link that acts per frame (faults, records) still
    /// does. On an error, the frames before it may have been sent.
    fn send_all(&mut self, frames: &[CanFrame]) -> Result<(), LinkError> {
        frames.iter().try_for_each(|f| self.send(f))
    }

    /// Waits up to `timeout` for one frame; `Ok(None)` when none came.
    ///
    /// A malformed packet from the peer is reported as [`LinkError::Malformed`] and skipped:
    /// the next call goes on with the following input.
    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError>;

    /// A short description for logs ("udp 127.0.0.1:4000", ...).
    fn describe(&self) -> String;

    /// The frame received last completed an authenticated message
    /// (`protocol::can::CanBus::authenticated`): a transport with peers answers its sender, and
    /// if the message was `fresh` trusts it from now on (UDP answers it; a TCP listener keeps
    /// its connection). Nothing by default.
    fn authenticated(&mut self, fresh: bool) {
        let _ = fresh;
    }
}

impl<L: Link + ?Sized> Link for Box<L> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        (**self).send(frame)
    }
    fn send_all(&mut self, frames: &[CanFrame]) -> Result<(), LinkError> {
        (**self).send_all(frames)
    }
    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        (**self).recv(timeout)
    }
    fn describe(&self) -> String {
        (**self).describe()
    }
    fn authenticated(&mut self, fresh: bool) {
        (**self).authenticated(fresh)
    }
}

/// A parsed link address (see the module table).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LinkAddress {
    /// cannelloni over UDP, sending to the address.
    Udp(SocketAddrV4),
    /// cannelloni over UDP, listening on the address.
    UdpListen(SocketAddrV4),
    /// slcan over TCP, connecting.
    SlcanTcp(SocketAddrV4),
    /// slcan over TCP, accepting one connection.
    SlcanTcpListen(SocketAddrV4),
    /// slcan over a serial device.
    SlcanSerial {
        /// Device path.
        path: PathBuf,
        /// Baud rate.
        baud: u32,
    },
    /// Linux SocketCAN interface.
    SocketCan(String),
}

fn loopback(address: &str, hostport: &str) -> Result<SocketAddrV4, LinkError> {
    let bad = |reason: &str| LinkError::Address {
        address: address.to_string(),
        reason: reason.to_string(),
    };
    let addr = SocketAddrV4::from_str(hostport).map_err(|_| bad("expected 127.0.0.1:PORT"))?;
    if *addr.ip() != Ipv4Addr::LOCALHOST {
        return Err(bad(
            "only 127.0.0.1 is allowed: this project never talks to another host",
        ));
    }
    Ok(addr)
}

impl FromStr for LinkAddress {
    type Err = LinkError;

    fn from_str(s: &str) -> Result<Self, LinkError> {
        let bad = |reason: &str| LinkError::Address {
            address: s.to_string(),
            reason: reason.to_string(),
        };
        let (scheme, rest) = s
            .split_once("://")
            .ok_or_else(|| bad("expected SCHEME://..."))?;
        match scheme {
            "udp" => Ok(Self::Udp(loopback(s, rest)?)),
            "udp-listen" => Ok(Self::UdpListen(loopback(s, rest)?)),
            "slcan+tcp" => Ok(Self::SlcanTcp(loopback(s, rest)?)),
            "slcan+tcp-listen" => Ok(Self::SlcanTcpListen(loopback(s, rest)?)),
            "slcan+serial" => {
                let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
                if path.is_empty() {
                    return Err(bad("expected slcan+serial:///dev/DEVICE[?baud=N]"));
                }
                let mut baud = 115_200;
                for kv in query.split('&').filter(|kv| !kv.is_empty()) {
                    match kv.split_once('=') {
                        Some(("baud", v)) => {
                            baud = v.parse().map_err(|_| bad("baud must be a number"))?
                        }
                        _ => return Err(bad("the only option is baud=N")),
                    }
                }
                Ok(Self::SlcanSerial {
                    path: PathBuf::from(path),
                    baud,
                })
            }
            "socketcan" => {
                if rest.is_empty()
                    || rest.len() > 15
                    || !rest
                        .chars()
                        .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
                {
                    return Err(bad("expected socketcan://IFACE, e.g. socketcan://can0"));
                }
                Ok(Self::SocketCan(rest.to_string()))
            }
            _ => Err(bad(
                "unknown scheme; use udp, udp-listen, slcan+tcp, slcan+tcp-listen, slcan+serial or socketcan",
            )),
        }
    }
}

impl fmt::Display for LinkAddress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Udp(a) => write!(f, "udp://{a}"),
            Self::UdpListen(a) => write!(f, "udp-listen://{a}"),
            Self::SlcanTcp(a) => write!(f, "slcan+tcp://{a}"),
            Self::SlcanTcpListen(a) => write!(f, "slcan+tcp-listen://{a}"),
            Self::SlcanSerial { path, baud } => {
                write!(f, "slcan+serial://{}?baud={baud}", path.display())
            }
            Self::SocketCan(i) => write!(f, "socketcan://{i}"),
        }
    }
}

impl LinkAddress {
    /// Opens the link. A connecting TCP address waits up to `timeout` for its peer to listen;
    /// listening addresses return at once (a listening slcan link accepts connections as they
    /// come, with [`slcan::DEFAULT_IDLE_TIMEOUT`]).
    pub fn open(&self, timeout: Duration) -> Result<Box<dyn Link>, LinkError> {
        Ok(match self {
            Self::Udp(a) => Box::new(udp::UdpLink::connect(*a)?),
            Self::UdpListen(a) => Box::new(udp::UdpLink::listen(*a)?),
            Self::SlcanTcp(a) => Box::new(slcan::SlcanLink::connect_tcp(*a, timeout)?),
            Self::SlcanTcpListen(a) => {
                Box::new(slcan::SlcanListener::bind(*a, slcan::DEFAULT_IDLE_TIMEOUT)?)
            }
            #[cfg(feature = "serial")]
            Self::SlcanSerial { path, baud } => {
                Box::new(slcan::SlcanLink::open_serial(path, *baud)?)
            }
            #[cfg(not(feature = "serial"))]
            Self::SlcanSerial { .. } => {
                return Err(LinkError::Address {
                    address: self.to_string(),
                    reason: "this build has no serial support; rebuild with --features serial"
                        .into(),
                });
            }
            #[cfg(feature = "socketcan")]
            Self::SocketCan(iface) => Box::new(socketcan::SocketCanLink::open(iface)?),
            #[cfg(not(feature = "socketcan"))]
            Self::SocketCan(_) => {
                return Err(LinkError::Address {
                    address: self.to_string(),
                    reason:
                        "this build has no SocketCAN support; rebuild with --features socketcan"
                            .into(),
                });
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_parse_and_print_back() {
        for s in [
            "udp://127.0.0.1:4000",
            "udp-listen://127.0.0.1:4001",
            "slcan+tcp://127.0.0.1:5555",
            "slcan+tcp-listen://127.0.0.1:5556",
            "slcan+serial:///dev/ttyACM0?baud=921600",
            "socketcan://vcan0",
        ] {
            let a: LinkAddress = s.parse().unwrap();
            assert_eq!(a.to_string(), s);
        }
    }

    #[test]
    fn only_loopback_is_accepted() {
        for s in [
            "udp://10.0.0.1:4000",
            "udp://0.0.0.0:4000",
            "slcan+tcp://192.168.1.2:80",
            "udp://localhost:4000",
            "udp://127.0.0.1",
            "tcp://127.0.0.1:1",
            "socketcan://",
            "slcan+serial://?baud=9600",
            "slcan+serial:///dev/x?baud=fast",
        ] {
            let e = s.parse::<LinkAddress>().unwrap_err();
            assert!(e.to_string().contains(s), "{e}");
        }
        let e = "udp://10.0.0.1:4000".parse::<LinkAddress>().unwrap_err();
        assert!(e.to_string().contains("127.0.0.1"), "{e}");
    }
}
