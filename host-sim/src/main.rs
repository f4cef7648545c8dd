//! `host-sim`: the command line of the simulator. `host-sim --help` lists the commands.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use firmware_core::{LearnerKind, LearnerParams};
use host_sim::experiment::{self, InProcessLink, Mode, RunConfig};
use host_sim::registry;
use host_sim::synthetic::{self, SyntheticConfig};
use host_sim::teacher::StatementSet;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

#[derive(Parser, Debug)]
#[command(
    name = "host-sim",
    version,
    about = "Teach a racecar's learner from corrective feedback, in simulation"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Use a scenario even if its teacher's own policy cannot drive a lap of it (every scenario
    /// is checked when it is loaded; skipping the check is said on standard error).
    #[arg(long, global = true)]
    no_scenario_check: bool,
}

/// Whether loaded scenarios are checked (`--no-scenario-check` clears it).
static SCENARIO_CHECK: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(true);

/// Loads a scenario by name or path: checked (its teacher must drive a lap) unless
/// `--no-scenario-check`, which is said on standard error.
fn load_scenario(name_or_path: &str) -> Result<host_sim::scenario::Scenario> {
    if SCENARIO_CHECK.load(std::sync::atomic::Ordering::Relaxed) {
        return registry::load_scenario(name_or_path);
    }
    let s = registry::load_scenario_unchecked(name_or_path)?;
    eprintln!(
        "host-sim: scenario {}: not checked (--no-scenario-check): its teacher may not be able to drive a lap",
        s.name
    );
    Ok(s)
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Watch the learner learn from a synthetic programmatic teacher (no world: random features
    /// for 64 actions, hidden teacher weights). Prints the latent-loss curve and the corrections.
    Demo(DemoArgs),
    /// Run one experiment: a learner taught by a programmatic teacher in a household.
    ///
    /// Writes DIR/steps.csv (one row per control tick: step, action, teacher_action,
    /// latent_loss, corrected, corrections, collision, reset, lap, progress, x, y, theta) and
    /// DIR/summary.json (configuration, seed, final weights, totals, mean latent loss of the
    /// first and last 10% of the steps, wall time).
    Run(RunArgs),
    /// List the built-in scenarios, teacher presets and experiments.
    List,
    /// Draw the built-in household maps into DIR (NAME.pgm + NAME.yaml, map_server format).
    GenMaps {
        /// Output folder.
        #[arg(long, default_value = "host-sim/scenarios/maps")]
        out: PathBuf,
    },
    /// Generate a household from a seed: DIR/NAME.pgm + .yaml (map_server) and DIR/NAME.toml.
    Generate(host_sim::generator::cli::GenerateArgs),
    /// Draw the 64 trajectories of the lattice into an SVG file.
    Lattice {
        /// The SVG file to write.
        #[arg(long, default_value = "lattice.svg")]
        out: PathBuf,
    },
    /// Draw a scenario's map, path and objects into a PNG, optionally with the poses of a run.
    Draw {
        /// Scenario name or file.
        #[arg(long, default_value = "doors")]
        scenario: String,
        /// A steps.csv of `host-sim run` whose poses to draw.
        #[arg(long)]
        run: Option<PathBuf>,
        /// The PNG file to write.
        #[arg(long, default_value = "scenario.png")]
        out: PathBuf,
    },
    /// Reproduce the paper's section 6: the variety, noise (and sigma sweep) and threshold
    /// experiments and the path figures, trials in parallel.
    ///
    /// Writes into DIR: variety.csv, noise.csv, thresholds.csv (per step: mean and standard
    /// deviation across trials of the latent loss and the cumulative corrections),
    /// noise_sweep.csv, summary.csv, paths.csv, figures/*.png and *.svg, and REPORT.md, which
    /// checks the paper's claims with these numbers. The learner is the paper's: plain OGD, step
    /// 0.01. With --shard i/n it runs only slice i of n of the trial grid and writes its raw
    /// results for `host-sim merge`.
    Reproduce(ReproduceArgs),
    /// Run the reproduction's claims with every teacher's weights at ×1/4, ×1/2, ×1, ×2 and ×4
    /// of the calibrated scale, and write the table of verdicts (Markdown).
    ScaleSweep(ScaleSweepArgs),
    /// Every online learner against every kind of feedback, with and without 20% random
    /// answers, in every world (docs/learners.md), and the learner `run` uses by default for
    /// each kind of feedback, chosen from it by a stated rule. Writes Markdown.
    Learners {
        /// Seeds per cell.
        #[arg(long, default_value_t = 3)]
        seeds: u32,
        /// Steps per run.
        #[arg(long, default_value_t = 5_000)]
        steps: u32,
        /// Worker threads (default: one per core). The output does not depend on it.
        #[arg(long)]
        jobs: Option<usize>,
        /// The Markdown file to write.
        #[arg(long, default_value = "out/learners.md")]
        out: PathBuf,
    },
    /// Calibrate the teachers' scale from the paper's words (docs/reproduction/CALIBRATION.md):
    /// the path follower along each teacher's lap, the targets' exact intervals, the rule's
    /// scale, and the latent-loss statistics it rests on. Prints Markdown.
    Calibrate,
    /// Merge the folders of `host-sim reproduce --shard i/n` runs into the outputs of one run
    /// (byte-identical to running the whole grid on one machine).
    Merge {
        /// The shard folders (every shard of one grid, each once).
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Output folder.
        #[arg(long, default_value = "out/reproduce")]
        out: PathBuf,
    },
    /// Measure simulated steps per second of one run on one core.
    Bench {
        /// Scenario name or file.
        #[arg(long, default_value = "doors")]
        scenario: String,
        /// Steps to simulate.
        #[arg(long, default_value_t = 5_000)]
        steps: u32,
    },
}

#[derive(clap::Args, Debug)]
struct RunArgs {
    /// Built-in scenario (doors, stairs-right, stairs-chairs, basement; see `host-sim list`) or
    /// the path of a scenario TOML file.
    #[arg(long, default_value = "doors")]
    scenario: String,
    /// How the learner is taught: action (the teacher's action), preference (learner's action
    /// vs a random one), semantic (statements such as "avoid doors"), bc (behaviour cloning on
    /// the teacher's demonstration of the run's first 50 ticks, then frozen), teacher (the
    /// teacher's own policy drives, frozen).
    #[arg(long, default_value = "action", value_parser = parse_mode)]
    feedback: Mode,
    /// Number of control ticks (0.1 s each).
    #[arg(long, default_value_t = 5_000)]
    steps: u32,
    /// Seed of the teacher's noise and random queries; the same seed gives the same CSV bytes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The teacher corrects when its perceived latent loss of the learner's action exceeds
    /// this (default: the scenario's, 1.0 unless it says otherwise).
    #[arg(long, allow_negative_numbers = true)]
    threshold: Option<f32>,
    /// Standard deviation of the Gaussian noise on every latent loss the teacher perceives
    /// (default: the scenario's, 0 unless it says otherwise).
    #[arg(long, allow_negative_numbers = true)]
    noise: Option<f32>,
    /// Online learner: ogd, ogd-decaying, averaged-ogd, adagrad or coactive. Default: the one
    /// docs/learners.md chose for the kind of feedback (`host-sim learners`).
    #[arg(long, value_parser = parse_kind)]
    learner: Option<LearnerKind>,
    /// Step size (default: the learner's own: 0.01 for the OGD family, 0.1 AdaGrad, 1 coactive).
    #[arg(long, allow_negative_numbers = true)]
    step: Option<f32>,
    /// What the semantic teacher says: paper (doors, stairs, chairs and the path by cross-track
    /// error, the paper's teacher; the default) or rich (every feature the teacher weighs, also
    /// obstacles and keep right).
    #[arg(long, default_value = "paper", value_parser = parse_statements)]
    statements: StatementSet,
    /// Probability that a correction answers at random (a random action, statements towards a
    /// random action, or a coin's preference), drawn from the run's seed. Default 0.
    #[arg(long, allow_negative_numbers = true)]
    random_answers: Option<f32>,
    /// Output folder (created if missing).
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Run the learner on the car's controller over this CAN link (udp://127.0.0.1:PORT,
    /// slcan+tcp://127.0.0.1:PORT, slcan+serial:///dev/…, socketcan://IFACE; `hil_mock serve`
    /// or the firmware at the other end). Without it, the learner runs in this process.
    #[arg(long)]
    link: Option<String>,
    /// With --link: write every frame to this candump log.
    #[arg(long, requires = "link")]
    record: Option<PathBuf>,
    /// With --link: disturb the frames the host sends (drop=P,corrupt=P,duplicate=P,
    /// reorder=P,delay=P,max-delay-ms=N,seed=N).
    #[arg(long, requires = "link")]
    faults: Option<String>,
    /// With --link: the frames the host sends, classic or fd.
    #[arg(long, requires = "link", default_value = "fd", value_parser = parse_frame_mode)]
    frame_mode: protocol::isotp::FrameMode,
    /// With --link: wait this long for each answer before sending the request again (ms). The
    /// default suits loopback and CAN; a slow serial line needs more.
    #[arg(long, requires = "link", default_value_t = 20)]
    try_timeout_ms: u64,
    /// With --link: the car's key file (`hil_mock keygen FILE`); without it (or --insecure)
    /// a run over a link refuses to start.
    #[arg(long, requires = "link", conflicts_with = "insecure")]
    key: Option<PathBuf>,
    /// With --link: use the public all-zero key (anyone on the bus can drive and teach the car).
    #[arg(long, requires = "link")]
    insecure: bool,
}

fn parse_frame_mode(s: &str) -> Result<protocol::isotp::FrameMode, String> {
    match s {
        "classic" => Ok(protocol::isotp::FrameMode::Classic),
        "fd" => Ok(protocol::isotp::FrameMode::Fd),
        _ => Err(format!("unknown frame mode '{s}', expected classic or fd")),
    }
}

/// The learner's link for `run`: in process, or a `RemoteCar` over `--link`.
fn car_link(args: &RunArgs, config: &RunConfig) -> Result<Box<dyn experiment::CarLink>> {
    use hil_mock::transport::fault::{FaultConfig, FaultyLink};
    use hil_mock::transport::record::RecordingLink;
    use hil_mock::transport::{Link, LinkAddress};
    let Some(link) = &args.link else {
        return Ok(Box::new(InProcessLink::new(config.learner)?));
    };
    let key = hil_mock::key::choose(args.key.as_deref(), args.insecure, "host-sim")?;
    let address: LinkAddress = link.parse()?;
    let faults = args
        .faults
        .as_deref()
        .map(|f| f.parse::<FaultConfig>().map_err(anyhow::Error::msg))
        .transpose()
        .context("--faults")?;
    let mut link: Box<dyn Link> = match address {
        // A TCP connection ends with the car's process: open it again when the car is back.
        LinkAddress::SlcanTcp(_) => {
            Box::new(hil_mock::transport::reconnect::ReconnectingLink::open(
                address,
                std::time::Duration::from_secs(30),
            )?)
        }
        _ => address.open(std::time::Duration::from_secs(30))?,
    };
    if let Some(path) = &args.record {
        link = Box::new(RecordingLink::new(link, path, "can0")?);
    }
    if let Some(f) = faults {
        link = Box::new(FaultyLink::new(link, f));
    }
    eprintln!(
        "host-sim: the learner runs on the car, over {}",
        link.describe()
    );
    let remote = host_sim::remote::RemoteCar::new(
        link,
        host_sim::remote::RemoteConfig {
            mode: args.frame_mode,
            try_timeout: std::time::Duration::from_millis(args.try_timeout_ms.max(1)),
            ..host_sim::remote::RemoteConfig::new(key)
        },
    );
    Ok(Box::new(remote))
}

#[derive(clap::Args, Debug)]
struct ReproduceArgs {
    /// Trials per setting (trial t has seed SEED + t).
    #[arg(long, default_value_t = 10)]
    trials: u32,
    /// Control ticks per trial.
    #[arg(long, default_value_t = 5_000)]
    steps: u32,
    /// Seed of trial 0.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: one per core). The outputs do not depend on it.
    #[arg(long)]
    jobs: Option<usize>,
    /// Output folder (created if missing).
    #[arg(long, default_value = "out/reproduce")]
    out: PathBuf,
    /// Run only slice INDEX of COUNT of the trial grid (INDEX from 0, e.g. a SLURM array task id
    /// or a Kubernetes JOB_COMPLETION_INDEX) and write its raw results for `host-sim merge`.
    #[arg(long, value_name = "INDEX/COUNT")]
    shard: Option<host_sim::reproduce::Shard>,
    /// Multiply every teacher's weights by this factor (default 1: the calibrated teachers of
    /// docs/reproduction/CALIBRATION.md).
    #[arg(long, default_value_t = 1.0)]
    teacher_scale: f32,
}

#[derive(clap::Args, Debug)]
struct ScaleSweepArgs {
    /// Trials per setting (fewer than the report's 10 keeps the five grids quick; the output
    /// says how many).
    #[arg(long, default_value_t = 5)]
    trials: u32,
    /// Control ticks per trial.
    #[arg(long, default_value_t = 5_000)]
    steps: u32,
    /// Seed of trial 0.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: one per core). The output does not depend on it.
    #[arg(long)]
    jobs: Option<usize>,
    /// The Markdown file to write.
    #[arg(long, default_value = "out/SCALE_SWEEP.md")]
    out: PathBuf,
}

#[derive(clap::Args, Debug)]
struct DemoArgs {
    /// Number of rounds.
    #[arg(long, default_value_t = 5_000)]
    steps: usize,
    /// Seed of the teacher and of every random draw; the same seed gives the same run.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The teacher corrects when the latent loss of the learner's action exceeds this.
    #[arg(long, default_value_t = 0.05)]
    threshold: f32,
    /// Probability that a correction names a random action instead of the teacher's best.
    #[arg(long, default_value_t = 0.0)]
    noise: f64,
    /// Online learner: ogd, ogd-decaying, averaged-ogd, adagrad or coactive.
    #[arg(long, default_value = "averaged-ogd", value_parser = parse_kind)]
    learner: LearnerKind,
    /// Step size (default: the learner's own, 0.01 for the OGD family).
    #[arg(long)]
    step: Option<f32>,
    /// Number of lines of the printed curve (rows cover geometrically growing spans of rounds).
    #[arg(long, default_value_t = 16)]
    rows: usize,
}

fn parse_kind(s: &str) -> Result<LearnerKind, String> {
    LearnerKind::from_name(s).ok_or_else(|| {
        let names: Vec<_> = LearnerKind::ALL.iter().map(|k| k.name()).collect();
        format!(
            "unknown learner '{s}', expected one of {}",
            names.join(", ")
        )
    })
}

fn parse_statements(s: &str) -> Result<StatementSet, String> {
    StatementSet::from_name(s)
        .ok_or_else(|| format!("unknown statement set '{s}', expected paper or rich"))
}

fn parse_mode(s: &str) -> Result<Mode, String> {
    Mode::from_name(s).ok_or_else(|| {
        format!("unknown feedback '{s}', expected one of action, preference, semantic, bc, teacher")
    })
}

fn run_config(args: &RunArgs) -> Result<RunConfig> {
    let scenario = load_scenario(&args.scenario)?;
    let kind = args
        .learner
        .unwrap_or_else(|| host_sim::learners::default_learner(args.feedback));
    let mut learner = LearnerParams::new(kind);
    if let Some(step) = args.step {
        learner = learner.with_step(step);
    }
    let config = RunConfig {
        mode: args.feedback,
        steps: args.steps,
        seed: args.seed,
        threshold: args.threshold,
        noise: args.noise,
        learner,
        statements: Some(args.statements),
        random_answers: args.random_answers,
        ..RunConfig::new(Arc::new(scenario))
    };
    config.check()?;
    Ok(config)
}

fn prepare_out(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("output folder {}: cannot create", dir.display()))?;
    let probe = dir.join(".host-sim-write-test");
    std::fs::write(&probe, b"")
        .with_context(|| format!("output folder {}: not writable", dir.display()))?;
    let _ = std::fs::remove_file(probe);
    Ok(())
}

