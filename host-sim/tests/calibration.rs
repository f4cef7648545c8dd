//! The teachers' calibration (`docs/reproduction/CALIBRATION.md`): the procedure, run again,
//! prints what the document holds, and the presets carry the scales its rule gave.

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

#[test]
fn the_presets_carry_the_rule_s_scales() {
    let c = calibrate::run().unwrap();
    for (household, s) in &c.scales {
        let p = PRESETS.iter().find(|p| p.name == *household).unwrap();
        assert_eq!(p.scale, *s as f32, "{household}");
        assert_eq!(p.weights, scaled(&p.ratios, p.scale), "{household}");
        assert_eq!(p.ratios[4], -1.0, "{household}: ratios have path weight −1");
    }
}
