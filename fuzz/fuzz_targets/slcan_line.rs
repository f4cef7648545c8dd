//! Any bytes fed to the slcan line reader, and any line handed to the slcan parser, give a frame,
//! a command, an acknowledgement or an error, never a panic; a parsed frame encodes to a line
//! that parses back to the same frame.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::slcan::{Feed, Line, LineReader, MAX_LINE, encode, parse_line};

fn check(line: &[u8]) {
    if let Ok(Line::Frame(f)) = parse_line(line) {
        let mut out = [0u8; MAX_LINE];
        let encoded = encode(&f, &mut out);
        let back = encoded.strip_suffix(b"\r").unwrap_or(encoded);
        assert_eq!(parse_line(back), Ok(Line::Frame(f)));
    }
}

fuzz_target!(|data: &[u8]| {
    check(data);
    let mut reader = LineReader::new();
    for &b in data {
        match reader.push(b) {
            Feed::Line(l) => {
                let l = l.to_vec();
                check(&l);
            }
            Feed::Overflow | Feed::Bell | Feed::Pending => {}
        }
    }
});
