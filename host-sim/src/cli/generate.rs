//! `host-sim generate`: the command line of the generator.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use rayon::prelude::*;

use host_sim::report::plot::MapDrawing;
use host_sim::world::generator::{DEFAULT_ATTEMPTS, GenerateError, Options, World, generate};
use host_sim::world::scenario::Scenario;
use host_sim::world::teacher;

/// Most worlds of one command.
pub(crate) const MAX_COUNT: u32 = 100_000;

/// Generate households: seeded floor plans with a closed path and doors, stairs and chairs,
/// each written as DIR/NAME.pgm + NAME.yaml (ROS map_server) and DIR/NAME.toml (a scenario for
/// `host-sim run --scenario DIR/NAME.toml`). Every teacher preset's own policy laps each world.
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct GenerateArgs {
    /// The seed: the same options give the same bytes.
    #[arg(long)]
    pub(crate) seed: u64,
    /// Output folder (created if missing; files of the same name are replaced).
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// The scenario's teacher: doors, stairs-right or stairs-chairs (the world is the same for
    /// all three).
    #[arg(long, default_value = "doors")]
    pub(crate) teacher: String,
    /// Name of the files and the scenario (default gen-SEED; only with --count 1).
    #[arg(long)]
    pub(crate) name: Option<String>,
    /// Narrowest hallway (m).
    #[arg(long, default_value_t = 1.4, allow_negative_numbers = true)]
    pub(crate) hallway_min: f64,
    /// Widest hallway (m).
    #[arg(long, default_value_t = 2.5, allow_negative_numbers = true)]
    pub(crate) hallway_max: f64,
    /// Worlds drawn at most per seed (a world that fails its checks is drawn again from the
    /// seed's next stream).
    #[arg(long, default_value_t = DEFAULT_ATTEMPTS)]
    pub(crate) attempts: u32,
    /// Generate the worlds of seeds SEED, SEED+1, …, in parallel, and print what they are and
    /// how often the checks refused an attempt.
    #[arg(long, default_value_t = 1)]
    pub(crate) count: u32,
    /// Also draw each world into PICTURE/NAME.png: map, path, objects, the scenario teacher's
    /// lap (purple) and its path follower's (orange dots).
    #[arg(long)]
    pub(crate) picture: Option<PathBuf>,
}

/// Runs `host-sim generate`.
pub(crate) fn run(args: &GenerateArgs) -> Result<()> {
    if args.count == 0 || args.count > MAX_COUNT {
        bail!("--count must be in 1..={MAX_COUNT}, got {}", args.count);
    }
    if args.count > 1 && args.name.is_some() {
        bail!("--name names one world: use it without --count");
    }
    let seeds: Vec<u64> = (0..u64::from(args.count))
        .map(|k| args.seed.checked_add(k))
        .collect::<Option<_>>()
        .context("--seed + --count overflows u64")?;
    let options = |seed| Options {
        seed,
        teacher: args.teacher.clone(),
        name: args.name.clone(),
        hallway_min: args.hallway_min,
        hallway_max: args.hallway_max,
        attempts: args.attempts,
    };
    // Bad options are refused before anything is drawn or written.
    options(args.seed).check()?;
    let started = std::time::Instant::now();
    let worlds: Vec<Result<World, GenerateError>> =
        seeds.par_iter().map(|&s| generate(&options(s))).collect();
    let elapsed = started.elapsed();
    let mut failed = Vec::new();
    for (seed, w) in seeds.iter().zip(&worlds) {
        match w {
            Ok(world) => {
                report(world, args.count == 1)?;
                write(world, &args.out, args.picture.as_deref())?;
            }
            Err(e) => {
                outln!("seed {seed}: {e}")?;
                failed.push(*seed);
            }
        }
    }
    if args.count > 1 {
        out!("{}", survey(&worlds, elapsed.as_secs_f64()))?;
    }
    match failed.len() {
        0 => Ok(()),
        1 if args.count == 1 => Err(worlds
            .into_iter()
            .find_map(Result::err)
            .map(anyhow::Error::from)
            .unwrap_or_else(|| anyhow::anyhow!("no world"))),
        n => bail!("{n} of {} seeds gave no world: {failed:?}", args.count),
    }
}

