//! Figures of the reproduction: line charts with a ± one-standard-deviation band (plotters), as
//! SVG and PNG, and map panels composed into one picture.
//!
//! The SVG goes through plotters' SVG backend (text as `<text>`). The PNG goes through
//! [`PngCanvas`], a plotters drawing backend over an RGB buffer whose text is drawn with the
//! 8×8 glyphs of the `font8x8` crate, scaled: no system font is read, so the PNG bytes are the
//! same on every machine, like the CSVs.

use std::path::Path;

use anyhow::{Result, anyhow};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendTextStyle, DrawingErrorKind, FontTransform,
};

/// The PNG canvas's (never produced) error.
#[derive(Debug)]
pub struct CanvasError;

impl std::fmt::Display for CanvasError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("canvas error")
    }
}

impl std::error::Error for CanvasError {}

/// An RGB raster that plotters draws on, with bitmap-font text.
#[derive(Clone, Debug)]
pub struct PngCanvas {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
}

impl PngCanvas {
    /// A white canvas.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            rgb: vec![255; width as usize * height as usize * 3],
        }
    }

    /// Copies an RGB image (`w` × `h`, row-major) with its top-left corner at (`x`, `y`).
    pub fn blit(&mut self, x: i32, y: i32, w: usize, h: usize, rgb: &[u8]) {
        for row in 0..h {
            for col in 0..w {
                let i = (row * w + col) * 3;
                if let Some(px) = rgb.get(i..i + 3) {
                    self.put(x + col as i32, y + row as i32, [px[0], px[1], px[2]], 1.0);
                }
            }
        }
    }

    fn put(&mut self, x: i32, y: i32, c: [u8; 3], alpha: f64) {
        if x < 0 || y < 0 || x >= self.width as i32 || y >= self.height as i32 {
            return;
        }
        let i = (y as usize * self.width as usize + x as usize) * 3;
        let a = alpha.clamp(0.0, 1.0);
        for k in 0..3 {
            let old = self.rgb[i + k] as f64;
            self.rgb[i + k] = (c[k] as f64 * a + old * (1.0 - a)).round() as u8;
        }
    }

    /// Draws `text` with its top-left corner at (`x`, `y`), glyphs scaled by `scale`.
    pub fn text(&mut self, text: &str, x: i32, y: i32, scale: i32, c: [u8; 3]) {
        self.glyphs(text, (x, y), scale, c, FontTransform::None);
    }

    fn glyphs(&mut self, text: &str, at: (i32, i32), scale: i32, c: [u8; 3], t: FontTransform) {
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
                            let u = (k as i32 * 8 + gx) * scale + sx;
                            let v = gy as i32 * scale + sy;
                            let (dx, dy) = t.transform(u, v);
                            self.put(at.0 + dx, at.1 + dy, c, 1.0);
                        }
                    }
                }
            }
        }
    }

    /// The PNG file's bytes.
    pub fn png_bytes(&self) -> Result<Vec<u8>> {
        encode_png(self.width as usize, self.height as usize, &self.rgb)
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

/// Encodes an RGB image as PNG.
pub fn encode_png(width: usize, height: usize, rgb: &[u8]) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, width as u32, height as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(|e| anyhow!("png: {e}"))?;
        w.write_image_data(rgb).map_err(|e| anyhow!("png: {e}"))?;
    }
    Ok(out)
}

fn glyph_scale(size: f64) -> i32 {
    ((size / 11.0).round() as i32).max(1)
}

/// The plotters backend drawing on a [`PngCanvas`].
#[derive(Debug)]
pub struct PngTarget<'a>(pub &'a mut PngCanvas);

impl DrawingBackend for PngTarget<'_> {
    type ErrorType = CanvasError;

    fn get_size(&self) -> (u32, u32) {
        (self.0.width, self.0.height)
    }

    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<CanvasError>> {
        Ok(())
    }

    fn present(&mut self) -> Result<(), DrawingErrorKind<CanvasError>> {
        Ok(())
    }

    fn draw_pixel(
        &mut self,
        p: BackendCoord,
        c: BackendColor,
    ) -> Result<(), DrawingErrorKind<CanvasError>> {
        self.0.put(p.0, p.1, [c.rgb.0, c.rgb.1, c.rgb.2], c.alpha);
        Ok(())
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<CanvasError>> {
        let s = glyph_scale(style.size()) as u32;
        Ok((8 * s * text.chars().count() as u32, 8 * s))
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<CanvasError>> {
        let s = glyph_scale(style.size());
        let (w, h) = (8 * s * text.chars().count() as i32, 8 * s);
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
        let (ox, oy) = t.transform(dx, dy);
        let c = style.color().rgb;
        self.0
            .glyphs(text, (pos.0 + ox, pos.1 + oy), s, [c.0, c.1, c.2], t);
        Ok(())
    }
}

/// One curve: points `(x, mean, std)`.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Colour.
    pub colour: RGBColor,
    /// `(x, mean, standard deviation)`.
    pub points: Vec<(f64, f64, f64)>,
}

