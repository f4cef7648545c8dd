//! A run as an animated picture (`host-sim draw --run DIR --animate OUT`): an APNG, written with
//! the `png` crate, sized for a README.
//!
//! # A frame
//!
//! * a header: the tick, the corrections, the laps and the resets so far, and `correction`
//!   (red) in the frames where the teacher corrected the learner, `reset: CAUSE` where the car
//!   was put back;
//! * the map with its path and objects ([`MapDrawing`]), the car's recent trail (orange dots), the
//!   64 trajectories of the lattice from the car's pose (grey-blue where they are free, pink
//!   where they collide), the chosen one (thick red-orange), the teacher's (thick green) and a
//!   red border in the frames of a correction, and the car's footprint (dark blue);
//! * a strip below: the latent loss of every tick of the animated span (grey ahead of the
//!   cursor, blue behind it; one column is the largest loss of its ticks), the corrections as red
//!   marks at its top, the cursor black.
//!
//! # Where each part comes from
//!
//! Everything but the free trajectories is a column of `steps.csv` (see
//! [`super::run_folder::StepRow`]). Which trajectories were free is not written there: it is
//! recomputed from the recorded pose, exactly, because the collision mask depends only on the
//! range scan ([`firmware_core::evaluator::Evaluator`]) and the scan only on the pose and the
//! map ([`crate::world::sim::observe`]); the pose is written in Rust's shortest round-trip form,
//! so it reads back bit for bit. (A run with `--no-scenario-check` or an edited map would be
//! recomputed on the map as it is now.) The trajectories themselves are the lattice's, fixed in
//! the car's frame.
//!
//! # The file
//!
//! One frame per `every` ticks from `from` to `to` (the frame of ticks `t..t+every` shows tick
//! `t`'s pose and choice, and flashes a correction or a reset of any of its ticks), at `fps`
//! frames per second, looping. Colours are a palette; every frame after the first stores only
//! the rectangle that changed, its unchanged pixels transparent (blended over the previous
//! frame), so a frame costs about what moved.

use std::path::Path;

use anyhow::{Context, Result, anyhow, bail, ensure};
use firmware_core::ActionIndex;
use firmware_core::evaluator::Evaluator;
use firmware_core::lattice::trajectory;
use nalgebra::Point2;

use super::plot::MapDrawing;
use super::raster::glyph;
use super::run_folder::StepRow;
use crate::world::car::{CarParams, CarState, Pose};
use crate::world::scenario::Scenario;

/// How to animate a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AnimateOptions {
    /// The first tick.
    pub from: u32,
    /// One past the last tick (None: the run's end).
    pub to: Option<u32>,
    /// Ticks per frame (None: the fewest that keep the animation at [`DEFAULT_FRAMES`] frames
    /// or fewer).
    pub every: Option<u32>,
    /// Frames per second (1 to 50); 10 with `every = 1` is the car's own pace.
    pub fps: u32,
    /// Widest map picture (pixels; a whole number of pixels per map cell, 1 to 8).
    pub max_width: usize,
}

/// Most frames of an animation when `every` is not given.
pub const DEFAULT_FRAMES: u32 = 300;

impl Default for AnimateOptions {
    fn default() -> Self {
        Self {
            from: 0,
            to: None,
            every: None,
            fps: 10,
            max_width: 720,
        }
    }
}

/// What was written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Animation {
    /// Frames.
    pub frames: u32,
    /// Ticks per frame.
    pub every: u32,
    /// Width (pixels).
    pub width: u32,
    /// Height (pixels).
    pub height: u32,
    /// Bytes of the file.
    pub bytes: usize,
}

const HEADER: usize = 14;
const STRIP: usize = 44;
const GAP: usize = 4;
/// Ticks of trail behind the car.
const TRAIL: usize = 150;

