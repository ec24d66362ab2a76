//! The board's firmware as a bus-agnostic state machine: link behaviour,
//! registers, real-time blocks, broadcast protocol, watchdog and safety,
//! with the plant integrated underneath.
//!
//! Feed it raw packets as they arrive ([`Firmware::receive`]); it answers
//! like the board's link would ([`Reply`]). Ask it for its own broadcast
//! packets ([`Firmware::poll_transmit`], at or after
//! [`Firmware::next_wakeup`]) and tell it when one went out
//! ([`Firmware::transmitted`]). Time only moves when the caller says so;
//! state between calls is computed exactly (the watchdog fires at its
//! exact expiry even if nothing is received then).
//!
//! Beside the firmware: [`config`], what a board is (board ID, QLA1 or
//! DQLA, firmware profile, FPGA version, axes, seed); [`node`], the
//! firmware as a node on the simulated bus ([`node::BoardNode`]); [`rig`],
//! ready-made buses of such boards.
//!
//! Link behaviour (`fpga-board.md`, `ieee1394.md`, the Rev 8 FireWire.v):
//! - A packet is taken when addressed to this node, to broadcast (63), or
//!   to node 0 at the snooped query (`0x1800`) or command
//!   (`0xFFFF_FFFF_0000`) addresses; only the physical ID is compared,
//!   whatever the bus ID. Only packets addressed to this node are
//!   acknowledged: writes *unified* with `ack_complete`, reads
//!   *concatenated* with `ack_pending` and the response at once. Only
//!   quadlet and block reads and writes are taken: a lock request gets no
//!   acknowledge.
//! - A request for this node whose header CRC fails is acknowledged
//!   `ack_data_error` and gets no response; a data CRC error is answered
//!   `ack_data_error`. Nothing damaged is committed: the firmware writes
//!   such a quadlet write, and a real-time block write as it arrives,
//!   before it knows; Firelink does that only with
//!   [`BoardConfig::commit_corrupt_writes`]. In the seed profile a query
//!   whose header CRC fails is still recognised and answered with
//!   sequence `0xFFFF`.
//! - Every block read up to 2048 bytes is answered complete with exactly
//!   the bytes asked for (0 and part-quadlet lengths included); a block
//!   read of the main space, at any offset, reads the real-time block.
//! - Reads decode the main space from bits 7:0 only (Rev 8: spaces 9-15
//!   read as the main space); `0xFFFF_F000_0400-042C` is the
//!   configuration ROM (Rev 8). Unmapped addresses read 0; writes to them
//!   are acknowledged and ignored (they still refresh the watchdog).
//!
//! Modelling choices where the spec leaves room (each is deliberate):
//! - The watchdog runs from power-up: with no write for 30 ms STATUS bit 23
//!   is set even though no amplifier was on.
//! - One STATUS word may switch power and amplifiers on together (power is
//!   applied first). Amplifiers drive from
//!   `max(request, supply good + 40 ms) + enable delay`; the supply is
//!   good 5 ms (configurable) after power is enabled. The relay's sensed state follows its command.
//! - STATUS's 4-bit amplifier fields cover axes 1-4; on a DQLA, axes 5-8
//!   are enabled and reported through the Rev 8 DAC word and MOTOR_STATUS.
//!   A DQLA reports its second pair of temperature sensors in bits 31:16.
//! - MOTOR_CONFIG's current limit (power-up `0x0418`) is stored, not
//!   applied: the firmware checks it only in voltage control, and voltage
//!   control is not modelled (the plant is driven by current either way);
//!   its delay unit is 1024 clocks (20.83 us).
//! - Rev 7+ chain: a board whose predecessors stay silent transmits anyway
//!   [`CHAIN_TIMEOUT_PER_BOARD`] per missing predecessor after its first
//!   slot. The seed profile answers every query in its TDMA slot whatever
//!   the mask ([`seed_slot`]: clock-exact on Rev 4, seed 000's firmware).
//! - Hub memory holds 512 quadlets: entries that do not fit are dropped
//!   (16 QLA1 Rev 8 boards need 529, so hosts query them in two groups).
//!   Every query restarts the hub from its start whatever its mask, and
//!   every board, selected or not, stores the selected boards' broadcasts.
//!   Quadlets past those written since the query read what the memory
//!   last held there (as `hdl/` does), not 0. A board that missed the
//!   query keeps appending to the previous cycle. Once every selected
//!   board has updated (and before any query), the quadlet after the last
//!   block (register `0x1802`, the quadlets written) reads the timing word
//!   `{bcReadStart, bcTimer}` (HubReg.v): the hub timer, 14 bits wrapping,
//!   when a read last addressed hub quadlet 0, and when that quadlet goes
//!   out (4 clocks per quadlet at S400).
//! - A query with sequence 0 is ignored.
//!
//! ```
//! use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
//! use firelink_board::qla::{Firmware, PhyRegisters, Reply};
//! use firelink_board::time::SimTime;
//! use firelink_wire::packet::{AsyncHeader, NodeId, Packet, PacketRepr, Ack};
//!
//! let mut fw = Firmware::new(BoardConfig::new(3, Hardware::Qla1, Profile::Rev8));
//! let mut phy = PhyRegisters::new(2);
//! fw.bus_reset(SimTime::ZERO, 2, 1);
//! // The host (node 5) reads FW_VERSION (register 7).
//! let req = PacketRepr::ReadQuadletRequest {
//!     header: AsyncHeader::new(NodeId::local(2), NodeId::local(5), 1),
//!     offset: 7,
//! };
//! let mut buf = [0u8; 16];
//! req.emit(&mut buf).unwrap();
//! let Reply::AckThenResponse { ack, response } = fw.receive(SimTime::from_micros(10), &buf, &mut phy) else {
//!     panic!("no response");
//! };
//! assert_eq!(ack, Ack::Pending);
//! let resp = Packet::new_checked(&response[..]).unwrap();
//! assert_eq!(resp.quadlet_data(), 8);
//! ```

mod brake;
pub mod config;
mod dallas;
mod digest;
mod dout;
mod dqla_expander;
mod ethernet;
mod ethernet_v3;
mod expander;
mod hub;
pub mod node;
mod phy;
pub(crate) mod power;
mod prom;
mod registers;
pub mod rig;

pub use brake::{BrakeLine, BrakeWire};
pub use dallas::Instrument;
pub use dout::{OUTPUTS as DIGITAL_OUTPUTS, WAVEFORM_ENTRIES};
pub use ethernet_v3::PHY_RESET_TIME;
pub use hub::{
    CHAIN_TIMEOUT_PER_BOARD, FIRST_SLOT_CLOCKS, SEED_OFFSET, SEED_SLOT, SEED_SLOT_CLOCKS, seed_slot,
};
pub use phy::{PhyAccess, PhyRegisters};
pub use power::{
    DEFAULT_ENABLE_DELAY, ENABLE_DELAY_UNIT_CLOCKS, MISMATCH_AMPS, MISMATCH_TIME, SAFETY_TICK,
    SUPPLY_HOLD, WATCHDOG_POWER_UP_TICKS,
};

use firelink_wire::field::read_quadlet;
use firelink_wire::packet::{
    Ack, AsyncHeader, CrcStatus, NodeId, Packet, PacketRepr, Rcode, Tcode,
};
use firelink_wire::qla::address::{
    COMMAND_SNOOP_OFFSET, HUB_MEMORY_OFFSET, HUB_MEMORY_QUADLETS, HUB_QUERY_OFFSET,
    REALTIME_BLOCK_OFFSET, STATUS_BROADCAST_OFFSET, STATUS_BROADCAST_PRIORITY,
};
use firelink_wire::qla::broadcast::{
    BroadcastHeader, CORRUPT_QUERY_SEQ, Query, status_broadcast_offset,
};
use firelink_wire::qla::registers::PhyData;

use crate::plant::{Plant, QLA_AMPS_PER_BIT};
use crate::time::{SimDuration, SimTime};
use config::{BoardConfig, Profile};
use dallas::Dallas;
use dout::DigitalOutputs;
use dqla_expander::DqlaExpanders;
use ethernet::Ethernet;
use ethernet_v3::EthernetV3;
use expander::Expander;
use firelink_wire::qla::MAX_AXES;
use firelink_wire::qla::realtime::BoardLayout;
use hub::{Hub, HubClock, Pending};
use power::{AxisState, Power, Watchdog};
use prom::{FpgaProm, QlaProm};

