//! Issue 35: every word the Rev 8 firmware defines, answered as the
//! firmware defines it. One test per row of the issue; each sends the
//! request as raw bytes and names the firmware file and line (Rev 8
//! numbering, jhu-cisst/mechatronics-firmware `FPGA1394_QLA/Verilog/`) it
//! follows.
//!
//! Most tests send raw datagrams over loopback UDP to an in-process
//! `firelink emulate` (the bridge serving 127.0.0.1 on an ephemeral
//! port). What the bridge cannot carry from a host (a damaged header, a
//! lock request) goes to the board over the simulated bus from the PC's
//! link, as the bridge's own link would send it.

use crate::common;

use std::net::UdpSocket;
use std::time::Duration;

use common::{Server, qla1s, request_datagram};
use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::node::{BoardNode, status_broadcast_class};
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_bus::host::{Completion, Outcome};
use firelink_bus::trace::PacketKind;
use firelink_bus::{ArbitrationClass, HostLink, SimDuration, TraceLevel};
use firelink_wire::bridge::{ExtraData, split_board_datagram};
use firelink_wire::packet::{Ack, AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Speed, Tcode};

/// The reference host's source ID.
const HOST: NodeId = NodeId(0xFFD0);

/// One reply datagram, decoded.
#[derive(Debug)]
struct Reply {
    rcode: Rcode,
    /// The quadlet (quadlet response) or the payload bytes.
    data: Vec<u8>,
    /// The block response's data-length field.
    data_length: u16,
    extra: ExtraData,
}

impl Reply {
    fn quadlet(&self) -> u32 {
        u32::from_be_bytes(self.data.get(..4).unwrap().try_into().unwrap())
    }

    fn quadlets(&self) -> Vec<u32> {
        self.data
            .chunks_exact(4)
            .map(|c| u32::from_be_bytes(c.try_into().unwrap()))
            .collect()
    }
}

/// A host sending raw datagrams to an emulator over loopback UDP.
struct UdpHost {
    _server: Server,
    socket: UdpSocket,
    generation: u8,
    tl: u8,
}

impl UdpHost {
    /// An emulator of `boards` (the first one Ethernet-connected), and the
    /// bus generation learnt from one read of the bridge board.
    fn start(boards: Vec<BoardConfig>) -> UdpHost {
        let server = Server::start(boards);
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        socket.connect(server.addr).unwrap();
        socket
            .set_read_timeout(Some(Duration::from_secs(5)))
            .unwrap();
        let mut host = UdpHost {
            _server: server,
            socket,
            generation: 0,
            tl: 0,
        };
        let first = host
            .request(true, |h| PacketRepr::ReadQuadletRequest {
                header: h,
                offset: 4,
            })
            .expect("the bridge board answers");
        host.generation = first.extra.generation;
        host
    }

    fn header(&mut self, destination: NodeId) -> AsyncHeader {
        self.tl = (self.tl + 1) & 0x3F;
        AsyncHeader::new(destination, HOST, self.tl)
    }

    /// Send the packet `build` makes from a header to node 0 (the bridge
    /// board, with `no_forward`); the reply, if the packet is a read.
    fn request(
        &mut self,
        no_forward: bool,
        build: impl FnOnce(AsyncHeader) -> PacketRepr<'static>,
    ) -> Option<Reply> {
        let header = self.header(NodeId::local(0));
        self.send(no_forward, &build(header))
    }

    /// Send `repr` as it is; wait for the reply of a read.
    fn send(&mut self, no_forward: bool, repr: &PacketRepr<'_>) -> Option<Reply> {
        let datagram = request_datagram(no_forward, self.generation, repr);
        self.socket.send(&datagram).unwrap();
        let is_read = matches!(
            repr,
            PacketRepr::ReadQuadletRequest { .. } | PacketRepr::ReadBlockRequest { .. }
        );
        if !is_read {
            return None;
        }
        let mut buf = vec![0u8; 8192];
        let n = self.socket.recv(&mut buf).expect("a reply to the read");
        let (p, extra) = split_board_datagram(&buf[..n]).unwrap();
        let (data, data_length) = if p.tcode() == Tcode::ReadQuadletResponse {
            (p.quadlet_data().to_be_bytes().to_vec(), 4)
        } else {
            (p.payload().to_vec(), p.data_length())
        };
        Some(Reply {
            rcode: p.rcode(),
            data,
            data_length,
            extra,
        })
    }

