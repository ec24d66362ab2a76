//! `firelink emulate`: emulated boards behind an Ethernet bridge on UDP
//! (or, with `--fw-cdev`, as the kernel's /dev/fw* devices on a unix
//! socket for the preloaded twin; with `--network eth`, FPGA V3 boards at
//! Rev 9 on the Ethernet-only network, each at its own address), paced to
//! wall-clock time, until SIGINT or SIGTERM.

use std::io::Write;
use std::net::{Ipv4Addr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use clap::{Args, ValueEnum};

use firelink_control::config::IoConfig;
use firelink_emulate::Event;
use firelink_emulate::fw_cdev::{self, Twin};
use firelink_emulate::qla::eth_serve::EthEvent;
use firelink_host::stop::server_stop_flag;
use firelink_testbed::emulated::{BoardSettings, FpgaVersion, Hardware, Profile, SimDuration};
use firelink_testbed::emulation::{
    BridgeServer, CpuLatencyNote, EthRequest, EthServer, ServeError, refuse_on_eth, robot_preset,
};
use firelink_testbed::fault_script::{FaultScript, FaultScriptError};
use firelink_testbed::rig::RobotKind;
use firelink_testbed::rig::served::{BusFaults, ServedBoards};
use firelink_testbed::snake::is_snake_config;

use crate::args::CpuLatencyArg;
use crate::demo::load_config;
use crate::error::CliError;

/// Options of `firelink emulate`.
#[derive(Args, Debug, Clone)]
pub struct EmulateArgs {
    /// Number of boards (IDs 0..N, 1..=16) with generic motors.
    #[arg(long, default_value_t = 8, conflicts_with = "config", value_parser = crate::args::board_count)]
    pub boards: u8,
    /// A robot configuration (saw-robot-io v6 JSON): emulate its boards
    /// with matching plants (SNAKE boards: seed 001's 7-channel nodes).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Emulate seed 001's 36-axis Snake system on its 7-channel nodes
    /// (`configs/snake-seed001.json`), for `firelink snake-tool` and
    /// `firelink demo --robot snake --port udp:...`.
    #[arg(long, value_enum, conflicts_with_all = ["config", "boards"])]
    pub robot: Option<RobotKind>,
    /// Firmware (seed: seed 000's TDMA and 0xFFFF rule).
    #[arg(long, default_value = "rev8", value_parser = crate::args::firmware())]
    pub firmware: Profile,
    /// Companion board of every board.
    #[arg(long, default_value = "QLA1", value_parser = crate::args::hardware())]
    pub hardware: Hardware,
    /// FPGA board of every board (default: V2 for a QLA1, V3 for a DQLA,
    /// the only FPGA the firmware builds a DQLA for; a V2 DQLA is refused).
    #[arg(long, value_parser = crate::args::fpga())]
    pub fpga: Option<FpgaVersion>,
    /// One board's settings (repeatable): `ID:key=value,...` with keys
    /// hardware (QLA1, DQLA), fpga (V2, V3), firmware (7, 8, 9),
    /// fpga-serial, qla-serial, qla2-serial, supply-volts,
    /// qla2-supply-volts, instrument (MODEL/VERSION/NAME). Serials are the
    /// board's own: with --config a robot's simulation.boards, else
    /// unique defaults per board ID (never the arm's serial_number).
    #[arg(long = "board-set", value_name = "ID:KEY=VALUE,...")]
    pub board_set: Vec<BoardSettings>,
    /// Seed of the measurement noise and the fault injector.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Address to listen on (loopback unless you ask otherwise: any other
    /// address prints a warning).
    #[arg(long, default_value = "127.0.0.1:1394")]
    pub listen: SocketAddr,
    /// Do not also listen on the loopback broadcast address.
    #[arg(long = "no-broadcast")]
    pub no_broadcast: bool,
    /// Board ID of the Ethernet-connected board (default: the lowest).
    #[arg(long = "bridge-board", value_parser = crate::args::board_id)]
    pub bridge_board: Option<u8>,
    /// Fault: drop each packet on the bus with this probability (0..=1).
    #[arg(long = "drop-rate", default_value_t = 0.0, value_parser = crate::args::probability)]
    pub drop_rate: f64,
    /// Fault: flip a bit in each packet on the bus with this probability (0..=1).
    #[arg(long = "corrupt-rate", default_value_t = 0.0, value_parser = crate::args::probability)]
    pub corrupt_rate: f64,
    /// Commit damaged writes as real Rev 8 boards do: a quadlet write whose
    /// header CRC fails and a real-time block write whose data CRC fails
    /// are acknowledged ack_data_error and written all the same. Off by
    /// default (the emulated boards acknowledge them alike but commit
    /// nothing); for testing a host's robustness against real boards,
    /// e.g. with --corrupt-rate.
    #[arg(long = "commit-corrupt-writes")]
    pub commit_corrupt_writes: bool,
    /// Fault: drop each response a board sends (quadlet and block read
    /// responses) with this probability (0..=1): the host's request is
    /// answered by nothing (over --fw-cdev: RCODE_CANCELLED after the
    /// split time-out).
    #[arg(long = "drop-response-rate", default_value_t = 0.0, value_parser = crate::args::probability)]
    pub drop_response_rate: f64,
    /// Fault: the addressed board is busy for each request the host sends
    /// with this probability (0..=1): it takes nothing and acknowledges
    /// ack_busy_X (over --fw-cdev: RCODE_BUSY).
    #[arg(long = "busy-rate", default_value_t = 0.0, value_parser = crate::args::probability)]
    pub busy_rate: f64,
    /// Fault: this many bus resets in a row (0..=1000), 1 ms apart, from
    /// `--fault-at-ms` (or `--fault-after-requests`).
    #[arg(long = "reset-storm", value_name = "N", default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=1000))]
    pub reset_storm: u32,
    /// With --fw-cdev (and fw-run): the split time-out, ms of emulated
    /// time: a request whose response is lost completes with
    /// RCODE_CANCELLED this long after it was sent (the kernel's default:
    /// 2000; a short one keeps tests of lost responses short).
    #[arg(long = "split-timeout-ms", value_name = "MS", default_value_t = 2000, value_parser = clap::value_parser!(u64).range(1..=60_000))]
    pub split_timeout_ms: u64,
    /// Fault: unplug this board's cable (bus reset) after `--fault-at-ms`.
    #[arg(long = "unplug-board", value_parser = crate::args::board_id)]
    pub unplug_board: Option<u8>,
    /// Fault: this board stops answering after `--fault-at-ms`.
    #[arg(long = "mute-board", value_parser = crate::args::board_id)]
    pub mute_board: Option<u8>,
    /// Faults as a plan, after the fault flags above: entries separated by
    /// `;`, e.g. `mute@t=0us:id=4` (board 4 stops answering at
    /// `--fault-at-ms`), `unplug@t=2000us:id=5` (2 ms after it),
    /// `drop@start:tcode=0x6,rate=0.01`, `corrupt@start:dest=2,offset=0x1800,count=3`
    /// (kinds mute, unplug, drop, corrupt; the bus cannot pause the host
    /// nor count servo cycles).
    #[arg(long = "faults", value_name = "SCRIPT", value_parser = fault_script)]
    pub faults: Option<FaultScript>,
    /// When the timed faults happen, in ms of emulated time.
    #[arg(long = "fault-at-ms", default_value_t = 5000)]
    pub fault_at_ms: u64,
    /// With --fw-cdev (and fw-run): start the timed faults when the twin
    /// has taken this many requests instead of at --fault-at-ms (a fault
    /// at a point of the program's run, however long it took to start).
    #[arg(long = "fault-after-requests", value_name = "N")]
    pub fault_after_requests: Option<u64>,
    /// Serve the emulated boards as Linux /dev/fw* devices instead of the
    /// Ethernet bridge: the kernel's firewire-cdev side on this unix
    /// socket, for programs run with the twin preloaded (`firelink fw-run`
    /// does both). The PC's card is /dev/fw0, the boards /dev/fw1...
    #[arg(long = "fw-cdev", value_name = "SOCKET")]
    pub fw_cdev: Option<PathBuf>,
    /// Hold every CPU's wake-up latency at this many microseconds while
    /// serving (a PM QoS request on /dev/cpu_dma_latency, as real-time
    /// Linux tools such as cyclictest hold; needs root), or `off`. With 0
    /// (the default) idle CPUs poll instead of sleeping, so a datagram
    /// handed from a host on one idle CPU to the emulator on another is
    /// taken in microseconds, not the tens a sleeping (in a VM: halted)
    /// CPU takes to wake: on a quiet 2-vCPU VM an 8-board SEQ_R_BC_W cycle
    /// took 1028-1184 us without it and 196-264 us with it
    /// (BENCHMARKS.md). Idle CPUs spin while the emulator runs. Not
    /// permitted: served all the same, with a note.
    #[arg(long = "cpu-latency", value_name = "US|off", default_value = "0", value_parser = crate::args::cpu_latency)]
    pub cpu_latency: CpuLatencyArg,
    /// Stop by itself after this many seconds (0: run until a signal).
    #[arg(long = "duration-s", default_value_t = 0.0, value_parser = crate::args::seconds_or_forever)]
    pub duration_s: f64,
    /// The network the boards are on: `bridge` (one Ethernet board in
    /// front of a FireWire bus, the FPGA V2 way; any FPGA and firmware) or
    /// `eth` (the Ethernet-only network of FPGA V3 boards at firmware Rev
    /// 9: every board its own address, --eth-base + board ID on --listen's
    /// port; needs --fpga V3 --firmware 9).
    #[arg(long, value_enum, default_value_t = NetworkArg::Bridge)]
    pub network: NetworkArg,
    /// With --network eth: board 0's address; board N listens at it + N
    /// (loopback by default; 169.254.0.100 is the stock one).
    #[arg(long = "eth-base", default_value = "127.0.0.100")]
    pub eth_base: Ipv4Addr,
    /// Also join the multicast group 224.0.0.100, where a Rev 9 host sends
    /// its group requests (--network eth: the queries and command blocks;
    /// a Rev 9 bridge: the host's Ethernet broadcasts). Needs a multicast
    /// route, e.g. on `lo` inside a network namespace; without it the
    /// host's group requests reach the boards through the loopback
    /// broadcast address.
    #[arg(long)]
    pub multicast: bool,
    /// With --network eth: the boards' order along the chain from the host
    /// (board IDs, comma-separated; default: as emulated, ascending). The
    /// first is the hub; hub blocks arrive in this order.
    #[arg(long, value_delimiter = ',', value_parser = crate::args::board_id)]
    pub chain: Vec<u8>,
}

/// `--network`: what connects the host to the boards.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum NetworkArg {
    /// The Ethernet/FireWire bridge (FPGA V2 style).
    Bridge,
    /// The Ethernet-only network (FPGA V3, firmware Rev 9).
    Eth,
}

