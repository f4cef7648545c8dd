//! Two connected in-process link ends, for tests: what one sends, the other receives, in order.

use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::time::Duration;

use protocol::can::CanFrame;

use super::{Link, LinkError};

/// One end of an in-memory link.
#[derive(Debug)]
pub struct MemoryLink {
    tx: Sender<CanFrame>,
    rx: Receiver<CanFrame>,
    name: &'static str,
}

impl MemoryLink {
    /// Two connected ends.
    pub fn pair() -> (MemoryLink, MemoryLink) {
        let (a_tx, b_rx) = channel();
        let (b_tx, a_rx) = channel();
        (
            MemoryLink {
                tx: a_tx,
                rx: a_rx,
                name: "a",
            },
            MemoryLink {
                tx: b_tx,
                rx: b_rx,
                name: "b",
            },
        )
    }
}

impl Link for MemoryLink {
    fn send(&mut self, frame: &CanFrame) -> Result<(), LinkError> {
        self.tx
            .send(*frame)
            .map_err(|_| LinkError::Closed("the other end was dropped".into()))
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, LinkError> {
        match self.rx.recv_timeout(timeout) {
            Ok(f) => Ok(Some(f)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => {
                Err(LinkError::Closed("the other end was dropped".into()))
            }
        }
    }

    fn describe(&self) -> String {
        format!("memory ({})", self.name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::can::CanId;

    #[test]
    fn frames_cross_in_order() {
        let (mut a, mut b) = MemoryLink::pair();
        let id = CanId::standard(0x10).unwrap();
        for i in 0..5u8 {
            a.send(&CanFrame::new(id, &[i]).unwrap()).unwrap();
        }
        for i in 0..5u8 {
            assert_eq!(b.recv(Duration::ZERO).unwrap().unwrap().data(), &[i]);
        }
        assert_eq!(b.recv(Duration::from_millis(1)).unwrap(), None);
        drop(a);
        assert!(matches!(b.recv(Duration::ZERO), Err(LinkError::Closed(_))));
    }
}
