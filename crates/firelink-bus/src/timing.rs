//! The 1394a timing model: gaps, arbitration, packet envelopes, repeat delay.
//!
//! Every figure the bus uses lives in [`BusTiming`], so a test or a study can
//! change one and see its effect. The defaults are the 1394a cable PHY
//! constants (`ieee1394.md`, "Timing on the wire"):
//!
//! | constant | default | meaning |
//! |---|---|---|
//! | base rate | 98.304 Mb/s | S100; S200 and S400 are 2x and 4x |
//! | subaction gap | (27 + 16 g) / 98.304 MHz | idle time before a fair or priority request may arbitrate (10.5 us at g = 63, 4.5 us at 26, 1.1 us at 5) |
//! | arbitration reset gap | (51 + 32 g) / 98.304 MHz | idle time that opens a new fairness interval |
//! | ack gap, isochronous gap | 0.04 us | before an ack; before an isochronous-style request arbitrates |
//! | data prefix | 0.14 us | before every packet (1394 MIN_DATA_PREFIX) |
//! | data end | 0.24 us | after the last packet of a transmission (1394 DATA_END_TIME) |
//! | repeat delay | 0.144 us per PHY hop | data repeated by each PHY (1394 PHY_DELAY) |
//! | arbitration | 2 x hops to the root x repeat delay + 0.02 us | request up to the root, grant back down |
//! | bus reset | 166.7 us long, 1.3 us short | reset signalling before tree-ID and self-ID |
//!
//! A packet's wire time is `data prefix + 8 x bytes / speed + data end`. A
//! concatenated response follows its ack after one more data prefix and
//! without a data end in between. An ack is 8 bits at the speed of the packet
//! it acknowledges. A PHY packet is 64 bits (the quadlet and its complement).

use firelink_wire::packet::Speed;

use crate::time::SimDuration;

/// The 1394 base rate in bits per second (one "base-rate bit time").
pub const BASE_RATE: u64 = 98_304_000;

/// The power-up gap count.
pub const DEFAULT_GAP_COUNT: u8 = 63;

/// Bits in an ack packet.
pub const ACK_BITS: u64 = 8;

/// Bits of a PHY packet on the wire (a quadlet and its complement).
pub const PHY_PACKET_BITS: u64 = 64;

/// All timing figures of the bus. See the module docs for the defaults.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusTiming {
    /// Data prefix before every packet.
    pub data_prefix: SimDuration,
    /// Data end after the last packet of a transmission.
    pub data_end: SimDuration,
    /// Separation between an ack and a concatenated response (a data prefix).
    pub concat_prefix: SimDuration,
    /// Idle time before an ack is sent.
    pub ack_gap: SimDuration,
    /// Idle time before an isochronous-style request may arbitrate.
    pub iso_gap: SimDuration,
    /// Repeat delay of one PHY hop (each cable plus the repeating PHY).
    pub hop_delay: SimDuration,
    /// Fixed part of every arbitration (grant handshake at the winner).
    pub arbitration_base: SimDuration,
    /// Bus-reset signalling of a long reset (cable connect/disconnect, IBR).
    pub reset_long: SimDuration,
    /// Bus-reset signalling of a short (arbitrated) reset.
    pub reset_short: SimDuration,
    /// Gap between self-ID packets.
    pub self_id_gap: SimDuration,
    /// Cycle-start period of the cycle master.
    pub cycle_period: SimDuration,
}

impl Default for BusTiming {
    fn default() -> Self {
        BusTiming {
            data_prefix: SimDuration::from_nanos(140),
            data_end: SimDuration::from_nanos(240),
            concat_prefix: SimDuration::from_nanos(140),
            ack_gap: SimDuration::from_nanos(40),
            iso_gap: SimDuration::from_nanos(40),
            hop_delay: SimDuration::from_nanos(144),
            arbitration_base: SimDuration::from_nanos(20),
            reset_long: SimDuration::from_micros_f64(166.7),
            reset_short: SimDuration::from_micros_f64(1.3),
            self_id_gap: SimDuration::from_nanos(40),
            cycle_period: SimDuration::from_micros(125),
        }
    }
}

impl BusTiming {
    /// `n` base-rate bit times.
    pub fn base_bits(n: u64) -> SimDuration {
        SimDuration::from_bits(n, BASE_RATE)
    }

    /// The subaction gap for gap count `g` (values above 63 are clamped).
    pub fn subaction_gap(&self, gap_count: u8) -> SimDuration {
        let g = u64::from(gap_count.min(63));
        Self::base_bits(27 + 16 * g)
    }

    /// The arbitration reset gap for gap count `g`.
    pub fn arb_reset_gap(&self, gap_count: u8) -> SimDuration {
        let g = u64::from(gap_count.min(63));
        Self::base_bits(51 + 32 * g)
    }

    /// Time to clock `bits` at `speed`.
    pub fn bits(&self, bits: u64, speed: Speed) -> SimDuration {
        SimDuration::from_bits(bits, speed.bits_per_second())
    }

