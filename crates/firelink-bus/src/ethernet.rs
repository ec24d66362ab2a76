//! The Ethernet-only network of FPGA V3 boards at firmware Rev 9, as a
//! timing model beside the 1394 bus: a daisy chain of 1 Gb/s links through
//! each board's two Ethernet ports and its switch, the host on one end.
//!
//! ```text
//! host ── Eth1 [board a] Eth2 ── Eth1 [board b] Eth2 ── Eth1 [board c]
//!              switch: Eth1, Eth2, PS, RT (the real-time side, EthernetIO)
//! ```
//!
//! What it answers, all in virtual time passed in ([`SimTime`]); nothing
//! here reads a clock or draws a random number:
//! - when a frame the host sends reaches a board's real-time side
//!   ([`EthChain::from_host`]), when a board's frame reaches the host
//!   ([`EthChain::to_host`]), when a board's multicast reaches every other
//!   board ([`EthChain::from_board`]); each link carries one frame at a
//!   time per direction (a frame waits for the link), the switch forwards
//!   after the first [`CUT_THROUGH_BYTES`];
//! - what each switch has learned (the host's port, the ports behind
//!   which other FPGA boards were heard) and so which board is the hub
//!   ([`EthChain::is_hub`]) and the `srcPort` of each request
//!   ([`EthChain::source_port`], bits 6:5 of a reply's extra data);
//! - the broadcast read's hub updates ([`EthChain::hub_updates`]): in
//!   which order, and when, every selected board's status block lands in a
//!   board's hub memory.
//!
//! ## Parameters and their sources
//!
//! | figure | value | source |
//! |---|---|---|
//! | link rate | 1 Gb/s (8 ns a byte) | RTL8211F at 1000 Mb/s; ETH_STATUS speed `10` (FpgaIO.h) |
//! | preamble + SFD | 8 bytes | IEEE 802.3; EthSwitch.v waits for `0xD5` |
//! | MAC header, FCS | 14, 4 bytes | IEEE 802.3; EthernetIO.v `ETH_FRAME_SIZE` |
//! | IPv4, UDP headers | 20, 8 bytes | EthernetIO.v `IPv4_HDR_SIZE`, `UDP_HDR_SIZE` |
//! | minimum frame | 64 bytes (header to FCS) | IEEE 802.3 |
//! | inter-frame gap | 12 bytes | IEEE 802.3; EthSwitch.v's CRC latch relies on it |
//! | cut-through | 14 bytes | EthSwitch.v: a 14-byte FIFO (preamble and destination MAC) before the out-port is chosen |
//! | switch fixed latency | 64 ns (8 clocks at 125 MHz) | modelling choice: the FIFO hand-over between clock domains; no source states it |
//! | request to reply | 1 us | modelling choice: the firmware answers as the request ends (EthernetIO.v `responseRequired`); the time to read registers onto the reply is not stated |
//! | query to own status block in the hub | 3 us | EthBasePort.cpp `WaitBroadcastRead`: 3 us for one board |
//! | each further status block | 38 us | the same formula's slope, `3 + 38 (N - 1)` us measured on a contiguous chain: calibrated, the per-block work behind it is not in the sources |
//!
//! The hub takes the status blocks one at a time in arrival order (its own
//! first, then by distance), each at least [`EthTiming::hub_block_interval`]
//! after the previous: on a contiguous chain of N selected boards the last
//! lands `3 + 38 (N - 1)` us after the query reached the hub, the host's
//! own wait. Entries are therefore in chain order, not board order.
//!
//! Learning (EthSwitch.v): a frame arriving on Eth1 or Eth2 records its
//! source MAC as the host's on that port, and marks the port as leading to
//! an FPGA board when the source is one (the company ID `FA:61:0E`).
//! Boards first hear each other when the host sets their IP address (each
//! then multicasts a raw quadlet write, EthernetIO.v `ipWrite`) and in
//! every broadcast read (`hubSend`). A board whose host port leads to no
//! other FPGA board might be the hub: before any board has been heard,
//! every board that has heard the host is.
//!
//! ```
//! use firelink_bus::ethernet::{EthChain, EthTiming, Framing};
//! use firelink_bus::SimTime;
//! let mut chain = EthChain::new(EthTiming::default(), &[2, 0, 1]).unwrap();
//! // A quadlet read (2 + 16 bytes of UDP payload) to the far board.
//! let at = chain.from_host(SimTime::ZERO, Framing::Udp, 18, Some(1))[0].1;
//! assert!(at > SimTime::from_micros(0));
//! assert_eq!(chain.hub(), Some(2));
//! ```

