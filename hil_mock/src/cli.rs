//! The `hil_mock` command line: `keygen`, `serve`, `replay`, `bench-latency`.
//!
//! ```text
//! hil_mock keygen car.key
//! hil_mock serve --link udp-listen://127.0.0.1:47000 --key car.key --flash car.flash
//!                [--init-flash] [--watchdog-ms 200] [--record bus.log]
//!                [--faults drop=0.1,corrupt=0.01,seed=7] [--frame-mode fd] [--idle-timeout-ms N]
//! hil_mock serve --link ... --insecure      # the public all-zero key, announced at every start
//! hil_mock replay bus.log --link udp://127.0.0.1:47000 [--realtime]
//! hil_mock bench-latency [--link udp] [--count 10000] [--no-pin]
//! ```
//!
//! `serve` refuses to start without `--key FILE` or `--insecure`. It prints one line
//! `listening on ADDRESS` on stdout once its link is open (with the real port when the address
//! asked for port 0), then serves until killed (a listening slcan link serves one connection
//! after another; a connecting link ends when its peer closes). Each start takes a new random
//! epoch, so nothing recorded before it is accepted after it.
//! [`main`] is the whole program, so another package can build the same binary (the end-to-end
//! tests do, to kill it with SIGKILL).

use std::ffi::OsString;
use std::io::Write;
use std::net::{SocketAddr, SocketAddrV4, TcpListener};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand, ValueEnum};
use firmware_core::observation::Observation;
use protocol::car::CarConfig;
use protocol::isotp::FrameMode;
use protocol::link::{Inbox, Received, transmit};
use protocol::message::{Message, ObservationMessage};
use protocol::stream::Direction;

use protocol::message::ConfigureMessage;
use protocol::secure::HostSecurity;

use crate::flash::Open;
use crate::key;
use crate::server::{BatchBus, LinkBus, Server, StartState, fresh_learner};
use crate::transport::fault::{FaultConfig, FaultyLink};
use crate::transport::record::{RecordingLink, read_log, replay};
use crate::transport::slcan::{DEFAULT_IDLE_TIMEOUT, SlcanListener};
use crate::transport::udp::UdpLink;
use crate::transport::{Link, LinkAddress};

/// The car's controller, stood in for.
#[derive(Debug, Parser)]
#[command(name = "hil_mock", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// CAN frame format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Mode {
    /// Classic CAN (8-byte frames).
    Classic,
    /// CAN FD (64-byte frames).
    Fd,
}

impl From<Mode> for FrameMode {
    fn from(m: Mode) -> Self {
        match m {
            Mode::Classic => FrameMode::Classic,
            Mode::Fd => FrameMode::Fd,
        }
    }
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Write a new random 128-bit key to FILE (mode 0600; never overwrites).
    Keygen {
        /// The key file to create.
        file: PathBuf,
    },
    /// Run the car's controller on a link.
    Serve {
        /// Where to listen or connect: udp-listen://127.0.0.1:PORT, udp://…,
        /// slcan+tcp-listen://127.0.0.1:PORT, slcan+tcp://…, slcan+serial:///dev/…, socketcan://IFACE.
        #[arg(long)]
        link: String,
        /// The car's key file (`hil_mock keygen FILE`).
        #[arg(long, conflicts_with = "insecure")]
        key: Option<PathBuf>,
        /// Run with the public all-zero key: anyone on the bus can drive and teach the car.
        #[arg(long)]
        insecure: bool,
        /// The flash image (a header and two pages); restored on start, created if missing.
        /// Without it nothing persists. A file that is not an image is refused.
        #[arg(long)]
        flash: Option<PathBuf>,
        /// Erase the --flash file into an empty image first, whatever it holds.
        #[arg(long, requires = "flash")]
        init_flash: bool,
        /// Command a stop after this long without an observation (ms).
        #[arg(long, default_value_t = 200)]
        watchdog_ms: u32,
        /// Write every frame to this candump log.
        #[arg(long)]
        record: Option<PathBuf>,
        /// Disturb the frames the car sends: drop=P,corrupt=P,duplicate=P,reorder=P,delay=P,
        /// max-delay-ms=N,seed=N.
        #[arg(long)]
        faults: Option<String>,
        /// The frames the car transmits.
        #[arg(long, value_enum, default_value_t = Mode::Fd)]
        frame_mode: Mode,
        /// A listening slcan link closes a connection that brought no authenticated message
        /// for this long and serves the next (ms).
        #[arg(long, default_value_t = DEFAULT_IDLE_TIMEOUT.as_millis() as u64)]
        idle_timeout_ms: u64,
        /// How long a connecting link waits for its peer (s).
        #[arg(long, default_value_t = 60)]
        connect_timeout_s: u64,
    },
    /// Send the frames of a candump log through a link.
    Replay {
        /// The candump log.
        log: PathBuf,
        /// Where to send them.
        #[arg(long)]
        link: String,
        /// Space the frames as they were logged.
        #[arg(long)]
        realtime: bool,
    },
    /// Observation → action round trips over UDP loopback to a server thread, and a plain UDP
    /// ping-pong on the same loopback interleaved with them (the floor).
    BenchLatency {
        /// The transport (only udp).
        #[arg(long, default_value = "udp")]
        link: String,
        /// Round trips measured.
        #[arg(long, default_value_t = 10_000)]
        count: u32,
        /// Leave the threads where the scheduler puts them, rather than the host's side on one
        /// CPU and the car's on another (see `bench_latency`).
        #[arg(long)]
        no_pin: bool,
    },
}

