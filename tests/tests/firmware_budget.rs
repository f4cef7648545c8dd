//! The car's tick within its instruction budget on the Cortex-M4F (issue 17): the worst act of
//! the real ticks recorded from the simulator may cost at most 50 000 instructions.
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

/// The worst real tick's act, in instructions: issue 17's target.
const WORST_TICK_BUDGET: u64 = 50_000;

/// What this test enforces until the target is met: the measured worst and a little margin, so
/// that a regression fails here. 72 306 instructions when the evaluator's first rewrite landed;
/// 90 090 once protocol version 3 quantized the observations, which changed the states the
/// recorded runs visit (the synthetic scenes moved by under 0.1%). Issue 17 stays open while this
/// is above [`WORST_TICK_BUDGET`]; lower it to that when met.
const WORST_TICK_GUARD: u64 = 95_000;

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
fn worst_real_tick_is_within_its_guard() -> Result<()> {
    let m = measure()?;
    let get = |k: &str| m.get(k).copied().context(format!("no {k} in the summary"));
    assert_eq!(
        get("act_max_budget")?,
        WORST_TICK_BUDGET,
        "the script's budget and this test's"
    );
    ensure!(get("act_n")? >= 30, "too few real ticks measured");
    let worst = get("act_max")?;
    assert!(
        worst <= WORST_TICK_GUARD,
        "the worst real tick costs {worst} instructions, over the guard of {WORST_TICK_GUARD} \
         (the target is {WORST_TICK_BUDGET}) \
         (mean {}, clutter scene {}, worst act + worst update {})",
        get("act_mean")?,
        get("clutter")?,
        get("act_and_update")?
    );
    Ok(())
}
