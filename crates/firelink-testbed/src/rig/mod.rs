//! Rigs: a robot configuration's boards, each actuator driving the plant its
//! configuration names (`simulation.plant`), on a simulated bus with the
//! PC's link ([`SimPort`]), or behind an in-process `firelink emulate`
//! bridge on loopback UDP ([`Emulator`]). Every bus of boards is built by
//! the one [`RigBuilder`] ([`builder`]): boards by ID, seed, faults by
//! board ID, the bridge board. What `firelink emulate` serves is
//! assembled from typed options in [`served`].

pub mod builder;
pub mod host_clock;
pub mod served;

pub use builder::{Rig, RigBuilder, RobotKind};
pub use host_clock::{HostClock, HostClockedPort};

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, mpsc};
use std::thread::JoinHandle;

use firelink_board::plant::AxisParams;
use firelink_board::plant::presets;
use firelink_board::qla::config::{BoardConfig, BrakeWire, FpgaVersion, Hardware, Profile};
use firelink_board::qla::node::BoardNode;
use firelink_bus::{Bus, HostModel, Node, NodeHandle, SimDuration};
use firelink_control::config::{FpgaGeneration, HardwareVersion, IoConfig};
use firelink_emulate::{BridgeStats, ServeConfig};
use firelink_host::sim::SimPort;
use firelink_host::udp::{UdpPort, WaitMode};

use crate::TestbedError;
use crate::cpu::ThreadCpuClock;
use crate::fault_script::{BoardFault, BoardFaultChannel};
use crate::plant_map;

/// Board configurations for every board `config` uses, plus generic
/// boards after them up to `boards` (at most 16; for the bench beyond 8
/// boards).
///
/// Each board is the companion board its robot names (`QLA1` or `DQLA`;
/// a `dRA1` is emulated as a QLA1) and carries its plants (an MTM's
/// gripper on the axis after its last actuator) and what is plugged into
/// it (a PSM's sterile adapter and instrument).
///
/// **Serial numbers**, one rule for every board of every file: a board's
/// PROMs hold that *board's* own serial numbers, as a real FPGA board's
/// and QLA's do (printed on their labels, `3791-14`), never the arm's
/// `serial_number` (which names the arm, not its controller boards). They
/// are what a robot's `simulation.boards` gives the board; a board it does
/// not name (every board of a dVRK file without Firelink's sections, or a
/// brake board) keeps the emulator's default, unique per board ID
/// ([`default_fpga_serial`](firelink_board::qla::config::default_fpga_serial),
/// [`default_qla_serial`](firelink_board::qla::config::default_qla_serial)). A
/// serial the PROM cannot hold (more than 8 characters) stays in the
/// configuration and is reported by [`BoardConfig::check`]; its PROM is
/// left erased.
pub fn board_configs(config: &IoConfig, profile: Profile, boards: usize) -> Vec<BoardConfig> {
    board_configs_starting_at(config, profile, boards, |j| {
        plant_map::start_position(config, j)
    })
}

