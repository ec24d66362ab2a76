//! Records what one emulated board sees on the simulated bus and what it
//! answers, for the Verilog cross-check (`hdl/tests/test_crosscheck.py`).
//!
//! ```text
//! cargo run -p firelink-board --example hdl_stream -- hdl/build/stream.json
//! ```
//!
//! 1. A session runs on the simulated bus: the PC's link at the root and
//!    three QLA1 Rev 8 boards (IDs 0, 1, 2) on a daisy chain. The PC does
//!    what a robot program does: discovery reads, PHY register access,
//!    watchdog and power setup, encoder preloads, then broadcast cycles at
//!    1 kHz (query, hub read, command block) with amplifiers enabled and
//!    currents commanded, real-time block reads, a few deliberately corrupt
//!    packets (bad header CRC, bad data CRC), and a quiet spell that lets
//!    the watchdog fire. The bus trace is kept at the verbose level.
//! 2. From the trace, every packet delivered to board 1 (the board under
//!    test) is taken with the instant its last bit arrived, plus the
//!    instants its own status broadcasts finished.
//! 3. That stream is replayed into a fresh `Firmware` with the same
//!    configuration (the software board): its replies, its status
//!    broadcasts and the instant each became ready to go, and, at each
//!    packet, the values of the board's sensors (ADC, encoder counter and
//!    velocity words, switch lines, temperatures) are recorded. The replay
//!    must answer exactly as the board did on the bus (checked here).
//! 4. Everything is written as JSON: times in 49.152 MHz clocks since
//!    power-up (the FPGA's own count), bytes in hex.
//!
//! The Verilog testbench drives the same packets into the HDL node at the
//! same clocks, with the same sensor values on its QLA inputs, and compares
//! every ack, every response byte and every status broadcast (bytes and the
//! clock of its bus request).

use std::fmt::Write as _;
use std::process::ExitCode;

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_board::qla::{Firmware, Reply};
use firelink_bus::trace::{PacketKind, TraceEvent};
use firelink_bus::{HostLink, SimDuration, SimTime, TraceLevel};
use firelink_wire::packet::{AsyncHeader, NodeId, PacketRepr, Speed};

/// Index of the board under test (board ID 1, physical ID 1).
const DUT: usize = 1;
/// Boards on the bus.
const BOARDS: u8 = 3;

/// The boards: QLA1 Rev 8, generic motors, a motor supply that is good
/// 1 ms after power is enabled (keeps the simulated span, and so the
/// Verilog simulation, short).
fn configs() -> Vec<BoardConfig> {
    (0..BOARDS)
        .map(|id| {
            let mut cfg =
                BoardConfig::new(id, Hardware::Qla1, Profile::Rev8).with_seed(100 + u64::from(id));
            cfg.supply_rise = SimDuration::from_millis(1);
            cfg
        })
        .collect()
}

/// The PC's side of the session.
struct Pc {
    rig: BoardRig,
    tl: u8,
}

impl Pc {
    fn node(&self, board: usize) -> NodeId {
        let phy = self
            .rig
            .boards
            .get(board)
            .and_then(|h| self.rig.bus.phy_id(*h))
            .unwrap_or(0);
        NodeId::local(phy)
    }

    fn header(&mut self, dest: NodeId) -> AsyncHeader {
        self.tl = (self.tl + 1) % 64;
        let source = self
            .rig
            .bus
            .node::<HostLink>(self.rig.host)
            .map_or(NodeId::local(63), HostLink::node_id);
        AsyncHeader::new(dest, source, self.tl)
    }

    /// Send raw bytes and wait for the transaction (or 200 us).
    fn send(&mut self, bytes: Vec<u8>) {
        let host = self.rig.host;
        if let Ok(token) = HostLink::submit_on(&mut self.rig.bus, host, &bytes, Speed::S400) {
            let deadline = self.rig.bus.now() + SimDuration::from_micros(200);
            let _ = HostLink::wait_on(&mut self.rig.bus, host, token, deadline);
        }
    }

