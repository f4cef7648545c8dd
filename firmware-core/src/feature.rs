//! The feature layout φ(s, a) ∈ R^F and the table of features for all actions.
//!
//! Every action `a` of a tick has a feature vector `φ(s, a)` of [`FEATURE_COUNT`] entries, in the
//! order of [`Feature`]; a [`FeatureTable`] holds one row per action. The layout follows the paper's
//! section 6: clearance to obstacles, clearance to each semantic class, the path error, and the
//! lateral displacement of the trajectory's end (right positive). The evaluator
//! ([`crate::evaluator`]) fills the table from an observation; tests and synthetic teachers may
//! fill it directly.
//!
//! Numbers in a table are trusted only after [`FeatureTable::check`]: each entry must be finite
//! with magnitude at most [`FEATURE_BOUND`].
//!
//! ```
//! use firmware_core::{dot, Feature, FeatureTable, ActionIndex, FEATURE_COUNT};
//!
//! let mut table = FeatureTable::ZERO;
//! let a = ActionIndex::new(3).unwrap();
//! table[a][Feature::Door.index()] = 2.5;
//! let mut w = [0.0; FEATURE_COUNT];
//! w[Feature::Door.index()] = 2.0;
//! assert_eq!(dot(&w, &table[a]), 5.0);
//! ```

use core::fmt;
use core::ops::{Index, IndexMut};

use serde::{Deserialize, Serialize};

use crate::action::{ActionIndex, ActionMask, MAX_ACTIONS};

/// Number of features per action.
pub const FEATURE_COUNT: usize = 6;

/// Largest magnitude a feature may have. Larger values are rejected as absurd.
///
/// The evaluator's features stay within ±10 (see [`crate::evaluator`]); the bound leaves room for
/// hand-built or synthetic features while keeping every score `w·φ` far from `f32` overflow
/// (`FEATURE_COUNT · WEIGHT_BOUND · FEATURE_BOUND = 6e10`).
pub const FEATURE_BOUND: f32 = 1.0e4;

/// Largest magnitude a weight may reach. An update that would cross it is refused.
pub const WEIGHT_BOUND: f32 = 1.0e6;

/// One feature vector (one row of a [`FeatureTable`]).
pub type Features = [f32; FEATURE_COUNT];

/// The learner's weight vector: the policy is `argmax_a w · φ(s, a)`.
pub type Weights = [f32; FEATURE_COUNT];

/// The entries of a feature vector, in storage order.
///
/// Each feature has a *subject* a semantic statement can name ("avoid doors", "stay on the
/// path", "keep right"); [`Feature::grows_away`] says in which direction the value moves as a
/// trajectory goes away from its subject.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
#[repr(u8)]
pub enum Feature {
    /// Clearance to obstacles (range-scan points), summed along the trajectory.
    Obstacles = 0,
    /// Clearance to doors, summed along the trajectory.
    Door = 1,
    /// Clearance to stairs, summed along the trajectory.
    Stairs = 2,
    /// Clearance to chairs, summed along the trajectory.
    Chair = 3,
    /// Cross-track plus along-track error of the trajectory's end against the path reference.
    Path = 4,
    /// Lateral displacement of the trajectory's end, right positive.
    Right = 5,
}

impl Feature {
    /// All features in storage order.
    pub const ALL: [Feature; FEATURE_COUNT] = [
        Feature::Obstacles,
        Feature::Door,
        Feature::Stairs,
        Feature::Chair,
        Feature::Path,
        Feature::Right,
    ];

    /// Position of this feature in a [`Features`] vector.
    #[inline]
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The feature stored at `index`.
    pub const fn from_index(index: usize) -> Option<Self> {
        if index < FEATURE_COUNT {
            Some(Self::ALL[index])
        } else {
            None
        }
    }

    /// Whether the value grows as a trajectory moves away from the feature's subject.
    ///
    /// True for the clearances and the path error; false for [`Feature::Right`], which grows
    /// *towards* its subject, the right-hand side.
    #[inline]
    pub const fn grows_away(self) -> bool {
        !matches!(self, Feature::Right)
    }