/// [`board_configs`], joint `j` starting at `start(j)`.
pub fn board_configs_starting_at(
    config: &IoConfig,
    profile: Profile,
    boards: usize,
    start: impl Fn(usize) -> f64,
) -> Vec<BoardConfig> {
    let uses = config.boards();
    let mut out: Vec<BoardConfig> = Vec::new();
    let lines = plant_map::input_lines(config);
    let brakes = plant_map::brake_wires(config);
    let instruments = plant_map::instruments(config);
    let grippers: Vec<(u8, u8)> = config
        .robots
        .iter()
        .filter_map(plant_map::gripper_slot)
        .collect();
    // A set of DQLA arms (today's controllers) has exactly the boards its
    // arms name: the dVRK gives a DQLA arm the first ID of the QLA pair it
    // replaces, and the IDs between are no board at all.
    let dqla_set = !uses.is_empty() && uses.iter().all(|u| u.hardware == HardwareVersion::Dqla);
    let named = config.board_slots();
    for id in 0..boards.min(16) as u8 {
        let board_use = uses.iter().find(|u| u.board_id == id);
        if dqla_set && board_use.is_none() && usize::from(id) < named {
            continue;
        }
        let hardware = match board_use.map(|u| u.hardware) {
            Some(HardwareVersion::Dqla) => Hardware::Dqla,
            _ => Hardware::Qla1,
        };
        let mut b = BoardConfig::new(id, hardware, profile).with_seed(u64::from(id) + 1);
        let mut axes: Vec<AxisParams> = vec![presets::unused_channel(); hardware.axes()];
        let mut any = false;
        for (i, j) in config.joints().enumerate() {
            if j.actuator.board_id == id {
                if let (Some(slot), Some(p)) = (
                    axes.get_mut(usize::from(j.actuator.axis_id)),
                    plant_map::plant_starting_at(config, i, start(i)),
                ) {
                    *slot = p;
                    any = true;
                }
            }
        }
        for &(_, axis) in grippers.iter().filter(|(board, _)| *board == id) {
            let used = config
                .joints()
                .any(|j| j.actuator.board_id == id && j.actuator.axis_id == axis);
            if let (false, Some(slot)) = (used, axes.get_mut(usize::from(axis))) {
                *slot = plant_map::gripper_params();
            }
        }
        if any {
            b = b.with_axes(axes);
        }
        let held = lines.get(usize::from(id)).copied().unwrap_or(0);
        b = b.with_input_lines(held);
        if let Some((_, instrument)) = instruments.iter().find(|(board, _)| *board == id) {
            b = b.with_instrument(instrument.clone());
        }
        for wire in brakes.iter().filter(|(board, _)| *board == id) {
            if let BrakeWire::Drives { axis, .. } = &wire.1 {
                if let Some(slot) = b.axes.get_mut(*axis) {
                    *slot = presets::brake_coil();
                }
            }
            b = b.with_brake(wire.1.clone());
        }
        let board_serial = config.board_serial(id);
        let qla_serial = board_serial
            .and_then(|s| s.qla.as_deref())
            .filter(|s| !s.is_empty());
        if let Some(serial) = qla_serial {
            for q in 0..b.qla_count() {
                b = b.with_qla_serial(q, serial);
            }
        }
        if let Some(fpga) = board_serial.and_then(|s| s.fpga.as_deref()) {
            b.fpga_serial = fpga.to_string();
        }
        // The board's own FPGA and firmware, where its robot names them.
        if let Some(sim) = config.board_simulation(id) {
            if let Some(g) = sim.fpga_version {
                b.fpga = match g {
                    FpgaGeneration::V2 => FpgaVersion::V2,
                    FpgaGeneration::V3 => FpgaVersion::V3,
                };
            }
            if let Some(p) = sim.firmware.and_then(Profile::from_number) {
                b = b.with_profile(p);
            }
        }
        out.push(b);
    }
    out
}

/// A bus: the PC's (or the bridge's) link at the root, then the boards
/// daisy-chained, reset, with the gap count Linux would set for its hops
/// ([`RigBuilder::qla`] with no faults).
///
/// # Errors
/// [`TestbedError::NoBoards`].
pub fn build_bus(
    boards: Vec<BoardConfig>,
) -> Result<(Bus, NodeHandle, Vec<NodeHandle>), TestbedError> {
    let rig = RigBuilder::qla(boards).build()?;
    Ok((
        rig.bus,
        rig.host,
        rig.boards.into_iter().map(|(_, h)| h).collect(),
    ))
}

/// An emulated QLA-family board as a bus node, named `board<ID>`.
pub fn qla_node(cfg: BoardConfig) -> Box<dyn Node> {
    let name = format!("board{}", cfg.board_id);
    Box::new(BoardNode::new(cfg).with_name(name))
}

/// `n` boards with generic motors, IDs 0..n.
pub fn generic_boards(n: u8, hardware: Hardware, profile: Profile, seed: u64) -> Vec<BoardConfig> {
    (0..n)
        .map(|id| {
            BoardConfig::new(id, hardware, profile).with_seed(seed.wrapping_add(u64::from(id)))
        })
        .collect()
}

/// The simulated port: the PC's link with the seed-000 PC model (optional)
/// and the boards.
pub fn sim_port(
    boards: Vec<BoardConfig>,
    pc_model: bool,
) -> Result<(SimPort, Vec<NodeHandle>), TestbedError> {
    let (bus, pc, handles) = build_bus(boards)?;
    let model = HostModel::seed000(bus.timing());
    let mut port = SimPort::new(bus, pc);
    if pc_model {
        port = port.with_host_model(model);
    }
    Ok((port, handles))
}

