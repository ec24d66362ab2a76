//! The HTTP side: one page, its assets, a WebSocket stream, a small JSON
//! API, CSV download and the Fig. 11 plot, on axum/tokio.
//!
//! Security (a page that can enable motor power): every state-changing
//! request and the WebSocket need the per-run token and an `Origin` that
//! is this server's own; anything else is refused with 403 and changes
//! nothing. The token is printed (in the URL) on the terminal only.

use std::collections::VecDeque;
use std::fmt::Write as _;
use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use axum::Router;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::Deserialize;
use serde_json::{Value, json};
use tokio::sync::broadcast;

use firelink_host::WatchdogSetting;
use firelink_testbed::demo::DemoFault;

use firelink_testbed::service::{Command, CommandOutcome, Frame, Shared};

const INDEX_HTML: &str = include_str!("../assets/index.html");
const APP_JS: &str = include_str!("../assets/app.js");
const APP_CSS: &str = include_str!("../assets/app.css");
const UPLOT_JS: &str = include_str!("../assets/vendor/uPlot.iife.min.js");
const UPLOT_CSS: &str = include_str!("../assets/vendor/uPlot.min.css");

/// How often the server drains frames and pushes to browsers.
const TICK: Duration = Duration::from_millis(20);
/// Samples per joint sent per tick at most (the rest are decimated).
const SAMPLES_PER_TICK: usize = 20;
/// Seconds of samples kept for the CSV download.
pub const CSV_SECONDS: f64 = 30.0;

/// One recorded sample of every joint (for CSV and the charts).
#[derive(Debug, Clone)]
struct Sample {
    t: f64,
    /// setpoint, position, commanded current per joint, flattened.
    values: Vec<f32>,
}

/// The server's state.
pub struct Console {
    shared: Arc<Shared>,
    token: String,
    origins: Vec<String>,
    ring: Mutex<VecDeque<Sample>>,
    ring_capacity: usize,
    latest: Mutex<Value>,
    last_command: Mutex<Option<CommandOutcome>>,
    stream: broadcast::Sender<Arc<str>>,
    faults: Vec<DemoFault>,
}

impl Console {
    /// A console for `shared`, answering on `addr` (the origins it accepts
    /// are this address and, on loopback, `localhost`), with the faults the
    /// port can inject.
    pub fn new(
        shared: Arc<Shared>,
        token: String,
        addr: SocketAddr,
        faults: Vec<DemoFault>,
    ) -> Console {
        let port = addr.port();
        let mut origins = vec![format!("http://{addr}")];
        if addr.ip().is_loopback() {
            origins.push(format!("http://localhost:{port}"));
            origins.push(format!("http://127.0.0.1:{port}"));
        }
        let ring_capacity = (CSV_SECONDS * shared.rate_hz).ceil() as usize;
        let (stream, _) = broadcast::channel(64);
        Console {
            shared,
            token,
            origins,
            ring: Mutex::new(VecDeque::with_capacity(ring_capacity)),
            ring_capacity,
            latest: Mutex::new(Value::Null),
            last_command: Mutex::new(None),
            stream,
            faults,
        }
    }

    /// Reads that need the token only (a browser sends no `Origin` with a
    /// same-origin GET).
    fn token_ok(
        &self,
        headers: &HeaderMap,
        token: Option<&str>,
    ) -> Result<(), (StatusCode, String)> {
        let given = token.or_else(|| {
            headers
                .get("x-firelink-token")
                .and_then(|v| v.to_str().ok())
        });
        if given != Some(self.token.as_str()) {
            return Err((StatusCode::FORBIDDEN, "missing or wrong token".into()));
        }
        Ok(())
    }

