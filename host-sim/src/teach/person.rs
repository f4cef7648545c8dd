//! What a person at the teaching console (`host-sim teach`) can do, and the feedback each
//! becomes.
//!
//! A [`Teaching`] is one thing the person did about one tick: a click on a trajectory, an answer
//! in preference mode, a spoken statement, the E-stop. [`Teaching::effect`] maps it, against
//! what the learner did in that tick ([`TickRound`]), to its [`Effect`]: the [`Feedback`] the
//! learner takes (the same kinds the programmatic teachers give, DESIGN section 4) and whether
//! the car stops.
//!
//! | the person | key | feedback |
//! |---|---|---|
//! | clicks a trajectory ("go there") | `[` `]` choose, `Enter` | [`Feedback::Action`]: that trajectory |
//! | in preference mode (`P`), answers which of the learner's choice and one other is better | `1` learner's, `2` the other | [`Feedback::Preference`] |
//! | says a statement | `D` avoid doors, `S` avoid stairs, `C` avoid chairs, `L` stay on the path, `R` keep right, `W` keep off the walls | [`Feedback::Semantic`] with that one statement |
//! | rewards the learner's action of the tick | `7` −1, `8` −½, `9` +½, `0` +1 | [`Feedback::Reward`]: that reward, in hundredths ([`firmware_core::feedback::REWARD_STEPS`] a unit) |
//! | marks the learner's action of the tick correct or incorrect | `G` correct, `B` incorrect | [`Feedback::Correctness`] |
//! | labels the last ticks good or bad | `V` good, `X` bad | [`Feedback::Span`] over the [`TICK_HISTORY`] ticks up to the one shown (the ticks the learner remembers): correct/incorrect of each one's action |
//! | presses E-stop | `Esc` | [`Feedback::EStop`] (the intervention: the action of the current tick was unacceptable), and the car stops (the session pauses; over a link the host sends nothing more after it and the car's watchdog stops it) |
//!
//! The first four statements are the paper's (its semantic teacher speaks of doors, stairs,
//! chairs and the path, section 6); "keep right" and "keep off the walls" are the rest of what the
//! features can say (`host-sim run --statements rich`).
//!
//! # New kinds of feedback
//!
//! Each kind is, here, one variant of [`Teaching`] (its fields are the `content` the page
//! sends), its name in [`Teaching::kind`] and [`Teaching::KINDS`], and one arm of
//! [`Teaching::effect`] (with a unit test below); on the page, one entry in the table of controls
//! (`console/assets/console.js`, `CONTROLS`: its button, its key, and `teach({kind, content})`)
//! and its label in `KIND_LABELS`; and a row of the table in `docs/console.md`. Nothing else
//! changes: the WebSocket command carries any [`Teaching`] (`console/wire.rs`), the session
//! applies whatever feedback the effect gives, counts it as a correction and records it, and the
//! replay reads it back from `feedback.jsonl`. A kind the learner takes later (an intervention for
//! the E-stop, a reward, a correct/incorrect mark, good/bad over a span of ticks, a ranking, a
//! perturbed trajectory) slots in the same way. A span is about several ticks, but names only its
//! last: `Session::teach` judges it against that tick's [`TickRound`] (it needs a choice there),
//! and the learner applies it to each tick of the span it still holds (firmware-core's
//! `Agent::feedback`), so the session needs nothing more. The serialised form of
//! a [`Teaching`] is what `feedback.jsonl` holds (`kind`, `content`), so old sessions keep
//! replaying when kinds are added. A kind whose *meaning* changes is another matter: the E-stop,
//! which taught nothing in session format 1, teaches since format 2, so a format-1 session is
//! refused by the replay with a message naming both formats (`session.rs`, `SESSION_FORMAT`).
//!
//! Reward and correct/incorrect judge only the learner's action of the tick (firmware-core's
//! `feedback::executed`): they say "not this one" or "this one" and never point at a better
//! trajectory, and the size of a reward does not change the generalized hinge's step (it is
//! recorded and travels all the same).

#[cfg(doc)]
use firmware_core::agent::TICK_HISTORY;
use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, CorrectnessFeedback, EStopFeedback, Feature, Feedback,
    Polarity, PreferenceFeedback, RewardFeedback, SemanticFeedback, SpanFeedback, Statement,
};
use serde::{Deserialize, Serialize};

