//! # firelink-web: the web console
//!
//! `firelink web` serves one page on 127.0.0.1 that shows the boards and
//! every axis live, draws strip charts of setpoint, position and current
//! per joint (uPlot, shipped in the binary: no network needed), and drives
//! the robot: lifecycle (configure, power, home, enable, disable), relay,
//! amplifiers, watchdog, fault injection, the bench's Fig. 11 on demand and
//! the last seconds as CSV.
//!
//! Two halves that never wait on each other:
//! - [`robot_loop`]: one thread owns the robot and runs its servo cycles;
//!   it hands frames to the server through lock-free queues of preallocated
//!   frames and takes commands the same way;
//! - [`server`]: axum on tokio; drains the frames every 20 ms, keeps the
//!   last seconds for CSV, streams to browsers over a WebSocket, and checks
//!   the per-run token and the `Origin` of everything that can change the
//!   robot.
//!
//! Losing the browser changes nothing: the loop goes on, and the boards'
//! watchdogs stay armed.

pub mod robot_loop;
pub mod server;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::Duration;

use firelink_board::config::Profile;
use firelink_control::config::{IoConfig, presets};
use firelink_control::runner::Pacing;
use firelink_host::udp::UdpPort;
use firelink_testbed::demo::{DemoFault, DemoPort, Injector};
use firelink_testbed::rig;

use robot_loop::{LoopOptions, Shared};

/// Why the console could not start.
#[derive(Debug, thiserror::Error)]
pub enum WebError {
    /// A bad option.
    #[error("{0}")]
    Options(String),
    /// The robot could not be set up.
    #[error(transparent)]
    Testbed(#[from] firelink_testbed::TestbedError),
    /// Sockets or threads.
    #[error("I/O: {0}")]
    Io(#[from] std::io::Error),
}

/// Options of `firelink web`.
#[derive(Debug, Clone)]
pub struct WebOptions {
    /// Where the boards are (sim, emulate or udp:HOST[:PORT]).
    pub port: DemoPort,
    /// The robot configuration (default: seed 000's dVRK).
    pub config: Option<PathBuf>,
    /// Control rate, Hz.
    pub rate_hz: f64,
    /// Board watchdog period.
    pub watchdog: Duration,
    /// Address to listen on.
    pub listen: SocketAddr,
}

/// A running console.
pub struct Running {
    /// The address it listens on.
    pub addr: SocketAddr,
    /// The URL with the token, to open in a browser.
    pub url: String,
    shared: Arc<Shared>,
    robot: Option<JoinHandle<()>>,
    emulator: Option<rig::Emulator>,
}

impl Running {
    /// Commands the server has accepted so far (refused requests never
    /// reach the robot).
    pub fn commands_accepted(&self) -> u64 {
        self.shared.queued.load(Ordering::Relaxed)
    }

    /// Stop the robot loop (it powers off first) and the emulator.
    pub fn stop(mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.robot.take() {
            let _ = t.join();
        }
        if let Some(e) = self.emulator.take() {
            let _ = e.stop();
        }
    }
}

fn token() -> Result<String, WebError> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes)
        .map_err(|e| WebError::Options(format!("no randomness for the token: {e}")))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

fn spawn<P: Injector + Send + 'static>(
    port: P,
    name: String,
    options: LoopOptions,
) -> Result<(Arc<Shared>, JoinHandle<()>), WebError> {
    let (robot, shared) = robot_loop::prepare(port, name, &options)?;
    let loop_shared = Arc::clone(&shared);
    let handle = std::thread::Builder::new()
        .name("firelink-robot".into())
        .spawn(move || robot_loop::run(robot, loop_shared, options))?;
    Ok((shared, handle))
}

/// Start the robot loop and bind the server; run the server with
/// [`serve`]. Prints nothing.
///
/// # Errors
/// Bad options, a failed scan, an address already in use.
pub async fn start(
    options: &WebOptions,
) -> Result<(Running, tokio::net::TcpListener, Vec<DemoFault>), WebError> {
    if !(options.rate_hz.is_finite() && options.rate_hz > 0.0 && options.rate_hz <= 20_000.0) {
        return Err(WebError::Options(format!(
            "rate {} Hz: must be 0 < rate <= 20000",
            options.rate_hz
        )));
    }
    let config: IoConfig = match &options.config {
        Some(path) => IoConfig::load(path).map_err(|e| WebError::Options(e.to_string()))?,
        None => presets::dvrk_seed000(),
    };
    let boards = config
        .boards()
        .iter()
        .map(|b| usize::from(b.board_id) + 1)
        .max()
        .unwrap_or(0);
    let loop_options = |pacing| LoopOptions {
        config: config.clone(),
        rate_hz: options.rate_hz,
        watchdog: options.watchdog,
        pacing,
    };
    let all = DemoFault::ALL
        .iter()
        .copied()
        .filter(|f| *f != DemoFault::None)
        .collect();
    let remote = vec![DemoFault::StopHost, DemoFault::FollowingError];
    let (shared, robot, emulator, faults) = match &options.port {
        DemoPort::Sim | DemoPort::Loopback => {
            let (port, _) =
                rig::sim_port(rig::board_configs(&config, Profile::Rev8, boards), false)?;
            let (s, h) = spawn(port, "sim".into(), loop_options(Pacing::Virtual))?;
            (s, h, None, all)
        }
        DemoPort::Emulate => {
            let emu = rig::Emulator::start(rig::board_configs(&config, Profile::Rev8, boards))?;
            let name = format!("udp:{} (in-process emulator)", emu.addr);
            let mut port = emu.port()?;
            port.set_timeout(Duration::from_millis(20));
            let (s, h) = spawn(port, name, loop_options(Pacing::WallClock))?;
            (s, h, Some(emu), remote)
        }
        DemoPort::Udp(addr) => {
            let mut port = UdpPort::open(*addr).map_err(firelink_testbed::TestbedError::from)?;
            port.set_timeout(Duration::from_millis(20));
            let (s, h) = spawn(port, format!("udp:{addr}"), loop_options(Pacing::WallClock))?;
            (s, h, None, remote)
        }
    };
    let listener = tokio::net::TcpListener::bind(options.listen).await?;
    let addr = listener.local_addr()?;
    let token = token()?;
    let url = format!("http://{addr}/?token={token}");
    let running = Running {
        addr,
        url,
        shared: Arc::clone(&shared),
        robot: Some(robot),
        emulator,
    };
    Ok((running, listener, faults))
}

/// Serve `running`'s console on `listener` until `shutdown` completes.
///
/// # Errors
/// The server failed.
pub async fn serve(
    running: &Running,
    listener: tokio::net::TcpListener,
    faults: Vec<DemoFault>,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<(), WebError> {
    let token = running
        .url
        .split("token=")
        .nth(1)
        .unwrap_or_default()
        .to_string();
    let console = Arc::new(server::Console::new(
        Arc::clone(&running.shared),
        token,
        running.addr,
        faults,
    ));
    let drain = tokio::spawn(server::drain_forever(Arc::clone(&console)));
    let app = server::router(console);
    let r = axum::serve(listener, app)
        .with_graceful_shutdown(shutdown)
        .await;
    drain.abort();
    r.map_err(WebError::Io)
}
