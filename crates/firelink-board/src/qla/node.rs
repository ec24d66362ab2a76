//! The board as a node on the simulated bus: a thin adapter from
//! [`firelink_bus::Node`] to [`Firmware`].
//!
//! Received packets go to [`Firmware::receive_unsealed`] (its reply
//! becomes the node's ack, or ack and concatenated response at the
//! request's speed, the response's CRCs written by the bus);
//! status broadcasts are requested as soon as the firmware has one ready,
//! with a timer at [`Firmware::next_wakeup`] for the ones waiting for
//! their slot; PHY_CTRL reaches the node's PHY registers through the
//! context. Damage the firmware notices is reported to the bus trace.
//!
//! ```
//! use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
//! use firelink_board::qla::node::BoardNode;
//! use firelink_bus::{Bus, BusConfig, NodeConfig};
//! let mut bus = Bus::new(BusConfig::default());
//! let a = bus.add(BoardNode::new(BoardConfig::new(0, Hardware::Qla1, Profile::Rev8)), NodeConfig::board());
//! let b = bus.add(BoardNode::new(BoardConfig::new(1, Hardware::Qla1, Profile::Rev8)), NodeConfig::board());
//! bus.daisy_chain(&[a, b]).unwrap();
//! bus.reset();
//! bus.run_until_idle();
//! assert!(bus.node::<BoardNode>(a).unwrap().firmware().phy_id().is_some());
//! ```

use firelink_bus::{ArbitrationClass, Node, NodeCtx, ResetInfo, RxReply, SimTime, TransmitRequest};
use firelink_wire::packet::{Ack, Speed};

use crate::qla::config::{BoardConfig, Profile};
use crate::qla::{Firmware, PhyAccess, Reply};

/// Timer token of the broadcast slot.
const SLOT_TIMER: u64 = 1;
/// Timer token of the watchdog: the board acts on its own when the host
/// goes quiet (amplifiers off at the exact instant), not when the next
/// packet happens to arrive.
const WATCHDOG_TIMER: u64 = 2;

/// An emulated board on the simulated bus.
#[derive(Debug, Clone)]
pub struct BoardNode {
    name: String,
    firmware: Firmware,
    speed: Speed,
    class: ArbitrationClass,
    next_token: u64,
    in_flight: Option<u64>,
    /// The watchdog's period and timed-out flag when its timer was last
    /// set.
    watchdog_settings: (u16, bool),
}

/// The node's PHY registers, reached through the callback context.
pub(crate) struct CtxPhy<'c, 'a>(pub(crate) &'c mut NodeCtx<'a>);

impl PhyAccess for CtxPhy<'_, '_> {
    fn read_phy_register(&mut self, register: u8) -> u8 {
        self.0.read_phy_register(register)
    }

    fn write_phy_register(&mut self, register: u8, value: u8) {
        self.0.write_phy_register(register, value);
    }
}

/// What a board's link puts on the bus for the firmware's `reply` to a
/// packet that arrived at `speed` (a response goes back at that speed,
/// its CRCs as the firmware filled them).
pub(crate) fn on_bus(reply: Reply, speed: Speed) -> RxReply {
    match reply {
        Reply::Silent => RxReply::Silent,
        Reply::Ack(ack) => RxReply::Ack(ack),
        Reply::AckThenResponse { ack, response } => RxReply::AckThenResponse {
            ack,
            response,
            speed,
        },
    }
}

/// Lend `firmware` a spare packet buffer of the bus unless it holds one:
/// the packets it builds then reuse the memory of finished ones.
#[inline(always)]
fn stock_packet_buffer(firmware: &mut Firmware, ctx: &mut NodeCtx<'_>) {
    if !firmware.has_packet_buffer() {
        firmware.lend_packet_buffer(ctx.take_buffer());
    }
}

/// Tell the bus about a damaged packet the firmware of node `name`
/// noticed, if any.
pub(crate) fn report_rx_error(
    name: &str,
    error: Option<impl core::fmt::Display>,
    ctx: &mut NodeCtx<'_>,
) {
    if let Some(error) = error {
        ctx.report_error(format!("{name}: {error}"));
    }
}

/// How a board running `profile` asks for the bus for its status
/// broadcast: with an isochronous-class request (seed 000's bus
/// arbitration acceleration; the Rev 7 and Rev 8 FireWire.v request the
/// broadcast's block write that way). Rev 9 asks with a priority-class
/// request instead.
pub fn status_broadcast_class(profile: Profile) -> ArbitrationClass {
    match profile {
        Profile::Seed | Profile::Rev7 | Profile::Rev8 => ArbitrationClass::Isochronous,
        Profile::Rev9 => ArbitrationClass::Priority,
    }
}

impl BoardNode {
    /// A board named `board <id>` whose status broadcasts go out at S400
    /// with its profile's bus request ([`status_broadcast_class`]).
    pub fn new(config: BoardConfig) -> BoardNode {
        let class = status_broadcast_class(config.profile);
        BoardNode {
            name: format!("board {}", config.board_id),
            firmware: Firmware::new(config),
            speed: Speed::S400,
            class,
            next_token: 0,
            in_flight: None,
            watchdog_settings: (0, false),
        }
    }

