//! Furniture and the objects that go with it: a dining table with its chairs, a living room's
//! sofa and armchairs, staircases in open rooms, front doors, hallway cabinets, and a piece of
//! furniture in the closed rooms.
//!
//! Everything is placed in the local frame of its side ([`Frame`]: `u` along, `v` outwards from
//! the block of rooms). In an open room the path's lane is at `v = lane`; the **corridor**
//! `v < lane + 1 m` stays free, and the furniture stands beyond it, the nearest pieces (chairs,
//! armchairs, the foot of a staircase) at its edge: a car on the lane passes 1 m from them.

use firmware_core::observation::SemanticClass;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::geometry::{Frame, Rect, Span, ceil_grid, choose_k, floor_grid, pick};
use super::plan::{Band, DOORWAY, ObjectShape, Paint, Plan, PlanObject, WALL};

/// Free depth beyond an open room's lane (mm).
pub(crate) const CORRIDOR: i32 = 1000;
/// Gap between pieces along a side (mm).
const GAP: i32 = 300;
/// A dining chair: a 40 cm square, seen as a disc of 30 cm.
const CHAIR: i32 = 400;
const CHAIR_RADIUS: i32 = 300;
/// An armchair: a 60 cm square, seen as a disc of 40 cm.
const ARMCHAIR: i32 = 600;
const ARMCHAIR_RADIUS: i32 = 400;

/// A doorway: the opening (or closed door) in a wall, and its span along the wall.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Doorway {
    pub(crate) rect: Rect,
    pub(crate) span: Span,
}

/// A piece to place along an open room.
#[derive(Clone, Copy, Debug)]
enum Piece {
    /// A staircase from the corridor's edge up to the outer wall.
    Stairs {
        width: i32,
    },
    /// A table along the room, chairs along its side that faces the lane, and maybe one at
    /// each end. (A chair behind the table would be out of the detector's line of sight from
    /// the lane: the table is an obstacle in the map.)
    Dining {
        table: i32,
        table_depth: i32,
        per_side: i32,
        ends: bool,
    },
    Living {
        sofa: Option<i32>,
        armchairs: i32,
        coffee: Option<i32>,
    },
    FrontDoor,
}

impl Piece {
    fn len(&self) -> i32 {
        match *self {
            Piece::Stairs { width } => width,
            Piece::Dining { table, ends, .. } => table + if ends { 2 * (CHAIR + 100) } else { 0 },
            Piece::Living {
                sofa, armchairs, ..
            } => sofa.unwrap_or(0).max(if armchairs == 2 {
                3 * ARMCHAIR
            } else {
                ARMCHAIR
            }),
            Piece::FrontDoor => DOORWAY,
        }
    }
}

/// Furnishes an open room of the ring: a dining or a living group within the straight part of
/// the lane (`straight`, so that the path runs past it), a staircase up to the outer wall when
/// `stairs`, and maybe the front door, each at a random free place along the room (the ring's
/// extent `along`, 30 cm in from its ends), 30 cm apart. If the staircase finds no room beside
/// the group, the group is placed first; if neither order works, a lone armchair replaces the
/// group (a world keeps its staircases). A front door that finds no room is left out.
#[allow(clippy::too_many_arguments)]
pub(crate) fn open_room(
    rng: &mut ChaCha8Rng,
    p: &mut Plan,
    frame: Frame,
    band: Band,
    along: Span,
    straight: Span,
    dining: bool,
    stairs: bool,
) {
    let span = Span {
        a: along.a + GAP,
        b: along.b - GAP,
    };
    let near = band.lane + CORRIDOR;
    // At least 1.4 m: the room is at least 3.7 m deep, the lane at most 1.3 m from the block.
    let zone = band.depth - near;
    // The group fits the lane's straight part, at least 1.8 m: the block's side (at least 3 m)
    // plus the two crossing lanes, less two chamfers of at most `lane + lane − 0.7 m` each.
    let fit = floor_grid(straight.len()).max(1200);
    let group = if dining {
        let table = pick(rng, 1200, fit.min(1800));
        Piece::Dining {
            table,
            table_depth: pick(rng, 800, (zone - CHAIR - 100).min(1000)),
            per_side: if table >= 1600 { 3 } else { 2 },
            ends: rng.random_bool(0.5) && table + 2 * (CHAIR + 100) <= fit,
        }
    } else {
        let armchairs = if rng.random_bool(0.5) || fit < 3 * ARMCHAIR {
            1
        } else {
            2
        };
        let sofa = (zone >= ARMCHAIR + 300 + 800).then(|| pick(rng, 1600, fit.clamp(1600, 2400)));
        let coffee = (zone >= ARMCHAIR + 200 + 500 + 200 + 800 && rng.random_bool(0.5))
            .then(|| pick(rng, 800, 1200));
        Piece::Living {
            sofa,
            armchairs,
            coffee,
        }
    };
    let stairs = stairs.then(|| Piece::Stairs {
        width: pick(rng, 900, 1200),
    });
    let door = rng.random_bool(0.5).then_some(Piece::FrontDoor);
    // The group within the straight part, the staircase anywhere: the staircase first, else
    // the group first, else the staircase and a lone armchair; the last keeps what it placed
    // (the staircase, first, always fits alone).
    let armchair = Piece::Living {
        sofa: None,
        armchairs: 1,
        coffee: None,
    };
    let orders: [[Option<(Piece, Span)>; 2]; 3] = [
        [stairs.map(|st| (st, span)), Some((group, straight))],
        [Some((group, straight)), stairs.map(|st| (st, span))],
        [stairs.map(|st| (st, span)), Some((armchair, straight))],
    ];
    let mut free = vec![span];
    let mut placed = Vec::new();
    for order in orders {
        free = vec![span];
        placed.clear();
        for &(piece, within) in order.iter().flatten() {
            if let Some(u0) = take(rng, &mut free, piece.len(), within) {
                placed.push((u0, piece));
            }
        }
        if placed.len() == order.iter().flatten().count() {
            break;
        }
    }
    if let Some(d) = door
        && let Some(u0) = take(rng, &mut free, d.len(), span)
    {
        placed.push((u0, d));
    }
    for (u0, piece) in placed {
        place(p, frame, band, near, u0, piece);
    }
}

