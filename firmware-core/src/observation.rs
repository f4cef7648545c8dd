//! What the car observes in one tick: a downsampled range scan, detected semantic objects, the
//! path reference and its speed. Fixed capacity, validated before use.
//!
//! # Frames and units
//!
//! Everything is in the **car frame**: origin at the rear-axle midpoint (the point the lattice's
//! trajectories describe, and where the range sensor sits), `x` forward, `y` to the left, angles
//! counter-clockwise from `x`, in radians. Lengths are metres, speeds metres per second.
//!
//! # The scan
//!
//! [`SCAN_BEAMS`] ranges over the full circle; beam `j` looks along
//! `bearing(j) = −π + (j + ½)·2π/SCAN_BEAMS`, so the beams are symmetric about the car's axis
//! (beam `j` mirrors beam `SCAN_BEAMS − 1 − j`) and none points exactly ahead or behind. A beam
//! without a return reads [`SCAN_MAX_RANGE`].
//!
//! # Semantic objects
//!
//! Up to [`MAX_OBJECTS`] detected doors, stairs or chairs, each a disc: centre and radius. The
//! distance from a point to an object is the distance to its disc (0 inside).
//!
//! # Validation
//!
//! [`Observation::check`] rejects NaN, infinities and values outside the documented ranges with
//! an [`ObservationError`] naming the field, and returns a [`ValidObservation`]: the only input
//! the evaluator takes, so an observation is validated once, where it enters (the agent's
//! [`act`](crate::agent::Agent::act), the host's teacher), and never again.
//!
//! ```
//! use firmware_core::observation::{Observation, SemanticClass, SemanticObject};
//!
//! let mut obs = Observation::open_space();
//! obs.objects.push(SemanticObject { class: SemanticClass::Door, x: 1.0, y: 0.8, radius: 0.45 }).unwrap();
//! let valid = obs.check().unwrap();
//! assert_eq!(valid.objects.len(), 1); // reads like the observation it wraps
//! obs.scan.ranges[3] = f32::NAN;
//! assert!(obs.check().is_err());
//! ```

use core::f32::consts::PI;
use core::fmt;

use serde::de::{self, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::feature::Feature;

pub use crate::lattice::SCAN_BEAMS;

/// Largest range a beam may report (metres); also the reading of a beam without a return.
pub const SCAN_MAX_RANGE: f32 = 10.0;

/// Largest number of semantic objects in one observation.
pub const MAX_OBJECTS: usize = 8;

/// Objects farther than this from the car (metres, either coordinate) are out of range.
pub const OBJECT_COORDINATE_BOUND: f32 = 20.0;

/// Largest object radius (metres).
pub const MAX_OBJECT_RADIUS: f32 = 5.0;

/// The path reference must lie within this distance of the car (metres, either coordinate).
pub const REFERENCE_COORDINATE_BOUND: f32 = 5.0;

/// Largest speed magnitude (m/s).
pub const MAX_SPEED: f32 = 10.0;

/// The bearing of beam `j` (radians, counter-clockwise from the car's `x` axis), in `(−π, π)`.
#[inline]
pub fn beam_bearing(j: usize) -> f32 {
    -PI + (j as f32 + 0.5) * (2.0 * PI / SCAN_BEAMS as f32)
}

/// The downsampled range scan: one range per beam, metres.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Scan {
    /// Range of each beam; [`SCAN_MAX_RANGE`] when there is no return.
    pub ranges: [f32; SCAN_BEAMS],
}

impl Scan {
    /// A scan that sees nothing (every beam at [`SCAN_MAX_RANGE`]).
    pub const EMPTY: Self = Self {
        ranges: [SCAN_MAX_RANGE; SCAN_BEAMS],
    };
}

impl Default for Scan {
    fn default() -> Self {
        Self::EMPTY
    }
}

