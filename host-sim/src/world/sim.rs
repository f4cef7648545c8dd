//! The world in motion: sensing (the [`Observation`] the car gets) and the episode (driving one
//! control tick, collisions, stuck detection, resets and laps).
//!
//! # Sensing, in the car frame (rear axle, x forward, y left)
//!
//! * **Range scan**: 64 beams cast from the rear axle at the firmware's bearings
//!   ([`beam_bearing`]) through the occupancy grid (DDA, unknown cells block), at most
//!   [`SCAN_MAX_RANGE`] = 10 m. A run whose learner is in this process takes
//!   [`Episode::observe_near`] instead: each beam cast only to its [`scan_cut`] (0.34 m sideways
//!   to 1.71 m ahead), beyond which no evaluation can see a scan point; the evaluation is the
//!   same, bit for bit, and most beams need no cast at all (the clearance around the car, or at
//!   the beam's start, middle and end, shows them free).
//! * **Semantic detections**: every object whose nearest point is within [`SENSOR_RANGE`] (5 m)
//!   and in line of sight (the segment from the sensor to that point crosses no blocked cell
//!   before its last [`LOS_SLACK_CELLS`] cells, so objects drawn as obstacles, a stairwell's
//!   railing, remain visible); the [`MAX_OBJECTS`] nearest (ties by scenario order), each as the
//!   disc of [`WorldObject::disc_seen_from`](crate::world::scenario::WorldObject::disc_seen_from).
//! * **Path reference**: the path point 1 m (arc length) ahead of the car's projection onto the
//!   path, with the path's heading there.
//! * **Speed**: the car's forward speed.
//!
//! # The episode
//!
//! One [`Episode::drive`] is one control tick ([`TICK_SECONDS`] = 0.1 s): the chosen trajectory
//! is fixed in the world at the current pose and tracked for [`PHYSICS_STEPS`] physics steps.
//! The footprint is checked against the map after every physics step. The car is put back at
//! the start, keeping the learner (the caller does not touch it), when:
//!
//! * its footprint touches an occupied or unknown cell (**collision**);
//! * its progress along the path has not grown by [`PROGRESS_EPSILON`] for [`STUCK_TICKS`] ticks
//!   (5 s, **stuck**), or it is more than [`LOST_DISTANCE`] from the path (**lost**);
//! * the agent had no allowed action: the car stops, which is counted, and since a stopped car
//!   sees the same blocked world again it is put back at once (**blocked**).
//!
//! Laps are counted by progress: every full path length of progress within an episode is a lap.
//! On an open path, reaching its end counts a lap and starts the next one from the start.
//!
//! "The start" is the scenario's start pose, or the one an episode was given
//! ([`Episode::starting_at`], the seeded jitter of [`crate::teach::experiment::StartJitter`]).
//!
//! The projection onto the path searches only 1 m behind to 2 m ahead of the previous one, so it
//! cannot jump to a neighbouring hallway.

use std::cell::Cell;
use std::sync::{Arc, LazyLock};

use firmware_core::ActionIndex;
use firmware_core::lattice::trajectory;
use firmware_core::observation::{
    MAX_OBJECTS, Observation, PathReference, SCAN_BEAMS, SCAN_MAX_RANGE, Scan, beam_bearing,
};
use firmware_core::observation::{ObjectList, SemanticObject};

use nalgebra::Isometry2;

use crate::world::car::{CarParams, CarState, Footprint, Pose, Tracker, wrap_angle};
use crate::world::map::Viewpoint;
use crate::world::scenario::Scenario;
use protocol::quantize::{quantize_but_scan, quantize_range};

/// Range of the semantic detector (m).
pub const SENSOR_RANGE: f64 = 5.0;

/// Line of sight ignores this many cells at the object's end (objects may be drawn as obstacles).
pub const LOS_SLACK_CELLS: f64 = 1.5;

/// The path reference is this far ahead along the path (m).
pub const LOOKAHEAD: f64 = 1.0;

/// Length of a control tick (s).
pub const TICK_SECONDS: f64 = 0.1;

/// Physics steps per control tick.
pub const PHYSICS_STEPS: u32 = 10;

/// Ticks without progress before the car counts as stuck (5 s).
pub const STUCK_TICKS: u32 = 50;

/// Progress (m) that resets the stuck counter.
pub const PROGRESS_EPSILON: f64 = 0.1;

/// Farther than this from the path (m), the car is lost.
pub const LOST_DISTANCE: f64 = 2.0;

/// Why the car was put back at the start.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ResetReason {
    /// The footprint touched the map.
    Collision,
    /// No progress for [`STUCK_TICKS`] ticks.
    Stuck,
    /// Farther than [`LOST_DISTANCE`] from the path.
    Lost,
    /// The agent had no allowed action.
    Blocked,
    /// The end of an open path was reached (a lap, not a failure).
    PathEnd,
}

impl ResetReason {
    /// A short name for CSV files.
    pub const fn name(self) -> &'static str {
        match self {
            ResetReason::Collision => "collision",
            ResetReason::Stuck => "stuck",
            ResetReason::Lost => "lost",
            ResetReason::Blocked => "blocked",
            ResetReason::PathEnd => "path-end",
        }
    }

    /// The reason called `name` (see [`ResetReason::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        [
            ResetReason::Collision,
            ResetReason::Stuck,
            ResetReason::Lost,
            ResetReason::Blocked,
            ResetReason::PathEnd,
        ]
        .into_iter()
        .find(|r| r.name() == name)
    }
}

