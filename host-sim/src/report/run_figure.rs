//! The figure of one run, which `host-sim run` writes beside its `steps.csv`: the latent loss
//! and the corrections against the tick (`run.png`, `run.svg`).
//!
//! The latent loss is drawn as a centred moving mean over 5% of the run
//! ([`smoothing_window`]), as the reproduction's curves are, since one tick's loss depends on
//! where the car happens to be; the corrections and the resets (every cause) are cumulative.

use std::path::Path;

use anyhow::Result;
use plotters::style::RGBColor;

use super::figure::{PALETTE, Panel, Series, write_chart};
use super::statistics::{sampled, smoothed, smoothing_window};
use crate::teach::config::Mode;
use crate::teach::record::RunReport;
use crate::world::sim::ResetReason;

/// Draws `report`'s figure into `stem.png` and `stem.svg`.
pub fn write_run_figure(stem: &Path, report: &RunReport) -> Result<()> {
    let n = report.records.len();
    let window = smoothing_window(n);
    let loss: Vec<(f64, f64)> = report
        .records
        .iter()
        .map(|r| (r.latent_loss as f64, 0.0))
        .collect();
    let corrections: Vec<(f64, f64)> = report
        .records
        .iter()
        .map(|r| (r.corrections as f64, 0.0))
        .collect();
    let mut resets = 0.0;
    let resets: Vec<(f64, f64)> = report
        .records
        .iter()
        .map(|r| {
            if r.reset.is_some_and(|c| c != ResetReason::PathEnd) {
                resets += 1.0;
            }
            (resets, 0.0)
        })
        .collect();
    let panels = [
        Panel {
            title: "Latent loss".into(),
            x_label: "tick (0.1 s)".into(),
            y_label: "latent loss".into(),
            band: true,
            legend_left: false,
            series: vec![Series {
                label: format!("mean over {window} ticks"),
                colour: PALETTE[0],
                points: smoothed(&loss, window),
            }],
        },
        Panel {
            title: "Corrections, resets".into(),
            x_label: "tick (0.1 s)".into(),
            y_label: "count".into(),
            band: true,
            legend_left: true,
            series: vec![
                Series {
                    label: "corrections".into(),
                    colour: PALETTE[1],
                    points: sampled(&corrections),
                },
                Series {
                    label: "resets, every cause".into(),
                    colour: RGBColor(0, 0, 0),
                    points: sampled(&resets),
                },
            ],
        },
    ];
    let taught = match report.mode {
        Mode::Online(kind) => format!("{} feedback", kind.name()),
        Mode::BehaviourCloning => "behaviour cloning".into(),
        Mode::Teacher => "the teacher's own policy".into(),
    };
    let title = format!(
        "{}, {taught}, seed {}, {}",
        report.scenario,
        report.seed,
        report.learner.kind.name(),
    );
    write_chart(stem, &title, &panels, 2, (560, 380))
}
