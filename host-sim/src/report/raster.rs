//! The one raster of every picture host-sim draws, and its one way to a PNG file.
//!
//! A [`Raster`] is an RGB image, row-major from the top. The map drawings
//! ([`crate::report::plot::MapDrawing`]) paint cells, paths and objects on one; the charts of the
//! reproduction ([`crate::report::figure`]) are drawn on one by plotters through
//! [`PngBackend`]; the sheets of map pictures are composed on one. Its text is drawn with the 8×8
//! glyphs of the `font8x8` crate, scaled: no system font is read, so the PNG bytes are the same
//! on every machine, like the CSVs. [`Raster::png_bytes`] is the only PNG encoder of the crate.

use std::path::Path;

use anyhow::{Result, anyhow};
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendTextStyle, DrawingBackend, DrawingErrorKind, FontTransform,
};

/// An RGB image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Raster {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
}

impl Raster {
    /// A `width` × `height` image filled with `colour`.
    pub fn new(width: usize, height: usize, colour: [u8; 3]) -> Self {
        Self {
            width,
            height,
            rgb: colour.repeat(width * height),
        }
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The pixels, RGB, row-major from the top.
    pub fn rgb(&self) -> &[u8] {
        &self.rgb
    }

    /// Paints pixel (`x`, `y`); a pixel outside the image is not drawn.
    pub fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if let Some(i) = self.index(x, y) {
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }

    /// Mixes `c` into pixel (`x`, `y`) with opacity `alpha` (0 to 1).
    pub fn blend(&mut self, x: i64, y: i64, c: [u8; 3], alpha: f64) {
        if let Some(i) = self.index(x, y) {
            let a = alpha.clamp(0.0, 1.0);
            for k in 0..3 {
                let old = self.rgb[i + k] as f64;
                self.rgb[i + k] = (c[k] as f64 * a + old * (1.0 - a)).round() as u8;
            }
        }
    }

    fn index(&self, x: i64, y: i64) -> Option<usize> {
        (x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height)
            .then(|| (y as usize * self.width + x as usize) * 3)
    }

    /// Copies `image` with its top-left corner at (`x`, `y`).
    pub fn blit(&mut self, x: i64, y: i64, image: &Raster) {
        for row in 0..image.height {
            for col in 0..image.width {
                let i = (row * image.width + col) * 3;
                let px = &image.rgb[i..i + 3];
                self.put(x + col as i64, y + row as i64, [px[0], px[1], px[2]]);
            }
        }
    }

    /// Draws `text` with its top-left corner at (`x`, `y`), glyphs scaled by `scale`.
    pub fn text(&mut self, text: &str, x: i64, y: i64, scale: i64, c: [u8; 3]) {
        self.glyphs(text, (x, y), scale, c, FontTransform::None);
    }

    fn glyphs(&mut self, text: &str, at: (i64, i64), scale: i64, c: [u8; 3], t: FontTransform) {
        for (k, ch) in text.chars().enumerate() {
            let glyph = glyph(ch);
            for (gy, bits) in glyph.iter().enumerate() {
                for gx in 0..8 {
                    if bits >> gx & 1 == 0 {
                        continue;
                    }
                    for sy in 0..scale {
                        for sx in 0..scale {
                            // Unrotated offset from the anchor.
                            let u = (k as i64 * 8 + gx) * scale + sx;
                            let v = gy as i64 * scale + sy;
                            let (dx, dy) = t.transform(u as i32, v as i32);
                            self.put(at.0 + dx as i64, at.1 + dy as i64, c);
                        }
                    }
                }
            }
        }
    }

    /// The PNG file's bytes (8-bit RGB).
    pub fn png_bytes(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, self.width as u32, self.height as u32);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc.write_header().map_err(|e| anyhow!("png: {e}"))?;
            w.write_image_data(&self.rgb)
                .map_err(|e| anyhow!("png: {e}"))?;
        }
        Ok(out)
    }

    /// Writes the PNG file `path`.
    pub fn write_png(&self, path: &Path) -> Result<()> {
        let bytes = self.png_bytes()?;
        std::fs::write(path, bytes).map_err(|e| anyhow!("{}: cannot write: {e}", path.display()))
    }
}

