//! Power, amplifiers, motion, watchdog and safety, driven through packets
//! as a host's servo loop would.

use crate::common;

use common::*;
use firelink_board::plant::presets;
use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::time::{SimDuration, SimTime};
use firelink_wire::packet::Ack;

const STATUS: u64 = 0;
const POWER_ON: u32 = 0x000C_0000;
const POWER_OFF: u32 = 0x0008_0000;
const RELAY_ON: u32 = 0x0003_0000;
/// The DAC code for zero motor current (mid-scale).
const ZERO_CURRENT: u16 = 0x8000;

/// A Rev 8 QLA1 board whose axes reach a terminal velocity quickly
/// (strong viscous friction), so velocity can be compared with the plant.
fn damped_board(profile: Profile) -> Rig {
    let mut axis = presets::generic_motor();
    axis.motor.viscous_friction = 6e-4;
    let cfg = BoardConfig::new(3, Hardware::Qla1, profile)
        .with_axes(vec![axis; 4])
        .with_seed(7);
    Rig::new(cfg, 1)
}

/// One servo cycle: a real-time write block with these DAC codes
/// (valid) and a control quadlet.
fn servo_write(r: &mut Rig, dacs: [u16; 4], control: u32) {
    let id = u32::from(r.fw.board_id());
    let mut block = Vec::new();
    if r.fw.config().profile.is_rev8() {
        block.push((id << 8) | 6);
        block.extend(dacs.iter().map(|&d| 0x8000_0000 | u32::from(d)));
    } else {
        block.extend(
            dacs.iter()
                .map(|&d| 0x8000_0000 | (id << 24) | u32::from(d)),
        );
    }
    block.push(control);
    assert_eq!(r.write_block(0, &block), Some(Ack::Complete));
}

/// Run the servo loop every `period` until `until`.
fn servo_until(r: &mut Rig, until: SimTime, period: SimDuration, dacs: [u16; 4]) {
    while r.now < until {
        servo_write(r, dacs, 0);
        r.wait(period);
    }
}

/// Run the servo loop every millisecond until `until_ms` milliseconds.
fn servo_every_ms_until(r: &mut Rig, until_ms: u64, dacs: [u16; 4]) {
    servo_until(
        r,
        SimTime::from_millis(until_ms),
        SimDuration::from_millis(1),
        dacs,
    );
}

/// Run the servo loop every `period` until `until`, commanding zero current
/// on every axis.
fn servo_zero_current_until(r: &mut Rig, until: SimTime, period: SimDuration) {
    servo_until(r, until, period, [ZERO_CURRENT; 4]);
}

/// DAC codes that command `code` on `axis` and zero current on the others.
fn on_one_axis(axis: usize, code: u16) -> [u16; 4] {
    let mut dacs = [ZERO_CURRENT; 4];
    dacs[axis] = code;
    dacs
}

#[test]
fn power_supply_hold_and_enable_delay() {
    let mut r = damped_board(Profile::Rev8);
    r.wait(SimDuration::from_millis(1));
    assert_eq!(r.write(STATUS, POWER_ON | RELAY_ON), Some(Ack::Complete));
    assert_eq!(r.write(STATUS, 0x0000_0101), Some(Ack::Complete));
    let t_on = SimTime::from_micros(1_000 + 5_000 + 40_000 + 2_500);
    // Supply good after 5 ms; amplifier requested at once, on after the
    // 40 ms hold and the 2.5 ms delay.
    servo_zero_current_until(
        &mut r,
        SimTime::from_millis(5),
        SimDuration::from_micros(500),
    );
    let s = r.read(STATUS);
    assert_eq!(s & (1 << 19), 0, "supply not good yet");
    assert_eq!(
        s & 0x0007_0000,
        0x0007_0000,
        "power enabled, relay on and sensed"
    );
    assert_eq!(s & 0xF, 1, "amplifier 1 requested");
    servo_zero_current_until(
        &mut r,
        SimTime::from_micros(6_500),
        SimDuration::from_micros(500),
    );
    assert_ne!(r.read(STATUS) & (1 << 19), 0, "supply good");
    servo_zero_current_until(
        &mut r,
        SimTime(t_on.0 - 1_000_000_000),
        SimDuration::from_micros(250),
    );
    assert!(r.now < t_on);
    assert_eq!(r.read(0x1C) >> 29 & 1, 0, "not on before the delay");
    assert!(!r.fw.amplifier_on(0));
    r.now = t_on;
    r.fw.advance(t_on);
    assert_eq!(r.read(0x1C) >> 28 & 3, 3, "on and requested");
    assert!(r.fw.amplifier_on(0));
    assert!(!r.fw.amplifier_on(1));
}

