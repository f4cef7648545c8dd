//! `host-sim`: the command line of the simulator. `host-sim --help` lists the commands.
//!
//! This file holds the commands' list and `host-sim run`; the other commands are in [`cli`].

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use firmware_core::{LearnerKind, LearnerParams};
use host_sim::teach::experiment::{self, InProcessLink, Mode, RunConfig};
use host_sim::world::registry;
use host_sim::world::teacher::StatementSet;

mod cli;

use cli::{parse_kind, prepare_out, progress_bar};

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
fn load_scenario(name_or_path: &str) -> Result<host_sim::world::scenario::Scenario> {
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
    Demo(cli::demo::DemoArgs),
    /// Run one experiment: a learner taught by a programmatic teacher in a household.
    ///
    /// Writes DIR/steps.csv (one row per control tick: step, action, teacher_action,
    /// latent_loss, corrected, corrections, collision, reset, lap, progress, x, y, theta,
    /// feedback (the kind given, if any), effort_s (a person's seconds for it)) and
    /// DIR/summary.json (configuration, seed, final weights, totals with the effort and the
    /// feedback of each kind, mean latent loss of the first and last 10% of the steps, wall
    /// time).
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
    Generate(cli::generate::GenerateArgs),
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
    Reproduce(cli::reproduce::ReproduceArgs),
    /// Run the reproduction's claims with every teacher's weights at ×1/4, ×1/2, ×1, ×2 and ×4
    /// of the calibrated scale, and write the table of verdicts (Markdown).
    ScaleSweep(cli::reproduce::ScaleSweepArgs),
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
    /// How the learner is taught. One kind of feedback (the teacher corrects when its perceived
    /// latent loss of the learner's action exceeds the threshold, and says):
    ///
    ///   action        the action it wanted
    ///   preference    which of two (the learner's and a random one) it prefers
    ///   semantic      statements such as "avoid doors", "stay on the path"
    ///   perturbation  it pushes the learner's trajectory half way towards the one it wanted
    ///                 (the pushed trajectory's features go to the car)
    ///   reward        a score of the learner's action in [-1, 1] (-1 for a perceived loss of 10
    ///                 or more)
    ///   correctness   "incorrect" about the learner's action
    ///   span          "bad" about a stretch of up to 4 ticks it would correct, once it ends
    ///   ranking       the order of 4 shown actions (the learner's and 3 random ones)
    ///   estop         it stops the car (the car stands this tick)
    ///
    /// Or several kinds in one stream: mix:KIND=WEIGHT,... draws the kind of each correction
    /// with these weights from the run's seed (any non-negative numbers, at least one positive,
    /// each kind once; e.g. mix:action=0.2,preference=0.3,semantic=0.5), mix:all (the nine in
    /// equal parts), cheapest (the kind cheapest for a person that is still informative; the
    /// effort each kind costs is in `host-sim/src/teach/kinds.rs`). Or no online learning: bc
    /// (behaviour cloning on the teacher's demonstration of the run's first 50 ticks, then
    /// frozen), teacher (the teacher's own policy drives, frozen).
    #[arg(long, default_value = "action", value_parser = parse_mode, verbatim_doc_comment)]
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
    /// docs/learners.md chose for action, preference and semantic feedback (`host-sim
    /// learners`); averaged-ogd for the other kinds, mixes and cheapest.
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
    let remote = host_sim::teach::remote::RemoteCar::new(
        link,
        host_sim::teach::remote::RemoteConfig {
            mode: args.frame_mode,
            try_timeout: std::time::Duration::from_millis(args.try_timeout_ms.max(1)),
            ..host_sim::teach::remote::RemoteConfig::new(key)
        },
    );
    Ok(Box::new(remote))
}

fn parse_statements(s: &str) -> Result<StatementSet, String> {
    StatementSet::from_name(s)
        .ok_or_else(|| format!("unknown statement set '{s}', expected paper or rich"))
}

fn parse_mode(s: &str) -> Result<Mode, String> {
    Mode::parse(s)
}

fn run_config(args: &RunArgs) -> Result<RunConfig> {
    let scenario = load_scenario(&args.scenario)?;
    let kind = args
        .learner
        .unwrap_or_else(|| host_sim::teach::learners::default_learner(args.feedback));
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

fn main() -> ExitCode {
    let cli = Cli::parse();
    if cli.no_scenario_check {
        SCENARIO_CHECK.store(false, std::sync::atomic::Ordering::Relaxed);
    }
    let result = match &cli.command {
        Command::Demo(args) => cli::demo::demo(args),
        Command::Run(args) => run(args),
        Command::List => {
            cli::inspect::list();
            Ok(())
        }
        Command::GenMaps { out } => host_sim::world::households::write_all(out).map(|files| {
            for f in files {
                println!("wrote {f}");
            }
        }),
        Command::Generate(args) => cli::generate::run(args),
        Command::Lattice { out } => host_sim::report::plot::lattice_svg(out).map(|()| {
            println!("wrote {}", out.display());
        }),
        Command::Bench { scenario, steps } => cli::inspect::bench(scenario, *steps),
        Command::Reproduce(args) => cli::reproduce::reproduce(args),
        Command::Merge { dirs, out } => cli::reproduce::merge(dirs, out),
        Command::ScaleSweep(args) => cli::reproduce::scale_sweep(args),
        Command::Learners {
            seeds,
            steps,
            jobs,
            out,
        } => cli::learners::learners(*seeds, *steps, *jobs, out),
        Command::Calibrate => host_sim::teach::calibrate::run().map(|c| {
            print!("{}", host_sim::teach::calibrate::markdown(&c));
        }),
        Command::Draw { scenario, run, out } => cli::inspect::draw(scenario, run.as_deref(), out),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("host-sim: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