/// What one tick of driving did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickResult {
    /// The car was put back at the start, and why.
    pub reset: Option<ResetReason>,
    /// A lap was completed in this tick.
    pub lap: bool,
}

/// The car in a scenario: state, progress along the path, laps.
#[derive(Clone, Debug)]
pub struct Episode {
    scenario: Arc<Scenario>,
    /// Where this episode starts and every reset returns (the scenario's start unless jittered).
    start: Pose,
    params: CarParams,
    /// The footprint test's constants for `params` on the scenario's map.
    footprint: Footprint,
    /// Per beam, its [`scan_cut`] and a cell more, in cells of the scenario's map (what
    /// [`Episode::observe_near`] reads the clearance along before it casts a beam).
    cut_cells: [f64; SCAN_BEAMS],
    /// The beams that [`Episode::observe_near`] found short of their cut last time (one bit
    /// each): it casts them again without its point tests first, which would most likely not
    /// settle them. Only which test runs first depends on it, never a range (see
    /// `observe_within`).
    scan_hits: Cell<u64>,
    car: CarState,
    /// Arc length of the car's projection onto the path.
    s: f64,
    /// Progress since the start of the episode (m, signed).
    progress: f64,
    best: f64,
    since_progress: u32,
    episode_laps: u32,
    laps: u32,
}

impl Episode {
    /// The car at the scenario's start.
    pub fn new(scenario: Arc<Scenario>) -> Self {
        let start = scenario.start;
        Self::starting_at(scenario, start)
    }

    /// The car at `start` instead of the scenario's start; every reset returns there. The caller
    /// checks that the pose is free (see [`crate::teach::experiment::StartJitter`]).
    pub fn starting_at(scenario: Arc<Scenario>, start: Pose) -> Self {
        let params = CarParams::MUSHR;
        let footprint = params.footprint_on(&scenario.map);
        let cut_cells = cut_cells(&scenario.map);
        let mut e = Self {
            cut_cells,
            scan_hits: Cell::new(0),
            car: CarState::at(start),
            start,
            scenario,
            params,
            footprint,
            s: 0.0,
            progress: 0.0,
            best: 0.0,
            since_progress: 0,
            episode_laps: 0,
            laps: 0,
        };
        e.reset();
        e
    }

    /// Back to the start (laps are kept).
    pub fn reset(&mut self) {
        self.car = CarState::at(self.start);
        let st = self.start;
        self.s = self.scenario.path.project(&st.position()).0;
        self.progress = 0.0;
        self.best = 0.0;
        self.since_progress = 0;
        self.episode_laps = 0;
    }

    /// Where the episode starts.
    pub fn start(&self) -> Pose {
        self.start
    }

    /// The car's state.
    pub fn car(&self) -> &CarState {
        &self.car
    }

    /// Laps completed so far.
    pub fn laps(&self) -> u32 {
        self.laps
    }

    /// Progress along the path since the episode started (m).
    pub fn progress(&self) -> f64 {
        self.progress
    }

    /// The car's projection onto the path (m of arc length from the path's start).
    pub fn station(&self) -> f64 {
        self.s
    }

    /// How far along the path the car has come over the run (m): the laps it completed times
    /// the path's length, plus its progress into the current lap (forward positive). A reset
    /// puts the car back at the start of its lap, and its progress with it, so a car that keeps
    /// being reset before a lap ends makes none.
    pub fn path_progress(&self) -> f64 {
        let length = self.scenario.path.length();
        self.laps as f64 * length + (self.progress - self.episode_laps as f64 * length)
    }

    /// The scenario.
    pub fn scenario(&self) -> &Arc<Scenario> {
        &self.scenario
    }

    /// What the car senses now.
    pub fn observe(&self) -> Observation {
        observe(&self.scenario, &self.car, self.s)
    }

    /// What the car senses now, as far as the evaluator and the features of a perturbation can
    /// tell: [`Episode::observe`] with every beam cast only to its [`scan_cut`], and a beam
    /// that reaches it reading [`SCAN_MAX_RANGE`]. Every other number is `observe`'s, bit for
    /// bit, and so is every evaluation of it (its mask, its features, a deformed trajectory's
    /// features): no scan point beyond the cut comes within the obstacle clip of any sample. For
    /// a learner in this process, which acts on the host's evaluation; the car, which gets the
    /// observation itself, needs [`Episode::observe`].
    pub fn observe_near(&self) -> Observation {
        observe_within(
            &self.scenario,
            &self.car,
            self.s,
            &SCAN_CUT,
            &self.cut_cells,
            &SCAN_CUT_ORDER,
            &self.scan_hits,
        )
    }

    /// One control tick standing still (the teacher stopped the car: an E-stop): the car's speed
    /// drops to 0 and it stays where it is. A car held long enough is stuck and reset, like one
    /// that makes no progress.
    pub fn hold(&mut self) -> TickResult {
        self.car.speed = 0.0;
        self.since_progress += 1;
        if self.since_progress >= STUCK_TICKS {
            self.reset();
            return TickResult {
                reset: Some(ResetReason::Stuck),
                lap: false,
            };
        }
        TickResult {
            reset: None,
            lap: false,
        }
    }