fn report(world: &World, long: bool) -> Result<()> {
    let s = &world.summary;
    if long {
        for r in &world.refused {
            outln!("attempt {} refused: {}", r.attempt, r.why)?;
        }
    }
    outln!(
        "{} (seed {}, attempt {}): {} m × {} m, path {:.1} m; hallways {:?} m, {} open room(s), {} room(s) in the block; {} doors, {} staircases, {} chairs",
        world.options.name,
        world.options.seed,
        world.attempt,
        s.width,
        s.height,
        s.path_length,
        s.hallways,
        s.open_rooms,
        s.block_rooms,
        s.doors,
        s.stairs,
        s.chairs
    )?;
    if long {
        for (lap, c) in world.laps.iter().zip(&world.contrasts) {
            outln!(
                "  {:<13} lap in {} ticks; its path follower ({}, {} ticks): another choice at {} ticks, over the threshold at {}",
                c.teacher,
                lap.ticks,
                c.end,
                c.ticks,
                c.differs,
                c.over_threshold
            )?;
        }
    }
    Ok(())
}

/// A picture of `scenario` (`world`, loaded from its files, so that the outside is grey): the
/// map, path and objects, the scenario teacher's lap (purple) and its path follower's (orange
/// dots).
fn draw(world: &World, scenario: &Scenario) -> MapDrawing {
    let mut r = MapDrawing::of_scenario(scenario);
    r.trace(&world.contrast().trace);
    r.polyline(&world.lap().trace, [150, 0, 200]);
    r
}

fn write(world: &World, out: &Path, picture: Option<&Path>) -> Result<()> {
    let toml = world.write(out)?;
    for (name, _) in world.files() {
        outln!("wrote {}", out.join(name).display())?;
    }
    // What a user will load: the files just written.
    let loaded = Scenario::load(&toml)?;
    if let Some(dir) = picture {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
        let png = dir.join(format!("{}.png", world.options.name));
        draw(world, &loaded).write_png(&png)?;
        outln!("wrote {}", png.display())?;
    }
    Ok(())
}

/// What a batch of worlds looks like: attempts, refusals by reason, and per teacher how much
/// its preferences matter along the path.
fn survey(worlds: &[Result<World, GenerateError>], seconds: f64) -> String {
    let ok: Vec<&World> = worlds.iter().filter_map(|w| w.as_ref().ok()).collect();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\n{} of {} seeds gave a world in {seconds:.1} s",
        ok.len(),
        worlds.len()
    );
    let mut attempts = BTreeMap::new();
    let mut reasons = BTreeMap::new();
    for w in &ok {
        *attempts.entry(w.attempt).or_insert(0u32) += 1;
        for r in &w.refused {
            *reasons.entry(r.why.label()).or_insert(0u32) += 1;
        }
    }
    fn list<K: std::fmt::Display>(m: &BTreeMap<K, u32>) -> String {
        m.iter()
            .map(|(k, v)| format!("{k}: {v}"))
            .collect::<Vec<_>>()
            .join(", ")
    }
    let _ = writeln!(
        out,
        "accepted at attempt (attempt: worlds): {}",
        list(&attempts)
    );
    let _ = writeln!(
        out,
        "refused attempts (reason: count): {}",
        if reasons.is_empty() {
            "none".into()
        } else {
            list(&reasons)
        }
    );
    let stat = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n == 0 {
            return "-".to_string();
        }
        format!("{} / {} / {}", v[0], v[n / 2], v[n - 1])
    };
    let field = |f: &dyn Fn(&World) -> f64| stat(ok.iter().map(|w| f(w)).collect());
    let _ = writeln!(
        out,
        "min / median / max: path {} m, doors {}, staircases {}, chairs {}",
        field(&|w| (w.summary.path_length * 10.0).round() / 10.0),
        field(&|w| w.summary.doors as f64),
        field(&|w| w.summary.stairs as f64),
        field(&|w| w.summary.chairs as f64)
    );
    let _ = writeln!(
        out,
        "per teacher, along its path follower's lap (min / median / max; worlds with none):"
    );
    for (i, p) in teacher::PRESETS.iter().enumerate() {
        let differs: Vec<f64> = ok.iter().map(|w| w.contrasts[i].differs as f64).collect();
        let over: Vec<f64> = ok
            .iter()
            .map(|w| w.contrasts[i].over_threshold as f64)
            .collect();
        let none = |v: &[f64]| v.iter().filter(|&&x| x == 0.0).count();
        let _ = writeln!(
            out,
            "  {:<13} ticks with another choice {} ({}); ticks over the threshold {} ({})",
            p.name,
            stat(differs.clone()),
            none(&differs),
            stat(over.clone()),
            none(&over)
        );
    }
    out
}
