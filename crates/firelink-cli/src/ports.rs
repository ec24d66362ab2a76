//! Opening a port from the strings users know: `udp:HOST[:PORT]`,
//! `sim[:N[:FIRMWARE]]` or `fw[:N]` (FireWire card N), checked by clap
//! ([`PortSpec`]).

use std::net::SocketAddr;

use clap::{Args, ValueEnum};

use firelink_board::config::{Hardware, Profile};
use firelink_host::Port;
use firelink_host::firewire::{FirewirePort, FwOptions};
use firelink_host::trace::PcapWriter;
use firelink_host::udp::UdpPort;

use crate::CliError;
use crate::args::{FirmwareArg, UdpWaitArg};

/// What `--port` names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PortSpec {
    /// `sim[:N[:FIRMWARE]]`: N emulated QLA1 boards on an in-process
    /// simulated bus.
    Sim {
        /// Boards, 1..=16.
        boards: u8,
        /// Their firmware.
        firmware: Profile,
    },
    /// `udp:HOST[:PORT]`: a bridge board (or `firelink emulate`).
    Udp(SocketAddr),
    /// `fw` or `fw:N`: FireWire card N (0 by default) through Linux
    /// /dev/fw* (or the twin of `firelink fw-run`).
    Fw(u32),
}

const EXPECTED: &str = "sim[:N[:7|8|seed]] (N 1..=16), udp:HOST, udp:HOST:PORT, fw or fw:N";

/// `--port` (clap).
fn parse_port(text: &str) -> Result<PortSpec, CliError> {
    let bad = || CliError::Port {
        port: text.to_string(),
        expected: EXPECTED,
    };
    if let Some(rest) = text.strip_prefix("sim") {
        let mut parts = rest.split(':').filter(|p| !p.is_empty());
        let boards = match parts.next() {
            Some(n) => n
                .parse::<u8>()
                .ok()
                .filter(|n| (1..=16).contains(n))
                .ok_or_else(bad)?,
            None => 8,
        };
        let firmware = match parts.next() {
            Some(f) => FirmwareArg::from_str(f, true).map_err(|_| bad())?.into(),
            None => Profile::Rev8,
        };
        if parts.next().is_some() {
            return Err(bad());
        }
        return Ok(PortSpec::Sim { boards, firmware });
    }
    if text.starts_with("udp") {
        return Ok(PortSpec::Udp(udp_address(text)?));
    }
    if text == "fw" {
        return Ok(PortSpec::Fw(0));
    }
    if let Some(card) = text.strip_prefix("fw:") {
        return card.parse().map(PortSpec::Fw).map_err(|_| bad());
    }
    Err(bad())
}

/// `udp:HOST` or `udp:HOST:PORT` as a socket address: HOST an IP address
/// or a name (resolved, IPv4 preferred: `udp:localhost` is 127.0.0.1).
///
/// # Errors
/// [`CliError::PortAddress`] naming the text and what is wrong with it.
pub fn udp_address(text: &str) -> Result<SocketAddr, CliError> {
    UdpPort::parse_address(text).map_err(|error| CliError::PortAddress {
        port: text.to_string(),
        error,
    })
}

/// The `--port` option shared by every command that talks to boards.
#[derive(Args, Debug, Clone)]
pub struct PortArgs {
    /// Where the boards are: `udp:HOST` (bridge board on UDP port 1394),
    /// `udp:HOST:PORT`, `sim[:N[:7|8|seed]]` (N emulated QLA1 boards on
    /// an in-process simulated bus; default 8 at firmware Rev 8), or
    /// `fw` / `fw:N` (FireWire card 0 / N through /dev/fw*).
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
    #[arg(long = "udp-wait", value_enum, default_value_t = UdpWaitArg::Block)]
    pub udp_wait: UdpWaitArg,
    /// Record every 1394 packet the host sends and receives to this pcap
    /// file (Wireshark opens it; the host library's replay tests play such
    /// files back).
    #[arg(long)]
    pub pcap: Option<std::path::PathBuf>,
}

/// Open the port named by `args`, recording its packets when asked.
pub fn open_port(args: &PortArgs) -> Result<Box<dyn Port>, CliError> {
    let mut port: Box<dyn Port> = match args.port {
        PortSpec::Sim { boards, firmware } => {
            let boards = firelink_testbed::rig::generic_boards(boards, Hardware::Qla1, firmware, 0);
            Box::new(firelink_testbed::rig::sim_port(boards, false)?.0)
        }
        PortSpec::Udp(addr) => {
            let mut port = UdpPort::open(addr)?;
            port.set_timeout(std::time::Duration::from_millis(args.timeout_ms));
            port.set_wait_mode(args.udp_wait.into());
            Box::new(port)
        }
        PortSpec::Fw(card) => Box::new(FirewirePort::open(FwOptions {
            card,
            stop_cycle_master: !args.keep_cycle_master,
            timeout: std::time::Duration::from_millis(args.timeout_ms),
        })?),
    };
    if let Some(path) = &args.pcap {
        let file = std::io::BufWriter::new(std::fs::File::create(path)?);
        port.add_link_filter(Box::new(PcapWriter::new(file)?))?;
    }
    Ok(port)
}