/// The program: parses `std::env::args`, runs, prints errors, returns the exit code.
pub fn main() -> ExitCode {
    run_from(std::env::args_os())
}

/// [`main`] with explicit arguments (the first is the program name).
pub fn run_from(args: impl IntoIterator<Item = OsString>) -> ExitCode {
    let cli = match Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::from(2)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        // Whoever read standard output has gone (`hil_mock bench-latency | head -1`).
        Err(e) if closed_stdout(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hil_mock: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(command: Command) -> Result<()> {
    match command {
        Command::Keygen { file } => {
            key::keygen(&file)?;
            say(format_args!(
                "wrote a new key to {}; give it to the car (hil_mock serve --key, or the \
                 firmware's CAR_KEY_FILE) and to its hosts (host-sim run --key)",
                file.display()
            ))
        }
        Command::Serve {
            link,
            key,
            insecure,
            flash,
            init_flash,
            watchdog_ms,
            record,
            faults,
            frame_mode,
            idle_timeout_ms,
            connect_timeout_s,
        } => {
            let key = key::choose(key.as_deref(), insecure, "hil_mock")?;
            let address: LinkAddress = link.parse()?;
            let faults = faults
                .map(|f| f.parse::<FaultConfig>().map_err(anyhow::Error::msg))
                .transpose()
                .context("--faults")?;
            let config = CarConfig {
                watchdog_ms,
                mode: frame_mode.into(),
            };
            let epoch = key::random_epoch()?;
            let mut server = match &flash {
                Some(path) => {
                    let open = if init_flash {
                        Open::Initialise
                    } else {
                        Open::Existing
                    };
                    let (server, state) = Server::with_flash(config, path, open, &key, epoch)?;
                    eprintln!("hil_mock: flash {}: {state}", path.display());
                    server
                }
                None => {
                    eprintln!("hil_mock: {}", StartState::NoFlash);
                    Server::in_memory(config, &key, epoch)
                }
            };
            eprintln!("hil_mock: epoch {epoch}, {}", server.node().status());
            let link = open_serving(
                &address,
                Duration::from_millis(idle_timeout_ms),
                Duration::from_secs(connect_timeout_s),
            )?;
            let link = wrap(link, record.as_deref(), faults)?;
            serve(&mut server, link)
        }
        Command::Replay {
            log,
            link,
            realtime,
        } => {
            let address: LinkAddress = link.parse()?;
            let frames = read_log(&log)?;
            let mut link = address.open(Duration::from_secs(10))?;
            let n = replay(&frames, &mut *link, realtime)?;
            let frames = if n == 1 { "frame" } else { "frames" };
            say(format_args!(
                "replayed {n} {frames} from {} to {address}",
                log.display()
            ))
        }
        Command::BenchLatency {
            link,
            count,
            no_pin,
        } => {
            if link != "udp" {
                bail!("bench-latency measures udp only, got --link {link}");
            }
            if count < 2 {
                bail!("--count must be at least 2 (the first round trip follows the ping-pongs)");
            }
            let r = bench_latency(count, !no_pin)?;
            let idle = count.div_ceil(BENCH_BLOCK);
            say(format_args!("{}", r.placement))?;
            say(format_args!(
                "{} observation → action round trips over UDP loopback (CAN FD frames, {} per observation), \
                 back to back: p50 {:.0} µs, p99 {:.0} µs, max {:.0} µs",
                count - idle,
                r.frames_per_observation,
                r.link.p50_us,
                r.link.p99_us,
                r.link.max_us
            ))?;
            say(format_args!(
                "{idle} after a block of ping-pongs (the car's server asleep, woken by the \
                 observation): p50 {:.0} µs, p99 {:.0} µs, max {:.0} µs; all {count} together: \
                 p50 {:.0} µs, p99 {:.0} µs",
                r.after_idle.p50_us,
                r.after_idle.p99_us,
                r.after_idle.max_us,
                r.all.p50_us,
                r.all.p99_us
            ))?;
            say(format_args!(
                "{} plain UDP ping-pongs of {PING_BYTES} bytes on the same loopback, interleaved: \
                 p50 {:.0} µs, p99 {:.0} µs, max {:.0} µs",
                r.count, r.ping.p50_us, r.ping.p99_us, r.ping.max_us
            ))?;
            say(format_args!(
                "the link over the ping-pong: p50 {:.1}×, p99 {:.1}×",
                r.link.p50_us / r.ping.p50_us,
                r.link.p99_us / r.ping.p99_us
            ))
        }
    }
}

/// Writes one line to standard output, returning the error of a closed pipe instead of
/// panicking as `println!` does.
fn say(line: std::fmt::Arguments<'_>) -> Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "{line}")?;
    out.flush()?;
    Ok(())
}

/// Whether `e` is standard output's reader gone (a broken pipe): the command then ends quietly
/// with success.
fn closed_stdout(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Opens a link for serving; a listening address on port 0 gets an ephemeral port. Prints
/// `listening on ADDRESS` (or `connected to ADDRESS`) on stdout.
fn open_serving(
    address: &LinkAddress,
    idle_timeout: Duration,
    connect_timeout: Duration,
) -> Result<Box<dyn Link>> {
    let say = |what: &str, a: &str| say(format_args!("{what} {a}"));
    Ok(match address {
        LinkAddress::UdpListen(a) => {
            let link = UdpLink::listen(*a)?;
            let SocketAddr::V4(local) = link.local_addr()? else {
                bail!("udp bound to a non-IPv4 address");
            };
            say("listening on", &LinkAddress::UdpListen(local).to_string())?;
            Box::new(link)
        }
        LinkAddress::SlcanTcpListen(a) => {
            let listener =
                TcpListener::bind(a).with_context(|| format!("bind {a} for slcan over TCP"))?;
            let local = match listener.local_addr() {
                Ok(SocketAddr::V4(l)) => l,
                _ => SocketAddrV4::new(*a.ip(), a.port()),
            };
            say(
                "listening on",
                &LinkAddress::SlcanTcpListen(local).to_string(),
            )?;
            Box::new(SlcanListener::from_listener(listener, idle_timeout)?)
        }
        other => {
            let link = other.open(connect_timeout)?;
            say("connected to", &other.to_string())?;
            link
        }
    })
}

fn wrap(
    link: Box<dyn Link>,
    record: Option<&std::path::Path>,
    faults: Option<FaultConfig>,
) -> Result<Box<dyn Link>> {
    // Faults outermost: the log shows the frames as they went onto (and came off) the wire.
    let link: Box<dyn Link> = match record {
        Some(path) => Box::new(RecordingLink::new(link, path, "can0")?),
        None => link,
    };
    Ok(match faults {
        Some(f) => Box::new(FaultyLink::new(link, f)),
        None => link,
    })
}

fn serve(server: &mut Server, mut link: Box<dyn Link>) -> Result<()> {
    let stop = AtomicBool::new(false);
    match server.run(&mut *link, &stop) {
        Ok(()) => Ok(()),
        // The peer hung up (a connecting link's TCP peer closed): the end of a session.
        Err(crate::transport::LinkError::Closed(why)) => {
            eprintln!("hil_mock: link closed ({why}); {}", server.summary());
            Ok(())
        }
        Err(e) => {
            eprintln!("hil_mock: {}", server.summary());
            Err(anyhow::Error::new(e).context(format!("serving on {}", link.describe())))
        }
    }
}

/// Percentiles of one set of round trips (µs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoundTrips {
    /// Median.
    pub p50_us: f64,
    /// 99th percentile.
    pub p99_us: f64,
    /// Largest.
    pub max_us: f64,
}

impl RoundTrips {
    /// The percentiles of `samples` (µs; sorted here). `samples` must not be empty.
    fn of(samples: &mut [f64]) -> Self {
        samples.sort_by(f64::total_cmp);
        let at = |q: f64| samples[((samples.len() as f64 * q) as usize).min(samples.len() - 1)];
        Self {
            p50_us: at(0.50),
            p99_us: at(0.99),
            max_us: samples[samples.len() - 1],
        }
    }
}

/// Where [`bench_latency`] ran its two sides.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Placement {
    /// Each side on a CPU of its own: the host's thread on `host`; the car's server, and the
    /// ping-pong's echo, on `car`.
    Pinned {
        /// The host's CPU.
        host: usize,
        /// The car's CPU.
        car: usize,
    },
    /// Wherever the scheduler put them: asked for (`--no-pin`), or fewer than two CPUs to run
    /// on, or not Linux.
    Free,
}

impl std::fmt::Display for Placement {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Placement::Pinned { host, car } => write!(
                f,
                "the host's thread pinned to CPU {host}, the car's server and the echo to CPU {car} \
                 (--no-pin: where the scheduler puts them)"
            ),
            Placement::Free => {
                f.write_str("the threads where the scheduler puts them (not pinned)")
            }
        }
    }
}

