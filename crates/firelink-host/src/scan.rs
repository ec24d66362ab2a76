//! Discovery: find the boards behind a port, learn what they are, build the
//! board <-> node map and pick the best I/O protocol they all support.
//!
//! The order follows what the reference host does over the bridge
//! (`fpga-board.md` §8): first the Ethernet-connected board itself through a
//! broadcast no-forward read (ports without a bridge simply fail that read),
//! then per candidate node HW_VERSION (nodes that do not answer are skipped),
//! FW_VERSION, ETH_STATUS, STATUS (board ID) and GIT_DESC.

use firelink_wire::board::address::{BoardRegister, HUB_MEMORY_QUADLETS, Register};
use firelink_wire::board::broadcast::hub_block_quadlets;
use firelink_wire::board::realtime::{BlockFormat, BoardLayout, FirmwareRev};
use firelink_wire::board::registers::{FpgaVersion, GitDesc, HardwareVersion, StatusRead};
use firelink_wire::packet::Speed;

use crate::board::BoardInfo;
use crate::error::{HostError, Result};
use crate::port::{Dest, Port};

/// The three I/O protocols, in increasing efficiency.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Protocol {
    /// One block read and one block write per board per cycle (seed 000's
    /// baseline).
    Sequential,
    /// One block read per board, then one broadcast write of all commands.
    SequentialReadBroadcastWrite,
    /// Query, wait, one hub read, one broadcast write (seed 000).
    Broadcast,
}

impl Protocol {
    /// Stable name used on the command line and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Protocol::Sequential => "sequential",
            Protocol::SequentialReadBroadcastWrite => "sequential-read-broadcast-write",
            Protocol::Broadcast => "broadcast",
        }
    }

    /// Parse a [`name`](Self::name) (also `seq`, `bcast`, `seq-bc`).
    pub fn from_name(name: &str) -> Option<Protocol> {
        match name {
            "sequential" | "seq" => Some(Protocol::Sequential),
            "sequential-read-broadcast-write" | "seq-bc" | "seqrbw" => {
                Some(Protocol::SequentialReadBroadcastWrite)
            }
            "broadcast" | "bcast" | "bc" => Some(Protocol::Broadcast),
            _ => None,
        }
    }
}

/// A node that answered but is not a board this host can drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnsupportedNode {
    /// Physical node ID.
    pub node: u8,
    /// Its HW_VERSION.
    pub hardware: HardwareVersion,
    /// Its FW_VERSION (0 if not read).
    pub firmware: u32,
}

/// Everything a scan found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScanReport {
    /// Boards found, sorted by board ID.
    pub boards: Vec<BoardInfo>,
    /// Candidate nodes that did not answer.
    pub silent_nodes: Vec<u8>,
    /// Nodes that answered with hardware or firmware this host cannot use.
    pub unsupported: Vec<UnsupportedNode>,
    /// Boards whose ID repeats one already found (second and later nodes).
    pub duplicate_ids: Vec<(u8, u8)>,
    /// Board ID of the Ethernet-connected board, when the port is a bridge.
    pub bridge_board: Option<u8>,
    /// The best protocol every board supports.
    pub protocol: Protocol,
    /// Why that protocol (and not a better one).
    pub protocol_reason: &'static str,
    /// Bus generation the scan ran in.
    pub generation: u32,
}

fn reg(r: BoardRegister) -> u64 {
    // Board registers always have an offset (channel 0, offset < 16).
    Register::board(r).offset().unwrap_or(0)
}

/// Read a board's identity registers at `dest`.
fn identify<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
) -> Result<(HardwareVersion, u32, u32, u32, u32)> {
    let hw = port.read_quadlet(dest, reg(BoardRegister::HwVersion))?;
    let fw = port.read_quadlet(dest, reg(BoardRegister::FwVersion))?;
    let eth = port.read_quadlet(dest, reg(BoardRegister::EthStatus))?;
    let status = port.read_quadlet(dest, reg(BoardRegister::Status))?;
    let git = port.read_quadlet(dest, reg(BoardRegister::GitDesc))?;
    Ok((HardwareVersion::from(hw), fw, eth, status, git))
}

