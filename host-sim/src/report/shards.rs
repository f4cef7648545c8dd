//! A shard's raw results on disk (`--shard i/n`), and the merge that reads them back.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail, ensure};

use super::grid::{Options, SHARD_FORMAT, Setting, Shard, TrialResult, jobs, settings};
use super::paths::PathTrace;
use crate::world::sim::ResetReason;

pub(crate) fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("{}: cannot create", parent.display()))?;
    }
    std::fs::write(path, bytes).with_context(|| format!("{}: cannot write", path.display()))
}

pub(crate) fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))
}

/// Writes a shard's raw results (the paper's grid and the kinds experiment) and its manifest
/// into `dir`.
pub fn write_shard(
    dir: &Path,
    o: &Options,
    shard: Shard,
    results: &[TrialResult],
    kinds: &[super::kinds::KindTrial],
) -> Result<()> {
    super::kinds::write_shard(dir, kinds)?;
    let all = settings();
    for r in results {
        let key = all[r.setting].key();
        let mut csv = String::from("latent_loss,corrections,progress,lap,reset\n");
        for i in 0..r.latent.len() {
            let _ = writeln!(
                csv,
                "{},{},{},{},{}",
                r.latent[i],
                r.corrections[i],
                r.progress[i],
                r.laps[i],
                r.resets[i].map_or("", |x| x.name())
            );
        }
        write_file(
            &dir.join("trials")
                .join(&key)
                .join(format!("{}.csv", r.trial)),
            csv.as_bytes(),
        )?;
        if let Some(p) = &r.path {
            let mut csv = String::from("x,y\n");
            for (x, y) in &p.points {
                let _ = writeln!(csv, "{x},{y}");
            }
            write_file(
                &dir.join("trials").join(&key).join("path.csv"),
                csv.as_bytes(),
            )?;
            write_file(
                &dir.join("trials").join(&key).join("path-end.csv"),
                format!("end,mean_latent_loss\n{},{}\n", p.end, p.mean_latent_loss).as_bytes(),
            )?;
        }
    }
    let manifest = serde_json::json!({
        "format": SHARD_FORMAT,
        "trials": o.trials,
        "steps": o.steps,
        "seed": o.seed,
        "teacher_scale": o.teacher_scale,
        "shard": shard.index,
        "shards": shard.count,
        "jobs": results.len(),
        "settings": all.iter().map(Setting::key).collect::<Vec<_>>(),
        "kind_jobs": kinds.len(),
        "kind_settings": super::kinds::settings().iter().map(|s| s.key()).collect::<Vec<_>>(),
    });
    write_file(
        &dir.join("manifest.json"),
        (serde_json::to_string_pretty(&manifest)? + "\n").as_bytes(),
    )
}

fn read_manifest(dir: &Path) -> Result<(Options, Shard)> {
    let path = dir.join("manifest.json");
    let v: serde_json::Value = serde_json::from_str(&read_text(&path)?)
        .with_context(|| format!("{}: not JSON", path.display()))?;
    let num = |k: &str| {
        v.get(k)
            .and_then(serde_json::Value::as_u64)
            .with_context(|| format!("{}: no number {k:?}", path.display()))
    };
    ensure!(
        num("format")? == SHARD_FORMAT as u64,
        "{}: shard format {} (this build reads {SHARD_FORMAT})",
        path.display(),
        num("format")?
    );
    let keys: Vec<String> = settings().iter().map(Setting::key).collect();
    let kind_keys: Vec<String> = super::kinds::settings().iter().map(|s| s.key()).collect();
    ensure!(
        v.get("settings") == Some(&serde_json::json!(keys))
            && v.get("kind_settings") == Some(&serde_json::json!(kind_keys)),
        "{}: written by a build with other settings",
        path.display()
    );
    let small = |k: &str| -> Result<u32> {
        u32::try_from(num(k)?).with_context(|| format!("{}: {k} too large", path.display()))
    };
    let teacher_scale = v
        .get("teacher_scale")
        .and_then(serde_json::Value::as_f64)
        .with_context(|| format!("{}: no number \"teacher_scale\"", path.display()))?
        as f32;
    let o = Options {
        trials: small("trials")?,
        steps: small("steps")?,
        seed: num("seed")?,
        teacher_scale,
    };
    o.check()
        .with_context(|| format!("{}: bad grid", path.display()))?;
    let (index, count) = (small("shard")?, small("shards")?);
    ensure!(
        count > 0 && index < count,
        "{}: bad shard {index}/{count}",
        path.display()
    );
    Ok((o, Shard { index, count }))
}