#[test]
fn dac_current_motion_and_velocity_fields() {
    let mut r = damped_board(Profile::Rev8);
    // Preload axis 2 before anything moves.
    r.write(0x24, 0x80_0000 + 1000);
    assert_eq!(position_counts(r.read(0x25)), 1000);
    r.write(STATUS, POWER_ON);
    // Rev 8: amplifiers enabled through the DAC word (bit 29 mask, 28 on).
    let cmd = amps_to_dac(0.3);
    r.write(0x11, 0xB000_0000 | u32::from(cmd));
    r.write(0x21, 0xB000_0000 | u32::from(cmd));
    servo_until(
        &mut r,
        SimTime::from_millis(150),
        SimDuration::from_micros(100),
        [cmd, cmd, ZERO_CURRENT, ZERO_CURRENT],
    );
    assert!(r.fw.amplifier_on(0) && r.fw.amplifier_on(1));
    for axis in 0..2usize {
        let ch = ((axis as u64) + 1) << 4;
        // DAC -> current: the measured current follows the command.
        let i = adc_to_amps(r.read(ch));
        assert!((i - 0.3).abs() < 0.02, "axis {axis}: {i} A");
        // Current -> motion: the encoder counts what the plant turned.
        let plant = r.fw.plant().axis(axis).unwrap();
        let raw = plant.encoder().count();
        let v_plant = plant.motor_velocity() * plant.counts_per_rad();
        let preload = if axis == 1 { 1000 } else { 0 };
        assert_eq!(position_counts(r.read(ch | 5)), raw + preload);
        // Velocity fields agree with the plant's velocity.
        let period = r.read(ch | 6);
        assert_eq!(
            period & 0x3800_0000,
            0,
            "no direction change, error, partial"
        );
        let v = period_to_velocity(period);
        assert!(v > 0.0);
        assert!((v - v_plant).abs() / v_plant < 0.01, "{v} vs {v_plant}");
        let qtr1 = r.read(ch | 7);
        let qtr5 = r.read(ch | 9);
        let q1 = f64::from(qtr1 & 0x03FF_FFFF);
        let q5 = f64::from(qtr5 & 0x03FF_FFFF);
        let full = f64::from(period & 0x03FF_FFFF);
        assert!((4.0 * q1 - full).abs() / full < 0.01);
        assert!((q1 - q5).abs() / q1 < 0.01);
        assert_eq!(qtr1 >> 26 & 0xF, qtr5 >> 26 & 0xF, "same edge type");
        assert_eq!(qtr1 >> 30, 1, "counting up, no overflow");
        let run = f64::from(r.read(ch | 10) & 0x03FF_FFFF);
        assert!(
            run <= q1 * 1.05,
            "running counter {run} within a quarter {q1}"
        );
    }
    // Axes 3 and 4 did not move.
    assert_eq!(position_counts(r.read(0x35)), 0);
    assert_ne!(r.read(0x36) & 0x8000_0000, 0);
    // Negative current turns the other way.
    let neg = amps_to_dac(-0.3);
    servo_until(
        &mut r,
        SimTime::from_millis(300),
        SimDuration::from_micros(100),
        [neg, cmd, ZERO_CURRENT, ZERO_CURRENT],
    );
    let v = period_to_velocity(r.read(0x16));
    assert!(v < 0.0, "{v}");
    // Stop: the period grows with the running counter, then overflows.
    r.write(STATUS, POWER_OFF);
    r.wait(SimDuration::from_millis(1500));
    assert_ne!(
        r.read(0x16) & 0x8000_0000,
        0,
        "period overflow when stopped"
    );
    assert_ne!(r.read(0x1A) & 0x8000_0000, 0, "running counter overflow");
}

