//! Occupancy-grid maps in ROS `map_server` format, and fast ray casting through them.
//!
//! A map is a YAML file naming an image (PGM or PNG) and how to read it:
//!
//! ```yaml
//! image: basement_hallways_10cm.png   # relative to the YAML file
//! resolution: 0.1                      # metres per pixel
//! origin: [-30.0, -30.0, 0.0]          # pose (x, y, yaw) of the lower-left pixel
//! negate: 0                            # 1: white is occupied
//! occupied_thresh: 0.65
//! free_thresh: 0.196
//! mode: trinary                        # trinary (default), scale or raw
//! ```
//!
//! Pixel `v` (the mean of the colour channels, scaled to 0–255) becomes the occupancy
//! probability `p = (255 − v)/255` (`v/255` with `negate: 1`): occupied when
//! `p > occupied_thresh`, free when `p < free_thresh`, unknown otherwise. A fully transparent
//! pixel is unknown. In `raw` mode the pixel value is the occupancy in percent (0 free, 100
//! occupied, anything else unknown unless below `free_thresh · 100`). Image row 0 is the **top**
//! of the map: the origin is the lower-left pixel. The car treats **unknown cells as
//! obstacles**, and so does the range sensor; everything outside the image is unknown.
//!
//! Every problem, a missing file, malformed YAML, a bad threshold, an unreadable image, comes
//! back as a [`MapError`] naming the file and the problem. Nothing here panics on bad input.
//!
//! Ray casting ([`OccupancyGrid::raycast`]) walks the grid cell by cell (Amanatides–Woo DDA): the
//! cost is the number of cells crossed, at most `range / resolution · 2`.
//!
//! ```
//! use host_sim::world::map::OccupancyGrid;
//! // A 4 m × 4 m room at 0.1 m/px: walls on the border.
//! let grid = OccupancyGrid::from_fn(40, 40, 0.1, [0.0, 0.0, 0.0], |c, r| {
//!     c == 0 || r == 0 || c == 39 || r == 39
//! });
//! let d = grid.raycast(2.0, 2.0, 0.0, 10.0);
//! assert!((d - 1.9).abs() < 1e-9); // the wall's cells start at x = 3.9
//! ```

use std::path::{Path, PathBuf};

mod files;

pub use files::{MAX_IMAGE_SIDE, MapError, MapMeta, MapMode};
use files::{decode_pgm, decode_png, image_err};

/// One cell's state.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[repr(u8)]
pub enum Cell {
    /// Free space.
    Free = 0,
    /// An obstacle.
    Occupied = 1,
    /// Not mapped; the car treats it as an obstacle.
    Unknown = 2,
}

/// Chebyshev distance transform (two passes, unit steps to the 8 neighbours, exact for the
/// Chebyshev metric): per cell, the distance in cells to the nearest cell that is not free,
/// the outside of the grid included; 0 for those cells. Saturates at `u16::MAX`.
fn chebyshev_clearance(width: usize, height: usize, cells: &[Cell]) -> Vec<u16> {
    let mut d = vec![0u16; width * height];
    for r in 0..height {
        for c in 0..width {
            let i = r * width + c;
            if cells[i] == Cell::Free {
                // Distance to the outside (the ring of cells just beyond the border).
                let border = (c + 1).min(r + 1).min(width - c).min(height - r);
                d[i] = border.min(u16::MAX as usize) as u16;
            }
        }
    }
    let at = |d: &[u16], c: i64, r: i64| -> Option<u16> {
        (c >= 0 && r >= 0 && (c as usize) < width && (r as usize) < height)
            .then(|| d[r as usize * width + c as usize])
    };
    for r in 0..height as i64 {
        for c in 0..width as i64 {
            let i = r as usize * width + c as usize;
            for (dc, dr) in [(-1, 0), (-1, -1), (0, -1), (1, -1)] {
                if let Some(n) = at(&d, c + dc, r + dr) {
                    d[i] = d[i].min(n.saturating_add(1));
                }
            }
        }
    }
    for r in (0..height as i64).rev() {
        for c in (0..width as i64).rev() {
            let i = r as usize * width + c as usize;
            for (dc, dr) in [(1, 0), (1, 1), (0, 1), (-1, 1)] {
                if let Some(n) = at(&d, c + dc, r + dr) {
                    d[i] = d[i].min(n.saturating_add(1));
                }
            }
        }
    }
    d
}

