//! The floor plan: a ring of hallways and open rooms around a block of rooms, rooms beyond the
//! hallways, doorways, and the closed reference path (the rules are in the module documentation
//! of [`crate::world::generator`]).
//!
//! A plan is drawn in integer millimetres: [`Paint`] operations in order (walls and floor over
//! rectangles), the semantic objects, and the path's waypoints.

use firmware_core::observation::SemanticClass;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::furnish::{self, Doorway};
use super::geometry::{
    Frame, GRID, Rect, Side, Span, ceil_grid, choose_k, floor_grid, metres, pick,
};
use super::lanes::Lanes;

/// Thickness of every wall (mm).
pub(crate) const WALL: i32 = 150;
/// Width of every doorway (mm).
pub(crate) const DOORWAY: i32 = 900;
/// Unknown margin around the building, outside its outer wall (mm).
pub(crate) const MARGIN: i32 = 350;

/// One drawing step: later steps paint over earlier ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Paint {
    /// Occupied.
    Wall(Rect),
    /// Free.
    Floor(Rect),
}

/// The shape of a semantic object (mm).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ObjectShape {
    /// A disc: centre and radius.
    Disc { x: i32, y: i32, r: i32 },
    /// An axis-aligned rectangle.
    Rect(Rect),
}

/// A semantic object of the plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct PlanObject {
    pub(crate) class: SemanticClass,
    pub(crate) shape: ObjectShape,
    /// What it is, for the scenario file's comments.
    pub(crate) what: &'static str,
}

impl PlanObject {
    /// A disc of `radius` at the middle of `r`.
    pub(crate) fn disc(class: SemanticClass, r: Rect, radius: i32, what: &'static str) -> Self {
        let (x, y) = r.centre();
        Self {
            class,
            shape: ObjectShape::Disc { x, y, r: radius },
            what,
        }
    }
}

/// What a band of the ring is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum BandKind {
    /// A hallway; `outer` > 0: a row of rooms that deep (wall included) beyond it.
    Hallway { outer: i32 },
    /// An open room the path crosses: a dining room (table and chairs) or a living room.
    Room { dining: bool },
}

/// One side of the ring.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Band {
    pub(crate) side: Side,
    pub(crate) kind: BandKind,
    /// Depth from the core's face to the band's outer wall (mm): a hallway's width.
    pub(crate) depth: i32,
    /// Distance of the path's lane from the core's face (mm).
    pub(crate) lane: i32,
}

impl Band {
    fn outer(&self) -> i32 {
        match self.kind {
            BandKind::Hallway { outer } => outer,
            BandKind::Room { .. } => 0,
        }
    }
}

/// A generated floor plan.
#[derive(Clone, Debug)]
pub(crate) struct Plan {
    /// Canvas size (mm), the unknown margin included.
    pub(crate) size: (i32, i32),
    /// The inside of the building's outer wall.
    pub(crate) building: Rect,
    /// The block of rooms inside the ring (its walls included).
    pub(crate) core: Rect,
    pub(crate) core_rooms: usize,
    pub(crate) bands: [Band; 4],
    pub(crate) counter_clockwise: bool,
    pub(crate) paint: Vec<Paint>,
    pub(crate) objects: Vec<PlanObject>,
    /// The closed path, the start first (facing the second waypoint).
    pub(crate) waypoints: Vec<(i32, i32)>,
}

/// Ranges of the plan's draws (mm); the module documentation of [`crate::world::generator`] lists them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Ranges {
    /// Hallway widths.
    pub(crate) hallway: (i32, i32),
}

pub(crate) const ROOM_BAND_DEPTH: (i32, i32) = (3700, 5500);
pub(crate) const ROOM_LANE: (i32, i32) = (900, 1300);
pub(crate) const OUTER_ROOMS: (i32, i32) = (2500, 4000);
pub(crate) const CORE_WIDTH: (i32, i32) = (4000, 10000);
pub(crate) const CORE_HEIGHT: (i32, i32) = (3000, 7000);
pub(crate) const ROOM_WIDTH: (i32, i32) = (2500, 5000);
pub(crate) const ALCOVE_WIDTH: (i32, i32) = (2000, 2600);
/// Probability that a doorway's door is open (free in the map).
pub(crate) const OPEN_DOOR: f64 = 0.6;

