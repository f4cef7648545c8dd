//! `host-sim learners`: every online learner against every kind of feedback, with and without
//! random answers, in every world, and the rule that picks `host-sim run`'s default learner from
//! that table.
//!
//! # The table
//!
//! A **cell** is a world (the households `doors`, `stairs-right`, `stairs-chairs` and the
//! `basement` scenario, each with its own calibrated teacher, and three generated households,
//! `gen-0/doors`, `gen-1/stairs-right` and `gen-2/stairs-chairs`: the generator's worlds of seeds
//! 0, 1 and 2, `host-sim generate`, each with one of the three calibrated teachers; every teacher
//! at threshold 1.0 with the paper's statements), a kind of feedback (action, preference, semantic), a noise (none, or 20% random
//! answers: [`crate::world::teacher::TeacherSpec::random_answers`] = 0.2) and a learner kind (each at its
//! default step, [`LearnerKind::default_step`]). Each cell runs [`Options::seeds`] seeds with the
//! reproduction's start jitter and reports, as means over the seeds: the final latent loss (last
//! tenth), laps, resets (all causes) and corrections.
//!
//! # The rule (fixed before the table was first run)
//!
//! One learner per kind of feedback, because what a correction says differs between them. For a
//! kind of feedback, over its cells (every world × two noises; the rule was written for the four
//! fixed worlds, and applies unchanged since the generated ones joined the table):
//!
//! 1. a learner **fails a cell** when its mean laps are below half of the best learner's mean laps
//!    in that cell (it does not get around the world the others get around); the fewest failed
//!    cells wins;
//! 2. among those, the lowest **mean rank** of the final latent loss over the cells (rank 1 for
//!    the lowest loss in a cell, ties sharing their ranks) wins;
//! 3. if still tied, the first in [`LearnerKind::ALL`]'s order.
//!
//! [`DEFAULT_LEARNERS`] holds what the rule chose on the committed table
//! (`docs/learners.md`); behaviour cloning takes the action feedback's learner (its samples are
//! action feedback). The reproduction of the paper always uses the paper's learner, plain OGD
//! with η = 0.01, whatever this table says.

use std::fmt::Write as _;
use std::sync::Arc;

use anyhow::{Context, Result};
use firmware_core::{LearnerKind, LearnerParams};
use rayon::prelude::*;

use crate::teach::experiment::{self, Mode, RunConfig, StartJitter};
use crate::world::scenario::Scenario;
use crate::world::teacher::{self, FeedbackKind, PAPER_KINDS, StatementSet};
use crate::world::{generator, registry};

/// The worlds of the table: the built-in scenarios, then generated households
/// (`gen-SEED/TEACHER`: the generator's world of that seed with that calibrated teacher).
pub const WORLDS: [&str; 7] = [
    "doors",
    "stairs-right",
    "stairs-chairs",
    "basement",
    "gen-0/doors",
    "gen-1/stairs-right",
    "gen-2/stairs-chairs",
];

/// The scenario of a world of [`WORLDS`]: a built-in one, or `gen-SEED/TEACHER` generated.
pub fn load_world(name: &str) -> Result<Scenario> {
    let Some((seed, teacher)) = name.strip_prefix("gen-").and_then(|r| r.split_once('/')) else {
        return registry::load_scenario(name);
    };
    let seed: u64 = seed
        .parse()
        .with_context(|| format!("{name}: not gen-SEED/TEACHER"))?;
    let preset =
        teacher::preset(teacher).with_context(|| format!("{name}: no teacher {teacher}"))?;
    let world = generator::generate(&generator::Options::new(seed))
        .map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    Ok(generator::with_teacher(
        &world.scenario,
        name.to_string(),
        preset,
    ))
}

/// The random-answer probabilities of the table: none, and 20%.
pub const NOISES: [f32; 2] = [0.0, 0.2];

/// `host-sim run`'s default learner for each kind of feedback, chosen by the rule of the module
/// documentation on the table of `docs/learners.md`.
pub const DEFAULT_LEARNERS: [(FeedbackKind, LearnerKind); 3] = [
    (FeedbackKind::Action, LearnerKind::Coactive),
    (FeedbackKind::Preference, LearnerKind::Ogd),
    (FeedbackKind::Semantic, LearnerKind::AdaGrad),
];