    /// Drives one control tick along `action`'s trajectory; `None` (nothing allowed) stops the
    /// car and puts it back at the start.
    pub fn drive(&mut self, action: Option<ActionIndex>) -> TickResult {
        let Some(action) = action else {
            self.reset();
            return TickResult {
                reset: Some(ResetReason::Blocked),
                lap: false,
            };
        };
        // The heading's cosine and sine, once per pose (each use would compute the same bits).
        let mut rotation = self.car.pose.rotation();
        let mut tracker = Tracker::new_turned(self.car.pose, rotation, trajectory(action));
        let footprint = self.footprint;
        let dt = TICK_SECONDS / PHYSICS_STEPS as f64;
        // Far enough from every wall for the whole tick: no step's footprint test can hit.
        let speed = self.car.speed.abs().max(tracker.speed().abs());
        let travel = footprint.travel(PHYSICS_STEPS, dt, speed);
        let clear = footprint.clear_within(&self.scenario.map, self.car.pose, rotation, travel);
        // The rear axle moves less than the footprint's centre (`travel` bounds both).
        tracker.narrow_within(travel);
        for _ in 0..PHYSICS_STEPS {
            let steer = tracker.steering_turned(self.car.pose, rotation, &self.params);
            rotation = self
                .car
                .step_turned(&self.params, steer, tracker.speed(), dt, rotation);
            if !clear && footprint.hits(&self.scenario.map, self.car.pose, rotation) {
                self.reset();
                return TickResult {
                    reset: Some(ResetReason::Collision),
                    lap: false,
                };
            }
        }
        let path = &self.scenario.path;
        let (s, d) = path.project_near(&self.car.pose.position(), self.s, 1.0, 2.0);
        self.progress += path.delta(self.s, s);
        self.s = s;
        let mut lap = false;
        if path.is_closed() {
            if self.progress >= (self.episode_laps + 1) as f64 * path.length() {
                self.episode_laps += 1;
                self.laps += 1;
                lap = true;
            }
        } else if s >= path.length() - 0.25 {
            self.laps += 1;
            self.reset();
            return TickResult {
                reset: Some(ResetReason::PathEnd),
                lap: true,
            };
        }
        if d > LOST_DISTANCE {
            self.reset();
            return TickResult {
                reset: Some(ResetReason::Lost),
                lap,
            };
        }
        if self.progress > self.best + PROGRESS_EPSILON {
            self.best = self.progress;
            self.since_progress = 0;
        } else {
            self.since_progress += 1;
            if self.since_progress >= STUCK_TICKS {
                self.reset();
                return TickResult {
                    reset: Some(ResetReason::Stuck),
                    lap,
                };
            }
        }
        TickResult { reset: None, lap }
    }
}

/// `(cos, sin)` of every beam's bearing ([`beam_bearing`]).
static BEAM_DIRECTIONS: LazyLock<[(f64, f64); SCAN_BEAMS]> = LazyLock::new(|| {
    std::array::from_fn(|j| {
        let b = beam_bearing(j) as f64;
        (libm::cos(b), libm::sin(b))
    })
});

/// Margin beyond the obstacle clip within which [`scan_cut`] keeps a beam's point (m): far above
/// the f32 rounding of the evaluator's distances and the evaluator's own reach margin (1 mm).
#[cfg(test)]
const CUT_MARGIN: f64 = 0.05;

/// Per beam: how far [`Episode::observe_near`] casts it (m). Beyond it, the beam's scan point is
/// at least the obstacle clip + `CUT_MARGIN` (5 cm) from every sample the evaluator measures (every
/// lattice trajectory's) and every sample of a perturbation's deformed trajectory (every pair
/// pushed [`PUSH`](firmware_core::feedback::PUSH) of the way, and each trajectory as it is),
/// after the range's rounding to the wire's centimetres (hence 1 cm more): such a beam is one
/// the evaluator leaves out and no feature can see, whatever its range.
pub fn scan_cut(beam: usize) -> Option<f64> {
    SCAN_CUT.get(beam).copied()
}

/// [`scan_cut`]'s table, computed once and written down: the test
/// `scan_cut_is_the_farthest_chord_end_over_every_sample` computes it from its definition, over
/// every sample (every lattice trajectory's and every deformed trajectory's), and fails, printing
/// the table to paste here, when a change to the lattice or to a perturbation moves any bit of
/// it. Every literal is the shortest decimal that reads back as its `f64`'s bits. Computed at the
/// first scan instead (a `LazyLock`, until 2026-12-04), it cost every process that loads a
/// scenario (whose check drives a lap) about 33 million instructions, 4 160 trajectories' samples
/// against 64 beams: `host-sim bench --steps 1` 10 → 5 ms of wall time in release, 20 → 10 ms in
/// the dev build the tests spawn (issue 17).
#[rustfmt::skip]
const SCAN_CUT: [f64; SCAN_BEAMS] = [
    0.33603182930496, 0.3382103337746598, 0.34169201301277263, 0.34649962594189054,
    0.35266266184092454, 0.36021562831738385, 0.3691955809840415, 0.37963899484679975,
    0.3915777410283583, 0.40503424821877654, 0.420015852987739, 0.4365086687312033,
    0.45447118557946153, 0.47382829814513183, 0.49446619281047877, 0.5162289136017866,
    0.5389170865887268, 0.5622891413359979, 0.594567354574776, 0.669666126500861,
    1.0285567486346125, 1.3144819619946642, 1.4607036169266039, 1.5571305843039454,
    1.6165306513512931, 1.651466918229317, 1.6771504921825138, 1.6931698101663823,
    1.6992474496130983, 1.7041176803319946, 1.7081101130855976, 1.7080318717095937,
    1.7080318717095937, 1.7081101130855976, 1.7041176803319946, 1.6992474496130983,
    1.6931698101663823, 1.6771504921825138, 1.651466918229317, 1.6165306513512931,
    1.5571305843039454, 1.4607036169266039, 1.3144819619946642, 1.0285567486346125,
    0.669666126500861, 0.594567354574776, 0.5622891413359979, 0.5389170865887268,
    0.5162289136017866, 0.49446619281047877, 0.47382829814513183, 0.45447118557946153,
    0.4365086687312033, 0.420015852987739, 0.40503424821877654, 0.3915777410283583,
    0.37963899484679975, 0.3691955809840415, 0.36021562831738385, 0.35266266184092454,
    0.34649962594189054, 0.34169201301277263, 0.3382103337746598, 0.33603182930496,
];

