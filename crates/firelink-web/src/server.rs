//! The HTTP side: one page, its assets, a WebSocket stream, a small JSON
//! API, CSV download and the Fig. 11 plot, on axum/tokio.
//!
//! Security (a page that can switch motor power on):
//! - Everything that reveals or changes the robot's state (`/api/*`,
//!   `/ws`) needs the per-run token, in the `X-Firelink-Token` header or
//!   in the console's cookie; never in the URL (a token in the URL of an
//!   API call is refused: URLs end up in logs and histories). The
//!   terminal prints `http://ADDR/?token=T` once: a `GET /` with the
//!   right token sets the cookie (`HttpOnly`, `SameSite=Strict`) and
//!   redirects (303) to `/`, so the token leaves the address bar at once.
//!   Tokens are compared in constant time.
//! - What changes the robot, and the WebSocket, also need an `Origin` of
//!   this console's own: `http://HOST` where `HOST` (the request's `Host`
//!   header) is the address the request reached (the connection's own
//!   address, or on loopback any loopback address or `localhost`), or an
//!   origin given with `--allow-origin`. A name that merely resolves here
//!   (DNS rebinding) is not enough.
//!
//! Anything else is refused with 403 and changes nothing.
//!
//! A command's answer is its outcome: the handler waits (at most
//! [`COMMAND_WAIT`]) for the outcome carrying its command's id: 200 done,
//! 409 refused by the robot's state (with the reason), 500 failed on the
//! way, 400 malformed, 202 still running (then `GET /api/command/ID`
//! gives the outcome once there).