/// The MAX7317 expanders of a companion board: ID 0 on a QLA1, IDs 1 and 2
/// (QLA 1 and QLA 2) on a DQLA (DQLA.v).
fn qla_expanders(hardware: &crate::qla::config::Hardware) -> Vec<Expander> {
    match hardware {
        crate::qla::config::Hardware::Qla1 => vec![Expander::new()],
        crate::qla::config::Hardware::Dqla => firelink_wire::qla::dqla::DQLA_MAX7317_IDS
            .iter()
            .map(|&id| Expander::with_id(id))
            .collect(),
    }
}

/// IP_ADDR at power-up: no address assigned (EthernetIO.v `IP_UNASSIGNED`).
pub const IP_UNASSIGNED: u32 = 0xFFFF_FFFF;

/// Largest block read served, bytes (one S400 payload; the firmware's
/// 10-bit quadlet counters; `fpga-board-extras.md` §8). Longer reads are
/// answered with rcode `address_error` and no data.
pub const MAX_BLOCK_READ: usize = 2048;

/// Seed profile: how long after the end of its TDMA slot a status
/// broadcast may still arrive before it counts as late.
pub const SLOT_GRACE: SimDuration = SimDuration::from_micros(2);

/// Largest block write taken, bytes: the firmware's request packet memory
/// holds 512 quadlets, the header (4), its CRC and the data CRC included,
/// leaving 506 quadlets of data (inference; the reference host never
/// writes more: 2024 bytes on FireWire and over loopback UDP). A longer
/// write is refused with `ack_type_error` and nothing is committed.
pub const MAX_BLOCK_WRITE: usize = 2024;

/// Quadlets of the link's received-packet memory (FPGA1394V2.v: space 5
/// reads it).
const PACKET_MEMORY_QUADLETS: usize = 512;

/// The memory the link writes every packet it receives into, from its
/// first quadlet on, header and CRCs included; what a packet does not
/// reach keeps what earlier packets left.
#[derive(Debug, Clone)]
struct PacketMemory(Vec<u8>);

impl PacketMemory {
    fn new() -> PacketMemory {
        PacketMemory(vec![0; PACKET_MEMORY_QUADLETS * 4])
    }

    /// Store a received packet (whole quadlets, as far as the memory goes).
    fn store(&mut self, bytes: &[u8]) {
        let n = (bytes.len() / 4 * 4).min(self.0.len());
        if let (Some(dst), Some(src)) = (self.0.get_mut(..n), bytes.get(..n)) {
            dst.copy_from_slice(src);
        }
    }

    /// Quadlet `index` (address bits 8:0).
    fn quadlet(&self, index: u16) -> u32 {
        firelink_wire::field::read_quadlet(&self.0, usize::from(index) % PACKET_MEMORY_QUADLETS)
    }
}

/// How the board's link answers a packet.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Reply {
    /// No acknowledge (broadcast, snooped, not for us, or a header CRC
    /// error).
    Silent,
    /// An acknowledge only (unified write, or an error ack).
    Ack(Ack),
    /// `ack_pending` followed at once by this response packet
    /// (concatenated read).
    AckThenResponse {
        /// The acknowledge.
        ack: Ack,
        /// The response packet, CRCs filled in (left zero by
        /// [`Firmware::receive_unsealed`], for the bus to write).
        response: Vec<u8>,
    },
}

/// A damaged packet the board noticed (for traces and fault-injection
/// evidence); see [`Firmware::take_rx_error`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RxError {
    /// A header CRC failed: `ack_data_error` if the packet was a request
    /// for this node, otherwise nothing; nothing committed.
    HeaderCrc,
    /// A data CRC failed: `ack_data_error`, nothing committed.
    DataCrc,
    /// A quadlet write whose header CRC failed, committed all the same
    /// ([`BoardConfig::commit_corrupt_writes`](crate::qla::config::BoardConfig::commit_corrupt_writes)).
    HeaderCrcCommitted,
    /// A real-time block write whose data CRC failed, committed all the
    /// same ([`BoardConfig::commit_corrupt_writes`](crate::qla::config::BoardConfig::commit_corrupt_writes)).
    DataCrcCommitted,
    /// A query with a failed header CRC, answered with sequence `0xFFFF`
    /// (seed profile).
    CorruptQuery,
    /// A second status broadcast from a board already heard since the
    /// query (the bus delivered one twice): not stored again.
    DuplicateBroadcast,
    /// Seed profile: a status broadcast that arrived after its sender's
    /// TDMA slot had ended (stored all the same).
    LateBroadcast,
    /// A block write longer than the request memory: `ack_type_error`, not
    /// committed.
    WriteTooLong,
}

impl core::fmt::Display for RxError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            RxError::HeaderCrc => "header CRC error: not committed",
            RxError::DataCrc => "data CRC error: ack_data_error, not committed",
            RxError::HeaderCrcCommitted => {
                "header CRC error: ack_data_error, quadlet written as the firmware does"
            }
            RxError::DataCrcCommitted => {
                "data CRC error: ack_data_error, real-time block written as the firmware does"
            }
            RxError::CorruptQuery => "corrupt query: answered with sequence 0xFFFF",
            RxError::DuplicateBroadcast => "duplicate status broadcast: stored once",
            RxError::LateBroadcast => "status broadcast arrived after its slot",
            RxError::WriteTooLong => "block write beyond 2024 bytes: ack_type_error, not committed",
        })
    }
}

/// One emulated board: firmware state, registers, hub and plant.
#[derive(Debug, Clone)]
pub struct Firmware {
    cfg: BoardConfig,
    /// `cfg.layout()`, worked out once (the configuration never changes):
    /// every packet that lands in the hub and every sample asks for it.
    layout: BoardLayout,
    plant: Plant,
    /// Time the state corresponds to.
    now: SimTime,
    phy_id: Option<u8>,
    generation: u32,
    // Board registers.
    phy_ctrl: u32,
    phy_data: PhyData,
    dout: DigitalOutputs,
    ip_addr: u32,
    fpga_prom: FpgaProm,
    /// One per QLA (a DQLA has two).
    qla_proms: Vec<QlaProm>,
    dallas: Dallas,
    /// One MAX7317 per QLA: ID 0 on a QLA1, IDs 1 and 2 on a DQLA.
    expanders: Vec<Expander>,
    /// A DQLA's MAX7301 pair (IDs 3 and 4; unused on a QLA1).
    dqla_expanders: DqlaExpanders,
    /// The expander ID register 14 last named (the firmware's `chan_id`):
    /// on a DQLA the one that answers register-14 reads.
    expander_selected: u8,
    ethernet: Ethernet,
    /// The Ethernet side of an FPGA V3 (unused on a V1 or V2).
    ethernet_v3: EthernetV3,
    power: Power,
    watchdog: Watchdog,
    axes: Vec<AxisState>,
    /// Last real-time sample (block read or query): the timestamp base.
    last_sample: SimTime,
    hub: Hub,
    rx_error: Option<RxError>,
    /// The link's received-packet memory (space 5).
    rx_memory: PacketMemory,
    /// A buffer kept for block reads (no allocation per read).
    scratch: Vec<u8>,
    /// Memory for the next packet this board builds (a response or a
    /// status broadcast), lent by the bus with
    /// [`lend_packet_buffer`](Self::lend_packet_buffer); empty (the
    /// packet then gets new memory) when none was lent.
    packet_buffer: Vec<u8>,
    /// The header quadlets of the last status broadcast built and their
    /// CRC: the next one's header is the same (it changes only with the
    /// node ID or the block's length), so its CRC is not worked out again.
    broadcast_header_crc: Option<([u32; 4], u32)>,
    /// The next internal event, or earlier: every write moves the
    /// watchdog's expiry later without touching this, so when it comes it
    /// is worked out again before anything is done, if it was the
    /// watchdog's (`next_event_is_watchdog`).
    next_event: Option<SimTime>,
    /// `next_event` is the watchdog's expiry, earlier than every other
    /// event. Otherwise it is an amplifier's enable or a safety tick,
    /// which only a change marked by `events_stale` can move (the
    /// watchdog's expiry only moves later): when it comes it is exact.
    next_event_is_watchdog: bool,
    /// What the next internal event depends on (power, amplifier requests
    /// and enable delays, watchdog settings) may have changed since
    /// `next_event` was worked out. A real-time block that changes only
    /// the commands leaves it: `next_event` is still that event or
    /// earlier (see `next_event_is_watchdog`).
    events_stale: bool,
    /// The control state (power, amplifier requests, commands) may have
    /// changed since the plant's inputs were worked out.
    drive_stale: bool,
}

