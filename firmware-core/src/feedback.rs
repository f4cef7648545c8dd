//! Feedback and the pseudo-losses it becomes.
//!
//! A correction from the teacher is turned into a *pseudo-loss* `Δ(s, ·)` over the actions of
//! the round it refers to (paper, sections 5 and 6; DESIGN section 4). Every pseudo-loss is
//! shifted so that its minimum over the allowed actions is 0; `â = argmin Δ` is the action the
//! feedback points to.
//!
//! The paper's three kinds, then the rest of its Table 1 and beyond (each in a file of its own,
//! with the cited work's definition and where ours differs):
//!
//! | feedback | `Δ(a)` before the shift | points at a better action? |
//! |---|---|---|
//! | [`ActionFeedback`] (the teacher's action `a*`) | 0 for `a*`, [`WRONG_ACTION_LOSS`] for every other action | yes: `a*` |
//! | [`PreferenceFeedback`] (`a_p` preferred over `a_np`) | `‖φ_p − φ_a‖ − ‖φ_np − φ_a‖` | the better of two |
//! | [`SemanticFeedback`] (statements such as "avoid doors") | per statement: 0 for an action that does strictly better than the learner's choice on the statement's quantity, [`SEMANTIC_LOSS`] otherwise; statements add up | the actions better on the subjects named |
//! | [`PerturbationFeedback`] (the corrected trajectory's features `φ̄`, [`perturbation`]) | `‖φ(a) − φ̄‖` | the action nearest the correction |
//! | [`RankingFeedback`] (K shown actions, best first, [`ranking`]) | `Σ_j c_j (‖φ_(1) − φ_a‖ − ‖φ_(j) − φ_a‖) / Σ_j c_j` | the best of K |
//! | [`RewardFeedback`] (`r ∈ [−1, 1]` for the executed `a_t`, [`executed`]) | `r < 0`: [`EXECUTED_LOSS`]·`|r|` for `a_t`, 0 elsewhere; `r > 0`: 0 for `a_t`, [`EXECUTED_LOSS`]·`r` elsewhere | no: only "not `a_t`" (or "`a_t`") |
//! | [`CorrectnessFeedback`] (`a_t` correct or incorrect, [`executed`]) | incorrect: [`EXECUTED_LOSS`] for `a_t`, 0 elsewhere; correct: the reverse | no |
//! | [`EStopFeedback`] (the teacher stopped the car, [`executed`]) | [`EXECUTED_LOSS`] for `a_t`, 0 elsewhere | no |
//! | [`SpanFeedback`] (good/bad over the last ticks, [`span`]) | correct/incorrect of each labelled tick's `a_t`, each tick the car still holds | no |
//!
//! A statement's *quantity* is its feature's value, except for a statement about the path ("stay
//! on the path"): the paper judges the path by **cross-track error**, so such a statement compares
//! the cross-track error of each trajectory's end against the round's path reference
//! ([`crate::evaluator::cross_track_errors`]), not [`Feature::Path`] (which adds the along-track
//! error). A round learns its path reference with [`Round::with_reference`] (the
//! [`crate::agent::Agent`] remembers each tick's); a statement about the path in a round without
//! one is refused ([`LearnError::NoPathReference`]).
//!
//! Every kind is bounded (at most [`MAX_RANKED`] distances per action, no loop over anything
//! longer than the 64 actions), allocates nothing and refuses what is malformed before it
//! writes anything: an action the round does not allow, a degenerate feedback (a preference or
//! a ranking with an action twice, no statement, a reward of 0, a span of no tick), a number
//! out of its stated range ([`LearnError::OutOfRange`]).
//!
//! No correction means no pseudo-loss and no update: there is nothing to call.
//!
//! New kinds of feedback slot in beside these by implementing [`PseudoLossSource`]; everything
//! downstream (surrogate, learners) sees only the [`PseudoLoss`].
//!
//! ```
//! use firmware_core::{ActionFeedback, ActionIndex, ActionMask, FeatureTable, Round, pseudo_loss};
//!
//! let table = FeatureTable::ZERO;
//! let chosen = ActionIndex::new(0).unwrap();
//! let round = Round::new(&table, ActionMask::ALL, chosen).unwrap();
//! let teacher = ActionFeedback { action: ActionIndex::new(9).unwrap() };
//! let delta = pseudo_loss(&teacher, &round).unwrap();
//! assert_eq!(delta[ActionIndex::new(9).unwrap()], 0.0);
//! assert_eq!(delta[chosen], 100.0);
//! ```

