//! The Snake node of seed 001, driven only by packets as a host would send
//! them: the register map of Table 1 cell by cell, the blocks and their
//! valid bits, the watchdog, the digital pots and their EEPROM, the link
//! rules, and the plant behind each channel.

use crate::common;

use common::*;
use firelink_board::qla::{PhyRegisters, Reply};
use firelink_board::snake::channel::AmplifierModel;
use firelink_board::snake::firmware::{EEPROM_WRITE_TIME, POT_SPI_TIME};
use firelink_board::snake::{SNAKE_VERSION, SnakeFirmware, SnakeNode, SnakeNodeConfig};
use firelink_board::time::{SimDuration, SimTime};
use firelink_bus::{Bus, BusConfig, HostLink, NodeConfig};
use firelink_wire::packet::{Ack, AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Speed};
use firelink_wire::snake::address::{Access, ChannelDevice, GlobalRegister, SnakeRegister};
use firelink_wire::snake::block::{READ_BLOCK_QUADLETS, ReadBlock, ReadBlockRepr};
use firelink_wire::snake::registers::{
    AdcData, ChannelCommand, DacCommand, DacReadback, ENCODER_MIDPOINT, EncoderData, EncoderPeriod,
    PotCommand, PotOutputs, PotResult, PowerControl, SnakeStatus, Wiper,
};

const NODE: u8 = 2;

/// One Snake node on a private wire with a host.
struct SnakeRig {
    fw: SnakeFirmware,
    phy: PhyRegisters,
    now: SimTime,
    tl: u8,
}

impl SnakeRig {
    fn new(cfg: SnakeNodeConfig) -> SnakeRig {
        let mut fw = SnakeFirmware::new(cfg);
        fw.bus_reset(SimTime::ZERO, NODE, 1);
        SnakeRig {
            fw,
            phy: PhyRegisters::new(NODE),
            now: SimTime::from_micros(10),
            tl: 0,
        }
    }

    fn dest(&self) -> NodeId {
        NodeId::local(NODE)
    }

    fn tl(&mut self) -> u8 {
        self.tl = (self.tl + 1) & 0x3F;
        self.tl
    }

    fn wait(&mut self, dt: SimDuration) {
        self.now += dt;
        self.fw.advance(self.now);
    }

    fn deliver(&mut self, packet: &[u8]) -> Reply {
        self.now += SimDuration::from_micros(1);
        self.fw.receive(self.now, packet, &mut self.phy)
    }

    fn write(&mut self, offset: u64, value: u32) -> Option<Ack> {
        let tl = self.tl();
        match self.deliver(&quadlet_write(self.dest(), tl, offset, value)) {
            Reply::Ack(a) => Some(a),
            Reply::Silent => None,
            other => panic!("unexpected reply to a write: {other:?}"),
        }
    }

    /// A quadlet read: the value, or the rcode of the response.
    fn read(&mut self, offset: u64) -> Result<u32, Rcode> {
        let tl = self.tl();
        let Reply::AckThenResponse { ack, response } =
            self.deliver(&quadlet_read(self.dest(), tl, offset))
        else {
            panic!("no response to a quadlet read of {offset:#x}");
        };
        assert_eq!(ack, Ack::Pending);
        let p = Packet::new_checked(&response[..]).unwrap();
        assert!(p.verify().is_ok());
        assert_eq!(p.tl(), tl);
        assert_eq!(p.destination_id(), NodeId::local(HOST_PHY));
        match p.rcode() {
            Rcode::Complete => Ok(p.quadlet_data()),
            other => Err(other),
        }
    }

    fn block_read_raw(&mut self, offset: u64, quadlets: usize) -> Result<Vec<u32>, Rcode> {
        let tl = self.tl();
        let Reply::AckThenResponse { response, .. } =
            self.deliver(&block_read(self.dest(), tl, offset, quadlets))
        else {
            panic!("no response to a block read");
        };
        let p = Packet::new_checked(&response[..]).unwrap();
        assert!(p.verify().is_ok());
        match p.rcode() {
            Rcode::Complete => Ok(quads(p.payload())),
            other => Err(other),
        }
    }