// Colours drawn over the map (the map's own come from the raster).
const WHITE: [u8; 3] = [255, 255, 255];
const TEXT: [u8; 3] = [0, 0, 0];
const RED: [u8; 3] = [220, 0, 0];
const FREE: [u8; 3] = [140, 160, 200];
const BLOCKED: [u8; 3] = [250, 175, 175];
const CHOSEN: [u8; 3] = [235, 70, 0];
const TEACHER: [u8; 3] = [0, 150, 0];
const CAR: [u8; 3] = [20, 30, 110];
const TRAIL_DOT: [u8; 3] = [255, 165, 60];
const AHEAD: [u8; 3] = [205, 205, 205];
const BEHIND: [u8; 3] = [40, 110, 200];
const STRIP_BG: [u8; 3] = [245, 245, 245];
const INSET_FRAME: [u8; 3] = [120, 120, 120];

/// The close-up beside the map: this many metres on a side, centred this far ahead of the rear
/// axle (the trajectories reach about 1 m ahead), at least [`MIN_INSET`] pixels.
const INSET_METRES: f64 = 3.0;
const INSET_AHEAD: f64 = 0.5;
const MIN_INSET: usize = 200;

/// The colours of an animation; index 0 is transparent (used only in the stored rectangles of
/// frames after the first).
struct Palette(Vec<[u8; 3]>);

impl Palette {
    fn new() -> Self {
        Self(vec![[0, 0, 0]])
    }

    fn index(&mut self, c: [u8; 3]) -> Result<u8> {
        if let Some(i) = self.0.iter().skip(1).position(|&p| p == c) {
            return Ok(i as u8 + 1);
        }
        ensure!(self.0.len() < 256, "more than 255 colours in an animation");
        self.0.push(c);
        Ok((self.0.len() - 1) as u8)
    }
}

/// A frame: palette indices, row-major from the top.
#[derive(Clone)]
struct Canvas {
    width: usize,
    height: usize,
    px: Vec<u8>,
    /// Drawing is clipped to `x0..x1, y0..y1`.
    clip: (i64, i64, i64, i64),
}

impl Canvas {
    fn new(width: usize, height: usize, fill: u8) -> Self {
        Self {
            width,
            height,
            px: vec![fill; width * height],
            clip: (0, 0, width as i64, height as i64),
        }
    }

    fn put(&mut self, x: i64, y: i64, i: u8) {
        let (x0, y0, x1, y1) = self.clip;
        if x >= x0 && y >= y0 && x < x1 && y < y1 {
            self.px[y as usize * self.width + x as usize] = i;
        }
    }

    /// Clips drawing to the rectangle `x, y, w, h` (within the canvas); `None`: the canvas.
    fn clip_to(&mut self, r: Option<(usize, usize, usize, usize)>) {
        let (w, h) = (self.width, self.height);
        let (x, y, rw, rh) = r.unwrap_or((0, 0, w, h));
        self.clip = (
            x.min(w) as i64,
            y.min(h) as i64,
            (x + rw).min(w) as i64,
            (y + rh).min(h) as i64,
        );
    }

    fn rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, i: u8) {
        for y in y0..y1 {
            for x in x0..x1 {
                self.put(x, y, i);
            }
        }
    }

    /// A line `thick` pixels wide (a square brush).
    fn line(&mut self, a: (f64, f64), b: (f64, f64), thick: i64, i: u8) {
        let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as i64).max(1);
        let lo = -(thick - 1) / 2;
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let (x, y) = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
            for dy in lo..lo + thick {
                for dx in lo..lo + thick {
                    self.put(x.floor() as i64 + dx, y.floor() as i64 + dy, i);
                }
            }
        }
    }

    /// Fills the convex polygon `pts` (pixels).
    fn fill(&mut self, pts: &[(f64, f64)], i: u8) {
        let y0 = pts
            .iter()
            .map(|p| p.1)
            .fold(f64::INFINITY, f64::min)
            .floor() as i64;
        let y1 = pts
            .iter()
            .map(|p| p.1)
            .fold(f64::NEG_INFINITY, f64::max)
            .ceil() as i64;
        for y in y0..=y1 {
            let yc = y as f64 + 0.5;
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for k in 0..pts.len() {
                let (a, b) = (pts[k], pts[(k + 1) % pts.len()]);
                if (a.1 <= yc) != (b.1 <= yc) {
                    let x = a.0 + (yc - a.1) / (b.1 - a.1) * (b.0 - a.0);
                    lo = lo.min(x);
                    hi = hi.max(x);
                }
            }
            if lo <= hi {
                for x in lo.round() as i64..hi.round() as i64 {
                    self.put(x, y, i);
                }
            }
        }
    }

    fn text(&mut self, s: &str, x: i64, y: i64, i: u8) {
        for (k, ch) in s.chars().enumerate() {
            for (gy, bits) in glyph(ch).iter().enumerate() {
                for gx in 0..8 {
                    if bits >> gx & 1 == 1 {
                        self.put(x + k as i64 * 8 + gx, y + gy as i64, i);
                    }
                }
            }
        }
    }
}

