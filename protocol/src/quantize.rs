//! The observation as it travels: fixed-point numbers, so that a tick fits in 5% of a classic CAN
//! bus (DESIGN section 7), and [`quantize`], the one function through which every observation
//! passes before any learner sees it, in process or over the link.
//!
//! | field | on the wire | step (largest rounding error) | representable |
//! |---|---|---|---|
//! | scan range | 10 bits, centimetres, 64 packed into 80 bytes | 1 cm (5 mm) | 0 – 10.23 m |
//! | object centre `x`, `y` | `i16`, millimetres | 1 mm (0.5 mm) | ±32.767 m |
//! | object radius | `u16`, millimetres, at least 1 | 1 mm (0.5 mm) | 0.001 – 65.535 m |
//! | path reference `x`, `y` | `i16`, millimetres | 1 mm (0.5 mm) | ±32.767 m |
//! | path heading | `i16`, 10⁻⁴ rad, within ±31 415 | 10⁻⁴ rad (5·10⁻⁵ rad) | ±3.2767 rad |
//! | speed | `i16`, mm/s | 1 mm/s (0.5 mm/s) | ±32.767 m/s |
//!
//! Every fixed-size integer is written little-endian in as many bytes as its width (not as a
//! varint). Values are rounded half away from zero, so the mirrored observation quantizes to the
//! mirror of the quantized one.
//!
//! # Valid stays valid, invalid stays invalid
//!
//! [`quantize`] is total and never makes an invalid observation valid or a valid one invalid
//! ([`Observation::validate`] gives the same verdict before and after):
//!
//! * a value within its documented bound rounds to the nearest step, which is within the bound
//!   too (a heading of ±π becomes ±3.1415, a radius below half a millimetre becomes 1 mm);
//! * a value that is out of its bound, infinite or NaN becomes a code out of every bound (range
//!   10.23 m, coordinate or speed 32.767, heading 3.2767 rad, radius 0), which the car refuses
//!   as it would have refused the original.
//!
//! `quantize` is idempotent (the decoded numbers encode to the same codes, checked for every
//! code), so the observation a host quantizes, sends and the car decodes is the one the host
//! has: a run with the learner in process and one over the link see the same numbers, bit for
//! bit.
//!
//! ```
//! use firmware_core::observation::Observation;
//! use protocol::quantize::quantize;
//!
//! let mut obs = Observation::open_space();
//! obs.scan.ranges[3] = 1.23456;
//! obs.speed = 0.9876;
//! let q = quantize(&obs);
//! assert_eq!((q.scan.ranges[3], q.speed), (1.23, 0.988));
//! assert_eq!(quantize(&q), q);
//! ```

use core::f32::consts::PI;
use core::fmt;

