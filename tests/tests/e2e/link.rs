//! The learner over a CAN link: `host-sim`'s experiment with the learner in `hil_mock`
//! (a `protocol::car::CarNode`) behind real transports, faults, restarts and the watchdog.
//!
//! Every run is compared with the same run in process: per-step CSV bytes and the final weights'
//! bit patterns must be identical. Every message is authenticated with one test key. Sockets are
//! on 127.0.0.1, ports ephemeral. No assertion is about time: waits are generous upper bounds on
//! things that must happen.

use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, TcpListener};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::time::Duration;

use firmware_core::FeedbackKind;
use firmware_core::observation::Observation;
use hil_mock::flash::{FlashStore, HEADER_SIZE, Open, PAGE_SIZE, PageStatus};
use hil_mock::server::LinkBus;
use hil_mock::transport::fault::{FaultConfig, FaultStats, FaultyLink};
use hil_mock::transport::memory::MemoryLink;
use hil_mock::transport::reconnect::ReconnectingLink;
use hil_mock::transport::record::{RecordingLink, read_log};
use hil_mock::transport::slcan::SlcanLink;
use hil_mock::transport::udp::UdpLink;
use hil_mock::transport::{Link, LinkAddress};
use host_sim::teach::config::Mode;
use host_sim::teach::experiment::{self, CarLink, RunConfig};
use host_sim::teach::kinds::Mix;
use host_sim::teach::record::RunReport;
use host_sim::teach::remote::{RemoteCar, RemoteConfig, RemoteStats};
use protocol::car::{CarConfig, CarStats, Persisted};
use protocol::isotp::FrameMode;
use protocol::link::{Inbox, Received, transmit};
use protocol::message::{ActionCommand, ConfigureMessage, Message, ObservationMessage, StopReason};
use protocol::secure::HostSecurity;
use protocol::stream::Direction;

use crate::common::*;

#[test]
fn same_seed_same_bits_in_process_over_memory_udp_and_slcan() {
    let config = config(600);
    let local = experiment::run(&config).unwrap();
    assert!(local.corrections() > 10, "the run learns");

    let (host, car_end) = MemoryLink::pair();
    let server = ServerThread::spawn(move || car_end, car(FrameMode::Fd));
    let (memory, _) = remote_run(&config, host, FrameMode::Fd);
    let stats = server.stop();
    assert_same(&local, &memory, "memory link");
    assert_eq!(stats.feedback_applied, local.corrections());

    // UDP, with the host's side recorded in the candump format.
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("host.log");
    let (host, car_end) = udp_pair();
    let server = ServerThread::spawn(move || car_end, car(FrameMode::Fd));
    let host = RecordingLink::new(host, &log, "can0").unwrap();
    let (udp, _) = remote_run(&config, host, FrameMode::Fd);
    let stats = server.stop();
    assert_same(&local, &udp, "cannelloni over UDP");
    assert_eq!(stats.feedback_applied, local.corrections());
    let frames = read_log(&log).unwrap();
    let on = |id: u16| {
        frames
            .iter()
            .filter(|l| l.frame.id().raw() == id as u32)
            .count()
    };
    // Every observation (2 FD frames each, 3 with many objects) and its action.
    assert!(on(0x104) >= 2 * 600, "{}", on(0x104));
    // At least one action frame per tick and one ack per feedback (more when a slow answer
    // made the host ask again).
    assert!(on(0x101) >= 600, "{}", on(0x101));
    assert!(on(0x107) >= local.corrections() as usize);

    // slcan over TCP, classic CAN frames (up to 23 per observation) both ways.
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let SocketAddr::V4(addr) = listener.local_addr().unwrap() else {
        unreachable!("bound on 127.0.0.1")
    };
    let server = ServerThread::spawn(
        move || SlcanLink::accept_from(&listener, Duration::from_secs(30)).unwrap(),
        car(FrameMode::Classic),
    );
    let host = SlcanLink::connect_tcp(addr, Duration::from_secs(30)).unwrap();
    let (slcan, _) = remote_run(&config, host, FrameMode::Classic);
    let stats = server.stop();
    assert_same(&local, &slcan, "slcan over TCP");
    assert_eq!(stats.feedback_applied, local.corrections());
}

fn hostile(seed: u64) -> FaultConfig {
    FaultConfig {
        drop: 0.10,
        corrupt: 0.01,
        duplicate: 0.01,
        reorder: 0.01,
        delay: 0.01,
        max_delay: Duration::from_millis(4),
        seed,
    }
}