impl Firmware {
    /// A board freshly powered up at time zero: motor power and relay off,
    /// amplifiers off, watchdog 30 ms, encoders at the neutral count, no
    /// node ID until the first bus reset.
    pub fn new(cfg: BoardConfig) -> Firmware {
        let plant = Plant::new(cfg.plant_axes(), cfg.seed, cfg.plant_step);
        let axes = plant
            .axes()
            .iter()
            .map(|a| AxisState::new(a.encoder().count()))
            .collect();
        let fpga_prom = FpgaProm::new(&cfg.fpga_serial);
        let qla_proms = cfg.qla_serials().iter().map(|s| QlaProm::new(s)).collect();
        let dallas = Dallas::new(cfg.instrument.as_ref());
        let ethernet = Ethernet::new(cfg.board_id);
        let cfg_hardware = cfg.hardware;
        let layout = cfg.layout();
        let hub = Hub::new(SimTime::ZERO, layout.format());
        let mut fw = Firmware {
            power: Power::new(cfg.motor_supply_present, cfg.supply_rise),
            cfg,
            layout,
            plant,
            now: SimTime::ZERO,
            phy_id: None,
            generation: 0,
            phy_ctrl: 0,
            phy_data: PhyData::default(),
            dout: DigitalOutputs::new(),
            ip_addr: IP_UNASSIGNED,
            fpga_prom,
            qla_proms,
            dallas,
            expanders: qla_expanders(&cfg_hardware),
            dqla_expanders: DqlaExpanders::new(),
            expander_selected: 0,
            ethernet,
            ethernet_v3: EthernetV3::new(),
            watchdog: Watchdog::new(SimTime::ZERO),
            axes,
            last_sample: SimTime::ZERO,
            hub,
            rx_error: None,
            rx_memory: PacketMemory::new(),
            scratch: Vec::new(),
            packet_buffer: Vec::new(),
            broadcast_header_crc: None,
            next_event: None,
            next_event_is_watchdog: false,
            events_stale: true,
            drive_stale: true,
        };
        // Brakes are engaged until their channels release them.
        fw.hold_braked_joints();
        fw
    }

    /// The configuration.
    pub fn config(&self) -> &BoardConfig {
        &self.cfg
    }

    /// The rotary-switch board ID.
    pub fn board_id(&self) -> u8 {
        self.cfg.board_id
    }

    /// The physical ID from the last bus reset.
    pub fn phy_id(&self) -> Option<u8> {
        self.phy_id
    }

    /// The bus generation from the last bus reset.
    pub fn generation(&self) -> u32 {
        self.generation
    }

    /// The time the state corresponds to.
    pub fn now(&self) -> SimTime {
        self.now
    }

    /// The plant (to observe the physics), as of the last time the
    /// firmware looked at it: [`advance`](Self::advance) brings it to the
    /// time given.
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The plant, e.g. to apply an external torque to an axis.
    pub fn plant_mut(&mut self) -> &mut Plant {
        &mut self.plant
    }

    /// Whether the amplifier of `axis` drives its motor now.
    pub fn amplifier_on(&self, axis: usize) -> bool {
        self.axes
            .get(axis)
            .is_some_and(|a| a.is_on(&self.power, self.now, self.cfg.io_expander))
    }

    /// The current command of `axis` as applied (DAC code, MOTOR_STATUS
    /// 15:0), or `None` for an axis the board does not have.
    pub fn axis_command(&self, axis: usize) -> Option<u16> {
        self.axes.get(axis).map(|a| a.command)
    }

    /// When the host last wrote to this board (what refreshes the
    /// watchdog).
    pub fn last_host_write(&self) -> SimTime {
        self.watchdog.last_write
    }

    /// When the watchdog will fire if nothing is written before (`None`:
    /// disabled, or already fired).
    pub fn watchdog_expiry(&self) -> Option<SimTime> {
        self.watchdog.expiry()
    }

    /// The watchdog period, in ticks of 256 clocks (0: off).
    pub fn watchdog_period_ticks(&self) -> u16 {
        self.watchdog.ticks
    }

    /// Whether the watchdog has fired (STATUS bit 23).
    pub fn watchdog_timed_out(&self) -> bool {
        self.watchdog.timed_out
    }

    /// Bytes `address..address + len` of the FPGA configuration PROM.
    pub fn fpga_prom_bytes(&self, address: usize, len: usize) -> Vec<u8> {
        self.fpga_prom.read(address, len)
    }

    /// Bytes `address..address + len` of QLA PROM `qla` (0, or 0/1 on a
    /// DQLA); `None` for a QLA the board does not have.
    pub fn qla_prom_bytes(&self, qla: usize, address: usize, len: usize) -> Option<Vec<u8>> {
        self.qla_proms.get(qla).map(|p| p.read(address, len))
    }

    /// The raw digital outputs now (bit i = DOUT i+1; what register 6
    /// bits 3:0 and DIGIN bits 15:12 read).
    pub fn digital_outputs(&self) -> u8 {
        self.dout.raw_outputs(self.now)
    }

    /// Put an instrument on the 1-wire line, or take it off (`None`).
    pub fn set_instrument(&mut self, instrument: Option<&Instrument>) {
        self.dallas.set_instrument(instrument);
    }

    /// Connect or disconnect this board's Ethernet port (an FPGA V2 whose
    /// port is connected is the bridge board: link up).
    pub fn set_ethernet_link(&mut self, up: bool) {
        self.ethernet.set_link(up);
        self.ethernet_v3.set_link(up);
    }

    /// A FireWire packet arrived over this board's Ethernet port (the
    /// bridge records it in the Ethernet debug window).
    pub fn ethernet_received(&mut self, packet: &[u8]) {
        self.ethernet.received(packet);
    }

    /// Connect or disconnect the motor supply at `now` (fault injection).
    pub fn set_motor_supply(&mut self, now: SimTime, present: bool) {
        self.catch_up(now);
        self.power.supply_present = present;
        self.power.update_supply(now);
        self.control_changed();
        self.sync_plant();
    }

    /// A bus reset gave this board physical ID `phy_id`. Pending
    /// transactions (its broadcast) are dropped; registers are kept.
    pub fn bus_reset(&mut self, now: SimTime, phy_id: u8, generation: u32) {
        self.catch_up(now);
        self.phy_id = Some(phy_id & 0x3F);
        self.generation = generation;
        self.hub.pending = None;
        self.hub.in_flight = None;
    }

    /// Let time pass up to `now`: the watchdog, amplifier enables and
    /// safety checks at their exact times, and the plant (observed at
    /// `now`, see [`plant`](Self::plant)). Earlier times are ignored.
    pub fn advance(&mut self, now: SimTime) {
        self.catch_up(now);
        self.observe();
    }

    /// Let time pass up to `now` for the board's own events only (the
    /// watchdog, amplifier enables, the current check at every safety
    /// tick), without looking at the plant: where the plant's integration
    /// is split then depends only on the packets the board handles, as on
    /// the real board, whose sensors are sampled only when read.
    pub fn pass_time(&mut self, now: SimTime) {
        self.catch_up(now);
    }

    /// Let time pass up to `now` for the board's own events (the
    /// watchdog, amplifier enables, the current check at every safety
    /// tick), each at its exact time; the plant follows lazily: it is
    /// integrated when it is looked at ([`observe`](Self::observe)) and
    /// takes new inputs at their exact times.
    #[inline]
    fn catch_up(&mut self, now: SimTime) {
        if now <= self.now {
            return;
        }
        // Nothing due by then (most packets): only the clock moves. The
        // loop below stays out of line, so this costs a few instructions.
        if !self.events_stale && self.next_event.is_none_or(|t| t > now) {
            self.now = now;
            return;
        }
        self.process_events_until(now);
    }

    /// [`catch_up`](Self::catch_up) when an event may be due by `now`.
    #[inline(never)]
    fn process_events_until(&mut self, now: SimTime) {
        loop {
            let exact = self.events_stale || !self.next_event_is_watchdog;
            if self.events_stale {
                (self.next_event, self.next_event_is_watchdog) = self.next_internal_event();
                self.events_stale = false;
            }
            if self.next_event.is_none_or(|t| t > now) {
                break;
            }
            // Due by the bound: work it out exactly (the watchdog may have
            // been refreshed since), unless it just was or is not the
            // watchdog's, and act if it really is.
            if !exact {
                (self.next_event, self.next_event_is_watchdog) = self.next_internal_event();
            }
            let Some(t) = self.next_event.filter(|t| *t <= now) else {
                continue;
            };
            self.now = t;
            self.process_events();
        }
        self.now = now;
    }

    /// The power, amplifier, command or watchdog state changed: the next
    /// internal event and the plant's inputs are worked out again. (A
    /// real-time block marks only what it changed, see `realtime_write`.)
    pub(crate) fn control_changed(&mut self) {
        self.events_stale = true;
        self.drive_stale = true;
    }

