//! The Snake node on the simulated bus: a thin adapter from
//! [`firelink_bus::Node`] to [`SnakeFirmware`].
//!
//! Received packets go to [`SnakeFirmware::receive`]; its reply becomes
//! the node's ack (or ack and concatenated response at the request's
//! speed). A timer follows [`SnakeFirmware::next_wakeup`], so the
//! watchdog disables the amplifiers at its exact expiry and pot commands
//! finish on time even when no packet arrives.
//!
//! ```
//! use firelink_board::snake::{SnakeNode, SnakeNodeConfig};
//! use firelink_bus::{Bus, BusConfig, NodeConfig};
//! let mut bus = Bus::new(BusConfig::default());
//! let a = bus.add(SnakeNode::new(SnakeNodeConfig::new(0)), NodeConfig::board());
//! let b = bus.add(SnakeNode::new(SnakeNodeConfig::new(1)), NodeConfig::board());
//! bus.daisy_chain(&[a, b]).unwrap();
//! bus.reset();
//! // Two nodes, each with its own physical ID (the root gets the highest).
//! assert_eq!(bus.node::<SnakeNode>(a).unwrap().firmware().phy_id(), Some(1));
//! assert_eq!(bus.node::<SnakeNode>(b).unwrap().firmware().phy_id(), Some(0));
//! ```

use firelink_bus::{Node, NodeCtx, ResetInfo, RxReply, SimTime};
use firelink_wire::packet::Speed;

use super::config::SnakeNodeConfig;
use super::firmware::SnakeFirmware;
use crate::qla::node::{CtxPhy, on_bus, report_rx_error};

/// Timer token of the node's next self-driven change.
const WAKEUP_TIMER: u64 = 1;

/// An emulated Snake node on the simulated bus.
#[derive(Debug, Clone)]
pub struct SnakeNode {
    name: String,
    firmware: SnakeFirmware,
    timer: Option<SimTime>,
}

impl SnakeNode {
    /// A node named `snake <id>`.
    pub fn new(config: SnakeNodeConfig) -> SnakeNode {
        SnakeNode {
            name: format!("snake {}", config.board_id),
            firmware: SnakeFirmware::new(config),
            timer: None,
        }
    }

    /// The firmware (registers, plant).
    pub fn firmware(&self) -> &SnakeFirmware {
        &self.firmware
    }

    /// The firmware, e.g. to inject an amplifier fault.
    pub fn firmware_mut(&mut self) -> &mut SnakeFirmware {
        &mut self.firmware
    }

    /// Keep one timer at the firmware's next wake-up.
    fn arm(&mut self, now: SimTime, ctx: &mut NodeCtx<'_>) {
        let due = self.firmware.next_wakeup().map(|t| t.max(now));
        if due != self.timer {
            match due {
                Some(t) => ctx.set_timer(t, WAKEUP_TIMER),
                None => ctx.cancel_timer(WAKEUP_TIMER),
            }
            self.timer = due;
        }
    }
}

impl Node for SnakeNode {
    fn name(&self) -> &str {
        &self.name
    }

    fn on_bus_reset(&mut self, now: SimTime, info: &ResetInfo, ctx: &mut NodeCtx<'_>) {
        self.firmware.bus_reset(now, info.phy_id, info.generation);
        self.arm(now, ctx);
    }

    fn on_receive(
        &mut self,
        now: SimTime,
        packet: &[u8],
        speed: Speed,
        ctx: &mut NodeCtx<'_>,
    ) -> RxReply {
        let reply = self.firmware.receive(now, packet, &mut CtxPhy(ctx));
        report_rx_error(&self.name, self.firmware.take_rx_error(), ctx);
        self.arm(now, ctx);
        on_bus(reply, speed)
    }

    fn on_timer(&mut self, now: SimTime, _token: u64, ctx: &mut NodeCtx<'_>) {
        self.timer = None;
        self.firmware.advance(now);
        self.arm(now, ctx);
    }
}
