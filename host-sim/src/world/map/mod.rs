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

/// `v.floor() as i64`, exactly (saturating, NaN to 0), without the call to a software `floor`
/// that the baseline x86-64 target (no SSE4.1) makes.
#[inline]
fn floor_to_int(v: f64) -> i64 {
    let i = v as i64;
    i.saturating_sub(i64::from((i as f64) > v))
}

/// One axis of a ray from grid coordinate `g`, in cell `cell`, along direction component `d`:
/// the step between cells (±1), the ray parameter between two crossings of the axis's cell
/// boundaries (infinite when `d` is 0), and the parameter of the first crossing.
#[inline]
fn axis_start(g: f64, cell: i64, d: f64) -> (i64, f64, f64) {
    let step = if d > 0.0 { 1 } else { -1 };
    let delta = if d != 0.0 {
        1.0 / d.abs()
    } else {
        f64::INFINITY
    };
    let first = if d > 0.0 {
        (cell as f64 + 1.0 - g) * delta
    } else if d < 0.0 {
        (g - cell as f64) * delta
    } else {
        f64::INFINITY
    };
    (step, delta, first)
}

/// A world point in a grid's coordinates, with its cell's clearance
/// ([`OccupancyGrid::viewpoint`]).
#[derive(Clone, Copy, Debug)]
pub struct Viewpoint {
    gx: f64,
    gy: f64,
    /// The point's cell.
    cx: i64,
    cy: i64,
    /// The cell's index in the padded clearance (0, a cell of the ring, outside the grid).
    at: usize,
    clearance: u16,
}

impl Viewpoint {
    /// [`OccupancyGrid::clearance_cells`] of the point.
    pub fn clearance_cells(&self) -> u16 {
        self.clearance
    }
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
    /// Stored with a ring of zeros around the grid (rows of `width + 2`, cell `(c, r)` at
    /// `(c + 1, r + 1)`), so that a ray cast, which never moves more than one cell beyond the free
    /// square it leaves, stays on the array without checking its bounds ([`Self::padded`]).
    clearance: Vec<u16>,
    /// `width` and `height` as `f64` (what [`Self::padded_at`] compares grid coordinates with).
    extent: [f64; 2],
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
        let unpadded = chebyshev_clearance(width, height, &cells);
        let mut clearance = vec![0u16; (width + 2) * (height + 2)];
        for (r, row) in unpadded.chunks_exact(width.max(1)).enumerate() {
            let at = (r + 1) * (width + 2) + 1;
            clearance[at..at + width].copy_from_slice(row);
        }
        Self {
            width,
            height,
            resolution,
            origin,
            cos_yaw: libm::cos(origin[2]),
            sin_yaw: libm::sin(origin[2]),
            cells,
            clearance,
            extent: [width as f64, height as f64],
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
        // The hot path of collision checks.
        self.blocked_cell(floor_to_int(gx), floor_to_int(gy))
    }

    /// The Chebyshev distance, in cells, from the cell of the world point `(x, y)` to the
    /// nearest cell that is not free (0 when that cell itself is not free or outside the map).
    /// Every cell within `clearance_cells − 1` cells of it, along each axis, is free: a point
    /// less than `(clearance_cells − 1)·resolution` metres from `(x, y)` lies in a free cell.
    #[inline]
    pub fn clearance_cells(&self, x: f64, y: f64) -> u16 {
        let (gx, gy) = self.to_grid(x, y);
        let (cx, cy) = (floor_to_int(gx), floor_to_int(gy));
        self.padded(cx, cy).map_or(0, |i| self.clearance[i])
    }

    /// The index of cell `(cx, cy)` in the padded `clearance`; `None` outside the grid.
    #[inline]
    fn padded(&self, cx: i64, cy: i64) -> Option<usize> {
        if cx < 0 || cy < 0 || cx as usize >= self.width || cy as usize >= self.height {
            return None;
        }
        Some((cy as usize + 1) * (self.width + 2) + cx as usize + 1)
    }