/// One chart of a figure.
#[derive(Clone, Debug)]
pub struct Panel {
    /// Title above the chart.
    pub title: String,
    /// x axis label.
    pub x_label: String,
    /// y axis label.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series>,
    /// Draw mean ± std as a shaded band (else: error bars at every point).
    pub band: bool,
    /// Put the legend in the upper left corner (for rising curves) instead of the upper right.
    pub legend_left: bool,
}

/// A palette that reads on white (matplotlib's tab10).
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

fn bounds(p: &Panel) -> (f64, f64, f64, f64) {
    let (mut x0, mut x1, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
    for s in &p.series {
        for &(x, m, sd) in &s.points {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y1 = y1.max(m + sd);
        }
    }
    if !x0.is_finite() || x1 <= x0 {
        (x0, x1) = (0.0, 1.0);
    }
    let y1 = if y1.is_finite() && y1 > 0.0 {
        y1 * 1.05
    } else {
        1.0
    };
    (x0, x1, 0.0, y1)
}

/// A tick label: at most three decimals, trailing zeros dropped.
fn tick(v: &f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.to_string() }
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<()> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("drawing: {e}");
    let (x0, x1, y0, y1) = bounds(p);
    let mut chart = ChartBuilder::on(area)
        .caption(&p.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(&p.x_label)
        .y_desc(&p.y_label)
        .x_labels(6)
        .y_labels(6)
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .light_line_style(WHITE)
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(e)?;
    for s in &p.series {
        if p.band {
            let mut poly: Vec<(f64, f64)> = s.points.iter().map(|&(x, m, d)| (x, m + d)).collect();
            poly.extend(
                s.points
                    .iter()
                    .rev()
                    .map(|&(x, m, d)| (x, (m - d).max(0.0))),
            );
            chart
                .draw_series(std::iter::once(Polygon::new(poly, s.colour.mix(0.18))))
                .map_err(e)?;
        } else {
            let cap = (x1 - x0) / 150.0;
            for &(x, m, d) in &s.points {
                let (lo, hi) = ((m - d).max(0.0), m + d);
                let style = s.colour.stroke_width(1);
                chart
                    .draw_series([
                        PathElement::new(vec![(x, lo), (x, hi)], style),
                        PathElement::new(vec![(x - cap, lo), (x + cap, lo)], style),
                        PathElement::new(vec![(x - cap, hi), (x + cap, hi)], style),
                    ])
                    .map_err(e)?;
            }
        }
    }
    for s in &p.series {
        let colour = s.colour;
        chart
            .draw_series(LineSeries::new(
                s.points.iter().map(|&(x, m, _)| (x, m)),
                colour.stroke_width(2),
            ))
            .map_err(e)?
            .label(s.label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(3))
            });
    }
    chart
        .configure_series_labels()
        .position(if p.legend_left {
            SeriesLabelPosition::UpperLeft
        } else {
            SeriesLabelPosition::UpperRight
        })
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(e)?;
    Ok(())
}

fn draw_figure<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    panels: &[Panel],
    cols: usize,
) -> Result<()> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("drawing: {e}");
    root.fill(&WHITE).map_err(e)?;
    let root = root.titled(title, ("sans-serif", 22)).map_err(e)?;
    let cols = cols.max(1);
    let rows = panels.len().div_ceil(cols).max(1);
    let areas = root.split_evenly((rows, cols));
    for (area, p) in areas.iter().zip(panels) {
        draw_panel(area, p)?;
    }
    root.present().map_err(e)?;
    Ok(())
}

/// Draws `panels` (`cols` per row, `panel_size` pixels each) under `title` into `stem.png` and
/// `stem.svg`.
pub fn write_chart(
    stem: &Path,
    title: &str,
    panels: &[Panel],
    cols: usize,
    panel_size: (u32, u32),
) -> Result<()> {
    let cols = cols.max(1);
    let rows = panels.len().div_ceil(cols).max(1) as u32;
    let size = (panel_size.0 * cols as u32, panel_size.1 * rows + 40);
    let mut svg = String::new();
    draw_figure(
        SVGBackend::with_string(&mut svg, size).into_drawing_area(),
        title,
        panels,
        cols,
    )?;
    write(&stem.with_extension("svg"), svg.as_bytes())?;
    let mut canvas = PngCanvas::new(size.0, size.1);
    draw_figure(
        PngTarget(&mut canvas).into_drawing_area(),
        title,
        panels,
        cols,
    )?;
    write(&stem.with_extension("png"), &canvas.png_bytes()?)?;
    Ok(())
}

/// One picture of a figure made of pictures (maps with paths).
#[derive(Clone, Debug)]
pub struct Picture {
    /// Caption under it.
    pub caption: String,
    /// Width (pixels).
    pub width: usize,
    /// Height (pixels).
    pub height: usize,
    /// RGB, row-major.
    pub rgb: Vec<u8>,
}

