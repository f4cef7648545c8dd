//! What a run leaves behind and what is read back from it: the learner file continues a learner
//! bit-identically, and the animation's free trajectories are the run's own.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Result;
use firmware_core::agent::Decision;
use firmware_core::observation::Observation;
use firmware_core::{Feedback, LearnerKind, LearnerParams, LearnerSnapshot};
use host_sim::report::animation::free_trajectories;
use host_sim::report::run_folder::read_steps;
use host_sim::teach::experiment::{self, CarLink, InProcessLink, Mode, RunConfig};
use host_sim::teach::learner_file;
use host_sim::world::registry;
use host_sim::world::teacher::FeedbackKind;

/// The learner in process, saved to a file at tick `at` and replaced by a fresh agent that
/// loaded that file: the run goes on with the learner that went through the file.
struct SavedAndLoaded {
    inner: InProcessLink,
    at: u32,
    file: PathBuf,
    loaded: Option<LearnerSnapshot>,
}

impl CarLink for SavedAndLoaded {
    fn restore(&mut self, snapshot: &LearnerSnapshot) -> Result<()> {
        self.inner.restore(snapshot)
    }

    fn act(&mut self, tick: u32, obs: &Observation) -> Result<Decision> {
        if tick == self.at {
            learner_file::save(&self.inner.snapshot()?, &self.file)?;
            let loaded = learner_file::load(&self.file)?;
            let mut fresh = InProcessLink::new(loaded.params)?;
            fresh.restore(&loaded)?;
            self.inner = fresh;
            self.loaded = Some(loaded);
        }
        self.inner.act(tick, obs)
    }

    fn feedback(&mut self, tick: u32, feedback: &Feedback) -> Result<()> {
        self.inner.feedback(tick, feedback)
    }

    fn snapshot(&mut self) -> Result<LearnerSnapshot> {
        self.inner.snapshot()
    }
}

#[test]
fn a_saved_learner_loads_and_continues_bit_identically() {
    let tmp = tempfile::tempdir().unwrap();
    let doors = Arc::new(registry::load_scenario("doors").unwrap());
    for (kind, learner) in [
        (FeedbackKind::Action, LearnerKind::AdaGrad),
        (FeedbackKind::Preference, LearnerKind::Coactive),
        (FeedbackKind::Semantic, LearnerKind::AveragedOgd),
        (FeedbackKind::Action, LearnerKind::OgdDecaying),
    ] {
        let config = RunConfig {
            mode: Mode::Online(kind),
            steps: 700,
            seed: 5,
            noise: Some(0.25),
            learner: LearnerParams::new(learner),
            ..RunConfig::new(doors.clone())
        };
        let whole = experiment::run(&config).unwrap();
        let mut link = SavedAndLoaded {
            inner: InProcessLink::new(config.learner).unwrap(),
            at: 350,
            file: tmp.path().join("learner.bin"),
            loaded: None,
        };
        let interrupted = experiment::run_with(&config, &mut link, &mut |_| {}).unwrap();
        let what = format!("{kind:?} / {learner:?}");
        let loaded = link.loaded.expect("the learner went through the file");
        assert!(
            loaded.state.steps > 0,
            "{what}: the saved learner had learned"
        );
        assert!(
            interrupted.csv_bytes() == whole.csv_bytes(),
            "{what}: the records differ"
        );
        assert_eq!(interrupted.final_snapshot, whole.final_snapshot, "{what}");
        let bits = |w: &[f32]| w.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(&interrupted.final_snapshot.state.average),
            bits(&whole.final_snapshot.state.average),
            "{what}"
        );
    }
}

/// The learner behind the link, its collision masks kept.
struct Masks {
    inner: InProcessLink,
    masks: Vec<u64>,
}

impl CarLink for Masks {
    fn restore(&mut self, snapshot: &LearnerSnapshot) -> Result<()> {
        self.inner.restore(snapshot)
    }

    fn act(&mut self, tick: u32, obs: &Observation) -> Result<Decision> {
        let d = self.inner.act(tick, obs)?;
        self.masks.push(d.allowed.bits());
        Ok(d)
    }

    fn feedback(&mut self, tick: u32, feedback: &Feedback) -> Result<()> {
        self.inner.feedback(tick, feedback)
    }

    fn snapshot(&mut self) -> Result<LearnerSnapshot> {
        self.inner.snapshot()
    }
}

/// The animation recomputes which trajectories were free from the poses in steps.csv: exactly
/// the masks the learner had, also where the car met walls and was reset.
#[test]
fn the_animation_s_free_trajectories_are_the_run_s() {
    let tmp = tempfile::tempdir().unwrap();
    for name in ["doors", "stairs-chairs"] {
        let s = Arc::new(registry::load_scenario(name).unwrap());
        let config = RunConfig {
            mode: Mode::Online(FeedbackKind::Semantic),
            steps: 1000,
            learner: LearnerParams::new(LearnerKind::AveragedOgd),
            ..RunConfig::new(s.clone())
        };
        let mut link = Masks {
            inner: InProcessLink::new(config.learner).unwrap(),
            masks: Vec::new(),
        };
        let report = experiment::run_with(&config, &mut link, &mut |_| {}).unwrap();
        let csv = tmp.path().join(format!("{name}.csv"));
        std::fs::write(&csv, report.csv_bytes()).unwrap();
        let rows = read_steps(&csv).unwrap();
        assert_eq!(rows.len(), 1000);
        let free = free_trajectories(&s, &rows).unwrap();
        assert!(
            link.masks.iter().filter(|&&m| m != u64::MAX).count() > 50,
            "{name}: the run this test needs meets obstacles"
        );
        assert_eq!(free, link.masks, "{name}");
    }
}