    /// Time to clock a packet of `len` bytes at `speed` (no prefix or end).
    pub fn payload_time(&self, len: usize, speed: Speed) -> SimDuration {
        self.bits(len as u64 * 8, speed)
    }

    /// Whole wire time of a lone packet of `len` bytes: prefix, bits, end.
    pub fn packet_time(&self, len: usize, speed: Speed) -> SimDuration {
        self.data_prefix + self.payload_time(len, speed) + self.data_end
    }

    /// Whole wire time of a lone ack at `speed`.
    pub fn ack_time(&self, speed: Speed) -> SimDuration {
        self.data_prefix + self.bits(ACK_BITS, speed) + self.data_end
    }

    /// Arbitration time of a node `hops_to_root` hops from the root: the
    /// request travels up, the grant travels down.
    pub fn arbitration(&self, hops_to_root: u32) -> SimDuration {
        self.hop_delay * (2 * u64::from(hops_to_root)) + self.arbitration_base
    }

    /// Nominal wire time of a concatenated block read between two nodes
    /// `hops` apart, from the start of the request to the end of the final
    /// ack, when the requester is the root (no arbitration wait): request,
    /// ack gap, ack_pending, response, ack gap, ack_complete.
    pub fn nominal_block_read(&self, payload: usize, speed: Speed, hops: u32) -> SimDuration {
        let prop = self.hop_delay * u64::from(hops);
        let request = self.packet_time(20, speed);
        let response_len = 20 + payload_with_crc(payload);
        request
            + prop
            + self.ack_gap
            + self.data_prefix
            + self.bits(ACK_BITS, speed)
            + self.concat_prefix
            + self.payload_time(response_len, speed)
            + self.data_end
            + prop
            + self.ack_gap
            + self.ack_time(speed)
    }

    /// Nominal wire time of a concatenated quadlet read between two nodes
    /// `hops` apart (16-byte request, ack_pending, 20-byte response, final
    /// ack), when the requester is the root.
    pub fn nominal_quadlet_read(&self, speed: Speed, hops: u32) -> SimDuration {
        let prop = self.hop_delay * u64::from(hops);
        self.packet_time(16, speed)
            + prop
            + self.ack_gap
            + self.data_prefix
            + self.bits(ACK_BITS, speed)
            + self.concat_prefix
            + self.payload_time(20, speed)
            + self.data_end
            + prop
            + self.ack_gap
            + self.ack_time(speed)
    }

    /// Nominal wire time of a unified quadlet write (a 20-byte request and
    /// ack_complete).
    pub fn nominal_quadlet_write(&self, speed: Speed, hops: u32) -> SimDuration {
        let prop = self.hop_delay * u64::from(hops);
        self.packet_time(20, speed) + prop + self.ack_gap + self.ack_time(speed)
    }

    /// Nominal wire time of a unified block write (request and ack_complete).
    pub fn nominal_block_write(&self, payload: usize, speed: Speed, hops: u32) -> SimDuration {
        let prop = self.hop_delay * u64::from(hops);
        self.packet_time(20 + payload_with_crc(payload), speed)
            + prop
            + self.ack_gap
            + self.ack_time(speed)
    }
}

/// Bytes of a block payload on the wire: padded to quadlets, plus the data
/// CRC when there is any data.
pub fn payload_with_crc(payload: usize) -> usize {
    if payload == 0 {
        0
    } else {
        payload.div_ceil(4) * 4 + 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_match_the_commonly_quoted_figures() {
        let t = BusTiming::default();
        let us = |d: SimDuration| d.as_micros_f64();
        assert!((us(t.subaction_gap(63)) - 10.53).abs() < 0.01);
        assert!((us(t.subaction_gap(26)) - 4.51).abs() < 0.01);
        assert!((us(t.subaction_gap(5)) - 1.09).abs() < 0.01);
        assert!((us(t.arb_reset_gap(63)) - 21.03).abs() < 0.01);
        assert_eq!(t.subaction_gap(200), t.subaction_gap(63));
    }

    #[test]
    fn packet_times() {
        let t = BusTiming::default();
        // A 20-byte quadlet write at S400: 0.407 us of bits + 0.38 us envelope.
        let q = t.packet_time(20, Speed::S400).as_micros_f64();
        assert!((q - 0.7869).abs() < 0.001, "{q}");
        // The same at S100 is four times the bits.
        let q100 = t.packet_time(20, Speed::S100).as_micros_f64();
        assert!((q100 - (0.38 + 4.0 * 0.4069)).abs() < 0.001);
        // A 48-byte block read and a 16-byte block write stay well under 5 us.
        assert!(t.nominal_block_read(48, Speed::S400, 1).as_micros_f64() < 5.0);
        assert!(t.nominal_block_write(16, Speed::S400, 1).as_micros_f64() < 5.0);
        assert_eq!(payload_with_crc(0), 0);
        assert_eq!(payload_with_crc(5), 12);
    }
}