impl Placement {
    /// Two CPUs this thread may run on, the first two of its affinity mask, or [`Placement::Free`]
    /// when `pin` is false or there are not two.
    fn choose(pin: bool) -> Self {
        #[cfg(target_os = "linux")]
        if pin && let Ok(set) = rustix::thread::sched_getaffinity(None) {
            let mut cpus = (0..rustix::thread::CpuSet::MAX_CPU).filter(|&c| set.is_set(c));
            if let (Some(host), Some(car)) = (cpus.next(), cpus.next()) {
                return Placement::Pinned { host, car };
            }
        }
        let _ = pin;
        Placement::Free
    }

    /// Pins the calling thread to the host's CPU (`car`: the car's).
    fn enter(self, car: bool) -> Result<()> {
        #[cfg(target_os = "linux")]
        if let Placement::Pinned { host, car: c } = self {
            let cpu = if car { c } else { host };
            let mut set = rustix::thread::CpuSet::new();
            set.set(cpu);
            rustix::thread::sched_setaffinity(None, &set)
                .map_err(std::io::Error::from)
                .with_context(|| format!("pin a thread to CPU {cpu}"))?;
        }
        let _ = car;
        Ok(())
    }
}

/// Round-trip figures of [`bench_latency`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Latency {
    /// Round trips measured (of each kind).
    pub count: u32,
    /// Where the two sides ran.
    pub placement: Placement,
    /// CAN FD frames per observation.
    pub frames_per_observation: usize,
    /// Observation → action through the car's server, back to back: the round trips that
    /// followed another (the link within its busy poll, [`crate::transport::udp`]).
    pub link: RoundTrips,
    /// The other round trips: the first after each block of ping-pongs (one in
    /// [`BENCH_BLOCK`]), the link idle longer than its busy poll, so that the car's server was
    /// asleep and the observation had to wake it, as in a car driven at a real tick rate.
    pub after_idle: RoundTrips,
    /// Every round trip measured (`link` and `after_idle` together).
    pub all: RoundTrips,
    /// The floor: a plain UDP ping-pong of one datagram of [`PING_BYTES`] each way between two
    /// blocking sockets on the same loopback, measured interleaved with `link`.
    pub ping: RoundTrips,
}