    fn emit(repr: &PacketRepr<'_>) -> Vec<u8> {
        let mut buf = vec![0u8; repr.buffer_len()];
        let len = repr.emit(&mut buf).unwrap_or(0);
        buf.truncate(len);
        buf
    }

    fn read(&mut self, dest: NodeId, offset: u64) {
        let header = self.header(dest);
        self.send(Self::emit(&PacketRepr::ReadQuadletRequest {
            header,
            offset,
        }));
    }

    fn write(&mut self, dest: NodeId, offset: u64, data: u32) {
        let header = self.header(dest);
        self.send(Self::emit(&PacketRepr::WriteQuadletRequest {
            header,
            offset,
            data,
        }));
    }

    fn read_block(&mut self, dest: NodeId, offset: u64, bytes: u16) {
        let header = self.header(dest);
        self.send(Self::emit(&PacketRepr::ReadBlockRequest {
            header,
            offset,
            data_length: bytes,
            extended_tcode: 0,
        }));
    }

    fn write_block(&mut self, dest: NodeId, offset: u64, data: &[u8]) -> Vec<u8> {
        let header = self.header(dest);
        Self::emit(&PacketRepr::WriteBlockRequest {
            header,
            offset,
            extended_tcode: 0,
            data,
        })
    }

    fn idle(&mut self, d: SimDuration) {
        let t = self.rig.bus.now() + d;
        self.rig.bus.run_until(t);
    }

    /// The command block of every board: DAC words (bit 31 valid, Rev 8
    /// amplifier request in bits 29:28) and a control word.
    fn command_block(&self, cycle: u32, amps: Option<bool>) -> Vec<u8> {
        let mut out = Vec::new();
        for id in 0..u32::from(BOARDS) {
            out.extend(((id << 8) | 6).to_be_bytes());
            for axis in 0..4u32 {
                let command = 0x8000 + ((cycle * 37 + axis * 1000 + id * 300) % 0x1800);
                let amp = match amps {
                    Some(true) => 0x3000_0000,
                    Some(false) => 0x2000_0000,
                    None => 0,
                };
                out.extend((0x8000_0000u32 | amp | command).to_be_bytes());
            }
            out.extend(0u32.to_be_bytes());
        }
        out
    }

    /// One broadcast I/O cycle (seed 000): query, hub read from the board
    /// under test, command block to node 0 (snooped).
    fn broadcast_cycle(&mut self, seq: u16, mask: u16, amps: Option<bool>) {
        let query = (u32::from(seq) << 16) | u32::from(mask);
        self.write(NodeId::local(0), 0x1800, query);
        self.idle(SimDuration::from_micros(20));
        let hub = u16::try_from((33 * mask.count_ones() + 1) * 4).unwrap_or(4);
        let dut = self.node(DUT);
        self.read_block(dut, 0x1000, hub);
        let block = self.command_block(u32::from(seq), amps);
        let packet = self.write_block(NodeId::local(0), 0xFFFF_FFFF_0000, &block);
        self.send(packet);
    }
}