/// Takes `len` out of the free spans, within `within`, at a random place in a random span that
/// fits; what is left of that span, less [`GAP`] on each side of the piece, stays free.
fn take(rng: &mut ChaCha8Rng, free: &mut Vec<Span>, len: i32, within: Span) -> Option<i32> {
    let fits: Vec<(usize, Span)> = free
        .iter()
        .enumerate()
        .filter_map(|(i, f)| {
            let a = ceil_grid(f.a.max(within.a));
            let b = floor_grid(f.b.min(within.b));
            (b - a >= len).then_some((i, Span { a, b }))
        })
        .collect();
    if fits.is_empty() {
        return None;
    }
    let (i, s) = fits[rng.random_range(0..fits.len())];
    let u0 = pick(rng, s.a, s.b - len);
    let f = free.remove(i);
    let rest = [
        Span {
            a: f.a,
            b: u0 - GAP,
        },
        Span {
            a: u0 + len + GAP,
            b: f.b,
        },
    ];
    for (k, r) in rest.into_iter().filter(|r| r.len() > 0).enumerate() {
        free.insert(i + k, r);
    }
    Some(u0)
}

fn place(p: &mut Plan, frame: Frame, band: Band, near: i32, u0: i32, piece: Piece) {
    let wall = band.depth;
    match piece {
        Piece::Stairs { width } => {
            let r = frame.rect(u0, u0 + width, near, wall);
            p.paint.push(Paint::Wall(r));
            p.objects.push(PlanObject {
                class: SemanticClass::Stairs,
                shape: ObjectShape::Rect(r),
                what: "a staircase from the corridor up to the outer wall",
            });
        }
        Piece::Dining {
            table,
            table_depth,
            per_side,
            ends,
        } => {
            let t0 = u0 + if ends { CHAIR + 100 } else { 0 };
            let tv = near + CHAIR + 100;
            p.paint.push(Paint::Wall(frame.rect(
                t0,
                t0 + table,
                tv,
                tv + table_depth,
            )));
            let mut chairs = Vec::new();
            for i in 0..per_side {
                let c = floor_grid(t0 + table * (2 * i + 1) / (2 * per_side)) - CHAIR / 2;
                chairs.push((c, near));
            }
            if ends {
                let cv = floor_grid(tv + table_depth / 2) - CHAIR / 2;
                chairs.push((u0, cv));
                chairs.push((t0 + table + 100, cv));
            }
            for (cu, cv) in chairs {
                let r = frame.rect(cu, cu + CHAIR, cv, cv + CHAIR);
                seat(p, r, CHAIR_RADIUS, "a chair at the dining table");
            }
        }
        Piece::Living {
            sofa,
            armchairs,
            coffee,
        } => {
            let len = piece.len();
            let mut at = vec![u0 + len / 2 - ARMCHAIR / 2];
            if armchairs == 2 {
                at = vec![u0, u0 + len - ARMCHAIR];
            }
            for cu in at {
                let cu = floor_grid(cu);
                let r = frame.rect(cu, cu + ARMCHAIR, near, near + ARMCHAIR);
                seat(p, r, ARMCHAIR_RADIUS, "an armchair");
            }
            if let Some(s) = sofa {
                let a = floor_grid(u0 + (len - s) / 2);
                p.paint
                    .push(Paint::Wall(frame.rect(a, a + s, wall - 800, wall)));
            }
            if let Some(c) = coffee {
                let a = floor_grid(u0 + (len - c) / 2);
                let v = near + ARMCHAIR + 200;
                p.paint.push(Paint::Wall(frame.rect(a, a + c, v, v + 500)));
            }
        }
        Piece::FrontDoor => {
            front_door(p, frame.rect(u0, u0 + DOORWAY, wall, wall + WALL));
        }
    }
}

