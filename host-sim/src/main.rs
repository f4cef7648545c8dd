//! `host-sim`: the command line of the simulator. `host-sim --help` lists the commands.
//!
//! This file holds the commands' list and `host-sim run`; the other commands are in [`cli`].

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use host_sim::checks;
use host_sim::teach::experiment::{self, InProcessLink, Mode, RunConfig};
use host_sim::world::registry;
use host_sim::world::teacher::StatementSet;

mod cli;

use cli::{out, outln, prepare_out, progress_bar};

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
    /// feedback (the kind given, if any), effort_s (a person's seconds for it); units in
    /// docs/outputs.md), DIR/summary.json (configuration, seed, final weights by feature,
    /// totals with the effort and the feedback of each kind, mean latent loss of the first and
    /// last 10% of the steps, wall time) and DIR/run.png and run.svg (the latent loss and the
    /// corrections against the tick).
    Run(RunArgs),
    /// Teach the car yourself, from a web page: a console on 127.0.0.1 (the URL with its
    /// one-time token is printed; nothing is opened by itself). The learner runs in this process,
    /// or on the car with --link.
    ///
    /// Writes into the session's folder: steps.csv and summary.json (as `run` does),
    /// feedback.jsonl (every teaching: tick, kind, content, wall time), snapshots.jsonl (the
    /// learner after every feedback) and, with --link, candump.log.
    Teach(cli::teach::TeachArgs),
    /// Replay a session of `host-sim teach` against a fresh learner in this process and check
    /// that steps.csv, snapshots.jsonl and the final weights come out byte for byte the same.
    ReplaySession(cli::teach::ReplayArgs),
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
    /// Draw a scenario's map, path and objects into a PNG, optionally with the poses of a run,
    /// or a run as an animation (--run DIR --animate OUT).
    Draw(cli::inspect::DrawArgs),
    /// Reproduce the paper's section 6: the variety, noise (and σ sweep) and threshold
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
        /// Seeds per cell, 1 to 100.
        #[arg(long, default_value_t = 3, allow_negative_numbers = true,
              value_parser = checks::count_flag(host_sim::teach::learners::SEEDS))]
        seeds: u32,
        /// Steps per run, 10 to 10 000 000.
        #[arg(long, default_value_t = 5_000, allow_negative_numbers = true,
              value_parser = checks::count_flag(host_sim::teach::learners::STEPS))]
        steps: u32,
        /// Worker threads (default: one per core). The output does not depend on it.
        #[arg(long, allow_negative_numbers = true, value_parser = checks::count_flag(cli::JOBS))]
        jobs: Option<u32>,
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
        /// Steps to simulate, 1 to 10 000 000.
        #[arg(long, default_value_t = 5_000, allow_negative_numbers = true,
              value_parser = checks::count_flag(1..=checks::MAX_STEPS))]
        steps: u32,
        /// Times to run it, 1 to 1 000: each run is timed alone, then the best, the median and
        /// the worst are given (this machine's speed moves from one run to the next).
        #[arg(long, default_value_t = 5, allow_negative_numbers = true,
              value_parser = checks::count_flag(1..=1_000))]
        runs: u32,
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
    /// Number of control ticks (0.1 s each), 1 to 10 000 000.
    #[arg(long, default_value_t = 5_000, allow_negative_numbers = true,
          value_parser = checks::count_flag(1..=checks::MAX_STEPS))]
    steps: u32,
    /// Seed of the teacher's noise and random queries; the same seed gives the same CSV bytes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The teacher corrects when its perceived latent loss of the learner's action exceeds
    /// this, 0 to 1000 (default: the scenario's, 1.0 unless it says otherwise).
    #[arg(long, allow_negative_numbers = true, value_parser = checks::flag(checks::threshold))]
    threshold: Option<f64>,
    /// Standard deviation σ of the Gaussian noise on every latent loss the teacher perceives,
    /// 0 to 1000 (default: the scenario's, 0 unless it says otherwise).
    #[arg(long, allow_negative_numbers = true, value_parser = checks::flag(checks::noise))]
    noise: Option<f64>,
    #[command(flatten)]
    learner: cli::LearnerArgs,
    /// Start from the learner in this file (parameters and state, as `--save-learner` wrote
    /// it) instead of a fresh one: teach it further, or test it in another household. Online
    /// feedback only; a file of another format version, or a corrupted one, is refused.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["learner", "step"])]
    load_learner: Option<PathBuf>,
    /// After the run, write the learner (parameters and state: the versioned snapshot the car
    /// persists in its flash) to this file, for `--load-learner`.
    #[arg(long, value_name = "FILE")]
    save_learner: Option<PathBuf>,
    /// What the semantic teacher says: paper (doors, stairs, chairs and the path by cross-track
    /// error, the paper's teacher; the default) or rich (every feature the teacher weighs, also
    /// obstacles and keep right).
    #[arg(long, default_value = "paper")]
    statements: StatementSet,
    /// Probability that a correction answers at random (a random action, statements towards a
    /// random action, or a coin's preference), drawn from the run's seed. Default 0.
    #[arg(long, allow_negative_numbers = true, value_parser = checks::flag(checks::probability))]
    random_answers: Option<f64>,
    /// Output folder (created if missing).
    #[arg(long, default_value = "out")]
    out: PathBuf,
    #[command(flatten)]
    link: cli::link::LinkArgs,
    /// With --link: write every frame to this candump log.
    #[arg(long, requires = "link")]
    record: Option<PathBuf>,
}