/// Frames held back often, behind later ones: 30 % delayed up to 8 ms, 20 % reordered.
fn held_back(seed: u64) -> FaultConfig {
    FaultConfig {
        drop: 0.05,
        corrupt: 0.0,
        duplicate: 0.02,
        reorder: 0.2,
        delay: 0.3,
        max_delay: Duration::from_millis(8),
        seed,
    }
}

/// What a run through injected faults gives: its report, the faults on the host's side, the
/// host's and the car's counters.
struct FaultyRun {
    report: RunReport,
    faults: FaultStats,
    remote: RemoteStats,
    car: CarStats,
}

/// Runs `config` on a car node served on `car_end` from a host on `host`, `faults` injected
/// both ways (seeded `car_seed` on the car's side, `host_seed` on the host's), FD frames, one
/// try a millisecond.
fn run_through_faults<L: Link + Send + 'static>(
    config: &RunConfig,
    (host, car_end): (L, L),
    faults: fn(u64) -> FaultConfig,
    (car_seed, host_seed): (u64, u64),
) -> FaultyRun {
    let server = ServerThread::spawn(
        move || FaultyLink::new(car_end, faults(car_seed)),
        car(FrameMode::Fd),
    );
    let mut remote = RemoteCar::new(
        FaultyLink::new(host, faults(host_seed)),
        RemoteConfig {
            try_timeout: Duration::from_millis(1),
            ..remote_config(FrameMode::Fd)
        },
    );
    let report = experiment::run_with(config, &mut remote, &mut |_| {}).unwrap();
    let faults = remote.link().stats();
    let remote_stats = remote.stats();
    drop(remote);
    FaultyRun {
        report,
        faults,
        remote: remote_stats,
        car: server.stop(),
    }
}

#[test]
fn faults_both_ways_lose_no_feedback_and_apply_none_twice() {
    let config = config(800);
    let local = experiment::run(&config).unwrap();
    for transport in ["memory", "udp"] {
        let (host, car_end): (Box<dyn Link>, Box<dyn Link>) = match transport {
            "memory" => {
                let (h, c) = MemoryLink::pair();
                (Box::new(h), Box::new(c))
            }
            _ => {
                let (h, c) = udp_pair();
                (Box::new(h), Box::new(c))
            }
        };
        let started = std::time::Instant::now();
        let FaultyRun {
            report,
            faults,
            remote: remote_stats,
            car: stats,
        } = run_through_faults(&config, (host, car_end), hostile, (1, 2));
        eprintln!(
            "{transport}: {:.1} s, {remote_stats:?}, {stats:?}, {faults:?}",
            started.elapsed().as_secs_f64()
        );
        assert_same(&local, &report, transport);
        // Every feedback sent was applied, exactly once.
        assert_eq!(stats.feedback_applied, local.corrections(), "{transport}");
        assert_eq!(remote_stats.feedback_acked, local.corrections() as u64);
        assert_eq!(stats.feedback_refused, 0, "{transport}");
        // The faults happened: frames were dropped, corrupted, duplicated, reordered, and
        // copies of feedback reached the car.
        assert!(faults.dropped > 100, "{transport}: {faults:?}");
        assert!(faults.corrupted > 0 && faults.duplicated > 0 && faults.reordered > 0);
        assert!(remote_stats.retransmissions > 100, "{remote_stats:?}");
        assert!(
            stats.errors > 0,
            "the car reported lost messages: {stats:?}"
        );
    }
}

/// Frames held back behind later ones, often, both ways: messages arrive after what their
/// sender sent after them. The host must read the car's state only from the newest car message
/// (`HostSecurity::opened_newest`): taking a late welcome's status as current stopped runs as
/// "the car lost what it was taught". The car must not act on an observation that a later host
/// message overtook (`CarStats::stale_observations`): a late copy of a tick's observation,
/// acted on after the tick's feedback, replaced the tick's record with another learner's
/// decision, and a span feedback about it then taught the car something else than the run in
/// process (with action feedback, 12 runs of 12 failed without the host's two rules; with span
/// feedback, 5 of 5 without the car's, the per-step CSV differing; with all three, 8 of 8 passed
/// in both modes). Every kind in turn (`mix:all`) runs too.
#[test]
fn frames_held_back_behind_later_ones_stop_no_run_and_change_nothing_learned() {
    // Action feedback; span feedback, which reads a tick's record again later; every kind in turn.
    // The three runs side by side, each on links and a car of its own: most of a run's time is
    // spent waiting for frames held back (one after the other they took 6.6 s of wall time and
    // 0.8 s of CPU time, the end-to-end binary's longest test).
    std::thread::scope(|scope| {
        for mode in [
            Mode::Online(FeedbackKind::Action),
            Mode::Online(FeedbackKind::Span),
            Mode::Mix(Mix::ALL),
        ] {
            scope.spawn(move || held_back_run(mode));
        }
    });
}

