//! Every kind of feedback in one stream: the single kinds, seeded mixes, the cost-aware teacher,
//! the effort a person spends, and how informative each correction was.
//!
//! # How a run is taught ([`Teaching`])
//!
//! * **one kind** (`host-sim run --feedback KIND`): every correction is of that kind;
//! * **a mix** (`--feedback mix:action=0.2,preference=0.3,semantic=0.5`, or `mix:all` for the
//!   nine kinds in equal parts): at each correction the kind is drawn with the given weights
//!   (any non-negative numbers, at least one positive; they need not add up to 1) from the
//!   teacher's seeded generator ([`Mix`]);
//! * **the cost-aware teacher** (`--feedback cheapest`): at each correction, the kind that is
//!   cheapest for a person ([`EFFORT_SECONDS`]) while still informative (below).
//!
//! Whatever the kind, the teacher is the paper's: the same latent weights, threshold and noise
//! model ([`crate::world::teacher`]); it corrects when its perceived latent loss of the learner's
//! action exceeds the threshold, and what it says is in `world/teacher/kinds.rs`.
//!
//! # Spans
//!
//! A good/bad label covers a stretch of ticks (ARC's critiques of segments). When the kind of a
//! correction is `span`, the teacher does not answer at once: it watches, and labels the
//! stretch of consecutive ticks it would correct once the stretch ends (the next tick it would
//! not correct, or one without an action: the label goes out then, about the stretch's last
//! tick) or reaches [`SPAN_TICKS`] ticks (the label goes out at once). One message, one effort,
//! for up to four ticks. The car learns from each labelled tick it still holds, its last
//! [`TICK_HISTORY`] (`firmware_core::feedback::span`); with four ticks at most and the label
//! out by the tick after the stretch, every tick this teacher labels is still held (a person's
//! longer span would lose its older ticks). While it watches, the teacher gives no other
//! feedback.
//!
//! # Effort ([`EFFORT_SECONDS`])
//!
//! Seconds of a person's time per feedback. The user studies cited by the paper and by issue 15
//! (Bajcsy et al. 2017, Jain et al. 2015, Bıyık et al., Knox and Stone's TAMER, MacGlashan et
//! al.'s COACH, Cui and Niekum's ARC) report task times, numbers of queries or trainer reaction
//! delays, not seconds per feedback of each kind in a form we could take over, so **every number
//! here is our stated guess**, ordered by what a person has to do:
//!
//! | kind | seconds | what the person does (the guess's reasoning) |
//! |---|---:|---|
//! | E-stop | 1.0 | presses a button (TAMER's and COACH's trainers answer within about a second with a key press) |
//! | correctness | 1.0 | says or clicks "wrong" |
//! | reward | 1.5 | picks a score on a scale |
//! | span | 2.0 | watches a stretch, then marks it bad (one label for up to four ticks) |
//! | preference | 3.0 | looks at two drawn trajectories, clicks one |
//! | semantic | 3.0 | says a rule or two ("avoid the doors") |
//! | perturbation | 4.0 | pushes or drags the car's trajectory towards what it wanted |
//! | action | 5.0 | finds the trajectory it wanted among the 64 drawn and clicks it |
//! | ranking | 6.0 | orders four drawn trajectories |
//!
//! # Informative enough ([`INFORMATIVE`])
//!
//! The cost-aware teacher judges a candidate feedback by its own perceived latent loss `L̃`
//! (it knows nothing else): with `M` the minimisers of the candidate's pseudo-loss
//! (`firmware_core::pseudo_loss`, the car's own), its perceived informativeness is
//! `α̃ = (L̃(a_t) − mean_{m∈M} L̃(m)) / (L̃(a_t) − min L̃)`, the paper's assumption 2 measured on
//! the set the feedback points to. It takes the cheapest kind with `α̃ ≥ 0.5` (at least half way
//! from the learner's action to its own best), in the order of the table (ties in seconds in
//! the table's order), and when none reaches it, the kind with the largest `α̃` (the cheaper on
//! ties). It never presses the E-stop: "incorrect" teaches the same at the same cost without
//! stopping the car. It uses no kind it could not give (nothing to say, an indifferent
//! preference).
//!
//! # How informative each correction was ([`Informativeness`])
//!
//! For every correction (every labelled tick the car holds, for a span), with the *true* latent
//! loss `L` and `M` the minimisers of the feedback's pseudo-loss on that tick: `L(a_t)`, the mean
//! of `L` over `M` and its largest value over `M`. The report's α of a kind is
//! `(L(a_t) − mean_M L) / L(a_t)` (the teacher's best has `L = 0`): 1 when the feedback points
//! exactly at the teacher's best, 0 when it points at actions as bad as the learner's, negative
//! when worse; "worst" takes the largest `L` over `M` instead of the mean (the paper's
//! assumption 2 must hold for *the* minimiser, whichever the learner's tie-break picks).

