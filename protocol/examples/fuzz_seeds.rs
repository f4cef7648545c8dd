//! Writes the seed corpus of the protocol's fuzz targets from real encoded messages:
//! `fuzz/corpus/frame_decode/*.bin` (plain envelopes, secured PDUs and bare payloads),
//! `fuzz/corpus/reassembler_feed/*.bin` (the secured messages' CAN frames, in the record format
//! `fuzz/fuzz_targets/reassembler_feed.rs` reads), `fuzz/corpus/car_node/*.bin` (sessions of
//! the car node: configure, observe, feedback, polls, a restart) and
//! `fuzz/corpus/slcan_line/*.bin` (slcan lines). The fuzz targets know the key `0x42…` and the
//! car's epoch 3, so these seeds pass authentication there. `hil_mock`'s targets get theirs from
//! `cargo run -p hil_mock --example transport_fuzz_seeds`.
//!
//! ```text
//! cargo run -p protocol --example fuzz_seeds [-- OUT_DIR]     # default: fuzz/corpus
//! ```

use std::path::PathBuf;

use firmware_core::feature::Feature;
use firmware_core::observation::{Observation, SemanticClass, SemanticObject};
use firmware_core::{
    ActionFeedback, ActionIndex, ActionMask, CorrectnessFeedback, EStopFeedback, Feedback, Learner,
    LearnerParams, PerturbationFeedback, PreferenceFeedback, RankingFeedback, RewardFeedback,
    SemanticFeedback, SpanFeedback,
};
use protocol::can::{CanFrame, FD_LENGTHS};
use protocol::isotp::{FrameMode, Segmenter};
use protocol::message::{
    ActionCommand, CarStatus, ConfigureMessage, DeliveryId, ErrorCode, ErrorReport,
    FeedbackMessage, Hello, MAX_MESSAGE_SIZE, Message, ObservationMessage, StopReason,
    WeightsReport, Welcome,
};
use protocol::secure::{CarSecurity, Endpoint, HostSecurity, Key};
use protocol::stream::{Direction, Stream};

fn a(i: usize) -> ActionIndex {
    ActionIndex::new(i).expect("below 64")
}

fn messages() -> Vec<(&'static str, Message)> {
    let mut full = Observation::open_space();
    for i in 0..8 {
        let o = SemanticObject {
            class: SemanticClass::ALL[i % 3],
            x: 1.0 + i as f32,
            y: -1.0,
            radius: 0.4,
        };
        full.objects.push(o).expect("8 objects fit");
    }
    full.scan.ranges[10] = 0.75;
    let id = DeliveryId {
        session: 3,
        seq: 250,
    };
    let feedback = |tick, feedback| Message::Feedback(FeedbackMessage { id, tick, feedback });
    // The kinds of issue 15, each under a sequence number of its own (a session seed applies
    // them all).
    let numbered = |seq, tick, feedback| {
        Message::Feedback(FeedbackMessage {
            id: DeliveryId { session: 3, seq },
            tick,
            feedback,
        })
    };
    let learner = Learner::new(LearnerParams::default().check().expect("default is valid"));
    vec![
        (
            "observation_open",
            Message::Observation(ObservationMessage {
                tick: 1,
                observation: Observation::open_space(),
            }),
        ),
        (
            "observation_full",
            Message::Observation(ObservationMessage {
                tick: u32::MAX,
                observation: full,
            }),
        ),
        (
            "action",
            Message::Action(
                ActionCommand::new(41, Some(a(12))).with_allowed(ActionMask::from_bits(0xF0F0)),
            ),
        ),
        (
            "stop",
            Message::Action(ActionCommand::stop(42, StopReason::Watchdog)),
        ),
        (
            "feedback_action",
            feedback(41, Feedback::Action(ActionFeedback { action: a(5) })),
        ),
        (
            "feedback_preference",
            feedback(
                40,
                Feedback::Preference(PreferenceFeedback {
                    preferred: a(2),
                    other: a(60),
                }),
            ),
        ),
        (
            "feedback_semantic",
            feedback(
                39,
                Feedback::Semantic(
                    SemanticFeedback::new()
                        .avoid(Feature::Stairs)
                        .prefer(Feature::Right),
                ),
            ),
        ),
        (
            "feedback_perturbation",
            numbered(
                251,
                38,
                Feedback::Perturbation(
                    PerturbationFeedback::new(&[9.5, 10.0, 3.25, 10.0, 0.75, -2.5])
                        .expect("in range"),
                ),
            ),
        ),
        (
            "feedback_reward",
            numbered(
                252,
                37,
                Feedback::Reward(RewardFeedback::new(-0.4).expect("in range")),
            ),
        ),
        (
            "feedback_correctness",
            numbered(
                253,
                36,
                Feedback::Correctness(CorrectnessFeedback { correct: false }),
            ),
        ),
        (
            "feedback_span",
            numbered(
                254,
                35,
                Feedback::Span(SpanFeedback {
                    ticks: 4,
                    good: false,
                }),
            ),
        ),
        (
            "feedback_ranking",
            numbered(
                255,
                34,
                Feedback::Ranking(
                    RankingFeedback::new(&[a(3), a(17), a(0), a(63)], true).expect("four"),
                ),
            ),
        ),
        (
            "feedback_estop",
            numbered(0, 33, Feedback::EStop(EStopFeedback)),
        ),
        ("ack", Message::Ack(protocol::message::Ack { id })),
        (
            "nack",
            Message::Nack(protocol::message::Nack {
                id,
                code: protocol::message::NackCode::UnknownTick,
            }),
        ),
        ("heartbeat", Message::Heartbeat),
        (
            "weights",
            Message::Weights(WeightsReport {
                status: CarStatus {
                    session: Some(3),
                    generation: 17,
                },
                snapshot: learner.snapshot(),
            }),
        ),
        (
            "configure",
            Message::Configure(ConfigureMessage {
                session: 3,
                snapshot: Learner::new(LearnerParams::paper().check().expect("paper is valid"))
                    .snapshot(),
            }),
        ),
        ("weights_request", Message::WeightsRequest),
        (
            "hello",
            Message::Hello(Hello {
                nonce: [1, 2, 3, 4, 5, 6, 7, 8],
                epoch: 0,
                counter: 0,
            }),
        ),
        (
            "welcome",
            Message::Welcome(Welcome {
                nonce: [1, 2, 3, 4, 5, 6, 7, 8],
                epoch: 9,
                counter: 4,
                host_next: 0,
                status: CarStatus::default(),
                refused: 0,
            }),
        ),
        ("reset", Message::Reset),
        (
            "error",
            Message::Error(ErrorReport {
                code: ErrorCode::Observation,
                tick: Some(41),
            }),
        ),
    ]
}

