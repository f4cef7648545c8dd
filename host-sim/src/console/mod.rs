//! The teaching console: a person teaches the car from a web page (`host-sim teach`, DESIGN
//! section 8).
//!
//! ```text
//!  browser ──HTTP/WebSocket, 127.0.0.1, token──▶ axum on tokio (this thread)
//!                                                 │ commands (std channel)   ▲ state (watch)
//!                                                 ▼                         │
//!                                   the session's thread: Session ── CarLink ── learner
//!                                   (10 Hz × speed)       │                  (in process, or
//!                                                         ▼                   the car's over CAN)
//!                                   steps.csv, summary.json, feedback.jsonl, snapshots.jsonl
//! ```
//!
//! [`Console::bind`] takes a port on 127.0.0.1 (a free one unless told) and a new token;
//! [`Console::run`] serves the page until the session ends: the person finishes it, Ctrl-C, the
//! tick limit, or the learner's link fails. Nothing is opened by itself: the caller prints
//! [`Console::url`]. The page, its script and style are embedded in the binary
//! (`console/assets/`), and the page loads nothing from anywhere else (its
//! `Content-Security-Policy` says so to the browser).
//!
//! | path | what |
//! |---|---|
//! | `/?token=…` | the page |
//! | `/console.js`, `/console.css` (`?token=…`) | its script and style |
//! | `/map.png?token=…` | the household's picture ([`crate::report::plot::MapDrawing`]) |
//! | `/ws?token=…` | the WebSocket: [`wire`] |
//!
//! Every request is checked by [`access::Access`] first (token, `Host`, `Origin`).
//!
//! The session itself runs on its own thread ([`driver::Driver`]), since the learner's link
//! blocks; the async side only moves messages. The page is described in
//! `docs/console.md`.

pub mod access;
pub mod driver;
pub mod wire;

use std::net::{Ipv4Addr, SocketAddr, TcpListener};
use std::sync::{Arc, Mutex, mpsc};

use anyhow::{Context, Result};
use axum::Router;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Request, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use tokio::sync::{oneshot, watch};

use self::access::Access;
use self::driver::{Control, Driver, Outcome, Trace};
use self::wire::{Command, PictureFrame};
use crate::teach::session::{Session, SessionAbout, SessionFiles};
use crate::world::scenario::Scenario;

const INDEX_HTML: &str = include_str!("assets/index.html");
const CONSOLE_JS: &str = include_str!("assets/console.js");
const CONSOLE_CSS: &str = include_str!("assets/console.css");

/// Widest picture of the household (pixels).
const PICTURE_WIDTH: usize = 1000;

/// A console bound to its port, not serving yet.
#[derive(Debug)]
pub struct Console {
    listener: TcpListener,
    access: Access,
}

impl Console {
    /// Binds 127.0.0.1:`port` (0: a free port) and draws a new token.
    pub fn bind(port: u16) -> Result<Self> {
        let listener = TcpListener::bind((Ipv4Addr::LOCALHOST, port))
            .with_context(|| format!("cannot listen on 127.0.0.1:{port}"))?;
        let port = listener.local_addr()?.port();
        Ok(Self {
            listener,
            access: Access::new(port)?,
        })
    }

    /// The address it listens on.
    pub fn local_addr(&self) -> Result<SocketAddr> {
        Ok(self.listener.local_addr()?)
    }

    /// The URL to open, with the token.
    pub fn url(&self) -> String {
        self.access.url()
    }

    /// Serves the page for `session` until the session ends, writing into `files`; `link` names
    /// the learner's link, if any. Returns how it ended.
    pub fn run(
        self,
        session: Session,
        files: SessionFiles,
        about: SessionAbout,
        link: Option<String>,
    ) -> Result<Outcome> {
        let scenario = session.config().scenario.clone();
        let (png, frame) = picture(&scenario)?;
        let scene = wire::scene(&scenario, &frame, &session, link.as_deref()).to_string();
        let authority = self.access.authority();
        let index = INDEX_HTML.replace("{{TOKEN}}", self.access.token());
        let (state_tx, state_rx) = watch::channel(Arc::<str>::from("{}"));
        let (control_tx, control_rx) = mpsc::channel::<Control>();
        let trace: Trace = Arc::new(Mutex::new(Vec::new()));
        let (done_tx, done_rx) = oneshot::channel::<()>();
        let driver = Driver::new(session, files, about, state_tx, trace.clone());
        let sim = std::thread::Builder::new()
            .name("session".into())
            .spawn(move || {
                let outcome = driver.run(control_rx);
                // Let the pages show the end before the server stops.
                std::thread::sleep(std::time::Duration::from_millis(500));
                let _ = done_tx.send(());
                outcome
            })
            .context("cannot start the session's thread")?;
        let app = App {
            access: self.access,
            index: index.into(),
            scene: scene.into(),
            png: png.into(),
            state: state_rx,
            controls: control_tx.clone(),
            trace,
            csp: format!(
                "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; \
                 connect-src ws://{authority} ws://localhost:{port}; base-uri 'none'; \
                 form-action 'none'; frame-ancestors 'none'",
                port = self.listener.local_addr()?.port()
            ),
        };
        let router = Router::new()
            .route("/", get(index_page))
            .route("/console.js", get(script))
            .route("/console.css", get(style))
            .route("/map.png", get(map_png))
            .route("/ws", get(websocket))
            .fallback(not_found)
            .layer(middleware::from_fn_with_state(app.clone(), guard))
            .with_state(app);
        self.listener.set_nonblocking(true)?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_io()
            .build()
            .context("cannot start the console's runtime")?;
        let served = runtime.block_on(async move {
            let listener = tokio::net::TcpListener::from_std(self.listener)?;
            let shutdown = async move {
                let mut done = done_rx;
                tokio::select! {
                    _ = &mut done => {}
                    _ = tokio::signal::ctrl_c() => {
                        let _ = control_tx.send(Control::Interrupt);
                        let _ = done.await;
                    }
                }
            };
            axum::serve(listener, router)
                .with_graceful_shutdown(shutdown)
                .await
        });
        let outcome = sim
            .join()
            .map_err(|_| anyhow::anyhow!("the session's thread panicked"))?;
        served.context("the console's server failed")?;
        Ok(outcome)
    }
}

