//! The `host-sim` command: outputs, help, and clear errors with a non-zero exit.

use std::process::{Command, Output};

fn host_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn run_writes_the_csv_and_the_summary() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("new/folder");
    let o = host_sim(&[
        "run",
        "--scenario",
        "doors",
        "--feedback",
        "semantic",
        "--steps",
        "120",
        "--seed",
        "3",
        "--threshold",
        "0.5",
        "--noise",
        "0.25",
        "--learner",
        "ogd",
        "--step",
        "0.02",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("steps.csv")).unwrap();
    let lines: Vec<_> = csv.lines().collect();
    assert_eq!(lines.len(), 121);
    assert_eq!(
        lines[0],
        "step,action,teacher_action,latent_loss,corrected,corrections,collision,reset,lap,progress,x,y,theta,feedback,effort_s"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["config"]["feedback"], "semantic");
    assert_eq!(summary["config"]["learner"], "ogd");
    assert_eq!(summary["seed"], 3);
    assert_eq!(summary["config"]["threshold"], 0.5);
    assert_eq!(summary["final_weights"].as_array().unwrap().len(), 6);
    for key in [
        "mean_latent_loss_first_10pct",
        "mean_latent_loss_last_10pct",
        "corrections",
        "collisions",
        "laps",
        "wall_time_s",
    ] {
        assert!(summary.get(key).is_some(), "summary lacks {key}");
    }
}

/// The line `run` prints and `summary.json` count resets by cause, as the CSV's rows do: here a
/// semantic learner early in its training, put back at the start when every trajectory collides.
#[test]
fn run_counts_resets_by_cause_in_its_line_and_its_summary() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("r");
    let o = host_sim(&[
        "run",
        "--scenario",
        "doors",
        "--feedback",
        "semantic",
        "--learner",
        "averaged-ogd",
        "--steps",
        "1000",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let line = String::from_utf8_lossy(&o.stdout)
        .lines()
        .next()
        .unwrap()
        .to_string();
    let csv = std::fs::read_to_string(out.join("steps.csv")).unwrap();
    let count = |cause: &str| {
        csv.lines()
            .skip(1)
            .filter(|l| l.split(',').nth(7) == Some(cause))
            .count()
    };
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let causes = ["collision", "stuck", "lost", "blocked"];
    assert!(
        causes.iter().map(|c| count(c)).sum::<usize>() >= 1,
        "the run this test needs has a reset"
    );
    for cause in causes {
        let n = count(cause);
        assert!(line.contains(&format!("{n} {cause}")), "{cause}: {line}");
        assert_eq!(summary["resets"][cause], n as u64, "{cause}");
    }
    assert!(line.contains(" m of progress"), "{line}");
    let progress = summary["totals"]["progress_m"].as_f64().unwrap();
    let last: f64 = csv
        .lines()
        .last()
        .unwrap()
        .split(',')
        .nth(9)
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        (progress - last).abs() < 1e-3 && progress > 10.0,
        "{progress} {last}"
    );
}

#[test]
fn bad_input_is_a_clear_error_and_a_failure_exit() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["run", "--scenario", "kitchen", "--out", out],
            "unknown scenario \"kitchen\"",
        ),
        (
            &["run", "--scenario", "/no/such/file.toml", "--out", out],
            "file.toml: cannot read",
        ),
        (
            &["run", "--steps", "many", "--out", out],
            "invalid value 'many'",
        ),
        (
            &["run", "--steps", "0", "--out", out],
            "steps must be in 1..=",
        ),
        (
            &["run", "--noise", "-1", "--out", out],
            "noise must be finite and >= 0",
        ),
        (
            &["run", "--threshold", "NaN", "--out", out],
            "threshold must be finite",
        ),
        (
            &["run", "--feedback", "shouting", "--out", out],
            "unknown feedback 'shouting'",
        ),
        (
            &["run", "--learner", "sgd", "--out", out],
            "unknown learner 'sgd'",
        ),
        (
            &["run", "--step", "-0.5", "--out", out],
            "learner parameters",
        ),
    ];
    for (args, want) in cases {
        let o = host_sim(args);
        assert!(!o.status.success(), "{args:?} should fail");
        let e = stderr(&o);
        assert!(e.contains(want), "{args:?}: wanted {want:?} in {e:?}");
    }
    // An output "folder" that is a file.
    let file = tmp.path().join("plain-file");
    std::fs::write(&file, "x").unwrap();
    let o = host_sim(&["run", "--steps", "5", "--out", file.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("output folder"), "{}", stderr(&o));
}

#[test]
fn help_explains_every_option() {
    let o = host_sim(&["run", "--help"]);
    assert!(o.status.success());
    let help = String::from_utf8_lossy(&o.stdout);
    for opt in [
        "--scenario",
        "--feedback",
        "--steps",
        "--seed",
        "--threshold",
        "--noise",
        "--learner",
        "--step",
        "--out",
    ] {
        assert!(help.contains(opt), "help lacks {opt}");
    }
    assert!(help.contains("behaviour cloning") && help.contains("steps.csv"));
}

#[test]
fn lattice_list_and_demo_still_work() {
    let tmp = tempfile::tempdir().unwrap();
    let svg = tmp.path().join("lattice.svg");
    let o = host_sim(&["lattice", "--out", svg.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg") && text.matches("<polyline").count() >= 64);
    let o = host_sim(&["list"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("stairs-chairs"));
    let png = tmp.path().join("doors.png");
    let o = host_sim(&[
        "draw",
        "--scenario",
        "doors",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    let o = host_sim(&["demo", "--steps", "300"]);
    assert!(o.status.success(), "{}", stderr(&o));
}
