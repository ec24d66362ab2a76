//! Discovery: find the boards behind a port, learn what they are, build the
//! board <-> node map and pick the best I/O protocol they all support.
//!
//! The order follows what the reference host does over the bridge
//! (`fpga-board.md` §8): first the Ethernet-connected board itself through a
//! broadcast no-forward read (ports without a bridge simply fail that read),
//! then per candidate node HW_VERSION (nodes that do not answer are skipped),
//! FW_VERSION, ETH_STATUS, STATUS (board ID) and GIT_DESC.
//!
//! The broadcast protocol needs every selected board's block in one hub
//! memory (512 quadlets) and one read response. When all the boards'
//! blocks do not fit (16 QLA1 Rev 8 boards need 529 quadlets), the boards
//! are split into the fewest *broadcast groups* whose hub blocks fit
//! ([`broadcast_groups`]): each cycle sends one query per group (its board
//! mask selects who answers, `fpga-board.md` §6.1) and reads that group's
//! hub block before the next query, then one command block to all boards.

use firelink_wire::packet::Speed;
use firelink_wire::qla::address::{BoardRegister, HUB_MEMORY_QUADLETS, Register};
use firelink_wire::qla::broadcast::hub_block_quadlets;
use firelink_wire::qla::realtime::{BlockFormat, BoardLayout, FirmwareRev};
use firelink_wire::qla::registers::{FpgaVersion, GitDesc, HardwareVersion, StatusRead};

use crate::error::{HostError, Result};
use crate::port::{Dest, Port};
use crate::qla::board::BoardInfo;

/// The three I/O protocols, in increasing efficiency.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Protocol {
    /// One block read and one block write per board per cycle (seed 000's
    /// baseline).
    #[cfg_attr(
        feature = "clap",
        value(alias = "seq", help = "One block read and one block write per board")
    )]
    Sequential,
    /// One block read per board, then one broadcast write of all commands.
    #[cfg_attr(feature = "clap", value(alias = "seq-bc", alias = "seqrbw"))]
    SequentialReadBroadcastWrite,
    /// Query, wait, one hub read, one broadcast write (seed 000); the
    /// query, wait and hub read once per group when the boards' blocks
    /// overflow one hub ([`broadcast_groups`]).
    #[cfg_attr(
        feature = "clap",
        value(
            alias = "bcast",
            alias = "bc",
            help = "Query, status broadcasts, one hub read (each per broadcast group when \
                    the boards overflow one hub), one broadcast write"
        )
    )]
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
    /// With the broadcast protocol: the board mask of each query of a
    /// cycle (one group when every block fits one hub), in order; empty
    /// for the other protocols.
    pub broadcast_groups: Vec<u16>,
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
///
/// The broadcast protocol is chosen whenever the boards support it and
/// their hub blocks fit the hub memory in [`broadcast_groups`] (one group,
/// or more when together they would overflow it).
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
    match broadcast_groups(boards).map(|g| g.len()) {
        Some(1) => (
            Protocol::Broadcast,
            "every board supports the broadcast protocol",
        ),
        Some(_) => (
            Protocol::Broadcast,
            "the boards' hub block would exceed the 512-quadlet hub memory: one query per \
             group of boards whose hub block fits",
        ),
        None if format == BlockFormat::Rev4 => (
            Protocol::SequentialReadBroadcastWrite,
            "the hub block would exceed the 512-quadlet hub memory (Rev 4 boards answer \
             every query whatever its board mask)",
        ),
        None => (
            Protocol::SequentialReadBroadcastWrite,
            "a board's hub entry would exceed the 512-quadlet hub memory",
        ),
    }
}

/// The largest hub block one query may fill: the hub memory, and one S400
/// read response.
fn hub_limit_quadlets() -> usize {
    HUB_MEMORY_QUADLETS.min(Speed::S400.max_async_payload() / 4)
}