/// The default learner of `run` for `mode`: the table's choice for its kind of feedback; the
/// action feedback's for behaviour cloning and the teacher's own drive. The kinds the table
/// does not measure (those beyond the paper's three), mixes and the cost-aware teacher get the
/// car's default, averaged OGD: the one learner that applies every kind at its right iterate
/// (`firmware_core::AveragedOgd`), which a stream of mixed kinds needs.
pub fn default_learner(mode: Mode) -> LearnerKind {
    let kind = match mode {
        Mode::Online(k) => k,
        Mode::Mix(_) | Mode::Cheapest => return LearnerKind::AveragedOgd,
        Mode::BehaviourCloning | Mode::Teacher => FeedbackKind::Action,
    };
    DEFAULT_LEARNERS
        .iter()
        .find(|(k, _)| *k == kind)
        .map_or(LearnerKind::AveragedOgd, |(_, l)| *l)
}

/// The size of the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Options {
    /// Seeds per cell (0, 1, …).
    pub seeds: u32,
    /// Steps per run.
    pub steps: u32,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            seeds: 3,
            steps: 5_000,
        }
    }
}

/// One cell of the table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    /// The world.
    pub world: &'static str,
    /// The kind of feedback.
    pub feedback: FeedbackKind,
    /// Probability of a random answer.
    pub noise: f32,
    /// The learner.
    pub learner: LearnerKind,
    /// Final latent loss (mean of the last tenth), mean over seeds.
    pub final_loss: f64,
    /// Laps, mean over seeds.
    pub laps: f64,
    /// Resets of every cause, mean over seeds.
    pub resets: f64,
    /// Corrections, mean over seeds.
    pub corrections: f64,
}

/// A cell's coordinates: world, kind of feedback, probability of a random answer, learner.
pub type CellKey = (&'static str, FeedbackKind, f32, LearnerKind);

/// One run's figures: final latent loss, laps, resets, corrections.
type RunFigures = (f64, f64, f64, f64);

/// Every (world, feedback, noise, learner) of the table, in its order.
pub fn cells() -> Vec<CellKey> {
    let mut out = Vec::new();
    for feedback in PAPER_KINDS {
        for world in WORLDS {
            for noise in NOISES {
                for learner in LearnerKind::ALL {
                    out.push((world, feedback, noise, learner));
                }
            }
        }
    }
    out
}

/// The seeds per cell the table accepts (`--seeds`).
pub const SEEDS: std::ops::RangeInclusive<u32> = 1..=100;
/// The steps per run the table accepts (`--steps`).
pub const STEPS: std::ops::RangeInclusive<u32> = 10..=experiment::MAX_STEPS;

/// Runs the table on the current rayon pool; `done` is called after each run.
pub fn run_table(o: &Options, done: &(dyn Fn() + Sync)) -> Result<Vec<Cell>> {
    use crate::checks::named;
    crate::checks::count(o.seeds.into(), SEEDS).map_err(named("--seeds"))?;
    crate::checks::count(o.steps.into(), STEPS).map_err(named("--steps"))?;
    let mut worlds = std::collections::BTreeMap::new();
    for w in WORLDS {
        worlds.insert(w, Arc::new(load_world(w)?));
    }
    let jobs: Vec<(CellKey, u32)> = cells()
        .into_iter()
        .flat_map(|c| (0..o.seeds).map(move |s| (c, s)))
        .collect();
    let runs: Vec<Result<RunFigures>> = jobs
        .par_iter()
        .map(|&((world, feedback, noise, learner), seed)| {
            let config = RunConfig {
                mode: Mode::Online(feedback),
                steps: o.steps,
                seed: seed as u64,
                learner: LearnerParams::new(learner),
                start_jitter: Some(StartJitter::REPRODUCE),
                statements: Some(StatementSet::Paper),
                random_answers: Some(noise),
                ..RunConfig::new(worlds[world].clone())
            };
            let r = experiment::run(&config).with_context(|| {
                format!(
                    "{world}, {}, {} random answers, {}, seed {seed}",
                    feedback.name(),
                    noise,
                    learner.name()
                )
            })?;
            done();
            Ok((
                r.first_last(0.1).1,
                r.laps() as f64,
                r.resets.iter().sum::<u32>() as f64,
                r.corrections() as f64,
            ))
        })
        .collect();
    let runs: Vec<RunFigures> = runs.into_iter().collect::<Result<_>>()?;
    let n = o.seeds as usize;
    Ok(cells()
        .into_iter()
        .zip(runs.chunks(n))
        .map(|((world, feedback, noise, learner), r)| {
            let mean = |f: &dyn Fn(&RunFigures) -> f64| r.iter().map(f).sum::<f64>() / n as f64;
            Cell {
                world,
                feedback,
                noise,
                learner,
                final_loss: mean(&|x| x.0),
                laps: mean(&|x| x.1),
                resets: mean(&|x| x.2),
                corrections: mean(&|x| x.3),
            }
        })
        .collect())
}

/// A learner's standing for one kind of feedback under the rule.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Standing {
    /// The learner.
    pub learner: LearnerKind,
    /// Cells where its laps are below half the best learner's.
    pub failed: usize,
    /// Mean rank of its final latent loss over the cells.
    pub mean_rank: f64,
}

