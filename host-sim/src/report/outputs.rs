//! Every file of a finished grid: the CSVs, the figures and the report.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result};

use super::aggregate::{Aggregate, aggregate_all};
use super::figure::{self, PALETTE, Panel, Series};
use super::files::{write_csv, write_file};
use super::grid::{
    Group, HOUSEHOLDS, NOISE_CURVES, Options, PATH_TICKS, Results, Setting, load_households,
    paper_learner,
};
use super::panels::{corrections_panel, loss_panel, map_picture, progress_panel};
use super::paths::{PathTrace, learner_lap};
use super::plot::MapDrawing;
use super::sections::report;
use super::worlds;
use crate::teach::experiment::{self, Mode};
use crate::world::scenario::Scenario;
use crate::world::teacher::{TeacherSpec, scaled};

/// The per-step CSV of some settings: each row's key columns (`keys`, their values beside
/// each aggregate), the step, and the means and standard deviations across trials.
fn per_step_csv(out: &Path, keys: &[&str], rows: &[(Vec<String>, &Aggregate)]) -> Result<()> {
    let mut header = keys.to_vec();
    header.extend([
        "step",
        "latent_loss_mean",
        "latent_loss_std",
        "corrections_mean",
        "corrections_std",
        "progress_mean",
        "progress_std",
    ]);
    write_csv(
        out,
        &header,
        rows.iter().flat_map(|(key, a)| {
            a.loss
                .iter()
                .zip(&a.corrections)
                .zip(&a.progress_curve)
                .enumerate()
                .map(move |(i, ((l, c), p))| {
                    let mut row = key.clone();
                    row.push(i.to_string());
                    row.extend(
                        [l.0, l.1, c.0, c.1]
                            .iter()
                            .map(|v| format!("{v:.6}"))
                            .chain([p.0, p.1].iter().map(|v| format!("{v:.3}"))),
                    );
                    row
                })
        }),
    )
}

/// One experiment's per-step CSV (`NAME.csv`, keyed by `key`) and its figure (`figures/NAME`):
/// latent loss and corrections of the settings `on_figure` picks, labelled "KEY VALUE".
#[expect(
    clippy::too_many_arguments,
    reason = "one call per experiment, every argument named"
)]
fn write_curves(
    out: &Path,
    figs: &Path,
    name: &str,
    title: &str,
    aggs: &[&Aggregate],
    key: &str,
    value: impl Fn(&Aggregate) -> String,
    on_figure: impl Fn(&Aggregate) -> bool,
) -> Result<()> {
    let rows: Vec<(Vec<String>, &Aggregate)> = aggs.iter().map(|a| (vec![value(a)], *a)).collect();
    per_step_csv(&out.join(format!("{name}.csv")), &[key], &rows)?;
    let curves: Vec<(String, &Aggregate)> = aggs
        .iter()
        .filter(|a| on_figure(a))
        .map(|a| (format!("{key} {}", value(a)), *a))
        .collect();
    figure::write_chart(
        &figs.join(name),
        title,
        &[
            loss_panel("latent loss", &curves),
            corrections_panel("corrections", &curves),
        ],
        2,
        (600, 420),
    )
}

fn summary_csv(out: &Path, aggs: &[Aggregate]) -> Result<()> {
    let f6 = |v: f64| format!("{v:.6}");
    let f3 = |v: f64| format!("{v:.3}");
    write_csv(
        out,
        &[
            "experiment",
            "household",
            "feedback",
            "sigma",
            "threshold",
            "trials",
            "first_tenth_loss_mean",
            "first_tenth_loss_std",
            "final_loss_mean",
            "final_loss_std",
            "corrections_mean",
            "corrections_std",
            "first_tenth_corrections_mean",
            "last_tenth_corrections_mean",
            "laps_mean",
            "laps_std",
            "trials_lapped",
            "progress_m_mean",
            "progress_m_std",
            "resets_collision_mean",
            "resets_stuck_mean",
            "resets_lost_mean",
            "resets_blocked_mean",
        ],
        aggs.iter().map(|a| {
            let s = &a.setting;
            let mut row = vec![
                s.group.name().to_string(),
                s.household.to_string(),
                s.mode.name().to_string(),
                s.noise.to_string(),
                s.threshold.to_string(),
                a.trials.to_string(),
            ];
            row.extend(
                [a.first_loss, a.final_loss]
                    .iter()
                    .flat_map(|&(m, sd)| [f6(m), f6(sd)]),
            );
            row.extend([
                f3(a.total_corrections.0),
                f3(a.total_corrections.1),
                f3(a.first_tenth_corrections.0),
                f3(a.last_tenth_corrections.0),
                f3(a.laps.0),
                f3(a.laps.1),
                a.lapped.to_string(),
                f3(a.progress.0),
                f3(a.progress.1),
            ]);
            row.extend(a.resets.iter().map(|&r| f3(r)));
            row
        }),
    )
}

