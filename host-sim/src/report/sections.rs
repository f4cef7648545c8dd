//! The report's text: the header, the calibration, the claims, the tables of each experiment.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use firmware_core::PAPER_STEP;

use super::aggregate::Aggregate;
use super::claims::{self, verdicts};
use super::grid::{Group, Options, PATH_TICKS};
use super::paths::PathTrace;
use super::statistics::{SMOOTHING, smoothing_window, tenth};
use crate::teach::experiment::StartJitter;

/// `a ± b` of the laps and progress, and the mean resets by cause, for the tables.
pub(crate) fn task_cells(a: &Aggregate) -> String {
    format!(
        "{} ({}/{}) | {:.0} ± {:.0} | {}",
        claims::pm1(a.laps),
        a.lapped,
        a.trials,
        a.progress.0,
        a.progress.1,
        a.resets
            .iter()
            .map(|r| format!("{r:.1}"))
            .collect::<Vec<_>>()
            .join(" / ")
    )
}

pub(crate) const TASK_HEAD: &str =
    "laps (trials that lapped) | progress (m) | resets: collision / stuck / lost / blocked";

/// One row per setting of `group`: its key columns (`keys`, the values `key_of` gives), the
/// losses, the corrections, the task.
pub(crate) fn summary_table(
    r: &mut String,
    aggs: &[Aggregate],
    group: Group,
    keys: &[&str],
    key_of: impl Fn(&Aggregate) -> Vec<String>,
) {
    let _ = writeln!(
        r,
        "| {} | first-tenth loss | final loss | corrections | first → last tenth corrections | {TASK_HEAD} |\n|{}",
        keys.join(" | "),
        "---|".repeat(keys.len() + 7)
    );
    for a in aggs.iter().filter(|a| a.setting.group == group) {
        let _ = writeln!(
            r,
            "| {} | {} | {} | {} | {:.1} → {:.1} | {} |",
            key_of(a).join(" | "),
            claims::pm(a.first_loss),
            claims::pm(a.final_loss),
            claims::pm1(a.total_corrections),
            a.first_tenth_corrections.0,
            a.last_tenth_corrections.0,
            task_cells(a)
        );
    }
}

/// The report's calibration section: the targets in one line each, the procedure's figures, the
/// rule's outcome and the frozen weights.
pub(crate) fn calibration_section(
    r: &mut String,
    o: &Options,
    c: &crate::teach::calibrate::Calibration,
) {
    let _ = writeln!(
        r,
        "## Calibration of the teachers\n\n\
         The paper gives what each teacher wants but not the scale of its weights, and the scale \
         decides which regime a threshold lands in (the latent loss grows with it, the policy does \
         not). `docs/reproduction/CALIBRATION.md` wrote down, before any claim was checked, \
         targets from the paper's own words, stated on the *path follower* (the teacher without \
         its semantic weights, the learner that \"just focuses on following the line\") along \
         each teacher's own lap: `S(h, s, τ)` is the share of what the path follower's ignoring \
         the semantic objects costs that a teacher of threshold τ sees, `m` the median cost of a \
         passage where the two choose differently.\n\n\
         * **T1** (\"In Avoid Doors, all methods of feedback converge near zero\"): `S(doors, s, 1.0) ≥ 0.75`.\n\
         * **T2** (the stairs households: \"the teacher threshold being too high for the task\"): \
         `S(h, s, 1.0) ≤ 0.5`.\n\
         * **T3** (\"the middle ground, in our case, around 0.25 - 0.5\"): `S(h, s, 0.25) ≥ 0.75` in \
         both stairs households.\n\
         * **T4** (noise: \"a good job at the task with σ = 1.0. At σ = 2.0 the learner does not \
         care for the doors\"): `√2 ≤ m(doors, s) ≤ 2√2`.\n\n\
         `host-sim calibrate` computes each target's interval of the scale exactly from the laps \
         and applies the rule fixed with the targets:\n"
    );
    r.push_str(&crate::teach::calibrate::markdown(c));
    let _ = writeln!(
        r,
        "\nThe frozen teachers (`host-sim/src/world/teacher.rs`), frozen in a commit of their own before \
         any claim was run with them:\n\n\
         | teacher | scale | weights (obstacles, door, stairs, chair, path, right) |\n|---|---|---|"
    );
    for p in crate::world::teacher::PRESETS {
        let _ = writeln!(
            r,
            "| {} | {} | {:?} |",
            p.name,
            crate::teach::calibrate::two_digits(p.scale as f64),
            p.weights
        );
    }
    if o.teacher_scale != 1.0 {
        let _ = writeln!(
            r,
            "\n**This run multiplied every teacher's weights by {}** (a point of the scale sweep), \
             so its teachers are not the calibrated ones.",
            o.teacher_scale
        );
    }
    let _ = writeln!(
        r,
        "\nHow every claim's verdict depends on the scale (each teacher's at ×¼, ×½, ×1, ×2, ×4) is \
         in [`SCALE_SWEEP.md`](SCALE_SWEEP.md) (`host-sim scale-sweep`).\n"
    );
}

