//! `host-sim reproduce` and `host-sim merge`: the paper's section 6, end to end.
//!
//! # The trial grid
//!
//! A **setting** is one curve of the paper: a household, a way of teaching, a teacher noise σ and
//! threshold. [`settings`](grid::settings) lists them in a fixed order:
//!
//! * **variety**: action, preference and semantic feedback, and behaviour cloning, in each of
//!   `doors`, `stairs-right` and `stairs-chairs` (σ = 0, threshold 1.0);
//! * **noise**: action feedback in `doors`, threshold 1.0, σ from 0 to 2.0 in steps of 0.125
//!   ([`NOISE_SWEEP`](grid::NOISE_SWEEP)); the curves of σ = 0, 0.25, 0.5, 1.0 are the paper's figure, the whole
//!   sweep gives the final latent loss against σ;
//! * **thresholds**: action feedback in `stairs-chairs`, σ = 0, the paper's thresholds 0, 0.25,
//!   0.5, 0.75, 1.0 and, so that the whole regime is visible, 2, 4 and 8 ([`THRESHOLDS`](grid::THRESHOLDS)).
//!
//! Each setting runs `trials` trials; trial `t` has seed `seed + t` (the same seeds in every
//! setting: common random numbers make the comparisons between settings less noisy). A seed
//! drives the teacher's noise and random preference queries and the start-pose jitter
//! ([`StartJitter::REPRODUCE`](crate::teach::experiment::StartJitter::REPRODUCE)), so trials differ even with a noiseless teacher. Every run uses
//! **the paper's learner, plain OGD with a constant step of 0.01** ([`paper_learner`](grid::paper_learner)), not the
//! crate's default averaged OGD, the paper's semantic teacher (doors, stairs, chairs and the path
//! by cross-track error; [`crate::world::teacher::StatementSet::Paper`]) and the teachers calibrated by
//! `host-sim calibrate` ([`crate::teach::calibrate`]), optionally all multiplied by
//! [`Options::teacher_scale`] (the scale sweep, [`scale_sweep`]).
//!
//! A **job** is one (setting, trial); jobs are numbered setting-major. Job `k` belongs to shard
//! `k mod n` of `--shard i/n` (round robin, so each shard gets a share of every experiment).
//!
//! # Paths
//!
//! For the path figures, trial 0 of the noise settings σ = 0, 1, 2 and of every threshold drives
//! one more lap after training: its final learner, frozen, from the scenario's own start (no
//! jitter), until a lap is done, the car is reset, or [`PATH_TICKS`](grid::PATH_TICKS) ticks. The teacher's own
//! policy drives the same way on each household. The mean true latent loss along the drawn lap
//! is reported beside it, with how the lap ended.
//!
//! # Outputs (`finalize`)
//!
//! `variety.csv`, `noise.csv`, `thresholds.csv` (per step: mean and sample standard deviation
//! across trials of the latent loss, of the cumulative corrections and of the progress along the
//! path), `noise_sweep.csv` (final latent loss and corrections against σ), `summary.csv` (one
//! row per setting, task success included), `paths.csv`, `figures/*.png` and `figures/*.svg`,
//! and `REPORT.md`: the calibration of the teachers, then the paper's claims
//! ([`crate::report::claims::CLAIMS`]) checked with these numbers, then the tables and figures. The
//! **final latent loss** of a trial is its mean latent loss over the last tenth of the steps (one
//! step's loss depends on where the car happens to be); the report gives its mean and standard
//! deviation across trials. **Task success** is reported beside it: laps, progress along the path
//! (metres: laps times the path's length plus the current lap's progress; a reset takes back its
//! lap's progress) and resets by cause. Nothing in these files depends on the
//! machine, the number of threads or the sharding: a merged result is byte-identical to a
//! one-machine run. The wall time is printed, never written into them.
//!
//! # Shards
//!
//! `--shard i/n` writes only its jobs' raw results: `manifest.json` and
//! `trials/KEY/TRIAL.csv` (`latent_loss,corrections,progress,lap,reset` per step; floats in
//! Rust's shortest round-trip form, so nothing is lost), plus `trials/KEY/path.csv` and
//! `path-end.csv` for the path runs. `host-sim merge DIR... --out DIR` checks that the shards
//! belong to one grid and cover it exactly once, reads them and writes the outputs above.
//!
//! # The files
//!
//! * [`grid`]: the settings, the options, the shards and the jobs that run them.
//! * [`shards`]: a shard's raw results on disk, and the merge that reads them back.
//! * [`statistics`]: means, standard deviations, rank correlations, the normal tail, smoothing.
//! * [`aggregate`]: one setting across its trials.
//! * [`claims`]: the paper's claims, one pure function each.
//! * [`paths`]: the laps drawn on the maps.
//! * [`raster`]: the one raster and PNG encoder of every picture; [`figure`] (charts, sheets of
//!   pictures), [`plot`] (the lattice, maps) and [`panels`] (the report's panels) draw on it.
//! * [`outputs`]: every file of a finished grid; [`sections`]: the report's text.
//! * [`worlds`]: the claims across worlds: every claim in each of many generated households,
//!   with intervals (`--worlds K`).
//! * [`sweep`]: the claims at other scales of the teachers.
//! * [`registry`]: the paper's experiments by name (`host-sim list`).
//! * [`run_figure`]: the figure of one `host-sim run`; [`run_folder`]: a run's folder read back;
//!   [`animation`]: a run as an animated picture (`host-sim draw --run DIR --animate FILE`).

pub mod aggregate;
pub mod animation;
pub mod claims;
pub mod figure;
pub mod files;
pub mod grid;
pub mod outputs;
pub mod panels;
pub mod paths;
pub mod plot;
pub mod raster;
pub mod registry;
pub mod run_figure;
pub mod run_folder;
pub mod sections;
pub mod shards;
pub mod statistics;
pub mod sweep;
pub mod worlds;

pub use grid::{Options, Shard, jobs, run_shard};
pub use outputs::finalize;
pub use shards::{read_shards, write_shard};
pub use sweep::{scale_sweep, scale_sweep_markdown};