pub mod executed;
pub mod perturbation;
pub mod ranking;
pub mod span;

pub use executed::{
    CorrectnessFeedback, EStopFeedback, EXECUTED_LOSS, REWARD_STEPS, RewardFeedback,
};
pub use perturbation::{DeformedTrajectory, Milli, PUSH, PerturbationFeedback};
pub use ranking::{MAX_RANKED, RankingFeedback};
pub use span::{MAX_SPAN, SpanFeedback};

use core::ops::Index;

use serde::{Deserialize, Serialize};

use crate::action::{ActionIndex, ActionMask, MAX_ACTIONS};
use crate::error::LearnError;
use crate::evaluator::cross_track_errors;
use crate::feature::{Columns, FEATURE_COUNT, Feature, FeatureTable, Features, Weights, ieee_sqrt};
use crate::observation::{PathReference, REFERENCE_COORDINATE_BOUND};
use crate::policy::WIDE;

/// `Δ` of every action but the teacher's, for action feedback (the paper's value).
pub const WRONG_ACTION_LOSS: f32 = 100.0;

/// `Δ` of an action that does not beat the learner's choice on a statement's feature.
pub const SEMANTIC_LOSS: f32 = 100.0;

/// Largest magnitude a pseudo-loss entry may have before the shift.
pub const PSEUDO_LOSS_BOUND: f32 = 1.0e6;

/// The learner's side of one round: the features of the tick, the allowed actions, the action
/// the learner chose and, when known, the tick's path reference and the scores the choice was
/// made with. Feedback is always judged against a round.
#[derive(Clone, Copy, Debug)]
pub struct Round<'a> {
    features: &'a FeatureTable,
    allowed: ActionMask,
    chosen: ActionIndex,
    reference: Option<PathReference>,
    scored: Option<Scored<'a>>,
}

/// Scores of a round's allowed actions and the weights they are of.
#[derive(Clone, Copy, Debug)]
struct Scored<'a> {
    weights: Weights,
    scores: &'a [f32; MAX_ACTIONS],
}

impl<'a> Round<'a> {
    /// Checks and builds a round: at least one allowed action, `chosen` allowed, and the features
    /// of the allowed actions finite and within [`crate::FEATURE_BOUND`].
    pub fn new(
        features: &'a FeatureTable,
        allowed: ActionMask,
        chosen: ActionIndex,
    ) -> Result<Self, LearnError> {
        if allowed.is_empty() {
            return Err(LearnError::NoAllowedAction);
        }
        if !allowed.contains(chosen) {
            return Err(LearnError::ActionNotAllowed(chosen));
        }
        features.check(allowed)?;
        Ok(Self {
            features,
            allowed,
            chosen,
            reference: None,
            scored: None,
        })
    }

    /// The round with the scores `w · φ(a)` of its allowed actions at the weights `w` (what
    /// [`crate::policy::select_scored`] keeps while it chooses): the surrogate takes them instead
    /// of scoring the table again when it is evaluated at weights of the same bits (for the
    /// averaged learner, relative feedback, linearized at the weights that chose), and scores the
    /// table itself at any other weights. Each allowed entry must be `dot(w, φ(a))` of this
    /// round's table, as `select_scored` leaves it; forbidden entries are never read.
    pub fn with_scores(mut self, w: &Weights, scores: &'a [f32; MAX_ACTIONS]) -> Self {
        self.scored = Some(Scored {
            weights: *w,
            scores,
        });
        self
    }