// serde implements arrays only up to 32 elements: the scan is written as a fixed-length tuple
// (postcard: 64 little-endian f32s, no length prefix).
impl Serialize for Scan {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut t = serializer.serialize_tuple(SCAN_BEAMS)?;
        for r in &self.ranges {
            t.serialize_element(r)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Scan {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct ScanVisitor;
        impl<'de> Visitor<'de> for ScanVisitor {
            type Value = Scan;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{SCAN_BEAMS} ranges")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Scan, A::Error> {
                let mut ranges = [0.0f32; SCAN_BEAMS];
                for (i, r) in ranges.iter_mut().enumerate() {
                    *r = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                Ok(Scan { ranges })
            }
        }
        deserializer.deserialize_tuple(SCAN_BEAMS, ScanVisitor)
    }
}

#[cfg(feature = "max-size")]
impl postcard::experimental::max_size::MaxSize for Scan {
    const POSTCARD_MAX_SIZE: usize = SCAN_BEAMS * 4;
}

/// A class of semantic object the teacher may care about.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
#[repr(u8)]
pub enum SemanticClass {
    /// A door: people may step out of it.
    Door = 0,
    /// A staircase: a fall hazard.
    Stairs = 1,
    /// A chair: people sit and stand up.
    Chair = 2,
}

impl SemanticClass {
    /// All classes.
    pub const ALL: [SemanticClass; 3] = [
        SemanticClass::Door,
        SemanticClass::Stairs,
        SemanticClass::Chair,
    ];

    /// The feature holding the clearance to this class.
    pub const fn feature(self) -> Feature {
        match self {
            SemanticClass::Door => Feature::Door,
            SemanticClass::Stairs => Feature::Stairs,
            SemanticClass::Chair => Feature::Chair,
        }
    }

    /// A short lower-case name.
    pub const fn name(self) -> &'static str {
        match self {
            SemanticClass::Door => "door",
            SemanticClass::Stairs => "stairs",
            SemanticClass::Chair => "chair",
        }
    }

    /// The class named `name` (see [`SemanticClass::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == name)
    }
}

impl fmt::Display for SemanticClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A detected semantic object: a disc in the car frame.
#[derive(Clone, Copy, PartialEq, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct SemanticObject {
    /// What it is.
    pub class: SemanticClass,
    /// Centre, forward (m).
    pub x: f32,
    /// Centre, left (m).
    pub y: f32,
    /// Radius (m), in `(0, MAX_OBJECT_RADIUS]`.
    pub radius: f32,
}

/// The path point about 1 m ahead of the car, and the path's heading there, in the car frame.
#[derive(Clone, Copy, PartialEq, Debug, Default, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct PathReference {
    /// Forward (m).
    pub x: f32,
    /// Left (m).
    pub y: f32,
    /// Heading of the path at the point (rad, in `[−π, π]`).
    pub heading: f32,
}

/// The detected objects: at most [`MAX_OBJECTS`]; `push` hands an object back when full.
pub type ObjectList = heapless::Vec<SemanticObject, MAX_OBJECTS>;

/// Everything the car observes in one tick.
#[derive(Clone, PartialEq, Debug, Default, Serialize, Deserialize)]
pub struct Observation {
    /// The downsampled range scan.
    pub scan: Scan,
    /// Detected semantic objects within sensor range and line of sight.
    pub objects: ObjectList,
    /// The path reference.
    pub reference: PathReference,
    /// The car's forward speed (m/s).
    pub speed: f32,
}

#[cfg(feature = "max-size")]
impl postcard::experimental::max_size::MaxSize for Observation {
    // The object list is a postcard sequence: a varint length (one byte up to 127) and the items.
    const POSTCARD_MAX_SIZE: usize = Scan::POSTCARD_MAX_SIZE
        + 1
        + MAX_OBJECTS * SemanticObject::POSTCARD_MAX_SIZE
        + PathReference::POSTCARD_MAX_SIZE
        + f32::POSTCARD_MAX_SIZE;
}

#[cfg(feature = "max-size")]
const _: () = assert!(
    MAX_OBJECTS <= 127,
    "the list length stays a one-byte varint"
);

