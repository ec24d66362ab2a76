//! The runner's test rig: a configuration's boards emulated on the
//! simulated bus (`firelink_testbed::rig`), in virtual time, with handles
//! to look at the boards and to break things.
#![allow(dead_code)]

use std::time::Duration;

use firelink_board::qla::Firmware;
use firelink_board::qla::config::Profile;
use firelink_board::qla::node::BoardNode;
use firelink_bus::NodeHandle;
use firelink_bus::fault::{FaultPlan, PacketFault, PacketMatch, TimedFault};
use firelink_control::config::IoConfig;
use firelink_host::sim::SimPort;
use firelink_testbed::rig;
use firelink_wire::packet::Tcode;
use firelink_wire::qla::realtime::FirmwareRev;

/// Emulated boards for every board `config` uses, joint `j` starting at
/// `start(j)`, on a simulated bus behind a [`SimPort`]. `seed_000`: the
/// boards run seed 000's own firmware (Rev 4: a corrupt query is answered
/// with sequence 0xFFFF); otherwise Rev 8.
pub fn port(config: &IoConfig, seed_000: bool, start: impl Fn(usize) -> f64) -> SimPort {
    let profile = if seed_000 {
        Profile::Seed
    } else {
        Profile::Rev8
    };
    let mut boards = rig::board_configs_starting_at(config, profile, config.board_slots(), start);
    if seed_000 {
        boards = boards
            .into_iter()
            .map(|b| b.with_firmware(FirmwareRev::Rev4))
            .collect();
    }
    rig::sim_port(boards, false).expect("boards").0
}

/// The node of board `id` (the PC was added first, then boards 0, 1, ...).
fn node(id: u8) -> NodeHandle {
    NodeHandle(usize::from(id) + 1)
}

/// Board `id`'s firmware.
pub fn board(port: &SimPort, id: u8) -> &Firmware {
    port.bus()
        .node::<BoardNode>(node(id))
        .expect("a board node")
        .firmware()
}

/// Whether board `id`'s watchdog has expired.
pub fn watchdog_expired(port: &SimPort, id: u8) -> bool {
    board(port, id).watchdog_timed_out()
}

/// Whether any amplifier of board `id` is on.
pub fn any_amp_on(port: &SimPort, id: u8) -> bool {
    let fw = board(port, id);
    (0..fw.config().hardware.axes()).any(|a| fw.amplifier_on(a))
}

/// The host stops for `d`: the bus and the boards go on without it.
pub fn stop_host(port: &mut SimPort, d: Duration) {
    use firelink_host::Port;
    port.wait(d);
}

/// The next broadcast query reaches every board with its header CRC broken.
pub fn corrupt_next_query(port: &mut SimPort) {
    let query = PacketMatch::any()
        .tcode(Tcode::WriteQuadletRequest)
        .offset(0x1800);
    port.bus_mut().set_fault_plan(FaultPlan::new().once(
        query,
        PacketFault::CorruptQuadlet {
            index: 3,
            xor: 0x0100_0000,
        },
    ));
}

/// Board `id` stops answering for good (its cable pulled).
pub fn lose_board(port: &mut SimPort, id: u8) {
    let now = port.bus().now();
    port.bus_mut().set_fault_plan(FaultPlan::new().at(
        now,
        TimedFault::StopAnswering {
            node: node(id),
            duration: None,
        },
    ));
}

/// The joint on `(board, axis)` runs into an obstacle: an opposing force as
/// large as its motor's peak torque (at the current limit) holds it
/// wherever the motor pushes, so a moving setpoint builds a following
/// error.
pub fn block_axis(port: &mut SimPort, board_id: u8, axis: usize) {
    let fw = port
        .bus_mut()
        .node_mut::<BoardNode>(node(board_id))
        .expect("a board node")
        .firmware_mut();
    if let Some(a) = fw.plant_mut().axis_mut(axis) {
        let p = a.params();
        let peak = p.motor.torque_constant * p.amplifier.current_limit * p.load.gear_ratio.abs();
        a.set_external_torque(-peak);
    }
}