/// One run of [`frames_held_back_behind_later_ones_stop_no_run_and_change_nothing_learned`].
fn held_back_run(mode: Mode) {
    let config = RunConfig {
        mode,
        ..config(800)
    };
    let local = experiment::run(&config).unwrap();
    let FaultyRun {
        report,
        faults,
        remote: remote_stats,
        car: stats,
    } = run_through_faults(&config, MemoryLink::pair(), held_back, (3, 4));
    let what = mode.name();
    eprintln!("{what}: {remote_stats:?}, {stats:?}, {faults:?}");
    assert_same(
        &local,
        &report,
        &format!("memory, frames held back, {what}"),
    );
    assert_eq!(stats.feedback_applied, local.corrections(), "{what}");
    assert_eq!(remote_stats.feedback_acked, local.corrections() as u64);
    assert!(faults.reordered > 50 && faults.delayed > 50, "{faults:?}");
    assert!(remote_stats.hellos > 1, "{remote_stats:?}");
    // Late welcomes and late observations were met, and neither was taken.
    assert!(remote_stats.refused.stale > 0, "{remote_stats:?}");
    assert!(stats.stale_observations > 0, "{stats:?}");
}

#[test]
fn sigkill_and_restart_at_several_points_lose_nothing() {
    sigkill_and_restart("udp-listen");
}

#[test]
fn sigkill_and_restart_over_slcan_tcp_lose_nothing() {
    // The TCP connection dies with the car's process; the host's link opens it again.
    sigkill_and_restart("slcan+tcp-listen");
}

/// Runs with `hil_mock` serving on `scheme`, killed with SIGKILL and restarted at several points.
fn sigkill_and_restart(scheme: &'static str) {
    // Killed while the run goes on (after these steps: wherever the next step is when the
    // signal lands), and between an action and the feedback about it (before these feedbacks:
    // the restarted car has forgotten the tick and the host shows it again).
    const STEP_KILLS: [u32; 4] = [40, 150, 260, 480];
    const FEEDBACK_KILLS: [u32; 2] = [5, 17];
    const KILLS: usize = STEP_KILLS.len() + FEEDBACK_KILLS.len();
    let config = config(600);
    let local = experiment::run(&config).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let flash = dir.path().join("car.flash");
    let server = spawn_server_on(&flash, scheme, 0);
    let port = server.port;
    let host: Box<dyn Link> = if scheme == "udp-listen" {
        Box::new(UdpLink::connect(SocketAddrV4::new(Ipv4Addr::LOCALHOST, port)).unwrap())
    } else {
        let address: LinkAddress = format!("slcan+tcp://127.0.0.1:{port}").parse().unwrap();
        Box::new(ReconnectingLink::open(address, Duration::from_secs(30)).unwrap())
    };

    // A supervisor kills the server whenever a kill is requested and starts it again on the
    // same port and flash. The run goes on meanwhile, so each kill lands wherever the run is:
    // between an observation and its action, before or after a feedback was persisted, ...
    let requested = Arc::new(AtomicU32::new(0));
    let done = Arc::new(AtomicU32::new(0));
    let finished = Arc::new(AtomicBool::new(false));
    let (r, d, f) = (requested.clone(), done.clone(), finished.clone());
    let flash_path = flash.clone();
    let supervisor = std::thread::spawn(move || {
        let mut server = server;
        let mut log = String::new();
        while !f.load(Ordering::Relaxed) {
            if d.load(Ordering::Relaxed) == r.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(1));
                continue;
            }
            server.kill9();
            log.push_str(&server.stderr.lock().unwrap());
            server = spawn_server_on(&flash_path, scheme, port);
            d.fetch_add(1, Ordering::Relaxed);
        }
        server.kill9();
        log.push_str(&server.stderr.lock().unwrap());
        log
    });
    let kill = |wait: bool| {
        // One kill at a time: wait for the previous restart, then ask for the next.
        wait_for(|| done.load(Ordering::Relaxed) == requested.load(Ordering::Relaxed));
        let n = requested.fetch_add(1, Ordering::Relaxed) + 1;
        if wait {
            wait_for(|| done.load(Ordering::Relaxed) == n);
        }
    };
    let mut car = KillBeforeFeedback {
        inner: RemoteCar::new(host, remote_config(FrameMode::Fd)),
        feedbacks: 0,
        at: &FEEDBACK_KILLS,
        kill: &kill,
    };
    let report = experiment::run_with(&config, &mut car, &mut |rec| {
        if STEP_KILLS.contains(&rec.step) {
            kill(false);
        }
    })
    .unwrap();
    let remote = car.inner;
    wait_for(|| done.load(Ordering::Relaxed) == requested.load(Ordering::Relaxed));
    finished.store(true, Ordering::Relaxed);
    let log = supervisor.join().unwrap();
    eprintln!("{:?}\n{log}", remote.stats());
    assert_eq!(done.load(Ordering::Relaxed), KILLS as u32);
    assert!(remote.stats().reobserved >= FEEDBACK_KILLS.len() as u64);
    assert_same(&local, &report, "killed and restarted");
    if scheme != "udp-listen" {
        // Each kill closed the connection and the host opened it again.
        let link = remote.link().describe();
        assert!(link.contains(&format!("reopened {KILLS} times")), "{link}");
    }
    // Every restart found what the previous process wrote (the configuration at least).
    assert_eq!(log.matches("restored write").count(), KILLS, "{log}");
    // No restart lost state: the car was never configured again.
    assert_eq!(remote.stats().restores, 0, "{:?}", remote.stats());
    assert!(
        remote.stats().car_restarts >= KILLS as u64,
        "{:?}",
        remote.stats()
    );
    // The flash holds the final learner.
    let (_, r) = FlashStore::open(&flash, Open::Existing).unwrap();
    assert_eq!(r.unwrap().state.snapshot, report.final_snapshot);
}