/// Draws a plan from `rng`.
pub(crate) fn plan(rng: &mut ChaCha8Rng, ranges: Ranges) -> Plan {
    let counter_clockwise = rng.random_bool(0.5);
    // The ring: one or two open rooms, hallways on the other sides.
    let room_bands = if rng.random_bool(0.5) { 1 } else { 2 };
    let room_sides = choose_k(rng, 4, room_bands);
    let bands = Side::ALL.map(|side| {
        if room_sides.contains(&side.index()) {
            let depth = pick(rng, ROOM_BAND_DEPTH.0, ROOM_BAND_DEPTH.1);
            let lane = pick(rng, ROOM_LANE.0, ROOM_LANE.1);
            let dining = rng.random_bool(0.5);
            Band {
                side,
                kind: BandKind::Room { dining },
                depth,
                lane,
            }
        } else {
            let depth = pick(rng, ranges.hallway.0, ranges.hallway.1);
            let outer = if rng.random_bool(0.5) {
                pick(rng, OUTER_ROOMS.0, OUTER_ROOMS.1)
            } else {
                0
            };
            Band {
                side,
                kind: BandKind::Hallway { outer },
                depth,
                lane: depth / 2,
            }
        }
    });
    let core_w = pick(rng, CORE_WIDTH.0, CORE_WIDTH.1);
    let core_h = pick(rng, CORE_HEIGHT.0, CORE_HEIGHT.1);
    let [s, e, n, w] = bands;
    let start = MARGIN + WALL;
    let core = Rect {
        x0: start + w.outer() + w.depth,
        y0: start + s.outer() + s.depth,
        x1: start + w.outer() + w.depth + core_w,
        y1: start + s.outer() + s.depth + core_h,
    };
    let ring = Rect {
        x0: core.x0 - w.depth,
        y0: core.y0 - s.depth,
        x1: core.x1 + e.depth,
        y1: core.y1 + n.depth,
    };
    let building = Rect {
        x0: ring.x0 - w.outer(),
        y0: ring.y0 - s.outer(),
        x1: ring.x1 + e.outer(),
        y1: ring.y1 + n.outer(),
    };
    let size = (building.x1 + WALL + MARGIN, building.y1 + WALL + MARGIN);
    let mut p = Plan {
        size,
        building,
        core,
        core_rooms: 0,
        bands,
        counter_clockwise,
        paint: vec![Paint::Wall(building.grown(WALL)), Paint::Floor(building)],
        objects: Vec::new(),
        waypoints: Vec::new(),
    };

    // Staircases: one or two, each in an open room or in an alcove beyond a hallway with rooms.
    let candidates: Vec<Side> = bands
        .iter()
        .filter(|b| !matches!(b.kind, BandKind::Hallway { outer: 0 }))
        .map(|b| b.side)
        .collect();
    let stairs_count = if rng.random_bool(0.5) { 1 } else { 2 };
    let stairs_sides: Vec<Side> = choose_k(rng, candidates.len(), stairs_count)
        .into_iter()
        .map(|i| candidates[i])
        .collect();

    let lanes = Lanes::new(&core, &bands);
    let mut outer_wall_doorways: [Vec<Span>; 4] = Default::default();
    core_block(rng, &mut p);
    for b in bands {
        if let BandKind::Hallway { outer } = b.kind
            && outer > 0
        {
            let alcove = stairs_sides
                .contains(&b.side)
                .then(|| lanes.straight(b.side));
            let spans = outer_rooms(rng, &mut p, b, ring, alcove);
            outer_wall_doorways[b.side.index()] = spans;
        }
    }
    for b in bands {
        let frame = Frame::new(b.side, &core);
        match b.kind {
            // Open rooms are furnished along the whole ring's side (beyond the corridor, clear
            // of the corners where the path turns), hallways along the block's side.
            BandKind::Room { dining } => furnish::open_room(
                rng,
                &mut p,
                frame,
                b,
                along(b.side, &ring),
                lanes.straight(b.side),
                dining,
                stairs_sides.contains(&b.side),
            ),
            BandKind::Hallway { outer } => furnish::hallway(
                rng,
                &mut p,
                frame,
                b,
                along(b.side, &core),
                outer == 0,
                &outer_wall_doorways[b.side.index()],
            ),
        }
    }
    p.waypoints = lanes.path(counter_clockwise);
    p
}