    /// [`Self::padded`] of the cell of grid point `(x, y)`: the same index for every `x` and `y`
    /// but NaN (which `floor_to_int` puts in cell 0). A coordinate lies in a cell of the grid
    /// (its floor in `0..width`) exactly when it is in `[0, width)`, and there its floor is its
    /// truncation: two comparisons a coordinate instead of `floor_to_int`'s saturating conversion,
    /// its correction and the bounds checks. (Truncated through `i64`, whose saturating
    /// conversion costs fewer instructions than `usize`'s; a side is at most
    /// [`MAX_IMAGE_SIDE`] cells.)
    #[inline(always)]
    fn padded_at(&self, x: f64, y: f64) -> Option<usize> {
        let [w, h] = self.extent;
        if x >= 0.0 && y >= 0.0 && x < w && y < h {
            Some((y as i64 as usize + 1) * (self.width + 2) + x as i64 as usize + 1)
        } else {
            None
        }
    }

    /// Distance from `(x, y)` along heading `angle` (world frame, radians) to the first cell
    /// that is not free, at most `max_range`. A ray starting in a blocked cell returns 0.
    ///
    /// Amanatides–Woo traversal, skipping free space: in a cell of clearance `c` every cell
    /// within `c − 1` cells along each axis is free, so the ray leaves that square in one jump to
    /// the cell the traversal would step into next, instead of one step per cell. The crossing
    /// times of a jump are computed in closed form (`t + k·Δt`) where the cell-by-cell traversal
    /// adds `Δt` `k` times: the distances agree to rounding (about 10⁻¹⁵ m, far below the
    /// sensor's 1 cm quantization; `raycast_agrees_with_the_cell_by_cell_traversal` checks
    /// every beam of many poses on every map).
    pub fn raycast(&self, x: f64, y: f64, angle: f64, max_range: f64) -> f64 {
        let a = angle - self.origin[2];
        self.cast(&self.viewpoint(x, y), libm::cos(a), libm::sin(a), max_range)
    }

    /// [`OccupancyGrid::raycast`] along the unit vector `(dx, dy)` (world frame) instead of an
    /// angle: no trigonometry per ray when the caller rotates directions it knows (the scan's
    /// beams by the car's heading). The same distance as `raycast` at the vector's angle, to
    /// rounding.
    pub fn raycast_along(&self, x: f64, y: f64, along: (f64, f64), max_range: f64) -> f64 {
        let (gdx, gdy) = self.grid_direction(along);
        self.cast(&self.viewpoint(x, y), gdx, gdy, max_range)
    }

    /// The unit vector `(dx, dy)` of the world frame in the grid's (turned by the origin's yaw).
    #[inline]
    pub(crate) fn grid_direction(&self, (dx, dy): (f64, f64)) -> (f64, f64) {
        (
            dx * self.cos_yaw + dy * self.sin_yaw,
            -dx * self.sin_yaw + dy * self.cos_yaw,
        )
    }

