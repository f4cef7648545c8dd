//! The path: one lane per side of the ring, the corners cut by chamfers.

use super::geometry::{Rect, Side, Span, floor_grid};
use super::plan::Band;

/// The path's lanes: their lines, and the chamfers that cut the corners.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Lanes {
    ys: i32,
    yn: i32,
    xe: i32,
    xw: i32,
    /// Chamfers at the south-east, north-east, north-west and south-west corners.
    se: i32,
    ne: i32,
    nw: i32,
    sw: i32,
}

impl Lanes {
    /// One lane per side (a hallway's middle, an open room's lane); a chamfer of
    /// `lane_a + lane_b − 0.7 m`, within 0.5–1.5 m, keeps at least 0.7/√2 ≈ 0.5 m from the
    /// block's corner.
    pub(crate) fn new(core: &Rect, bands: &[Band; 4]) -> Self {
        let [s, e, n, w] = bands;
        let cut = |a: &Band, b: &Band| floor_grid((a.lane + b.lane - 700).clamp(500, 1500));
        Self {
            ys: core.y0 - s.lane,
            yn: core.y1 + n.lane,
            xe: core.x1 + e.lane,
            xw: core.x0 - w.lane,
            se: cut(s, e),
            ne: cut(n, e),
            nw: cut(n, w),
            sw: cut(s, w),
        }
    }

    /// The straight part of a side's lane, along the side.
    pub(crate) fn straight(&self, side: Side) -> Span {
        match side {
            Side::South => Span {
                a: self.xw + self.sw,
                b: self.xe - self.se,
            },
            Side::North => Span {
                a: self.xw + self.nw,
                b: self.xe - self.ne,
            },
            Side::East => Span {
                a: self.ys + self.se,
                b: self.yn - self.ne,
            },
            Side::West => Span {
                a: self.ys + self.sw,
                b: self.yn - self.nw,
            },
        }
    }

    /// The closed path, starting in the middle of the south lane.
    pub(crate) fn path(&self, counter_clockwise: bool) -> Vec<(i32, i32)> {
        let Self {
            ys,
            yn,
            xe,
            xw,
            se,
            ne,
            nw,
            sw,
        } = *self;
        let ring = [
            (xe - se, ys),
            (xe, ys + se),
            (xe, yn - ne),
            (xe - ne, yn),
            (xw + nw, yn),
            (xw, yn - nw),
            (xw, ys + sw),
            (xw + sw, ys),
        ];
        let start = (floor_grid((xw + xe) / 2), ys);
        let mut pts = vec![start];
        if counter_clockwise {
            pts.extend(ring);
        } else {
            pts.extend(ring.iter().rev());
        }
        pts
    }
}
