//! Puts memory.x where cortex-m-rt's link.x finds it; with the `replay` feature, copies the
//! recorded ticks named by `REPLAY_TICKS` into OUT_DIR for `include_bytes!`.
fn main() {
    let out = std::path::PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR"));
    std::fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-env-changed=REPLAY_TICKS");
    if std::env::var_os("CARGO_FEATURE_REPLAY").is_some() {
        let Some(ticks) = std::env::var_os("REPLAY_TICKS") else {
            panic!(
                "the replay feature needs REPLAY_TICKS=FILE (cargo run -p tests --example record_ticks -- FILE)"
            );
        };
        let ticks = std::path::PathBuf::from(ticks);
        std::fs::copy(&ticks, out.join("ticks.bin"))
            .unwrap_or_else(|e| panic!("REPLAY_TICKS={}: {e}", ticks.display()));
        println!("cargo:rerun-if-changed={}", ticks.display());
    }
}
