//! One request for the served boards, whatever serves them: what
//! `firelink emulate` and `firelink fw-run` ask for ([`EmulateRequest`],
//! clap's `Args` behind the `clap` feature), turned into the boards
//! ([`EmulateRequest::served_boards`]) and into a server with its sockets
//! bound ([`EmulateRequest::open`]: the Ethernet bridge, the Ethernet-only
//! network or the /dev/fw* twin), ready to serve until a stop.
//!
//! Nothing here prints: what a front end should tell its user goes to the
//! `say` callbacks (the configuration's warnings, the plant map's notes, a
//! listening address that is not loopback) and [`Emulation::banner`]; the
//! server's events go to [`Emulation::serve`]'s callback.

use std::fmt::Display;
use std::net::{Ipv4Addr, SocketAddr};
use std::os::fd::OwnedFd;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use firelink_bus::Detail;
use firelink_control::config::IoConfig;
use firelink_emulate::fw_cdev::{self, Twin};
use firelink_host::stop::server_stop_flag;

use super::{BridgeServer, CpuLatencyNote, EthRequest, EthServer, Refused, ServeError};
use super::{refuse_on_eth, robot_preset};
use crate::emulated::{BoardSettings, FpgaVersion, Hardware, Profile, SimDuration};
use crate::fault_script::FaultScript;
use crate::limits::CpuLatencyRequest;
use crate::rig::RobotKind;
use crate::rig::served::{BusFaults, ServedBoards};
use crate::snake::is_snake_config;

/// What connects the host to the served boards (`--network`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Network {
    /// The Ethernet/FireWire bridge (FPGA V2 style).
    Bridge,
    /// The Ethernet-only network (FPGA V3, firmware Rev 9).
    Eth,
}