/// The per-step columns of one trial's file.
type TrialColumns = (
    Vec<f32>,
    Vec<u32>,
    Vec<f64>,
    Vec<u32>,
    Vec<Option<ResetReason>>,
);

fn parse_trial(path: &Path, steps: u32) -> Result<TrialColumns> {
    let text = read_text(path)?;
    let mut lines = text.lines();
    ensure!(
        lines.next() == Some("latent_loss,corrections,progress,lap,reset"),
        "{}: bad header",
        path.display()
    );
    let mut out: TrialColumns = Default::default();
    for (i, line) in lines.enumerate() {
        let bad = || format!("{}: line {}: bad row {line:?}", path.display(), i + 2);
        let f: Vec<&str> = line.split(',').collect();
        ensure!(f.len() == 5, "{}", bad());
        let l: f32 = f[0]
            .parse()
            .ok()
            .filter(|v: &f32| v.is_finite())
            .with_context(bad)?;
        let p: f64 = f[2]
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .with_context(bad)?;
        let reset = match f[4] {
            "" => None,
            name => Some(ResetReason::from_name(name).with_context(bad)?),
        };
        out.0.push(l);
        out.1.push(f[1].parse().ok().with_context(bad)?);
        out.2.push(p);
        out.3.push(f[3].parse().ok().with_context(bad)?);
        out.4.push(reset);
    }
    ensure!(
        out.0.len() == steps as usize,
        "{}: {} rows, expected {steps}",
        path.display(),
        out.0.len()
    );
    Ok(out)
}

fn parse_path(dir: &Path) -> Result<PathTrace> {
    let path = dir.join("path.csv");
    let text = read_text(&path)?;
    let mut points = Vec::new();
    for (i, line) in text.lines().skip(1).enumerate() {
        let bad = || format!("{}: line {}: bad row {line:?}", path.display(), i + 2);
        let (x, y) = line.split_once(',').with_context(bad)?;
        let x: f64 = x
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .with_context(bad)?;
        let y: f64 = y
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .with_context(bad)?;
        points.push((x, y));
    }
    let end_path = dir.join("path-end.csv");
    let end_text = read_text(&end_path)?;
    let row = end_text
        .lines()
        .nth(1)
        .with_context(|| format!("{}: no row", end_path.display()))?;
    let (end, loss) = row
        .split_once(',')
        .with_context(|| format!("{}: bad row", end_path.display()))?;
    let mean_latent_loss: f64 = loss
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite())
        .with_context(|| format!("{}: bad loss", end_path.display()))?;
    Ok(PathTrace {
        points,
        end: end.to_string(),
        mean_latent_loss,
    })
}

/// The raw results of a grid: options, the paper's trials, the kinds experiment's trials.
pub type Shards = (Options, Vec<TrialResult>, Vec<super::kinds::KindTrial>);

/// Reads shard folders; checks that they are one grid, each shard exactly once.
pub fn read_shards(dirs: &[PathBuf]) -> Result<Shards> {
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
    let mut kinds = Vec::new();
    for (index, dir) in &seen {
        kinds.extend(super::kinds::read_shard(
            dir,
            &o,
            Shard {
                index: *index,
                count: n,
            },
        )?);
        for (s, t) in jobs(
            &o,
            Shard {
                index: *index,
                count: n,
            },
        ) {
            let sdir = dir.join("trials").join(all[s].key());
            let (latent, corrections, progress, laps, resets) =
                parse_trial(&sdir.join(format!("{t}.csv")), o.steps)?;
            let path = if all[s].draw_path && t == 0 {
                Some(parse_path(&sdir)?)
            } else {
                None
            };
            results.push(TrialResult {
                setting: s,
                trial: t,
                latent,
                corrections,
                progress,
                laps,
                resets,
                path,
            });
        }
    }
    results.sort_by_key(|r| (r.setting, r.trial));
    kinds.sort_by_key(|r| (r.setting, r.trial));
    Ok((o, results, kinds))
}