    /// Bring the plant to `self.now`, to read what it measures.
    fn observe(&mut self) {
        self.hold_braked_joints();
        self.plant.advance_to(self.now);
    }

    /// The joints this board carries take their brakes' states (see
    /// [`brake`]): from the plant's clock on, where they changed.
    fn hold_braked_joints(&mut self) {
        for wire in &self.cfg.brakes {
            if let BrakeWire::Holds { axis, line } = wire {
                let engaged = !line.released();
                if let Some(a) = self.plant.axis_mut(*axis) {
                    if a.braked() != engaged {
                        a.set_brake(engaged);
                    }
                }
            }
        }
    }

    /// The brakes this board's channels drive follow their amplifiers.
    fn drive_brakes(&mut self) {
        for wire in &self.cfg.brakes {
            if let BrakeWire::Drives { axis, .. } = wire {
                // The plant's amplifier has the inputs just handed to it
                // (its calibrated zero included).
                if let Some(a) = self.plant.axis(*axis) {
                    wire.drive(a.enabled(), a.commanded_current());
                }
            }
        }
    }

    /// The earliest internal event strictly after `self.now`, and whether
    /// it is the watchdog's expiry, earlier than every other event.
    fn next_internal_event(&self) -> (Option<SimTime>, bool) {
        let expander = self.cfg.io_expander;
        self.next_event_after(
            self.watchdog.expiry(),
            self.axes.iter().map(|a| a.on_at(&self.power, expander)),
        )
    }

    /// [`next_internal_event`](Self::next_internal_event) from the
    /// watchdog's `expiry` and the amplifiers' enables `on_at`
    /// ([`AxisState::on_at`], by axis) as they stand.
    #[inline(always)]
    fn next_event_after(
        &self,
        expiry: Option<SimTime>,
        on_at: impl Iterator<Item = Option<SimTime>>,
    ) -> (Option<SimTime>, bool) {
        let now = self.now;
        let watchdog = expiry.filter(|t| *t > now);
        // The amplifiers' enables and the safety tick.
        let mut next: Option<SimTime> = None;
        let mut any_on = false;
        for on in on_at.flatten() {
            if on > now {
                next = Some(next.map_or(on, |n| n.min(on)));
            } else {
                any_on = true;
            }
        }
        if any_on {
            let step = SAFETY_TICK.0;
            let tick = SimTime((now.0 / step + 1).saturating_mul(step));
            next = Some(next.map_or(tick, |n| n.min(tick)));
        }
        match (watchdog, next) {
            (Some(w), None) => (Some(w), true),
            (Some(w), Some(n)) if w < n => (Some(w), true),
            (_, next) => (next, false),
        }
    }

    /// Apply what is due at `self.now` (an internal event's time).
    fn process_events(&mut self) {
        let now = self.now;
        // The next event is worked out after any event; the plant's inputs
        // again only when an amplifier turned on or off.
        let expiry = self.watchdog.expiry();
        let timed_out = expiry.is_some_and(|t| now >= t);
        if timed_out {
            self.watchdog.timed_out = true;
            for a in &mut self.axes {
                a.requested = false;
            }
            self.drive_stale = true;
        }
        // When each amplifier drives (worked out once for this event).
        let mut on_at = [None; MAX_AXES];
        for (slot, a) in on_at.iter_mut().zip(&self.axes) {
            *slot = a.on_at(&self.power, self.cfg.io_expander);
        }
        // Whether the current check took an amplifier's request away.
        let mut disabled = false;
        // (A board has at most MAX_AXES axes: QLA1 4, DQLA 8.)
        let on = |i: usize| on_at.get(i).copied().flatten().is_some_and(|t| now >= t);
        // An amplifier's enable delay ending now.
        if on_at.contains(&Some(now)) {
            self.drive_stale = true;
        }
        // The current check (section 7), at every safety tick.
        if now.0 % SAFETY_TICK.0 == 0 && (0..self.axes.len()).any(on) {
            // The measured current is exact at the plant's clock without
            // integrating the motion.
            self.plant.pass_to(now);
            let threshold = power::mismatch_counts();
            let expander = self.cfg.io_expander;
            for (i, a) in self.axes.iter_mut().enumerate() {
                // The check runs in current control unless MOTOR_CONFIG
                // bit 31 turned it off (MotorChannelQLA.v).
                let checked = !a.disable_safety && a.current_control(expander);
                if !on(i) || !checked {
                    a.mismatch_since = None;
                    continue;
                }
                let command = f64::from(a.effective_command());
                // Far enough within the threshold, whatever the noise: no
                // need to draw it (rounding moves a code by half of one).
                let (center, spread) = self.plant.measured_current_range(i);
                let bound = (registers::current_to_codes(center) - command).abs()
                    + spread / QLA_AMPS_PER_BIT
                    + 1.0;
                let diff = if bound <= threshold {
                    0.0
                } else {
                    let measured = registers::current_to_counts(self.plant.measured_current(i));
                    (f64::from(measured) - command).abs()
                };
                if diff <= threshold {
                    a.mismatch_since = None;
                    continue;
                }
                let since = *a.mismatch_since.get_or_insert(now);
                if now - since >= MISMATCH_TIME {
                    a.requested = false;
                    a.safety_disabled = true;
                    a.mismatch_since = None;
                    self.drive_stale = true;
                    disabled = true;
                }
            }
        }
        self.sync_plant();
        // The next event: from the watchdog's expiry and the enables
        // worked out above while neither changed (the plant's inputs do
        // not move them), else afresh.
        if timed_out || disabled {
            self.events_stale = true;
        } else {
            let enables = on_at.iter().take(self.axes.len()).copied();
            (self.next_event, self.next_event_is_watchdog) = self.next_event_after(expiry, enables);
            self.events_stale = false;
        }
    }

    /// Hand the amplifier inputs to the plant, from `self.now` on, where
    /// they changed (inlined: mostly nothing changed, and that is one
    /// test).
    #[inline]
    fn sync_plant(&mut self) {
        if self.drive_stale {
            self.sync_plant_now();
        }
    }

    /// [`sync_plant`](Self::sync_plant) when the inputs may have changed.
    #[inline(never)]
    fn sync_plant_now(&mut self) {
        self.drive_stale = false;
        let now = self.now;
        let mut clock_set = false;
        for (i, a) in self.axes.iter().enumerate() {
            let on = a.is_on(&self.power, now, self.cfg.io_expander);
            let dac = a.effective_command();
            let changed = self
                .plant
                .axis(i)
                .is_some_and(|x| x.dac() != dac || x.enabled() != on);
            if !changed {
                continue;
            }
            if !clock_set {
                self.plant.pass_to(now);
                clock_set = true;
            }
            if let Some(axis) = self.plant.axis_mut(i) {
                axis.set_drive(dac, on);
            }
        }
        if !self.cfg.brakes.is_empty() {
            self.drive_brakes();
            self.hold_braked_joints();
        }
    }

    /// The damage noticed in the last packet received, if any (cleared by
    /// this call and by every [`receive`](Self::receive)).
    pub fn take_rx_error(&mut self) -> Option<RxError> {
        self.rx_error.take()
    }

    /// Handle one packet as it arrived at `now` (CRCs are checked here).
    /// `phy` is this node's PHY, reached through PHY_CTRL.
    pub fn receive(&mut self, now: SimTime, bytes: &[u8], phy: &mut dyn PhyAccess) -> Reply {
        self.receive_checked(now, bytes, None, phy)
    }

    /// [`receive`](Self::receive) with the packet's CRC status already
    /// known (`crc`: what [`Packet::crc_status`] says of these bytes; the
    /// simulated bus works it out once for every node a packet reaches).
    /// `None` checks them here.
    ///
    /// Inlined into the bus node's `on_receive`, its caller for every
    /// packet delivered.
    #[inline]
    pub fn receive_checked(
        &mut self,
        now: SimTime,
        bytes: &[u8],
        crc: Option<CrcStatus>,
        phy: &mut dyn PhyAccess,
    ) -> Reply {
        self.receive_as(now, bytes, crc, Crcs::Filled, phy)
    }

    /// [`receive_checked`](Self::receive_checked) for a link whose bus
    /// writes a read response's CRCs itself
    /// ([`RxReply::AckThenSealedResponse`](firelink_bus::RxReply::AckThenSealedResponse)):
    /// the same reply, its response's header CRC and data CRC fields left
    /// zero.
    #[inline]
    pub fn receive_unsealed(
        &mut self,
        now: SimTime,
        bytes: &[u8],
        crc: Option<CrcStatus>,
        phy: &mut dyn PhyAccess,
    ) -> Reply {
        self.receive_as(now, bytes, crc, Crcs::LeftToTheBus, phy)
    }