/// The learner's link for `run`: in process, or a `RemoteCar` over `--link`.
fn car_link(args: &RunArgs, config: &RunConfig) -> Result<Box<dyn experiment::CarLink>> {
    Ok(
        match cli::link::remote_car(&args.link, args.record.as_deref())? {
            Some(remote) => Box::new(remote),
            None => Box::new(InProcessLink::new(config.learner)?),
        },
    )
}

fn parse_mode(s: &str) -> Result<Mode, String> {
    Mode::parse(s)
}

fn run_config(args: &RunArgs) -> Result<RunConfig> {
    let scenario = load_scenario(&args.scenario)?;
    let mut learner = args
        .learner
        .params(|| host_sim::teach::learners::default_learner(args.feedback));
    let initial = match &args.load_learner {
        Some(path) => {
            let snapshot = host_sim::teach::learner_file::load(path)?;
            learner = snapshot.params;
            Some(snapshot)
        }
        None => None,
    };
    let config = RunConfig {
        mode: args.feedback,
        steps: args.steps,
        seed: args.seed,
        threshold: args.threshold.map(|t| t as f32),
        noise: args.noise.map(|n| n as f32),
        learner,
        statements: Some(args.statements),
        random_answers: args.random_answers.map(|p| p as f32),
        initial,
        ..RunConfig::new(Arc::new(scenario))
    };
    config.check()?;
    Ok(config)
}

fn run(args: &RunArgs) -> Result<()> {
    let config = run_config(args)?;
    let out_dir = prepare_out(&args.out)?;
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
    // Where the scenario came from, so `draw --run` finds it and refuses another.
    let source = &config.scenario.source;
    let source = std::fs::canonicalize(source).unwrap_or_else(|_| source.clone());
    summary["config"]["scenario_file"] = serde_json::json!(source);
    if let (Some(path), Some(initial)) = (&args.load_learner, &config.initial) {
        summary["config"]["loaded_learner"] = serde_json::json!({
            "file": path,
            "learner_steps": initial.state.steps,
            "weights": host_sim::teach::record::weights_by_name(&initial.state.average),
        });
    }
    let json = args.out.join("summary.json");
    let text = serde_json::to_string_pretty(&summary)?;
    std::fs::write(&json, text + "\n")
        .with_context(|| format!("{}: cannot write", json.display()))?;
    let figure = args.out.join("run");
    host_sim::report::run_figure::write_run_figure(&figure, &report)?;
    if let Some(path) = &args.save_learner {
        host_sim::teach::learner_file::save(&report.final_snapshot, path)?;
    }
    out_dir.keep();
    let (first, last) = report.first_last(0.1);
    outln!(
        "{} / {} / seed {}: {} steps, mean latent loss {:.3} (first 10%) -> {:.3} (last 10%), {} corrections, {}",
        report.scenario,
        config.mode.name(),
        config.seed,
        report.records.len(),
        first,
        last,
        report.corrections(),
        report.task_success().describe()
    )?;
    outln!(
        "final weights: {}",
        host_sim::teach::record::describe_weights(&report.final_snapshot.state.average)
    )?;
    outln!(
        "wrote {}, {} and {} ({wall:.2} s)",
        csv.display(),
        json.display(),
        figure.with_extension("png").display()
    )?;
    if let Some(path) = &args.save_learner {
        outln!(
            "saved the learner ({}, {} steps) to {}",
            config.learner.kind.name(),
            report.final_snapshot.state.steps,
            path.display()
        )?;
    }
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
        Command::Teach(args) => cli::teach::teach(args, load_scenario),
        Command::ReplaySession(args) => cli::teach::replay_session(args, load_scenario),
        Command::List => cli::inspect::list(),
        Command::GenMaps { out } => host_sim::world::households::write_all(out).and_then(|files| {
            for f in files {
                outln!("wrote {f}")?;
            }
            Ok(())
        }),
        Command::Generate(args) => cli::generate::run(args),
        Command::Lattice { out } => host_sim::report::plot::lattice_svg(out)
            .and_then(|()| Ok(outln!("wrote {}", out.display())?)),
        Command::Bench {
            scenario,
            steps,
            runs,
        } => cli::inspect::bench(scenario, *steps, *runs),
        Command::Reproduce(args) => cli::reproduce::reproduce(args),
        Command::Merge { dirs, out } => cli::reproduce::merge(dirs, out),
        Command::ScaleSweep(args) => cli::reproduce::scale_sweep(args),
        Command::Learners {
            seeds,
            steps,
            jobs,
            out,
        } => cli::learners::learners(*seeds, *steps, *jobs, out),
        Command::Calibrate => host_sim::teach::calibrate::run()
            .and_then(|c| Ok(out!("{}", host_sim::teach::calibrate::markdown(&c))?)),
        Command::Draw(args) => cli::inspect::draw(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // Whoever read standard output has gone (`host-sim list | head -1`): nothing to say.
        Err(e) if cli::closed_stdout(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("host-sim: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