/// What to serve and how: the options of `firelink emulate` (clap's
/// `Args` behind the `clap` feature), also `firelink fw-run`'s boards.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct EmulateRequest {
    /// Number of boards (IDs 0..N, 1..=16) with generic motors.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = 8, conflicts_with = "config", value_parser = crate::limits::board_count)
    )]
    pub boards: u8,
    /// A robot configuration (saw-robot-io v6 JSON): emulate its boards
    /// with matching plants (SNAKE boards: seed 001's 7-channel nodes).
    #[cfg_attr(feature = "clap", arg(long))]
    pub config: Option<PathBuf>,
    /// Emulate seed 001's 36-axis Snake system on its 7-channel nodes
    /// (`configs/snake-seed001.json`), for `firelink snake-tool` and
    /// `firelink demo --robot snake --port udp:...`.
    #[cfg_attr(feature = "clap", arg(long, value_enum, conflicts_with_all = ["config", "boards"]))]
    pub robot: Option<RobotKind>,
    /// Firmware (seed: seed 000's TDMA and 0xFFFF rule).
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value = "rev8", value_parser = crate::cli_args::firmware())
    )]
    pub firmware: Profile,
    /// Companion board of every board.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value = "QLA1", value_parser = crate::cli_args::hardware())
    )]
    pub hardware: Hardware,
    /// FPGA board of every board (default: V2 for a QLA1, V3 for a DQLA,
    /// the only FPGA the firmware builds a DQLA for; a V2 DQLA is refused).
    #[cfg_attr(feature = "clap", arg(long, value_parser = crate::cli_args::fpga()))]
    pub fpga: Option<FpgaVersion>,
    /// One board's settings (repeatable): `ID:key=value,...` with keys
    /// hardware (QLA1, DQLA), fpga (V2, V3), firmware (7, 8, 9),
    /// fpga-serial, qla-serial, qla2-serial, supply-volts,
    /// qla2-supply-volts, instrument (MODEL/VERSION/NAME). Serials are the
    /// board's own: with --config a robot's simulation.boards, else
    /// unique defaults per board ID (never the arm's serial_number).
    #[cfg_attr(
        feature = "clap",
        arg(long = "board-set", value_name = "ID:KEY=VALUE,...")
    )]
    pub board_set: Vec<BoardSettings>,
    /// Seed of the measurement noise and the fault injector.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 0))]
    pub seed: u64,
    /// Address to listen on (loopback unless you ask otherwise: any other
    /// address prints a warning).
    #[cfg_attr(feature = "clap", arg(long, default_value = "127.0.0.1:1394"))]
    pub listen: SocketAddr,
    /// Do not also listen on the loopback broadcast address.
    #[cfg_attr(feature = "clap", arg(long = "no-broadcast"))]
    pub no_broadcast: bool,
    /// Board ID of the Ethernet-connected board (default: the lowest).
    #[cfg_attr(
        feature = "clap",
        arg(long = "bridge-board", value_parser = crate::limits::board_id)
    )]
    pub bridge_board: Option<u8>,
    /// Fault: drop each packet on the bus with this probability (0..=1).
    #[cfg_attr(
        feature = "clap",
        arg(long = "drop-rate", default_value_t = 0.0, value_parser = crate::limits::probability)
    )]
    pub drop_rate: f64,
    /// Fault: flip a bit in each packet on the bus with this probability (0..=1).
    #[cfg_attr(
        feature = "clap",
        arg(long = "corrupt-rate", default_value_t = 0.0, value_parser = crate::limits::probability)
    )]
    pub corrupt_rate: f64,
    /// Commit damaged writes as real Rev 8 boards do: a quadlet write whose
    /// header CRC fails and a real-time block write whose data CRC fails
    /// are acknowledged ack_data_error and written all the same. Off by
    /// default (the emulated boards acknowledge them alike but commit
    /// nothing); for testing a host's robustness against real boards,
    /// e.g. with --corrupt-rate.
    #[cfg_attr(feature = "clap", arg(long = "commit-corrupt-writes"))]
    pub commit_corrupt_writes: bool,
    /// Fault: drop each response a board sends (quadlet and block read
    /// responses) with this probability (0..=1): the host's request is
    /// answered by nothing (over --fw-cdev: RCODE_CANCELLED after the
    /// split time-out).
    #[cfg_attr(
        feature = "clap",
        arg(long = "drop-response-rate", default_value_t = 0.0, value_parser = crate::limits::probability)
    )]
    pub drop_response_rate: f64,
    /// Fault: the addressed board is busy for each request the host sends
    /// with this probability (0..=1): it takes nothing and acknowledges
    /// ack_busy_X (over --fw-cdev: RCODE_BUSY).
    #[cfg_attr(
        feature = "clap",
        arg(long = "busy-rate", default_value_t = 0.0, value_parser = crate::limits::probability)
    )]
    pub busy_rate: f64,
    /// Fault: this many bus resets in a row (0..=1000), 1 ms apart, from
    /// `--fault-at-ms` (or `--fault-after-requests`).
    #[cfg_attr(
        feature = "clap",
        arg(long = "reset-storm", value_name = "N", default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=1000))
    )]
    pub reset_storm: u32,
    /// With --fw-cdev (and fw-run): the split time-out, ms of emulated
    /// time: a request whose response is lost completes with
    /// RCODE_CANCELLED this long after it was sent (the kernel's default:
    /// 2000; a short one keeps tests of lost responses short).
    #[cfg_attr(
        feature = "clap",
        arg(long = "split-timeout-ms", value_name = "MS", default_value_t = 2000, value_parser = clap::value_parser!(u64).range(1..=60_000))
    )]
    pub split_timeout_ms: u64,
    /// Fault: unplug this board's cable (bus reset) after `--fault-at-ms`.
    #[cfg_attr(
        feature = "clap",
        arg(long = "unplug-board", value_parser = crate::limits::board_id)
    )]
    pub unplug_board: Option<u8>,
    /// Fault: this board stops answering after `--fault-at-ms`.
    #[cfg_attr(
        feature = "clap",
        arg(long = "mute-board", value_parser = crate::limits::board_id)
    )]
    pub mute_board: Option<u8>,
    /// Faults as a plan, after the fault flags above: entries separated by
    /// `;`, e.g. `mute@t=0us:id=4` (board 4 stops answering at
    /// `--fault-at-ms`), `unplug@t=2000us:id=5` (2 ms after it),
    /// `drop@start:tcode=0x6,rate=0.01`, `corrupt@start:dest=2,offset=0x1800,count=3`
    /// (kinds mute, unplug, drop, corrupt; the bus cannot pause the host
    /// nor count servo cycles).
    #[cfg_attr(feature = "clap", arg(long = "faults", value_name = "SCRIPT"))]
    pub faults: Option<FaultScript>,
    /// When the timed faults happen, in ms of emulated time.
    #[cfg_attr(feature = "clap", arg(long = "fault-at-ms", default_value_t = 5000))]
    pub fault_at_ms: u64,
    /// With --fw-cdev (and fw-run): start the timed faults when the twin
    /// has taken this many requests instead of at --fault-at-ms (a fault
    /// at a point of the program's run, however long it took to start).
    #[cfg_attr(feature = "clap", arg(long = "fault-after-requests", value_name = "N"))]
    pub fault_after_requests: Option<u64>,
    /// Serve the emulated boards as Linux /dev/fw* devices instead of the
    /// Ethernet bridge: the kernel's firewire-cdev side on this unix
    /// socket, for programs run with the twin preloaded (`firelink fw-run`
    /// does both). The PC's card is /dev/fw0, the boards /dev/fw1...
    #[cfg_attr(feature = "clap", arg(long = "fw-cdev", value_name = "SOCKET"))]
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
    #[cfg_attr(
        feature = "clap",
        arg(long = "cpu-latency", value_name = "US|off", default_value = "0", value_parser = crate::limits::cpu_latency)
    )]
    pub cpu_latency: CpuLatencyRequest,
    /// Stop by itself after this many seconds (0: run until a signal).
    #[cfg_attr(
        feature = "clap",
        arg(long = "duration-s", default_value_t = 0.0, value_parser = crate::limits::seconds_or_forever)
    )]
    pub duration_s: f64,
    /// The network the boards are on: `bridge` (one Ethernet board in
    /// front of a FireWire bus, the FPGA V2 way; any FPGA and firmware) or
    /// `eth` (the Ethernet-only network of FPGA V3 boards at firmware Rev
    /// 9: every board its own address, --eth-base + board ID on --listen's
    /// port; needs --fpga V3 --firmware 9).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = Network::Bridge))]
    pub network: Network,
    /// With --network eth: board 0's address; board N listens at it + N
    /// (loopback by default; 169.254.0.100 is the stock one).
    #[cfg_attr(
        feature = "clap",
        arg(long = "eth-base", default_value = "127.0.0.100")
    )]
    pub eth_base: Ipv4Addr,
    /// Also join the multicast group 224.0.0.100, where a Rev 9 host sends
    /// its group requests (--network eth: the queries and command blocks;
    /// a Rev 9 bridge: the host's Ethernet broadcasts). Needs a multicast
    /// route, e.g. on `lo` inside a network namespace; without it the
    /// host's group requests reach the boards through the loopback
    /// broadcast address.
    #[cfg_attr(feature = "clap", arg(long))]
    pub multicast: bool,
    /// With --network eth: the boards' order along the chain from the host
    /// (board IDs, comma-separated; default: as emulated, ascending). The
    /// first is the hub; hub blocks arrive in this order.
    #[cfg_attr(
        feature = "clap",
        arg(long, value_delimiter = ',', value_parser = crate::limits::board_id)
    )]
    pub chain: Vec<u8>,
    /// The simulated bus's level of detail behind the bridge and the
    /// /dev/fw* twin: `fast` (a packet's deliveries in one batch where
    /// that is exact) or `packet` (every delivery an event of its own); the
    /// same answer either way, and the stop line counts the datagrams (the
    /// twin: requests) each way ran. The Ethernet-only network has no 1394
    /// bus and refuses `packet`.
    #[cfg_attr(feature = "clap", arg(long, default_value = "fast"))]
    pub detail: Detail,
}

