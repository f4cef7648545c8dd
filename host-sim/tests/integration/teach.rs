//! `host-sim teach` and `replay-session` without a browser: the console answers only with its
//! token, Ctrl-C ends a session with its files written, a folder holding a session is not
//! overwritten, and bad session folders are named. (The page itself is tested in a real browser
//! by console.rs beside this file.)

use crate::support::{get, host_sim};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A `host-sim teach` killed when dropped.
struct Teach(Child);

impl Drop for Teach {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn the_console_answers_only_its_token_and_ctrl_c_writes_the_session() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["teach", "--scenario", "doors", "--session-dir"])
        .arg(&dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let teach = Teach(child);
    let url = loop {
        let line = lines.next().expect("a URL").unwrap();
        if let Some(url) = line.strip_prefix("open ") {
            break url.to_string();
        }
    };
    let rest = url.strip_prefix("http://127.0.0.1:").expect(&url);
    let (port, query) = rest.split_once("/?").unwrap();
    let authority = format!("127.0.0.1:{port}");
    assert!(
        query.starts_with("token=") && query.len() == 6 + 32,
        "{query}"
    );

    let ok = get(&authority, &format!("/?{query}"), "");
    assert!(ok.0.contains("200"), "{ok:?}");
    assert!(
        ok.1.contains("Teach the car") && ok.1.contains(query),
        "the page links its assets with the token"
    );
    for (path, headers, why) in [
        ("/".to_string(), "", "needs the token"),
        (
            "/?token=00000000000000000000000000000000".to_string(),
            "",
            "wrong token",
        ),
        (
            format!("/console.js?{query}"),
            "Origin: http://evil.example\r\n",
            "are not this console's",
        ),
        (
            format!("/map.png?{query}"),
            "Origin: null\r\n",
            "are not this console's",
        ),
        (
            "/ws".to_string(),
            "Upgrade: websocket\r\nConnection: Upgrade\r\n",
            "needs the token",
        ),
    ] {
        let (status, body) = get(&authority, &path, headers);
        assert!(status.contains("403"), "{path}: {status}");
        assert!(body.contains(why), "{path}: {body}");
    }
    // DNS rebinding: another name for this address.
    let mut s = TcpStream::connect(&authority).unwrap();
    write!(
        s,
        "GET /?{query} HTTP/1.1\r\nHost: evil.example:{port}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    assert!(text.starts_with("HTTP/1.1 403"), "{text}");
    let (status, body) = get(&authority, &format!("/map.png?{query}"), "");
    assert!(status.contains("200") && body.len() > 100, "{status}");
    let css = get(&authority, &format!("/console.css?{query}"), "");
    assert!(css.0.contains("200"), "{css:?}");

    // Ctrl-C: the session ends and its files are written.
    let kill = Command::new("kill")
        .args(["-INT", &teach.0.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let mut teach = teach;
    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        if let Some(s) = teach.0.try_wait().unwrap() {
            break s;
        }
        assert!(
            Instant::now() < deadline,
            "host-sim teach did not end on Ctrl-C"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success(), "{status:?}");
    let said: Vec<String> = lines.map_while(Result::ok).collect();
    assert!(
        said.iter()
            .any(|l| l.contains("session ended (interrupted")),
        "{said:?}"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["session"]["finished"], true);
    assert_eq!(summary["session"]["ticks"], 0);
    assert_eq!(
        std::fs::read_to_string(dir.join("feedback.jsonl")).unwrap(),
        ""
    );
    // Zero ticks replay too.
    let replay = host_sim(&["replay-session", dir.to_str().unwrap()]);
    assert!(replay.status.success(), "{replay:?}");

    // The folder holds a session now: a second one is refused before anything starts.
    let again = host_sim(&["teach", "--session-dir", dir.to_str().unwrap()]);
    assert!(!again.status.success());
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(err.contains("holds a session already"), "{err}");
}

#[test]
fn replaying_a_folder_that_is_not_a_session_names_what_is_wrong() {
    let tmp = tempfile::tempdir().unwrap();
    let out = host_sim(&["replay-session", tmp.path().to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("summary.json") && err.contains("cannot read"),
        "{err}"
    );
    // A run's folder is not a session.
    let run = tmp.path().join("run");
    let r = host_sim(&["run", "--steps", "20", "--out", run.to_str().unwrap()]);
    assert!(r.status.success(), "{r:?}");
    let out = host_sim(&["replay-session", run.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("not a session"), "{err}");
}
