//! The robots other than the dVRK: seed 001's Snake system ([`snake`])
//! and seed 002's MAHRU humanoid ([`mahru`]), each with its own view in
//! the same page, behind the same security ([`Gate`]) as the dVRK's.
//!
//! Each robot runs as the dVRK does: one thread owns the rig and runs its
//! cycles; it never waits on the server. The hand-off ([`Exchange`]) is
//! lock-free: a small pool of preallocated frames travels between two
//! bounded queues (the loop fills one every [`PUBLISH_SECONDS`] of the
//! robot's time and after each command; none free: it takes back the
//! oldest the server has not read, counted), and commands arrive on a
//! third queue the loop polls between cycles, each with the channel its
//! outcome goes back on. The frame that shows a command done is handed
//! over before the command's outcome, so whoever is told the outcome then
//! reads a state at least that new.
//!
//! The HTTP side ([`router`]) serves the page, `GET /api/info` (what the
//! robot is), `GET /api/state` (its newest frame as JSON, with a `robot`
//! field) and `POST /api/command` (a JSON command: malformed or unknown
//! ones are refused with 400 and the reason before they reach the robot;
//! the robot's answer is 200 done, 409 refused by its state, 500 failed,
//! or 202 still running).

pub mod mahru;
pub mod snake;

use std::fmt;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};
use std::thread::JoinHandle;

use axum::Router;
use axum::extract::{ConnectInfo, State};
use axum::http::{HeaderMap, StatusCode, Uri};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use crossbeam_queue::ArrayQueue;
use serde_json::{Value, json};
use tokio::sync::{Notify, oneshot};

use firelink_testbed::loop_outcome::{CommandOutcome, LoopExit, Verdict};

use crate::server::{COMMAND_WAIT, Gate, Peer, answer, outcome_response, refusal, with_assets};

/// Which robot the console drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum RobotKind {
    /// The dVRK (seed 000's QLA boards): the console's first view.
    #[default]
    Dvrk,
    /// Seed 001's Snake system: 36 axes on six 7-channel nodes.
    Snake,
    /// Seed 002's MAHRU humanoid: 14 modules on three chains.
    Mahru,
}

impl fmt::Display for RobotKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            RobotKind::Dvrk => "dvrk",
            RobotKind::Snake => "snake",
            RobotKind::Mahru => "mahru",
        })
    }
}

/// How often the loop hands a frame over, seconds of the robot's time
/// (the page polls about as often).
pub const PUBLISH_SECONDS: f64 = 0.02;
/// Frames in the pool: the server holds one, the rest wait in the queues.
const POOL: usize = 8;
/// Commands that may wait for the loop.
const QUEUE: usize = 16;

/// A command on its way to the loop, with where its outcome goes.
pub struct Pending<C> {
    /// The id the outcome carries.
    pub id: u64,
    /// What to do.
    pub command: C,
    reply: oneshot::Sender<CommandOutcome>,
}

/// What the loop and the server share for one robot: frames of type `F`
/// and commands of type `C`.
pub struct Exchange<F, C> {
    full: ArrayQueue<Box<F>>,
    free: ArrayQueue<Box<F>>,
    requests: ArrayQueue<Pending<C>>,
    /// Outcomes whose waiter had given up (shown as the last command).
    late: ArrayQueue<CommandOutcome>,
    /// Frames skipped because none was free.
    pub skipped: AtomicU64,
    /// Commands accepted and queued.
    pub accepted: AtomicU64,
    last_id: AtomicU64,
    /// Set to stop the loop (it powers the robot down first).
    pub stop: AtomicBool,
    /// How the loop ended, once it has.
    pub exit: OnceLock<LoopExit>,
    /// Told once the loop has ended.
    pub ended: Notify,
}

impl<F, C> Exchange<F, C> {
    /// An exchange with a pool of frames made by `frame`.
    pub fn new(frame: impl Fn() -> F) -> Exchange<F, C> {
        let free = ArrayQueue::new(POOL);
        for _ in 0..POOL {
            let _ = free.push(Box::new(frame()));
        }
        Exchange {
            full: ArrayQueue::new(POOL),
            free,
            requests: ArrayQueue::new(QUEUE),
            late: ArrayQueue::new(QUEUE),
            skipped: AtomicU64::new(0),
            accepted: AtomicU64::new(0),
            last_id: AtomicU64::new(0),
            stop: AtomicBool::new(false),
            exit: OnceLock::new(),
            ended: Notify::new(),
        }
    }

