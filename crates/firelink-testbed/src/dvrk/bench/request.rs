//! What `firelink bench` asks for, as typed ([`BenchRequest`], clap's
//! `Args` behind the `clap` feature): the transports and wait modes as
//! lists, the board counts as text, a bridge as a port string;
//! [`BenchRequest::options`] makes the run's [`BenchOptions`].

use std::time::Duration;

use firelink_bus::Detail;
use firelink_host::qla::scan::Protocol;
use firelink_host::udp::WaitMode;

use super::{BenchOptions, BenchTransport, parse_board_counts};
use crate::emulated::Profile;
use crate::port_spec::{PortKind, PortSpec, parse_port};

/// `--port` of the benchmark: the port grammar, of which it takes
/// `udp:HOST` (port 1394) or `udp:HOST:PORT` (the bridge it measures:
/// `udp` and `udpfw` alike).
///
/// # Errors
/// Not a port string, or another kind of port (one line naming it).
pub fn bridge_address(text: &str) -> Result<PortSpec, String> {
    const COMMAND: &str = "firelink bench --port";
    let spec = parse_port(text).map_err(|e| e.to_string())?;
    spec.refuse_unless(COMMAND, &[PortKind::Udp])
        .map_err(|e| e.to_string())?;
    match spec {
        PortSpec::Udp(_) | PortSpec::UdpFw(_) => Ok(spec),
        other => Err(other.refused(COMMAND, "it takes udp".into()).to_string()),
    }
}

/// The benchmark's options as a command line gives them.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct BenchRequest {
    /// Transports (comma-separated; default `sim,udp`, with `--port` only
    /// `udp`).
    #[cfg_attr(feature = "clap", arg(long, value_enum, value_delimiter = ','))]
    pub transport: Vec<BenchTransport>,
    /// UDP points: measure the boards behind this bridge (`udp:HOST` on
    /// port 1394, or `udp:HOST:PORT`: a running `firelink emulate` or real
    /// boards) instead of an in-process emulator: one point per protocol
    /// with the boards the scan finds; no emulator CPU. With `--transport
    /// eth`: the Ethernet-only network answering there (`firelink emulate
    /// --network eth` or FPGA V3 boards at Rev 9).
    #[cfg_attr(feature = "clap", arg(long, value_parser = bridge_address))]
    pub port: Option<PortSpec>,
    /// UDP points: how the host's reads wait (comma-separated, each
    /// measured side by side): `block` (sleep in the kernel) or `spin`
    /// (poll the socket).
    #[cfg_attr(
        feature = "clap",
        arg(long = "udp-wait", value_enum, value_delimiter = ',', default_values_t = [WaitMode::Blocking])
    )]
    pub udp_wait: Vec<WaitMode>,
    /// UDP points: the host's time-out for each answer, ms (a cycle that
    /// waits longer counts an error; real hosts use about 20).
    #[cfg_attr(
        feature = "clap",
        arg(long = "udp-timeout-ms", default_value_t = 20, value_parser = crate::limits::timeout_ms)
    )]
    pub udp_timeout_ms: u64,
    /// Board counts (comma-separated, 1..=62); above 16 (the board-ID
    /// space) the figures come from the cost model fitted to the 16-board
    /// run.
    #[cfg_attr(feature = "clap", arg(long, default_value = "2,4,8,16,32,62"))]
    pub boards: String,
    /// Protocols (comma-separated).
    #[cfg_attr(
        feature = "clap",
        arg(long, value_enum, value_delimiter = ',', default_values_t = [Protocol::Sequential, Protocol::Broadcast])
    )]
    pub protocol: Vec<Protocol>,
    /// Measured cycles per point (after 20 warm-up cycles), 1 to 10^7.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = 1000, value_parser = crate::limits::measured)
    )]
    pub cycles: u64,
    /// Firmware of the emulated boards.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value = "rev8", value_parser = crate::cli_args::firmware())
    )]
    pub firmware: Profile,
    /// Control period for the seed-002 budget check, us (default: 6 kHz).
    #[cfg_attr(
        feature = "clap",
        arg(long = "period-us", default_value_t = 166.67, value_parser = crate::limits::period_us)
    )]
    pub period_us: f64,
    /// Broadcast protocol: the host's wait between the query and the hub
    /// read, us per board (seed 000's PC sleeps 5 us x N).
    #[cfg_attr(
        feature = "clap",
        arg(long = "wait-us", default_value_t = 5.0, value_parser = crate::limits::wait_us)
    )]
    pub wait_us: f64,
    /// Idle time between cycles, us: a paced control loop leaves the bus
    /// idle between cycles (longer than the 21 us arbitration reset gap, so
    /// the PC's fairness interval restarts), as at seed 000's 6 kHz.
    #[cfg_attr(
        feature = "clap",
        arg(long = "idle-us", default_value_t = 50.0, value_parser = crate::limits::wait_us)
    )]
    pub idle_us: f64,
    /// The simulated bus's level of detail (`sim` points, and the bus
    /// behind the in-process emulator and the /dev/fw* twin): `fast` (a
    /// packet's deliveries in one batch where that is exact) or `packet`
    /// (every delivery an event of its own); the same answer either way,
    /// and the report counts what ran each way.
    #[cfg_attr(feature = "clap", arg(long, default_value = "fast"))]
    pub detail: Detail,
}