    /// A short lower-case name ("obstacles", "door", ...), for logs and CSV headers.
    pub const fn name(self) -> &'static str {
        match self {
            Feature::Obstacles => "obstacles",
            Feature::Door => "door",
            Feature::Stairs => "stairs",
            Feature::Chair => "chair",
            Feature::Path => "path",
            Feature::Right => "right",
        }
    }
}

impl fmt::Display for Feature {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// `a · b`, summed from index 0 upwards.
///
/// The order is part of the contract: it is what makes the host and the Cortex-M4F produce
/// bit-identical scores (no fused multiply-add, no reassociation).
#[inline]
pub fn dot(a: &Features, b: &Features) -> f32 {
    // Written out: the firmware is optimised for size, which keeps a loop a loop (about twice the
    // instructions of the six multiply-adds on a Cortex-M4). Same operations, same order.
    const _: () = assert!(FEATURE_COUNT == 6);
    let mut s = 0.0f32;
    s += a[0] * b[0];
    s += a[1] * b[1];
    s += a[2] * b[2];
    s += a[3] * b[3];
    s += a[4] * b[4];
    s += a[5] * b[5];
    s
}

/// [`dot`] of `w` and action `a`'s features read from a sealed table's columns: the same
/// operations in the same order, the same bits.
#[inline(always)]
pub(crate) fn column_dot(w: &Weights, columns: &Columns, a: usize) -> f32 {
    let mut s = 0.0f32;
    for f in 0..FEATURE_COUNT {
        s += w[f] * columns[f][a];
    }
    s
}

/// The correctly rounded square root (IEEE 754), as `libm::sqrtf` computes it: with the `std`
/// feature `f32::sqrt`, the same bits (both correctly rounded; tested below on a dense sample and
/// every special value, and exhaustively by `cargo test -p firmware-core --release --features
/// std --lib -- --ignored ieee_sqrt_all_bit_patterns`), which the compiler puts four to a
/// `sqrtps` on x86-64 where `libm`'s one `sqrtss` in an `asm!` block stays alone; without it (the
/// car) `libm::sqrtf`. Not [`crate::evaluator::sqrt`], which is not correctly rounded.
#[inline(always)]
pub(crate) fn ieee_sqrt(x: f32) -> f32 {
    #[cfg(feature = "std")]
    return x.sqrt();
    #[cfg(not(feature = "std"))]
    return libm::sqrtf(x);
}

/// Whether every entry is finite with magnitude at most `bound`.
#[inline]
pub(crate) fn within(v: &Features, bound: f32) -> bool {
    v.iter().all(|x| x.is_finite() && x.abs() <= bound)
}

/// Why a feature table was refused.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum FeatureError {
    /// An entry of an allowed action's row is NaN or infinite.
    NotFinite {
        /// The action whose row holds the entry.
        action: ActionIndex,
    },
    /// An entry of an allowed action's row exceeds [`FEATURE_BOUND`] in magnitude.
    OutOfBounds {
        /// The action whose row holds the entry.
        action: ActionIndex,
    },
}

impl fmt::Display for FeatureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FeatureError::NotFinite { action } => {
                write!(f, "features of action {action} are not finite")
            }
            FeatureError::OutOfBounds { action } => {
                write!(f, "features of action {action} exceed {FEATURE_BOUND}")
            }
        }
    }
}

impl core::error::Error for FeatureError {}

/// Every action's value of each feature, feature by feature: six columns of [`MAX_ACTIONS`]
/// (a sealed table's, on a host: see [`FeatureTable`]).
pub(crate) type Columns = [[f32; MAX_ACTIONS]; FEATURE_COUNT];

/// The features of every action for one tick: `MAX_ACTIONS × FEATURE_COUNT` `f32`s (1.5 KiB),
/// one row per action.
///
/// On a host (every target but the car's Cortex-M4F, `target_arch = "arm"`: where the learner's
/// passes over the actions compute several `f32`s side by side) a table also keeps a copy of its
/// entries feature by feature (six columns of 64, 1.5 KiB more), which those passes load as whole
/// vectors instead of gathering each action's six features from its row, and whether every entry
/// was within [`FEATURE_BOUND`], which [`FeatureTable::check`] then needs not look at again.
/// [`FeatureTable::seal`] makes them (the evaluator does once it has written a table, and a table
/// from [`FeatureTable::ZERO`] or [`FeatureTable::from_rows`] has them); a write through
/// [`FeatureTable::rows_mut`] or `IndexMut` leaves them stale until the next seal, and the passes
/// read the rows meanwhile. The same bits either way: each action's numbers come from the same
/// operations in the same order. The car keeps the rows alone, and `seal` does nothing there.
#[derive(Clone)]
pub struct FeatureTable {
    rows: [Features; MAX_ACTIONS],
    /// The host's copy feature by feature, and what the last seal found.
    #[cfg(not(target_arch = "arm"))]
    sealed: Sealed,
}

