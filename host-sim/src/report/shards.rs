//! A shard's raw results on disk (`--shard i/n`), and the merge that reads them back.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail, ensure};
use nalgebra::Point2;
use serde::{Deserialize, Serialize};

use super::aggregate::TrialSummary;
use super::files::{read_csv, read_text, write_csv, write_file};
use super::grid::{
    Job, Options, Results, SHARD_FORMAT, Setting, Shard, TrialResult, jobs, settings,
};
use super::paths::PathTrace;
use super::worlds::{WorldTrial, world_setting_key, world_settings, worlds};
use crate::world::sim::ResetReason;

/// Writes a shard's raw results and its manifest into `dir`.
pub fn write_shard(dir: &Path, o: &Options, shard: Shard, results: &Results) -> Result<()> {
    let all = settings();
    for r in &results.grid {
        let dir = dir.join("trials").join(all[r.setting].key());
        write_csv(
            &dir.join(format!("{}.csv", r.trial)),
            &["latent_loss", "corrections", "progress", "lap", "reset"],
            (0..r.latent.len()).map(|i| {
                [
                    r.latent[i].to_string(),
                    r.corrections[i].to_string(),
                    r.progress[i].to_string(),
                    r.laps[i].to_string(),
                    r.resets[i].map_or("", |x| x.name()).to_string(),
                ]
            }),
        )?;
        if let Some(p) = &r.path {
            write_csv(
                &dir.join("path.csv"),
                &["x", "y"],
                p.points.iter().map(|q| [q.x.to_string(), q.y.to_string()]),
            )?;
            write_csv(
                &dir.join("path-end.csv"),
                &["end", "mean_latent_loss"],
                [[p.end.clone(), p.mean_latent_loss.to_string()]],
            )?;
        }
    }
    if !results.worlds.is_empty() {
        write_worlds(&dir.join("worlds.csv"), o, &results.worlds)?;
    }
    let manifest = Manifest {
        format: SHARD_FORMAT,
        jobs: results.grid.len() + results.worlds.len(),
        seed: o.seed,
        settings: all.iter().map(Setting::key).collect(),
        shard: shard.index,
        shards: shard.count,
        steps: o.steps,
        teacher_scale: o.teacher_scale,
        trials: o.trials,
        world_settings: world_settings().iter().map(world_setting_key).collect(),
        world_trials: o.world_trials,
        worlds: o.worlds,
    };
    write_file(
        &dir.join("manifest.json"),
        (serde_json::to_string_pretty(&manifest)? + "\n").as_bytes(),
    )
}

/// A shard's `manifest.json`: the grid it belongs to and which slice of it it holds. Written
/// last, so a folder without one did not finish.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    /// [`SHARD_FORMAT`].
    format: u32,
    /// Jobs (setting, trial) in the shard.
    jobs: usize,
    /// Seed of trial 0.
    seed: u64,
    /// Every setting's key, in the grid's order: a build with other settings cannot merge.
    settings: Vec<String>,
    /// This shard.
    shard: u32,
    /// Number of shards.
    shards: u32,
    /// Steps per trial.
    steps: u32,
    /// The teachers' scale.
    teacher_scale: f32,
    /// Trials per setting.
    trials: u32,
    /// Every world setting's key, in order.
    world_settings: Vec<String>,
    /// Trials per setting in each world.
    world_trials: u32,
    /// Generated worlds per teacher.
    worlds: u32,
}

/// Just the format of a manifest, read first so that another format is named as such.
#[derive(Deserialize)]
struct Format {
    format: u32,
}

fn read_manifest(dir: &Path) -> Result<(Options, Shard)> {
    let path = dir.join("manifest.json");
    let text = read_text(&path)?;
    let Format { format } = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a shard's manifest", path.display()))?;
    ensure!(
        format == SHARD_FORMAT,
        "{}: shard format {format} (this build reads {SHARD_FORMAT})",
        path.display(),
    );
    let m: Manifest = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a shard's manifest", path.display()))?;
    let keys: Vec<String> = settings().iter().map(Setting::key).collect();
    let world_keys: Vec<String> = world_settings().iter().map(world_setting_key).collect();
    ensure!(
        m.settings == keys && m.world_settings == world_keys,
        "{}: written by a build with other settings",
        path.display()
    );
    let o = Options {
        trials: m.trials,
        steps: m.steps,
        seed: m.seed,
        teacher_scale: m.teacher_scale,
        worlds: m.worlds,
        world_trials: m.world_trials,
    };
    o.check()
        .with_context(|| format!("{}: bad grid", path.display()))?;
    ensure!(
        m.shards > 0 && m.shard < m.shards,
        "{}: bad shard {}/{}",
        path.display(),
        m.shard,
        m.shards
    );
    Ok((
        o,
        Shard {
            index: m.shard,
            count: m.shards,
        },
    ))
}