/// The teacher's own lap of every household (purple in the path figures).
fn teacher_laps(
    o: &Options,
    households: &BTreeMap<&'static str, Arc<Scenario>>,
) -> Result<BTreeMap<&'static str, PathTrace>> {
    let mut laps = BTreeMap::new();
    for h in HOUSEHOLDS {
        let s = &households[h];
        let teacher = TeacherSpec {
            weights: scaled(&s.teacher.weights, o.teacher_scale),
            ..s.teacher
        };
        let snap = experiment::learner_with(paper_learner(), teacher.weights)?;
        laps.insert(h, learner_lap(s, &snap, teacher, PATH_TICKS)?);
    }
    Ok(laps)
}

/// Writes every output of a finished grid into `out`; returns the report's text.
pub fn finalize(out: &Path, o: &Options, results: &Results) -> Result<String> {
    let aggs = aggregate_all(o, &results.grid)?;
    let households = load_households()?;
    let figs = out.join("figures");
    std::fs::create_dir_all(&figs).with_context(|| format!("{}: cannot create", figs.display()))?;
    let find = |g: Group, pred: &dyn Fn(&Setting) -> bool| -> Vec<&Aggregate> {
        aggs.iter()
            .filter(|a| a.setting.group == g && pred(&a.setting))
            .collect()
    };
    let teacher_paths = teacher_laps(o, &households)?;
    // The teacher's pace in each household: metres of path per tick of its lap.
    let pace = |h: &str| {
        let t = &teacher_paths[h];
        (t.end == "lap" && t.points.len() > 1)
            .then(|| households[h].path.length() / (t.points.len() - 1) as f64)
    };

    // Variety.
    let variety = find(Group::Variety, &|_| true);
    let rows: Vec<(Vec<String>, &Aggregate)> = variety
        .iter()
        .map(|a| {
            let s = &a.setting;
            (vec![s.household.to_string(), s.mode.name().to_string()], *a)
        })
        .collect();
    per_step_csv(&out.join("variety.csv"), &["household", "feedback"], &rows)?;
    let by_house = |h: &str, online_only: bool| -> Vec<(String, &Aggregate)> {
        variety
            .iter()
            .filter(|a| {
                a.setting.household == h
                    && (!online_only || matches!(a.setting.mode, Mode::Online(_)))
            })
            .map(|a| (a.setting.mode.name().to_string(), *a))
            .collect()
    };
    let mut panels = Vec::new();
    for h in HOUSEHOLDS {
        panels.push(loss_panel(
            &format!("{h}: latent loss"),
            &by_house(h, false),
        ));
    }
    for h in HOUSEHOLDS {
        panels.push(corrections_panel(
            &format!("{h}: corrections"),
            &by_house(h, true),
        ));
    }
    figure::write_chart(
        &figs.join("variety"),
        "Learning from a variety of feedback (mean ± std across trials)",
        &panels,
        3,
        (560, 400),
    )?;

    // Noise.
    let noise = find(Group::Noise, &|_| true);
    write_curves(
        out,
        &figs,
        "noise",
        "Learning under noisy feedback: doors, action feedback, threshold 1.0",
        &noise,
        "σ",
        |a| a.setting.noise.to_string(),
        |a| NOISE_CURVES.contains(&a.setting.noise),
    )?;
    write_csv(
        &out.join("noise_sweep.csv"),
        &[
            "sigma",
            "trials",
            "final_latent_loss_mean",
            "final_latent_loss_std",
            "corrections_mean",
            "corrections_std",
        ],
        noise.iter().map(|a| {
            [
                a.setting.noise.to_string(),
                a.trials.to_string(),
                format!("{:.6}", a.final_loss.0),
                format!("{:.6}", a.final_loss.1),
                format!("{:.3}", a.total_corrections.0),
                format!("{:.3}", a.total_corrections.1),
            ]
        }),
    )?;
    let sweep_series = |label: &str, get: &dyn Fn(&Aggregate) -> (f64, f64), c| Series {
        label: label.to_string(),
        colour: c,
        points: noise
            .iter()
            .map(|a| {
                let (m, s) = get(a);
                (a.setting.noise as f64, m, s)
            })
            .collect(),
    };
    figure::write_chart(
        &figs.join("noise_sweep"),
        "Noise sweep: final latent loss and corrections against σ",
        &[
            Panel {
                title: "final latent loss".into(),
                x_label: "σ".into(),
                y_label: "latent loss".into(),
                band: false,
                legend_left: true,
                series: vec![sweep_series("final loss", &|a| a.final_loss, PALETTE[0])],
            },
            Panel {
                title: "corrections in all".into(),
                x_label: "σ".into(),
                y_label: "corrections".into(),
                band: false,
                legend_left: true,
                series: vec![sweep_series(
                    "corrections",
                    &|a| a.total_corrections,
                    PALETTE[1],
                )],
            },
        ],
        2,
        (600, 420),
    )?;

    // Thresholds.
    let thr = find(Group::Thresholds, &|_| true);
    write_curves(
        out,
        &figs,
        "thresholds",
        "Teacher thresholds: stairs-chairs, action feedback",
        &thr,
        "threshold",
        |a| a.setting.threshold.to_string(),
        |_| true,
    )?;
    summary_csv(&out.join("summary.csv"), &aggs)?;

    // Task success.
    let mut panels = Vec::new();
    for h in HOUSEHOLDS {
        panels.push(progress_panel(
            &format!("{h}: progress"),
            &by_house(h, false),
            pace(h),
        ));
    }
    fn labelled<'a>(
        v: &[&'a Aggregate],
        key: &str,
        value: &dyn Fn(&Aggregate) -> String,
    ) -> Vec<(String, &'a Aggregate)> {
        v.iter()
            .map(|a| (format!("{key} {}", value(a)), *a))
            .collect()
    }
    let noise_curves: Vec<&Aggregate> = noise
        .iter()
        .copied()
        .filter(|a| NOISE_CURVES.contains(&a.setting.noise))
        .collect();
    panels.push(progress_panel(
        "doors, noise: progress",
        &labelled(&noise_curves, "σ", &|a| a.setting.noise.to_string()),
        pace("doors"),
    ));
    panels.push(progress_panel(
        "stairs-chairs, thresholds: progress",
        &labelled(&thr, "threshold", &|a| a.setting.threshold.to_string()),
        pace("stairs-chairs"),
    ));
    figure::write_chart(
        &figs.join("task_success"),
        "Task success: progress along the path (m; a reset takes back its lap's; mean ± std across trials)",
        &panels,
        3,
        (560, 400),
    )?;

    // Paths, every map at one scale.
    let maps: Vec<&Scenario> = HOUSEHOLDS.iter().map(|h| &*households[h]).collect();
    let scale = MapDrawing::common_scale(&maps, 720);
    let cm = 100.0 * MapDrawing::metres_per_pixel(maps[0], scale);
    let mut paths_csv: Vec<[String; 7]> = Vec::new();
    let mut add_path = |fig: &str, h: &str, who: &str, key: &str, p: &PathTrace| {
        for (i, q) in p.points.iter().enumerate() {
            paths_csv.push([
                fig.into(),
                h.into(),
                who.into(),
                key.into(),
                i.to_string(),
                format!("{:.4}", q.x),
                format!("{:.4}", q.y),
            ]);
        }
    };
    let mut pics = Vec::new();
    for h in HOUSEHOLDS {
        let t = &teacher_paths[h];
        add_path("teachers", h, "teacher", "teacher", t);
        pics.push(map_picture(
            &households[h],
            scale,
            format!(
                "{h}: {} teacher, {}",
                households[h].teacher.preset.unwrap_or("its"),
                t.loss_and_end()
            ),
            t,
            None,
        ));
    }
    figure::write_pictures(
        &figs.join("paths_teachers"),
        "The teachers' paths",
        &format!(
            "purple: the teacher's own policy, one lap from the start; blue: the reference path; doors brown, stairs red, chairs green; every map at 1 px = {cm:.1} cm"
        ),
        &pics,
        3,
    )?;
    let mut path_rows = Vec::new();
    for (g, stem, title, house) in [
        (
            Group::Noise,
            "paths_noise",
            "Paths after training under noise (doors, action feedback)",
            "doors",
        ),
        (
            Group::Thresholds,
            "paths_thresholds",
            "Paths after training with different thresholds (stairs-chairs)",
            "stairs-chairs",
        ),
    ] {
        let mut pics = Vec::new();
        for a in find(g, &|s| s.draw_path) {
            let Some(p) = &a.path else { continue };
            let label = match g {
                Group::Noise => format!("σ {}", a.setting.noise),
                _ => format!("threshold {}", a.setting.threshold),
            };
            add_path(stem, house, "learner", &a.setting.key(), p);
            pics.push(map_picture(
                &households[house],
                scale,
                format!("{label}: latent loss {}", p.loss_and_end()),
                &teacher_paths[house],
                Some(p),
            ));
            path_rows.push((label, house, p.clone()));
        }
        figure::write_pictures(
            &figs.join(stem),
            title,
            &format!(
                "orange: trial 0's trained learner, frozen, one lap from the start; purple: the teacher; caption: mean latent loss along the drive (how it ended); 1 px = {cm:.1} cm"
            ),
            &pics,
            3,
        )?;
    }
    write_csv(
        &out.join("paths.csv"),
        &["figure", "household", "who", "setting", "point", "x", "y"],
        paths_csv,
    )?;

    let calibration = crate::teach::calibrate::run()?;
    let across = if o.worlds > 0 {
        Some(worlds::section::write(out, &figs, o, &results.worlds)?)
    } else {
        None
    };
    let report = report(
        o,
        &aggs,
        &calibration,
        across.as_deref(),
        &teacher_paths,
        &path_rows,
        cm,
    );
    write_file(&out.join("REPORT.md"), report.as_bytes())?;
    Ok(report)
}
