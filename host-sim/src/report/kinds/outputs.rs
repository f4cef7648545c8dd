//! The files of the kinds experiment: `kinds.csv`, `kinds_curves.csv`, `kinds_alpha.csv`, the
//! figures `kinds_loss`, `kinds_corrections`, `kinds_effort`, `kinds_progress`, and the report's
//! section.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use firmware_core::FeedbackKind;
use plotters::style::RGBColor;

use super::{KIND_TRIALS, KIND_WORLDS, KindAggregate, Options, resets_cell, trials};
use crate::report::claims;
use crate::report::figure::{self, PALETTE, Panel, Series};
use crate::report::files::write_file;
use crate::report::statistics::{sampled, smoothed, smoothing_window, tenth};
use crate::teach::experiment::Mode;
use crate::teach::kinds::{EFFORT_SECONDS, INFORMATIVE, SPAN_TICKS};
use crate::teach::record::RESET_CAUSES;

/// Twelve colours that read on white: the report's palette (tab10's first eight), tab10's last
/// two, black, gold.
const COLOURS: [RGBColor; 12] = [
    PALETTE[0],
    PALETTE[1],
    PALETTE[2],
    PALETTE[3],
    PALETTE[4],
    PALETTE[5],
    PALETTE[6],
    PALETTE[7],
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(0, 0, 0),
    RGBColor(230, 180, 0),
];

/// A short label for a chart's legend.
fn label(m: Mode) -> String {
    match m {
        Mode::Mix(x) if x == crate::teach::kinds::Mix::ALL => "mix: all nine".into(),
        Mode::Mix(_) => "mix: paper's three".into(),
        m => m.name(),
    }
}

/// The latent loss of each teaching of `world` against `x` (a per-step curve of the same
/// aggregate, its mean used as the abscissa: the step, the corrections or the effort so far).
fn loss_against(aggs: &[&KindAggregate], title: &str, x_label: &str, x: &Abscissa) -> Panel {
    Panel {
        title: title.to_string(),
        x_label: x_label.to_string(),
        y_label: "latent loss".into(),
        band: false,
        legend_left: false,
        series: aggs
            .iter()
            .enumerate()
            .map(|(i, a)| Series {
                label: label(a.setting.mode),
                colour: COLOURS[i % COLOURS.len()],
                points: smoothed(&a.loss, smoothing_window(a.loss.len()))
                    .into_iter()
                    .map(|(step, m, _)| (x(a, step as usize), m, 0.0))
                    .collect(),
            })
            .collect(),
    }
}

/// Where a step of an aggregate lies on a chart's x axis.
type Abscissa = dyn Fn(&KindAggregate, usize) -> f64;

fn per_step_csv(aggs: &[KindAggregate]) -> String {
    let mut out = String::from(
        "world,teaching,step,latent_loss_mean,latent_loss_std,corrections_mean,effort_s_mean,progress_mean\n",
    );
    for a in aggs {
        for i in 0..a.loss.len() {
            let _ = writeln!(
                out,
                "{},{},{i},{:.6},{:.6},{:.3},{:.3},{:.3}",
                a.setting.world,
                a.setting.mode.name().replace(',', ";"),
                a.loss[i].0,
                a.loss[i].1,
                a.corrections[i].0,
                a.effort[i].0,
                a.progress_curve[i].0
            );
        }
    }
    out
}

fn summary_csv(aggs: &[KindAggregate]) -> String {
    let mut out = String::from(
        "world,teaching,trials,first_tenth_loss_mean,first_tenth_loss_std,final_loss_mean,final_loss_std,corrections_mean,corrections_std,effort_s_mean,effort_s_std,laps_mean,trials_lapped,progress_m_mean,progress_m_std,resets_collision_mean,resets_stuck_mean,resets_lost_mean,resets_blocked_mean",
    );
    for k in FeedbackKind::ALL {
        let _ = write!(out, ",feedback_{}_mean", k.name());
    }
    out.push('\n');
    for a in aggs {
        let _ = write!(
            out,
            "{},{},{},{:.6},{:.6},{:.6},{:.6},{:.3},{:.3},{:.3},{:.3},{:.3},{},{:.3},{:.3}",
            a.setting.world,
            a.setting.mode.name().replace(',', ";"),
            a.trials,
            a.first_loss.0,
            a.first_loss.1,
            a.final_loss.0,
            a.final_loss.1,
            a.total_corrections.0,
            a.total_corrections.1,
            a.total_effort.0,
            a.total_effort.1,
            a.laps.0,
            a.lapped,
            a.progress.0,
            a.progress.1
        );
        for r in a.resets {
            let _ = write!(out, ",{r:.3}");
        }
        for k in a.kinds {
            let _ = write!(out, ",{k:.3}");
        }
        out.push('\n');
    }
    out
}