    /// The scores the round carries, when they are at weights of the same bits as `w`.
    #[inline]
    pub(crate) fn scores_at(&self, w: &Weights) -> Option<&'a [f32; MAX_ACTIONS]> {
        let scored = self.scored.as_ref()?;
        let same = scored
            .weights
            .iter()
            .zip(w)
            .all(|(x, y)| x.to_bits() == y.to_bits());
        same.then_some(scored.scores)
    }

    /// The round with the tick's path reference (from its observation), which statements about
    /// the path are judged against. Refused ([`LearnError::BadPathReference`]) when a coordinate
    /// is not finite or beyond [`REFERENCE_COORDINATE_BOUND`], or the heading is outside
    /// `[−π, π]`: the bounds [`crate::observation::Observation::validate`] checks.
    pub fn with_reference(mut self, reference: PathReference) -> Result<Self, LearnError> {
        let ok = |v: f32, bound: f32| v.is_finite() && libm::fabsf(v) <= bound;
        if !(ok(reference.x, REFERENCE_COORDINATE_BOUND)
            && ok(reference.y, REFERENCE_COORDINATE_BOUND)
            && ok(reference.heading, core::f32::consts::PI))
        {
            return Err(LearnError::BadPathReference);
        }
        self.reference = Some(reference);
        Ok(self)
    }

    /// The tick's path reference, if the round has one.
    #[inline]
    pub fn reference(&self) -> Option<&PathReference> {
        self.reference.as_ref()
    }

    /// The features of every action.
    #[inline]
    pub fn features(&self) -> &'a FeatureTable {
        self.features
    }

    /// The allowed actions.
    #[inline]
    pub fn allowed(&self) -> ActionMask {
        self.allowed
    }

    /// The action the learner chose.
    #[inline]
    pub fn chosen(&self) -> ActionIndex {
        self.chosen
    }

    /// `φ(s, a)`.
    #[inline]
    pub fn phi(&self, a: ActionIndex) -> &'a Features {
        &self.features[a]
    }

    fn require_allowed(&self, a: ActionIndex) -> Result<(), LearnError> {
        if self.allowed.contains(a) {
            Ok(())
        } else {
            Err(LearnError::ActionNotAllowed(a))
        }
    }
}

/// A pseudo-loss `Δ(s, ·)`: finite, at least 0 on every allowed action and 0 on at least one.
/// Entries of forbidden actions are 0 and never read.
#[derive(Clone, PartialEq, Debug)]
pub struct PseudoLoss {
    values: [f32; MAX_ACTIONS],
    /// Bit `i` set when entry `i` is 0 (of either sign): the allowed actions holding the minimum,
    /// and every forbidden one. Low word first: two `u32`s keep the struct 4-aligned (a `u64`
    /// would make each copy on the car's stack 12 bytes larger, not 8).
    zeros: [u32; 2],
    absolute: bool,
}

impl PseudoLoss {
    /// Checks raw values over the allowed actions and shifts them so that their minimum is 0.
    pub fn from_raw(values: [f32; MAX_ACTIONS], allowed: ActionMask) -> Result<Self, LearnError> {
        let mut delta = Self::raw(false);
        delta.values = values;
        delta.shift(allowed)?;
        Ok(delta)
    }

    /// Zeros, to be written raw by a [`PseudoLossSource`] and then [`PseudoLoss::shift`]ed in
    /// place (no second array of raw values on the stack).
    fn raw(absolute: bool) -> Self {
        Self {
            values: [0.0; MAX_ACTIONS],
            zeros: [0; 2],
            absolute,
        }
    }

    /// [`PseudoLossSource::write_pseudo_loss`] of `source` into a fresh pseudo-loss, checked and
    /// shifted in place.
    fn written<S: PseudoLossSource + ?Sized>(
        source: &S,
        round: &Round<'_>,
    ) -> Result<Self, LearnError> {
        let mut delta = Self::raw(source.is_absolute());
        source.write_pseudo_loss(round, &mut delta.values)?;
        delta.shift(round.allowed())?;
        Ok(delta)
    }

    /// [`PseudoLoss::from_raw`]'s check and shift, in place; on `Err` the values are unchanged.
    /// Every action allowed, on a `WIDE` target, takes a copy of the first pass without the
    /// mask's test per entry, and [`subtract_all`] for the second.
    fn shift(&mut self, allowed: ActionMask) -> Result<(), LearnError> {
        if WIDE && allowed == ActionMask::ALL {
            self.shift_of::<true>(allowed)
        } else {
            self.shift_of::<false>(allowed)
        }
    }

