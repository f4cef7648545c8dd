//! A learner that learned, persisted through the flash store and restored, continues
//! bit-identically: protocol envelope + hil_mock flash + firmware-core snapshot together.

use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, FeatureTable, Learner, LearnerParams, OnlineLearner,
    Round,
};
use hil_mock::flash::{FlashStore, Open};
use protocol::car::Persisted;
use protocol::delivery::FeedbackReceiver;

fn table(k: usize) -> FeatureTable {
    let mut t = FeatureTable::ZERO;
    for (a, row) in t.rows_mut().iter_mut().enumerate() {
        for (f, x) in row.iter_mut().enumerate() {
            *x = (((a * 7 + f * 13 + k * 31) % 17) as f32 - 8.0) / 4.0;
        }
    }
    t
}

fn teach(learner: &mut Learner, k: usize) {
    let t = table(k);
    let chosen = learner.select(&t, ActionMask::ALL).unwrap();
    let round = Round::new(&t, ActionMask::ALL, chosen).unwrap();
    let want = ActionIndex::new((k * 11) % 64).unwrap();
    learner
        .learn(&round, &ActionFeedback { action: want })
        .unwrap();
}

#[test]
fn restart_from_flash_continues_bit_identically() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("weights.flash");
    let mut straight = Learner::new(LearnerParams::default().check().unwrap());
    let mut restarted = straight;
    for k in 0..40 {
        teach(&mut straight, k);
        teach(&mut restarted, k);
        let (mut store, _) = FlashStore::open(&path, Open::Existing).unwrap();
        store
            .save(&Persisted {
                session: Some(1),
                generation: k as u32 + 1,
                snapshot: restarted.snapshot(),
                receiver: FeedbackReceiver::new(),
            })
            .unwrap();
        drop(store); // "power off"
        let (_, restored) = FlashStore::open(&path, Open::Existing).unwrap();
        restarted = restored.unwrap().learner;
    }
    assert_eq!(
        tests::weight_bits(straight.weights()),
        tests::weight_bits(restarted.weights())
    );
    assert_eq!(straight, restarted);
}
