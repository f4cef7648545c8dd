//! # firmware-core: learning online from corrective feedback, on a microcontroller
//!
//! The learner of *Learning Online from Corrective Feedback: A Meta-Algorithm for Robotics*
//! (Schmittle, Choudhury, Srinivasa, CoRL 2020) for a MuSHR-class racecar, written to run on the
//! car's own Cortex-M4F: `no_std`, no heap (there is no `alloc` in this crate, so a `Vec` or a
//! `Box` does not compile), no `unsafe`, fixed-size buffers, `f32` arithmetic.
//!
//! ## What happens in one control tick
//!
//! ```text
//!  observation ──evaluate──▶ φ[64][F] + mask ──policy──▶ a_t = argmax_a w·φ(a)
//!                                                              │
//!  teacher corrects? ── no ──▶ nothing changes                 ▼
//!        │ yes                                        the car tracks a_t
//!        ▼
//!  feedback ──▶ pseudo-loss Δ[64] ──▶ surrogate ℓ(w), subgradient g ──▶ learner step
//! ```
//!
//! * [`observation`]: what the car observes in one tick (a 64-beam downsampled scan, up to 8
//!   semantic objects, the path reference 1 m ahead, its speed), checked once into a
//!   [`ValidObservation`](observation::ValidObservation) before use.
//! * [`lattice`]: the 64 candidate trajectories, fixed at compile time by `build.rs` (49 cruise
//!   shapes of two curvature segments, lane shifts included, and 15 slow creep arcs).
//! * [`evaluator`]: from one observation, the features of all 64 trajectories and the collision
//!   mask; exact, and several times cheaper than brute force.
//! * [`feature`]: the feature layout φ(s, a) ∈ R^[`FEATURE_COUNT`] and the per-tick
//!   [`FeatureTable`] of all [`MAX_ACTIONS`] actions.
//! * [`policy`]: `argmax_a w·φ(s, a)` over the actions an [`ActionMask`] allows, ties to the
//!   lowest index.
//! * [`feedback`]: what the teacher says (the action it wanted, a preference between two actions,
//!   spoken rules, a corrected trajectory, a ranking of K actions, a reward, correct/incorrect,
//!   good/bad over the last ticks, an E-stop: every kind of the paper's Table 1) and the
//!   [`PseudoLoss`] each becomes; any mix of kinds may arrive in one stream.
//! * [`surrogate`]: the generalized hinge (and the perceptron loss) over a pseudo-loss: value and
//!   subgradient.
//! * [`learner`]: online learners behind [`OnlineLearner`] (OGD constant and `1/√t`, averaged OGD,
//!   diagonal AdaGrad, the Coactive perceptron, optional L2-ball projection), checked parameters,
//!   and versioned snapshots.
//! * [`agent`]: all of the above for one car: act on an observation, learn from feedback about
//!   one of the last ticks.