/// Which trajectories were free at each row's pose (see the module documentation).
pub fn free_trajectories(scenario: &Scenario, rows: &[StepRow]) -> Result<Vec<u64>> {
    let mut evaluator = Evaluator::new();
    rows.iter()
        .map(|r| {
            let car = CarState::at(Pose {
                x: r.x,
                y: r.y,
                theta: r.theta,
            });
            let mut obs = crate::world::sim::observe(scenario, &car, 0.0);
            // The mask does not depend on the path reference (nor on the speed): any valid one.
            obs.reference = firmware_core::observation::PathReference {
                x: 1.0,
                y: 0.0,
                heading: 0.0,
            };
            let valid = obs
                .check()
                .map_err(|e| anyhow!("tick {}: the observation at its pose: {e}", r.step))?;
            Ok(evaluator.evaluation(valid).allowed().bits())
        })
        .collect()
}

/// Writes the animation of `rows` (a run of `scenario`) into the APNG file `out`; `title`
/// heads every frame's strip.
pub fn animate(
    scenario: &Scenario,
    rows: &[StepRow],
    title: &str,
    o: &AnimateOptions,
    out: &Path,
) -> Result<Animation> {
    let bytes = animation_bytes(scenario, rows, title, o)?;
    std::fs::write(out, &bytes.0).with_context(|| format!("{}: cannot write", out.display()))?;
    Ok(Animation {
        bytes: bytes.0.len(),
        ..bytes.1
    })
}

/// Where a frame's parts are, in pixels.
struct Layout {
    width: usize,
    height: usize,
    /// The map: its top, width and height.
    map_y: usize,
    map_w: usize,
    map_h: usize,
    /// The close-up: its left edge and side.
    inset_x: usize,
    inset: usize,
    /// The strip: its top, the top of its bars and their height.
    strip_y: usize,
    bar_top: usize,
    bar_h: usize,
}

/// The indices of the colours drawn over the map.
struct Inks {
    white: u8,
    text: u8,
    red: u8,
    free: u8,
    blocked: u8,
    chosen: u8,
    teacher: u8,
    car: u8,
    trail: u8,
    behind: u8,
    frame: u8,
}