/// The 8×8 glyph of `ch`: ASCII, Latin-1 (±, ×, °, …) and Greek (σ, τ, …) from `font8x8`; a few
/// symbols the reports use drawn here (→, −, ≤, ≥, √, ∞); `?` for anything else.
pub fn glyph(ch: char) -> [u8; 8] {
    use font8x8::legacy::{BASIC_LEGACY, GREEK_LEGACY, LATIN_LEGACY};
    let code = ch as usize;
    match ch {
        '\u{0}'..='\u{7f}' => BASIC_LEGACY[code],
        '\u{a0}'..='\u{ff}' => LATIN_LEGACY[code - 0xa0],
        '\u{390}'..='\u{3c9}' => GREEK_LEGACY[code - 0x390],
        '→' => [0x00, 0x08, 0x18, 0x3F, 0x18, 0x08, 0x00, 0x00],
        '−' => [0x00, 0x00, 0x00, 0x3F, 0x00, 0x00, 0x00, 0x00],
        '≤' => [0x30, 0x0C, 0x03, 0x0C, 0x30, 0x00, 0x3F, 0x00],
        '≥' => [0x03, 0x0C, 0x30, 0x0C, 0x03, 0x00, 0x3F, 0x00],
        '√' => [0x70, 0x10, 0x10, 0x10, 0x13, 0x16, 0x1C, 0x18],
        '∞' => [0x00, 0x00, 0x36, 0x49, 0x49, 0x36, 0x00, 0x00],
        _ => BASIC_LEGACY[b'?' as usize],
    }
}

/// The raster backend's (never produced) error.
#[derive(Debug)]
pub struct RasterError;

impl std::fmt::Display for RasterError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("raster error")
    }
}

impl std::error::Error for RasterError {}

fn glyph_scale(size: f64) -> i64 {
    ((size / 11.0).round() as i64).max(1)
}

/// The plotters drawing backend over a [`Raster`].
#[derive(Debug)]
pub struct PngBackend<'a>(pub &'a mut Raster);

impl DrawingBackend for PngBackend<'_> {
    type ErrorType = RasterError;

    fn get_size(&self) -> (u32, u32) {
        (self.0.width as u32, self.0.height as u32)
    }

    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<RasterError>> {
        Ok(())
    }

    fn present(&mut self) -> Result<(), DrawingErrorKind<RasterError>> {
        Ok(())
    }

    fn draw_pixel(
        &mut self,
        p: BackendCoord,
        c: BackendColor,
    ) -> Result<(), DrawingErrorKind<RasterError>> {
        self.0
            .blend(p.0 as i64, p.1 as i64, [c.rgb.0, c.rgb.1, c.rgb.2], c.alpha);
        Ok(())
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<RasterError>> {
        let s = glyph_scale(style.size()) as u32;
        Ok((8 * s * text.chars().count() as u32, 8 * s))
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<RasterError>> {
        let s = glyph_scale(style.size());
        let (w, h) = (8 * s * text.chars().count() as i64, 8 * s);
        let dx = match style.anchor().h_pos {
            HPos::Left => 0,
            HPos::Right => -w,
            HPos::Center => -w / 2,
        };
        let dy = match style.anchor().v_pos {
            VPos::Top => 0,
            VPos::Center => -h / 2,
            VPos::Bottom => -h,
        };
        let t = style.transform();
        let (ox, oy) = t.transform(dx as i32, dy as i32);
        let c = style.color().rgb;
        self.0.glyphs(
            text,
            (pos.0 as i64 + ox as i64, pos.1 as i64 + oy as i64),
            s,
            [c.0, c.1, c.2],
            t,
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigma_and_plus_minus_have_their_own_glyphs() {
        let q = glyph('?');
        for c in ['σ', '±', '×', '→', 'τ', '√', '≤'] {
            assert_ne!(glyph(c), q, "{c}");
            assert_ne!(glyph(c), [0; 8], "{c}");
        }
        assert_eq!(glyph('σ'), font8x8::legacy::GREEK_LEGACY[0x3c3 - 0x390]);
        assert_eq!(glyph('A'), font8x8::legacy::BASIC_LEGACY[65]);
        assert_eq!(glyph('€'), q);
    }

    #[test]
    fn pixels_outside_are_not_drawn_and_blits_are_clipped() {
        let mut r = Raster::new(3, 2, [255, 255, 255]);
        r.put(-1, 0, [0, 0, 0]);
        r.put(3, 1, [0, 0, 0]);
        assert_eq!(r, Raster::new(3, 2, [255, 255, 255]));
        r.blit(2, 1, &Raster::new(2, 2, [1, 2, 3]));
        assert_eq!(&r.rgb()[15..18], &[1, 2, 3]);
        assert_eq!(r.rgb().iter().filter(|&&v| v == 1).count(), 1);
        r.blend(0, 0, [0, 0, 0], 0.5);
        assert_eq!(&r.rgb()[0..3], &[128, 128, 128]);
        let png = r.png_bytes().unwrap();
        assert!(png.starts_with(b"\x89PNG"));
    }
}
