//! The CAN identifier plan: one standard (11-bit) identifier per message class and direction.
//!
//! Each identifier is a *stream*: one sender, frames in order, one [`Reassembler`] at the
//! receiver. Messages on different identifiers may interleave on the bus frame by frame and are
//! reassembled independently; an error on one stream never touches another.
//!
//! Identifiers are `ID_BASE + 2 · class + direction` (host → car even, car → host odd). Lower
//! identifiers win arbitration, so the classes are numbered by urgency:
//!
//! | id | class | host → car | car → host |
//! |---|---|---|---|
//! | 0x100 / 0x101 | [`Class::Safety`] | reset | action command (or stop) |
//! | 0x102 / 0x103 | [`Class::Heartbeat`] | heartbeat | heartbeat |
//! | 0x104 / 0x105 | [`Class::Observation`] | observation | (unused) |
//! | 0x106 / 0x107 | [`Class::Feedback`] | feedback | ack, nack |
//! | 0x108 / 0x109 | [`Class::Error`] | error report | error report |
//! | 0x10A / 0x10B | [`Class::Config`] | learner configuration, weights request, hello | weights report, welcome |
//!
//! The action command outranks everything else of the protocol because the car must not wait for
//! an observation's 23 frames to say "stop". Identifiers below [`ID_BASE`] stay free for traffic
//! that must win over this protocol (a hardware emergency stop, the motor controller).
//!
//! [`Reassembler`]: crate::isotp::Reassembler
//!
//! ```
//! use protocol::stream::{Class, Direction, Stream};
//! use protocol::message::MessageKind;
//!
//! let s = Stream::for_kind(MessageKind::Action, Direction::CarToHost).unwrap();
//! assert_eq!(s.id().raw(), 0x101);
//! assert_eq!(Stream::from_id(s.id()), Some(s));
//! // The car never sends observations.
//! assert_eq!(Stream::for_kind(MessageKind::Observation, Direction::CarToHost), None);
//! ```

use core::fmt;

use crate::can::CanId;
use crate::message::MessageKind;

/// The first identifier of the plan.
pub const ID_BASE: u16 = 0x100;

/// Number of message classes.
pub const CLASS_COUNT: usize = 6;

const _: () = assert!(
    ID_BASE as usize + 2 * CLASS_COUNT <= 0x800,
    "the plan fits standard identifiers"
);

/// Which way a message travels.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, PartialOrd, Ord)]
#[repr(u8)]
pub enum Direction {
    /// From the host (planner, simulator, teacher's laptop) to the car's controller.
    HostToCar = 0,
    /// From the car's controller to the host.
    CarToHost = 1,
}

impl Direction {
    /// The other direction.
    pub const fn reverse(self) -> Self {
        match self {
            Direction::HostToCar => Direction::CarToHost,
            Direction::CarToHost => Direction::HostToCar,
        }
    }
}

/// A class of messages, in priority order (first = most urgent = lowest identifier).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, PartialOrd, Ord)]
#[repr(u8)]
pub enum Class {
    /// Action commands and stops (car → host), reset (host → car).
    Safety = 0,
    /// Heartbeats, both ways.
    Heartbeat = 1,
    /// Observations (host → car).
    Observation = 2,
    /// Feedback (host → car), acks and nacks (car → host).
    Feedback = 3,
    /// Error reports, both ways.
    Error = 4,
    /// Learner configuration, weights requests and hellos (host → car), weights reports and
    /// welcomes (car → host).
    Config = 5,
}

impl Class {
    /// Every class, in priority order.
    pub const ALL: [Class; CLASS_COUNT] = [
        Class::Safety,
        Class::Heartbeat,
        Class::Observation,
        Class::Feedback,
        Class::Error,
        Class::Config,
    ];

    /// The class of a message kind.
    pub const fn of(kind: MessageKind) -> Self {
        match kind {
            MessageKind::Action | MessageKind::Reset => Class::Safety,
            MessageKind::Heartbeat => Class::Heartbeat,
            MessageKind::Observation => Class::Observation,
            MessageKind::Feedback | MessageKind::Ack | MessageKind::Nack => Class::Feedback,
            MessageKind::Error => Class::Error,
            MessageKind::Configure
            | MessageKind::Weights
            | MessageKind::WeightsRequest
            | MessageKind::Hello
            | MessageKind::Welcome => Class::Config,
        }
    }
}

/// The direction a message kind travels in; `None`: both.
pub const fn direction_of(kind: MessageKind) -> Option<Direction> {
    match kind {
        MessageKind::Observation
        | MessageKind::Feedback
        | MessageKind::Configure
        | MessageKind::WeightsRequest
        | MessageKind::Reset
        | MessageKind::Hello => Some(Direction::HostToCar),
        MessageKind::Action
        | MessageKind::Ack
        | MessageKind::Nack
        | MessageKind::Weights
        | MessageKind::Welcome => Some(Direction::CarToHost),
        MessageKind::Heartbeat | MessageKind::Error => None,
    }
}

