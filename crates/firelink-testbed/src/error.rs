//! What can go wrong assembling or running a testbed.

/// A testbed failure, with the layer that failed.
#[derive(Debug, thiserror::Error)]
pub enum TestbedError {
    /// The rig has no boards to emulate.
    #[error("no boards to emulate")]
    NoBoards,
    /// A fault or the bridge names a board ID the rig does not have.
    #[error("{role} {board}: no such board on the rig")]
    NoSuchBoard {
        /// What the board was to be (`muted board`, `bridge board`).
        role: &'static str,
        /// The board ID given.
        board: u8,
    },
    /// A port string that is not one.
    #[error(transparent)]
    PortSpec(#[from] crate::port_spec::PortSpecError),
    /// A well-formed port this program cannot use.
    #[error(transparent)]
    PortRefused(#[from] crate::port_spec::PortRefused),
    /// The host library failed (scan, I/O).
    #[error(transparent)]
    Host(#[from] firelink_host::HostError),
    /// The robot program failed (lifecycle, fault, time-out).
    #[error(transparent)]
    Runner(#[from] firelink_control::runner::RunnerError),
    /// A configuration is unusable.
    #[error("configuration: {0}")]
    Config(String),
    /// The emulator could not start (sockets, thread).
    #[error("emulator: {0}")]
    Emulator(String),
    /// Sockets.
    #[error("I/O: {0}")]
    Io(#[from] std::io::Error),
    /// A robot program failed (or was stopped) after it had started to
    /// power the robot; the robot was powered down before this was
    /// returned, and `power_down` says what the boards reported.
    #[error("{error}; then powered down: {power_down}")]
    PoweredDown {
        /// What ended the program.
        error: Box<TestbedError>,
        /// What the boards said after the power-down.
        power_down: firelink_host::PowerDown,
    },
}

impl TestbedError {
    /// What ended the program, under a [`TestbedError::PoweredDown`].
    pub fn cause(&self) -> &TestbedError {
        match self {
            TestbedError::PoweredDown { error, .. } => error.cause(),
            other => other,
        }
    }

    /// The stop request that ended the program, if a signal or the caller
    /// stopped it (not a failure).
    pub fn stopped_by(&self) -> Option<firelink_host::stop::StopReason> {
        match self {
            TestbedError::Runner(firelink_control::runner::RunnerError::Stopped(r)) => Some(*r),
            TestbedError::PoweredDown { error, .. } => error.stopped_by(),
            _ => None,
        }
    }
}