impl Default for EmulateRequest {
    /// `firelink emulate` with every default: eight generic QLA1 boards at
    /// Rev 8 behind the bridge on 127.0.0.1:1394, no faults, until a
    /// signal.
    fn default() -> Self {
        let served = ServedBoards::default();
        EmulateRequest {
            boards: served.boards,
            config: None,
            robot: None,
            firmware: served.firmware,
            hardware: served.hardware,
            fpga: served.fpga,
            board_set: Vec::new(),
            seed: served.seed,
            listen: SocketAddr::from(([127, 0, 0, 1], 1394)),
            no_broadcast: false,
            bridge_board: None,
            drop_rate: 0.0,
            corrupt_rate: 0.0,
            commit_corrupt_writes: false,
            drop_response_rate: 0.0,
            busy_rate: 0.0,
            reset_storm: 0,
            split_timeout_ms: 2000,
            unplug_board: None,
            mute_board: None,
            faults: None,
            fault_at_ms: 5000,
            fault_after_requests: None,
            fw_cdev: None,
            cpu_latency: CpuLatencyRequest::Microseconds(0),
            duration_s: 0.0,
            network: Network::Bridge,
            eth_base: Ipv4Addr::new(127, 0, 0, 100),
            multicast: false,
            chain: Vec::new(),
            detail: served.detail,
        }
    }
}

