//! The generator's options, the attempts, and the world it hands back: the bytes of its files,
//! the scenario in memory, the checks and measurements.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context;
use firmware_core::observation::SemanticClass;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

use super::check::{self, Contrast, Lap};
use super::geometry::metres;
use super::plan::{self, ObjectShape, Paint, Plan, Ranges};
use crate::car::{CarParams, Pose};
use crate::households::{Canvas, yaml};
use crate::map::{Cell, MapMeta, OccupancyGrid};
use crate::path::RefPath;
use crate::plot::Raster;
use crate::scenario::{Scenario, Shape, WorldObject};
use crate::teacher::{self, Preset, TeacherSpec};

/// Hallway widths a user may ask for (m): below 1.2 m the car's lane (the width less 0.25 m of
/// collision margin on each side) is under 0.7 m.
pub const HALLWAY_LIMITS: (f64, f64) = (1.2, 3.0);
/// Attempts by default.
pub const DEFAULT_ATTEMPTS: u32 = 16;
/// Most attempts a user may ask for.
pub const MAX_ATTEMPTS: u32 = 64;

/// What to generate.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// The seed: the same options give the same bytes.
    pub seed: u64,
    /// The scenario's teacher: a preset name (`doors`, `stairs-right`, `stairs-chairs`).
    pub teacher: String,
    /// The files' and scenario's name (default `gen-SEED`): letters, digits, `-`, `_`, `.`.
    pub name: Option<String>,
    /// Narrowest hallway (m).
    pub hallway_min: f64,
    /// Widest hallway (m).
    pub hallway_max: f64,
    /// Worlds drawn at most before giving up.
    pub attempts: u32,
}

impl Options {
    /// The defaults for `seed`: teacher `doors`, name `gen-SEED`, hallways 1.4–2.5 m, 8 attempts.
    pub fn new(seed: u64) -> Self {
        Self {
            seed,
            teacher: "doors".into(),
            name: None,
            hallway_min: 1.4,
            hallway_max: 2.5,
            attempts: DEFAULT_ATTEMPTS,
        }
    }

    /// Validates the options.
    pub fn check(&self) -> Result<ValidOptions, OptionsError> {
        let preset = teacher::preset(&self.teacher).ok_or_else(|| {
            let names: Vec<_> = teacher::PRESETS.iter().map(|p| p.name).collect();
            OptionsError::Teacher {
                given: self.teacher.clone(),
                known: names.join(", "),
            }
        })?;
        let name = match &self.name {
            None => format!("gen-{}", self.seed),
            Some(n) => {
                let bad = |problem| OptionsError::Name {
                    name: n.clone(),
                    problem,
                };
                if n.is_empty() || n.len() > 64 {
                    return Err(bad("must have 1 to 64 characters"));
                }
                if n.starts_with('.') {
                    return Err(bad("must not start with '.'"));
                }
                if !n
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
                {
                    return Err(bad(
                        "may hold only letters, digits, '-', '_' and '.' (it names files)",
                    ));
                }
                n.clone()
            }
        };
        let (min, max) = (self.hallway_min, self.hallway_max);
        let bad = |problem: String| OptionsError::Hallway { min, max, problem };
        if !(min.is_finite() && max.is_finite()) {
            return Err(bad("must be finite numbers".into()));
        }
        let (lo, hi) = HALLWAY_LIMITS;
        if min < lo || max > hi {
            return Err(bad(format!("must lie within {lo}–{hi} m")));
        }
        if min > max {
            return Err(bad("the narrowest exceeds the widest".into()));
        }
        // On the 5 cm grid, inward.
        let min_mm = (libm::ceil(min * 20.0 - 1e-9) as i32) * 50;
        let max_mm = (libm::floor(max * 20.0 + 1e-9) as i32) * 50;
        if min_mm > max_mm {
            return Err(bad(
                "no width on the map's 5 cm grid lies between them".into()
            ));
        }
        if self.attempts == 0 || self.attempts > MAX_ATTEMPTS {
            return Err(OptionsError::Attempts(self.attempts));
        }
        let defaults = Options::new(self.seed);
        let mut command = format!("host-sim generate --seed {}", self.seed);
        if self.teacher != defaults.teacher {
            let _ = write!(command, " --teacher {}", self.teacher);
        }
        if let Some(n) = &self.name {
            let _ = write!(command, " --name {n}");
        }
        if min != defaults.hallway_min {
            let _ = write!(command, " --hallway-min {min}");
        }
        if max != defaults.hallway_max {
            let _ = write!(command, " --hallway-max {max}");
        }
        Ok(ValidOptions {
            seed: self.seed,
            teacher: preset,
            name,
            hallway_mm: (min_mm, max_mm),
            attempts: self.attempts,
            command,
        })
    }
}

/// Options that passed [`Options::check`].
#[derive(Clone, Debug, PartialEq)]
pub struct ValidOptions {
    /// The seed.
    pub seed: u64,
    /// The scenario's teacher.
    pub teacher: &'static Preset,
    /// The name of the files and the scenario.
    pub name: String,
    /// Hallway widths (mm, on the 5 cm grid).
    pub hallway_mm: (i32, i32),
    /// Attempts at most.
    pub attempts: u32,
    /// The command line that makes this world (for the scenario file's header).
    pub command: String,
}