#[test]
fn watchdog_expiry_and_clearing() {
    let mut r = damped_board(Profile::Rev8);
    r.write(STATUS, POWER_ON | RELAY_ON);
    r.write(STATUS, 0x0000_0F0F);
    let cmd = amps_to_dac(0.2);
    servo_every_ms_until(&mut r, 60, [cmd; 4]);
    assert!(r.fw.amplifier_on(0));
    let last_write = r.now;
    servo_write(&mut r, [cmd; 4], 0);
    // Reads do not refresh the watchdog.
    while r.now + SimDuration::from_millis(1) < SimTime(last_write.0 + 29_990_000_000) {
        assert_eq!(r.read(STATUS) & (1 << 23), 0);
        r.wait(SimDuration::from_millis(1));
    }
    r.now = SimTime(last_write.0 + 29_990_000_000);
    assert_eq!(r.read(STATUS) & (1 << 23), 0, "not yet at 29.99 ms");
    r.now = SimTime(last_write.0 + 30_001_000_000);
    let s = r.read(STATUS);
    assert_ne!(s & (1 << 23), 0, "timed out at 30 ms");
    assert_eq!(s & 0xF, 0, "every amplifier off");
    assert_eq!(s & 0x0007_0000, 0x0007_0000, "power and relay untouched");
    for axis in 0..4 {
        assert!(!r.fw.amplifier_on(axis));
        assert!(!r.fw.plant().axis(axis).unwrap().enabled());
    }
    // Neither a watchdog write, a DAC write nor a power-off write clears it.
    r.write(3, 0x1680);
    r.write(0x11, 0x8000_9000);
    r.write(STATUS, RELAY_ON);
    assert_ne!(r.read(STATUS) & (1 << 23), 0);
    // An amplifier enable clears it.
    r.write(STATUS, 0x0000_0101);
    let s = r.read(STATUS);
    assert_eq!(s & (1 << 23), 0);
    assert_eq!(s & 0xF, 1);
    // ... and so does a power enable.
    r.wait(SimDuration::from_millis(31));
    assert_ne!(r.read(STATUS) & (1 << 23), 0);
    r.write(STATUS, POWER_ON);
    assert_eq!(r.read(STATUS) & (1 << 23), 0);
}

#[test]
fn broadcast_traffic_refreshes_the_watchdog_and_zero_disables_it() {
    let mut r = damped_board(Profile::Rev8);
    // Queries to node 0 (snooped) every 10 ms keep it alive for 100 ms.
    for seq in 1..=10u32 {
        let q = quadlet_write(
            firelink_wire::packet::NodeId::local(0),
            0,
            0x1800,
            seq << 16 | 0x8,
        );
        r.deliver(&q);
        r.wait(SimDuration::from_millis(10));
    }
    assert_eq!(r.read(STATUS) & (1 << 23), 0);
    r.wait(SimDuration::from_millis(25));
    assert_ne!(r.read(STATUS) & (1 << 23), 0);
    // Period 0: never fires.
    let mut r = damped_board(Profile::Rev8);
    r.write(3, 0);
    r.wait(SimDuration::from_millis(500));
    assert_eq!(r.read(STATUS) & (1 << 23), 0);
}

#[test]
fn rev7_amplifiers_through_status() {
    let mut r = damped_board(Profile::Rev7);
    r.write(STATUS, POWER_ON);
    r.write(STATUS, 0x0000_0C04);
    let cmd = amps_to_dac(0.2);
    servo_every_ms_until(&mut r, 60, [cmd; 4]);
    let s = r.read(STATUS);
    assert_eq!(s & 0xF, 0b0100, "axis 3 requested, axis 4 off");
    assert_eq!(s >> 8 & 0xF, 0b0100, "Rev 7 amplifier status bits");
    // DAC amp bits mean nothing before Rev 8.
    r.write(0x11, 0xB000_8000);
    assert_eq!(r.read(STATUS) & 0xF, 0b0100);
    // Power off drops every request.
    r.write(STATUS, POWER_OFF);
    assert_eq!(r.read(STATUS) & 0xF, 0);
    // Amplifiers cannot be requested without power.
    r.write(STATUS, 0x0000_0F0F);
    assert_eq!(r.read(STATUS) & 0xF, 0);
}

