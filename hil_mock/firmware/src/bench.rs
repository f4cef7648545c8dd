//! Fixed workloads for instruction counting and stack measurement.
//!
//! Three scenes (open space; a 1.5 m corridor with a door; clutter with a chair and stairs)
//! exercise the evaluator from its cheapest to a busy case. The count of one tick is the
//! difference between runs with N and with 0 iterations, divided by N (see `scripts/firmware`).

use firmware_core::agent::Agent;
use firmware_core::evaluator::beam_direction;
use firmware_core::lattice::SCAN_BEAMS;
use firmware_core::observation::{
    Observation, PathReference, SCAN_MAX_RANGE, SemanticClass, SemanticObject,
};
use firmware_core::{
    ActionFeedback, ActionIndex, CorrectnessFeedback, EStopFeedback, Feature, Feedback,
    PerturbationFeedback, PreferenceFeedback, RankingFeedback, RewardFeedback, SemanticFeedback,
    SpanFeedback,
};

/// The three scenes.
pub fn scenes() -> [Observation; 3] {
    let open = Observation::open_space();
    let mut corridor = Observation::open_space();
    for j in 0..SCAN_BEAMS {
        let (_, s) = beam_direction(j).unwrap_or((1.0, 0.0));
        let r = 0.75 / if s < 0.0 { -s } else { s };
        corridor.scan.ranges[j] = if r < SCAN_MAX_RANGE {
            r
        } else {
            SCAN_MAX_RANGE
        };
    }
    let _ = corridor.objects.push(SemanticObject {
        class: SemanticClass::Door,
        x: 1.5,
        y: 0.9,
        radius: 0.45,
    });
    let mut cluttered = corridor.clone();
    for j in (0..SCAN_BEAMS).step_by(3) {
        cluttered.scan.ranges[j] = 0.6 + 0.02 * j as f32;
    }
    let _ = cluttered.objects.push(SemanticObject {
        class: SemanticClass::Chair,
        x: 1.0,
        y: -0.5,
        radius: 0.3,
    });
    let _ = cluttered.objects.push(SemanticObject {
        class: SemanticClass::Stairs,
        x: 2.5,
        y: 0.0,
        radius: 1.0,
    });
    cluttered.reference = PathReference {
        x: 0.95,
        y: 0.2,
        heading: 0.3,
    };
    [open, corridor, cluttered]
}

/// `n` ticks of observation → action, on scene `only` or on the scenes in turn; returns a
/// checksum of the actions.
pub fn act(agent: &mut Agent, n: u32, only: Option<usize>) -> u32 {
    let scenes = scenes();
    let mut sum = 0u32;
    for t in 0..n {
        let scene = &scenes[only.unwrap_or(t as usize % 3) % 3];
        if let Ok(d) = agent.act(t, scene) {
            sum = sum
                .wrapping_mul(31)
                .wrapping_add(d.action.map_or(99, |a| a.get() as u32));
        }
    }
    sum
}

/// Kinds of feedback [`feedback`] cycles through: every kind of `firmware_core::FeedbackKind`.
pub const KINDS: u32 = 9;

/// The feedback of iteration `i`: action, preference, semantic, perturbation, reward,
/// correctness, span (the last two ticks), ranking (four actions) and E-stop in turn.
pub fn feedback(i: u32) -> Feedback {
    let a = |k: u32| ActionIndex::new((k % 49) as usize).unwrap_or(ActionIndex::FIRST);
    match i % KINDS {
        0 => ActionFeedback { action: a(7 + i) }.into(),
        1 => PreferenceFeedback {
            preferred: a(3 + i),
            other: a(20 + i),
        }
        .into(),
        2 => SemanticFeedback::new()
            .avoid(Feature::Door)
            .prefer(Feature::Path)
            .into(),
        3 => match PerturbationFeedback::new(&[9.0, 6.5, 10.0, 10.0, 0.4, -1.5]) {
            Some(p) => p.into(),
            None => EStopFeedback.into(),
        },
        4 => match RewardFeedback::new(-0.5) {
            Some(r) => r.into(),
            None => EStopFeedback.into(),
        },
        5 => CorrectnessFeedback { correct: false }.into(),
        6 => SpanFeedback {
            ticks: 2,
            good: false,
        }
        .into(),
        7 => match RankingFeedback::new(&[a(5 + i), a(11 + i), a(2 + i), a(30 + i)], true) {
            Some(r) => r.into(),
            None => EStopFeedback.into(),
        },
        _ => EStopFeedback.into(),
    }
}

/// Two ticks on the corridor scene, then `n` feedback-to-update steps about the second (a span
/// covers both); returns the number of accepted updates.
pub fn learn(agent: &mut Agent, n: u32) -> u32 {
    let scenes = scenes();
    let _ = agent.act(0, &scenes[1]);
    let _ = agent.act(1, &scenes[1]);
    let mut ok = 0;
    for i in 0..n {
        if agent.feedback(1, &feedback(i)).is_ok() {
            ok += 1;
        }
    }
    ok
}
