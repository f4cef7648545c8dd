//! Drawings: the 64-trajectory lattice as an SVG (`host-sim lattice`).
//!
//! Cruise trajectories (actions 0–48, 1 m) are drawn in blue, creep trajectories (49–63,
//! 0.5 m) in orange, from the rear axle at the origin, x forward (right in the picture), y left
//! (up). The straight action 0 is drawn thicker.

use std::path::Path;

use anyhow::{Result, anyhow};
use firmware_core::ActionIndex;
use firmware_core::lattice::{Family, trajectory};
use plotters::prelude::*;

/// Draws the lattice into the SVG file `out`.
pub fn lattice_svg(out: &Path) -> Result<()> {
    let root = SVGBackend::new(out, (800, 800)).into_drawing_area();
    root.fill(&WHITE)
        .map_err(|e| anyhow!("{}: {e}", out.display()))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "firmware-core lattice: 64 trajectories (car frame)",
            ("sans-serif", 22),
        )
        .margin(20)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(-0.1f64..1.1f64, -0.6f64..0.6f64)
        .map_err(|e| anyhow!("{}: {e}", out.display()))?;
    chart
        .configure_mesh()
        .x_desc("x forward (m)")
        .y_desc("y left (m)")
        .draw()
        .map_err(|e| anyhow!("{}: {e}", out.display()))?;
    let cruise = RGBColor(31, 119, 180);
    let creep = RGBColor(255, 127, 14);
    for a in ActionIndex::all() {
        let t = trajectory(a);
        let mut pts = vec![(0.0, 0.0)];
        pts.extend(t.poses.iter().map(|p| (p.x as f64, p.y as f64)));
        let colour = if t.family == Family::Cruise {
            cruise
        } else {
            creep
        };
        let width = if a.get() == 0 { 3 } else { 1 };
        chart
            .draw_series(LineSeries::new(pts, colour.stroke_width(width)))
            .map_err(|e| anyhow!("{}: {e}", out.display()))?;
    }
    root.present()
        .map_err(|e| anyhow!("{}: {e}", out.display()))?;
    Ok(())
}