impl EmulateRequest {
    /// The robot configuration the request names (`config`, loaded, or
    /// `robot`'s preset), if any. `say` gets the loader's warnings
    /// (`warning: ...`) and what the mapping to plants notes (`note: ...`;
    /// not for Snake nodes, which map one to one), one line each.
    ///
    /// # Errors
    /// The configuration cannot be loaded; [`Refused`] for MAHRU.
    pub fn config(&self, say: &mut dyn FnMut(&str)) -> Result<Option<IoConfig>, ServeError> {
        let config = match (&self.config, self.robot) {
            (Some(path), _) => {
                let loaded = IoConfig::load_with_warnings(path)?;
                for w in &loaded.warnings {
                    say(&format!("warning: {w}"));
                }
                Some(loaded.config)
            }
            (None, Some(robot)) => Some(robot_preset(robot)?),
            (None, None) => None,
        };
        for config in config.iter().filter(|c| !is_snake_config(c)) {
            for note in crate::plant_map::notes(config) {
                say(&format!("note: {note}"));
            }
        }
        Ok(config)
    }

    /// The boards the request asks for, `config`'s or generic ones (the one
    /// place the board options are read, for every front end).
    pub fn served_boards(&self, config: Option<IoConfig>) -> ServedBoards {
        ServedBoards {
            config,
            boards: self.boards,
            hardware: self.hardware,
            firmware: self.firmware,
            fpga: self.fpga,
            board_set: self.board_set.clone(),
            commit_corrupt_writes: self.commit_corrupt_writes,
            seed: self.seed,
            faults: BusFaults {
                drop_rate: self.drop_rate,
                corrupt_rate: self.corrupt_rate,
                drop_response_rate: self.drop_response_rate,
                busy_rate: self.busy_rate,
                reset_storm: self.reset_storm,
                unplug_board: self.unplug_board,
                mute_board: self.mute_board,
                plan: self.faults.clone().unwrap_or_default(),
            },
            fault_at: SimDuration::from_micros(self.fault_at_ms.saturating_mul(1000)),
            fault_after_requests: self.fault_after_requests,
            bridge_board: self.bridge_board,
            split_timeout: SimDuration::from_millis(self.split_timeout_ms),
            detail: self.detail,
        }
    }

