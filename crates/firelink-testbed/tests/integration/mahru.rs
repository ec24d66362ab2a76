//! Seed 002's MAHRU system on the simulated bus: the module protocol
//! (every command code, unknown ones ignored, QWRITE slicing), the
//! MotionController (ModID mapping across a renumbering bus reset, a
//! missed module stops the robot, a lost host is caught by the modules'
//! watchdogs), the force/torque bias, the demo, and the figures of Tables
//! I, III and IV within tolerance of the seed's.
//!
//! Everything runs in virtual time; counts are kept small enough for a
//! debug build (the full 1e6-read distribution is `firelink budget`).

use firelink_control::ServoPeriod;
use std::time::Duration;

use firelink_board::mahru::{
    BodyParams, DeviceConfig, FtLoad, FtParams, JointParams, ModuleConfig, ModuleNode,
    ResponderTiming,
};
use firelink_bus::{HostLink, NodeHandle, SimDuration, TimedFault};
use firelink_host::HostError;
use firelink_host::Port;
use firelink_host::mahru::rtos::Rtos;
use firelink_host::mahru::{ControllerState, MissReason, MotionController, MotionError, Setpoints};
use firelink_host::port::Dest;
use firelink_host::sim::SimPort;
use firelink_testbed::mahru::budget::{BudgetOptions, run_budget};
use firelink_testbed::mahru::can::{Table4Options, run_table4};
use firelink_testbed::mahru::main_loop::MainLoop;
use firelink_testbed::mahru::rig::{build_bus, sbc_port};
use firelink_testbed::mahru::table3::{Table3Options, run_table3};
use firelink_testbed::mahru::{MahruConfig, MahruDemoOptions, run_mahru_demo};
use firelink_wire::mahru::{
    Command, FtBlock, IdCheck, Identity, JointBlock, ModId, ModMask, ModuleKind, ModuleState,
    ParameterRecord, QWRITE_LEN, SetpointSlot,
};
use firelink_wire::packet::{AsyncHeader, NodeId, PacketRepr, Rcode, Speed};

fn motor(id: u8) -> ModuleConfig {
    ModuleConfig {
        mod_id: ModId(id),
        name: format!("motor{id}"),
        firmware: 2,
        timing: MahruConfig::seed002().responder_timing(),
        speed: Speed::S400,
        device: DeviceConfig::Motor(JointParams::default()),
    }
}

fn wrist(id: u8) -> ModuleConfig {
    ModuleConfig {
        mod_id: ModId(id),
        name: format!("ft{id}"),
        firmware: 2,
        timing: ResponderTiming::IMMEDIATE,
        speed: Speed::S400,
        device: DeviceConfig::ForceTorque(FtParams {
            load: FtLoad::Wrist {
                shoulder: ModId(0),
                elbow: ModId(1),
            },
            body: BodyParams::default(),
            offset: [2.0, -1.0, 3.0, 0.1, -0.1, 0.05],
            noise: [0.2, 0.01],
            seed: 5,
            initial_pose: [0.0; 10],
        }),
    }
}

fn record(id: u8) -> ParameterRecord {
    ParameterRecord {
        mod_id: ModId(id),
        gear_ratio: 100.0,
        kp: 300.0,
        ki: 100.0,
        kd: 10.0,
        position_min: -2.0,
        position_max: 2.0,
        torque_max: 60.0,
    }
}

/// A small bus with plain (overhead-free) ports: motors 0 and 1 and a
/// wrist sensor 12 on one chain.
fn small_bus() -> (SimPort, Vec<NodeHandle>) {
    let b = build_bus(&[vec![motor(0), motor(1), wrist(12)]], 3).unwrap();
    let handles = b.modules.iter().map(|m| m.handle).collect();
    (SimPort::new(b.bus, b.pc), handles)
}

fn node_of(port: &SimPort, h: NodeHandle) -> u8 {
    port.bus().phy_id(h).unwrap()
}

/// Let a module's DSP catch up with the present (its servo runs lazily,
/// on its next event).
fn advance(port: &mut SimPort, h: NodeHandle) {
    port.bus_mut()
        .with_node::<ModuleNode, _>(h, |n, ctx| n.advance(ctx.now()))
        .unwrap();
}

fn module(port: &SimPort, h: NodeHandle) -> &ModuleNode {
    port.bus().node::<ModuleNode>(h).unwrap()
}