/// One frame as a `reassembler_feed` record, `dt` milliseconds (a multiple of 4) after the
/// previous one.
fn record(out: &mut Vec<u8>, frame: &CanFrame, dt: u32) {
    let stream = Stream::from_id(frame.id()).expect("frames of the plan");
    let selector = match stream.direction {
        Direction::HostToCar => stream.index() as u8,
        Direction::CarToHost => 6,
    };
    let ctrl = selector | if frame.is_fd() { 0x08 } else { 0 } | ((dt / 4) as u8) << 4;
    let n = frame.data().len();
    let code = if frame.is_fd() {
        FD_LENGTHS.iter().position(|&l| l == n).expect("FD length") as u8
    } else {
        n as u8
    };
    out.extend_from_slice(&[ctrl, code]);
    out.extend_from_slice(frame.data());
}

/// The key and epoch the fuzz targets use.
const KEY: Key = Key::new([0x42; 16]);
const EPOCH: u32 = 3;

/// The stream `msg` travels on, and its direction.
fn stream_of(msg: &Message) -> Stream {
    let dir = if Stream::for_kind(msg.kind(), Direction::HostToCar).is_some() {
        Direction::HostToCar
    } else {
        Direction::CarToHost
    };
    Stream::for_kind(msg.kind(), dir).expect("every kind travels some way")
}

/// `msg` as a secured PDU, sealed by the host or the car (key 0x42…, epoch 3, counter 0).
fn secured(msg: &Message) -> Vec<u8> {
    let stream = stream_of(msg);
    let mut buf = [0u8; MAX_MESSAGE_SIZE];
    let bytes = match stream.direction {
        Direction::HostToCar => {
            HostSecurity::assume_fresh_car(&KEY, EPOCH).seal(msg, stream, &mut buf)
        }
        Direction::CarToHost => CarSecurity::new(&KEY, EPOCH).seal(msg, stream, &mut buf),
    };
    bytes.expect("fits").to_vec()
}

/// The postcard payload of `msg` (variant number and fields).
fn payload(msg: &Message) -> Vec<u8> {
    let mut buf = [0u8; MAX_MESSAGE_SIZE];
    let bytes = msg.emit(&mut buf).expect("fits");
    bytes[1..bytes.len() - 2].to_vec()
}

fn frames(msg: &Message, mode: FrameMode) -> Vec<CanFrame> {
    let stream = stream_of(msg);
    let bytes = secured(msg);
    Segmenter::new(stream.id(), &bytes, mode)
        .expect("non-empty, short")
        .collect()
}