use std::collections::VecDeque;
use std::fmt;

use firmware_core::agent::TICK_HISTORY;
use firmware_core::{
    ActionIndex, Feedback, FeedbackKind, PseudoLoss, Round, SpanFeedback, pseudo_loss,
};
use rand::RngExt;

use crate::world::teacher::{Judgement, Teacher};

/// A person's seconds per feedback of each kind: our stated guesses (see the module
/// documentation), in the order the cost-aware teacher tries them.
pub const EFFORT_SECONDS: [(FeedbackKind, f32); 9] = [
    (FeedbackKind::EStop, 1.0),
    (FeedbackKind::Correctness, 1.0),
    (FeedbackKind::Reward, 1.5),
    (FeedbackKind::Span, 2.0),
    (FeedbackKind::Preference, 3.0),
    (FeedbackKind::Semantic, 3.0),
    (FeedbackKind::Perturbation, 4.0),
    (FeedbackKind::Action, 5.0),
    (FeedbackKind::Ranking, 6.0),
];

/// Seconds of a person's time for one feedback of `kind`.
pub fn effort(kind: FeedbackKind) -> f32 {
    EFFORT_SECONDS
        .iter()
        .find(|(k, _)| *k == kind)
        .map_or(0.0, |(_, s)| *s)
}

/// The perceived informativeness the cost-aware teacher asks of a kind before it takes it.
pub const INFORMATIVE: f32 = 0.5;

/// The longest stretch of ticks a span teacher watches before it labels it: the ticks the car
/// holds.
pub const SPAN_TICKS: u8 = TICK_HISTORY as u8;

/// Weights of a mix are stored in millionths.
const PARTS: f64 = 1.0e6;

/// The largest weight of one kind in a mix.
pub const MAX_MIX_WEIGHT: f64 = 1.0e3;

/// A seeded random mix of kinds: weights in millionths, in [`FeedbackKind`] order.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub struct Mix {
    parts: [u32; 9],
}

impl Mix {
    /// Every kind in equal parts (`mix:all`).
    pub const ALL: Mix = Mix {
        parts: [1_000_000; 9],
    };

    /// Parses what follows `mix:`: `KIND=WEIGHT` pairs separated by commas, or `all`. The error
    /// names the part that is wrong.
    pub fn parse(spec: &str) -> Result<Self, String> {
        if spec.trim() == "all" {
            return Ok(Self::ALL);
        }
        let mut parts = [0u32; 9];
        let mut seen = [false; 9];
        if spec.trim().is_empty() {
            return Err(
                "mix: no kind given (expected KIND=WEIGHT,... or all, e.g. mix:action=0.2,preference=0.8)"
                    .into(),
            );
        }
        for part in spec.split(',') {
            let part = part.trim();
            let Some((name, weight)) = part.split_once('=') else {
                return Err(format!("mix: '{part}' is not KIND=WEIGHT"));
            };
            let (name, weight) = (name.trim(), weight.trim());
            let Some(kind) = FeedbackKind::from_name(name) else {
                return Err(format!(
                    "mix: '{part}': unknown kind '{name}' (kinds: {})",
                    kind_names()
                ));
            };
            let w: f64 = weight
                .parse()
                .map_err(|_| format!("mix: '{part}': weight '{weight}' is not a number"))?;
            if !(w.is_finite() && (0.0..=MAX_MIX_WEIGHT).contains(&w)) {
                return Err(format!(
                    "mix: '{part}': weight {weight} must be a number from 0 to {MAX_MIX_WEIGHT}"
                ));
            }
            let i = kind as usize;
            if seen[i] {
                return Err(format!("mix: '{part}': kind '{name}' given twice"));
            }
            seen[i] = true;
            parts[i] = (w * PARTS).round() as u32;
        }
        if parts.iter().all(|&p| p == 0) {
            return Err(format!(
                "mix: '{spec}': every weight is 0 (at least one must be positive)"
            ));
        }
        Ok(Self { parts })
    }