/// The rule of the module documentation: every learner's standing for `feedback`, best first.
pub fn standings(cells: &[Cell], feedback: FeedbackKind) -> Vec<Standing> {
    let mine: Vec<&Cell> = cells.iter().filter(|c| c.feedback == feedback).collect();
    let mut groups: Vec<(&str, f32)> = Vec::new();
    for c in &mine {
        if !groups.contains(&(c.world, c.noise)) {
            groups.push((c.world, c.noise));
        }
    }
    let mut out: Vec<Standing> = LearnerKind::ALL
        .iter()
        .filter(|&&l| mine.iter().any(|c| c.learner == l))
        .map(|&learner| Standing {
            learner,
            failed: 0,
            mean_rank: 0.0,
        })
        .collect();
    for (world, noise) in &groups {
        let group: Vec<&&Cell> = mine
            .iter()
            .filter(|c| c.world == *world && c.noise == *noise)
            .collect();
        let best_laps = group.iter().map(|c| c.laps).fold(0.0, f64::max);
        for c in &group {
            let s = out
                .iter_mut()
                .find(|s| s.learner == c.learner)
                .expect("every learner has a standing");
            if c.laps < best_laps / 2.0 {
                s.failed += 1;
            }
            // Rank with ties shared: 1 + the number strictly lower + half the others tied.
            let lower = group.iter().filter(|o| o.final_loss < c.final_loss).count();
            let tied = group
                .iter()
                .filter(|o| o.final_loss == c.final_loss)
                .count();
            s.mean_rank += (1.0 + lower as f64 + (tied as f64 - 1.0) / 2.0) / groups.len() as f64;
        }
    }
    // A stable sort keeps LearnerKind::ALL's order among equals (step 3 of the rule).
    out.sort_by(|a, b| {
        a.failed
            .cmp(&b.failed)
            .then(a.mean_rank.total_cmp(&b.mean_rank))
    });
    out
}

