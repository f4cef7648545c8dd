//! A small blocking W3C WebDriver client: the commands the console's browser tests send to
//! chromedriver, as JSON over HTTP/1.1 on 127.0.0.1, one connection per command.
//!
//! The tests used the `fantoccini` crate until 2026-12: its WebDriver types (the `webdriver`
//! crate) brought about fifty crates of their own into every all-features build (an older
//! `http`, two `cookie`s, `url` and `idna` with two generations of the ICU tables, `time`), for
//! the eleven commands below. The protocol is the W3C recommendation's
//! (<https://www.w3.org/TR/webdriver2/>): a command is a method and a path under the session, its
//! parameters a JSON body, its answer `{"value": ...}`, an error `{"value": {"error", "message"}}`
//! with a 4xx or 5xx status.

use std::io::{Read, Write};
use std::net::{Ipv4Addr, TcpStream};
use std::time::Duration;

use base64::Engine;
use serde_json::{Value, json};

/// The W3C name of an element reference in a command's answer.
const ELEMENT: &str = "element-6066-11e4-a52e-4f735466cecf";

/// A WebDriver command that failed: its HTTP status and the driver's error and message, or why
/// the answer could not be read.
#[derive(Debug)]
pub(crate) struct Error(String);

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Error {}

type Result<T> = std::result::Result<T, Error>;

/// A session of a WebDriver server listening on 127.0.0.1 (chromedriver).
pub(crate) struct Session {
    port: u16,
    id: String,
}

/// An element of the page, as the driver named it.
pub(crate) struct Element<'a> {
    session: &'a Session,
    id: String,
}

/// One HTTP/1.1 exchange with the driver on 127.0.0.1:`port`: the status code and the body's
/// JSON.
fn exchange(port: u16, method: &str, path: &str, body: Option<&Value>) -> Result<(u16, Value)> {
    let io = |e: std::io::Error| Error(format!("{method} {path}: {e}"));
    let mut stream = TcpStream::connect((Ipv4Addr::LOCALHOST, port)).map_err(io)?;
    // No command of the tests' takes long; a driver that hangs fails the test instead.
    stream
        .set_read_timeout(Some(Duration::from_secs(120)))
        .map_err(io)?;
    let body = body.map(Value::to_string).unwrap_or_default();
    let request = format!(
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json; \
         charset=utf-8\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    stream.write_all(request.as_bytes()).map_err(io)?;
    // chromedriver keeps the connection open whatever the request asks: the answer ends where its
    // length says (or its last chunk), not where the stream does.
    let mut raw = Vec::new();
    let mut buf = [0u8; 16 * 1024];
    let (head, split) = loop {
        if let Some(split) = raw.windows(4).position(|w| w == b"\r\n\r\n") {
            break (
                String::from_utf8_lossy(&raw[..split]).into_owned(),
                split + 4,
            );
        }
        let n = stream.read(&mut buf).map_err(io)?;
        if n == 0 {
            return Err(Error(format!(
                "{method} {path}: the answer ended in its headers"
            )));
        }
        raw.extend_from_slice(&buf[..n]);
    };
    let status: u16 = head
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| Error(format!("{method} {path}: no status in {head:?}")))?;
    let header = |name: &str| {
        head.lines().skip(1).find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.trim()
                .eq_ignore_ascii_case(name)
                .then(|| v.trim().to_ascii_lowercase())
        })
    };
    let chunked = header("transfer-encoding").is_some_and(|v| v.contains("chunked"));
    let length: Option<usize> = header("content-length").and_then(|v| v.parse().ok());
    let complete = |body: &[u8]| match (chunked, length) {
        (true, _) => dechunk(body).is_some(),
        (false, Some(n)) => body.len() >= n,
        (false, None) => false,
    };
    while !complete(&raw[split..]) {
        let n = stream.read(&mut buf).map_err(io)?;
        if n == 0 {
            break;
        }
        raw.extend_from_slice(&buf[..n]);
    }
    let body = &raw[split..];
    let content = match (chunked, length) {
        (true, _) => dechunk(body)
            .ok_or_else(|| Error(format!("{method} {path}: a malformed chunked answer")))?,
        (false, Some(n)) => body
            .get(..n)
            .ok_or_else(|| Error(format!("{method} {path}: the answer ended early")))?
            .to_vec(),
        (false, None) => body.to_vec(),
    };
    let value = serde_json::from_slice(&content)
        .map_err(|e| Error(format!("{method} {path}: status {status}, not JSON: {e}")))?;
    Ok((status, value))
}

/// The body of a chunked transfer (RFC 9112, section 7.1), or `None` if it is malformed.
fn dechunk(mut data: &[u8]) -> Option<Vec<u8>> {
    let mut out = Vec::new();
    loop {
        let line = data.windows(2).position(|w| w == b"\r\n")?;
        let size = std::str::from_utf8(&data[..line]).ok()?;
        let size = usize::from_str_radix(size.split(';').next()?.trim(), 16).ok()?;
        data = &data[line + 2..];
        if size == 0 {
            return Some(out);
        }
        out.extend_from_slice(data.get(..size)?);
        data = data.get(size + 2..)?;
    }
}

/// The command's `value`, or its error.
fn value(port: u16, method: &str, path: &str, body: Option<&Value>) -> Result<Value> {
    let (status, answer) = exchange(port, method, path, body)?;
    let value = answer.get("value").cloned().unwrap_or(Value::Null);
    if (200..300).contains(&status) {
        Ok(value)
    } else {
        Err(Error(format!(
            "{method} {path}: status {status}, {}: {}",
            value["error"].as_str().unwrap_or("no error named"),
            value["message"].as_str().unwrap_or("no message")
        )))
    }
}

