//! Golden values pin the seeded synthetic run: a change to the learner's arithmetic, the
//! teacher, or the random stream shows up here first.

use host_sim::teach::synthetic::{SyntheticConfig, run};

#[test]
fn synthetic_run_is_pinned() {
    let config = SyntheticConfig {
        steps: 3_000,
        seed: 42,
        noise: 0.2,
        ..SyntheticConfig::default()
    };
    let a = run(&config).unwrap();
    let b = run(&config).unwrap();
    assert_eq!(a, b, "same seed, same run");
    let hash = tests::hash_f32s(a.latent_loss.iter().chain(a.weights.iter()));
    const GOLDEN: u64 = 0xdcc1_ef64_5c4c_2659;
    assert_eq!(
        hash, GOLDEN,
        "golden changed: got {hash:#018x}, pinned {GOLDEN:#018x}"
    );
}
