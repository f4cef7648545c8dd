//! The household generator: the same seed gives the same bytes; every world of seeds 0–99 loads
//! from its files, its teachers lap it, its objects are within the detector's reach from the
//! path; bad options are refused with a message; a seed that gives no world says why.

use std::path::Path;
use std::sync::Arc;

use crate::support::host_sim;
use host_sim::teach::experiment::{self, Mode, RunConfig};
use host_sim::teach::record::fnv1a;
use host_sim::world::generator::{self, GenerateError, Options, OptionsError, World, check};
use host_sim::world::map::Cell;
use host_sim::world::scenario::Scenario;
use host_sim::world::teacher::{PRESETS, TeacherSpec};
use rayon::prelude::*;

fn digest(w: &World) -> [u64; 3] {
    w.files().map(|(_, bytes)| fnv1a(bytes))
}

/// The FNV-1a digests of `gen-0.pgm`, `.yaml` and `.toml`. They change when the plan's rules,
/// the drawing, the scenario text, or what the teachers' laps accept change: regenerate the
/// pictures in `docs/worlds/` in the same commit and say why.
const GOLDEN_SEED_0: [u64; 3] = [
    3_145_353_028_847_230_511,
    1_686_931_365_411_762_045,
    4_850_369_175_232_007_306,
];

#[test]
fn the_same_seed_gives_the_same_bytes() {
    let a = generator::generate(&Options::new(0)).unwrap();
    let b = generator::generate(&Options::new(0)).unwrap();
    assert_eq!(a.files(), b.files());
    assert_eq!(
        digest(&a),
        GOLDEN_SEED_0,
        "seed 0's files changed: got {:?}, golden {:?}",
        digest(&a),
        GOLDEN_SEED_0
    );
    // Written twice, the files are the same bytes.
    let (d1, d2) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    a.write(d1.path()).unwrap();
    b.write(d2.path()).unwrap();
    for (name, bytes) in a.files() {
        assert_eq!(std::fs::read(d1.path().join(&name)).unwrap(), bytes);
        assert_eq!(std::fs::read(d2.path().join(&name)).unwrap(), bytes);
    }
    // Another seed, another world.
    let c = generator::generate(&Options::new(1)).unwrap();
    assert_ne!(a.pgm, c.pgm);
    // Another teacher: the same world, another teacher in the scenario.
    let d = generator::generate(&Options {
        teacher: "stairs-chairs".into(),
        ..Options::new(0)
    })
    .unwrap();
    assert_eq!(a.pgm, d.pgm);
    assert_eq!(a.yaml, d.yaml);
    let differ: Vec<(&str, &str)> = a
        .toml
        .lines()
        .zip(d.toml.lines())
        .filter(|(x, y)| x != y)
        .collect();
    assert_eq!(
        differ,
        [
            (
                "# A generated household: `host-sim generate --seed 0`.",
                "# A generated household: `host-sim generate --seed 0 --teacher stairs-chairs`."
            ),
            ("preset = \"doors\"", "preset = \"stairs-chairs\"")
        ]
    );
}

/// Drives `spec`'s own policy in `s` from the start (the experiment's teacher mode, not the
/// generator's lap driver) and returns the tick of its first lap, failing on any reset before.
fn first_lap(s: &Scenario, spec: TeacherSpec, budget: u32) -> Result<usize, String> {
    let scenario = Arc::new(Scenario {
        teacher: spec,
        ..s.clone()
    });
    let config = RunConfig {
        mode: Mode::Teacher,
        steps: budget,
        ..RunConfig::new(scenario)
    };
    let r = experiment::run(&config).map_err(|e| e.to_string())?;
    for (i, rec) in r.records.iter().enumerate() {
        if let Some(reset) = rec.reset {
            return Err(format!(
                "reset ({}) at tick {i}, ({:.2}, {:.2})",
                reset.name(),
                rec.x,
                rec.y
            ));
        }
        if rec.lap >= 1 {
            return Ok(i);
        }
    }
    Err(format!("no lap in {budget} ticks"))
}

