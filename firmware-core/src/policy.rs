//! The linear policy `a_t = argmax over allowed a of w · φ(s, a)`.
//!
//! Ties go to the lowest index, so a zero weight vector picks the lowest allowed action. The
//! lattice puts the straight trajectory at index 0 for that reason.
//!
//! ```
//! use firmware_core::{policy, ActionIndex, ActionMask, FeatureTable};
//!
//! let mut table = FeatureTable::ZERO;
//! table[ActionIndex::new(7).unwrap()][0] = 1.0;
//! let w = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
//! assert_eq!(policy::select(&w, &table, ActionMask::ALL), ActionIndex::new(7));
//! assert_eq!(policy::select(&w, &table, ActionMask::NONE), None);
//! ```

use crate::action::{ActionIndex, ActionMask, MAX_ACTIONS};
use crate::feature::{FeatureTable, Weights, column_dot, dot};

/// The score `w · φ(s, a)` of one action.
#[inline]
pub fn score(w: &Weights, table: &FeatureTable, a: ActionIndex) -> f32 {
    dot(w, &table[a])
}

/// The scores of every allowed action; forbidden entries are left untouched.
pub fn scores(
    w: &Weights,
    table: &FeatureTable,
    allowed: ActionMask,
    out: &mut [f32; MAX_ACTIONS],
) {
    for a in allowed {
        out[a.get()] = score(w, table, a);
    }
}

/// Whether the target computes several `f32`s side by side (x86-64's SSE2, AArch64's NEON): the
/// learner's passes over the actions then run over all [`MAX_ACTIONS`] without a test or a branch
/// per action, which the compiler vectorises. On the car's Cortex-M4F (one `f32` at a time,
/// cheap branches) they run over the allowed actions one by one. Each action's numbers come
/// from the same operations in the same order either way: the same bits.
pub(crate) const WIDE: bool = !cfg!(target_arch = "arm");

/// The allowed action of highest score, lowest index on ties; `None` when nothing is allowed.
///
/// With finite weights and a checked table (see [`FeatureTable::check`]) no score is NaN, so
/// the result is the exact argmax.
pub fn select(w: &Weights, table: &FeatureTable, allowed: ActionMask) -> Option<ActionIndex> {
    if WIDE {
        return select_among(&all_scores(w, table), allowed);
    }
    select_keeping(w, table, allowed, |_, _| {})
}

/// [`select`], keeping the score of every allowed action in `scores` (on a `WIDE` target every
/// action's, a forbidden one's never to be read; on the car the forbidden entries are left
/// untouched): a round that carries them ([`crate::Round::with_scores`]) takes them instead of
/// scoring the table again when it learns at the same weights.
pub fn select_scored(
    w: &Weights,
    table: &FeatureTable,
    allowed: ActionMask,
    scores: &mut [f32; MAX_ACTIONS],
) -> Option<ActionIndex> {
    if WIDE {
        score_all(w, table, scores);
        return select_among(scores, allowed);
    }
    select_keeping(w, table, allowed, |a, s| scores[a] = s)
}

/// [`select`] one action at a time, handing each score to `keep` as it is computed: [`choose`]'s
/// comparisons, on the mask's two 32-bit halves (a 64-bit shift or count is several
/// instructions on a Cortex-M4). The running best starts as NaN rather than as nothing: no score
/// is at most NaN, so the first is taken, as `choose` takes it; then each later one that is not
/// at most the best so far.
#[inline(always)]
fn select_keeping(
    w: &Weights,
    table: &FeatureTable,
    allowed: ActionMask,
    mut keep: impl FnMut(usize, f32),
) -> Option<ActionIndex> {
    let bits = allowed.bits();
    if bits == 0 {
        return None;
    }
    let ([low, high], []) = table.rows().as_chunks::<32>() else {
        unreachable!("64 actions")
    };
    let (mut best, mut at) = (f32::NAN, 0);
    for (half, base, rows) in [(bits as u32, 0, low), ((bits >> 32) as u32, 32, high)] {
        let mut bits = half;
        while bits != 0 {
            let i = bits.trailing_zeros() as usize & 31;
            bits &= bits - 1;
            let s = dot(w, &rows[i]);
            let a = base + i;
            keep(a & (MAX_ACTIONS - 1), s);
            #[allow(clippy::neg_cmp_op_on_partial_ord)]
            if !(s <= best) {
                (best, at) = (s, a);
            }
        }
    }
    ActionIndex::new(at)
}