    /// The traversal of [`OccupancyGrid::raycast`] from `view` along the unit vector `(dx, dy)`
    /// (grid frame). The start's cell, its index and its clearance come with the view, computed
    /// once for every ray from it.
    fn cast(&self, view: &Viewpoint, dx: f64, dy: f64, max_range: f64) -> f64 {
        let Viewpoint {
            gx,
            gy,
            cx,
            cy,
            mut at,
            clearance: mut c,
        } = *view;
        // Outside the grid or in a blocked cell: 0. Otherwise every move below is to a neighbour
        // of the free square around the cell, on the array (its ring at worst, which is 0 and
        // ends it).
        if c == 0 {
            return 0.0;
        }
        let max_t = max_range / self.resolution;
        let (step_x, t_delta_x, mut t_max_x) = axis_start(gx, cx, dx);
        let (step_y, t_delta_y, mut t_max_y) = axis_start(gy, cy, dy);
        let row = step_y as isize * (self.width + 2) as isize;
        let step_x = step_x as isize;
        let (abs_x, abs_y) = (dx.abs(), dy.abs());
        loop {
            let t = if c >= 2 {
                // The square of cells within r = c − 1 of the cell is free: the traversal
                // crosses r more boundaries on the axis it leaves the square by, and steps into
                // the cell beyond; on the other axis it crosses every boundary before that (a tie
                // steps the row first, as below). Never more than r: the square is left once.
                let r = c as isize - 1;
                let rf = r as f64;
                let out_x = t_max_x + rf * t_delta_x;
                let out_y = t_max_y + rf * t_delta_y;
                let (moved, t) = if out_x < out_y {
                    let mut moved = step_x * (r + 1);
                    if t_max_y <= out_x {
                        let rows = ((((out_x - t_max_y) * abs_y) as isize) + 1).min(r);
                        moved += row * rows;
                        t_max_y += rows as f64 * t_delta_y;
                    }
                    t_max_x = out_x + t_delta_x;
                    (moved, out_x)
                } else {
                    let mut moved = row * (r + 1);
                    if t_max_x < out_y {
                        // The crossings strictly before out_y: ⌈q⌉ for q > 0.
                        let q = (out_y - t_max_x) * abs_x;
                        let whole = q as isize;
                        let columns = (whole + isize::from((whole as f64) < q)).min(r);
                        moved += step_x * columns;
                        t_max_x += columns as f64 * t_delta_x;
                    }
                    t_max_y = out_y + t_delta_y;
                    (moved, out_y)
                };
                at = at.wrapping_add_signed(moved);
                t
            } else if t_max_x < t_max_y {
                let t = t_max_x;
                t_max_x += t_delta_x;
                at = at.wrapping_add_signed(step_x);
                t
            } else {
                let t = t_max_y;
                t_max_y += t_delta_y;
                at = at.wrapping_add_signed(row);
                t
            };
            if t >= max_t {
                return max_range;
            }
            c = self.clearance.get(at).copied().unwrap_or(0);
            if c == 0 {
                return t * self.resolution;
            }
        }
    }

    /// Whether the straight segment from `a` to `b` crosses no blocked cell before the last
    /// `slack` metres (the end may lie in or on a blocked object).
    pub fn line_of_sight(&self, a: (f64, f64), b: (f64, f64), slack: f64) -> bool {
        self.line_of_sight_from(&self.viewpoint(a.0, a.1), a, b, slack)
    }

    /// [`OccupancyGrid::line_of_sight`] with `a`'s viewpoint given (`self.viewpoint(a.0, a.1)`,
    /// computed once for every segment from `a`): the same answer.
    pub fn line_of_sight_from(
        &self,
        view: &Viewpoint,
        a: (f64, f64),
        b: (f64, f64),
        slack: f64,
    ) -> bool {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len = libm::sqrt(dx * dx + dy * dy);
        let reach = len - slack;
        if reach <= 0.0 {
            return true;
        }
        let along = (dx / len, dy / len);
        // Free a cell beyond the reach: the cast would end at the reach (no cast needed). One
        // viewpoint for both.
        let along = self.grid_direction(along);
        self.free_by_points_in_grid(view, along, (reach + self.resolution) / self.resolution, 2)
            || self.raycast_in_grid(view, along, reach) >= reach
    }

    /// Whether every point of the segment from `(x, y)` along the unit vector `(dx, dy)` (world
    /// frame) for `length` metres lies in a free cell, as far as the clearance of its two ends
    /// tells (`false` when it does not settle it): a point less than `c − 1` cells from an end
    /// along each axis (Chebyshev) lies in a free cell when that end's cell has clearance `c`, and
    /// the Chebyshev distances of a point of the segment to its ends sum to the segment's
    /// Chebyshev length, so the segment is covered when that length is below
    /// `(c_start − 1) + (c_end − 1)` (with a 10⁻⁶ cell margin for rounding). A cast along a
    /// segment this says is free, of at most `length − resolution`, reaches its end: the first
    /// blocked cell is entered at least `length` away.
    pub fn free_by_its_ends(&self, x: f64, y: f64, along: (f64, f64), length: f64) -> bool {
        self.free_from(&self.viewpoint(x, y), along, length)
    }