#[test]
fn a_corrupted_page_on_disk_falls_back_to_the_other_page() {
    let dir = tempfile::tempdir().unwrap();
    let flash = dir.path().join("car.flash");
    let learner = hil_mock::server::fresh_learner();
    let mut older = learner;
    firmware_core::OnlineLearner::step(&mut older, &[0.5, -0.25, 0.0, 0.0, 1.0, 0.0]).unwrap();
    let mut newer = older;
    firmware_core::OnlineLearner::step(&mut newer, &[0.5, -0.25, 0.0, 0.0, 1.0, 0.0]).unwrap();
    let state = |l: &firmware_core::Learner, generation| Persisted {
        session: Some(3),
        generation,
        snapshot: l.snapshot(),
        receiver: Default::default(),
    };
    let (mut store, _) = FlashStore::open(&flash, Open::Existing).unwrap();
    store.save(&state(&older, 1)).unwrap(); // page 0, write 1
    store.save(&state(&newer, 2)).unwrap(); // page 1, write 2
    drop(store);
    let mut bytes = std::fs::read(&flash).unwrap();
    bytes[HEADER_SIZE + PAGE_SIZE + 60] ^= 0x04; // one bit of the newer page's payload
    std::fs::write(&flash, &bytes).unwrap();

    let server = spawn_server(&flash, 0);
    let host = UdpLink::connect(SocketAddrV4::new(Ipv4Addr::LOCALHOST, server.port)).unwrap();
    let mut remote = RemoteCar::new(host, remote_config(FrameMode::Fd));
    assert_eq!(remote.snapshot().unwrap(), older.snapshot());
    let log = server.stderr_when(|l| l.contains("restored"));
    assert!(
        log.contains("restored write 1 from page 0")
            && log.contains("fell back from corrupt page 1"),
        "{log}"
    );
    // The welcome told the host what the car holds.
    assert_eq!(
        remote.car_status(),
        Some(protocol::message::CarStatus {
            session: Some(3),
            generation: 1
        })
    );
}

/// The host's side of a raw exchange with a car that just started in epoch 7 (as
/// [`ServerThread`] starts it).
struct RawHost {
    link: MemoryLink,
    inbox: Inbox,
    sec: HostSecurity,
}