/// The household's picture as PNG bytes, and where it puts the world.
pub fn picture(scenario: &Scenario) -> Result<(Vec<u8>, PictureFrame)> {
    let scale = (PICTURE_WIDTH / scenario.map.width().max(1)).clamp(1, 8);
    let drawing = crate::report::plot::MapDrawing::of_scenario_scaled(scenario, scale);
    let (width, height) = drawing.size();
    let png = drawing.raster().png_bytes().context("map picture")?;
    let origin = scenario.map.origin();
    Ok((
        png,
        PictureFrame {
            width,
            height,
            origin: (origin[0], origin[1]),
            metres_per_pixel: crate::report::plot::MapDrawing::metres_per_pixel(scenario, scale),
        },
    ))
}

#[derive(Clone)]
struct App {
    access: Access,
    index: Arc<str>,
    scene: Arc<str>,
    png: Arc<[u8]>,
    state: watch::Receiver<Arc<str>>,
    controls: mpsc::Sender<Control>,
    trace: Trace,
    csp: String,
}

/// Refuses what [`Access`] refuses; adds the headers every answer carries.
async fn guard(State(app): State<App>, request: Request, next: Next) -> Response {
    let checked = {
        let text = |name: header::HeaderName| {
            request
                .headers()
                .get(name)
                .map(|v| v.to_str().unwrap_or("(not text)").to_string())
        };
        app.access.check(
            request.uri().query(),
            text(header::HOST).as_deref(),
            text(header::ORIGIN).as_deref(),
        )
    };
    let mut response = match checked {
        Ok(()) => next.run(request).await,
        Err(refusal) => (StatusCode::FORBIDDEN, format!("{refusal}\n")).into_response(),
    };
    let headers = response.headers_mut();
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    headers.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    headers.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    if let Ok(v) = HeaderValue::from_str(&app.csp) {
        headers.insert(header::CONTENT_SECURITY_POLICY, v);
    }
    response
}

async fn index_page(State(app): State<App>) -> Response {
    (
        [(header::CONTENT_TYPE, "text/html; charset=utf-8")],
        app.index.to_string(),
    )
        .into_response()
}

async fn script() -> Response {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        CONSOLE_JS,
    )
        .into_response()
}

async fn style() -> Response {
    (
        [(header::CONTENT_TYPE, "text/css; charset=utf-8")],
        CONSOLE_CSS,
    )
        .into_response()
}

async fn map_png(State(app): State<App>) -> Response {
    ([(header::CONTENT_TYPE, "image/png")], app.png.to_vec()).into_response()
}

async fn not_found() -> Response {
    (StatusCode::NOT_FOUND, "not found\n").into_response()
}

async fn websocket(State(app): State<App>, upgrade: WebSocketUpgrade) -> Response {
    upgrade.on_upgrade(move |socket| page(app, socket))
}

/// One page: the scene and the trace, then every state, and its commands to the session.
async fn page(app: App, mut socket: WebSocket) {
    let trace = app
        .trace
        .lock()
        .map(|t| serde_json::json!({"type": "trace", "points": *t}).to_string())
        .unwrap_or_default();
    let mut state = app.state.clone();
    let first = state.borrow_and_update().to_string();
    for text in [app.scene.to_string(), trace, first] {
        if socket.send(Message::Text(text.into())).await.is_err() {
            return;
        }
    }
    loop {
        tokio::select! {
            changed = state.changed() => {
                if changed.is_err() {
                    break;
                }
                let text = state.borrow_and_update().to_string();
                if socket.send(Message::Text(text.into())).await.is_err() {
                    break;
                }
            }
            received = socket.recv() => match received {
                Some(Ok(Message::Text(text))) => match serde_json::from_str::<Command>(&text) {
                    Ok(c) => {
                        if app.controls.send(Control::Command(c)).is_err() {
                            break;
                        }
                    }
                    Err(e) => {
                        let error = serde_json::json!({
                            "type": "error",
                            "text": format!("message refused: {e}"),
                        });
                        if socket.send(Message::Text(error.to_string().into())).await.is_err() {
                            break;
                        }
                    }
                },
                Some(Ok(Message::Close(_))) | Some(Err(_)) | None => break,
                Some(Ok(_)) => {}
            },
        }
    }
}
