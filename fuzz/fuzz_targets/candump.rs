//! Any text handed to the candump parsers gives a frame or a message, never a panic; a parsed
//! frame formats to the notation it parses back from.
#![no_main]

use hil_mock::transport::record::{format_frame, parse_frame, parse_line};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(f) = parse_frame(&text) {
        assert_eq!(parse_frame(&format_frame(&f)), Ok(f));
    }
    if let Ok(l) = parse_line(&text) {
        assert!(l.time.is_finite());
        assert_eq!(parse_frame(&format_frame(&l.frame)), Ok(l.frame));
    }
});
