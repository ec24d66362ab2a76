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
                bytes: Vec::new(),
                speed: Speed::S100,
                class: ArbitrationClass::Priority,
                token: None,
                kind: PacketKind::CycleStart,
                ready_at: now,
                delayed: true,
                faults: Vec::new(),
                // Known when the packet is built, at its grant.
                crc: None,
            });
        }
        if self.is_idle() {
            self.schedule_arbitration(now);
        }
    }
}

/// The CRC status of every [`cycle_start_packet`]: a header CRC, which
/// matches (it was just computed), and no data block.
pub(super) const CYCLE_START_CRC: CrcStatus = CrcStatus {
    header_ok: Some(true),
    data_ok: None,
};

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

#[cfg(test)]
mod tests {
    use super::super::probe::{chain, probe};
    use super::*;
    use firelink_wire::packet::Packet;

    #[test]
    fn the_root_sends_a_cycle_start_every_125_us_when_on() {
        let cfg = BusConfig {
            cycle_master: true,
            ..BusConfig::default()
        };
        let (mut bus, nodes) = chain(2, cfg);
        bus.trace_mut().clear();
        bus.run_for(SimDuration::from_micros(1000));
        let starts: Vec<&PacketRecord> = bus
            .trace()
            .packets()
            .iter()
            .filter(|p| p.kind == PacketKind::CycleStart)
            .collect();
        assert!(starts.len() >= 7, "{}", starts.len());
        assert!(starts.iter().all(|p| p.sender == nodes[0].0), "the root");
        for pair in starts.windows(2) {
            let period = pair[1].arb_start.unwrap_or(pair[1].start)
                - pair[0].arb_start.unwrap_or(pair[0].start);
            assert_eq!(period, SimDuration::from_micros(125));
        }
        // The other node receives them.
        assert!(probe(&bus, nodes[1]).received.len() >= 7);
    }

    #[test]
    fn no_cycle_starts_when_off() {
        let (mut bus, _) = chain(2, BusConfig::default());
        bus.run_for(SimDuration::from_micros(1000));
        assert!(
            bus.trace()
                .packets()
                .iter()
                .all(|p| p.kind != PacketKind::CycleStart)
        );
    }

    #[test]
    fn a_cycle_start_packet_carries_the_cycle_time() {
        // 1.5 cycles after the start: cycle 1, offset half a cycle (1536
        // ticks of 24.576 MHz).
        let bytes = cycle_start_packet(5, SimTime(187_500_000));
        let p = Packet::new_checked(&bytes[..]).unwrap();
        assert_eq!(p.tcode(), Tcode::CycleStart);
        assert!(p.destination_id().is_broadcast());
        assert_eq!(p.source_id(), NodeId::local(5));
        assert!(p.verify().is_ok());
        let cycle_time = u32::from_be_bytes(bytes[12..16].try_into().unwrap());
        assert_eq!((cycle_time >> 12) & 0x1FFF, 1, "cycle count");
        assert_eq!(cycle_time & 0xFFF, 1536, "cycle offset");
    }
}
