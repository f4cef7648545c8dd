//! The built-in scenarios by name (`--scenario NAME`), loaded and checked, in the manner of
//! rapier's example registry: the CLI lists them. The paper's experiments by name are in
//! [`crate::report::registry`].
//!
//! Built-in scenarios live in `host-sim/scenarios/` (located at build time through
//! `CARGO_MANIFEST_DIR`). Loading one checks it ([`crate::world::check`]); scenarios are shared
//! read-only through `Arc` by the runs that use them.
//!
//! ```no_run
//! use host_sim::world::registry;
//! let scenario = registry::load_scenario("doors").unwrap();
//! assert_eq!(scenario.name, "doors");
//! ```

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Result, bail};

use crate::world::scenario::Scenario;

/// A built-in scenario.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BuiltinScenario {
    /// Its name (`--scenario NAME`).
    pub name: &'static str,
    /// The file in `scenarios/`.
    pub file: &'static str,
    /// One line about it.
    pub description: &'static str,
}

/// The built-in scenarios.
pub const SCENARIOS: &[BuiltinScenario] = &[
    BuiltinScenario {
        name: "doors",
        file: "doors.toml",
        description: "a flat with bedroom doors along 2 m hallways; the teacher avoids doors",
    },
    BuiltinScenario {
        name: "stairs-right",
        file: "stairs-right.toml",
        description: "1.6 m hallways and two staircases; the teacher avoids stairs and keeps right",
    },
    BuiltinScenario {
        name: "stairs-chairs",
        file: "stairs-chairs.toml",
        description: "a stairwell, a dining room and a living room; the teacher avoids stairs and chairs",
    },
    BuiltinScenario {
        name: "basement",
        file: "basement.toml",
        description: "the MIT basement hallways of MuSHR's map set, with doors placed on it",
    },
];

/// The folder of the built-in scenarios.
pub fn scenario_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios")
}

/// The file of a built-in scenario name, or `name_or_path` itself when it is not one.
pub fn resolve(name_or_path: &str) -> PathBuf {
    match SCENARIOS.iter().find(|s| s.name == name_or_path) {
        Some(s) => scenario_dir().join(s.file),
        None => PathBuf::from(name_or_path),
    }
}

/// Loads a built-in scenario by name, or a scenario file by path, and checks that its teacher's
/// own policy drives a lap of it ([`crate::world::check::teacher_lap`]); a scenario that fails is
/// refused with where and why.
pub fn load_scenario(name_or_path: &str) -> Result<Scenario> {
    let s = load_scenario_unchecked(name_or_path)?;
    crate::world::check::teacher_lap(&Arc::new(s.clone()))?;
    Ok(s)
}

/// [`load_scenario`] without the teacher's lap (`host-sim --no-scenario-check`).
pub fn load_scenario_unchecked(name_or_path: &str) -> Result<Scenario> {
    let path = resolve(name_or_path);
    if !path.exists() && !name_or_path.contains(['/', '.']) {
        let names: Vec<_> = SCENARIOS.iter().map(|s| s.name).collect();
        bail!(
            "unknown scenario {name_or_path:?}: a built-in name ({}) or a path to a .toml file",
            names.join(", ")
        );
    }
    Ok(Scenario::load(&path)?)
}
