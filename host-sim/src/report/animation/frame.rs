//! What every frame draws on (its layout, inks, the map drawn twice, the loss strip) and one
//! frame's drawing.

use nalgebra::Point2;

use super::canvas::Canvas;
use super::{INSET_AHEAD, INSET_METRES, TRAIL};
use crate::report::plot::MapDrawing;
use crate::report::run_folder::StepRow;
use crate::world::car::CarParams;

/// Where a frame's parts are, in pixels.
pub(super) struct Layout {
    pub(super) width: usize,
    pub(super) height: usize,
    /// The map: its top, width and height.
    pub(super) map_y: usize,
    pub(super) map_w: usize,
    pub(super) map_h: usize,
    /// The close-up: its left edge and side.
    pub(super) inset_x: usize,
    pub(super) inset: usize,
    /// The strip: its top, the top of its bars and their height.
    pub(super) strip_y: usize,
    pub(super) bar_top: usize,
    pub(super) bar_h: usize,
}

/// The indices of the colours drawn over the map.
pub(super) struct Inks {
    pub(super) white: u8,
    pub(super) text: u8,
    pub(super) red: u8,
    pub(super) free: u8,
    pub(super) blocked: u8,
    pub(super) chosen: u8,
    pub(super) teacher: u8,
    pub(super) car: u8,
    pub(super) trail: u8,
    pub(super) behind: u8,
    pub(super) frame: u8,
}

/// What every frame draws on.
pub(super) struct Scene {
    pub(super) layout: Layout,
    pub(super) ink: Inks,
    pub(super) strip: Strip,
    pub(super) fine: Fine,
    /// The lattice's trajectories in the car's frame, each from the rear axle.
    pub(super) lattice: Vec<Vec<(f64, f64)>>,
    /// The map at the picture's scale.
    pub(super) raster: MapDrawing,
}

/// The map drawn finer for the close-up, as palette indices.
pub(super) struct Fine {
    pub(super) raster: MapDrawing,
    pub(super) width: i64,
    pub(super) height: i64,
    pub(super) px: Vec<u8>,
}

/// The latent-loss strip: one column per pixel, its ticks' largest latent loss.
pub(super) struct Strip {
    pub(super) top: f64,
    pub(super) loss: Vec<f64>,
    pub(super) corrected: Vec<bool>,
    pub(super) ticks: usize,
}

impl Strip {
    pub(super) fn new(ticks: &[StepRow], width: usize) -> Self {
        let mut loss = vec![0.0f64; width];
        let mut corrected = vec![false; width];
        for (k, r) in ticks.iter().enumerate() {
            let c = k * width / ticks.len();
            loss[c] = loss[c].max(r.latent_loss);
            corrected[c] |= r.corrected;
        }
        // The 95th percentile of the columns that have ticks, so one spike does not flatten
        // the rest.
        let mut sorted: Vec<f64> = loss.iter().copied().filter(|&x| x > 0.0).collect();
        sorted.sort_by(f64::total_cmp);
        let top = sorted
            .get((sorted.len() as f64 * 0.95) as usize)
            .or(sorted.last())
            .copied()
            .unwrap_or(1.0)
            .max(1e-6);
        Self {
            top,
            loss,
            corrected,
            ticks: ticks.len(),
        }
    }

    pub(super) fn column(&self, tick: usize, width: usize) -> usize {
        tick * width / self.ticks
    }

    pub(super) fn bar(&self, c: &mut Canvas, l: &Layout, col: usize, ink: u8) {
        let h = ((self.loss[col] / self.top).min(1.0) * l.bar_h as f64).round() as i64;
        let base = (l.bar_top + l.bar_h) as i64;
        c.rect(col as i64, base - h, col as i64 + 1, base, ink);
    }
}

/// One frame: ticks `k0..k1` of the animated span.
pub(super) struct Frame<'a> {
    pub(super) k0: usize,
    pub(super) k1: usize,
    pub(super) ticks: &'a [StepRow],
    /// The run's ticks before the span (for the reset count).
    pub(super) earlier: &'a [StepRow],
    /// The trajectories free at tick `k0`, one bit per action.
    pub(super) free: u64,
}

