//! The benchmark's Ethernet-only points: the real `IoSystem` over
//! [`EthPort`] against FPGA V3 boards at firmware Rev 9 on the
//! Ethernet-only network (the in-process `eth_serve` network on loopback,
//! or an address given), and beside it the *floor*: the same port calls
//! (the query to the group, the wait, the hub's unsolicited response of
//! the same size, the command block) against a loopback responder that
//! answers at once and emulates nothing, in blocks alternating with the
//! point's own cycles ([`super::udp`]'s machinery). The host waits after
//! the query as the Rev 9 host does (3 + 38 (N - 1) us); the bridge
//! companions measured beside it (FPGA V2 at Rev 8 and at Rev 9) wait as
//! the same host does through the bridge (10 + 10 (N - 1) us).
//!
//! And the firmware's stated timing for the same chain
//! ([`StatedTiming`]): the Rev 9 host's own waits (EthBasePort
//! `WaitBroadcastRead`: 3 + 38 (N - 1) us on the Ethernet-only network,
//! 10 + 10 (N - 1) us through the bridge) and the cycle the simulated
//! Ethernet timing model ([`firelink_bus::ethernet`]) gives the chain: the
//! query, every board's status block landing in the hub, the hub's
//! response to the host, the command block to the farthest board.

use std::net::{IpAddr, SocketAddr};
use std::time::Duration;

use serde::Serialize;

use firelink_board::qla::config::{BoardConfig, FpgaVersion};
use firelink_bus::SimTime;
use firelink_bus::ethernet::{EthChain, EthTiming, Framing};
use firelink_emulate::qla::eth_network::EthNetwork;
use firelink_emulate::qla::eth_serve::{EthServeConfig, eth_bind, eth_serve};
use firelink_host::eth::{EthAddresses, EthPort, ethernet_only_broadcast_wait};
use firelink_host::qla::scan::Protocol;
use firelink_host::udp::WaitMode;
use firelink_wire::bridge::{CONTROL_WORD_LEN, EXTRA_DATA_LEN};
use firelink_wire::qla::broadcast::{command_block_quadlets, hub_block_quadlets};

use super::server_thread::ServerThread;
use super::udp::{ModeRun, Responder, Side, SideSettings, idle_time, run_sides};
use crate::TestbedError;

/// The in-process Ethernet-only network: the boards on loopback at
/// 127.0.0.100 + ID (a free port), served on a thread of their own.
pub(super) struct InProcessNetwork {
    /// The port every board listens on.
    pub port: u16,
    server: ServerThread<()>,
}

impl InProcessNetwork {
    /// Serve `boards` (FPGA V3 at Rev 9), chained in that order from the
    /// host.
    ///
    /// # Errors
    /// Boards the network refuses; sockets that cannot be bound.
    pub(super) fn start(boards: Vec<BoardConfig>) -> Result<InProcessNetwork, TestbedError> {
        let mut net = EthNetwork::new(boards, EthTiming::default())
            .map_err(|e| TestbedError::Config(e.to_string()))?;
        let config = EthServeConfig {
            port: 0,
            ..EthServeConfig::default()
        };
        let sockets = eth_bind(&config, &net.board_ids())?;
        let port = sockets.port;
        let server = ServerThread::spawn(move |stop| {
            // A socket failure ends the server; the host's cycles then
            // count the misses.
            let _ = eth_serve(&mut net, &sockets, stop, |_| {});
        });
        Ok(InProcessNetwork { port, server })
    }

    /// CPU time its server thread has used so far.
    pub(super) fn cpu_time(&self) -> Option<Duration> {
        self.server.cpu_time()
    }
}

/// Where the boards of an Ethernet-only point are.
pub(super) enum EthTarget<'a> {
    /// The in-process network.
    InProcess(&'a InProcessNetwork),
    /// A network at this address (`udp:HOST`, probed as the Rev 9 host
    /// does).
    External(SocketAddr),
}