/// What loading the written files gives is the world the generator checked.
fn assert_loads_as_generated(w: &World, dir: &Path) -> Scenario {
    let toml = w.write(dir).unwrap();
    let loaded = Scenario::load(&toml).unwrap();
    let s = &w.scenario;
    let name = &w.options.name;
    assert_eq!(loaded.name, *name);
    assert_eq!(loaded.path, s.path, "{name}");
    assert_eq!(loaded.start, s.start, "{name}");
    assert_eq!(loaded.objects, s.objects, "{name}");
    assert_eq!(loaded.teacher, s.teacher, "{name}");
    let (m, g) = (&loaded.map, &s.map);
    assert_eq!((m.width(), m.height()), (g.width(), g.height()), "{name}");
    assert_eq!(m.resolution(), g.resolution());
    assert_eq!(m.origin(), g.origin());
    let mut unknown = 0;
    for r in 0..m.height() {
        for c in 0..m.width() {
            let (a, b) = (m.cell(c, r).unwrap(), g.cell(c, r).unwrap());
            assert_eq!(a == Cell::Free, b == Cell::Free, "{name}: cell ({c}, {r})");
            unknown += usize::from(a == Cell::Unknown);
        }
    }
    assert!(
        unknown > 0,
        "{name}: the outside of the building is unknown"
    );
    loaded
}

#[test]
fn worlds_0_to_99_load_lap_and_show_their_objects() {
    let tmp = tempfile::tempdir().unwrap();
    let worlds: Vec<(u64, World)> = (0..100u64)
        .into_par_iter()
        .map(|seed| {
            // Each teacher names the scenario of a third of the worlds.
            let options = Options {
                teacher: PRESETS[seed as usize % 3].name.into(),
                ..Options::new(seed)
            };
            (seed, generator::generate(&options).unwrap())
        })
        .collect();
    let mut over_none = [0u32; 3];
    for (seed, w) in &worlds {
        let loaded = assert_loads_as_generated(w, tmp.path());
        let name = &w.options.name;
        // Every object is within the detector's range of some point of the path, in sight.
        assert_eq!(
            check::unreachable_objects(&loaded),
            Vec::<usize>::new(),
            "{name}"
        );
        assert!(w.summary.doors >= 1 && w.summary.stairs >= 1 && w.summary.chairs >= 1);
        let l = w.summary.path_length;
        assert!((15.0..=80.0).contains(&l), "{name}: path {l} m");
        for (i, p) in PRESETS.iter().enumerate() {
            // Every teacher laps the loaded world, driven by the experiment loop.
            let lap = &w.laps[i];
            assert_eq!(lap.trace.len() as u32, lap.ticks + 1, "{name}: {}", p.name);
            // (as many ticks as the generator's lap took, and 20 more)
            first_lap(&loaded, TeacherSpec::from_preset(p), lap.ticks + 20)
                .unwrap_or_else(|e| panic!("seed {seed}, {}: {e}", p.name));
            // The teacher's policy differs from its path follower's somewhere on the path.
            let c = &w.contrasts[i];
            assert!(c.differs > 0, "{name}: {} {c:?}", p.name);
            over_none[i] += u32::from(c.over_threshold == 0);
        }
    }
    println!(
        "worlds where a teacher would never correct its path follower (doors, stairs-right, stairs-chairs): {over_none:?}"
    );
}

#[test]
fn a_seed_that_gives_no_world_says_why() {
    // The first seed whose first attempt is refused: with as few attempts as it needed less
    // one, it gives no world, and the error lists each refusal.
    let (seed, w) = (0..50u64)
        .map(|s| (s, generator::generate(&Options::new(s)).unwrap()))
        .find(|(_, w)| w.attempt > 0)
        .expect("some first attempt among seeds 0-49 is refused");
    let e = generator::generate(&Options {
        attempts: w.attempt,
        ..Options::new(seed)
    })
    .unwrap_err();
    let GenerateError::NoWorld { seed: s, refusals } = &e else {
        panic!("{e}");
    };
    assert_eq!(*s, seed);
    assert_eq!(*refusals, w.refused);
    let msg = e.to_string();
    assert!(msg.contains(&format!("no world for seed {seed}")), "{msg}");
    for r in refusals {
        assert!(
            msg.contains(&format!("attempt {}: {}", r.attempt, r.why)),
            "{msg}"
        );
    }
    println!("{msg}");
}