    fn block(&mut self) -> ReadBlockRepr {
        let q = self.block_read_raw(0, READ_BLOCK_QUADLETS).unwrap();
        let b = bytes(&q);
        ReadBlockRepr::parse(&ReadBlock::new_checked(&b[..]).unwrap()).unwrap()
    }

    fn block_write(&mut self, words: &[u32]) -> Option<Ack> {
        let tl = self.tl();
        match self.deliver(&block_write(self.dest(), tl, 0, words)) {
            Reply::Ack(a) => Some(a),
            Reply::Silent => None,
            other => panic!("unexpected reply: {other:?}"),
        }
    }

    /// Run a pot command to completion; the result.
    fn pot(&mut self, channel: u8, command: PotCommand) -> PotResult {
        let control = SnakeRegister::channel(channel, ChannelDevice::PotControl)
            .unwrap()
            .offset();
        assert_eq!(self.write(control, command.to_word()), Some(Ack::Complete));
        self.wait(EEPROM_WRITE_TIME);
        let data = control + 1;
        PotResult(self.read(data).unwrap())
    }

    fn status(&mut self) -> SnakeStatus {
        SnakeStatus(self.read(0).unwrap())
    }
}

fn reg(channel: u8, device: ChannelDevice) -> u64 {
    SnakeRegister::channel(channel, device).unwrap().offset()
}