#[test]
fn every_command_code_is_handled_and_unknown_ones_are_ignored() {
    let (mut port, h) = small_bus();
    let (m0, m1, ft) = (
        node_of(&port, h[0]),
        node_of(&port, h[1]),
        node_of(&port, h[2]),
    );
    // IDREQUEST (11) and IDCHECK (12).
    let id = Identity::from_quadlet(port.read_quadlet(Dest::node(m1), 11).unwrap()).unwrap();
    assert_eq!(
        (id.mod_id, id.kind),
        (ModId(1), ModuleKind::MotorController)
    );
    let id = Identity::from_quadlet(port.read_quadlet(Dest::node(ft), 11).unwrap()).unwrap();
    assert_eq!((id.mod_id, id.kind), (ModId(12), ModuleKind::ForceTorque));
    let check = IdCheck::from_quadlet(port.read_quadlet(Dest::node(m0), 12).unwrap()).unwrap();
    assert_eq!(check.mod_id, ModId(0));
    assert_eq!(check.phy_id, m0);
    assert_eq!(u32::from(check.generation), port.generation() & 0x3FF);
    assert_eq!(check.state, ModuleState::Idle);
    // PARAMETER (13): point to point to module 0, broadcast for module 1.
    let mut b = [0u8; 32];
    record(0).emit(&mut b).unwrap();
    port.write_block(Dest::node(m0), 13, &b).unwrap();
    record(1).emit(&mut b).unwrap();
    port.write_block(Dest::BROADCAST, 13, &b).unwrap();
    port.wait(Duration::from_micros(50));
    for &m in &h[..2] {
        assert_eq!(module(&port, m).state(), ModuleState::Parameterized);
    }
    assert_eq!(
        module(&port, h[1]).motor().unwrap().parameters_record(),
        Some(&record(1))
    );
    // SETBIAS (14) for the sensor only.
    port.write_quadlet(Dest::BROADCAST, 14, ModMask(0).with(ModId(12)).0)
        .unwrap();
    port.wait(Duration::from_micros(50));
    assert!(module(&port, h[2]).force_torque().unwrap().biased());
    // READY (15), sent as the seed's computer sends broadcasts: source ID
    // 0xFFFF (local bus, node 0x3F); START (16) from the port as usual.
    let ready = PacketRepr::WriteQuadletRequest {
        header: AsyncHeader::new(NodeId(0xFFFF), NodeId(0xFFFF), 0),
        offset: Command::Ready.offset(),
        data: ModMask::ALL.0,
    };
    let mut raw = vec![0u8; ready.buffer_len()];
    ready.emit(&mut raw).unwrap();
    let pc = port.host();
    HostLink::submit_on(port.bus_mut(), pc, &raw, Speed::S400).unwrap();
    port.wait(Duration::from_micros(20));
    assert_eq!(module(&port, h[0]).state(), ModuleState::Ready);
    port.write_quadlet(Dest::BROADCAST, 16, ModMask::ALL.0)
        .unwrap();
    port.wait(Duration::from_micros(50));
    assert_eq!(module(&port, h[0]).state(), ModuleState::Running);
    // QWRITE (18), QREAD (17), FTREAD (19).
    let mut sp = Setpoints::default();
    sp.set(ModId(0), 0.1, 0.0, 0.0, 0.0);
    sp.set(ModId(1), -0.1, 0.0, 0.0, 0.0);
    let mut q = [0u8; QWRITE_LEN];
    for i in 0..2u8 {
        let slot = SetpointSlot {
            sequence: 9,
            ..*sp.slot(ModId(i)).unwrap()
        };
        slot.emit(&mut q[usize::from(i) * 32..]).unwrap();
    }
    port.write_block(Dest::BROADCAST, 18, &q).unwrap();
    // A servo tick (200 us) takes the set-point.
    port.wait(Duration::from_micros(300));
    let mut block = [0u8; 32];
    port.read_block(Dest::node(m1), 17, &mut block).unwrap();
    let j = JointBlock::parse(&block).unwrap();
    assert_eq!(
        (j.mod_id, j.state, j.sequence),
        (ModId(1), ModuleState::Running, 9)
    );
    assert_eq!(j.target_urad, -100_000);
    let mut ftb = [0u8; 24];
    port.read_block(Dest::node(ft), 19, &mut ftb).unwrap();
    FtBlock::parse(&ftb).unwrap();
    // STOP (0): amplifiers off.
    port.write_quadlet(Dest::BROADCAST, 0, ModMask::ALL.0)
        .unwrap();
    port.wait(Duration::from_micros(50));
    for &m in &h {
        assert_eq!(module(&port, m).state(), ModuleState::Stopped);
    }
    assert!(!module(&port, h[0]).motor().unwrap().amplifier_on());
    // Every code of Table II was handled by some module.
    for code in [0, 11, 12, 13, 14, 15, 16, 17, 18, 19] {
        let n: u32 = h
            .iter()
            .map(|&m| module(&port, m).stats().commands[code])
            .sum();
        assert!(n > 0, "command {code} not counted");
    }
    // Unknown codes: a P2P read answers address error and changes
    // nothing; a broadcast is ignored.
    let before = module(&port, h[0]).stats().ignored;
    assert_eq!(
        port.read_quadlet(Dest::node(m0), 20),
        Err(HostError::Rcode {
            node: m0,
            rcode: Rcode::AddressError
        })
    );
    port.write_quadlet(Dest::BROADCAST, 21, ModMask::ALL.0)
        .unwrap();
    port.write_quadlet(Dest::BROADCAST, 17, ModMask::ALL.0)
        .unwrap();
    port.wait(Duration::from_micros(50));
    assert_eq!(module(&port, h[0]).stats().ignored, before + 3);
    assert_eq!(module(&port, h[0]).state(), ModuleState::Stopped);
    // Wrong kind: QREAD of a sensor, FTREAD of a motor, a short QREAD.
    assert!(port.read_block(Dest::node(ft), 17, &mut block).is_err());
    assert!(port.read_block(Dest::node(m0), 19, &mut ftb).is_err());
    assert!(
        port.read_block(Dest::node(m0), 17, &mut block[..28])
            .is_err()
    );
    // A PARAMETER block with a bad record is refused whole.
    let mut bad = [0u8; 64];
    record(0).emit(&mut bad).unwrap();
    record(1).emit(&mut bad[32..]).unwrap();
    bad[32 + 4..32 + 8].copy_from_slice(&0.0f32.to_bits().to_be_bytes());
    let refused = module(&port, h[0]).stats().refused;
    port.write_block(Dest::BROADCAST, 13, &bad).unwrap();
    port.wait(Duration::from_micros(50));
    assert_eq!(module(&port, h[0]).stats().refused, refused + 1);
}