/// The session on the bus.
fn session() -> BoardRig {
    let options = RigOptions {
        trace: TraceLevel::Verbose,
        ..RigOptions::default()
    };
    let rig = BoardRig::daisy_chain(configs(), &options);
    let mut pc = Pc { rig, tl: 0 };
    let dut = pc.node(DUT);
    pc.idle(SimDuration::from_micros(50));
    // Discovery, as the reference host does it.
    for b in 0..usize::from(BOARDS) {
        let n = pc.node(b);
        for reg in [4, 7, 12, 0, 15] {
            pc.read(n, reg);
        }
    }
    // PHY registers through PHY_CTRL / PHY_DATA.
    for reg in [0u32, 1, 2, 3] {
        pc.write(dut, 1, reg);
        pc.idle(SimDuration::from_micros(5));
        pc.read(dut, 2);
    }
    // Watchdog 2 ms, power and relay on (broadcast), preloads, delays.
    pc.write(NodeId::BROADCAST, 3, 0x0180);
    pc.write(NodeId::BROADCAST, 0, 0x000C_0000);
    pc.write(NodeId::BROADCAST, 0, 0x0003_0000);
    for axis in 1..=4u64 {
        pc.write(dut, 0x10 * axis + 4, 0x0080_0000 + 0x100 * axis as u32);
        pc.write(dut, 0x10 * axis + 0xB, 0x0328_2000);
    }
    pc.read_block(dut, 0, 128);
    // Broadcast cycles at 1 kHz until the supply is good and the
    // amplifiers have been on for a while.
    let mut seq = 1u16;
    for cycle in 0..46u32 {
        let amps = match cycle {
            0..=4 => None,
            5 => Some(true),
            _ => None,
        };
        pc.broadcast_cycle(seq, 0b111, amps);
        seq += 1;
        if cycle % 10 == 3 || cycle == 45 {
            pc.read_block(dut, 0, 128);
            pc.read(dut, 0x25);
            pc.read(dut, 0x1C);
        }
        let spent = pc.rig.bus.now();
        let next = SimTime(spent.0.div_ceil(1_000_000_000) * 1_000_000_000);
        pc.rig.bus.run_until(next);
    }
    // Corrupt packets to the board under test: a bad header CRC and a bad
    // data CRC (no effect, the second answered ack_data_error).
    let mut bad = Vec::new();
    let header = pc.header(dut);
    bad.extend(Pc::emit(&PacketRepr::WriteQuadletRequest {
        header,
        offset: 3,
        data: 0x10,
    }));
    if let Some(b) = bad.get_mut(17) {
        *b ^= 0x04;
    }
    pc.send(bad);
    let block = pc.command_block(999, Some(false));
    let mut bad = pc.write_block(dut, 0, block.get(24..48).unwrap_or(&[]));
    if let Some(b) = bad.last_mut() {
        *b ^= 0x01;
    }
    pc.send(bad);
    pc.read(dut, 3);
    pc.read(dut, 0);
    // A query that selects boards 0 and 1 only, then one that selects a
    // board that is not there (board 1 then waits for board 0 only).
    pc.broadcast_cycle(seq, 0b011, None);
    seq += 1;
    pc.idle(SimDuration::from_micros(500));
    pc.broadcast_cycle(seq, 0b110, None);
    // Silence: the watchdog (2 ms) fires; the host finds out.
    pc.idle(SimDuration::from_millis(3));
    pc.read(dut, 0);
    pc.read_block(dut, 0, 128);
    pc.read_block(dut, 0x1000, 80);
    pc.idle(SimDuration::from_micros(50));
    pc.rig
}

/// One thing the board under test lived through.
enum Event {
    Reset {
        at: SimTime,
        phy: u8,
    },
    Receive {
        at: SimTime,
        bytes: Vec<u8>,
        speed: Speed,
        live: Reply,
    },
    Transmitted {
        at: SimTime,
    },
}

impl Event {
    fn at(&self) -> SimTime {
        match self {
            Event::Reset { at, .. } | Event::Receive { at, .. } | Event::Transmitted { at } => *at,
        }
    }
}

