//! Linux SocketCAN, through the `socketcan` crate (cargo feature `socketcan`).
//!
//! Opens a raw CAN FD socket on an interface (`can0`, `vcan0`, a `slcand`-attached adapter);
//! classic and FD frames both pass. Runs only where the kernel has CAN support: on a machine
//! without it, opening fails with the OS's error.

use std::time::Duration;

use protocol::can::{CanFrame, CanId};
use socketcan::{
    CanAnyFrame, CanDataFrame, CanFdFrame, CanFdSocket, EmbeddedFrame, ExtendedId, Id, ShouldRetry,
    Socket, StandardId,
};

use super::{Link, LinkError};

/// A SocketCAN interface.
#[derive(Debug)]
pub struct SocketCanLink {
    socket: CanFdSocket,
    iface: String,
}

/// Our frame as a SocketCAN frame.
pub fn to_socketcan(frame: &CanFrame) -> Option<CanAnyFrame> {
    let id: Id = match frame.id() {
        CanId::Standard(id) => StandardId::new(id)?.into(),
        CanId::Extended(id) => ExtendedId::new(id)?.into(),
    };
    if frame.is_fd() {
        let mut f = CanFdFrame::new(id, frame.data())?;
        f.set_brs(true);
        Some(CanAnyFrame::Fd(f))
    } else {
        Some(CanAnyFrame::Normal(CanDataFrame::new(id, frame.data())?))
    }
}

/// A SocketCAN data frame as ours; `None` for remote and error frames.
pub fn from_socketcan(frame: &CanAnyFrame) -> Option<CanFrame> {
    let convert = |id: Id| match id {
        Id::Standard(s) => CanId::standard(s.as_raw()),
        Id::Extended(e) => CanId::extended(e.as_raw()),
    };
    match frame {
        CanAnyFrame::Normal(f) => CanFrame::new(convert(f.id())?, f.data()).ok(),
        CanAnyFrame::Fd(f) => CanFrame::new_fd(convert(f.id())?, f.data()).ok(),
        CanAnyFrame::Remote(_) | CanAnyFrame::Error(_) => None,
    }
}

impl SocketCanLink {
    /// Opens `iface` in CAN FD mode.
    pub fn open(iface: &str) -> Result<Self, LinkError> {
        let socket = CanFdSocket::open(iface)
            .map_err(|e| LinkError::io(format!("open SocketCAN interface {iface}"), e))?;
        Ok(Self {
            socket,
            iface: iface.to_string(),
        })
    }
}

impl Link for SocketCanLink {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        let f = to_socketcan(frame).ok_or_else(|| {
            LinkError::malformed("socketcan", format!("cannot convert {frame:?}"))
        })?;
        self.socket
            .write_frame_insist(&f)
            .map_err(|e| LinkError::io(format!("{} write", self.iface), e))
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        match self
            .socket
            .read_frame_timeout(timeout.max(Duration::from_micros(1)))
        {
            Ok(f) => Ok(from_socketcan(&f)),
            Err(e) if e.should_retry() || e.kind() == std::io::ErrorKind::TimedOut => Ok(None),
            Err(e) => Err(LinkError::io(format!("{} read", self.iface), e)),
        }
    }

    fn describe(&self) -> String {
        format!("socketcan {}", self.iface)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_convert_both_ways() {
        for f in [
            CanFrame::new(CanId::standard(0x7FF).unwrap(), &[1, 2, 3]).unwrap(),
            CanFrame::new(CanId::extended(0x1FFF_FFFF).unwrap(), &[]).unwrap(),
            CanFrame::new_fd(CanId::standard(0x10).unwrap(), &[9; 64]).unwrap(),
        ] {
            assert_eq!(from_socketcan(&to_socketcan(&f).unwrap()), Some(f));
        }
    }

    /// Runs where a `vcan0` interface exists (`ip link add vcan0 type vcan && ip link set up
    /// vcan0`); elsewhere, such as on a kernel without CAN, it says why it skipped.
    #[test]
    fn vcan0_loopback_if_present() {
        let (mut a, mut b) = match (SocketCanLink::open("vcan0"), SocketCanLink::open("vcan0")) {
            (Ok(a), Ok(b)) => (a, b),
            (Err(e), _) | (_, Err(e)) => {
                eprintln!("skipped: no usable vcan0 on this machine ({e})");
                return;
            }
        };
        let f = CanFrame::new(CanId::standard(0x123).unwrap(), &[0xAB]).unwrap();
        a.send(&f).unwrap();
        assert_eq!(b.recv(Duration::from_secs(1)).unwrap(), Some(f));
    }
}