/// The host's port on `target`, its boards given their addresses.
fn host_port(target: &EthTarget<'_>) -> Result<EthPort, TestbedError> {
    let addrs = match target {
        EthTarget::InProcess(net) => EthAddresses::loopback(net.port),
        EthTarget::External(addr) => {
            let probe = EthPort::probe(*addr, crate::rig::UDP_TIMEOUT.max(Duration::from_secs(1)))?;
            if !probe.is_ethernet_only() {
                return Err(TestbedError::Config(format!(
                    "bench --transport eth: the board answering at {addr} is not an FPGA V3 at \
                     firmware Rev 9 or later (firmware {}), so the Rev 9 host would use the \
                     bridge: measure it with --transport udp",
                    probe.firmware
                )));
            }
            probe
                .ethernet_only_addresses()
                .ok_or_else(|| TestbedError::Config(format!("{addr}: no board addresses")))?
        }
    };
    let mut port = EthPort::open(addrs)?;
    port.init()?;
    Ok(port)
}

/// Measure the broadcast protocol on the Ethernet-only network at
/// `target`, with its floor, interleaved in blocks.
///
/// # Errors
/// The network cannot be reached or scanned.
pub(super) fn measure_point(
    target: &EthTarget<'_>,
    options: &super::BenchOptions,
) -> Result<ModeRun, TestbedError> {
    let responder = Responder::start()?;
    // The floor's "boards" are the responder: the group and board 0 at
    // its own address.
    let IpAddr::V4(ip) = responder.addr.ip() else {
        return Err(TestbedError::Config(
            "the floor's responder is not IPv4".into(),
        ));
    };
    let floor = EthPort::open(EthAddresses {
        base: ip,
        port: responder.addr.port(),
        group: ip,
    })?;
    let settings = SideSettings {
        wait: WaitMode::Blocking,
        // The Rev 9 host's own: 3 + 38 (N - 1) us.
        host_wait: super::HostWait::Port,
        protocol: Protocol::Broadcast,
        options,
        idle: idle_time(options),
    };
    let server_cpu = || match target {
        EthTarget::InProcess(net) => net.cpu_time(),
        EthTarget::External(_) => None,
    };
    let side = Side::open(
        host_port(target)?,
        floor,
        &responder,
        &settings,
        &server_cpu,
    )?;
    let mut runs = run_sides(vec![side], &responder, options, &server_cpu);
    runs.pop()
        .ok_or_else(|| TestbedError::Config("bench: no Ethernet-only run".into()))
}

/// `n` boards for the Ethernet-only network: `boards` (the bridge's
/// configurations) as FPGA V3 at Rev 9.
pub(super) fn as_v3(boards: Vec<BoardConfig>) -> Vec<BoardConfig> {
    boards
        .into_iter()
        .map(|b| b.with_fpga(FpgaVersion::V3))
        .collect()
}

/// The firmware's stated timing of one broadcast cycle for a contiguous
/// chain of boards, us.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StatedTiming {
    /// The Rev 9 host's wait after the query on the Ethernet-only network:
    /// 3 + 38 (N - 1) (EthBasePort `WaitBroadcastRead`).
    pub host_wait_us: f64,
    /// The same host's wait through the bridge: 10 + 10 (N - 1).
    pub bridge_host_wait_us: f64,
    /// The timing model's read: from the host starting to send the query
    /// to the last byte of the hub's response reaching it.
    pub model_read_us: f64,
    /// The timing model's cycle: the read, then the command block sent at
    /// once, until its last byte reaches the farthest board.
    pub model_cycle_us: f64,
}