/// A host table's columns and bound check, as of its last seal.
#[cfg(not(target_arch = "arm"))]
#[derive(Clone, Copy)]
struct Sealed {
    columns: Columns,
    /// Whether `columns` hold the rows' entries: no write since the last seal.
    fresh: bool,
    /// Whether every entry, allowed or not, was finite and within [`FEATURE_BOUND`] then.
    in_bounds: bool,
}

/// What [`Sealed::of`] does, at run time: `rows` into `columns`, and whether every entry is
/// finite and within [`FEATURE_BOUND`]. In loops the compiler vectorises (four entries of a
/// column gathered into one vector, stored and compared whole): about 1 100 instructions a table
/// on x86-64 (`examples/round_count seal`), where `Sealed::of`'s `const` loops take about 1 600.
/// Not inlined: inlined into a caller's loop, the compiler was seen to leave it scalar.
#[cfg(not(target_arch = "arm"))]
#[inline(never)]
fn transpose(rows: &[Features; MAX_ACTIONS], columns: &mut Columns) -> bool {
    let mut good = true;
    for a in 0..MAX_ACTIONS {
        for f in 0..FEATURE_COUNT {
            let x = rows[a][f];
            columns[f][a] = x;
            good &= x.abs() <= FEATURE_BOUND;
        }
    }
    good
}

/// Whether every entry is finite and within [`FEATURE_BOUND`]: one comparison per entry (false
/// for NaN and both infinities) without an early exit, which the compiler vectorises.
#[inline(always)]
fn all_in_bounds(rows: &[Features; MAX_ACTIONS]) -> bool {
    rows.as_flattened()
        .iter()
        .fold(true, |good, x| good & (x.abs() <= FEATURE_BOUND))
}

impl FeatureTable {
    /// A table of zeros.
    pub const ZERO: Self = Self::from_rows([[0.0; FEATURE_COUNT]; MAX_ACTIONS]);

    /// A table from its rows (sealed).
    pub const fn from_rows(rows: [Features; MAX_ACTIONS]) -> Self {
        Self {
            rows,
            #[cfg(not(target_arch = "arm"))]
            sealed: Sealed::of(&rows),
        }
    }

    /// All rows, indexed by action.
    #[inline]
    pub const fn rows(&self) -> &[Features; MAX_ACTIONS] {
        &self.rows
    }

    /// All rows, mutable. On a host the table is no longer sealed: the learner's passes read the
    /// rows until [`FeatureTable::seal`].
    #[inline]
    pub fn rows_mut(&mut self) -> &mut [Features; MAX_ACTIONS] {
        self.unseal();
        &mut self.rows
    }

    /// Makes the table's copy feature by feature and checks every entry against
    /// [`FEATURE_BOUND`] once (on a host; nothing on the car), for the learner's passes over the
    /// actions to load whole columns and [`FeatureTable::check`] to take that check's result. For
    /// a table written through [`FeatureTable::rows_mut`] or `IndexMut` once it is written; the
    /// evaluator seals what it writes.
    #[inline]
    pub fn seal(&mut self) {
        #[cfg(not(target_arch = "arm"))]
        {
            let Sealed {
                columns,
                fresh,
                in_bounds,
            } = &mut self.sealed;
            *in_bounds = transpose(&self.rows, columns);
            *fresh = true;
        }
    }

    /// Whether the table is sealed: always false on the car, which keeps no copy.
    #[inline]
    pub fn is_sealed(&self) -> bool {
        self.columns().is_some()
    }