    /// [`PseudoLoss::shift`], every action allowed when `ALL`.
    #[inline(always)]
    fn shift_of<const ALL: bool>(&mut self, allowed: ActionMask) -> Result<(), LearnError> {
        let values = &mut self.values;
        // One comparison per entry for the bound, false for NaN and both infinities, and the
        // minimum without branches, in eight running minima side by side (eight actions at a
        // time, each bit of the mask tested at a constant position) rather than one chain of 64
        // dependent comparisons. Every entry equal to the minimum has its bits but for the sign
        // of a zero, which the first allowed zero in index order gives, as one running minimum
        // would (`v < min` keeps the first of equals).
        let bits = allowed.bits();
        let mut good = true;
        let mut lanes = [f32::INFINITY; 8];
        const _: () = assert!(MAX_ACTIONS.is_multiple_of(8));
        for (k, chunk) in values.as_chunks::<8>().0.iter().enumerate() {
            for j in 0..8 {
                let here = ALL || lane(bits, k, j);
                let v = chunk[j];
                good &= !here | (v.abs() <= PSEUDO_LOSS_BOUND);
                let lower = if WIDE {
                    here & (v < lanes[j])
                } else {
                    here && v < lanes[j]
                };
                lanes[j] = if lower { v } else { lanes[j] };
            }
        }
        if !good {
            return Err(LearnError::BadPseudoLoss);
        }
        let mut min = f32::INFINITY;
        for m in lanes {
            min = if m < min { m } else { min };
        }
        if min == 0.0
            && let Some(a) = allowed.iter().find(|a| values[a.get()] == 0.0)
        {
            min = values[a.get()];
        }
        if allowed.is_empty() {
            return Err(LearnError::NoAllowedAction);
        }
        // `v − min` is 0 exactly when `v == min` (finite values: no underflow to 0 on the way).
        if ALL {
            self.zeros = split(subtract_all(values, min));
            return Ok(());
        }
        let (mut zeros, mut bytes) = (0u64, [0u8; MAX_ACTIONS / 8]);
        for (k, chunk) in values.as_chunks_mut::<8>().0.iter_mut().enumerate() {
            let mut z = 0u8;
            for (j, v) in chunk.iter_mut().enumerate() {
                let here = ALL || lane(bits, k, j);
                z |= ((!here | (*v == min)) as u8) << j;
                *v = if here { *v - min } else { 0.0 };
            }
            if WIDE {
                bytes[k] = z;
            } else {
                zeros |= (z as u64) << (8 * k);
            }
        }
        if WIDE {
            zeros = u64::from_le_bytes(bytes);
        }
        self.zeros = split(zeros);
        Ok(())
    }

    /// Marks the pseudo-loss as *absolute* (see [`PseudoLossSource::is_absolute`]).
    pub fn with_absolute(mut self, absolute: bool) -> Self {
        self.absolute = absolute;
        self
    }

    /// Whether the pseudo-loss ranks its target above every action on its own, rather than only
    /// relative to the actions its feedback judged (see [`PseudoLossSource::is_absolute`]).
    #[inline]
    pub fn is_absolute(&self) -> bool {
        self.absolute
    }

    /// All entries, indexed by action.
    #[inline]
    pub fn values(&self) -> &[f32; MAX_ACTIONS] {
        &self.values
    }

    /// The entries that are 0, as the bits of an [`ActionMask`]: within the round's allowed
    /// actions, the ones `Δ` points to (`argmin Δ`).
    #[inline]
    pub fn zeros(&self) -> u64 {
        (self.zeros[1] as u64) << 32 | self.zeros[0] as u64
    }
}

impl Index<ActionIndex> for PseudoLoss {
    type Output = f32;
    #[inline]
    fn index(&self, a: ActionIndex) -> &f32 {
        &self.values[a.get()]
    }
}

/// Whether bit `8k + j` of `bits` is set, `j < 8`. On a `WIDE` target as a bit of a 32-bit word,
/// which the compiler tests in every lane of a vector at once (and the running minima without a
/// branch, the zero bits gathered as bytes), where the bits of a byte become byte lanes widened
/// in steps; on the car as a bit of the byte, the code it has always run.
#[inline(always)]
fn lane(bits: u64, k: usize, j: usize) -> bool {
    if WIDE {
        (bits >> (8 * k)) as u32 & 1 << j != 0
    } else {
        (bits >> (8 * k)) as u8 >> j & 1 == 1
    }
}

/// `v − min` for every entry, and the entries equal to `min` as the bits of a mask: a shift's
/// second pass when every action is allowed (on a `WIDE` target). Each comparison is a byte
/// (0 or 1) of an array, which the compiler computes four entries at a time beside the
/// subtractions, in the entries' own order; each eight bytes become eight bits by one
/// multiplication (byte `j`, 0 or 1, lands on bit `56 + j` and nothing carries). Written as bits
/// shifted into a word, the compiler gathered the entries eight apart and shuffled them back:
/// 387 instructions a pass (`examples/round_count preference` under callgrind), where this is
/// straight-line code of about 215 (the whole shift 520 → 355).
#[inline(always)]
fn subtract_all(values: &mut [f32; MAX_ACTIONS], min: f32) -> u64 {
    let mut bytes = [0u8; MAX_ACTIONS];
    for (v, b) in values.iter_mut().zip(bytes.iter_mut()) {
        *b = (*v == min) as u8;
        *v -= min;
    }
    let mut zeros = 0u64;
    for (k, eight) in bytes.as_chunks::<8>().0.iter().enumerate() {
        zeros |= (u64::from_le_bytes(*eight).wrapping_mul(0x0102_0408_1020_4080) >> 56) << (8 * k);
    }
    zeros
}