use crate::time::{SimDuration, SimTime};

/// Bits per second of every link (1000BASE-T).
pub const LINK_BITS_PER_SECOND: u64 = 1_000_000_000;
/// Preamble and start-of-frame delimiter.
pub const PREAMBLE_BYTES: usize = 8;
/// Destination and source MAC, EtherType or length.
pub const MAC_HEADER_BYTES: usize = 14;
/// Frame check sequence.
pub const FCS_BYTES: usize = 4;
/// Smallest frame from MAC header to FCS (shorter ones are padded).
pub const MIN_FRAME_BYTES: usize = 64;
/// Idle time between two frames on one link.
pub const INTERFRAME_GAP_BYTES: usize = 12;
/// IPv4 header without options.
pub const IPV4_HEADER_BYTES: usize = 20;
/// UDP header.
pub const UDP_HEADER_BYTES: usize = 8;
/// Bytes a switch takes in before it forwards (EthSwitch.v's FIFO).
pub const CUT_THROUGH_BYTES: usize = 14;
/// Boards one network can hold (4-bit board IDs).
pub const MAX_BOARDS: usize = 16;

/// A port of a board's switch (EthSwitch.v `INDEX_ETH1` .. `INDEX_RT`; the
/// index is the `srcPort` a reply's extra data carries).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SwitchPort {
    /// The first Ethernet jack (index 0).
    Eth1,
    /// The second Ethernet jack (index 1).
    Eth2,
    /// The Zynq's processor side (index 2).
    Ps,
    /// The real-time side, the board's firmware (index 3).
    Rt,
}

impl SwitchPort {
    /// The switch's index of the port.
    pub fn index(self) -> u8 {
        match self {
            SwitchPort::Eth1 => 0,
            SwitchPort::Eth2 => 1,
            SwitchPort::Ps => 2,
            SwitchPort::Rt => 3,
        }
    }

    /// The other Ethernet jack (the PS and RT ports have none).
    fn other_jack(self) -> Option<SwitchPort> {
        match self {
            SwitchPort::Eth1 => Some(SwitchPort::Eth2),
            SwitchPort::Eth2 => Some(SwitchPort::Eth1),
            SwitchPort::Ps | SwitchPort::Rt => None,
        }
    }

    fn jack(self) -> usize {
        usize::from(self == SwitchPort::Eth2)
    }
}

/// How a frame carries its payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Framing {
    /// IPv4 + UDP (the host's requests, the boards' replies).
    Udp,
    /// Raw Ethernet: the payload right after the MAC header (the boards'
    /// multicast writes, EthernetIO.v `ipWrite` and `hubSend`).
    Raw,
}

impl Framing {
    /// Header bytes between the MAC header and the payload.
    fn overhead(self) -> usize {
        match self {
            Framing::Udp => IPV4_HEADER_BYTES + UDP_HEADER_BYTES,
            Framing::Raw => 0,
        }
    }
}

/// Bytes of the frame that carries `payload` bytes, preamble to FCS
/// (padded to the minimum frame).
pub fn frame_bytes(framing: Framing, payload: usize) -> usize {
    let frame = MAC_HEADER_BYTES + framing.overhead() + payload + FCS_BYTES;
    PREAMBLE_BYTES + frame.max(MIN_FRAME_BYTES)
}

