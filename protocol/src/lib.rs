//! # protocol: the wire between the host and the car
//!
//! `no_std`, no heap, no `unsafe` (DESIGN section 7). Every buffer is a fixed array whose size is
//! a compile-time constant checked against the largest message.
//!
//! ```text
//!  Message ──seal──▶ secured PDU [version | postcard | freshness | MAC] ──Segmenter──▶ CAN frames
//!                                                                                    │ bus, id per stream
//!  Message ◀─open─── MAC, freshness, decode ◀────── Reassembler (one per stream) ◀───┘
//! ```
//!
//! * [`message`]: the messages (observation, action command, feedback, ack/nack, heartbeat,
//!   weights report, configuration, reset, error, weights request, hello, welcome), their maximum
//!   sizes, total decoding.
//! * [`quantize`]: the observation's fixed-point wire form and [`quantize::quantize`], the one
//!   function every observation passes through before a learner sees it.
//! * [`secure`]: authenticated PDUs (AES-128-CMAC, freshness counters, replay window), the
//!   car's and the host's [`secure::Endpoint`]s and their hello/welcome handshake.
//! * [`envelope`]: the versioned, CRC-checked postcard envelope (the storage form) and its
//!   checked view.
//! * [`can`]: checked CAN / CAN FD frames and the [`can::CanBus`] trait transports implement.
//! * [`slcan`]: the Lawicel serial-line CAN codec (the car's UART speaks it).
//! * [`stream`]: the CAN identifier plan, one identifier per message class and direction.
//! * [`isotp`]: ISO-TP-style segmentation and fixed-buffer reassembly for classic CAN and CAN FD.
//! * [`link`]: the two glued together: [`link::transmit`] and the per-stream [`link::Inbox`].
//! * [`delivery`]: acknowledged feedback: retransmission with bounded retries, dedupe windows
//!   per session.
//! * [`budget`]: bits on the wire per frame, message and control tick; bus load.
//! * [`car`]: the car's node ([`car::CarNode`]): the agent behind the authenticated link,
//!   sessions that bind feedback, exactly-once feedback persisted before its ack, the watchdog
//!   and the safe state; shared by `hil_mock` and the firmware.
//!
//! Decoding is total: any byte sequence gives a value or an error, never a panic (fuzzed in
//! `fuzz/`). Nothing a message asks for happens before its MAC and freshness are checked. The
//! wire format and the threat model are in `docs/protocol.md`.
//!
//! One tick, end to end:
//!
//! ```
//! use firmware_core::{ActionFeedback, ActionIndex, Feedback};
//! use firmware_core::observation::Observation;
//! use protocol::isotp::{FeedResult, FrameMode, Reassembler, Segmenter};
//! use protocol::message::{Message, ObservationMessage, MAX_MESSAGE_SIZE};
//! use protocol::secure::{CarSecurity, Endpoint, HostSecurity, Key};
//! use protocol::stream::{Direction, Stream};
//!
//! let key = Key::new([7; 16]);
//! let (mut host, mut car) = (HostSecurity::assume_fresh_car(&key, 1), CarSecurity::new(&key, 1));
//! let msg = Message::Observation(ObservationMessage { tick: 7, observation: Observation::open_space() });
//! let stream = Stream::for_kind(msg.kind(), Direction::HostToCar).unwrap();
//! let mut buf = [0u8; MAX_MESSAGE_SIZE];
//! let bytes = host.seal(&msg, stream, &mut buf).unwrap();
//! let mut rx: Reassembler = Reassembler::new();
//! let mut frames = 0;
//! for frame in Segmenter::new(stream.id(), bytes, FrameMode::Classic).unwrap() {
//!     frames += 1;
//!     if let FeedResult::Complete(b) = rx.feed(&frame, 0) {
//!         assert_eq!(car.open(stream, b).unwrap(), msg);
//!     }
//! }
//! assert_eq!(frames, 14); // 97 bytes: a first frame (6 bytes) and 13 consecutive frames (7 each)
//! ```

#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod budget;
pub mod can;
pub mod car;
pub mod delivery;
pub mod envelope;
pub mod isotp;
pub mod link;
pub mod message;
pub mod quantize;
pub mod secure;
pub mod slcan;
pub mod stream;

pub use envelope::{ENVELOPE_OVERHEAD, EnvelopeError, PROTOCOL_VERSION, open, seal};
pub use message::{DecodeError, MAX_MESSAGE_SIZE, Message, MessageKind};
