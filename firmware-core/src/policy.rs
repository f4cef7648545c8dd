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
use crate::feature::{FeatureTable, Weights, dot};

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

/// The allowed action of highest score, lowest index on ties; `None` when nothing is allowed.
///
/// With finite weights and a checked table (see [`FeatureTable::check`]) no score is NaN, so
/// the result is the exact argmax.
pub fn select(w: &Weights, table: &FeatureTable, allowed: ActionMask) -> Option<ActionIndex> {
    let mut best: Option<(ActionIndex, f32)> = None;
    for a in allowed {
        let s = score(w, table, a);
        match best {
            Some((_, b)) if s <= b => {}
            _ => best = Some((a, s)),
        }
    }
    best.map(|(a, _)| a)
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
