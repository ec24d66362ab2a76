//! Issue 31 (boards and firmware) behind the bridge: Rev 9 FPGA V2 boards
//! keep the UDP bridge (the host library's scan and broadcast cycle over
//! loopback), and the FPGA V3 / DQLA registers answer the reference host's
//! sequences (fpgatest's `DQLA_IOExp_Check`, `ReadRTL8211F_Register`,
//! `WriteEthernetPhyReset`, MotorVoltage's `MeasureMotorSupplyVoltage` for
//! a DQLA), replayed as raw datagrams in virtual time.

use crate::common;

use std::time::Duration;

use common::{RefHost, Server, bridge, qla1s};
use firelink_board::qla::config::{BoardConfig, FpgaVersion, Hardware, Profile};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::{Protocol, scan};
use firelink_wire::qla::dqla::MAX7301_CONFIG;

/// Generous: test builds are unoptimised and share two cores.
const TIMEOUT: Duration = Duration::from_millis(100);

/// Rev 9 on FPGA V2 keeps the FireWire bridge: the host library scans four
/// such boards behind one Ethernet board, runs the broadcast cycle with
/// no error, and its commands reach the boards.
#[test]
fn rev9_v2_boards_keep_the_bridge() {
    let server = Server::start(qla1s(4, Profile::Rev9));
    let mut p = server.port(TIMEOUT);
    let report = scan(&mut p).unwrap();
    assert_eq!(report.boards.len(), 4);
    assert_eq!(report.bridge_board, Some(0));
    assert_eq!(report.protocol, Protocol::Broadcast);
    for b in &report.boards {
        assert_eq!((b.firmware, b.fpga), (9, FpgaVersion::V2));
        assert_ne!(b.git.raw(), 0, "GIT_DESC reads at Rev 9");
    }
    let (mut io, _) = IoSystem::open(server.port(TIMEOUT), IoOptions::default()).unwrap();
    assert_eq!(io.protocol(), Protocol::Broadcast);
    for _ in 0..50 {
        io.cycle();
    }
    for b in io.boards_mut() {
        b.set_power(true);
    }
    for _ in 0..5 {
        io.cycle();
    }
    let stats = *io.stats();
    assert_eq!(stats.total_errors(), 0, "{stats:?}");
    assert!(io.boards().iter().all(|b| b.power_enabled()));
}

/// A Rev 9 V2 bridge board's ETH_STATUS: bit 31 (V2), ACCESS_ERR (bit 24)
/// 0 as from Rev 9 on; the real-time hub blocks are Rev 8's (33 quadlets
/// per QLA1 with its header).
#[test]
fn rev9_v2_registers_and_hub() {
    let mut host = RefHost::new(bridge(qla1s(2, Profile::Rev9)));
    assert_eq!(host.qread(0, 7), 9);
    let eth = host.qread(0, 12);
    assert_eq!(eth >> 31, 1, "{eth:#x}");
    assert_eq!(eth & 0x0100_0000, 0, "ACCESS_ERR reads 0 from Rev 9");
    host.qwrite(63, 0x1800, 1 << 16 | 0b11);
    let hub = host.bread(0, 0x1000, 67 * 4);
    assert_eq!(hub[0] >> 24, 33);
    assert_eq!(hub[33] >> 24, 33);
}

/// Board 0: a QLA1 on an FPGA V3 (the Ethernet-connected one, Eth1 up);
/// board 1: a DQLA (V3 by default); both Rev 9.
fn v3_host() -> RefHost {
    RefHost::new(bridge(vec![
        BoardConfig::new(0, Hardware::Qla1, Profile::Rev9).with_fpga(FpgaVersion::V3),
        BoardConfig::new(1, Hardware::Dqla, Profile::Rev9),
    ]))
}

/// ETH_STATUS of a V3 at Rev 9 (FpgaIO.h bits; FPGA1394V3.v's word): 01
/// in bits 31:30, clocks OK, UDP, PSETH_EN (bit 16), ACCESS_ERR 0; port
/// bytes {init OK, IRQ, link, speed 1000, 001}: Eth1 linked on the
/// Ethernet-connected board only. A PHY reset (`WriteEthernetPhyReset(1)`
/// = `0x04000080`) takes Eth1 down for 170 ms; the PS Ethernet enable is
/// written with its mask (bit 25).
#[test]
fn v3_ethernet_status_and_control() {
    let mut host = v3_host();
    assert_eq!(host.qread(0, 12), 0x40B1_D1F1, "Eth1 up, Eth2 no link");
    assert_eq!(host.qread(1, 12), 0x40B1_D1D1, "not Ethernet-connected");
    host.qwrite(0, 12, 0x0400_0080);
    assert_eq!(host.qread(0, 12) & 0xFFFF, 0xD151, "Eth1 in reset");
    host.sleep_us(171_000);
    assert_eq!(host.qread(0, 12) & 0xFFFF, 0xD1F1, "Eth1 back");
    host.qwrite(1, 12, 0x0200_0000);
    assert_eq!(host.qread(1, 12) & 0x0001_0000, 0, "PS Ethernet disabled");
    // WriteEthernetClearErrors at Rev 9 on a V3: 0x60000000, nothing set.
    host.qwrite(1, 12, 0x6000_0000);
    assert_eq!(host.qread(1, 12), 0x40B0_D1D1);
}