fn main() -> std::io::Result<()> {
    let out = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("fuzz/corpus"), PathBuf::from);
    let dir = |name: &str| -> std::io::Result<PathBuf> {
        let d = out.join(name);
        std::fs::create_dir_all(&d)?;
        Ok(d)
    };
    let (decode_dir, feed_dir) = (dir("frame_decode")?, dir("reassembler_feed")?);
    let (node_dir, slcan_dir) = (dir("car_node")?, dir("slcan_line")?);
    let msgs = messages();
    let mut count = 0;
    for (name, msg) in &msgs {
        let mut buf = [0u8; MAX_MESSAGE_SIZE];
        std::fs::write(
            decode_dir.join(format!("{name}.bin")),
            msg.emit(&mut buf).expect("fits"),
        )?;
        std::fs::write(decode_dir.join(format!("{name}_secured.bin")), secured(msg))?;
        std::fs::write(decode_dir.join(format!("{name}_payload.bin")), payload(msg))?;
        count += 3;
    }
    // Frames of the host's messages (what the car's inbox reassembles), classic and FD.
    for (name, msg) in msgs
        .iter()
        .filter(|(_, m)| Stream::for_kind(m.kind(), Direction::HostToCar).is_some())
    {
        for (mode, suffix) in [(FrameMode::Classic, "classic"), (FrameMode::Fd, "fd")] {
            let mut rec = Vec::new();
            for f in frames(msg, mode) {
                record(&mut rec, &f, 0);
            }
            std::fs::write(feed_dir.join(format!("{name}_{suffix}.bin")), rec)?;
            count += 1;
        }
    }
    // An observation interleaved with a heartbeat and a feedback, one frame lost, a late frame.
    let named = |n: &str| {
        &msgs
            .iter()
            .find(|(k, _)| *k == n)
            .expect("a seed message")
            .1
    };
    let obs = frames(named("observation_open"), FrameMode::Classic);
    let hb = frames(named("heartbeat"), FrameMode::Classic);
    let fb = frames(named("feedback_action"), FrameMode::Classic);
    let mut rec = Vec::new();
    for (i, f) in obs.iter().enumerate() {
        if i == 7 {
            continue; // lost: a gap
        }
        record(&mut rec, f, if i == 20 { 60 } else { 0 }); // late: a timeout
        if i == 3 {
            record(&mut rec, &hb[0], 4);
            for g in &fb {
                record(&mut rec, g, 0);
            }
        }
    }
    std::fs::write(feed_dir.join("interleaved_faults.bin"), rec)?;
    count += 1;
    // Sessions of the car node: records `[op][...]` (fuzz/fuzz_targets/car_node.rs).
    let session = |mode_bit: u8, names: &[&str]| {
        let mut rec = Vec::new();
        for n in names {
            match *n {
                "poll" => rec.push(2 | (30 << 2)),
                "restart" => rec.push(3),
                "garbage" => {
                    rec.push(0);
                    rec.extend_from_slice(&[0x02, 3, 1, 2, 3]);
                }
                _ => {
                    let p = payload(named(n));
                    rec.push(1 | mode_bit);
                    rec.push(p.len() as u8);
                    rec.extend_from_slice(&p);
                }
            }
        }
        rec
    };
    let taught = [
        "hello",
        "configure",
        "observation_full",
        "feedback_action",
        "feedback_action",
        "heartbeat",
        "poll",
        "weights_request",
        "restart",
        "feedback_action",
        "observation_open",
        "feedback_preference",
        "garbage",
        "reset",
        "poll",
        "poll",
    ];
    std::fs::write(node_dir.join("session_classic.bin"), session(0, &taught))?;
    std::fs::write(node_dir.join("session_fd.bin"), session(4, &taught))?;
    // A mixed stream: every kind of feedback about recent ticks, an E-stop, a refused one.
    let mixed = [
        "hello",
        "configure",
        "observation_open",
        "observation_full",
        "feedback_perturbation",
        "feedback_reward",
        "observation_open",
        "feedback_correctness",
        "feedback_span",
        "feedback_ranking",
        "feedback_estop",
        "observation_full",
        "feedback_semantic",
        "poll",
    ];
    std::fs::write(node_dir.join("mixed_classic.bin"), session(0, &mixed))?;
    std::fs::write(node_dir.join("mixed_fd.bin"), session(4, &mixed))?;
    count += 4;
    // slcan lines: the frames of a few messages, adapter commands, acknowledgements, garbage.
    let mut lines = Vec::new();
    for n in ["configure", "feedback_semantic", "heartbeat"] {
        for mode in [FrameMode::Classic, FrameMode::Fd] {
            for f in frames(named(n), mode) {
                let mut line = [0u8; protocol::slcan::MAX_LINE];
                lines.push(protocol::slcan::encode(&f, &mut line).to_vec());
            }
        }
    }
    lines.extend([
        b"C\rS8\rO\rV\r".to_vec(),
        b"z\r\r\x07".to_vec(),
        b"t12\rT1ABCDEF0\r".to_vec(),
    ]);
    for (i, l) in lines.iter().enumerate() {
        std::fs::write(slcan_dir.join(format!("line_{i:02}.bin")), l)?;
        count += 1;
    }
    println!("wrote {count} seeds under {}", out.display());
    Ok(())
}