    /// [`receive_checked`](Self::receive_checked), a read response's CRCs
    /// written as `crcs` says.
    #[inline(always)]
    fn receive_as(
        &mut self,
        now: SimTime,
        bytes: &[u8],
        crc: Option<CrcStatus>,
        crcs: Crcs,
        phy: &mut dyn PhyAccess,
    ) -> Reply {
        self.rx_error = None;
        if self.receive_hub_broadcast(now, bytes, crc) {
            return Reply::Silent;
        }
        let Ok(packet) = Packet::new_checked(bytes) else {
            return Reply::Silent;
        };
        let tcode = packet.tcode();
        if !tcode.has_header_crc() {
            return Reply::Silent;
        }
        // The link stores every packet it receives in its packet memory
        // (space 5), whole quadlets as they arrive.
        self.rx_memory.store(bytes);
        // Only the physical ID is compared, not the bus ID (FireWire.v
        // l.891): a request to bus 0 or 0x3EF reaches the node as well.
        let dest = packet.destination_id();
        let to_me = self.phy_id == Some(dest.phy());
        let broadcast = dest.is_broadcast();
        let to_node0 = !to_me && dest.phy() == 0;
        if !(to_me || broadcast || to_node0) {
            return Reply::Silent;
        }
        let crc = crc.unwrap_or_else(|| packet.crc_status());
        self.catch_up(now);
        let reply = self.receive_inner(now, &packet, crc, crcs, to_me, broadcast, to_node0, phy);
        self.sync_plant();
        reply
    }

    /// [`receive_checked`](Self::receive_checked)'s path for the packet
    /// most deliveries carry: another board's status broadcast, a block
    /// write to broadcast landing in hub memory, both CRCs known good. Its
    /// header is read once from the raw quadlets and the data goes straight
    /// to the hub, doing exactly what the general path does for it (packet
    /// memory, time, watchdog refresh, late and duplicate broadcasts, the
    /// plant's inputs); the reply is silence. `false`, with nothing done,
    /// for any other packet (or CRCs not yet checked).
    ///
    /// The header is read from the quadlets here, not through
    /// [`Packet`]'s checked view and accessors (the general path's): that
    /// view, tried in its place, cost 6,900 instructions more per demo
    /// cycle (221,788 -> 228,703). The length test below is `check_len`'s
    /// for a block write, and `status_broadcast_into`'s test and
    /// `hub_broadcast_fast_path_matches_the_general_path` hold the two
    /// paths together.
    #[inline]
    fn receive_hub_broadcast(
        &mut self,
        now: SimTime,
        bytes: &[u8],
        crc: Option<CrcStatus>,
    ) -> bool {
        /// Header and header CRC of a block write.
        const BLOCK_HEADER_BYTES: usize = 20;
        let Some(crc) = crc else {
            return false;
        };
        if bytes.len() < BLOCK_HEADER_BYTES
            || crc.header_ok != Some(true)
            || crc.data_ok == Some(false)
        {
            return false;
        }
        let first = read_quadlet(bytes, 0);
        let tcode = ((first >> 4) & 0xF) as u8;
        let destination_phy = ((first >> 16) & 0x3F) as u8;
        // To broadcast, and not (as it could only be for a node 63) to
        // this node as well.
        if tcode != u8::from(Tcode::WriteBlockRequest)
            || destination_phy != NodeId::BROADCAST_PHY
            || self.phy_id == Some(NodeId::BROADCAST_PHY)
        {
            return false;
        }
        let offset_low = read_quadlet(bytes, 2);
        let address = u64::from(offset_low & 0xFFFF);
        if !(HUB_MEMORY_OFFSET..HUB_MEMORY_OFFSET + HUB_MEMORY_QUADLETS as u64).contains(&address) {
            return false;
        }
        let data_length = (read_quadlet(bytes, 3) >> 16) as usize;
        // A longer write is refused, a shorter buffer not taken: both left
        // to the general path.
        let total = if data_length > 0 {
            BLOCK_HEADER_BYTES + data_length.div_ceil(4) * 4 + 4
        } else {
            BLOCK_HEADER_BYTES
        };
        if data_length > MAX_BLOCK_WRITE || bytes.len() < total {
            return false;
        }
        self.rx_memory.store(bytes);
        self.catch_up(now);
        let second = read_quadlet(bytes, 1);
        let offset = (u64::from(second & 0xFFFF) << 32) | u64::from(offset_low);
        let source_phy = ((second >> 16) & 0x3F) as u8;
        if self.late_for_its_slot(now, source_phy, offset) {
            self.rx_error = Some(RxError::LateBroadcast);
        }
        let data = bytes
            .get(BLOCK_HEADER_BYTES..BLOCK_HEADER_BYTES + data_length)
            .unwrap_or(&[]);
        // A write: it refreshes the watchdog (as `write_block_from`).
        self.watchdog.last_write = now;
        if !self.hub.store(now, data, self.layout.format()) {
            self.rx_error = Some(RxError::DuplicateBroadcast);
        }
        self.sync_plant();
        true
    }

    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn receive_inner(
        &mut self,
        now: SimTime,
        packet: &Packet<&[u8]>,
        crc: CrcStatus,
        crcs: Crcs,
        to_me: bool,
        broadcast: bool,
        to_node0: bool,
        phy: &mut dyn PhyAccess,
    ) -> Reply {
        let tcode = packet.tcode();
        let offset = packet.offset();
        let request = matches!(
            tcode,
            Tcode::WriteQuadletRequest
                | Tcode::WriteBlockRequest
                | Tcode::ReadQuadletRequest
                | Tcode::ReadBlockRequest
        );
        if crc.header_ok != Some(true) {
            self.rx_error = Some(RxError::HeaderCrc);
            if self.cfg.profile == Profile::Seed
                && tcode == Tcode::WriteQuadletRequest
                && offset & 0xFFFF == HUB_QUERY_OFFSET
            {
                self.rx_error = Some(RxError::CorruptQuery);
                self.query(now, None);
                return Reply::Silent;
            }
            // A request for this node whose header CRC fails is
            // acknowledged ack_data_error and gets no response (FireWire.v
            // l.1090). The firmware writes a quadlet write all the same
            // (l.1097); Firelink does only when told to.
            if !(to_me && request) {
                return Reply::Silent;
            }
            if tcode == Tcode::WriteQuadletRequest && self.cfg.commit_corrupt_writes {
                self.rx_error = Some(RxError::HeaderCrcCommitted);
                self.write_quadlet(now, offset, packet.quadlet_data(), phy);
            }
            return Reply::Ack(Ack::DataError);
        }
        let ack = |a: Ack| if to_me { Reply::Ack(a) } else { Reply::Silent };
        match tcode {
            Tcode::WriteQuadletRequest => {
                if to_node0 && offset & 0xFFFF != HUB_QUERY_OFFSET {
                    return Reply::Silent;
                }
                self.write_quadlet(now, offset, packet.quadlet_data(), phy);
                ack(Ack::Complete)
            }
            Tcode::WriteBlockRequest => {
                if to_node0 && offset != COMMAND_SNOOP_OFFSET {
                    return Reply::Silent;
                }
                let too_long = usize::from(packet.data_length()) > MAX_BLOCK_WRITE;
                if crc.data_ok == Some(false) {
                    self.rx_error = Some(RxError::DataCrc);
                    // The firmware writes a real-time block (address 0)
                    // quadlet by quadlet as it arrives, before the data
                    // CRC is known (FireWire.v l.855); Firelink does only
                    // when told to.
                    if self.cfg.commit_corrupt_writes
                        && offset & 0xFFFF == REALTIME_BLOCK_OFFSET
                        && !too_long
                    {
                        self.rx_error = Some(RxError::DataCrcCommitted);
                        self.write_block_from(now, offset, packet.data(), to_me && !broadcast, phy);
                    }
                    return ack(Ack::DataError);
                }
                if too_long {
                    self.rx_error = Some(RxError::WriteTooLong);
                    return ack(Ack::TypeError);
                }
                if broadcast && self.late_for_its_slot(now, packet.source_id().phy(), offset) {
                    self.rx_error = Some(RxError::LateBroadcast);
                }
                self.write_block_from(now, offset, packet.data(), to_me && !broadcast, phy);
                ack(Ack::Complete)
            }
            Tcode::ReadQuadletRequest | Tcode::ReadBlockRequest if to_me => {
                let header = AsyncHeader {
                    destination: packet.source_id(),
                    source: NodeId::local(self.phy_id.unwrap_or(0)),
                    tl: packet.tl(),
                    rt: 0,
                    pri: 0,
                };
                let response = if tcode == Tcode::ReadQuadletRequest {
                    let data = self.read_quadlet(now, offset);
                    emit_as(
                        &PacketRepr::ReadQuadletResponse {
                            header,
                            rcode: Rcode::Complete,
                            data,
                        },
                        core::mem::take(&mut self.packet_buffer),
                        crcs,
                    )
                } else {
                    self.block_read_response(now, header, offset, packet.data_length(), crcs)
                };
                Reply::AckThenResponse {
                    ack: Ack::Pending,
                    response,
                }
            }
            // Responses to requests a board never makes: taken, ignored.
            Tcode::WriteResponse
            | Tcode::ReadQuadletResponse
            | Tcode::ReadBlockResponse
            | Tcode::LockResponse => ack(Ack::Complete),
            // The link takes quadlet and block reads and writes only: a
            // lock request (or any other) gets no acknowledge at all
            // (FireWire.v l.893-919).
            _ => Reply::Silent,
        }
    }