/// How many points along a beam, after the car, [`Episode::observe_near`] reads the clearance of
/// before it casts the beam ([`OccupancyGrid::free_by_points_from`]).
///
/// [`OccupancyGrid::free_by_points_from`]: crate::world::map::OccupancyGrid::free_by_points_from
const SCAN_FREE_POINTS: u32 = 2;

/// The observation of a car in `scenario` whose projection onto the path is at arc length `s`,
/// quantized to the protocol's wire steps (`protocol::quantize::quantize`: ranges in
/// centimetres, lengths in millimetres, the heading in 10⁻⁴ rad), so that the learner and the
/// teacher see the same numbers in process as over the link.
pub fn observe(scenario: &Scenario, car: &CarState, s: f64) -> Observation {
    // Every cut at the sensor's range: no beam reads the clearance along it (`cut_cells` unread).
    observe_within(
        scenario,
        car,
        s,
        &[SCAN_MAX_RANGE as f64; SCAN_BEAMS],
        &[0.0; SCAN_BEAMS],
        &BEAMS_IN_ORDER,
        &Cell::new(0),
    )
}

/// The beams by number (every cut the same: in order of their cuts).
const BEAMS_IN_ORDER: [u8; SCAN_BEAMS] = {
    let mut order = [0u8; SCAN_BEAMS];
    let mut j = 0;
    while j < SCAN_BEAMS {
        order[j] = j as u8;
        j += 1;
    }
    order
};

/// The beams in order of their [`scan_cut`], shortest first (by number among equal cuts).
static SCAN_CUT_ORDER: LazyLock<[u8; SCAN_BEAMS]> = LazyLock::new(|| {
    let mut order = BEAMS_IN_ORDER;
    order.sort_by(|&a, &b| SCAN_CUT[usize::from(a)].total_cmp(&SCAN_CUT[usize::from(b)]));
    order
});

/// Per beam, its [`scan_cut`] and a cell more in cells of `map` (`(cut + resolution) /
/// resolution`, as [`OccupancyGrid::free_by_points_from`] computes it from the length).
///
/// [`OccupancyGrid::free_by_points_from`]: crate::world::map::OccupancyGrid::free_by_points_from
fn cut_cells(map: &crate::world::map::OccupancyGrid) -> [f64; SCAN_BEAMS] {
    let res = map.resolution();
    SCAN_CUT.map(|cut| (cut + res) / res)
}

