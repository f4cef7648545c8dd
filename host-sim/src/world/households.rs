//! The three built-in households, drawn as occupancy grids (`host-sim gen-maps`).
//!
//! The paper's Gibson households (Tolstoy, Corozal, Newfields) could not be redistributed (see
//! `scenarios/maps/SOURCES.md`), so these are look-alikes in their spirit, drawn from rectangles
//! at 5 cm per pixel: rooms, 1.6–2 m hallways, 0.9 m doorways, 0.15 m walls, furniture. Outside
//! the building the map is unknown (grey), which the car treats as an obstacle.
//!
//! * `doors`: a flat around two bedrooms: a 2 m hallway on three sides and a living room on the
//!   fourth. The bedrooms' doors open onto the hallways.
//! * `stairs-right`: 1.6 m hallways around a block of rooms, a foyer with a stairwell, and a
//!   second staircase going down from an alcove of the long hallway.
//! * `stairs-chairs`: a hallway with a stairwell, a dining room with a table and chairs, and a
//!   living room with armchairs, all on one loop.
//!
//! The generated files are committed under `scenarios/maps/`; a test regenerates them and
//! checks that they are byte-identical, so the drawing code and the files cannot drift apart.
//! The objects and paths of the scenarios are in the scenario files beside them.

use std::path::Path;

use anyhow::{Context, Result};

/// Pixel values (map_server, `negate: 0`).
const FREE: u8 = 254;
const WALL: u8 = 0;
const UNKNOWN: u8 = 205;

/// Metres per pixel of the generated maps.
pub const RESOLUTION: f64 = 0.05;

/// A grey image drawn in metres (origin at the lower-left corner).
#[derive(Clone, Debug)]
pub struct Canvas {
    width: usize,
    height: usize,
    /// Row 0 at the bottom.
    px: Vec<u8>,
}

impl Canvas {
    /// A `w` × `h` metre canvas, all unknown.
    pub fn new(w: f64, h: f64) -> Self {
        let width = (w / RESOLUTION).round() as usize;
        let height = (h / RESOLUTION).round() as usize;
        Self {
            width,
            height,
            px: vec![UNKNOWN; width * height],
        }
    }

    fn fill(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, v: u8) {
        let c0 = (x0 / RESOLUTION).round().max(0.0) as usize;
        let c1 = ((x1 / RESOLUTION).round() as usize).min(self.width);
        let r0 = (y0 / RESOLUTION).round().max(0.0) as usize;
        let r1 = ((y1 / RESOLUTION).round() as usize).min(self.height);
        for r in r0..r1 {
            for c in c0..c1 {
                self.px[r * self.width + c] = v;
            }
        }
    }

    /// Walls (occupied) over a rectangle.
    pub fn wall(&mut self, x0: f64, y0: f64, x1: f64, y1: f64) {
        self.fill(x0, y0, x1, y1, WALL);
    }

    /// Free floor over a rectangle.
    pub fn floor(&mut self, x0: f64, y0: f64, x1: f64, y1: f64) {
        self.fill(x0, y0, x1, y1, FREE);
    }

    /// Binary PGM (P5), top row first, as map_server reads it.
    pub fn to_pgm(&self) -> Vec<u8> {
        let mut out = format!("P5\n{} {}\n255\n", self.width, self.height).into_bytes();
        for r in (0..self.height).rev() {
            out.extend_from_slice(&self.px[r * self.width..(r + 1) * self.width]);
        }
        out
    }
}

/// The `doors` flat (16 m × 11 m).
pub fn doors() -> Canvas {
    let mut c = Canvas::new(16.0, 11.0);
    c.wall(0.35, 0.35, 15.65, 10.65);
    c.floor(0.5, 0.5, 5.0, 10.5); // living room
    c.floor(5.0, 0.5, 15.5, 2.5); // south hallway, 2 m
    c.floor(13.5, 0.5, 15.5, 10.5); // east hallway, 2 m
    c.floor(5.0, 8.5, 15.5, 10.5); // north hallway, 2 m
    c.floor(5.15, 2.65, 9.2, 8.35); // bedroom 1
    c.floor(9.35, 2.65, 13.35, 8.35); // bedroom 2
    // Doorways, 0.9 m.
    c.floor(6.5, 2.4, 7.4, 2.75);
    c.floor(11.0, 2.4, 11.9, 2.75);
    c.floor(13.25, 5.0, 13.6, 5.9);
    c.floor(7.5, 8.25, 8.4, 8.6);
    c.floor(10.5, 8.25, 11.4, 8.6);
    c.floor(4.9, 4.0, 5.25, 4.9);
    // Furniture: sofa, armchair, coffee table, bookcase; beds and wardrobes.
    c.wall(0.5, 3.0, 1.3, 6.0);
    c.wall(1.5, 6.6, 2.1, 7.4);
    c.wall(0.5, 9.6, 2.0, 10.5);
    c.wall(5.6, 5.5, 7.6, 7.9);
    c.wall(10.0, 5.5, 12.0, 7.9);
    c.wall(12.8, 2.65, 13.35, 4.4);
    c
}

