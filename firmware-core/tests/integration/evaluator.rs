//! The evaluator against a naive brute-force std evaluator on random observations, and on
//! hand-built scenes (a wall ahead, a door on the left, mirror symmetry).

use crate::support::naive;
use firmware_core::agent::Agent;
use firmware_core::evaluator::{Evaluator, FEATURE_ERROR_BOUND, beam_direction};
use firmware_core::lattice::{Family, SCAN_BEAMS, mirror_action, trajectory};
use firmware_core::observation::{
    MAX_OBJECTS, Observation, PathReference, SCAN_MAX_RANGE, SemanticClass, SemanticObject,
};
use firmware_core::{
    ActionIndex, ActionMask, FEATURE_COUNT, Feature, FeatureTable, Learner, LearnerParams,
};
use proptest::prelude::*;

fn evaluate(obs: &Observation) -> (FeatureTable, ActionMask) {
    let mut table = FeatureTable::ZERO;
    let mask = Evaluator::new().evaluate(obs.check().unwrap(), &mut table);
    (table, mask)
}

fn class() -> impl Strategy<Value = SemanticClass> {
    proptest::sample::select(SemanticClass::ALL.to_vec())
}

fn object() -> impl Strategy<Value = SemanticObject> {
    (class(), -4.0f32..4.0, -4.0f32..4.0, 0.05f32..1.5).prop_map(|(class, x, y, radius)| {
        SemanticObject {
            class,
            x,
            y,
            radius,
        }
    })
}

/// Scans of several kinds: uniform noise, a corridor, a wall ahead, clutter, mostly empty.
fn scan() -> impl Strategy<Value = [f32; SCAN_BEAMS]> {
    let uniform = proptest::collection::vec(0.0f32..=SCAN_MAX_RANGE, SCAN_BEAMS);
    let near =
        proptest::collection::vec(prop_oneof![0.05f32..2.0, Just(SCAN_MAX_RANGE)], SCAN_BEAMS);
    let corridor = (0.3f32..1.5, 0.3f32..1.5).prop_map(|(left, right)| {
        (0..SCAN_BEAMS)
            .map(|j| {
                let (_, s) = beam_direction(j).unwrap();
                let d = if s > 0.0 { left / s } else { right / -s };
                d.min(SCAN_MAX_RANGE)
            })
            .collect::<Vec<f32>>()
    });
    let wall = (0.2f32..2.5).prop_map(|x| {
        (0..SCAN_BEAMS)
            .map(|j| {
                let (c, _) = beam_direction(j).unwrap();
                if c > 0.05 {
                    (x / c).min(SCAN_MAX_RANGE)
                } else {
                    SCAN_MAX_RANGE
                }
            })
            .collect::<Vec<f32>>()
    });
    prop_oneof![uniform, near, corridor, wall].prop_map(|v| {
        let mut a = [0.0; SCAN_BEAMS];
        a.copy_from_slice(&v);
        a
    })
}

