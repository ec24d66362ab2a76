//! Opening a port from the strings users know: `udp:HOST[:PORT]`.

use clap::Args;

use firelink_host::Port;
use firelink_host::trace::PcapWriter;
use firelink_host::udp::UdpPort;

use crate::CliError;

/// The `--port` option shared by every command that talks to boards.
#[derive(Args, Debug, Clone)]
pub struct PortArgs {
    /// Where the boards are: `udp:HOST` (bridge board on UDP port 1394),
    /// `udp:HOST:PORT`, or `sim[:N[:7|8|seed]]` (N emulated QLA1 boards on
    /// an in-process simulated bus; default 8 at firmware Rev 8).
    #[arg(long, default_value = "udp:127.0.0.1")]
    pub port: String,
    /// Read time-out in milliseconds (1..=60000).
    #[arg(long = "timeout-ms", default_value_t = 20, value_parser = crate::args::timeout_ms)]
    pub timeout_ms: u64,
    /// Record every 1394 packet the host sends and receives to this pcap
    /// file (Wireshark opens it; the host library's replay tests play such
    /// files back).
    #[arg(long)]
    pub pcap: Option<std::path::PathBuf>,
}

/// Open the port named by `args`, recording its packets when asked.
pub fn open_port(args: &PortArgs) -> Result<Box<dyn Port>, CliError> {
    let mut port = open_unrecorded(args)?;
    if let Some(path) = &args.pcap {
        let file = std::io::BufWriter::new(std::fs::File::create(path)?);
        port.add_link_filter(Box::new(PcapWriter::new(file)?))?;
    }
    Ok(port)
}

fn open_unrecorded(args: &PortArgs) -> Result<Box<dyn Port>, CliError> {
    if let Some(rest) = args.port.strip_prefix("sim") {
        let mut parts = rest.split(':').filter(|p| !p.is_empty());
        let boards = match parts.next() {
            Some(n) => n
                .parse::<u8>()
                .ok()
                .filter(|n| (1..=16).contains(n))
                .ok_or_else(|| {
                    CliError::Conflict(format!("sim port: {n:?} is not 1..=16 boards"))
                })?,
            None => 8,
        };
        let profile = match parts.next() {
            Some(f) => crate::args::parse_profile(f).map_err(CliError::Conflict)?,
            None => firelink_board::config::Profile::Rev8,
        };
        let boards = firelink_testbed::rig::generic_boards(
            boards,
            firelink_board::config::Hardware::Qla1,
            profile,
            0,
        );
        return Ok(Box::new(firelink_testbed::rig::sim_port(boards, false)?.0));
    }
    if args.port.starts_with("udp") {
        let addr = UdpPort::parse_address(&args.port)?;
        let mut port = UdpPort::open(addr)?;
        port.set_timeout(std::time::Duration::from_millis(args.timeout_ms));
        return Ok(Box::new(port));
    }
    Err(CliError::Conflict(format!(
        "unknown port {:?}: expected sim[:N[:FIRMWARE]], udp:HOST or udp:HOST:PORT",
        args.port
    )))
}