/// A 64-bit mask as two words, low first (see [`PseudoLoss`]'s `zeros`).
#[inline]
fn split(bits: u64) -> [u32; 2] {
    [bits as u32, (bits >> 32) as u32]
}

/// Anything that becomes a pseudo-loss over a round's actions.
///
/// Implement this to add a kind of feedback. Write the *unshifted* `Δ` of every allowed action;
/// [`pseudo_loss`] checks and shifts it.
pub trait PseudoLossSource {
    /// Writes `Δ(s, a)` for every allowed action `a` of `round` into `out`.
    fn write_pseudo_loss(
        &self,
        round: &Round<'_>,
        out: &mut [f32; MAX_ACTIONS],
    ) -> Result<(), LearnError>;

    /// Whether the feedback names the action the teacher holds best, so that its pseudo-loss
    /// ranks that action above *every* other on its own. True for [`ActionFeedback`]. False
    /// (the default) for feedback that judges actions only relative to the ones it compares or
    /// to the executed one: a preference, a ranking, statements about how the learner's choice
    /// could be better, a reward, correct/incorrect, a span, an E-stop; and for a perturbation,
    /// whose margins are too small to be taken at another iterate (see [`perturbation`]). A learner may apply absolute feedback to any of its iterates, relative feedback
    /// only to the weights that chose the judged action (see [`crate::AveragedOgd`]).
    fn is_absolute(&self) -> bool {
        false
    }

    /// The checked and shifted pseudo-loss: [`PseudoLossSource::write_pseudo_loss`], then
    /// [`PseudoLoss::from_raw`]. An implementation may give the same result by a shorter way.
    fn to_pseudo_loss(&self, round: &Round<'_>) -> Result<PseudoLoss, LearnError> {
        PseudoLoss::written(self, round)
    }
}

/// The shifted pseudo-loss of `source` for `round`.
pub fn pseudo_loss<S: PseudoLossSource + ?Sized>(
    source: &S,
    round: &Round<'_>,
) -> Result<PseudoLoss, LearnError> {
    source.to_pseudo_loss(round)
}

/// The teacher names the action it wanted.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct ActionFeedback {
    /// The teacher's action.
    pub action: ActionIndex,
}

impl PseudoLossSource for ActionFeedback {
    fn write_pseudo_loss(
        &self,
        round: &Round<'_>,
        out: &mut [f32; MAX_ACTIONS],
    ) -> Result<(), LearnError> {
        round.require_allowed(self.action)?;
        for a in round.allowed() {
            out[a.get()] = if a == self.action {
                0.0
            } else {
                WRONG_ACTION_LOSS
            };
        }
        Ok(())
    }

    fn is_absolute(&self) -> bool {
        true
    }

    /// Already shifted: the teacher's action, allowed, holds the minimum 0, and every other
    /// allowed action 100 − 0. The same values as the check and shift of the raw ones, directly.
    fn to_pseudo_loss(&self, round: &Round<'_>) -> Result<PseudoLoss, LearnError> {
        round.require_allowed(self.action)?;
        let bits = round.allowed().bits();
        let mut values = [WRONG_ACTION_LOSS; MAX_ACTIONS];
        for a in ActionMask::from_bits(!bits) {
            values[a.get()] = 0.0;
        }
        values[self.action.get()] = 0.0;
        Ok(PseudoLoss {
            values,
            zeros: split(!bits | 1 << self.action.get()),
            absolute: true,
        })
    }
}

/// The teacher, shown two actions, prefers one.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct PreferenceFeedback {
    /// The action the teacher prefers.
    pub preferred: ActionIndex,
    /// The action the teacher does not prefer.
    pub other: ActionIndex,
}

/// Euclidean distance `‖x − y‖`, summed from index 0.
#[inline]
pub(crate) fn distance(x: &Features, y: &Features) -> f32 {
    ieee_sqrt(squared_distance(x, y))
}

/// `‖x − y‖²`, summed from index 0 ([`distance`] before its root).
#[inline(always)]
fn squared_distance(x: &Features, y: &Features) -> f32 {
    let mut s = 0.0f32;
    for i in 0..FEATURE_COUNT {
        let d = x[i] - y[i];
        s += d * d;
    }
    s
}