    fn block_read_response(
        &mut self,
        now: SimTime,
        header: AsyncHeader,
        offset: u64,
        length: u16,
        crcs: Crcs,
    ) -> Vec<u8> {
        let length = usize::from(length);
        // Every length up to the largest is answered complete with exactly
        // that many bytes, 0 and lengths that are not whole quadlets
        // included (FireWire.v l.1162); a length of 0 reads nothing.
        let packet = core::mem::take(&mut self.packet_buffer);
        if length > MAX_BLOCK_READ {
            return block_response_into(header, Rcode::AddressError, &[], packet, crcs);
        }
        let mut data = core::mem::take(&mut self.scratch);
        data.clear();
        data.resize(length.div_ceil(4) * 4, 0);
        if length > 0 {
            self.read_block_into(now, offset, &mut data);
        }
        data.truncate(length);
        let response = block_response_into(header, Rcode::Complete, &data, packet, crcs);
        self.scratch = data;
        response
    }

    /// Whether this board holds memory for its next packet (see
    /// [`lend_packet_buffer`](Self::lend_packet_buffer)).
    pub fn has_packet_buffer(&self) -> bool {
        self.packet_buffer.capacity() > 0
    }

    /// Memory for the next packet this board builds (a response from
    /// [`receive`](Self::receive) or a broadcast from
    /// [`poll_transmit`](Self::poll_transmit)), so that building it does
    /// not allocate; what it held is dropped. A board lent none allocates.
    pub fn lend_packet_buffer(&mut self, buffer: Vec<u8>) {
        self.packet_buffer = buffer;
    }

    /// The status broadcast, when its slot has come at `now`: a block
    /// write to broadcast, priority 0xA, carrying this board's header and
    /// real-time block (section 6.2). Hand it to the bus, then call
    /// [`transmitted`](Self::transmitted) when it has gone out.
    ///
    /// Inlined: the node asks after every packet it handles, and the
    /// answer is almost always "not yet"; the packet is built out of line.
    #[inline]
    pub fn poll_transmit(&mut self, now: SimTime) -> Option<Vec<u8>> {
        self.poll_transmit_as(now, Crcs::Filled)
    }

    /// [`poll_transmit`](Self::poll_transmit) for a sender whose bus writes
    /// the packet's CRCs itself
    /// ([`NodeCtx::transmit_sealed`](firelink_bus::NodeCtx::transmit_sealed)):
    /// the same packet with its header and data CRC fields left zero.
    #[inline]
    pub fn poll_transmit_unsealed(&mut self, now: SimTime) -> Option<Vec<u8>> {
        self.poll_transmit_as(now, Crcs::LeftToTheBus)
    }

    #[inline(always)]
    fn poll_transmit_as(&mut self, now: SimTime, crcs: Crcs) -> Option<Vec<u8>> {
        self.catch_up(now);
        let ready = self
            .hub
            .pending
            .as_ref()
            .is_some_and(|p| p.ready(now, self.hub.seen));
        if !ready {
            return None;
        }
        self.take_status_broadcast(crcs)
    }

    /// [`poll_transmit`](Self::poll_transmit)'s status broadcast once it
    /// is ready: the waiting broadcast taken (and dropped if this board
    /// has no node ID), its packet built.
    #[inline(never)]
    fn take_status_broadcast(&mut self, crcs: Crcs) -> Option<Vec<u8>> {
        let pending = self.hub.pending.take()?;
        let phy = self.phy_id?;
        let offset = status_broadcast_offset(self.cfg.firmware, self.cfg.board_id)
            .unwrap_or(STATUS_BROADCAST_OFFSET);
        let header_crc = match crcs {
            Crcs::Filled => Some(&mut self.broadcast_header_crc),
            Crcs::LeftToTheBus => None,
        };
        let packet = status_broadcast_into(
            phy,
            offset,
            &pending.payload,
            core::mem::take(&mut self.packet_buffer),
            header_crc,
        );
        self.hub.in_flight = Some(pending.payload);
        Some(packet)
    }

    /// The status broadcast handed out by
    /// [`poll_transmit`](Self::poll_transmit) finished at `now`: store it
    /// in this board's own hub memory, in arrival order.
    pub fn transmitted(&mut self, now: SimTime) {
        self.catch_up(now);
        if let Some(payload) = self.hub.in_flight.take() {
            let _ = self.hub.store(now, &payload, self.layout.format());
            self.hub.keep_payload(payload);
        }
    }

    /// When [`poll_transmit`](Self::poll_transmit) should next be called:
    /// the slot of the waiting status broadcast (which also becomes ready
    /// when the boards before it have been heard, so poll after every
    /// received packet too).
    pub fn next_wakeup(&self) -> Option<SimTime> {
        self.hub.pending.as_ref().map(|p| p.due(self.hub.seen))
    }

    /// Run the hub as the Ethernet-only network's (FPGA V3, Rev 9:
    /// EthernetIO.v's `hub_eth`): its timers count the 125 MHz Ethernet
    /// clock, 16 bits (the update time in each entry keeps 15).
    pub fn use_ethernet_hub(&mut self) {
        self.hub.clock = HubClock::Ethernet;
    }

    /// The Ethernet-only network: this board's status block (header and
    /// real-time block, wire order), taken as soon as the query selected
    /// it (EthernetIO.v `hubSend` multicasts it when the query arrives,
    /// no slot to wait for). `None` if the last query did not select this
    /// board, or the block was taken already.
    pub fn take_status_block(&mut self, now: SimTime) -> Option<Vec<u8>> {
        self.catch_up(now);
        self.hub.pending.take().map(|p| p.payload)
    }

    /// Store a status block (as [`take_status_block`](Self::take_status_block)
    /// gave it, this board's or another's) landing in this board's hub
    /// memory at `now`, in arrival order. `false` if the hub refused it
    /// (a second block of one board for one query, or one that does not
    /// fit).
    pub fn store_status_block(&mut self, now: SimTime, payload: &[u8]) -> bool {
        self.catch_up(now);
        self.hub.store(now, payload, self.layout.format())
    }

    /// Whether the hub holds every block the last query selected (false
    /// before any query).
    pub fn hub_complete(&self) -> bool {
        self.hub.complete()
    }

    /// The broadcast read response the hub board sends the host unasked
    /// once its hub is complete (EthernetIO.v `bcResp`): a block read
    /// response with `header`, carrying the hub memory from its start, the
    /// entries in arrival order and the timing quadlet after them
    /// (HubReg.v's `bc_quads`). `None` while the hub is not complete.
    pub fn broadcast_read_response(
        &mut self,
        now: SimTime,
        header: AsyncHeader,
    ) -> Option<Vec<u8>> {
        if !self.hub.complete() {
            return None;
        }
        self.catch_up(now);
        let bytes = (self.hub.count + 1) * 4;
        let length = u16::try_from(bytes).ok()?;
        Some(self.block_read_response(now, header, HUB_MEMORY_OFFSET, length, Crcs::Filled))
    }

    /// Seed profile: whether a status broadcast from node `sender`
    /// arriving at `now` (at `offset`) is later than its TDMA slot allows:
    /// the end of the slot plus 2 us. (Only the seed profile has slots to
    /// be late for: that test inlined, the rest out of line.)
    #[inline(always)]
    fn late_for_its_slot(&self, now: SimTime, sender: u8, offset: u64) -> bool {
        self.cfg.profile == Profile::Seed && self.late_for_seed_slot(now, sender, offset)
    }

