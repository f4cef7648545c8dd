//! Helpers shared by the end-to-end tests in `tests/tests/`.
//!
//! The tests themselves live in `tests/`: one file per concern (`persistence.rs`,
//! `determinism.rs`, ...). This library holds what several of them use.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

use firmware_core::Weights;

/// FNV-1a over bytes: a small, stable hash for golden values.
pub fn fnv1a(bytes: impl IntoIterator<Item = u8>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// FNV-1a over the bit patterns of `f32`s (so `-0.0` and `0.0`, or two NaNs, differ).
pub fn hash_f32s<'a>(values: impl IntoIterator<Item = &'a f32>) -> u64 {
    fnv1a(values.into_iter().flat_map(|x| x.to_bits().to_le_bytes()))
}

/// The weights' bit patterns, for exact comparisons with readable failures.
pub fn weight_bits(w: &Weights) -> [u32; firmware_core::FEATURE_COUNT] {
    w.map(f32::to_bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_the_reference_vectors() {
        assert_eq!(fnv1a(*b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(*b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(*b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn f32_hash_sees_bit_patterns() {
        assert_ne!(hash_f32s(&[0.0]), hash_f32s(&[-0.0]));
    }
}