/// [`squared_distance`] from `x` to action `a`'s features read from a sealed table's columns:
/// the same operations in the same order.
#[inline(always)]
fn column_squared_distance(x: &Features, columns: &Columns, a: usize) -> f32 {
    let mut s = 0.0f32;
    for i in 0..FEATURE_COUNT {
        let d = x[i] - columns[i][a];
        s += d * d;
    }
    s
}

impl PseudoLossSource for PreferenceFeedback {
    fn write_pseudo_loss(
        &self,
        round: &Round<'_>,
        out: &mut [f32; MAX_ACTIONS],
    ) -> Result<(), LearnError> {
        if self.preferred == self.other {
            return Err(LearnError::DegenerateFeedback);
        }
        round.require_allowed(self.preferred)?;
        round.require_allowed(self.other)?;
        let p = round.phi(self.preferred);
        let np = round.phi(self.other);
        if !WIDE {
            for a in round.allowed() {
                let phi = round.phi(a);
                out[a.get()] = distance(p, phi) - distance(np, phi);
            }
            return Ok(());
        }
        // Every action's entry, allowed or not (a forbidden one is never read), each as
        // `distance` computes it: both squares and both roots of an action in one pass, which the
        // compiler runs four actions side by side (the roots too with the `std` feature, see
        // `ieee_sqrt`), no array of squares between them.
        match round.features().columns() {
            // A sealed table's columns, loaded whole.
            Some(columns) => {
                for (i, v) in out.iter_mut().enumerate() {
                    *v = ieee_sqrt(column_squared_distance(p, columns, i))
                        - ieee_sqrt(column_squared_distance(np, columns, i));
                }
            }
            None => {
                for (v, phi) in out.iter_mut().zip(round.features().rows()) {
                    *v = distance(p, phi) - distance(np, phi);
                }
            }
        }
        Ok(())
    }
}

/// Whether a statement asks to keep away from its subject or to seek it.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub enum Polarity {
    /// "Avoid doors", "keep away from the stairs".
    Avoid,
    /// "Stay on the path", "keep right".
    Prefer,
}

/// One spoken rule: a polarity about a feature's subject.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub struct Statement {
    /// The feature whose subject the statement names.
    pub subject: Feature,
    /// Avoid or prefer that subject.
    pub polarity: Polarity,
}

impl Statement {
    /// Whether the statement is satisfied better by a *higher* value of its feature.
    #[inline]
    pub const fn wants_higher(self) -> bool {
        matches!(self.polarity, Polarity::Avoid) == self.subject.grows_away()
    }
}

/// Semantic feedback: up to one statement per feature ("avoid doors", "stay on the path", ...).
///
/// A statement about [`Feature::Path`] is judged by the cross-track error of each trajectory's
/// end (see the module documentation), every other statement by its feature.
///
/// ```
/// use firmware_core::{Feature, SemanticFeedback};
/// let said = SemanticFeedback::new().avoid(Feature::Door).prefer(Feature::Path);
/// assert_eq!(said.len(), 2);
/// ```
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Default, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub struct SemanticFeedback {
    polarity: [Option<Polarity>; FEATURE_COUNT],
}

impl SemanticFeedback {
    /// No statement yet.
    pub const fn new() -> Self {
        Self {
            polarity: [None; FEATURE_COUNT],
        }
    }

    /// Adds (or replaces) the statement about `statement.subject`.
    pub const fn with(mut self, statement: Statement) -> Self {
        self.polarity[statement.subject.index()] = Some(statement.polarity);
        self
    }

    /// Adds "avoid `subject`".
    pub const fn avoid(self, subject: Feature) -> Self {
        self.with(Statement {
            subject,
            polarity: Polarity::Avoid,
        })
    }

    /// Adds "prefer `subject`".
    pub const fn prefer(self, subject: Feature) -> Self {
        self.with(Statement {
            subject,
            polarity: Polarity::Prefer,
        })
    }

    /// The statement about `subject`, if any.
    pub const fn get(&self, subject: Feature) -> Option<Polarity> {
        self.polarity[subject.index()]
    }

