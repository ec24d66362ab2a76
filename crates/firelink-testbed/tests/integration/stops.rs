//! Joints driven open loop into their stops through the host library, as
//! in the report that asked for stops: seed 000's dVRK, MTMR's first axis,
//! its wrist roll and a PSM tool actuator each given a constant current
//! for 4 s (30 % of their maximum: at the full current a joint this free
//! runs so fast that the back-EMF eats the supply, the measured current
//! falls 0.44 A short of the command and the QLA's current check turns the
//! amplifier off before the stop, as on the real board). Each joint stops at its mechanical stop a little beyond its
//! software limit; there the pot still reads what the encoder reads; the
//! amplifier carries the full commanded current (the motor is stalled).

use std::time::Duration;

use firelink_board::plant::Axis;
use firelink_board::qla::config::Profile;
use firelink_board::qla::node::BoardNode;
use firelink_bus::NodeHandle;
use firelink_control::config::{IoConfig, presets};
use firelink_host::Port;
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::sim::SimPort;
use firelink_testbed::plant_map;
use firelink_testbed::rig;

/// One driven joint after the run.
#[derive(Debug)]
struct Driven {
    encoder: f64,
    pot: f64,
    truth: f64,
    stops: (f64, f64),
    soft: (f64, f64),
    commanded: f64,
    measured: f64,
    /// Joint units per encoder count.
    resolution: f64,
}

/// The emulated axis behind (board ID, axis), as it is now.
fn plant_axis(io: &IoSystem<SimPort>, handles: &[NodeHandle], board_id: u8, axis: usize) -> Axis {
    io.port()
        .bus()
        .node::<BoardNode>(handles[usize::from(board_id)])
        .unwrap()
        .firmware()
        .plant()
        .axis(axis)
        .unwrap()
        .clone()
}

/// Drive `joints` (joint index, signed fraction of its maximum current)
/// for `seconds` with every amplifier of theirs on; everything else off.
fn drive(config: &IoConfig, joints: &[(usize, f64)], seconds: f64) -> Vec<Driven> {
    let boards = rig::board_configs(config, Profile::Rev8, config.board_slots());
    let (port, handles) = rig::sim_port(boards, false).unwrap();
    let (mut io, _) = IoSystem::open(port, IoOptions::default()).unwrap();
    io.set_watchdog(firelink_host::WatchdogSetting::from_ms(50.0).unwrap())
        .unwrap();
    let refs: Vec<_> = joints
        .iter()
        .map(|&(i, _)| config.joints().nth(i).unwrap())
        .collect();
    let slot = |board_id: u8, io: &IoSystem<_>| {
        io.boards()
            .iter()
            .position(|b| b.board_id() == board_id)
            .unwrap()
    };
    let tick = |io: &mut IoSystem<SimPort>| {
        io.read_all();
        io.write_all();
        io.port_mut().wait(Duration::from_millis(1));
    };
    for b in io.boards_mut() {
        b.set_power(true);
        b.set_relay(true);
    }
    for _ in 0..200 {
        tick(&mut io);
    }
    // The encoders count from where the joints were at power-up.
    let start: Vec<(f64, f64)> = refs
        .iter()
        .map(|j| {
            let a = j.actuator;
            let b = &io.boards()[slot(a.board_id, &io)];
            let axis = usize::from(a.axis_id);
            let counts = b.encoder_counts(axis).unwrap();
            let truth = plant_axis(&io, &handles, a.board_id, axis).joint_position();
            (a.encoder.counts_to_position(i64::from(counts)), truth)
        })
        .collect();
    for (j, &(_, sign)) in refs.iter().zip(joints) {
        let k = slot(j.actuator.board_id, &io);
        let axis = usize::from(j.actuator.axis_id);
        let bits = j
            .actuator
            .drive
            .current_to_bits(sign * j.actuator.drive.maximum_current);
        let b = &mut io.boards_mut()[k];
        b.set_amp_enable(axis, true).unwrap();
        b.set_dac(axis, bits).unwrap();
    }
    for _ in 0..(seconds * 1000.0) as usize {
        tick(&mut io);
    }
    refs.iter()
        .zip(joints)
        .zip(&start)
        .map(|((j, &(_, sign)), &(enc0, truth0))| {
            let a = j.actuator;
            let b = &io.boards()[slot(a.board_id, &io)];
            let axis = usize::from(a.axis_id);
            assert!(b.amp_enabled(axis), "{}", j.label);
            let counts = b.encoder_counts(axis).unwrap();
            let plant_axis = plant_axis(&io, &handles, a.board_id, axis);
            let stops = plant_axis.params().stops;
            let soft = a.encoder.position_limits_soft;
            Driven {
                encoder: a.encoder.counts_to_position(i64::from(counts)) - enc0 + truth0,
                pot: a
                    .potentiometer
                    .unwrap()
                    .bits_to_position(b.pot_bits(axis).unwrap()),
                truth: plant_axis.joint_position(),
                stops: (stops.lower.unwrap(), stops.upper.unwrap()),
                soft: (soft.lower, soft.upper),
                commanded: sign * a.drive.maximum_current,
                measured: a.drive.bits_to_current(b.current_bits(axis).unwrap()),
                resolution: a.encoder.bits_to_position.scale.abs(),
            }
        })
        .collect()
}