/// Every figure of the model; the defaults are the table in the module
/// docs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EthTiming {
    /// Link rate in bits per second.
    pub link_bits_per_second: u64,
    /// Fixed latency of a switch on top of the cut-through bytes.
    pub switch_latency: SimDuration,
    /// From the end of a request at a board's real-time side to its reply
    /// starting back.
    pub response_latency: SimDuration,
    /// From a query reaching a selected board to its own status block in
    /// its hub memory.
    pub status_ready: SimDuration,
    /// The least time between two status blocks landing in one hub.
    pub hub_block_interval: SimDuration,
}

impl Default for EthTiming {
    fn default() -> Self {
        EthTiming {
            link_bits_per_second: LINK_BITS_PER_SECOND,
            switch_latency: SimDuration::from_nanos(64),
            response_latency: SimDuration::from_micros(1),
            status_ready: SimDuration::from_micros(3),
            hub_block_interval: SimDuration::from_micros(38),
        }
    }
}

impl EthTiming {
    /// Time on the wire of `bytes` bytes.
    pub fn bytes_time(&self, bytes: usize) -> SimDuration {
        SimDuration::from_bits(8 * bytes as u64, self.link_bits_per_second)
    }

    /// Time on the wire of the frame carrying `payload` (no gap).
    pub fn frame_time(&self, framing: Framing, payload: usize) -> SimDuration {
        self.bytes_time(frame_bytes(framing, payload))
    }

    /// What one hop adds before the next link may start: cut-through and
    /// the switch's fixed latency.
    fn hop_latency(&self) -> SimDuration {
        self.bytes_time(CUT_THROUGH_BYTES) + self.switch_latency
    }

    /// The host's own wait for a broadcast read of `boards` boards on a
    /// contiguous chain (EthBasePort.cpp `WaitBroadcastRead`): 3 + 38 (N -
    /// 1) us.
    pub fn host_wait(boards: usize) -> SimDuration {
        SimDuration::from_micros(3 + 38 * boards.saturating_sub(1) as u64)
    }
}

/// Why a chain cannot be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ChainError {
    /// No boards.
    #[error("an Ethernet chain needs at least one board")]
    Empty,
    /// More boards than board IDs.
    #[error("an Ethernet chain holds at most {MAX_BOARDS} boards, {0} given")]
    TooMany(usize),
    /// A board ID above 15.
    #[error("board ID {0} is not 0..=15")]
    BadId(u8),
    /// The same board twice.
    #[error("board {0} appears twice in the chain")]
    Duplicate(u8),
}

/// One board of the chain and what its switch has learned.
#[derive(Debug, Clone, PartialEq, Eq)]
struct ChainBoard {
    id: u8,
    /// The jack cabled toward the host.
    host_side: SwitchPort,
    /// Where the host's MAC was last heard.
    host_port: Option<SwitchPort>,
    /// Per jack, the boards heard on it (bit = board ID).
    fpga_heard: [u16; 2],
}

/// The chain: its boards nearest the host first, what each switch has
/// learned, and until when each link is busy in each direction.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EthChain {
    timing: EthTiming,
    boards: Vec<ChainBoard>,
    /// Link `i` ends at the board at position `i` (link 0 from the host):
    /// free again toward the far end / toward the host.
    away_free: Vec<SimTime>,
    toward_free: Vec<SimTime>,
}

impl EthChain {
    /// The chain of `ids`, nearest the host first, each board's Eth1
    /// toward the host, nothing learned yet.
    ///
    /// # Errors
    /// No boards, more than 16, an ID above 15, an ID twice.
    pub fn new(timing: EthTiming, ids: &[u8]) -> Result<EthChain, ChainError> {
        if ids.is_empty() {
            return Err(ChainError::Empty);
        }
        if ids.len() > MAX_BOARDS {
            return Err(ChainError::TooMany(ids.len()));
        }
        let mut seen = 0u16;
        for &id in ids {
            if usize::from(id) >= MAX_BOARDS {
                return Err(ChainError::BadId(id));
            }
            if seen & (1 << id) != 0 {
                return Err(ChainError::Duplicate(id));
            }
            seen |= 1 << id;
        }
        Ok(EthChain {
            timing,
            boards: ids
                .iter()
                .map(|&id| ChainBoard {
                    id,
                    host_side: SwitchPort::Eth1,
                    host_port: None,
                    fpga_heard: [0; 2],
                })
                .collect(),
            away_free: vec![SimTime::ZERO; ids.len()],
            toward_free: vec![SimTime::ZERO; ids.len()],
        })
    }