    /// Quadlet read of `offset` at node `node` (forwarded over FireWire).
    fn qread(&mut self, node: u8, offset: u64) -> u32 {
        self.qread_to(NodeId::local(node), offset)
    }

    fn qread_to(&mut self, destination: NodeId, offset: u64) -> u32 {
        let header = self.header(destination);
        let r = self
            .send(false, &PacketRepr::ReadQuadletRequest { header, offset })
            .unwrap_or_else(|| panic!("no answer from {destination} at {offset:#x}"));
        assert_eq!(r.rcode, Rcode::Complete);
        r.quadlet()
    }

    fn qwrite(&mut self, node: u8, offset: u64, data: u32) {
        self.qwrite_to(NodeId::local(node), offset, data);
    }

    fn qwrite_to(&mut self, destination: NodeId, offset: u64, data: u32) {
        let header = self.header(destination);
        self.send(
            false,
            &PacketRepr::WriteQuadletRequest {
                header,
                offset,
                data,
            },
        );
    }

    fn bread(&mut self, node: u8, offset: u64, bytes: u16) -> Reply {
        let header = self.header(NodeId::local(node));
        self.send(
            false,
            &PacketRepr::ReadBlockRequest {
                header,
                offset,
                data_length: bytes,
                extended_tcode: 0,
            },
        )
        .unwrap_or_else(|| panic!("no answer to a block read at {offset:#x}"))
    }
}

/// Two Rev 8 QLA1 boards (IDs 0 and 1) behind the bridge, their
/// watchdogs off (virtual time follows the wall clock here: a slow run
/// must not set STATUS bit 23 between two reads compared).
fn two_boards() -> UdpHost {
    let mut host = UdpHost::start(qla1s(2, Profile::Rev8));
    host.qwrite(63, 3, 0);
    assert_eq!(host.qread(0, 3), 0);
    assert_eq!(host.qread(1, 3), 0);
    host
}

/// Row 1. EthernetIO.v: the IP address register (11) powers up
/// `IP_UNASSIGNED`, `0xFFFFFFFF`, until a host writes one.
#[test]
fn row01_ip_address_powers_up_unassigned() {
    let mut host = two_boards();
    assert_eq!(host.qread(0, 11), 0xFFFF_FFFF);
    assert_eq!(host.qread(1, 11), 0xFFFF_FFFF);
    host.qwrite(1, 11, 0x6400_FEA9);
    assert_eq!(host.qread(1, 11), 0x6400_FEA9);
    // A reboot (STATUS 0x00300000) brings it back.
    host.qwrite(1, 0, 0x0030_0000);
    assert_eq!(host.qread(1, 11), 0xFFFF_FFFF);
}

/// Row 2. BoardRegs.v: GIT_DESC (register 15) exists from Rev 9 on; a
/// Rev 8 board reads 0 there.
#[test]
fn row02_register_15_reads_0_at_rev_8() {
    let mut host = two_boards();
    assert_eq!(host.qread(0, 15), 0);
    assert_eq!(host.qread(1, 15), 0);
}

/// Row 3. QLA.v: while a real-time block is read (`blk_rt_rd`), the
/// temperature quadlet (`temp_sense`) carries the data buffer's status
/// (`reg_databuf`, DataBuffer.v: not collecting, channel 1, address 0 =
/// `0x0400`) in bits 31:16; a quadlet read of register 5 does not.
#[test]
fn row03_realtime_temperature_quadlet_carries_the_data_buffer_status() {
    let mut host = two_boards();
    let block = host.bread(1, 0, 128).quadlets();
    let temperature = host.qread(1, 5);
    assert_eq!(temperature >> 16, 0);
    assert_eq!(block[3], 0x0400_0000 | temperature);
    // The data buffer's own status register reads the same.
    assert_eq!(host.qread(1, 0x7800), 0x0400);
}