/// Lays `pictures` out `cols` per row with captions, a title and a legend line, into
/// `stem.png`, and `stem.svg` (the same pictures embedded as PNG data, text as text). Each
/// picture takes its own width (or its caption's, if wider) and the next follows it after a
/// small gap, so pictures of different sizes sit side by side without blank columns.
pub fn write_pictures(
    stem: &Path,
    title: &str,
    legend: &str,
    pictures: &[Picture],
    cols: usize,
) -> Result<()> {
    const PAD: usize = 10;
    const HEAD: usize = 56;
    const CAPTION: usize = 28;
    let cols = cols.max(1);
    // Where each picture goes: rows of `cols`, each as tall as its tallest picture.
    let mut at = Vec::with_capacity(pictures.len());
    let (mut w, mut h) = (PAD, HEAD);
    for row in pictures.chunks(cols) {
        let mut x = PAD;
        for p in row {
            at.push((x, h));
            x += p.width.max(8 * p.caption.chars().count()) + PAD;
        }
        w = w.max(x);
        h += row.iter().map(|p| p.height).max().unwrap_or(1) + CAPTION + PAD;
    }
    let mut canvas = PngCanvas::new(w as u32, h as u32);
    canvas.text(title, PAD as i32, 8, 2, [0, 0, 0]);
    canvas.text(legend, PAD as i32, 34, 1, [60, 60, 60]);
    let mut svg = format!(
        "<svg width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" xmlns=\"http://www.w3.org/2000/svg\">\n\
         <rect width=\"{w}\" height=\"{h}\" fill=\"#FFFFFF\"/>\n\
         <text x=\"{PAD}\" y=\"24\" font-family=\"sans-serif\" font-size=\"20\">{}</text>\n\
         <text x=\"{PAD}\" y=\"44\" font-family=\"sans-serif\" font-size=\"13\" fill=\"#3C3C3C\">{}</text>\n",
        xml_escape(title),
        xml_escape(legend)
    );
    for (p, &(x, y)) in pictures.iter().zip(&at) {
        canvas.blit(x as i32, y as i32, p.width, p.height, &p.rgb);
        canvas.text(
            &p.caption,
            x as i32,
            (y + p.height + 8) as i32,
            1,
            [0, 0, 0],
        );
        let png = encode_png(p.width, p.height, &p.rgb)?;
        svg.push_str(&format!(
            "<image x=\"{x}\" y=\"{y}\" width=\"{}\" height=\"{}\" href=\"data:image/png;base64,{}\"/>\n\
             <text x=\"{x}\" y=\"{}\" font-family=\"sans-serif\" font-size=\"14\">{}</text>\n",
            p.width,
            p.height,
            base64(&png),
            y + p.height + 18,
            xml_escape(&p.caption)
        ));
    }
    svg.push_str("</svg>\n");
    write(&stem.with_extension("png"), &canvas.png_bytes()?)?;
    write(&stem.with_extension("svg"), svg.as_bytes())?;
    Ok(())
}

fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::write(path, bytes).map_err(|e| anyhow!("{}: cannot write: {e}", path.display()))
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Standard base64 with padding.
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_rfc_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(i.as_bytes()), o);
        }
    }

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

    /// Pictures of different widths sit side by side with one gap between them, not in
    /// columns as wide as the widest.
    #[test]
    fn pictures_take_their_own_width() {
        let dir = tempfile::tempdir().unwrap();
        let pic = |width: usize, height: usize| Picture {
            caption: "c".into(),
            width,
            height,
            rgb: vec![0; width * height * 3],
        };
        let stem = dir.path().join("pics");
        write_pictures(
            &stem,
            "t",
            "l",
            &[pic(100, 40), pic(300, 60), pic(50, 20)],
            2,
        )
        .unwrap();
        let png = std::fs::read(stem.with_extension("png")).unwrap();
        let be = |i: usize| u32::from_be_bytes(png[i..i + 4].try_into().unwrap());
        // Width: 10 + 100 + 10 + 300 + 10; height: 56 + (60 + 28 + 10) + (20 + 28 + 10).
        assert_eq!((be(16), be(20)), (430, 212));
    }

    #[test]
    fn a_chart_is_drawn_as_png_and_svg_with_text() {
        let dir = tempfile::tempdir().unwrap();
        let panel = Panel {
            title: "t".into(),
            x_label: "step".into(),
            y_label: "loss".into(),
            series: vec![Series {
                label: "a".into(),
                colour: PALETTE[0],
                points: (0..10)
                    .map(|i| (i as f64, 1.0 / (1.0 + i as f64), 0.1))
                    .collect(),
            }],
            band: true,
            legend_left: false,
        };
        let stem = dir.path().join("fig");
        write_chart(&stem, "Title", &[panel], 1, (400, 300)).unwrap();
        let png = std::fs::read(stem.with_extension("png")).unwrap();
        assert!(png.starts_with(b"\x89PNG"));
        let svg = std::fs::read_to_string(stem.with_extension("svg")).unwrap();
        assert!(svg.contains("Title") && svg.contains("<polyline"));
    }
}
