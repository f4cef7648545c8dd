//! Map loading: the shared MuSHR maps, the generated households, and every kind of bad file.

use std::path::{Path, PathBuf};

use host_sim::world::map::{Cell, MapError, OccupancyGrid};

/// `../shared/maps` relative to the repository root (CI has `../shared` beside the checkout).
fn shared_maps() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/maps")
}

fn load_err(dir: &Path, yaml: &str) -> String {
    let p = dir.join("m.yaml");
    std::fs::write(&p, yaml).unwrap();
    let e = OccupancyGrid::load(&p).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("m.yaml") || text.contains(".p"),
        "names the file: {text}"
    );
    text
}

#[test]
fn the_shared_mushr_maps_load() {
    let dir = shared_maps();
    let sandbox = OccupancyGrid::load(&dir.join("sandbox.yaml")).unwrap();
    assert_eq!((sandbox.width(), sandbox.height()), (1000, 1000));
    assert_eq!(sandbox.origin(), [-50.0, -50.0, 0.0]);
    assert!(
        !sandbox.is_blocked(0.0, 0.0),
        "the sandbox's middle is free"
    );
    assert!(sandbox.is_blocked(-49.8, 0.0), "its wall is not");

    let b10 = OccupancyGrid::load(&dir.join("basement_hallways_10cm.yaml")).unwrap();
    assert_eq!((b10.width(), b10.height()), (600, 600));
    let [free, occupied, unknown] = b10.counts();
    assert_eq!(occupied, 4_843, "SOURCES.md: 4,843 occupied pixels");
    let frac = free as f64 / 360_000.0;
    assert!(
        (frac - 0.162).abs() < 0.001,
        "SOURCES.md: 16.2 % free, got {frac}"
    );
    assert_eq!(free + occupied + unknown, 360_000);

    let b5 = OccupancyGrid::load(&dir.join("basement_hallways_5cm.yaml")).unwrap();
    assert_eq!((b5.width(), b5.height()), (1200, 1200));
    assert_eq!(b5.resolution(), 0.05);
    // The same place is free in both resolutions (the north hallway).
    assert!(!b10.is_blocked(10.0, 15.5) && !b5.is_blocked(10.0, 15.5));
    // Rows are flipped: the top image row is the map's highest y, which is unknown here.
    assert_eq!(b10.cell(0, 599), Some(Cell::Unknown));
}

#[test]
fn the_generated_households_are_what_the_generator_draws() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/maps");
    for (name, canvas) in host_sim::world::households::all() {
        let on_disk = std::fs::read(dir.join(format!("{name}.pgm"))).unwrap();
        assert!(
            on_disk == canvas.to_pgm(),
            "{name}.pgm differs from households.rs: run `host-sim gen-maps` and commit"
        );
        let yaml = std::fs::read_to_string(dir.join(format!("{name}.yaml"))).unwrap();
        assert_eq!(yaml, host_sim::world::households::yaml(name));
        let grid = OccupancyGrid::load(&dir.join(format!("{name}.yaml"))).unwrap();
        let [free, occupied, unknown] = grid.counts();
        assert!(free > 0 && occupied > 0 && unknown > 0, "{name}");
    }
}

