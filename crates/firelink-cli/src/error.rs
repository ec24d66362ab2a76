//! The command line's one error type: every failure a subcommand reports
//! as one line on stderr, and the exit status each maps to
//! ([`EXIT_STATUS`]).

use firelink_host::qla::register_address::AddressError;
use firelink_testbed::emulation::ServeError;

use firelink_host::hex;

/// Everything the command line reports as a one-line error.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// Bad hex text.
    #[error(transparent)]
    Hex(#[from] hex::HexError),
    /// The wire layer rejected the bytes or fields.
    #[error(transparent)]
    Wire(#[from] firelink_wire::Error),
    /// Bad JSON.
    #[error("invalid JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// A required field is absent.
    #[error("missing field {0}")]
    Missing(&'static str),
    /// A field is too large.
    #[error("{name} = {value:#x} is out of range (maximum {max:#x})")]
    Range {
        /// Field.
        name: &'static str,
        /// Value given.
        value: u64,
        /// Largest allowed.
        max: u64,
    },
    /// A robot configuration file is invalid (every problem, with its path).
    #[error(transparent)]
    Config(#[from] firelink_control::config::ConfigErrors),
    /// A `--port` that is not a port string.
    #[error(transparent)]
    PortSpec(#[from] firelink_testbed::port_spec::PortSpecError),
    /// A `--port` this command cannot use.
    #[error(transparent)]
    PortRefused(#[from] firelink_testbed::port_spec::PortRefused),
    /// A register address outside the board's map, or a register name
    /// that is not on the board.
    #[error(transparent)]
    Address(#[from] AddressError),
    /// A register read or write was refused (its address), failed (the
    /// port) or, over the bridge, could not be confirmed by reading back.
    #[error(transparent)]
    Register(#[from] firelink_host::qla::board_access::RegisterError),
    /// The emulated boards cannot be served as asked: an option they
    /// cannot honour, boards the Ethernet-only network cannot hold or that
    /// cannot be assembled, a socket that cannot be bound.
    #[error(transparent)]
    Serve(#[from] ServeError),
    /// A `snake-tool` command or session failed (a refused command names
    /// itself and what was wrong).
    #[error(transparent)]
    Tool(#[from] firelink_testbed::snake::tool::ToolError),
    /// The benchmark's options cannot be run as given (the option is
    /// named first: its board counts cannot be measured or modelled, or
    /// the level of detail has no simulated bus to apply to).
    #[error("{0}")]
    BenchOptions(String),
    /// The preloaded /dev/fw* twin library (`fw-run`) is not built.
    #[error(transparent)]
    TwinLibraryMissing(#[from] firelink_testbed::fw_run::TwinLibraryMissing),
    /// A companion binary (`firelink-web`, `firelink-ros2`) is not built.
    #[error("{name} is not built: run `cargo build --release -p {name}` (looked for {path})")]
    CompanionMissing {
        /// Its name.
        name: String,
        /// Where it was looked for.
        path: String,
    },
    /// The host library failed.
    #[error(transparent)]
    Host(#[from] firelink_host::HostError),
    /// A packet record could not be decoded or encoded.
    #[error(transparent)]
    Packet(#[from] firelink_host::packet_json::PacketJsonError),
    /// A run finished and its verdict is "failed" (the report says why).
    #[error("{0}")]
    Failed(String),
    /// `firelink budget`: the cycle does not fit its period (the report
    /// says by how much).
    #[error("{0}")]
    DoesNotFit(String),
    /// Assembling or running an emulated robot failed.
    #[error(transparent)]
    Testbed(#[from] firelink_testbed::TestbedError),
    /// Drawing a figure failed.
    #[error(transparent)]
    Plot(#[from] firelink_plot::PlotError),
    /// Writing output failed.
    #[error("output: {0}")]
    Io(#[from] std::io::Error),
}

impl CliError {
    /// The stop request (a signal) that ended a robot program, if that is
    /// what this error is.
    fn stopped_by(&self) -> Option<firelink_host::stop::StopReason> {
        match self {
            CliError::Testbed(e) => e.stopped_by(),
            _ => None,
        }
    }

    /// The exit status for this error (see [`EXIT_STATUS`]): 128 + the
    /// signal's number when a signal stopped a robot program (powered
    /// down), 3 when the command ran to the end and its result failed its
    /// check, else 1.
    pub fn exit_code(&self) -> u8 {
        if let Some(reason) = self.stopped_by() {
            return u8::try_from(reason.exit_status()).unwrap_or(1);
        }
        match self {
            CliError::Failed(_) | CliError::DoesNotFit(_) => 3,
            _ => 1,
        }
    }
}

/// The exit statuses, as `firelink --help` shows them.
pub const EXIT_STATUS: &str = "Exit status: 0 done (and every check passed); 1 error (a file, \
a port or the boards could not be used); 2 usage (an option or value refused); 3 the run \
finished but failed its check (`demo`: a fault, errors or overruns; `budget`: the cycle does \
not fit its period); 128 + N stopped by signal N (SIGINT 130, SIGTERM 143, SIGHUP 129) \
with the robot powered down.";