/// The stated timing of a broadcast cycle of `boards` (chained in that
/// order from the host, every one selected by the query).
pub fn stated_timing(boards: &[BoardConfig]) -> Result<StatedTiming, TestbedError> {
    let ids: Vec<u8> = boards.iter().map(|b| b.board_id).collect();
    let timing = EthTiming::default();
    let mut chain = EthChain::new(timing, &ids).map_err(|e| TestbedError::Config(e.to_string()))?;
    // The host's IP write, each board's raw multicast after it: the
    // switches learn where the boards are (so only the nearest is the hub).
    let quadlet_write = CONTROL_WORD_LEN + 20;
    let taught = chain.from_host(SimTime::ZERO, Framing::Udp, quadlet_write, None);
    for &(id, at) in &taught {
        chain.from_board(
            at + timing.response_latency,
            Framing::Raw,
            quadlet_write,
            id,
        );
    }
    let hub = chain
        .hub()
        .ok_or_else(|| TestbedError::Config("no hub on the chain".into()))?;
    let layouts = boards.iter().map(|b| b.layout());
    let status_bytes = layouts
        .clone()
        .map(|l| l.broadcast_quadlets() * 4)
        .max()
        .unwrap_or(0);
    let hub_bytes = hub_block_quadlets(layouts.clone()) * 4;
    let command_bytes = command_block_quadlets(layouts) * 4;
    // The query, well after the learning.
    let start = SimTime::from_micros(1000);
    let query = chain.from_host(start, Framing::Udp, quadlet_write, None);
    let mask = ids.iter().fold(0u16, |m, &id| {
        m | 1u16.checked_shl(u32::from(id)).unwrap_or(0)
    });
    // A raw status block: control word, the 1394 block write's header and
    // CRCs, the block.
    let landed = chain.hub_updates(&query, mask, CONTROL_WORD_LEN + 24 + status_bytes, hub);
    let complete = landed.last().map_or(start, |l| l.1);
    // The response: the block read response's header and CRCs, the hub,
    // the extra data.
    let response = 20 + hub_bytes + 4 + EXTRA_DATA_LEN;
    let answered = chain.to_host(
        complete + timing.response_latency,
        Framing::Udp,
        response,
        hub,
    );
    let command = CONTROL_WORD_LEN + 20 + command_bytes + 4;
    let written = chain
        .from_host(answered, Framing::Udp, command, None)
        .into_iter()
        .map(|(_, at)| at)
        .max()
        .unwrap_or(answered);
    let us = |t: SimTime| t.saturating_since(start).as_secs_f64() * 1e6;
    let n = ids.len();
    Ok(StatedTiming {
        host_wait_us: ethernet_only_broadcast_wait(n).as_secs_f64() * 1e6,
        bridge_host_wait_us: 10.0 + 10.0 * n.saturating_sub(1) as f64,
        model_read_us: us(answered),
        model_cycle_us: us(written),
    })
}

/// The board sets of the `eth` transport's points.
pub const ETH_SET: &str = "FPGA V3, Rev 9, Ethernet-only";
/// The bridge companion at Rev 8.
pub const BRIDGE_REV8_SET: &str = "FPGA V2, Rev 8, bridge";
/// The bridge companion at Rev 9.
pub const BRIDGE_REV9_SET: &str = "FPGA V2, Rev 9, bridge";

/// A board count and the stated timing of its chain.
pub(super) type BoardsStated = (usize, StatedTiming);