/// [`observe`] with beam `j` cast only to `cut[j]` (at most [`SCAN_MAX_RANGE`]): a beam that
/// reaches it reads `SCAN_MAX_RANGE`, every other the range `observe` gives it (the same
/// traversal, stopped earlier). `cut_cells[j]` is `cut[j]` and a cell more in cells of the map
/// ([`cut_cells`]), read for the beams cut short of `SCAN_MAX_RANGE` only. `order` holds every
/// beam once, in order of their cuts (shortest first).
///
/// The beams in `cast_first` are cast without the point tests before (those tests settle only
/// beams whose cast would reach the cut, so the ranges are the same whichever beams skip them);
/// it is then set to the beams whose cast stopped short of their cut (one bit each), a hint for
/// the next tick's scan.
fn observe_within(
    scenario: &Scenario,
    car: &CarState,
    s: f64,
    cut: &[f64; SCAN_BEAMS],
    cut_cells: &[f64; SCAN_BEAMS],
    order: &[u8; SCAN_BEAMS],
    cast_first: &Cell<u64>,
) -> Observation {
    let pose = car.pose;
    let map = &scenario.map;
    // Each beam's direction: its unit vector in the car frame turned by the heading.
    let rotation = pose.rotation();
    let (sin, cos) = (rotation.sin_angle(), rotation.cos_angle());
    // Every cell within `clearance − 1` cells of the car's is free, and a ray leaves that square
    // only after at least `clearance − 1` cells of travel: a beam whose cut is shorter by a cell
    // more reads what its cast would give, SCAN_MAX_RANGE, without the cast.
    let view = map.viewpoint(pose.x, pose.y);
    let free = (f64::from(view.clearance_cells()) - 2.0) * map.resolution();
    // Each range quantized to the wire's step as it is made (`quantize_but_scan` below leaves
    // the scan as it is): the sensor's range, most beams', once.
    let far = quantize_range(SCAN_MAX_RANGE);
    let mut scan = Scan {
        ranges: [far; SCAN_BEAMS],
    };
    // The beams whose cut is within the free square come first in `order`: they read `far`
    // as they are.
    let first = order.partition_point(|&j| cut[usize::from(j) & (SCAN_BEAMS - 1)] <= free);
    let (skip_points, mut hits) = (cast_first.get(), 0u64);
    let directions = &*BEAM_DIRECTIONS;
    for &j in &order[first..] {
        let j = usize::from(j) & (SCAN_BEAMS - 1);
        let (bc, bs) = directions[j];
        let cut = cut[j];
        // The beam's direction in the grid's frame, once for both tests below.
        let along = map.grid_direction((cos * bc - sin * bs, sin * bc + cos * bs));
        // Free a cell beyond the cut: the cast would reach the cut (no cast needed).
        if cut < SCAN_MAX_RANGE as f64
            && skip_points >> j & 1 == 0
            && map.free_by_points_in_grid(&view, along, cut_cells[j], SCAN_FREE_POINTS)
        {
            continue;
        }
        let r = map.raycast_in_grid(&view, along, cut);
        if r >= cut {
            continue;
        }
        scan.ranges[j] = quantize_range((r as f32).min(SCAN_MAX_RANGE));
        hits |= 1 << j;
    }
    let iso = pose.isometry_turned(rotation);
    let objects = detect_from(scenario, pose, &iso, &view);
    let (r, rh) = scenario.path.point_at(s + LOOKAHEAD);
    let local = iso.inverse_transform_point(&r);
    let pi = std::f32::consts::PI;
    let heading = (wrap_angle(rh - pose.theta) as f32).clamp(-pi, pi);
    cast_first.set(hits);
    quantize_but_scan(Observation {
        scan,
        objects,
        reference: PathReference {
            x: local.x as f32,
            y: local.y as f32,
            heading,
        },
        speed: car.speed as f32,
    })
}

/// The semantic detections from `pose`.
pub fn detect(scenario: &Scenario, pose: Pose) -> ObjectList {
    detect_from(
        scenario,
        pose,
        &pose.isometry(),
        &scenario.map.viewpoint(pose.x, pose.y),
    )
}

