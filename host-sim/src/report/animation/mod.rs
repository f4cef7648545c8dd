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

mod canvas;
mod frame;

use std::path::Path;

use anyhow::{Context, Result, anyhow, bail, ensure};
use firmware_core::ActionIndex;
use firmware_core::evaluator::Evaluator;
use firmware_core::lattice::trajectory;

use super::plot::MapDrawing;
use super::run_folder::StepRow;
use crate::world::car::{CarState, Pose};
use crate::world::scenario::Scenario;
use canvas::{Canvas, Palette, changed};
use frame::{Fine, Frame, Inks, Layout, Scene, Strip};

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