pub(crate) fn report(
    o: &Options,
    aggs: &[Aggregate],
    calibration: &crate::teach::calibrate::Calibration,
    across_worlds: Option<&str>,
    teacher_paths: &BTreeMap<&str, PathTrace>,
    path_rows: &[(String, &str, PathTrace)],
    cm_per_px: f64,
) -> String {
    let k = tenth(o.steps as usize);
    let w = smoothing_window(o.steps as usize);
    let mut r = String::new();
    let _ = writeln!(r, "# Reproduction of the paper's section 6\n");
    let worlds = crate::report::worlds::worlds(o.worlds).len();
    let world_runs = if worlds > 0 {
        let settings = crate::report::worlds::world_settings().len();
        format!(
            "; and {worlds} worlds × {settings} settings × {} trials = {} runs of {} steps for the \
             claims across worlds",
            o.world_trials,
            worlds * settings * o.world_trials as usize,
            o.steps
        )
    } else {
        String::new()
    };
    let _ = writeln!(
        r,
        "Generated by `host-sim reproduce {}` (or the merge of its shards: the same bytes). {} \
         settings × {} trials = {} runs of {} steps{world_runs}. Deterministic: the same grid gives \
         this file byte for byte; the wall time is printed by the command, not written here.\n",
        o.flags(),
        aggs.len(),
        o.trials,
        aggs.len() * o.trials as usize,
        o.steps
    );
    let _ = writeln!(
        r,
        "* **Learner**: the paper's, plain online gradient descent with a constant step of {PAPER_STEP} \
         (`LearnerParams::paper()`), not the crate's default averaged OGD.\n\
         * **Teachers**: calibrated from the paper's words before any claim was checked (next section). \
         The semantic teacher is the paper's: statements about doors, stairs, chairs and the path, the \
         path judged by cross-track error, summed (the richer statements of `host-sim run --statements \
         rich` are not used here).\n\
         * **Behaviour cloning**: the paper's baseline was \"trained on 50 samples of action feedback\" \
         and \"does not receive additional training from the initial first 50 datapoints\". We read \
         the 50 datapoints as the first 50 ticks of a run: the teacher's own policy drives ticks 0–49 \
         from the run's start pose, each tick labelled with the teacher's action; the 50 samples are \
         fitted offline with the same generalized hinge and learner (epochs over them in tick order \
         until an epoch changes nothing, at most 200), and the fitted learner is frozen for the whole \
         run, from the same start. Behaviour cloning means imitating demonstrations, and the paper \
         gives its baseline no corrections of its own driving, hence the teacher's demonstration.\n\
         * **Trials**: trial t has seed {} + t, in every setting; the seed drives the teacher's noise and \
         random preference queries and a start-pose jitter (up to {} m sideways, {} rad of heading), so \
         that trials differ even with a noiseless teacher.\n\
         * **Households**: `doors`, `stairs-right`, `stairs-chairs`, look-alikes of the paper's Gibson \
         households (which could not be redistributed), with the teachers avoid doors; avoid stairs and \
         keep right; avoid stairs and chairs. Every scenario's teacher drives a lap of it before it is \
         used.\n\
         * **Final latent loss**: a trial's mean latent loss over its last tenth ({k} steps); the \
         first-tenth loss likewise. Numbers are mean ± sample standard deviation across trials.\n\
         * **Task success**, beside the latent loss: laps, progress along the path (metres: the laps \
         completed times the path's length plus the progress into the current lap; a reset puts the car \
         back at the start, so it takes back the progress of its lap) and resets by cause \
         (collision, stuck, lost, blocked), per trial, averaged. A latent loss of zero cannot tell a car \
         that laps from one that circles where the teacher would circle too.\n\
         * Figures: latent-loss curves are a centred moving mean over {w} steps ({:.0}% of the run) of \
         the per-step means across trials; the band is ± one standard deviation across trials, smoothed \
         the same way; corrections and progress are cumulative and drawn as they are. The CSVs hold \
         every step's raw mean and standard deviation.\n",
        o.seed,
        StartJitter::REPRODUCE.lateral,
        StartJitter::REPRODUCE.heading,
        100.0 * SMOOTHING,
    );

    calibration_section(&mut r, o, calibration);

    let _ = writeln!(r, "## Claims\n");
    r.push_str(&claims::render(&verdicts(o, aggs)));
    if let Some(section) = across_worlds {
        r.push_str(section);
    }

    // Tables and figures.
    let _ = writeln!(
        r,
        "## Variety\n\n![variety](figures/variety.png)\n\n\
         The paper's figure has the same panels (latent loss, corrections; a column per household). \
         Its latent losses are in its own feature units (\"around 20\" in the stairs households); \
         ours are in this project's features and calibrated teachers, so compare the shapes and the \
         orders, not the values.\n"
    );
    summary_table(
        &mut r,
        aggs,
        Group::Variety,
        &["household", "feedback"],
        |a| vec![a.setting.household.into(), a.setting.mode.name().into()],
    );
    let _ = writeln!(
        r,
        "\n## Task success\n\n![task success](figures/task_success.png)\n\n\
         The paper has no such figure: it measures learning by latent loss and corrections only. \
         Each panel shows the progress along the path (mean ± std across trials) against the step; \
         the black line is the teacher's own pace (its lap's length over its lap's ticks). Laps and \
         resets by cause are in the tables of each experiment.\n"
    );
    let _ = writeln!(
        r,
        "## Noise\n\n![noise](figures/noise.png)\n\n![noise sweep](figures/noise_sweep.png)\n\n\
         The paper's figure has the four curves σ = 0, 0.25, 0.5, 1.0; the sweep to σ = 2 (the \
         second figure) is ours.\n"
    );
    summary_table(&mut r, aggs, Group::Noise, &["σ"], |a| {
        vec![a.setting.noise.to_string()]
    });
    let _ = writeln!(
        r,
        "\n## Thresholds\n\n![thresholds](figures/thresholds.png)\n\n\
         The paper's figure has the thresholds 0 to 1; 2, 4 and 8 are ours, so that the whole \
         regime, up to where the teacher stops correcting, is visible.\n"
    );
    summary_table(&mut r, aggs, Group::Thresholds, &["threshold"], |a| {
        vec![a.setting.threshold.to_string()]
    });
    let _ = writeln!(
        r,
        "\n## Paths\n\nThe teacher's own policy (purple) and trial 0's trained learner, frozen (orange), each \
         driving one lap from the scenario's start (at most {PATH_TICKS} ticks; it ends early at a reset). \
         Every map is drawn at the same scale, 1 px = {cm_per_px:.1} cm. The paper draws its learners' \
         paths in its 3-D Gibson households; ours are 2-D maps, and a drive that ended in a reset is \
         short, so its mean latent loss is beside how it ended.\n\n\
         ![teachers](figures/paths_teachers.png)\n\n![paths under noise](figures/paths_noise.png)\n\n\
         ![paths by threshold](figures/paths_thresholds.png)\n"
    );
    let _ = writeln!(
        r,
        "| figure | household | points | ended | mean latent loss along it (how it ended) |\n|---|---|---|---|---|"
    );
    for (h, p) in teacher_paths {
        let _ = writeln!(
            r,
            "| teacher | {h} | {} | {} | {} |",
            p.points.len(),
            p.end,
            p.loss_and_end()
        );
    }
    for (label, h, p) in path_rows {
        let _ = writeln!(
            r,
            "| {label} | {h} | {} | {} | {} |",
            p.points.len(),
            p.end,
            p.loss_and_end()
        );
    }
    let _ = writeln!(
        r,
        "\n## Files\n\n* `variety.csv`, `noise.csv`, `thresholds.csv`: per step, mean and standard deviation \
         across trials of the latent loss, the cumulative corrections and the progress along the path (m).\n\
         * `noise_sweep.csv`: final latent loss and corrections against σ.\n\
         * `summary.csv`: one row per setting, laps, progress and resets by cause included.\n\
         * `paths.csv`: the drawn paths.\n\
         * `figures/`: every figure as PNG and SVG."
    );
    if across_worlds.is_some() {
        let _ = writeln!(
            r,
            "* `worlds.csv`: every world of the claims across worlds, each claim's verdict and \
             effect size there, and action feedback's laps and resets."
        );
    }
    r
}
