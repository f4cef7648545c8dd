//! Scenario files: the built-in ones load and meet their specification; bad files are errors
//! naming the field.

use std::path::Path;

use host_sim::world::registry;
use host_sim::world::scenario::Scenario;

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A valid scenario on a 6 m × 4 m room, with `extra` appended.
fn room(dir: &Path, extra: &str) -> String {
    // A free room with a wall border, 0.1 m/px.
    let (w, h) = (60usize, 40usize);
    let mut pgm = format!("P5\n{w} {h}\n255\n").into_bytes();
    for r in 0..h {
        for c in 0..w {
            let wall = r < 2 || c < 2 || r >= h - 2 || c >= w - 2;
            pgm.push(if wall { 0 } else { 254 });
        }
    }
    std::fs::write(dir.join("room.pgm"), pgm).unwrap();
    write(
        dir,
        "room.yaml",
        "image: room.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n",
    );
    format!(
        "map = \"room.yaml\"\n[path]\nwaypoints = [[1.0, 1.0], [5.0, 1.0], [5.0, 3.0], [1.0, 3.0]]\n[teacher]\npreset = \"doors\"\n{extra}"
    )
}

fn err(extra: &str) -> String {
    let tmp = tempfile::tempdir().unwrap();
    let text = room(tmp.path(), extra);
    let p = write(tmp.path(), "s.toml", &text);
    let e = Scenario::load(&p).unwrap_err().to_string();
    assert!(e.contains("s.toml"), "names the file: {e}");
    e
}

#[test]
fn the_built_in_scenarios_load_with_long_paths() {
    for s in registry::SCENARIOS {
        let scn = registry::load_scenario(s.name).unwrap();
        assert_eq!(scn.name, s.name);
        assert!(scn.path.is_closed(), "{}", s.name);
        assert!(
            scn.path.length() >= 30.0,
            "{}: path {} m, at least 30 m wanted",
            s.name,
            scn.path.length()
        );
        assert!(!scn.objects.is_empty());
        assert_eq!(scn.teacher.threshold, 1.0);
        assert_eq!(scn.teacher.noise, 0.0);
    }
    let doors = registry::load_scenario("doors").unwrap();
    assert_eq!(doors.teacher.preset, Some("doors"));
    assert!(registry::load_scenario("no-such-household").is_err());
}

#[test]
fn a_user_scenario_with_explicit_weights_and_a_rectangle_loads() {
    let tmp = tempfile::tempdir().unwrap();
    let text = room(tmp.path(), "").replace(
        "preset = \"doors\"",
        "weights = { door = 1.0, path = -2.0 }\nthreshold = 0.5\nnoise = 0.25",
    ) + "[[objects]]\nclass = \"stairs\"\nshape = \"rect\"\nx = 3.0\ny = 2.0\nwidth = 2.0\nheight = 0.6\nyaw = 0.0\n";
    let p = write(tmp.path(), "mine.toml", &text);
    let s = Scenario::load(&p).unwrap();
    assert_eq!(s.name, "mine");
    assert_eq!(s.teacher.weights, [0.0, 1.0, 0.0, 0.0, -2.0, 0.0]);
    assert_eq!((s.teacher.threshold, s.teacher.noise), (0.5, 0.25));
    assert_eq!(s.path.length(), 12.0);
    // The rectangle is seen as the disc on its long axis nearest to the car.
    let (c, r) = s.objects[0].disc_seen_from(&nalgebra::Point2::new(10.0, 2.5));
    assert_eq!((c.x, c.y, r), (3.7, 2.0, 0.3));
    // Start defaults to the first waypoint facing the second.
    assert_eq!((s.start.x, s.start.y, s.start.theta), (1.0, 1.0, 0.0));
}

