//! The `host-sim` command: outputs, help, and clear errors with a non-zero exit.

use crate::support::{host_sim, stderr};
use std::process::{Command, Output};

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
    assert_eq!(summary["final_weights"].as_object().unwrap().len(), 6);
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
            "'--steps <STEPS>': must be in 1..=10000000, got 0",
        ),
        (
            &["run", "--noise", "-1", "--out", out],
            "'--noise <NOISE>': must be in [0, 1000], got -1",
        ),
        (
            &["run", "--threshold", "NaN", "--out", out],
            "'--threshold <THRESHOLD>': must be in [0, 1000], got NaN",
        ),
        (
            &["run", "--feedback", "shouting", "--out", out],
            "invalid value 'shouting' for '--feedback <FEEDBACK>'",
        ),
        (
            &["run", "--learner", "sgd", "--out", out],
            "[possible values: ogd, ogd-decaying, averaged-ogd, adagrad, coactive]",
        ),
        (
            &["run", "--step", "-0.5", "--out", out],
            "'--step <STEP>': must be in (0, 1000], got -0.5",
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
    // Its axes say 0.0, never -0.0, and a legend names the two families.
    assert!(text.contains("\n0.0\n") && !text.contains("-0.0"), "{text}");
    assert!(
        text.contains("cruise: actions 0–48, 1.0 m at 1.0 m/s"),
        "{text}"
    );
    assert!(text.contains("creep: actions 49–63, 0.5 m"), "{text}");
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

#[test]
fn bench_times_each_run_and_sums_them_up() {
    let o = host_sim(&["bench", "--steps", "300", "--runs", "3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 5, "{out}");
    assert!(
        lines[0].starts_with("doors: 300 simulated steps (action feedback, ")
            && lines[0].ends_with("corrections), 3 runs"),
        "{out}"
    );
    for (i, line) in lines[1..4].iter().enumerate() {
        assert!(line.starts_with(&format!("  run {}: ", i + 1)), "{out}");
    }
    // Best, median and worst, in that order (the best the most steps a second).
    let rates: Vec<f64> = lines[4]
        .split(": ")
        .nth(1)
        .unwrap()
        .split(", ")
        .map(|part| part.rsplit(' ').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(rates.len(), 3, "{out}");
    assert!(
        rates[0] >= rates[1] && rates[1] >= rates[2] && rates[2] > 0.0,
        "{out}"
    );
    assert!(lines[4].starts_with("steps per second"), "{out}");
}

/// Runs `host-sim args` with its standard output a pipe whose reader has gone.
fn into_closed_pipe(args: &[&str]) -> Output {
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary runs");
    drop(child.stdout.take());
    child.wait_with_output().expect("the binary ends")
}

/// `host-sim list | head -1` and the like: a reader that goes away ends the command quietly.
#[test]
fn a_closed_pipe_ends_a_command_quietly() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("r");
    for args in [
        &["list"][..],
        &["demo", "--steps", "300"],
        &["run", "--steps", "30", "--out", out.to_str().unwrap()],
        &[
            "lattice",
            "--out",
            tmp.path().join("l.svg").to_str().unwrap(),
        ],
    ] {
        let o = into_closed_pipe(args);
        assert!(
            o.status.success(),
            "{args:?}: {:?} {}",
            o.status,
            stderr(&o)
        );
        assert_eq!(stderr(&o), "", "{args:?}");
    }
    // The run wrote its files before it found nobody reading.
    assert!(out.join("steps.csv").is_file() && out.join("summary.json").is_file());
}

/// A cause is said once, not once per layer of context.
#[test]
fn an_error_says_its_cause_once() {
    let tmp = tempfile::tempdir().unwrap();
    let scenario = tmp.path().join("s.toml");
    std::fs::write(
        &scenario,
        "map = \"missing.yaml\"\n[path]\nwaypoints = [[0, 0], [1, 1]]\n[teacher]\npreset = \"doors\"\n",
    )
    .unwrap();
    let o = host_sim(&[
        "run",
        "--scenario",
        scenario.to_str().unwrap(),
        "--out",
        tmp.path().join("o").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert_eq!(e.matches("cannot read").count(), 1, "{e}");
    assert_eq!(e.matches("os error 2").count(), 1, "{e}");
    assert!(e.contains("s.toml: map: ") && e.contains("missing.yaml: cannot read: No such file"));
}

/// The TOML parser's own layout: the line, a caret under the column, then what is wrong.
#[test]
fn a_toml_error_keeps_its_lines() {
    let tmp = tempfile::tempdir().unwrap();
    let scenario = tmp.path().join("bad.toml");
    std::fs::write(
        &scenario,
        "map = \"m.yaml\"\n[teacher]\nthreshold = = 1.0\n",
    )
    .unwrap();
    let o = host_sim(&["run", "--scenario", scenario.to_str().unwrap()]);
    assert!(!o.status.success());
    let e = stderr(&o);
    let lines: Vec<&str> = e.lines().collect();
    assert!(
        lines[0].ends_with("bad.toml: TOML parse error at line 3, column 13"),
        "{e}"
    );
    assert!(lines.contains(&"3 | threshold = = 1.0"), "{e}");
    assert!(
        lines
            .iter()
            .any(|l| l.trim_end().ends_with("|             ^")),
        "{e}"
    );
    assert!(!e.contains(" | 3 | "), "squashed onto one line: {e}");
}

/// A run that fails after its output folder was made (here: no key for its link) removes the
/// folders it made, and nothing else.
#[test]
fn a_failed_run_leaves_no_empty_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let key = tmp.path().join("no.key");
    let run = |out: &std::path::Path| {
        let o = host_sim(&[
            "run",
            "--steps",
            "10",
            "--link",
            "udp://127.0.0.1:9",
            "--key",
            key.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(!o.status.success());
        assert!(stderr(&o).contains("no.key"), "{}", stderr(&o));
    };
    run(&tmp.path().join("new/deeper/run"));
    assert!(!tmp.path().join("new").exists(), "left behind");
    // A folder that was there before stays.
    let existing = tmp.path().join("kept");
    std::fs::create_dir(&existing).unwrap();
    run(&existing);
    assert!(existing.is_dir());
}

/// `run` names the final weights by feature, in what it prints and in summary.json, writes its
/// figure, and records its scenario's file.
#[test]
fn run_names_its_weights_and_draws_its_figure() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("r");
    let o = host_sim(&["run", "--steps", "100", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    let line = stdout
        .lines()
        .find(|l| l.starts_with("final weights: "))
        .unwrap();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for name in ["obstacles", "door", "stairs", "chair", "path", "right"] {
        let w = summary["final_weights"][name].as_f64().unwrap() as f32;
        assert!(line.contains(&format!("{name} {w}")), "{name}: {line}");
        assert!(summary["config"]["teacher_weights"][name].is_number());
    }
    let file = summary["config"]["scenario_file"].as_str().unwrap();
    assert!(file.ends_with("scenarios/doors.toml"), "{file}");
    for f in ["run.png", "run.svg"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    assert!(
        std::fs::read(out.join("run.png"))
            .unwrap()
            .starts_with(b"\x89PNG")
    );
}

/// `draw --run DIR` draws a run on its own scenario and refuses another one.
#[test]
fn draw_refuses_a_run_of_another_scenario() {
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("doors_out");
    let o = host_sim(&["run", "--steps", "50", "--out", run.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let png = tmp.path().join("d.png");
    let o = host_sim(&[
        "draw",
        "--scenario",
        "stairs-right",
        "--run",
        run.to_str().unwrap(),
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("is of scenario doors") && stderr(&o).contains("not stairs-right"),
        "{}",
        stderr(&o)
    );
    assert!(!png.exists());
    for scenario in [&["--scenario", "doors"][..], &[]] {
        let mut args = vec!["draw", "--run", run.to_str().unwrap()];
        args.extend_from_slice(scenario);
        args.extend_from_slice(&["--out", png.to_str().unwrap()]);
        let o = host_sim(&args);
        assert!(o.status.success(), "{scenario:?}: {}", stderr(&o));
        assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    }
}

/// `draw --run DIR --animate OUT`: an APNG of the expected frames and size.
#[test]
fn animate_writes_the_expected_frames() {
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("run");
    let o = host_sim(&["run", "--steps", "60", "--out", run.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let apng = tmp.path().join("run.png");
    let o = host_sim(&[
        "draw",
        "--run",
        run.to_str().unwrap(),
        "--animate",
        apng.to_str().unwrap(),
        "--from",
        "10",
        "--every",
        "4",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Ticks 10..60 at 4 a frame: 13 frames.
    let said = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(said.contains("13 frames of 544 × 282 pixels"), "{said}");
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&apng).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let info = reader.info();
    assert_eq!((info.width, info.height), (544, 282));
    assert_eq!(info.animation_control.map(|a| a.num_frames), Some(13));
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let mut frames = 0;
    while reader.next_frame(&mut buf).is_ok() {
        frames += 1;
    }
    assert_eq!(frames, 13);
}

/// `--save-learner` keeps what was learned; `--load-learner` starts from it in another household;
/// another version or a corrupted file is refused with a message.
#[test]
fn a_learner_is_saved_and_loaded_and_a_bad_file_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("doors.learner");
    let f = file.to_str().unwrap();
    let out = |n: &str| tmp.path().join(n).to_str().unwrap().to_string();
    let o = host_sim(&[
        "run",
        "--steps",
        "300",
        "--learner",
        "adagrad",
        "--save-learner",
        f,
        "--out",
        &out("a"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("saved the learner (adagrad, "));
    let taught: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("a/summary.json")).unwrap())
            .unwrap();
    let o = host_sim(&[
        "run",
        "--scenario",
        "stairs-right",
        "--steps",
        "50",
        "--load-learner",
        f,
        "--out",
        &out("b"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let tested: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("b/summary.json")).unwrap())
            .unwrap();
    assert_eq!(tested["config"]["learner"], "adagrad");
    assert_eq!(
        tested["config"]["loaded_learner"]["weights"],
        taught["final_weights"]
    );
    assert_eq!(
        tested["config"]["loaded_learner"]["learner_steps"],
        taught["learner_steps"]
    );

    let good = std::fs::read(&file).unwrap();
    let refused = |bytes: &[u8], want: &str| {
        let bad = tmp.path().join("bad.learner");
        std::fs::write(&bad, bytes).unwrap();
        let o = host_sim(&[
            "run",
            "--load-learner",
            bad.to_str().unwrap(),
            "--out",
            &out("c"),
        ]);
        assert!(!o.status.success(), "{want}");
        assert!(
            stderr(&o).contains(want),
            "wanted {want:?} in {}",
            stderr(&o)
        );
        assert!(!tmp.path().join("c").exists(), "{want}: an output folder");
    };
    let mut corrupted = good.clone();
    let n = corrupted.len();
    corrupted[n / 2] ^= 0x01;
    refused(&corrupted, "corrupted (its CRC does not match its bytes)");
    refused(&good[..10], "corrupted (shorter than a snapshot)");
    refused(b"weights = [1, 2, 3]\n", "not a learner file");
    // Another snapshot version, its CRC made right: the version is the payload's first byte.
    let mut other = good.clone();
    other[9] = 9;
    let crc = crc16(&other[8..n - 2]);
    other[n - 2..].copy_from_slice(&crc.to_le_bytes());
    refused(
        &other,
        "a learner snapshot of format version 9; this build reads version 1",
    );
    // A loaded learner is the learner: not with --learner, not for behaviour cloning.
    let o = host_sim(&["run", "--load-learner", f, "--learner", "ogd"]);
    assert!(!o.status.success() && stderr(&o).contains("cannot be used with"));
    let o = host_sim(&[
        "run",
        "--load-learner",
        f,
        "--feedback",
        "bc",
        "--out",
        &out("d"),
    ]);
    assert!(!o.status.success() && stderr(&o).contains("a loaded learner is taught online"));
}

/// CRC-16/IBM-3740, the learner file's (the protocol envelope's).
fn crc16(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &b in bytes {
        crc ^= (b as u16) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                crc << 1 ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// doors.toml with its teacher's `key = value` replaced, written into `dir`.
fn doors_with(dir: &std::path::Path, key: &str, value: &str) -> std::path::PathBuf {
    let scenarios = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let text = std::fs::read_to_string(scenarios.join("doors.toml")).unwrap();
    let maps = scenarios.join("maps/doors.yaml");
    let text = text
        .replace(
            "map = \"maps/doors.yaml\"",
            &format!("map = {:?}", maps.display().to_string()),
        )
        .replace(
            &format!("{key} = {}", if key == "noise" { "0.0" } else { "1.0" }),
            &format!("{key} = {value}"),
        );
    assert!(text.contains(&format!("{key} = {value}")));
    let file = dir.join(format!("{key}.toml"));
    std::fs::write(&file, text).unwrap();
    file
}

/// One set of checks, one wording: a bad threshold or noise says the same from a flag and from
/// a scenario file.
#[test]
fn a_bad_value_says_the_same_from_a_flag_and_from_a_scenario() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    for (key, value, want) in [
        ("threshold", "1e30", "must be in [0, 1000], got 1e30"),
        ("noise", "1e30", "must be in [0, 1000], got 1e30"),
        ("threshold", "-1", "must be in [0, 1000], got -1"),
        ("noise", "nan", "must be in [0, 1000], got NaN"),
        ("threshold", "1001", "must be in [0, 1000], got 1001"),
    ] {
        let flag = format!("--{key}");
        let o = host_sim(&["run", &flag, value, "--out", out.to_str().unwrap()]);
        assert!(!o.status.success(), "{flag} {value}");
        let from_flag = stderr(&o);
        assert!(
            from_flag.contains(&format!("'{value}' for '{flag} <")),
            "{from_flag}"
        );
        let file = doors_with(tmp.path(), key, value);
        let o = host_sim(&[
            "run",
            "--scenario",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(!o.status.success(), "teacher.{key} = {value}");
        let from_file = stderr(&o);
        assert!(
            from_file.contains(&format!("{key}.toml: teacher.{key}: ")),
            "{from_file}"
        );
        // The same words after the value's name.
        let said = |e: &str, after: &str| {
            let rest = &e[e.find(after).unwrap() + after.len()..];
            rest.lines().next().unwrap().to_string()
        };
        assert_eq!(
            said(&from_flag, &format!("{flag} <{}>': ", key.to_uppercase())),
            want
        );
        assert_eq!(said(&from_file, &format!("teacher.{key}: ")), want);
        assert!(!out.exists());
    }
}

/// Each number a flag takes is checked before the command starts, against its real limits,
/// with the number named.
#[test]
fn flags_are_checked_before_anything_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o");
    let o_ = out.to_str().unwrap();
    for (args, want) in [
        (
            &["run", "--steps", "99999999999", "--out", o_][..],
            "must be in 1..=10000000, got 99999999999",
        ),
        (
            &["run", "--steps", "-3", "--out", o_],
            "must be in 1..=10000000, got -3",
        ),
        (
            &["run", "--step", "nan", "--out", o_],
            "'--step <STEP>': must be in (0, 1000], got NaN",
        ),
        (
            &["run", "--random-answers", "1.5", "--out", o_],
            "must be in [0, 1], got 1.5",
        ),
        (
            &["demo", "--noise", "-1"],
            "'--noise <NOISE>': must be in [0, 1], got -1",
        ),
        (
            &["demo", "--threshold", "nan"],
            "'--threshold <THRESHOLD>': must be in [0, 1000], got NaN",
        ),
        (&["demo", "--steps", "0"], "must be in 1..=10000000, got 0"),
        (&["bench", "--steps", "0"], "must be in 1..=10000000, got 0"),
        (&["bench", "--runs", "0"], "must be in 1..=1000, got 0"),
        (
            &["reproduce", "--steps", "5", "--out", o_],
            "must be in 10..=10000000, got 5",
        ),
        (
            &["reproduce", "--jobs", "0", "--out", o_],
            "'--jobs <JOBS>': must be in 1..=1024, got 0",
        ),
        (
            &["reproduce", "--teacher-scale", "-2", "--out", o_],
            "must be in (0, 1000], got -2",
        ),
        (
            &["learners", "--seeds", "101", "--out", o_],
            "must be in 1..=100, got 101",
        ),
    ] {
        let o = host_sim(args);
        assert!(!o.status.success(), "{args:?}");
        assert!(
            stderr(&o).contains(want),
            "{args:?}: wanted {want:?} in {}",
            stderr(&o)
        );
        assert!(o.stdout.is_empty(), "{args:?} printed before its error");
        assert!(!out.exists(), "{args:?}");
    }
}

/// `merge` of shards of two grids says which grids, in words.
#[test]
fn merge_names_two_grids_in_words() {
    let tmp = tempfile::tempdir().unwrap();
    let shard = |steps: &str, index: &str| {
        let dir = tmp.path().join(format!("s{steps}-{index}"));
        let o = host_sim(&[
            "reproduce",
            "--trials",
            "1",
            "--steps",
            steps,
            "--worlds",
            "0",
            "--shard",
            &format!("{index}/40"),
            "--out",
            dir.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        dir
    };
    let (a, b) = (shard("30", "0"), shard("20", "1"));
    let o = host_sim(&[
        "merge",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--out",
        tmp.path().join("m").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("a different grid (1 trials × 20 steps, seed 0, 40 shards) from the first folder's (1 trials × 30 steps, seed 0, 40 shards)"),
        "{e}"
    );
    assert!(!e.contains("Options {"), "{e}");
}