impl BenchRequest {
    /// The benchmark's options: the transports asked for (default `sim`
    /// and `udp`, only `udp` with a bridge), the wait modes once each in
    /// the order given, the board counts parsed and checked.
    ///
    /// # Errors
    /// A board count outside 1..=62, or counts above 16 with no measured
    /// count before them; `--detail packet` with no point on a simulated
    /// bus (one line).
    pub fn options(&self) -> Result<BenchOptions, String> {
        let transports = match (self.transport.is_empty(), self.port) {
            (false, _) => self.transport.clone(),
            (true, Some(_)) => vec![BenchTransport::Udp],
            (true, None) => vec![BenchTransport::Sim, BenchTransport::Udp],
        };
        // Only `sim`, `fw` and the in-process emulators (`udp`, and `eth`'s
        // bridge companions, without `--port`) run a simulated 1394 bus.
        let simulated = transports.iter().any(|t| match t {
            BenchTransport::Sim | BenchTransport::Fw => true,
            BenchTransport::Udp | BenchTransport::Eth => self.port.is_none(),
        });
        if self.detail == Detail::Packet && !simulated {
            return Err(
                "--detail packet: no point of this run is on a simulated 1394 bus \
                 (a bridge named by --port is measured as it is)"
                    .into(),
            );
        }
        let mut udp_waits = Vec::new();
        for w in self.udp_wait.iter().copied() {
            if !udp_waits.contains(&w) {
                udp_waits.push(w);
            }
        }
        Ok(BenchOptions {
            transports,
            boards: parse_board_counts(&self.boards).map_err(|e| format!("--boards: {e}"))?,
            protocols: self.protocol.clone(),
            cycles: self.cycles,
            firmware: self.firmware,
            period_us: self.period_us,
            wait_us_per_board: self.wait_us,
            idle_us: self.idle_us,
            udp_waits,
            udp_timeout: Duration::from_millis(self.udp_timeout_ms),
            udp_target: match self.port {
                Some(PortSpec::Udp(addr) | PortSpec::UdpFw(addr)) => Some(addr),
                _ => None,
            },
            detail: self.detail,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request() -> BenchRequest {
        BenchRequest {
            transport: Vec::new(),
            port: None,
            udp_wait: vec![WaitMode::Blocking],
            udp_timeout_ms: 20,
            boards: "2,4".into(),
            protocol: vec![Protocol::Broadcast],
            cycles: 10,
            firmware: Profile::Rev8,
            period_us: 166.67,
            wait_us: 5.0,
            idle_us: 50.0,
            detail: Detail::Fast,
        }
    }

    #[test]
    fn transports_default_by_whether_a_bridge_is_named() {
        let options = request().options().unwrap();
        assert_eq!(
            options.transports,
            vec![BenchTransport::Sim, BenchTransport::Udp]
        );
        assert_eq!(options.boards, vec![2, 4]);
        assert_eq!(options.udp_target, None);
        let bridge = BenchRequest {
            port: Some(bridge_address("udp:127.0.0.1:1400").unwrap()),
            udp_wait: vec![WaitMode::Spinning, WaitMode::Blocking, WaitMode::Spinning],
            ..request()
        };
        let options = bridge.options().unwrap();
        assert_eq!(options.transports, vec![BenchTransport::Udp]);
        assert_eq!(options.udp_target, Some(([127, 0, 0, 1], 1400).into()));
        assert_eq!(
            options.udp_waits,
            vec![WaitMode::Spinning, WaitMode::Blocking]
        );
        let asked = BenchRequest {
            transport: vec![BenchTransport::Eth],
            ..bridge
        };
        assert_eq!(
            asked.options().unwrap().transports,
            vec![BenchTransport::Eth]
        );
    }

    #[test]
    fn the_port_is_a_bridge_and_the_counts_are_checked() {
        assert!(bridge_address("udp:127.0.0.1").is_ok());
        let e = bridge_address("sim").unwrap_err();
        assert!(e.contains("firelink bench --port"), "{e}");
        assert!(bridge_address("nonsense:").is_err());
        let bad = BenchRequest {
            boards: "0".into(),
            ..request()
        };
        assert!(bad.options().is_err());
        // The packet level needs a simulated bus in some point.
        let outside = BenchRequest {
            port: Some(bridge_address("udp:127.0.0.1:1400").unwrap()),
            detail: Detail::Packet,
            ..request()
        };
        let e = outside.options().unwrap_err();
        assert!(e.starts_with("--detail packet: no point"), "{e}");
        let with_sim = BenchRequest {
            transport: vec![BenchTransport::Sim, BenchTransport::Udp],
            ..outside
        };
        assert_eq!(with_sim.options().unwrap().detail, Detail::Packet);
    }
}