/// The board masks of the broadcast queries of one cycle: all the boards
/// in one group when their hub block fits the hub memory (and one S400
/// read response), else the fewest groups whose hub blocks each fit, as
/// even as possible (16 QLA1 Rev 8 boards: boards 0-7 and 8-15, 265
/// quadlets each). Groups are ordered by their lowest board ID; a board is
/// in exactly one.
///
/// `None` when the boards cannot run the broadcast protocol from one hub:
/// no boards, a board whose own entry does not fit, or Rev 4 boards (seed
/// 000's firmware answers every query in its TDMA slot whatever the mask,
/// so its hub cannot be split) that do not fit together.
pub fn broadcast_groups(boards: &[BoardInfo]) -> Option<Vec<u16>> {
    let limit = hub_limit_quadlets();
    let all = boards.iter().fold(0u16, |m, b| m | board_bit(b.board_id));
    if boards.is_empty() {
        return None;
    }
    if hub_block_quadlets(boards.iter().map(|b| b.layout)) <= limit {
        return Some(vec![all]);
    }
    if boards
        .iter()
        .any(|b| b.layout.format() == BlockFormat::Rev4)
    {
        return None;
    }
    // Each group's hub: its entries, then the timing quadlet (Rev 7+).
    let capacity = limit.checked_sub(hub_block_quadlets(core::iter::empty()))?;
    let costs: Vec<usize> = boards
        .iter()
        .map(|b| b.layout.broadcast_quadlets())
        .collect();
    let assignment = pack_fewest(&costs, capacity)?;
    let groups = assignment.iter().copied().max().map_or(0, |g| g + 1);
    let mut masks = vec![0u16; groups];
    for (board, &g) in boards.iter().zip(&assignment) {
        if let Some(m) = masks.get_mut(g) {
            *m |= board_bit(board.board_id);
        }
    }
    masks.retain(|&m| m != 0);
    masks.sort_by_key(|m| m.trailing_zeros());
    // Every group fits (the packing's invariant, checked on the real sizes).
    let fits = masks.iter().all(|&m| {
        hub_block_quadlets(
            boards
                .iter()
                .filter(|b| m & board_bit(b.board_id) != 0)
                .map(|b| b.layout),
        ) <= limit
    });
    fits.then_some(masks)
}

fn board_bit(id: u8) -> u16 {
    1u16.checked_shl(u32::from(id)).unwrap_or(0)
}

/// Steps one packing search may take before it gives up (an exotic mix of
/// block sizes): the caller then tries a larger capacity or one more group,
/// so the answer stays valid, perhaps less even.
const PACK_BUDGET: u32 = 200_000;