/// A loaded occupancy grid. Row 0 is the **bottom** row (lowest `y`), as in
/// `nav_msgs/OccupancyGrid`.
#[derive(Clone, Debug)]
pub struct OccupancyGrid {
    width: usize,
    height: usize,
    resolution: f64,
    origin: [f64; 3],
    cos_yaw: f64,
    sin_yaw: f64,
    cells: Vec<Cell>,
    /// Per cell: Chebyshev distance, in cells, to the nearest cell that is not free (outside
    /// the grid counts as not free); 0 for such cells. See [`OccupancyGrid::clearance_cells`].
    clearance: Vec<u16>,
    /// Where the map came from (for messages).
    source: PathBuf,
}

impl OccupancyGrid {
    /// Loads the map described by the YAML file at `path`.
    pub fn load(path: &Path) -> Result<Self, MapError> {
        let text = std::fs::read_to_string(path).map_err(|error| MapError::Io {
            path: path.to_path_buf(),
            error,
        })?;
        let meta = MapMeta::parse(&text, path)?;
        Self::from_meta(&meta, path)
    }

    /// Loads the image `meta` names; `yaml` is the YAML file (for messages).
    pub fn from_meta(meta: &MapMeta, yaml: &Path) -> Result<Self, MapError> {
        let bytes = std::fs::read(&meta.image).map_err(|error| MapError::Io {
            path: meta.image.clone(),
            error,
        })?;
        let ext = meta
            .image
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        let grey = if bytes.starts_with(b"\x89PNG") {
            decode_png(&bytes, &meta.image)?
        } else if bytes.starts_with(b"P5") || bytes.starts_with(b"P2") {
            decode_pgm(&bytes, &meta.image)?
        } else {
            return Err(image_err(
                &meta.image,
                format!(
                    "neither PNG nor PGM (extension {:?}); map_server images must be one of these",
                    ext.unwrap_or_default()
                ),
            ));
        };
        let mut cells = vec![Cell::Unknown; grey.width * grey.height];
        for r in 0..grey.height {
            // Image row r (from the top) is grid row height-1-r (from the bottom).
            let gr = grey.height - 1 - r;
            for c in 0..grey.width {
                let i = r * grey.width + c;
                cells[gr * grey.width + c] = meta.classify(grey.value[i], grey.alpha[i]);
            }
        }
        Ok(Self::from_cells(
            grey.width,
            grey.height,
            meta.resolution,
            meta.origin,
            cells,
            yaml.to_path_buf(),
        ))
    }

    fn from_cells(
        width: usize,
        height: usize,
        resolution: f64,
        origin: [f64; 3],
        cells: Vec<Cell>,
        source: PathBuf,
    ) -> Self {
        let clearance = chebyshev_clearance(width, height, &cells);
        Self {
            width,
            height,
            resolution,
            origin,
            cos_yaw: libm::cos(origin[2]),
            sin_yaw: libm::sin(origin[2]),
            cells,
            clearance,
            source,
        }
    }

    /// A grid built from a function `blocked(column, row)` (row 0 at the bottom): blocked cells
    /// are occupied, the rest free. For tests and generated maps.
    pub fn from_fn(
        width: usize,
        height: usize,
        resolution: f64,
        origin: [f64; 3],
        blocked: impl Fn(usize, usize) -> bool,
    ) -> Self {
        let mut cells = Vec::with_capacity(width * height);
        for r in 0..height {
            for c in 0..width {
                cells.push(if blocked(c, r) {
                    Cell::Occupied
                } else {
                    Cell::Free
                });
            }
        }
        Self::from_cells(width, height, resolution, origin, cells, PathBuf::new())
    }

    /// Width in cells.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in cells.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Metres per cell.
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// Pose of the lower-left corner `(x, y, yaw)`.
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// The YAML file the map was loaded from (empty for built grids).
    pub fn source(&self) -> &Path {
        &self.source
    }

    /// The cell at `(column, row)`, row 0 at the bottom; `None` outside the grid.
    pub fn cell(&self, column: usize, row: usize) -> Option<Cell> {
        (column < self.width && row < self.height).then(|| self.cells[row * self.width + column])
    }

    /// Number of cells of each state: `[free, occupied, unknown]`.
    pub fn counts(&self) -> [usize; 3] {
        let mut n = [0; 3];
        for c in &self.cells {
            n[*c as usize] += 1;
        }
        n
    }