/// `ReadRTL8211F_Register(chan, 1, reg)`: a write of `0x60000000 | 1<<23 |
/// reg<<18` to `0x4nA0`, then reads of `0x4nA0` until bits 26:24 are 0 and
/// 20:16 name the register: the PHY IDs `0x001C` and `0xC916` the
/// firmware checks, on both ports of both boards.
#[test]
fn rtl8211f_ids_through_mdio() {
    let mut host = v3_host();
    for node in [0u8, 1] {
        for window in [0x41A0u64, 0x42A0] {
            for (reg, id) in [(2u32, 0x001Cu32), (3, 0xC916)] {
                host.qwrite(node, window, 0x6000_0000 | 1 << 23 | reg << 18);
                let r = host.qread(node, window);
                assert_eq!(r & 0x0700_0000, 0, "idle");
                assert_eq!((r >> 16) & 0x1F, reg);
                assert_eq!(r & 0xFFFF, id, "board {node} {window:#x}");
            }
        }
    }
    // A V2 has no MDIO window there: its window reads its debug data.
    let mut v2 = RefHost::new(bridge(qla1s(1, Profile::Rev9)));
    v2.qwrite(0, 0x41A0, 0x6088_0000);
    assert_ne!(v2.qread(0, 0x41A0) & 0xFFFF, 0x001C);
}

/// fpgatest's `DQLA_IOExp_Check(board, 3)` and `(board, 4)`: the NOP
/// `chan<<16 | 0x08000000` selects the chip, bits 23/22 clear (found,
/// configured); each configuration command's read (`0x80 | register`)
/// answers at the first attempt with the command echoed in 15:8 and its
/// data in 7:0 (it read 0 before: "command mismatch, received: 0"); the
/// debug register counts no output error. The QLAs' MAX7317s answer to
/// IDs 1 and 2.
#[test]
fn dqla_expanders_pass_fpgatest_checks() {
    let mut host = v3_host();
    assert_eq!(host.qread(1, 14), 0, "no expander named yet");
    for chan in [3u32, 4] {
        let chan = chan << 16;
        host.qwrite(1, 14, chan | 0x0800_0000);
        let r = host.qread(1, 14);
        assert_eq!(r & 0x00C0_0000, 0, "found and configured: {r:#x}");
        assert_eq!(r & 0x0200_0000, 0, "no read error");
        for command in MAX7301_CONFIG {
            let read = u32::from(command & 0xFF00) | 0x8000;
            host.qwrite(1, 14, chan | read);
            let r = host.qread(1, 14);
            assert_eq!(r & 0x0C00_0000, 0, "no I/O in process");
            assert_eq!(r & 0xFF00, read & 0xFF00, "command echo");
            assert_eq!(r & 0x1000_0000, 0);
            assert_eq!(
                r & 0xFF,
                u32::from(command & 0xFF),
                "configuration {command:#x}"
            );
        }
        host.qwrite(1, 14, chan | 0x4000_0000);
        assert_eq!((host.qread(1, 14) >> 16) & 0xFF, 0, "output errors");
    }
    for id in [1u32, 2] {
        host.qwrite(1, 14, id << 16 | 0x8E00);
        assert_eq!(host.qread(1, 14) >> 29, 0b010);
        assert_eq!(host.qread(1, 14) & 0xFF00, 0x8E00);
    }
    // STATUS bits 13:12 (DQLA expanders found), 1:0 (QLA expanders).
    let status = host.qread(1, 0);
    assert_eq!((status >> 12) & 0b11, 0b11, "{status:#x}");
    assert_eq!(status & 0b11, 0b11);
}

/// MotorVoltage.cpp's `MeasureMotorSupplyVoltage(port, board, index)` on a
/// DQLA: power on, then DAC 4 (`0x41`, index 1) or DAC 8 (`0x81`, index
/// 2) stepped with the valid bit, 1 ms apart, the comparator read from
/// STATUS bit `index << 4`; steps back and halves at each crossing. The
/// DQLA at board 1 stands for boards 1 and 2: 12 V and 24 V.
#[test]
fn dqla_motor_supplies_measured_per_qla() {
    let mut host = v3_host();
    let bits_to_volts = 2.5 / 65535.0 * 21.0;
    host.qwrite(1, 0, 0x000C_0000);
    host.sleep_us(60_000);
    for (index, dac, nominal) in [(1u32, 0x41u64, 12.0), (2, 0x81, 24.0)] {
        assert_ne!(host.qread(1, 0) & (1 << (index - 1)), 0, "IsQLAExpanded");
        let mut volts: u32 = 0;
        let mut step: u32 = 0x1000;
        while volts <= 0xFFFF {
            host.qwrite(1, dac, volts | 0x8000_0000);
            host.sleep_us(1000);
            let below = host.qread(1, 0) & (index << 4) != 0;
            if !below {
                if step == 1 {
                    break;
                }
                volts -= step;
                step >>= 1;
            }
            volts += step;
        }
        let measured = f64::from(volts) * bits_to_volts;
        assert!(
            (measured - nominal).abs() < 0.01 * nominal,
            "QLA {index}: {measured} V, expected {nominal}"
        );
    }
}
