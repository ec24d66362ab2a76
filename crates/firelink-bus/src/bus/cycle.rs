//! The cycle master: while `cycle_master` is on, the root sends a cycle
//! start packet every 125 us (priority over asynchronous requests).

use super::*;

impl Bus {
    pub(super) fn cycle_tick(&mut self) {
        if !self.cfg.cycle_master {
            self.cycle_tick_scheduled = false;
            return;
        }
        let next = self.now + self.cfg.timing.cycle_period;
        self.push(next, None, Ev::CycleTick);
        if self.medium == Medium::Resetting || self.tree.node_count() == 0 {
            return;
        }
        let root = self.tree.root;
        let now = self.now;
        let slot = &mut self.slots[root];
        if slot.muted {
            return;
        }
        if !slot
            .queue
            .front()
            .is_some_and(|p| p.kind == PacketKind::CycleStart)
        {
            slot.queue.push_front(Pending {
                bytes: Arc::from(Vec::new()),
                speed: Speed::S100,
                class: ArbitrationClass::Priority,
                token: None,
                kind: PacketKind::CycleStart,
                ready_at: now,
                delayed: true,
                faults: Vec::new(),
            });
        }
        if self.is_idle() {
            self.schedule_arbitration(now);
        }
    }

    // ----- timed faults -------------------------------------------------------------
}

/// A cycle start packet from `source_phy` carrying the cycle time at `at`.
pub(super) fn cycle_start_packet(source_phy: u8, at: SimTime) -> Vec<u8> {
    let ticks = (u128::from(at.0) * 24_576_000 / 1_000_000_000_000) as u64;
    let offset = ticks % 3072;
    let cycles = ticks / 3072;
    let cycle_time = (((cycles / 8000) % 128) << 25) | ((cycles % 8000) << 12) | offset;
    let q = [
        0xFFFF_0000 | (u32::from(u8::from(Tcode::CycleStart)) << 4),
        (u32::from(NodeId::local(source_phy).0) << 16) | 0xFFFF,
        0xF000_0200,
        cycle_time as u32,
    ];
    let mut out = Vec::with_capacity(20);
    for w in q {
        out.extend_from_slice(&w.to_be_bytes());
    }
    let crc = crc1394(&out);
    out.extend_from_slice(&crc.to_be_bytes());
    out
}