    /// The columns of a sealed table (never on the car).
    #[inline(always)]
    pub(crate) fn columns(&self) -> Option<&Columns> {
        #[cfg(not(target_arch = "arm"))]
        return self.sealed.fresh.then_some(&self.sealed.columns);
        #[cfg(target_arch = "arm")]
        return None;
    }

    /// Marks the copy feature by feature stale (on a host), before a write.
    #[inline(always)]
    fn unseal(&mut self) {
        #[cfg(not(target_arch = "arm"))]
        {
            self.sealed.fresh = false;
        }
    }

    /// Checks the rows of the allowed actions: finite, magnitude at most [`FEATURE_BOUND`].
    /// Rows of forbidden actions are never read by the learner and are not checked.
    pub fn check(&self, allowed: ActionMask) -> Result<(), FeatureError> {
        // One comparison per entry over every row (the evaluator's rows of forbidden actions are
        // zeros), or the seal's of the same entries; the first bad allowed row is looked for
        // only when some row is bad.
        #[cfg(not(target_arch = "arm"))]
        let good = if self.sealed.fresh {
            self.sealed.in_bounds
        } else {
            all_in_bounds(&self.rows)
        };
        #[cfg(target_arch = "arm")]
        let good = all_in_bounds(&self.rows);
        if good {
            return Ok(());
        }
        for a in allowed {
            let row = &self.rows[a.get()];
            if row.iter().any(|x| !x.is_finite()) {
                return Err(FeatureError::NotFinite { action: a });
            }
            if !within(row, FEATURE_BOUND) {
                return Err(FeatureError::OutOfBounds { action: a });
            }
        }
        Ok(())
    }
}

#[cfg(not(target_arch = "arm"))]
impl Sealed {
    /// The columns of `rows` and their bound check, for the `const` tables ([`FeatureTable::seal`]
    /// does the same at run time).
    const fn of(rows: &[Features; MAX_ACTIONS]) -> Self {
        let mut columns = [[0.0; MAX_ACTIONS]; FEATURE_COUNT];
        let mut in_bounds = true;
        let mut a = 0;
        while a < MAX_ACTIONS {
            let mut f = 0;
            while f < FEATURE_COUNT {
                let x = rows[a][f];
                columns[f][a] = x;
                in_bounds &= x.abs() <= FEATURE_BOUND;
                f += 1;
            }
            a += 1;
        }
        Self {
            columns,
            fresh: true,
            in_bounds,
        }
    }
}

/// Equal rows: the host's copy feature by feature is not compared (a stale one is not wrong).
impl PartialEq for FeatureTable {
    fn eq(&self, other: &Self) -> bool {
        self.rows == other.rows
    }
}

/// The rows, as a derived `Debug` prints them (not the host's copy).
impl fmt::Debug for FeatureTable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("FeatureTable")
            .field("rows", &self.rows)
            .finish()
    }
}

impl Default for FeatureTable {
    fn default() -> Self {
        Self::ZERO
    }
}

impl Index<ActionIndex> for FeatureTable {
    type Output = Features;
    #[inline]
    fn index(&self, a: ActionIndex) -> &Features {
        &self.rows[a.get()]
    }
}