fn run(args: &RunArgs) -> Result<()> {
    let config = run_config(args)?;
    prepare_out(&args.out)?;
    let bar = progress_bar(
        config.steps as u64,
        "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} steps ({per_sec}) {msg}",
    );
    let mut link = car_link(args, &config)?;
    let started = Instant::now();
    let report = experiment::run_with(&config, &mut *link, &mut |r| {
        if r.step % 50 == 0 {
            bar.set_position(r.step as u64);
            bar.set_message(format!("{} corrections, {} laps", r.corrections, r.lap));
        }
    })?;
    bar.finish_and_clear();
    let wall = started.elapsed().as_secs_f64();
    let csv = args.out.join("steps.csv");
    std::fs::write(&csv, report.csv_bytes())
        .with_context(|| format!("{}: cannot write", csv.display()))?;
    let mut summary = report.summary();
    summary["wall_time_s"] = serde_json::json!(wall);
    let json = args.out.join("summary.json");
    let text = serde_json::to_string_pretty(&summary)?;
    std::fs::write(&json, text + "\n")
        .with_context(|| format!("{}: cannot write", json.display()))?;
    let (first, last) = report.first_last(0.1);
    println!(
        "{} / {} / seed {}: {} steps, mean latent loss {:.3} (first 10%) -> {:.3} (last 10%), {} corrections, {}",
        report.scenario,
        config.mode.name(),
        config.seed,
        report.records.len(),
        first,
        last,
        report.corrections(),
        report.task_success().describe()
    );
    println!("final weights {:?}", report.final_snapshot.state.average);
    println!(
        "wrote {} and {} ({wall:.2} s)",
        csv.display(),
        json.display()
    );
    Ok(())
}

