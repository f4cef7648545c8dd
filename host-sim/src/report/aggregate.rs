//! One setting across its trials: per-step means and standard deviations, first- and
//! last-tenth losses, corrections and task success.

use anyhow::{Result, ensure};

use super::grid::{Options, Setting, TrialResult, settings};
use super::paths::PathTrace;
use super::statistics::{mean_std, tenth};

/// One setting across its trials.
#[derive(Clone, Debug)]
pub struct Aggregate {
    /// The setting.
    pub setting: Setting,
    /// Trials.
    pub trials: usize,
    /// Per step: mean and std of the latent loss.
    pub loss: Vec<(f64, f64)>,
    /// Per step: mean and std of the cumulative corrections.
    pub corrections: Vec<(f64, f64)>,
    /// Per step: mean and std of the progress along the path (m).
    pub progress_curve: Vec<(f64, f64)>,
    /// Mean latent loss of the first tenth of the steps: mean and std across trials.
    pub first_loss: (f64, f64),
    /// Final latent loss (mean of the last tenth): mean and std across trials.
    pub final_loss: (f64, f64),
    /// Corrections in all.
    pub total_corrections: (f64, f64),
    /// Corrections in the first tenth.
    pub first_tenth_corrections: (f64, f64),
    /// Corrections in the last tenth.
    pub last_tenth_corrections: (f64, f64),
    /// Laps in all.
    pub laps: (f64, f64),
    /// Trials with at least one lap.
    pub lapped: usize,
    /// Progress along the path at the end (m).
    pub progress: (f64, f64),
    /// Resets per trial by cause (means): collision, stuck, lost, blocked.
    pub resets: [f64; 4],
    /// Trial 0's trained learner's lap.
    pub path: Option<PathTrace>,
}

impl Aggregate {
    /// An aggregate of `setting` over `trials` trials with every number 0 and no curve (for
    /// tests and for filling in by hand).
    pub fn empty(setting: Setting, trials: usize) -> Self {
        Self {
            setting,
            trials,
            loss: Vec::new(),
            corrections: Vec::new(),
            progress_curve: Vec::new(),
            first_loss: (0.0, 0.0),
            final_loss: (0.0, 0.0),
            total_corrections: (0.0, 0.0),
            first_tenth_corrections: (0.0, 0.0),
            last_tenth_corrections: (0.0, 0.0),
            laps: (0.0, 0.0),
            lapped: 0,
            progress: (0.0, 0.0),
            resets: [0.0; 4],
            path: None,
        }
    }
}

/// What the report keeps of one trial besides its curves: the numbers every table and claim
/// uses. The across-worlds experiment keeps only these ([`crate::report::worlds`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrialSummary {
    /// Mean latent loss of the first tenth of the steps.
    pub first_loss: f64,
    /// Mean latent loss of the last tenth (the final loss).
    pub final_loss: f64,
    /// Corrections in all.
    pub corrections: u32,
    /// Corrections in the first tenth.
    pub first_tenth_corrections: u32,
    /// Corrections in the last tenth.
    pub last_tenth_corrections: u32,
    /// Laps in all.
    pub laps: u32,
    /// Progress along the path at the end (m).
    pub progress: f64,
    /// Resets by cause: collision, stuck, lost, blocked.
    pub resets: [u32; 4],
}

impl TrialSummary {
    /// The summary of a trial of at least one step.
    pub fn of(t: &TrialResult) -> Self {
        let steps = t.latent.len();
        let k = tenth(steps);
        let mean_of =
            |xs: &[f32]| xs.iter().map(|&x| x as f64).sum::<f64>() / xs.len().max(1) as f64;
        let last = t.corrections[steps - 1];
        Self {
            first_loss: mean_of(&t.latent[..k]),
            final_loss: mean_of(&t.latent[steps - k..]),
            corrections: last,
            first_tenth_corrections: t.corrections[k - 1],
            last_tenth_corrections: last
                - if steps > k {
                    t.corrections[steps - k - 1]
                } else {
                    0
                },
            laps: t.laps[steps - 1],
            progress: t.progress[steps - 1],
            resets: t.reset_counts(),
        }
    }
}

/// The aggregate of `setting` over the summaries of its trials, without curves.
pub fn aggregate_summaries(setting: Setting, trials: &[TrialSummary]) -> Aggregate {
    let over = |f: &dyn Fn(&TrialSummary) -> f64| -> (f64, f64) {
        mean_std(&trials.iter().map(f).collect::<Vec<_>>())
    };
    let n = trials.len().max(1) as f64;
    let mut resets = [0.0; 4];
    for t in trials {
        for (r, c) in resets.iter_mut().zip(t.resets) {
            *r += c as f64 / n;
        }
    }
    Aggregate {
        first_loss: over(&|t| t.first_loss),
        final_loss: over(&|t| t.final_loss),
        total_corrections: over(&|t| t.corrections as f64),
        first_tenth_corrections: over(&|t| t.first_tenth_corrections as f64),
        last_tenth_corrections: over(&|t| t.last_tenth_corrections as f64),
        laps: over(&|t| t.laps as f64),
        lapped: trials.iter().filter(|t| t.laps > 0).count(),
        progress: over(&|t| t.progress),
        resets,
        ..Aggregate::empty(setting, trials.len())
    }
}