#[test]
fn missing_and_malformed_files_are_errors_that_name_them() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let e = OccupancyGrid::load(&dir.join("nope.yaml")).unwrap_err();
    assert!(matches!(e, MapError::Io { .. }));
    assert!(e.to_string().contains("nope.yaml"), "{e}");

    let t = load_err(dir, "image: [unclosed\nresolution: 0.1\n");
    assert!(t.contains("malformed YAML"), "{t}");
    let t = load_err(dir, "- just\n- a list\n");
    assert!(t.contains("expected a mapping"), "{t}");
    let t = load_err(dir, "resolution: 0.1\norigin: [0, 0, 0]\n");
    assert!(t.contains("image: missing"), "{t}");
    let t = load_err(dir, "image: m.pgm\nresolution: -0.1\norigin: [0, 0, 0]\n");
    assert!(t.contains("resolution: must be in (0, 10]"), "{t}");
    let t = load_err(dir, "image: m.pgm\nresolution: 0.1\norigin: [0, 0]\n");
    assert!(t.contains("origin: must be a list [x, y, yaw]"), "{t}");
    let t = load_err(dir, "image: m.pgm\nresolution: 0.1\norigin: [0, .nan, 0]\n");
    assert!(t.contains("origin: must hold three finite numbers"), "{t}");
    let t = load_err(
        dir,
        "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 1.5\n",
    );
    assert!(
        t.contains("occupied_thresh: must be in [0, 1], got 1.5"),
        "{t}"
    );
    let t = load_err(
        dir,
        "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 0.3\nfree_thresh: 0.6\n",
    );
    assert!(
        t.contains("free_thresh: must not exceed occupied_thresh"),
        "{t}"
    );
    let t = load_err(
        dir,
        "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 2\n",
    );
    assert!(t.contains("negate: must be 0 or 1"), "{t}");
    let t = load_err(
        dir,
        "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: fancy\n",
    );
    assert!(t.contains("mode: must be trinary, scale or raw"), "{t}");
    let t = load_err(
        dir,
        "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nresolutoin: 2\n",
    );
    assert!(t.contains("unknown key"), "{t}");

    // The YAML is fine but the image is missing, truncated, or not an image.
    let good = "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n";
    let p = dir.join("m.yaml");
    std::fs::write(&p, good).unwrap();
    let e = OccupancyGrid::load(&p).unwrap_err().to_string();
    assert!(e.contains("m.pgm") && e.contains("cannot read"), "{e}");
    std::fs::write(dir.join("m.pgm"), b"P5\n4 4\n255\n\x00\x00").unwrap();
    let e = OccupancyGrid::load(&p).unwrap_err().to_string();
    assert!(e.contains("m.pgm") && e.contains("truncated"), "{e}");
    std::fs::write(dir.join("m.pgm"), b"GIF89a....").unwrap();
    let e = OccupancyGrid::load(&p).unwrap_err().to_string();
    assert!(e.contains("neither PNG nor PGM"), "{e}");
    std::fs::write(dir.join("m.pgm"), b"\x89PNG\r\n\x1a\ngarbage").unwrap();
    let e = OccupancyGrid::load(&p).unwrap_err().to_string();
    assert!(e.contains("m.pgm: bad image: PNG"), "{e}");
}

#[test]
fn a_small_pgm_reads_with_flipped_rows_and_thresholds() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // 3 × 2 pixels: top row white, grey, black; bottom row black, white, white (ASCII P2).
    std::fs::write(
        dir.join("m.pgm"),
        "P2\n# comment\n3 2\n255\n255 205 0\n0 255 255\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("m.yaml"),
        "image: m.pgm\nresolution: 1.0\norigin: [10.0, 20.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
    )
    .unwrap();
    let g = OccupancyGrid::load(&dir.join("m.yaml")).unwrap();
    assert_eq!(g.cell(0, 1), Some(Cell::Free)); // top-left
    assert_eq!(g.cell(1, 1), Some(Cell::Unknown));
    assert_eq!(g.cell(2, 1), Some(Cell::Occupied));
    assert_eq!(g.cell(0, 0), Some(Cell::Occupied)); // bottom-left = origin
    assert!(g.is_blocked(10.5, 20.5));
    assert!(!g.is_blocked(11.5, 20.5));
    // negate: 1 swaps black and white.
    std::fs::write(
        dir.join("n.yaml"),
        "image: m.pgm\nresolution: 1.0\norigin: [0, 0, 0]\nnegate: 1\n",
    )
    .unwrap();
    let n = OccupancyGrid::load(&dir.join("n.yaml")).unwrap();
    assert_eq!(n.cell(0, 1), Some(Cell::Occupied));
    assert_eq!(n.cell(2, 1), Some(Cell::Free));
}