    /// The same chain with board `id` cabled the other way round (its Eth2
    /// toward the host); unknown IDs change nothing.
    pub fn with_host_side(mut self, id: u8, port: SwitchPort) -> EthChain {
        if let Some(b) = self.boards.iter_mut().find(|b| b.id == id)
            && port.other_jack().is_some()
        {
            b.host_side = port;
        }
        self
    }

    /// The timing figures.
    pub fn timing(&self) -> &EthTiming {
        &self.timing
    }

    /// Board IDs, nearest the host first.
    pub fn order(&self) -> impl Iterator<Item = u8> + '_ {
        self.boards.iter().map(|b| b.id)
    }

    /// Position of board `id` (0 = nearest the host).
    pub fn position(&self, id: u8) -> Option<usize> {
        self.boards.iter().position(|b| b.id == id)
    }

    /// The switch port through which board `id` hears the host: the
    /// `srcPort` of the replies to the host's requests.
    pub fn source_port(&self, id: u8) -> Option<SwitchPort> {
        self.boards.iter().find(|b| b.id == id).map(|b| b.host_side)
    }

    /// Whether board `id` might be the hub (EthernetIO.v `isHub`): it has
    /// heard the host, and no FPGA board behind the host's port.
    pub fn is_hub(&self, id: u8) -> bool {
        self.boards.iter().find(|b| b.id == id).is_some_and(|b| {
            b.host_port
                .is_some_and(|p| b.fpga_heard.get(p.jack()).is_some_and(|m| *m == 0))
        })
    }

    /// The hub nearest the host, if any board has heard the host.
    pub fn hub(&self) -> Option<u8> {
        self.order().find(|&id| self.is_hub(id))
    }

    /// A frame of `payload` bytes from the host at `now`, to board `to`
    /// (unicast) or every board (`None`: multicast or broadcast): when it
    /// has reached each addressed board's real-time side, in chain order.
    /// Every switch it passes learns the host's port.
    pub fn from_host(
        &mut self,
        now: SimTime,
        framing: Framing,
        payload: usize,
        to: Option<u8>,
    ) -> Vec<(u8, SimTime)> {
        let frame = self.timing.frame_time(framing, payload);
        let gap = self.timing.bytes_time(INTERFRAME_GAP_BYTES);
        let last = match to {
            Some(id) => match self.position(id) {
                Some(p) => p,
                None => return Vec::new(),
            },
            None => self.boards.len() - 1,
        };
        let mut arrivals = Vec::with_capacity(if to.is_some() { 1 } else { last + 1 });
        let mut start = now;
        for (position, board) in self.boards.iter_mut().enumerate().take(last + 1) {
            let free = &mut self.away_free[position];
            start = start.max(*free);
            *free = start + frame + gap;
            board.host_port = Some(board.host_side);
            if to.is_none() || to == Some(board.id) {
                arrivals.push((board.id, start + frame + self.timing.switch_latency));
            }
            start += self.timing.hop_latency();
        }
        arrivals
    }

    /// A frame of `payload` bytes from board `id`'s real-time side at
    /// `now` to the host: when its last byte reaches the host.
    pub fn to_host(&mut self, now: SimTime, framing: Framing, payload: usize, id: u8) -> SimTime {
        let frame = self.timing.frame_time(framing, payload);
        let gap = self.timing.bytes_time(INTERFRAME_GAP_BYTES);
        let Some(from) = self.position(id) else {
            return now;
        };
        let mut start = now + self.timing.switch_latency;
        for position in (0..=from).rev() {
            let free = &mut self.toward_free[position];
            start = start.max(*free);
            *free = start + frame + gap;
            if position > 0 {
                start += self.timing.hop_latency();
            }
        }
        start + frame
    }

    /// A multicast frame of `payload` bytes from board `id`'s real-time
    /// side at `now`: when it reaches every other board's real-time side,
    /// nearest first. Each board it reaches learns on which jack board
    /// `id` is.
    pub fn from_board(
        &mut self,
        now: SimTime,
        framing: Framing,
        payload: usize,
        id: u8,
    ) -> Vec<(u8, SimTime)> {
        let frame = self.timing.frame_time(framing, payload);
        let gap = self.timing.bytes_time(INTERFRAME_GAP_BYTES);
        let Some(from) = self.position(id) else {
            return Vec::new();
        };
        let mut arrivals = Vec::with_capacity(self.boards.len().saturating_sub(1));
        let leave = now + self.timing.switch_latency;
        // Toward the host: link `p` carries it from board p to board p - 1.
        let mut start = leave;
        for position in (1..=from).rev() {
            let free = &mut self.toward_free[position];
            start = start.max(*free);
            *free = start + frame + gap;
            let to = &mut self.boards[position - 1];
            if let Some(jack) = to.host_side.other_jack() {
                to.fpga_heard[jack.jack()] |= 1 << id;
            }
            arrivals.push((to.id, start + frame + self.timing.switch_latency));
            start += self.timing.hop_latency();
        }
        // Away from the host: link `p` carries it from board p - 1 to p.
        let mut start = leave;
        for position in from + 1..self.boards.len() {
            let free = &mut self.away_free[position];
            start = start.max(*free);
            *free = start + frame + gap;
            let to = &mut self.boards[position];
            to.fpga_heard[to.host_side.jack()] |= 1 << id;
            arrivals.push((to.id, start + frame + self.timing.switch_latency));
            start += self.timing.hop_latency();
        }
        arrivals.sort_by_key(|&(_, at)| at);
        arrivals
    }

    /// The broadcast read as board `hub`'s memory sees it (see
    /// [`broadcast_read`](Self::broadcast_read)): the boards in the order
    /// their blocks land in `hub`'s memory, and when each lands.
    pub fn hub_updates(
        &mut self,
        query_at: &[(u8, SimTime)],
        mask: u16,
        block_bytes: usize,
        hub: u8,
    ) -> Vec<(u8, SimTime)> {
        self.broadcast_read(query_at, mask, block_bytes)
            .landings
            .into_iter()
            .find(|l| l.board == hub)
            .map(|l| l.entries)
            .unwrap_or_default()
    }

    /// The broadcast read: the query reached each board at the times in
    /// `query_at`; every board selected by `mask` (and given a time) takes
    /// its `block_bytes`-byte status block [`EthTiming::status_ready`]
    /// after and multicasts it (a raw frame). For every board of
    /// `query_at`: the blocks in the order they land in its hub memory,
    /// when each lands: its own first, then by arrival, one every
    /// [`EthTiming::hub_block_interval`] at the soonest. The multicasts
    /// occupy the links and teach the switches.
    pub fn broadcast_read(
        &mut self,
        query_at: &[(u8, SimTime)],
        mask: u16,
        block_bytes: usize,
    ) -> BroadcastPlan {
        let selected = |id: u8| mask & 1u16.checked_shl(u32::from(id)).unwrap_or(0) != 0;
        let mut ready = Vec::with_capacity(query_at.len());
        let mut reached = Vec::with_capacity(query_at.len());
        for &(id, at) in query_at {
            if !selected(id) {
                continue;
            }
            let t = at + self.timing.status_ready;
            ready.push((id, t));
            reached.push((id, self.from_board(t, Framing::Raw, block_bytes, id)));
        }
        let landings = query_at
            .iter()
            .map(|&(board, _)| {
                let mut arrivals: Vec<(u8, SimTime)> = ready
                    .iter()
                    .zip(&reached)
                    .filter_map(|(&(sender, t), (_, to))| {
                        if sender == board {
                            Some((sender, t))
                        } else {
                            to.iter()
                                .find(|(r, _)| *r == board)
                                .map(|&(_, at)| (sender, at))
                        }
                    })
                    .collect();
                // Its own block first, then by arrival.
                arrivals.sort_by_key(|&(id, t)| (id != board, t));
                let mut previous: Option<SimTime> = None;
                for entry in &mut arrivals {
                    if let Some(p) = previous {
                        entry.1 = entry.1.max(p + self.timing.hub_block_interval);
                    }
                    previous = Some(entry.1);
                }
                HubLanding {
                    board,
                    entries: arrivals,
                }
            })
            .collect();
        BroadcastPlan { ready, landings }
    }
}