    /// (Loop) Fill a free frame with `fill` and hand it over. None free
    /// (the server has not read for a while): the oldest waiting frame is
    /// taken back instead, counted as skipped, so the newest state always
    /// reaches the server. No allocation.
    pub fn publish(&self, fill: impl FnOnce(&mut F)) {
        let frame = self.free.pop().or_else(|| {
            let oldest = self.full.pop();
            if oldest.is_some() {
                self.skipped.fetch_add(1, Ordering::Relaxed);
            }
            oldest
        });
        let Some(mut frame) = frame else {
            self.skipped.fetch_add(1, Ordering::Relaxed);
            return;
        };
        fill(&mut frame);
        if let Err(frame) = self.full.push(frame) {
            let _ = self.free.push(frame);
            self.skipped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// (Loop) The next command waiting, if any.
    pub fn next_request(&self) -> Option<Pending<C>> {
        self.requests.pop()
    }

    /// (Loop) Hand `each` the commands waiting, at most as many as the
    /// queue holds (a flood of commands cannot hold the cycles up).
    pub fn take_requests(&self, mut each: impl FnMut(Pending<C>)) {
        for _ in 0..self.requests.capacity() {
            match self.requests.pop() {
                Some(p) => each(p),
                None => break,
            }
        }
    }

    /// (Loop) Answer `pending` with `result` (done with what it found, or
    /// refused or failed with why), described as `what`.
    pub fn answer(&self, pending: Pending<C>, what: String, result: Result<String, Refused>) {
        let (result, detail) = match result {
            Ok(found) => (Verdict::Ok, found),
            Err(Refused(verdict, why)) => (verdict, why),
        };
        let outcome = CommandOutcome {
            id: pending.id,
            command: what,
            result,
            detail,
        };
        if let Err(outcome) = pending.reply.send(outcome) {
            if let Err(outcome) = self.late.push(outcome) {
                let _ = self.late.pop();
                let _ = self.late.push(outcome);
            }
        }
    }

    /// (Loop) It has ended: record how, refuse whatever still waits and
    /// tell the server.
    pub fn finish(&self, exit: LoopExit, describe: impl Fn(&C) -> String) {
        let why = format!("not run: the robot loop has ended ({exit})");
        let _ = self.exit.set(exit);
        while let Some(p) = self.requests.pop() {
            let what = describe(&p.command);
            self.answer(p, what, Err(Refused(Verdict::Refused, why.clone())));
        }
        self.ended.notify_one();
    }

    /// (Server) Queue `command`; the receiver gets its outcome.
    ///
    /// # Errors
    /// The queue is full (the loop is behind).
    fn submit(&self, command: C) -> Result<(u64, oneshot::Receiver<CommandOutcome>), ()> {
        let id = self.last_id.fetch_add(1, Ordering::Relaxed) + 1;
        let (reply, rx) = oneshot::channel();
        self.requests
            .push(Pending { id, command, reply })
            .map_err(|_| ())?;
        self.accepted.fetch_add(1, Ordering::Relaxed);
        Ok((id, rx))
    }

    /// (Server) The newest frame handed over since the last call, if any;
    /// the older ones go back to the pool. Give it back with
    /// [`recycle`](Self::recycle).
    fn newest(&self) -> Option<Box<F>> {
        let mut newest = None;
        while let Some(f) = self.full.pop() {
            if let Some(old) = newest.replace(f) {
                let _ = self.free.push(old);
            }
        }
        newest
    }

    fn recycle(&self, frame: Box<F>) {
        let _ = self.free.push(frame);
    }
}

/// Why a command was not done: [`Verdict::Refused`] (the state does not
/// allow it; nothing changed) or [`Verdict::Failed`], and why.
#[derive(Debug)]
pub struct Refused(pub Verdict, pub String);

/// A refusal by the robot's state.
pub fn refused(why: impl Into<String>) -> Refused {
    Refused(Verdict::Refused, why.into())
}

/// A failure on the way.
pub fn failed(why: impl Into<String>) -> Refused {
    Refused(Verdict::Failed, why.into())
}

/// One robot as the server sees it: its frames as JSON, its commands
/// parsed and checked.
pub trait RobotModel: Send + Sync + 'static {
    /// What the loop hands over.
    type Frame: Send + Sync + 'static;
    /// What the page can ask.
    type Command: Send + 'static;
    /// `/api/info`'s robot-specific part.
    fn info(&self) -> Value;
    /// A frame as `/api/state` shows it (the server adds the common
    /// fields).
    fn render(&self, frame: &Self::Frame) -> Value;
    /// A command from its JSON body, checked against this robot (axes,
    /// channels, ranges).
    ///
    /// # Errors
    /// What is wrong with it, in a sentence.
    fn parse(&self, body: &[u8]) -> Result<Self::Command, String>;
    /// A command's short name for outcomes.
    fn describe(command: &Self::Command) -> String;
}

/// A robot running in its own thread, with its model.
pub struct Hosted<M: RobotModel> {
    model: M,
    exchange: Arc<Exchange<M::Frame, M::Command>>,
    thread: Mutex<Option<JoinHandle<LoopExit>>>,
    /// The newest frame, rendered (server side).
    latest: Mutex<Value>,
    last_command: Mutex<Option<CommandOutcome>>,
    kind: RobotKind,
    port_name: String,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl<M: RobotModel> Hosted<M> {
    /// The robot of `model` whose loop runs in `thread`, sharing
    /// `exchange`.
    pub fn new(
        kind: RobotKind,
        port_name: String,
        model: M,
        exchange: Arc<Exchange<M::Frame, M::Command>>,
        thread: JoinHandle<LoopExit>,
    ) -> Hosted<M> {
        Hosted {
            model,
            exchange,
            thread: Mutex::new(Some(thread)),
            latest: Mutex::new(Value::Null),
            last_command: Mutex::new(None),
            kind,
            port_name,
        }
    }
}

/// A running robot other than the dVRK, as the console drives it.
pub trait RobotView: Send + Sync + 'static {
    /// `GET /api/info`.
    fn info(&self) -> Value;
    /// `GET /api/state`: the newest frame.
    fn state(&self) -> Value;
    /// Check and queue a command.
    ///
    /// # Errors
    /// 400 (malformed, unknown, out of range) or 503 (the loop has ended
    /// or is behind), with why.
    fn submit(
        &self,
        body: &[u8],
    ) -> Result<(u64, String, oneshot::Receiver<CommandOutcome>), (StatusCode, String)>;
    /// Record an outcome as the last command's.
    fn record(&self, outcome: &CommandOutcome);
    /// Commands accepted so far.
    fn accepted(&self) -> u64;
    /// How the loop ended, once it has.
    fn exit(&self) -> Option<LoopExit>;
    /// Told when the loop ends.
    fn ended(&self) -> &Notify;
    /// Stop the loop (it powers the robot down) and say how it ended.
    fn stop(&self) -> LoopExit;
}

impl<M: RobotModel> RobotView for Hosted<M> {
    fn info(&self) -> Value {
        let mut v = self.model.info();
        if let Value::Object(map) = &mut v {
            map.insert("robot".into(), json!(self.kind.to_string()));
            map.insert("port".into(), json!(self.port_name));
            map.insert("command_wait_s".into(), json!(COMMAND_WAIT.as_secs_f64()));
        }
        v
    }