#[test]
fn qwrite_is_sliced_by_mod_id() {
    let chain: Vec<ModuleConfig> = (0..10).map(motor).collect();
    let b = build_bus(&[chain], 1).unwrap();
    let handles: Vec<_> = b.modules.iter().map(|m| m.handle).collect();
    let mut port = SimPort::new(b.bus, b.pc);
    let mut block = vec![0u8; 32 * 10];
    for i in 0..10u8 {
        record(i).emit(&mut block[usize::from(i) * 32..]).unwrap();
    }
    port.write_block(Dest::BROADCAST, Command::Parameter.offset(), &block)
        .unwrap();
    port.write_quadlet(Dest::BROADCAST, 15, u32::MAX).unwrap();
    port.write_quadlet(Dest::BROADCAST, 16, u32::MAX).unwrap();
    let mut q = [0u8; QWRITE_LEN];
    for i in 0..10u8 {
        SetpointSlot {
            mod_id: i,
            valid: true,
            sequence: 100 + u16::from(i),
            position_urad: 10_000 * i32::from(i),
            ..SetpointSlot::default()
        }
        .emit(&mut q[usize::from(i) * 32..])
        .unwrap();
    }
    port.write_block(Dest::BROADCAST, 18, &q).unwrap();
    port.wait(Duration::from_micros(300));
    for (i, h) in handles.iter().enumerate() {
        advance(&mut port, *h);
        let m = port.bus().node::<ModuleNode>(*h).unwrap().motor().unwrap();
        assert_eq!(m.sequence(), Some(100 + i as u16));
        assert!(
            (m.target() - 0.01 * i as f64).abs() < 1e-9,
            "module {i}: {}",
            m.target()
        );
        assert_eq!(m.setpoints_taken(), 1);
    }
}