/// A rectangle's extent along a side: x for south and north, y for east and west.
pub(crate) fn along(side: Side, r: &Rect) -> Span {
    if side.horizontal() {
        Span { a: r.x0, b: r.x1 }
    } else {
        Span { a: r.y0, b: r.y1 }
    }
}

/// The block of rooms: walls around, split along its longer side into rooms of 2.5–5 m, each
/// with one or two doorways (a door in each) onto the ring, and maybe a piece of furniture.
fn core_block(rng: &mut ChaCha8Rng, p: &mut Plan) {
    let core = p.core;
    p.paint.push(Paint::Wall(core));
    let wide = core.width() >= core.height();
    let (long0, long1) = if wide {
        (core.x0, core.x1)
    } else {
        (core.y0, core.y1)
    };
    let long = long1 - long0;
    let n_min = ((long + ROOM_WIDTH.1 - 1) / ROOM_WIDTH.1).max(1);
    let n_max = (long / ROOM_WIDTH.0).max(n_min);
    let n = rng.random_range(n_min..=n_max);
    p.core_rooms = n as usize;
    // Cut walls [c, c + WALL], near the even split, jittered by up to 30 cm.
    let mut cuts = Vec::new();
    for i in 1..n {
        let even = floor_grid(long0 + long * i / n);
        // The wall [c, c + 15 cm] is centred on the jittered cut within 2.5 cm.
        cuts.push(even + pick(rng, -300, 300) - GRID);
    }
    for i in 0..n as usize {
        let a = if i == 0 {
            long0 + WALL
        } else {
            cuts[i - 1] + WALL
        };
        let b = if i + 1 == n as usize {
            long1 - WALL
        } else {
            cuts[i]
        };
        let room = if wide {
            Rect {
                x0: a,
                y0: core.y0 + WALL,
                x1: b,
                y1: core.y1 - WALL,
            }
        } else {
            Rect {
                x0: core.x0 + WALL,
                y0: a,
                x1: core.x1 - WALL,
                y1: b,
            }
        };
        p.paint.push(Paint::Floor(room));
        // The faces of this room on the ring.
        let mut faces = if wide {
            vec![Side::South, Side::North]
        } else {
            vec![Side::West, Side::East]
        };
        if i == 0 {
            faces.push(if wide { Side::West } else { Side::South });
        }
        if i + 1 == n as usize {
            faces.push(if wide { Side::East } else { Side::North });
        }
        let k = if rng.random_bool(0.5) { 1 } else { 2 };
        let mut doorways = Vec::new();
        for f in choose_k(rng, faces.len(), k) {
            let side = faces[f];
            let frame = Frame::new(side, &core);
            let span = along(side, &room);
            if let Some(d) = doorway(rng, p, frame, span, -WALL, "a door of the block's rooms") {
                doorways.push(d);
            }
        }
        furnish::room_furniture(rng, p, room, &doorways);
    }
}

/// A doorway with its door in the wall at `v ∈ [v0, v0 + WALL]` of `frame`, somewhere along
/// `span` at least 30 cm from its ends; open (free) with probability [`OPEN_DOOR`].
pub(crate) fn doorway(
    rng: &mut ChaCha8Rng,
    p: &mut Plan,
    frame: Frame,
    span: Span,
    v0: i32,
    what: &'static str,
) -> Option<Doorway> {
    let lo = ceil_grid(span.a + 300);
    let hi = floor_grid(span.b - 300 - DOORWAY);
    if hi < lo {
        return None;
    }
    let d = pick(rng, lo, hi);
    let open = rng.random_bool(OPEN_DOOR);
    let rect = frame.rect(d, d + DOORWAY, v0, v0 + WALL);
    if open {
        p.paint.push(Paint::Floor(rect));
    }
    p.objects.push(PlanObject::disc(
        SemanticClass::Door,
        rect,
        DOORWAY / 2,
        what,
    ));
    Some(Doorway {
        rect,
        span: Span {
            a: d,
            b: d + DOORWAY,
        },
    })
}