/// What one broadcast read does on the chain
/// ([`EthChain::broadcast_read`]).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct BroadcastPlan {
    /// When each selected board takes its status block and multicasts it.
    pub ready: Vec<(u8, SimTime)>,
    /// Per board, the blocks landing in its hub memory.
    pub landings: Vec<HubLanding>,
}

/// The blocks landing in one board's hub memory, in order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HubLanding {
    /// The board whose hub it is.
    pub board: u8,
    /// (sender, when its block lands), in landing order.
    pub entries: Vec<(u8, SimTime)>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chain(ids: &[u8]) -> EthChain {
        EthChain::new(EthTiming::default(), ids).unwrap()
    }

    #[test]
    fn frame_sizes_include_every_header_and_the_minimum() {
        // A quadlet read: 2-byte control word + 16-byte packet, padded to 64.
        assert_eq!(frame_bytes(Framing::Udp, 18), 8 + 64);
        // A Rev 9 QLA1 block read response: 24 + 128 + 8 extra bytes.
        assert_eq!(frame_bytes(Framing::Udp, 160), 8 + 14 + 28 + 160 + 4);
        // A raw hub multicast of a 33-quadlet block: 2 + 24 + 132.
        assert_eq!(frame_bytes(Framing::Raw, 158), 8 + 14 + 158 + 4);
        let t = EthTiming::default();
        assert_eq!(
            t.frame_time(Framing::Udp, 160),
            SimDuration::from_nanos(8 * 214)
        );
    }

    #[test]
    fn the_host_reaches_far_boards_later_by_one_hop_each() {
        let mut c = chain(&[0, 1, 2, 3]);
        let t = *c.timing();
        let all = c.from_host(SimTime::ZERO, Framing::Udp, 18, None);
        assert_eq!(
            all.iter().map(|a| a.0).collect::<Vec<_>>(),
            vec![0, 1, 2, 3]
        );
        let first = t.frame_time(Framing::Udp, 18) + t.switch_latency;
        assert_eq!(all[0].1, SimTime::ZERO + first);
        for w in all.windows(2) {
            assert_eq!(w[1].1 - w[0].1, t.hop_latency());
        }
    }

    #[test]
    fn frames_wait_for_a_busy_link() {
        let mut c = chain(&[0]);
        let t = *c.timing();
        let a = c.from_host(SimTime::ZERO, Framing::Udp, 1000, Some(0))[0].1;
        let b = c.from_host(SimTime::ZERO, Framing::Udp, 18, Some(0))[0].1;
        // The second starts only after the first and its gap.
        let expected = SimTime::ZERO
            + t.frame_time(Framing::Udp, 1000)
            + t.bytes_time(INTERFRAME_GAP_BYTES)
            + t.frame_time(Framing::Udp, 18)
            + t.switch_latency;
        assert_eq!(b, expected);
        assert!(b > a);
        // A reply toward the host uses the other direction: not delayed.
        let up = c.to_host(SimTime::ZERO, Framing::Udp, 28, 0);
        assert_eq!(
            up,
            SimTime::ZERO + t.switch_latency + t.frame_time(Framing::Udp, 28)
        );
    }

    #[test]
    fn learning_makes_the_nearest_board_the_only_hub() {
        let mut c = chain(&[5, 3, 9]);
        assert_eq!(c.hub(), None, "nobody has heard the host");
        c.from_host(SimTime::ZERO, Framing::Udp, 22, None);
        // Before the boards hear each other every one might be the hub.
        assert!(c.is_hub(5) && c.is_hub(3) && c.is_hub(9));
        // Setting the IPs makes each board multicast once.
        for id in [5, 3, 9] {
            c.from_board(SimTime::from_micros(10), Framing::Raw, 22, id);
        }
        assert!(c.is_hub(5));
        assert!(!c.is_hub(3) && !c.is_hub(9));
        assert_eq!(c.hub(), Some(5));
    }

    #[test]
    fn source_port_follows_the_cabling() {
        let c = chain(&[0, 1]).with_host_side(1, SwitchPort::Eth2);
        assert_eq!(c.source_port(0).map(SwitchPort::index), Some(0));
        assert_eq!(c.source_port(1).map(SwitchPort::index), Some(1));
        // A reversed board learns the host and its neighbours on the right jacks.
        let mut c = c;
        c.from_host(SimTime::ZERO, Framing::Udp, 22, None);
        c.from_board(SimTime::ZERO, Framing::Raw, 22, 0);
        c.from_board(SimTime::ZERO, Framing::Raw, 22, 1);
        assert_eq!(c.hub(), Some(0));
        assert!(!c.is_hub(1));
    }

    #[test]
    fn a_contiguous_chain_reproduces_the_hosts_wait() {
        for n in [1usize, 2, 4, 8, 16] {
            let ids: Vec<u8> = (0..n as u8).collect();
            let mut c = chain(&ids);
            let query = c.from_host(SimTime::ZERO, Framing::Udp, 22, None);
            let mask = ((1u32 << n) - 1) as u16;
            let landed = c.hub_updates(&query, mask, 158, 0);
            assert_eq!(landed.len(), n);
            let hub_query = query[0].1;
            let last = landed.last().unwrap().1 - hub_query;
            assert_eq!(last, EthTiming::host_wait(n), "{n} boards");
        }
    }

    #[test]
    fn hub_entries_follow_the_chain_not_the_board_ids() {
        let mut c = chain(&[3, 1, 0, 2]);
        let query = c.from_host(SimTime::ZERO, Framing::Udp, 22, None);
        let landed = c.hub_updates(&query, 0b1111, 158, 3);
        assert_eq!(
            landed.iter().map(|l| l.0).collect::<Vec<_>>(),
            vec![3, 1, 0, 2]
        );
        // Only the selected boards answer.
        let mut c = chain(&[3, 1, 0, 2]);
        let query = c.from_host(SimTime::ZERO, Framing::Udp, 22, None);
        let landed = c.hub_updates(&query, 0b0101, 158, 3);
        assert_eq!(landed.iter().map(|l| l.0).collect::<Vec<_>>(), vec![0, 2]);
    }

    #[test]
    fn the_same_inputs_give_the_same_times() {
        let run = || {
            let mut c = chain(&[4, 2, 7]);
            let q = c.from_host(SimTime::from_micros(5), Framing::Udp, 22, None);
            c.hub_updates(&q, 0xFFFF, 158, 4)
        };
        assert_eq!(run(), run());
    }

    #[test]
    fn bad_chains_are_refused_by_name() {
        assert_eq!(
            EthChain::new(EthTiming::default(), &[]),
            Err(ChainError::Empty)
        );
        assert_eq!(
            EthChain::new(EthTiming::default(), &[16]),
            Err(ChainError::BadId(16))
        );
        assert_eq!(
            EthChain::new(EthTiming::default(), &[1, 1]),
            Err(ChainError::Duplicate(1))
        );
        let many: Vec<u8> = (0..17).collect();
        assert_eq!(
            EthChain::new(EthTiming::default(), &many),
            Err(ChainError::TooMany(17))
        );
    }
}