/// A statement a person can say: the paper's four and the two more the features allow.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Spoken {
    /// "Avoid doors".
    AvoidDoors,
    /// "Avoid stairs".
    AvoidStairs,
    /// "Avoid chairs".
    AvoidChairs,
    /// "Stay on the path" (judged by cross-track error).
    StayOnPath,
    /// "Keep right".
    KeepRight,
    /// "Keep off the walls".
    KeepOffWalls,
}

impl Spoken {
    /// Every statement, the paper's four first.
    pub const ALL: [Spoken; 6] = [
        Spoken::AvoidDoors,
        Spoken::AvoidStairs,
        Spoken::AvoidChairs,
        Spoken::StayOnPath,
        Spoken::KeepRight,
        Spoken::KeepOffWalls,
    ];

    /// The paper's statements (doors, stairs, chairs and the path).
    pub const PAPER: [Spoken; 4] = [
        Spoken::AvoidDoors,
        Spoken::AvoidStairs,
        Spoken::AvoidChairs,
        Spoken::StayOnPath,
    ];

    /// Its name in `feedback.jsonl` and on the wire: `avoid-doors`, ….
    pub const fn name(self) -> &'static str {
        match self {
            Spoken::AvoidDoors => "avoid-doors",
            Spoken::AvoidStairs => "avoid-stairs",
            Spoken::AvoidChairs => "avoid-chairs",
            Spoken::StayOnPath => "stay-on-path",
            Spoken::KeepRight => "keep-right",
            Spoken::KeepOffWalls => "keep-off-walls",
        }
    }

    /// The statement the learner takes.
    pub const fn statement(self) -> Statement {
        let (subject, polarity) = match self {
            Spoken::AvoidDoors => (Feature::Door, Polarity::Avoid),
            Spoken::AvoidStairs => (Feature::Stairs, Polarity::Avoid),
            Spoken::AvoidChairs => (Feature::Chair, Polarity::Avoid),
            Spoken::StayOnPath => (Feature::Path, Polarity::Prefer),
            Spoken::KeepRight => (Feature::Right, Polarity::Prefer),
            Spoken::KeepOffWalls => (Feature::Obstacles, Polarity::Avoid),
        };
        Statement { subject, polarity }
    }
}

/// One thing a person did at the console about one tick. Serialised as
/// `{"kind": …, "content": {…}}`, one line of `feedback.jsonl` with the tick and wall time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", content = "content", rename_all = "kebab-case")]
pub enum Teaching {
    /// "Go there": the trajectory the person clicked.
    Action {
        /// The trajectory.
        action: ActionIndex,
    },
    /// Of two trajectories shown, the person prefers one.
    Preference {
        /// The better one.
        preferred: ActionIndex,
        /// The worse one.
        other: ActionIndex,
    },
    /// A spoken statement.
    Statement {
        /// What was said.
        statement: Spoken,
    },
    /// The emergency stop: an intervention about the current tick.
    Estop {},
    /// A reward for the learner's action of the tick.
    Reward {
        /// The reward in hundredths of a unit: −100 (−1, the worst) to 100 (+1, the best), not 0.
        hundredths: i8,
    },
    /// The learner's action of the tick was correct, or incorrect.
    Correctness {
        /// Whether it was correct.
        correct: bool,
    },
    /// The last ticks, up to and including the one named, were all good or all bad.
    Span {
        /// How many ticks: 1 to [`firmware_core::MAX_SPAN`].
        ticks: u8,
        /// Good or bad.
        good: bool,
    },
}

/// What a [`Teaching`] does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Effect {
    /// The feedback for the learner, if any.
    pub feedback: Option<Feedback>,
    /// Whether the car stops.
    pub stop: bool,
}

/// What the learner did in the tick a [`Teaching`] is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TickRound {
    /// The trajectories that did not collide.
    pub allowed: ActionMask,
    /// The learner's choice (`None`: nothing was allowed, the car stopped).
    pub chosen: Option<ActionIndex>,
}

/// Why a [`Teaching`] was refused. Nothing reached the learner.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum TeachingError {
    /// The tick had no allowed trajectory: there was nothing to correct.
    #[error("every trajectory of that tick collides: there was no choice to correct")]
    NoChoice,
    /// The trajectory collides in that tick.
    #[error("trajectory {0} collides in that tick")]
    NotAllowed(ActionIndex),
    /// A preference between a trajectory and itself.
    #[error("a preference needs two different trajectories, got {0} twice")]
    SameAction(ActionIndex),
    /// A reward of 0 (which says nothing) or beyond ±1.
    #[error("a reward is −100 to 100 hundredths and not 0, got {0}")]
    BadReward(i8),
    /// A span of no tick, or longer than [`firmware_core::MAX_SPAN`].
    #[error("a span is 1 to {max} ticks, got {0}", max = firmware_core::MAX_SPAN)]
    BadSpan(u8),
}