    /// [`late_for_its_slot`](Self::late_for_its_slot) on the seed profile.
    #[inline(never)]
    fn late_for_seed_slot(&self, now: SimTime, sender: u8, offset: u64) -> bool {
        let in_hub = (STATUS_BROADCAST_OFFSET
            ..STATUS_BROADCAST_OFFSET + u64::from(HUB_MEMORY_QUADLETS as u32) * 4)
            .contains(&offset);
        let Some(query_at) = self.hub.query_at else {
            return false;
        };
        in_hub
            && now > query_at + seed_slot(self.cfg.firmware, sender.saturating_add(1)) + SLOT_GRACE
    }

    /// A broadcast query at `now`: `Some(word)`, or `None` for a query
    /// known only to be corrupt (seed profile). A word with sequence 0 is
    /// not a query (hosts never send one) and is ignored.
    ///
    /// The firmware latches its real-time block on every query, named in
    /// the board mask or not (the JHU firmware's FireWire.v starts its
    /// sampler on any hub query); a board the query leaves out never sends
    /// that sample, and a block read samples afresh, so of its latch only
    /// the restarted timestamp can be seen: that is all such a board does
    /// here (no plant integrated, no block built).
    fn query(&mut self, now: SimTime, word: Option<u32>) {
        let seq = match word {
            Some(w) => {
                let Ok(query) = Query::parse(w) else {
                    return;
                };
                self.hub.query = Some(query);
                query.seq
            }
            None => CORRUPT_QUERY_SEQ,
        };
        self.hub.start_cycle(now);
        let id = self.cfg.board_id;
        // When this board's status broadcast may go, and the boards it
        // waits for, if the query asks for it.
        let schedule = match self.cfg.profile {
            Profile::Seed => self.phy_id.map(|node| {
                let at = now + seed_slot(self.cfg.firmware, node);
                (at, 0, at)
            }),
            Profile::Rev7 | Profile::Rev8 | Profile::Rev9 => {
                let mask = self.hub.mask();
                (mask & (1 << id) != 0).then(|| {
                    let before = mask & ((1u16 << id) - 1);
                    let earliest = now + SimDuration::from_clocks(FIRST_SLOT_CLOCKS);
                    let chain = CHAIN_TIMEOUT_PER_BOARD.0 * u64::from(before.count_ones());
                    (earliest, before, earliest + SimDuration(chain))
                })
            }
        };
        let Some((earliest, wait_for, deadline)) = schedule else {
            self.last_sample = now;
            return;
        };
        let len = self.layout.read_block_len();
        let header = BroadcastHeader {
            seq,
            quadlets: u16::try_from(len / 4 + 1).unwrap_or(u16::MAX),
        };
        // The header and the sample overwrite every byte (the sample writes
        // every quadlet of its block): the last broadcast's memory needs no
        // clearing, only its length.
        let mut payload = self.hub.spare_payload();
        payload.resize(len + 4, 0);
        if let Some(head) = payload.get_mut(..4) {
            head.copy_from_slice(&header.to_word().to_be_bytes());
        }
        if let Some(block) = payload.get_mut(4..) {
            self.sample_block_into(now, block);
        }
        self.hub.pending = Some(Pending {
            payload,
            earliest,
            wait_for,
            deadline,
        });
    }
}

/// Why a block read of `length` bytes is refused, if it is: not whole
/// quadlets (`resp_type_error`), or more than `max_bytes`
/// (`resp_address_error`).
pub(crate) fn block_read_refusal(length: usize, max_bytes: usize) -> Option<Rcode> {
    if length == 0 || length % 4 != 0 {
        Some(Rcode::TypeError)
    } else if length > max_bytes {
        Some(Rcode::AddressError)
    } else {
        None
    }
}

/// A block read response carrying `rcode` and `data` (empty when the read
/// is refused).
pub(crate) fn block_response_packet(header: AsyncHeader, rcode: Rcode, data: &[u8]) -> Vec<u8> {
    block_response_into(header, rcode, data, Vec::new(), Crcs::Filled)
}

/// [`block_response_packet`] built in `buffer`'s memory, its CRCs written
/// as `crcs` says.
fn block_response_into(
    header: AsyncHeader,
    rcode: Rcode,
    data: &[u8],
    buffer: Vec<u8>,
    crcs: Crcs,
) -> Vec<u8> {
    emit_as(
        &PacketRepr::ReadBlockResponse {
            header,
            rcode,
            extended_tcode: 0,
            data,
        },
        buffer,
        crcs,
    )
}

/// The status broadcast of the board at physical ID `phy`: a block write
/// of `payload` to broadcast at `offset`, label 0, retry code 0, priority
/// [`STATUS_BROADCAST_PRIORITY`], built in `buffer`'s memory. The same
/// bytes as [`emit_into`] makes of that [`PacketRepr::WriteBlockRequest`]
/// (CRCs included), with the header's quadlets written directly.
/// `header_crc` remembers the last header's quadlets and CRC: a header
/// equal to it takes that CRC (the CRC of the same 16 bytes), another is
/// worked out and remembered. With no `header_crc` both CRC fields are
/// left zero, for the bus to write ([`Crcs::LeftToTheBus`]).
fn status_broadcast_into(
    phy: u8,
    offset: u64,
    payload: &[u8],
    mut buffer: Vec<u8>,
    header_crc: Option<&mut Option<([u32; 4], u32)>>,
) -> Vec<u8> {
    let Ok(data_length) = u16::try_from(payload.len()) else {
        return emit_into(
            &PacketRepr::WriteBlockRequest {
                header: AsyncHeader::new(NodeId::BROADCAST, NodeId::local(phy), 0)
                    .with_pri(STATUS_BROADCAST_PRIORITY),
                offset,
                extended_tcode: 0,
                data: payload,
            },
            buffer,
        );
    };
    let header = [
        (u32::from(NodeId::BROADCAST.0) << 16)
            | (u32::from(u8::from(Tcode::WriteBlockRequest)) << 4)
            | u32::from(STATUS_BROADCAST_PRIORITY & 0xF),
        (u32::from(NodeId::local(phy).0) << 16) | ((offset >> 32) & 0xFFFF) as u32,
        offset as u32,
        u32::from(data_length) << 16,
    ];
    buffer.clear();
    for quadlet in header {
        buffer.extend_from_slice(&quadlet.to_be_bytes());
    }
    let fill = header_crc.is_some();
    let crc = match header_crc {
        None => 0,
        Some(&mut Some((quadlets, crc))) if quadlets == header => crc,
        Some(memo) => {
            let crc = firelink_wire::crc::crc1394(&buffer);
            *memo = Some((header, crc));
            crc
        }
    };
    buffer.extend_from_slice(&crc.to_be_bytes());
    if !payload.is_empty() {
        let start = buffer.len();
        buffer.extend_from_slice(payload);
        buffer.resize(start + payload.len().div_ceil(4) * 4, 0);
        let data_crc = match fill {
            true => buffer.get(start..).map_or(0, firelink_wire::crc::crc1394),
            false => 0,
        };
        buffer.extend_from_slice(&data_crc.to_be_bytes());
    }
    buffer
}

/// Who writes a built packet's CRCs.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Crcs {
    /// The firmware, as the packet is built.
    Filled,
    /// The bus, as the packet goes out
    /// ([`NodeCtx::transmit_sealed`](firelink_bus::NodeCtx::transmit_sealed),
    /// [`RxReply::AckThenSealedResponse`](firelink_bus::RxReply::AckThenSealedResponse)).
    LeftToTheBus,
}

/// Emit a packet this module built (always valid: fields in range).
pub(crate) fn emit(repr: &PacketRepr<'_>) -> Vec<u8> {
    emit_into(repr, Vec::new())
}

/// [`emit`] into `buffer`'s memory (whatever it held is dropped; it grows
/// only when the packet does not fit).
pub(crate) fn emit_into(repr: &PacketRepr<'_>, buffer: Vec<u8>) -> Vec<u8> {
    emit_as(repr, buffer, Crcs::Filled)
}

/// [`emit_into`] with the CRCs written as `crcs` says: for
/// [`Crcs::LeftToTheBus`], the same bytes with the header CRC and data
/// CRC fields left zero ([`PacketRepr::emit_unsealed`]; the bus's sealing
/// makes them `emit_into`'s).
fn emit_as(repr: &PacketRepr<'_>, mut buffer: Vec<u8>, crcs: Crcs) -> Vec<u8> {
    buffer.clear();
    buffer.resize(repr.buffer_len(), 0);
    let written = match crcs {
        Crcs::Filled => repr.emit(&mut buffer),
        Crcs::LeftToTheBus => repr.emit_unsealed(&mut buffer),
    };
    match written {
        Ok(len) => buffer.truncate(len),
        Err(_) => buffer.clear(),
    }
    buffer
}

#[cfg(test)]
mod tests {
    use super::*;
    use config::Hardware;