impl Session {
    /// A new session of the driver on 127.0.0.1:`port`, with these capabilities (W3C
    /// `alwaysMatch`).
    pub(crate) fn new(port: u16, capabilities: Value) -> Result<Session> {
        let body = json!({ "capabilities": { "alwaysMatch": capabilities } });
        let value = value(port, "POST", "/session", Some(&body))?;
        let id = value["sessionId"]
            .as_str()
            .ok_or_else(|| Error(format!("a new session without an id: {value}")))?
            .to_string();
        Ok(Session { port, id })
    }

    fn command(&self, method: &str, path: &str, body: Option<&Value>) -> Result<Value> {
        value(
            self.port,
            method,
            &format!("/session/{}{path}", self.id),
            body,
        )
    }

    /// Navigates to `url` and waits for the page to load.
    pub(crate) fn goto(&self, url: &str) -> Result<()> {
        self.command("POST", "/url", Some(&json!({ "url": url })))
            .map(drop)
    }

    /// Runs `script` (a function body: `return ...` gives the value) synchronously in the page.
    pub(crate) fn execute(&self, script: &str) -> Result<Value> {
        self.command(
            "POST",
            "/execute/sync",
            Some(&json!({ "script": script, "args": [] })),
        )
    }

    /// Performs one input source's actions (W3C "Perform Actions").
    pub(crate) fn perform(&self, source: Value) -> Result<()> {
        self.command("POST", "/actions", Some(&json!({ "actions": [source] })))
            .map(drop)
    }

    /// Releases every key and button the actions left pressed.
    pub(crate) fn release_actions(&self) -> Result<()> {
        self.command("DELETE", "/actions", None).map(drop)
    }

    /// A key pressed and released (`key`: one character, or a WebDriver key code point such as
    /// U+E00C for Escape).
    pub(crate) fn press(&self, key: char) -> Result<()> {
        let key = key.to_string();
        self.perform(json!({
            "type": "key",
            "id": "keyboard",
            "actions": [
                { "type": "keyDown", "value": key },
                { "type": "keyUp", "value": key },
            ],
        }))
    }

    /// A left click at the viewport's point (`x`, `y`), rounded to whole pixels.
    pub(crate) fn click_at(&self, x: f64, y: f64) -> Result<()> {
        self.perform(json!({
            "type": "pointer",
            "id": "mouse",
            "parameters": { "pointerType": "mouse" },
            "actions": [
                { "type": "pointerMove", "origin": "viewport", "x": x.round() as i64, "y": y.round() as i64 },
                { "type": "pointerDown", "button": 0 },
                { "type": "pointerUp", "button": 0 },
            ],
        }))?;
        self.release_actions()
    }

    /// The first element `selector` (CSS) matches.
    pub(crate) fn find(&self, selector: &str) -> Result<Element<'_>> {
        let value = self.command(
            "POST",
            "/element",
            Some(&json!({ "using": "css selector", "value": selector })),
        )?;
        let id = value[ELEMENT]
            .as_str()
            .ok_or_else(|| {
                Error(format!(
                    "{selector}: an element without a reference: {value}"
                ))
            })?
            .to_string();
        Ok(Element { session: self, id })
    }

    /// The element whose id is `id`.
    pub(crate) fn find_id(&self, id: &str) -> Result<Element<'_>> {
        self.find(&format!("[id=\"{id}\"]"))
    }

    /// A screenshot of the viewport, as PNG bytes.
    pub(crate) fn screenshot(&self) -> Result<Vec<u8>> {
        let value = self.command("GET", "/screenshot", None)?;
        let text = value
            .as_str()
            .ok_or_else(|| Error(format!("a screenshot that is not base64 text: {value}")))?;
        base64::engine::general_purpose::STANDARD
            .decode(text)
            .map_err(|e| Error(format!("a screenshot's base64: {e}")))
    }

    /// Ends the session (the browser closes).
    pub(crate) fn close(self) -> Result<()> {
        self.command("DELETE", "", None).map(drop)
    }
}

impl Element<'_> {
    fn command(&self, method: &str, what: &str, body: Option<&Value>) -> Result<Value> {
        self.session
            .command(method, &format!("/element/{}/{what}", self.id), body)
    }

    /// Clicks the element's centre, as a person would (scrolled into view first).
    pub(crate) fn click(&self) -> Result<()> {
        self.command("POST", "click", Some(&json!({}))).map(drop)
    }

    /// The element's rendered text.
    pub(crate) fn text(&self) -> Result<String> {
        let value = self.command("GET", "text", None)?;
        value
            .as_str()
            .map(str::to_string)
            .ok_or_else(|| Error(format!("an element's text that is not a string: {value}")))
    }
}

#[test]
fn a_chunked_answer_is_put_together_and_a_malformed_one_refused() {
    assert_eq!(
        dechunk(b"4\r\n{\"va\r\n8;ext=1\r\nlue\": 1}\r\n0\r\n\r\n").as_deref(),
        Some(&b"{\"value\": 1}"[..])
    );
    assert_eq!(dechunk(b"zz\r\nabc\r\n0\r\n\r\n"), None);
    assert_eq!(dechunk(b"10\r\nshort\r\n"), None);
}