#[test]
fn register_map_cell_by_cell() {
    let mut rig = SnakeRig::new(SnakeNodeConfig::new(9));
    // Global registers.
    let status = rig.status();
    assert_eq!(status.board_id(), 9);
    assert_eq!(status.raw(), 0x0900_0000, "power-up: nothing enabled");
    assert_eq!(rig.read(0x04), Ok(SNAKE_VERSION));
    assert_eq!(
        rig.write(0x04, 1),
        Some(Ack::TypeError),
        "version is read-only"
    );
    assert_eq!(rig.read(0x03), Ok(0), "watchdog off at power-up");
    assert_eq!(rig.write(0x03, 0x1234), Some(Ack::Complete));
    assert_eq!(rig.read(0x03), Ok(0x1234));
    assert_eq!(rig.write(0x03, 0x1_0000), Some(Ack::TypeError));
    assert_eq!(rig.read(0x03), Ok(0x1234));
    assert_eq!(rig.write(0x03, 0), Some(Ack::Complete));
    // PHY: read register 1 (gap count 63 at power-up) through control/data.
    assert_eq!(rig.write(0x01, 0x0001), Some(Ack::Complete));
    assert_eq!(rig.read(0x01), Ok(0x0001));
    assert_eq!(rig.read(0x02), Ok(0x013F));
    assert_eq!(rig.write(0x01, 0x1105), Some(Ack::Complete), "PHY write");
    assert_eq!(rig.phy.gap_count(), 5);
    assert_eq!(rig.write(0x01, 0xFFFF_0000), Some(Ack::TypeError));
    assert_eq!(
        rig.write(0x02, 0),
        Some(Ack::TypeError),
        "PHY data is read-only"
    );
    // Status write: power control with mask.
    assert_eq!(
        rig.write(0x00, PowerControl::all(true).raw()),
        Some(Ack::Complete)
    );
    assert_eq!(rig.status().amp_enable(), 0x7F);
    assert_eq!(rig.status().enable_mask(), 0x7F);
    rig.write(0x00, PowerControl::channel(4, false).unwrap().raw());
    assert_eq!(rig.status().amp_enable(), 0x77);
    assert_eq!(rig.status().enable_mask(), 0x08);

    for channel in 1..=7u8 {
        // ADC: both samples in range, read-only.
        let adc = AdcData(rig.read(reg(channel, ChannelDevice::Adc)).unwrap());
        assert_eq!(adc.raw() & 0xC000_C000, 0);
        assert_eq!(
            rig.write(reg(channel, ChannelDevice::Adc), 0),
            Some(Ack::TypeError)
        );
        // DAC: power-up midpoint and zero limit; each channel written apart.
        let dac = reg(channel, ChannelDevice::Dac);
        assert_eq!(rig.read(dac), Ok(0x0000_8000));
        let v = 0x9000 + u16::from(channel);
        rig.write(dac, DacCommand::MotorVoltage(v).to_word());
        rig.write(dac, DacCommand::CurrentLimit(0x1000).to_word());
        let back = DacReadback(rig.read(dac).unwrap());
        assert_eq!((back.motor_voltage(), back.current_limit()), (v, 0x1000));
        assert_eq!(rig.write(dac, 0x0004_0000), Some(Ack::TypeError));
        // Pot control and data.
        let ctl = reg(channel, ChannelDevice::PotControl);
        assert_eq!(rig.read(ctl), Ok(0));
        assert_eq!(PotResult(rig.read(ctl + 1).unwrap()), PotResult::default());
        let r = rig.pot(channel, PotCommand::ReadWiper);
        assert!(r.ready() && !r.busy() && !r.error());
        assert_eq!(r.data(), Wiper::NOMINAL.value());
        assert_eq!(rig.read(ctl), Ok(PotCommand::ReadWiper.to_word()));
        assert_eq!(rig.write(ctl + 1, 0), Some(Ack::TypeError));
        assert_eq!(rig.write(ctl, 0x9000_0000), Some(Ack::TypeError));
        // Encoder: preload, data, period.
        let pre = reg(channel, ChannelDevice::EncoderPreload);
        assert_eq!(rig.write(pre, ENCODER_MIDPOINT), Some(Ack::Complete));
        assert_eq!(rig.read(pre), Ok(ENCODER_MIDPOINT));
        let data = EncoderData(rig.read(reg(channel, ChannelDevice::EncoderData)).unwrap());
        assert_eq!((data.count(), data.overflow()), (ENCODER_MIDPOINT, false));
        assert_eq!(rig.write(pre, 0x0100_0000), Some(Ack::TypeError));
        let period = EncoderPeriod(
            rig.read(reg(channel, ChannelDevice::EncoderPeriod))
                .unwrap(),
        );
        assert_eq!(period.ticks(), i16::MAX, "no edge yet: saturated");
        // Not implemented.
        let freq = reg(channel, ChannelDevice::EncoderFrequency);
        assert_eq!(rig.read(freq), Err(Rcode::AddressError));
        assert_eq!(rig.write(freq, 0), Some(Ack::TypeError));
    }
    // Every cell's access agrees with what the node does.
    for r in SnakeRegister::all() {
        let read = rig.read(r.offset());
        assert_eq!(read.is_ok(), r.access().readable(), "{r}");
        if r.access() == Access::NotImplemented {
            assert_eq!(read, Err(Rcode::AddressError));
        }
    }
    // Outside Table 1.
    for offset in [0x05u64, 0x0F, 0x18, 0x80, 0xF0, 0x100, 0xFFFF_F000_0000] {
        assert_eq!(rig.read(offset), Err(Rcode::AddressError), "{offset:#x}");
        assert_eq!(rig.write(offset, 0), Some(Ack::TypeError), "{offset:#x}");
    }
    assert_eq!(
        SnakeRegister::from_offset(0x30).unwrap(),
        SnakeRegister::Channel {
            channel: 3,
            device: ChannelDevice::Adc
        }
    );
    assert_eq!(
        SnakeRegister::from_offset(0x3).unwrap(),
        SnakeRegister::Global(GlobalRegister::WatchdogPeriod)
    );
}

#[test]
fn block_write_honours_valid_bits() {
    let mut rig = SnakeRig::new(SnakeNodeConfig::new(0));
    let mut words = [0u32; 7];
    words[2] = ChannelCommand::valid(0xA000).to_word();
    words[6] = ChannelCommand::valid(0x7000).to_word();
    assert_eq!(rig.block_write(&words), Some(Ack::Complete));
    for channel in 1..=7u8 {
        let expect = match channel {
            3 => 0xA000,
            7 => 0x7000,
            _ => 0x8000,
        };
        assert_eq!(
            rig.fw.motor_command(channel),
            Some(expect),
            "channel {channel}"
        );
    }
    // Invalid quadlets leave their channels alone on the next write too.
    let mut words = [0u32; 7];
    words[0] = ChannelCommand::valid(0x8100).to_word();
    rig.block_write(&words);
    assert_eq!(rig.fw.motor_command(1), Some(0x8100));
    assert_eq!(rig.fw.motor_command(3), Some(0xA000));
    // A malformed quadlet refuses the whole block; a wrong size is
    // acknowledged and ignored.
    let mut bad = [ChannelCommand::valid(0x1111).to_word(); 7];
    bad[5] = 0x0001_0000;
    assert_eq!(rig.block_write(&bad), Some(Ack::TypeError));
    assert_eq!(rig.fw.motor_command(1), Some(0x8100));
    assert_eq!(
        rig.block_write(&[ChannelCommand::valid(0x2222).to_word(); 8]),
        Some(Ack::Complete)
    );
    assert_eq!(rig.fw.motor_command(1), Some(0x8100));
    assert_eq!(rig.fw.stats().wrong_size_block_writes, 1);
    assert_eq!(rig.fw.stats().block_writes, 2);
    // Block writes elsewhere than offset 0 are refused.
    let tl = rig.tl();
    let p = block_write(rig.dest(), tl, 0x10, &[0x8000_0000; 7]);
    assert_eq!(rig.deliver(&p), Reply::Ack(Ack::TypeError));
}

