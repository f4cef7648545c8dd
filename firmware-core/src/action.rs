//! Action indices and the 64-bit mask of allowed actions.
//!
//! The car chooses among [`MAX_ACTIONS`] candidate trajectories. An [`ActionIndex`] is a checked
//! index into that set; an [`ActionMask`] is one bit per action (bit `i` set: action `i` may be
//! chosen). Colliding trajectories are cleared from the mask by the evaluator, and every argmax in
//! this crate runs over the set bits only.
//!
//! ```
//! use firmware_core::{ActionIndex, ActionMask};
//!
//! let mut allowed = ActionMask::ALL;
//! allowed.remove(ActionIndex::new(0).unwrap());
//! assert_eq!(allowed.count(), 63);
//! assert_eq!(allowed.first(), ActionIndex::new(1));
//! ```

use core::fmt;

use serde::{Deserialize, Serialize};

/// Number of candidate actions (trajectories) the learner chooses from.
///
/// The mask is a `u64`, so this is also the largest lattice the crate can hold.
pub const MAX_ACTIONS: usize = 64;

const _: () = assert!(MAX_ACTIONS <= u64::BITS as usize, "ActionMask is one u64");
const _: () = assert!(MAX_ACTIONS <= u8::MAX as usize + 1, "ActionIndex is one u8");

/// A checked index of one of the [`MAX_ACTIONS`] actions.
///
/// Deserialisation checks the range too, so an index read from the wire is always valid.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
#[serde(try_from = "u8", into = "u8")]
pub struct ActionIndex(u8);

impl ActionIndex {
    /// The first action (index 0).
    pub const FIRST: Self = Self(0);

    /// `Some(index)` when `index < MAX_ACTIONS`.
    #[inline]
    pub const fn new(index: usize) -> Option<Self> {
        if index < MAX_ACTIONS {
            Some(Self(index as u8))
        } else {
            None
        }
    }

    /// The index as a `usize`, always below [`MAX_ACTIONS`].
    #[inline]
    pub const fn get(self) -> usize {
        self.0 as usize
    }

    /// Every action index in increasing order.
    pub fn all() -> impl DoubleEndedIterator<Item = Self> + ExactSizeIterator + Clone {
        (0..MAX_ACTIONS as u8).map(Self)
    }
}

/// An action index was not below [`MAX_ACTIONS`].
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct ActionOutOfRange(pub usize);

impl fmt::Display for ActionOutOfRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "action index {} is not below {}", self.0, MAX_ACTIONS)
    }
}

impl core::error::Error for ActionOutOfRange {}

impl TryFrom<u8> for ActionIndex {
    type Error = ActionOutOfRange;
    fn try_from(value: u8) -> Result<Self, Self::Error> {
        Self::new(value as usize).ok_or(ActionOutOfRange(value as usize))
    }
}

impl TryFrom<usize> for ActionIndex {
    type Error = ActionOutOfRange;
    fn try_from(value: usize) -> Result<Self, Self::Error> {
        Self::new(value).ok_or(ActionOutOfRange(value))
    }
}

impl From<ActionIndex> for u8 {
    fn from(a: ActionIndex) -> u8 {
        a.0
    }
}

impl fmt::Display for ActionIndex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.fmt(f)
    }
}

/// The set of allowed actions, one bit per action.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Default, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
#[serde(transparent)]
pub struct ActionMask(u64);

impl ActionMask {
    /// No action allowed.
    pub const NONE: Self = Self(0);
    /// Every one of the [`MAX_ACTIONS`] actions allowed.
    pub const ALL: Self = Self(if MAX_ACTIONS == 64 {
        u64::MAX
    } else {
        (1u64 << MAX_ACTIONS) - 1
    });

    /// The mask from raw bits; bits at or above [`MAX_ACTIONS`] are cleared.
    #[inline]
    pub const fn from_bits(bits: u64) -> Self {
        Self(bits & Self::ALL.0)
    }

    /// The raw bits.
    #[inline]
    pub const fn bits(self) -> u64 {
        self.0
    }

    /// Whether `action` is allowed.
    #[inline]
    pub const fn contains(self, action: ActionIndex) -> bool {
        self.0 & (1u64 << action.0) != 0
    }

    /// Allow `action`.
    #[inline]
    pub fn insert(&mut self, action: ActionIndex) {
        self.0 |= 1u64 << action.0;
    }