/// The robot configuration `args` names (`--config`, or `--robot`'s
/// preset), what its mapping to plants says on stderr (not for Snake
/// nodes, which map one to one).
fn served_config(args: &EmulateArgs) -> Result<Option<IoConfig>, CliError> {
    let config = match (&args.config, args.robot) {
        (Some(path), _) => Some(load_config(path)?),
        (None, Some(robot)) => Some(robot_preset(robot).map_err(ServeError::from)?),
        (None, None) => None,
    };
    for config in config.iter().filter(|c| !is_snake_config(c)) {
        for note in firelink_testbed::plant_map::notes(config) {
            eprintln!("note: {note}");
        }
    }
    Ok(config)
}

/// The boards `args` asks for, `config`'s or generic ones (the one place
/// `emulate`'s board options are read, for every front end).
fn served_boards(args: &EmulateArgs, config: Option<IoConfig>) -> ServedBoards {
    ServedBoards {
        config,
        boards: args.boards,
        hardware: args.hardware,
        firmware: args.firmware,
        fpga: args.fpga,
        board_set: args.board_set.clone(),
        commit_corrupt_writes: args.commit_corrupt_writes,
        seed: args.seed,
        faults: BusFaults {
            drop_rate: args.drop_rate,
            corrupt_rate: args.corrupt_rate,
            drop_response_rate: args.drop_response_rate,
            busy_rate: args.busy_rate,
            reset_storm: args.reset_storm,
            unplug_board: args.unplug_board,
            mute_board: args.mute_board,
            plan: args.faults.clone().unwrap_or_default(),
        },
        fault_at: SimDuration::from_micros(args.fault_at_ms.saturating_mul(1000)),
        fault_after_requests: args.fault_after_requests,
        bridge_board: args.bridge_board,
        split_timeout: SimDuration::from_millis(args.split_timeout_ms),
    }
}