/// Which field of an observation failed validation.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[non_exhaustive]
pub enum ObservationError {
    /// A scan range is NaN, infinite, negative or above [`SCAN_MAX_RANGE`].
    ScanRange {
        /// The beam.
        beam: u8,
    },
    /// An object's centre is not finite or beyond [`OBJECT_COORDINATE_BOUND`].
    ObjectPosition {
        /// The object's position in the list.
        index: u8,
    },
    /// An object's radius is not finite, not positive, or above [`MAX_OBJECT_RADIUS`].
    ObjectRadius {
        /// The object's position in the list.
        index: u8,
    },
    /// The path reference is not finite, beyond [`REFERENCE_COORDINATE_BOUND`], or its heading
    /// is outside `[−π, π]`.
    Reference,
    /// The speed is not finite or beyond [`MAX_SPEED`].
    Speed,
}

impl fmt::Display for ObservationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ObservationError::ScanRange { beam } => {
                write!(
                    f,
                    "scan range of beam {beam} is not in [0, {SCAN_MAX_RANGE}] m"
                )
            }
            ObservationError::ObjectPosition { index } => write!(
                f,
                "object {index}: centre not finite or beyond {OBJECT_COORDINATE_BOUND} m"
            ),
            ObservationError::ObjectRadius { index } => {
                write!(
                    f,
                    "object {index}: radius not in (0, {MAX_OBJECT_RADIUS}] m"
                )
            }
            ObservationError::Reference => write!(
                f,
                "path reference not finite, beyond {REFERENCE_COORDINATE_BOUND} m, or heading outside [-pi, pi]"
            ),
            ObservationError::Speed => write!(f, "speed not finite or beyond {MAX_SPEED} m/s"),
        }
    }
}

impl core::error::Error for ObservationError {}

/// `x` is finite and within `bound` of 0: a NaN or an infinity is never within a finite bound,
/// so the comparison alone decides (an `is_finite` test is four more instructions a number on
/// the car).
fn within(x: f32, bound: f32) -> bool {
    x.abs() <= bound
}

const _: () = assert!(
    SCAN_MAX_RANGE.is_finite()
        && OBJECT_COORDINATE_BOUND.is_finite()
        && MAX_OBJECT_RADIUS.is_finite()
        && REFERENCE_COORDINATE_BOUND.is_finite()
        && MAX_SPEED.is_finite(),
    "the checks' bounds are finite: a number within one is finite"
);

impl Observation {
    /// Nothing in sight, the path straight ahead 1 m away, standing still.
    pub fn open_space() -> Self {
        Self {
            scan: Scan::EMPTY,
            objects: ObjectList::new(),
            reference: PathReference {
                x: 1.0,
                y: 0.0,
                heading: 0.0,
            },
            speed: 0.0,
        }
    }

    /// Checks every number against its documented range, and vouches for it with a
    /// [`ValidObservation`].
    pub fn check(&self) -> Result<ValidObservation<'_>, ObservationError> {
        self.validate()?;
        Ok(ValidObservation(self))
    }

    /// Checks every number against its documented range ([`Observation::check`] without the
    /// wrapper).
    pub fn validate(&self) -> Result<(), ObservationError> {
        // Every range's bits at most the maximum's, as a `u32`: exactly the ranges +0 … the
        // maximum (a negative number's sign bit, NaN's and the infinities' exponent put theirs
        // above), four at a time with a branch each and no float comparison. Otherwise the
        // comparisons one by one tell, which accept −0 too and name the first range out.
        let max = SCAN_MAX_RANGE.to_bits();
        let quick = self.scan.ranges.as_chunks::<4>().0.iter().all(|r| {
            r[0].to_bits() <= max
                && r[1].to_bits() <= max
                && r[2].to_bits() <= max
                && r[3].to_bits() <= max
        });
        if !quick {
            for (j, &r) in self.scan.ranges.iter().enumerate() {
                // False for NaN and the infinities too (the range's ends are finite).
                if !(0.0..=SCAN_MAX_RANGE).contains(&r) {
                    return Err(ObservationError::ScanRange { beam: j as u8 });
                }
            }
        }
        for (i, o) in self.objects.iter().enumerate() {
            let index = i as u8;
            if !(within(o.x, OBJECT_COORDINATE_BOUND) && within(o.y, OBJECT_COORDINATE_BOUND)) {
                return Err(ObservationError::ObjectPosition { index });
            }
            if !(o.radius > 0.0 && o.radius <= MAX_OBJECT_RADIUS) {
                return Err(ObservationError::ObjectRadius { index });
            }
        }
        let p = &self.reference;
        if !(within(p.x, REFERENCE_COORDINATE_BOUND)
            && within(p.y, REFERENCE_COORDINATE_BOUND)
            && within(p.heading, PI))
        {
            return Err(ObservationError::Reference);
        }
        if !within(self.speed, MAX_SPEED) {
            return Err(ObservationError::Speed);
        }
        Ok(())
    }

    /// The observation seen in a mirror along the car's axis: beam `j` swaps with beam
    /// `SCAN_BEAMS − 1 − j`, every `y` and heading changes sign.
    pub fn mirrored(&self) -> Self {
        let mut out = self.clone();
        for j in 0..SCAN_BEAMS {
            out.scan.ranges[j] = self.scan.ranges[SCAN_BEAMS - 1 - j];
        }
        for o in out.objects.iter_mut() {
            o.y = -o.y;
        }
        out.reference.y = -out.reference.y;
        out.reference.heading = -out.reference.heading;
        out
    }
}