    /// The statements, in feature order.
    pub fn statements(&self) -> impl Iterator<Item = Statement> + '_ {
        Feature::ALL
            .iter()
            .zip(self.polarity.iter())
            .filter_map(|(&subject, p)| p.map(|polarity| Statement { subject, polarity }))
    }

    /// Number of statements.
    pub fn len(&self) -> usize {
        self.polarity.iter().filter(|p| p.is_some()).count()
    }

    /// Whether there is no statement.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl PseudoLossSource for SemanticFeedback {
    fn write_pseudo_loss(
        &self,
        round: &Round<'_>,
        out: &mut [f32; MAX_ACTIONS],
    ) -> Result<(), LearnError> {
        if self.is_empty() {
            return Err(LearnError::DegenerateFeedback);
        }
        // The path is judged by cross-track error: computed once, and only when a statement
        // names it (before anything is written, so a refusal leaves `out` as it was).
        let cross = match self.get(Feature::Path) {
            Some(_) => Some(cross_track_errors(
                round.reference().ok_or(LearnError::NoPathReference)?,
            )),
            None => None,
        };
        // On a wide target every action's entry, allowed or not (a forbidden one is never read).
        if WIDE {
            out.fill(0.0);
        } else {
            for a in round.allowed() {
                out[a.get()] = 0.0;
            }
        }
        let table = round.features();
        for s in self.statements() {
            let higher = s.wants_higher();
            match (&cross, s.subject, table.columns()) {
                (Some(cross), Feature::Path, _) => add_fails(round, higher, out, |a| cross[a]),
                // A sealed table's column, loaded whole.
                (_, subject, Some(columns)) => {
                    let column = &columns[subject.index()];
                    add_fails(round, higher, out, |a| column[a])
                }
                (_, subject, None) => {
                    let (rows, f) = (table.rows(), subject.index());
                    add_fails(round, higher, out, |a| rows[a][f])
                }
            }
        }
        Ok(())
    }
}

/// Adds [`SEMANTIC_LOSS`] to `out` for every allowed action that does not do strictly better
/// than the learner's choice on `quantity` (higher or lower, as the statement wants), and 0 to
/// the others: without a branch, and the same bits (`x + 0 = x` for the `x ≥ 0` here). On a
/// `WIDE` target, every action, allowed or not, side by side.
#[inline(always)]
fn add_fails(
    round: &Round<'_>,
    higher: bool,
    out: &mut [f32; MAX_ACTIONS],
    quantity: impl Fn(usize) -> f32,
) {
    let reference = quantity(round.chosen().get());
    let add = |out: &mut [f32; MAX_ACTIONS], a: usize| {
        let v = quantity(a);
        // `v > reference` or `v < reference`.
        let (x, y) = if higher {
            (v, reference)
        } else {
            (reference, v)
        };
        out[a] += if x > y { 0.0 } else { SEMANTIC_LOSS };
    };
    if WIDE {
        for a in 0..MAX_ACTIONS {
            add(out, a);
        }
    } else {
        for a in round.allowed() {
            add(out, a.get());
        }
    }
}

/// Every kind of feedback the learner takes.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize)]
#[cfg_attr(
    feature = "max-size",
    derive(postcard::experimental::max_size::MaxSize)
)]
pub enum Feedback {
    /// The action the teacher wanted.
    Action(ActionFeedback),
    /// A choice between two actions.
    Preference(PreferenceFeedback),
    /// Spoken rules.
    Semantic(SemanticFeedback),
    /// The features of a corrected trajectory.
    Perturbation(PerturbationFeedback),
    /// A scalar reward for the executed action.
    Reward(RewardFeedback),
    /// The executed action was correct or incorrect.
    Correctness(CorrectnessFeedback),
    /// A good or bad label of the last ticks.
    Span(SpanFeedback),
    /// K shown actions, best first.
    Ranking(RankingFeedback),
    /// The teacher stopped the car.
    EStop(EStopFeedback),
}

/// Every kind of [`Feedback`], without its content: the variant, in the same order.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug)]
#[repr(u8)]
pub enum FeedbackKind {
    /// [`Feedback::Action`].
    Action = 0,
    /// [`Feedback::Preference`].
    Preference = 1,
    /// [`Feedback::Semantic`].
    Semantic = 2,
    /// [`Feedback::Perturbation`].
    Perturbation = 3,
    /// [`Feedback::Reward`].
    Reward = 4,
    /// [`Feedback::Correctness`].
    Correctness = 5,
    /// [`Feedback::Span`].
    Span = 6,
    /// [`Feedback::Ranking`].
    Ranking = 7,
    /// [`Feedback::EStop`].
    EStop = 8,
}

impl FeedbackKind {
    /// Every kind, in variant order.
    pub const ALL: [FeedbackKind; 9] = [
        FeedbackKind::Action,
        FeedbackKind::Preference,
        FeedbackKind::Semantic,
        FeedbackKind::Perturbation,
        FeedbackKind::Reward,
        FeedbackKind::Correctness,
        FeedbackKind::Span,
        FeedbackKind::Ranking,
        FeedbackKind::EStop,
    ];

