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
//! - [`firelink_testbed::dvrk::service`]: one thread owns the robot and runs its servo cycles;
//!   it hands frames to the server through lock-free queues of preallocated
//!   frames and takes commands the same way;
//! - [`server`]: axum on tokio; drains the frames every 20 ms, keeps the
//!   last 30 s for CSV (at most 6 kHz of them: `server::CSV_MAX_RATE_HZ`),
//!   streams to browsers over a WebSocket, answers each command with its
//!   outcome, and checks the per-run token (header or cookie, never the
//!   URL) on everything that reveals or changes the robot and the `Origin`
//!   of everything that changes it.
//!
//! Losing the browser changes nothing: the loop goes on, and the boards'
//! watchdogs stay armed. The loop ending (a signal, a panic) ends the
//! server; [`Running::stop`] says what the power-down found.
//!
//! `--robot snake` and `--robot mahru` run seed 001's Snake system and seed
//! 002's MAHRU humanoid instead, each with its own view in the same page,
//! behind the same checks ([`robots`]).

pub mod robots;
pub mod server;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;

use firelink_control::ServoPeriod;
use firelink_control::config::{IoConfig, presets};
use firelink_testbed::dvrk::service::Service;
use firelink_testbed::loop_outcome::LoopExit;
use firelink_testbed::port_spec::PortSpec;

pub use robots::RobotKind;
use robots::RobotView;

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
    /// Which robot (the dVRK by default).
    pub robot: RobotKind,
    /// Where the boards are (`sim`, `emulate` or `udp:HOST[:PORT]`).
    pub port: PortSpec,
    /// The robot configuration (default: seed 000's dVRK, seed 001's Snake
    /// system or seed 002's MAHRU, by `robot`).
    pub config: Option<PathBuf>,
    /// The servo period (MAHRU: its control period, within its
    /// configuration's bounds too).
    pub period: ServoPeriod,
    /// Board watchdog.
    pub watchdog: firelink_host::WatchdogSetting,
    /// The dVRK's port's read time-out (`udp:`, `emulate`, `fw`): the scan
    /// waits that long for each absent node, a servo cycle that long for
    /// an answer before the board counts as missed (a fault).
    /// [`firelink_testbed::rig::UDP_TIMEOUT`] by default.
    pub timeout: std::time::Duration,
    /// Address to listen on.
    pub listen: SocketAddr,
    /// Origins accepted besides the console's own (from
    /// [`server::parse_origin`]): a name the machine is reached by, a
    /// proxy.
    pub allow_origins: Vec<String>,
}

/// A running console.
pub struct Running {
    /// The address it listens on.
    pub addr: SocketAddr,
    /// The URL with the token, to open in a browser (once: it sets the
    /// console's cookie and redirects to `/`).
    pub url: String,
    token: String,
    allow_origins: Vec<String>,
    backend: Backend,
}

/// The robot behind the console.
enum Backend {
    /// The dVRK's service.
    Dvrk(Service),
    /// The Snake system or MAHRU.
    Other(Arc<dyn RobotView>),
}

impl Running {
    /// Commands the server has accepted so far (refused requests never
    /// reach the robot).
    pub fn commands_accepted(&self) -> u64 {
        match &self.backend {
            Backend::Dvrk(service) => service.shared.queued.load(Ordering::Relaxed),
            Backend::Other(view) => view.accepted(),
        }
    }

    /// This run's token (for the `X-Firelink-Token` header).
    pub fn token(&self) -> &str {
        &self.token
    }

    /// How the robot loop ended, once it has (before [`stop`](Self::stop):
    /// a panic, or the process's stop request).
    pub fn loop_exit(&self) -> Option<LoopExit> {
        match &self.backend {
            Backend::Dvrk(service) => service.shared.exit.get().cloned(),
            Backend::Other(view) => view.exit(),
        }
    }

    /// Stop the robot loop (it powers the robot down first) and the
    /// emulator; returns what the power-down found (and the loop's panic,
    /// if it panicked).
    pub fn stop(self) -> LoopExit {
        match self.backend {
            Backend::Dvrk(service) => service.stop(),
            Backend::Other(view) => view.stop(),
        }
    }
}

fn token() -> Result<String, WebError> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes)
        .map_err(|e| WebError::Options(format!("no randomness for the token: {e}")))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// A configuration file with its warnings printed, or `None` without one.
fn load_config(options: &WebOptions) -> Result<Option<IoConfig>, WebError> {
    let Some(path) = &options.config else {
        return Ok(None);
    };
    let loaded =
        IoConfig::load_with_warnings(path).map_err(|e| WebError::Options(e.to_string()))?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    Ok(Some(loaded.config))
}