/// Row 4. HubReg.v l.64-65 (`last_write_addr`, `num_written`), `is_extra`,
/// l.134 (`bcReadStart`): register `0x1802` reads 1 at power-up (the last
/// write address powers up at 0; Rev 9 reads 0), and the extra word
/// `{bcReadStart, bcTimer}` (14-bit timers at Rev 8) is read at quadlet
/// `num_written` once every selected board has updated: quadlet 1 before
/// any query, after the last board's block after one.
#[test]
fn row04_hub_extra_word_and_quadlets_written() {
    let mut host = two_boards();
    assert_eq!(host.qread(1, 0x1802), 1, "power-up");
    // Before any query: quadlet 1 is the timer word; no read of quadlet 0
    // has latched bcReadStart yet.
    let word = host.qread(1, 0x1001);
    assert_ne!(word, 0xFFFF_FFFF);
    assert_eq!(word & 0xC000_C000, 0, "two 14-bit timers: {word:#x}");
    assert_eq!(word >> 16, 0, "bcReadStart at power-up: {word:#x}");
    assert_eq!(host.qread(1, 0x1000), 0, "the memory");
    // One broadcast cycle of both boards, read from board 1.
    host.qwrite(63, 0x1800, (7 << 16) | 0b11);
    let hub = host.bread(1, 0x1000, (2 * 33 + 1) * 4).quadlets();
    assert_eq!(host.qread(1, 0x1802), 66, "the blocks, not the extra word");
    let extra = hub[66];
    assert_ne!(extra, 0xFFFF_FFFF);
    let (read_start, timer) = (extra >> 16, extra & 0xFFFF);
    assert!(read_start < 0x4000 && timer < 0x4000, "{extra:#x}");
    // The timer when that quadlet goes out: 4 clocks per quadlet after a
    // 5-quadlet response header, from the read's start.
    assert_eq!(timer, (read_start + 4 * (5 + 66)) & 0x3FFF, "{extra:#x}");
}

/// Row 5. BoardRegs.v l.79, l.95: the watchdog register stores bit 31
/// (the LED select) with the 16-bit period.
#[test]
fn row05_watchdog_register_keeps_bit_31() {
    let mut host = UdpHost::start(qla1s(2, Profile::Rev8));
    assert_eq!(host.qread(1, 3), 0x1680);
    host.qwrite(1, 3, 0xFFFF_FFFF);
    assert_eq!(host.qread(1, 3), 0x8000_FFFF);
    host.qwrite(1, 3, 0x0000_1680);
    assert_eq!(host.qread(1, 3), 0x1680);
}

/// Row 6. BoardRegs.v l.94: PHY_DATA (register 2) holds 16 host-writable
/// bits (a PHY register read lands there too).
#[test]
fn row06_phy_data_is_host_writable() {
    let mut host = two_boards();
    host.qwrite(1, 2, 0xFFFF_FFFF);
    assert_eq!(host.qread(1, 2), 0x0000_FFFF);
    // A PHY read still lands there: register 3, `0x40`.
    host.qwrite(1, 1, 3);
    assert_eq!(host.qread(1, 2), 0x0340);
}

/// Row 7. MotorChannelQLA.v l.87 (`cur_ctrl`), l.172 (MOTOR_STATUS bit
/// 20): current control reads 1, with or without an I/O expander.
#[test]
fn row07_motor_status_shows_current_control() {
    let boards = vec![
        BoardConfig::new(0, Hardware::Qla1, Profile::Rev8),
        BoardConfig::new(1, Hardware::Qla1, Profile::Rev8).with_io_expander(false),
    ];
    let mut host = UdpHost::start(boards);
    for node in [0u8, 1] {
        for axis in 1..=4u64 {
            let status = host.qread(node, axis << 4 | 0xC);
            assert_eq!(status, 0x0010_8000, "board {node} axis {axis}");
        }
    }
}