    /// The world point `(x, y)` as rays start from it: its grid coordinates and its cell's
    /// clearance, computed once for all the rays of a scan.
    #[inline]
    pub fn viewpoint(&self, x: f64, y: f64) -> Viewpoint {
        let (gx, gy) = self.to_grid(x, y);
        let (cx, cy) = (floor_to_int(gx), floor_to_int(gy));
        let (at, clearance) = self
            .padded(cx, cy)
            .map_or((0, 0), |i| (i, self.clearance[i]));
        Viewpoint {
            gx,
            gy,
            cx,
            cy,
            at,
            clearance,
        }
    }

    /// [`OccupancyGrid::raycast_along`] from `view` (the same distance, bit for bit).
    #[inline]
    pub fn raycast_from(&self, view: &Viewpoint, along: (f64, f64), max_range: f64) -> f64 {
        self.raycast_in_grid(view, self.grid_direction(along), max_range)
    }

    /// [`OccupancyGrid::raycast_from`] along `along` turned into the grid's frame already
    /// ([`OccupancyGrid::grid_direction`]): the same distance, bit for bit.
    #[inline]
    pub(crate) fn raycast_in_grid(
        &self,
        view: &Viewpoint,
        (gdx, gdy): (f64, f64),
        max_range: f64,
    ) -> f64 {
        self.cast(view, gdx, gdy, max_range)
    }

    /// Whether every point of the segment from `view` along the unit vector `along` (world frame)
    /// for `length` metres lies in a free cell, as far as the clearance of its start and of
    /// `points` points spread evenly after it (the last at its end) tells (`false` when they do
    /// not settle it): [`OccupancyGrid::free_by_its_ends`] with points between the ends too. Their
    /// cells are read independently of each other, not one after another as a cast reads.
    ///
    /// Measured by `σ`, the Chebyshev distance from the start along the segment (in cells), a
    /// point at `σᵢ` whose cell has clearance `cᵢ` shows every point of the segment within
    /// `cᵢ − 1` of it (open) free, as in `free_by_its_ends`. Going from the start (`[0, c₀ − 1)`
    /// free), each point's interval must begin below the end of the free stretch so far (10⁻⁶
    /// cells of margin on each side, far above the rounding of the points' coordinates) and
    /// extends it; the segment is free when the stretch passes its end. As for
    /// `free_by_its_ends`, a cast along a segment this says is free, of at most
    /// `length − resolution`, reaches its end.
    ///
    /// Always inlined: its callers pass a constant `points`, and each point's fraction of the
    /// length (`i / points`) is then a constant too, the loop unrolled (the same numbers).
    #[inline(always)]
    pub fn free_by_points_from(
        &self,
        view: &Viewpoint,
        along: (f64, f64),
        length: f64,
        points: u32,
    ) -> bool {
        self.free_by_points_in_grid(
            view,
            self.grid_direction(along),
            length / self.resolution,
            points,
        )
    }

    /// [`OccupancyGrid::free_by_points_from`] along `along` turned into the grid's frame
    /// already, for `cells = length / resolution` cells: the same answer, for a caller that
    /// computes the direction and the length in cells once (the scan's beams, whose lengths do
    /// not change from tick to tick).
    #[inline(always)]
    pub(crate) fn free_by_points_in_grid(
        &self,
        view: &Viewpoint,
        (gdx, gdy): (f64, f64),
        cells: f64,
        points: u32,
    ) -> bool {
        const MARGIN: f64 = 1.0e-6;
        let start = f64::from(view.clearance);
        if start < 2.0 || points == 0 {
            return false;
        }
        // The greater of two numbers as `f64::max` gives it when neither is NaN, without its
        // NaN handling: a NaN direction puts every point outside the grid (`padded_at` is
        // `None` for NaN), which settles nothing before `m` or `free` is read.
        let greater = |a: f64, b: f64| if a > b { a } else { b };
        let m = greater(gdx.abs(), gdy.abs());
        // The free stretch so far: σ in [0, free).
        let mut free = start - 1.0;
        for i in 1..=points {
            let at = cells * (f64::from(i) / f64::from(points));
            let (x, y) = (view.gx + gdx * at, view.gy + gdy * at);
            let c = self
                .padded_at(x, y)
                .map_or(0.0, |i| f64::from(self.clearance[i]));
            let sigma = at * m;
            if c < 1.0 || sigma - (c - 1.0) + MARGIN >= free - MARGIN {
                return false;
            }
            free = greater(free, sigma + (c - 1.0));
        }
        free > cells * m + MARGIN
    }

