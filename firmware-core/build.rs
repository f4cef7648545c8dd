//! Generates the 64-trajectory lattice and the evaluator's precomputed tables.
//!
//! Geometry is computed in f64 with `libm` (the same results on every build host, unlike the
//! platform's `sin`), then rounded to f32 once. Output: `$OUT_DIR/lattice_tables.rs`, included
//! by `src/lattice/mod.rs`.

use std::fmt::Write as _;
use std::path::PathBuf;

#[path = "src/lattice/params.rs"]
#[allow(dead_code, unreachable_pub)]
mod params;

use params::*;

/// Number of regions (groups of nearby clusters) the semantic pass tests before their clusters.
/// A constant of the evaluator's pruning, not of the lattice: here rather than in params.rs.
const REGION_COUNT: usize = 8;

/// A point or a displacement of the plane, in f64.
///
/// The build script's own, so that building firmware-core does not compile nalgebra a second
/// time as a build dependency (issue 17, item 6: that copy sat on every build's critical path).
/// Each operation is nalgebra's own formula in the same order (`UnitComplex × Vector2` is
/// `(c·x − s·y, s·x + c·y)`, an isometry rotates then adds its translation, a vector over a
/// scalar divides each coordinate), so the tables are the same bytes.
#[derive(Clone, Copy)]
struct Xy {
    x: f64,
    y: f64,
}

impl Xy {
    const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }

    fn plus(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y)
    }

    fn minus(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y)
    }

    fn over(self, k: f64) -> Self {
        Self::new(self.x / k, self.y / k)
    }
}

/// A pose of the car's rear axle in the frame of the trajectory's start: where it is, and its
/// heading (tracked as an angle, the sum of curvature × arc length, and turned into a rotation by
/// `libm`, never by the platform's `sin`, so that every build host makes the same tables).
#[derive(Clone, Copy)]
struct Pose {
    at: Xy,
    heading: f64,
}

impl Pose {
    const START: Self = Self {
        at: Xy::new(0.0, 0.0),
        heading: 0.0,
    };

    /// `v` turned by the heading.
    fn rotate(&self, v: Xy) -> Xy {
        let (c, s) = (libm::cos(self.heading), libm::sin(self.heading));
        Xy::new(c * v.x - s * v.y, s * v.x + c * v.y)
    }

    /// The point `v` of the pose's own frame, in the start's frame.
    fn transform_point(&self, v: Xy) -> Xy {
        self.rotate(v).plus(self.at)
    }
}

/// The unit vector at right angles to heading `theta`, pointing away from the centre of a left
/// turn: `(sin θ, −cos θ)`.
fn normal(theta: f64) -> Xy {
    Xy::new(libm::sin(theta), -libm::cos(theta))
}

/// Advances `p` along an arc of curvature `k` by `s` metres (exact closed form): the chord of an
/// arc from heading θ₁ to θ₂ = θ₁ + k·s is `(n(θ₂) − n(θ₁)) / k`, a straight step is `s` along
/// the heading.
fn arc(p: Pose, k: f64, s: f64) -> Pose {
    if k.abs() < 1e-12 {
        Pose {
            at: p.at.plus(p.rotate(Xy::new(s, 0.0))),
            heading: p.heading,
        }
    } else {
        let heading = p.heading + k * s;
        Pose {
            at: p.at.plus(normal(heading).minus(normal(p.heading)).over(k)),
            heading,
        }
    }
}

struct Traj {
    /// (curvature, length) of each segment.
    segments: [(f64, f64); 2],
    speed: f64,
    /// Curvature levels in units of the family's step, for ordering and mirroring.
    levels: [i32; 2],
    creep: bool,
}

impl Traj {
    fn length(&self) -> f64 {
        self.segments[0].1 + self.segments[1].1
    }

    /// Pose after `s` metres.
    fn pose_at(&self, s: f64) -> Pose {
        let mut p = Pose::START;
        let mut left = s;
        for &(k, len) in &self.segments {
            let step = left.min(len);
            p = arc(p, k, step);
            left -= step;
            if left <= 0.0 {
                break;
            }
        }
        p
    }
}

fn f(x: f64) -> String {
    // `{:?}` of an f32 prints the shortest string that parses back to the same f32.
    format!("{:?}", x as f32)
}