/// The rooms beyond a hallway (`ring`: the outer edge of the ring). With `alcove` (the straight
/// part of the hallway's lane), one slot open to the hallway within it holds a staircase
/// against the outer wall. Returns the spans of the openings in the hallway's outer wall.
fn outer_rooms(
    rng: &mut ChaCha8Rng,
    p: &mut Plan,
    b: Band,
    ring: Rect,
    alcove: Option<Span>,
) -> Vec<Span> {
    let BandKind::Hallway { outer } = b.kind else {
        return Vec::new();
    };
    let frame = Frame::new(b.side, &p.core);
    let (band, frontage) = if b.side.horizontal() {
        (
            Span {
                a: p.building.x0,
                b: p.building.x1,
            },
            Span {
                a: ring.x0,
                b: ring.x1,
            },
        )
    } else {
        let s = Span {
            a: ring.y0,
            b: ring.y1,
        };
        (s, s)
    };
    let (v0, v1) = (b.depth, b.depth + outer);
    p.paint
        .push(Paint::Wall(frame.rect(band.a, band.b, v0, v1)));
    let mut openings = Vec::new();
    let mut segments = Vec::new();
    if let Some(straight) = alcove {
        let aw = pick(rng, ALCOVE_WIDTH.0, ALCOVE_WIDTH.1);
        // Within the straight part of the hallway's lane (the path runs past it) where it
        // fits, else as near as the hallway allows, 0.5 m in from its ends.
        let lo = ceil_grid(straight.a.max(frontage.a + 500));
        let hi = floor_grid(straight.b.min(frontage.b - 500) - aw).max(lo);
        let a = pick(rng, lo, hi);
        // Side walls at [a, a + WALL] and [a + aw − WALL, a + aw]; open to the hallway.
        p.paint
            .push(Paint::Floor(frame.rect(a + WALL, a + aw - WALL, v0, v1)));
        // The stairs fill the alcove from a landing of 0–0.5 m beyond the hallway's wall line
        // to the outer wall.
        let landing = pick(rng, 0, 500);
        let stairs = frame.rect(a + WALL, a + aw - WALL, v0 + WALL + landing, v1);
        p.paint.push(Paint::Wall(stairs));
        p.objects.push(PlanObject {
            class: SemanticClass::Stairs,
            shape: ObjectShape::Rect(stairs),
            what: "a staircase in an alcove off the hallway, up to the outer wall",
        });
        openings.push(Span {
            a: a + WALL,
            b: a + aw - WALL,
        });
        segments.push(Span { a: band.a, b: a });
        segments.push(Span {
            a: a + aw,
            b: band.b,
        });
    } else {
        segments.push(band);
    }
    for seg in segments {
        if seg.len() < 3 * WALL {
            continue;
        }
        let target = pick(rng, 2500, 4500);
        let n = ((seg.len() + target / 2) / target).max(1);
        let mut start = seg.a;
        for i in 1..=n {
            // Room interior [start, end]; a wall [end, end + WALL] follows unless it is the last.
            let end = if i == n {
                seg.b
            } else {
                floor_grid(seg.a + seg.len() * i / n)
            };
            if end - start >= 2 * GRID {
                let room = frame.rect(start, end, v0 + WALL, v1);
                p.paint.push(Paint::Floor(room));
                let front = Span {
                    a: start.max(frontage.a),
                    b: end.min(frontage.b),
                };
                let mut doors = Vec::new();
                if let Some(d) = doorway(
                    rng,
                    p,
                    frame,
                    front,
                    v0,
                    "a door of the rooms beyond the hallway",
                ) {
                    openings.push(d.span);
                    doors.push(d);
                }
                furnish::room_furniture(rng, p, room, &doors);
            }
            start = end + WALL;
        }
    }
    openings
}