    /// World point → continuous grid coordinates (cells, from the lower-left corner).
    #[inline]
    fn to_grid(&self, x: f64, y: f64) -> (f64, f64) {
        let dx = x - self.origin[0];
        let dy = y - self.origin[1];
        let gx = (dx * self.cos_yaw + dy * self.sin_yaw) / self.resolution;
        let gy = (-dx * self.sin_yaw + dy * self.cos_yaw) / self.resolution;
        (gx, gy)
    }

    /// The world coordinates of the centre of cell `(column, row)`.
    pub fn cell_center(&self, column: usize, row: usize) -> (f64, f64) {
        let gx = (column as f64 + 0.5) * self.resolution;
        let gy = (row as f64 + 0.5) * self.resolution;
        (
            self.origin[0] + gx * self.cos_yaw - gy * self.sin_yaw,
            self.origin[1] + gx * self.sin_yaw + gy * self.cos_yaw,
        )
    }

    #[inline]
    fn blocked_cell(&self, cx: i64, cy: i64) -> bool {
        if cx < 0 || cy < 0 || cx as usize >= self.width || cy as usize >= self.height {
            return true;
        }
        self.cells[cy as usize * self.width + cx as usize] != Cell::Free
    }

    /// Whether the world point lies in a cell that is not free (occupied, unknown, or outside
    /// the map).
    #[inline]
    pub fn is_blocked(&self, x: f64, y: f64) -> bool {
        let (gx, gy) = self.to_grid(x, y);
        // f64::floor is exact, like libm's, and a single instruction (the hot path of collision
        // checks).
        self.blocked_cell(gx.floor() as i64, gy.floor() as i64)
    }

    /// The Chebyshev distance, in cells, from the cell of the world point `(x, y)` to the
    /// nearest cell that is not free (0 when that cell itself is not free or outside the map).
    /// Every cell within `clearance_cells − 1` cells of it, along each axis, is free: a point
    /// less than `(clearance_cells − 1)·resolution` metres from `(x, y)` lies in a free cell.
    #[inline]
    pub fn clearance_cells(&self, x: f64, y: f64) -> u16 {
        let (gx, gy) = self.to_grid(x, y);
        let (cx, cy) = (gx.floor() as i64, gy.floor() as i64);
        if self.blocked_cell(cx, cy) {
            return 0;
        }
        self.clearance[cy as usize * self.width + cx as usize]
    }

    /// Distance from `(x, y)` along heading `angle` (world frame, radians) to the first cell
    /// that is not free, at most `max_range`. A ray starting in a blocked cell returns 0.
    ///
    /// Amanatides–Woo traversal: one step per cell crossed.
    pub fn raycast(&self, x: f64, y: f64, angle: f64, max_range: f64) -> f64 {
        let (gx, gy) = self.to_grid(x, y);
        let a = angle - self.origin[2];
        let (dx, dy) = (libm::cos(a), libm::sin(a));
        let mut cx = gx.floor() as i64;
        let mut cy = gy.floor() as i64;
        if self.blocked_cell(cx, cy) {
            return 0.0;
        }
        let max_t = max_range / self.resolution;
        let step_x: i64 = if dx > 0.0 { 1 } else { -1 };
        let step_y: i64 = if dy > 0.0 { 1 } else { -1 };
        let t_delta_x = if dx != 0.0 {
            1.0 / dx.abs()
        } else {
            f64::INFINITY
        };
        let t_delta_y = if dy != 0.0 {
            1.0 / dy.abs()
        } else {
            f64::INFINITY
        };
        let mut t_max_x = if dx > 0.0 {
            (cx as f64 + 1.0 - gx) * t_delta_x
        } else if dx < 0.0 {
            (gx - cx as f64) * t_delta_x
        } else {
            f64::INFINITY
        };
        let mut t_max_y = if dy > 0.0 {
            (cy as f64 + 1.0 - gy) * t_delta_y
        } else if dy < 0.0 {
            (gy - cy as f64) * t_delta_y
        } else {
            f64::INFINITY
        };
        loop {
            let t = if t_max_x < t_max_y {
                let t = t_max_x;
                t_max_x += t_delta_x;
                cx += step_x;
                t
            } else {
                let t = t_max_y;
                t_max_y += t_delta_y;
                cy += step_y;
                t
            };
            if t >= max_t {
                return max_range;
            }
            if self.blocked_cell(cx, cy) {
                return t * self.resolution;
            }
        }
    }

