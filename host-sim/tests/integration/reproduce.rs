//! `host-sim reproduce` and `host-sim merge`, at a tiny size (2 trials of 40 steps, 3 generated
//! worlds per teacher): every output exists and parses, the report checks every claim, in the
//! paper's households and across the worlds, and merged shards give the same bytes as one
//! machine.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::support::host_sim;
use host_sim::report::claims::{CLAIMS, SHORT};

const TINY: [&str; 6] = ["--trials", "2", "--steps", "40", "--worlds", "3"];

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "stdout: {}\nstderr: {}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

fn reproduce(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["reproduce", "--out", out.to_str().unwrap()];
    args.extend(TINY);
    args.extend(extra);
    host_sim(&args)
}

const CSVS: [&str; 9] = [
    "kinds.csv",
    "kinds_curves.csv",
    "kinds_alpha.csv",
    "variety.csv",
    "noise.csv",
    "noise_sweep.csv",
    "thresholds.csv",
    "summary.csv",
    "paths.csv",
];

const FIGURES: [&str; 12] = [
    "kinds_loss",
    "kinds_corrections",
    "kinds_effort",
    "kinds_progress",
    "task_success",
    "variety",
    "noise",
    "noise_sweep",
    "thresholds",
    "paths_teachers",
    "paths_noise",
    "paths_thresholds",
];

/// Every file below `dir`, relative to it, sorted.
fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p.strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    out.sort();
    out
}

fn outputs() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = CSVS.iter().map(PathBuf::from).collect();
    v.push("REPORT.md".into());
    v.push("worlds.csv".into());
    for f in FIGURES {
        v.push(Path::new("figures").join(format!("{f}.png")));
        v.push(Path::new("figures").join(format!("{f}.svg")));
    }
    v
}