    /// [`OccupancyGrid::free_by_its_ends`] from `view`.
    #[inline]
    pub fn free_from(&self, view: &Viewpoint, along: (f64, f64), length: f64) -> bool {
        let start = f64::from(view.clearance);
        if start < 2.0 {
            return false;
        }
        let (gdx, gdy) = self.grid_direction(along);
        let cells = length / self.resolution;
        let (ex, ey) = (view.gx + gdx * cells, view.gy + gdy * cells);
        let end = self
            .padded_at(ex, ey)
            .map_or(0.0, |i| f64::from(self.clearance[i]));
        cells * gdx.abs().max(gdy.abs()) + 1.0e-6 < (start - 1.0) + (end - 1.0)
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
                let got = g.padded(c, r).map_or(0, |i| g.clearance[i]) as i64;
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

    /// The cell-by-cell Amanatides–Woo traversal `raycast` replaced (one step and one
    /// `Δt` added per cell crossed).
    fn raycast_cell_by_cell(g: &OccupancyGrid, x: f64, y: f64, angle: f64, max_range: f64) -> f64 {
        let (gx, gy) = g.to_grid(x, y);
        let a = angle - g.origin[2];
        let (dx, dy) = (libm::cos(a), libm::sin(a));
        let mut cx = gx.floor() as i64;
        let mut cy = gy.floor() as i64;
        if g.blocked_cell(cx, cy) {
            return 0.0;
        }
        let max_t = max_range / g.resolution;
        let (step_x, t_delta_x, mut t_max_x) = axis_start(gx, cx, dx);
        let (step_y, t_delta_y, mut t_max_y) = axis_start(gy, cy, dy);
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
            if g.blocked_cell(cx, cy) {
                return t * g.resolution;
            }
        }
    }