/// The seed's robot, brought up, with its modules' handles.
fn robot(
    rtos: Rtos,
) -> (
    MotionController<SimPort>,
    Vec<firelink_testbed::mahru::rig::PlacedModule>,
    MahruConfig,
) {
    let config = MahruConfig {
        rtos: rtos.name().into(),
        ..MahruConfig::seed002()
    };
    let b = build_bus(&config.module_configs(), 7).unwrap();
    let port = sbc_port(b.bus, b.pc, rtos, 7, Speed::S400);
    let mut c = MotionController::new(port, config.layout().unwrap()).unwrap();
    c.bring_up().unwrap();
    (c, b.modules, config)
}

#[test]
fn mod_id_mapping_survives_a_renumbering_bus_reset() {
    let (mut c, modules, config) = robot(Rtos::Xenomai);
    let mut main = MainLoop::new(&config, config.period());
    for _ in 0..20 {
        main.period_once(&mut c, |_| {}).unwrap();
    }
    let before: Vec<Option<u8>> = c.nodes().to_vec();
    // Move the sensor chain from the card to the end of the legs: every
    // node is numbered anew.
    let pc = c.port().host();
    let first_sensor = modules.iter().find(|m| m.chain == 2).unwrap().handle;
    let legs_end = modules.iter().rfind(|m| m.chain == 0).unwrap().handle;
    let bus = c.port_mut().bus_mut();
    bus.disconnect(pc, first_sensor).unwrap();
    bus.connect(legs_end, first_sensor).unwrap();
    for _ in 0..20 {
        main.period_once(&mut c, |fb| {
            // Every joint block comes from the module the layout expects.
            for (i, j) in fb.joints.iter().enumerate() {
                if let Some(j) = j {
                    assert_eq!(j.mod_id, c_layout_id(i));
                }
            }
        })
        .unwrap();
    }
    assert_eq!(c.stats().resets_recovered, 1);
    assert_eq!(c.state(), ControllerState::Running);
    assert_ne!(c.nodes(), &before[..], "the reset renumbered the nodes");
    for m in &modules {
        assert_eq!(
            c.node_of(m.mod_id),
            c.port().bus().phy_id(m.handle),
            "{}",
            m.name
        );
    }
    // Mapping and bringing 14 modules up again takes longer than a period:
    // the period of the reset overruns, the next ones do not.
    assert_eq!(main.overruns, 1);
}

/// The layout order of the seed's robot (chain by chain).
fn c_layout_id(i: usize) -> ModId {
    let ids = [0, 1, 2, 3, 4, 5, 8, 6, 7, 9, 10, 11, 12, 13];
    ModId(ids[i])
}

#[test]
fn a_missed_module_stops_the_robot() {
    let (mut c, modules, config) = robot(Rtos::RtLinux);
    let mut main = MainLoop::new(&config, config.period());
    for _ in 0..10 {
        main.period_once(&mut c, |_| {}).unwrap();
    }
    let knee = modules.iter().find(|m| m.name == "l_knee").unwrap().handle;
    let now = c.port().bus().now();
    c.port_mut().bus_mut().schedule_fault(
        now + SimDuration::from_micros(100),
        TimedFault::StopAnswering {
            node: knee,
            duration: None,
        },
    );
    let err = loop {
        if let Err(e) = main.period_once(&mut c, |_| {}) {
            break e;
        }
    };
    assert!(
        matches!(
            err,
            MotionError::Missed {
                mod_id: ModId(1),
                reason: MissReason::Transaction(HostError::Timeout { .. })
            }
        ),
        "{err}"
    );
    assert_eq!(c.state(), ControllerState::Stopped);
    assert_eq!(c.fault(), Some(err));
    // Motion is refused until the robot is brought up again.
    assert!(matches!(c.read_all(), Err(MotionError::NotRunning(_))));
    // STOP reached every module that hears. The dead one hears nothing
    // (the bus does not even run its timers), but its DSP's watchdog has
    // stopped its joint: every amplifier is off.
    c.port_mut().wait(Duration::from_millis(20));
    advance(c.port_mut(), knee);
    let bus = c.port().bus();
    for m in &modules {
        let node = bus.node::<ModuleNode>(m.handle).unwrap();
        assert_eq!(node.state(), ModuleState::Stopped, "{}", m.name);
        assert!(node.motor().is_none_or(|j| !j.amplifier_on()), "{}", m.name);
    }
    let dead = bus.node::<ModuleNode>(knee).unwrap().motor().unwrap();
    assert_ne!(dead.flags() & JointBlock::WATCHDOG, 0);
    // The others were stopped by STOP, within the 1 ms time-out, before
    // their own watchdogs would have done it.
    for m in modules.iter().filter(|m| m.handle != knee) {
        let flags = bus
            .node::<ModuleNode>(m.handle)
            .unwrap()
            .motor()
            .map_or(0, |j| j.flags());
        assert_eq!(flags & JointBlock::WATCHDOG, 0, "{}", m.name);
    }
}