    /// The weight of `kind` (as given).
    pub fn weight(&self, kind: FeedbackKind) -> f64 {
        self.parts[kind as usize] as f64 / PARTS
    }

    /// The kinds with a positive weight.
    pub fn kinds(&self) -> impl Iterator<Item = FeedbackKind> + '_ {
        FeedbackKind::ALL
            .into_iter()
            .filter(|&k| self.parts[k as usize] > 0)
    }

    /// One kind, drawn with the weights: one uniform integer below their sum.
    pub fn draw<R: rand::Rng + ?Sized>(&self, rng: &mut R) -> FeedbackKind {
        let total: u64 = self.parts.iter().map(|&p| p as u64).sum();
        let mut x = rng.random_range(0..total);
        for k in FeedbackKind::ALL {
            let p = self.parts[k as usize] as u64;
            if x < p {
                return k;
            }
            x -= p;
        }
        FeedbackKind::Action
    }
}

impl fmt::Display for Mix {
    /// `mix:all`, or `mix:KIND=WEIGHT,...` in [`FeedbackKind`] order, the kinds of weight 0 left
    /// out: what [`Mix::parse`] reads back.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if *self == Self::ALL {
            return f.write_str("mix:all");
        }
        let pairs: Vec<String> = self
            .kinds()
            .map(|k| format!("{}={}", k.name(), self.weight(k)))
            .collect();
        write!(f, "mix:{}", pairs.join(","))
    }
}

/// The names of the kinds, for messages.
pub fn kind_names() -> String {
    FeedbackKind::ALL
        .iter()
        .map(|k| k.name())
        .collect::<Vec<_>>()
        .join(", ")
}

/// How the corrections of a run are chosen.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum Teaching {
    /// Always this kind.
    Kind(FeedbackKind),
    /// A kind drawn at each correction.
    Mix(Mix),
    /// The cheapest kind still informative.
    Cheapest,
}

/// One feedback the teacher gives: the tick it is about, what it says, what it cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Given {
    /// The tick the feedback is about.
    pub tick: u32,
    /// The feedback.
    pub feedback: Feedback,
    /// A person's seconds for it ([`effort`]).
    pub effort: f32,
}

impl Given {
    /// Whether the teacher stopped the car (the car stands this tick).
    pub fn halts(&self) -> bool {
        matches!(self.feedback, Feedback::EStop(_))
    }
}

/// How informative one correction was, in true latent loss (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Informativeness {
    /// The step the feedback was given at.
    pub step: u32,
    /// Its kind.
    pub kind: FeedbackKind,
    /// `L(a_t)` of the judged tick.
    pub chosen: f32,
    /// The mean `L` over the pseudo-loss's minimisers.
    pub mean: f32,
    /// The largest `L` over them.
    pub worst: f32,
}

impl Informativeness {
    /// `(L(a_t) − mean) / L(a_t)`; `None` when `L(a_t)` is 0 (a noisy teacher corrected its own
    /// best: nothing to measure against).
    pub fn alpha(&self) -> Option<f64> {
        (self.chosen > 0.0).then(|| (self.chosen - self.mean) as f64 / self.chosen as f64)
    }

    /// `(L(a_t) − worst) / L(a_t)`.
    pub fn alpha_worst(&self) -> Option<f64> {
        (self.chosen > 0.0).then(|| (self.chosen - self.worst) as f64 / self.chosen as f64)
    }
}

/// A tick the car holds, as the teacher judged it.
#[derive(Clone, Debug)]
struct Held {
    tick: u32,
    judgement: Judgement,
    chosen: ActionIndex,
}

/// A stretch of bad ticks a span teacher watches.
#[derive(Clone, Copy, Debug)]
struct Stretch {
    last: u32,
    ticks: u8,
    good: bool,
}

/// The teacher's side of a run beyond one tick: which kind each correction takes, the stretch
/// a span teacher watches, and, when it can label spans, a mirror of the ticks the car holds
/// (the spans' [`Informativeness`] is measured on them).
#[derive(Clone, Debug)]
pub struct Tutor {
    teaching: Teaching,
    watching: Option<Stretch>,
    /// Whether this teaching can label a span, the only feedback about ticks before the
    /// current one: otherwise no tick is held (a copy of every judgement saved).
    spans: bool,
    held: VecDeque<Held>,
}