/// An observation whose every number is within its documented range: made only by
/// [`Observation::check`], taken by the [`Evaluator`](crate::evaluator::Evaluator), so that an
/// observation is validated once. It reads like the observation it wraps (`Deref`).
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct ValidObservation<'a>(&'a Observation);

impl<'a> ValidObservation<'a> {
    /// The observation.
    #[inline]
    pub const fn get(self) -> &'a Observation {
        self.0
    }
}

impl core::ops::Deref for ValidObservation<'_> {
    type Target = Observation;
    #[inline]
    fn deref(&self) -> &Observation {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bearings_are_symmetric() {
        for j in 0..SCAN_BEAMS {
            let (a, b) = (beam_bearing(j), beam_bearing(SCAN_BEAMS - 1 - j));
            assert!((a + b).abs() < 1e-6, "{j}: {a} {b}");
            assert!(a > -PI && a < PI);
        }
    }

    #[test]
    fn each_field_is_validated() {
        let good = Observation::open_space();
        assert_eq!(good.validate(), Ok(()));
        assert_eq!(good.check().map(ValidObservation::get), Ok(&good));
        let mut o = good.clone();
        o.scan.ranges[9] = -0.1;
        assert_eq!(o.validate(), Err(ObservationError::ScanRange { beam: 9 }));
        let mut o = good.clone();
        o.scan.ranges[0] = f32::INFINITY;
        assert_eq!(o.validate(), Err(ObservationError::ScanRange { beam: 0 }));
        let mut o = good.clone();
        o.objects
            .push(SemanticObject {
                class: SemanticClass::Chair,
                x: 1.0,
                y: f32::NAN,
                radius: 0.3,
            })
            .unwrap();
        assert_eq!(
            o.validate(),
            Err(ObservationError::ObjectPosition { index: 0 })
        );
        let mut o = good.clone();
        o.objects
            .push(SemanticObject {
                class: SemanticClass::Chair,
                x: 1.0,
                y: 0.0,
                radius: 0.0,
            })
            .unwrap();
        assert_eq!(
            o.validate(),
            Err(ObservationError::ObjectRadius { index: 0 })
        );
        let mut o = good.clone();
        o.reference.heading = 4.0;
        assert_eq!(o.validate(), Err(ObservationError::Reference));
        let mut o = good.clone();
        o.speed = f32::NAN;
        assert_eq!(o.validate(), Err(ObservationError::Speed));
    }

    /// The quick test on the bits and the comparisons one by one: the same verdict and the same
    /// first beam named, on the values at and around the ends (both zeros included).
    #[test]
    fn the_ranges_are_validated_as_their_comparisons_say() {
        let max = SCAN_MAX_RANGE;
        let values = [
            0.0,
            -0.0,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MIN_POSITIVE,
            1.0,
            max,
            f32::from_bits(max.to_bits() + 1),
            f32::from_bits(max.to_bits() - 1),
            -max,
            -1.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            f32::MAX,
        ];
        let mut state = 0x853c_49e6_748f_ea9bu64;
        for case in 0..20_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let mut o = Observation::open_space();
            let (a, b) = ((state % 64) as usize, ((state >> 8) % 64) as usize);
            o.scan.ranges[a] = values[(state >> 16) as usize % values.len()];
            o.scan.ranges[b] = values[(state >> 24) as usize % values.len()];
            if case % 3 == 0 {
                o.scan.ranges[(state >> 32) as usize % 64] = -0.0;
            }
            let want = o
                .scan
                .ranges
                .iter()
                .position(|r| !(0.0..=max).contains(r))
                .map(|j| ObservationError::ScanRange { beam: j as u8 });
            assert_eq!(o.validate().err(), want, "{:?}", o.scan.ranges);
        }
    }

    /// Every number of an observation, set to a NaN or an infinity of either sign, is refused
    /// with its field's error: the checks compare with finite bounds and test no `is_finite`, so
    /// this is what says a non-finite number never passes them.
    #[test]
    fn every_non_finite_number_is_refused_by_its_field() {
        let mut good = Observation::open_space();
        good.objects
            .push(SemanticObject {
                class: SemanticClass::Door,
                x: 1.0,
                y: -1.0,
                radius: 0.4,
            })
            .unwrap();
        assert_eq!(good.validate(), Ok(()));
        type Field = (fn(&mut Observation) -> &mut f32, ObservationError);
        let fields: [Field; 9] = [
            (
                |o| &mut o.scan.ranges[0],
                ObservationError::ScanRange { beam: 0 },
            ),
            (
                |o| &mut o.scan.ranges[63],
                ObservationError::ScanRange { beam: 63 },
            ),
            (
                |o| &mut o.objects[0].x,
                ObservationError::ObjectPosition { index: 0 },
            ),
            (
                |o| &mut o.objects[0].y,
                ObservationError::ObjectPosition { index: 0 },
            ),
            (
                |o| &mut o.objects[0].radius,
                ObservationError::ObjectRadius { index: 0 },
            ),
            (|o| &mut o.reference.x, ObservationError::Reference),
            (|o| &mut o.reference.y, ObservationError::Reference),
            (|o| &mut o.reference.heading, ObservationError::Reference),
            (|o| &mut o.speed, ObservationError::Speed),
        ];
        for (field, error) in fields {
            for bad in [f32::NAN, -f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                let mut o = good.clone();
                *field(&mut o) = bad;
                assert_eq!(o.validate(), Err(error), "{bad} in {o:?}");
                assert!(o.check().is_err());
            }
        }
    }

    #[test]
    fn a_full_object_list_hands_the_object_back() {
        let mut o = Observation::open_space();
        let obj = SemanticObject {
            class: SemanticClass::Door,
            x: 1.0,
            y: 1.0,
            radius: 0.4,
        };
        for _ in 0..MAX_OBJECTS {
            o.objects.push(obj).unwrap();
        }
        assert_eq!(o.objects.push(obj), Err(obj));
    }

    #[test]
    fn postcard_round_trip_and_overlong_lists_fail() {
        let mut o = Observation::open_space();
        o.scan.ranges[5] = 1.25;
        o.objects
            .push(SemanticObject {
                class: SemanticClass::Stairs,
                x: 2.0,
                y: -1.0,
                radius: 1.0,
            })
            .unwrap();
        let bytes = postcard::to_allocvec(&o).unwrap();
        assert_eq!(postcard::from_bytes::<Observation>(&bytes).unwrap(), o);
        // A list length of 9 objects must be refused, not overflow.
        let mut bad = bytes.clone();
        bad[SCAN_BEAMS * 4] = 9;
        assert!(postcard::from_bytes::<Observation>(&bad).is_err());
    }
}
