//! Figures of the reproduction: line charts with a ± one-standard-deviation band (plotters), as
//! SVG and PNG, and map panels composed into one picture.
//!
//! The SVG goes through plotters' SVG backend (text as `<text>`). The PNG goes through
//! [`PngBackend`], plotters drawing on the crate's one [`Raster`] (bitmap-font text, the same
//! bytes on every machine).

use std::path::Path;

use anyhow::{Result, anyhow};
use base64::Engine as _;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::raster::{PngBackend, Raster};

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
    let mut canvas = Raster::new(size.0 as usize, size.1 as usize, [255, 255, 255]);
    draw_figure(
        PngBackend(&mut canvas).into_drawing_area(),
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
    /// The picture.
    pub image: Raster,
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
    // At least as wide as the title (16 px a character) and the legend (8 px).
    let text = (16 * title.chars().count()).max(8 * legend.chars().count());
    let (mut w, mut h) = (2 * PAD + text, HEAD);
    for row in pictures.chunks(cols) {
        let mut x = PAD;
        for p in row {
            at.push((x, h));
            x += p.image.size().0.max(8 * p.caption.chars().count()) + PAD;
        }
        w = w.max(x);
        h += row.iter().map(|p| p.image.size().1).max().unwrap_or(1) + CAPTION + PAD;
    }
    let mut canvas = Raster::new(w, h, [255, 255, 255]);
    canvas.text(title, PAD as i64, 8, 2, [0, 0, 0]);
    canvas.text(legend, PAD as i64, 34, 1, [60, 60, 60]);
    let mut svg = format!(
        "<svg width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" xmlns=\"http://www.w3.org/2000/svg\">\n\
         <rect width=\"{w}\" height=\"{h}\" fill=\"#FFFFFF\"/>\n\
         <text x=\"{PAD}\" y=\"24\" font-family=\"sans-serif\" font-size=\"20\">{}</text>\n\
         <text x=\"{PAD}\" y=\"44\" font-family=\"sans-serif\" font-size=\"13\" fill=\"#3C3C3C\">{}</text>\n",
        xml_escape(title),
        xml_escape(legend)
    );
    for (p, &(x, y)) in pictures.iter().zip(&at) {
        let (width, height) = p.image.size();
        canvas.blit(x as i64, y as i64, &p.image);
        canvas.text(&p.caption, x as i64, (y + height + 8) as i64, 1, [0, 0, 0]);
        let png = p.image.png_bytes()?;
        svg.push_str(&format!(
            "<image x=\"{x}\" y=\"{y}\" width=\"{}\" height=\"{}\" href=\"data:image/png;base64,{}\"/>\n\
             <text x=\"{x}\" y=\"{}\" font-family=\"sans-serif\" font-size=\"14\">{}</text>\n",
            width,
            height,
            base64::engine::general_purpose::STANDARD.encode(&png),
            y + height + 18,
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Pictures of different widths sit side by side with one gap between them, not in
    /// columns as wide as the widest.
    #[test]
    fn pictures_take_their_own_width() {
        let dir = tempfile::tempdir().unwrap();
        let pic = |width: usize, height: usize| Picture {
            caption: "c".into(),
            image: Raster::new(width, height, [0, 0, 0]),
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
        // A legend wider than the pictures widens the sheet: 10 + 60 × 8 + 10.
        write_pictures(&stem, "t", &"l".repeat(60), &[pic(100, 40)], 2).unwrap();
        let png = std::fs::read(stem.with_extension("png")).unwrap();
        let be = |i: usize| u32::from_be_bytes(png[i..i + 4].try_into().unwrap());
        assert_eq!(be(16), 500);
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