#[test]
fn a_short_reproduction_writes_every_output_and_checks_every_claim() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("r");
    let o = reproduce(&out, &["--jobs", "2"]);
    ok(&o);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("REPORT.md") && stdout.contains("figures"),
        "{stdout}"
    );
    for f in outputs() {
        let p = out.join(&f);
        let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert!(!bytes.is_empty(), "{} is empty", p.display());
        match p.extension().and_then(|e| e.to_str()) {
            Some("png") => assert!(bytes.starts_with(b"\x89PNG"), "{}", p.display()),
            Some("svg") => assert!(
                bytes.starts_with(b"<svg") && bytes.ends_with(b"</svg>\n"),
                "{}",
                p.display()
            ),
            _ => {}
        }
    }
    // Every CSV: a header, rows of as many fields, numbers where the header promises numbers.
    for name in CSVS {
        let text = std::fs::read_to_string(out.join(name)).unwrap();
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let mut rows = 0;
        for line in lines {
            let fields: Vec<&str> = line.split(',').collect();
            assert_eq!(fields.len(), header.len(), "{name}: {line}");
            for (h, v) in header.iter().zip(&fields) {
                let numeric = h.ends_with("_mean")
                    || h.ends_with("_std")
                    || ["step", "sigma", "threshold", "trials", "x", "y", "point"].contains(h);
                if numeric {
                    let x: f64 = v.parse().unwrap_or_else(|_| panic!("{name}: {h} = {v:?}"));
                    assert!(x.is_finite(), "{name}: {h} = {v}");
                }
            }
            rows += 1;
        }
        assert!(rows > 0, "{name} has no rows");
    }
    // Per-step CSVs: one row per step of every setting.
    let variety = std::fs::read_to_string(out.join("variety.csv")).unwrap();
    assert_eq!(variety.lines().count(), 1 + 12 * 40);
    let kinds = host_sim::report::kinds::settings().len();
    let curves = std::fs::read_to_string(out.join("kinds_curves.csv")).unwrap();
    assert_eq!(curves.lines().count(), 1 + kinds * 40);
    let summary = std::fs::read_to_string(out.join("kinds.csv")).unwrap();
    assert_eq!(summary.lines().count(), 1 + kinds);
    let sweep = std::fs::read_to_string(out.join("noise_sweep.csv")).unwrap();
    assert_eq!(
        sweep.lines().count(),
        1 + host_sim::report::grid::NOISE_SWEEP.len()
    );
    // The report names every claim with a verdict, and embeds every PNG.
    let report = std::fs::read_to_string(out.join("REPORT.md")).unwrap();
    for (i, c) in CLAIMS.iter().enumerate() {
        let row = report
            .lines()
            .find(|l| l.starts_with(&format!("| {} | {c} |", i + 1)))
            .unwrap_or_else(|| panic!("claim {c:?} missing from the table"));
        assert!(
            row.ends_with("| **holds** |") || row.ends_with("| **does not hold** |"),
            "{row}"
        );
        assert!(report.contains(&format!("### {}. {c}: **", i + 1)), "{c}");
    }
    for f in FIGURES {
        assert!(report.contains(&format!("(figures/{f}.png)")), "{f}");
    }
    assert!(report.contains("plain online gradient descent"));

    // The claims across worlds: the three households and the basement, and 3 generated worlds
    // for each of the 3 teachers; a row per claim; a picture of the worlds where one fails.
    assert!(
        report.contains("## The claims across worlds")
            && report.contains("worlds × 11 settings × 2 trials"),
        "{report}"
    );
    let worlds = std::fs::read_to_string(out.join("worlds.csv")).unwrap();
    let names: Vec<&str> = worlds
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(names.len(), 4 + 9, "{worlds}");
    assert_eq!(
        &names[..5],
        [
            "doors",
            "stairs-right",
            "stairs-chairs",
            "basement",
            "gen-0/doors"
        ]
    );
    assert_eq!(names[12], "gen-2/stairs-chairs");
    assert!(
        report.contains("Which order breaks, over the 9 generated worlds"),
        "{report}"
    );
    assert_eq!(
        worlds.lines().next().unwrap().split(',').count(),
        4 + 6 + 6 + 2 + 4,
        "{worlds}"
    );
    // Each verdict is the side of its effect size's boundary (effects::effect_holds).
    for line in worlds.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f[3], "1", "every world was made: {line}");
        for i in 0..6 {
            let holds = f[4 + i] == "1";
            let effect: f64 = f[10 + i].parse().unwrap();
            assert_eq!(
                host_sim::report::worlds::effects::effect_holds(i, effect),
                holds,
                "claim {} in {}: effect {effect}",
                i + 1,
                f[0]
            );
        }
    }
    for (i, c) in SHORT.iter().enumerate() {
        let row = report
            .lines()
            .find(|l| l.starts_with(&format!("| {} | {c} |", i + 1)))
            .unwrap_or_else(|| panic!("claim {c:?} missing from the worlds' table"));
        assert!(row.contains(" of 9 ("), "{row}");
        // Either it holds in every generated world, or the worlds where it fails are drawn.
        let holds_everywhere = report.contains(&format!(
            "**{}. {c}**: holds in every generated world.",
            i + 1
        ));
        let picture = format!("figures/worlds_claim{}.png", i + 1);
        assert!(
            holds_everywhere || (report.contains(&picture) && out.join(&picture).exists()),
            "claim {}",
            i + 1
        );
    }

    // The kinds section: every world's table, every kind's α row.
    assert!(report.contains("## Every kind of feedback, and mixed streams (issue 15)"));
    for w in host_sim::report::kinds::KIND_WORLDS {
        assert!(report.contains(&format!("### {w}\n")), "{w}");
    }
    for k in firmware_core::FeedbackKind::ALL {
        assert!(
            report
                .lines()
                .any(|l| l.starts_with(&format!("| {} | ", k.name()))),
            "{}",
            k.name()
        );
    }
}