/// Choose the best protocol for a set of boards.
pub fn best_protocol(boards: &[BoardInfo]) -> (Protocol, &'static str) {
    if boards.is_empty() {
        return (Protocol::Sequential, "no boards");
    }
    let Some(first) = boards.first() else {
        return (Protocol::Sequential, "no boards");
    };
    // Rev 4 (seed 000's firmware) introduced the broadcast protocol; the
    // revisions between it and Rev 7 are not described.
    if boards
        .iter()
        .any(|b| b.firmware < 7 && b.layout.format() != BlockFormat::Rev4)
    {
        return (Protocol::Sequential, "a board runs firmware before Rev 7");
    }
    let format = first.layout.format();
    if boards.iter().any(|b| b.layout.format() != format) {
        return (
            Protocol::SequentialReadBroadcastWrite,
            "boards mix Rev 7 and Rev 8 block formats",
        );
    }
    let max_payload_quadlets = Speed::S400.max_async_payload() / 4;
    let command_quadlets: usize = boards.iter().map(|b| b.layout.write_block_quadlets()).sum();
    if command_quadlets > max_payload_quadlets {
        return (
            Protocol::Sequential,
            "the command block exceeds one S400 payload",
        );
    }
    let hub = hub_block_quadlets(boards.iter().map(|b| b.layout));
    if hub > HUB_MEMORY_QUADLETS || hub > max_payload_quadlets {
        return (
            Protocol::SequentialReadBroadcastWrite,
            "the hub block would exceed the 512-quadlet hub memory",
        );
    }
    (
        Protocol::Broadcast,
        "every board supports the broadcast protocol",
    )
}

/// Find every board behind `port`.
///
/// # Errors
/// [`HostError::NoBoards`] when nothing answered (with what the port saw
/// instead: silence, garbage, bad CRCs, late or foreign answers);
/// [`HostError::BusReset`] when the bus kept resetting; port errors other than
/// time-outs and bad rcodes of individual nodes (those nodes are reported
/// as silent).
pub fn scan<P: Port + ?Sized>(port: &mut P) -> Result<ScanReport> {
    // A bus reset during the scan renumbers nodes: start again, a few
    // times at most (a bus that keeps resetting is reported as such).
    let mut last = HostError::NoBoards {
        seen: port.link_stats(),
    };
    for _ in 0..4 {
        match scan_once(port) {
            Err(e @ HostError::BusReset { .. }) => last = e,
            other => return other,
        }
    }
    Err(last)
}

fn scan_once<P: Port + ?Sized>(port: &mut P) -> Result<ScanReport> {
    let before = port.link_stats();
    // The Ethernet board itself, if this port is a bridge.
    let bridge_board = match identify(
        port,
        Dest {
            node: 63,
            no_forward: true,
        },
    ) {
        Ok((_, _, _, status, _)) => Some(StatusRead(status).board_id()),
        Err(e @ HostError::BusReset { .. }) => return Err(e),
        Err(_) => None,
    };
    let mut boards: Vec<BoardInfo> = Vec::new();
    let mut silent_nodes = Vec::new();
    let mut unsupported = Vec::new();
    let mut duplicate_ids = Vec::new();
    for node in port.candidate_nodes() {
        let dest = Dest::node(node);
        let (hardware, firmware, eth, status, git) = match identify(port, dest) {
            Ok(id) => id,
            Err(e @ HostError::BusReset { .. }) => return Err(e),
            Err(HostError::Io(kind)) => return Err(HostError::Io(kind)),
            Err(_) => {
                silent_nodes.push(node);
                continue;
            }
        };
        let layout = BoardLayout::for_hardware(hardware, FirmwareRev::from(firmware));
        let fpga = FpgaVersion::from_eth_status(eth);
        let (Some(layout), Ok(fpga)) = (layout, fpga) else {
            unsupported.push(UnsupportedNode {
                node,
                hardware,
                firmware,
            });
            continue;
        };
        let board_id = StatusRead(status).board_id();
        if boards.iter().any(|b| b.board_id == board_id) {
            duplicate_ids.push((board_id, node));
            continue;
        }
        boards.push(BoardInfo {
            board_id,
            node,
            hardware,
            firmware,
            fpga,
            git: GitDesc(git),
            layout,
        });
    }
    if boards.is_empty() {
        return Err(HostError::NoBoards {
            seen: port.link_stats().since(&before),
        });
    }
    boards.sort_by_key(|b| b.board_id);
    let (protocol, protocol_reason) = best_protocol(&boards);
    Ok(ScanReport {
        boards,
        silent_nodes,
        unsupported,
        duplicate_ids,
        bridge_board,
        protocol,
        protocol_reason,
        generation: port.generation(),
    })
}