#[test]
fn bad_scenarios_name_the_field() {
    let disc = |r: &str| {
        format!(
            "[[objects]]\nclass = \"door\"\nx = 1\ny = 1\nradius = 0.3\n[[objects]]\nclass = \"chair\"\nx = 2\ny = 1\nradius = 0.3\n[[objects]]\nclass = \"chair\"\nx = 3\ny = 1\nradius = {r}\n"
        )
    };
    let e = err(&disc("-0.5"));
    assert!(e.contains("objects[2].radius: must be positive"), "{e}");
    let e = err(&disc("7.0"));
    assert!(e.contains("objects[2].radius: must be at most 5"), "{e}");
    let e = err("[[objects]]\nclass = \"sofa\"\nx = 1\ny = 1\nradius = 0.3\n");
    assert!(
        e.contains("objects[0].class: unknown class \"sofa\""),
        "{e}"
    );
    let e = err("[[objects]]\nclass = \"door\"\nshape = \"star\"\nx = 1\ny = 1\n");
    assert!(e.contains("objects[0].shape: unknown shape"), "{e}");
    let e = err("[[objects]]\nclass = \"door\"\nshape = \"rect\"\nx = 1\ny = 1\nwidth = 1\n");
    assert!(e.contains("objects[0].height: missing"), "{e}");
    let e = err("[[objects]]\nclass = \"door\"\nx = 1e300\ny = 1\nradius = 0.3\n");
    assert!(e.contains("objects[0].x: must be a finite number"), "{e}");
    let e = err("[start]\nx = 0.1\ny = 1.0\ntheta = 0.0\n");
    assert!(e.contains("start: the car's footprint"), "{e}");
    let e = err("[start]\nx = 1.0\ny = 1.0\n");
    assert!(
        e.contains("TOML parse error at line") && e.contains("theta"),
        "{e}"
    );

    let tmp = tempfile::tempdir().unwrap();
    let base = room(tmp.path(), "");
    let cases = [
        (
            base.replace("preset = \"doors\"", "preset = \"kitchen\""),
            "teacher.preset: unknown preset \"kitchen\"",
        ),
        (
            base.replace("preset = \"doors\"", "preset = \"doors\"\nthreshold = -1"),
            "teacher.threshold: must be in [0, 1000], got -1",
        ),
        (
            base.replace("preset = \"doors\"", "preset = \"doors\"\nnoise = nan"),
            "teacher.noise: must be in [0, 1000]",
        ),
        (
            base.replace("preset = \"doors\"", "weights = { door = 0.0 }"),
            "teacher.weights: must not all be zero",
        ),
        (
            base.replace("preset = \"doors\"", "weights = { doors = 1.0 }"),
            "TOML parse error at line",
        ),
        (
            base.replace("[5.0, 1.0], ", "[5.0, 1.0, 2.0], "),
            "path.waypoints[1]: must be a pair [x, y]",
        ),
        (
            base.replace("[5.0, 1.0], ", "[0.05, 1.0], "),
            "path.waypoints[1]: (0.05, 1) is not in free space",
        ),
        (
            base.replace("[5.0, 1.0], [5.0, 3.0], [1.0, 3.0]", "[5.0, 1.0]"),
            "path.waypoints: needs at least 2 waypoints (3 for a closed loop)",
        ),
        (base.replace("room.yaml", "missing.yaml"), "map: "),
        (
            base.replace("[path]", "[path\n"),
            "TOML parse error at line",
        ),
        (
            base.replace("map = ", "mapp = "),
            "TOML parse error at line",
        ),
        (base.clone() + "speed = 3\n", "TOML parse error at line"),
    ];
    for (i, (text, want)) in cases.iter().enumerate() {
        let p = write(tmp.path(), &format!("case{i}.toml"), text);
        let e = Scenario::load(&p).unwrap_err().to_string();
        assert!(e.contains(want), "case {i}: wanted {want:?} in {e:?}");
        assert!(
            e.contains(&format!("case{i}.toml")),
            "case {i}: names the file: {e}"
        );
    }
    let e = Scenario::load(&tmp.path().join("absent.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("absent.toml: cannot read"), "{e}");
}

/// The room of [`room`] with a wall across it at x = 3 m, floor to ceiling: the path runs
/// through the wall, so the teacher's own policy cannot drive a lap.
fn walled_room(dir: &Path) -> std::path::PathBuf {
    let (w, h) = (60usize, 40usize);
    let mut pgm = format!("P5\n{w} {h}\n255\n").into_bytes();
    for r in 0..h {
        for c in 0..w {
            let wall = r < 2 || c < 2 || r >= h - 2 || c >= w - 2 || (29..31).contains(&c);
            pgm.push(if wall { 0 } else { 254 });
        }
    }
    std::fs::write(dir.join("walled.pgm"), pgm).unwrap();
    write(
        dir,
        "walled.yaml",
        "image: walled.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n",
    );
    write(
        dir,
        "walled.toml",
        "map = \"walled.yaml\"\n[path]\nwaypoints = [[1.0, 1.0], [5.0, 1.0], [5.0, 3.0], [1.0, 3.0]]\n[teacher]\npreset = \"doors\"\n",
    )
}

#[test]
fn a_scenario_whose_teacher_cannot_lap_is_refused_with_where_and_why() {
    let tmp = tempfile::tempdir().unwrap();
    let file = walled_room(tmp.path());
    // The file itself is well formed.
    let s = Scenario::load(&file).unwrap();
    let e = host_sim::world::check::teacher_lap(&std::sync::Arc::new(s)).unwrap_err();
    println!("{e}");
    // It stops in front of the wall, on the first leg of the path (y = 1, x below 3).
    assert!(e.x < 3.0 && (e.y - 1.0).abs() < 0.5, "{e:?}");
    assert!(e.station > 0.5 && e.station < 2.0, "{e:?}");
    let text = e.to_string();
    for part in [
        "walled: the teacher's own policy cannot drive a lap",
        &format!("at tick {}", e.tick),
        &format!("({:.2}, {:.2}) m", e.x, e.y),
        "m along the path (12.0 m long)",
        "--no-scenario-check",
    ] {
        assert!(text.contains(part), "{part:?} in {text}");
    }
    // Loading by path refuses it with the same message.
    let e = registry::load_scenario(file.to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("cannot drive a lap"), "{e}");
    assert!(registry::load_scenario_unchecked(file.to_str().unwrap()).is_ok());

    // The command line refuses it too, and runs it with --no-scenario-check, saying so.
    let host_sim = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(args)
            .output()
            .unwrap()
    };
    let out = tmp.path().join("out");
    let args = [
        "run",
        "--scenario",
        file.to_str().unwrap(),
        "--steps",
        "20",
        "--out",
        out.to_str().unwrap(),
    ];
    let o = host_sim(&args);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("cannot drive a lap") && err.contains("m along the path"),
        "{err}"
    );
    let mut skip = args.to_vec();
    skip.push("--no-scenario-check");
    let o = host_sim(&skip);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("not checked (--no-scenario-check)"), "{err}");
}

#[test]
fn every_built_in_teacher_drives_a_lap_within_the_check_s_limit() {
    for s in registry::SCENARIOS {
        let scn = std::sync::Arc::new(registry::load_scenario_unchecked(s.name).unwrap());
        let lap = host_sim::world::check::teacher_lap(&scn).unwrap();
        let limit = host_sim::world::check::lap_tick_limit(&scn);
        println!("{}: a lap in {} ticks (limit {limit})", s.name, lap.ticks);
        assert!(lap.ticks < limit / 2, "{}", s.name);
    }
}