fn observation() -> impl Strategy<Value = Observation> {
    (
        scan(),
        proptest::collection::vec(object(), 0..=MAX_OBJECTS),
        (
            -2.0f32..3.0,
            -2.0f32..2.0,
            -std::f32::consts::PI..=std::f32::consts::PI,
        ),
        -2.0f32..2.0,
    )
        .prop_map(|(ranges, objects, (x, y, heading), speed)| {
            let mut obs = Observation::open_space();
            obs.scan.ranges = ranges;
            for o in objects {
                obs.objects.push(o).unwrap();
            }
            obs.reference = PathReference { x, y, heading };
            obs.speed = speed;
            obs
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    /// The pruned evaluator and the brute-force one (exact square roots, every beam) agree: the
    /// same collision mask, and every feature of every trajectory that does not collide within
    /// the documented bound. The rows of colliding trajectories are zero.
    #[test]
    fn evaluator_matches_brute_force(obs in observation()) {
        let (table, mask) = evaluate(&obs);
        let reference = naive::evaluate(&obs).unwrap();
        for a in ActionIndex::all() {
            prop_assert_eq!(!mask.contains(a), reference.collides[a.get()], "collision of {}", a);
            if !mask.contains(a) {
                prop_assert_eq!(table[a], [0.0; FEATURE_COUNT], "row of colliding {}", a);
                continue;
            }
            for (f, (x, y)) in table[a].iter().zip(reference.features[a.get()].iter()).enumerate() {
                prop_assert!((x - y).abs() <= FEATURE_ERROR_BOUND, "feature {} of {}: {} vs {}", f, a, x, y);
            }
        }
    }

    /// Mirroring the observation mirrors every trajectory's features exactly, with the lateral
    /// sign flipped.
    #[test]
    fn mirror_symmetry(obs in observation()) {
        let (table, mask) = evaluate(&obs);
        let (mirrored, mirrored_mask) = evaluate(&obs.mirrored());
        for a in ActionIndex::all() {
            let m = mirror_action(a);
            prop_assert_eq!(mask.contains(a), mirrored_mask.contains(m));
            let mut expected = table[a];
            expected[Feature::Right.index()] = -expected[Feature::Right.index()];
            prop_assert_eq!(mirrored[m], expected, "action {} / mirror {}", a, m);
        }
    }

    /// Nothing in the scratch outlives an evaluation: one evaluator reused over a sequence of
    /// observations gives, bit for bit, what a fresh one gives for each (the agent makes a fresh
    /// one on its stack for every act), and an agent acting on them remembers those features.
    #[test]
    fn a_reused_evaluator_equals_a_fresh_one(seq in proptest::collection::vec(observation(), 1..6)) {
        let mut reused = Evaluator::new();
        let mut agent = Agent::new(Learner::new(LearnerParams::default().check().unwrap()));
        for (tick, obs) in seq.iter().enumerate() {
            let mut table = FeatureTable::ZERO;
            let mask = reused.evaluate(obs.check().unwrap(), &mut table);
            let (fresh, fresh_mask) = evaluate(obs);
            prop_assert_eq!(mask, fresh_mask);
            for a in ActionIndex::all() {
                prop_assert_eq!(table[a].map(f32::to_bits), fresh[a].map(f32::to_bits), "row of {}", a);
            }
            let evaluation = Evaluator::new().evaluation(obs.check().unwrap());
            prop_assert_eq!(evaluation.table(), &table);
            let mut taking = Agent::new(*agent.learner());
            let decision = agent.act(tick as u32, obs).unwrap();
            prop_assert_eq!(decision, taking.act_evaluated(tick as u32, &evaluation));
        }
    }

    /// Features stay within their documented ranges.
    #[test]
    fn features_stay_in_range(obs in observation()) {
        let (table, _) = evaluate(&obs);
        for a in ActionIndex::all() {
            let f = table[a];
            for i in 0..4 {
                prop_assert!((0.0..=10.0).contains(&f[i]), "{:?}", f);
            }
            prop_assert!((0.0..=4.0).contains(&f[Feature::Path.index()]));
            prop_assert!(f[Feature::Right.index()].abs() <= 4.9);
        }
    }
}

/// The reference's constants are its own, written from the documented feature definitions; the
/// crate's must equal them, so a changed constant fails here by name (and not only in a hash).
#[test]
fn crate_constants_equal_the_documented_ones_of_the_reference() {
    use firmware_core::evaluator::{COLLISION_RADIUS, PATH_CLIP, RIGHT_SCALE, SEMANTIC_CLIP};
    use firmware_core::lattice::{OBSTACLE_CLIP, SAMPLES};
    assert_eq!(
        COLLISION_RADIUS,
        naive::COLLISION_RADIUS,
        "collision radius"
    );
    assert_eq!(OBSTACLE_CLIP, naive::OBSTACLE_CLIP, "obstacle clip");
    assert_eq!(SEMANTIC_CLIP, naive::SEMANTIC_CLIP, "semantic clip");
    assert_eq!(PATH_CLIP, naive::PATH_CLIP, "path clip");
    assert_eq!(RIGHT_SCALE, naive::RIGHT_SCALE, "lateral scale");
    assert_eq!(
        SAMPLES,
        naive::COUNTED_SAMPLES,
        "samples a trajectory counts as"
    );
    // A class with no object: the same reading in both.
    let (table, _) = evaluate(&Observation::open_space());
    for a in ActionIndex::all() {
        for class in SemanticClass::ALL {
            assert_eq!(table[a][class.feature().index()], naive::ABSENT_CLASS);
        }
    }
}

#[test]
fn invalid_observations_are_refused_before_the_evaluator() {
    let mut obs = Observation::open_space();
    obs.scan.ranges[10] = f32::NAN;
    assert!(
        obs.check().is_err(),
        "no ValidObservation, so no evaluation"
    );
    // The evaluation the agent can take is the evaluator's own, bit for bit.
    let good = Observation::open_space();
    let (table, mask) = evaluate(&good);
    let evaluation = Evaluator::new().evaluation(good.check().unwrap());
    assert_eq!((evaluation.table(), evaluation.allowed()), (&table, mask));
}

/// A wall ahead at `x` metres: every beam that points forwards hits it.
fn wall_ahead(x: f32) -> Observation {
    let mut obs = Observation::open_space();
    for j in 0..SCAN_BEAMS {
        let (c, _) = beam_direction(j).unwrap();
        if c > 0.0 {
            obs.scan.ranges[j] = (x / c).min(SCAN_MAX_RANGE);
        }
    }
    obs
}

#[test]
fn a_wall_ahead_masks_the_trajectories_that_reach_it() {
    let (table, mask) = evaluate(&wall_ahead(1.2));
    let mut blocked = 0;
    for a in ActionIndex::all() {
        let t = trajectory(a);
        let reach = t.samples().iter().map(|c| c[0]).fold(f32::MIN, f32::max);
        // Trajectories whose footprint centre gets within 0.2 m of the wall collide; those that
        // stay 0.3 m or more short of it do not (the margin covers the gaps between beams).
        if reach > 1.2 - 0.2 {
            assert!(!mask.contains(a), "{a} reaches x = {reach} and is allowed");
            blocked += 1;
        }
        if reach < 1.2 - 0.3 {
            assert!(mask.contains(a), "{a} stops at x = {reach} and is masked");
        }
    }
    assert!(
        !mask.contains(ActionIndex::FIRST),
        "straight ahead is blocked"
    );
    assert!(blocked >= 20);
    // Every creep move stays clear, and the sharpest cruise turns get around.
    for a in ActionIndex::all().filter(|&a| trajectory(a).family == Family::Creep) {
        assert!(mask.contains(a), "{a}");
    }
    // Obstacle clearance shrinks towards the wall: the straight cruise's is the lowest.
    let straight = table[ActionIndex::FIRST][Feature::Obstacles.index()];
    let creep = table[ActionIndex::new(49).unwrap()][Feature::Obstacles.index()];
    assert!(straight < creep, "{straight} vs {creep}");
    // A wall 3 m away blocks nothing.
    assert_eq!(evaluate(&wall_ahead(3.0)).1, ActionMask::ALL);
}

#[test]
fn a_door_on_the_left_gives_left_turns_less_door_clearance() {
    let mut obs = Observation::open_space();
    obs.objects
        .push(SemanticObject {
            class: SemanticClass::Door,
            x: 1.0,
            y: 1.0,
            radius: 0.45,
        })
        .unwrap();
    let (table, _) = evaluate(&obs);
    let door = |a: ActionIndex| table[a][Feature::Door.index()];
    let right = |a: ActionIndex| table[a][Feature::Right.index()];
    // Every cruise trajectory that ends left of the straight one has less door clearance than
    // the straight one, and every one that ends right has more.
    let straight = door(ActionIndex::FIRST);
    for a in ActionIndex::all().filter(|&a| trajectory(a).family == Family::Cruise) {
        if right(a) < -0.5 {
            assert!(
                door(a) < straight,
                "{a} ends left with door clearance {} >= {straight}",
                door(a)
            );
        }
        if right(a) > 0.5 {
            assert!(
                door(a) > straight,
                "{a} ends right with door clearance {} <= {straight}",
                door(a)
            );
        }
    }
    // Classes without an object read 10 for every action.
    for a in ActionIndex::all() {
        assert_eq!(table[a][Feature::Stairs.index()], 10.0);
        assert_eq!(table[a][Feature::Chair.index()], 10.0);
    }
}

#[test]
fn path_and_lateral_features() {
    let (table, _) = evaluate(&Observation::open_space());
    let straight = ActionIndex::FIRST;
    assert_eq!(
        table[straight][Feature::Path.index()],
        0.0,
        "the straight trajectory ends on the reference"
    );
    assert_eq!(table[straight][Feature::Right.index()], 0.0);
    for a in ActionIndex::all() {
        let y = trajectory(a).end().y;
        assert_eq!(table[a][Feature::Right.index()], -10.0 * y);
        if a != straight {
            assert!(table[a][Feature::Path.index()] > 0.0);
        }
    }
    // A reference 1 m ahead and 0.26 m to the right is best met by a trajectory ending there
    // (the feature measures position only, not heading: the lane shift ending parallel at
    // (0.953, -0.260) and the turn-and-hold ending at (0.958, -0.262) are both within 5 cm).
    let mut obs = Observation::open_space();
    obs.reference = PathReference {
        x: 1.0,
        y: -0.26,
        heading: 0.0,
    };
    let (table, _) = evaluate(&obs);
    let path = |a: ActionIndex| table[a][Feature::Path.index()];
    let best = ActionIndex::all()
        .min_by(|&a, &b| path(a).total_cmp(&path(b)))
        .unwrap();
    let end = trajectory(best).end();
    assert!(path(best) < 0.05 && end.y < -0.2, "best {best}: {end:?}");
    let lane_shift = ActionIndex::all()
        .find(|&a| {
            let [s1, s2] = trajectory(a).segments;
            s1.curvature < 0.0 && s2.curvature == -s1.curvature && trajectory(a).end().y < -0.25
        })
        .unwrap();
    assert!(path(lane_shift) < 0.05, "{}", path(lane_shift));
    assert!(path(ActionIndex::FIRST) > 0.25);
}