impl Teaching {
    /// Its kind, as in `feedback.jsonl`: action, preference, statement, estop, reward,
    /// correctness, span.
    pub const fn kind(&self) -> &'static str {
        match self {
            Teaching::Action { .. } => "action",
            Teaching::Preference { .. } => "preference",
            Teaching::Statement { .. } => "statement",
            Teaching::Estop {} => "estop",
            Teaching::Reward { .. } => "reward",
            Teaching::Correctness { .. } => "correctness",
            Teaching::Span { .. } => "span",
        }
    }

    /// The names of every kind, in the order of the variants.
    pub const KINDS: [&'static str; 7] = [
        "action",
        "preference",
        "statement",
        "estop",
        "reward",
        "correctness",
        "span",
    ];

    /// What it does in a tick where the learner did `round`; refused when it names a trajectory
    /// that collided there, corrects a tick without a choice (for a span: its last tick), or
    /// gives a reward of 0 or beyond ±1 or a span of 0 ticks or more than
    /// [`firmware_core::MAX_SPAN`]. The E-stop is never refused: in a tick without a choice it stops the car and teaches
    /// nothing (there was no action to judge).
    pub fn effect(&self, round: TickRound) -> Result<Effect, TeachingError> {
        let learn = |feedback: Feedback| {
            Ok(Effect {
                feedback: Some(feedback),
                stop: false,
            })
        };
        let allowed = |a: ActionIndex| {
            if round.allowed.contains(a) {
                Ok(a)
            } else {
                Err(TeachingError::NotAllowed(a))
            }
        };
        if !matches!(self, Teaching::Estop {}) && round.chosen.is_none() {
            return Err(TeachingError::NoChoice);
        }
        match *self {
            Teaching::Action { action } => learn(Feedback::Action(ActionFeedback {
                action: allowed(action)?,
            })),
            Teaching::Preference { preferred, other } => {
                if preferred == other {
                    return Err(TeachingError::SameAction(preferred));
                }
                learn(Feedback::Preference(PreferenceFeedback {
                    preferred: allowed(preferred)?,
                    other: allowed(other)?,
                }))
            }
            Teaching::Statement { statement } => learn(Feedback::Semantic(
                SemanticFeedback::new().with(statement.statement()),
            )),
            // The intervention: the executed action was unacceptable (firmware-core's
            // `EStopFeedback`), and the car stops.
            Teaching::Estop {} => Ok(Effect {
                feedback: round.chosen.map(|_| Feedback::EStop(EStopFeedback)),
                stop: true,
            }),
            Teaching::Reward { hundredths } => {
                let reward = RewardFeedback { hundredths };
                reward
                    .check()
                    .map_err(|_| TeachingError::BadReward(hundredths))?;
                learn(Feedback::Reward(reward))
            }
            Teaching::Correctness { correct } => {
                learn(Feedback::Correctness(CorrectnessFeedback { correct }))
            }
            Teaching::Span { ticks, good } => {
                let span = SpanFeedback { ticks, good };
                span.check().map_err(|_| TeachingError::BadSpan(ticks))?;
                learn(Feedback::Span(span))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn a(i: usize) -> ActionIndex {
        ActionIndex::new(i).unwrap()
    }

    /// Trajectories 0–9 allowed, the learner chose 3.
    fn round() -> TickRound {
        TickRound {
            allowed: ActionMask::from_bits(0x3FF),
            chosen: Some(a(3)),
        }
    }

    #[test]
    fn a_click_is_action_feedback_for_that_trajectory() {
        let e = Teaching::Action { action: a(7) }.effect(round()).unwrap();
        assert_eq!(
            e,
            Effect {
                feedback: Some(Feedback::Action(ActionFeedback { action: a(7) })),
                stop: false
            }
        );
        // Clicking the learner's own choice confirms it.
        let e = Teaching::Action { action: a(3) }.effect(round()).unwrap();
        assert_eq!(
            e.feedback,
            Some(Feedback::Action(ActionFeedback { action: a(3) }))
        );
        assert_eq!(
            Teaching::Action { action: a(12) }.effect(round()),
            Err(TeachingError::NotAllowed(a(12)))
        );
    }

    #[test]
    fn a_preference_answer_is_preference_feedback_either_way() {
        // "The learner's choice is better" and "the other is better".
        for (p, o) in [(3, 8), (8, 3)] {
            let e = Teaching::Preference {
                preferred: a(p),
                other: a(o),
            }
            .effect(round())
            .unwrap();
            assert_eq!(
                e,
                Effect {
                    feedback: Some(Feedback::Preference(PreferenceFeedback {
                        preferred: a(p),
                        other: a(o)
                    })),
                    stop: false
                }
            );
        }
        let same = Teaching::Preference {
            preferred: a(3),
            other: a(3),
        };
        assert_eq!(same.effect(round()), Err(TeachingError::SameAction(a(3))));
        let blocked = Teaching::Preference {
            preferred: a(3),
            other: a(40),
        };
        assert_eq!(
            blocked.effect(round()),
            Err(TeachingError::NotAllowed(a(40)))
        );
    }

    #[test]
    fn each_statement_is_semantic_feedback_with_that_one_statement() {
        let want = [
            (Spoken::AvoidDoors, Feature::Door, Polarity::Avoid),
            (Spoken::AvoidStairs, Feature::Stairs, Polarity::Avoid),
            (Spoken::AvoidChairs, Feature::Chair, Polarity::Avoid),
            (Spoken::StayOnPath, Feature::Path, Polarity::Prefer),
            (Spoken::KeepRight, Feature::Right, Polarity::Prefer),
            (Spoken::KeepOffWalls, Feature::Obstacles, Polarity::Avoid),
        ];
        assert_eq!(want.len(), Spoken::ALL.len());
        for (spoken, subject, polarity) in want {
            let e = Teaching::Statement { statement: spoken }
                .effect(round())
                .unwrap();
            let Some(Feedback::Semantic(s)) = e.feedback else {
                panic!("{spoken:?}: {e:?}")
            };
            assert_eq!(s.len(), 1, "{spoken:?}");
            assert_eq!(s.get(subject), Some(polarity), "{spoken:?}");
            assert!(!e.stop);
        }
        // The words point the way the programmatic teacher's do: avoiding an object wants a
        // higher clearance, the path a lower cross-track error, the right-hand side a higher
        // `right`.
        assert!(Spoken::AvoidDoors.statement().wants_higher());
        assert!(!Spoken::StayOnPath.statement().wants_higher());
        assert!(Spoken::KeepRight.statement().wants_higher());
        assert!(Spoken::KeepOffWalls.statement().wants_higher());
    }

    #[test]
    fn the_estop_is_the_intervention_feedback_and_stops_the_car() {
        let e = Teaching::Estop {}.effect(round()).unwrap();
        assert_eq!(
            e,
            Effect {
                feedback: Some(Feedback::EStop(EStopFeedback)),
                stop: true
            }
        );
        // In a tick where everything collided, where nothing else is taken, it still stops the
        // car; there was no action to judge, so it teaches nothing.
        let blocked = TickRound {
            allowed: ActionMask::NONE,
            chosen: None,
        };
        assert_eq!(
            Teaching::Estop {}.effect(blocked),
            Ok(Effect {
                feedback: None,
                stop: true
            })
        );
        assert_eq!(
            Teaching::Statement {
                statement: Spoken::AvoidDoors
            }
            .effect(blocked),
            Err(TeachingError::NoChoice)
        );
    }

    #[test]
    fn each_reward_key_is_reward_feedback_of_that_size() {
        // The page's four keys: −1, −½, +½, +1.
        for (hundredths, value) in [(-100, -1.0), (-50, -0.5), (50, 0.5), (100, 1.0)] {
            let e = Teaching::Reward { hundredths }.effect(round()).unwrap();
            assert_eq!(
                e,
                Effect {
                    feedback: Some(Feedback::Reward(RewardFeedback { hundredths })),
                    stop: false
                }
            );
            let Some(Feedback::Reward(r)) = e.feedback else {
                unreachable!()
            };
            assert_eq!(r.value(), value);
            assert_eq!(Some(r), RewardFeedback::new(value));
        }
        // Zero says nothing; beyond ±1 is off the scale. Nothing reaches the learner.
        for bad in [0, 101, -101, i8::MIN, i8::MAX] {
            assert_eq!(
                Teaching::Reward { hundredths: bad }.effect(round()),
                Err(TeachingError::BadReward(bad)),
                "{bad}"
            );
        }
        let blocked = TickRound {
            allowed: ActionMask::NONE,
            chosen: None,
        };
        assert_eq!(
            Teaching::Reward { hundredths: 100 }.effect(blocked),
            Err(TeachingError::NoChoice)
        );
    }

    #[test]
    fn correct_and_incorrect_are_correctness_feedback() {
        for correct in [true, false] {
            assert_eq!(
                Teaching::Correctness { correct }.effect(round()),
                Ok(Effect {
                    feedback: Some(Feedback::Correctness(CorrectnessFeedback { correct })),
                    stop: false
                })
            );
        }
        let blocked = TickRound {
            allowed: ActionMask::NONE,
            chosen: None,
        };
        assert_eq!(
            Teaching::Correctness { correct: false }.effect(blocked),
            Err(TeachingError::NoChoice)
        );
    }

    #[test]
    fn good_and_bad_over_the_last_ticks_are_span_feedback() {
        // The page's two keys label the ticks the learner remembers.
        for good in [true, false] {
            let ticks = firmware_core::agent::TICK_HISTORY as u8;
            assert_eq!(
                Teaching::Span { ticks, good }.effect(round()),
                Ok(Effect {
                    feedback: Some(Feedback::Span(SpanFeedback { ticks, good })),
                    stop: false
                })
            );
        }
        let longest = firmware_core::MAX_SPAN;
        assert!(
            Teaching::Span {
                ticks: longest,
                good: true
            }
            .effect(round())
            .is_ok()
        );
        for bad in [0, longest + 1, u8::MAX] {
            assert_eq!(
                Teaching::Span {
                    ticks: bad,
                    good: false
                }
                .effect(round()),
                Err(TeachingError::BadSpan(bad)),
                "{bad}"
            );
        }
        let blocked = TickRound {
            allowed: ActionMask::NONE,
            chosen: None,
        };
        assert_eq!(
            Teaching::Span {
                ticks: 4,
                good: true
            }
            .effect(blocked),
            Err(TeachingError::NoChoice)
        );
    }

    #[test]
    fn teachings_serialise_as_kind_and_content_and_refuse_bad_input() {
        let cases = [
            (
                Teaching::Action { action: a(5) },
                r#"{"kind":"action","content":{"action":5}}"#,
            ),
            (
                Teaching::Preference {
                    preferred: a(1),
                    other: a(2),
                },
                r#"{"kind":"preference","content":{"preferred":1,"other":2}}"#,
            ),
            (
                Teaching::Statement {
                    statement: Spoken::StayOnPath,
                },
                r#"{"kind":"statement","content":{"statement":"stay-on-path"}}"#,
            ),
            (Teaching::Estop {}, r#"{"kind":"estop","content":{}}"#),
            (
                Teaching::Reward { hundredths: -50 },
                r#"{"kind":"reward","content":{"hundredths":-50}}"#,
            ),
            (
                Teaching::Correctness { correct: true },
                r#"{"kind":"correctness","content":{"correct":true}}"#,
            ),
            (
                Teaching::Span {
                    ticks: 4,
                    good: false,
                },
                r#"{"kind":"span","content":{"ticks":4,"good":false}}"#,
            ),
        ];
        assert_eq!(cases.len(), Teaching::KINDS.len());
        for (t, json) in cases {
            assert_eq!(serde_json::to_string(&t).unwrap(), json);
            assert_eq!(serde_json::from_str::<Teaching>(json).unwrap(), t);
            assert!(Teaching::KINDS.contains(&t.kind()));
        }
        for bad in [
            r#"{"kind":"action","content":{"action":64}}"#,
            r#"{"kind":"action","content":{"action":-1}}"#,
            r#"{"kind":"statement","content":{"statement":"fly"}}"#,
            r#"{"kind":"shout","content":{}}"#,
            r#"{"kind":"action"}"#,
            r#"{"kind":"reward","content":{"hundredths":200}}"#,
            r#"{"kind":"reward","content":{"hundredths":0.5}}"#,
            r#"{"kind":"correctness","content":{"correct":"yes"}}"#,
            r#"{"kind":"span","content":{"ticks":-1,"good":true}}"#,
            r#"{"kind":"span","content":{"ticks":4}}"#,
        ] {
            assert!(serde_json::from_str::<Teaching>(bad).is_err(), "{bad}");
        }
        for s in Spoken::ALL {
            assert_eq!(
                serde_json::to_string(&s).unwrap(),
                format!("\"{}\"", s.name())
            );
        }
    }
}