/// A row of a trial's file.
#[derive(Deserialize)]
struct TrialRow {
    latent_loss: f32,
    corrections: u32,
    progress: f64,
    lap: u32,
    reset: String,
}

/// A row of `path.csv`.
#[derive(Deserialize)]
struct PointRow {
    x: f64,
    y: f64,
}

/// The row of `path-end.csv`.
#[derive(Deserialize)]
struct PathEndRow {
    end: String,
    mean_latent_loss: f64,
}

/// Reads trial `trial` of the setting whose folder is `dir` (and its path when `path`).
fn read_trial(
    dir: &Path,
    setting: usize,
    trial: u32,
    steps: u32,
    path: bool,
) -> Result<TrialResult> {
    let file = dir.join(format!("{trial}.csv"));
    let rows: Vec<TrialRow> = read_csv(&file)?;
    ensure!(
        rows.len() == steps as usize,
        "{}: {} rows, expected {steps}",
        file.display(),
        rows.len()
    );
    let mut r = TrialResult {
        setting,
        trial,
        latent: Vec::with_capacity(rows.len()),
        corrections: Vec::with_capacity(rows.len()),
        progress: Vec::with_capacity(rows.len()),
        laps: Vec::with_capacity(rows.len()),
        resets: Vec::with_capacity(rows.len()),
        path: None,
    };
    for (i, row) in rows.into_iter().enumerate() {
        let bad = || format!("{}: line {}: bad row", file.display(), i + 2);
        ensure!(
            row.latent_loss.is_finite() && row.progress.is_finite(),
            "{}",
            bad()
        );
        let reset = match row.reset.as_str() {
            "" => None,
            name => Some(ResetReason::from_name(name).with_context(bad)?),
        };
        r.latent.push(row.latent_loss);
        r.corrections.push(row.corrections);
        r.progress.push(row.progress);
        r.laps.push(row.lap);
        r.resets.push(reset);
    }
    if path {
        r.path = Some(read_path(dir)?);
    }
    Ok(r)
}

fn read_path(dir: &Path) -> Result<PathTrace> {
    let file = dir.join("path.csv");
    let points: Vec<PointRow> = read_csv(&file)?;
    ensure!(
        points.iter().all(|p| p.x.is_finite() && p.y.is_finite()),
        "{}: a point is not finite",
        file.display()
    );
    let end_file = dir.join("path-end.csv");
    let end: Vec<PathEndRow> = read_csv(&end_file)?;
    let [end] = <[PathEndRow; 1]>::try_from(end)
        .ok()
        .with_context(|| format!("{}: not one row", end_file.display()))?;
    ensure!(
        end.mean_latent_loss.is_finite(),
        "{}: bad loss",
        end_file.display()
    );
    Ok(PathTrace {
        points: points.into_iter().map(|p| Point2::new(p.x, p.y)).collect(),
        end: end.end,
        mean_latent_loss: end.mean_latent_loss,
    })
}

/// The header of a shard's `worlds.csv`.
const WORLD_HEADER: [&str; 16] = [
    "world",
    "name",
    "setting",
    "trial",
    "generated",
    "first_loss",
    "final_loss",
    "corrections",
    "first_tenth_corrections",
    "last_tenth_corrections",
    "laps",
    "progress",
    "resets_collision",
    "resets_stuck",
    "resets_lost",
    "resets_blocked",
];

/// A row of a shard's `worlds.csv`: one trial of a world (zeros when the generator gave no
/// world for the seed).
#[derive(Deserialize)]
struct WorldRow {
    world: usize,
    name: String,
    setting: String,
    trial: u32,
    generated: u8,
    first_loss: f64,
    final_loss: f64,
    corrections: u32,
    first_tenth_corrections: u32,
    last_tenth_corrections: u32,
    laps: u32,
    progress: f64,
    resets_collision: u32,
    resets_stuck: u32,
    resets_lost: u32,
    resets_blocked: u32,
}

fn write_worlds(path: &Path, o: &Options, trials: &[WorldTrial]) -> Result<()> {
    let worlds = worlds(o.worlds);
    let settings = world_settings();
    write_csv(
        path,
        &WORLD_HEADER,
        trials.iter().map(|t| {
            let s = t.summary.unwrap_or(TrialSummary {
                first_loss: 0.0,
                final_loss: 0.0,
                corrections: 0,
                first_tenth_corrections: 0,
                last_tenth_corrections: 0,
                laps: 0,
                progress: 0.0,
                resets: [0; 4],
            });
            let mut row = vec![
                t.world.to_string(),
                worlds[t.world].name(),
                world_setting_key(&settings[t.setting]),
                t.trial.to_string(),
                u8::from(t.summary.is_some()).to_string(),
                s.first_loss.to_string(),
                s.final_loss.to_string(),
                s.corrections.to_string(),
                s.first_tenth_corrections.to_string(),
                s.last_tenth_corrections.to_string(),
                s.laps.to_string(),
                s.progress.to_string(),
            ];
            row.extend(s.resets.iter().map(u32::to_string));
            row
        }),
    )
}

