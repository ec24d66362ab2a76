//! A minimal host for the tests: builds request packets with
//! `firelink_wire` exactly as a host would, hands them to a board's
//! firmware and decodes the replies.

#![allow(dead_code)]

use firelink_board::qla::config::BoardConfig;
use firelink_board::qla::{Firmware, PhyRegisters, Reply};
use firelink_board::time::{SimDuration, SimTime};
use firelink_wire::packet::{Ack, AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Tcode};

/// The host's physical ID in the tests.
pub const HOST_PHY: u8 = 20;

/// Emit a request packet.
pub fn emit(repr: &PacketRepr<'_>) -> Vec<u8> {
    let mut buf = vec![0xA5u8; repr.buffer_len()];
    let len = repr.emit(&mut buf).expect("valid request");
    buf.truncate(len);
    buf
}

/// Big-endian bytes of quadlets.
pub fn bytes(quads: &[u32]) -> Vec<u8> {
    quads.iter().flat_map(|q| q.to_be_bytes()).collect()
}

/// Quadlets of big-endian bytes.
pub fn quads(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|c| u32::from_be_bytes(c.try_into().unwrap()))
        .collect()
}

pub fn quadlet_write(dest: NodeId, tl: u8, offset: u64, data: u32) -> Vec<u8> {
    emit(&PacketRepr::WriteQuadletRequest {
        header: AsyncHeader::new(dest, NodeId::local(HOST_PHY), tl),
        offset,
        data,
    })
}

pub fn block_write(dest: NodeId, tl: u8, offset: u64, data: &[u32]) -> Vec<u8> {
    let data = bytes(data);
    emit(&PacketRepr::WriteBlockRequest {
        header: AsyncHeader::new(dest, NodeId::local(HOST_PHY), tl),
        offset,
        extended_tcode: 0,
        data: &data,
    })
}

pub fn quadlet_read(dest: NodeId, tl: u8, offset: u64) -> Vec<u8> {
    emit(&PacketRepr::ReadQuadletRequest {
        header: AsyncHeader::new(dest, NodeId::local(HOST_PHY), tl),
        offset,
    })
}

pub fn block_read(dest: NodeId, tl: u8, offset: u64, quadlets: usize) -> Vec<u8> {
    emit(&PacketRepr::ReadBlockRequest {
        header: AsyncHeader::new(dest, NodeId::local(HOST_PHY), tl),
        offset,
        data_length: (quadlets * 4) as u16,
        extended_tcode: 0,
    })
}

/// One board on a private wire with a host, driven only by packets.
pub struct Rig {
    pub fw: Firmware,
    pub phy: PhyRegisters,
    pub node: u8,
    pub now: SimTime,
    tl: u8,
}

impl Rig {
    /// A board that got physical ID `node` at a bus reset at time zero.
    pub fn new(cfg: BoardConfig, node: u8) -> Rig {
        let mut fw = Firmware::new(cfg);
        fw.bus_reset(SimTime::ZERO, node, 1);
        Rig {
            fw,
            phy: PhyRegisters::new(node),
            node,
            now: SimTime::ZERO,
            tl: 0,
        }
    }

    pub fn dest(&self) -> NodeId {
        NodeId::local(self.node)
    }

    fn next_tl(&mut self) -> u8 {
        self.tl = (self.tl + 1) & 0x3F;
        self.tl
    }

    /// Let virtual time pass (nothing is sent).
    pub fn wait(&mut self, dt: SimDuration) {
        self.now += dt;
        self.fw.advance(self.now);
    }

    /// Deliver raw bytes now.
    pub fn deliver(&mut self, packet: &[u8]) -> Reply {
        self.fw.receive(self.now, packet, &mut self.phy)
    }

    /// Deliver a write request and take its ack (`None` if silent); a
    /// response to a write fails the test.
    fn write_ack(&mut self, request: &[u8]) -> Option<Ack> {
        match self.deliver(request) {
            Reply::Ack(a) => Some(a),
            Reply::Silent => None,
            other => panic!("unexpected reply to a write: {other:?}"),
        }
    }