/// Assign items of `costs` to the fewest groups of at most `capacity`
/// each, as even as possible: for each group count from the lower bound,
/// the smallest largest group that a search finds. Returns each item's
/// group; `None` when an item alone exceeds `capacity`.
fn pack_fewest(costs: &[usize], capacity: usize) -> Option<Vec<usize>> {
    let largest = costs.iter().copied().max()?;
    if largest > capacity {
        return None;
    }
    let total: usize = costs.iter().sum();
    let mut order: Vec<usize> = (0..costs.len()).collect();
    // Largest first; equal sizes in board order (stable sort).
    order.sort_by_key(|&i| core::cmp::Reverse(costs.get(i).copied().unwrap_or(0)));
    let first = total.div_ceil(capacity).max(1);
    for groups in first..=costs.len() {
        if pack(costs, &order, groups, capacity).is_none() {
            continue;
        }
        // The smallest capacity that still packs into `groups`.
        let (mut lo, mut hi) = (total.div_ceil(groups).max(largest), capacity);
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if pack(costs, &order, groups, mid).is_some() {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        return pack(costs, &order, groups, hi);
    }
    None
}

/// One packing of the items (visited in `order`) into `groups` groups of
/// at most `capacity`: a depth-first search that tries each distinct group
/// load once (groups of equal load are interchangeable) and gives up when
/// what remains cannot fit what is free, or after [`PACK_BUDGET`] steps.
fn pack(costs: &[usize], order: &[usize], groups: usize, capacity: usize) -> Option<Vec<usize>> {
    struct Search<'a> {
        costs: &'a [usize],
        order: &'a [usize],
        capacity: usize,
        loads: Vec<usize>,
        assign: Vec<usize>,
        steps: u32,
    }
    impl Search<'_> {
        fn place(&mut self, k: usize, remaining: usize) -> bool {
            let Some(&item) = self.order.get(k) else {
                return true;
            };
            self.steps += 1;
            if self.steps > PACK_BUDGET {
                return false;
            }
            let free: usize = self
                .loads
                .iter()
                .map(|l| self.capacity.saturating_sub(*l))
                .sum();
            if remaining > free {
                return false;
            }
            let cost = self.costs.get(item).copied().unwrap_or(0);
            for g in 0..self.loads.len() {
                let load = self.loads.get(g).copied().unwrap_or(usize::MAX);
                if load.saturating_add(cost) > self.capacity || self.loads[..g].contains(&load) {
                    continue;
                }
                self.loads[g] = load + cost;
                if let Some(a) = self.assign.get_mut(item) {
                    *a = g;
                }
                if self.place(k + 1, remaining - cost) {
                    return true;
                }
                self.loads[g] = load;
            }
            false
        }
    }
    let mut search = Search {
        costs,
        order,
        capacity,
        loads: vec![0; groups],
        assign: vec![0; costs.len()],
        steps: 0,
    };
    let total = costs.iter().sum();
    search.place(0, total).then_some(search.assign)
}

/// A board mask as board IDs and runs of them: `0-7`, `0, 2, 5-7`.
pub fn mask_boards(mask: u16) -> String {
    let mut out = String::new();
    let mut id = 0u32;
    while id < 16 {
        if mask & (1 << id) == 0 {
            id += 1;
            continue;
        }
        let start = id;
        while id + 1 < 16 && mask & (1 << (id + 1)) != 0 {
            id += 1;
        }
        if !out.is_empty() {
            out.push_str(", ");
        }
        if id > start {
            out.push_str(&format!("{start}-{id}"));
        } else {
            out.push_str(&format!("{start}"));
        }
        id += 1;
    }
    out
}

/// How a protocol runs, for reports: its [`name`](Protocol::name), and for
/// the broadcast protocol in more than one group the group count
/// (`broadcast, 2 groups`).
pub fn protocol_label(protocol: Protocol, groups: usize) -> String {
    match protocol {
        Protocol::Broadcast if groups > 1 => format!("{}, {groups} groups", protocol.name()),
        _ => protocol.name().to_string(),
    }
}

impl ScanReport {
    /// The chosen protocol as reports name it ([`protocol_label`]).
    pub fn protocol_label(&self) -> String {
        protocol_label(self.protocol, self.broadcast_groups.len())
    }
}