/// The table and the rule's choices as Markdown.
pub fn markdown(o: &Options, cells: &[Cell]) -> String {
    let mut r = String::from("# Which learner: every learner, feedback, noise and world\n\n");
    let _ = writeln!(
        r,
        "Generated by `host-sim learners --seeds {} --steps {}` (deterministic: the same options give \
         this file byte for byte). Each cell is {} seeds (0, 1, …) of {} steps with the reproduction's \
         start jitter, the world's calibrated teacher at threshold 1.0 with the paper's statements, \
         and the learner at its default step (0.01 for the OGD family, 0.1 AdaGrad, 1 Coactive). \
         \"20%\" is a teacher that answers at random in a fifth of its corrections (`host-sim run \
         --random-answers 0.2`). Numbers are means over the seeds: final latent loss (the last \
         tenth's mean), laps, resets (every cause) and corrections. The rule that picks the \
         default is in `host-sim/src/teach/learners.rs` and below; it was written before the table was \
         first run. The reproduction of the paper always uses the paper's learner, plain OGD.\n",
        o.seeds, o.steps, o.seeds, o.steps
    );
    for feedback in PAPER_KINDS {
        let _ = writeln!(r, "## {} feedback\n", feedback.name());
        let kinds: Vec<&str> = LearnerKind::ALL.iter().map(|k| k.name()).collect();
        let _ = writeln!(
            r,
            "final latent loss / laps / resets / corrections\n\n| world | random answers | {} |\n|---|---|{}",
            kinds.join(" | "),
            "---|".repeat(kinds.len())
        );
        for world in WORLDS {
            for noise in NOISES {
                let row: Vec<String> = LearnerKind::ALL
                    .iter()
                    .map(|&l| {
                        cells
                            .iter()
                            .find(|c| {
                                c.feedback == feedback
                                    && c.world == world
                                    && c.noise == noise
                                    && c.learner == l
                            })
                            .map_or("–".into(), |c| {
                                format!(
                                    "{:.3} / {:.1} / {:.1} / {:.0}",
                                    c.final_loss, c.laps, c.resets, c.corrections
                                )
                            })
                    })
                    .collect();
                let _ = writeln!(
                    r,
                    "| {world} | {:.0}% | {} |",
                    100.0 * noise,
                    row.join(" | ")
                );
            }
        }
        let st = standings(cells, feedback);
        let _ = writeln!(
            r,
            "\n| learner | cells failed (laps below half the best's) | mean rank of the final loss |\n|---|---|---|"
        );
        for s in &st {
            let _ = writeln!(
                r,
                "| {} | {} | {:.2} |",
                s.learner.name(),
                s.failed,
                s.mean_rank
            );
        }
        let _ = writeln!(
            r,
            "\n**Chosen for {} feedback: {}.**\n",
            feedback.name(),
            st[0].learner.name()
        );
    }
    let _ = writeln!(
        r,
        "## The rule\n\n\
         One learner per kind of feedback. Over its {} cells ({} worlds × two noises): (1) a \
         learner fails a cell when its mean laps are below half the best learner's there, and the \
         fewest failed cells wins; (2) then the lowest mean rank of the final latent loss (rank 1 \
         for the lowest loss in a cell, ties sharing their ranks); (3) then the first of ogd, \
         ogd-decaying, averaged-ogd, adagrad, coactive. `host-sim run` uses the chosen learner when \
         `--learner` is not given (behaviour cloning and the teacher's drive take the action \
         feedback's). The rule was written for the four built-in worlds before the table was first \
         run; the three generated worlds joined the table later (issue 12), under the same rule.",
        WORLDS.len() * NOISES.len(),
        WORLDS.len()
    );
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(world: &'static str, learner: LearnerKind, loss: f64, laps: f64) -> Cell {
        Cell {
            world,
            feedback: FeedbackKind::Action,
            noise: 0.0,
            learner,
            final_loss: loss,
            laps,
            resets: 0.0,
            corrections: 0.0,
        }
    }

    #[test]
    fn the_rule_counts_failed_cells_first_then_ranks() {
        use LearnerKind::*;
        // World a: ogd best loss but laps 1 of the best 4 (fails); world b: ogd best again.
        let cells = vec![
            cell("a", Ogd, 0.01, 1.0),
            cell("a", AveragedOgd, 0.02, 4.0),
            cell("a", AdaGrad, 0.03, 4.0),
            cell("b", Ogd, 0.01, 4.0),
            cell("b", AveragedOgd, 0.02, 4.0),
            cell("b", AdaGrad, 0.02, 3.0),
        ];
        let st = standings(&cells, FeedbackKind::Action);
        // Ranks in a: ogd 1, averaged 2, adagrad 3; in b: ogd 1, averaged and adagrad tie for 2
        // and 3 (2.5 each). Ogd has the best ranks but fails a cell, so it comes last.
        assert_eq!(st[0].learner, AveragedOgd);
        assert_eq!((st[0].failed, st[0].mean_rank), (0, 2.25));
        assert_eq!(st[1].learner, AdaGrad);
        assert_eq!((st[1].failed, st[1].mean_rank), (0, 2.75));
        assert_eq!(st[2].learner, Ogd);
        assert_eq!((st[2].failed, st[2].mean_rank), (1, 1.0));
        assert_eq!(st.len(), 3, "only the learners in the table stand");
    }

    #[test]
    fn the_default_follows_the_feedback() {
        for (k, l) in DEFAULT_LEARNERS {
            assert_eq!(default_learner(Mode::Online(k)), l);
        }
        assert_eq!(
            default_learner(Mode::BehaviourCloning),
            default_learner(Mode::Online(FeedbackKind::Action))
        );
    }
}
