//! The teachers' calibration (`docs/reproduction/CALIBRATION.md`): the procedure, run again,
//! prints what the document holds, and the frozen presets still satisfy every target of their
//! teacher.
//!
//! The scales were frozen when the rule first ran (doors 17, stairs-right 2.6, stairs-chairs
//! 3.0) and are not changed after the claims have been seen (the rule's point 3). A later change
//! of the world or the sensing moves the procedure's figures; the document then shows the new
//! figures, and this test checks that each frozen scale still lies in the interval its teacher's
//! own targets allow. If one ever leaves it, the calibration must be redone openly.

use host_sim::teach::calibrate;
use host_sim::world::teacher::{PRESETS, scaled};

fn documented() -> String {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../docs/reproduction/CALIBRATION.md"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let start = text.find("<!-- calibrate -->\n").expect("start marker") + 19;
    let end = text.find("<!-- /calibrate -->").expect("end marker");
    text[start..end].to_string()
}

#[test]
fn the_procedure_prints_what_calibration_md_holds() {
    let c = calibrate::run().unwrap();
    let printed = calibrate::markdown(&c);
    assert_eq!(
        printed,
        documented(),
        "docs/reproduction/CALIBRATION.md is stale: paste the output of `host-sim calibrate`"
    );
}

/// The scales frozen in `teacher.rs` when the rule first ran (issue 12).
const FROZEN: [(&str, f32); 3] = [
    ("doors", 17.0),
    ("stairs-right", 2.6),
    ("stairs-chairs", 3.0),
];

#[test]
fn the_frozen_presets_satisfy_their_teachers_targets() {
    let c = calibrate::run().unwrap();
    for (household, _) in &c.scales {
        let p = PRESETS.iter().find(|p| p.name == *household).unwrap();
        let frozen = FROZEN.iter().find(|(h, _)| h == household).unwrap().1;
        assert_eq!(p.scale, frozen, "{household}: the frozen scale changed");
        for t in c.targets.iter().filter(|t| t.household == *household) {
            assert!(
                t.interval.contains(f64::from(p.scale)),
                "{household}: the frozen scale {} fails {} ({}), which holds for s in {}",
                p.scale,
                t.target,
                t.condition,
                t.interval.describe()
            );
        }
        assert_eq!(p.weights, scaled(&p.ratios, p.scale), "{household}");
        assert_eq!(p.ratios[4], -1.0, "{household}: ratios have path weight −1");
    }
}