/// One line per side for the scenario file's comments.
pub(crate) fn describe(p: &Plan) -> Vec<String> {
    let mut out = vec![format!(
        "{} m × {} m inside the outer wall; a block of {} room(s), {} m × {} m, inside the ring; the path runs {}",
        metres(p.building.width()),
        metres(p.building.height()),
        p.core_rooms,
        metres(p.core.width()),
        metres(p.core.height()),
        if p.counter_clockwise {
            "counter-clockwise"
        } else {
            "clockwise"
        }
    )];
    for b in p.bands {
        out.push(match b.kind {
            BandKind::Hallway { outer: 0 } => {
                format!(
                    "{}: a hallway {} m wide along the outer wall",
                    b.side.name(),
                    metres(b.depth)
                )
            }
            BandKind::Hallway { outer } => format!(
                "{}: a hallway {} m wide, rooms {} m deep beyond it",
                b.side.name(),
                metres(b.depth),
                metres(outer - WALL)
            ),
            BandKind::Room { dining } => format!(
                "{}: a {} room {} m deep, the path {} m from the block",
                b.side.name(),
                if dining { "dining" } else { "living" },
                metres(b.depth),
                metres(b.lane)
            ),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn plans() -> impl Iterator<Item = Plan> {
        (0..400u64).map(|k| {
            let mut rng = ChaCha8Rng::seed_from_u64(k / 4);
            rng.set_stream(k % 4);
            plan(
                &mut rng,
                Ranges {
                    hallway: (1400, 2500),
                },
            )
        })
    }

    fn inside(r: &Rect, (x, y): (i32, i32)) -> bool {
        (r.x0..=r.x1).contains(&x) && (r.y0..=r.y1).contains(&y)
    }

    #[test]
    fn the_draws_stay_within_their_documented_ranges() {
        let mut sides = [0usize; 2];
        let mut outer = 0;
        for p in plans() {
            let (w, h) = (p.core.width(), p.core.height());
            assert!((CORE_WIDTH.0..=CORE_WIDTH.1).contains(&w), "{w}");
            assert!((CORE_HEIGHT.0..=CORE_HEIGHT.1).contains(&h), "{h}");
            let rooms = p
                .bands
                .iter()
                .filter(|b| matches!(b.kind, BandKind::Room { .. }))
                .count();
            assert!((1..=2).contains(&rooms));
            for b in p.bands {
                match b.kind {
                    BandKind::Hallway { outer: o } => {
                        sides[0] += 1;
                        assert!((1400..=2500).contains(&b.depth));
                        assert_eq!(b.lane, b.depth / 2);
                        if o > 0 {
                            outer += 1;
                            assert!((OUTER_ROOMS.0..=OUTER_ROOMS.1).contains(&o));
                        }
                    }
                    BandKind::Room { .. } => {
                        sides[1] += 1;
                        assert!((ROOM_BAND_DEPTH.0..=ROOM_BAND_DEPTH.1).contains(&b.depth));
                        assert!((ROOM_LANE.0..=ROOM_LANE.1).contains(&b.lane));
                    }
                }
            }
            // The path runs in the ring, between the block and the ring's outer edge.
            let ring = Rect {
                x0: p.core.x0 - p.bands[3].depth,
                y0: p.core.y0 - p.bands[0].depth,
                x1: p.core.x1 + p.bands[1].depth,
                y1: p.core.y1 + p.bands[2].depth,
            };
            assert_eq!(p.waypoints.len(), 9);
            for &pt in &p.waypoints {
                assert!(inside(&ring, pt) && !inside(&p.core, pt), "{pt:?}");
            }
            // Every object lies in the building; doors are 0.45 m discs, stairs rectangles.
            let mut classes = [0; 3];
            for o in &p.objects {
                classes[o.class as usize] += 1;
                match o.shape {
                    ObjectShape::Disc { x, y, r } => {
                        assert!(inside(&p.building.grown(WALL), (x, y)), "{o:?}");
                        if o.class == SemanticClass::Door {
                            assert_eq!(r, DOORWAY / 2);
                        }
                    }
                    ObjectShape::Rect(r) => {
                        assert_eq!(o.class, SemanticClass::Stairs);
                        assert!(
                            inside(&p.building, (r.x0, r.y0)) && inside(&p.building, (r.x1, r.y1))
                        );
                    }
                }
            }
            assert!(
                classes[0] >= p.core_rooms,
                "a door per room of the block at least"
            );
            assert!(
                (1..=2).contains(&classes[1]),
                "one or two staircases: {classes:?}"
            );
            assert!(classes[2] >= 1, "chairs in every open room: {classes:?}");
            // Every drawn edge is on the 5 cm grid.
            for op in &p.paint {
                let (Paint::Wall(r) | Paint::Floor(r)) = op;
                for v in [r.x0, r.y0, r.x1, r.y1] {
                    assert_eq!(v % GRID, 0, "{op:?}");
                }
                assert!(r.x0 <= r.x1 && r.y0 <= r.y1, "{op:?}");
            }
        }
        // Both kinds of side, and rooms beyond hallways, all occur.
        assert!(
            sides[0] > 300 && sides[1] > 300 && outer > 100,
            "{sides:?} {outer}"
        );
    }
}