#[test]
fn block_read_layout_timestamp_and_sizes() {
    let mut rig = SnakeRig::new(SnakeNodeConfig::new(5));
    rig.write(0x00, PowerControl::channel(2, true).unwrap().raw());
    let first = rig.block();
    assert_eq!(first.status.board_id(), 5);
    assert!(first.status.amp_enabled(2));
    rig.wait(SimDuration::from_micros(999));
    let second = rig.block();
    // 1 ms less the read's own microsecond: 49.152 clocks per us.
    let expected = (1000.0 * 49.152) as u32;
    assert!(
        second.timestamp.abs_diff(expected) <= 50,
        "{}",
        second.timestamp
    );
    // The block equals the quadlet registers read one by one.
    let adc = AdcData(rig.read(0x10).unwrap());
    assert_eq!(second.channels[0].adc, adc);
    // Any size up to 512 quadlets: the block first, zeros after.
    let long = rig.block_read_raw(0, 512).unwrap();
    assert_eq!(long.len(), 512);
    assert_eq!(long[0], second.status.raw());
    assert!(long[READ_BLOCK_QUADLETS..].iter().all(|q| *q == 0));
    let short = rig.block_read_raw(0, 2).unwrap();
    assert_eq!(short[0], second.status.raw());
    assert_eq!(rig.block_read_raw(0, 513), Err(Rcode::AddressError));
    assert_eq!(rig.block_read_raw(0x10, 4), Err(Rcode::AddressError));
}

#[test]
fn watchdog_expiry_disables_every_amplifier() {
    let mut rig = SnakeRig::new(SnakeNodeConfig::new(1));
    rig.write(0x00, PowerControl::all(true).raw());
    // 192 ticks of 256 clocks = 1 ms.
    rig.write(0x03, 192);
    let written = rig.now;
    // Writes within the period keep clearing the counter.
    for _ in 0..5 {
        rig.wait(SimDuration::from_micros(800));
        rig.block_write(&[0; 7]);
    }
    assert_eq!(rig.status().amp_enable(), 0x7F);
    assert!(!rig.status().watchdog_timeout());
    let last = rig.now;
    let expiry = rig.fw.watchdog_expiry().unwrap();
    assert!(expiry > written);
    assert!((expiry.0 - last.0) as f64 * 1e-6 - 1000.0 < 1.0);
    // Silence: off at the expiry, not before.
    rig.wait(SimDuration(expiry.0 - rig.now.0 - 1_000_000));
    assert!(rig.fw.amplifier_on(1));
    rig.wait(SimDuration::from_micros(2));
    assert!(!rig.fw.amplifier_on(1));
    let s = rig.status();
    assert!(s.watchdog_timeout());
    assert_eq!(s.amp_enable(), 0);
    // The flag stays until an amplifier is turned back on (a write that
    // only turns amplifiers off keeps it); re-enabling needs a write.
    rig.block_write(&[0; 7]);
    rig.write(0x00, PowerControl::all(false).raw());
    assert!(rig.status().watchdog_timeout());
    rig.write(0x00, PowerControl::channel(1, true).unwrap().raw());
    let s = rig.status();
    assert!(!s.watchdog_timeout());
    assert_eq!(s.amp_enable(), 0x01);
}