#[test]
fn merged_shards_are_byte_identical_to_one_machine() {
    let tmp = tempfile::tempdir().unwrap();
    let whole = tmp.path().join("whole");
    let shard_dirs: Vec<PathBuf> = (0..3)
        .map(|i| tmp.path().join(format!("shard{i}")))
        .collect();
    // The whole run and the three shards are four processes that share nothing but the machine:
    // run side by side (each alone is single-threaded most of its time; one after the other they
    // took 11 s of wall time, the longest of this binary's tests).
    std::thread::scope(|scope| {
        scope.spawn(|| ok(&reproduce(&whole, &["--jobs", "1"])));
        for (i, d) in shard_dirs.iter().enumerate() {
            scope.spawn(move || {
                ok(&reproduce(
                    d,
                    &["--shard", &format!("{i}/3"), "--jobs", "2"],
                ))
            });
        }
    });
    for d in &shard_dirs {
        assert!(d.join("manifest.json").exists());
        assert!(
            !d.join("REPORT.md").exists(),
            "a shard writes raw results only"
        );
    }
    let merged = tmp.path().join("merged");
    let mut args = vec!["merge"];
    // Out of order on purpose.
    for d in shard_dirs.iter().rev() {
        args.push(d.to_str().unwrap());
    }
    args.extend(["--out", merged.to_str().unwrap()]);
    ok(&host_sim(&args));
    let written = files(&whole);
    assert_eq!(written, files(&merged), "the same files");
    assert!(written.contains(&PathBuf::from("worlds.csv")));
    for f in written {
        let a = std::fs::read(whole.join(&f)).unwrap();
        let b = std::fs::read(merged.join(&f)).unwrap();
        assert!(
            a == b,
            "{} differs between one machine and merged shards",
            f.display()
        );
    }

    // A missing shard, a shard given twice and shards of different grids are refused.
    let out = tmp.path().join("bad");
    let s = |i: usize| shard_dirs[i].to_str().unwrap();
    let o = host_sim(&["merge", s(0), s(1), "--out", out.to_str().unwrap()]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("shards [2] of 3 are missing"), "{e}");
    assert!(e.contains("--shard INDEX/3` again"), "{e}");
    // A shard that did not finish (its folder without a manifest, as a failed SLURM task leaves
    // it) is named beside the missing index, so `sbatch --dependency=afterany` can merge.
    let failed = tmp.path().join("failed");
    std::fs::create_dir_all(failed.join("trials")).unwrap();
    let o = host_sim(&[
        "merge",
        s(0),
        s(1),
        failed.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("shards [2] of 3 are missing")
            && e.contains("failed has no manifest.json (a shard writes it last"),
        "{e}"
    );
    let o = host_sim(&[
        "merge",
        s(0),
        s(0),
        s(1),
        s(2),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("given twice"));
    let other = tmp.path().join("other");
    ok(&host_sim(&[
        "reproduce",
        "--trials",
        "1",
        "--steps",
        "40",
        "--worlds",
        "3",
        "--shard",
        "0/3",
        "--out",
        other.to_str().unwrap(),
    ]));
    let o = host_sim(&[
        "merge",
        other.to_str().unwrap(),
        s(1),
        s(2),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("different grid"));
}

#[test]
fn bad_options_are_clear_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["reproduce", "--shard", "3/3", "--out", out],
            "shard must be",
        ),
        (
            &["reproduce", "--shard", "a/b", "--out", out],
            "shard must be",
        ),
        (
            &["reproduce", "--trials", "0", "--out", out],
            "'--trials <TRIALS>': must be in 1..=10000, got 0",
        ),
        (
            &["reproduce", "--steps", "5", "--out", out],
            "'--steps <STEPS>': must be in 10..=10000000, got 5",
        ),
        (
            &["reproduce", "--jobs", "0", "--out", out],
            "'--jobs <JOBS>': must be in 1..=1024, got 0",
        ),
        (
            &["reproduce", "--world-trials", "0", "--out", out],
            "'--world-trials <WORLD_TRIALS>': must be in 1..=100, got 0",
        ),
        (&["merge", "/no/such/dir", "--out", out], "cannot read"),
    ];
    for (args, want) in cases {
        let o = host_sim(args);
        assert!(!o.status.success(), "{args:?} should fail");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(want), "{args:?}: wanted {want:?} in {e}");
    }
}