#[test]
fn joints_driven_hard_stop_at_their_stops_with_pot_and_encoder_agreeing() {
    let config = presets::dvrk_seed000();
    let index = |label: &str| {
        config
            .joints()
            .find(|j| j.label.as_str() == label)
            .unwrap()
            .index
    };
    let (mtmr1, roll, psm_j5) = (index("MTMR[0]"), index("MTMR[6]"), index("PSM1[4]"));
    let runs = drive(&config, &[(mtmr1, -0.3), (roll, 0.3), (psm_j5, -0.3)], 4.0);
    for (name, r) in ["MTMR[0]", "MTMR[6]", "PSM1[4]"].iter().zip(&runs) {
        println!("{name}: {r:?}");
        // At a stop, beyond the software limit on the side it was driven.
        let at_lower = (r.truth - r.stops.0).abs() < 1e-12;
        let at_upper = (r.truth - r.stops.1).abs() < 1e-12;
        assert!(at_lower || at_upper, "{name}: {r:?}");
        assert!(r.stops.0 < r.soft.0 && r.soft.1 < r.stops.1, "{name}");
        // The encoder reads the stop (counted from where the joint was at
        // power-up), and so does the pot, within a few ADC counts.
        assert!((r.encoder - r.truth).abs() <= r.resolution, "{name}: {r:?}");
        assert!((r.pot - r.encoder).abs() < 0.01, "{name}: {r:?}");
        // Stalled: the whole command flows.
        assert!((r.measured - r.commanded).abs() < 0.02, "{name}: {r:?}");
    }
    // The directions the report drove: MTMR's first axis down, the roll up
    // (to +456 degrees), PSM1's tool pitch down.
    assert!((runs[0].truth - runs[0].stops.0).abs() < 1e-12);
    assert!(
        (runs[1].truth.to_degrees() - 456.0).abs() < 1e-6,
        "{:?}",
        runs[1]
    );
    assert!((runs[2].truth - runs[2].stops.0).abs() < 1e-12);
}