impl RawHost {
    fn new(link: MemoryLink) -> Self {
        Self {
            link,
            inbox: Inbox::new(Direction::CarToHost),
            sec: HostSecurity::assume_fresh_car(&KEY, 7),
        }
    }

    fn send(&mut self, msg: &Message) {
        transmit(
            &mut LinkBus(&mut self.link),
            msg,
            Direction::HostToCar,
            FrameMode::Fd,
            &mut self.sec,
        )
        .unwrap();
    }

    /// The next message from the car.
    fn next(&mut self) -> Message {
        loop {
            let f = self
                .link
                .recv(Duration::from_secs(30))
                .unwrap()
                .expect("the car answers");
            if let Received::Message(m) = self.inbox.feed(&f, 0, &mut self.sec) {
                return m;
            }
        }
    }

    fn next_action(&mut self) -> ActionCommand {
        loop {
            if let Message::Action(a) = self.next() {
                return a;
            }
        }
    }

    fn configure(&mut self) {
        self.send(&Message::Configure(ConfigureMessage {
            session: 1,
            snapshot: hil_mock::server::fresh_learner().snapshot(),
        }));
        assert_eq!(
            self.next_action(),
            ActionCommand::stop(0, StopReason::Reconfigured)
        );
        assert!(matches!(self.next(), Message::Weights(_)));
    }

    /// Sends one observation and returns the next action command.
    fn observe(&mut self, tick: u32) -> ActionCommand {
        self.send(&Message::Observation(ObservationMessage {
            tick,
            observation: Observation::open_space(),
        }));
        self.next_action()
    }
}

#[test]
fn the_watchdog_stops_the_car_and_the_next_observation_resumes() {
    let (host, car_end) = MemoryLink::pair();
    let server = ServerThread::spawn(
        move || car_end,
        CarConfig {
            watchdog_ms: 30,
            mode: FrameMode::Fd,
        },
    );
    let mut host = RawHost::new(host);
    host.configure();
    let first = host.observe(1);
    assert!(first.track().is_some());
    // Silence: the car commands one stop for its last tick (waited for, not timed).
    let stop = host.next_action();
    assert_eq!(stop, ActionCommand::stop(1, StopReason::Watchdog));
    // Observations return: it drives again, and stops again when they stop.
    let resumed = host.observe(2);
    assert_eq!(resumed.tick, 2);
    assert!(resumed.track().is_some());
    assert_eq!(
        host.next_action(),
        ActionCommand::stop(2, StopReason::Watchdog)
    );
    // Issue 14: a reset stops the car at once and does not disarm the watchdog: when the car
    // drives again and observations cease, the stop comes.
    assert!(host.observe(3).track().is_some());
    host.send(&Message::Reset);
    assert_eq!(
        host.next_action(),
        ActionCommand::stop(3, StopReason::Reset)
    );
    assert!(host.observe(4).track().is_some());
    assert_eq!(
        host.next_action(),
        ActionCommand::stop(4, StopReason::Watchdog)
    );
    drop(host);
    let stats = server.stop();
    assert_eq!((stats.watchdog_stops, stats.actions), (3, 4));
    assert_eq!(
        stats.commanded_stops, 2,
        "the configuration's and the reset's"
    );
}

#[test]
fn watchdog_stops_between_ticks_do_not_change_a_run() {
    // A watchdog of 1 ms fires between almost every two ticks; the host tells its stops from
    // the car's answers and the run is the same as in process.
    let config = config(300);
    let local = experiment::run(&config).unwrap();
    let (host, car_end) = MemoryLink::pair();
    let server = ServerThread::spawn(
        move || car_end,
        CarConfig {
            watchdog_ms: 1,
            mode: FrameMode::Fd,
        },
    );
    let mut remote = RemoteCar::new(host, remote_config(FrameMode::Fd));
    let report = experiment::run_with(&config, &mut remote, &mut |_| {
        std::thread::sleep(Duration::from_millis(2));
    })
    .unwrap();
    drop(remote);
    let stats = server.stop();
    assert_same(&local, &report, "with watchdog stops");
    assert!(stats.watchdog_stops > 0, "{stats:?}");
}

#[test]
fn run_link_addresses_are_checked() {
    for bad in [
        "udp://192.168.1.1:4000",
        "tcp://127.0.0.1:1",
        "udp://127.0.0.1",
    ] {
        assert!(bad.parse::<LinkAddress>().is_err(), "{bad}");
    }
}