#[test]
fn watchdog_acts_on_the_bus_without_traffic() {
    let mut bus = Bus::new(BusConfig::default());
    let pc = bus.add(HostLink::new("pc"), NodeConfig::pc());
    let node = bus.add(SnakeNode::new(SnakeNodeConfig::new(0)), NodeConfig::board());
    bus.daisy_chain(&[pc, node]).unwrap();
    bus.reset();
    let send = |bus: &mut Bus, offset: u64, data: u32| {
        let p = emit(&PacketRepr::WriteQuadletRequest {
            header: AsyncHeader::new(NodeId::local(0), NodeId::local(1), 1),
            offset,
            data,
        });
        let t = HostLink::submit_on(bus, pc, &p, Speed::S400).unwrap();
        let deadline = bus.now() + SimDuration::from_micros(1000);
        HostLink::wait_on(bus, pc, t, deadline).unwrap()
    };
    send(&mut bus, 0, PowerControl::all(true).raw());
    send(&mut bus, 3, 96); // 0.5 ms
    let sent = bus.now();
    bus.run_until(sent + SimDuration::from_micros(490));
    assert!(
        bus.node::<SnakeNode>(node)
            .unwrap()
            .firmware()
            .amplifier_on(3)
    );
    bus.run_until(sent + SimDuration::from_micros(510));
    let fw = bus.node::<SnakeNode>(node).unwrap().firmware();
    assert!(!fw.amplifier_on(3));
    assert!(fw.watchdog_timed_out());
    // The firmware's state is the instant of expiry, not a later packet's.
    assert!(fw.now().0 <= (sent + SimDuration::from_micros(501)).0);
}

#[test]
fn eeprom_write_protect_and_pot_commands() {
    let mut rig = SnakeRig::new(SnakeNodeConfig::new(0));
    // Write-protected at power-up: refused, content unchanged.
    let r = rig.pot(
        4,
        PotCommand::WriteEeprom {
            word: 3,
            value: 0xBEEF,
        },
    );
    assert!(r.ready() && r.error());
    assert_eq!(rig.pot(4, PotCommand::ReadEeprom(3)).data(), 0);
    assert_eq!(rig.pot(4, PotCommand::ReadWriteProtect).data(), 1);
    // Cleared: written, read back; other channels untouched.
    rig.pot(4, PotCommand::WriteProtect(false));
    let r = rig.pot(
        4,
        PotCommand::WriteEeprom {
            word: 13,
            value: 0xBEEF,
        },
    );
    assert!(r.ready() && !r.error());
    assert_eq!(rig.pot(4, PotCommand::ReadEeprom(13)).data(), 0xBEEF);
    assert_eq!(rig.pot(5, PotCommand::ReadEeprom(13)).data(), 0);
    assert_eq!(rig.fw.pot(4).unwrap().eeprom[13], 0xBEEF);
    // Wiper and outputs.
    rig.pot(4, PotCommand::WriteWiper(Wiper::new(649).unwrap()));
    assert_eq!(rig.pot(4, PotCommand::ReadWiper).data(), 649);
    rig.pot(
        4,
        PotCommand::WriteOutputs(PotOutputs {
            speed_mode: true,
            o2: true,
        }),
    );
    assert_eq!(rig.pot(4, PotCommand::ReadOutputs).data(), 3);
    // A command while one runs is answered busy; the result shows busy.
    let ctl = reg(2, ChannelDevice::PotControl);
    rig.write(ctl, PotCommand::ReadWiper.to_word());
    assert_eq!(
        rig.write(ctl, PotCommand::ReadOutputs.to_word()),
        Some(Ack::BusyX)
    );
    let r = PotResult(rig.read(ctl + 1).unwrap());
    assert!(r.busy() && !r.ready());
    rig.wait(POT_SPI_TIME);
    let r = PotResult(rig.read(ctl + 1).unwrap());
    assert!(r.ready() && !r.busy());
    assert_eq!(r.op(), PotCommand::ReadWiper.op());
}