/// Row 8. MotorChannelQLA.v l.180-191: a valid DAC write with control
/// mode 1 (voltage) is taken with an I/O expander (mode in MOTOR_STATUS
/// 27:24, current control 0) and refused without one (command and mode
/// kept).
#[test]
fn row08_mode_1_dac_write() {
    let boards = vec![
        BoardConfig::new(0, Hardware::Qla1, Profile::Rev8),
        BoardConfig::new(1, Hardware::Qla1, Profile::Rev8).with_io_expander(false),
    ];
    let mut host = UdpHost::start(boards);
    host.qwrite(0, 0x11, 0x8100_9000);
    assert_eq!(host.qread(0, 0x1C), 0x0100_9000, "mode 1, voltage control");
    assert_eq!(host.qread(0, 0x11), 0x9000);
    host.qwrite(1, 0x11, 0x8100_9000);
    assert_eq!(host.qread(1, 0x1C), 0x0010_8000, "refused");
    assert_eq!(host.qread(1, 0x11), 0x8000);
    // Mode 2 is no mode: refused everywhere.
    host.qwrite(0, 0x21, 0x8200_9000);
    assert_eq!(host.qread(0, 0x2C), 0x0010_8000);
    // Back to mode 0 with the expander.
    host.qwrite(0, 0x11, 0x8000_8100);
    assert_eq!(host.qread(0, 0x1C), 0x0010_8100);
}

/// Row 9. MotorChannelQLA.v l.61 (`cur_lim` powers up `0x0418`, 200 mA),
/// l.79: MOTOR_CONFIG at power-up is `0x03780418` with an I/O expander
/// (bit 25) and `0x01780418` without one.
#[test]
fn row09_motor_config_at_power_up() {
    let boards = vec![
        BoardConfig::new(0, Hardware::Qla1, Profile::Rev8),
        BoardConfig::new(1, Hardware::Qla1, Profile::Rev8).with_io_expander(false),
    ];
    let mut host = UdpHost::start(boards);
    for axis in 1..=4u64 {
        let with = host.qread(0, axis << 4 | 0xB);
        assert_eq!(with, 0x0378_0418);
        assert_eq!(with & !0x0200_0000, 0x0178_0418, "expander bit masked");
        assert_eq!(host.qread(1, axis << 4 | 0xB), 0x0178_0418);
    }
}

/// Row 10. MotorChannelQLA.v l.196-199, l.79: a MOTOR_CONFIG write loads
/// the delay only with bit 25 and the current limit only with bit 24 (its
/// bit 15 forced to 0); bits 31 (disable safety) and 30 (force disable)
/// are stored and read back.
#[test]
fn row10_motor_config_writes() {
    let mut host = two_boards();
    // Neither load bit: delay and limit kept.
    host.qwrite(1, 0x1B, 0x0028_2000);
    assert_eq!(host.qread(1, 0x1B), 0x0378_0418);
    // Both, with bits 31/30 and limit bit 15.
    host.qwrite(1, 0x1B, 0xC328_8123);
    assert_eq!(host.qread(1, 0x1B), 0xC328_0123);
    // The limit alone; bits 31/30 follow every write.
    host.qwrite(1, 0x1B, 0x0100_0456);
    assert_eq!(host.qread(1, 0x1B), 0x0328_0456);
    // The delay alone.
    host.qwrite(1, 0x1B, 0x4250_7777);
    assert_eq!(host.qread(1, 0x1B), 0x4350_0456);
}

/// Row 11. EncPeriod.v l.74-82, l.162-164, l.188: before any encoder edge
/// the period reads `0xCBFFFFFF` (overflow, direction 1, partial), the
/// quarter cycles `0x43FFFFFF` (direction 1, no overflow bit), the running
/// counter `0x83FFFFFF` (counter at its top, overflow); in registers and
/// in the real-time block alike.
#[test]
fn row11_encoder_words_before_any_edge() {
    let mut host = two_boards();
    for axis in 1..=4u64 {
        let ch = axis << 4;
        assert_eq!(host.qread(1, ch | 6), 0xCBFF_FFFF, "period {axis}");
        assert_eq!(host.qread(1, ch | 7), 0x43FF_FFFF, "qtr1 {axis}");
        assert_eq!(host.qread(1, ch | 9), 0x43FF_FFFF, "qtr5 {axis}");
        assert_eq!(host.qread(1, ch | 10), 0x83FF_FFFF, "running {axis}");
    }
    let block = host.bread(1, 0, 128).quadlets();
    // QLA1 Rev 8: 4 + 4 ADC + 4 positions, then 4 each of period, qtr1,
    // qtr5, running.
    assert!(
        block[12..16].iter().all(|&w| w == 0xCBFF_FFFF),
        "{block:08x?}"
    );
    assert!(
        block[16..24].iter().all(|&w| w == 0x43FF_FFFF),
        "{block:08x?}"
    );
    assert!(
        block[24..28].iter().all(|&w| w == 0x83FF_FFFF),
        "{block:08x?}"
    );
}