    fn state(&self) -> Value {
        let ex = &self.exchange;
        while let Some(o) = ex.late.pop() {
            self.record(&o);
        }
        let mut latest = lock(&self.latest);
        if let Some(frame) = ex.newest() {
            *latest = self.model.render(&frame);
            ex.recycle(frame);
        }
        let mut out = latest.clone();
        drop(latest);
        if let Value::Object(map) = &mut out {
            map.insert("type".into(), json!("state"));
            map.insert("robot".into(), json!(self.kind.to_string()));
            map.insert(
                "skipped_frames".into(),
                json!(ex.skipped.load(Ordering::Relaxed)),
            );
            map.insert("last_command".into(), json!(*lock(&self.last_command)));
            map.insert(
                "loop_exit".into(),
                json!(ex.exit.get().map(ToString::to_string)),
            );
        }
        out
    }

    fn submit(
        &self,
        body: &[u8],
    ) -> Result<(u64, String, oneshot::Receiver<CommandOutcome>), (StatusCode, String)> {
        let command = self
            .model
            .parse(body)
            .map_err(|e| (StatusCode::BAD_REQUEST, e))?;
        if let Some(exit) = self.exchange.exit.get() {
            return Err((
                StatusCode::SERVICE_UNAVAILABLE,
                format!("the robot loop has ended: {exit}"),
            ));
        }
        let what = M::describe(&command);
        let (id, rx) = self.exchange.submit(command).map_err(|()| {
            (
                StatusCode::SERVICE_UNAVAILABLE,
                "the command queue is full: the robot loop is behind".to_string(),
            )
        })?;
        Ok((id, what, rx))
    }