/// The world trials of a shard's `worlds.csv`, checked against the jobs `expected` (world,
/// setting, trial) it must hold.
fn read_worlds(
    dir: &Path,
    o: &Options,
    expected: &[(usize, usize, u32)],
) -> Result<Vec<WorldTrial>> {
    if expected.is_empty() {
        return Ok(Vec::new());
    }
    let path = dir.join("worlds.csv");
    let rows: Vec<WorldRow> = read_csv(&path)?;
    ensure!(
        rows.len() == expected.len(),
        "{}: {} rows, expected {}",
        path.display(),
        rows.len(),
        expected.len()
    );
    let worlds = worlds(o.worlds);
    let settings = world_settings();
    rows.into_iter()
        .zip(expected)
        .enumerate()
        .map(|(i, (r, &(world, setting, trial)))| {
            let line = i + 2;
            ensure!(
                r.world == world
                    && r.name == worlds[world].name()
                    && r.setting == world_setting_key(&settings[setting])
                    && r.trial == trial,
                "{}: line {line}: {} {} trial {}, expected {} {} trial {trial}",
                path.display(),
                r.name,
                r.setting,
                r.trial,
                worlds[world].name(),
                world_setting_key(&settings[setting])
            );
            ensure!(
                r.first_loss.is_finite() && r.final_loss.is_finite() && r.progress.is_finite(),
                "{}: line {line}: a number is not finite",
                path.display()
            );
            Ok(WorldTrial {
                world,
                setting,
                trial,
                summary: (r.generated != 0).then_some(TrialSummary {
                    first_loss: r.first_loss,
                    final_loss: r.final_loss,
                    corrections: r.corrections,
                    first_tenth_corrections: r.first_tenth_corrections,
                    last_tenth_corrections: r.last_tenth_corrections,
                    laps: r.laps,
                    progress: r.progress,
                    resets: [
                        r.resets_collision,
                        r.resets_stuck,
                        r.resets_lost,
                        r.resets_blocked,
                    ],
                }),
            })
        })
        .collect()
}

/// Reads shard folders; checks that they are one grid, each shard exactly once.
pub fn read_shards(dirs: &[PathBuf]) -> Result<(Options, Results)> {
    ensure!(!dirs.is_empty(), "merge needs at least one shard folder");
    let mut grid: Option<(Options, u32)> = None;
    let mut seen = BTreeMap::new();
    // Folders without a manifest: a shard writes it last, so these did not finish (a failed or
    // cancelled job); they are named with the missing shards below.
    let mut unfinished: Vec<String> = Vec::new();
    for d in dirs {
        if d.is_dir() && !d.join("manifest.json").exists() {
            unfinished.push(d.display().to_string());
            continue;
        }
        let (o, shard) = read_manifest(d)?;
        match grid {
            None => grid = Some((o, shard.count)),
            Some((g, n)) => ensure!(
                g == o && n == shard.count,
                "{}: a different grid ({}, {} shards) from the first folder's ({}, {n} shards)",
                d.display(),
                o.describe(),
                shard.count,
                g.describe()
            ),
        }
        if let Some(other) = seen.insert(shard.index, d.clone()) {
            bail!(
                "shard {} given twice: {} and {}",
                shard.index,
                other.display(),
                d.display()
            );
        }
    }
    let unfinished_note = if unfinished.is_empty() {
        String::new()
    } else {
        format!(
            "; {} has no manifest.json (a shard writes it last, so it did not finish)",
            unfinished.join(", ")
        )
    };
    let Some((o, n)) = grid else {
        bail!("no finished shard among the folders{unfinished_note}");
    };
    let missing: Vec<u32> = (0..n).filter(|i| !seen.contains_key(i)).collect();
    ensure!(
        missing.is_empty(),
        "shards {missing:?} of {n} are missing{unfinished_note}: run `host-sim reproduce {} \
         --shard INDEX/{n}` again for each missing INDEX, then merge again",
        o.flags()
    );
    let all = settings();
    let mut results = Results::default();
    for (index, dir) in &seen {
        let mut world_jobs = Vec::new();
        for job in jobs(
            &o,
            Shard {
                index: *index,
                count: n,
            },
        ) {
            match job {
                Job::Grid { setting, trial } => {
                    let sdir = dir.join("trials").join(all[setting].key());
                    let path = all[setting].draw_path && trial == 0;
                    results
                        .grid
                        .push(read_trial(&sdir, setting, trial, o.steps, path)?);
                }
                Job::World {
                    world,
                    setting,
                    trial,
                } => world_jobs.push((world, setting, trial)),
            }
        }
        results.worlds.extend(read_worlds(dir, &o, &world_jobs)?);
    }
    results.grid.sort_by_key(|r| (r.setting, r.trial));
    results
        .worlds
        .sort_by_key(|r| (r.world, r.setting, r.trial));
    Ok((o, results))
}