    /// Forbid `action`.
    #[inline]
    pub fn remove(&mut self, action: ActionIndex) {
        self.0 &= !(1u64 << action.0);
    }

    /// Number of allowed actions.
    #[inline]
    pub const fn count(self) -> u32 {
        self.0.count_ones()
    }

    /// Whether no action is allowed.
    #[inline]
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The lowest allowed action.
    #[inline]
    pub const fn first(self) -> Option<ActionIndex> {
        if self.0 == 0 {
            None
        } else {
            Some(ActionIndex(self.0.trailing_zeros() as u8))
        }
    }

    /// The allowed actions in increasing order.
    #[inline]
    pub fn iter(self) -> MaskIter {
        #[cfg(target_arch = "arm")]
        return MaskIter([self.0 as u32, (self.0 >> 32) as u32]);
        #[cfg(not(target_arch = "arm"))]
        return MaskIter(self.0);
    }
}

impl FromIterator<ActionIndex> for ActionMask {
    fn from_iter<I: IntoIterator<Item = ActionIndex>>(iter: I) -> Self {
        let mut mask = Self::NONE;
        for a in iter {
            mask.insert(a);
        }
        mask
    }
}

impl IntoIterator for ActionMask {
    type Item = ActionIndex;
    type IntoIter = MaskIter;
    fn into_iter(self) -> MaskIter {
        self.iter()
    }
}

/// Iterator over the allowed actions of an [`ActionMask`], lowest first. On the car (`arm`) it
/// walks actions 0–31, then 32–63, one 32-bit half each (a 64-bit count of trailing zeros or
/// clear of the lowest bit is several instructions on a Cortex-M4); elsewhere the 64-bit word
/// itself (one instruction each on a 64-bit host: the halves took the simulator about 900
/// instructions a step more, in its teacher's loops). The same actions in the same order.
#[derive(Clone, Debug)]
pub struct MaskIter(
    #[cfg(target_arch = "arm")] [u32; 2],
    #[cfg(not(target_arch = "arm"))] u64,
);

impl Iterator for MaskIter {
    type Item = ActionIndex;

    #[cfg(target_arch = "arm")]
    #[inline]
    fn next(&mut self) -> Option<ActionIndex> {
        let [lo, hi] = &mut self.0;
        let i = if *lo != 0 {
            let i = lo.trailing_zeros();
            *lo &= *lo - 1;
            i
        } else if *hi != 0 {
            let i = hi.trailing_zeros() + 32;
            *hi &= *hi - 1;
            i
        } else {
            return None;
        };
        Some(ActionIndex(i as u8))
    }

    #[cfg(not(target_arch = "arm"))]
    #[inline]
    fn next(&mut self) -> Option<ActionIndex> {
        if self.0 == 0 {
            return None;
        }
        let i = self.0.trailing_zeros();
        self.0 &= self.0 - 1;
        Some(ActionIndex(i as u8))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        #[cfg(target_arch = "arm")]
        let n = (self.0[0].count_ones() + self.0[1].count_ones()) as usize;
        #[cfg(not(target_arch = "arm"))]
        let n = self.0.count_ones() as usize;
        (n, Some(n))
    }
}

impl ExactSizeIterator for MaskIter {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_range_is_checked() {
        assert!(ActionIndex::new(63).is_some());
        assert!(ActionIndex::new(64).is_none());
        assert_eq!(ActionIndex::try_from(200u8), Err(ActionOutOfRange(200)));
    }

    #[test]
    fn mask_iterates_lowest_first() {
        let m = ActionMask::from_bits(0b1010_0001);
        let v: [usize; 3] = {
            let mut it = m.iter().map(ActionIndex::get);
            [it.next().unwrap(), it.next().unwrap(), it.next().unwrap()]
        };
        assert_eq!(v, [0, 5, 7]);
        assert_eq!(m.iter().len(), 3);
        assert_eq!(ActionMask::ALL.count(), 64);
        assert_eq!(ActionMask::NONE.first(), None);
    }

    #[test]
    fn deserialising_an_out_of_range_index_fails() {
        let bytes = postcard::to_allocvec(&64u8).unwrap();
        assert!(postcard::from_bytes::<ActionIndex>(&bytes).is_err());
        let bytes = postcard::to_allocvec(&63u8).unwrap();
        assert_eq!(
            postcard::from_bytes::<ActionIndex>(&bytes).unwrap().get(),
            63
        );
    }
}
