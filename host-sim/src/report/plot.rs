//! Drawings: the 64-trajectory lattice as an SVG (`host-sim lattice`), and a scenario's map with
//! its path, objects and a run's poses on a [`Raster`] (`host-sim draw`, [`MapDrawing`]).
//!
//! # The lattice drawing
//!
//! Cruise trajectories (actions 0–48, 1 m) are drawn in blue, creep trajectories (49–63,
//! 0.5 m) in orange, from the rear axle at the origin, x forward (right in the picture), y left
//! (up); a legend names the two. The straight action 0 is drawn thicker.

use std::path::Path;

use anyhow::{Result, anyhow};
use firmware_core::ActionIndex;
use firmware_core::lattice::{Family, trajectory};
use nalgebra::{Point2, Vector2};
use plotters::prelude::*;

use super::raster::Raster;

/// Draws the lattice into the SVG file `out`, with a legend of its two families.
pub fn lattice_svg(out: &Path) -> Result<()> {
    let e = |e: DrawingAreaErrorKind<std::io::Error>| anyhow!("{}: {e}", out.display());
    let root = SVGBackend::new(out, (800, 800)).into_drawing_area();
    root.fill(&WHITE).map_err(e)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "firmware-core lattice: 64 trajectories (car frame)",
            ("sans-serif", 22),
        )
        .margin(20)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(-0.1f64..1.1f64, -0.6f64..0.6f64)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("x forward (m)")
        .y_desc("y left (m)")
        .x_label_formatter(&axis_label)
        .y_label_formatter(&axis_label)
        .draw()
        .map_err(e)?;
    let cruise = RGBColor(31, 119, 180);
    let creep = RGBColor(255, 127, 14);
    for family in [Family::Cruise, Family::Creep] {
        let colour = if family == Family::Cruise {
            cruise
        } else {
            creep
        };
        let actions: Vec<ActionIndex> = ActionIndex::all()
            .filter(|&a| trajectory(a).family == family)
            .collect();
        for (k, &a) in actions.iter().enumerate() {
            let t = trajectory(a);
            let mut pts = vec![(0.0, 0.0)];
            pts.extend(t.poses().iter().map(|p| (p.x as f64, p.y as f64)));
            let width = if a.get() == 0 { 3 } else { 1 };
            let series = chart
                .draw_series(LineSeries::new(pts, colour.stroke_width(width)))
                .map_err(e)?;
            // One legend entry per family, with its actions, length and speed.
            if k == 0 {
                let (first, last) = (actions[0].get(), actions[actions.len() - 1].get());
                let name = match family {
                    Family::Cruise => "cruise",
                    Family::Creep => "creep",
                };
                let which = if last - first + 1 == actions.len() {
                    format!("actions {first}–{last}")
                } else {
                    format!("{} actions", actions.len())
                };
                series
                    .label(format!(
                        "{name}: {which}, {:.1} m at {:.1} m/s",
                        t.length(),
                        t.speed
                    ))
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
                    });
            }
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()
        .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}

/// An axis label with one decimal, and 0 for the values that round to it (never `-0.0`).
fn axis_label(v: &f64) -> String {
    let s = format!("{v:.1}");
    if s == "-0.0" { "0.0".into() } else { s }
}

/// A scenario's map drawn on a [`Raster`] with its path, objects and start, and optionally a
/// driven trajectory (`host-sim draw`): free cells white, occupied black, unknown grey; the path
/// blue, doors brown, stairs red, chairs green, the driven poses orange, the start magenta.
#[derive(Clone, Debug)]
pub struct MapDrawing {
    raster: Raster,
    /// Pixels per map cell.
    scale: usize,
    grid: std::sync::Arc<crate::world::map::OccupancyGrid>,
}

const PATH_BLUE: [u8; 3] = [30, 100, 230];
const DRIVEN: [u8; 3] = [255, 140, 0];

impl MapDrawing {
    /// The map of `scenario` with its path, objects and start drawn, at most about 1000 pixels
    /// wide.
    pub fn of_scenario(scenario: &crate::world::scenario::Scenario) -> Self {
        Self::of_scenario_within(scenario, 1000)
    }

    /// The same, at the largest whole number of pixels per cell (1 to 8) that keeps it at most
    /// `max_width` pixels wide (at least one pixel per cell).
    pub fn of_scenario_within(
        scenario: &crate::world::scenario::Scenario,
        max_width: usize,
    ) -> Self {
        let scale = (max_width / scenario.map.width().max(1)).clamp(1, 8);
        Self::of_scenario_scaled(scenario, scale)
    }

    /// The largest whole number of pixels per cell (1 to 8) that keeps every one of `scenarios`
    /// at most `max_width` pixels wide: drawing them all at it gives one scale for all.
    pub fn common_scale(
        scenarios: &[&crate::world::scenario::Scenario],
        max_width: usize,
    ) -> usize {
        let widest = scenarios.iter().map(|s| s.map.width()).max().unwrap_or(1);
        (max_width / widest.max(1)).clamp(1, 8)
    }

    /// Metres per pixel of a scenario drawn at `scale` pixels per cell.
    pub fn metres_per_pixel(scenario: &crate::world::scenario::Scenario, scale: usize) -> f64 {
        scenario.map.resolution() / scale.max(1) as f64
    }