/// The minimisers of `delta` on `j`'s allowed actions, as (mean, largest) of `loss`.
fn over_minimisers(delta: &PseudoLoss, j: &Judgement, loss: &[f32; 64]) -> Option<(f32, f32)> {
    let mut n = 0u32;
    let (mut sum, mut worst) = (0.0f64, f32::NEG_INFINITY);
    for a in j.allowed() {
        if delta[a] == 0.0 {
            n += 1;
            sum += loss[a.get()] as f64;
            worst = worst.max(loss[a.get()]);
        }
    }
    (n > 0).then(|| ((sum / n as f64) as f32, worst))
}

/// The pseudo-loss of `fb` about the tick `j` judged, where the learner chose `chosen`.
fn delta_of(fb: &Feedback, j: &Judgement, chosen: ActionIndex) -> Option<PseudoLoss> {
    let round = Round::new(j.table(), j.allowed(), chosen)
        .and_then(|r| r.with_reference(j.evaluation.reference()))
        .ok()?;
    // A span's pseudo-loss on one tick is its label's.
    pseudo_loss(fb, &round).ok()
}

/// The cost-aware teacher's perceived informativeness of `fb` (see the module documentation).
fn perceived_alpha(fb: &Feedback, j: &Judgement, chosen: ActionIndex) -> f32 {
    let Some(delta) = delta_of(fb, j, chosen) else {
        return f32::NEG_INFINITY;
    };
    let Some((mean, _)) = over_minimisers(&delta, j, &j.perceived) else {
        return f32::NEG_INFINITY;
    };
    let best = j
        .allowed()
        .iter()
        .map(|a| j.perceived[a.get()])
        .fold(f32::INFINITY, f32::min);
    let span = j.perceived[chosen.get()] - best;
    if span > 0.0 {
        (j.perceived[chosen.get()] - mean) / span
    } else {
        f32::NEG_INFINITY
    }
}

/// How informative `fb` was about the tick `j` judged, where the learner chose `chosen` (given
/// at step `now`).
fn measure(
    now: u32,
    kind: FeedbackKind,
    fb: &Feedback,
    j: &Judgement,
    chosen: ActionIndex,
) -> Option<Informativeness> {
    let delta = delta_of(fb, j, chosen)?;
    let (mean, worst) = over_minimisers(&delta, j, &j.latent)?;
    Some(Informativeness {
        step: now,
        kind,
        chosen: j.latent[chosen.get()],
        mean,
        worst,
    })
}

impl Tutor {
    /// A tutor for `teaching`, holding no tick.
    pub fn new(teaching: Teaching) -> Self {
        let spans = match teaching {
            Teaching::Kind(k) => k == FeedbackKind::Span,
            Teaching::Mix(m) => m.weight(FeedbackKind::Span) > 0.0,
            Teaching::Cheapest => true,
        };
        Self {
            teaching,
            watching: None,
            spans,
            held: VecDeque::with_capacity(if spans { TICK_HISTORY } else { 0 }),
        }
    }

    /// One tick: the teacher judged it (`j`), the learner chose `action` (the car acted on the
    /// tick already). Returns the feedback to send now, if any, and how informative it was.
    pub fn tick(
        &mut self,
        teacher: &mut Teacher,
        tick: u32,
        j: &Judgement,
        action: Option<ActionIndex>,
    ) -> (Option<Given>, Vec<Informativeness>) {
        // The car's memory: an acted tick takes the oldest slot; a tick without an action
        // frees the slot it took (the oldest, once all are in use).
        if self.held.len() == TICK_HISTORY {
            self.held.pop_front();
        }
        if let Some(a) = action.filter(|_| self.spans) {
            self.held.push_back(Held {
                tick,
                judgement: j.clone(),
                chosen: a,
            });
        }
        let bad = action.filter(|&a| teacher.corrects(j, a) && j.choice != Some(a));
        if let Some(s) = self.watching {
            if bad.is_some() {
                let s = Stretch {
                    last: tick,
                    ticks: s.ticks + 1,
                    ..s
                };
                if s.ticks >= SPAN_TICKS {
                    self.watching = None;
                    return self.label(tick, s);
                }
                self.watching = Some(s);
                return (None, Vec::new());
            }
            self.watching = None;
            return self.label(tick, s);
        }
        let Some(a) = bad else {
            return (None, Vec::new());
        };
        let chosen = match self.teaching {
            Teaching::Kind(k) => teacher.feedback(k, j, a).map(|fb| (k, fb)),
            Teaching::Mix(m) => {
                let k = m.draw(teacher.rng());
                teacher.feedback(k, j, a).map(|fb| (k, fb))
            }
            Teaching::Cheapest => Self::cheapest(teacher, j, a),
        };
        let Some((kind, fb)) = chosen else {
            return (None, Vec::new());
        };
        if let Feedback::Span(label) = fb {
            let s = Stretch {
                last: tick,
                ticks: 1,
                good: label.good,
            };
            if s.ticks >= SPAN_TICKS {
                return self.label(tick, s);
            }
            self.watching = Some(s);
            return (None, Vec::new());
        }
        let info = measure(tick, kind, &fb, j, a).into_iter().collect();
        (
            Some(Given {
                tick,
                feedback: fb,
                effort: effort(kind),
            }),
            info,
        )
    }