/// α of `kind` over the kind settings `pick` selects.
fn alpha_over(
    aggs: &[KindAggregate],
    kind: FeedbackKind,
    pick: &dyn Fn(&KindAggregate) -> bool,
) -> super::AlphaSums {
    let mut s = super::AlphaSums::default();
    for a in aggs.iter().filter(|a| pick(a)) {
        s.add(&a.alpha[kind as usize]);
    }
    s
}

fn alpha_cell(s: &super::AlphaSums) -> String {
    match s.means() {
        Some((m, _, _)) => format!("{m:.2}"),
        None => "–".into(),
    }
}

fn alpha_csv(aggs: &[KindAggregate]) -> String {
    let mut out =
        String::from("kind,runs,world,measured,alpha_mean,alpha_worst_mean,share_alpha_positive\n");
    for k in FeedbackKind::ALL {
        for (runs, own) in [("own", true), ("mixed", false)] {
            for w in KIND_WORLDS {
                let s = alpha_over(aggs, k, &|a| {
                    a.setting.world == w && (a.setting.mode == Mode::Online(k)) == own
                });
                if let Some((m, worst, share)) = s.means() {
                    let _ = writeln!(
                        out,
                        "{},{runs},{w},{},{m:.6},{worst:.6},{share:.6}",
                        k.name(),
                        s.n
                    );
                }
            }
        }
    }
    out
}

/// Writes the kinds experiment's files into `out` (and `out/figures`); returns the report's
/// section.
pub fn write_outputs(out: &Path, o: &Options, aggs: &[KindAggregate]) -> Result<String> {
    let figs = out.join("figures");
    write_file(&out.join("kinds.csv"), summary_csv(aggs).as_bytes())?;
    write_file(&out.join("kinds_curves.csv"), per_step_csv(aggs).as_bytes())?;
    write_file(&out.join("kinds_alpha.csv"), alpha_csv(aggs).as_bytes())?;
    let of =
        |w: &str| -> Vec<&KindAggregate> { aggs.iter().filter(|a| a.setting.world == w).collect() };
    let step = |_: &KindAggregate, i: usize| i as f64;
    let corrections = |a: &KindAggregate, i: usize| a.corrections[i.min(a.corrections.len() - 1)].0;
    let effort = |a: &KindAggregate, i: usize| a.effort[i.min(a.effort.len() - 1)].0;
    let charts: [(&str, &str, &str, &Abscissa); 3] = [
        (
            "kinds_loss",
            "Every kind of feedback and mixes: latent loss against the step (mean across trials)",
            "step",
            &step,
        ),
        (
            "kinds_corrections",
            "Latent loss against the corrections given so far (mean across trials)",
            "corrections",
            &corrections,
        ),
        (
            "kinds_effort",
            "Latent loss against a person's effort so far (s, mean across trials)",
            "effort (s)",
            &effort,
        ),
    ];
    for (stem, title, x_label, x) in charts {
        let panels: Vec<Panel> = KIND_WORLDS
            .iter()
            .map(|w| loss_against(&of(w), w, x_label, x))
            .collect();
        figure::write_chart(&figs.join(stem), title, &panels, 2, (720, 520))?;
    }
    let progress: Vec<Panel> = KIND_WORLDS
        .iter()
        .map(|w| Panel {
            title: (*w).to_string(),
            x_label: "step".into(),
            y_label: "progress along the path (m)".into(),
            band: false,
            legend_left: true,
            series: of(w)
                .iter()
                .enumerate()
                .map(|(i, a)| Series {
                    label: label(a.setting.mode),
                    colour: COLOURS[i % COLOURS.len()],
                    points: sampled(&a.progress_curve)
                        .into_iter()
                        .map(|(x, m, _)| (x, m, 0.0))
                        .collect(),
                })
                .collect(),
        })
        .collect();
    figure::write_chart(
        &figs.join("kinds_progress"),
        "Task success: progress along the path against the step (mean across trials)",
        &progress,
        2,
        (720, 520),
    )?;
    Ok(section(o, aggs))
}