/// The `eth` transport's points: at every measured board count (1..=16),
/// the Ethernet-only network in process, then the bridge with FPGA V2
/// boards at Rev 8 and at Rev 9 (every wait mode asked), each with its
/// floor; with [`super::BenchOptions::udp_target`], that network alone.
/// Also the stated timing of each count's chain.
pub(super) fn eth_raws(
    generic: &firelink_control::config::IoConfig,
    options: &super::BenchOptions,
    progress: &mut dyn FnMut(super::BenchTransport, Protocol, usize),
) -> Result<(Vec<super::Raw>, Vec<BoardsStated>), TestbedError> {
    let transport = super::BenchTransport::Eth;
    let mut raws = Vec::new();
    let mut stated = Vec::new();
    if let Some(addr) = options.udp_target {
        progress(transport, Protocol::Broadcast, 0);
        let run = measure_point(&EthTarget::External(addr), options)?;
        let boards = run.boards;
        let mut raw =
            super::raw_of_run(transport, &format!("udp:{addr}"), Protocol::Broadcast, run);
        raw.board_set = Some(ETH_SET);
        raws.push(raw);
        let chain = as_v3(super::bench_boards(
            generic,
            firelink_board::qla::config::Profile::Rev9,
            boards,
        ));
        stated.push((boards, stated_timing(&chain)?));
        return Ok((raws, stated));
    }
    for &n in options.boards.iter().filter(|&&n| n <= 16) {
        progress(transport, Protocol::Broadcast, n);
        let chain = as_v3(super::bench_boards(
            generic,
            firelink_board::qla::config::Profile::Rev9,
            n,
        ));
        stated.push((n, stated_timing(&chain)?));
        let net = InProcessNetwork::start(chain)?;
        let run = measure_point(&EthTarget::InProcess(&net), options);
        drop(net);
        let mut raw = super::raw_of_run(
            transport,
            "in-process Ethernet-only network",
            Protocol::Broadcast,
            run?,
        );
        raw.board_set = Some(ETH_SET);
        raws.push(raw);
        for (profile, set) in [
            (firelink_board::qla::config::Profile::Rev8, BRIDGE_REV8_SET),
            (firelink_board::qla::config::Profile::Rev9, BRIDGE_REV9_SET),
        ] {
            let boards = super::bench_boards(generic, profile, n)
                .into_iter()
                .map(|b| b.with_fpga(FpgaVersion::V2))
                .collect();
            let emu = crate::rig::Emulator::start_rig(
                crate::rig::RigBuilder::qla(boards).detail(options.detail),
            )?;
            let bridge = super::udp::Bridge {
                addr: emu.addr,
                emulator: Some(&emu),
            };
            // The Rev 9 host's wait through the bridge: 10 + 10 (N - 1) us.
            let runs = super::udp::measure_point(
                &bridge,
                Protocol::Broadcast,
                options,
                super::HostWait::Rev9Bridge,
            );
            let stats = emu.stop()?;
            raws.extend(runs?.into_iter().map(|m| {
                let mut r = super::raw_of_run(
                    super::BenchTransport::Udp,
                    "in-process emulator",
                    Protocol::Broadcast,
                    m,
                );
                r.board_set = Some(set);
                r.detail = Some(stats.detail);
                r
            }));
        }
    }
    Ok((raws, stated))
}

/// One board count of the `eth` transport: the Ethernet-only network, the
/// bridge at Rev 8 and Rev 9, their floors and the stated timing, us
/// (medians of the same run).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EthComparison {
    /// Boards.
    pub boards: usize,
    /// The Ethernet-only network's broadcast cycle (median).
    pub eth_us: f64,
    /// Its floor (the same datagrams against a responder).
    pub eth_floor_us: f64,
    /// The bridge, FPGA V2 at Rev 8 (the first wait mode measured).
    pub bridge_rev8_us: Option<f64>,
    /// Its floor.
    pub bridge_rev8_floor_us: Option<f64>,
    /// The bridge, FPGA V2 at Rev 9.
    pub bridge_rev9_us: Option<f64>,
    /// Its floor.
    pub bridge_rev9_floor_us: Option<f64>,
    /// The firmware's stated timing of the chain.
    pub stated: StatedTiming,
    /// `eth_us` over its floor.
    pub eth_over_floor: f64,
    /// The bridge at Rev 8 over the Ethernet-only network.
    pub bridge_rev8_over_eth: Option<f64>,
    /// The bridge at Rev 9 over the Ethernet-only network.
    pub bridge_rev9_over_eth: Option<f64>,
    /// `eth_us` over the model's cycle.
    pub eth_over_model: f64,
}

/// The comparisons of the `eth` points among `results` (one per board
/// count with a stated timing).
pub(super) fn comparisons(
    results: &[super::BenchPoint],
    stated: &[(usize, StatedTiming)],
) -> Vec<EthComparison> {
    let find = |set: &str, boards: usize| {
        results
            .iter()
            .find(|r| r.board_set == Some(set) && r.boards == boards)
            .and_then(|r| {
                r.udp
                    .as_ref()
                    .map(|u| (r.io_time_us.median, u.floor_us.median))
            })
    };
    let ratio = |a: Option<(f64, f64)>, b: f64| a.map(|(x, _)| super::ratio3(x, b));
    stated
        .iter()
        .filter_map(|&(boards, stated)| {
            let (eth_us, eth_floor_us) = find(ETH_SET, boards)?;
            let rev8 = find(BRIDGE_REV8_SET, boards);
            let rev9 = find(BRIDGE_REV9_SET, boards);
            Some(EthComparison {
                boards,
                eth_us,
                eth_floor_us,
                bridge_rev8_us: rev8.map(|r| r.0),
                bridge_rev8_floor_us: rev8.map(|r| r.1),
                bridge_rev9_us: rev9.map(|r| r.0),
                bridge_rev9_floor_us: rev9.map(|r| r.1),
                stated,
                eth_over_floor: super::ratio3(eth_us, eth_floor_us),
                bridge_rev8_over_eth: ratio(rev8, eth_us),
                bridge_rev9_over_eth: ratio(rev9, eth_us),
                eth_over_model: super::ratio3(eth_us, stated.model_cycle_us),
            })
        })
        .collect()
}