fn main() {
    println!("cargo::rerun-if-changed=src/lattice/params.rs");
    println!("cargo::rerun-if-changed=build.rs");

    let kappa_max = libm::tan(MAX_PLANNING_STEERING as f64) / WHEELBASE as f64;

    // Cruise: two 0.5 m segments, curvature levels -3..=3 (thirds of kappa_max).
    let half = (CRUISE_LEVELS as i32 - 1) / 2;
    let mut cruise = Vec::new();
    for l1 in -half..=half {
        for l2 in -half..=half {
            cruise.push(Traj {
                segments: [
                    (
                        kappa_max * l1 as f64 / half as f64,
                        CRUISE_SEGMENT_LENGTH as f64,
                    ),
                    (
                        kappa_max * l2 as f64 / half as f64,
                        CRUISE_SEGMENT_LENGTH as f64,
                    ),
                ],
                speed: CRUISE_SPEED as f64,
                levels: [l1, l2],
                creep: false,
            });
        }
    }
    // Gentlest first; mirror pairs adjacent, left-turning first.
    cruise.sort_by_key(|t| {
        let [a, b] = t.levels;
        // The pair's canonical member turns left first; its mirror image sorts right after it.
        let left_first = a > 0 || (a == 0 && b > 0);
        let (ca, cb) = if left_first || (a == 0 && b == 0) {
            (a, b)
        } else {
            (-a, -b)
        };
        (a.abs() + b.abs(), a.abs(), -ca, -cb, !left_first)
    });

    // Creep: one 0.5 m arc (written as two equal halves), levels -7..=7.
    let chalf = (CREEP_LEVELS as i32 - 1) / 2;
    let mut creep = Vec::new();
    for l in -chalf..=chalf {
        let k = kappa_max * l as f64 / chalf as f64;
        creep.push(Traj {
            segments: [
                (k, CREEP_LENGTH as f64 / 2.0),
                (k, CREEP_LENGTH as f64 / 2.0),
            ],
            speed: CREEP_SPEED as f64,
            levels: [l, l],
            creep: true,
        });
    }
    creep.sort_by_key(|t| (t.levels[0].abs(), -t.levels[0]));

    let all: Vec<Traj> = cruise.into_iter().chain(creep).collect();
    assert_eq!(all.len(), 64, "the lattice has exactly 64 trajectories");

    let mirror: Vec<usize> = all
        .iter()
        .map(|t| {
            all.iter()
                .position(|m| m.creep == t.creep && m.levels == [-t.levels[0], -t.levels[1]])
                .expect("every trajectory has a mirror image")
        })
        .collect();

    // Poses at s = L·i/SAMPLES, i = 1..=SAMPLES, and the footprint centre at each.
    let mut out = String::new();
    writeln!(
        out,
        "// @generated by build.rs from src/lattice/params.rs. Do not edit."
    )
    .unwrap();
    writeln!(
        out,
        "/// `κ_max = tan(MAX_PLANNING_STEERING) / WHEELBASE` (1/m)."
    )
    .unwrap();
    writeln!(out, "pub const MAX_CURVATURE: f32 = {};", f(kappa_max)).unwrap();
    writeln!(out, "/// The 64 trajectories, indexed by action.").unwrap();
    writeln!(
        out,
        "pub static TRAJECTORIES: [Trajectory; crate::MAX_ACTIONS] = ["
    )
    .unwrap();

    let mut points: Vec<(f32, f32)> = Vec::new();
    let mut ends: Vec<String> = Vec::new();
    let mut centres_of: Vec<String> = Vec::new();
    let mut poses_of: Vec<String> = Vec::new();
    let mut sample_of: Vec<[usize; SAMPLES]> = Vec::new();
    let mut counts: Vec<usize> = Vec::new();
    for (i, t) in all.iter().enumerate() {
        let mut poses = String::new();
        let mut centers = String::new();
        let mut idx = [0usize; SAMPLES];
        for k in 0..SAMPLES {
            let s = t.length() * (k + 1) as f64 / SAMPLES as f64;
            let p = t.pose_at(s);
            write!(
                poses,
                "Pose {{ x: {}, y: {}, theta: {} }}, ",
                f(p.at.x),
                f(p.at.y),
                f(p.heading)
            )
            .unwrap();
        }
        let end = t.pose_at(t.length());
        ends.push(format!("[{}, {}]", f(end.at.x), f(end.at.y)));
        // Clearance samples every SAMPLE_SPACING of arc; unused slots repeat the last sample.
        let count = (t.length() / SAMPLE_SPACING as f64).round() as usize;
        assert!((1..=SAMPLES).contains(&count));
        counts.push(count);
        for (k, slot) in idx.iter_mut().enumerate() {
            let s = SAMPLE_SPACING as f64 * (k.min(count - 1) + 1) as f64;
            // The footprint's centre, FOOTPRINT_CENTER_OFFSET ahead of the rear axle.
            let centre = t
                .pose_at(s)
                .transform_point(Xy::new(FOOTPRINT_CENTER_OFFSET as f64, 0.0));
            let pt = (centre.x as f32, centre.y as f32);
            write!(centers, "[{:?}, {:?}], ", pt.0, pt.1).unwrap();
            *slot = match points
                .iter()
                .position(|q| q.0.to_bits() == pt.0.to_bits() && q.1.to_bits() == pt.1.to_bits())
            {
                Some(j) => j,
                None => {
                    points.push(pt);
                    points.len() - 1
                }
            };
        }
        sample_of.push(idx);
        let seg = |(k, len): (f64, f64)| {
            format!(
                "Segment {{ curvature: {}, length: {}, steering: {} }}",
                f(k),
                f(len),
                f(libm::atan(k * WHEELBASE as f64))
            )
        };
        writeln!(
            out,
            "    Trajectory {{ family: Family::{}, segments: [{}, {}], speed: {}, index: {}, sample_count: {}, mirror: {} }},",
            if t.creep { "Creep" } else { "Cruise" },
            seg(t.segments[0]),
            seg(t.segments[1]),
            f(t.speed),
            i,
            counts[i],
            mirror[i],
        )
        .unwrap();
        centres_of.push(format!("[{centers}]"));
        poses_of.push(format!("[{poses}]"));
    }
    writeln!(out, "];").unwrap();
    writeln!(
        out,
        "/// Per trajectory, its poses (`Trajectory::poses`), apart from the trajectories so that an\n\
         /// image that reads only their segments (the car's) does not hold them."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static TRAJECTORY_POSES: [[Pose; SAMPLES]; crate::MAX_ACTIONS] = [{}];",
        poses_of.join(",\n")
    )
    .unwrap();
    writeln!(
        out,
        "/// Per trajectory, its clearance samples (`Trajectory::samples`; unused slots repeat the\n\
         /// last), apart from the trajectories so that an image that reads only their segments\n\
         /// (the car's) does not hold them."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static TRAJECTORY_SAMPLES: [[[f32; 2]; SAMPLES]; crate::MAX_ACTIONS] = [{}];",
        centres_of.join(",\n")
    )
    .unwrap();
    writeln!(
        out,
        "/// The end of every trajectory, `[x, y]`: the position of its last pose (the evaluator's\n\
         /// own copy, so that the car's image needs no whole trajectory)."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static END_POINTS: [[f32; 2]; crate::MAX_ACTIONS] = [{}];",
        ends.join(", ")
    )
    .unwrap();

    // Beam directions.
    let bearing = |j: usize| {
        -std::f64::consts::PI + (j as f64 + 0.5) * (2.0 * std::f64::consts::PI / SCAN_BEAMS as f64)
    };
    let list = |v: Vec<String>| v.join(", ");
    // Computed for the left half and mirrored, so beam j and beam SCAN_BEAMS-1-j are exact mirror
    // images (cos equal, sin negated): the evaluator is then exactly mirror-symmetric.
    let direction = |j: usize| {
        let m = SCAN_BEAMS - 1 - j;
        if j >= SCAN_BEAMS / 2 {
            (libm::cos(bearing(j)), libm::sin(bearing(j)))
        } else {
            (libm::cos(bearing(m)), -libm::sin(bearing(m)))
        }
    };
    writeln!(
        out,
        "pub(crate) static BEAM_COS: [f32; {SCAN_BEAMS}] = [{}];",
        list((0..SCAN_BEAMS).map(|j| f(direction(j).0)).collect())
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static BEAM_SIN: [f32; {SCAN_BEAMS}] = [{}];",
        list((0..SCAN_BEAMS).map(|j| f(direction(j).1)).collect())
    )
    .unwrap();

    // Clusters of nearby samples, which the evaluator prunes together: the samples at the same arc
    // length of trajectories that share their start (the first segments from the origin, the
    // creep arcs, the second segments from each first segment's end) lie on a short arc; each such
    // ring is halved until every sample is within CLUSTER_SPREAD of its cluster's centre.
    let mut ring_of: Vec<Option<(i32, usize)>> = vec![None; points.len()];
    for (a, t) in all.iter().enumerate() {
        for (k, &u) in sample_of[a][..counts[a]].iter().enumerate() {
            let key = if t.creep || k < SAMPLES / 2 {
                (i32::MAX, k)
            } else {
                (t.levels[0], k)
            };
            ring_of[u] = Some(ring_of[u].map_or(
                key,
                |old: (i32, usize)| {
                    if key.1 < old.1 { key } else { old }
                },
            ));
        }
    }
    let mut rings: Vec<((i32, usize), Vec<usize>)> = Vec::new();
    for (u, key) in ring_of.iter().enumerate() {
        let key = key.expect("every sample belongs to a trajectory");
        match rings.iter_mut().find(|(k, _)| *k == key) {
            Some((_, members)) => members.push(u),
            None => rings.push((key, vec![u])),
        }
    }
    let bounds = |members: &[usize]| {
        let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
        for &u in members {
            let q = [points[u].0 as f64, points[u].1 as f64];
            for i in 0..2 {
                lo[i] = lo[i].min(q[i]);
                hi[i] = hi[i].max(q[i]);
            }
        }
        let centre = [
            ((lo[0] + hi[0]) / 2.0) as f32 as f64,
            ((lo[1] + hi[1]) / 2.0) as f32 as f64,
        ];
        let spread = members
            .iter()
            .map(|&u| {
                libm::hypot(
                    points[u].0 as f64 - centre[0],
                    points[u].1 as f64 - centre[1],
                )
            })
            .fold(0.0, f64::max);
        (
            centre,
            spread,
            if hi[0] - lo[0] >= hi[1] - lo[1] { 0 } else { 1 },
        )
    };
    let mut clusters: Vec<Vec<usize>> = Vec::new();
    let mut todo: Vec<Vec<usize>> = rings.into_iter().map(|(_, m)| m).collect();
    while let Some(mut members) = todo.pop() {
        let (_, spread, axis) = bounds(&members);
        if spread <= CLUSTER_SPREAD as f64 || members.len() == 1 {
            clusters.push(members);
            continue;
        }
        let coordinate = |u: usize| if axis == 0 { points[u].0 } else { points[u].1 };
        members.sort_by(|&a, &b| coordinate(a).total_cmp(&coordinate(b)).then(a.cmp(&b)));
        let upper = members.split_off(members.len() / 2);
        todo.push(upper);
        todo.push(members);
    }
    // Clusters by increasing distance of their centre from the sensor (samples renumbered below,
    // in their first-appearance order within a cluster).
    let rho_of = |c: [f64; 2]| libm::hypot(c[0], c[1]);
    for members in &mut clusters {
        members.sort_unstable();
    }
    clusters.sort_by(|a, b| {
        rho_of(bounds(a).0)
            .total_cmp(&rho_of(bounds(b).0))
            .then(a[0].cmp(&b[0]))
    });
    // Regions: groups of nearby clusters, which the semantic pass tests as one where it can
    // (see `Evaluator::semantic`): k-means on the clusters' centres (weighted by their members),
    // started from the centre farthest from the lattice's and then, one at a time, the centre
    // farthest from those taken (deterministic), a fixed number of rounds. Each region has the
    // centre of its members' bounding box and the largest distance of a member from it, rounded
    // up as a cluster's. Samples are renumbered region by region, then cluster by cluster (in
    // `REGION_CLUSTERS` order), so that a region's members are consecutive too; `CLUSTERS` keeps
    // its order (by distance from the sensor).
    let every: Vec<usize> = (0..points.len()).collect();
    let (centre, _, _) = bounds(&every);
    let centres: Vec<[f64; 2]> = clusters.iter().map(|m| bounds(m).0).collect();
    let d2 = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2);
    let mut seeds = vec![
        *centres
            .iter()
            .max_by(|a, b| d2(**a, centre).total_cmp(&d2(**b, centre)))
            .expect("clusters"),
    ];
    while seeds.len() < REGION_COUNT.min(centres.len()) {
        let far = |c: &[f64; 2]| seeds.iter().map(|s| d2(*c, *s)).fold(f64::MAX, f64::min);
        let next = *centres
            .iter()
            .max_by(|a, b| far(a).total_cmp(&far(b)))
            .expect("clusters");
        seeds.push(next);
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for _ in 0..50 {
        groups = vec![Vec::new(); seeds.len()];
        for (i, c) in centres.iter().enumerate() {
            let (g, _) = seeds
                .iter()
                .enumerate()
                .map(|(g, s)| (g, d2(*c, *s)))
                .fold((0, f64::MAX), |best, x| if x.1 < best.1 { x } else { best });
            groups[g].push(i);
        }
        groups.retain(|g| !g.is_empty());
        seeds = groups
            .iter()
            .map(|g| {
                let w: f64 = g.iter().map(|&i| clusters[i].len() as f64).sum();
                let mut m = [0.0; 2];
                for &i in g {
                    for k in 0..2 {
                        m[k] += centres[i][k] * clusters[i].len() as f64 / w;
                    }
                }
                m
            })
            .collect();
    }
    let order: Vec<usize> = groups
        .iter()
        .flatten()
        .flat_map(|&i| clusters[i].iter().copied())
        .collect();
    let mut cluster_start = vec![0usize; clusters.len()];
    let mut next = 0;
    for &i in groups.iter().flatten() {
        cluster_start[i] = next;
        next += clusters[i].len();
    }
    assert_eq!(order.len(), points.len());
    let mut renumber = vec![0usize; points.len()];
    for (new, &old) in order.iter().enumerate() {
        renumber[old] = new;
    }
    for idx in &mut sample_of {
        for u in idx.iter_mut() {
            *u = renumber[*u];
        }
    }
    let cluster_info: Vec<([f64; 2], f64)> = clusters
        .iter()
        .map(|m| {
            let (c, spread, _) = bounds(m);
            (c, spread)
        })
        .collect();
    let points: Vec<(f32, f32)> = order.iter().map(|&old| points[old]).collect();
    let mut trajectories_of = vec![0u64; points.len()];
    for (a, idx) in sample_of.iter().enumerate() {
        for &u in &idx[..counts[a]] {
            trajectories_of[u] |= 1u64 << a;
        }
    }

    writeln!(
        out,
        "/// Number of distinct footprint-centre sample points over the whole lattice."
    )
    .unwrap();
    writeln!(out, "pub const UNIQUE_SAMPLES: usize = {};", points.len()).unwrap();
    writeln!(
        out,
        "/// The distinct sample points, region by region, cluster by cluster (see [`REGIONS`], [`CLUSTERS`])."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static SAMPLE_POINTS: [[f32; 2]; UNIQUE_SAMPLES] = [{}];",
        list(
            points
                .iter()
                .map(|p| format!("[{:?}, {:?}]", p.0, p.1))
                .collect()
        )
    )
    .unwrap();
    let max_rho = points
        .iter()
        .map(|&p| rho_of([p.0 as f64, p.1 as f64]))
        .fold(0.0, f64::max);
    writeln!(
        out,
        "/// Largest distance of a sample point from the sensor (m)."
    )
    .unwrap();
    writeln!(out, "pub const MAX_SAMPLE_RHO: f32 = {};", f(max_rho)).unwrap();
    writeln!(
        out,
        "/// Per distinct sample: the trajectories it belongs to, one bit per action."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static SAMPLE_TRAJECTORIES: [u64; UNIQUE_SAMPLES] = [{}];",
        list(
            trajectories_of
                .iter()
                .map(|m| format!("{m:#018x}"))
                .collect()
        )
    )
    .unwrap();

    // For each cluster and each of two distances d (the collision radius, the obstacle clip), the
    // beams whose scan point may come within d of one of its samples, i.e. within d + spread of
    // its centre: a window of bearings and a band of range bins (`RANGE_BIN_WIDTH` wide). A point
    // on the ray at bearing β is at least ρ·sin|Δβ| from a centre at range ρ and bearing α when
    // |Δβ| ≤ 90°, and at least ρ beyond, so the window is |Δβ| ≤ asin(d'/ρ) for d' = d + spread
    // (the half plane for a centre nearer than d'; the evaluator adds the beams shorter than d',
    // whatever their bearing), widened by 0.01 rad so that no f32 rounding can matter. A point
    // whose range is not within d' of ρ is farther than d': the band holds the bins that meet
    // [ρ − d' − REACH_MARGIN, ρ + d' + REACH_MARGIN].
    let bin_width = RANGE_BIN_WIDTH as f64;
    let margin = REACH_MARGIN as f64;
    let max_spread = cluster_info.iter().map(|c| c.1).fold(0.0, f64::max);
    assert!(max_spread <= CLUSTER_SPREAD as f64 || clusters.iter().any(|m| m.len() == 1));
    let range_bins =
        ((max_rho + OBSTACLE_CLIP as f64 + max_spread + margin) / bin_width).ceil() as usize;
    writeln!(
        out,
        "/// Number of range bins the evaluator sorts the beams into: enough for every cluster's reach."
    )
    .unwrap();
    writeln!(out, "pub(crate) const RANGE_BINS: usize = {range_bins};").unwrap();
    // For each beam, the largest range at which its scan point can come within the obstacle clip
    // (and the margin) of some sample: on the ray along the beam's direction (the f32 cosine and
    // sine the evaluator multiplies the range by), the farthest point of the union of the discs
    // of that radius around the samples, rounded up. A longer beam is out of every sample's
    // reach. (Every ray starts within the clip of the first samples, so the nearest end is 0.)
    let beam_reach: Vec<f64> = (0..SCAN_BEAMS)
        .map(|j| {
            let (c, s) = direction(j);
            let (c, s) = (c as f32 as f64, s as f32 as f64);
            let radius = OBSTACLE_CLIP as f64 + margin;
            let far = points
                .iter()
                .filter_map(|&(x, y)| {
                    let (x, y) = (x as f64, y as f64);
                    let t = c * x + s * y;
                    let q = t * t - (x * x + y * y) + radius * radius;
                    (q > 0.0).then(|| t + q.sqrt())
                })
                .fold(0.0, f64::max);
            let far = far * (1.0 + 1e-6) + 1e-5;
            assert!(
                far > 0.0 && far < range_bins as f64 * bin_width,
                "beam {j}: {far}"
            );
            far
        })
        .collect();
    writeln!(
        out,
        "/// Per beam: the largest range at which its scan point may come within the obstacle clip of a sample."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static BEAM_REACH: [f32; {SCAN_BEAMS}] = [{}];",
        list(
            beam_reach
                .iter()
                .map(|&r| format!("{:?}", (r as f32).next_up()))
                .collect()
        )
    )
    .unwrap();
    // On a host (not the car: these are compiled for every target but `arm`), the evaluator
    // measures the samples `LANES` at a time, in chunks of consecutive samples. For each beam and
    // range bin, the chunks one of whose samples a scan point of that beam in that bin may come
    // within the obstacle clip of: on the segment of the beam's ray (its f32 cosine and sine)
    // over the bin (widened by 0.1 mm each side, more than the rounding of the range times the
    // bins' scale, and cut at the beam's reach), a chunk none of whose samples is nearer than the
    // clip and a millimetre (far above the f32 rounding of a point's coordinates and of a
    // squared distance) is left out.
    const LANES: usize = 16;
    let chunks = points.len().div_ceil(LANES);
    assert!(chunks <= 32, "a chunk mask is a u32");
    let beam_chunks: Vec<Vec<u32>> = (0..SCAN_BEAMS)
        .map(|j| {
            let (c, s) = direction(j);
            let (c, s) = (c as f32 as f64, s as f32 as f64);
            (0..range_bins)
                .map(|b| {
                    let r0 = (b as f64 * bin_width - 1e-4).max(0.0);
                    let r1 = ((b + 1) as f64 * bin_width + 1e-4).min(beam_reach[j]);
                    let mut mask = 0u32;
                    if r0 > r1 {
                        return mask;
                    }
                    for (k, chunk) in points.chunks(LANES).enumerate() {
                        let near = chunk.iter().any(|&(x, y)| {
                            let (x, y) = (x as f64, y as f64);
                            let t = (c * x + s * y).clamp(r0, r1);
                            let (dx, dy) = (x - t * c, y - t * s);
                            (dx * dx + dy * dy).sqrt() < OBSTACLE_CLIP as f64 + margin
                        });
                        if near {
                            mask |= 1 << k;
                        }
                    }
                    mask
                })
                .collect()
        })
        .collect();
    writeln!(
        out,
        "/// Samples side by side in a wide target's passes (not the car's)."
    )
    .unwrap();
    writeln!(
        out,
        "#[cfg(not(target_arch = \"arm\"))]\npub(crate) const LANES: usize = {LANES};"
    )
    .unwrap();
    writeln!(
        out,
        "/// Per beam and range bin: the chunks of `LANES` samples that its scan point may come within the obstacle clip of (a wide target's)."
    )
    .unwrap();
    writeln!(
        out,
        "#[cfg(not(target_arch = \"arm\"))]\npub(crate) static BEAM_CHUNKS: [[u32; RANGE_BINS]; {SCAN_BEAMS}] = [{}];",
        list(
            beam_chunks
                .iter()
                .map(|m| format!("[{}]", list(m.iter().map(|x| format!("{x:#x}")).collect())))
                .collect()
        )
    )
    .unwrap();
    let reach = |c: [f64; 2], d: f64| {
        let r = rho_of(c);
        let alpha = libm::atan2(c[1], c[0]);
        // A centre nearer the sensor than d: the half plane, and the evaluator adds the beams
        // shorter than d (`behind`). Beyond d the window alone holds every beam within d.
        let behind = r <= d * 1.001;
        let h = if behind {
            std::f64::consts::FRAC_PI_2 + 0.01
        } else {
            libm::asin(d / r) + 0.01
        };
        let beams: Vec<usize> = (0..SCAN_BEAMS)
            .filter(|&j| {
                let mut delta = bearing(j) - alpha;
                while delta > std::f64::consts::PI {
                    delta -= 2.0 * std::f64::consts::PI;
                }
                while delta < -std::f64::consts::PI {
                    delta += 2.0 * std::f64::consts::PI;
                }
                delta.abs() <= h
            })
            .collect();
        assert!(!beams.is_empty() && beams.len() <= SCAN_BEAMS / 2 + 2);
        let window: u64 = beams.iter().fold(0u64, |m, &j| m | 1u64 << j);
        let lo = ((r - d - margin).max(0.0) / bin_width).floor() as usize;
        let hi = (((r + d + margin) / bin_width).ceil() as usize).min(range_bins);
        assert!(lo < hi && hi <= u8::MAX as usize);
        (
            beams.len(),
            format!(
                "Reach {{ window: [{:#010x}, {:#010x}], bins: [{lo}, {hi}], behind: {behind} }}",
                window as u32,
                (window >> 32) as u32
            ),
        )
    };
    let mut window_pairs = 0usize;
    let mut entries = Vec::new();
    for ((members, &(centre, spread)), &start) in
        clusters.iter().zip(cluster_info.iter()).zip(&cluster_start)
    {
        // Rounded up, so that every member is within `spread` of the f32 centre in f32 too.
        let spread = (spread * (1.0 + 1e-6) + 1e-6) as f32;
        let spread = if (spread as f64) < 0.0 { 0.0 } else { spread };
        let (pairs, clip) = reach(centre, OBSTACLE_CLIP as f64 + spread as f64);
        window_pairs += pairs * members.len();
        let end = start + members.len();
        let trajectories = (start..end).fold(0u64, |m, u| m | trajectories_of[u]);
        entries.push(format!(
            "Cluster {{ centre: [{:?}, {:?}], spread: {:?}, samples: [{start}, {end}], trajectories: {trajectories:#018x}, clip: {clip} }}",
            centre[0] as f32, centre[1] as f32, spread
        ));
    }
    writeln!(
        out,
        "/// Largest distance of a sample from its cluster's centre (m)."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) const MAX_CLUSTER_SPREAD: f32 = {};",
        f(max_spread * (1.0 + 1e-6) + 1e-6)
    )
    .unwrap();
    writeln!(out, "/// Number of sample clusters.").unwrap();
    writeln!(
        out,
        "pub(crate) const CLUSTER_COUNT: usize = {};",
        clusters.len()
    )
    .unwrap();
    writeln!(
        out,
        "/// The sample clusters, by increasing distance of their centre from the sensor."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static CLUSTERS: [Cluster; CLUSTER_COUNT] = [{}];",
        list(entries)
    )
    .unwrap();
    writeln!(
        out,
        "/// Number of (sample, beam) pairs in the clusters' windows of the obstacle clip."
    )
    .unwrap();
    writeln!(out, "pub const WINDOW_PAIRS: usize = {window_pairs};").unwrap();
    // Every sample as one cluster (the centre of their bounding box, the largest distance from
    // it, rounded up as above): the semantic pass settles an object for the whole lattice at
    // once where it can (see `Evaluator::semantic`).
    let every: Vec<usize> = (0..points.len()).collect();
    let (centre, spread, _) = bounds(&every);
    let spread = (spread * (1.0 + 1e-6) + 1e-6) as f32;
    let (_, clip) = reach(centre, OBSTACLE_CLIP as f64 + spread as f64);
    let trajectories = trajectories_of.iter().fold(0u64, |m, &t| m | t);
    writeln!(
        out,
        "/// Every sample as one cluster: the centre of their bounding box, and the largest distance from it."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static LATTICE: Cluster = Cluster {{ centre: [{:?}, {:?}], spread: {:?}, samples: [0, {}], trajectories: {trajectories:#018x}, clip: {clip} }};",
        centre[0] as f32,
        centre[1] as f32,
        spread,
        points.len()
    )
    .unwrap();
    let mut region_entries = Vec::new();
    let mut region_clusters = Vec::new();
    let mut max_region_spread = 0.0f64;
    let mut start = 0;
    for g in &groups {
        let members: Vec<usize> = g
            .iter()
            .flat_map(|&i| clusters[i].iter().copied())
            .collect();
        let (centre, spread, _) = bounds(&members);
        max_region_spread = max_region_spread.max(spread);
        let spread = (spread * (1.0 + 1e-6) + 1e-6) as f32;
        let first = region_clusters.len();
        region_clusters.extend_from_slice(g);
        let end = start + members.len();
        let trajectories = (start..end).fold(0u64, |m, u| m | trajectories_of[u]);
        region_entries.push(format!(
            "Region {{ centre: [{:?}, {:?}], spread: {:?}, samples: [{start}, {end}], clusters: [{first}, {}], trajectories: {trajectories:#018x} }}",
            centre[0] as f32,
            centre[1] as f32,
            spread,
            region_clusters.len()
        ));
        start = end;
    }
    assert!(region_clusters.len() == clusters.len() && clusters.len() <= u8::MAX as usize);
    writeln!(
        out,
        "/// Largest distance of a sample from its region's centre (m)."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) const MAX_REGION_SPREAD: f32 = {};",
        f(max_region_spread * (1.0 + 1e-6) + 1e-6)
    )
    .unwrap();
    writeln!(out, "/// Number of regions.").unwrap();
    writeln!(
        out,
        "pub(crate) const REGION_COUNT: usize = {};",
        region_entries.len()
    )
    .unwrap();
    writeln!(
        out,
        "/// Groups of nearby clusters (their clusters `REGION_CLUSTERS[clusters[0]..clusters[1]]`)."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static REGIONS: [Region; REGION_COUNT] = [{}];",
        list(region_entries)
    )
    .unwrap();
    writeln!(
        out,
        "/// The clusters (indices into `CLUSTERS`), region by region, increasing within each."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static REGION_CLUSTERS: [u8; CLUSTER_COUNT] = [{}];",
        list(region_clusters.iter().map(|i| i.to_string()).collect())
    )
    .unwrap();
    // Sums along trajectories share their starts: cruise trajectories with the same first
    // curvature share their first samples (all but the last of the first segment: that one lies a
    // hair into the second segment, f32 spacing times five being just above 0.5 m). Each
    // trajectory's sum is then a shared head (none for creep) and its own tail, added in the same
    // order as one pass along it.
    let mut heads: Vec<(i32, Vec<usize>)> = Vec::new();
    for (a, t) in all.iter().enumerate() {
        if t.creep {
            continue;
        }
        let idx = &sample_of[a][..counts[a]];
        match heads.iter_mut().find(|(l, _)| *l == t.levels[0]) {
            Some((_, head)) => {
                let common = head.iter().zip(idx).take_while(|(x, y)| x == y).count();
                head.truncate(common);
            }
            None => heads.push((t.levels[0], idx.to_vec())),
        }
    }
    let head_len = heads.iter().map(|(_, h)| h.len()).min().unwrap_or(0);
    assert!(
        head_len > 0,
        "cruise trajectories share their first samples"
    );
    for (_, head) in &mut heads {
        head.truncate(head_len);
    }
    // Creep trajectories take an empty head; short tails are padded. Both refer to the sample
    // index `PAD_SAMPLE`, the last slot of the evaluator's per-sample arrays (a power of two long),
    // whose clearance it keeps at 0: adding it changes no sum.
    let pad = points.len().next_power_of_two() - 1;
    assert!(pad >= points.len());
    writeln!(
        out,
        "/// The unused sample slot that pads heads and tails (its clearance stays 0)."
    )
    .unwrap();
    writeln!(out, "pub(crate) const PAD_SAMPLE: usize = {pad};").unwrap();
    heads.push((i32::MIN, vec![pad; head_len]));
    let tail_len = SAMPLES - head_len;
    let mut head_of = Vec::new();
    let mut tails = Vec::new();
    let mut scales = Vec::new();
    for (a, t) in all.iter().enumerate() {
        let idx = &sample_of[a][..counts[a]];
        let (head, mut tail) = if t.creep {
            (heads.len() - 1, idx.to_vec())
        } else {
            let h = heads
                .iter()
                .position(|(l, _)| *l == t.levels[0])
                .expect("every cruise trajectory has a head");
            assert_eq!(heads[h].1, idx[..head_len]);
            (h, idx[head_len..].to_vec())
        };
        assert!(!tail.is_empty() && tail.len() <= tail_len);
        tail.resize(tail_len, pad);
        head_of.push(head);
        tails.push(tail);
        scales.push(f((SAMPLES / counts[a]) as f64));
    }
    let indices = |v: &[usize]| format!("[{}]", list(v.iter().map(|i| i.to_string()).collect()));
    writeln!(
        out,
        "/// Number of shared heads: the cruise family's first curvatures, and an empty one."
    )
    .unwrap();
    writeln!(out, "pub(crate) const HEAD_COUNT: usize = {};", heads.len()).unwrap();
    writeln!(out, "/// Samples in a head.").unwrap();
    writeln!(out, "pub(crate) const HEAD_LEN: usize = {head_len};").unwrap();
    writeln!(out, "/// Samples in a tail (padded).").unwrap();
    writeln!(out, "pub(crate) const TAIL_LEN: usize = {tail_len};").unwrap();
    writeln!(
        out,
        "/// The samples of each head, in order along it (the last one empty: padding only)."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static HEADS: [[u16; HEAD_LEN]; HEAD_COUNT] = [{}];",
        list(heads.iter().map(|(_, h)| indices(h)).collect())
    )
    .unwrap();
    writeln!(out, "/// Per trajectory: its head in `HEADS`.").unwrap();
    writeln!(
        out,
        "pub(crate) static HEAD_OF: [u8; crate::MAX_ACTIONS] = [{}];",
        list(head_of.iter().map(|h| h.to_string()).collect())
    )
    .unwrap();
    writeln!(
        out,
        "/// Per trajectory: its samples after its head, in order, padded with `PAD_SAMPLE`."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static TAIL_OF: [[u16; TAIL_LEN]; crate::MAX_ACTIONS] = [{}];",
        list(tails.iter().map(|t| indices(t)).collect())
    )
    .unwrap();
    writeln!(
        out,
        "/// Per trajectory: `SAMPLES` over its number of samples, which scales its sums to ten samples."
    )
    .unwrap();
    writeln!(
        out,
        "pub(crate) static ROW_SCALE: [f32; crate::MAX_ACTIONS] = [{}];",
        list(scales)
    )
    .unwrap();
    writeln!(
        out,
        "#[cfg(test)]\npub(crate) static SAMPLE_OF: [[u16; {SAMPLES}]; crate::MAX_ACTIONS] = [{}];",
        list(
            sample_of
                .iter()
                .map(|s| format!("[{}]", list(s.iter().map(|i| i.to_string()).collect())))
                .collect()
        )
    )
    .unwrap();

    writeln!(
        out,
        "/// Per trajectory: its number of clearance samples (`TRAJECTORIES[a].samples().len()`)."
    )
    .unwrap();
    writeln!(
        out,
        "#[cfg(test)]\npub(crate) static SAMPLE_COUNT: [u8; crate::MAX_ACTIONS] = [{}];",
        list(counts.iter().map(|c| c.to_string()).collect())
    )
    .unwrap();

    let path =
        PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR")).join("lattice_tables.rs");
    std::fs::write(path, out).expect("write lattice tables");
}
