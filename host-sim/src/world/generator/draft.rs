//! One attempt: the plan drawn into the map's bytes, the scenario's text and the scenario in
//! memory, and the checks it must pass.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use firmware_core::observation::SemanticClass;
use nalgebra::Point2;

use super::check;
use super::geometry::metres;
use super::options::ValidOptions;
use super::plan::{self, ObjectShape, Paint, Plan};
use crate::world::car::{CarParams, Pose};
use crate::world::check::{LapFailure, TeacherLap, lap_of};
use crate::world::households::{Canvas, yaml};
use crate::world::map::{Cell, MapMeta, OccupancyGrid};
use crate::world::path::RefPath;
use crate::world::scenario::{Scenario, Shape, WorldObject};
use crate::world::teacher::{self, TeacherSpec};

/// Why an attempt was refused.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Why {
    /// A waypoint is not in free space.
    Waypoint {
        /// Its index.
        index: usize,
        /// Where.
        at: (f64, f64),
    },
    /// The car's footprint at the start touches the map.
    Start,
    /// An object is out of the detector's reach from every point of the path.
    OutOfReach {
        /// Its index in the scenario's objects.
        object: usize,
        /// What it is.
        what: &'static str,
        /// Its centre.
        at: (f64, f64),
    },
    /// A teacher's own policy did not complete a lap without a reset.
    NoLap {
        /// The teacher preset.
        teacher: &'static str,
        /// How its drive ended: a reset reason or `ticks`.
        end: &'static str,
        /// Where it ended.
        at: (f64, f64),
        /// After how many ticks.
        ticks: u32,
    },
}

impl Why {
    /// A short label for tallies: `doors teacher: blocked`, `out of reach: an armchair`.
    pub fn label(&self) -> String {
        match self {
            Why::Waypoint { .. } => "waypoint not free".into(),
            Why::Start => "start not free".into(),
            Why::OutOfReach { what, .. } => format!("out of reach: {what}"),
            Why::NoLap { teacher, end, .. } => format!("{teacher} teacher: {end}"),
        }
    }
}

impl std::fmt::Display for Why {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Why::Waypoint { index, at } => {
                write!(f, "waypoint {index} ({}, {}) is not free", at.0, at.1)
            }
            Why::Start => write!(f, "the car's footprint at the start touches the map"),
            Why::OutOfReach { object, what, at } => write!(
                f,
                "object {object} ({what}, at ({}, {})) is out of the detector's reach from every point of the path",
                at.0, at.1
            ),
            Why::NoLap {
                teacher,
                end,
                at,
                ticks,
            } => write!(
                f,
                "the {teacher} teacher's own policy did not lap: {end} at ({:.2}, {:.2}) after {ticks} ticks",
                at.0, at.1
            ),
        }
    }
}

/// The world's numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// Inside the outer wall (m).
    pub width: f64,
    /// Inside the outer wall (m).
    pub height: f64,
    /// The path's length (m).
    pub path_length: f64,
    /// Hallway widths (m), south, east, north, west order.
    pub hallways: Vec<f64>,
    /// Open rooms on the ring.
    pub open_rooms: usize,
    /// Rooms in the block.
    pub block_rooms: usize,
    /// Doors.
    pub doors: usize,
    /// Staircases.
    pub stairs: usize,
    /// Chairs (armchairs included).
    pub chairs: usize,
}

/// One attempt's files and scenario.
pub(crate) struct Draft {
    pub(crate) pgm: Vec<u8>,
    pub(crate) yaml: String,
    pub(crate) toml: String,
    pub(crate) scenario: Arc<Scenario>,
    /// What each object is.
    objects: Vec<&'static str>,
}

fn m(mm: i32) -> f64 {
    f64::from(mm) / 1000.0
}