/// The first of the highest scores, as [`select`] compares them one by one: the first is taken,
/// and every later one that is not at most the best so far (a NaN takes its place, and is
/// replaced by whatever follows).
#[inline(always)]
fn choose(scored: impl Iterator<Item = (ActionIndex, f32)>) -> Option<ActionIndex> {
    let mut best: Option<(ActionIndex, f32)> = None;
    for (a, s) in scored {
        match best {
            Some((_, b)) if s <= b => {}
            _ => best = Some((a, s)),
        }
    }
    best.map(|(a, _)| a)
}

/// [`select`] from every allowed action's score: [`first_max`], or the comparisons one by one
/// when a score is NaN (where the two differ).
#[inline(always)]
fn select_among(scores: &[f32; MAX_ACTIONS], allowed: ActionMask) -> Option<ActionIndex> {
    match first_max(scores, allowed) {
        (best, false) => best.map(|(a, _)| a),
        (_, true) => choose(allowed.iter().map(|a| (a, scores[a.get()]))),
    }
}

/// The score of every action, allowed or not, in index order: one pass over the whole table
/// without a test per action, which the compiler vectorises on a `WIDE` target (several actions
/// side by side, each summed in [`dot`]'s order: the same bits as [`score`]). A forbidden
/// action's row is not checked ([`FeatureTable::check`]): its score is whatever it is, never read.
#[inline]
pub(crate) fn all_scores(w: &Weights, table: &FeatureTable) -> [f32; MAX_ACTIONS] {
    let mut out = [0.0f32; MAX_ACTIONS];
    score_all(w, table, &mut out);
    out
}

/// [`all_scores`] written into `out` (no array of scores on the stack to be copied there).
#[inline(always)]
fn score_all(w: &Weights, table: &FeatureTable, out: &mut [f32; MAX_ACTIONS]) {
    match table.columns() {
        // A sealed table's columns, loaded whole.
        Some(columns) => {
            for (a, s) in out.iter_mut().enumerate() {
                *s = column_dot(w, columns, a);
            }
        }
        None => {
            for (s, row) in out.iter_mut().zip(table.rows()) {
                *s = dot(w, row);
            }
        }
    }
}

/// The first allowed action whose value is the largest of the allowed ones that are not NaN, and
/// that value (`None` when every allowed value is NaN or nothing is allowed); and whether some
/// allowed value is NaN. This is where a running maximum in index order (`if v > best`) ends,
/// NaNs passed over; here the maximum runs in eight running maxima side by side, each keeping
/// the chunk where it last grew (the first of its equals: `v > best` keeps the first), without a
/// branch, which the compiler vectorises on a `WIDE` target; then the lanes' maxima are compared
/// (a zero of either sign equals the other), the lowest index winning among equals.
///
/// Every action allowed (a round where nothing is forbidden), on a `WIDE` target, takes a copy
/// of the same passes without the mask's test per value.
#[inline]
pub(crate) fn first_max(
    values: &[f32; MAX_ACTIONS],
    allowed: ActionMask,
) -> (Option<(ActionIndex, f32)>, bool) {
    if WIDE && allowed == ActionMask::ALL {
        first_max_of::<true>(values, allowed)
    } else {
        first_max_of::<false>(values, allowed)
    }
}