    /// What can change the robot (and the WebSocket): the token and this
    /// console's own `Origin`.
    fn authorised(
        &self,
        headers: &HeaderMap,
        token: Option<&str>,
    ) -> Result<(), (StatusCode, String)> {
        let origin = headers.get(header::ORIGIN).and_then(|v| v.to_str().ok());
        match origin {
            Some(o) if self.origins.iter().any(|a| a == o) => {}
            Some(o) => {
                return Err((
                    StatusCode::FORBIDDEN,
                    format!("origin {o} is not this console's"),
                ));
            }
            None => return Err((StatusCode::FORBIDDEN, "no Origin header".into())),
        }
        self.token_ok(headers, token)
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

fn state_json(console: &Console, frame: &Frame) -> Value {
    json!({
        "type": "state",
        "t": frame.t,
        "cycle": frame.cycle,
        "state": frame.state.to_string(),
        "fault": frame.fault.map(|f| json!({"text": f.to_string(), "time": f.time, "cycle": f.cycle})),
        "io_us": frame.io_us,
        "errors": frame.errors,
        "boards": frame.boards,
        "axes": frame.axes,
        "joints": frame.joints,
        "skipped_frames": console.shared.skipped.load(Ordering::Relaxed),
        "last_command": *lock(&console.last_command),
    })
}

/// Drain the frames the loop filled: record, stream, give them back.
fn drain(console: &Console, tick: u64) {
    let mut t = Vec::new();
    let mut per_joint: Vec<[Vec<f32>; 3]> =
        vec![[Vec::new(), Vec::new(), Vec::new()]; console.shared.joint_labels.len()];
    let mut newest: Option<Box<Frame>> = None;
    while let Some(frame) = console.shared.full.pop() {
        let mut values = Vec::with_capacity(frame.joints.len() * 3);
        for j in &frame.joints {
            values.extend_from_slice(&[j.setpoint as f32, j.position as f32, j.current as f32]);
        }
        {
            let mut ring = lock(&console.ring);
            if ring.len() == console.ring_capacity {
                ring.pop_front();
            }
            ring.push_back(Sample { t: frame.t, values });
        }
        t.push(frame.t);
        for (k, j) in frame.joints.iter().enumerate() {
            if let Some(s) = per_joint.get_mut(k) {
                s[0].push(j.setpoint as f32);
                s[1].push(j.position as f32);
                s[2].push(j.current as f32);
            }
        }
        if let Some(old) = newest.replace(frame) {
            let _ = console.shared.free.push(old);
        }
    }
    while let Some(o) = console.shared.outcomes.pop() {
        *lock(&console.last_command) = Some(o);
    }
    let Some(frame) = newest else {
        return;
    };
    let state = state_json(console, &frame);
    *lock(&console.latest) = state.clone();
    let _ = console.shared.free.push(frame);
    // Decimate to at most SAMPLES_PER_TICK per joint.
    let step = t.len().div_ceil(SAMPLES_PER_TICK).max(1);
    let pick = |v: &[f32]| v.iter().step_by(step).copied().collect::<Vec<f32>>();
    let samples = json!({
        "type": "samples",
        "t": t.iter().step_by(step).copied().collect::<Vec<f64>>(),
        "setpoint": per_joint.iter().map(|s| pick(&s[0])).collect::<Vec<_>>(),
        "position": per_joint.iter().map(|s| pick(&s[1])).collect::<Vec<_>>(),
        "current": per_joint.iter().map(|s| pick(&s[2])).collect::<Vec<_>>(),
    });
    let _ = console.stream.send(Arc::from(samples.to_string()));
    if tick % 5 == 0 {
        let _ = console.stream.send(Arc::from(state.to_string()));
    }
}

/// The periodic drain, forever.
pub async fn drain_forever(console: Arc<Console>) {
    let mut interval = tokio::time::interval(TICK);
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut tick = 0u64;
    loop {
        interval.tick().await;
        drain(&console, tick);
        tick += 1;
    }
}

fn asset(body: &'static str, kind: &'static str) -> Response {
    (
        [(header::CONTENT_TYPE, HeaderValue::from_static(kind))],
        body,
    )
        .into_response()
}

async fn info(State(c): State<Arc<Console>>) -> Response {
    axum::Json(json!({
        "port": c.shared.port_name,
        "rate_hz": c.shared.rate_hz,
        "joints": c.shared.joint_labels,
        "boards": c.shared.board_infos.iter().map(|(id, fw, hw)| json!({"id": id, "firmware": fw, "hardware": hw})).collect::<Vec<_>>(),
        "faults": c.faults.iter().map(|f| f.name()).collect::<Vec<_>>(),
        "csv_seconds": CSV_SECONDS,
    }))
    .into_response()
}

async fn state(State(c): State<Arc<Console>>) -> Response {
    axum::Json(lock(&c.latest).clone()).into_response()
}

/// A command from the page.
#[derive(Debug, Deserialize)]
struct CommandRequest {
    action: String,
    #[serde(default)]
    on: Option<bool>,
    #[serde(default)]
    fault: Option<String>,
    /// A period in ms, or `"off"`.
    #[serde(default)]
    watchdog_ms: Option<Value>,
}

fn parse_command(c: &Console, r: &CommandRequest) -> Result<Command, String> {
    let on = || {
        r.on.ok_or_else(|| format!("{}: needs \"on\": true or false", r.action))
    };
    Ok(match r.action.as_str() {
        "configure" => Command::Configure,
        "power_on" => Command::PowerOn,
        "home" => Command::Home,
        "enable" => Command::Enable,
        "disable" => Command::Disable,
        "clear_fault" => Command::ClearFault,
        "relay" => Command::Relay(on()?),
        "amplifiers" => Command::Amplifiers(on()?),
        "watchdog" => {
            let setting = match &r.watchdog_ms {
                Some(Value::String(s)) if s.trim().eq_ignore_ascii_case("off") => {
                    WatchdogSetting::Off
                }
                Some(Value::Number(n)) => n
                    .as_f64()
                    .ok_or_else(|| format!("watchdog_ms {n}: not a number"))
                    .and_then(|ms| WatchdogSetting::from_ms(ms).map_err(|e| e.to_string()))?,
                _ => {
                    return Err("watchdog: needs \"watchdog_ms\": a period in ms or \"off\"".into());
                }
            };
            Command::Watchdog(setting)
        }
        "inject" => {
            let name = r.fault.as_deref().unwrap_or("");
            let fault: DemoFault = name
                .parse()
                .map_err(|e: firelink_testbed::TestbedError| e.to_string())?;
            if !c.faults.contains(&fault) || fault == DemoFault::None {
                return Err(format!("fault {name} cannot be injected on this port"));
            }
            Command::Inject(fault)
        }
        other => return Err(format!("unknown action {other:?}")),
    })
}

#[derive(Debug, Deserialize)]
struct TokenQuery {
    token: Option<String>,
    seconds: Option<f64>,
}

async fn command(
    State(c): State<Arc<Console>>,
    headers: HeaderMap,
    Query(q): Query<TokenQuery>,
    body: axum::body::Bytes,
) -> Response {
    if let Err(e) = c.authorised(&headers, q.token.as_deref()) {
        return e.into_response();
    }
    let request: CommandRequest = match serde_json::from_slice(&body) {
        Ok(r) => r,
        Err(e) => return (StatusCode::BAD_REQUEST, format!("bad command: {e}")).into_response(),
    };
    let command = match parse_command(&c, &request) {
        Ok(cmd) => cmd,
        Err(e) => return (StatusCode::BAD_REQUEST, e).into_response(),
    };
    match c.shared.commands.push(command) {
        Ok(()) => {
            c.shared.queued.fetch_add(1, Ordering::Relaxed);
            axum::Json(json!({"queued": format!("{command:?}")})).into_response()
        }
        Err(_) => (StatusCode::SERVICE_UNAVAILABLE, "command queue full").into_response(),
    }
}

async fn csv(
    State(c): State<Arc<Console>>,
    headers: HeaderMap,
    Query(q): Query<TokenQuery>,
) -> Response {
    if let Err(e) = c.token_ok(&headers, q.token.as_deref()) {
        return e.into_response();
    }
    let seconds = q.seconds.unwrap_or(CSV_SECONDS);
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= CSV_SECONDS) {
        return (
            StatusCode::BAD_REQUEST,
            format!("seconds: 0 < s <= {CSV_SECONDS}"),
        )
            .into_response();
    }
    let ring = lock(&c.ring);
    let newest = ring.back().map_or(0.0, |s| s.t);
    let mut out = String::from("t_s");
    for label in &c.shared.joint_labels {
        let _ = write!(out, ",{label} setpoint,{label} position,{label} current_A");
    }
    out.push('\n');
    for s in ring.iter().filter(|s| s.t >= newest - seconds) {
        let _ = write!(out, "{:.6}", s.t);
        for v in &s.values {
            let _ = write!(out, ",{v}");
        }
        out.push('\n');
    }
    (
        [
            (header::CONTENT_TYPE, HeaderValue::from_static("text/csv")),
            (
                header::CONTENT_DISPOSITION,
                HeaderValue::from_static("attachment; filename=\"firelink.csv\""),
            ),
        ],
        out,
    )
        .into_response()
}

async fn fig11(
    State(c): State<Arc<Console>>,
    headers: HeaderMap,
    Query(q): Query<TokenQuery>,
) -> Response {
    if let Err(e) = c.token_ok(&headers, q.token.as_deref()) {
        return e.into_response();
    }
    let made = tokio::task::spawn_blocking(|| -> Result<Vec<u8>, String> {
        use firelink_host::scan::Protocol;
        use firelink_testbed::bench::{BenchOptions, BenchTransport, run_bench};
        let report = run_bench(
            &BenchOptions {
                transports: vec![BenchTransport::Sim],
                boards: vec![1, 2, 4, 8, 16, 32, 62],
                protocols: vec![Protocol::Sequential, Protocol::Broadcast],
                cycles: 50,
                ..BenchOptions::default()
            },
            |_, _, _| {},
        )
        .map_err(|e| e.to_string())?;
        let path =
            std::env::temp_dir().join(format!("firelink-web-fig11-{}.png", std::process::id()));
        firelink_plot::fig11(&report, &path).map_err(|e| e.to_string())?;
        let bytes = std::fs::read(&path).map_err(|e| e.to_string());
        let _ = std::fs::remove_file(&path);
        bytes
    })
    .await;
    match made {
        Ok(Ok(png)) => (
            [(header::CONTENT_TYPE, HeaderValue::from_static("image/png"))],
            png,
        )
            .into_response(),
        Ok(Err(e)) => (StatusCode::INTERNAL_SERVER_ERROR, e).into_response(),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}

async fn ws(
    State(c): State<Arc<Console>>,
    headers: HeaderMap,
    Query(q): Query<TokenQuery>,
    upgrade: WebSocketUpgrade,
) -> Response {
    if let Err(e) = c.authorised(&headers, q.token.as_deref()) {
        return e.into_response();
    }
    let rx = c.stream.subscribe();
    let first = lock(&c.latest).to_string();
    upgrade.on_upgrade(move |socket| stream_to(socket, rx, first))
}

async fn stream_to(mut socket: WebSocket, mut rx: broadcast::Receiver<Arc<str>>, first: String) {
    if socket.send(Message::Text(first.into())).await.is_err() {
        return;
    }
    loop {
        match rx.recv().await {
            Ok(text) => {
                if socket
                    .send(Message::Text(text.to_string().into()))
                    .await
                    .is_err()
                {
                    return;
                }
            }
            // A slow browser misses messages; it never slows the robot.
            Err(broadcast::error::RecvError::Lagged(_)) => {}
            Err(broadcast::error::RecvError::Closed) => return,
        }
    }
}

/// The router of the console.
pub fn router(console: Arc<Console>) -> Router {
    Router::new()
        .route(
            "/",
            get(|| async { asset(INDEX_HTML, "text/html; charset=utf-8") }),
        )
        .route(
            "/app.js",
            get(|| async { asset(APP_JS, "text/javascript") }),
        )
        .route("/app.css", get(|| async { asset(APP_CSS, "text/css") }))
        .route(
            "/vendor/uPlot.iife.min.js",
            get(|| async { asset(UPLOT_JS, "text/javascript") }),
        )
        .route(
            "/vendor/uPlot.min.css",
            get(|| async { asset(UPLOT_CSS, "text/css") }),
        )
        .route("/api/info", get(info))
        .route("/api/state", get(state))
        .route("/api/command", post(command))
        .route("/api/csv", get(csv))
        .route("/api/fig11.png", get(fig11))
        .route("/ws", get(ws))
        .with_state(console)
}