    #[test]
    fn floor_to_int_is_floor() {
        for v in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.9999999999999996,
            -2.0000000000000004,
            1e300,
            -1e300,
            9.3e18,
            -9.3e18,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            4503599627370497.0,
        ] {
            assert_eq!(floor_to_int(v), v.floor() as i64, "{v}");
        }
        let mut x = 0x0123_4567_89AB_CDEFu64;
        for _ in 0..100_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let v = (x as i64) as f64 / (1u64 << (x % 60)) as f64;
            assert_eq!(floor_to_int(v), v.floor() as i64, "{v}");
        }
    }

    #[test]
    fn padded_at_is_padded_of_the_floor() {
        let g = room();
        let (w, h) = (g.width() as f64, g.height() as f64);
        let mut edges = vec![0.0, -0.0, 1e300, -1e300, f64::INFINITY, f64::NEG_INFINITY];
        for v in [w, h] {
            for d in [-1.0, 0.0, 1.0] {
                edges.push(v + d);
                edges.push(f64::from_bits((v + d).to_bits() - 1));
                edges.push(f64::from_bits((v + d).to_bits() + 1));
            }
        }
        edges.extend([1.0e-300, -1.0e-300, 0.5, -0.5, -1.0, 2.9999999999999996]);
        let mut x = 0x0123_4567_89AB_CDEFu64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x % 1_000_000) as f64 / 1_000_000.0 * (w + 4.0) - 2.0
        };
        let random: Vec<f64> = (0..20_000).map(|_| next()).collect();
        for (&a, &b) in edges
            .iter()
            .flat_map(|a| edges.iter().map(move |b| (a, b)))
            .chain(random.iter().zip(random.iter().skip(1)))
        {
            assert_eq!(
                g.padded_at(a, b),
                g.padded(floor_to_int(a), floor_to_int(b)),
                "{a} {b}"
            );
        }
    }

    #[test]
    fn raycast_agrees_with_the_cell_by_cell_traversal() {
        use crate::world::registry::{SCENARIOS, load_scenario_unchecked};
        use crate::world::sim::SENSOR_RANGE;
        use firmware_core::observation::{SCAN_BEAMS, SCAN_MAX_RANGE, beam_bearing};
        let mut grids = vec![std::sync::Arc::new(room())];
        for s in SCENARIOS {
            grids.push(load_scenario_unchecked(s.name).unwrap().map);
        }
        let (mut rays, mut jumped) = (0u64, 0u64);
        let mut uniform = crate::world::test_uniform(0x9E37_79B9_7F4A_7C15);
        for g in &grids {
            let (w, h) = (
                g.width() as f64 * g.resolution(),
                g.height() as f64 * g.resolution(),
            );
            let o = g.origin();
            for _ in 0..3000 {
                let (x, y) = (o[0] + uniform() * w, o[1] + uniform() * h);
                if g.is_blocked(x, y) {
                    continue;
                }
                let theta = (uniform() - 0.5) * 2.0 * std::f64::consts::PI;
                // The beams, and the axes and diagonals (a direction along an axis has a zero
                // component).
                // The direction as the sensing turns it: the beam's unit vector by the heading.
                let (s, c) = (libm::sin(theta), libm::cos(theta));
                let along = |b: f64| {
                    let (bc, bs) = (libm::cos(b), libm::sin(b));
                    (c * bc - s * bs, s * bc + c * bs)
                };
                let axes = (0..8).map(|k| (0.0, k as f64 * std::f64::consts::FRAC_PI_4));
                let beams = (0..SCAN_BEAMS).map(|j| (theta, beam_bearing(j) as f64));
                for (heading, b) in beams.chain(axes) {
                    let a = heading + b;
                    for range in [SCAN_MAX_RANGE as f64, SENSOR_RANGE] {
                        let want = raycast_cell_by_cell(g, x, y, a, range);
                        let by_angle = g.raycast(x, y, a, range);
                        let by_vector = if heading == 0.0 {
                            g.raycast_along(x, y, (libm::cos(b), libm::sin(b)), range)
                        } else {
                            g.raycast_along(x, y, along(b), range)
                        };
                        // What the car is sent: centimetres of the f32 range.
                        let cm = |r: f64| ((r as f32).min(SCAN_MAX_RANGE) * 100.0).round();
                        for got in [by_angle, by_vector] {
                            assert!(
                                (got - want).abs() <= 1e-12 * want.max(1.0),
                                "{}: ({x}, {y}) at {a}: {got} against {want}",
                                g.source().display()
                            );
                            assert_eq!(cm(got), cm(want), "({x}, {y}) at {a}");
                        }
                        rays += 1;
                        jumped += u64::from(g.clearance_cells(x, y) >= 2);
                    }
                }
            }
        }
        assert!(
            rays > 1_000_000 && jumped > rays / 2,
            "{rays} rays, {jumped} jumped"
        );
    }

    /// The room, a grid turned by its origin's yaw with a wall to pass (the segment tests work in
    /// the grid's frame) and every built-in scenario's map.
    fn segment_test_grids() -> Vec<std::sync::Arc<OccupancyGrid>> {
        use crate::world::registry::{SCENARIOS, load_scenario_unchecked};
        let mut grids = vec![std::sync::Arc::new(room())];
        grids.push(std::sync::Arc::new(OccupancyGrid::from_fn(
            80,
            60,
            0.05,
            [1.0, -2.0, 0.7],
            |c, r| c == 0 || r == 0 || c == 79 || r == 59 || (c == 40 && r < 35),
        )));
        for s in SCENARIOS {
            grids.push(load_scenario_unchecked(s.name).unwrap().map);
        }
        grids
    }

    /// A segment of the segment tests: a start uniform over the grid's rectangle, a direction
    /// `a` (and its unit vector) uniform over the circle, a length of 0.05 to 3.05 m.
    fn random_segment(
        g: &OccupancyGrid,
        uniform: &mut impl FnMut() -> f64,
    ) -> (f64, f64, f64, (f64, f64), f64) {
        let (w, h, o) = (
            g.width() as f64 * g.resolution(),
            g.height() as f64 * g.resolution(),
            g.origin(),
        );
        let (yc, ys) = (libm::cos(o[2]), libm::sin(o[2]));
        let (u, v) = (uniform() * w, uniform() * h);
        let (x, y) = (o[0] + u * yc - v * ys, o[1] + u * ys + v * yc);
        let a = (uniform() - 0.5) * 2.0 * std::f64::consts::PI;
        let along = (libm::cos(a), libm::sin(a));
        let length = 0.05 + uniform() * 3.0;
        (x, y, a, along, length)
    }

    #[test]
    fn a_segment_free_by_its_ends_is_one_every_cast_along_it_crosses() {
        let grids = segment_test_grids();
        let mut uniform = crate::world::test_uniform(0x2545_F491_4F6C_DD1D);
        let (mut free, mut tried) = (0u64, 0u64);
        for g in &grids {
            for _ in 0..20_000 {
                let (x, y, a, along, length) = random_segment(g, &mut uniform);
                tried += 1;
                if !g.free_by_its_ends(x, y, along, length) {
                    continue;
                }
                free += 1;
                let reach = length - g.resolution();
                assert_eq!(
                    g.raycast_along(x, y, along, reach),
                    reach,
                    "({x}, {y}) at {a}"
                );
                assert!(raycast_cell_by_cell(g, x, y, a, reach) >= reach - 1e-9);
                // Every point of it, a millimetre apart, is in a free cell.
                let mut s = 0.0;
                while s <= length {
                    assert!(
                        !g.is_blocked(x + s * along.0, y + s * along.1),
                        "{s} m along"
                    );
                    s += 0.001;
                }
            }
        }
        assert!(free > tried / 10 && free < tried, "{free} of {tried}");
    }

    #[test]
    fn a_segment_free_by_its_points_is_one_every_cast_along_it_crosses() {
        let grids = segment_test_grids();
        let mut uniform = crate::world::test_uniform(0x2545_F491_4F6C_DD1D);
        // Per number of points: segments said free, and those the ends alone do not settle.
        let mut free = [0u64; 5];
        let mut beyond_the_ends = [0u64; 5];
        let mut tried = 0u64;
        for g in &grids {
            for _ in 0..20_000 {
                let (x, y, a, along, length) = random_segment(g, &mut uniform);
                let view = g.viewpoint(x, y);
                tried += 1;
                let ends = g.free_from(&view, along, length);
                for points in 1..5u32 {
                    if !g.free_by_points_from(&view, along, length, points) {
                        continue;
                    }
                    free[points as usize] += 1;
                    beyond_the_ends[points as usize] += u64::from(!ends);
                    let reach = length - g.resolution();
                    assert_eq!(
                        g.raycast_from(&view, along, reach),
                        reach,
                        "({x}, {y}) at {a}, {points} points"
                    );
                    assert!(raycast_cell_by_cell(g, x, y, a, reach) >= reach - 1e-9);
                    // Every point of it, a millimetre apart, is in a free cell.
                    let mut s = 0.0;
                    while s <= length {
                        assert!(
                            !g.is_blocked(x + s * along.0, y + s * along.1),
                            "{s} m along, {points} points"
                        );
                        s += 0.001;
                    }
                }
            }
        }
        assert!(
            free[1] > tried / 10 && free[4] < tried && beyond_the_ends[2] > tried / 20,
            "{tried} tried: {free:?} free, {beyond_the_ends:?} beyond the ends"
        );
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
