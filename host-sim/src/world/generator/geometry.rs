//! Integer geometry of the floor plan: millimetres on the 5 cm grid, rectangles, the four sides
//! of the ring and their local frames, and seeded draws on the grid.
//!
//! Every length of a plan is a whole number of millimetres and every wall or floor edge a
//! multiple of [`GRID`]: the plan has no floating-point rounding to disagree about, and its
//! numbers print the same everywhere.

use rand::RngExt;
use rand_chacha::ChaCha8Rng;

/// The map's cell (mm): every drawn edge lies on this grid.
pub(crate) const GRID: i32 = 50;

/// An axis-aligned rectangle in world millimetres, `x0 < x1`, `y0 < y1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Rect {
    pub(crate) x0: i32,
    pub(crate) y0: i32,
    pub(crate) x1: i32,
    pub(crate) y1: i32,
}

impl Rect {
    /// The rectangle spanned by two corners, in any order.
    pub(crate) fn spanning(a: (i32, i32), b: (i32, i32)) -> Self {
        Self {
            x0: a.0.min(b.0),
            y0: a.1.min(b.1),
            x1: a.0.max(b.0),
            y1: a.1.max(b.1),
        }
    }

    pub(crate) fn width(&self) -> i32 {
        self.x1 - self.x0
    }

    pub(crate) fn height(&self) -> i32 {
        self.y1 - self.y0
    }

    /// The centre, in mm (exact: edges on the grid make even sums).
    pub(crate) fn centre(&self) -> (i32, i32) {
        ((self.x0 + self.x1) / 2, (self.y0 + self.y1) / 2)
    }

    /// Grown by `d` on every side.
    pub(crate) fn grown(&self, d: i32) -> Self {
        Self {
            x0: self.x0 - d,
            y0: self.y0 - d,
            x1: self.x1 + d,
            y1: self.y1 + d,
        }
    }
}

/// A side of the ring, and of the building.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Side {
    South,
    East,
    North,
    West,
}

impl Side {
    /// In counter-clockwise order from the south.
    pub(crate) const ALL: [Side; 4] = [Side::South, Side::East, Side::North, Side::West];

    pub(crate) const fn index(self) -> usize {
        match self {
            Side::South => 0,
            Side::East => 1,
            Side::North => 2,
            Side::West => 3,
        }
    }

    pub(crate) const fn name(self) -> &'static str {
        match self {
            Side::South => "south",
            Side::East => "east",
            Side::North => "north",
            Side::West => "west",
        }
    }

    /// Whether the side runs along x (south, north).
    pub(crate) const fn horizontal(self) -> bool {
        matches!(self, Side::South | Side::North)
    }
}

/// The local frame of a side: `u` along the side (world x for south and north, world y for east
/// and west), `v` outwards from the core's face on that side (`v = 0` on the face).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frame {
    side: Side,
    /// The core's face: its y (south, north) or x (east, west).
    face: i32,
}

impl Frame {
    pub(crate) fn new(side: Side, core: &Rect) -> Self {
        let face = match side {
            Side::South => core.y0,
            Side::North => core.y1,
            Side::East => core.x1,
            Side::West => core.x0,
        };
        Self { side, face }
    }

    /// The world point of local `(u, v)`.
    pub(crate) fn point(&self, u: i32, v: i32) -> (i32, i32) {
        match self.side {
            Side::South => (u, self.face - v),
            Side::North => (u, self.face + v),
            Side::East => (self.face + v, u),
            Side::West => (self.face - v, u),
        }
    }

    /// The world rectangle of local `u ∈ [u0, u1]`, `v ∈ [v0, v1]`.
    pub(crate) fn rect(&self, u0: i32, u1: i32, v0: i32, v1: i32) -> Rect {
        Rect::spanning(self.point(u0, v0), self.point(u1, v1))
    }
}

/// An interval `[a, b]` along a side (mm).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Span {
    pub(crate) a: i32,
    pub(crate) b: i32,
}

impl Span {
    pub(crate) fn len(&self) -> i32 {
        self.b - self.a
    }

    /// Whether the two intervals come closer than `gap`.
    pub(crate) fn near(&self, other: &Span, gap: i32) -> bool {
        self.a < other.b + gap && other.a < self.b + gap
    }
}

/// A multiple of [`GRID`] drawn uniformly from `[lo, hi]` (both multiples of the grid, `lo ≤ hi`).
pub(crate) fn pick(rng: &mut ChaCha8Rng, lo: i32, hi: i32) -> i32 {
    debug_assert!(lo % GRID == 0 && hi % GRID == 0 && lo <= hi, "{lo} {hi}");
    lo + GRID * rng.random_range(0..=(hi - lo) / GRID)
}

/// `v` rounded down to the grid.
pub(crate) fn floor_grid(v: i32) -> i32 {
    v.div_euclid(GRID) * GRID
}

/// `v` rounded up to the grid.
pub(crate) fn ceil_grid(v: i32) -> i32 {
    -floor_grid(-v)
}

/// `k` of `n` items drawn without replacement, in draw order.
pub(crate) fn choose_k(rng: &mut ChaCha8Rng, n: usize, k: usize) -> Vec<usize> {
    let mut pool: Vec<usize> = (0..n).collect();
    let mut out = Vec::with_capacity(k);
    for _ in 0..k.min(n) {
        let i = rng.random_range(0..pool.len());
        out.push(pool.remove(i));
    }
    out
}

/// Millimetres as metres, printed exactly (`6950` → `6.95`, `3000` → `3.0`).
pub(crate) fn metres(mm: i32) -> String {
    let sign = if mm < 0 { "-" } else { "" };
    let a = mm.unsigned_abs();
    let frac = format!("{:03}", a % 1000);
    let frac = frac.trim_end_matches('0');
    format!(
        "{sign}{}.{}",
        a / 1000,
        if frac.is_empty() { "0" } else { frac }
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metres_print_exactly() {
        assert_eq!(metres(6950), "6.95");
        assert_eq!(metres(3000), "3.0");
        assert_eq!(metres(50), "0.05");
        assert_eq!(metres(-1250), "-1.25");
        for mm in [-13901, -3, 0, 7, 13900, 13901, 200_001] {
            let v: f64 = metres(mm).parse().unwrap();
            assert_eq!(v, mm as f64 / 1000.0, "{mm}");
        }
    }

    #[test]
    fn frames_map_outwards_from_the_core() {
        let core = Rect {
            x0: 1000,
            y0: 2000,
            x1: 5000,
            y1: 6000,
        };
        assert_eq!(
            Frame::new(Side::South, &core).point(3000, 500),
            (3000, 1500)
        );
        assert_eq!(
            Frame::new(Side::North, &core).point(3000, 500),
            (3000, 6500)
        );
        assert_eq!(Frame::new(Side::East, &core).point(4000, 500), (5500, 4000));
        assert_eq!(Frame::new(Side::West, &core).point(4000, 500), (500, 4000));
        let r = Frame::new(Side::West, &core).rect(2500, 3500, 0, 150);
        assert_eq!(
            r,
            Rect {
                x0: 850,
                y0: 2500,
                x1: 1000,
                y1: 3500
            }
        );
    }
}
