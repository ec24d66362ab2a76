//! What every front end of the served boards (`firelink emulate`, its
//! `--network eth` and `--fw-cdev` forms, `fw-run`) decides the same way:
//! the bridge's and the Ethernet-only network's sockets and banners,
//! which options the Ethernet-only network refuses and why, what the
//! firmware is called, and the CPU wake-up latency held while serving;
//! and the one request that names the boards and how to serve them
//! ([`EmulateRequest`], `firelink emulate`'s options), opened into a bound
//! server ([`Emulation`]).

mod request;

pub use request::{EmulateRequest, Emulation, Network};

use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use firelink_board::qla::config::BoardConfig;
use firelink_control::config::{IoConfig, presets};
use firelink_emulate::qla::eth_network::{EthNetwork, NetworkError};
use firelink_emulate::qla::eth_serve::{EthEvent, EthServeConfig, EthSockets, MULTICAST_GROUP};
use firelink_emulate::{Bridge, Event, ServeConfig};
use firelink_host::cpu_latency::CpuLatencyHold;

use crate::emulated::{FpgaVersion, Profile};
use crate::rig::RobotKind;
use crate::rig::served::{ServedBoards, ServedBridge};

/// Why the boards cannot be served as asked.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// An option this network cannot honour.
    #[error(transparent)]
    Refused(#[from] Refused),
    /// Boards that cannot be on the Ethernet-only network.
    #[error(transparent)]
    Network(#[from] NetworkError),
    /// A socket could not be bound or joined (naming which and why).
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// The robot configuration could not be loaded (every problem, with
    /// its path).
    #[error(transparent)]
    Config(#[from] firelink_control::config::ConfigErrors),
    /// The boards cannot be assembled: an option names a board that is
    /// not emulated, or a board's settings are inconsistent.
    #[error(transparent)]
    Served(#[from] crate::rig::served::ServedError),
    /// The /dev/fw* twin's unix socket could not be bound (said after
    /// `output:`, as `firelink emulate --fw-cdev` always has).
    #[error("output: {0}")]
    TwinSocket(std::io::Error),
}

/// The bridge with its sockets bound: ready to serve.
pub struct BridgeServer {
    bridge: Bridge,
    unicast: UdpSocket,
    broadcast: Option<UdpSocket>,
    multicast: Option<UdpSocket>,
    banner: Vec<String>,
}

impl BridgeServer {
    /// Bind the bridge of `served` at `listen` (and the loopback broadcast
    /// address when `loopback_broadcast`; the Rev 9 host's multicast group
    /// when `multicast`).
    ///
    /// # Errors
    /// [`Refused`] `--multicast` below firmware Rev 9; a socket could not
    /// be bound or the group joined.
    pub fn open(
        served: ServedBridge,
        firmware: Profile,
        listen: SocketAddr,
        loopback_broadcast: bool,
        multicast: bool,
    ) -> Result<Self, ServeError> {
        let ServedBridge {
            bridge,
            kind,
            ids,
            boards,
        } = served;
        if multicast && !bridge.takes_multicast() {
            return Err(Refused {
                option: "--multicast",
                reason: "a bridge takes the host's group requests from firmware Rev 9 on: add \
                         --firmware 9 (or --network eth --fpga V3 --firmware 9)",
            }
            .into());
        }
        let config = ServeConfig {
            listen,
            loopback_broadcast,
        };
        let (unicast, broadcast) = firelink_emulate::bind(&config)?;
        let multicast = if multicast {
            let port = unicast.local_addr()?.port();
            Some(
                firelink_emulate::bind_multicast(MULTICAST_GROUP, port).map_err(|e| {
                    std::io::Error::new(
                        e.kind(),
                        format!(
                            "--multicast: cannot join {MULTICAST_GROUP}:{port} ({e}); the group \
                             needs a multicast route, e.g. on lo inside a network namespace"
                        ),
                    )
                })?,
            )
        } else {
            None
        };
        let mut banner = vec![format!(
            "emulating {} board(s) {:?} at firmware {}; bus generation {}",
            ids.len(),
            ids,
            firmware_name(kind, firmware),
            bridge.generation()
        )];
        banner.extend(boards.iter().map(|b| board_line(b, true)));
        Ok(BridgeServer {
            bridge,
            unicast,
            broadcast,
            multicast,
            banner,
        })
    }

    /// What is served: one line, then one per board.
    pub fn banner(&self) -> &[String] {
        &self.banner
    }

    /// The line saying the multicast group was joined, if it was.
    ///
    /// # Errors
    /// The socket's address cannot be read.
    pub fn multicast_line(&self) -> std::io::Result<Option<String>> {
        self.multicast
            .as_ref()
            .map(|group| {
                Ok(format!(
                    "joined multicast group {} (the Rev 9 host's Ethernet broadcasts)",
                    group.local_addr()?
                ))
            })
            .transpose()
    }

    /// Serve until `stop` is set, each event to `on_event`.
    ///
    /// # Errors
    /// A socket failed.
    pub fn serve(
        &mut self,
        stop: &Arc<AtomicBool>,
        on_event: impl FnMut(Event),
    ) -> std::io::Result<()> {
        let groups: Vec<&UdpSocket> = self.broadcast.iter().chain(self.multicast.iter()).collect();
        firelink_emulate::serve_groups(&mut self.bridge, &self.unicast, &groups, stop, on_event)
    }
}

/// The Ethernet-only network with its sockets bound: ready to serve.
pub struct EthServer {
    net: EthNetwork,
    sockets: EthSockets,
    banner: Vec<String>,
}

impl EthServer {
    /// Bind `boards` (in chain order) at `base` + board ID on `port` (and
    /// the loopback broadcast address, the multicast group when asked).
    ///
    /// # Errors
    /// The boards cannot be on the network; a socket could not be bound.
    pub fn open(
        boards: Vec<BoardConfig>,
        base: Ipv4Addr,
        port: u16,
        loopback_broadcast: bool,
        multicast: bool,
    ) -> Result<Self, ServeError> {
        let lines: Vec<String> = boards.iter().map(|b| board_line(b, false)).collect();
        let net = EthNetwork::new(boards, Default::default())?;
        let ids = net.board_ids();
        let config = EthServeConfig {
            base,
            port,
            loopback_broadcast,
            multicast: multicast.then_some(MULTICAST_GROUP),
        };
        let sockets = firelink_emulate::qla::eth_serve::eth_bind(&config, &ids)?;
        let mut banner = vec![format!(
            "emulating {} board(s) on the Ethernet-only network, chain from the host {:?} (hub: board {})",
            ids.len(),
            ids,
            ids.first().copied().unwrap_or(0)
        )];
        banner.extend(lines);
        Ok(EthServer {
            net,
            sockets,
            banner,
        })
    }

    /// What is served: one line, then one per board.
    pub fn banner(&self) -> &[String] {
        &self.banner
    }

    /// Serve until `stop` is set, each event to `on_event`.
    ///
    /// # Errors
    /// A socket failed.
    pub fn serve(
        &mut self,
        stop: &Arc<AtomicBool>,
        on_event: impl FnMut(EthEvent),
    ) -> std::io::Result<()> {
        firelink_emulate::qla::eth_serve::eth_serve(&mut self.net, &self.sockets, stop, on_event)
    }
}

/// An option the Ethernet-only network cannot take: the option and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{option}: {reason}")]
pub struct Refused {
    /// The option, as the command line spells it.
    pub option: &'static str,
    /// Why, and what to do instead.
    pub reason: &'static str,
}

/// What the front end asks besides the boards: the /dev/fw* twin, the
/// Snake robot, and a fault script (even an empty one).
#[derive(Debug, Clone, Copy, Default)]
pub struct EthRequest {
    /// `--fw-cdev`.
    pub twin: bool,
    /// `--robot snake`.
    pub snake: bool,
    /// `--faults` given.
    pub fault_script: bool,
}

/// The first option of `boards` and `asked` that the Ethernet-only
/// network (FPGA V3 boards at firmware Rev 9, no 1394 bus) cannot take.
///
/// # Errors
/// [`Refused`] naming the option and why.
pub fn refuse_on_eth(boards: &ServedBoards, asked: EthRequest) -> Result<(), Refused> {
    let bus_fault = "a fault of the simulated 1394 bus; the Ethernet-only network has no 1394 bus";
    let f = &boards.faults;
    let refusals: [(bool, &'static str, &'static str); 12] = [
        (
            asked.twin,
            "--fw-cdev",
            "the /dev/fw* twin is the FireWire front end, not the Ethernet-only network",
        ),
        (
            boards.bridge_board.is_some(),
            "--bridge-board",
            "the Ethernet-only network has no bridge: every board has its own address (the hub is the first of --chain)",
        ),
        (
            asked.snake,
            "--robot snake",
            "the Snake nodes are seed 001's FireWire nodes, not FPGA V3 boards",
        ),
        (f.drop_rate > 0.0, "--drop-rate", bus_fault),
        (f.corrupt_rate > 0.0, "--corrupt-rate", bus_fault),
        (
            f.drop_response_rate > 0.0,
            "--drop-response-rate",
            bus_fault,
        ),
        (f.busy_rate > 0.0, "--busy-rate", bus_fault),
        (f.reset_storm > 0, "--reset-storm", bus_fault),
        (f.unplug_board.is_some(), "--unplug-board", bus_fault),
        (f.mute_board.is_some(), "--mute-board", bus_fault),
        (asked.fault_script, "--faults", bus_fault),
        (
            boards.detail == firelink_bus::Detail::Packet,
            "--detail packet",
            "a level of detail of the simulated 1394 bus; the Ethernet-only network has no 1394 bus (its chain's timing is worked out per datagram)",
        ),
    ];
    if let Some((_, option, reason)) = refusals.into_iter().find(|r| r.0) {
        return Err(Refused { option, reason });
    }
    if boards.fpga != Some(FpgaVersion::V3) || boards.firmware != Profile::Rev9 {
        return Err(Refused {
            option: "--network eth",
            reason: "the Ethernet-only network is FPGA V3 boards at firmware Rev 9: add --fpga V3 --firmware 9",
        });
    }
    Ok(())
}

/// The configuration `firelink emulate --robot` serves: the robot's seed
/// configuration; MAHRU is refused (its modules speak seed 002's own
/// protocol, not the bridge's).
///
/// # Errors
/// [`Refused`] for MAHRU.
pub fn robot_preset(robot: RobotKind) -> Result<IoConfig, Refused> {
    match robot {
        RobotKind::Dvrk => Ok(presets::dvrk_seed000()),
        RobotKind::Snake => Ok(presets::snake_seed001()),
        RobotKind::Mahru => Err(Refused {
            option: "--robot mahru",
            reason: "the MAHRU modules speak seed 002's own protocol, not the FPGA1394 \
                     bridge's; run `firelink demo --robot mahru`",
        }),
    }
}

/// The firmware's name in the banner: the Snake node's, or the QLA
/// board's revision.
pub fn firmware_name(kind: RobotKind, firmware: Profile) -> &'static str {
    match firmware {
        _ if kind == RobotKind::Snake => "seed 001 Snake node",
        Profile::Rev7 => "Rev 7",
        Profile::Rev8 => "Rev 8",
        Profile::Rev9 => "Rev 9",
        Profile::Seed => "seed 000",
    }
}

/// One board in the banner: ID, hardware, serials, FPGA and firmware;
/// with `bridge`, also its motor supply and its instrument (the bridge's
/// banner shows them, the Ethernet-only network's does not).
pub fn board_line(b: &BoardConfig, bridge: bool) -> String {
    let mut line = format!(
        "  board {}: {}, FPGA serial {}, QLA serial {}",
        b.board_id,
        b.hardware.hardware_version().name(),
        b.fpga_serial,
        b.qla_serials().join(" / ")
    );
    if bridge {
        line.push_str(&format!(", motor supply {} V", b.motor_supply_volts));
    }
    line.push_str(&format!(
        ", FPGA V{}, Rev {}",
        b.fpga.number(),
        b.firmware.number()
    ));
    if let Some(i) = b.instrument.as_ref().filter(|_| bridge) {
        line.push_str(&format!(", instrument {} ({})", i.model, i.name));
    }
    line
}

/// The `--cpu-latency` request while serving: held until this drops, and
/// the line that says what took effect (a refusal is a note: the boards
/// are served all the same).
pub struct CpuLatencyNote {
    _hold: Option<CpuLatencyHold>,
    /// What took effect, for the banner; `None` when nothing was asked.
    pub line: Option<String>,
}

impl CpuLatencyNote {
    /// Hold every CPU's wake-up latency at `latency_us` microseconds, or
    /// ask nothing (`None`).
    pub fn take(latency_us: Option<u32>) -> Self {
        let Some(latency_us) = latency_us else {
            return Self {
                _hold: None,
                line: None,
            };
        };
        match CpuLatencyHold::take(u64::from(latency_us)) {
            Ok(hold) => Self {
                line: Some(hold.describe()),
                _hold: Some(hold),
            },
            Err(e) => Self {
                _hold: None,
                line: Some(format!(
                    "note: {e}; serving all the same (a host and the emulator on different \
                     idle CPUs may then wait tens of microseconds per hand-over; \
                     --cpu-latency off silences this)"
                )),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rig::served::BusFaults;

    fn eth_boards() -> ServedBoards {
        ServedBoards {
            fpga: Some(FpgaVersion::V3),
            firmware: Profile::Rev9,
            ..ServedBoards::default()
        }
    }

    #[test]
    fn the_eth_network_takes_v3_boards_at_rev_9_without_bus_faults() {
        assert_eq!(refuse_on_eth(&eth_boards(), EthRequest::default()), Ok(()));
        let rev8 = ServedBoards {
            firmware: Profile::Rev8,
            ..eth_boards()
        };
        let e = refuse_on_eth(&rev8, EthRequest::default()).unwrap_err();
        assert_eq!(e.option, "--network eth");
        let faulty = ServedBoards {
            faults: BusFaults {
                busy_rate: 0.1,
                ..BusFaults::default()
            },
            ..eth_boards()
        };
        let e = refuse_on_eth(&faulty, EthRequest::default()).unwrap_err();
        assert_eq!(e.option, "--busy-rate");
        // The first refusal in the options' order is the one reported.
        let asked = EthRequest {
            twin: true,
            snake: true,
            fault_script: true,
        };
        let e = refuse_on_eth(&faulty, asked).unwrap_err();
        assert_eq!(e.to_string().split(':').next(), Some("--fw-cdev"));
    }

    #[test]
    fn firmware_names() {
        assert_eq!(firmware_name(RobotKind::Dvrk, Profile::Rev9), "Rev 9");
        assert_eq!(
            firmware_name(RobotKind::Snake, Profile::Rev8),
            "seed 001 Snake node"
        );
    }
}
