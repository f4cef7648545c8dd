//! The car's tick within its instruction budget on the Cortex-M4F (issue 17): the worst act of
//! the real ticks recorded from the simulator may cost at most 50 000 instructions and their mean
//! 30 000; the clutter stress scene at most
//! 60 000; the worst act and the worst update together, and the car node's tick with its MACs,
//! under 150 000; the car image's flash at most 64 KiB, and its RAM with stack at most 16 KiB.
//!
//! The figures are `scripts/measure-firmware`'s (the qemu-insncount plugin under
//! `-icount shift=0`, repeatable to the instruction; see `docs/firmware.md`), taken with
//! `--summary FILE`, which leaves the docs alone. Ignored by default: it needs
//! `qemu-system-arm`, gcc for the plugin, and builds the firmware images (about a minute on two
//! cores). `.ci/run` runs it next to the bit-identical QEMU test:
//!
//! ```text
//! scripts/setup-qemu
//! cargo test -p tests --test firmware_budget -- --ignored
//! ```

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;

use anyhow::{Context, Result, ensure};

/// The worst real tick's act, in instructions: issue 17's target, met. Until then a guard a
/// little above the measured worst held it: 72 306 instructions when the evaluator's first
/// rewrite landed; 90 090 once protocol version 3 quantized the observations, which changed the
/// states the recorded runs visit (the synthetic scenes moved by under 0.1%); 72 668 after the
/// evaluator's second round (beams beyond their reach never binned, one `sincosf`); 68 087 after
/// the third (the semantic pass without per-member tests where a cluster's centre settles
/// them); 69 285 once the evaluator's scratch left the agent for the stack (zeroed at every
/// act); 67 542 after the fourth round (less work per tick for the rows, the sums and the
/// semantic pass); 66 809 after the fifth (the semantic pass settles an object for the whole
/// lattice first); 58 208 after the sixth (the obstacle pass's members two at a time, the
/// semantic pass's bisector of two objects); 57 731 after the obstacle pass's seventh round
/// (its dead test of the clip dropped); 56 252 after the semantic pass's seventh (regions of
/// clusters); 53 139 with the scratch kept by the agent, the clusters' spread and the range
/// bins swept and the heading's `f64` in integer arithmetic; 47 580 with the heading in fixed
/// point and the sums, the choice, the rows and the validation reworked (2026-12-03, late
/// evening).
const WORST_TICK_BUDGET: u64 = 50_000;

/// The mean real tick's act: issue 17's target, met. Its guard's history: 47 586 measured after
/// the second round, 43 406 after the third, 44 568 with the scratch on the stack, 42 023 after
/// the fourth, 38 788 after the fifth, 37 434 after the sixth, 37 311 after the obstacle pass's
/// seventh round, 34 734 after the semantic pass's seventh, 32 664 with the scratch kept, the
/// sweep and the heading's `f64`, 28 176 with the heading in fixed point and the sums, the
/// choice, the rows and the validation reworked.
const MEAN_TICK_BUDGET: u64 = 30_000;

/// The clutter stress scene's act (met: 50 929 measured after the second round, 40 878 after the
/// third).
const CLUTTER_BUDGET: u64 = 60_000;

/// One tick: the worst act and the worst update together, and the car node's tick (reassembly,
/// MAC check, decoding, act, the answer sealed): under 150 000 (1 ms at 168 MHz). Both are met
/// (108 200 and 102 627 after the second round).
const TICK_BUDGET: u64 = 150_000;

/// The car image's flash (text + data): issue 17's target, met (62 244 bytes once the node's
/// initial value left `.data`).
const FLASH_BUDGET: u64 = 65_536;

/// The car image's RAM with its stack (statics + the deepest stack of a served session):
/// issue 17's target, held since the evaluator's scratch left the agent for the stack of the
/// evaluation (7 420 bytes of statics with the reassembly buffers sized per stream; the
/// session's deepest stack varies by about 100 bytes with where the millisecond interrupt
/// lands).
const RAM_BUDGET: u64 = 16_384;

/// Runs `scripts/measure-firmware --summary` and reads its `key=value` lines.
fn measure() -> Result<HashMap<String, u64>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = tempfile::tempdir()?;
    let file = dir.path().join("summary.txt");
    let status = Command::new(root.join("scripts/measure-firmware"))
        .arg("--summary")
        .arg(&file)
        .status()
        .context("scripts/measure-firmware")?;
    ensure!(
        status.success(),
        "scripts/measure-firmware failed: {status}"
    );
    let text = std::fs::read_to_string(&file).context("the summary")?;
    text.lines()
        .filter_map(|line| line.split_once('='))
        .map(|(k, v)| Ok((k.to_string(), v.trim().parse().context(format!("{k}={v}"))?)))
        .collect()
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware images; .ci/run runs it"]
fn real_ticks_clutter_car_node_and_image_within_their_guards_and_budgets() -> Result<()> {
    let m = measure()?;
    let get = |k: &str| m.get(k).copied().context(format!("no {k} in the summary"));
    assert_eq!(
        get("act_max_budget")?,
        WORST_TICK_BUDGET,
        "the script's budget and this test's"
    );
    assert_eq!(
        get("act_mean_budget")?,
        MEAN_TICK_BUDGET,
        "the script's budget and this test's"
    );
    assert_eq!(
        get("clutter_budget")?,
        CLUTTER_BUDGET,
        "the script's budget and this test's"
    );
    ensure!(get("act_n")? >= 30, "too few real ticks measured");
    let worst = get("act_max")?;
    assert!(
        worst <= WORST_TICK_BUDGET,
        "the worst real tick costs {worst} instructions, over its budget of {WORST_TICK_BUDGET}"
    );
    let mean = get("act_mean")?;
    assert!(
        mean <= MEAN_TICK_BUDGET,
        "the real ticks cost {mean} instructions on average, over their budget of \
         {MEAN_TICK_BUDGET}"
    );
    let clutter = get("clutter")?;
    assert!(
        clutter <= CLUTTER_BUDGET,
        "the clutter scene costs {clutter} instructions, over its budget of {CLUTTER_BUDGET}"
    );
    let both = get("act_and_update")?;
    assert!(
        both < TICK_BUDGET,
        "the worst act and the worst update cost {both} instructions together, not under \
         {TICK_BUDGET}"
    );
    let node = get("node")?;
    assert!(
        node < TICK_BUDGET,
        "the car node's tick costs {node} instructions, not under {TICK_BUDGET}"
    );
    assert_eq!(
        get("flash_budget")?,
        FLASH_BUDGET,
        "the script's budget and this test's"
    );
    assert_eq!(
        get("ram_budget")?,
        RAM_BUDGET,
        "the script's budget and this test's"
    );
    let flash = get("flash")?;
    assert!(
        flash <= FLASH_BUDGET,
        "the car image takes {flash} bytes of flash, over its budget of {FLASH_BUDGET}"
    );
    let ram = get("ram_with_stack")?;
    assert!(
        ram <= RAM_BUDGET,
        "the car image takes {ram} bytes of RAM with its stack, over its budget of {RAM_BUDGET}"
    );
    Ok(())
}
