//! Issue 31 (boards and firmware): an FPGA V3 / Rev 9 QLA1 and a DQLA on
//! the simulated bus, driven through the host library as any program
//! drives them: the scan tells them apart, the broadcast cycle carries the
//! DQLA's 60-quadlet block, amplifiers go on and off per QLA, and the
//! watchdog turns them off when the host goes quiet.

use std::time::Duration;

use firelink_board::qla::config::{BoardConfig, FpgaVersion, Hardware, Profile};
use firelink_board::qla::node::BoardNode;
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::{Protocol, scan};
use firelink_host::sim::SimPort;
use firelink_host::{Port, WatchdogSetting};

/// Board 0: QLA1 on an FPGA V3 at Rev 9; board 1: a DQLA (on its V3 by
/// default) at Rev 9.
fn v3_port() -> SimPort {
    let boards = vec![
        BoardConfig::new(0, Hardware::Qla1, Profile::Rev9)
            .with_fpga(FpgaVersion::V3)
            .with_git_desc(0x0ABC_DEF8),
        BoardConfig::new(1, Hardware::Dqla, Profile::Rev9),
    ];
    let r = BoardRig::daisy_chain(boards, &RigOptions::default());
    SimPort::new(r.bus, r.host)
}

/// The emulated DQLA's amplifier states as its firmware holds them.
fn dqla_amps(io: &mut IoSystem<SimPort>) -> [bool; 8] {
    let now = firelink_board::time::SimTime(io.port().bus().now().0);
    let node = io.port().bus().node_by_phy(1).unwrap();
    let fw = io
        .port_mut()
        .bus_mut()
        .node_mut::<BoardNode>(node)
        .unwrap()
        .firmware_mut();
    fw.advance(now);
    core::array::from_fn(|axis| fw.amplifier_on(axis))
}

#[test]
fn scan_tells_v3_rev9_boards_and_the_dqla_apart() {
    let mut p = v3_port();
    let report = scan(&mut p).unwrap();
    assert_eq!(report.boards.len(), 2);
    let (qla, dqla) = (&report.boards[0], &report.boards[1]);
    for b in [qla, dqla] {
        assert_eq!(b.fpga, FpgaVersion::V3, "ETH_STATUS bits 31:30 = 01");
        assert_eq!(b.firmware, 9);
    }
    assert_eq!(
        qla.git.raw(),
        0x0ABC_DEF8,
        "GIT_DESC in register 15 (Rev 9)"
    );
    assert_eq!(qla.hardware.name(), "QLA1");
    assert_eq!(qla.layout.read_block_quadlets(), 32);
    assert_eq!(dqla.hardware.name(), "DQLA");
    assert_eq!(dqla.layout.motors(), 8);
    assert_eq!(dqla.layout.read_block_quadlets(), 60, "4 + 2x8 + 5x8");
    assert_eq!(dqla.layout.write_block_quadlets(), 10, "M + 2");
    assert_eq!(report.protocol, Protocol::Broadcast);
}

#[test]
fn broadcast_cycles_amplifiers_per_qla_and_the_watchdog() {
    let (mut io, _) = IoSystem::open(v3_port(), IoOptions::default()).unwrap();
    assert_eq!(io.protocol(), Protocol::Broadcast);
    for _ in 0..20 {
        let r = *io.cycle();
        assert!(r.all_ok(), "{r:?}");
    }
    assert_eq!(io.board(1).unwrap().axes(), 8);
    io.set_watchdog(WatchdogSetting::from_ms(10.0).unwrap())
        .unwrap();
    // Power on; wait for the supplies (held off 40 ms after they are good).
    for b in io.boards_mut() {
        b.set_power(true);
    }
    io.cycle();
    io.port_mut().wait(Duration::from_millis(60));
    // QLA 1 of the DQLA (axes 1-4) on, QLA 2 (axes 5-8) off.
    for axis in 0..8 {
        io.board_mut(1)
            .unwrap()
            .set_amp_enable(axis, axis < 4)
            .unwrap();
    }
    for _ in 0..10 {
        io.cycle();
        io.port_mut().wait(Duration::from_millis(1));
    }
    let seen: Vec<bool> = (0..8)
        .map(|a| io.board(1).unwrap().amp_enabled(a))
        .collect();
    assert_eq!(seen, [true, true, true, true, false, false, false, false]);
    assert_eq!(
        dqla_amps(&mut io),
        [true, true, true, true, false, false, false, false]
    );
    assert!(io.board(1).unwrap().power_enabled());
    // Now QLA 2 on and QLA 1 off.
    for axis in 0..8 {
        io.board_mut(1)
            .unwrap()
            .set_amp_enable(axis, axis >= 4)
            .unwrap();
    }
    for _ in 0..10 {
        io.cycle();
        io.port_mut().wait(Duration::from_millis(1));
    }
    assert_eq!(io.board(1).unwrap().amp_mask(), 0xF0);
    assert_eq!(io.stats().total_errors(), 0);
    // The host goes quiet for 30 ms: the 10 ms watchdog turns every
    // amplifier off and says so.
    io.port_mut().wait(Duration::from_millis(30));
    assert_eq!(dqla_amps(&mut io), [false; 8]);
    io.read_all();
    let b = io.board(1).unwrap();
    assert!(b.watchdog_expired());
    assert_eq!(b.amp_mask(), 0);
}