    /// The label of a watched stretch, sent at `now`.
    fn label(&self, now: u32, s: Stretch) -> (Option<Given>, Vec<Informativeness>) {
        let span = SpanFeedback {
            ticks: s.ticks,
            good: s.good,
        };
        let fb = Feedback::Span(span);
        let info = self
            .held
            .iter()
            .filter(|h| span.covers(s.last, h.tick))
            .filter_map(|h| measure(now, FeedbackKind::Span, &fb, &h.judgement, h.chosen))
            .collect();
        (
            Some(Given {
                tick: s.last,
                feedback: fb,
                effort: effort(FeedbackKind::Span),
            }),
            info,
        )
    }

    /// The cost-aware teacher's choice (see the module documentation).
    fn cheapest(
        teacher: &mut Teacher,
        j: &Judgement,
        chosen: ActionIndex,
    ) -> Option<(FeedbackKind, Feedback)> {
        let mut best: Option<(FeedbackKind, Feedback, f32)> = None;
        for (kind, _) in EFFORT_SECONDS {
            if kind == FeedbackKind::EStop {
                continue;
            }
            let Some(fb) = teacher.feedback(kind, j, chosen) else {
                continue;
            };
            let alpha = perceived_alpha(&fb, j, chosen);
            if alpha >= INFORMATIVE {
                return Some((kind, fb));
            }
            if best.as_ref().is_none_or(|b| alpha > b.2) {
                best = Some((kind, fb, alpha));
            }
        }
        best.map(|(k, fb, _)| (k, fb))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mixes_parse_print_and_refuse_naming_the_bad_part() {
        let m = Mix::parse("action=0.2,preference=0.3,semantic=0.5").unwrap();
        assert_eq!(m.to_string(), "mix:action=0.2,preference=0.3,semantic=0.5");
        assert_eq!(Mix::parse(&m.to_string()[4..]), Ok(m));
        assert_eq!(Mix::parse("all"), Ok(Mix::ALL));
        assert_eq!(Mix::ALL.to_string(), "mix:all");
        assert_eq!(m.weight(FeedbackKind::Preference), 0.3);
        for (spec, names) in [
            (
                "action=0.2,shouting=0.3",
                "'shouting=0.3': unknown kind 'shouting'",
            ),
            (
                "action=0.2,preference=x",
                "'preference=x': weight 'x' is not a number",
            ),
            ("action", "'action' is not KIND=WEIGHT"),
            ("action=-1", "'action=-1': weight -1 must be"),
            ("action=nan", "'action=nan': weight nan must be"),
            ("action=1,action=2", "'action=2': kind 'action' given twice"),
            ("action=0,estop=0", "every weight is 0"),
            ("", "no kind given"),
        ] {
            let e = Mix::parse(spec).unwrap_err();
            assert!(e.contains(names), "{spec}: {e}");
        }
    }

    #[test]
    fn a_mix_draws_its_kinds_in_their_proportions() {
        use rand::SeedableRng;
        let m = Mix::parse("action=1,estop=3").unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let n = 40_000;
        let estops = (0..n)
            .filter(|_| m.draw(&mut rng) == FeedbackKind::EStop)
            .count();
        let share = estops as f64 / n as f64;
        assert!((0.74..0.76).contains(&share), "{share}");
        let only = Mix::parse("ranking=2").unwrap();
        assert!((0..100).all(|_| only.draw(&mut rng) == FeedbackKind::Ranking));
    }

    #[test]
    fn the_effort_table_covers_every_kind_once_in_the_order_of_its_seconds() {
        for k in FeedbackKind::ALL {
            assert_eq!(EFFORT_SECONDS.iter().filter(|(x, _)| *x == k).count(), 1);
            assert!(effort(k) > 0.0);
        }
        assert!(EFFORT_SECONDS.windows(2).all(|w| w[0].1 <= w[1].1));
    }
}