/// Only the boards `config`'s robots use (a dVRK bus with just these
/// arms' controllers), in board-ID order, on the simulated bus with the PC
/// at the root: the port and each board's (ID, node).
///
/// # Errors
/// As [`sim_port`].
pub fn sim_port_of_used(
    config: &IoConfig,
    profile: Profile,
) -> Result<(SimPort, Vec<(u8, NodeHandle)>), TestbedError> {
    let used = config.board_set();
    let boards: Vec<_> = board_configs(config, profile, config.board_slots())
        .into_iter()
        .filter(|b| used.contains(b.board_id))
        .collect();
    let ids: Vec<u8> = boards.iter().map(|b| b.board_id).collect();
    let (port, handles) = sim_port(boards, false)?;
    Ok((port, ids.into_iter().zip(handles).collect()))
}

/// A board fault for the emulator's server thread, and where to say it
/// was applied.
struct FaultRequest {
    fault: BoardFault,
    after: SimDuration,
    done: mpsc::Sender<Result<(), TestbedError>>,
}

/// The fault channel of an in-process [`Emulator`]: a board fault sent
/// here is on the emulator's bus (its board found by ID, as the rig built
/// it) when [`board_fault`](Self::board_fault) returns.
#[derive(Clone)]
pub struct EmulatorFaults {
    /// The board IDs on its bus.
    boards: Vec<u8>,
    to_server: mpsc::Sender<FaultRequest>,
    interrupt: Arc<AtomicBool>,
}

impl BoardFaultChannel for EmulatorFaults {
    /// The board IDs on the emulator's bus, in chain order.
    fn boards(&self) -> &[u8] {
        &self.boards
    }

    /// `fault` on the emulator's bus, `after` from its present time.
    ///
    /// # Errors
    /// [`TestbedError::NoSuchBoard`]; the server has stopped.
    fn board_fault(&self, fault: BoardFault, after: SimDuration) -> Result<(), TestbedError> {
        let gone = || TestbedError::Emulator("the server has stopped: no fault applied".into());
        let (done, applied) = mpsc::channel();
        self.to_server
            .send(FaultRequest { fault, after, done })
            .map_err(|_| gone())?;
        // Sent before the server is woken: it finds the request when it
        // looks.
        self.interrupt.store(true, Ordering::SeqCst);
        applied.recv().map_err(|_| gone())?
    }
}

/// An in-process `firelink emulate`: the boards behind the UDP bridge on
/// 127.0.0.1 (an ephemeral port), served by a thread until stopped or
/// dropped.
pub struct Emulator {
    /// Where it listens.
    pub addr: SocketAddr,
    stop: Arc<AtomicBool>,
    faults: EmulatorFaults,
    thread: Option<JoinHandle<std::io::Result<BridgeStats>>>,
    cpu: Option<ThreadCpuClock>,
}

impl Emulator {
    /// Start serving `boards`.
    ///
    /// # Errors
    /// [`TestbedError::NoBoards`]; socket errors binding loopback.
    pub fn start(boards: Vec<BoardConfig>) -> Result<Emulator, TestbedError> {
        Emulator::start_rig(RigBuilder::qla(boards))
    }

    /// Start serving the rig `rig` builds (QLA boards or Snake nodes); the
    /// first board is the Ethernet-connected one.
    ///
    /// # Errors
    /// As [`start`](Self::start); what [`RigBuilder::build`] refuses.
    pub fn start_rig(rig: RigBuilder) -> Result<Emulator, TestbedError> {
        Emulator::start_with(rig, None)
    }

    /// Start serving `boards` in the time of the host that waits on
    /// `clock` (its port: a [`HostClockedPort`] over [`port`](Self::port)):
    /// each datagram is handled at the host's time when it arrived, never
    /// at the wall clock's, so neither thread's scheduling changes what the
    /// boards see. Host time 0 is the boards' time when serving starts.
    ///
    /// # Errors
    /// As [`start`](Self::start).
    pub fn start_following(
        boards: Vec<BoardConfig>,
        clock: HostClock,
    ) -> Result<Emulator, TestbedError> {
        Emulator::start_with(RigBuilder::qla(boards), Some(clock))
    }

