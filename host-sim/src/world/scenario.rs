//! Scenario files: a map, semantic objects, a reference path, a start pose and a teacher.
//!
//! A scenario is a TOML file. Paths inside it are relative to the file itself:
//!
//! ```toml
//! name = "doors"
//! description = "a flat with doors along its hallways"
//! map = "maps/doors.yaml"          # map_server YAML, relative to this file
//!
//! [path]
//! closed = true                    # a loop (default true); false: an open path, laps restart it
//! waypoints = [[1.0, 2.0], [14.0, 2.0], [14.0, 9.0], [1.0, 9.0]]
//!
//! [start]                          # optional: default is the first waypoint, facing the second
//! x = 1.0
//! y = 2.0
//! theta = 0.0                      # radians, counter-clockwise from +x
//!
//! [teacher]
//! preset = "doors"                 # or: weights = { door = 1.0, path = -2.0, obstacles = 0.5 }
//! threshold = 1.0                  # default 1.0
//! noise = 0.0                      # default 0
//!
//! [[objects]]
//! class = "door"                   # door, stairs or chair
//! x = 7.0
//! y = 3.0
//! radius = 0.45                    # a disc (shape = "disc" is the default)
//!
//! [[objects]]
//! class = "stairs"
//! shape = "rect"                   # a rectangle: centre, width (along yaw), height, yaw
//! x = 10.0
//! y = 5.0
//! width = 2.0
//! height = 1.0
//! yaw = 0.0
//! ```
//!
//! Every problem is a [`ScenarioError`] that names the file and the field
//! (`objects[2].radius: must be positive`); unknown keys are refused (a typo is an error, not a
//! silently ignored setting).
//!
//! # What the car sees of an object
//!
//! The observation carries discs. A disc is reported as it is. A rectangle is reduced to the
//! disc of radius `min(width, height)/2` centred on the point of its long axis's middle segment
//! nearest to the car: the car then sees the rectangle as the stadium it inscribes, with the
//! exact distance to its long sides and rounded ends.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use firmware_core::observation::{MAX_OBJECT_RADIUS, SemanticClass};
use firmware_core::{FEATURE_COUNT, Feature, Weights};
use nalgebra::{Point2, Vector2};
use serde::Deserialize;
use thiserror::Error;

use crate::checks;
use crate::world::car::{CarParams, Pose, rotation};
use crate::world::map::{MapError, OccupancyGrid};
use crate::world::path::RefPath;
use crate::world::teacher::{self, TeacherSpec};