/// The /dev/fw* twin of `args` and its board IDs.
pub fn build_twin(args: &EmulateArgs) -> Result<(Twin, Vec<u8>), CliError> {
    Ok(served_boards(args, served_config(args)?).twin()?)
}

/// Print the `--cpu-latency` line, if any, and flush.
fn report(out: &mut impl Write, note: &CpuLatencyNote) -> std::io::Result<()> {
    if let Some(line) = &note.line {
        writeln!(out, "{line}")?;
    }
    out.flush()
}

/// Print one server event as its line, at once.
fn log_line(out: &mut impl Write, event: impl std::fmt::Display) {
    let _ = writeln!(out, "{event}");
    let _ = out.flush();
}

/// `firelink emulate --fw-cdev SOCKET`: serve the twin until SIGINT,
/// SIGTERM or `--duration-s`.
fn run_twin(args: &EmulateArgs, path: &Path, out: &mut impl Write) -> Result<(), CliError> {
    let (mut twin, ids) = build_twin(args)?;
    let listener = fw_cdev::bind(path)?;
    let stop = stop_flag(args)?;
    let cpu_latency = CpuLatencyNote::take(args.cpu_latency.microseconds());
    writeln!(
        out,
        "emulating {} board(s) {:?} as /dev/fw1..fw{} (the PC's card: /dev/fw0); bus generation {}",
        ids.len(),
        ids,
        ids.len(),
        twin.bus().generation()
    )?;
    report(out, &cpu_latency)?;
    let served = fw_cdev::serve(&mut twin, &listener, &stop, |e| log_line(out, e));
    let _ = std::fs::remove_file(path);
    served?;
    Ok(())
}