use std::collections::{HashMap, VecDeque};
use std::fmt::Write as _;
use std::net::{IpAddr, SocketAddr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use axum::Router;
use axum::extract::connect_info::Connected;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{ConnectInfo, Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, Uri, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::Deserialize;
use serde_json::{Value, json};
use tokio::sync::{Notify, broadcast, oneshot};

use firelink_host::WatchdogSetting;
use firelink_testbed::demo::DemoFault;

use firelink_testbed::dvrk::service::{Command, Frame, Shared};
use firelink_testbed::loop_outcome::{CommandOutcome, Verdict};

const INDEX_HTML: &str = include_str!("../assets/index.html");
const APP_JS: &str = include_str!("../assets/app.js");
const APP_CSS: &str = include_str!("../assets/app.css");
const ROBOTS_JS: &str = include_str!("../assets/robots.js");
const UPLOT_JS: &str = include_str!("../assets/vendor/uPlot.iife.min.js");
const UPLOT_CSS: &str = include_str!("../assets/vendor/uPlot.min.css");

/// How often the server drains frames and outcomes and pushes to browsers.
const TICK: Duration = Duration::from_millis(20);
/// Samples per joint sent per tick at most (the rest are decimated).
const SAMPLES_PER_TICK: usize = 20;
/// Seconds of samples kept for the CSV download.
pub const CSV_SECONDS: f64 = 30.0;
/// The highest rate the CSV's samples are kept at: a faster loop keeps
/// every k-th frame it hands over (k the smallest whole number that brings
/// the rate to this or below; at 6 kHz and under, every frame; frames the
/// loop skipped when the console fell behind are not counted, so the kept
/// ones are then unevenly spaced; their times say so). So the ring holds at
/// most `CSV_SECONDS` x this many samples at any servo rate (180 000, not
/// the 3 million 30 s of a 100 kHz loop would be).
pub const CSV_MAX_RATE_HZ: f64 = 6_000.0;
/// How long `POST /api/command` waits for its command's outcome before it
/// answers 202 (still running). Every command takes well under a second of
/// the robot's time (power-on waits for the supply and the amplifiers'
/// enable delay, homing averages the pots for a few hundred cycles); the
/// bound is for a machine so loaded that the robot's thread lags.
pub const COMMAND_WAIT: Duration = Duration::from_secs(5);
/// Outcomes kept for `GET /api/command/ID`.
const RECENT_OUTCOMES: usize = 64;
/// The header that may carry the token.
pub const TOKEN_HEADER: &str = "x-firelink-token";

/// One recorded sample of every joint (for CSV and the charts).
#[derive(Debug, Clone)]
struct Sample {
    t: f64,
    /// setpoint, position, commanded current per joint, flattened (shared:
    /// a CSV request's copy under the ring's lock is a count, not a copy
    /// of the values).
    values: Arc<[f32]>,
}

/// The samples kept for the CSV: the last [`CSV_SECONDS`] of the loop's
/// cycles, at most [`CSV_MAX_RATE_HZ`] of them a second (a faster loop's
/// cycles decimated by a whole factor).
#[derive(Debug)]
struct SampleRing {
    samples: VecDeque<Sample>,
    capacity: usize,
    /// Keep one cycle in this many.
    keep_every: u64,
    /// Cycles offered so far.
    seen: u64,
}

impl SampleRing {
    /// The ring for a loop at `rate_hz`.
    fn for_rate(rate_hz: f64) -> SampleRing {
        let keep_every = (rate_hz / CSV_MAX_RATE_HZ).ceil().max(1.0) as u64;
        let capacity = (CSV_SECONDS * rate_hz / keep_every as f64).ceil() as usize;
        SampleRing {
            samples: VecDeque::with_capacity(capacity),
            capacity,
            keep_every,
            seen: 0,
        }
    }

    /// Offer one cycle's sample: kept if it is one of the decimation's,
    /// the oldest dropped when full. `values` is made only for a kept one.
    fn offer(&mut self, t: f64, values: impl FnOnce() -> Vec<f32>) {
        let keep = self.seen % self.keep_every == 0;
        self.seen += 1;
        if !keep {
            return;
        }
        if self.samples.len() == self.capacity {
            self.samples.pop_front();
        }
        self.samples.push_back(Sample {
            t,
            values: values().into(),
        });
    }

    /// The samples of the last `seconds` (by the newest's time), sharing
    /// their values with the ring.
    fn last(&self, seconds: f64) -> Vec<Sample> {
        let newest = self.samples.back().map_or(0.0, |s| s.t);
        self.samples
            .iter()
            .filter(|s| s.t >= newest - seconds)
            .cloned()
            .collect()
    }
}

/// The two ends of a connection, for the `Origin` check: the address the
/// client reached (`local`) is this server's own.
#[derive(Debug, Clone, Copy)]
pub struct Peer {
    /// This server's end.
    pub local: SocketAddr,
    /// The client's end.
    pub remote: SocketAddr,
}

impl Connected<axum::serve::IncomingStream<'_, tokio::net::TcpListener>> for Peer {
    fn connect_info(stream: axum::serve::IncomingStream<'_, tokio::net::TcpListener>) -> Peer {
        let remote = *stream.remote_addr();
        // A socket that cannot say its own address: an unspecified one,
        // which matches no Host (only --allow-origin origins pass).
        let local = stream
            .io()
            .local_addr()
            .unwrap_or_else(|_| SocketAddr::from(([0, 0, 0, 0], 0)));
        Peer { local, remote }
    }
}

/// A refused request: status and reason.
pub(crate) type Refusal = (StatusCode, String);

/// The server's state.
pub struct Console {
    shared: Arc<Shared>,
    gate: Gate,
    ring: Mutex<SampleRing>,
    latest: Mutex<Value>,
    last_command: Mutex<Option<CommandOutcome>>,
    recent: Mutex<VecDeque<CommandOutcome>>,
    waiters: Mutex<HashMap<u64, oneshot::Sender<CommandOutcome>>>,
    stream: broadcast::Sender<Arc<str>>,
    faults: Vec<DemoFault>,
    loop_ended: AtomicBool,
    /// Told once when the robot loop has ended (a panic, a signal).
    pub ended: Notify,
}

/// The name of the cookie that carries the token of the console on `port`
/// (cookies do not tell ports apart: two consoles on one host must not
/// overwrite each other's).
pub fn cookie_name(port: u16) -> String {
    format!("firelink-token-{port}")
}

/// Whether `given` is `secret`, in time that does not depend on where
/// they differ: every byte of the secret is compared, and the lengths
/// without an early exit.
pub fn same_secret(given: &[u8], secret: &[u8]) -> bool {
    let mut diff = u8::from(given.len() != secret.len());
    for (i, s) in secret.iter().enumerate() {
        diff |= s ^ given.get(i).copied().unwrap_or(0);
    }
    std::hint::black_box(diff) == 0
}

/// `host[:port]` as a `Host` header gives it: the name (brackets removed)
/// and the port (80 when absent). `None` when malformed.
fn split_host(host: &str) -> Option<(&str, u16)> {
    let (name, port) = if let Some(rest) = host.strip_prefix('[') {
        let (name, after) = rest.split_once(']')?;
        match after {
            "" => (name, None),
            p => (name, Some(p.strip_prefix(':')?)),
        }
    } else {
        match host.rsplit_once(':') {
            Some((name, _)) if name.contains(':') => return None,
            Some((name, p)) => (name, Some(p)),
            None => (host, None),
        }
    };
    let port = match port {
        Some(p) => p.parse().ok()?,
        None => 80,
    };
    (!name.is_empty()).then_some((name, port))
}

/// Whether `host` (a request's `Host` header) names this server as the
/// client reached it at `local`: the same port, and the same address, or
/// on loopback any loopback address, `0.0.0.0` or `localhost`. Names that
/// resolve to this machine are not known here (give them with
/// `--allow-origin`).
pub fn host_is_own(host: &str, local: SocketAddr) -> bool {
    let Some((name, port)) = split_host(host) else {
        return false;
    };
    let here = local.ip().to_canonical();
    if port != local.port() {
        return false;
    }
    if name.eq_ignore_ascii_case("localhost") {
        return here.is_loopback();
    }
    match name.parse::<IpAddr>() {
        Ok(ip) => {
            let ip = ip.to_canonical();
            // (0.0.0.0 in a URL reaches this machine over loopback.)
            let local_alias = ip.is_loopback() || ip.is_unspecified();
            ip == here || (local_alias && here.is_loopback())
        }
        Err(_) => false,
    }
}

/// An origin for `--allow-origin`: `http://HOST[:PORT]` or
/// `https://HOST[:PORT]`, as a browser sends it (lower case, no path).
///
/// # Errors
/// Anything else, `*` and `null` included.
pub fn parse_origin(text: &str) -> Result<String, String> {
    let t = text.trim().trim_end_matches('/').to_ascii_lowercase();
    let rest = t
        .strip_prefix("http://")
        .or_else(|| t.strip_prefix("https://"))
        .ok_or_else(|| {
            format!("{text:?}: an origin is http://HOST[:PORT] or https://HOST[:PORT]")
        })?;
    let ok_chars = rest
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || "-.:[]".contains(c));
    if !ok_chars || split_host(rest).is_none() {
        return Err(format!(
            "{text:?}: an origin is http://HOST[:PORT] or https://HOST[:PORT] (no path)"
        ));
    }
    Ok(t)
}