    /// The /dev/fw* twin of the request's boards and their IDs (`say` as
    /// for [`config`](Self::config)).
    ///
    /// # Errors
    /// As [`config`](Self::config); the boards cannot be assembled.
    pub fn twin(&self, say: &mut dyn FnMut(&str)) -> Result<(Twin, Vec<u8>), ServeError> {
        Ok(self.served_boards(self.config(say)?).twin()?)
    }

    /// The boards with their server bound, as the request asks: the
    /// Ethernet-only network (`network` eth), the /dev/fw* twin on its
    /// socket (`fw_cdev`) or the bridge; its stop flag set by SIGINT,
    /// SIGTERM or after `duration_s`, and the `cpu_latency` request held
    /// while it lives. `say` gets the lines for the user that are not the
    /// banner (see [`config`](Self::config); a listening address that is
    /// not loopback).
    ///
    /// # Errors
    /// An option the chosen network cannot honour ([`Refused`]), the
    /// configuration, the boards, a socket or the signal handlers.
    pub fn open(&self, say: &mut dyn FnMut(&str)) -> Result<Emulation, ServeError> {
        // (The command line's parser bounds it; a request made in code
        // is checked here, before anything is bound.)
        self.run_length()?;
        if self.network == Network::Eth {
            return self.open_eth(say);
        }
        if !self.chain.is_empty() {
            return Err(Refused {
                option: "--chain",
                reason: "belongs to the Ethernet-only network: add --network eth --fpga V3 --firmware 9",
            }
            .into());
        }
        if let Some(path) = &self.fw_cdev {
            return self.open_twin(path, say);
        }
        if !self.listen.ip().is_loopback() {
            say(&format!(
                "firelink emulate: WARNING: listening on udp {}, not loopback: anyone who can \
                 reach it can switch the emulated boards' motor power on and move their motors \
                 (the boards' protocol has no token)",
                self.listen
            ));
        }
        let served = self.served_boards(self.config(say)?).bridge()?;
        let server = BridgeServer::open(
            served,
            self.firmware,
            self.listen,
            !self.no_broadcast,
            self.multicast,
        )?;
        let (stop, cpu_latency) = self.stop_and_latency()?;
        let mut banner = server.banner().to_vec();
        banner.extend(cpu_latency.line.clone());
        banner.extend(server.multicast_line()?);
        Ok(Emulation {
            server: Server::Bridge(Box::new(server)),
            banner,
            stop,
            _cpu_latency: cpu_latency,
        })
    }

    /// How long to serve: `None` until stopped (`duration_s` 0).
    ///
    /// # Errors
    /// [`Refused`] a negative, not finite or too large `duration_s`.
    fn run_length(&self) -> Result<Option<Duration>, Refused> {
        if self.duration_s == 0.0 {
            return Ok(None);
        }
        match Duration::try_from_secs_f64(self.duration_s) {
            Ok(d) => Ok(Some(d)),
            Err(_) => Err(Refused {
                option: "--duration-s",
                reason: "must be 0 (serve until stopped) or a finite number of seconds above 0",
            }),
        }
    }

    /// The stop flag (SIGINT, SIGTERM, `duration_s`), then the CPU latency
    /// request, as every server takes them once bound.
    fn stop_and_latency(&self) -> Result<(Arc<AtomicBool>, CpuLatencyNote), ServeError> {
        let stop = server_stop_flag(self.run_length()?)?;
        Ok((stop, CpuLatencyNote::take(self.cpu_latency.microseconds())))
    }