/// Print the comparison table.
pub(super) fn fmt_comparisons(
    rows: &[EthComparison],
    f: &mut std::fmt::Formatter<'_>,
) -> std::fmt::Result {
    if rows.is_empty() {
        return Ok(());
    }
    let num = |v: Option<f64>, d: usize| v.map_or("-".to_string(), |x| format!("{x:.d$}"));
    writeln!(
        f,
        "\nEthernet-only network (FPGA V3, Rev 9) against the bridge (FPGA V2 at Rev 8 and Rev 9), \
         broadcast cycle medians and floors of the same run, us; the firmware's stated timing: the \
         Rev 9 host's waits (3 + 38 (N - 1) Ethernet-only, 10 + 10 (N - 1) bridge) and the Ethernet \
         timing model's read (query to the hub's response) and cycle (and the command block)"
    )?;
    writeln!(
        f,
        "{:>6} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>7} {:>7} {:>7} {:>7}",
        "boards",
        "eth",
        "floor",
        "br R8",
        "floor",
        "br R9",
        "floor",
        "wait",
        "br wait",
        "model rd",
        "model cy",
        "R8/eth",
        "R9/eth",
        "eth/flr",
        "eth/mdl"
    )?;
    for r in rows {
        writeln!(
            f,
            "{:>6} {:>8.1} {:>8.1} {:>8} {:>8} {:>8} {:>8} {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>7} {:>7} {:>7.2} {:>7.2}",
            r.boards,
            r.eth_us,
            r.eth_floor_us,
            num(r.bridge_rev8_us, 1),
            num(r.bridge_rev8_floor_us, 1),
            num(r.bridge_rev9_us, 1),
            num(r.bridge_rev9_floor_us, 1),
            r.stated.host_wait_us,
            r.stated.bridge_host_wait_us,
            r.stated.model_read_us,
            r.stated.model_cycle_us,
            num(r.bridge_rev8_over_eth, 2),
            num(r.bridge_rev9_over_eth, 2),
            r.eth_over_floor,
            r.eth_over_model
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_board::qla::config::{Hardware, Profile};

    fn qla1s(n: u8) -> Vec<BoardConfig> {
        as_v3(
            (0..n)
                .map(|id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev9))
                .collect(),
        )
    }

    /// The host's waits are the Rev 9 formulas; the model's read is longer
    /// than the host's wait (the query's and response's own frames, the
    /// response latency) and grows with the chain; the cycle adds the
    /// command block.
    #[test]
    fn stated_timing_follows_the_hosts_formulas_and_the_model() {
        let mut last_read = 0.0;
        for n in [1u8, 4, 8, 16] {
            let t = stated_timing(&qla1s(n)).unwrap();
            let k = f64::from(n) - 1.0;
            assert_eq!(t.host_wait_us, 3.0 + 38.0 * k);
            assert_eq!(t.bridge_host_wait_us, 10.0 + 10.0 * k);
            assert!(t.model_read_us > t.host_wait_us, "{n}: {t:?}");
            assert!(t.model_read_us > last_read, "{n}: {t:?}");
            assert!(t.model_cycle_us > t.model_read_us, "{n}: {t:?}");
            last_read = t.model_read_us;
        }
    }

    /// The same chain gives the same times.
    #[test]
    fn stated_timing_is_deterministic() {
        assert_eq!(
            stated_timing(&qla1s(8)).unwrap(),
            stated_timing(&qla1s(8)).unwrap()
        );
    }
}
