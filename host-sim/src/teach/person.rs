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
//! | presses E-stop | `Esc` | none yet: the car stops (the session pauses; over a link the host sends nothing more and the car's watchdog stops it) and the event is recorded |
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
//! perturbed trajectory) slots in the same way; the E-stop's arm is where an intervention feedback
//! goes once `firmware-core` has one. A kind about several ticks (a span) needs more: today
//! `Session::teach` judges a teaching against the one [`TickRound`] of the tick it names. The serialised form of
//! a [`Teaching`] is what `feedback.jsonl` holds (`kind`, `content`), so old sessions keep
//! replaying when kinds are added.

use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, Feature, Feedback, Polarity, PreferenceFeedback,
    SemanticFeedback, Statement,
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
    /// The emergency stop.
    Estop {},
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
}

impl Teaching {
    /// Its kind, as in `feedback.jsonl`: action, preference, statement, estop.
    pub const fn kind(&self) -> &'static str {
        match self {
            Teaching::Action { .. } => "action",
            Teaching::Preference { .. } => "preference",
            Teaching::Statement { .. } => "statement",
            Teaching::Estop {} => "estop",
        }
    }

    /// The names of every kind, in the order of the variants.
    pub const KINDS: [&'static str; 4] = ["action", "preference", "statement", "estop"];

    /// What it does in a tick where the learner did `round`; refused when it names a trajectory
    /// that collided there, or corrects a tick without a choice. The E-stop is never refused.
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
            // No intervention feedback in firmware-core yet: the car stops, the event is kept.
            Teaching::Estop {} => Ok(Effect {
                feedback: None,
                stop: true,
            }),
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
    fn the_estop_stops_the_car_and_teaches_nothing_yet() {
        let e = Teaching::Estop {}.effect(round()).unwrap();
        assert_eq!(
            e,
            Effect {
                feedback: None,
                stop: true
            }
        );
        // Also in a tick where everything collided, where nothing else is taken.
        let blocked = TickRound {
            allowed: ActionMask::NONE,
            chosen: None,
        };
        assert!(Teaching::Estop {}.effect(blocked).unwrap().stop);
        assert_eq!(
            Teaching::Statement {
                statement: Spoken::AvoidDoors
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
        ];
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