/// The console's security checks (see the module docs), the same for
/// every robot: the run's token and the origins accepted.
pub struct Gate {
    token: String,
    cookie: String,
    allowed_origins: Vec<String>,
}

impl Gate {
    /// The checks of a console with the run's `token`, listening on
    /// `listen` (its port names the cookie), accepting also the
    /// `allowed_origins` (from [`parse_origin`]).
    pub fn new(token: String, listen: SocketAddr, allowed_origins: Vec<String>) -> Gate {
        Gate {
            token,
            cookie: cookie_name(listen.port()),
            allowed_origins,
        }
    }

    /// Reads: the token in the header or the cookie; never in the URL.
    pub(crate) fn token_ok(&self, headers: &HeaderMap, uri: &Uri) -> Result<(), Refusal> {
        let forbidden = |why: &str| Err((StatusCode::FORBIDDEN, why.to_string()));
        let in_url = uri
            .query()
            .unwrap_or("")
            .split('&')
            .any(|pair| pair.split('=').next() == Some("token"));
        if in_url {
            return forbidden(
                "the token goes in the X-Firelink-Token header or the console's cookie, \
                 never in the URL",
            );
        }
        let secret = self.token.as_bytes();
        let from_header = headers
            .get_all(TOKEN_HEADER)
            .iter()
            .any(|v| same_secret(v.as_bytes(), secret));
        let from_cookie = headers
            .get_all(header::COOKIE)
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(';'))
            .filter_map(|c| c.trim().split_once('='))
            .filter(|(name, _)| *name == self.cookie)
            .any(|(_, value)| same_secret(value.as_bytes(), secret));
        if from_header || from_cookie {
            Ok(())
        } else {
            forbidden("missing or wrong token")
        }
    }

    /// The request's `Origin` is this console's own (see the module
    /// docs), the connection's end here being `local`.
    fn origin_ok(&self, headers: &HeaderMap, local: SocketAddr) -> Result<(), Refusal> {
        let forbidden = |why: String| Err((StatusCode::FORBIDDEN, why));
        let Some(origin) = headers.get(header::ORIGIN) else {
            return forbidden(
                "no Origin header (browsers send one; a script sends Origin: http://ADDR)".into(),
            );
        };
        let Ok(origin) = origin.to_str() else {
            return forbidden("an Origin header that is not text".into());
        };
        if self
            .allowed_origins
            .iter()
            .any(|a| a.eq_ignore_ascii_case(origin))
        {
            return Ok(());
        }
        let host = headers
            .get(header::HOST)
            .and_then(|h| h.to_str().ok())
            .filter(|h| host_is_own(h, local));
        if let Some(host) = host {
            let own = origin
                .strip_prefix("http://")
                .is_some_and(|o| o.eq_ignore_ascii_case(host));
            if own {
                return Ok(());
            }
        }
        forbidden(format!(
            "origin {origin} is not this console's (its own address, or one given with \
             --allow-origin)"
        ))
    }

    /// What can change the robot (and the WebSocket): the token and this
    /// console's own `Origin`.
    pub(crate) fn may_change(
        &self,
        headers: &HeaderMap,
        uri: &Uri,
        local: SocketAddr,
    ) -> Result<(), Refusal> {
        self.token_ok(headers, uri)?;
        self.origin_ok(headers, local)
    }

    /// `/`: the page (static: it shows nothing until its API calls are
    /// authorised). `/?token=T` with this run's token sets the cookie and
    /// redirects to `/`; a wrong token is refused.
    pub(crate) fn index(&self, uri: &Uri) -> Response {
        let token = Query::<IndexQuery>::try_from_uri(uri)
            .ok()
            .and_then(|q| q.0.token);
        let Some(token) = token else {
            let mut r = asset(INDEX_HTML, "text/html; charset=utf-8");
            r.headers_mut().extend(page_headers());
            return r;
        };
        if !same_secret(token.as_bytes(), self.token.as_bytes()) {
            return (
                StatusCode::FORBIDDEN,
                [(header::CONTENT_TYPE, "text/plain; charset=utf-8")],
                "wrong or old token: open the URL this run of firelink web printed\n",
            )
                .into_response();
        }
        let cookie = format!(
            "{}={}; Path=/; HttpOnly; SameSite=Strict",
            self.cookie, self.token
        );
        let mut r = StatusCode::SEE_OTHER.into_response();
        let h = r.headers_mut();
        h.extend(page_headers());
        h.insert(header::LOCATION, HeaderValue::from_static("/"));
        if let Ok(v) = HeaderValue::from_str(&cookie) {
            h.insert(header::SET_COOKIE, v);
        }
        r
    }
}

