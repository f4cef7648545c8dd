//! A shard's raw results on disk (`--shard i/n`), and the merge that reads them back.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail, ensure};
use nalgebra::Point2;
use serde::{Deserialize, Serialize};

use super::files::{read_csv, read_text, write_csv, write_file};
use super::grid::{Options, SHARD_FORMAT, Setting, Shard, TrialResult, jobs, settings};
use super::paths::PathTrace;
use crate::world::sim::ResetReason;

/// Writes a shard's raw results and its manifest into `dir`.
pub fn write_shard(dir: &Path, o: &Options, shard: Shard, results: &[TrialResult]) -> Result<()> {
    let all = settings();
    for r in results {
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
    let manifest = Manifest {
        format: SHARD_FORMAT,
        jobs: results.len(),
        seed: o.seed,
        settings: all.iter().map(Setting::key).collect(),
        shard: shard.index,
        shards: shard.count,
        steps: o.steps,
        teacher_scale: o.teacher_scale,
        trials: o.trials,
    };
    write_file(
        &dir.join("manifest.json"),
        (serde_json::to_string_pretty(&manifest)? + "\n").as_bytes(),
    )
}

/// A shard's `manifest.json`: the grid it belongs to and which slice of it it holds. Written
/// last, so a folder without one did not finish. (Fields in alphabetical order: the order of
/// the files written before it was a struct.)
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
    ensure!(
        m.settings == keys,
        "{}: written by a build with other settings",
        path.display()
    );
    let o = Options {
        trials: m.trials,
        steps: m.steps,
        seed: m.seed,
        teacher_scale: m.teacher_scale,
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

/// Reads shard folders; checks that they are one grid, each shard exactly once.
pub fn read_shards(dirs: &[PathBuf]) -> Result<(Options, Vec<TrialResult>)> {
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
        "shards {missing:?} of {n} are missing{unfinished_note}: run `host-sim reproduce --trials {} \
         --steps {} --seed {}{} --shard INDEX/{n}` again for each missing INDEX, then merge again",
        o.trials,
        o.steps,
        o.seed,
        if o.teacher_scale != 1.0 {
            format!(" --teacher-scale {}", o.teacher_scale)
        } else {
            String::new()
        }
    );
    let all = settings();
    let mut results = Vec::new();
    for (index, dir) in &seen {
        for (s, t) in jobs(
            &o,
            Shard {
                index: *index,
                count: n,
            },
        ) {
            let sdir = dir.join("trials").join(all[s].key());
            results.push(read_trial(
                &sdir,
                s,
                t,
                o.steps,
                all[s].draw_path && t == 0,
            )?);
        }
    }
    results.sort_by_key(|r| (r.setting, r.trial));
    Ok((o, results))
}