impl Draft {
    pub(crate) fn new(plan: &Plan, o: &ValidOptions, attempt: u32) -> anyhow::Result<Self> {
        let mut canvas = Canvas::new(m(plan.size.0), m(plan.size.1));
        for p in &plan.paint {
            match *p {
                Paint::Wall(r) => canvas.wall(m(r.x0), m(r.y0), m(r.x1), m(r.y1)),
                Paint::Floor(r) => canvas.floor(m(r.x0), m(r.y0), m(r.x1), m(r.y1)),
            }
        }
        let pgm = canvas.to_pgm();
        let yaml = yaml(&o.name);
        let toml = scenario_text(plan, o, attempt);
        let objects = plan
            .objects
            .iter()
            .map(|ob| {
                let shape = match ob.shape {
                    ObjectShape::Disc { x, y, r } => (m(x), m(y), Shape::Disc { radius: m(r) }),
                    ObjectShape::Rect(r) => {
                        let (x, y) = r.centre();
                        (
                            m(x),
                            m(y),
                            Shape::Rect {
                                width: m(r.width()),
                                height: m(r.height()),
                                yaw: 0.0,
                            },
                        )
                    }
                };
                WorldObject {
                    class: ob.class,
                    centre: Point2::new(shape.0, shape.1),
                    shape: shape.2,
                }
            })
            .collect();
        let meta = MapMeta::parse(&yaml, Path::new(&format!("{}.yaml", o.name)))?;
        let cells = |mm: i32| (mm / super::geometry::GRID) as usize;
        let grid = grid_of(&pgm, (cells(plan.size.0), cells(plan.size.1)), &meta)?;
        let points: Vec<Point2<f64>> = plan
            .waypoints
            .iter()
            .map(|&(x, y)| Point2::new(m(x), m(y)))
            .collect();
        let path =
            RefPath::new(points, true).map_err(|e| anyhow::anyhow!("the plan's path: {e}"))?;
        let (at, theta) = path.point_at(0.0);
        let scenario = Scenario {
            name: o.name.clone(),
            description: description(plan, o),
            source: PathBuf::from(format!("{}.toml", o.name)),
            map: Arc::new(grid),
            path,
            start: Pose::at(at, theta),
            objects,
            teacher: TeacherSpec::from_preset(o.teacher),
        };
        Ok(Self {
            pgm,
            yaml,
            toml,
            scenario: Arc::new(scenario),
            objects: plan.objects.iter().map(|o| o.what).collect(),
        })
    }

    /// The checks: `Err(why)` when the world fails one; every preset teacher's lap, in
    /// [`teacher::PRESETS`] order, when it passes them all.
    pub(crate) fn accept(&self) -> Result<Vec<TeacherLap>, Why> {
        let s = &self.scenario;
        for (index, &at) in s.path.points().iter().enumerate() {
            if s.map.is_blocked(at.x, at.y) {
                return Err(Why::Waypoint {
                    index,
                    at: (at.x, at.y),
                });
            }
        }
        if CarParams::MUSHR.footprint_hits(&s.map, s.start) {
            return Err(Why::Start);
        }
        if let Some(&object) = check::unreachable_objects(s).first() {
            let o = &s.objects[object];
            return Err(Why::OutOfReach {
                object,
                what: self.objects[object],
                at: (o.centre.x, o.centre.y),
            });
        }
        // The scenario check of `load_scenario`, with each preset teacher in turn.
        teacher::PRESETS
            .iter()
            .map(|p| {
                lap_of(s, TeacherSpec::from_preset(p)).map_err(|u| Why::NoLap {
                    teacher: p.name,
                    end: u.failure.name(),
                    at: (u.x, u.y),
                    ticks: match u.failure {
                        LapFailure::Reset(_) => u.tick + 1,
                        LapFailure::TooSlow { ticks, .. } => ticks,
                    },
                })
            })
            .collect()
    }