    fn start_with(rig: RigBuilder, following: Option<HostClock>) -> Result<Emulator, TestbedError> {
        let (unicast, _) = firelink_emulate::bind(&ServeConfig {
            listen: SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 0),
            loopback_broadcast: false,
        })?;
        let addr = unicast.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let interrupt = Arc::new(AtomicBool::new(false));
        let (flag, wake) = (stop.clone(), interrupt.clone());
        let (to_server, requests) = mpsc::channel::<FaultRequest>();
        let (ready, started) = mpsc::channel();
        // The bus is built on the server thread.
        let thread = std::thread::spawn(move || {
            let built = rig.build().and_then(|r| {
                let boards = r.boards.clone();
                r.bridge(None).map(|b| (b, boards))
            });
            let (mut bridge, boards) = match built {
                Ok(b) => b,
                Err(e) => {
                    let _ = ready.send(Err(e));
                    return Ok(BridgeStats::default());
                }
            };
            let _ = ready.send(Ok(boards.iter().map(|(id, _)| *id).collect()));
            let origin = bridge.bus().now();
            let host_time = following.map(|clock| {
                move |at: std::time::Instant| {
                    let d = clock.at(at);
                    origin
                        + SimDuration::from_nanos(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
                }
            });
            // Serve until stopped; a fault request interrupts the serving,
            // is applied to the bus between two datagrams, and serving
            // goes on (datagrams wait in the socket meanwhile).
            loop {
                match &host_time {
                    Some(at) => {
                        firelink_emulate::serve_following(
                            &mut bridge,
                            &unicast,
                            &wake,
                            at,
                            |_| {},
                        )?;
                    }
                    None => firelink_emulate::serve(&mut bridge, &unicast, None, &wake, |_| {})?,
                }
                // Cleared before the stop flag is read: a stop that comes
                // after this sets `wake` again, so the next `serve`
                // returns at once and the flag is seen (cleared after the
                // read, that stop's wake-up would be lost and `join` hang).
                wake.store(false, Ordering::SeqCst);
                if flag.load(Ordering::SeqCst) {
                    break;
                }
                while let Ok(r) = requests.try_recv() {
                    let applied = crate::fault_script::apply_on_bus(
                        bridge.bus_mut(),
                        &boards,
                        crate::fault_script::ScriptedFault::Board(r.fault),
                        r.after,
                    );
                    let _ = r.done.send(applied);
                }
            }
            Ok(bridge.stats())
        });
        let boards = match started.recv() {
            Ok(Ok(ids)) => ids,
            Ok(Err(e)) => return Err(e),
            Err(_) => return Err(TestbedError::Emulator("the server thread failed".into())),
        };
        let cpu = ThreadCpuClock::of(&thread);
        Ok(Emulator {
            addr,
            stop,
            faults: EmulatorFaults {
                boards,
                to_server,
                interrupt,
            },
            thread: Some(thread),
            cpu,
        })
    }

    /// Its fault channel: board faults applied on its bus by the server
    /// thread (a [`FaultTarget`](crate::fault_script::FaultTarget) for the
    /// host's port to it: [`fault_target`](Self::fault_target)).
    pub fn faults(&self) -> EmulatorFaults {
        self.faults.clone()
    }

    /// The fault target of a port to it.
    pub fn fault_target(&self) -> crate::fault_script::FaultTarget {
        crate::fault_script::FaultTarget::emulator(self.faults())
    }

    /// CPU time the server thread has used so far (user and system), while
    /// it runs; `None` once it has stopped or where thread clocks cannot
    /// be read.
    pub fn server_cpu_time(&self) -> Option<std::time::Duration> {
        self.cpu
            .and_then(|c| c.now_while_running(self.thread.as_ref()))
    }

