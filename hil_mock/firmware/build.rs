//! Puts the memory map (memory-car.x; 512 KiB of flash for the replay image's recorded ticks)
//! where cortex-m-rt's link.x finds it as memory.x; writes the car's key, read from the key
//! file named by `CAR_KEY_FILE` (`hil_mock keygen FILE`), into OUT_DIR/key.rs (the image
//! refuses to build without one, unless the feature `insecure` asks for the public all-zero
//! key); with the `replay` feature, copies the recorded ticks named by `REPLAY_TICKS` into
//! OUT_DIR for `include_bytes!`.
fn main() {
    let out = std::path::PathBuf::from(std::env::var_os("OUT_DIR").expect("OUT_DIR"));
    // The car's memory map, memory-car.x, becomes OUT_DIR/memory.x (not named memory.x in the
    // package: the linker would find it there first). The replay image (a measurement tool,
    // never the car's) holds the recorded ticks as data besides the code and may use all
    // 512 KiB of the emulated machine's code memory; every other image keeps the 128 KiB.
    let memory = std::fs::read_to_string("memory-car.x").expect("read memory-car.x");
    let memory = if std::env::var_os("CARGO_FEATURE_REPLAY").is_some() {
        let car_flash = "FLASH : ORIGIN = 0x00000000, LENGTH = 128K";
        assert!(
            memory.contains(car_flash),
            "memory-car.x: no line `{car_flash}`"
        );
        memory.replace(car_flash, "FLASH : ORIGIN = 0x00000000, LENGTH = 512K")
    } else {
        memory
    };
    std::fs::write(out.join("memory.x"), memory).expect("write memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory-car.x");
    println!("cargo:rerun-if-env-changed=REPLAY_TICKS");
    println!("cargo:rerun-if-env-changed=CAR_KEY_FILE");
    let key = match std::env::var_os("CAR_KEY_FILE") {
        Some(path) => {
            let path = std::path::PathBuf::from(path);
            println!("cargo:rerun-if-changed={}", path.display());
            let text = std::fs::read_to_string(&path)
                .unwrap_or_else(|e| panic!("CAR_KEY_FILE={}: {e}", path.display()));
            let digits = text.trim();
            if digits.len() != 32 || !digits.bytes().all(|b| b.is_ascii_hexdigit()) {
                panic!(
                    "CAR_KEY_FILE={}: a key file is 32 hexadecimal digits (hil_mock keygen FILE)",
                    path.display()
                );
            }
            let bytes: Vec<u8> = (0..16)
                .map(|i| u8::from_str_radix(&digits[2 * i..2 * i + 2], 16).expect("hex"))
                .collect();
            if bytes.iter().all(|&b| b == 0) {
                panic!(
                    "CAR_KEY_FILE: the all-zero key is public; build with --features insecure to say you mean it"
                );
            }
            bytes
        }
        None if std::env::var_os("CARGO_FEATURE_INSECURE").is_some() => vec![0; 16],
        None => panic!(
            "no key: build with CAR_KEY_FILE=FILE (hil_mock keygen FILE makes one; the car and its \
             hosts share it), or with --features insecure for the public all-zero key"
        ),
    };
    let key_rs = format!(
        "/// The car's key, from the key file given at build time (`CAR_KEY_FILE`).\n\
         pub const KEY: [u8; 16] = {key:?};\n"
    );
    std::fs::write(out.join("key.rs"), key_rs).expect("write key.rs");
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
