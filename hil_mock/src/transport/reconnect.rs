//! A connecting link that survives its peer going away: [`ReconnectingLink`].
//!
//! A TCP connection to a car (slcan over `slcan+tcp://`, QEMU's serial port, a `hil_mock`
//! restarted after a crash) ends when the car's process does; a datagram link (UDP) does not
//! notice. The protocol above already recovers from lost frames by retransmission, so a lost
//! connection is turned into lost frames: the link opens its address again, at most once per
//! [`RECONNECT_INTERVAL`], and meanwhile sends nothing and receives nothing. The first opening is
//! strict (an address nobody listens on is an error at once); only a connection that was up and
//! went away is reopened.

use std::time::{Duration, Instant};

use protocol::can::CanFrame;

use super::{Link, LinkAddress, LinkError};

/// The least time between two attempts to open the address again.
pub const RECONNECT_INTERVAL: Duration = Duration::from_millis(50);

/// How long one attempt to open the address again may wait for the peer.
const REOPEN_TIMEOUT: Duration = Duration::from_millis(200);

/// A link to `address` that reopens it when the connection is closed or fails.
pub struct ReconnectingLink {
    address: LinkAddress,
    inner: Option<Box<dyn Link>>,
    last_attempt: Option<Instant>,
    last_error: Option<String>,
    reconnects: u64,
}

impl ReconnectingLink {
    /// Opens `address` (waiting up to `timeout` for the peer); an error if that fails.
    pub fn open(address: LinkAddress, timeout: Duration) -> Result<Self, LinkError> {
        let inner = address.open(timeout)?;
        Ok(Self {
            address,
            inner: Some(inner),
            last_attempt: None,
            last_error: None,
            reconnects: 0,
        })
    }

    /// How many times the connection was opened again.
    pub fn reconnects(&self) -> u64 {
        self.reconnects
    }

    /// The connection, reopened if it is down and the interval has passed; `None` when down.
    fn connection(&mut self) -> Option<&mut Box<dyn Link>> {
        if self.inner.is_none() {
            let due = self
                .last_attempt
                .is_none_or(|t| t.elapsed() >= RECONNECT_INTERVAL);
            if due {
                self.last_attempt = Some(Instant::now());
                match self.address.open(REOPEN_TIMEOUT) {
                    Ok(link) => {
                        self.inner = Some(link);
                        self.reconnects += 1;
                        self.last_error = None;
                    }
                    Err(e) => self.last_error = Some(e.to_string()),
                }
            }
        }
        self.inner.as_mut()
    }

    /// Whether `e` means the connection is gone (rather than bad input on a live one).
    fn is_lost(e: &LinkError) -> bool {
        matches!(e, LinkError::Closed(_) | LinkError::Io { .. })
    }

    fn lose(&mut self, e: &LinkError) {
        self.last_error = Some(e.to_string());
        self.inner = None;
        self.last_attempt = Some(Instant::now());
    }
}

impl std::fmt::Debug for ReconnectingLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReconnectingLink")
            .field("link", &self.describe())
            .finish_non_exhaustive()
    }
}

impl Link for ReconnectingLink {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        self.send_all(std::slice::from_ref(frame))
    }

    fn send_all(&mut self, frames: &[CanFrame]) -> Result<(), LinkError> {
        let Some(link) = self.connection() else {
            // Down: the frames are lost, as on a bus without a listener; the sender retries.
            return Ok(());
        };
        match link.send_all(frames) {
            Err(e) if Self::is_lost(&e) => {
                self.lose(&e);
                Ok(())
            }
            r => r,
        }
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        let Some(link) = self.connection() else {
            std::thread::sleep(timeout.min(RECONNECT_INTERVAL));
            return Ok(None);
        };
        match link.recv(timeout) {
            Err(e) if Self::is_lost(&e) => {
                self.lose(&e);
                Ok(None)
            }
            r => r,
        }
    }

    fn authenticated(&mut self, fresh: bool) {
        if let Some(link) = self.inner.as_mut() {
            link.authenticated(fresh);
        }
    }

    fn describe(&self) -> String {
        let state = match (&self.inner, &self.last_error) {
            (Some(link), _) => link.describe(),
            (None, Some(e)) => format!("{} (down: {e})", self.address),
            (None, None) => format!("{} (down)", self.address),
        };
        if self.reconnects > 0 {
            format!("{state}, reopened {} times", self.reconnects)
        } else {
            state
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::slcan::SlcanLink;
    use protocol::can::CanId;
    use std::net::{Ipv4Addr, TcpListener};

    fn frame(b: u8) -> CanFrame {
        CanFrame::new(CanId::standard(0x104).unwrap(), &[b]).unwrap()
    }

    #[test]
    fn nobody_listening_is_an_error_at_first() {
        // A port that was free a moment ago: nothing listens on it.
        let port = TcpListener::bind((Ipv4Addr::LOCALHOST, 0))
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let address: LinkAddress = format!("slcan+tcp://127.0.0.1:{port}").parse().unwrap();
        assert!(ReconnectingLink::open(address, Duration::from_millis(100)).is_err());
    }

    #[test]
    fn a_lost_connection_is_reopened_and_frames_flow_again() {
        let listener = TcpListener::bind((Ipv4Addr::LOCALHOST, 0)).unwrap();
        let addr = match listener.local_addr().unwrap() {
            std::net::SocketAddr::V4(a) => a,
            other => panic!("{other}"),
        };
        let address: LinkAddress = format!("slcan+tcp://{addr}").parse().unwrap();
        let accept = |l: &TcpListener| SlcanLink::accept_from(l, Duration::from_secs(10)).unwrap();
        let car = std::thread::scope(|s| {
            let t = s.spawn(|| accept(&listener));
            let mut host = ReconnectingLink::open(address.clone(), Duration::from_secs(5)).unwrap();
            let mut car = t.join().unwrap();
            host.send(&frame(1)).unwrap();
            assert_eq!(car.recv(Duration::from_secs(5)).unwrap(), Some(frame(1)));
            // The car goes away: the host loses frames, not its link.
            drop(car);
            let t = s.spawn(|| accept(&listener));
            let mut got = None;
            for i in 0..200u8 {
                host.send(&frame(i)).unwrap();
                if host.recv(Duration::from_millis(10)).unwrap().is_some() {
                    unreachable!("nobody sends to the host");
                }
                if host.reconnects() > 0 {
                    got = Some(i);
                    break;
                }
            }
            assert!(got.is_some(), "{}", host.describe());
            let mut car = t.join().unwrap();
            // The frame sent when the connection came back arrives, then the next one.
            host.send(&frame(250)).unwrap();
            assert_eq!(car.recv(Duration::from_secs(5)).unwrap(), got.map(frame));
            assert_eq!(car.recv(Duration::from_secs(5)).unwrap(), Some(frame(250)));
            assert!(
                host.describe().contains("reopened 1 times"),
                "{}",
                host.describe()
            );
            car
        });
        drop(car);
    }
}