impl Console {
    /// A console for `shared` with the run's `token`, listening on `listen`
    /// (its port names the cookie), accepting also the `allowed_origins`
    /// (from [`parse_origin`]), with the faults the port can inject.
    pub fn new(
        shared: Arc<Shared>,
        token: String,
        listen: SocketAddr,
        allowed_origins: Vec<String>,
        faults: Vec<DemoFault>,
    ) -> Console {
        let ring = SampleRing::for_rate(shared.period.rate_hz());
        let (stream, _) = broadcast::channel(64);
        Console {
            shared,
            gate: Gate::new(token, listen, allowed_origins),
            ring: Mutex::new(ring),
            latest: Mutex::new(Value::Null),
            last_command: Mutex::new(None),
            recent: Mutex::new(VecDeque::with_capacity(RECENT_OUTCOMES)),
            waiters: Mutex::new(HashMap::new()),
            stream,
            faults,
            loop_ended: AtomicBool::new(false),
            ended: Notify::new(),
        }
    }

    fn token_ok(&self, headers: &HeaderMap, uri: &Uri) -> Result<(), Refusal> {
        self.gate.token_ok(headers, uri)
    }

    fn may_change(&self, headers: &HeaderMap, uri: &Uri, local: SocketAddr) -> Result<(), Refusal> {
        self.gate.may_change(headers, uri, local)
    }