fn start_dvrk(options: &WebOptions) -> Result<Service, WebError> {
    let config = load_config(options)?.unwrap_or_else(presets::dvrk_seed000);
    Ok(Service::start_with_timeout(
        &options.port,
        config,
        options.period,
        options.watchdog,
        options.timeout,
    )?)
}

/// The robots other than the dVRK run on the simulated bus only.
fn sim_only(options: &WebOptions) -> Result<(), WebError> {
    match options.port {
        PortSpec::Sim(None) => Ok(()),
        _ => Err(WebError::Options(format!(
            "--robot {}: --port sim only (the robot's own nodes on the simulated bus; \
             not {})",
            options.robot, options.port
        ))),
    }
}

fn start_snake(
    options: &WebOptions,
) -> Result<robots::Hosted<robots::snake::SnakeModel>, WebError> {
    sim_only(options)?;
    let config = load_config(options)?.unwrap_or_else(presets::snake_seed001);
    robots::snake::start(config, options.period, options.watchdog)
}

fn start_mahru(
    options: &WebOptions,
) -> Result<robots::Hosted<robots::mahru::MahruModel>, WebError> {
    sim_only(options)?;
    let config = match &options.config {
        Some(path) => firelink_testbed::mahru::MahruConfig::load(path)?,
        None => firelink_testbed::mahru::MahruConfig::seed002(),
    };
    robots::mahru::start(config, options.period)
}

/// Start the robot service and bind the server; run the server with
/// [`serve`]. Prints nothing.
///
/// # Errors
/// Bad options, a failed scan, an address already in use.
pub async fn start(options: &WebOptions) -> Result<(Running, tokio::net::TcpListener), WebError> {
    let backend = match options.robot {
        RobotKind::Dvrk => Backend::Dvrk(start_dvrk(options)?),
        RobotKind::Snake => Backend::Other(Arc::new(start_snake(options)?)),
        RobotKind::Mahru => Backend::Other(Arc::new(start_mahru(options)?)),
    };
    let listener = tokio::net::TcpListener::bind(options.listen).await?;
    let addr = listener.local_addr()?;
    let token = token()?;
    // Listening on every address: the URL names this machine's loopback
    // one (a browser elsewhere uses an address of this machine instead).
    let shown = match addr.ip() {
        std::net::IpAddr::V4(ip) if ip.is_unspecified() => {
            SocketAddr::from((std::net::Ipv4Addr::LOCALHOST, addr.port()))
        }
        std::net::IpAddr::V6(ip) if ip.is_unspecified() => {
            SocketAddr::from((std::net::Ipv6Addr::LOCALHOST, addr.port()))
        }
        _ => addr,
    };
    let url = format!("http://{shown}/?token={token}");
    Ok((
        Running {
            addr,
            url,
            token,
            allow_origins: options.allow_origins.clone(),
            backend,
        },
        listener,
    ))
}

/// Serve `running`'s console on `listener` until `shutdown` completes or
/// the robot loop ends (see [`Running::loop_exit`]).
///
/// # Errors
/// The server failed.
pub async fn serve(
    running: &Running,
    listener: tokio::net::TcpListener,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<(), WebError> {
    let view = match &running.backend {
        Backend::Dvrk(service) => return serve_dvrk(running, service, listener, shutdown).await,
        Backend::Other(view) => Arc::clone(view),
    };
    let gate = server::Gate::new(
        running.token.clone(),
        running.addr,
        running.allow_origins.clone(),
    );
    let app = robots::router(Arc::new(robots::RobotConsole::new(gate, Arc::clone(&view))));
    let stop = async move {
        tokio::select! {
            () = shutdown => {}
            () = view.ended().notified() => {}
        }
    };
    axum::serve(
        listener,
        app.into_make_service_with_connect_info::<server::Peer>(),
    )
    .with_graceful_shutdown(stop)
    .await
    .map_err(WebError::Io)
}

/// [`serve`] for the dVRK.
async fn serve_dvrk(
    running: &Running,
    service: &Service,
    listener: tokio::net::TcpListener,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> Result<(), WebError> {
    let console = Arc::new(server::Console::new(
        Arc::clone(&service.shared),
        running.token.clone(),
        running.addr,
        running.allow_origins.clone(),
        service.faults.clone(),
    ));
    let drain = tokio::spawn(server::drain_forever(Arc::clone(&console)));
    let ended = Arc::clone(&console);
    let app = server::router(console);
    let stop = async move {
        tokio::select! {
            () = shutdown => {}
            () = ended.ended.notified() => {}
        }
    };
    let r = axum::serve(
        listener,
        app.into_make_service_with_connect_info::<server::Peer>(),
    )
    .with_graceful_shutdown(stop)
    .await;
    drain.abort();
    r.map_err(WebError::Io)
}