/// A refused option, with what is wrong.
#[derive(Clone, Debug, PartialEq, Error)]
#[non_exhaustive]
pub enum OptionsError {
    /// Not a teacher preset.
    #[error("unknown teacher {given:?}: one of {known}")]
    Teacher {
        /// What was given.
        given: String,
        /// The presets.
        known: String,
    },
    /// A name that cannot name files.
    #[error("name {name:?}: {problem}")]
    Name {
        /// What was given.
        name: String,
        /// What is wrong.
        problem: &'static str,
    },
    /// Bad hallway widths.
    #[error("hallway widths {min}–{max} m: {problem}")]
    Hallway {
        /// The narrowest given.
        min: f64,
        /// The widest given.
        max: f64,
        /// What is wrong.
        problem: String,
    },
    /// Attempts out of range.
    #[error("attempts must be in 1..={MAX_ATTEMPTS}, got {0}")]
    Attempts(u32),
}

/// An attempt that failed its checks, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Refusal {
    /// The attempt (the stream of the seed's generator).
    pub attempt: u32,
    /// Why it was refused.
    pub why: Why,
}

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
        end: String,
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

/// Why no world came out.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum GenerateError {
    /// The options were refused.
    #[error("{0}")]
    Options(#[from] OptionsError),
    /// Every attempt failed its checks.
    #[error("no world for seed {seed} passed its checks in {} attempts: {}", .refusals.len(), list(.refusals))]
    NoWorld {
        /// The seed.
        seed: u64,
        /// Every attempt's reason.
        refusals: Vec<Refusal>,
    },
    /// The simulator failed while checking (a bug, not the world's fault).
    #[error("seed {seed}, attempt {attempt}: {message}")]
    Check {
        /// The seed.
        seed: u64,
        /// The attempt.
        attempt: u32,
        /// What failed.
        message: String,
    },
}

fn list(r: &[Refusal]) -> String {
    r.iter()
        .map(|r| format!("attempt {}: {}", r.attempt, r.why))
        .collect::<Vec<_>>()
        .join("; ")
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

/// A generated world that passed its checks.
#[derive(Clone, Debug)]
pub struct World {
    /// The options it was made with.
    pub options: ValidOptions,
    /// The attempt that passed.
    pub attempt: u32,
    /// The attempts before it, and why they failed.
    pub refused: Vec<Refusal>,
    /// `NAME.pgm`.
    pub pgm: Vec<u8>,
    /// `NAME.yaml`.
    pub yaml: String,
    /// `NAME.toml`.
    pub toml: String,
    /// The scenario, in memory (what loading the files gives, but for the map's unknown cells,
    /// here occupied: the car and its sensor treat both alike).
    pub scenario: Arc<Scenario>,
    /// Every preset teacher's lap, in [`teacher::PRESETS`] order.
    pub laps: Vec<Lap>,
    /// Every preset teacher against its path follower, in the same order.
    pub contrasts: Vec<Contrast>,
    /// Its numbers.
    pub summary: Summary,
}

impl World {
    /// The files: name and bytes (`NAME.pgm`, `NAME.yaml`, `NAME.toml`).
    pub fn files(&self) -> [(String, &[u8]); 3] {
        let n = &self.options.name;
        [
            (format!("{n}.pgm"), &self.pgm[..]),
            (format!("{n}.yaml"), self.yaml.as_bytes()),
            (format!("{n}.toml"), self.toml.as_bytes()),
        ]
    }

    /// Writes the files into `dir` (created if missing; files of the same name are replaced).
    /// Returns the scenario file's path.
    pub fn write(&self, dir: &Path) -> anyhow::Result<PathBuf> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
        for (name, bytes) in self.files() {
            let p = dir.join(&name);
            std::fs::write(&p, bytes).with_context(|| format!("{}: cannot write", p.display()))?;
        }
        Ok(dir.join(format!("{}.toml", self.options.name)))
    }

    /// The lap of the scenario's teacher.
    pub fn lap(&self) -> &Lap {
        let i = preset_index(self.options.teacher);
        &self.laps[i]
    }

    /// The scenario's teacher against its path follower.
    pub fn contrast(&self) -> &Contrast {
        let i = preset_index(self.options.teacher);
        &self.contrasts[i]
    }

    /// A picture of `scenario` (this world, loaded from its files, so that the outside is
    /// grey): the map, path and objects, the scenario teacher's lap (purple) and its path
    /// follower's (orange dots).
    pub fn draw(&self, scenario: &Scenario) -> Raster {
        let mut r = Raster::of_scenario(scenario);
        r.trace(&self.contrast().trace);
        r.polyline(&self.lap().trace, [150, 0, 200]);
        r
    }
}

