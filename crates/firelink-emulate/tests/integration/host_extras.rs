//! Issue 13 through the host library: the firmware features of
//! `fpga-board-extras.md` driven by `firelink_host::qla::extras` over loopback
//! UDP against the emulator, as a dVRK host drives real boards.

use crate::common;

use common::Server;

use std::time::Duration;

use firelink_board::qla::Instrument;
use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_host::qla::extras::dallas::read_tool;
use firelink_host::qla::extras::dout::{
    read_digital_outputs, read_dout_control, read_waveform_table, start_waveform, waveform_status,
    write_digital_outputs, write_pwm, write_waveform_table,
};
use firelink_host::qla::extras::ethernet::{eth_status, has_eth_debug_data, read_ksz8851_register};
use firelink_host::qla::extras::prom::{
    fpga_prom_id, fpga_serial_number, qla_serial_number, write_fpga_serial_number,
    write_qla_serial_number,
};
use firelink_host::qla::extras::supply::{
    measure_dqla_supply_voltage, measure_motor_supply_voltage,
};
use firelink_host::qla::extras::{FeatureError, is_qla_expanded, read_phy_register};
use firelink_host::qla::scan::scan;
use firelink_host::{Dest, HostError, Port};

fn boards() -> Vec<BoardConfig> {
    vec![
        BoardConfig::new(0, Hardware::Qla1, Profile::Rev8)
            .with_fpga_serial("5496-01")
            .with_qla_serial(0, "22723"),
        BoardConfig::new(1, Hardware::Qla1, Profile::Rev8).with_instrument(Instrument {
            model: 420_006,
            version: 12,
            name: "PROGRASP FORCEPS".into(),
        }),
        BoardConfig::new(2, Hardware::Dqla, Profile::Rev8),
    ]
}

#[test]
fn serial_numbers_and_proms() {
    let server = Server::start(boards());
    // Generous: test builds are unoptimised and the machine is shared.
    let mut p = server.port(Duration::from_millis(500));
    // Discovery waits out a time-out per absent node: keep it short there.
    p.set_timeout(Duration::from_millis(50));
    let found = scan(&mut p).unwrap();
    assert_eq!(found.boards.len(), 3);
    p.set_timeout(Duration::from_millis(500));
    let b0 = Dest::node(0);
    assert_eq!(fpga_prom_id(&mut p, b0).unwrap(), 0x0020_2015);
    assert_eq!(fpga_serial_number(&mut p, b0).unwrap(), "5496-01");
    assert_eq!(qla_serial_number(&mut p, b0, 0).unwrap(), "22723");
    // Defaults: unique per board ID; a DQLA's two QLAs on channels 1, 2.
    let f1 = fpga_serial_number(&mut p, Dest::node(1)).unwrap();
    let f2 = fpga_serial_number(&mut p, Dest::node(2)).unwrap();
    assert_ne!(f1, f2);
    let q2a = qla_serial_number(&mut p, Dest::node(2), 1).unwrap();
    let q2b = qla_serial_number(&mut p, Dest::node(2), 2).unwrap();
    assert_ne!(q2a, q2b);
    assert!(
        qla_serial_number(&mut p, Dest::node(2), 0).is_err(),
        "a DQLA has no channel 0"
    );
    // pgm1394's write, then the host reads the new serials.
    write_fpga_serial_number(&mut p, Dest::node(1), "1234-567").unwrap();
    assert_eq!(
        fpga_serial_number(&mut p, Dest::node(1)).unwrap(),
        "1234-567"
    );
    write_qla_serial_number(&mut p, Dest::node(1), 0, "1234-56").unwrap();
    assert_eq!(
        qla_serial_number(&mut p, Dest::node(1), 0).unwrap(),
        "1234-56"
    );
    assert!(matches!(
        write_qla_serial_number(&mut p, Dest::node(1), 0, "123456789"),
        Err(FeatureError::Format(_))
    ));
}