    /// Stop the server and return its counters.
    ///
    /// # Errors
    /// The server's socket error, or a panic of its thread.
    pub fn stop(mut self) -> Result<BridgeStats, TestbedError> {
        self.stop.store(true, Ordering::SeqCst);
        self.faults.interrupt.store(true, Ordering::SeqCst);
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(r)) => Ok(r?),
            Some(Err(_)) => Err(TestbedError::Emulator("the server thread panicked".into())),
            None => Ok(BridgeStats::default()),
        }
    }

    /// A UDP port to it.
    pub fn port(&self) -> Result<UdpPort, TestbedError> {
        udp_port(self.addr)
    }

    /// A UDP port to it whose reads wait as `wait` says.
    pub fn port_with(&self, wait: WaitMode) -> Result<UdpPort, TestbedError> {
        udp_port_with(self.addr, wait)
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        self.faults.interrupt.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The time-out the testbed's programs give a UDP port: a servo cycle that
/// waits longer has failed anyway.
pub const UDP_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(20);

/// A UDP port to the bridge at `addr` with [`UDP_TIMEOUT`].
///
/// # Errors
/// The socket could not be opened.
pub fn udp_port(addr: std::net::SocketAddr) -> Result<UdpPort, TestbedError> {
    udp_port_with(addr, WaitMode::default())
}

/// [`udp_port`] whose reads wait as `wait` says.
///
/// # Errors
/// The socket could not be opened.
pub fn udp_port_with(addr: std::net::SocketAddr, wait: WaitMode) -> Result<UdpPort, TestbedError> {
    let mut p = UdpPort::open(addr)?;
    p.set_timeout(UDP_TIMEOUT);
    p.set_wait_mode(wait);
    Ok(p)
}

/// The port a `udp:` (`force_bridge` false: the Ethernet-only network
/// when the board answering is an FPGA V3 at Rev 9 or later, else the
/// bridge) or `udpfw:` (the bridge) string opens, with the rig's time-out
/// and the bridge's reads waiting as `wait` says.
///
/// # Errors
/// The sockets could not be opened; the Ethernet-only network's IP write.
pub fn net_port_with(
    addr: std::net::SocketAddr,
    force_bridge: bool,
    wait: WaitMode,
) -> Result<firelink_host::eth::UdpNetPort, TestbedError> {
    Ok(firelink_host::eth::UdpNetPort::open(
        addr,
        force_bridge,
        UDP_TIMEOUT,
        wait,
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_control::config::presets;

    /// Every board's PROMs hold the board's own serial numbers (the
    /// configuration's `simulation.boards`, else the unique default),
    /// never its arm's; each board is the companion board its
    /// configuration names.
    #[test]
    fn boards_carry_their_own_serials_and_hardware() {
        use firelink_board::qla::config::{default_fpga_serial, default_qla_serial};
        let dvrk = presets::dvrk_seed000();
        let boards = board_configs(&dvrk, Profile::Rev8, 9);
        for b in &boards {
            assert_eq!(b.qla_serials(), [default_qla_serial(b.board_id, 0)]);
            assert_eq!(b.fpga_serial, default_fpga_serial(b.board_id));
            assert_eq!(b.check(), Ok(()));
        }
        // The stock files name every board of their arm, the ECM's brake
        // board too.
        for (config, ids) in [
            (presets::stock_ecm(), [4u8, 5]),
            (presets::stock_psm1(), [6, 7]),
            (presets::stock_mtmr(), [2, 3]),
        ] {
            let boards = board_configs(&config, Profile::Rev8, config.board_slots());
            for id in ids {
                let given = config.board_serial(id).unwrap();
                let b = &boards[usize::from(id)];
                assert_eq!(Some(&b.qla_serials()[0]), given.qla.as_ref());
                assert_eq!(Some(&b.fpga_serial), given.fpga.as_ref());
                assert_ne!(b.qla_serials()[0], config.robots[0].serial_number);
            }
        }
        // Without Firelink's sections (a dVRK file as generated): every
        // board its own default, all different.
        let mut plain = presets::stock_ecm();
        plain.robots[0].simulation = None;
        let boards = board_configs(&plain, Profile::Rev8, plain.board_slots());
        assert_eq!(boards[4].qla_serials(), [default_qla_serial(4, 0)]);
        assert_eq!(boards[5].qla_serials(), [default_qla_serial(5, 0)]);
        let snake = presets::snake_36axes();
        let boards = board_configs(&snake, Profile::Rev8, 8);
        assert_eq!(boards[0].hardware, Hardware::Dqla);
        assert_eq!(boards[0].qla_serials().len(), 2);
        assert_eq!(boards[7].hardware, Hardware::Qla1);
        // A DQLA goes on its FPGA V3; a QLA1 on a V2 unless its robot's
        // simulation names the FPGA and firmware.
        assert_eq!(boards[0].fpga, FpgaVersion::V3);
        assert_eq!(boards[7].fpga, FpgaVersion::V2);
        let mut named = presets::snake_36axes();
        named.robots[3].simulation = Some(firelink_control::config::RobotSimulation {
            boards: vec![firelink_control::config::BoardSimulation {
                board_id: 7,
                serial: firelink_control::config::BoardSerial {
                    fpga: None,
                    qla: None,
                },
                fpga_version: Some(FpgaGeneration::V3),
                firmware: Some(9),
            }],
            ..Default::default()
        });
        let boards = board_configs(&named, Profile::Rev8, 8);
        assert_eq!(
            (boards[7].fpga, boards[7].profile),
            (FpgaVersion::V3, Profile::Rev9)
        );
        assert_eq!(boards[7].firmware.number(), 9);
        assert_eq!(
            (boards[6].fpga, boards[6].profile),
            (FpgaVersion::V2, Profile::Rev8)
        );
    }
}
