//! The panels of the charts (latent loss, corrections, progress) and the map pictures.

use super::aggregate::Aggregate;
use super::figure::{PALETTE, Panel, Picture, Series};
use super::paths::PathTrace;
use super::statistics::{sampled, smoothed, smoothing_window};
use crate::world::scenario::Scenario;

pub(crate) fn loss_panel(title: &str, rows: &[(String, &Aggregate)]) -> Panel {
    Panel {
        title: title.to_string(),
        x_label: "step".into(),
        y_label: "latent loss".into(),
        band: true,
        legend_left: false,
        series: rows
            .iter()
            .enumerate()
            .map(|(i, (label, a))| Series {
                label: label.clone(),
                colour: PALETTE[i % PALETTE.len()],
                points: smoothed(&a.loss, smoothing_window(a.loss.len())),
            })
            .collect(),
    }
}

pub(crate) fn corrections_panel(title: &str, rows: &[(String, &Aggregate)]) -> Panel {
    Panel {
        title: title.to_string(),
        x_label: "step".into(),
        y_label: "corrections".into(),
        band: true,
        legend_left: true,
        series: rows
            .iter()
            .enumerate()
            .map(|(i, (label, a))| Series {
                label: label.clone(),
                colour: PALETTE[i % PALETTE.len()],
                points: sampled(&a.corrections),
            })
            .collect(),
    }
}

/// Progress along the path against the step, and the teacher's own pace (`pace` metres per
/// tick) as a reference line.
pub(crate) fn progress_panel(
    title: &str,
    rows: &[(String, &Aggregate)],
    pace: Option<f64>,
) -> Panel {
    let mut series: Vec<Series> = rows
        .iter()
        .enumerate()
        .map(|(i, (label, a))| Series {
            label: label.clone(),
            colour: PALETTE[i % PALETTE.len()],
            points: sampled(&a.progress_curve),
        })
        .collect();
    let steps = rows.first().map_or(0, |(_, a)| a.progress_curve.len()) as f64;
    if let Some(p) = pace {
        series.push(Series {
            label: "teacher's pace".into(),
            colour: plotters::style::RGBColor(0, 0, 0),
            points: vec![(0.0, 0.0, 0.0), (steps, p * steps, 0.0)],
        });
    }
    Panel {
        title: title.to_string(),
        x_label: "step".into(),
        y_label: "progress along the path (m)".into(),
        band: true,
        legend_left: true,
        series,
    }
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
    let mut r = crate::report::plot::Raster::of_scenario_scaled(scenario, scale);
    r.polyline(&teacher.points, TEACHER_COLOUR);
    if let Some(l) = learner {
        r.polyline(&l.points, LEARNER_COLOUR);
    }
    let (width, height) = r.size();
    Picture {
        caption,
        width,
        height,
        rgb: r.rgb().to_vec(),
    }
}