/// The `stairs-right` house (18 m × 11 m).
pub fn stairs_right() -> Canvas {
    let mut c = Canvas::new(18.0, 11.0);
    c.wall(0.35, 0.35, 17.65, 10.65);
    c.floor(0.5, 0.5, 4.5, 10.5); // foyer
    c.floor(4.5, 0.5, 17.5, 2.1); // south hallway, 1.6 m
    c.floor(15.9, 0.5, 17.5, 10.5); // east hallway, 1.6 m
    c.floor(4.5, 8.9, 17.5, 10.5); // north hallway, 1.6 m
    // Stairwell in the foyer: a railing around the opening.
    c.wall(0.5, 3.6, 2.0, 6.6);
    // Alcove off the south hallway with stairs going down (railing beyond the landing).
    c.floor(9.0, 2.1, 11.0, 3.4);
    c.wall(9.0, 3.4, 11.0, 3.6);
    // Rooms in the middle block, with doors.
    c.floor(4.65, 3.75, 8.85, 8.75);
    c.floor(11.15, 2.25, 15.75, 8.75);
    c.floor(5.8, 8.65, 6.7, 9.0);
    c.floor(13.0, 8.65, 13.9, 9.0);
    c.floor(15.65, 4.0, 16.0, 4.9);
    // Furniture.
    c.wall(3.9, 5.5, 4.5, 7.0); // coat rack and shoe cabinet
    c.wall(5.2, 5.0, 7.2, 7.0);
    c.wall(12.0, 5.0, 14.5, 7.5);
    c
}

/// The `stairs-chairs` house (17 m × 12 m).
pub fn stairs_chairs() -> Canvas {
    let mut c = Canvas::new(17.0, 12.0);
    c.wall(0.35, 0.35, 16.65, 11.65);
    c.floor(0.5, 0.5, 2.3, 11.5); // west hallway, 1.8 m
    c.floor(0.5, 0.5, 16.5, 2.3); // south hallway, 1.8 m
    c.floor(10.5, 0.5, 16.5, 11.5); // dining room, 6 m wide
    c.floor(0.5, 7.0, 16.5, 11.5); // living room across the north
    c.wall(2.3, 2.3, 10.5, 7.0); // the middle block (kitchen, closed)
    // Stairwell off the west hallway (railing on the hallway side with a gap for the landing).
    c.floor(2.3, 3.2, 3.5, 5.2);
    c.wall(3.5, 3.2, 3.7, 5.2);
    // Stairs up in the north-west corner (not drivable).
    c.wall(0.5, 10.2, 2.3, 11.5);
    // Dining table in the middle of the dining room; chairs are obstacles too.
    c.wall(12.6, 4.5, 14.4, 7.5);
    for (x, y) in [
        (12.05, 5.2),
        (12.05, 6.5),
        (14.55, 5.2),
        (14.55, 6.5),
        (13.25, 3.95),
        (13.25, 7.65),
    ] {
        c.wall(x, y, x + 0.4, y + 0.4);
    }
    // Living room: sofa along the north wall, armchairs, a sideboard.
    c.wall(4.0, 10.7, 8.0, 11.5);
    c.wall(3.2, 9.6, 3.8, 10.2);
    c.wall(8.4, 9.6, 9.0, 10.2);
    c.wall(10.6, 0.5, 12.0, 0.9);
    c
}

/// Every household: (name, canvas).
pub fn all() -> Vec<(&'static str, Canvas)> {
    vec![
        ("doors", doors()),
        ("stairs-right", stairs_right()),
        ("stairs-chairs", stairs_chairs()),
    ]
}

/// The map_server YAML for a generated map.
pub fn yaml(name: &str) -> String {
    format!(
        "image: {name}.pgm\nresolution: {RESOLUTION}\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
}

/// Writes every household's `NAME.pgm` and `NAME.yaml` into `dir`.
pub fn write_all(dir: &Path) -> Result<Vec<String>> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let mut written = Vec::new();
    for (name, canvas) in all() {
        let pgm = dir.join(format!("{name}.pgm"));
        std::fs::write(&pgm, canvas.to_pgm())
            .with_context(|| format!("{}: cannot write", pgm.display()))?;
        let y = dir.join(format!("{name}.yaml"));
        std::fs::write(&y, yaml(name)).with_context(|| format!("{}: cannot write", y.display()))?;
        written.push(pgm.display().to_string());
        written.push(y.display().to_string());
    }
    Ok(written)
}