#[test]
fn a_lost_host_is_caught_by_the_watchdogs_and_exit_stops_the_robot() {
    let (mut c, modules, config) = robot(Rtos::Xenomai);
    let mut main = MainLoop::new(&config, config.period());
    for _ in 0..10 {
        main.period_once(&mut c, |_| {}).unwrap();
    }
    // The host stops sending: within the 10 ms watchdog (plus a servo
    // tick) every joint has stopped itself.
    let quiet = c.port().bus().now();
    c.port_mut().wait(Duration::from_millis(11));
    for m in modules.iter().filter(|m| m.chain != 2) {
        let node = c.port().bus().node::<ModuleNode>(m.handle).unwrap();
        let j = node.motor().unwrap();
        assert!(!j.amplifier_on(), "{}", m.name);
        assert_ne!(j.flags() & JointBlock::WATCHDOG, 0);
    }
    assert!(c.port().bus().now() <= quiet + SimDuration::from_millis(12));
    // The next read sees the fault and stops the robot.
    assert!(matches!(c.read_all(), Err(MotionError::ModuleFault { .. })));
    // Bring up again and walk: running.
    c.bring_up().unwrap();
    let mut main = MainLoop::new(&config, config.period());
    for _ in 0..5 {
        main.period_once(&mut c, |_| {}).unwrap();
    }
    assert_eq!(c.state(), ControllerState::Running);
}

/// A port shared with the test, so that the bus can be seen after the
/// controller that owned the port is gone.
struct Shared(std::rc::Rc<std::cell::RefCell<SimPort>>);

impl Port for Shared {
    fn name(&self) -> &str {
        "shared"
    }
    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> firelink_host::Result<u32> {
        self.0.borrow_mut().read_quadlet(dest, offset)
    }
    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> firelink_host::Result<()> {
        self.0.borrow_mut().write_quadlet(dest, offset, value)
    }
    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> firelink_host::Result<()> {
        self.0.borrow_mut().read_block(dest, offset, out)
    }
    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> firelink_host::Result<()> {
        self.0.borrow_mut().write_block(dest, offset, data)
    }
    fn wait(&mut self, d: Duration) {
        self.0.borrow_mut().wait(d)
    }
    fn now(&self) -> Duration {
        self.0.borrow().now()
    }
    fn generation(&self) -> u32 {
        self.0.borrow().generation()
    }
    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        self.0.borrow().candidate_nodes()
    }
}

#[test]
fn dropping_a_running_controller_stops_the_robot() {
    let config = MahruConfig::seed002();
    let b = build_bus(&config.module_configs(), 7).unwrap();
    let handles: Vec<_> = b.modules.iter().map(|m| m.handle).collect();
    let port = std::rc::Rc::new(std::cell::RefCell::new(sbc_port(
        b.bus,
        b.pc,
        Rtos::Xenomai,
        7,
        Speed::S400,
    )));
    {
        let mut c = MotionController::new(Shared(port.clone()), config.layout().unwrap()).unwrap();
        c.bring_up().unwrap();
        let mut main = MainLoop::new(&config, config.period());
        for _ in 0..5 {
            main.period_once(&mut c, |_| {}).unwrap();
        }
    }
    let mut port = port.borrow_mut();
    port.wait(Duration::from_micros(100));
    for h in handles {
        let m = port.bus().node::<ModuleNode>(h).unwrap();
        assert_eq!(m.state(), ModuleState::Stopped);
        assert!(m.motor().is_none_or(|j| !j.amplifier_on()));
        assert_eq!(
            m.motor().map_or(0, |j| j.flags() & JointBlock::WATCHDOG),
            0,
            "STOP, not the watchdog"
        );
    }
}