    /// Record an outcome: the last command, and the recent ones by id.
    fn record(&self, outcome: &CommandOutcome) {
        if outcome.id != 0 {
            let mut recent = lock(&self.recent);
            if recent.len() == RECENT_OUTCOMES {
                recent.pop_front();
            }
            recent.push_back(outcome.clone());
        }
        *lock(&self.last_command) = Some(outcome.clone());
    }

    /// Hand an outcome to whoever waits for its id.
    fn wake(&self, outcome: CommandOutcome) {
        if let Some(waiter) = lock(&self.waiters).remove(&outcome.id) {
            let _ = waiter.send(outcome);
        }
    }

    /// Whether the robot loop has ended, and how.
    fn loop_exit(&self) -> Option<String> {
        self.shared.exit.get().map(ToString::to_string)
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A JSON answer `{"result": ..., "detail": ...}` (refusals and errors).
pub(crate) fn answer(status: StatusCode, result: &str, detail: &str) -> Response {
    (
        status,
        axum::Json(json!({"result": result, "detail": detail})),
    )
        .into_response()
}

pub(crate) fn refusal((status, why): Refusal) -> Response {
    answer(status, "forbidden", &why)
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
        "loop_exit": console.loop_exit(),
    })
}

/// Drain the frames the loop filled: record, stream, give them back;
/// hand outcomes to their waiters.
///
/// Outcomes are taken first and handed out last: the loop publishes the
/// frame that shows a command done before its outcome, so whoever is told
/// the outcome then reads (`/api/state`) a frame at least that new.
fn drain(console: &Console, tick: u64) {
    let mut outcomes = Vec::new();
    while let Some(o) = console.shared.outcomes.pop() {
        console.record(&o);
        outcomes.push(o);
    }
    publish_frames(console, tick);
    for o in outcomes {
        console.wake(o);
    }
    if console.shared.exit.get().is_some() && !console.loop_ended.swap(true, Ordering::Relaxed) {
        // No outcome will come any more: whoever still waits is told so
        // (their sender is dropped), and the server is asked to stop.
        lock(&console.waiters).clear();
        console.ended.notify_one();
    }
}