/// Which flash pages a restart finds corrupted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Corrupt {
    /// Both: the car comes back without a configured learner.
    Both,
    /// The newest good one: the car comes back with the state before its last write.
    Newest,
}

/// Flips a byte in the payload of the pages `which` names.
fn corrupt(flash: &Path, which: Corrupt) {
    let mut bytes = std::fs::read(flash).unwrap();
    let (pages, _) = hil_mock::flash::decode_pages(&bytes);
    let newest = pages
        .iter()
        .enumerate()
        .filter_map(|(i, p)| match p {
            PageStatus::Good(g) => Some((*g, i)),
            _ => None,
        })
        .max()
        .map(|(_, i)| i);
    for i in 0..2 {
        if which == Corrupt::Both || Some(i) == newest {
            bytes[HEADER_SIZE + i * PAGE_SIZE + 40] ^= 0x01;
        }
    }
    std::fs::write(flash, bytes).unwrap();
}

/// A run with `hil_mock` (a child process) killed with SIGKILL before feedback number
/// `before_feedback`, its flash corrupted as `which` says, and restarted on the same port and
/// flash file.
fn run_with_a_lossy_restart(
    config: &RunConfig,
    before_feedback: u32,
    which: Corrupt,
) -> (
    anyhow::Result<host_sim::teach::record::RunReport>,
    host_sim::teach::remote::RemoteStats,
    String,
) {
    let dir = tempfile::tempdir().unwrap();
    let flash = dir.path().join("car.flash");
    let server = std::sync::Mutex::new(spawn_server(&flash, 0));
    let port = server.lock().unwrap().port;
    let host = UdpLink::connect(SocketAddrV4::new(Ipv4Addr::LOCALHOST, port)).unwrap();
    let log = std::sync::Mutex::new(String::new());
    let kill = |_: bool| {
        let mut s = server.lock().unwrap();
        s.kill9();
        log.lock().unwrap().push_str(&s.stderr.lock().unwrap());
        corrupt(&flash, which);
        *s = spawn_server(&flash, port);
    };
    let mut car = KillBeforeFeedback {
        inner: RemoteCar::new(host, remote_config(FrameMode::Fd)),
        feedbacks: 0,
        at: &[before_feedback],
        kill: &kill,
    };
    let result = experiment::run_with(config, &mut car, &mut |_| {});
    let stats = car.inner.stats();
    let mut s = server.lock().unwrap();
    s.kill9();
    log.lock().unwrap().push_str(&s.stderr.lock().unwrap());
    let log = log.lock().unwrap().clone();
    (result, stats, log)
}

/// Issue 14, item 4: a car that comes back without its state before it was taught anything is
/// configured again with the host's snapshot, and the run ends bit-identical.
#[test]
fn a_flash_lost_before_any_correction_is_restored_and_the_run_stays_bit_identical() {
    let config = config(300);
    let local = experiment::run(&config).unwrap();
    let (report, stats, log) = run_with_a_lossy_restart(&config, 1, Corrupt::Both);
    let report = report.unwrap_or_else(|e| panic!("{e:#}\n{log}"));
    assert!(log.contains("no configured learner"), "{log}");
    assert_eq!((stats.car_restarts, stats.restores), (1, 1), "{stats:?}");
    assert_same(&local, &report, "restored after a lost flash");
}

/// Issue 14, item 4: a car that comes back having lost acknowledged corrections (both pages
/// unreadable, or the newest) is not driven on silently: the run fails, naming the loss.
#[test]
fn a_flash_lost_after_corrections_stops_the_run_naming_the_loss() {
    let config = config(300);
    for (which, gone, cause) in [
        (
            Corrupt::Both,
            "3 acknowledged corrections are gone",
            "unreadable or erased",
        ),
        (
            Corrupt::Newest,
            "1 acknowledged corrections are gone",
            "an older state",
        ),
    ] {
        let (report, stats, log) = run_with_a_lossy_restart(&config, 4, which);
        let e = format!("{:#}", report.expect_err("the run must not go on"));
        eprintln!("{which:?}: {e}\n{stats:?}");
        assert!(e.contains("the car lost what it was taught"), "{e}");
        assert!(
            e.contains(gone) && e.contains(cause),
            "{which:?}: {e}\n{log}"
        );
        assert!(e.contains("undo 3 of them"), "{e}");
        assert_eq!(stats.restores, 0);
    }
}