    /// Quadlet write to this board; returns the ack (None if silent).
    pub fn write(&mut self, offset: u64, value: u32) -> Option<Ack> {
        let tl = self.next_tl();
        let p = quadlet_write(self.dest(), tl, offset, value);
        self.write_ack(&p)
    }

    /// Block write to this board; returns the ack.
    pub fn write_block(&mut self, offset: u64, data: &[u32]) -> Option<Ack> {
        let tl = self.next_tl();
        let p = block_write(self.dest(), tl, offset, data);
        self.write_ack(&p)
    }

    /// Deliver a read request and take its concatenated response, checking
    /// the ack_pending before it; `what` names the read for the failure.
    fn read_response(&mut self, request: &[u8], what: &str, offset: u64) -> Vec<u8> {
        let Reply::AckThenResponse { ack, response } = self.deliver(request) else {
            panic!("no response to a {what} of {offset:#x}");
        };
        assert_eq!(ack, Ack::Pending);
        response
    }

    /// Quadlet read; checks the concatenated response.
    pub fn read(&mut self, offset: u64) -> u32 {
        let tl = self.next_tl();
        let p = quadlet_read(self.dest(), tl, offset);
        let response = self.read_response(&p, "quadlet read", offset);
        let repr = PacketRepr::parse_verified(&response).expect("response CRCs");
        let PacketRepr::ReadQuadletResponse {
            header,
            rcode,
            data,
        } = repr
        else {
            panic!("wrong response {repr:?}");
        };
        assert_eq!(header.tl, tl);
        assert_eq!(header.destination, NodeId::local(HOST_PHY));
        assert_eq!(header.source, self.dest());
        assert_eq!(rcode, Rcode::Complete);
        data
    }

    /// Block read; returns (rcode, quadlets).
    pub fn read_block_rcode(&mut self, offset: u64, quadlets: usize) -> (Rcode, Vec<u32>) {
        let tl = self.next_tl();
        let p = block_read(self.dest(), tl, offset, quadlets);
        let response = self.read_response(&p, "block read", offset);
        let packet = Packet::new_checked(&response[..]).unwrap();
        assert_eq!(packet.tcode(), Tcode::ReadBlockResponse);
        let repr = PacketRepr::parse_verified(&response).expect("response CRCs");
        let PacketRepr::ReadBlockResponse {
            header,
            rcode,
            data,
            ..
        } = repr
        else {
            panic!("wrong response {repr:?}");
        };
        assert_eq!(header.tl, tl);
        (rcode, quads(data))
    }

    /// Block read expecting success.
    pub fn read_block(&mut self, offset: u64, quadlets: usize) -> Vec<u32> {
        let (rcode, data) = self.read_block_rcode(offset, quadlets);
        assert_eq!(rcode, Rcode::Complete);
        assert_eq!(data.len(), quadlets);
        data
    }
}

/// DAC code for a current, QLA scaling.
pub fn amps_to_dac(amps: f64) -> u16 {
    (32768.0 + amps * 65536.0 / 12.5)
        .round()
        .clamp(0.0, 65535.0) as u16
}

/// Current of an ADC current code, QLA scaling.
pub fn adc_to_amps(bits: u32) -> f64 {
    f64::from(bits & 0xFFFF) * 12.5 / 65536.0 - 6.25
}

/// Encoder velocity in counts/s from an ENC_PERIOD word (Rev 7+): a full
/// quadrature cycle (4 counts) per period.
pub fn period_to_velocity(word: u32) -> f64 {
    let clocks = f64::from(word & 0x03FF_FFFF);
    if word & 0x8000_0000 != 0 || clocks == 0.0 {
        return 0.0;
    }
    let v = 4.0 * 49.152e6 / clocks;
    if word & 0x4000_0000 != 0 { v } else { -v }
}

/// Signed count of an ENC_POSITION word.
pub fn position_counts(word: u32) -> i64 {
    i64::from(word & 0x00FF_FFFF) - 0x80_0000
}