/// What went wrong loading a scenario. Every variant names the file.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("{path}: cannot read: {error}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error (in the message, so not a `source`: a chain of causes prints it once).
        error: std::io::Error,
    },
    /// The TOML does not parse or has the wrong shape.
    #[error("{path}: {message}")]
    Toml {
        /// The file.
        path: PathBuf,
        /// What the parser said, in its own layout: "TOML parse error at line 18, column 13",
        /// then the line with a caret under the column, then what is wrong, on lines of their
        /// own.
        message: String,
    },
    /// A field has a bad value.
    #[error("{path}: {field}: {problem}")]
    Field {
        /// The file.
        path: PathBuf,
        /// The field, e.g. `objects[2].radius`.
        field: String,
        /// What is wrong with it.
        problem: String,
    },
    /// The map could not be loaded.
    #[error("{path}: map: {error}")]
    Map {
        /// The scenario file.
        path: PathBuf,
        /// The map's error (in the message, so not a `source`).
        error: MapError,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    description: Option<String>,
    map: String,
    path: RawPath,
    start: Option<RawStart>,
    teacher: Option<RawTeacher>,
    #[serde(default)]
    objects: Vec<RawObject>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPath {
    waypoints: Vec<Vec<f64>>,
    closed: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStart {
    x: f64,
    y: f64,
    theta: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTeacher {
    preset: Option<String>,
    weights: Option<RawWeights>,
    threshold: Option<f64>,
    noise: Option<f64>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawWeights {
    obstacles: Option<f64>,
    door: Option<f64>,
    stairs: Option<f64>,
    chair: Option<f64>,
    path: Option<f64>,
    right: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawObject {
    class: String,
    shape: Option<String>,
    x: f64,
    y: f64,
    radius: Option<f64>,
    width: Option<f64>,
    height: Option<f64>,
    yaw: Option<f64>,
}

/// The shape of a semantic object in the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A disc.
    Disc {
        /// Radius (m).
        radius: f64,
    },
    /// A rectangle centred on the object's position.
    Rect {
        /// Side along `yaw` (m).
        width: f64,
        /// Side across `yaw` (m).
        height: f64,
        /// Orientation (rad).
        yaw: f64,
    },
}

/// A semantic object in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldObject {
    /// Door, stairs or chair.
    pub class: SemanticClass,
    /// Its centre (m).
    pub centre: Point2<f64>,
    /// Its shape.
    pub shape: Shape,
}

impl WorldObject {
    /// The disc the car at `p` sees (see the module documentation): its centre and radius.
    pub fn disc_seen_from(&self, p: &Point2<f64>) -> (Point2<f64>, f64) {
        match self.shape {
            Shape::Disc { radius } => (self.centre, radius),
            Shape::Rect { width, height, yaw } => {
                // The long axis and half the middle segment's length.
                let (axis, half, r) = if width >= height {
                    (Vector2::x(), (width - height) / 2.0, height / 2.0)
                } else {
                    (Vector2::y(), (height - width) / 2.0, width / 2.0)
                };
                let u = rotation(yaw) * axis;
                let t = (p - self.centre).dot(&u).clamp(-half, half);
                (self.centre + u * t, r)
            }
        }
    }

    /// The point of the (seen) object nearest to `p`, and its distance (0 inside).
    pub fn nearest_point(&self, p: &Point2<f64>) -> (Point2<f64>, f64) {
        let (c, r) = self.disc_seen_from(p);
        let v = p - c;
        let d = v.norm();
        if d <= r {
            (*p, 0.0)
        } else {
            (c + v / d * r, d - r)
        }
    }
}

/// A loaded, validated scenario. Cheap to share between runs (`Arc` map).
#[derive(Clone, Debug)]
pub struct Scenario {
    /// Its name (the file stem when the file does not say).
    pub name: String,
    /// What it is.
    pub description: String,
    /// The file it came from.
    pub source: PathBuf,
    /// The map.
    pub map: Arc<OccupancyGrid>,
    /// The reference path.
    pub path: RefPath,
    /// Where every episode starts.
    pub start: Pose,
    /// The semantic objects.
    pub objects: Vec<WorldObject>,
    /// The teacher the scenario asks for.
    pub teacher: TeacherSpec,
}

fn err(path: &Path, field: impl Into<String>, problem: impl Into<String>) -> ScenarioError {
    ScenarioError::Field {
        path: path.to_path_buf(),
        field: field.into(),
        problem: problem.into(),
    }
}

fn finite(path: &Path, field: String, v: f64, bound: f64) -> Result<f64, ScenarioError> {
    if v.is_finite() && v.abs() <= bound {
        Ok(v)
    } else {
        Err(err(
            path,
            field,
            format!("must be a finite number within ±{bound}, got {v}"),
        ))
    }
}

/// Largest coordinate accepted in a scenario (m).
pub const COORDINATE_BOUND: f64 = 1.0e5;

impl Scenario {
    /// Loads and validates the scenario file at `path`, and its map.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|error| ScenarioError::Io {
            path: path.to_path_buf(),
            error,
        })?;
        Self::parse(&text, path)
    }

    /// Parses scenario text; `path` locates the map and names the file in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Self, ScenarioError> {
        let raw: RawScenario = toml::from_str(text).map_err(|e| ScenarioError::Toml {
            path: path.to_path_buf(),
            message: e.to_string().trim_end().to_string(),
        })?;
        let name = match raw.name {
            Some(n) if n.trim().is_empty() => return Err(err(path, "name", "must not be empty")),
            Some(n) => n,
            None => path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scenario".into()),
        };
        if raw.map.trim().is_empty() {
            return Err(err(path, "map", "must name a map_server YAML file"));
        }
        let map_path = path.parent().unwrap_or(Path::new("")).join(&raw.map);
        let map = OccupancyGrid::load(&map_path).map_err(|error| ScenarioError::Map {
            path: path.to_path_buf(),
            error,
        })?;

        let mut points = Vec::with_capacity(raw.path.waypoints.len());
        for (i, w) in raw.path.waypoints.iter().enumerate() {
            let field = format!("path.waypoints[{i}]");
            if w.len() != 2 {
                return Err(err(path, field, "must be a pair [x, y]"));
            }
            let x = finite(path, field.clone(), w[0], COORDINATE_BOUND)?;
            let y = finite(path, field.clone(), w[1], COORDINATE_BOUND)?;
            if map.is_blocked(x, y) {
                return Err(err(
                    path,
                    field,
                    format!("({x}, {y}) is not in free space of the map"),
                ));
            }
            points.push(Point2::new(x, y));
        }
        let closed = raw.path.closed.unwrap_or(true);
        let ref_path =
            RefPath::new(points, closed).map_err(|e| err(path, "path.waypoints", e.to_string()))?;

        let start = match raw.start {
            Some(s) => Pose {
                x: finite(path, "start.x".into(), s.x, COORDINATE_BOUND)?,
                y: finite(path, "start.y".into(), s.y, COORDINATE_BOUND)?,
                theta: finite(path, "start.theta".into(), s.theta, 100.0)?,
            },
            None => {
                let (p, theta) = ref_path.point_at(0.0);
                Pose::at(p, theta)
            }
        };
        let car = CarParams::MUSHR;
        if car.footprint_hits(&map, start) {
            return Err(err(
                path,
                "start",
                format!(
                    "the car's footprint at ({}, {}, {}) overlaps an occupied or unknown cell",
                    start.x, start.y, start.theta
                ),
            ));
        }
        if ref_path.project(&start.position()).1 > 1.0 {
            return Err(err(path, "start", "must be within 1 m of the path"));
        }

        let mut objects = Vec::with_capacity(raw.objects.len());
        for (i, o) in raw.objects.iter().enumerate() {
            let f = |name: &str| format!("objects[{i}].{name}");
            let class = SemanticClass::from_name(&o.class).ok_or_else(|| {
                err(
                    path,
                    f("class"),
                    format!("unknown class {:?}: door, stairs or chair", o.class),
                )
            })?;
            let x = finite(path, f("x"), o.x, COORDINATE_BOUND)?;
            let y = finite(path, f("y"), o.y, COORDINATE_BOUND)?;
            let positive = |name: &str, v: Option<f64>, max: f64| -> Result<f64, ScenarioError> {
                let v = v.ok_or_else(|| err(path, f(name), "missing"))?;
                if !v.is_finite() || v <= 0.0 {
                    return Err(err(path, f(name), format!("must be positive, got {v}")));
                }
                if v > max {
                    return Err(err(
                        path,
                        f(name),
                        format!("must be at most {max} m, got {v}"),
                    ));
                }
                Ok(v)
            };
            let max_r = MAX_OBJECT_RADIUS as f64;
            let shape = match o.shape.as_deref().unwrap_or("disc") {
                "disc" => {
                    for (k, v) in [("width", o.width), ("height", o.height), ("yaw", o.yaw)] {
                        if v.is_some() {
                            return Err(err(path, f(k), "only for shape = \"rect\""));
                        }
                    }
                    Shape::Disc {
                        radius: positive("radius", o.radius, max_r)?,
                    }
                }
                "rect" => {
                    if o.radius.is_some() {
                        return Err(err(path, f("radius"), "only for shape = \"disc\""));
                    }
                    let width = positive("width", o.width, 50.0)?;
                    let height = positive("height", o.height, 50.0)?;
                    if width.min(height) / 2.0 > max_r {
                        return Err(err(
                            path,
                            f("width"),
                            format!("the shorter side must be at most {} m", 2.0 * max_r),
                        ));
                    }
                    let yaw = finite(path, f("yaw"), o.yaw.unwrap_or(0.0), 100.0)?;
                    Shape::Rect { width, height, yaw }
                }
                other => {
                    return Err(err(
                        path,
                        f("shape"),
                        format!("unknown shape {other:?}: disc or rect"),
                    ));
                }
            };
            objects.push(WorldObject {
                class,
                centre: Point2::new(x, y),
                shape,
            });
        }

        let teacher = parse_teacher(raw.teacher, path)?;
        Ok(Self {
            name,
            description: raw.description.unwrap_or_default(),
            source: path.to_path_buf(),
            map: Arc::new(map),
            path: ref_path,
            start,
            objects,
            teacher,
        })
    }
}