fn preset_index(p: &Preset) -> usize {
    teacher::PRESETS
        .iter()
        .position(|q| q.name == p.name)
        .unwrap_or(0)
}

/// Generates a world: draws plans until one passes its checks (see the module documentation).
pub fn generate(options: &Options) -> Result<World, GenerateError> {
    let options = options.check()?;
    let mut refused = Vec::new();
    for attempt in 0..options.attempts {
        let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
        rng.set_stream(u64::from(attempt));
        let plan = plan::plan(
            &mut rng,
            Ranges {
                hallway: options.hallway_mm,
            },
        );
        let internal = |e: anyhow::Error| GenerateError::Check {
            seed: options.seed,
            attempt,
            message: format!("{e:#}"),
        };
        let draft = Draft::new(&plan, &options, attempt).map_err(internal)?;
        match draft.accept().map_err(internal)? {
            Err(why) => refused.push(Refusal { attempt, why }),
            Ok(laps) => {
                let mut contrasts = Vec::new();
                for p in &teacher::PRESETS {
                    let c = check::contrast(&draft.scenario, p.name, TeacherSpec::from_preset(p))
                        .map_err(internal)?;
                    contrasts.push(c);
                }
                let summary = draft.summary(&plan);
                return Ok(World {
                    options,
                    attempt,
                    refused,
                    pgm: draft.pgm,
                    yaml: draft.yaml,
                    toml: draft.toml,
                    scenario: draft.scenario,
                    laps,
                    contrasts,
                    summary,
                });
            }
        }
    }
    Err(GenerateError::NoWorld {
        seed: options.seed,
        refusals: refused,
    })
}

/// One attempt's files and scenario.
struct Draft {
    pgm: Vec<u8>,
    yaml: String,
    toml: String,
    scenario: Arc<Scenario>,
    objects: Vec<&'static str>,
}

fn m(mm: i32) -> f64 {
    f64::from(mm) / 1000.0
}

impl Draft {
    fn new(plan: &Plan, o: &ValidOptions, attempt: u32) -> anyhow::Result<Self> {
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
                    x: shape.0,
                    y: shape.1,
                    shape: shape.2,
                }
            })
            .collect();
        let meta = MapMeta::parse(&yaml, Path::new(&format!("{}.yaml", o.name)))?;
        let grid = grid_of(&pgm, &meta);
        let points: Vec<(f64, f64)> = plan.waypoints.iter().map(|&(x, y)| (m(x), m(y))).collect();
        let path =
            RefPath::new(points, true).map_err(|e| anyhow::anyhow!("the plan's path: {e}"))?;
        let (x, y, theta) = path.point_at(0.0);
        let scenario = Scenario {
            name: o.name.clone(),
            description: description(plan, o),
            source: PathBuf::from(format!("{}.toml", o.name)),
            map: Arc::new(grid),
            path,
            start: Pose { x, y, theta },
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

    /// The checks: `Ok(Err(why))` when the world fails one, `Err` when the simulator fails.
    fn accept(&self) -> anyhow::Result<Result<Vec<Lap>, Why>> {
        let s = &self.scenario;
        for (index, &at) in s.path.points().iter().enumerate() {
            if s.map.is_blocked(at.0, at.1) {
                return Ok(Err(Why::Waypoint { index, at }));
            }
        }
        if CarParams::MUSHR.footprint_hits(&s.map, s.start) {
            return Ok(Err(Why::Start));
        }
        if let Some(&object) = check::unreachable_objects(s).first() {
            let o = &s.objects[object];
            return Ok(Err(Why::OutOfReach {
                object,
                what: self.objects[object],
                at: (o.x, o.y),
            }));
        }
        let mut laps = Vec::new();
        for p in &teacher::PRESETS {
            let lap = check::teacher_lap(s, p.name, TeacherSpec::from_preset(p))?;
            if !lap.lapped() {
                return Ok(Err(Why::NoLap {
                    teacher: p.name,
                    end: lap.end.clone(),
                    at: lap.last(),
                    ticks: lap.ticks,
                }));
            }
            laps.push(lap);
        }
        Ok(Ok(laps))
    }

    fn summary(&self, plan: &Plan) -> Summary {
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
fn grid_of(pgm: &[u8], meta: &MapMeta) -> OccupancyGrid {
    // The header is "P5\n{w} {h}\n255\n" (Canvas::to_pgm).
    let text = String::from_utf8_lossy(&pgm[..pgm.len().min(32)]).into_owned();
    let mut fields = text.split_ascii_whitespace().skip(1);
    let mut next = || -> usize { fields.next().and_then(|t| t.parse().ok()).unwrap_or(0) };
    let (w, h) = (next(), next());
    let data = &pgm[pgm.len() - w * h..];
    let free: Vec<bool> = data
        .iter()
        .map(|&v| meta.classify(f64::from(v), 255.0) == Cell::Free)
        .collect();
    OccupancyGrid::from_fn(w, h, meta.resolution, meta.origin, |c, r| {
        // Image row 0 is the top; grid row 0 the bottom.
        !free[(h - 1 - r) * w + c]
    })
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