impl Frame<'_> {
    pub(super) fn draw(&self, c: &mut Canvas, scene: &Scene) {
        let Scene {
            layout: l,
            ink,
            strip,
            fine,
            lattice,
            raster,
        } = scene;
        let r = &self.ticks[self.k0];
        let span = &self.ticks[self.k0..self.k1];
        let corrected = span.iter().find(|t| t.corrected);
        let reset = span
            .iter()
            .find_map(|t| t.reset.as_deref())
            .filter(|&x| x != "path-end");

        // The strip behind the cursor, the corrections, the cursor.
        let cursor = strip.column(self.k0, l.width);
        for col in 0..=cursor {
            strip.bar(c, l, col, ink.behind);
            if strip.corrected[col] {
                let y = l.bar_top as i64;
                c.rect(col as i64, y - 2, col as i64 + 1, y + 2, ink.red);
            }
        }
        c.rect(
            cursor as i64,
            l.bar_top as i64,
            cursor as i64 + 1,
            l.height as i64,
            ink.text,
        );

        // The map: the trail, the chosen trajectory, the footprint, the close-up's square.
        c.clip_to(Some((0, l.map_y, l.map_w, l.map_h)));
        let map_px = |x: f64, y: f64| {
            let (px, py) = raster.to_px(Point2::new(x, y));
            (px as f64 + 0.5, (py + l.map_y as i64) as f64 + 0.5)
        };
        let trail = &self.ticks[self.k0.saturating_sub(TRAIL)..self.k0];
        for t in trail {
            let (x, y) = map_px(t.x, t.y);
            c.put(x as i64, y as i64, ink.trail);
        }
        let pose = |p: (f64, f64)| {
            let (s, co) = (r.theta.sin(), r.theta.cos());
            (r.x + p.0 * co - p.1 * s, r.y + p.0 * s + p.1 * co)
        };
        if let Some(a) = r.action {
            for w in lattice[a as usize].windows(2) {
                let (a, b) = (pose(w[0]), pose(w[1]));
                c.line(map_px(a.0, a.1), map_px(b.0, b.1), 2, ink.chosen);
            }
        }
        let car = CarParams::MUSHR;
        let (hl, hw) = (car.length / 2.0, car.width / 2.0);
        let corners: Vec<(f64, f64)> = [(-hl, -hw), (hl, -hw), (hl, hw), (-hl, hw)]
            .iter()
            .map(|&(u, v)| pose((car.center_offset + u, v)))
            .collect();
        let on_map: Vec<(f64, f64)> = corners.iter().map(|p| map_px(p.0, p.1)).collect();
        c.fill(&on_map, ink.car);
        let centre = pose((INSET_AHEAD, 0.0));
        let half = INSET_METRES / 2.0;
        let (a, b) = (
            map_px(centre.0 - half, centre.1 + half),
            map_px(centre.0 + half, centre.1 - half),
        );
        for (p, q) in [
            ((a.0, a.1), (b.0, a.1)),
            ((b.0, a.1), (b.0, b.1)),
            ((b.0, b.1), (a.0, b.1)),
            ((a.0, b.1), (a.0, a.1)),
        ] {
            c.line(p, q, 1, ink.frame);
        }

        c.clip_to(None);

        // The close-up: the map around the car, north up, and everything at its scale.
        let (ix, iy, n) = (l.inset_x as f64, l.map_y as f64, l.inset as f64);
        let ppm = n / INSET_METRES;
        let inset_px = |x: f64, y: f64| {
            (
                ix + n / 2.0 + (x - centre.0) * ppm,
                iy + n / 2.0 - (y - centre.1) * ppm,
            )
        };
        c.clip_to(Some((l.inset_x, l.map_y, l.inset, l.inset)));
        for j in 0..l.inset {
            for i in 0..l.inset {
                let wx = centre.0 + (i as f64 + 0.5 - n / 2.0) / ppm;
                let wy = centre.1 - (j as f64 + 0.5 - n / 2.0) / ppm;
                let (px, py) = fine.raster.to_px(Point2::new(wx, wy));
                let v = if px >= 0 && py >= 0 && px < fine.width && py < fine.height {
                    fine.px[(py * fine.width + px) as usize]
                } else {
                    ink.frame
                };
                c.put(l.inset_x as i64 + i as i64, (l.map_y + j) as i64, v);
            }
        }
        for t in trail {
            let (x, y) = inset_px(t.x, t.y);
            c.rect(
                x as i64 - 1,
                y as i64 - 1,
                x as i64 + 1,
                y as i64 + 1,
                ink.trail,
            );
        }
        let in_inset: Vec<(f64, f64)> = corners.iter().map(|p| inset_px(p.0, p.1)).collect();
        c.fill(&in_inset, ink.car);
        let polyline = |c: &mut Canvas, pts: &[(f64, f64)], thick: i64, i: u8| {
            for w in pts.windows(2) {
                let (a, b) = (pose(w[0]), pose(w[1]));
                c.line(inset_px(a.0, a.1), inset_px(b.0, b.1), thick, i);
            }
        };
        for (a, pts) in lattice.iter().enumerate() {
            if self.free >> a & 1 == 0 {
                polyline(c, pts, 1, ink.blocked);
            }
        }
        for (a, pts) in lattice.iter().enumerate() {
            if self.free >> a & 1 == 1 {
                polyline(c, pts, 1, ink.free);
            }
        }
        if let Some(t) = corrected.and_then(|t| t.teacher_action) {
            polyline(c, &lattice[t as usize], 3, ink.teacher);
        }
        if let Some(a) = r.action {
            polyline(c, &lattice[a as usize], 3, ink.chosen);
        }
        c.clip_to(None);
        // A correction: a red border round the close-up.
        let border = if corrected.is_some() {
            ink.red
        } else {
            ink.frame
        };
        let (x0, y0) = (l.inset_x as i64, l.map_y as i64);
        let (x1, y1) = (x0 + l.inset as i64, y0 + l.inset as i64);
        let thick = if corrected.is_some() { 3 } else { 1 };
        for d in 0..thick {
            c.rect(x0, y0 + d, x1, y0 + d + 1, border);
            c.rect(x0, y1 - 1 - d, x1, y1 - d, border);
            c.rect(x0 + d, y0, x0 + d + 1, y1, border);
            c.rect(x1 - 1 - d, y0, x1 - d, y1, border);
        }

        // The header.
        let resets = self.ticks[..self.k1]
            .iter()
            .chain(self.earlier)
            .filter(|t| t.reset.as_deref().is_some_and(|x| x != "path-end"))
            .count();
        let last = &self.ticks[self.k1 - 1];
        let head = format!(
            "tick {:>5}  corrections {:>4}  laps {:>2}  resets {:>3}",
            r.step, last.corrections, last.lap, resets
        );
        c.text(&head, 2, 3, ink.text);
        let mut x = 2 + 8 * head.chars().count() as i64 + 16;
        if corrected.is_some() {
            c.text("correction", x, 3, ink.red);
            x += 8 * 11;
        }
        if let Some(cause) = reset {
            c.text(&format!("reset: {cause}"), x, 3, ink.red);
        }
    }
}
