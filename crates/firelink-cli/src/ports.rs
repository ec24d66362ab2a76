//! `--port` on the command line: the one grammar of port strings
//! ([`PortSpec`]: `sim[:N[:FW]]`, `emulate`, `udp:HOST[:PORT]`, `fw[:N]`),
//! parsed by clap for every command that takes a port, and opening it for
//! the bus tools (scan, info, read, write, monitor).

use clap::Args;

use firelink_host::Port;
use firelink_host::trace::PcapWriter;
use firelink_host::udp::WaitMode;
use firelink_testbed::port_spec::PortKind;
use firelink_testbed::ports::{PortOptions, open_bus_port};

pub use firelink_testbed::port_spec::{PortSpec, parse_port};

use crate::error::CliError;

/// `--port` of a command that takes only some kinds of port: parsed, then
/// refused unless of one of `accepted` (naming `command` and the port).
///
/// # Errors
/// As [`parse_port`]; [`CliError::PortRefused`].
pub fn parse_port_for(
    text: &str,
    command: &str,
    accepted: &[PortKind],
) -> Result<PortSpec, CliError> {
    let spec = parse_port(text)?;
    spec.refuse_unless(command, accepted)?;
    Ok(spec)
}

/// The `--port` option shared by every command that talks to boards.
#[derive(Args, Debug, Clone)]
pub struct PortArgs {
    /// Where the boards are: `udp:HOST` (bridge board on UDP port 1394),
    /// `udp:HOST:PORT`, `sim` (seed 000's dVRK: 8 emulated QLA1 boards on
    /// an in-process simulated bus, firmware Rev 8), `sim:N[:7|8|9|seed]`
    /// (boards 0..N of it at that firmware), or `fw` / `fw:N` (FireWire
    /// card 0 / N through /dev/fw*).
    #[arg(long, default_value = "udp:127.0.0.1", value_parser = parse_port)]
    pub port: PortSpec,
    /// FireWire (`fw`): leave the PC's cycle-start packets on (by default
    /// the card's STATE_CLEAR is written at open to stop them, as the
    /// dVRK's host does).
    #[arg(long = "keep-cycle-master")]
    pub keep_cycle_master: bool,
    /// Read time-out in milliseconds (1..=60000).
    #[arg(long = "timeout-ms", default_value_t = 20, value_parser = crate::args::timeout_ms)]
    pub timeout_ms: u64,
    /// How a UDP port's reads wait for the answer: `block` (sleep in the
    /// kernel, low CPU) or `spin` (poll the socket, low latency, one core
    /// busy while waiting).
    #[arg(long = "udp-wait", value_enum, default_value_t = WaitMode::Blocking)]
    pub udp_wait: WaitMode,
    /// Record every 1394 packet the host sends and receives to this pcap
    /// file (Wireshark opens it; the host library's replay tests play such
    /// files back).
    #[arg(long)]
    pub pcap: Option<std::path::PathBuf>,
}

/// Open the port named by `args` for `command` (`firelink scan`), recording
/// its packets when asked.
pub fn open_port(args: &PortArgs, command: &str) -> Result<Box<dyn Port>, CliError> {
    let options = PortOptions {
        timeout: std::time::Duration::from_millis(args.timeout_ms),
        udp_wait: args.udp_wait,
        stop_cycle_master: !args.keep_cycle_master,
        ..PortOptions::default()
    };
    let mut port: Box<dyn Port> = open_bus_port(command, &args.port, &options)?;
    if let Some(path) = &args.pcap {
        let file = std::io::BufWriter::new(std::fs::File::create(path)?);
        port.add_link_filter(Box::new(PcapWriter::new(file)?))?;
    }
    Ok(port)
}