/// The board under test's view of the session, from the trace.
fn events(rig: &BoardRig) -> Vec<Event> {
    let trace = rig.bus.trace();
    let dut = rig.boards.get(DUT).map_or(usize::MAX, |h| h.0);
    let phy = rig
        .boards
        .get(DUT)
        .and_then(|h| rig.bus.phy_id(*h))
        .unwrap_or(0);
    let reply_of = |id: u64| -> Reply {
        let ack = trace
            .packets()
            .iter()
            .find(|p| p.kind == PacketKind::Ack && p.answers == Some(id) && p.sender == dut)
            .and_then(|p| p.ack());
        let response = trace
            .packets()
            .iter()
            .find(|p| {
                p.kind == PacketKind::ConcatResponse && p.answers == Some(id) && p.sender == dut
            })
            .map(|p| p.bytes.to_vec());
        match (ack, response) {
            (Some(ack), Some(response)) => Reply::AckThenResponse { ack, response },
            (Some(ack), None) => Reply::Ack(ack),
            _ => Reply::Silent,
        }
    };
    let mut out = Vec::new();
    for entry in trace.entries() {
        match &entry.event {
            TraceEvent::ResetDone { .. } => out.push(Event::Reset {
                at: entry.time,
                phy,
            }),
            TraceEvent::Deliver { packet, node } if *node == dut => {
                if let Some(p) = trace.packet(*packet) {
                    out.push(Event::Receive {
                        at: entry.time,
                        bytes: p.bytes.to_vec(),
                        speed: p.speed,
                        live: reply_of(*packet),
                    });
                }
            }
            _ => {}
        }
    }
    for p in trace.packets() {
        if p.sender == dut && p.kind == PacketKind::Request {
            out.push(Event::Transmitted { at: p.end });
        }
    }
    out.sort_by_key(Event::at);
    out
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().fold(String::new(), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

fn list(values: &[u32]) -> String {
    let items: Vec<String> = values.iter().map(u32::to_string).collect();
    format!("[{}]", items.join(","))
}

/// The sensor values the board's QLA inputs carry at `now`, as JSON.
fn inputs(fw: &mut Firmware, now: SimTime) -> String {
    let axis = |fw: &mut Firmware, reg: u64| -> Vec<u32> {
        (1..=4u64)
            .map(|a| fw.read_quadlet(now, a * 0x10 + reg))
            .collect()
    };
    let adc = axis(fw, 0);
    let period = axis(fw, 6);
    let qtr1 = axis(fw, 7);
    let qtr5 = axis(fw, 9);
    let run = axis(fw, 10);
    let din = fw.read_quadlet(now, 10);
    let temperature = fw.read_quadlet(now, 5) & 0xFFFF;
    let raw: Vec<u32> = (0..4)
        .map(|i| fw.plant().axis(i).map_or(0, |a| a.encoder().count() as u32))
        .collect();
    let field = |shift: u32| (din >> shift) & 0xF;
    format!(
        "{{\"adc\":{},\"enc_raw\":{},\"enc_period\":{},\"enc_qtr1\":{},\"enc_qtr5\":{},\"enc_run\":{},\
         \"enc_a\":{},\"enc_b\":{},\"enc_index\":{},\"neg_limit\":{},\"pos_limit\":{},\"home\":{},\
         \"temperature\":{}}}",
        list(&adc),
        list(&raw),
        list(&period),
        list(&qtr1),
        list(&qtr5),
        list(&run),
        field(24),
        field(20),
        field(16),
        field(8),
        field(4),
        field(0),
        temperature
    )
}

fn reply_json(reply: &Reply) -> String {
    match reply {
        Reply::Silent => "null".to_string(),
        Reply::Ack(ack) => format!("{{\"ack\":{},\"response\":null}}", u8::from(*ack)),
        Reply::AckThenResponse { ack, response } => format!(
            "{{\"ack\":{},\"response\":\"{}\"}}",
            u8::from(*ack),
            hex(response)
        ),
    }
}

/// Replay the stream into a fresh software board; returns the JSON and the
/// number of replies that differ from the live run (must be 0).
fn replay(rig: &BoardRig, stream: &[Event]) -> (String, usize) {
    let cfg = configs().remove(DUT);
    let supply_rise = cfg.supply_rise;
    let mut fw = Firmware::new(cfg);
    let regs = rig
        .boards
        .get(DUT)
        .and_then(|h| rig.bus.phy_registers(*h))
        .copied()
        .unwrap_or_default();
    let mut phy = regs;
    let mut json = String::new();
    let mut broadcasts = Vec::new();
    let mut mismatches = 0;
    let mut power_on = false;
    let initial = inputs(&mut fw, SimTime::ZERO);
    let poll = |fw: &mut Firmware, now: SimTime, broadcasts: &mut Vec<String>| {
        while let Some(packet) = fw.poll_transmit(now) {
            broadcasts.push(format!(
                "{{\"ready_clock\":{},\"bytes\":\"{}\"}}",
                now.clocks(),
                hex(&packet)
            ));
        }
    };
    for event in stream {
        let at = event.at();
        // Slots that came due before this event.
        while let Some(due) = fw.next_wakeup().filter(|t| *t < at) {
            poll(&mut fw, due, &mut broadcasts);
            if fw.next_wakeup() == Some(due) {
                break;
            }
        }
        match event {
            Event::Reset { phy: id, .. } => {
                fw.bus_reset(at, *id, 0);
                let _ = writeln!(
                    json,
                    "{{\"kind\":\"reset\",\"clock\":{},\"phy_id\":{id}}},",
                    at.clocks()
                );
            }
            Event::Receive {
                bytes, speed, live, ..
            } => {
                // The sensors are read from a copy: reading them would make
                // the plant integrate up to this instant, which the board on
                // the bus did only when a packet read them (the split of the
                // integration moves the motion in its last digits, enough to
                // move a code now and then).
                let sensors = inputs(&mut fw.clone(), at);
                let reply = fw.receive(at, bytes, &mut phy);
                if &reply != live {
                    mismatches += 1;
                    eprintln!(
                        "replay differs from the bus at {:?}: {reply:?} vs {live:?}",
                        at
                    );
                }
                let speed = match speed {
                    Speed::S100 => 0,
                    Speed::S200 => 1,
                    Speed::S400 => 2,
                };
                let _ = writeln!(
                    json,
                    "{{\"kind\":\"rx\",\"clock\":{},\"t_ps\":{},\"speed\":{speed},\"bytes\":\"{}\",\
                     \"inputs\":{sensors},\"reply\":{}}},",
                    at.clocks(),
                    at.0,
                    hex(bytes),
                    reply_json(&reply)
                );
                // Motor power switched on here: the supply comparator says
                // good `supply_rise` later (first clock at or after).
                let on = fw.clone().read_quadlet(at, 0) & (1 << 18) != 0;
                if on && !power_on {
                    let good = at + supply_rise;
                    let mut k = good.clocks();
                    if SimTime::from_clocks(k) < good {
                        k += 1;
                    }
                    let _ = writeln!(json, "{{\"kind\":\"supply_good\",\"clock\":{k}}},");
                }
                power_on = on;
            }
            Event::Transmitted { .. } => {
                fw.transmitted(at);
                let _ = writeln!(json, "{{\"kind\":\"tx_done\",\"clock\":{}}},", at.clocks());
            }
        }
        poll(&mut fw, at, &mut broadcasts);
    }
    let events = json.trim_end().trim_end_matches(',').to_string();
    let registers: Vec<u32> = (0..16).map(|r| u32::from(regs.read(r))).collect();
    let clock_hz = firelink_board::time::SYSTEM_CLOCK_HZ;
    let out = format!(
        "{{\"board_id\":{DUT},\"phy_id\":{},\"clock_hz\":{clock_hz},\"supply_rise_ps\":{},\n\
         \"phy_registers\":{},\n\"initial\":{initial},\n\"events\":[\n{events}\n],\n\
         \"broadcasts\":[\n{}\n]}}\n",
        regs.read(0) >> 2,
        supply_rise.0,
        list(&registers),
        broadcasts.join(",\n")
    );
    (out, mismatches)
}

fn main() -> ExitCode {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "hdl_stream.json".to_string());
    let rig = session();
    let stream = events(&rig);
    let (json, mismatches) = replay(&rig, &stream);
    if mismatches != 0 {
        eprintln!("hdl_stream: {mismatches} replies of the replay differ from the live run");
        return ExitCode::FAILURE;
    }
    if let Err(e) = std::fs::write(&path, json) {
        eprintln!("hdl_stream: cannot write {path}: {e}");
        return ExitCode::FAILURE;
    }
    let received = stream
        .iter()
        .filter(|e| matches!(e, Event::Receive { .. }))
        .count();
    println!("hdl_stream: {received} packets received by board {DUT}, written to {path}");
    ExitCode::SUCCESS
}