    /// The twin, bound at `path`.
    fn open_twin(
        &self,
        path: &std::path::Path,
        say: &mut dyn FnMut(&str),
    ) -> Result<Emulation, ServeError> {
        let (twin, ids) = self.twin(say)?;
        let listener = fw_cdev::bind(path).map_err(ServeError::TwinSocket)?;
        let (stop, cpu_latency) = self.stop_and_latency()?;
        let mut banner = vec![format!(
            "emulating {} board(s) {:?} as /dev/fw1..fw{} (the PC's card: /dev/fw0); bus generation {}",
            ids.len(),
            ids,
            ids.len(),
            twin.bus().generation()
        )];
        banner.extend(cpu_latency.line.clone());
        Ok(Emulation {
            server: Server::Twin {
                twin: Box::new(twin),
                listener,
                path: path.to_path_buf(),
            },
            banner,
            stop,
            _cpu_latency: cpu_latency,
        })
    }

    /// The Ethernet-only network, its options checked first.
    fn open_eth(&self, say: &mut dyn FnMut(&str)) -> Result<Emulation, ServeError> {
        let asked = EthRequest {
            twin: self.fw_cdev.is_some(),
            snake: self.robot == Some(RobotKind::Snake),
            fault_script: self.faults.is_some(),
        };
        refuse_on_eth(&self.served_boards(None), asked)?;
        let boards = self.served_boards(self.config(say)?).chain(&self.chain)?;
        if !self.eth_base.is_loopback() {
            say(&format!(
                "firelink emulate: WARNING: the boards listen on {} + ID, not loopback: anyone who can \
                 reach them can switch the emulated boards' motor power on and move their motors",
                self.eth_base
            ));
        }
        let server = EthServer::open(
            boards,
            self.eth_base,
            self.listen.port(),
            !self.no_broadcast,
            self.multicast,
        )?;
        let (stop, cpu_latency) = self.stop_and_latency()?;
        let mut banner = server.banner().to_vec();
        banner.extend(cpu_latency.line.clone());
        Ok(Emulation {
            server: Server::Eth(Box::new(server)),
            banner,
            stop,
            _cpu_latency: cpu_latency,
        })
    }
}

/// The served boards with their server bound ([`EmulateRequest::open`]):
/// what to show first, then serving until the stop flag.
pub struct Emulation {
    server: Server,
    banner: Vec<String>,
    stop: Arc<AtomicBool>,
    _cpu_latency: CpuLatencyNote,
}

/// The server of an [`Emulation`].
enum Server {
    Bridge(Box<BridgeServer>),
    Eth(Box<EthServer>),
    Twin {
        twin: Box<Twin>,
        listener: OwnedFd,
        path: PathBuf,
    },
}

impl Emulation {
    /// What is served, one line each: the boards, then what the CPU
    /// latency request took effect as and the multicast group joined
    /// (when asked).
    pub fn banner(&self) -> &[String] {
        &self.banner
    }