/// Row 12. FireWire.v l.1306, l.1407: a block read of the main space at a
/// non-zero offset is a real-time block read, answered from the sampled
/// block from that quadlet on (offset 1, 8 bytes: STATUS and DIGITAL_IN).
#[test]
fn row12_main_space_block_read_at_an_offset() {
    let mut host = two_boards();
    let status = host.qread(1, 0);
    let digin = host.qread(1, 10);
    let r = host.bread(1, 0x0001, 8);
    assert_eq!(r.rcode, Rcode::Complete);
    assert_eq!(r.quadlets(), vec![status, digin]);
    // Offset 4: the first ADC quadlet, not HW_VERSION.
    let r = host.bread(1, 0x0004, 4);
    assert_ne!(r.quadlet(), 0x514C_4131);
    // The pot reading carries measurement noise: close, not equal.
    let pot = i64::from(r.quadlet() >> 16);
    let again = i64::from(host.qread(1, 0x10) >> 16);
    assert!((pot - again).abs() < 256, "axis 1 pot {pot} vs {again}");
}

/// Row 13. FireWire.v l.1162: a block read of any length up to the
/// largest is answered `resp_complete` with exactly that many bytes, 0
/// and 6 included.
#[test]
fn row13_block_reads_of_length_0_and_6() {
    let mut host = two_boards();
    let r = host.bread(1, 0x0001, 0);
    assert_eq!((r.rcode, r.data_length), (Rcode::Complete, 0));
    let status = host.qread(1, 0);
    let r = host.bread(1, 0x0001, 6);
    assert_eq!((r.rcode, r.data_length), (Rcode::Complete, 6));
    assert_eq!(r.data.get(..4), Some(&status.to_be_bytes()[..]));
}

/// Row 14. FireWire.v l.351, l.443-470: quadlet reads of
/// `0xFFFFF0000400-042C` answer the configuration ROM's bus information
/// block and root directory (quadlet 4 the firmware version).
#[test]
fn row14_configuration_rom() {
    const ROM: [u32; 12] = [
        0x0404_8496,
        0x3133_3934,
        0x00FF_A000,
        0xFA61_0E0E,
        0x0000_0008,
        0x0005_9395,
        0x0C00_83C0,
        0x03FA_610E,
        0x8100_0003,
        0x1700_0002,
        0x8100_0006,
        0x0004_56C4,
    ];
    let mut host = two_boards();
    for (k, &q) in ROM.iter().enumerate() {
        let offset = 0xFFFF_F000_0400 + 4 * k as u64;
        assert_eq!(host.qread(1, offset), q, "{offset:#x}");
    }
}

/// Row 15. FireWire.v l.891: only the physical ID of the destination is
/// compared; a request to bus 0 or to bus `0x3EF` is answered and
/// committed.
#[test]
fn row15_destination_bus_id_is_not_compared() {
    let mut host = two_boards();
    for bus in [0x0000u16, 0xFBC0] {
        let node = NodeId(bus | 1);
        assert_eq!(host.qread_to(node, 4), 0x514C_4131, "{node}");
        host.qwrite_to(node, 3, 0x0000_0123);
        assert_eq!(host.qread(1, 3), 0x0123, "{node}: committed");
        host.qwrite(1, 3, 0x1680);
    }
}

/// A rig of two Rev 8 boards on the simulated bus (PC's link at the root).
fn bus_rig(boards: Vec<BoardConfig>) -> BoardRig {
    let options = RigOptions {
        trace: TraceLevel::Verbose,
        ..RigOptions::default()
    };
    let mut rig = BoardRig::daisy_chain(boards, &options);
    let t = rig.bus.now() + SimDuration::from_micros(20);
    rig.bus.run_until(t);
    rig
}