fn parse_teacher(raw: Option<RawTeacher>, path: &Path) -> Result<TeacherSpec, ScenarioError> {
    let Some(raw) = raw else {
        return Err(err(
            path,
            "teacher",
            "missing: give a preset (doors, stairs-right, stairs-chairs) or weights",
        ));
    };
    let mut spec = match (&raw.preset, &raw.weights) {
        (Some(_), Some(_)) => {
            return Err(err(
                path,
                "teacher",
                "give either preset or weights, not both",
            ));
        }
        (None, None) => {
            return Err(err(path, "teacher", "give a preset or weights"));
        }
        (Some(name), None) => {
            let p = teacher::preset(name).ok_or_else(|| {
                let names: Vec<_> = teacher::PRESETS.iter().map(|p| p.name).collect();
                err(
                    path,
                    "teacher.preset",
                    format!("unknown preset {name:?}: one of {}", names.join(", ")),
                )
            })?;
            TeacherSpec::from_preset(p)
        }
        (None, Some(w)) => {
            let mut weights: Weights = [0.0; FEATURE_COUNT];
            let given = [
                (Feature::Obstacles, w.obstacles),
                (Feature::Door, w.door),
                (Feature::Stairs, w.stairs),
                (Feature::Chair, w.chair),
                (Feature::Path, w.path),
                (Feature::Right, w.right),
            ];
            for (f, v) in given {
                if let Some(v) = v {
                    let field = format!("teacher.weights.{}", f.name());
                    weights[f.index()] =
                        checks::teacher_weight(v).map_err(|m| err(path, field, m))? as f32;
                }
            }
            if weights.iter().all(|&x| x == 0.0) {
                return Err(err(path, "teacher.weights", "must not all be zero"));
            }
            TeacherSpec::with_weights(None, weights)
        }
    };
    // The same checks, in the same words, as the command line's --threshold and --noise.
    if let Some(t) = raw.threshold {
        spec.threshold =
            checks::threshold(t).map_err(|m| err(path, "teacher.threshold", m))? as f32;
    }
    if let Some(s) = raw.noise {
        spec.noise = checks::noise(s).map_err(|m| err(path, "teacher.noise", m))? as f32;
    }
    Ok(spec)
}
