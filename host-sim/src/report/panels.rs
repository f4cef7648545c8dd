//! The panels of the charts (latent loss, corrections, progress) and the map pictures.

use super::aggregate::Aggregate;
use super::figure::{PALETTE, Panel, Picture, Series};
use super::paths::PathTrace;
use super::plot::MapDrawing;
use super::statistics::{sampled, smoothed, smoothing_window};
use crate::world::scenario::Scenario;

/// A panel of one curve per row, `points` of each aggregate, coloured in the palette's order.
fn curves_panel(
    title: &str,
    y_label: &str,
    legend_left: bool,
    rows: &[(String, &Aggregate)],
    points: impl Fn(&Aggregate) -> Vec<(f64, f64, f64)>,
) -> Panel {
    Panel {
        title: title.to_string(),
        x_label: "step".into(),
        y_label: y_label.into(),
        band: true,
        legend_left,
        series: rows
            .iter()
            .enumerate()
            .map(|(i, (label, a))| Series {
                label: label.clone(),
                colour: PALETTE[i % PALETTE.len()],
                points: points(a),
            })
            .collect(),
    }
}

/// Latent loss against the step, smoothed ([`smoothed`]).
pub(crate) fn loss_panel(title: &str, rows: &[(String, &Aggregate)]) -> Panel {
    curves_panel(title, "latent loss", false, rows, |a| {
        smoothed(&a.loss, smoothing_window(a.loss.len()))
    })
}

/// Cumulative corrections against the step.
pub(crate) fn corrections_panel(title: &str, rows: &[(String, &Aggregate)]) -> Panel {
    curves_panel(title, "corrections", true, rows, |a| {
        sampled(&a.corrections)
    })
}

/// Progress along the path against the step, and the teacher's own pace (`pace` metres per
/// tick) as a reference line.
pub(crate) fn progress_panel(
    title: &str,
    rows: &[(String, &Aggregate)],
    pace: Option<f64>,
) -> Panel {
    let mut panel = curves_panel(title, "progress along the path (m)", true, rows, |a| {
        sampled(&a.progress_curve)
    });
    let steps = rows.first().map_or(0, |(_, a)| a.progress_curve.len()) as f64;
    if let Some(p) = pace {
        panel.series.push(Series {
            label: "teacher's pace".into(),
            colour: plotters::style::RGBColor(0, 0, 0),
            points: vec![(0.0, 0.0, 0.0), (steps, p * steps, 0.0)],
        });
    }
    panel
}

pub(crate) const TEACHER_COLOUR: [u8; 3] = [150, 0, 200];
pub(crate) const LEARNER_COLOUR: [u8; 3] = [255, 140, 0];

pub(crate) fn map_picture(
    scenario: &Scenario,
    scale: usize,
    caption: String,
    teacher: &PathTrace,
    learner: Option<&PathTrace>,
) -> Picture {
    let mut r = MapDrawing::of_scenario_scaled(scenario, scale);
    r.polyline(&teacher.points, TEACHER_COLOUR);
    if let Some(l) = learner {
        r.polyline(&l.points, LEARNER_COLOUR);
    }
    Picture {
        caption,
        image: r.into_raster(),
    }
}