fn section(o: &Options, aggs: &[KindAggregate]) -> String {
    let t = trials(o);
    let k = tenth(o.steps as usize);
    let mut r = String::new();
    let _ = writeln!(
        r,
        "## Every kind of feedback, and mixed streams (issue 15)\n\n\
         The paper's claim is that one meta-algorithm learns from any feedback that becomes a \
         pseudo-loss; its experiments use three kinds, each in a run of its own. Here every kind \
         of its Table 1 (`firmware_core::feedback`: action, preference, semantic, trajectory \
         perturbation, scalar reward, correct/incorrect, good/bad labels of a span of ticks, a \
         ranking of four shown actions, an E-stop), a seeded mix of the paper's three \
         (`mix:{}`), the nine in equal parts (`mix:all`) and a cost-aware teacher (`cheapest`) \
         teach in the three households and the MIT basement.\n\n\
         * **Teachers**: each world's calibrated teacher at the paper's threshold 1.0, without \
         noise; every kind is given from the same latent weights, threshold and noise model \
         (`host-sim/src/world/teacher/kinds.rs`).\n\
         * **Learner**: the car's default, averaged OGD with a step of 0.01, for every kind: a \
         mixed stream needs one learner that applies each kind at its right iterate. (The paper's \
         plain OGD, the sections above, is not this one.)\n\
         * **Trials**: {t} per setting (at most {KIND_TRIALS}, to keep the reproduction within a \
         minute), seeds {} + trial, the reproduction's start jitter.\n\
         * **Effort**: a person's seconds per feedback, **our stated guesses** (the cited studies \
         do not report seconds per feedback of each kind in a form we could take over; \
         `host-sim/src/teach/kinds.rs` gives the reasoning): {}.\n\
         * **Spans**: the span teacher watches a stretch of ticks it would correct and labels it \
         bad in one message when it ends or reaches {SPAN_TICKS} ticks; the car applies the label \
         to each labelled tick it still holds.\n\
         * **Cost-aware teacher**: at each correction the cheapest kind whose perceived \
         informativeness α̃ (the paper's assumption 2 in its own perceived losses, over the \
         minimisers of the candidate's pseudo-loss) is at least {INFORMATIVE}, else the most \
         informative; never the E-stop (\"incorrect\" teaches the same without stopping the car).\n\
         * First and final loss: the mean latent loss of the first and the last tenth ({k} \
         steps); mean ± std across trials.\n",
        super::PAPER_MIX,
        o.seed,
        EFFORT_SECONDS
            .iter()
            .map(|(k, s)| format!("{} {s} s", k.name()))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        r,
        "![kinds: latent loss](figures/kinds_loss.png)\n\n\
         ![kinds: latent loss against corrections](figures/kinds_corrections.png)\n\n\
         ![kinds: latent loss against effort](figures/kinds_effort.png)\n\n\
         ![kinds: progress](figures/kinds_progress.png)\n"
    );
    for w in KIND_WORLDS {
        let rows: Vec<&KindAggregate> = aggs.iter().filter(|a| a.setting.world == w).collect();
        let _ = writeln!(
            r,
            "### {w}\n\n\
             | teaching | first-tenth loss | final loss | final / first | corrections | effort (s) | laps (trials that lapped) | progress (m) | resets: {} | feedback given (per trial) |\n\
             |---|---|---|---|---|---|---|---|---|---|",
            RESET_CAUSES.join(" / ")
        );
        for a in &rows {
            let ratio = if a.first_loss.0 > 0.0 {
                format!("{:.2}", a.final_loss.0 / a.first_loss.0)
            } else {
                "–".into()
            };
            let given: Vec<String> = FeedbackKind::ALL
                .iter()
                .zip(a.kinds)
                .filter(|(_, n)| *n > 0.0)
                .map(|(k, n)| format!("{} {n:.0}", k.name()))
                .collect();
            let _ = writeln!(
                r,
                "| {} | {} | {} | {ratio} | {} | {} | {} ({}/{}) | {:.0} ± {:.0} | {} | {} |",
                a.setting.mode.name(),
                claims::pm(a.first_loss),
                claims::pm(a.final_loss),
                claims::pm1(a.total_corrections),
                claims::pm1(a.total_effort),
                claims::pm1(a.laps),
                a.lapped,
                a.trials,
                a.progress.0,
                a.progress.1,
                resets_cell(&a.resets),
                given.join(", ")
            );
        }
        if let Some(best) = rows
            .iter()
            .min_by(|x, y| x.final_loss.0.total_cmp(&y.final_loss.0))
        {
            let near: Vec<&&KindAggregate> = rows
                .iter()
                .filter(|a| a.final_loss.0 <= 2.0 * best.final_loss.0.max(1e-9))
                .collect();
            let cheapest = near
                .iter()
                .min_by(|x, y| x.total_effort.0.total_cmp(&y.total_effort.0));
            let _ = writeln!(
                r,
                "\nLowest final loss: {} ({:.3}). Least effort among the teachings within twice \
                 that: {}.\n",
                best.setting.mode.name(),
                best.final_loss.0,
                cheapest.map_or("–".to_string(), |c| format!(
                    "{} ({:.0} s, final loss {:.3})",
                    c.setting.mode.name(),
                    c.total_effort.0,
                    c.final_loss.0
                ))
            );
        }
    }
    let _ = writeln!(
        r,
        "### How informative each kind is (the paper's assumption 2, measured)\n\n\
         For every correction, with `L` the teacher's true latent loss and `M` the minimisers of \
         the feedback's pseudo-loss on the judged tick (each labelled tick the car holds, for a \
         span): α = (L(a_t) − mean over M of L) / L(a_t), 1 when the feedback points exactly at \
         the teacher's best, 0 when at actions as bad as the learner's, negative when worse. The \
         paper assumes a fixed α > 0 for every correction; \"worst\" takes the largest L over M \
         instead of the mean (the assumption must hold for whichever minimiser the learner's \
         tie-break picks), and the share is that of corrections with α > 0. \"Own runs\" are the \
         kind's runs alone; \"in mixes\" its corrections in the mixes and the cost-aware teacher's \
         runs. Corrections of an action whose true loss is 0 (none without noise) are not \
         measured.\n\n\
         | kind | points at a better action? | {} | own runs: α | worst α | share α > 0 | corrections measured | in mixes: α (measured) |\n\
         |---|---|{}---|---|---|---|---|",
        KIND_WORLDS
            .iter()
            .map(|w| format!("α {w}"))
            .collect::<Vec<_>>()
            .join(" | "),
        "---|".repeat(KIND_WORLDS.len())
    );
    for kind in FeedbackKind::ALL {
        let own = |w: Option<&str>| {
            alpha_over(aggs, kind, &|a| {
                a.setting.mode == Mode::Online(kind) && w.is_none_or(|w| a.setting.world == w)
            })
        };
        let pooled = own(None);
        let mixed = alpha_over(aggs, kind, &|a| a.setting.mode != Mode::Online(kind));
        let (m, worst, share) = pooled.means().unwrap_or((f64::NAN, f64::NAN, f64::NAN));
        let _ = writeln!(
            r,
            "| {} | {} | {} | {m:.2} | {worst:.2} | {:.0}% | {} | {} ({}) |",
            kind.name(),
            if kind.points_at_better() {
                "yes"
            } else {
                "no: only the executed action"
            },
            KIND_WORLDS
                .iter()
                .map(|w| alpha_cell(&own(Some(w))))
                .collect::<Vec<_>>()
                .join(" | "),
            100.0 * share,
            pooled.n,
            alpha_cell(&mixed),
            mixed.n
        );
    }
    let _ = writeln!(
        r,
        "\nThe kinds that judge only the executed action (reward, correct/incorrect, span, E-stop) \
         make every other action a minimiser: their α is that of the average other action, and the \
         generalized hinge moves towards the learner's runner-up, whatever it is worth to the \
         teacher (`firmware_core::feedback::executed`). A reward's size does not change the step. \
         Files: `kinds.csv` (one row per setting), `kinds_curves.csv` (per step), \
         `kinds_alpha.csv` (α per kind, world and runs).\n"
    );
    r
}