/// Size of the ping-pong's datagram: a cannelloni packet of one 64-byte CAN FD frame.
pub const PING_BYTES: usize = crate::transport::udp::HEADER_LEN + 6 + 64;

/// Round trips of each kind measured in turn, so that both see the same load.
pub const BENCH_BLOCK: u32 = 100;

/// Starts a server thread on UDP 127.0.0.1 (ephemeral port) and measures `count` observation →
/// action round trips (after 100 unmeasured ones), CAN FD frames both ways; and, interleaved
/// with them in blocks of 100, `count` round trips of a plain UDP ping-pong on the same loopback
/// (an echo thread), the floor any UDP transport stands on.
///
/// With `pin` (and two CPUs to run on, on Linux) the host's side runs on one CPU and the car's
/// server and the echo on another, as a car is a computer of its own. Left to the scheduler, the
/// two sides often end up on one CPU (a wake-up over loopback pulls the woken thread to the
/// waker's CPU), where each side's busy poll ([`crate::transport::udp`]) holds the CPU its peer
/// waits for until the poll's window runs out (docs/performance.md, "The link"). The measuring
/// runs in threads of its own: the caller's thread keeps its affinity.
pub fn bench_latency(count: u32, pin: bool) -> Result<Latency> {
    if count < 2 {
        bail!("bench_latency: at least 2 round trips (the first follows the ping-pongs)");
    }
    let placement = Placement::choose(pin);
    std::thread::scope(|s| {
        s.spawn(|| {
            placement.enter(false)?;
            measure_latency(count, placement)
        })
        .join()
        .map_err(|_| anyhow::anyhow!("the bench's host thread panicked"))?
    })
}