#[test]
fn force_torque_bias_is_taken_while_hanging() {
    let (c, modules, config) = robot(Rtos::Xenomai);
    let bus = c.port().bus();
    for m in modules.iter().filter(|m| m.chain == 2) {
        let ft = bus
            .node::<ModuleNode>(m.handle)
            .unwrap()
            .force_torque()
            .unwrap();
        assert!(ft.biased());
        assert!(ft.standing(), "START lowered the robot");
        // The bias is the offset (and the hand's weight at the wrists).
        let offset = match &config.module_configs()[2]
            .iter()
            .find(|x| x.mod_id == m.mod_id)
            .unwrap()
            .device
        {
            DeviceConfig::ForceTorque(p) => p.offset,
            DeviceConfig::Motor(_) => unreachable!(),
        };
        let bias = ft.bias();
        let hanging = if m.name.contains("wrist") {
            // Forearm at the elbow's 0.4 rad: the hand's weight along -z and x.
            let w = config.body.hand_mass_kg * 9.81;
            [w * 0.4f64.sin(), 0.0, -w * 0.4f64.cos()]
        } else {
            [0.0; 3]
        };
        for a in 0..3 {
            assert!(
                (bias[a] - offset[a] - hanging[a]).abs() < 0.5,
                "{} axis {a}: {}",
                m.name,
                bias[a]
            );
        }
    }
}

#[test]
fn the_demo_walks_at_2_ms_without_an_error_and_is_deterministic() {
    let options = MahruDemoOptions {
        config: MahruConfig::seed002(),
        duration_s: 1.5,
        period: Some(ServoPeriod::from_duration(Duration::from_millis(2)).unwrap()),
        find_fastest: true,
        detail: firelink_bus::Detail::Fast,
    };
    let report = run_mahru_demo(&options, |_| {}).unwrap();
    report.verdict().unwrap();
    assert_eq!(report.periods, 750);
    assert_eq!(report.modules.len(), 14);
    // The feet carry the robot's weight; each wrist sees its hand.
    assert!((report.weight_on_feet_n - report.body_weight_n).abs() < 0.02 * report.body_weight_n);
    assert_eq!(report.force_torque.len(), 4);
    for ft in &report.force_torque {
        assert!(ft.max[2] > ft.min[2], "{} reads a moving load", ft.name);
    }
    // The joints track within a few milliradians.
    for m in report.modules.iter().filter(|m| m.kind == "motor") {
        assert!(m.tracking_max_mrad.unwrap() < 10.0, "{}", m.name);
    }
    let fastest = report.fastest.unwrap();
    assert!(fastest.period_us < 2000.0 && fastest.period_us >= report.timing.busy.max);
    assert_eq!(fastest.overruns, 0);
    let again = run_mahru_demo(&options, |_| {}).unwrap();
    assert_eq!(
        serde_json::to_string(&report).unwrap(),
        serde_json::to_string(&again).unwrap()
    );
    // A period too short for the work overruns: errors, verdict fails.
    let short = run_mahru_demo(
        &MahruDemoOptions {
            period: Some(ServoPeriod::from_duration(Duration::from_micros(1000)).unwrap()),
            duration_s: 0.1,
            find_fastest: false,
            ..options
        },
        |_| {},
    )
    .unwrap();
    assert!(short.errors.overruns > 0);
    assert!(short.verdict().is_err());
}

#[test]
fn table_i_from_the_simulation_reproduces_the_seeds_example() {
    let report = run_budget(
        &BudgetOptions {
            samples: 40,
            periods: 300,
            ..BudgetOptions::default()
        },
        |_| {},
    )
    .unwrap();
    assert_eq!((report.nm, report.ns), (10, 4));
    for r in &report.per_rtos {
        // 1.64 ms (Xenomai) and 1.56 ms (RTLinux), within 10 %.
        assert!(
            r.example.diff_pct.abs() < 10.0,
            "{}: {:?}",
            r.rtos,
            r.example
        );
        assert!(r.seed_arithmetic.fits && r.literal.fits);
        assert!(r.literal.total_us > r.seed_arithmetic.total_us);
        assert_eq!(r.table.len(), 8);
        // The end-to-end worst period stays within the budget's bound.
        assert!(r.end_to_end.within_bound, "{}", r.rtos);
        assert_eq!(r.end_to_end.overruns, 0);
        // A broadcast has no ack: cheaper than a read.
        assert!(r.transactions.bwb.max < r.transactions.prb.max);
    }
    // A period the budget does not fit in is said so.
    let tight = run_budget(
        &BudgetOptions {
            period: Some(ServoPeriod::from_duration(Duration::from_micros(1200)).unwrap()),
            samples: 5,
            periods: 10,
            rtos: vec![Rtos::Xenomai],
            ..BudgetOptions::default()
        },
        |_| {},
    )
    .unwrap();
    assert!(!tight.per_rtos[0].seed_arithmetic.fits);
    assert!(tight.per_rtos[0].seed_arithmetic.slack_us < 0.0);
}