use firmware_core::observation::{
    MAX_OBJECT_RADIUS, MAX_OBJECTS, MAX_SPEED, OBJECT_COORDINATE_BOUND, ObjectList, Observation,
    PathReference, REFERENCE_COORDINATE_BOUND, SCAN_BEAMS, SCAN_MAX_RANGE, Scan, SemanticClass,
    SemanticObject,
};
use postcard::experimental::max_size::MaxSize;
use serde::de::{self, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Bits of one scan range on the wire.
pub const RANGE_BITS: u32 = 10;

/// Scan ranges per metre on the wire (centimetres).
pub const RANGE_STEPS_PER_METRE: f32 = 100.0;

/// The range code of an invalid range: 10.23 m, beyond [`SCAN_MAX_RANGE`].
const RANGE_INVALID: u16 = (1 << RANGE_BITS) - 1;

/// Bytes of the packed scan.
pub const PACKED_SCAN_BYTES: usize = (SCAN_BEAMS * RANGE_BITS as usize).div_ceil(8);

/// Millimetres per metre.
const MM: f32 = 1000.0;

/// Heading steps per radian.
const HEADING_STEPS: f32 = 10_000.0;

/// The largest heading code: 3.1415 rad, the last step within π.
const HEADING_MAX: i16 = 31_415;

/// The code of an out-of-bound signed quantity (32.767 m, m/s or 3.2767 rad): beyond every
/// bound.
const SIGNED_INVALID: i16 = i16::MAX;

const _: () = assert!(
    SCAN_MAX_RANGE * RANGE_STEPS_PER_METRE < RANGE_INVALID as f32,
    "the invalid range code is beyond the largest range"
);
const _: () = assert!(
    OBJECT_COORDINATE_BOUND * MM < SIGNED_INVALID as f32,
    "object coordinates fit an i16 with room for an invalid code"
);
const _: () = assert!(
    REFERENCE_COORDINATE_BOUND * MM < SIGNED_INVALID as f32,
    "reference coordinates fit an i16 with room for an invalid code"
);
const _: () = assert!(
    MAX_SPEED * MM < SIGNED_INVALID as f32,
    "speeds fit an i16 with room for an invalid code"
);
const _: () = assert!(MAX_OBJECT_RADIUS * MM < u16::MAX as f32, "radii fit a u16");
const _: () = assert!(
    (HEADING_MAX as f32) / HEADING_STEPS <= PI && PI * HEADING_STEPS < SIGNED_INVALID as f32,
    "the heading codes cover [-π, π] and an invalid code lies beyond"
);
const _: () = assert!(PACKED_SCAN_BYTES == 80);

/// Rounds half away from zero (no `libm` needed; exact for the magnitudes used here, below 2²²).
fn round(x: f32) -> i32 {
    if x >= 0.0 {
        (x + 0.5) as i32
    } else {
        (x - 0.5) as i32
    }
}

fn within(x: f32, bound: f32) -> bool {
    x.is_finite() && x.abs() <= bound
}

/// A valid range (`0 ≤ r ≤ SCAN_MAX_RANGE`, which NaN and the infinities are not) rounded half up
/// to its centimetre (it is not negative: `round` for such numbers), anything else the invalid
/// code. One comparison and a select, no branch: [`quantize`] runs it on 64 ranges a tick.
fn range_code(r: f32) -> u16 {
    if (0.0..=SCAN_MAX_RANGE).contains(&r) {
        (r * RANGE_STEPS_PER_METRE + 0.5) as u16
    } else {
        RANGE_INVALID
    }
}

fn range_value(code: u16) -> f32 {
    code as f32 / RANGE_STEPS_PER_METRE
}

/// Millimetres of a signed length within `bound` metres.
fn mm_code(x: f32, bound: f32) -> i16 {
    if within(x, bound) {
        round(x * MM) as i16
    } else {
        SIGNED_INVALID
    }
}

fn mm_value(code: i16) -> f32 {
    code as f32 / MM
}

fn radius_code(r: f32) -> u16 {
    if within(r, MAX_OBJECT_RADIUS) && r > 0.0 {
        round(r * MM).max(1) as u16
    } else {
        0
    }
}

fn radius_value(code: u16) -> f32 {
    code as f32 / MM
}

fn heading_code(h: f32) -> i16 {
    if within(h, PI) {
        round(h * HEADING_STEPS).clamp(-(HEADING_MAX as i32), HEADING_MAX as i32) as i16
    } else {
        SIGNED_INVALID
    }
}

fn heading_value(code: i16) -> f32 {
    code as f32 / HEADING_STEPS
}

/// The observation a learner sees: every number rounded to its wire step (see the module
/// documentation). Total, idempotent, and it keeps the verdict of [`Observation::validate`].
///
/// Each number goes through its code and back (`value(code(x))`) without the wire form in
/// between: the codes fit their packed fields (a range code is at most 1023, 10 bits), so packing
/// and unpacking them loses nothing and this is `WireObservation::encode(obs).decode()`, bit for
/// bit (`quantize_is_the_wire_round_trip` checks it), at a fraction of the cost.
pub fn quantize(obs: &Observation) -> Observation {
    let mut scan = Scan::EMPTY;
    for (q, &r) in scan.ranges.iter_mut().zip(&obs.scan.ranges) {
        *q = range_value(range_code(r));
    }
    quantize_but_scan(Observation {
        scan,
        objects: obs.objects.clone(),
        reference: obs.reference,
        speed: obs.speed,
    })
}

/// The scan range `r` (m) as [`quantize`] gives it: for a caller that quantizes each range as
/// it makes it (most ranges of a simulated scan are one value, quantized once).
#[inline]
pub fn quantize_range(r: f32) -> f32 {
    range_value(range_code(r))
}

/// [`quantize`] of `obs` but its scan, taken as it is: when every range of `obs` is already
/// [`quantize_range`] of the range it stands for, this is `quantize` of the observation with
/// those ranges, bit for bit (each number is quantized by itself).
pub fn quantize_but_scan(mut obs: Observation) -> Observation {
    for o in obs.objects.iter_mut() {
        o.x = mm_value(mm_code(o.x, OBJECT_COORDINATE_BOUND));
        o.y = mm_value(mm_code(o.y, OBJECT_COORDINATE_BOUND));
        o.radius = radius_value(radius_code(o.radius));
    }
    let r = &mut obs.reference;
    r.x = mm_value(mm_code(r.x, REFERENCE_COORDINATE_BOUND));
    r.y = mm_value(mm_code(r.y, REFERENCE_COORDINATE_BOUND));
    r.heading = heading_value(heading_code(r.heading));
    obs.speed = mm_value(mm_code(obs.speed, MAX_SPEED));
    obs
}

/// The 64 ranges, 10 bits each, packed little-endian: range `j` is bits `10·j .. 10·j + 10` of
/// the 640-bit little-endian number the 80 bytes make.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct PackedScan([u8; PACKED_SCAN_BYTES]);

impl PackedScan {
    fn encode(scan: &Scan) -> Self {
        let mut bytes = [0u8; PACKED_SCAN_BYTES];
        for (j, &r) in scan.ranges.iter().enumerate() {
            let code = range_code(r) as u32;
            let bit = j * RANGE_BITS as usize;
            let (byte, shift) = (bit / 8, bit % 8);
            let v = code << shift;
            bytes[byte] |= v as u8;
            bytes[byte + 1] |= (v >> 8) as u8;
            if shift + RANGE_BITS as usize > 16 {
                bytes[byte + 2] |= (v >> 16) as u8;
            }
        }
        Self(bytes)
    }

    fn decode(&self) -> Scan {
        let mut scan = Scan::EMPTY;
        for (j, r) in scan.ranges.iter_mut().enumerate() {
            let bit = j * RANGE_BITS as usize;
            let (byte, shift) = (bit / 8, bit % 8);
            let mut v = self.0[byte] as u32 | (self.0[byte + 1] as u32) << 8;
            if byte + 2 < PACKED_SCAN_BYTES {
                v |= (self.0[byte + 2] as u32) << 16;
            }
            *r = range_value(((v >> shift) & ((1 << RANGE_BITS) - 1)) as u16);
        }
        scan
    }
}

// serde implements arrays up to 32 elements only: the packed scan is a fixed-length tuple of
// bytes (postcard: the 80 bytes, no length prefix).
impl Serialize for PackedScan {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut t = serializer.serialize_tuple(PACKED_SCAN_BYTES)?;
        for b in &self.0 {
            t.serialize_element(b)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for PackedScan {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = PackedScan;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{PACKED_SCAN_BYTES} bytes of packed ranges")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<PackedScan, A::Error> {
                let mut bytes = [0u8; PACKED_SCAN_BYTES];
                for (i, b) in bytes.iter_mut().enumerate() {
                    *b = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                Ok(PackedScan(bytes))
            }
        }
        deserializer.deserialize_tuple(PACKED_SCAN_BYTES, V)
    }
}

impl MaxSize for PackedScan {
    const POSTCARD_MAX_SIZE: usize = PACKED_SCAN_BYTES;
}

/// A fixed-width little-endian `i16` (postcard would write a zigzag varint of 1 to 3 bytes).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize, MaxSize)]
pub(crate) struct I16([u8; 2]);

impl I16 {
    pub(crate) const fn new(v: i16) -> Self {
        Self(v.to_le_bytes())
    }
    pub(crate) const fn get(self) -> i16 {
        i16::from_le_bytes(self.0)
    }
}

/// A fixed-width little-endian `u16`.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize, MaxSize)]
pub(crate) struct U16([u8; 2]);

impl U16 {
    pub(crate) const fn new(v: u16) -> Self {
        Self(v.to_le_bytes())
    }
    pub(crate) const fn get(self) -> u16 {
        u16::from_le_bytes(self.0)
    }
}

#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize, MaxSize)]
struct WireObject {
    class: SemanticClass,
    x: I16,
    y: I16,
    radius: U16,
}

/// The observation's wire form (see the module table).
#[derive(Clone, PartialEq, Eq, Debug, Serialize, Deserialize)]
pub(crate) struct WireObservation {
    scan: PackedScan,
    objects: heapless::Vec<WireObject, MAX_OBJECTS>,
    reference: [I16; 3],
    speed: I16,
}

impl MaxSize for WireObservation {
    // The object list is a postcard sequence: a varint length (one byte up to 127), the items.
    const POSTCARD_MAX_SIZE: usize = PackedScan::POSTCARD_MAX_SIZE
        + 1
        + MAX_OBJECTS * WireObject::POSTCARD_MAX_SIZE
        + 3 * I16::POSTCARD_MAX_SIZE
        + I16::POSTCARD_MAX_SIZE;
}

const _: () = assert!(MAX_OBJECTS <= 127, "the list length is a one-byte varint");

impl WireObservation {
    pub(crate) fn encode(obs: &Observation) -> Self {
        let mut objects = heapless::Vec::new();
        for o in &obs.objects {
            // As many objects as the observation's list holds: there is room.
            let _ = objects.push(WireObject {
                class: o.class,
                x: I16::new(mm_code(o.x, OBJECT_COORDINATE_BOUND)),
                y: I16::new(mm_code(o.y, OBJECT_COORDINATE_BOUND)),
                radius: U16::new(radius_code(o.radius)),
            });
        }
        let r = &obs.reference;
        Self {
            scan: PackedScan::encode(&obs.scan),
            objects,
            reference: [
                I16::new(mm_code(r.x, REFERENCE_COORDINATE_BOUND)),
                I16::new(mm_code(r.y, REFERENCE_COORDINATE_BOUND)),
                I16::new(heading_code(r.heading)),
            ],
            speed: I16::new(mm_code(obs.speed, MAX_SPEED)),
        }
    }

    pub(crate) fn decode(&self) -> Observation {
        let mut objects = ObjectList::new();
        for o in &self.objects {
            let _ = objects.push(SemanticObject {
                class: o.class,
                x: mm_value(o.x.get()),
                y: mm_value(o.y.get()),
                radius: radius_value(o.radius.get()),
            });
        }
        Observation {
            scan: self.scan.decode(),
            objects,
            reference: PathReference {
                x: mm_value(self.reference[0].get()),
                y: mm_value(self.reference[1].get()),
                heading: heading_value(self.reference[2].get()),
            },
            speed: mm_value(self.speed.get()),
        }
    }
}

/// `#[serde(with = "observation")]`: an [`Observation`] written in its wire form.
pub(crate) mod observation {
    use super::*;

    pub(crate) fn serialize<S: Serializer>(obs: &Observation, s: S) -> Result<S::Ok, S::Error> {
        WireObservation::encode(obs).serialize(s)
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Observation, D::Error> {
        Ok(WireObservation::deserialize(d)?.decode())
    }
}

/// Fixed-point codecs of the action command's track (see `message::Track`).
pub(crate) mod track {
    use super::round;

    /// Steering steps per radian.
    pub(crate) const STEERING_STEPS: f32 = 10_000.0;
    /// Length and speed steps per metre (millimetres).
    pub(crate) const MM: f32 = super::MM;

    /// The signed code of `x` in `steps` per unit, saturating at the ends of `i16`; NaN is 0.
    pub(crate) fn signed(x: f32, steps: f32) -> i16 {
        round(x * steps).clamp(i16::MIN as i32, i16::MAX as i32) as i16
    }

    /// The unsigned code of `x` in `steps` per unit, saturating at the ends of `u16`; NaN and
    /// negative numbers are 0.
    pub(crate) fn unsigned(x: f32, steps: f32) -> u16 {
        round(x * steps).clamp(0, u16::MAX as i32) as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware_core::observation::SemanticClass;
    use proptest::prelude::*;

    #[test]
    fn every_code_decodes_to_a_number_that_encodes_back() {
        // Valid codes come back as they are; the others decode to numbers out of bounds.
        for c in 0..(1u16 << RANGE_BITS) {
            let r = range_value(c);
            if c <= 1000 {
                assert_eq!(range_code(r), c, "range {c}");
            } else {
                assert!(r > SCAN_MAX_RANGE, "range code {c}");
            }
        }
        for c in i16::MIN..=i16::MAX {
            let v = mm_value(c);
            if within(v, OBJECT_COORDINATE_BOUND) {
                assert_eq!(mm_code(v, OBJECT_COORDINATE_BOUND), c, "mm {c}");
            }
            let h = heading_value(c);
            if c.unsigned_abs() <= HEADING_MAX as u16 {
                assert_eq!(heading_code(h), c, "heading {c}");
            } else {
                assert!(!within(h, PI), "heading code {c} is out of range");
            }
        }
        for c in 1..=(MAX_OBJECT_RADIUS * MM) as u16 {
            assert_eq!(radius_code(radius_value(c)), c, "radius {c}");
        }
    }

    #[test]
    fn range_code_is_the_rule_of_every_other_field() {
        // The rule of `mm_code` and the others (finite, within the bound, `round` half away
        // from zero), with the range's own `r ≥ 0`: `range_code` is the same in one select.
        let rule = |r: f32| {
            if within(r, SCAN_MAX_RANGE) && r >= 0.0 {
                round(r * RANGE_STEPS_PER_METRE) as u16
            } else {
                RANGE_INVALID
            }
        };
        let same = |r: f32| {
            assert_eq!(
                range_value(range_code(r)).to_bits(),
                range_value(rule(r)).to_bits(),
                "{r:e} ({:#x})",
                r.to_bits()
            );
        };
        for r in [
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            SCAN_MAX_RANGE,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            f32::MAX,
            f32::MIN,
            1e10,
            -1e10,
        ] {
            same(r);
        }
        // Every half centimetre up to 10.5 m (the rounding boundaries and the steps), each with
        // its neighbours four representable numbers either way.
        for k in 0..=2100u32 {
            let r = k as f32 * 0.005;
            for d in -4i32..=4 {
                same(f32::from_bits(r.to_bits().wrapping_add_signed(d)));
                same(-f32::from_bits(r.to_bits().wrapping_add_signed(d)));
            }
        }
        // And a dense sweep of every bit pattern from 0 to 16 m, one in 61.
        let mut bits = 0u32;
        while bits <= 16.0f32.to_bits() {
            same(f32::from_bits(bits));
            same(f32::from_bits(bits | 0x8000_0000));
            bits += 61;
        }
    }

    #[test]
    fn steps_and_bounds_are_as_documented() {
        assert_eq!(range_code(1.234), 123);
        assert_eq!(range_code(1.235), 124, "half away from zero");
        assert_eq!(range_code(SCAN_MAX_RANGE), 1000);
        assert_eq!(
            range_code(10.004),
            RANGE_INVALID,
            "out of range, not rounded in"
        );
        assert_eq!(range_code(-0.001), RANGE_INVALID);
        assert_eq!(range_code(f32::NAN), RANGE_INVALID);
        assert_eq!(mm_code(-1.2345, 20.0), -1235);
        assert_eq!(mm_code(20.0, 20.0), 20_000);
        assert_eq!(mm_code(20.0001, 20.0), SIGNED_INVALID);
        assert_eq!(radius_code(0.0001), 1, "a tiny disc stays a disc");
        assert_eq!(radius_code(0.0), 0);
        assert_eq!(heading_code(PI), HEADING_MAX);
        assert_eq!(heading_code(-PI), -HEADING_MAX);
        assert_eq!(heading_code(3.2), SIGNED_INVALID);
        // Every range error is within half a centimetre.
        for k in 0..=10_000 {
            let r = k as f32 / 1000.0;
            let q = range_value(range_code(r));
            assert!((q - r).abs() <= 0.005 + 1e-6, "{r} -> {q}");
        }
    }

    #[test]
    fn the_packed_scan_holds_each_range_in_its_own_bits() {
        let mut scan = Scan::EMPTY;
        for (j, r) in scan.ranges.iter_mut().enumerate() {
            *r = (j * 13 % 1001) as f32 / 100.0;
        }
        let packed = PackedScan::encode(&scan);
        // Beam 0 is the low 10 bits of the first two bytes.
        assert_eq!(packed.0[0] as u16 | ((packed.0[1] as u16 & 0x03) << 8), 0);
        assert_eq!(packed.decode(), scan);
        // One beam's code changes only its own bits.
        let mut other = scan;
        other.ranges[37] = 9.99;
        let changed: std::vec::Vec<usize> = PackedScan::encode(&other)
            .0
            .iter()
            .zip(packed.0.iter())
            .enumerate()
            .filter(|(_, (a, b))| a != b)
            .map(|(i, _)| i)
            .collect();
        assert!(changed.iter().all(|&i| i == 46 || i == 47), "{changed:?}");
    }

    fn any_f32() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => -40.0f32..40.0,
            1 => -0.001f32..0.001,
            1 => prop::num::f32::ANY,
            1 => Just(PI),
            1 => Just(-PI),
            1 => Just(SCAN_MAX_RANGE),
        ]
    }

    fn observation() -> impl Strategy<Value = Observation> {
        let objects = proptest::collection::vec(
            (0usize..3, any_f32(), any_f32(), any_f32()).prop_map(|(c, x, y, radius)| {
                SemanticObject {
                    class: SemanticClass::ALL[c],
                    x,
                    y,
                    radius,
                }
            }),
            0..=MAX_OBJECTS,
        );
        (
            proptest::collection::vec(prop_oneof![3 => 0.0f32..10.0, 1 => any_f32()], SCAN_BEAMS),
            objects,
            (any_f32(), any_f32(), any_f32(), any_f32()),
        )
            .prop_map(|(ranges, objs, (x, y, heading, speed))| {
                let mut obs = Observation::open_space();
                obs.scan.ranges.copy_from_slice(&ranges);
                for o in objs {
                    obs.objects.push(o).unwrap();
                }
                obs.reference = PathReference { x, y, heading };
                obs.speed = speed;
                obs
            })
    }

    proptest! {
        #[test]
        fn quantize_is_idempotent_and_keeps_the_verdict(obs in observation()) {
            let q = quantize(&obs);
            prop_assert_eq!(&quantize(&q), &q);
            prop_assert_eq!(obs.validate().is_ok(), q.validate().is_ok());
            if obs.validate().is_ok() {
                prop_assert_eq!(quantize(&obs.mirrored()), q.mirrored());
                for (a, b) in obs.scan.ranges.iter().zip(q.scan.ranges.iter()) {
                    prop_assert!((a - b).abs() <= 0.005 + 1e-6);
                }
                prop_assert!((obs.speed - q.speed).abs() <= 0.0005 + 1e-6);
            }
        }

        #[test]
        fn quantize_is_the_wire_round_trip(obs in observation()) {
            // Bit for bit (`{:?}` tells -0 from +0 and shows NaN): the direct rounding is the
            // encoding and decoding it replaced.
            let wire = WireObservation::encode(&obs).decode();
            prop_assert_eq!(format!("{:?}", quantize(&obs)), format!("{:?}", wire));
        }

        #[test]
        fn a_scan_quantized_range_by_range_is_quantize(obs in observation()) {
            // What the simulator does: each range quantized as it is made, the rest after.
            let mut scan = obs.scan;
            for r in scan.ranges.iter_mut() {
                *r = quantize_range(*r);
            }
            let by_parts = quantize_but_scan(Observation { scan, ..obs.clone() });
            prop_assert_eq!(format!("{:?}", by_parts), format!("{:?}", quantize(&obs)));
        }

        #[test]
        fn any_bytes_decode_to_finite_numbers(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            if let Ok((w, _)) = postcard::take_from_bytes::<WireObservation>(&bytes) {
                let obs = w.decode();
                prop_assert!(obs.scan.ranges.iter().all(|r| r.is_finite()));
                // Whatever arrives keeps its verdict through another quantization.
                let q = quantize(&obs);
                prop_assert_eq!(obs.validate().is_ok(), q.validate().is_ok());
                if obs.validate().is_ok() {
                    prop_assert_eq!(q, obs);
                }
            }
        }
    }
}