/// The frames part of [`drain`].
fn publish_frames(console: &Console, tick: u64) {
    let mut t = Vec::new();
    let mut per_joint: Vec<[Vec<f32>; 3]> =
        vec![[Vec::new(), Vec::new(), Vec::new()]; console.shared.joint_labels.len()];
    let mut newest: Option<Box<Frame>> = None;
    while let Some(frame) = console.shared.full.pop() {
        lock(&console.ring).offer(frame.t, || {
            let mut values = Vec::with_capacity(frame.joints.len() * 3);
            for j in &frame.joints {
                values.extend_from_slice(&[j.setpoint as f32, j.position as f32, j.current as f32]);
            }
            values
        });
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

/// The page's own headers: never framed by another site, no referrer.
fn page_headers() -> [(header::HeaderName, HeaderValue); 4] {
    [
        (header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY")),
        (
            header::CONTENT_SECURITY_POLICY,
            HeaderValue::from_static("frame-ancestors 'none'"),
        ),
        (
            header::REFERRER_POLICY,
            HeaderValue::from_static("no-referrer"),
        ),
        (header::CACHE_CONTROL, HeaderValue::from_static("no-store")),
    ]
}

#[derive(Debug, Deserialize)]
struct IndexQuery {
    token: Option<String>,
}

/// `/`: see [`Gate::index`].
async fn index(State(c): State<Arc<Console>>, uri: Uri) -> Response {
    c.gate.index(&uri)
}

async fn info(State(c): State<Arc<Console>>, headers: HeaderMap, uri: Uri) -> Response {
    if let Err(e) = c.token_ok(&headers, &uri) {
        return refusal(e);
    }
    axum::Json(json!({
        "robot": "dvrk",
        "port": c.shared.port_name,
        "rate_hz": c.shared.period.rate_hz(),
        "period_us": c.shared.period.as_micros_f64(),
        "joints": c.shared.joint_labels,
        "boards": c.shared.board_infos.iter().map(|(id, fw, hw)| json!({"id": id, "firmware": fw, "hardware": hw})).collect::<Vec<_>>(),
        "faults": c.faults.iter().map(|f| f.name()).collect::<Vec<_>>(),
        "csv_seconds": CSV_SECONDS,
        "command_wait_s": COMMAND_WAIT.as_secs_f64(),
    }))
    .into_response()
}

async fn state(State(c): State<Arc<Console>>, headers: HeaderMap, uri: Uri) -> Response {
    if let Err(e) = c.token_ok(&headers, &uri) {
        return refusal(e);
    }
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

/// The HTTP answer of a command's outcome: 200 done, 409 refused, 500
/// failed.
pub(crate) fn outcome_response(o: &CommandOutcome) -> Response {
    let status = match o.result {
        Verdict::Ok => StatusCode::OK,
        Verdict::Refused => StatusCode::CONFLICT,
        Verdict::Failed => StatusCode::INTERNAL_SERVER_ERROR,
    };
    (status, axum::Json(o)).into_response()
}

fn running_response(id: u64, command: &Command) -> Response {
    (
        StatusCode::ACCEPTED,
        axum::Json(json!({
            "id": id,
            "command": command.to_string(),
            "result": "running",
            "detail": format!(
                "still running after {} s: GET /api/command/{id} gives its outcome once there",
                COMMAND_WAIT.as_secs()
            ),
        })),
    )
        .into_response()
}

fn ended_response(c: &Console) -> Response {
    answer(
        StatusCode::SERVICE_UNAVAILABLE,
        "unavailable",
        &format!(
            "the robot loop has ended: {}",
            c.loop_exit().unwrap_or_default()
        ),
    )
}

async fn command(
    State(c): State<Arc<Console>>,
    ConnectInfo(peer): ConnectInfo<Peer>,
    headers: HeaderMap,
    uri: Uri,
    body: axum::body::Bytes,
) -> Response {
    if let Err(e) = c.may_change(&headers, &uri, peer.local) {
        return refusal(e);
    }
    let request: CommandRequest = match serde_json::from_slice(&body) {
        Ok(r) => r,
        Err(e) => {
            return answer(
                StatusCode::BAD_REQUEST,
                "malformed",
                &format!("bad command: {e}"),
            );
        }
    };
    let command = match parse_command(&c, &request) {
        Ok(cmd) => cmd,
        Err(e) => return answer(StatusCode::BAD_REQUEST, "malformed", &e),
    };
    if c.shared.exit.get().is_some() {
        return ended_response(&c);
    }
    // The waiter is in place before the command can run.
    let id = c.shared.new_id();
    let (tx, rx) = oneshot::channel();
    lock(&c.waiters).insert(id, tx);
    let queued = c
        .shared
        .requests
        .push(firelink_testbed::dvrk::service::Request { id, command });
    if queued.is_err() {
        lock(&c.waiters).remove(&id);
        return answer(
            StatusCode::SERVICE_UNAVAILABLE,
            "unavailable",
            "the command queue is full: the robot loop is behind",
        );
    }
    c.shared.queued.fetch_add(1, Ordering::Relaxed);
    match tokio::time::timeout(COMMAND_WAIT, rx).await {
        Ok(Ok(outcome)) => outcome_response(&outcome),
        // The loop ended with the command still queued or running.
        Ok(Err(_)) => ended_response(&c),
        Err(_) => {
            lock(&c.waiters).remove(&id);
            // It may have ended between the time-out and the removal.
            match lock(&c.recent).iter().find(|o| o.id == id) {
                Some(o) => outcome_response(o),
                None => running_response(id, &command),
            }
        }
    }
}

/// `GET /api/command/ID`: a recent command's outcome (as its POST would
/// have answered), 202 while it runs, 404 for an id never given or long
/// forgotten.
async fn command_outcome(
    State(c): State<Arc<Console>>,
    headers: HeaderMap,
    uri: Uri,
    id: Result<Path<u64>, axum::extract::rejection::PathRejection>,
) -> Response {
    if let Err(e) = c.token_ok(&headers, &uri) {
        return refusal(e);
    }
    let Ok(Path(id)) = id else {
        return answer(StatusCode::BAD_REQUEST, "malformed", "an id is a number");
    };
    if let Some(o) = lock(&c.recent).iter().find(|o| o.id == id) {
        return outcome_response(o);
    }
    let pending = lock(&c.waiters).contains_key(&id)
        || (id > 0 && id <= c.shared.last_id.load(Ordering::Relaxed) && c.loop_exit().is_none());
    if pending {
        return (
            StatusCode::ACCEPTED,
            axum::Json(json!({"id": id, "result": "running", "detail": "not finished yet"})),
        )
            .into_response();
    }
    answer(
        StatusCode::NOT_FOUND,
        "unknown",
        &format!("no recent command {id}"),
    )
}

#[derive(Debug, Deserialize)]
struct CsvQuery {
    seconds: Option<f64>,
}

async fn csv(State(c): State<Arc<Console>>, headers: HeaderMap, uri: Uri) -> Response {
    if let Err(e) = c.token_ok(&headers, &uri) {
        return refusal(e);
    }
    let seconds = match Query::<CsvQuery>::try_from_uri(&uri) {
        Ok(q) => q.0.seconds.unwrap_or(CSV_SECONDS),
        Err(e) => return answer(StatusCode::BAD_REQUEST, "malformed", &e.body_text()),
    };
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= CSV_SECONDS) {
        return answer(
            StatusCode::BAD_REQUEST,
            "malformed",
            &format!("seconds: 0 < s <= {CSV_SECONDS}"),
        );
    }
    // Copied out under the lock, formatted without it: the robot's
    // frames go on into the ring meanwhile.
    let samples = lock(&c.ring).last(seconds);
    let mut out = String::from("t_s");
    for label in &c.shared.joint_labels {
        let _ = write!(out, ",{label} setpoint,{label} position,{label} current_A");
    }
    out.push('\n');
    for s in &samples {
        let _ = write!(out, "{:.6}", s.t);
        for v in s.values.iter() {
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

async fn fig11(State(c): State<Arc<Console>>, headers: HeaderMap, uri: Uri) -> Response {
    if let Err(e) = c.token_ok(&headers, &uri) {
        return refusal(e);
    }
    let made = tokio::task::spawn_blocking(|| -> Result<Vec<u8>, String> {
        use firelink_host::qla::scan::Protocol;
        use firelink_testbed::dvrk::bench::{BenchOptions, BenchTransport, run_bench};
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
        Ok(Err(e)) => answer(StatusCode::INTERNAL_SERVER_ERROR, "failed", &e),
        Err(e) => answer(StatusCode::INTERNAL_SERVER_ERROR, "failed", &e.to_string()),
    }
}

async fn ws(
    State(c): State<Arc<Console>>,
    ConnectInfo(peer): ConnectInfo<Peer>,
    headers: HeaderMap,
    uri: Uri,
    upgrade: Result<WebSocketUpgrade, axum::extract::ws::rejection::WebSocketUpgradeRejection>,
) -> Response {
    if let Err(e) = c.may_change(&headers, &uri, peer.local) {
        return refusal(e);
    }
    let upgrade = match upgrade {
        Ok(u) => u,
        Err(e) => return e.into_response(),
    };
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

/// `router` with the page's static assets (the same for every robot:
/// they reveal nothing and need nothing).
pub(crate) fn with_assets<S: Clone + Send + Sync + 'static>(router: Router<S>) -> Router<S> {
    router
        .route(
            "/app.js",
            get(|| async { asset(APP_JS, "text/javascript") }),
        )
        .route(
            "/robots.js",
            get(|| async { asset(ROBOTS_JS, "text/javascript") }),
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
}

/// The router of the console. Serve it with
/// `into_make_service_with_connect_info::<Peer>()` (the `Origin` check
/// needs the connection's own address).
pub fn router(console: Arc<Console>) -> Router {
    with_assets(Router::new())
        .route("/", get(index))
        .route("/api/info", get(info))
        .route("/api/state", get(state))
        .route("/api/command", post(command))
        .route("/api/command/{id}", get(command_outcome))
        .route("/api/csv", get(csv))
        .route("/api/fig11.png", get(fig11))
        .route("/ws", get(ws))
        .with_state(console)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_csv_ring_is_bounded_at_any_servo_rate() {
        let most = (CSV_SECONDS * CSV_MAX_RATE_HZ) as usize;
        // Up to the kept rate, every cycle (30 s of them).
        for (rate, capacity) in [(1000.0, 30_000), (6000.0, most)] {
            let r = SampleRing::for_rate(rate);
            assert_eq!((r.capacity, r.keep_every), (capacity, 1), "{rate} Hz");
        }
        // 100 kHz: one cycle in 17 (5.9 kHz), not 3 million samples.
        let mut r = SampleRing::for_rate(100_000.0);
        assert_eq!(r.keep_every, 17);
        assert!(r.capacity <= most, "{}", r.capacity);
        assert!(r.samples.capacity() < 200_000, "{}", r.samples.capacity());
        // A minute of cycles: the ring stays at its capacity, each kept
        // sample 17 cycles after the one before, the newest the last kept.
        let period = 1e-5;
        let cycles = 6_000_000u64;
        for k in 0..cycles {
            r.offer(k as f64 * period, Vec::new);
        }
        assert_eq!(r.samples.len(), r.capacity);
        let newest = r.samples.back().unwrap().t;
        assert!(
            ((cycles - 1) / 17 * 17) as f64 * period == newest,
            "{newest}"
        );
        let kept = r.last(1.0);
        let step = kept[1].t - kept[0].t;
        assert!((step - 17.0 * period).abs() < 1e-9, "{step}");
        assert_eq!(kept.len(), 1.0f64.div_euclid(17.0 * period) as usize + 1);
    }

    #[test]
    fn secrets_compare_whole() {
        assert!(same_secret(b"0123abcd", b"0123abcd"));
        assert!(!same_secret(b"0123abcX", b"0123abcd"));
        assert!(!same_secret(b"0123abc", b"0123abcd"));
        assert!(!same_secret(b"0123abcd0", b"0123abcd"));
        assert!(!same_secret(b"", b"0123abcd"));
        // A shorter guess padded with what the padding would be is still
        // wrong (the lengths differ).
        assert!(!same_secret(b"ab", b"ab\0"));
    }

    #[test]
    fn hosts_are_ours_only_at_the_address_reached() {
        let lan: SocketAddr = "192.168.1.20:8080".parse().unwrap();
        let lo: SocketAddr = "127.0.0.1:8080".parse().unwrap();
        let lo6: SocketAddr = "[::1]:8080".parse().unwrap();
        let mapped: SocketAddr = "[::ffff:192.168.1.20]:8080".parse().unwrap();
        // A listener on 0.0.0.0 reached on its LAN address.
        assert!(host_is_own("192.168.1.20:8080", lan));
        assert!(host_is_own("192.168.1.20:8080", mapped));
        assert!(!host_is_own("192.168.1.21:8080", lan));
        assert!(!host_is_own("192.168.1.20:8081", lan));
        assert!(!host_is_own("192.168.1.20", lan));
        assert!(!host_is_own("localhost:8080", lan));
        assert!(!host_is_own("127.0.0.1:8080", lan));
        // A name (DNS rebinding) is never enough.
        assert!(!host_is_own("evil.example:8080", lan));
        assert!(!host_is_own("evil.example:8080", lo));
        // On loopback: every loopback address and localhost.
        for h in [
            "127.0.0.1:8080",
            "localhost:8080",
            "LocalHost:8080",
            "[::1]:8080",
        ] {
            assert!(host_is_own(h, lo), "{h}");
            assert!(host_is_own(h, lo6), "{h}");
        }
        // Malformed hosts are nobody's.
        for h in ["", ":8080", "[::1", "[::1]x", "::1:8080", "a:b", "a:99999"] {
            assert!(!host_is_own(h, lo), "{h:?}");
        }
        let port80: SocketAddr = "127.0.0.1:80".parse().unwrap();
        assert!(host_is_own("localhost", port80));
    }

    #[test]
    fn allowed_origins_are_plain_origins() {
        assert_eq!(
            parse_origin("http://Robot.Lab:8080/").unwrap(),
            "http://robot.lab:8080"
        );
        assert_eq!(
            parse_origin("https://[fe80::1]:8443").unwrap(),
            "https://[fe80::1]:8443"
        );
        for bad in [
            "*",
            "null",
            "robot.lab:8080",
            "http://",
            "http://a/b",
            "ftp://a",
            "http://a b",
        ] {
            assert!(parse_origin(bad).is_err(), "{bad}");
        }
    }
}