/// [`bench_latency`]'s work, on the host's thread.
fn measure_latency(count: u32, placement: Placement) -> Result<Latency> {
    let mut car_link = UdpLink::listen(SocketAddrV4::new(std::net::Ipv4Addr::LOCALHOST, 0))?;
    let SocketAddr::V4(car_addr) = car_link.local_addr()? else {
        bail!("udp bound to a non-IPv4 address");
    };
    let key = key::random_key()?;
    let epoch = key::random_epoch()?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let car_key = key.clone();
    let server = std::thread::spawn(move || {
        placement.enter(true)?;
        let mut server = Server::in_memory(
            CarConfig {
                mode: FrameMode::Fd,
                ..CarConfig::default()
            },
            &car_key,
            epoch,
        )
        .without_event_lines();
        server
            .run(&mut car_link, &flag)
            .map_err(anyhow::Error::from)
    });
    let (mut ping, echo) = ping_pong(placement)?;
    let mut host = UdpLink::connect(car_addr)?;
    let mut sec = HostSecurity::assume_fresh_car(&key, epoch);
    let mut inbox = Inbox::new(Direction::CarToHost);
    // Configure first: a car without a configured learner does not act.
    let configure = Message::Configure(ConfigureMessage {
        session: 1,
        snapshot: fresh_learner().snapshot(),
    });
    transmit(
        &mut LinkBus(&mut host),
        &configure,
        Direction::HostToCar,
        FrameMode::Fd,
        &mut sec,
    )
    .map_err(|e| anyhow::anyhow!("send: {e}"))?;
    loop {
        let Some(f) = host.recv(Duration::from_secs(5))? else {
            bail!("no answer to the configuration within 5 s");
        };
        if let Received::Message(Message::Weights(_)) = inbox.feed(&f, 0, &mut sec) {
            break;
        }
    }
    let mut samples = Vec::with_capacity(count as usize);
    let mut after_idle = Vec::new();
    let mut all = Vec::with_capacity(count as usize);
    let mut floor = Vec::with_capacity(count as usize);
    let mut frames_per_observation = 0;
    let warmup = 100;
    for tick in 0..count + warmup {
        if tick % BENCH_BLOCK == 0 {
            let n = BENCH_BLOCK.min(count + warmup - tick);
            for _ in 0..n {
                let us = ping(tick)?;
                if tick >= warmup {
                    floor.push(us);
                }
            }
        }
        let mut obs = Observation::open_space();
        obs.scan.ranges[(tick % 64) as usize] = 2.0 + (tick % 7) as f32 * 0.5;
        let msg = Message::Observation(ObservationMessage {
            tick,
            observation: obs,
        });
        let t0 = Instant::now();
        let mut bus = BatchBus::new(&mut host);
        frames_per_observation = transmit(
            &mut bus,
            &msg,
            Direction::HostToCar,
            FrameMode::Fd,
            &mut sec,
        )
        .map_err(|e| anyhow::anyhow!("send: {e}"))?;
        bus.flush()?;
        let deadline = t0 + Duration::from_secs(5);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                bail!("no action for tick {tick} within 5 s");
            }
            let Some(f) = host.recv(left)? else { continue };
            if let Received::Message(Message::Action(a)) = inbox.feed(&f, 0, &mut sec)
                && a.tick == tick
                && a.answers_observation()
            {
                break;
            }
        }
        if tick >= warmup {
            let us = t0.elapsed().as_secs_f64() * 1e6;
            all.push(us);
            if tick % BENCH_BLOCK == 0 {
                after_idle.push(us);
            } else {
                samples.push(us);
            }
        }
    }
    stop.store(true, Ordering::Relaxed);
    drop(ping);
    echo.join()
        .map_err(|_| anyhow::anyhow!("the echo thread panicked"))??;
    server
        .join()
        .map_err(|_| anyhow::anyhow!("the server thread panicked"))??;
    Ok(Latency {
        count,
        placement,
        frames_per_observation,
        link: RoundTrips::of(&mut samples),
        after_idle: RoundTrips::of(&mut after_idle),
        all: RoundTrips::of(&mut all),
        ping: RoundTrips::of(&mut floor),
    })
}