fn emit(repr: &PacketRepr<'_>) -> Vec<u8> {
    let mut buf = vec![0u8; repr.buffer_len()];
    let n = repr.emit(&mut buf).unwrap();
    buf.truncate(n);
    buf
}

/// The physical ID of board `index` and the PC link's node ID.
fn ids(rig: &BoardRig, index: usize) -> (NodeId, NodeId) {
    let phy = rig.bus.phy_id(rig.boards[index]).unwrap();
    let pc = rig.bus.node::<HostLink>(rig.host).unwrap().node_id();
    (NodeId::local(phy), pc)
}

/// Send `bytes` from the PC's link as they are and wait for the outcome.
fn transact(rig: &mut BoardRig, bytes: &[u8]) -> Completion {
    let host = rig.host;
    let token = HostLink::submit_on(&mut rig.bus, host, bytes, Speed::S400).unwrap();
    let deadline = rig.bus.now() + SimDuration::from_micros(500);
    HostLink::wait_on(&mut rig.bus, host, token, deadline).expect("the transaction ends")
}

fn register(rig: &mut BoardRig, index: usize, offset: u64) -> u32 {
    let (dest, pc) = ids(rig, index);
    let read = emit(&PacketRepr::ReadQuadletRequest {
        header: AsyncHeader::new(dest, pc, 40),
        offset,
    });
    let done = transact(rig, &read);
    let response = done.response.expect("a response");
    Packet::new_checked(&response[..]).unwrap().quadlet_data()
}

/// Row 16. FireWire.v l.1090: a quadlet read whose header CRC fails is
/// acknowledged `ack_data_error` (0xD) and gets no response.
#[test]
fn row16_bad_header_crc_read_gets_ack_data_error() {
    let mut rig = bus_rig(qla1s(2, Profile::Rev8));
    let (dest, pc) = ids(&rig, 1);
    let mut read = emit(&PacketRepr::ReadQuadletRequest {
        header: AsyncHeader::new(dest, pc, 9),
        offset: 4,
    });
    // Flip a bit of the header CRC (bytes 12..16 of a quadlet read).
    read[13] ^= 0x20;
    let done = transact(&mut rig, &read);
    assert_eq!(done.ack, Some(Ack::DataError));
    assert_eq!(done.outcome, Outcome::AckError);
    assert!(done.response.is_none());
}

/// Row 17. FireWire.v l.893-919: the link takes only quadlet and block
/// reads and writes; a lock request (tcode 9) gets no acknowledge at all.
#[test]
fn row17_lock_request_gets_no_ack() {
    let mut rig = bus_rig(qla1s(2, Profile::Rev8));
    let (dest, pc) = ids(&rig, 1);
    let mut lock = emit(&PacketRepr::WriteBlockRequest {
        header: AsyncHeader::new(dest, pc, 10),
        offset: 0x11,
        extended_tcode: 2,
        data: &[0, 0, 0x80, 0, 0x80, 0, 0x90, 0],
    });
    lock[3] = (lock[3] & 0x0F) | (9 << 4);
    {
        let mut p = Packet::new_unchecked(&mut lock[..]);
        p.fill_header_crc();
    }
    assert_eq!(
        Packet::new_checked(&lock[..]).unwrap().tcode(),
        Tcode::LockRequest
    );
    let done = transact(&mut rig, &lock);
    assert_eq!(done.ack, None);
    assert_eq!(done.outcome, Outcome::NoAck);
    assert_eq!(register(&mut rig, 1, 0x11), 0x8000, "nothing written");
}

/// Row 18. FireWire.v l.956 (only offset bits 15:0 are decoded),
/// FPGA1394V2.v l.187-191 (the read mux): `0xFFFF00000400` reads STATUS
/// (the main space decodes bits 7:0), `0xC000` reads STATUS at Rev 8 (an
/// unused space falls through to the board registers; 0 at Rev 9), and
/// `0x5000` reads the received-packet memory: the read request itself.
#[test]
fn row18_offsets_above_bit_15_and_space_c() {
    let mut host = two_boards();
    let status = host.qread(1, 0);
    assert_eq!(host.qread(1, 0xFFFF_0000_0400), status);
    assert_eq!(host.qread(1, 0xC000), status);
    // Quadlet 0 of the request as it arrived over FireWire: destination,
    // label, tcode 4 (the bridge passes it on as the host sent it).
    let tl = (host.tl + 1) & 0x3F;
    let q0 = (0xFFC1u32 << 16) | (u32::from(tl) << 10) | (0x4 << 4);
    assert_eq!(host.qread(1, 0x5000), q0);
}