/// One CAN identifier of the plan: a class in a direction.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, PartialOrd, Ord)]
pub struct Stream {
    /// The class of the messages on it.
    pub class: Class,
    /// Which way they travel.
    pub direction: Direction,
}

impl Stream {
    /// The stream of `class` in `direction`.
    pub const fn new(class: Class, direction: Direction) -> Self {
        Self { class, direction }
    }

    /// The stream that carries `kind` in `direction`, if `kind` travels that way.
    pub const fn for_kind(kind: MessageKind, direction: Direction) -> Option<Self> {
        match direction_of(kind) {
            Some(d) if d as u8 != direction as u8 => None,
            _ => Some(Self::new(Class::of(kind), direction)),
        }
    }

    /// Its CAN identifier.
    pub const fn id(self) -> CanId {
        CanId::Standard(self.raw_id())
    }

    /// Its 11-bit identifier.
    pub const fn raw_id(self) -> u16 {
        ID_BASE + 2 * self.class as u16 + self.direction as u16
    }

    /// The stream of identifier `id`, if it is one of the plan.
    pub fn from_id(id: CanId) -> Option<Self> {
        let CanId::Standard(raw) = id else {
            return None;
        };
        let offset = raw.checked_sub(ID_BASE)? as usize;
        let class = *Class::ALL.get(offset / 2)?;
        let direction = if offset.is_multiple_of(2) {
            Direction::HostToCar
        } else {
            Direction::CarToHost
        };
        Some(Self::new(class, direction))
    }

    /// Whether a message of `kind` may travel on this stream.
    pub const fn carries(self, kind: MessageKind) -> bool {
        match Self::for_kind(kind, self.direction) {
            Some(s) => s.class as u8 == self.class as u8,
            None => false,
        }
    }

    /// Index of the stream's class, `0..CLASS_COUNT`: where a per-direction table keeps its
    /// state.
    pub const fn index(self) -> usize {
        self.class as usize
    }
}

impl fmt::Display for Stream {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let dir = match self.direction {
            Direction::HostToCar => "host->car",
            Direction::CarToHost => "car->host",
        };
        write!(f, "{:?} {dir} ({})", self.class, self.id())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plan_is_the_documented_table() {
        let table = [
            (Class::Safety, 0x100),
            (Class::Heartbeat, 0x102),
            (Class::Observation, 0x104),
            (Class::Feedback, 0x106),
            (Class::Error, 0x108),
            (Class::Config, 0x10A),
        ];
        for (class, id) in table {
            assert_eq!(
                Stream::new(class, Direction::HostToCar).id(),
                CanId::Standard(id)
            );
            assert_eq!(
                Stream::new(class, Direction::CarToHost).id(),
                CanId::Standard(id + 1)
            );
        }
        // Urgent classes win arbitration.
        let action = Stream::for_kind(MessageKind::Action, Direction::CarToHost).unwrap();
        let obs = Stream::for_kind(MessageKind::Observation, Direction::HostToCar).unwrap();
        let hb = Stream::for_kind(MessageKind::Heartbeat, Direction::HostToCar).unwrap();
        assert!(action.id().raw() < hb.id().raw() && hb.id().raw() < obs.id().raw());
    }

    #[test]
    fn ids_round_trip_and_foreign_ids_are_not_ours() {
        for class in Class::ALL {
            for direction in [Direction::HostToCar, Direction::CarToHost] {
                let s = Stream::new(class, direction);
                assert_eq!(Stream::from_id(s.id()), Some(s));
            }
        }
        assert_eq!(Stream::from_id(CanId::Standard(ID_BASE - 1)), None);
        assert_eq!(Stream::from_id(CanId::Standard(ID_BASE + 12)), None);
        assert_eq!(Stream::from_id(CanId::Standard(0)), None);
        assert_eq!(Stream::from_id(CanId::Extended(ID_BASE as u32)), None);
    }

    #[test]
    fn every_kind_has_exactly_its_streams() {
        for kind in MessageKind::ALL {
            let mut carriers = 0;
            for class in Class::ALL {
                for direction in [Direction::HostToCar, Direction::CarToHost] {
                    if Stream::new(class, direction).carries(kind) {
                        carriers += 1;
                        assert_eq!(class, Class::of(kind));
                    }
                }
            }
            let expected = if direction_of(kind).is_some() { 1 } else { 2 };
            assert_eq!(carriers, expected, "{kind}");
        }
        let ack_stream = Stream::new(Class::Feedback, Direction::CarToHost);
        assert!(ack_stream.carries(MessageKind::Ack) && ack_stream.carries(MessageKind::Nack));
        assert!(!ack_stream.carries(MessageKind::Feedback));
    }
}