#[test]
fn foreign_and_damaged_packets_are_ignored() {
    let mut rig = SnakeRig::new(SnakeNodeConfig::new(0));
    let before = rig.fw.stats();
    // Another node, broadcast, a lock request: silent, nothing changes.
    let other = quadlet_write(NodeId::local(NODE + 1), 1, 0, 0x7F7F);
    assert_eq!(rig.deliver(&other), Reply::Silent);
    let bc = quadlet_write(NodeId::BROADCAST, 1, 0, 0x7F7F);
    assert_eq!(rig.deliver(&bc), Reply::Silent);
    // A lock request (compare-swap): a block write's shape, tcode 9.
    let mut lock = block_write(rig.dest(), 3, 0, &[0, 1]);
    lock[3] = (0x9 << 4) | (lock[3] & 0xF);
    Packet::new_unchecked(&mut lock[..]).fill_header_crc();
    assert_eq!(rig.deliver(&lock), Reply::Silent);
    assert_eq!(rig.status().amp_enable(), 0);
    // A header CRC error and a data CRC error: dropped silently.
    let mut p = quadlet_write(rig.dest(), 1, 0, 0x7F7F);
    p[13] ^= 0x01;
    assert_eq!(rig.deliver(&p), Reply::Silent);
    let mut p = block_write(rig.dest(), 1, 0, &[0x8000_9000; 7]);
    let last = p.len() - 1;
    p[last] ^= 0x80;
    assert_eq!(rig.deliver(&p), Reply::Silent);
    assert_eq!(rig.fw.motor_command(1), Some(0x8000));
    assert_eq!(rig.deliver(&[1, 2, 3]), Reply::Silent);
    let s = rig.fw.stats();
    assert_eq!(s.unsupported_tcode - before.unsupported_tcode, 1);
    assert_eq!(s.header_crc, 1);
    assert_eq!(s.data_crc, 1);
    assert!(s.not_addressed - before.not_addressed >= 3);
}

/// A locked-in generic motor on channel 1: the current is what the
/// amplifier commands.
fn locked_channel() -> SnakeNodeConfig {
    let mut p = firelink_board::plant::presets::generic_motor();
    p.motor.coulomb_friction = 1e3;
    p.current_sense.noise_amps = 0.0;
    SnakeNodeConfig::new(0).with_channels(vec![p])
}

#[test]
fn torque_mode_current_follows_gain_and_limit() {
    let model = AmplifierModel::default();
    let mut rig = SnakeRig::new(locked_channel());
    let dac = reg(1, ChannelDevice::Dac);
    rig.write(0x00, PowerControl::channel(1, true).unwrap().raw());
    rig.write(dac, DacCommand::CurrentLimit(0xFFFF).to_word());
    rig.write(dac, DacCommand::MotorVoltage(0xA000).to_word());
    rig.wait(SimDuration::from_millis(20));
    let gain = Wiper::NOMINAL.feedback_gain();
    let expect = model.torque_amps(0xA000, gain);
    let i = rig.fw.plant().axis(0).unwrap().current();
    assert!((i - expect).abs() < 0.005, "{i} vs {expect}");
    // The ADC's current monitor says the same (API units: +8192).
    let adc = AdcData(rig.read(0x10).unwrap());
    let amps = f64::from(adc.current()) * 2.5 / 16384.0 / model.monitor_volts_per_amp;
    assert!((amps - expect).abs() < 0.01, "{amps}");
    // A higher wiper, a higher gain: less current for the same command.
    rig.pot(1, PotCommand::WriteWiper(Wiper::new(649).unwrap()));
    rig.wait(SimDuration::from_millis(20));
    let i2 = rig.fw.plant().axis(0).unwrap().current();
    assert!((i2 - expect * gain / 3.57727).abs() < 0.005, "{i2}");
    // The limit channel caps it.
    rig.write(dac, DacCommand::CurrentLimit(0x0800).to_word());
    rig.wait(SimDuration::from_millis(20));
    let cap = model.limit_amps(0x0800);
    let i3 = rig.fw.plant().axis(0).unwrap().current();
    assert!((i3 - cap).abs() < 0.002, "{i3} vs {cap}");
    // Disabled: no current.
    rig.write(0x00, PowerControl::all(false).raw());
    rig.wait(SimDuration::from_millis(20));
    assert_eq!(rig.fw.plant().axis(0).unwrap().current(), 0.0);
}