#[test]
fn current_mismatch_disables_the_amplifier() {
    let mut axis = presets::generic_motor();
    axis.amplifier.current_limit = 0.5;
    axis.motor.coulomb_friction = 10.0; // stalled: no back-EMF
    let cfg = BoardConfig::new(0, Hardware::Qla1, Profile::Rev8).with_axis(0, axis);
    let mut r = Rig::new(cfg, 0);
    r.write(STATUS, POWER_ON);
    r.write(STATUS, 0x0000_0101);
    // 2 A asked, 0.5 A delivered: 1.5 A mismatch.
    let cmd = amps_to_dac(2.0);
    servo_every_ms_until(&mut r, 60, on_one_axis(0, cmd));
    assert!(r.fw.amplifier_on(0));
    let on_since = SimTime::from_micros(47_500);
    servo_until(
        &mut r,
        SimTime(on_since.0 + 49_000_000_000),
        SimDuration::from_millis(1),
        on_one_axis(0, cmd),
    );
    assert!(r.fw.amplifier_on(0), "still on before 50 ms of mismatch");
    servo_until(
        &mut r,
        SimTime(on_since.0 + 51_000_000_000),
        SimDuration::from_millis(1),
        on_one_axis(0, cmd),
    );
    assert!(!r.fw.amplifier_on(0));
    let s = r.read(STATUS);
    assert_eq!(s & 0xF, 0, "request dropped");
    assert_eq!(s >> 4 & 0xF, 1, "safety amp disable, axis 1");
    assert_ne!(r.read(0x1C) & (1 << 17), 0, "MOTOR_STATUS safety disable");
    // Enabling again clears the flag.
    r.write(STATUS, 0x0000_0101);
    assert_eq!(r.read(STATUS) >> 4 & 0xF, 0);
    // A consistent command keeps it on.
    let ok = amps_to_dac(0.3);
    servo_every_ms_until(&mut r, 300, on_one_axis(0, ok));
    assert!(r.fw.amplifier_on(0));
}

#[test]
fn missing_motor_supply() {
    let mut cfg = BoardConfig::new(0, Hardware::Qla1, Profile::Rev8);
    cfg.motor_supply_present = false;
    let mut r = Rig::new(cfg, 0);
    r.write(STATUS, POWER_ON);
    r.write(STATUS, 0x0000_0101);
    servo_every_ms_until(&mut r, 100, [ZERO_CURRENT; 4]);
    let s = r.read(STATUS);
    assert_eq!(s & (1 << 19), 0, "supply never good");
    assert_ne!(s & (1 << 15), 0, "supply fault");
    assert_ne!(r.read(10) & (1 << 31), 0, "V-fault in DIGITAL_IN");
    assert!(!r.fw.amplifier_on(0));
    // Connecting it: good after the rise, amplifiers after hold + delay.
    r.fw.set_motor_supply(r.now, true);
    servo_every_ms_until(&mut r, 150, [ZERO_CURRENT; 4]);
    assert_ne!(r.read(STATUS) & (1 << 19), 0);
    assert!(r.fw.amplifier_on(0));
    // Losing it turns the amplifier off at once.
    r.fw.set_motor_supply(r.now, false);
    assert!(!r.fw.amplifier_on(0));
}

/// MOTOR_CONFIG: bits 25/24 load the delay and the limit
/// (MotorChannelQLA.v l.196-199); in current control the limit is only
/// stored (the firmware checks it in voltage control), so the command
/// reaches the amplifier whole.
#[test]
fn motor_config_delay_and_current_limit() {
    let mut r = damped_board(Profile::Rev8);
    // No enable delay, current limit 0x400 counts (about 78 mA), both
    // loaded.
    r.write(0x1B, 0x0300_0400);
    assert_eq!(r.read(0x1B), 0x0300_0400);
    r.write(STATUS, POWER_ON);
    r.write(0x11, 0xB000_0000 | u32::from(amps_to_dac(1.0)));
    servo_until(
        &mut r,
        SimTime::from_micros(44_900),
        SimDuration::from_micros(100),
        on_one_axis(0, amps_to_dac(1.0)),
    );
    assert!(!r.fw.amplifier_on(0));
    r.now = SimTime::from_micros(45_000);
    r.fw.advance(r.now);
    assert!(r.fw.amplifier_on(0), "on right after the 40 ms hold");
    r.wait(SimDuration::from_millis(2));
    let i = r.fw.plant().axis(0).unwrap().current();
    assert!((i - 1.0).abs() < 0.02, "{i}");
}

