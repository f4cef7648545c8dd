//! Every teacher preset's own policy drives its household for a full lap without collision, and
//! behaves as its task says.

use std::sync::Arc;

use host_sim::teach::experiment::{self, Mode, RunConfig};
use host_sim::teach::record::RunReport;
use host_sim::world::registry;

fn teacher_drive(name: &str, steps: u32) -> RunReport {
    let s = Arc::new(registry::load_scenario(name).unwrap());
    let config = RunConfig {
        mode: Mode::Teacher,
        steps,
        ..RunConfig::new(s)
    };
    experiment::run(&config).unwrap()
}

fn assert_clean_lap(name: &str, steps: u32) -> RunReport {
    let r = teacher_drive(name, steps);
    let first_lap = r
        .records
        .iter()
        .position(|x| x.lap >= 1)
        .unwrap_or_else(|| panic!("{name}: no lap in {steps} steps"));
    println!(
        "{name}: first lap after {first_lap} ticks; {} laps in {steps}",
        r.laps()
    );
    assert_eq!(
        r.resets, [0; 4],
        "{name}: resets (collision, stuck, lost, blocked)"
    );
    assert!(
        r.records.iter().all(|x| x.latent_loss == 0.0),
        "{name}: the teacher's own loss is 0"
    );
    assert_eq!(r.corrections(), 0);
    r
}

#[test]
fn doors_teacher_laps_and_keeps_away_from_doors() {
    let r = assert_clean_lap("doors", 500);
    // Passing bedroom 1's south door (x = 6.95, on the hallway's north wall at y = 2.5) the
    // teacher keeps to the south half of the 2 m hallway (centre y = 1.5).
    let near: Vec<_> = r
        .records
        .iter()
        .filter(|x| (6.6..7.3).contains(&x.x) && x.y < 2.5)
        .collect();
    assert!(!near.is_empty());
    assert!(
        near.iter().all(|x| x.y < 1.3),
        "{:?}",
        near.iter().map(|x| x.y).collect::<Vec<_>>()
    );
}

#[test]
fn stairs_right_teacher_laps_and_keeps_right_of_the_stairs() {
    let r = assert_clean_lap("stairs-right", 600);
    // Along the south hallway (eastbound, path at y = 1.3) past the stairs alcove on the left.
    let near: Vec<_> = r
        .records
        .iter()
        .filter(|x| (9.0..11.0).contains(&x.x) && x.y < 2.1)
        .collect();
    assert!(!near.is_empty());
    assert!(
        near.iter().all(|x| x.y < 1.2),
        "{:?}",
        near.iter().map(|x| x.y).collect::<Vec<_>>()
    );
}

#[test]
fn stairs_chairs_teacher_laps_and_keeps_away_from_chairs() {
    let r = assert_clean_lap("stairs-chairs", 500);
    // Northbound through the dining room (path at x = 11.5) past the chairs on the east.
    let near: Vec<_> = r
        .records
        .iter()
        .filter(|x| (5.0..7.0).contains(&x.y) && x.x > 10.5 && x.x < 12.0)
        .collect();
    assert!(!near.is_empty());
    assert!(
        near.iter().all(|x| x.x < 11.3),
        "{:?}",
        near.iter().map(|x| x.x).collect::<Vec<_>>()
    );
}

#[test]
fn basement_teacher_laps() {
    assert_clean_lap("basement", 1_500);
}