    /// Whether the straight segment from `a` to `b` crosses no blocked cell before the last
    /// `slack` metres (the end may lie in or on a blocked object).
    pub fn line_of_sight(&self, a: (f64, f64), b: (f64, f64), slack: f64) -> bool {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len = libm::sqrt(dx * dx + dy * dy);
        let reach = len - slack;
        if reach <= 0.0 {
            return true;
        }
        self.raycast(a.0, a.1, libm::atan2(dy, dx), reach) >= reach
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clearance_is_the_chebyshev_distance_to_the_nearest_blocked_cell() {
        // Walls, a pillar and a diagonal: check every cell against a brute-force search.
        let g = OccupancyGrid::from_fn(23, 17, 0.1, [0.0, 0.0, 0.3], |c, r| {
            (c == 7 && r < 9) || ((14..=16).contains(&c) && (10..=12).contains(&r)) || c + r == 30
        });
        let (w, h) = (23i64, 17i64);
        for r in 0..h {
            for c in 0..w {
                let mut want = i64::MAX;
                for br in -1..=h {
                    for bc in -1..=w {
                        if g.blocked_cell(bc, br) {
                            want = want.min((bc - c).abs().max((br - r).abs()));
                        }
                    }
                }
                let got = g.clearance[(r * w + c) as usize] as i64;
                assert_eq!(got, want, "cell ({c}, {r})");
            }
        }
    }

    fn room() -> OccupancyGrid {
        OccupancyGrid::from_fn(40, 30, 0.1, [-1.0, -1.0, 0.0], |c, r| {
            c == 0 || r == 0 || c == 39 || r == 29
        })
    }

    #[test]
    fn raycast_hits_the_walls_in_all_directions() {
        let g = room();
        // Free interior spans x in [-0.9, 2.9], y in [-0.9, 1.9].
        let (x, y) = (0.5, 0.5);
        let right = g.raycast(x, y, 0.0, 10.0);
        let up = g.raycast(x, y, std::f64::consts::FRAC_PI_2, 10.0);
        let left = g.raycast(x, y, std::f64::consts::PI, 10.0);
        let down = g.raycast(x, y, -std::f64::consts::FRAC_PI_2, 10.0);
        assert!((right - 2.4).abs() < 1e-9, "{right}");
        assert!((up - 1.4).abs() < 1e-9, "{up}");
        assert!((left - 1.4).abs() < 1e-9, "{left}");
        assert!((down - 1.4).abs() < 1e-9, "{down}");
        assert_eq!(g.raycast(x, y, 0.3, 0.5), 0.5, "max range");
        assert_eq!(g.raycast(-0.95, 0.0, 0.0, 3.0), 0.0, "inside a wall");
    }

    #[test]
    fn raycast_matches_a_fine_march() {
        let g = room();
        for k in 0..50 {
            let a = k as f64 * 0.1257;
            let d = g.raycast(0.33, 0.21, a, 10.0);
            // March in 1 mm steps.
            let mut s = 0.0;
            while s < 10.0 && !g.is_blocked(0.33 + s * a.cos(), 0.21 + s * a.sin()) {
                s += 0.001;
            }
            assert!((d - s).abs() < 0.0015, "angle {a}: dda {d} march {s}");
        }
    }

    #[test]
    fn outside_is_blocked_and_rows_are_bottom_up() {
        let g = OccupancyGrid::from_fn(3, 2, 1.0, [0.0, 0.0, 0.0], |c, r| c == 2 && r == 0);
        assert!(g.is_blocked(2.5, 0.5));
        assert!(!g.is_blocked(2.5, 1.5));
        assert!(g.is_blocked(-0.1, 0.5));
        assert!(g.is_blocked(0.5, 2.1));
        assert_eq!(g.cell_center(2, 0), (2.5, 0.5));
    }

    #[test]
    fn classify_follows_map_server() {
        let meta = MapMeta::parse(
            "image: x.png\nresolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
            Path::new("m.yaml"),
        )
        .unwrap();
        assert_eq!(meta.classify(0.0, 255.0), Cell::Occupied);
        assert_eq!(meta.classify(255.0, 255.0), Cell::Free);
        assert_eq!(meta.classify(205.0, 255.0), Cell::Unknown);
        assert_eq!(meta.classify(255.0, 0.0), Cell::Unknown);
        assert!(!meta.negate);
        assert_eq!(meta.mode, MapMode::Trinary);
    }
}