/// A scripted session; returns per-millisecond (position, period, ADC).
fn session(seed: u64) -> Vec<(u32, u32, u32)> {
    let mut axis = presets::psm_joint(1).unwrap();
    axis.load.gravity = None;
    let cfg = BoardConfig::new(2, Hardware::Qla1, Profile::Rev8)
        .with_axes(vec![axis; 4])
        .with_seed(seed);
    let mut r = Rig::new(cfg, 0);
    r.write(STATUS, POWER_ON);
    r.write(STATUS, 0x0000_0F0F);
    let mut trace = Vec::new();
    for ms in 0..200u64 {
        let amps = 0.5 * ((ms as f64) * 0.05).sin();
        servo_write(&mut r, [amps_to_dac(amps); 4], 0);
        r.wait(SimDuration::from_millis(1));
        let block = r.read_block(0, 32);
        trace.push((block[8], block[12], block[4]));
    }
    trace
}

#[test]
fn same_seed_same_trace() {
    let a = session(99);
    let b = session(99);
    let c = session(100);
    assert_eq!(a, b);
    // The encoder is noise-free; the current sense is seeded.
    let enc = |t: &[(u32, u32, u32)]| t.iter().map(|x| (x.0, x.1)).collect::<Vec<_>>();
    assert_eq!(enc(&a), enc(&c));
    assert_ne!(a, c);
    // Something moved.
    assert_ne!(a.first().unwrap().0, a.last().unwrap().0);
}

#[test]
fn dqla_axes_5_to_8_through_the_dac_word() {
    let cfg = BoardConfig::new(4, Hardware::Dqla, Profile::Rev8);
    let mut r = Rig::new(cfg, 0);
    r.write(STATUS, POWER_ON);
    let cmd = amps_to_dac(0.2);
    r.write(0x81, 0xB000_0000 | u32::from(cmd));
    for _ in 0..60 {
        r.write(0x81, 0x8000_0000 | u32::from(cmd));
        r.wait(SimDuration::from_millis(1));
    }
    assert!(r.fw.amplifier_on(7));
    assert_eq!(r.read(0x8C) >> 28 & 3, 3);
    let i = adc_to_amps(r.read(0x80));
    assert!((i - 0.2).abs() < 0.02, "{i}");
    // Rev 8 DQLA block: 4 + 2*8 + 5*8 = 60 quadlets, MOTOR_STATUS of axis 8 last.
    let block = r.read_block(0, 60);
    assert_eq!(block[59] >> 28 & 3, 3);
}

#[test]
fn amplifier_temperature_rises_under_load() {
    let mut axis = presets::generic_motor();
    axis.motor.coulomb_friction = 10.0; // stalled
    axis.thermal.time_constant = 0.05;
    axis.thermal.thermal_resistance = 10.0;
    let cfg = BoardConfig::new(0, Hardware::Qla1, Profile::Rev8).with_axis(2, axis);
    let mut r = Rig::new(cfg, 0);
    // 25 C at 0.5 C per bit (the MAX6576 through the firmware).
    assert_eq!(r.read(5), 0x3232);
    r.write(STATUS, POWER_ON);
    r.write(STATUS, 0x0000_0404);
    let cmd = amps_to_dac(2.0);
    servo_every_ms_until(&mut r, 400, on_one_axis(2, cmd));
    let t = r.read(5);
    // Axes 3-4 share the sensor in bits 7:0: 2 A through 2 ohm of heat
    // plus the idle power, 10 K/W: more than 10 degrees above ambient.
    let celsius = |byte: u32| f64::from(byte) / 2.0;
    assert!(celsius(t & 0xFF) > 35.0, "{t:#x}");
    assert_eq!(celsius(t >> 8), 25.0, "axes 1-2 stay at ambient");
}