    /// The status broadcast built directly is byte for byte what the
    /// packet representation emits, whatever the payload's length, with
    /// no header CRC remembered, with this header's remembered and after
    /// another header's (the remembered CRC follows the header).
    #[test]
    fn status_broadcast_matches_the_emitted_packet() {
        let emitted = |phy: u8, offset: u64, payload: &[u8]| {
            emit_into(
                &PacketRepr::WriteBlockRequest {
                    header: AsyncHeader::new(NodeId::BROADCAST, NodeId::local(phy), 0)
                        .with_pri(STATUS_BROADCAST_PRIORITY),
                    offset,
                    extended_tcode: 0,
                    data: payload,
                },
                Vec::new(),
            )
        };
        for len in [0usize, 1, 3, 4, 7, 64, 100, 300, 2000] {
            let payload: Vec<u8> = (0..len).map(|i| (i * 37 + 11) as u8).collect();
            for phy in [0u8, 5, 62] {
                let offset = 0xFFFF_FF00_1000 + u64::from(phy) * 0x20;
                let expected = emitted(phy, offset, &payload);
                let built =
                    status_broadcast_into(phy, offset, &payload, vec![0xAA; 9], Some(&mut None));
                assert_eq!(built, expected, "payload of {len} bytes from node {phy}");
                let mut memo = None;
                for round in 0..2 {
                    let again =
                        status_broadcast_into(phy, offset, &payload, vec![1], Some(&mut memo));
                    assert_eq!(
                        again, expected,
                        "{len} bytes from node {phy}, round {round}"
                    );
                }
                let other =
                    status_broadcast_into(phy ^ 1, offset, &payload, Vec::new(), Some(&mut memo));
                assert_eq!(
                    other,
                    emitted(phy ^ 1, offset, &payload),
                    "{len} bytes, other"
                );
                let back =
                    status_broadcast_into(phy, offset, &payload, Vec::new(), Some(&mut memo));
                assert_eq!(back, expected, "{len} bytes from node {phy}, after another");
                // Left for the bus to seal: the same bytes once both CRCs
                // are filled in, and none filled before.
                let mut unsealed =
                    status_broadcast_into(phy, offset, &payload, vec![0xAA; 9], None);
                assert_eq!(unsealed.len(), expected.len(), "{len} bytes, unsealed");
                let mut packet = firelink_wire::packet::Packet::new_checked(&mut unsealed[..])
                    .expect("a whole packet");
                assert_eq!(packet.header_crc(), Some(0), "{len} bytes: left to the bus");
                packet.fill_header_crc();
                packet.fill_data_crc();
                assert_eq!(unsealed, expected, "{len} bytes from node {phy}, sealed");
            }
        }
    }

    /// A read response built for the bus to seal is, once sealed, byte
    /// for byte the response built with its CRCs, and the board is left
    /// the same: quadlet reads, block reads of every kind of length (none,
    /// not whole quadlets, the hub's, too long) and a request that gets
    /// no response.
    #[test]
    fn an_unsealed_read_response_sealed_is_the_filled_one() {
        let query = query_packet(7, 0b0011);
        let mut filled = Firmware::new(BoardConfig::new(0, Hardware::Qla1, Profile::Rev8));
        let mut phy = PhyRegisters::new(0);
        filled.bus_reset(SimTime::ZERO, 0, 1);
        filled.receive(SimTime::from_micros(100), &query, &mut phy);
        let other = broadcast_of(Profile::Rev8, 1, &query, SimTime::from_micros(200));
        filled.receive(SimTime::from_micros(210), &other, &mut phy);
        let mut unsealed = filled.clone();
        let header = AsyncHeader::new(NodeId::local(0), NodeId::local(9), 5);
        let mut requests = vec![
            emit(&PacketRepr::ReadQuadletRequest { header, offset: 0 }),
            emit(&PacketRepr::ReadQuadletRequest { header, offset: 4 }),
            emit(&PacketRepr::WriteQuadletRequest {
                header,
                offset: 0,
                data: 1,
            }),
        ];
        for (offset, data_length) in [
            (0, 0),
            (0, 3),
            (0, 16),
            (HUB_MEMORY_OFFSET, 64),
            (HUB_MEMORY_OFFSET, MAX_BLOCK_READ as u16),
            (HUB_MEMORY_OFFSET, MAX_BLOCK_READ as u16 + 4),
        ] {
            requests.push(emit(&PacketRepr::ReadBlockRequest {
                header,
                offset,
                data_length,
                extended_tcode: 0,
            }));
        }
        let mut responses = 0;
        for (i, request) in requests.iter().enumerate() {
            let now = SimTime::from_micros(300 + i as u64);
            let a = filled.receive(now, request, &mut phy);
            let crc = Packet::new_checked(&request[..]).unwrap().crc_status();
            let b = unsealed.receive_unsealed(now, request, Some(crc), &mut phy);
            match (a, b) {
                (
                    Reply::AckThenResponse { ack, response },
                    Reply::AckThenResponse {
                        ack: ack_b,
                        response: mut bytes,
                    },
                ) => {
                    assert_eq!(ack, ack_b);
                    let mut packet = Packet::new_checked(&mut bytes[..]).expect("a whole packet");
                    assert_eq!(packet.header_crc(), Some(0), "request {i}: left to the bus");
                    packet.fill_header_crc();
                    packet.fill_data_crc();
                    assert_eq!(bytes, response, "request {i}, sealed");
                    responses += 1;
                }
                (a, b) => assert_eq!(a, b, "request {i}"),
            }
            assert_eq!(format!("{filled:?}"), format!("{unsealed:?}"));
        }
        assert_eq!(responses, requests.len() - 1);
    }

    fn query_packet(seq: u16, mask: u16) -> Vec<u8> {
        let word = Query {
            seq,
            board_mask: mask,
        }
        .to_word()
        .unwrap();
        emit(&PacketRepr::WriteQuadletRequest {
            header: AsyncHeader::new(NodeId::BROADCAST, NodeId::local(9), 0),
            offset: HUB_QUERY_OFFSET,
            data: word,
        })
    }

    /// A board's status broadcast after `query`, sent at `at`.
    fn broadcast_of(profile: Profile, board: u8, query: &[u8], at: SimTime) -> Vec<u8> {
        let mut fw = Firmware::new(BoardConfig::new(board, Hardware::Qla1, profile));
        let mut phy = PhyRegisters::new(board);
        fw.bus_reset(SimTime::ZERO, board, 1);
        fw.receive(SimTime::from_micros(100), query, &mut phy);
        fw.poll_transmit(at).expect("the broadcast is due")
    }

    /// A status broadcast of another board (good, repeated, late, with a
    /// damaged data CRC) leaves the receiving board exactly as the general
    /// path does, whether its CRCs come checked (the hub fast path) or
    /// not.
    #[test]
    fn hub_broadcast_fast_path_matches_the_general_path() {
        for profile in [Profile::Seed, Profile::Rev7, Profile::Rev8] {
            let query = query_packet(7, 0b1111);
            let mut fast = Firmware::new(BoardConfig::new(2, Hardware::Qla1, profile));
            let mut phy = PhyRegisters::new(2);
            fast.bus_reset(SimTime::ZERO, 2, 1);
            fast.receive(SimTime::from_micros(100), &query, &mut phy);
            let mut general = fast.clone();
            let on_time = broadcast_of(profile, 1, &query, SimTime::from_micros(200));
            let mut damaged = broadcast_of(profile, 3, &query, SimTime::from_micros(260));
            let last = damaged.len() - 1;
            damaged[last] ^= 1;
            let packets = [
                (210, &on_time),
                (230, &on_time),
                (270, &damaged),
                (
                    5_000,
                    &broadcast_of(profile, 0, &query, SimTime::from_micros(4_000)),
                ),
            ];
            let mut errors = Vec::new();
            for (micros, packet) in packets {
                let now = SimTime::from_micros(micros);
                let crc = Packet::new_checked(&packet[..]).unwrap().crc_status();
                let a = fast.receive_checked(now, packet, Some(crc), &mut phy);
                let b = general.receive(now, packet, &mut phy);
                assert_eq!(a, b);
                let error = fast.take_rx_error();
                assert_eq!(error, general.take_rx_error());
                errors.push(error);
                assert_eq!(format!("{fast:?}"), format!("{general:?}"));
            }
            assert!(
                fast.hub.count > 0,
                "{profile:?}: the broadcasts were stored"
            );
            assert!(errors.contains(&Some(RxError::DuplicateBroadcast)));
            assert!(errors.contains(&Some(RxError::DataCrc)));
            if profile == Profile::Seed {
                assert!(errors.contains(&Some(RxError::LateBroadcast)), "{errors:?}");
            }
        }
    }
}