/// A plain UDP ping-pong on 127.0.0.1: an echo thread on a blocking socket (on the car's CPU
/// when pinned), and a function that sends one [`PING_BYTES`] datagram to it and waits
/// (blocking) for it to come back, returning the round trip in µs. Dropping the function sends
/// the echo thread an empty datagram, which ends it.
#[allow(clippy::type_complexity)]
fn ping_pong(
    placement: Placement,
) -> Result<(
    impl FnMut(u32) -> Result<f64>,
    std::thread::JoinHandle<Result<()>>,
)> {
    use std::net::UdpSocket;
    let echo = UdpSocket::bind("127.0.0.1:0").context("bind the echo socket")?;
    let at = echo.local_addr()?;
    let handle = std::thread::spawn(move || -> Result<()> {
        placement.enter(true)?;
        let mut buf = [0u8; 2 * PING_BYTES];
        loop {
            let (n, from) = echo.recv_from(&mut buf).context("echo receive")?;
            if n == 0 {
                return Ok(());
            }
            echo.send_to(&buf[..n], from).context("echo send")?;
        }
    });
    let socket = UdpSocket::bind("127.0.0.1:0").context("bind the ping socket")?;
    socket.connect(at).context("connect the ping socket")?;
    socket.set_read_timeout(Some(Duration::from_secs(5)))?;
    struct Pinger(std::net::UdpSocket);
    impl Drop for Pinger {
        fn drop(&mut self) {
            let _ = self.0.send(&[]);
        }
    }
    let pinger = Pinger(socket);
    let ping = move |n: u32| -> Result<f64> {
        let mut packet = [0u8; PING_BYTES];
        packet[..4].copy_from_slice(&n.to_le_bytes());
        let mut back = [0u8; 2 * PING_BYTES];
        let t0 = Instant::now();
        pinger.0.send(&packet).context("ping send")?;
        let got = pinger.0.recv(&mut back).context("no echo within 5 s")?;
        let us = t0.elapsed().as_secs_f64() * 1e6;
        if back[..got] != packet {
            bail!("the echo came back changed");
        }
        Ok(us)
    };
    Ok((ping, handle))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn code(args: &[&str]) -> ExitCode {
        run_from(args.iter().map(OsString::from))
    }

    #[test]
    fn bad_arguments_exit_non_zero_with_a_message() {
        assert_eq!(code(&["hil_mock", "serve"]), ExitCode::from(2));
        assert_eq!(code(&["hil_mock", "fly"]), ExitCode::from(2));
        for args in [
            ["hil_mock", "serve", "--link", "udp-listen://10.0.0.1:4000"],
            ["hil_mock", "serve", "--link", "carrier-pigeon://x"],
            ["hil_mock", "bench-latency", "--link", "slcan"],
            ["hil_mock", "replay", "/nonexistent/bus.log", "--link"],
        ] {
            assert_ne!(code(&args), ExitCode::SUCCESS, "{args:?}");
        }
        assert_eq!(
            code(&[
                "hil_mock",
                "serve",
                "--insecure",
                "--link",
                "udp-listen://127.0.0.1:0",
                "--faults",
                "drop=7"
            ]),
            ExitCode::FAILURE
        );
        // Without a key, or with both a key and --insecure, the car does not start.
        assert_eq!(
            code(&["hil_mock", "serve", "--link", "udp-listen://127.0.0.1:0"]),
            ExitCode::FAILURE
        );
        assert_ne!(
            code(&[
                "hil_mock",
                "serve",
                "--key",
                "k",
                "--insecure",
                "--link",
                "udp-listen://127.0.0.1:0"
            ]),
            ExitCode::SUCCESS
        );
    }

    #[test]
    fn keygen_writes_a_key_and_serve_refuses_a_file_that_is_not_a_flash_image() {
        let dir = tempfile::tempdir().unwrap();
        let key = dir.path().join("car.key");
        let k = key.display().to_string();
        assert_eq!(code(&["hil_mock", "keygen", &k]), ExitCode::SUCCESS);
        assert!(crate::key::read_key_file(&key).is_ok());
        assert_eq!(
            code(&["hil_mock", "keygen", &k]),
            ExitCode::FAILURE,
            "no overwrite"
        );
        let notes = dir.path().join("notes.txt");
        std::fs::write(&notes, vec![b'x'; 100_000]).unwrap();
        let n = notes.display().to_string();
        assert_eq!(
            code(&[
                "hil_mock",
                "serve",
                "--key",
                &k,
                "--flash",
                &n,
                "--link",
                "udp-listen://127.0.0.1:0"
            ]),
            ExitCode::FAILURE
        );
        assert_eq!(
            std::fs::read(&notes).unwrap(),
            vec![b'x'; 100_000],
            "untouched"
        );
    }

    #[test]
    fn replay_sends_a_log_s_frames() {
        use protocol::can::{CanFrame, CanId};
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("bus.log");
        std::fs::write(
            &log,
            "(1700000000.000000) can0 104#0102\n(1700000000.001000) can0 10A##1AABB\n",
        )
        .unwrap();
        let mut car = UdpLink::listen(SocketAddrV4::new(std::net::Ipv4Addr::LOCALHOST, 0)).unwrap();
        let SocketAddr::V4(addr) = car.local_addr().unwrap() else {
            unreachable!()
        };
        let args = [
            "hil_mock".to_string(),
            "replay".into(),
            log.display().to_string(),
            "--link".into(),
            format!("udp://{addr}"),
        ];
        assert_eq!(run_from(args.iter().map(OsString::from)), ExitCode::SUCCESS);
        let id = |i| CanId::standard(i).unwrap();
        let got: Vec<_> = (0..2)
            .map(|_| car.recv(Duration::from_secs(10)).unwrap().unwrap())
            .collect();
        assert_eq!(
            got,
            [
                CanFrame::new(id(0x104), &[1, 2]).unwrap(),
                CanFrame::new_fd(id(0x10A), &[0xAA, 0xBB]).unwrap()
            ]
        );
    }

    #[test]
    fn the_latency_bench_runs() {
        #[cfg(target_os = "linux")]
        let (ours, cpus) = {
            let set = rustix::thread::sched_getaffinity(None).unwrap();
            (set, set.count())
        };
        for pin in [true, false] {
            let r = bench_latency(50, pin).unwrap();
            assert_eq!(r.count, 50);
            assert!(r.frames_per_observation >= 2, "{r:?}");
            for t in [r.link, r.after_idle, r.all, r.ping] {
                assert!(t.p50_us <= t.p99_us && t.p99_us <= t.max_us, "{r:?}");
            }
            // The first measured round trip follows the first block of ping-pongs.
            assert!(r.after_idle.max_us <= r.all.max_us && r.link.max_us <= r.all.max_us);
            #[cfg(target_os = "linux")]
            {
                match r.placement {
                    Placement::Pinned { host, car } => {
                        assert!(pin && host != car, "{r:?}");
                        assert!(ours.is_set(host) && ours.is_set(car), "{r:?}");
                    }
                    Placement::Free => assert!(!pin || cpus < 2, "{r:?}"),
                }
                // The bench pinned threads of its own, not the caller's.
                assert_eq!(rustix::thread::sched_getaffinity(None).unwrap(), ours);
            }
        }
        assert!(bench_latency(1, true).is_err());
    }
}