    /// Serve until SIGINT, SIGTERM or the request's duration, each server
    /// event to `on_event` (as it happens); the twin's socket file is
    /// removed when it stops.
    ///
    /// # Errors
    /// A socket failed.
    pub fn serve(self, mut on_event: impl FnMut(&dyn Display)) -> std::io::Result<()> {
        let stop = &self.stop;
        match self.server {
            Server::Bridge(mut server) => server.serve(stop, |e| on_event(&e)),
            Server::Eth(mut server) => server.serve(stop, |e| on_event(&e)),
            Server::Twin {
                mut twin,
                listener,
                path,
            } => {
                let served = fw_cdev::serve(&mut twin, &listener, stop, |e| on_event(&e));
                let _ = std::fs::remove_file(&path);
                served
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_request_becomes_the_boards_it_names() {
        let request = EmulateRequest {
            boards: 4,
            seed: 7,
            drop_rate: 0.25,
            mute_board: Some(2),
            fault_at_ms: 1500,
            split_timeout_ms: 30,
            bridge_board: Some(1),
            ..EmulateRequest::default()
        };
        let served = request.served_boards(None);
        assert_eq!(served.boards, 4);
        assert_eq!(served.seed, 7);
        assert_eq!(served.faults.drop_rate, 0.25);
        assert_eq!(served.faults.mute_board, Some(2));
        assert_eq!(served.fault_at, SimDuration::from_millis(1500));
        assert_eq!(served.split_timeout, SimDuration::from_millis(30));
        assert_eq!(served.bridge_board, Some(1));
        // With every default: the served boards' own defaults.
        let defaults = EmulateRequest::default().served_boards(None);
        let expected = ServedBoards::default();
        assert_eq!(defaults.boards, expected.boards);
        assert_eq!(defaults.fault_at, expected.fault_at);
        assert_eq!(defaults.split_timeout, expected.split_timeout);
        assert_eq!(defaults.faults, expected.faults);
    }

    #[test]
    fn a_chain_off_the_eth_network_and_mahru_are_refused_by_name() {
        let error = |request: EmulateRequest| match request.open(&mut |_| {}) {
            Ok(_) => panic!("opened"),
            Err(e) => e.to_string(),
        };
        // A run length the command line's parser would refuse, made in
        // code: refused before anything is bound.
        for duration_s in [f64::INFINITY, f64::NAN, -1.0, 1e300] {
            let e = error(EmulateRequest {
                duration_s,
                ..EmulateRequest::default()
            });
            assert!(
                e.starts_with("--duration-s: must be 0"),
                "{duration_s}: {e}"
            );
        }
        let e = error(EmulateRequest {
            chain: vec![1, 0],
            ..EmulateRequest::default()
        });
        assert!(
            e.starts_with("--chain: belongs to the Ethernet-only network"),
            "{e}"
        );
        let e = error(EmulateRequest {
            robot: Some(RobotKind::Mahru),
            ..EmulateRequest::default()
        });
        assert!(e.starts_with("--robot mahru: "), "{e}");
        // The eth network's own refusals come before anything is bound.
        let e = error(EmulateRequest {
            network: Network::Eth,
            ..EmulateRequest::default()
        });
        assert!(e.starts_with("--network eth: "), "{e}");
        // The packet level is the 1394 bus's; the network has none.
        let e = error(EmulateRequest {
            network: Network::Eth,
            fpga: Some(FpgaVersion::V3),
            firmware: Profile::Rev9,
            detail: Detail::Packet,
            ..EmulateRequest::default()
        });
        assert!(e.starts_with("--detail packet: "), "{e}");
        assert!(e.contains("no 1394 bus"), "{e}");
    }

    #[test]
    fn a_configuration_says_its_plant_notes() {
        let mut lines = Vec::new();
        let request = EmulateRequest {
            robot: Some(RobotKind::Dvrk),
            ..EmulateRequest::default()
        };
        let config = request.config(&mut |l| lines.push(l.to_string())).unwrap();
        assert!(config.is_some());
        assert!(lines.iter().all(|l| l.starts_with("note: ")), "{lines:?}");
        // Snake nodes map one to one: nothing to note.
        lines.clear();
        let snake = EmulateRequest {
            robot: Some(RobotKind::Snake),
            ..EmulateRequest::default()
        };
        assert!(
            snake
                .config(&mut |l| lines.push(l.to_string()))
                .unwrap()
                .is_some()
        );
        assert!(lines.is_empty(), "{lines:?}");
    }

    /// The request's `Default` is the command line's defaults.
    #[cfg(feature = "clap")]
    #[test]
    fn the_default_is_what_the_command_line_gives_with_no_options() {
        use clap::{Args, FromArgMatches};
        let command = EmulateRequest::augment_args(clap::Command::new("emulate"));
        let parsed =
            EmulateRequest::from_arg_matches(&command.get_matches_from(["emulate"])).unwrap();
        assert_eq!(
            format!("{parsed:?}"),
            format!("{:?}", EmulateRequest::default())
        );
    }
}