/// A chair or an armchair: an obstacle `r`, seen as a disc of `radius` at its middle.
fn seat(p: &mut Plan, r: Rect, radius: i32, what: &'static str) {
    p.paint.push(Paint::Wall(r));
    p.objects
        .push(PlanObject::disc(SemanticClass::Chair, r, radius, what));
}

/// A closed front door in the outer wall `r` (the wall stays).
fn front_door(p: &mut Plan, r: Rect) {
    p.objects.push(PlanObject::disc(
        SemanticClass::Door,
        r,
        DOORWAY / 2,
        "the front door (closed) in the outer wall",
    ));
}

/// A hallway: a front door when it runs along the outer wall (probability 0.4), and in a
/// hallway of 2 m or more a cabinet against its outer wall (probability 0.5), clear of the
/// openings in that wall.
pub(crate) fn hallway(
    rng: &mut ChaCha8Rng,
    p: &mut Plan,
    frame: Frame,
    band: Band,
    along: Span,
    on_outer_wall: bool,
    openings: &[Span],
) {
    let mut taken: Vec<Span> = openings.to_vec();
    let wall = band.depth;
    if on_outer_wall && rng.random_bool(0.4) {
        let lo = along.a + GAP;
        let hi = floor_grid(along.b - GAP - DOORWAY);
        if hi >= lo {
            let u0 = pick(rng, lo, hi);
            front_door(p, frame.rect(u0, u0 + DOORWAY, wall, wall + WALL));
            taken.push(Span {
                a: u0,
                b: u0 + DOORWAY,
            });
        }
    }
    if band.depth >= 2000 && rng.random_bool(0.5) {
        let len = pick(rng, 800, 1500);
        let lo = along.a + 500;
        let hi = floor_grid(along.b - 500 - len);
        for _ in 0..8 {
            if hi < lo {
                break;
            }
            let u0 = pick(rng, lo, hi);
            let s = Span { a: u0, b: u0 + len };
            if taken.iter().all(|t| !t.near(&s, GAP)) {
                p.paint
                    .push(Paint::Wall(frame.rect(u0, u0 + len, wall - 400, wall)));
                break;
            }
        }
    }
}

/// With probability 0.7, a bed, desk or wardrobe (0.9–1.6 m × 0.6–2 m) in a corner of a closed
/// room, at least 1 m from its doorways and leaving 0.6 m of the room free both ways.
pub(crate) fn room_furniture(rng: &mut ChaCha8Rng, p: &mut Plan, room: Rect, doors: &[Doorway]) {
    if !rng.random_bool(0.7) {
        return;
    }
    let (a, b) = (pick(rng, 900, 1600), pick(rng, 600, 2000));
    let (w, h) = if rng.random_bool(0.5) { (a, b) } else { (b, a) };
    if room.width() - w < 600 || room.height() - h < 600 {
        return;
    }
    for corner in choose_k(rng, 4, 4) {
        let x0 = if corner & 1 == 0 {
            room.x0
        } else {
            room.x1 - w
        };
        let y0 = if corner & 2 == 0 {
            room.y0
        } else {
            room.y1 - h
        };
        let r = Rect {
            x0,
            y0,
            x1: x0 + w,
            y1: y0 + h,
        };
        let clear = doors.iter().all(|d| {
            let dx = (d.rect.x0 - r.x1).max(r.x0 - d.rect.x1);
            let dy = (d.rect.y0 - r.y1).max(r.y0 - d.rect.y1);
            dx.max(dy) >= 1000
        });
        if clear {
            p.paint.push(Paint::Wall(r));
            return;
        }
    }
}
