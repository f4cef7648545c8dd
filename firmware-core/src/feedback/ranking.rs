//! A ranking of K shown actions, or the best of K (APReL: Bıyık et al. 2022; Baxter et al.'s
//! users ranked shown trajectories; Jain et al. 2015's re-ranking).
//!
//! The teacher is shown K actions and orders them, best first ([`RankingFeedback::ordered`]), or
//! only picks the best of them (not ordered). With `d_j(a) = ‖φ(a_(j)) − φ(a)‖` the feature
//! distance from action `a` to the shown action ranked `j`:
//!
//! ```text
//! Δ(a) = Σ_{j=2..K} c_j (d_1(a) − d_j(a)) / Σ_{j=2..K} c_j,   c_j = j − 1 (ordered) or 1 (best of K)
//! ```
//!
//! Each term is the paper's preference pseudo-loss (equation for `Δ` in section 5.3) of the
//! best shown action over the one ranked `j`; for K = 2 the sum is exactly the preference's
//! `‖φ_p − φ_a‖ − ‖φ_np − φ_a‖` (tested bit for bit). An ordered ranking weighs the pair with
//! the action ranked `j` by `j − 1`: the lower the teacher put an action, the harder the
//! pseudo-loss pushes away from it.
//!
//! **Why only the pairs with the best.** APReL's ranking likelihood (Plackett–Luce) is a chain
//! of best-of choices among the actions left, and summing the preference pseudo-loss over every
//! ordered pair `i < j` would use the whole order. But by the triangle inequality each term
//! `d_1(a) − d_j(a) ≥ −‖φ(a_(1)) − φ(a_(j))‖` is smallest at `a = a_(1)`, so the sum above is
//! always minimised by the best shown action (the paper's assumption 1 whenever the teacher's
//! best is among the shown), while with the pairs among the lower-ranked actions added it is
//! not: on random 6-feature scenes with 3 to 6 shown actions the all-pairs sum's minimiser was
//! another action in 19% of 20 000 draws. The order below the best therefore enters through the
//! weights only.
//!
//! K is 2 to [`MAX_RANKED`]; the actions must differ and be allowed in the round.
//!
//! ```
//! use firmware_core::{ActionIndex, RankingFeedback};
//! let a = |i| ActionIndex::new(i).unwrap();
//! let r = RankingFeedback::new(&[a(4), a(0), a(9)], true).unwrap();
//! assert_eq!(r.best(), Some(a(4)));
//! assert_eq!(r.as_slice().len(), 3);
//! ```

use core::hash::{Hash, Hasher};

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::{Round, distance};
use crate::action::{ActionIndex, MAX_ACTIONS};
use crate::error::LearnError;

/// The most actions one ranking orders.
pub const MAX_RANKED: usize = 8;

/// K shown actions, best first, and whether the rest is ordered too.
#[derive(Clone, Copy, Debug)]
pub struct RankingFeedback {
    actions: [ActionIndex; MAX_RANKED],
    len: u8,
    /// Whether the actions after the best are in the teacher's order too (a ranking) or only
    /// the best was picked (best of K).
    pub ordered: bool,
}

impl RankingFeedback {
    /// The ranking of `actions`, best first; `None` when there are more than [`MAX_RANKED`].
    /// Whether it is one the pseudo-loss takes (two or more, all different) is checked when it
    /// is used.
    pub fn new(actions: &[ActionIndex], ordered: bool) -> Option<Self> {
        if actions.len() > MAX_RANKED {
            return None;
        }
        let mut out = [ActionIndex::FIRST; MAX_RANKED];
        out[..actions.len()].copy_from_slice(actions);
        Some(Self {
            actions: out,
            len: actions.len() as u8,
            ordered,
        })
    }

    /// The shown actions, best first.
    pub fn as_slice(&self) -> &[ActionIndex] {
        &self.actions[..usize::from(self.len).min(MAX_RANKED)]
    }

    /// The best shown action.
    pub fn best(&self) -> Option<ActionIndex> {
        self.as_slice().first().copied()
    }

    /// Two or more actions, all different.
    pub fn check(&self) -> Result<(), LearnError> {
        let s = self.as_slice();
        if s.len() < 2 {
            return Err(LearnError::DegenerateFeedback);
        }
        let mut seen = 0u64;
        for a in s {
            let bit = 1u64 << a.get();
            if seen & bit != 0 {
                return Err(LearnError::DegenerateFeedback);
            }
            seen |= bit;
        }
        Ok(())
    }
}

impl PartialEq for RankingFeedback {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice() && self.ordered == other.ordered
    }
}

impl Eq for RankingFeedback {}

impl Hash for RankingFeedback {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.as_slice().hash(state);
        self.ordered.hash(state);
    }
}

/// On the wire: the shown actions as a sequence (a length byte, then one byte each), then
/// `ordered`.
#[derive(Serialize)]
struct WireRef<'a> {
    actions: &'a [ActionIndex],
    ordered: bool,
}

#[derive(Deserialize)]
struct Wire {
    actions: heapless::Vec<ActionIndex, MAX_RANKED>,
    ordered: bool,
}

impl Serialize for RankingFeedback {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        WireRef {
            actions: self.as_slice(),
            ordered: self.ordered,
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for RankingFeedback {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let w = Wire::deserialize(d)?;
        // At most MAX_RANKED: heapless refuses a longer sequence.
        Self::new(&w.actions, w.ordered)
            .ok_or_else(|| serde::de::Error::custom("too many ranked actions"))
    }
}

#[cfg(feature = "max-size")]
impl postcard::experimental::max_size::MaxSize for RankingFeedback {
    // A varint length (one byte up to 127), one byte per action, the flag.
    const POSTCARD_MAX_SIZE: usize = 1 + MAX_RANKED + 1;
}

impl super::PseudoLossSource for RankingFeedback {
    fn write_pseudo_loss(
        &self,
        round: &Round<'_>,
        out: &mut [f32; MAX_ACTIONS],
    ) -> Result<(), LearnError> {
        self.check()?;
        let shown = self.as_slice();
        for &a in shown {
            round.require_allowed(a)?;
        }
        let best = round.phi(shown[0]);
        let weight = |j: usize| if self.ordered { j as f32 } else { 1.0 };
        let mut total = 0.0f32;
        for j in 1..shown.len() {
            total += weight(j);
        }
        for a in round.allowed() {
            let phi = round.phi(a);
            let d1 = distance(best, phi);
            let mut s = 0.0f32;
            for (j, &other) in shown.iter().enumerate().skip(1) {
                s += weight(j) * (d1 - distance(round.phi(other), phi));
            }
            out[a.get()] = s / total;
        }
        Ok(())
    }
}