/// The APNG file's bytes and what they hold.
pub fn animation_bytes(
    scenario: &Scenario,
    rows: &[StepRow],
    title: &str,
    o: &AnimateOptions,
) -> Result<(Vec<u8>, Animation)> {
    let n = rows.len() as u32;
    let to = o.to.unwrap_or(n);
    ensure!(n > 0, "the run has no steps");
    ensure!(
        o.from < to && to <= n,
        "--from {} and --to {to} must satisfy from < to <= {n} (the run's steps)",
        o.from
    );
    ensure!(
        (1..=50).contains(&o.fps),
        "--fps must be in 1..=50, got {}",
        o.fps
    );
    let span = to - o.from;
    let every = match o.every {
        Some(0) => bail!("--every must be at least 1"),
        Some(e) => e,
        None => span.div_ceil(DEFAULT_FRAMES),
    };
    let frames = span.div_ceil(every);
    let ticks = &rows[o.from as usize..to as usize];
    let free = free_trajectories(scenario, ticks)?;

    // The map at the largest whole scale that leaves room for the close-up beside it.
    let mut raster = MapDrawing::of_scenario_scaled(scenario, 1);
    for s in (2..=8).rev() {
        let r = MapDrawing::of_scenario_scaled(scenario, s);
        let (w, h) = r.size();
        if w + GAP + h.max(MIN_INSET) <= o.max_width {
            raster = r;
            break;
        }
    }
    let (map_w, map_h) = raster.size();
    let inset = map_h.max(MIN_INSET);
    let width = (map_w + GAP + inset).max(8 * 60);
    let strip_y = HEADER + map_h.max(inset) + GAP;
    let l = Layout {
        width,
        height: strip_y + STRIP,
        map_y: HEADER,
        map_w,
        map_h,
        inset_x: map_w + GAP,
        inset,
        strip_y,
        bar_top: strip_y + 12,
        bar_h: STRIP - 14,
    };

    let mut palette = Palette::new();
    let ink = Inks {
        white: palette.index(WHITE)?,
        text: palette.index(TEXT)?,
        red: palette.index(RED)?,
        free: palette.index(FREE)?,
        blocked: palette.index(BLOCKED)?,
        chosen: palette.index(CHOSEN)?,
        teacher: palette.index(TEACHER)?,
        car: palette.index(CAR)?,
        trail: palette.index(TRAIL_DOT)?,
        behind: palette.index(BEHIND)?,
        frame: palette.index(INSET_FRAME)?,
    };
    // The map as palette indices, and the background: the map, the strip's ticks ahead.
    let rgb = raster.rgb();
    let map: Vec<u8> = rgb
        .chunks(3)
        .map(|c| palette.index([c[0], c[1], c[2]]))
        .collect::<Result<_>>()?;
    let mut bg = Canvas::new(l.width, l.height, ink.white);
    for y in 0..map_h {
        let row = &map[y * map_w..(y + 1) * map_w];
        let at = (l.map_y + y) * l.width;
        bg.px[at..at + map_w].copy_from_slice(row);
    }
    // The close-up's map: the scale that gives it at least a pixel per pixel.
    let ppm = inset as f64 / INSET_METRES;
    let fine_scale = (ppm * scenario.map.resolution()).ceil().clamp(1.0, 8.0) as usize;
    let fine = MapDrawing::of_scenario_scaled(scenario, fine_scale);
    let fine_map = Fine {
        width: fine.size().0 as i64,
        height: fine.size().1 as i64,
        px: fine
            .rgb()
            .chunks(3)
            .map(|c| palette.index([c[0], c[1], c[2]]))
            .collect::<Result<_>>()?,
        raster: fine,
    };
    let strip_bg = palette.index(STRIP_BG)?;
    bg.rect(
        0,
        l.strip_y as i64,
        l.width as i64,
        l.height as i64,
        strip_bg,
    );
    let strip = Strip::new(ticks, l.width);
    let ahead = palette.index(AHEAD)?;
    for col in 0..l.width {
        strip.bar(&mut bg, &l, col, ahead);
    }
    bg.text(
        &format!("{title}; latent loss (cut at {:.2})", strip.top),
        2,
        l.strip_y as i64 + 2,
        ink.text,
    );

    let lattice: Vec<Vec<(f64, f64)>> = ActionIndex::all()
        .map(|a| {
            let mut pts = vec![(0.0, 0.0)];
            pts.extend(
                trajectory(a)
                    .poses()
                    .iter()
                    .map(|p| (p.x as f64, p.y as f64)),
            );
            pts
        })
        .collect();
    let (width, height) = (l.width, l.height);
    let scene = Scene {
        layout: l,
        ink,
        strip,
        fine: fine_map,
        lattice,
        raster,
    };

    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, width as u32, height as u32);
        enc.set_color(png::ColorType::Indexed);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_palette(palette.0.concat());
        let mut trns = vec![255u8; palette.0.len()];
        trns[0] = 0;
        enc.set_trns(trns);
        let png_err = |e: png::EncodingError| anyhow!("png: {e}");
        enc.set_animated(frames, 0).map_err(png_err)?;
        enc.set_frame_delay(1, o.fps as u16).map_err(png_err)?;
        let mut w = enc.write_header().map_err(png_err)?;
        let mut previous: Option<Vec<u8>> = None;
        for f in 0..frames {
            let k0 = (f * every) as usize;
            let k1 = (k0 + every as usize).min(ticks.len());
            let mut c = bg.clone();
            let frame = Frame {
                k0,
                k1,
                ticks,
                earlier: &rows[..o.from as usize],
                free: free[k0],
            };
            frame.draw(&mut c, &scene);
            // Store only what changed, unchanged pixels transparent.
            let (x0, y0, fw, fh, data) = match &previous {
                None => (0, 0, width, height, c.px.clone()),
                Some(p) => changed(p, &c.px, width, height),
            };
            w.reset_frame_position().map_err(png_err)?;
            w.set_frame_dimension(fw as u32, fh as u32)
                .map_err(png_err)?;
            w.set_frame_position(x0 as u32, y0 as u32)
                .map_err(png_err)?;
            w.set_blend_op(if previous.is_some() {
                png::BlendOp::Over
            } else {
                png::BlendOp::Source
            })
            .map_err(png_err)?;
            w.set_dispose_op(png::DisposeOp::None).map_err(png_err)?;
            w.write_image_data(&data).map_err(png_err)?;
            previous = Some(c.px);
        }
        w.finish().map_err(png_err)?;
    }
    let animation = Animation {
        frames,
        every,
        width: width as u32,
        height: height as u32,
        bytes: bytes.len(),
    };
    Ok((bytes, animation))
}