/// [`detect`] with the pose's transform given (`pose.isometry()`) and its viewpoint on the
/// map (`scenario.map.viewpoint(pose.x, pose.y)`).
fn detect_from(
    scenario: &Scenario,
    pose: Pose,
    iso: &Isometry2<f64>,
    view: &Viewpoint,
) -> ObjectList {
    let p = pose.position();
    let slack = LOS_SLACK_CELLS * scenario.map.resolution();
    // The MAX_OBJECTS nearest seen so far, in order (distance, then scenario order), kept by
    // insertion: the first MAX_OBJECTS of all the seen ones sorted, without a list of them all.
    let mut nearest = [(0.0f64, 0usize); MAX_OBJECTS];
    let mut len = 0;
    for (i, o) in scenario.objects.iter().enumerate() {
        let (q, d) = o.nearest_point(&p);
        if d <= SENSOR_RANGE
            && scenario
                .map
                .line_of_sight_from(view, (p.x, p.y), (q.x, q.y), slack)
        {
            // Behind every one as near (they come earlier in the scenario).
            let at = nearest[..len].partition_point(|n| n.0.total_cmp(&d).is_le());
            if at < MAX_OBJECTS {
                len = (len + 1).min(MAX_OBJECTS);
                nearest.copy_within(at..len - 1, at + 1);
                nearest[at] = (d, i);
            }
        }
    }
    let mut list = ObjectList::new();
    for &(_, i) in &nearest[..len] {
        let o = &scenario.objects[i];
        let (c, r) = o.disc_seen_from(&p);
        let local = iso.inverse_transform_point(&c);
        let obj = SemanticObject {
            class: o.class,
            x: local.x as f32,
            y: local.y as f32,
            radius: r as f32,
        };
        // At most MAX_OBJECTS are taken, so the list has room.
        let _ = list.push(obj);
    }
    list
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::map::OccupancyGrid;
    use crate::world::path::RefPath;
    use crate::world::scenario::{Shape, WorldObject};
    use crate::world::teacher::{TeacherSpec, preset};
    use firmware_core::MAX_ACTIONS;
    use firmware_core::evaluator::beam_direction;
    use firmware_core::feedback::{DeformedTrajectory, PUSH};
    use firmware_core::lattice::OBSTACLE_CLIP;
    use firmware_core::observation::SemanticClass;
    use nalgebra::Point2;

    /// A 10 m × 6 m room (0.05 m cells) with a wall across x = 6 from y = 0 to y = 4, a path
    /// along y = 1 and `objects`.
    fn world(objects: Vec<WorldObject>) -> Scenario {
        let map = OccupancyGrid::from_fn(200, 120, 0.05, [0.0, 0.0, 0.0], |c, r| {
            c == 0 || r == 0 || c == 199 || r == 119 || (c == 120 && r < 80)
        });
        Scenario {
            name: "room".into(),
            description: String::new(),
            source: Default::default(),
            map: Arc::new(map),
            path: RefPath::new(vec![Point2::new(1.0, 1.0), Point2::new(5.0, 1.0)], false).unwrap(),
            start: Pose {
                x: 1.0,
                y: 1.0,
                theta: 0.0,
            },
            objects,
            teacher: TeacherSpec::from_preset(preset("doors").unwrap()),
        }
    }

    fn chair(x: f64, y: f64) -> WorldObject {
        WorldObject {
            class: SemanticClass::Chair,
            centre: Point2::new(x, y),
            shape: Shape::Disc { radius: 0.2 },
        }
    }

    #[test]
    fn the_scan_sees_the_walls_in_the_car_frame() {
        let s = world(vec![]);
        let car = CarState::at(Pose {
            x: 2.0,
            y: 1.0,
            theta: 0.0,
        });
        let obs = observe(&s, &car, 1.0);
        obs.validate().unwrap();
        for j in 0..SCAN_BEAMS {
            let b = beam_bearing(j) as f64;
            let (c, sn) = (b.cos(), b.sin());
            // Expected: the nearest of the walls x = 0.05, x = 6.0 (for y < 4), y = 0.05, y = 5.95.
            let mut want = f64::INFINITY;
            if c > 0.0 {
                let t = (6.0 - 2.0) / c;
                if 1.0 + t * sn < 4.0 {
                    want = want.min(t);
                }
            }
            if c < 0.0 {
                want = want.min((0.05 - 2.0) / c);
            }
            if sn < 0.0 {
                want = want.min((0.05 - 1.0) / sn);
            }
            if sn > 0.0 {
                want = want.min((5.95 - 1.0) / sn);
            }
            let want = want.min(SCAN_MAX_RANGE as f64);
            let got = obs.scan.ranges[j] as f64;
            assert!((got - want).abs() < 0.08, "beam {j}: {got} vs {want}");
        }
        // The path reference is 1 m ahead along the path.
        assert!((obs.reference.x - 1.0).abs() < 1e-6 && obs.reference.y.abs() < 1e-6);
        assert_eq!(obs.reference.heading, 0.0);
    }

    #[test]
    fn detections_need_range_and_line_of_sight_and_keep_the_nearest_eight() {
        // Behind the wall at x = 6 (y < 4): invisible. Beyond 5 m: invisible.
        let mut objects = vec![chair(7.0, 1.0), chair(1.5, 5.9 - 0.2)];
        for k in 0..9 {
            objects.push(chair(2.5 + 0.3 * k as f64, 2.5));
        }
        let s = world(objects);
        let seen = detect(
            &s,
            Pose {
                x: 2.0,
                y: 1.0,
                theta: std::f64::consts::FRAC_PI_2,
            },
        );
        assert_eq!(seen.len(), MAX_OBJECTS);
        // Nearest first; in the car frame (facing +y), x forward = world y, y left = −world x.
        let d: Vec<f32> = seen
            .iter()
            .map(|o| (o.x * o.x + o.y * o.y).sqrt())
            .collect();
        assert!(d.windows(2).all(|w| w[0] <= w[1]), "{d:?}");
        assert!((seen[0].x - 1.5).abs() < 1e-6 && (seen[0].y + 0.5).abs() < 1e-6);
        // Only the row of nine, minus its farthest one.
        assert!(seen.iter().all(|o| (o.x - 1.5).abs() < 1e-6));
        let behind_wall = detect(
            &s,
            Pose {
                x: 5.5,
                y: 1.0,
                theta: 0.0,
            },
        );
        assert!(
            behind_wall.iter().all(|o| o.x < 1.0),
            "the chair behind the wall is hidden"
        );
        let beyond = world(vec![chair(8.0, 5.0)]);
        assert!(
            detect(
                &beyond,
                Pose {
                    x: 1.0,
                    y: 1.0,
                    theta: 0.0
                }
            )
            .is_empty()
        );
    }

    #[test]
    fn detections_are_the_nearest_of_all_seen_in_order() {
        // Against the definition: every object seen, sorted by distance then scenario order, the
        // first MAX_OBJECTS. Crowds of chairs on a coarse lattice (many equal distances), seen
        // from many poses.
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = |n: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % n
        };
        let (mut full, mut ties) = (0, 0);
        for _ in 0..60 {
            let count = 1 + next(25);
            let objects: Vec<_> = (0..count)
                .map(|_| chair(0.5 + 0.5 * next(18) as f64, 0.5 + 0.5 * next(10) as f64))
                .collect();
            let s = world(objects);
            for _ in 0..20 {
                let pose = Pose {
                    x: 0.3 + 0.25 * next(36) as f64,
                    y: 0.3 + 0.25 * next(22) as f64,
                    theta: next(628) as f64 / 100.0,
                };
                let p = pose.position();
                let slack = LOS_SLACK_CELLS * s.map.resolution();
                let mut seen: Vec<(f64, usize)> = Vec::new();
                for (i, o) in s.objects.iter().enumerate() {
                    let (q, d) = o.nearest_point(&p);
                    if d <= SENSOR_RANGE && s.map.line_of_sight((p.x, p.y), (q.x, q.y), slack) {
                        seen.push((d, i));
                    }
                }
                seen.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                let iso = pose.isometry();
                let want: Vec<_> = seen
                    .iter()
                    .take(MAX_OBJECTS)
                    .map(|&(_, i)| {
                        let (c, _) = s.objects[i].disc_seen_from(&p);
                        let l = iso.inverse_transform_point(&c);
                        ((l.x as f32).to_bits(), (l.y as f32).to_bits())
                    })
                    .collect();
                let got: Vec<_> = detect(&s, pose)
                    .iter()
                    .map(|o| (o.x.to_bits(), o.y.to_bits()))
                    .collect();
                assert_eq!(got, want, "{pose:?}");
                full += usize::from(seen.len() > MAX_OBJECTS);
                ties += usize::from(seen.windows(2).any(|w| w[0].0 == w[1].0));
            }
        }
        assert!(
            full > 50 && ties > 50,
            "{full} with more than a list, {ties} with ties"
        );
    }

    /// The evaluation of `obs` and, for a few pairs, a perturbation's features in it, as text
    /// (`{:?}` tells −0 from +0: equal text is equal bits).
    fn seen(obs: &Observation) -> String {
        let valid = obs.check().unwrap();
        let evaluation = firmware_core::evaluator::Evaluator::new().evaluation(valid);
        let pairs = [(0, 63), (5, 40), (20, 21), (33, 7), (63, 0), (12, 12)];
        let deformed: Vec<_> = pairs
            .iter()
            .map(|&(a, b)| {
                let (a, b) = (ActionIndex::new(a).unwrap(), ActionIndex::new(b).unwrap());
                DeformedTrajectory::between(a, b, PUSH).features(valid)
            })
            .collect();
        format!("{evaluation:?} {deformed:?}")
    }

    /// Every sample [`scan_cut`] keeps its beams' points away from: every lattice trajectory's, and
    /// every deformed trajectory's of a perturbation.
    fn cut_samples() -> Vec<[f32; 2]> {
        let actions = || (0..MAX_ACTIONS).filter_map(ActionIndex::new);
        let mut points: Vec<[f32; 2]> = Vec::new();
        for a in actions() {
            points.extend_from_slice(trajectory(a).samples());
            for b in actions() {
                points.extend_from_slice(DeformedTrajectory::between(a, b, PUSH).samples());
            }
        }
        points
    }

    #[test]
    fn scan_cut_is_the_farthest_chord_end_over_every_sample() {
        // The definition, every sample's root taken: per beam, the farthest range at which its
        // point is within the radius of a sample (the far end of the chord of the disc around
        // it), 1 cm more for the wire's rounding, at most the sensor's range.
        let points = cut_samples();
        let radius = OBSTACLE_CLIP as f64 + CUT_MARGIN;
        let want: [f64; SCAN_BEAMS] = std::array::from_fn(|j| {
            let (c, s) = beam_direction(j).unwrap();
            let (c, s) = (c as f64, s as f64);
            let far = points
                .iter()
                .filter_map(|p| {
                    let (x, y) = (p[0] as f64, p[1] as f64);
                    let t = c * x + s * y;
                    let q = t * t - (x * x + y * y) + radius * radius;
                    (q > 0.0).then(|| t + q.sqrt())
                })
                .fold(0.0, f64::max);
            (far + 0.01).min(SCAN_MAX_RANGE as f64)
        });
        let differ: Vec<usize> = (0..SCAN_BEAMS)
            .filter(|&j| scan_cut(j).unwrap().to_bits() != want[j].to_bits())
            .collect();
        let table: Vec<String> = want
            .chunks(4)
            .map(|row| {
                row.iter()
                    .map(|v| format!("{v:?},"))
                    .collect::<Vec<_>>()
                    .join(" ")
            })
            .collect();
        assert!(
            differ.is_empty(),
            "SCAN_CUT differs from its definition at beams {differ:?}; the table is\n{}",
            table.join("\n")
        );
    }

    #[test]
    fn a_beam_at_its_cut_is_one_no_evaluation_sees() {
        // The smallest range a beam that reaches its cut can read on the wire (its true range,
        // at least the cut, rounded to the centimetre), in open space and with every other beam
        // close enough to be measured (so the evaluator does not take its open-space exit).
        for others in [SCAN_MAX_RANGE, 0.6] {
            let mut far = Observation::open_space();
            far.scan.ranges = [others; SCAN_BEAMS];
            for j in 0..SCAN_BEAMS {
                let cut = scan_cut(j).unwrap();
                assert!(cut > 0.25 && cut < 3.0, "beam {j}: {cut}");
                let mut near = far.clone();
                near.scan.ranges[j] = (libm::floor((cut - 0.005) * 100.0) / 100.0) as f32;
                let mut at_max = far.clone();
                at_max.scan.ranges[j] = SCAN_MAX_RANGE;
                assert_eq!(seen(&near), seen(&at_max), "beam {j} at {cut} m");
            }
        }
        assert_eq!(scan_cut(SCAN_BEAMS), None);
    }

    #[test]
    fn observe_near_is_evaluated_as_observe_is() {
        // Every built-in scenario, a few hundred ticks of seeded random allowed actions.
        for builtin in crate::world::registry::SCENARIOS {
            let scenario = Arc::new(crate::world::registry::load_scenario(builtin.name).unwrap());
            let mut e = Episode::new(scenario);
            let mut evaluator = firmware_core::evaluator::Evaluator::new();
            let mut state = 0x9e37_79b9_7f4a_7c15u64;
            let (mut cut_beams, mut steps) = (0, 0);
            while steps < 300 {
                let (whole, near) = (e.observe(), e.observe_near());
                assert_eq!(seen(&whole), seen(&near), "{} tick {steps}", builtin.name);
                let mut rest = whole.clone();
                rest.scan = near.scan;
                assert_eq!(format!("{rest:?}"), format!("{near:?}"), "all but the scan");
                for j in 0..SCAN_BEAMS {
                    let cut = scan_cut(j).unwrap() as f32;
                    let (w, n) = (whole.scan.ranges[j], near.scan.ranges[j]);
                    if n == SCAN_MAX_RANGE && w != n {
                        assert!(w >= cut - 0.006, "{} beam {j}: {w} read {n}", builtin.name);
                        cut_beams += 1;
                    } else {
                        assert_eq!(w.to_bits(), n.to_bits(), "{} beam {j}", builtin.name);
                    }
                }
                let allowed: Vec<_> = evaluator
                    .evaluation(whole.check().unwrap())
                    .allowed()
                    .iter()
                    .collect();
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                let action =
                    (!allowed.is_empty()).then(|| allowed[(state >> 33) as usize % allowed.len()]);
                e.drive(action);
                steps += 1;
            }
            assert!(cut_beams > 0, "{}: some beam was cut", builtin.name);
        }
    }

    #[test]
    fn the_scan_is_the_same_whichever_beams_skip_the_point_tests() {
        // The beams cast first (without the point tests) are a hint only: none, every one, the
        // hits of the tick before (as `observe_near` runs) and seeded random sets give the same
        // observation, bit for bit, on every built-in scenario; and the hits are the beams cut
        // short of their cut.
        let order = *SCAN_CUT_ORDER;
        let mut sorted = order;
        sorted.sort_unstable();
        assert_eq!(sorted, BEAMS_IN_ORDER, "every beam once");
        assert!(order.windows(2).all(|w| {
            let (a, b) = (SCAN_CUT[usize::from(w[0])], SCAN_CUT[usize::from(w[1])]);
            a < b || (a == b && w[0] < w[1])
        }));
        let mut uniform = crate::world::test_uniform(0x2545_f491_4f6c_dd1d);
        let mut skipped_hits = 0;
        for builtin in crate::world::registry::SCENARIOS {
            let scenario = Arc::new(crate::world::registry::load_scenario(builtin.name).unwrap());
            let mut e = Episode::new(scenario);
            let mut evaluator = firmware_core::evaluator::Evaluator::new();
            for tick in 0..300 {
                let hint = e.scan_hits.get();
                let near = e.observe_near();
                let hits = e.scan_hits.get();
                let random = (uniform() * (u64::MAX as f64)) as u64;
                for cast_first in [0, u64::MAX, hint, random, !hint] {
                    let cell = Cell::new(cast_first);
                    let again = observe_within(
                        &e.scenario,
                        &e.car,
                        e.s,
                        &SCAN_CUT,
                        &e.cut_cells,
                        &SCAN_CUT_ORDER,
                        &cell,
                    );
                    assert_eq!(
                        format!("{again:?}"),
                        format!("{near:?}"),
                        "{} tick {tick}",
                        builtin.name
                    );
                    assert_eq!(cell.get(), hits, "{} tick {tick}", builtin.name);
                }
                for j in 0..SCAN_BEAMS {
                    let short = near.scan.ranges[j] != SCAN_MAX_RANGE;
                    assert_eq!(hits >> j & 1 == 1, short, "{} beam {j}", builtin.name);
                    skipped_hits += usize::from(short && hint >> j & 1 == 1);
                }
                let allowed: Vec<_> = evaluator
                    .evaluation(near.check().unwrap())
                    .allowed()
                    .iter()
                    .collect();
                let pick = (uniform() * allowed.len() as f64) as usize;
                e.drive(allowed.get(pick).copied());
            }
        }
        assert!(skipped_hits > 1000, "{skipped_hits} hits cast first");
    }

    #[test]
    fn driving_into_a_wall_resets_and_blocked_resets() {
        let mut e = Episode::new(Arc::new(world(vec![])));
        // Straight ahead along y = 1: the wall at x = 6 comes after about 4.5 m of driving.
        let mut reset = None;
        for _ in 0..100 {
            let r = e.drive(ActionIndex::new(0));
            if r.reset.is_some() {
                reset = r.reset;
                break;
            }
        }
        assert_eq!(
            reset,
            Some(ResetReason::PathEnd),
            "the open path ends at x = 5 first"
        );
        assert_eq!(e.laps(), 1);
        let mut e = Episode::new(Arc::new(world(vec![])));
        // Circling right from y = 1 hits the south wall (y = 0.05) within a turn.
        let right = ActionIndex::new(8).unwrap();
        assert!(firmware_core::lattice::trajectory(right).end().y < 0.0);
        let mut got = None;
        for _ in 0..50 {
            if let Some(r) = e.drive(Some(right)).reset {
                got = Some(r);
                break;
            }
        }
        assert_eq!(got, Some(ResetReason::Collision));
        assert_eq!(
            e.car().pose,
            Pose {
                x: 1.0,
                y: 1.0,
                theta: 0.0
            },
            "back at the start"
        );
        assert_eq!(e.drive(None).reset, Some(ResetReason::Blocked));
    }
}