#[test]
fn speed_mode_holds_a_speed_and_the_encoder_counts() {
    let mut rig = SnakeRig::new(SnakeNodeConfig::new(0));
    let dac = reg(1, ChannelDevice::Dac);
    rig.pot(
        1,
        PotCommand::WriteOutputs(PotOutputs {
            speed_mode: true,
            o2: false,
        }),
    );
    rig.write(reg(1, ChannelDevice::EncoderPreload), ENCODER_MIDPOINT);
    rig.write(0x00, PowerControl::channel(1, true).unwrap().raw());
    rig.write(dac, DacCommand::CurrentLimit(0xFFFF).to_word());
    rig.write(dac, DacCommand::MotorVoltage(0x8800).to_word());
    rig.wait(SimDuration::from_millis(300));
    let w1 = rig.fw.plant().axis(0).unwrap().motor_velocity();
    rig.wait(SimDuration::from_millis(100));
    let w2 = rig.fw.plant().axis(0).unwrap().motor_velocity();
    assert!(w1 > 1.0, "{w1}");
    assert!((w2 - w1).abs() / w1 < 0.02, "steady: {w1} {w2}");
    // Twice the command, about twice the speed.
    rig.write(dac, DacCommand::MotorVoltage(0x9000).to_word());
    rig.wait(SimDuration::from_millis(400));
    let w3 = rig.fw.plant().axis(0).unwrap().motor_velocity();
    assert!((w3 / w2 - 2.0).abs() < 0.2, "{w2} {w3}");
    // The encoder counted up from the preload; the period is positive.
    let e = EncoderData(rig.read(0x15).unwrap());
    assert!(e.count() > ENCODER_MIDPOINT && !e.overflow());
    let p = EncoderPeriod(rig.read(0x16).unwrap());
    assert!(p.ticks() > 0 && p.ticks() < i16::MAX);
    let cps = p.counts_per_second();
    let true_cps = w3 * rig.fw.plant().axis(0).unwrap().counts_per_rad();
    assert!(
        (cps - true_cps).abs() / true_cps < 0.1,
        "{cps} vs {true_cps}"
    );
}

#[test]
fn an_amplifier_fault_disables_its_channel() {
    let mut rig = SnakeRig::new(SnakeNodeConfig::new(0));
    rig.write(0x00, PowerControl::all(true).raw());
    let now = rig.now;
    rig.fw.set_fault(now, 6, true);
    let s = rig.status();
    assert!(s.fault(6));
    assert!(!s.amp_enabled(6));
    assert_eq!(s.amp_enable(), 0x5F);
    // Cannot be enabled while the line is asserted.
    rig.write(0x00, PowerControl::channel(6, true).unwrap().raw());
    assert!(!rig.status().amp_enabled(6));
    let now = rig.now;
    rig.fw.set_fault(now, 6, false);
    rig.write(0x00, PowerControl::channel(6, true).unwrap().raw());
    assert!(rig.status().amp_enabled(6));
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        /// Untrusted bytes never panic the node; every packet is counted
        /// once.
        #[test]
        fn any_bytes_are_handled(packets in proptest::collection::vec(
            proptest::collection::vec(any::<u8>(), 0..64), 1..20)) {
            let mut rig = SnakeRig::new(SnakeNodeConfig::new(0));
            for p in &packets {
                let _ = rig.deliver(p);
            }
            prop_assert_eq!(rig.fw.stats().packets, packets.len() as u64);
        }

        /// Well-formed requests anywhere in the address space: a read is
        /// always answered with a packet whose CRCs check; a write never
        /// changes what Table 1 says it cannot.
        #[test]
        fn requests_anywhere_are_answered_cleanly(
            ops in proptest::collection::vec((0u8..4, 0u64..0x120, any::<u32>(), 1usize..40), 1..40)
        ) {
            let mut rig = SnakeRig::new(SnakeNodeConfig::new(3));
            for (kind, offset, value, quadlets) in ops {
                match kind {
                    0 => { let _ = rig.read(offset); }
                    1 => {
                        let version_before = rig.read(0x04);
                        let _ = rig.write(offset, value);
                        prop_assert_eq!(rig.read(0x04), version_before);
                    }
                    2 => { let _ = rig.block_read_raw(offset & 0x1, quadlets); }
                    _ => {
                        let words: Vec<u32> = (0..quadlets as u32).map(|k| value ^ k).collect();
                        let _ = rig.block_write(&words);
                    }
                }
            }
            prop_assert_eq!(rig.status().board_id(), 3);
        }
    }
}