    fn record(&self, outcome: &CommandOutcome) {
        *lock(&self.last_command) = Some(outcome.clone());
    }

    fn accepted(&self) -> u64 {
        self.exchange.accepted.load(Ordering::Relaxed)
    }

    fn exit(&self) -> Option<LoopExit> {
        self.exchange.exit.get().cloned()
    }

    fn ended(&self) -> &Notify {
        &self.exchange.ended
    }

    fn stop(&self) -> LoopExit {
        self.exchange.stop.store(true, Ordering::Relaxed);
        let thread = lock(&self.thread).take();
        match thread.map(JoinHandle::join) {
            Some(Ok(exit)) => exit,
            Some(Err(p)) => LoopExit {
                power_down: None,
                panic: Some(panic_text(p.as_ref()).to_string()),
                stopped_by: None,
            },
            None => self.exit().unwrap_or(LoopExit {
                power_down: None,
                panic: None,
                stopped_by: None,
            }),
        }
    }
}

/// The console of a robot other than the dVRK: its security and its
/// robot.
pub struct RobotConsole {
    gate: Gate,
    view: Arc<dyn RobotView>,
}

impl RobotConsole {
    /// A console for `view` behind `gate`.
    pub fn new(gate: Gate, view: Arc<dyn RobotView>) -> RobotConsole {
        RobotConsole { gate, view }
    }
}

async fn index(State(c): State<Arc<RobotConsole>>, uri: Uri) -> Response {
    c.gate.index(&uri)
}

async fn info(State(c): State<Arc<RobotConsole>>, headers: HeaderMap, uri: Uri) -> Response {
    if let Err(e) = c.gate.token_ok(&headers, &uri) {
        return refusal(e);
    }
    axum::Json(c.view.info()).into_response()
}

async fn state(State(c): State<Arc<RobotConsole>>, headers: HeaderMap, uri: Uri) -> Response {
    if let Err(e) = c.gate.token_ok(&headers, &uri) {
        return refusal(e);
    }
    axum::Json(c.view.state()).into_response()
}

async fn command(
    State(c): State<Arc<RobotConsole>>,
    ConnectInfo(peer): ConnectInfo<Peer>,
    headers: HeaderMap,
    uri: Uri,
    body: axum::body::Bytes,
) -> Response {
    if let Err(e) = c.gate.may_change(&headers, &uri, peer.local) {
        return refusal(e);
    }
    let (id, what, rx) = match c.view.submit(&body) {
        Ok(queued) => queued,
        Err((status, why)) => {
            let result = if status == StatusCode::BAD_REQUEST {
                "malformed"
            } else {
                "unavailable"
            };
            return answer(status, result, &why);
        }
    };
    match tokio::time::timeout(COMMAND_WAIT, rx).await {
        Ok(Ok(outcome)) => {
            c.view.record(&outcome);
            outcome_response(&outcome)
        }
        Ok(Err(_)) => answer(
            StatusCode::SERVICE_UNAVAILABLE,
            "unavailable",
            "the robot loop ended before the command ran",
        ),
        Err(_) => (
            StatusCode::ACCEPTED,
            axum::Json(json!({
                "id": id,
                "command": what,
                "result": "running",
                "detail": format!(
                    "still running after {} s: the state's last_command shows its outcome once there",
                    COMMAND_WAIT.as_secs()
                ),
            })),
        )
            .into_response(),
    }
}

/// The router of a robot console. Serve it with
/// `into_make_service_with_connect_info::<Peer>()`.
pub fn router(console: Arc<RobotConsole>) -> Router {
    with_assets(Router::new())
        .route("/", get(index))
        .route("/api/info", get(info))
        .route("/api/state", get(state))
        .route("/api/command", post(command))
        .with_state(console)
}

/// Parse a JSON command body into `C` (an internally tagged enum on
/// `action`), with serde's reason on failure.
///
/// # Errors
/// Not JSON, no or an unknown `action`, a missing or mistyped field.
pub fn parse_json<C: serde::de::DeserializeOwned>(body: &[u8]) -> Result<C, String> {
    serde_json::from_slice(body).map_err(|e| format!("bad command: {e}"))
}

/// Keep virtual time in step with the wall clock: sleep while the robot's
/// clock (`robot_s` since the start) is ahead of the wall's, at most
/// `cap` at a time.
pub fn pace(robot_s: f64, wall: std::time::Instant, cap: std::time::Duration) {
    let ahead = robot_s - wall.elapsed().as_secs_f64();
    if ahead > 0.0 {
        std::thread::sleep(std::time::Duration::from_secs_f64(ahead).min(cap));
    }
}

/// A panic's message.
fn panic_text(payload: &(dyn std::any::Any + Send)) -> &str {
    payload
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("a panic without a message")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames go round the pool: the server gets the newest, the older
    /// ones and the one it read go back; a loop with no free frame takes
    /// the oldest waiting one back (counted), so the newest still arrives.
    #[test]
    fn frames_go_round_the_pool_and_the_newest_wins() {
        let ex: Exchange<u64, ()> = Exchange::new(|| 0);
        for k in 1..=3 {
            ex.publish(|f| *f = k);
        }
        let newest = ex.newest().unwrap();
        assert_eq!(*newest, 3);
        assert!(ex.newest().is_none());
        ex.recycle(newest);
        for k in 0..POOL as u64 + 2 {
            ex.publish(|f| *f = 10 + k);
        }
        assert_eq!(ex.skipped.load(Ordering::Relaxed), 2);
        assert_eq!(*ex.newest().unwrap(), 10 + POOL as u64 + 1);
    }

    /// A command's outcome reaches its waiter with the command's id; one
    /// whose waiter gave up is kept for the state; whatever still waits
    /// when the loop ends is refused with why.
    #[test]
    fn outcomes_reach_their_waiters_or_the_state() {
        let ex: Exchange<u8, &'static str> = Exchange::new(|| 0);
        let (id, mut rx) = ex.submit("first").unwrap();
        let p = ex.next_request().unwrap();
        assert_eq!((p.id, p.command), (id, "first"));
        ex.answer(p, "first".into(), Ok("done".into()));
        let o = rx.try_recv().unwrap();
        assert_eq!(
            (o.id, o.result, o.detail.as_str()),
            (id, Verdict::Ok, "done")
        );
        let (_, rx) = ex.submit("abandoned").unwrap();
        drop(rx);
        let p = ex.next_request().unwrap();
        ex.answer(p, "abandoned".into(), Err(failed("a time-out")));
        let late = ex.late.pop().unwrap();
        assert_eq!(
            (late.result, late.detail.as_str()),
            (Verdict::Failed, "a time-out")
        );
        let (_, mut rx) = ex.submit("queued").unwrap();
        let exit = LoopExit {
            power_down: Some(firelink_host::PowerDown::default()),
            panic: None,
            stopped_by: None,
        };
        ex.finish(exit, |c| (*c).to_string());
        let o = rx.try_recv().unwrap();
        assert_eq!(o.result, Verdict::Refused);
        assert!(
            o.detail.starts_with("not run: the robot loop has ended"),
            "{}",
            o.detail
        );
        assert_eq!(ex.accepted.load(Ordering::Relaxed), 3);
    }
}
