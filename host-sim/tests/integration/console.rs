//! The teaching console end to end, in a real headless browser: Debian's chromium driven through
//! chromedriver by a small W3C WebDriver client of our own (`console/webdriver.rs`). `host-sim
//! teach` runs as a person would start it; the test opens the printed URL, teaches through real
//! clicks and key presses, finishes the session and replays it with `host-sim replay-session`.
//!
//! Ignored by default: it needs `chromium` and `chromedriver` (scripts/setup-browser installs
//! them).
//!
//! ```text
//! scripts/setup-browser
//! cargo test -p host-sim --test integration -- --ignored console::
//! ```
//!
//! The screenshots are saved under target/tmp/console/ (`CARGO_TARGET_TMPDIR`).

use std::io::{BufRead, BufReader};
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, mpsc};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use webdriver::Session;

mod webdriver;

/// One browser at a time: the machine has two cores.
static BROWSER: Mutex<()> = Mutex::new(());

/// The browser's turn: a test that failed holding it does not stop the next.
fn one_browser() -> MutexGuard<'static, ()> {
    BROWSER
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// How long anything may take before the test gives up (a failure, not a measurement).
const PATIENCE: Duration = Duration::from_secs(60);

/// A child process killed when dropped.
struct Process(Child);

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_port() -> u16 {
    TcpListener::bind((Ipv4Addr::LOCALHOST, 0))
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// chromedriver on a free port of 127.0.0.1, and a headless chromium session through it.
fn browser(profile: &Path) -> (Process, Session) {
    let port = free_port();
    let driver = Command::new("chromedriver")
        .arg(format!("--port={port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("chromedriver runs (scripts/setup-browser installs it)");
    let driver = Process(driver);
    let deadline = Instant::now() + PATIENCE;
    while TcpStream::connect((Ipv4Addr::LOCALHOST, port)).is_err() {
        assert!(Instant::now() < deadline, "chromedriver did not listen");
        std::thread::sleep(Duration::from_millis(50));
    }
    let mut caps = serde_json::Map::new();
    caps.insert(
        "goog:chromeOptions".into(),
        json!({
            "binary": "/usr/bin/chromium",
            "args": [
                "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                "--no-first-run", "--disable-background-networking",
                "--disable-component-update", "--disable-sync",
                format!("--user-data-dir={}", profile.display()),
                "--window-size=1400,1100",
            ],
        }),
    );
    let client = Session::new(port, Value::Object(caps)).expect("a chromium session");
    (driver, client)
}

/// `host-sim teach ARGS`, and the URL it printed; its later output is collected.
fn teach(args: &[&str]) -> (Process, String, mpsc::Receiver<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("teach")
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("host-sim runs");
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    let child = Process(child);
    loop {
        let line = rx
            .recv_timeout(PATIENCE)
            .expect("host-sim teach prints its URL");
        if let Some(url) = line.strip_prefix("open ") {
            assert!(url.starts_with("http://127.0.0.1:"), "{url}");
            return (child, url.to_string(), rx);
        }
    }
}

/// Status line and body of a plain GET of `url` (no browser).
fn get(url: &str) -> (String, String) {
    let rest = url.strip_prefix("http://").unwrap();
    let (authority, path) = rest.split_at(rest.find('/').unwrap());
    crate::support::get(authority, path, "")
}

fn js(c: &Session, script: &str) -> Value {
    c.execute(script).expect(script)
}

/// Polls `script` until it returns something truthy.
fn until(c: &Session, script: &str, what: &str) -> Value {
    let deadline = Instant::now() + PATIENCE;
    loop {
        let v = js(c, script);
        let truthy = match &v {
            Value::Null => false,
            Value::Bool(b) => *b,
            Value::Number(n) => n.as_f64() != Some(0.0),
            Value::String(s) => !s.is_empty(),
            _ => true,
        };
        if truthy {
            return v;
        }
        assert!(Instant::now() < deadline, "waited in vain for {what}");
        std::thread::sleep(Duration::from_millis(40));
    }
}

fn press(c: &Session, key: char) {
    c.press(key).expect("a key press");
}

/// A real click at page point (x, y).
fn click_at(c: &Session, x: f64, y: f64) {
    c.click_at(x, y).expect("a click");
}

fn click_button(c: &Session, id: &str) {
    c.find_id(id).expect(id).click().expect(id);
}

fn text(c: &Session, id: &str) -> String {
    c.find_id(id).expect(id).text().expect(id)
}

fn weights(c: &Session) -> Vec<String> {
    let v = js(
        c,
        "return [...document.querySelectorAll('#weights .row')].map(r => r.dataset.value || '')",
    );
    serde_json::from_value(v).unwrap()
}

fn corrections(c: &Session) -> u64 {
    text(c, "corrections").parse().unwrap()
}

fn wait_corrections(c: &Session, n: u64) {
    until(
        c,
        &format!("return document.getElementById('corrections').textContent === '{n}'"),
        &format!("{n} corrections"),
    );
}

/// Opens the console, waits for the map and the 64 trajectories, and checks them.
fn open(c: &Session, url: &str) {
    c.goto(url).unwrap();
    let drawn = until(
        c,
        "const d = window.teachConsole && window.teachConsole.drawn; \
         return d && d.map && d.trajectories === 64 ? d : null",
        "the map and the 64 trajectories drawn",
    );
    assert!(drawn["allowed"].as_u64().unwrap() > 1, "{drawn}");
    assert!(drawn["chosen"].is_u64(), "{drawn}");
    // The map really is on the canvas: its pixels are not all the background.
    let painted = js(
        c,
        "const v = document.getElementById('view'); \
         const d = v.getContext('2d').getImageData(0, 0, v.width, v.height).data; \
         let white = 0; for (let i = 0; i < d.length; i += 4) \
           if (d[i] > 250 && d[i + 1] > 250 && d[i + 2] > 250) white++; \
         return white",
    );
    assert!(
        painted.as_u64().unwrap() > 10_000,
        "free space drawn: {painted}"
    );
}

/// Clicks the allowed trajectory whose end is farthest from the learner's choice; returns it.
fn click_a_trajectory(c: &Session) -> u64 {
    let pick = js(
        c,
        "const s = window.teachConsole.state(); \
         const end = (a) => window.teachConsole.pointOf(a); \
         const mine = end(s.chosen); let best = null, far = -1; \
         for (const a of s.allowed) { const p = end(a); \
           const d = Math.hypot(p.x - mine.x, p.y - mine.y); if (d > far) { far = d; best = a; } } \
         return {action: best, point: end(best)}",
    );
    let a = pick["action"].as_u64().unwrap();
    click_at(
        c,
        pick["point"]["x"].as_f64().unwrap(),
        pick["point"]["y"].as_f64().unwrap(),
    );
    a
}

fn lines(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn artifacts() -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("console");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Saves the page, from its top, as `name` under target/tmp/console/.
fn screenshot(c: &Session, name: &str) {
    js(c, "window.scrollTo(0, 0); return true");
    std::thread::sleep(Duration::from_millis(200));
    let png = c.screenshot().expect("a screenshot");
    std::fs::write(artifacts().join(name), png).unwrap();
}

/// Ends the session with the page's button and waits for host-sim teach to exit.
fn finish(c: &Session, teach: &mut Process, out: &mpsc::Receiver<String>) -> Vec<String> {
    click_button(c, "finish");
    until(
        c,
        "return !document.getElementById('ended').hidden",
        "the page says the session ended",
    );
    let deadline = Instant::now() + PATIENCE;
    let status = loop {
        if let Some(s) = teach.0.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "host-sim teach did not exit");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "{status:?}");
    out.try_iter().collect()
}

/// `host-sim replay-session DIR` succeeds, and its files are the session's, byte for byte.
fn replays_byte_for_byte(dir: &Path) {
    let replay = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["replay-session", dir.to_str().unwrap()])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&replay.stdout);
    assert!(replay.status.success(), "{replay:?}");
    assert!(stdout.contains("identical"), "{stdout}");
    for name in ["steps.csv", "snapshots.jsonl"] {
        let (a, b) = (
            std::fs::read(dir.join(name)).unwrap(),
            std::fs::read(dir.join("replay").join(name)).unwrap(),
        );
        assert!(!a.is_empty() && a == b, "{name} differs");
    }
    let summary = |p: PathBuf| -> Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let (a, b) = (
        summary(dir.join("summary.json")),
        summary(dir.join("replay").join("summary.json")),
    );
    for key in ["final_weights", "final_iterate", "learner_steps", "totals"] {
        assert_eq!(a[key], b[key], "{key}");
    }
}

#[test]
#[ignore = "needs chromium and chromedriver (scripts/setup-browser); .ci/run runs it"]
fn a_person_teaches_in_the_browser_and_the_session_replays_byte_for_byte() {
    let _one = one_browser();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("session");
    let (mut teach, url, out) = teach(&[
        "--scenario",
        "doors",
        "--session-dir",
        dir.to_str().unwrap(),
    ]);
    let base = url.split("/?").next().unwrap().to_string();

    // Without the token, or with another, the console refuses: to a plain request and in the
    // browser.
    let (status, body) = get(&format!("{base}/"));
    assert!(status.contains("403"), "{status}");
    assert!(body.contains("needs the token"), "{body}");
    assert!(get(&format!("{base}/?token=0123")).0.contains("403"));
    assert!(get(&format!("{base}/ws")).0.contains("403"));
    let (_driver, c) = browser(&tmp.path().join("profile"));
    c.goto(&format!("{base}/")).unwrap();
    let refused = c.find("body").unwrap().text().unwrap();
    assert!(refused.contains("refused"), "{refused}");

    // With it: the map and the 64 trajectories.
    open(&c, &url);
    assert_eq!(text(&c, "status"), "paused");
    assert_eq!(corrections(&c), 0);
    let before = weights(&c);
    assert_eq!(before.len(), 6);

    // A click on a trajectory: "go there". The counter goes up and the weights move.
    let clicked = click_a_trajectory(&c);
    wait_corrections(&c, 1);
    until(
        &c,
        "return [...document.querySelectorAll('#weights .row')].some(r => Number(r.dataset.value) !== 0)",
        "the weights to move",
    );
    assert_ne!(weights(&c), before, "the weights changed");

    // A preference: the mode by its button, the answer by its key ("the other is better").
    click_button(&c, "preference");
    until(
        &c,
        "return window.teachConsole.mode() === 'preference' && window.teachConsole.candidate() !== null",
        "preference mode",
    );
    press(&c, '2');
    wait_corrections(&c, 2);
    // A statement, by its key: "stay on the path".
    press(&c, 'l');
    wait_corrections(&c, 3);
    // And by its button: "avoid doors".
    click_button(&c, "say-avoid-doors");
    wait_corrections(&c, 4);

    // Play, pause, single steps.
    let t0: u64 = text(&c, "tick").parse().unwrap();
    press(&c, ' ');
    until(
        &c,
        &format!(
            "return Number(document.getElementById('tick').textContent) >= {}",
            t0 + 5
        ),
        "the ticks to run",
    );
    press(&c, ' ');
    until(
        &c,
        "return document.getElementById('status').textContent === 'paused'",
        "the pause",
    );
    let t1: u64 = text(&c, "tick").parse().unwrap();
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(text(&c, "tick").parse::<u64>().unwrap(), t1, "paused stays");
    press(&c, '.');
    until(
        &c,
        &format!(
            "return document.getElementById('tick').textContent === '{}'",
            t1 + 1
        ),
        "a single step",
    );
    click_button(&c, "step");
    until(
        &c,
        &format!(
            "return document.getElementById('tick').textContent === '{}'",
            t1 + 2
        ),
        "another step",
    );
    // Faster, then a click at the new tick.
    press(&c, '+');
    until(
        &c,
        "return document.getElementById('speed').textContent === '2×'",
        "2×",
    );
    click_button(&c, "preference");
    click_a_trajectory(&c);
    wait_corrections(&c, 5);

    // The page as it is now: the README's screenshot.
    screenshot(&c, "console.png");

    // A reward of +½ by its key, and "incorrect" by its button: each about the learner's choice
    // in the tick shown, each a correction.
    press(&c, '9');
    wait_corrections(&c, 6);
    click_button(&c, "mark-incorrect");
    wait_corrections(&c, 7);
    // "The last ticks were bad", by its key.
    press(&c, 'x');
    wait_corrections(&c, 8);
    let counts = text(&c, "teachings");
    assert!(
        counts.contains("1 rewards") && counts.contains("1 marks") && counts.contains("1 spans"),
        "{counts}"
    );

    // The E-stop, by its key: the intervention, a correction too.
    press(&c, '\u{E00C}');
    until(
        &c,
        "return document.getElementById('status').textContent === 'E-STOPPED'",
        "the E-stop",
    );
    wait_corrections(&c, 9);

    let said = finish(&c, &mut teach, &out);
    assert!(said.iter().any(|l| l.contains("session ended")), "{said:?}");
    c.close().unwrap();

    // The session's files: every teaching with its tick, kind, content and wall time.
    let feedback = lines(&dir.join("feedback.jsonl"));
    let kinds: Vec<&str> = feedback
        .iter()
        .map(|e| e["kind"].as_str().unwrap())
        .collect();
    assert_eq!(
        kinds,
        [
            "action",
            "preference",
            "statement",
            "statement",
            "action",
            "reward",
            "correctness",
            "span",
            "estop"
        ]
    );
    assert_eq!(feedback[0]["content"]["action"], clicked);
    assert_eq!(feedback[2]["content"]["statement"], "stay-on-path");
    assert_eq!(feedback[3]["content"]["statement"], "avoid-doors");
    assert_eq!(feedback[5]["content"]["hundredths"], 50);
    assert_eq!(feedback[6]["content"]["correct"], false);
    assert_eq!(
        feedback[7]["content"],
        serde_json::json!({"ticks": 4, "good": false})
    );
    assert!(
        feedback
            .iter()
            .all(|e| e["tick"].is_u64() && e["wall_time_ms"].is_u64())
    );
    assert_eq!(lines(&dir.join("snapshots.jsonl")).len(), 9);
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["config"]["feedback"], "person");
    assert_eq!(summary["session"]["finished"], true);
    assert_eq!(summary["session"]["ticks"], t1 + 2);
    replays_byte_for_byte(&dir);
}