fn list() {
    println!("scenarios (--scenario NAME, or a path to your own .toml):");
    for s in registry::SCENARIOS {
        let length = load_scenario(s.name)
            .map(|scn| format!("{:6.1} m path", scn.path.length()))
            .unwrap_or_else(|e| format!("(cannot load: {e})"));
        println!("  {:<14} {length}  {}", s.name, s.description);
    }
    println!("teacher presets (weights: obstacles, door, stairs, chair, path, right):");
    for p in host_sim::teacher::PRESETS {
        println!("  {:<14} {:?}  {}", p.name, p.weights, p.description);
    }
    println!("experiments:");
    for e in registry::EXPERIMENTS {
        println!("  {:<14} {}", e.name, e.description);
    }
}

fn draw(scenario: &str, run: Option<&Path>, out: &Path) -> Result<()> {
    let s = load_scenario(scenario)?;
    let mut raster = host_sim::plot::Raster::of_scenario(&s);
    if let Some(csv) = run {
        raster.trace(&host_sim::plot::read_trace(csv)?);
    }
    raster.write_png(out)?;
    println!("wrote {}", out.display());
    Ok(())
}

fn reproduce(args: &ReproduceArgs) -> Result<()> {
    use host_sim::reproduce::{self, Options, Shard};
    let o = Options {
        trials: args.trials,
        steps: args.steps,
        seed: args.seed,
        teacher_scale: args.teacher_scale,
    };
    o.check()?;
    let shard = args.shard.unwrap_or(Shard::WHOLE);
    prepare_out(&args.out)?;
    let pool = worker_pool(args.jobs)?;
    let jobs = reproduce::jobs(&o, shard).len();
    let bar = progress_bar(
        jobs as u64,
        "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} trials, {eta} left {msg}",
    );
    bar.set_message(format!("({} threads)", pool.current_num_threads()));
    let started = Instant::now();
    let results = pool.install(|| reproduce::run_shard(&o, shard, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let ran = started.elapsed().as_secs_f64();
    println!(
        "ran {jobs} trials of {} steps on {} threads in {ran:.1} s",
        o.steps,
        pool.current_num_threads()
    );
    if shard.count > 1 {
        reproduce::write_shard(&args.out, &o, shard, &results)?;
        println!(
            "wrote shard {}/{} into {}; combine every shard with `host-sim merge DIR... --out DIR`",
            shard.index,
            shard.count,
            args.out.display()
        );
        return Ok(());
    }
    let report = reproduce::finalize(&args.out, &o, &results)?;
    print_outcome(&args.out, &report);
    println!(
        "wall time {:.1} s ({ran:.1} s of trials)",
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The rayon pool of `--jobs` threads (default: one per core).
fn worker_pool(jobs: Option<usize>) -> Result<rayon::ThreadPool> {
    if jobs == Some(0) {
        bail!("--jobs must be positive");
    }
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = jobs {
        pool = pool.num_threads(n);
    }
    pool.build().context("cannot start the worker threads")
}

fn scale_sweep(args: &ScaleSweepArgs) -> Result<()> {
    use host_sim::reproduce::{self, Options, SWEEP_FACTORS, Shard};
    let o = Options {
        trials: args.trials,
        steps: args.steps,
        seed: args.seed,
        teacher_scale: 1.0,
    };
    o.check()?;
    let pool = worker_pool(args.jobs)?;
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        prepare_out(parent)?;
    }
    let jobs = reproduce::jobs(&o, Shard::WHOLE).len() * SWEEP_FACTORS.len();
    let bar = progress_bar(
        jobs as u64,
        "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} trials, {eta} left {msg}",
    );
    let started = Instant::now();
    let rows = pool.install(|| reproduce::scale_sweep(&o, &SWEEP_FACTORS, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let text = reproduce::scale_sweep_markdown(&o, &rows);
    std::fs::write(&args.out, &text)
        .with_context(|| format!("{}: cannot write", args.out.display()))?;
    for line in text.lines().filter(|l| l.starts_with("| ")) {
        println!("{line}");
    }
    println!(
        "wrote {} ({jobs} trials on {} threads in {:.1} s)",
        args.out.display(),
        pool.current_num_threads(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

fn learners(seeds: u32, steps: u32, jobs: Option<usize>, out: &Path) -> Result<()> {
    use host_sim::learners::{self, Options};
    let o = Options { seeds, steps };
    let pool = worker_pool(jobs)?;
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        prepare_out(parent)?;
    }
    let runs = learners::cells().len() * seeds as usize;
    let bar = progress_bar(
        runs as u64,
        "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} runs, {eta} left",
    );
    let started = Instant::now();
    let cells = pool.install(|| learners::run_table(&o, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let text = learners::markdown(&o, &cells);
    std::fs::write(out, &text).with_context(|| format!("{}: cannot write", out.display()))?;
    for line in text.lines().filter(|l| l.starts_with("**Chosen")) {
        println!("{line}");
    }
    println!(
        "wrote {} ({runs} runs on {} threads in {:.1} s)",
        out.display(),
        pool.current_num_threads(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

fn print_outcome(out: &Path, report: &str) {
    for line in report
        .lines()
        .filter(|l| l.starts_with("| ") && l.ends_with("hold** |") || l.ends_with("holds** |"))
    {
        println!("{line}");
    }
    println!("report:  {}", out.join("REPORT.md").display());
    println!("figures: {}", out.join("figures").display());
}

fn merge(dirs: &[PathBuf], out: &Path) -> Result<()> {
    let started = Instant::now();
    let (o, results) = host_sim::reproduce::read_shards(dirs)?;
    prepare_out(out)?;
    let report = host_sim::reproduce::finalize(out, &o, &results)?;
    println!(
        "merged {} shard folders ({} trials x {} steps) in {:.1} s",
        dirs.len(),
        o.trials,
        o.steps,
        started.elapsed().as_secs_f64()
    );
    print_outcome(out, &report);
    Ok(())
}

fn bench(scenario: &str, steps: u32) -> Result<()> {
    if steps == 0 {
        bail!("--steps must be positive");
    }
    let s = Arc::new(load_scenario(scenario)?);
    let config = RunConfig {
        steps,
        ..RunConfig::new(s)
    };
    let started = Instant::now();
    let report = experiment::run(&config)?;
    let wall = started.elapsed().as_secs_f64();
    println!(
        "{}: {} simulated steps (action feedback, {} corrections) in {:.3} s: {:.0} steps/s on one core",
        report.scenario,
        steps,
        report.corrections(),
        wall,
        steps as f64 / wall
    );
    Ok(())
}

fn demo(args: &DemoArgs) -> Result<()> {
    anyhow::ensure!(
        args.steps > 0 && args.rows > 0,
        "--steps and --rows must be positive"
    );
    let mut learner = LearnerParams::new(args.learner);
    if let Some(step) = args.step {
        learner = learner.with_step(step);
    }
    let config = SyntheticConfig {
        steps: args.steps,
        seed: args.seed,
        threshold: args.threshold,
        noise: args.noise,
        learner,
        ..SyntheticConfig::default()
    };
    println!(
        "synthetic teacher: {} rounds, seed {}, threshold {}, {:.0}% random answers, learner {}",
        config.steps,
        config.seed,
        config.threshold,
        100.0 * config.noise,
        args.learner.name()
    );
    let report = synthetic::run(&config)?;
    // Row boundaries spaced geometrically, so the fast early learning gets rows of its own.
    let mut bounds = vec![0usize];
    for k in 1..=args.rows {
        let b = ((args.steps as f64).powf(k as f64 / args.rows as f64)).round() as usize;
        if b > *bounds.last().unwrap_or(&0) {
            bounds.push(b.min(args.steps));
        }
    }
    let random_mean = report.random_loss.iter().map(|&x| x as f64).sum::<f64>() / args.steps as f64;
    println!(
        "{:>13}  {:>11}  {:>11}  latent loss (40 marks = a random policy's)",
        "rounds", "mean loss", "corrections"
    );
    let mut corrections = 0;
    for w in bounds.windows(2) {
        let (start, end) = (w[0], w[1]);
        let chunk = &report.latent_loss[start..end];
        let mean = chunk.iter().map(|&x| x as f64).sum::<f64>() / chunk.len() as f64;
        corrections += report.corrected[start..end].iter().filter(|&&c| c).count();
        let bar = ((40.0 * mean / random_mean).round() as usize).min(60);
        println!(
            "{:>6}-{:<6}  {:>11.5}  {:>11}  {}",
            start,
            end - 1,
            mean,
            corrections,
            "#".repeat(bar)
        );
    }
    let tail = (args.steps / 10).max(1);
    let tail_mean = report.latent_loss[args.steps - tail..]
        .iter()
        .map(|&x| x as f64)
        .sum::<f64>()
        / tail as f64;
    println!(
        "last {tail} rounds: mean latent loss {tail_mean:.5} ({:.3}% of a random policy's {random_mean:.3}); {} corrections in all",
        100.0 * tail_mean / random_mean,
        report.corrections()
    );
    println!("teacher weights {:?}", report.teacher);
    println!("learned weights {:?}", report.weights);
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if cli.no_scenario_check {
        SCENARIO_CHECK.store(false, std::sync::atomic::Ordering::Relaxed);
    }
    let result = match &cli.command {
        Command::Demo(args) => demo(args),
        Command::Run(args) => run(args),
        Command::List => {
            list();
            Ok(())
        }
        Command::GenMaps { out } => host_sim::households::write_all(out).map(|files| {
            for f in files {
                println!("wrote {f}");
            }
        }),
        Command::Generate(args) => host_sim::generator::cli::run(args),
        Command::Lattice { out } => host_sim::plot::lattice_svg(out).map(|()| {
            println!("wrote {}", out.display());
        }),
        Command::Bench { scenario, steps } => bench(scenario, *steps),
        Command::Reproduce(args) => reproduce(args),
        Command::Merge { dirs, out } => merge(dirs, out),
        Command::ScaleSweep(args) => scale_sweep(args),
        Command::Learners {
            seeds,
            steps,
            jobs,
            out,
        } => learners(*seeds, *steps, *jobs, out),
        Command::Calibrate => host_sim::calibrate::run().map(|c| {
            print!("{}", host_sim::calibrate::markdown(&c));
        }),
        Command::Draw { scenario, run, out } => draw(scenario, run.as_deref(), out),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("host-sim: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// A progress bar of `len` units on standard error, hidden when that is not a terminal.
fn progress_bar(len: u64, template: &str) -> ProgressBar {
    let target = if std::io::stderr().is_terminal() {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    };
    let bar = ProgressBar::with_draw_target(Some(len), target);
    bar.set_style(
        ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}