#[test]
fn a_stock_dvrk_file_without_firelink_sections_gets_the_arm_it_names() {
    // A dVRK configuration as its generator writes it: no `simulation`, no
    // `limits`. The emulator still knows the PSM's mechanics from the
    // robot's name, with stops 3 degrees (3 mm) beyond the soft limits.
    let mut config = presets::stock_psm1();
    for r in &mut config.robots {
        r.simulation = None;
        for a in &mut r.actuators {
            a.simulation = None;
            a.limits = None;
        }
    }
    for j in config.joints() {
        let p = plant_map::plant_for(&config, j.index).unwrap();
        assert!(p.name.starts_with("PSM J"), "{}", p.name);
        let soft = j.actuator.encoder.position_limits_soft;
        let margin = if j.actuator_index == 2 {
            0.003
        } else {
            3f64.to_radians()
        };
        assert!((p.stops.lower.unwrap() - (soft.lower - margin)).abs() < 1e-12);
        assert!((p.stops.upper.unwrap() - (soft.upper + margin)).abs() < 1e-12);
        // The amplifier honours the file's calibrated zero.
        assert_eq!(
            f64::from(p.amplifier.zero_code),
            j.actuator.drive.current_to_bits.offset
        );
    }
    assert!(firelink_testbed::plant_map::notes(&config).is_empty());
    // Drive the tool pitch (the report's joint 5) into its lower stop: the
    // pot agrees with the encoder there.
    let runs = drive(&config, &[(4, -0.3)], 2.0);
    let r = &runs[0];
    assert!((r.truth - r.stops.0).abs() < 1e-12, "{r:?}");
    assert!((r.pot - r.encoder).abs() < 0.01, "{r:?}");
}

/// The ECM's brakes (board 5, channels 0-2) hold joints 1-3: a current on
/// a braked joint moves nothing; once its brake's channel carries the
/// release current the same current moves it, and its brake engages again
/// when the channel is turned off.
#[test]
fn an_engaged_brake_holds_its_joint_until_its_channel_releases_it() {
    let config = presets::stock_ecm();
    let boards = rig::board_configs(&config, Profile::Rev8, config.board_slots());
    let (port, handles) = rig::sim_port(boards, false).unwrap();
    let (mut io, _) = IoSystem::open(port, IoOptions::default()).unwrap();
    io.set_watchdog(firelink_host::WatchdogSetting::from_ms(50.0).unwrap())
        .unwrap();
    let slot = |id: u8, io: &IoSystem<SimPort>| {
        io.boards().iter().position(|b| b.board_id() == id).unwrap()
    };
    let tick = |io: &mut IoSystem<SimPort>, ms: usize| {
        for _ in 0..ms {
            io.read_all();
            io.write_all();
            io.port_mut().wait(Duration::from_millis(1));
        }
    };
    for b in io.boards_mut() {
        b.set_power(true);
        b.set_relay(true);
    }
    tick(&mut io, 100);
    let j1 = &config.robots[0].actuators[0];
    let brake = config.robots[0].brakes.as_ref().unwrap()[0];
    let q = |io: &IoSystem<SimPort>| plant_axis(io, &handles, 4, 0).joint_position();
    let (k4, k5) = (slot(4, &io), slot(5, &io));
    let start = q(&io);
    let push = j1.drive.current_to_bits(0.3 * j1.drive.maximum_current);
    io.boards_mut()[k4].set_amp_enable(0, true).unwrap();
    io.boards_mut()[k4].set_dac(0, push).unwrap();
    tick(&mut io, 300);
    assert_eq!(q(&io), start, "braked: not a count of motion");
    assert!(plant_axis(&io, &handles, 4, 0).braked());
    // Release: the console's release current on board 5's channel 0.
    let f = brake.drive.current_to_bits;
    let code = (f.scale * brake.release_current.unwrap() + f.offset).round() as u16;
    io.boards_mut()[k5].set_amp_enable(0, true).unwrap();
    io.boards_mut()[k5].set_dac(0, code).unwrap();
    tick(&mut io, 300);
    assert!(!plant_axis(&io, &handles, 4, 0).braked());
    let moved = q(&io);
    assert!((moved - start).abs() > 0.01, "released: {start} -> {moved}");
    // Channel off: engaged again, the joint stops where it is.
    io.boards_mut()[k5].set_amp_enable(0, false).unwrap();
    tick(&mut io, 5);
    let held = q(&io);
    tick(&mut io, 200);
    assert!(plant_axis(&io, &handles, 4, 0).braked());
    assert_eq!(q(&io), held);
}