impl IndexMut<ActionIndex> for FeatureTable {
    #[inline]
    fn index_mut(&mut self, a: ActionIndex) -> &mut Features {
        self.unseal();
        &mut self.rows[a.get()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::policy::WIDE;

    #[test]
    fn layout_is_stable() {
        for (i, f) in Feature::ALL.iter().enumerate() {
            assert_eq!(f.index(), i);
            assert_eq!(Feature::from_index(i), Some(*f));
        }
        assert_eq!(Feature::from_index(FEATURE_COUNT), None);
    }

    #[test]
    fn check_rejects_bad_rows_of_allowed_actions_only() {
        let mut t = FeatureTable::ZERO;
        let a = ActionIndex::new(5).unwrap();
        t[a][2] = f32::NAN;
        assert_eq!(
            t.check(ActionMask::ALL),
            Err(FeatureError::NotFinite { action: a })
        );
        let mut others = ActionMask::ALL;
        others.remove(a);
        assert_eq!(t.check(others), Ok(()));
        t[a][2] = 2.0e4;
        assert_eq!(
            t.check(ActionMask::ALL),
            Err(FeatureError::OutOfBounds { action: a })
        );
        t[a][2] = -FEATURE_BOUND;
        assert_eq!(t.check(ActionMask::ALL), Ok(()));
    }

    #[test]
    fn a_sealed_table_checks_as_its_rows_do() {
        let a = ActionIndex::new(5).unwrap();
        let mut others = ActionMask::ALL;
        others.remove(a);
        for bad in [f32::NAN, f32::INFINITY, -2.0e4, FEATURE_BOUND, -0.0] {
            let mut t = FeatureTable::ZERO;
            t[a][2] = bad;
            let open = t.check(ActionMask::ALL);
            t.seal();
            assert_eq!(t.is_sealed(), WIDE);
            assert_eq!(t.check(ActionMask::ALL), open, "{bad}");
            assert_eq!(t.check(others), Ok(()));
            assert_eq!(
                FeatureTable::from_rows(*t.rows()).check(ActionMask::ALL),
                open
            );
        }
    }

    #[test]
    fn writes_unseal_and_seal_makes_the_columns() {
        assert_eq!(FeatureTable::ZERO.is_sealed(), WIDE);
        let mut t = FeatureTable::ZERO;
        for (a, row) in t.rows_mut().iter_mut().enumerate() {
            for (f, x) in row.iter_mut().enumerate() {
                *x = (a * FEATURE_COUNT + f) as f32 - 0.5;
            }
        }
        assert!(!t.is_sealed());
        let rows = *t.rows();
        t.seal();
        assert_eq!(t.is_sealed(), WIDE);
        let sealed = FeatureTable::from_rows(rows);
        assert_eq!(sealed.is_sealed(), WIDE);
        for table in [&t, &sealed] {
            if let Some(columns) = table.columns() {
                for (a, row) in rows.iter().enumerate() {
                    for f in 0..FEATURE_COUNT {
                        assert_eq!(columns[f][a].to_bits(), row[f].to_bits());
                    }
                }
            }
        }
        let a = ActionIndex::new(9).unwrap();
        t[a][1] = 3.0;
        assert!(!t.is_sealed());
        assert_eq!(t.rows()[9][1], 3.0);
        // Equal rows are equal tables, sealed or not.
        let mut u = t.clone();
        u.seal();
        assert_eq!(t, u);
        assert_eq!(format!("{t:?}"), format!("{u:?}"));
        assert_ne!(t, sealed);
        // A seal without a write changes nothing.
        let before = u.clone();
        u.seal();
        assert_eq!(u.columns(), before.columns());
    }

    /// `f32::sqrt` (what [`ieee_sqrt`] is with the `std` feature) and `libm::sqrtf` (without it)
    /// give the same bits for `bits`, NaNs included.
    fn same_sqrt(bits: u32) -> bool {
        let x = f32::from_bits(bits);
        x.sqrt().to_bits() == libm::sqrtf(x).to_bits()
    }

    #[test]
    fn ieee_sqrt_is_libm_sqrtf_on_a_dense_sample() {
        let specials = [
            0.0f32,
            -0.0,
            f32::MIN_POSITIVE,
            f32::from_bits(1),
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            -1.0,
            1.0,
            2.0,
            4.0,
            FEATURE_BOUND,
        ];
        for x in specials {
            assert!(same_sqrt(x.to_bits()), "{x:e}");
        }
        // Every 257th bit pattern (about 16.7 million, both signs, subnormals, NaNs), and every
        // 61st pattern from 0 to 4 (the squared distances and sums of the learner are mostly there).
        let mut bits = 0u32;
        while let Some(next) = bits.checked_add(257) {
            assert!(same_sqrt(bits), "{:e}", f32::from_bits(bits));
            bits = next;
        }
        for bits in (0..=4.0f32.to_bits()).step_by(61) {
            assert!(same_sqrt(bits), "{:e}", f32::from_bits(bits));
        }
    }

    #[test]
    #[ignore = "every f32 bit pattern: about 4.3e9 roots each way (run in release)"]
    fn ieee_sqrt_all_bit_patterns() {
        let differ = (0..=u32::MAX).filter(|&b| !same_sqrt(b)).count();
        assert_eq!(differ, 0);
    }
}