/// Row 19. FireWire.v (the status broadcast's bus request): a Rev 8 board
/// asks for the bus with an isochronous-class request (Rev 9 asks with a
/// priority-class one).
#[test]
fn row19_status_broadcast_asks_with_an_isochronous_request() {
    assert_eq!(
        status_broadcast_class(Profile::Rev8),
        ArbitrationClass::Isochronous
    );
    let mut rig = bus_rig(qla1s(2, Profile::Rev8));
    for b in &rig.boards {
        let node = rig.bus.node::<BoardNode>(*b).unwrap();
        assert_eq!(node.broadcast_class(), ArbitrationClass::Isochronous);
    }
    let (_, pc) = ids(&rig, 0);
    let query = emit(&PacketRepr::WriteQuadletRequest {
        header: AsyncHeader::new(NodeId::BROADCAST, pc, 1),
        offset: 0x1800,
        data: (3 << 16) | 0b11,
    });
    transact(&mut rig, &query);
    let t = rig.bus.now() + SimDuration::from_micros(100);
    rig.bus.run_until(t);
    let boards: Vec<usize> = rig.boards.iter().map(|h| h.0).collect();
    let broadcasts: Vec<_> = rig
        .bus
        .trace()
        .packets()
        .iter()
        .filter(|p| p.kind == PacketKind::Request && boards.contains(&p.sender))
        .collect();
    assert_eq!(broadcasts.len(), 2, "one status broadcast per board");
    for p in broadcasts {
        assert_eq!(p.class, Some(ArbitrationClass::Isochronous));
    }
}

/// The decision of issue 35 (FireWire.v l.1097: a quadlet write whose
/// header CRC fails is acknowledged 0xD and written; l.855: a real-time
/// block write is written quadlet by quadlet before its data CRC is
/// known). Firelink acknowledges both as the firmware does and commits
/// neither, unless the board is configured to (`commit_corrupt_writes`,
/// `firelink emulate --commit-corrupt-writes`).
#[test]
fn damaged_writes_are_acknowledged_and_committed_only_on_request() {
    for commit in [false, true] {
        let boards = (0..2)
            .map(|id| {
                BoardConfig::new(id, Hardware::Qla1, Profile::Rev8)
                    .with_commit_corrupt_writes(commit)
            })
            .collect();
        let mut rig = bus_rig(boards);
        let (dest, pc) = ids(&rig, 1);
        // A quadlet write with a damaged header CRC.
        let mut write = emit(&PacketRepr::WriteQuadletRequest {
            header: AsyncHeader::new(dest, pc, 11),
            offset: 0x11,
            data: 0x8000_9000,
        });
        write[17] ^= 0x04;
        let done = transact(&mut rig, &write);
        assert_eq!(done.ack, Some(Ack::DataError), "commit {commit}");
        let expected = if commit { 0x9000 } else { 0x8000 };
        assert_eq!(register(&mut rig, 1, 0x11), expected, "commit {commit}");
        // A real-time block write (header, 4 DACs, control) with a damaged
        // data CRC.
        let block: Vec<u8> = [
            (1u32 << 8) | 6,
            0x8000_9100,
            0x8000_9200,
            0x8000_9300,
            0x8000_9400,
            0,
        ]
        .iter()
        .flat_map(|q| q.to_be_bytes())
        .collect();
        let mut write = emit(&PacketRepr::WriteBlockRequest {
            header: AsyncHeader::new(dest, pc, 12),
            offset: 0,
            extended_tcode: 0,
            data: &block,
        });
        let last = write.len() - 1;
        write[last] ^= 0x01;
        let done = transact(&mut rig, &write);
        assert_eq!(done.ack, Some(Ack::DataError), "commit {commit}");
        let expected = if commit { 0x9200 } else { 0x8000 };
        assert_eq!(register(&mut rig, 1, 0x21), expected, "commit {commit}");
    }
}
