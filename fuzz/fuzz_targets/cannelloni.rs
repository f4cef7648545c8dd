//! Any datagram handed to the cannelloni decoder gives frames or an error, never a panic, and
//! adds no frame on error; decoded frames encode to a packet that decodes to the same frames.
#![no_main]

use hil_mock::transport::udp::{decode_packet, encode_packet};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut frames = Vec::new();
    match decode_packet(data, &mut frames) {
        Ok(seq) => {
            let mut packet = Vec::new();
            encode_packet(seq, &frames, &mut packet);
            let mut again = Vec::new();
            assert_eq!(decode_packet(&packet, &mut again).ok(), Some(seq));
            assert_eq!(again, frames);
        }
        Err(_) => assert!(frames.is_empty()),
    }
});