#[test]
#[ignore = "needs chromium and chromedriver (scripts/setup-browser); .ci/run runs it"]
fn the_console_teaches_the_car_over_the_link() {
    use hil_mock::server::Server;
    use hil_mock::transport::udp::UdpLink;
    use protocol::car::CarConfig;

    let _one = one_browser();
    let tmp = tempfile::tempdir().unwrap();
    // The car: a hil_mock server on UDP 127.0.0.1 with its key.
    let mut car = UdpLink::listen(SocketAddrV4::new(Ipv4Addr::LOCALHOST, 0)).unwrap();
    let SocketAddr::V4(addr) = car.local_addr().unwrap() else {
        unreachable!("bound on 127.0.0.1")
    };
    let key_file = tmp.path().join("car.key");
    let key = hil_mock::key::keygen(&key_file).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let server = std::thread::spawn(move || {
        let mut s = Server::in_memory(CarConfig::default(), &key, 9);
        s.run(&mut car, &flag).unwrap();
        s.node().stats()
    });
    let dir = tmp.path().join("session");
    let link = format!("udp://{addr}");
    let (mut teach, url, out) = teach(&[
        "--scenario",
        "stairs-right",
        "--session-dir",
        dir.to_str().unwrap(),
        "--link",
        &link,
        "--key",
        key_file.to_str().unwrap(),
    ]);
    let (_driver, c) = browser(&tmp.path().join("profile"));
    open(&c, &url);
    // The page shows the link's state.
    until(
        &c,
        "return document.getElementById('link').dataset.connected === 'true'",
        "the link connected",
    );
    let link_text = text(&c, "link");
    assert!(
        link_text.contains("connected") && link_text.contains("retransmissions"),
        "{link_text}"
    );
    click_a_trajectory(&c);
    wait_corrections(&c, 1);
    press(&c, 'd');
    wait_corrections(&c, 2);
    for _ in 0..5 {
        press(&c, '.');
    }
    until(
        &c,
        "return document.getElementById('tick').textContent === '5'",
        "five steps",
    );
    screenshot(&c, "console-link.png");
    finish(&c, &mut teach, &out);
    c.close().unwrap();
    stop.store(true, Ordering::Relaxed);
    let stats = server.join().unwrap();
    assert!(stats.observations >= 6, "{stats:?}");
    let candump = std::fs::read_to_string(dir.join("candump.log")).unwrap();
    assert!(candump.lines().count() > 10, "the frames are logged");
    // The car's session replays in process, byte for byte.
    replays_byte_for_byte(&dir);
}