#[test]
fn table_iii_read_times_by_payload_within_15_percent() {
    let report = run_table3(
        &Table3Options {
            reads: 20_000,
            ..Table3Options::default()
        },
        |_| {},
    )
    .unwrap();
    assert_eq!(report.points.len(), 12);
    assert!(report.worst_diff_pct() < 15.0, "{report}");
    for p in &report.points {
        assert!(p.total.p50 < p.total.p99 && p.total.p99 <= p.total.max);
    }
    // Time grows with the payload, and Xenomai is the slower system.
    let x = |n| report.point(Rtos::Xenomai, n).unwrap().total.max;
    let r = |n| report.point(Rtos::RtLinux, n).unwrap().total.max;
    assert!(x(496) > x(256) && x(256) > x(4));
    assert!(x(4) > r(4));
    // Table IV's split of the 4-byte read: request 29 / 27, response 32 / 31.
    let four = report.point(Rtos::Xenomai, 4).unwrap();
    assert!((four.request.max - 29.0).abs() < 0.15 * 29.0);
    assert!((four.response.max - 32.0).abs() < 0.15 * 32.0);
    // A slow responder dominates: an FPGA answering by itself reads 496
    // bytes in a fraction of the DSP module's time.
    let fpga = run_table3(
        &Table3Options {
            reads: 2_000,
            payloads: vec![496],
            responder: ResponderTiming::IMMEDIATE,
            ..Table3Options::default()
        },
        |_| {},
    )
    .unwrap();
    for rtos in Rtos::ALL {
        let fast = fpga.point(rtos, 496).unwrap().total.max;
        let slow = report.point(rtos, 496).unwrap().total.max;
        assert!(fast < 0.3 * slow, "{rtos}: {fast} vs {slow}");
    }
    // Seeded: the same run twice gives the same figures.
    let small = Table3Options {
        reads: 500,
        payloads: vec![64],
        ..Table3Options::default()
    };
    assert_eq!(
        run_table3(&small, |_| {}).unwrap(),
        run_table3(&small, |_| {}).unwrap()
    );
}

#[test]
fn table_iv_can_against_1394() {
    let report = run_table4(
        &Table4Options {
            cycles: 40,
            reads: 5_000,
            periods: 100,
            ..Table4Options::default()
        },
        |_| {},
    )
    .unwrap();
    let c = &report.can;
    assert_eq!((c.frames_sent, c.frames_received), (41, 52));
    // The model's cycle is within 15 % of the seed's CAN total.
    assert!(
        (c.total.p50 - 10_500.0).abs() < 0.15 * 10_500.0,
        "{}",
        c.total.p50
    );
    assert!(c.total.max <= c.worst_case_us);
    // The seed's ratio (181x, 172x) from the models, within 25 %.
    for r in &report.ratios {
        assert!(
            (r.model_as_the_seed - r.paper).abs() < 0.25 * r.paper,
            "{r:?}"
        );
        // Like for like, 1394's cycle is an order of magnitude faster.
        assert!(r.cycle_to_cycle > 5.0 && r.cycle_to_cycle < 30.0, "{r:?}");
    }
    // Error frames cost time and are counted.
    let noisy = run_table4(
        &Table4Options {
            cycles: 40,
            reads: 100,
            periods: 5,
            error_probability: 0.02,
            ..Table4Options::default()
        },
        |_| {},
    )
    .unwrap();
    assert!(noisy.can.error_frames > 0);
    assert!(noisy.can.total.max > c.total.max);
}
