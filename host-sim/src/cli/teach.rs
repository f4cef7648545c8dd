//! `host-sim teach` (a person teaches the car from a web page) and `host-sim replay-session`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{Result, bail};
use host_sim::checks::{self, MAX_STEPS};
use host_sim::console::Console;
use host_sim::teach::config::{Mode, RunConfig};
use host_sim::teach::experiment::InProcessLink;
use host_sim::teach::session::{
    Recorded, Session, SessionAbout, SessionFiles, SessionLink, names, replay,
};
use host_sim::world::scenario::Scenario;
use host_sim::world::teacher::FeedbackKind;

use super::LearnerArgs;
use super::link::{LinkArgs, remote_car};

#[derive(clap::Args, Debug)]
pub(crate) struct TeachArgs {
    /// Built-in scenario (doors, stairs-right, stairs-chairs, basement; see `host-sim list`) or
    /// the path of a scenario TOML file.
    #[arg(long, default_value = "doors")]
    scenario: String,
    // The learner (default: the one docs/learners.md chose for action feedback: a click is
    // action feedback).
    #[command(flatten)]
    learner: LearnerArgs,
    /// Seed of the scenario teacher's noise (its latent-loss line; the learner never sees it).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// The session's folder (created; refused if it holds a session). Default:
    /// out/sessions/SCENARIO-UNIXTIME.
    #[arg(long)]
    session_dir: Option<PathBuf>,
    /// End the session after this many ticks (0.1 s each), 1 to 10 000 000. Default: when the
    /// person finishes.
    #[arg(long, allow_negative_numbers = true,
          value_parser = checks::count_flag(1..=checks::MAX_STEPS))]
    max_ticks: Option<u32>,
    /// Listen on this port of 127.0.0.1 (default: a free one).
    #[arg(long, default_value_t = 0)]
    port: u16,
    #[command(flatten)]
    link: LinkArgs,
}

#[derive(clap::Args, Debug)]
pub(crate) struct ReplayArgs {
    /// The session's folder (`host-sim teach --session-dir`).
    dir: PathBuf,
    /// Where to write the replay's steps.csv, snapshots.jsonl and summary.json (default:
    /// DIR/replay).
    #[arg(long)]
    out: Option<PathBuf>,
}

fn unix_seconds() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

pub(crate) fn teach(args: &TeachArgs, load: fn(&str) -> Result<Scenario>) -> Result<()> {
    let scenario = load(&args.scenario)?;
    // A file is recorded by its full path, so that the replay finds it from anywhere.
    let given = Path::new(&args.scenario);
    let scenario_arg = if given.is_file() {
        std::fs::canonicalize(given)?.display().to_string()
    } else {
        args.scenario.clone()
    };
    let learner = args
        .learner
        .params(|| host_sim::teach::learners::default_learner(Mode::Online(FeedbackKind::Action)));
    let config = RunConfig {
        steps: args.max_ticks.unwrap_or(MAX_STEPS),
        seed: args.seed,
        learner,
        ..RunConfig::new(Arc::new(scenario))
    };
    config.check()?;
    let started = unix_seconds();
    let dir = args.session_dir.clone().unwrap_or_else(|| {
        PathBuf::from(format!("out/sessions/{}-{started}", config.scenario.name))
    });
    let files = SessionFiles::create(&dir)?;
    let console = Console::bind(args.port)?;
    let link: Box<dyn SessionLink> = match remote_car(&args.link, Some(&dir.join(names::CANDUMP)))?
    {
        Some(remote) => Box::new(remote),
        None => Box::new(InProcessLink::new(config.learner)?),
    };
    let name = config.scenario.name.clone();
    let session = Session::start(config, link)?;
    let about = SessionAbout {
        scenario: scenario_arg,
        link: args.link.link.clone(),
        started_unix_s: started,
        ..SessionAbout::default()
    };
    outln!(
        "host-sim teach: {name}, the {} learner {}; the session is written to {}",
        learner.kind.name(),
        match &args.link.link {
            Some(l) => format!("on the car over {l}"),
            None => "in this process".to_string(),
        },
        dir.display()
    )?;
    outln!("open {}", console.url())?;
    outln!("(only on this machine; the token is new each time; Ctrl-C ends the session)")?;
    let outcome = console.run(session, files, about, args.link.link.clone())?;
    // The session's own errors first: a closed standard output does not hide them.
    let said = outln!(
        "host-sim teach: session ended ({}): {} ticks, {} corrections, written to {}",
        outcome.ended_by,
        outcome.ticks,
        outcome.corrections,
        dir.display()
    )
    .and_then(|()| outln!("replay it: host-sim replay-session {}", dir.display()));
    outcome.written?;
    if outcome.failed {
        bail!("the session ended early: {}", outcome.ended_by);
    }
    Ok(said?)
}

pub(crate) fn replay_session(args: &ReplayArgs, load: fn(&str) -> Result<Scenario>) -> Result<()> {
    let recorded = Recorded::read(&args.dir)?;
    let scenario = load(&recorded.scenario)?;
    let replayed = replay(&recorded, RunConfig::new(Arc::new(scenario)))?;
    let out = args.out.clone().unwrap_or_else(|| args.dir.join("replay"));
    std::fs::create_dir_all(&out)?;
    std::fs::write(out.join(names::STEPS), &replayed.steps_csv)?;
    std::fs::write(out.join(names::SNAPSHOTS), &replayed.snapshots)?;
    let about = SessionAbout {
        scenario: recorded.scenario.clone(),
        finished: true,
        ended_by: Some(format!("a replay of {}", args.dir.display())),
        ..SessionAbout::default()
    };
    let summary = serde_json::to_string_pretty(&replayed.session.summary(&about))? + "\n";
    std::fs::write(out.join(names::SUMMARY), summary)?;
    outln!(
        "replayed {}: {} ticks, {} teachings, against a fresh {} learner in this process; wrote {}",
        args.dir.display(),
        recorded.ticks,
        recorded.entries.len(),
        recorded.learner.kind.name(),
        out.display()
    )?;
    if !replayed.differences.is_empty() {
        for d in &replayed.differences {
            eprintln!("differs: {d}");
        }
        bail!(
            "the replay differs from the session in {} place(s)",
            replayed.differences.len()
        );
    }
    outln!(
        "identical: {} and {} byte for byte, final weights {:?}",
        names::STEPS,
        names::SNAPSHOTS,
        replayed.session.snapshot().state.average
    )?;
    Ok(())
}