/// The aggregate of `setting` over `trials` (all of the same length): its summaries'
/// ([`aggregate_summaries`]) and the per-step curves.
pub fn aggregate(setting: Setting, trials: &[&TrialResult]) -> Aggregate {
    let steps = trials.first().map_or(0, |t| t.latent.len());
    if steps == 0 {
        return Aggregate::empty(setting, trials.len());
    }
    let per_step = |f: &dyn Fn(&TrialResult, usize) -> f64| -> Vec<(f64, f64)> {
        (0..steps)
            .map(|i| mean_std(&trials.iter().map(|t| f(t, i)).collect::<Vec<_>>()))
            .collect()
    };
    let summaries: Vec<TrialSummary> = trials.iter().map(|t| TrialSummary::of(t)).collect();
    Aggregate {
        path: trials
            .iter()
            .find(|t| t.trial == 0)
            .and_then(|t| t.path.clone()),
        loss: per_step(&|t, i| t.latent[i] as f64),
        corrections: per_step(&|t, i| t.corrections[i] as f64),
        progress_curve: per_step(&|t, i| t.progress[i]),
        ..aggregate_summaries(setting, &summaries)
    }
}

/// Aggregates every setting; checks the results are the whole grid.
pub fn aggregate_all(o: &Options, results: &[TrialResult]) -> Result<Vec<Aggregate>> {
    let all = settings();
    let mut by: Vec<Vec<&TrialResult>> = vec![Vec::new(); all.len()];
    for r in results {
        ensure!(
            r.setting < all.len() && r.latent.len() == o.steps as usize,
            "a result of another grid"
        );
        by[r.setting].push(r);
    }
    for (s, rs) in by.iter_mut().enumerate() {
        rs.sort_by_key(|r| r.trial);
        let trials: Vec<u32> = rs.iter().map(|r| r.trial).collect();
        ensure!(
            trials == (0..o.trials).collect::<Vec<_>>(),
            "{}: trials {trials:?}, expected 0..{}",
            all[s].key(),
            o.trials
        );
    }
    Ok(all
        .iter()
        .zip(&by)
        .map(|(s, rs)| aggregate(*s, rs))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::sim::ResetReason;

    /// A trial of 20 steps: latent loss `l[i]`, one correction at each step of `fixes`, progress
    /// 0.5 m a step, a lap at step 15, a `lost` reset at step 7.
    fn trial(t: u32, l: [f32; 20], fixes: &[usize]) -> TrialResult {
        let mut corrections = Vec::new();
        let mut c = 0;
        for i in 0..20 {
            if fixes.contains(&i) {
                c += 1;
            }
            corrections.push(c);
        }
        TrialResult {
            setting: 0,
            trial: t,
            latent: l.to_vec(),
            corrections,
            progress: (0..20).map(|i| 0.5 * (i + 1) as f64).collect(),
            laps: (0..20).map(|i| u32::from(i >= 15 && t == 0)).collect(),
            resets: (0..20)
                .map(|i| (i == 7).then_some(ResetReason::Lost))
                .collect(),
            path: None,
        }
    }

    #[test]
    fn aggregates_match_hand_computed_values() {
        // Two trials of 20 steps: a tenth is 2 steps.
        let mut a = [1.0f32; 20];
        a[0] = 4.0;
        a[1] = 2.0; // first tenth: (4 + 2) / 2 = 3
        a[18] = 0.5;
        a[19] = 0.25; // last tenth: (0.5 + 0.25) / 2 = 0.375
        let mut b = [2.0f32; 20];
        b[0] = 6.0; // first tenth: (6 + 2) / 2 = 4
        b[19] = 0.0; // last tenth: (2 + 0) / 2 = 1
        let ta = trial(0, a, &[0, 1, 5, 19]);
        let tb = trial(1, b, &[1, 2, 3, 18, 19]);
        let agg = aggregate(settings()[0], &[&ta, &tb]);
        assert_eq!(agg.trials, 2);
        // Means and sample standard deviations (n − 1) across the two trials.
        assert_eq!(agg.first_loss, (3.5, std::f64::consts::FRAC_1_SQRT_2));
        assert_eq!(agg.final_loss.0, 0.6875);
        assert!((agg.final_loss.1 - 0.625 * std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
        // Corrections: 4 and 5 in all; 2 and 1 in the first tenth (steps 0–1); 1 and 2 in the
        // last (steps 18–19).
        assert_eq!(agg.total_corrections.0, 4.5);
        assert_eq!(agg.first_tenth_corrections.0, 1.5);
        assert_eq!(agg.last_tenth_corrections.0, 1.5);
        // Task: one trial lapped once; 10 m of progress each; one `lost` reset each.
        assert_eq!((agg.laps.0, agg.lapped), (0.5, 1));
        assert_eq!(agg.progress, (10.0, 0.0));
        assert_eq!(agg.resets, [0.0, 0.0, 1.0, 0.0]);
        // Per step: step 0's loss is the mean of 4 and 6, std √2.
        assert_eq!(agg.loss[0], (5.0, std::f64::consts::SQRT_2));
        assert_eq!(agg.corrections[19], (4.5, std::f64::consts::FRAC_1_SQRT_2));
    }
}
