//! Any bytes handed to the message decoders give a message or an error, never a panic: the plain
//! envelope (storage) and the secured PDU (the wire, checked by the car's endpoint with a known
//! key); a decoded message re-encodes into bytes that decode to the same encoding.
#![no_main]

use firmware_core::{Feedback, LearnerSnapshot};
use libfuzzer_sys::fuzz_target;
use protocol::envelope::Envelope;
use protocol::message::{MAX_MESSAGE_SIZE, Message, MessageKind};
use protocol::secure::{CarSecurity, Endpoint, HostSecurity, Key, SecuredPdu};
use protocol::stream::{Direction, Stream};

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
        assert!(first.len() <= msg.kind().max_stored_size());
        let again = Message::parse(first).expect("a re-encoded message decodes");
        let mut b = [0u8; MAX_MESSAGE_SIZE];
        assert_eq!(first, again.emit(&mut b).unwrap());
    }
    // The wire: a secured PDU on every stream the car receives.
    let key = Key::new([0x42; 16]);
    let mut car = CarSecurity::new(&key, 3);
    if let Ok(pdu) = SecuredPdu::new_checked(data) {
        let _ = (pdu.body(), pdu.freshness_byte(), pdu.tag(), pdu.message());
    }
    for kind in MessageKind::ALL {
        if let Some(stream) = Stream::for_kind(kind, Direction::HostToCar) {
            let _ = car.open(stream, data);
        }
    }
    // Whatever decodes as a payload and travels host → car, sealed by the host, opens at the
    // car as the same message (once).
    if let Ok(msg) = Message::decode_payload(data)
        && let Some(stream) = Stream::for_kind(msg.kind(), Direction::HostToCar)
    {
        let mut host = HostSecurity::assume_fresh_car(&key, 3);
        let mut car = CarSecurity::new(&key, 3);
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        let pdu = host.seal(&msg, stream, &mut buf).expect("a decoded message seals");
        let opened = car.open(stream, pdu).expect("a sealed message opens");
        let (mut x, mut y) = ([0u8; MAX_MESSAGE_SIZE], [0u8; MAX_MESSAGE_SIZE]);
        assert_eq!(msg.emit(&mut x).unwrap(), opened.emit(&mut y).unwrap());
        if msg.kind() != MessageKind::Hello {
            assert!(car.open(stream, pdu).is_err(), "a copy is refused");
        }
    }
});
