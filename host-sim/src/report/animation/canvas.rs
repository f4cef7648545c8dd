//! The frame's pixels: a palette and a canvas of its indices, and the rectangle that changed
//! between two frames.

use anyhow::{Result, ensure};

use crate::report::raster::glyph;

/// The colours of an animation; index 0 is transparent (used only in the stored rectangles of
/// frames after the first).
pub(super) struct Palette(pub(super) Vec<[u8; 3]>);

impl Palette {
    pub(super) fn new() -> Self {
        Self(vec![[0, 0, 0]])
    }

    pub(super) fn index(&mut self, c: [u8; 3]) -> Result<u8> {
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
pub(super) struct Canvas {
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) px: Vec<u8>,
    /// Drawing is clipped to `x0..x1, y0..y1`.
    pub(super) clip: (i64, i64, i64, i64),
}

impl Canvas {
    pub(super) fn new(width: usize, height: usize, fill: u8) -> Self {
        Self {
            width,
            height,
            px: vec![fill; width * height],
            clip: (0, 0, width as i64, height as i64),
        }
    }

    pub(super) fn put(&mut self, x: i64, y: i64, i: u8) {
        let (x0, y0, x1, y1) = self.clip;
        if x >= x0 && y >= y0 && x < x1 && y < y1 {
            self.px[y as usize * self.width + x as usize] = i;
        }
    }

    /// Clips drawing to the rectangle `x, y, w, h` (within the canvas); `None`: the canvas.
    pub(super) fn clip_to(&mut self, r: Option<(usize, usize, usize, usize)>) {
        let (w, h) = (self.width, self.height);
        let (x, y, rw, rh) = r.unwrap_or((0, 0, w, h));
        self.clip = (
            x.min(w) as i64,
            y.min(h) as i64,
            (x + rw).min(w) as i64,
            (y + rh).min(h) as i64,
        );
    }

    pub(super) fn rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, i: u8) {
        for y in y0..y1 {
            for x in x0..x1 {
                self.put(x, y, i);
            }
        }
    }

    /// A line `thick` pixels wide (a square brush).
    pub(super) fn line(&mut self, a: (f64, f64), b: (f64, f64), thick: i64, i: u8) {
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
    pub(super) fn fill(&mut self, pts: &[(f64, f64)], i: u8) {
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

    pub(super) fn text(&mut self, s: &str, x: i64, y: i64, i: u8) {
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

/// The rectangle of `next` that differs from `prev`, with its unchanged pixels transparent
/// (index 0): `(x, y, width, height, pixels)`; one transparent pixel when nothing changed.
pub(super) fn changed(
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