    pub(crate) fn summary(&self, plan: &Plan) -> Summary {
        let count = |c: SemanticClass| plan.objects.iter().filter(|o| o.class == c).count();
        Summary {
            width: m(plan.building.width()),
            height: m(plan.building.height()),
            path_length: self.scenario.path.length(),
            hallways: plan
                .bands
                .iter()
                .filter(|b| matches!(b.kind, plan::BandKind::Hallway { .. }))
                .map(|b| m(b.depth))
                .collect(),
            open_rooms: plan
                .bands
                .iter()
                .filter(|b| matches!(b.kind, plan::BandKind::Room { .. }))
                .count(),
            block_rooms: plan.core_rooms,
            doors: count(SemanticClass::Door),
            stairs: count(SemanticClass::Stairs),
            chairs: count(SemanticClass::Chair),
        }
    }
}

/// The grid the map's files describe, read through the YAML's thresholds: a cell is free when
/// map_server reads its pixel as free; every other cell is occupied.
fn grid_of(pgm: &[u8], (w, h): (usize, usize), meta: &MapMeta) -> anyhow::Result<OccupancyGrid> {
    // The pixels, `w · h` bytes, top row first, end the PGM (Canvas::to_pgm).
    let data = pgm
        .len()
        .checked_sub(w * h)
        .map(|start| &pgm[start..])
        .ok_or_else(|| anyhow::anyhow!("the drawn map holds fewer than {w} × {h} pixels"))?;
    let free: Vec<bool> = data
        .iter()
        .map(|&v| meta.classify(f64::from(v), 255.0) == Cell::Free)
        .collect();
    Ok(OccupancyGrid::from_fn(
        w,
        h,
        meta.resolution,
        meta.origin,
        // Image row 0 is the top; grid row 0 the bottom.
        |c, r| !free[(h - 1 - r) * w + c],
    ))
}

fn description(plan: &Plan, o: &ValidOptions) -> String {
    let count = |c: SemanticClass| plan.objects.iter().filter(|x| x.class == c).count();
    format!(
        "a generated household (seed {}): {} doors, {} staircases, {} chairs",
        o.seed,
        count(SemanticClass::Door),
        count(SemanticClass::Stairs),
        count(SemanticClass::Chair)
    )
}

fn scenario_text(plan: &Plan, o: &ValidOptions, attempt: u32) -> String {
    let mut t = String::new();
    let _ = writeln!(t, "# A generated household: `{}`.", o.command);
    let _ = writeln!(
        t,
        "# Attempt {attempt} (stream {attempt} of the seed's generator){}.",
        if attempt == 0 {
            ""
        } else {
            "; the earlier attempts failed the generator's checks"
        }
    );
    for line in plan::describe(plan) {
        let _ = writeln!(t, "# {line}.");
    }
    let _ = writeln!(
        t,
        "# The rules: the documentation of host-sim's generator module (`cargo doc -p host-sim --open`)."
    );
    let _ = writeln!(t, "name = \"{}\"", o.name);
    let _ = writeln!(t, "description = \"{}\"", description(plan, o));
    let _ = writeln!(t, "map = \"{}.yaml\"", o.name);
    let _ = writeln!(t, "\n[path]\nclosed = true\nwaypoints = [");
    for row in plan.waypoints.chunks(4) {
        let cells: Vec<String> = row
            .iter()
            .map(|&(x, y)| format!("[{}, {}]", metres(x), metres(y)))
            .collect();
        let _ = writeln!(t, "    {},", cells.join(", "));
    }
    let _ = writeln!(t, "]\n\n[teacher]\npreset = \"{}\"", o.teacher.name);
    for ob in &plan.objects {
        let _ = writeln!(
            t,
            "\n# {}\n[[objects]]\nclass = \"{}\"",
            ob.what,
            ob.class.name()
        );
        match ob.shape {
            ObjectShape::Disc { x, y, r } => {
                let _ = writeln!(
                    t,
                    "x = {}\ny = {}\nradius = {}",
                    metres(x),
                    metres(y),
                    metres(r)
                );
            }
            ObjectShape::Rect(r) => {
                let (x, y) = r.centre();
                let _ = writeln!(
                    t,
                    "shape = \"rect\"\nx = {}\ny = {}\nwidth = {}\nheight = {}",
                    metres(x),
                    metres(y),
                    metres(r.width()),
                    metres(r.height())
                );
            }
        }
    }
    t
}