#[test]
fn outputs_waveforms_and_status_words() {
    let server = Server::start(boards());
    // Generous: test builds are unoptimised and the machine is shared.
    let mut p = server.port(Duration::from_millis(500));
    let b0 = Dest::node(0);
    // Levels in, the same levels out (the board stores their complement).
    write_digital_outputs(&mut p, b0, 0xF, 0b0110).unwrap();
    assert_eq!(read_digital_outputs(&mut p, b0).unwrap(), 0b0110);
    assert_eq!(p.read_quadlet(b0, 6).unwrap() & 0xF, 0b1001, "raw");
    write_digital_outputs(&mut p, b0, 0x1, 0x1).unwrap();
    assert_eq!(read_digital_outputs(&mut p, b0).unwrap(), 0b0111);
    // PWM 1 kHz, 25 % on output 2: the times read back as set.
    write_pwm(&mut p, b0, 1, 1000.0, 0.25).unwrap();
    assert_eq!(read_dout_control(&mut p, b0, 1).unwrap(), (12288, 36864));
    assert!(write_pwm(&mut p, b0, 1, 300.0, 0.5).is_err(), "<= 375 Hz");
    // A table of 600 entries (two block writes), read back whole.
    let table: Vec<u32> = (0..600u32).map(|i| 0x8000_0100 | (i & 0xF)).collect();
    write_waveform_table(&mut p, b0, 0, &table).unwrap();
    let mut back = vec![0u32; 600];
    read_waveform_table(&mut p, b0, 0, &mut back).unwrap();
    assert_eq!(back, table);
    let mut stop = [0u32; 1];
    write_waveform_table(&mut p, b0, 600, &stop).unwrap();
    read_waveform_table(&mut p, b0, 600, &mut stop).unwrap();
    assert_eq!(stop, [0]);
    assert!(!waveform_status(&mut p, b0).unwrap().0);
    start_waveform(&mut p, b0, 0x3, 0x3).unwrap();
    // 600 entries of 0x101 clocks: about 3.1 ms of the emulator's time,
    // then it stops at the end marker. Over UDP the emulator's clock
    // follows the wall, so how far it got by the first status read
    // depends on the machine: the status only has to be consistent (the
    // exact playback is tested in virtual time, `reference_sequences`).
    let (playing, index) = waveform_status(&mut p, b0).unwrap();
    assert!(
        playing && index < 600 || !playing && index == 600,
        "{playing} {index}"
    );
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    let (playing, index) = loop {
        let status = waveform_status(&mut p, b0).unwrap();
        if !status.0 || std::time::Instant::now() > deadline {
            break status;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    assert!(!playing);
    assert_eq!(index, 600);
    // The instrument on board 1; none on board 0.
    let tool = read_tool(&mut p, Dest::node(1)).unwrap();
    assert_eq!(
        (tool.model, tool.version, tool.name.as_str()),
        (420_006, 12, "PROGRASP FORCEPS")
    );
    assert!(matches!(
        read_tool(&mut p, b0),
        Err(FeatureError::Unavailable { .. })
    ));
    // Ethernet: the bridge board has the link, board 1 does not.
    assert_eq!(read_ksz8851_register(&mut p, b0, 0x10).unwrap(), 0x9400);
    assert_eq!(
        read_ksz8851_register(&mut p, b0, 0xC0).unwrap() & 0xFFF0,
        0x8870
    );
    assert!(eth_status(&mut p, b0).unwrap().link_up());
    assert!(!eth_status(&mut p, Dest::node(1)).unwrap().link_up());
    assert!(!has_eth_debug_data(&mut p, b0).unwrap(), "DBG0");
    // PHY registers and the expander.
    assert_eq!(read_phy_register(&mut p, b0, 2).unwrap(), 0xE2);
    assert_eq!(read_phy_register(&mut p, b0, 3).unwrap(), 0x40);
    assert!(is_qla_expanded(&mut p, b0).unwrap());
}

#[test]
fn motor_supply_measured_per_board() {
    let server = Server::start(vec![
        BoardConfig::new(3, Hardware::Qla1, Profile::Rev8),
        BoardConfig::new(4, Hardware::Qla1, Profile::Rev8).with_motor_supply_volts(30.0),
    ]);
    // Generous: test builds are unoptimised and the machine is shared.
    let mut p = server.port(Duration::from_millis(500));
    let v = measure_motor_supply_voltage(&mut p, Dest::node(0)).unwrap();
    assert!((v - 12.0).abs() < 0.1, "board 3: {v} V");
    let v = measure_motor_supply_voltage(&mut p, Dest::node(1)).unwrap();
    assert!((v - 30.0).abs() < 0.1, "board 4: {v} V");
    // Power is off again.
    assert_eq!(p.read_quadlet(Dest::node(1), 0).unwrap() & (1 << 18), 0);
}

/// A DQLA (on its FPGA V3) measures each QLA's supply through STATUS
/// (MotorVoltage.cpp with index 1 and 2); board 5 stands for boards 5 and
/// 6: 36 V and 24 V by default, here QLA 2 at 30 V.
#[test]
fn dqla_motor_supplies_measured_per_qla() {
    let server = Server::start(vec![
        BoardConfig::new(5, Hardware::Dqla, Profile::Rev9).with_qla2_supply_volts(30.0),
    ]);
    let mut p = server.port(Duration::from_millis(500));
    let v = measure_dqla_supply_voltage(&mut p, Dest::node(0), 1).unwrap();
    assert!((v - 36.0).abs() < 0.1, "QLA 1: {v} V");
    let v = measure_dqla_supply_voltage(&mut p, Dest::node(0), 2).unwrap();
    assert!((v - 30.0).abs() < 0.1, "QLA 2: {v} V");
    assert!(measure_dqla_supply_voltage(&mut p, Dest::node(0), 3).is_err());
    assert_eq!(p.read_quadlet(Dest::node(0), 0).unwrap() & (1 << 18), 0);
}

#[test]
fn block_reads_up_to_2048_bytes_and_the_node_63_read() {
    let server = Server::start(boards());
    // Generous: test builds are unoptimised and the machine is shared.
    let mut p = server.port(Duration::from_millis(500));
    let mut big = vec![0u8; 2048];
    p.read_block(Dest::node(0), 0x1000, &mut big).unwrap();
    let mut too_big = vec![0u8; 2052];
    assert!(matches!(
        p.read_block(Dest::node(0), 0x1000, &mut too_big),
        Err(HostError::InvalidRequest { .. })
    ));
    // A broadcast quadlet read is answered by the bridge board alone.
    let status = p.read_quadlet(Dest::BROADCAST, 0).unwrap();
    assert_eq!((status >> 24) & 0xF, 0);
    let mut after = [0u8; 4];
    p.read_block(Dest::node(1), 0, &mut after).unwrap();
    assert_eq!(
        p.stats().unmatched,
        0,
        "no second answer to the node-63 read"
    );
}