/// [`first_max`], every action allowed when `ALL`.
#[inline(always)]
fn first_max_of<const ALL: bool>(
    values: &[f32; MAX_ACTIONS],
    allowed: ActionMask,
) -> (Option<(ActionIndex, f32)>, bool) {
    let bits = allowed.bits();
    let mut lanes = [f32::NEG_INFINITY; 8];
    let mut at = [0u32; 8];
    let mut nan = [false; 8];
    const _: () = assert!(MAX_ACTIONS.is_multiple_of(8));
    for (k, chunk) in values.as_chunks::<8>().0.iter().enumerate() {
        let word = (bits >> (8 * k)) as u32;
        for j in 0..8 {
            let (here, v) = (ALL || word & 1 << j != 0, chunk[j]);
            nan[j] |= here & v.is_nan();
            let up = here & (v > lanes[j]);
            lanes[j] = if up { v } else { lanes[j] };
            at[j] = if up { k as u32 } else { at[j] };
        }
    }
    // A lane that grew holds a value above −∞ (never NaN), found at index 8·at + j, the first of
    // its equals in that lane; across the lanes the largest, the lowest index among equals: the
    // first index of all whose value equals the maximum.
    let mut best: Option<(usize, f32)> = None;
    for j in 0..8 {
        let (m, i) = (lanes[j], 8 * at[j] as usize + j);
        if m == f32::NEG_INFINITY {
            continue;
        }
        match best {
            Some((b, bm)) if m < bm || (m == bm && i > b) => {}
            _ => best = Some((i, m)),
        }
    }
    let first = match best {
        Some((i, _)) => ActionIndex::new(i).map(|a| (a, values[i])),
        // No allowed value above −∞: the first allowed −∞, if any.
        None => allowed
            .iter()
            .find(|a| values[a.get()] == f32::NEG_INFINITY)
            .map(|a| (a, values[a.get()])),
    };
    (first, nan.contains(&true))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn idx(i: usize) -> ActionIndex {
        ActionIndex::new(i).unwrap()
    }

    #[test]
    fn ties_go_to_the_lowest_allowed_index() {
        let table = FeatureTable::ZERO;
        let w = [1.0; 6];
        assert_eq!(select(&w, &table, ActionMask::ALL), Some(idx(0)));
        let mask: ActionMask = [idx(9), idx(4), idx(40)].into_iter().collect();
        assert_eq!(select(&w, &table, mask), Some(idx(4)));
    }

    /// `first_max` as it was first written: a running maximum over the allowed values in index
    /// order, then the first allowed value equal to it.
    fn first_max_reference(
        values: &[f32; MAX_ACTIONS],
        allowed: ActionMask,
    ) -> (Option<(ActionIndex, f32)>, bool) {
        let (mut max, mut nan) = (f32::NEG_INFINITY, false);
        for a in allowed {
            let v = values[a.get()];
            nan |= v.is_nan();
            if v > max {
                max = v;
            }
        }
        let first = allowed
            .iter()
            .find(|a| values[a.get()] == max)
            .map(|a| (a, values[a.get()]));
        (first, nan)
    }

    /// Few distinct values (zeros of both signs, infinities, NaN) so that ties are the rule; the
    /// first seven are scores, the last one more value for `first_max`.
    const SET: [f32; 8] = [
        f32::NEG_INFINITY,
        -1.0,
        -0.0,
        0.0,
        1.0,
        f32::INFINITY,
        f32::NAN,
        0.5,
    ];

    /// A xorshift generator of `u64`s from `seed` (nonzero): the tests' cases, without a crate.
    fn xorshift(mut state: u64) -> impl FnMut() -> u64 {
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        }
    }

    #[test]
    fn first_max_is_the_first_of_the_running_maximum() {
        let mut next = xorshift(0x9e37_79b9_7f4a_7c15);
        for case in 0..20_000 {
            // Some cases draw from fewer values: only −∞, −∞ and −1, no NaN, no 0.5.
            let span = [8, 2, 1, 7, 5][case % 5];
            let values: [f32; MAX_ACTIONS] =
                core::array::from_fn(|_| SET[(next() % span) as usize]);
            let allowed = match case % 4 {
                0 => ActionMask::ALL,
                1 => ActionMask::from_bits(next() & next()),
                2 => ActionMask::from_bits(1 << (next() % 64)),
                _ => ActionMask::from_bits(next()),
            };
            let (got, want) = (
                first_max(&values, allowed),
                first_max_reference(&values, allowed),
            );
            let bits =
                |r: (Option<(ActionIndex, f32)>, bool)| (r.0.map(|(a, v)| (a, v.to_bits())), r.1);
            assert_eq!(bits(got), bits(want), "{values:?} {allowed:?}");
        }
    }

    #[test]
    fn the_cars_select_is_choose() {
        // The car's `select_keeping` (the host takes `select_among`) against `choose`, on tables
        // of few values (ties, zeros of both signs, infinities, NaN scores).
        let mut next = xorshift(0x2545_f491_4f6c_dd1d);
        for case in 0..20_000 {
            let span = [7, 6, 5, 2][case % 4];
            let mut table = FeatureTable::ZERO;
            for a in 0..MAX_ACTIONS {
                table[idx(a)] = core::array::from_fn(|_| SET[(next() % span) as usize]);
            }
            let w: Weights = core::array::from_fn(|_| SET[1 + (next() % 4) as usize]);
            let allowed = match case % 3 {
                0 => ActionMask::ALL,
                1 => ActionMask::from_bits(next() & next()),
                _ => ActionMask::from_bits(next()),
            };
            let mut kept = [0.0f32; MAX_ACTIONS];
            let got = select_keeping(&w, &table, allowed, |a, s| kept[a] = s);
            let want = choose(allowed.iter().map(|a| (a, score(&w, &table, a))));
            assert_eq!(got, want, "{table:?} {w:?} {allowed:?}");
            for a in allowed {
                assert_eq!(kept[a.get()].to_bits(), score(&w, &table, a).to_bits());
            }
        }
    }

    #[test]
    fn forbidden_actions_are_never_chosen() {
        let mut table = FeatureTable::ZERO;
        table[idx(3)][0] = 10.0;
        table[idx(8)][0] = 5.0;
        let w = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let mut mask = ActionMask::ALL;
        assert_eq!(select(&w, &table, mask), Some(idx(3)));
        mask.remove(idx(3));
        assert_eq!(select(&w, &table, mask), Some(idx(8)));
    }
}