//! ## Sign convention
//!
//! The policy maximises `w·φ`. The teacher's latent loss of action `a` is
//! `L(a) = w*·(φ(a*) − φ(a)) ≥ 0`, `a* = argmax w*·φ`. Surrogates are minimised in `w`; the
//! generalized hinge's subgradient is `φ_sel − φ_â` and OGD steps `w ← w + η(φ_â − φ_sel)`,
//! which is the paper's rule (the paper writes the opposite sign because its policy is an
//! argmin). See [`surrogate`].
//!
//! ## The default learner and why
//!
//! [`LearnerParams::default`] is constant-step OGD acting on its averaged iterate (η = 0.01),
//! [`AveragedOgd`]; the paper's plain OGD is [`LearnerParams::paper`]. A real teacher is noisy:
//! with 20% of the answers replaced by random actions, plain OGD's iterate keeps being thrown off
//! by each wrong answer while the average settles (`tests/integration/learning.rs`, seeds 0–3:
//! 0.7–5.7% of a random policy's latent loss against at most 0.011%). Absolute feedback (the
//! teacher's action) is applied at the raw iterate, relative feedback (preferences, spoken rules)
//! at the average that chose the judged action ([`PseudoLossSource::is_absolute`]). In the simulated
//! households a table of every learner against every kind of feedback (`docs/learners.md`,
//! `host-sim learners`) has `host-sim run` default to AdaGrad for action and semantic feedback
//! and the Coactive perceptron for preferences; the car's default here stays averaged OGD, the
//! one learner that takes any mix of feedback in one stream at its right iterate.
//!
//! ## Bad input
//!
//! Nothing from outside is trusted: features must be finite and within [`FEATURE_BOUND`], pseudo-
//! losses within [`PSEUDO_LOSS_BOUND`], subgradients within [`GRADIENT_BOUND`], and no step may
//! take a weight beyond [`WEIGHT_BOUND`]. A refused call returns a small `Copy` error
//! ([`LearnError`], [`UpdateError`], [`ParamError`], [`SnapshotError`]) and changes nothing, so
//! the weights are always finite.
//!
//! ## Determinism
//!
//! Every sum runs in index order, no fused multiply-add is used, and square roots go through
//! `libm` (correctly rounded), so the host and the Cortex-M4F compute bit-identical weights from
//! the same inputs. The crate reads no clock and draws no random number: time and randomness
//! belong to the caller.
//!
//! ## Memory and time
//!
//! Nothing is allocated; everything lives in the caller's statics or stack. An [`agent::Agent`]
//! is 9 336 bytes on the car: the learner (under 100 B), the feature tables of the last four
//! ticks (1.5 KiB each) and its evaluator's scratch (2 944 bytes, reused from tick to tick);
//! off the car each tick also keeps select's 64 scores. The lattice and the evaluator's
//! precomputed tables are `static` data in flash.
//!
//! On the car's Cortex-M4F one tick (evaluate + select) costs 8.5 K instructions in open space and
//! 42 K on average over real simulator ticks (`scripts/measure-firmware`, `docs/firmware.md`);
//! on x86-64 it is 0.8–6 µs (`cargo bench -p firmware-core --features bench --bench evaluator`) and
//! a learning round (select + update) well under 2 µs (`--bench learner`, group `round`).

//! ## Cargo features
//!
//! * `max-size`: derive postcard's `MaxSize` for the types that travel on the wire (used by the
//!   `protocol` crate to bound message sizes at compile time).
//! * `std`: links `std` for its square root, the same bits as `libm`'s, which the compiler
//!   vectorises on the host (host-sim, hil_mock and the tests turn it on; the car's firmware
//!   never does).

#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

#[cfg(all(feature = "std", not(test)))]
extern crate std;

pub mod action;
pub mod agent;
pub mod error;
pub mod evaluator;
pub mod feature;
pub mod feedback;
pub mod lattice;
pub mod learner;
pub mod observation;
pub mod policy;
pub mod surrogate;
pub mod trig;

pub use action::{ActionIndex, ActionMask, ActionOutOfRange, MAX_ACTIONS};
pub use error::{LearnError, ParamError, SnapshotError, UpdateError};
pub use feature::{
    FEATURE_BOUND, FEATURE_COUNT, Feature, FeatureError, FeatureTable, Features, WEIGHT_BOUND,
    Weights, dot,
};
pub use feedback::{
    ActionFeedback, CorrectnessFeedback, EStopFeedback, Feedback, FeedbackKind, MAX_RANKED,
    MAX_SPAN, PSEUDO_LOSS_BOUND, PerturbationFeedback, Polarity, PreferenceFeedback, PseudoLoss,
    PseudoLossSource, RankingFeedback, RewardFeedback, Round, SEMANTIC_LOSS, SemanticFeedback,
    SpanFeedback, Statement, WRONG_ACTION_LOSS, pseudo_loss,
};
pub use learner::{
    AdaGrad, AveragedOgd, Coactive, GRADIENT_BOUND, Learner, LearnerKind, LearnerParams,
    LearnerSnapshot, LearnerState, MAX_STEP, Ogd, OnlineLearner, Outcome, PAPER_STEP,
    SNAPSHOT_VERSION, ValidLearnerParams, learn, learn_from_loss,
};
pub use surrogate::{Surrogate, SurrogateEval};