    /// The map of `scenario` at `scale` pixels per cell (1 to 8).
    pub fn of_scenario_scaled(scenario: &crate::world::scenario::Scenario, scale: usize) -> Self {
        use crate::world::map::Cell;
        let grid = scenario.map.clone();
        let scale = scale.clamp(1, 8);
        let (width, height) = (grid.width() * scale, grid.height() * scale);
        let mut r = Self {
            raster: Raster::new(width, height, [0, 0, 0]),
            scale,
            grid,
        };
        for row in 0..r.grid.height() {
            for col in 0..r.grid.width() {
                let c = match r.grid.cell(col, row) {
                    Some(Cell::Free) => [255, 255, 255],
                    Some(Cell::Occupied) => [0, 0, 0],
                    _ => [180, 180, 180],
                };
                for dy in 0..scale {
                    for dx in 0..scale {
                        let px = col * scale + dx;
                        let py = (r.grid.height() - 1 - row) * scale + dy;
                        r.raster.put(px as i64, py as i64, c);
                    }
                }
            }
        }
        for o in &scenario.objects {
            let colour = match o.class {
                firmware_core::observation::SemanticClass::Door => [150, 90, 30],
                firmware_core::observation::SemanticClass::Stairs => [220, 30, 30],
                firmware_core::observation::SemanticClass::Chair => [30, 170, 60],
            };
            r.fill_object(o, colour);
        }
        let pts = scenario.path.points();
        let n = pts.len();
        let segs = if scenario.path.is_closed() { n } else { n - 1 };
        for i in 0..segs {
            r.line(pts[i], pts[(i + 1) % n], PATH_BLUE);
        }
        let st = scenario.start;
        r.disc(st.position(), 0.15, [220, 0, 220]);
        r
    }

    /// The pixel (column, row from the top) of the world point `p`.
    pub fn to_px(&self, p: Point2<f64>) -> (i64, i64) {
        let (x, y) = (p.x, p.y);
        // Map yaw is ignored in drawings (all shipped maps have yaw 0).
        let o = self.grid.origin();
        let res = self.grid.resolution() / self.scale as f64;
        let px = ((x - o[0]) / res).floor() as i64;
        let py = self.raster.size().1 as i64 - 1 - ((y - o[1]) / res).floor() as i64;
        (px, py)
    }

    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        self.raster.put(x, y, c);
    }

    fn line(&mut self, a: Point2<f64>, b: Point2<f64>, c: [u8; 3]) {
        let (x0, y0) = self.to_px(a);
        let (x1, y1) = self.to_px(b);
        let n = (x1 - x0).abs().max((y1 - y0).abs()).max(1);
        for k in 0..=n {
            let x = x0 + (x1 - x0) * k / n;
            let y = y0 + (y1 - y0) * k / n;
            self.put(x, y, c);
            self.put(x + 1, y, c);
            self.put(x, y + 1, c);
        }
    }

    fn disc(&mut self, p: Point2<f64>, radius: f64, c: [u8; 3]) {
        let res = self.grid.resolution() / self.scale as f64;
        let r = (radius / res).ceil() as i64;
        let (cx, cy) = self.to_px(p);
        for dy in -r..=r {
            for dx in -r..=r {
                if dx * dx + dy * dy <= r * r {
                    self.put(cx + dx, cy + dy, c);
                }
            }
        }
    }

    fn fill_object(&mut self, o: &crate::world::scenario::WorldObject, c: [u8; 3]) {
        use crate::world::scenario::Shape;
        match o.shape {
            Shape::Disc { radius } => self.disc(o.centre, radius, c),
            Shape::Rect { width, height, yaw } => {
                let res = self.grid.resolution() / self.scale as f64 / 2.0;
                let rotation = crate::world::car::rotation(yaw);
                let (nu, nv) = ((width / res) as i64, (height / res) as i64);
                for i in 0..=nu {
                    for j in 0..=nv {
                        let u = -width / 2.0 + width * i as f64 / nu.max(1) as f64;
                        let v = -height / 2.0 + height * j as f64 / nv.max(1) as f64;
                        let (px, py) = self.to_px(o.centre + rotation * Vector2::new(u, v));
                        self.put(px, py, c);
                    }
                }
            }
        }
    }

    /// Draws a polyline through `points` (world frame), two pixels thick.
    pub fn polyline(&mut self, points: &[Point2<f64>], c: [u8; 3]) {
        for w in points.windows(2) {
            self.line(w[0], w[1], c);
        }
    }

    /// The drawing.
    pub fn raster(&self) -> &Raster {
        &self.raster
    }

    /// The drawing, handed over.
    pub fn into_raster(self) -> Raster {
        self.raster
    }

    /// Marks driven positions (world frame).
    pub fn trace(&mut self, points: &[Point2<f64>]) {
        for &p in points {
            let (px, py) = self.to_px(p);
            for d in [(0, 0), (1, 0), (0, 1), (-1, 0), (0, -1)] {
                self.put(px + d.0, py + d.1, DRIVEN);
            }
        }
    }

    /// Its size in pixels: width, height.
    pub fn size(&self) -> (usize, usize) {
        self.raster.size()
    }

    /// Its pixels, RGB, row by row from the top.
    pub fn rgb(&self) -> &[u8] {
        self.raster.rgb()
    }

    /// Writes the drawing as a PNG file.
    pub fn write_png(&self, out: &Path) -> Result<()> {
        self.raster.write_png(out)
    }
}