    /// A short lower-case name: action, preference, semantic, perturbation, reward,
    /// correctness, span, ranking, estop.
    pub const fn name(self) -> &'static str {
        match self {
            FeedbackKind::Action => "action",
            FeedbackKind::Preference => "preference",
            FeedbackKind::Semantic => "semantic",
            FeedbackKind::Perturbation => "perturbation",
            FeedbackKind::Reward => "reward",
            FeedbackKind::Correctness => "correctness",
            FeedbackKind::Span => "span",
            FeedbackKind::Ranking => "ranking",
            FeedbackKind::EStop => "estop",
        }
    }

    /// The kind called `name` (see [`FeedbackKind::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Whether a feedback of this kind can name an action better than the executed one. Reward,
    /// correct/incorrect, spans and E-stops judge the executed action only (see [`executed`]).
    pub const fn points_at_better(self) -> bool {
        matches!(
            self,
            FeedbackKind::Action
                | FeedbackKind::Preference
                | FeedbackKind::Semantic
                | FeedbackKind::Perturbation
                | FeedbackKind::Ranking
        )
    }
}

impl core::fmt::Display for FeedbackKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

impl Feedback {
    /// Its kind.
    pub const fn kind(&self) -> FeedbackKind {
        match self {
            Feedback::Action(_) => FeedbackKind::Action,
            Feedback::Preference(_) => FeedbackKind::Preference,
            Feedback::Semantic(_) => FeedbackKind::Semantic,
            Feedback::Perturbation(_) => FeedbackKind::Perturbation,
            Feedback::Reward(_) => FeedbackKind::Reward,
            Feedback::Correctness(_) => FeedbackKind::Correctness,
            Feedback::Span(_) => FeedbackKind::Span,
            Feedback::Ranking(_) => FeedbackKind::Ranking,
            Feedback::EStop(_) => FeedbackKind::EStop,
        }
    }
}

/// `$body` with `$f` bound to the feedback inside `$fb`, whatever its kind (a `match`, not a
/// trait object: a vtable would keep every kind's every method in the firmware).
macro_rules! each_kind {
    ($fb:expr, $f:ident => $body:expr) => {
        match $fb {
            Feedback::Action($f) => $body,
            Feedback::Preference($f) => $body,
            Feedback::Semantic($f) => $body,
            Feedback::Perturbation($f) => $body,
            Feedback::Reward($f) => $body,
            Feedback::Correctness($f) => $body,
            Feedback::Span($f) => $body,
            Feedback::Ranking($f) => $body,
            Feedback::EStop($f) => $body,
        }
    };
}

impl PseudoLossSource for Feedback {
    fn write_pseudo_loss(
        &self,
        round: &Round<'_>,
        out: &mut [f32; MAX_ACTIONS],
    ) -> Result<(), LearnError> {
        each_kind!(self, f => f.write_pseudo_loss(round, out))
    }

    fn is_absolute(&self) -> bool {
        each_kind!(self, f => f.is_absolute())
    }

    /// Action feedback takes its shortcut; every other kind writes its raw values, checked and
    /// shifted here once (one copy of the check in the firmware, not one per kind).
    fn to_pseudo_loss(&self, round: &Round<'_>) -> Result<PseudoLoss, LearnError> {
        if let Feedback::Action(f) = self {
            return f.to_pseudo_loss(round);
        }
        PseudoLoss::written(self, round)
    }
}

impl From<ActionFeedback> for Feedback {
    fn from(f: ActionFeedback) -> Self {
        Feedback::Action(f)
    }
}

impl From<PreferenceFeedback> for Feedback {
    fn from(f: PreferenceFeedback) -> Self {
        Feedback::Preference(f)
    }
}

impl From<SemanticFeedback> for Feedback {
    fn from(f: SemanticFeedback) -> Self {
        Feedback::Semantic(f)
    }
}

macro_rules! feedback_from {
    ($($t:ident => $v:ident),*) => {$(
        impl From<$t> for Feedback {
            fn from(f: $t) -> Self {
                Feedback::$v(f)
            }
        }
    )*};
}

feedback_from!(
    PerturbationFeedback => Perturbation,
    RewardFeedback => Reward,
    CorrectnessFeedback => Correctness,
    SpanFeedback => Span,
    RankingFeedback => Ranking,
    EStopFeedback => EStop
);