    /// The same node with another name.
    pub fn with_name(mut self, name: impl Into<String>) -> BoardNode {
        self.name = name.into();
        self
    }

    /// The same node broadcasting at `speed` with `class` arbitration.
    pub fn with_broadcast(mut self, speed: Speed, class: ArbitrationClass) -> BoardNode {
        self.speed = speed;
        self.class = class;
        self
    }

    /// How its status broadcasts ask for the bus.
    pub fn broadcast_class(&self) -> ArbitrationClass {
        self.class
    }

    /// The firmware (registers, plant).
    pub fn firmware(&self) -> &Firmware {
        &self.firmware
    }

    /// The firmware, e.g. to inject a supply fault or push an axis.
    pub fn firmware_mut(&mut self) -> &mut Firmware {
        &mut self.firmware
    }

    /// Hand ready broadcasts to the bus and re-arm the slot timer (inlined
    /// into each callback: it runs after every one).
    #[inline(always)]
    fn pump(&mut self, now: SimTime, ctx: &mut NodeCtx<'_>) {
        stock_packet_buffer(&mut self.firmware, ctx);
        // The bus writes the broadcast's CRCs, and so knows them good.
        while let Some(packet) = self.firmware.poll_transmit_unsealed(now) {
            self.next_token += 1;
            self.in_flight = Some(self.next_token);
            ctx.transmit_sealed(TransmitRequest {
                packet,
                speed: self.speed,
                class: self.class,
                token: self.next_token,
            });
        }
        // The slot timer at the waiting broadcast's slot; asked of the bus
        // only when that moves.
        let slot = self.firmware.next_wakeup().map(|at| at.max(now));
        // Both timers as armed when the callback began (what is asked here
        // is applied after it).
        let (slot_armed, watchdog_armed) = ctx.timer_pair(SLOT_TIMER, WATCHDOG_TIMER);
        match (slot, slot_armed) {
            (Some(at), Some(armed)) if armed == at => {}
            (Some(at), _) => ctx.set_timer(at, SLOT_TIMER),
            (None, Some(_)) => ctx.cancel_timer(SLOT_TIMER),
            (None, None) => {}
        }
        // One watchdog timer at a time, never later than the expiry (a
        // refreshed watchdog moves its expiry later; the timer, when it
        // fires early, just sets itself again).
        let armed = watchdog_armed.filter(|t| *t > now);
        // Its period and whether it runs decide when it fires; a write
        // only moves the expiry later. Armed and neither changed: as is.
        let settings = (
            self.firmware.watchdog_period_ticks(),
            self.firmware.watchdog_timed_out(),
        );
        if armed.is_some() && settings == self.watchdog_settings {
            return;
        }
        self.watchdog_settings = settings;
        let expiry = self.firmware.watchdog_expiry().map(|t| t.max(now));
        match (expiry, armed) {
            (Some(e), Some(t)) if t <= e => {}
            (Some(e), _) => ctx.set_timer(e, WATCHDOG_TIMER),
            (None, Some(_)) => ctx.cancel_timer(WATCHDOG_TIMER),
            (None, None) => {}
        }
    }
}

impl Node for BoardNode {
    fn name(&self) -> &str {
        &self.name
    }

    /// The firmware takes packets addressed to its own node, to broadcast
    /// and to node 0 (snooped); others' it ignores.
    fn hears_others(&self) -> bool {
        false
    }

    fn on_bus_reset(&mut self, now: SimTime, info: &ResetInfo, ctx: &mut NodeCtx<'_>) {
        self.firmware.bus_reset(now, info.phy_id, info.generation);
        self.in_flight = None;
        self.pump(now, ctx);
    }

    fn on_receive(
        &mut self,
        now: SimTime,
        packet: &[u8],
        speed: Speed,
        ctx: &mut NodeCtx<'_>,
    ) -> RxReply {
        let crc = ctx.received_crc_status();
        stock_packet_buffer(&mut self.firmware, ctx);
        // A read response is built unsealed: the bus writes its CRCs.
        let reply = self
            .firmware
            .receive_unsealed(now, packet, crc, &mut CtxPhy(ctx));
        report_rx_error(&self.name, self.firmware.take_rx_error(), ctx);
        self.pump(now, ctx);
        match reply {
            Reply::AckThenResponse { ack, response } => RxReply::AckThenSealedResponse {
                ack,
                response,
                speed,
            },
            other => on_bus(other, speed),
        }
    }

    fn on_transmitted(
        &mut self,
        now: SimTime,
        token: u64,
        _ack: Option<Ack>,
        ctx: &mut NodeCtx<'_>,
    ) {
        if self.in_flight == Some(token) {
            self.in_flight = None;
            self.firmware.transmitted(now);
        }
        self.pump(now, ctx);
    }

    fn on_timer(&mut self, now: SimTime, token: u64, ctx: &mut NodeCtx<'_>) {
        if token == WATCHDOG_TIMER {
            // Apply whatever is due now (the watchdog, if not refreshed);
            // the plant is left to be integrated when something reads it.
            self.firmware.pass_time(now);
        }
        self.pump(now, ctx);
    }
}
