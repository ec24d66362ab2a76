//! Opening a port from the strings users know: `udp:HOST[:PORT]`.

use clap::Args;

use firelink_host::Port;
use firelink_host::udp::UdpPort;

use crate::CliError;

/// The `--port` option shared by every command that talks to boards.
#[derive(Args, Debug, Clone)]
pub struct PortArgs {
    /// Where the boards are: `udp:HOST` (bridge board on UDP port 1394) or
    /// `udp:HOST:PORT`.
    #[arg(long, default_value = "udp:127.0.0.1")]
    pub port: String,
    /// Read time-out in milliseconds.
    #[arg(long = "timeout-ms", default_value_t = 20)]
    pub timeout_ms: u64,
}

/// Open the port named by `args`.
pub fn open_port(args: &PortArgs) -> Result<Box<dyn Port>, CliError> {
    if args.port.starts_with("udp") {
        let addr = UdpPort::parse_address(&args.port)?;
        let mut port = UdpPort::open(addr)?;
        port.set_timeout(std::time::Duration::from_millis(args.timeout_ms));
        return Ok(Box::new(port));
    }
    Err(CliError::Conflict(format!(
        "unknown port {:?}: expected udp:HOST or udp:HOST:PORT",
        args.port
    )))
}