/// What every frame draws on.
struct Scene {
    layout: Layout,
    ink: Inks,
    strip: Strip,
    fine: Fine,
    /// The lattice's trajectories in the car's frame, each from the rear axle.
    lattice: Vec<Vec<(f64, f64)>>,
    /// The map at the picture's scale.
    raster: MapDrawing,
}

/// The map drawn finer for the close-up, as palette indices.
struct Fine {
    raster: MapDrawing,
    width: i64,
    height: i64,
    px: Vec<u8>,
}

/// The latent-loss strip: one column per pixel, its ticks' largest latent loss.
struct Strip {
    top: f64,
    loss: Vec<f64>,
    corrected: Vec<bool>,
    ticks: usize,
}

impl Strip {
    fn new(ticks: &[StepRow], width: usize) -> Self {
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

    fn column(&self, tick: usize, width: usize) -> usize {
        tick * width / self.ticks
    }

    fn bar(&self, c: &mut Canvas, l: &Layout, col: usize, ink: u8) {
        let h = ((self.loss[col] / self.top).min(1.0) * l.bar_h as f64).round() as i64;
        let base = (l.bar_top + l.bar_h) as i64;
        c.rect(col as i64, base - h, col as i64 + 1, base, ink);
    }
}

/// One frame: ticks `k0..k1` of the animated span.
struct Frame<'a> {
    k0: usize,
    k1: usize,
    ticks: &'a [StepRow],
    /// The run's ticks before the span (for the reset count).
    earlier: &'a [StepRow],
    /// The trajectories free at tick `k0`, one bit per action.
    free: u64,
}

impl Frame<'_> {
    fn draw(&self, c: &mut Canvas, scene: &Scene) {
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

/// The rectangle of `next` that differs from `prev`, with its unchanged pixels transparent
/// (index 0): `(x, y, width, height, pixels)`; one transparent pixel when nothing changed.
fn changed(
    prev: &[u8],
    next: &[u8],
    width: usize,
    height: usize,
) -> (usize, usize, usize, usize, Vec<u8>) {
    let (mut x0, mut y0, mut x1, mut y1) = (width, height, 0, 0);
    for y in 0..height {
        for x in 0..width {
            if prev[y * width + x] != next[y * width + x] {
                x0 = x0.min(x);
                y0 = y0.min(y);
                x1 = x1.max(x + 1);
                y1 = y1.max(y + 1);
            }
        }
    }
    if x0 >= x1 {
        return (0, 0, 1, 1, vec![0]);
    }
    let mut data = Vec::with_capacity((x1 - x0) * (y1 - y0));
    for y in y0..y1 {
        for x in x0..x1 {
            let (p, n) = (prev[y * width + x], next[y * width + x]);
            data.push(if p == n { 0 } else { n });
        }
    }
    (x0, y0, x1 - x0, y1 - y0, data)
}