#[test]
fn bad_options_are_refused_with_a_message() {
    let refused = |o: Options| o.check().unwrap_err();
    let e = refused(Options {
        teacher: "nobody".into(),
        ..Options::new(1)
    });
    assert!(matches!(e, OptionsError::Teacher { .. }));
    assert!(
        e.to_string()
            .contains("one of doors, stairs-right, stairs-chairs"),
        "{e}"
    );
    for name in [
        "",
        "../up",
        "a/b",
        ".hidden",
        "white space",
        &"x".repeat(65),
    ] {
        let e = refused(Options {
            name: Some(name.into()),
            ..Options::new(1)
        });
        assert!(matches!(e, OptionsError::Name { .. }), "{name:?}: {e}");
    }
    for (min, max, says) in [
        (f64::NAN, 2.0, "finite"),
        (1.4, f64::INFINITY, "finite"),
        (1.0, 2.0, "within 1.2–3 m"),
        (1.4, 3.5, "within 1.2–3 m"),
        (2.0, 1.6, "narrowest exceeds the widest"),
        (1.41, 1.44, "5 cm grid"),
    ] {
        let e = refused(Options {
            hallway_min: min,
            hallway_max: max,
            ..Options::new(1)
        });
        assert!(matches!(e, OptionsError::Hallway { .. }), "{e}");
        assert!(e.to_string().contains(says), "{min}–{max}: {e}");
    }
    for attempts in [0, 65] {
        let e = refused(Options {
            attempts,
            ..Options::new(1)
        });
        assert_eq!(e, OptionsError::Attempts(attempts));
    }
    assert!(matches!(
        generator::generate(&Options {
            attempts: 0,
            ..Options::new(1)
        }),
        Err(GenerateError::Options(OptionsError::Attempts(0)))
    ));
    // Good options pass, on the grid: 1.42–2.48 m become 1.45–2.45 m.
    let v = Options {
        hallway_min: 1.42,
        hallway_max: 2.48,
        ..Options::new(1)
    }
    .check()
    .unwrap();
    assert_eq!(v.hallway_mm, (1450, 2450));

    // The command line refuses them too, and writes nothing.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("worlds");
    let o = out.to_str().unwrap();
    for (args, says) in [
        (vec!["--hallway-min", "2.6"], "narrowest exceeds the widest"),
        (vec!["--teacher", "nobody"], "unknown teacher"),
        (vec!["--name", "../x"], "name"),
        (vec!["--attempts", "0"], "attempts"),
        (vec!["--count", "0"], "--count"),
        (vec!["--count", "2", "--name", "x"], "--name"),
    ] {
        let mut all = vec!["generate", "--seed", "3", "--out", o];
        all.extend(args.iter());
        let r = host_sim(&all);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success(), "{args:?}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?}: nothing is written");
    }
    let r = host_sim(&["generate", "--seed", "-3", "--out", o]);
    assert!(!r.status.success());
}

#[test]
fn host_sim_runs_a_generated_world() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("worlds");
    let pics = tmp.path().join("pictures");
    let r = host_sim(&[
        "generate",
        "--seed",
        "5",
        "--teacher",
        "stairs-right",
        "--out",
        out.to_str().unwrap(),
        "--picture",
        pics.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    for f in ["gen-5.pgm", "gen-5.yaml", "gen-5.toml"] {
        assert!(out.join(f).exists(), "{f}: {stdout}");
    }
    let png = std::fs::read(pics.join("gen-5.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG"));
    // What the library makes is what the command wrote.
    let w = generator::generate(&Options {
        teacher: "stairs-right".into(),
        ..Options::new(5)
    })
    .unwrap();
    for (name, bytes) in w.files() {
        assert_eq!(std::fs::read(out.join(&name)).unwrap(), bytes, "{name}");
    }
    let toml = out.join("gen-5.toml");
    let run = tmp.path().join("run");
    let r = host_sim(&[
        "run",
        "--scenario",
        toml.to_str().unwrap(),
        "--feedback",
        "semantic",
        "--steps",
        "200",
        "--out",
        run.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let summary = std::fs::read_to_string(run.join("summary.json")).unwrap();
    assert!(summary.contains("\"gen-5\""), "{summary}");

    // A batch: seeds 7 and 8, and a survey of the attempts.
    let r = host_sim(&[
        "generate",
        "--seed",
        "7",
        "--count",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(stdout.contains("2 of 2 seeds gave a world"), "{stdout}");
    assert!(out.join("gen-7.toml").exists() && out.join("gen-8.toml").exists());
}
