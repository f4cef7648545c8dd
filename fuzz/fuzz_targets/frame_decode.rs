//! Any bytes handed to the message decoder give a message or an error, never a panic; a decoded
//! message re-encodes into bytes that decode to the same encoding.
#![no_main]

use firmware_core::{Feedback, LearnerSnapshot};
use libfuzzer_sys::fuzz_target;
use protocol::envelope::Envelope;
use protocol::message::{MAX_MESSAGE_SIZE, Message};

fuzz_target!(|data: &[u8]| {
    if let Ok(env) = Envelope::new_checked(data) {
        let _ = (env.version(), env.payload(), env.crc());
    }
    let _ = protocol::open::<Feedback>(data);
    let _ = protocol::open::<LearnerSnapshot>(data);
    if let Ok(msg) = Message::parse(data) {
        // Compare encodings, not values: an observation may hold NaNs (the firmware validates
        // observations when it uses them), and NaN != NaN.
        let mut a = [0u8; MAX_MESSAGE_SIZE];
        let first = msg.emit(&mut a).expect("a decoded message fits the buffer");
        assert!(first.len() <= msg.kind().max_encoded_size());
        let again = Message::parse(first).expect("a re-encoded message decodes");
        let mut b = [0u8; MAX_MESSAGE_SIZE];
        assert_eq!(first, again.emit(&mut b).unwrap());
    }
});