/// Find every board behind `port`.
///
/// Each candidate node's identity registers are read in turn. When an
/// answer arrived after its time-out (counted `late` in the port's
/// [`link_stats`](Port::link_stats)), the nodes that seemed silent are
/// asked again, up to three rounds in all, so that a board that was only
/// slow is found, not dropped. A port counts a late answer while it waits
/// for a later request, so the last node asked is not found this way (no
/// request follows it: a scan with no late answer sends exactly the
/// requests it always sent); and a late answer to anything else in the
/// scan (the bridge's own identity) also makes the silent nodes asked
/// again.
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
    let mut to_ask: Vec<u8> = port.candidate_nodes().collect();
    // A late answer means a node took longer than the port's time-out:
    // the nodes that seemed silent are asked again, so that a board that
    // was only slow is found rather than dropped. A round in which no new
    // late answer came ends it; at most this many rounds in all.
    const ROUNDS: usize = 3;
    for round in 0..ROUNDS {
        let late_before = port.link_stats().late;
        for node in std::mem::take(&mut to_ask) {
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
        let late_seen = port.link_stats().late > late_before;
        if silent_nodes.is_empty() || !late_seen || round + 1 == ROUNDS {
            break;
        }
        to_ask = std::mem::take(&mut silent_nodes);
    }
    if boards.is_empty() {
        return Err(HostError::NoBoards {
            seen: port.link_stats().since(&before),
        });
    }
    boards.sort_by_key(|b| b.board_id);
    let (protocol, protocol_reason) = best_protocol(&boards);
    let broadcast_groups = match protocol {
        Protocol::Broadcast => broadcast_groups(&boards).unwrap_or_default(),
        _ => Vec::new(),
    };
    Ok(ScanReport {
        boards,
        silent_nodes,
        unsupported,
        duplicate_ids,
        bridge_board,
        protocol,
        protocol_reason,
        broadcast_groups,
        generation: port.generation(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_wire::qla::registers::FpgaVersion;

    fn board(id: u8, layout: BoardLayout) -> BoardInfo {
        BoardInfo {
            board_id: id,
            node: id,
            hardware: HardwareVersion::Qla1,
            firmware: layout.firmware().number(),
            fpga: FpgaVersion::V2,
            git: GitDesc::default(),
            layout,
        }
    }

    fn boards(n: u8, layout: BoardLayout) -> Vec<BoardInfo> {
        (0..n).map(|id| board(id, layout)).collect()
    }

    fn hub_of(boards: &[BoardInfo], mask: u16) -> usize {
        hub_block_quadlets(
            boards
                .iter()
                .filter(|b| mask & (1 << b.board_id) != 0)
                .map(|b| b.layout),
        )
    }

    /// Each board in exactly one group, every group's hub block fits.
    fn check_partition(boards: &[BoardInfo], groups: &[u16]) {
        let all = boards.iter().fold(0u16, |m, b| m | (1 << b.board_id));
        assert_eq!(groups.iter().fold(0, |m, g| m | g), all);
        assert_eq!(
            groups.iter().map(|g| g.count_ones()).sum::<u32>(),
            all.count_ones()
        );
        for &g in groups {
            assert!(hub_of(boards, g) <= HUB_MEMORY_QUADLETS, "{g:#06x}");
        }
    }

    #[test]
    fn sixteen_qla1_rev8_boards_run_the_broadcast_protocol_in_two_even_groups() {
        let b = boards(16, BoardLayout::qla1(FirmwareRev::Rev8));
        assert_eq!(hub_block_quadlets(b.iter().map(|b| b.layout)), 529);
        let groups = broadcast_groups(&b).unwrap();
        assert_eq!(groups, vec![0x00FF, 0xFF00]);
        assert_eq!(hub_of(&b, groups[0]), 265);
        let (protocol, reason) = best_protocol(&b);
        assert_eq!(protocol, Protocol::Broadcast);
        assert!(reason.contains("512-quadlet hub memory"), "{reason}");
        assert_eq!(
            protocol_label(protocol, groups.len()),
            "broadcast, 2 groups"
        );
    }

    #[test]
    fn boards_that_fit_one_hub_make_one_group() {
        for (n, layout) in [
            (1, BoardLayout::qla1(FirmwareRev::Rev8)),
            (15, BoardLayout::qla1(FirmwareRev::Rev8)),
            (16, BoardLayout::qla1(FirmwareRev::Rev7)),
            (8, BoardLayout::dqla(FirmwareRev::Rev8)),
        ] {
            let b = boards(n, layout);
            let all = ((1u32 << n) - 1) as u16;
            assert_eq!(broadcast_groups(&b), Some(vec![all]), "{n}");
            assert_eq!(
                best_protocol(&b),
                (
                    Protocol::Broadcast,
                    "every board supports the broadcast protocol"
                )
            );
            assert_eq!(protocol_label(Protocol::Broadcast, 1), "broadcast");
        }
    }

    #[test]
    fn dqla_and_mixed_sizes_take_the_fewest_groups() {
        // 9 DQLA Rev 8 boards: 9 x 61 + 1 = 550 quadlets; 5 + 4.
        let b = boards(9, BoardLayout::dqla(FirmwareRev::Rev8));
        let groups = broadcast_groups(&b).unwrap();
        assert_eq!(groups.len(), 2);
        check_partition(&b, &groups);
        // 16 DQLA: 977 quadlets, at most 8 per hub: two groups of 8.
        let b = boards(16, BoardLayout::dqla(FirmwareRev::Rev8));
        let groups = broadcast_groups(&b).unwrap();
        assert_eq!(groups, vec![0x00FF, 0xFF00]);
        // Mixed sizes: DQLA 0-1 and 10-15 with QLA1 2-9 (8 x 61 + 8 x 33 +
        // 1 = 753 quadlets): two groups.
        let mixed: Vec<BoardInfo> = (0..16)
            .map(|id| {
                let layout = if (2..10).contains(&id) {
                    BoardLayout::qla1(FirmwareRev::Rev8)
                } else {
                    BoardLayout::dqla(FirmwareRev::Rev8)
                };
                board(id, layout)
            })
            .collect();
        let groups = broadcast_groups(&mixed).unwrap();
        assert_eq!(groups.len(), 2);
        check_partition(&mixed, &groups);
        // As even as possible: the larger group holds at most one block
        // more than half of the entries.
        let larger = groups.iter().map(|&g| hub_of(&mixed, g)).max().unwrap();
        assert!(larger <= 753 / 2 + 61, "{larger}");
        assert_eq!(best_protocol(&mixed).0, Protocol::Broadcast);
    }

    #[test]
    fn packing_finds_the_fewest_groups_where_first_fit_would_not() {
        // Capacity 10, sizes 4 4 6 6 in board order: runs of consecutive
        // boards need three groups ((4 4)(6)(6)); (4 6)(4 6) is two.
        let a = pack_fewest(&[4, 4, 6, 6], 10).unwrap();
        assert_eq!(a.iter().max(), Some(&1));
        let load = |g: usize| -> usize {
            a.iter()
                .zip([4, 4, 6, 6])
                .filter(|(x, _)| **x == g)
                .map(|(_, c)| c)
                .sum()
        };
        assert_eq!((load(0), load(1)), (10, 10));
        // 5 5 4 3 3 into 10: (5 5)(4 3 3), not three groups.
        assert_eq!(
            pack_fewest(&[5, 4, 3, 5, 3], 10).unwrap().iter().max(),
            Some(&1)
        );
        // An item larger than a group cannot be packed.
        assert_eq!(pack_fewest(&[11, 1], 10), None);
        assert_eq!(pack_fewest(&[], 10), None);
    }

    #[test]
    fn rev4_boards_cannot_be_split() {
        // Seed 000's firmware answers every query whatever its mask; 16
        // Rev 4 QLA1 boards fit one hub (16 x 13 quadlets).
        let rev4 = BoardLayout::qla1(FirmwareRev::Rev4);
        let b = boards(16, rev4);
        assert_eq!(broadcast_groups(&b), Some(vec![0xFFFF]));
        // No boards, no queries.
        assert_eq!(broadcast_groups(&[]), None);
    }

    #[test]
    fn masks_read_as_runs_of_board_ids() {
        assert_eq!(mask_boards(0x00FF), "0-7");
        assert_eq!(mask_boards(0xFF00), "8-15");
        assert_eq!(mask_boards(0b1110_0101), "0, 2, 5-7");
        assert_eq!(mask_boards(0x8000), "15");
        assert_eq!(mask_boards(0), "");
    }
}