/// A flag set by SIGINT, SIGTERM, or after `--duration-s`.
fn stop_flag(args: &EmulateArgs) -> std::io::Result<Arc<AtomicBool>> {
    server_stop_flag((args.duration_s > 0.0).then(|| Duration::from_secs_f64(args.duration_s)))
}

/// `firelink emulate`.
pub fn run(args: &EmulateArgs, out: &mut impl Write) -> Result<(), CliError> {
    if args.network == NetworkArg::Eth {
        return run_eth(args, out);
    }
    if !args.chain.is_empty() {
        return Err(CliError::NotSupported {
            option: "--chain",
            reason: "belongs to the Ethernet-only network: add --network eth --fpga V3 --firmware 9",
        });
    }
    if let Some(path) = &args.fw_cdev {
        return run_twin(args, path, out);
    }
    if !args.listen.ip().is_loopback() {
        eprintln!(
            "firelink emulate: WARNING: listening on udp {}, not loopback: anyone who can \
             reach it can switch the emulated boards' motor power on and move their motors \
             (the boards' protocol has no token)",
            args.listen
        );
    }
    let served = served_boards(args, served_config(args)?).bridge()?;
    let mut server = BridgeServer::open(
        served,
        args.firmware,
        args.listen,
        !args.no_broadcast,
        args.multicast,
    )?;
    let stop = stop_flag(args)?;
    let cpu_latency = CpuLatencyNote::take(args.cpu_latency.microseconds());
    for line in server.banner() {
        writeln!(out, "{line}")?;
    }
    if let Some(line) = &cpu_latency.line {
        writeln!(out, "{line}")?;
    }
    if let Some(line) = server.multicast_line()? {
        writeln!(out, "{line}")?;
    }
    out.flush()?;
    server.serve(&stop, |e: Event| log_line(out, e))?;
    Ok(())
}

/// `--faults`: a fault script's text.
fn fault_script(text: &str) -> Result<FaultScript, String> {
    text.parse().map_err(|e: FaultScriptError| e.to_string())
}

/// `firelink emulate --network eth`: the boards on the Ethernet-only
/// network until SIGINT, SIGTERM or `--duration-s`.
fn run_eth(args: &EmulateArgs, out: &mut impl Write) -> Result<(), CliError> {
    let asked = EthRequest {
        twin: args.fw_cdev.is_some(),
        snake: args.robot == Some(RobotKind::Snake),
        fault_script: args.faults.is_some(),
    };
    refuse_on_eth(&served_boards(args, None), asked).map_err(ServeError::from)?;
    let boards = served_boards(args, served_config(args)?).chain(&args.chain)?;
    if !args.eth_base.is_loopback() {
        eprintln!(
            "firelink emulate: WARNING: the boards listen on {} + ID, not loopback: anyone who can \
             reach them can switch the emulated boards' motor power on and move their motors",
            args.eth_base
        );
    }
    let mut server = EthServer::open(
        boards,
        args.eth_base,
        args.listen.port(),
        !args.no_broadcast,
        args.multicast,
    )?;
    let stop = stop_flag(args)?;
    let cpu_latency = CpuLatencyNote::take(args.cpu_latency.microseconds());
    for line in server.banner() {
        writeln!(out, "{line}")?;
    }
    report(out, &cpu_latency)?;
    server.serve(&stop, |e: EthEvent| log_line(out, e))?;
    Ok(())
}
