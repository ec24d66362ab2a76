//! What can go wrong assembling or running a testbed.

/// A testbed failure, with the layer that failed.
#[derive(Debug, thiserror::Error)]
pub enum TestbedError {
    /// The rig has no boards to emulate.
    #[error("no boards to emulate")]
    NoBoards,
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
}
