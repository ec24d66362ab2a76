//! The dVRK demo (seed 000's 28 axes on 8 QLA boards, or any QLA/DQLA
//! configuration): its options, how it opens each kind of port and runs
//! the shared demo program ([`run_program`]) on a QLA [`IoSystem`].
//! What every robot's demo shares (the program, the report, the faults,
//! the motions) is [`crate::demo`].

use std::time::Instant;

use firelink_board::qla::config::Profile;
use firelink_bus::{Detail, DetailReport};
use firelink_control::ServoPeriod;
use firelink_control::config::{IoConfig, presets};
use firelink_control::runner::{Pacing, Robot};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::{Protocol, ScanReport};
use firelink_host::sim::SimPort;
use firelink_host::stop::StopRequest;
use firelink_host::udp::WaitMode;
use firelink_host::{Port, WatchdogSetting};

use crate::TestbedError;
use crate::demo::{
    DemoFault, DemoIo, DemoPlan, DemoProgress, DemoReport, PortSpec, RealtimeStatus, check_run,
    realtime_status, run_program,
};
use crate::fault_script::{FaultScript, FaultTarget};
use crate::ports::{self, PortOptions};
use crate::rig;

/// Options of a demo run.
#[derive(Debug, Clone)]
pub struct DemoOptions {
    /// The robot (default: seed 000's dVRK, 28 axes on 8 QLA1 boards).
    pub config: IoConfig,
    /// The servo period (default 6 kHz).
    pub period: ServoPeriod,
    /// I/O protocol.
    pub protocol: Protocol,
    /// Seconds of motion after homing.
    pub duration_s: f64,
    /// Where the boards are (`sim:N[:FW]`: boards 0..N of the robot, at FW).
    pub port: PortSpec,
    /// Firmware of the emulated boards (sim, emulate; `sim:N:FW` names its
    /// own).
    pub firmware: Profile,
    /// The fault to inject half way (a named preset).
    pub fault: DemoFault,
    /// A fault script instead of the preset (`--faults`; `fault` must then
    /// be [`DemoFault::None`]).
    pub faults: Option<FaultScript>,
    /// Pacing; `None`: the port's default.
    pub pacing: Option<Pacing>,
    /// Board watchdog.
    pub watchdog: WatchdogSetting,
    /// How the UDP port's reads wait for their answer (emulate, udp).
    pub udp_wait: WaitMode,
    /// The read time-out of a UDP or FireWire port (emulate, udp, fw): a
    /// servo cycle whose answer takes longer counts the board as missed (a
    /// fault); the scan waits that long for each absent node.
    pub timeout: std::time::Duration,
    /// The simulated bus's level of detail (sim; the same answer either
    /// way).
    pub detail: Detail,
}

impl Default for DemoOptions {
    fn default() -> Self {
        DemoOptions {
            config: presets::dvrk_seed000(),
            period: ServoPeriod::from_rate_hz(6000.0).expect("6 kHz is a servo period"),
            protocol: Protocol::Broadcast,
            duration_s: 3.0,
            port: PortSpec::SIM,
            firmware: Profile::Rev8,
            fault: DemoFault::None,
            faults: None,
            pacing: None,
            watchdog: WatchdogSetting::default(),
            udp_wait: WaitMode::Blocking,
            timeout: rig::UDP_TIMEOUT,
            detail: Detail::Fast,
        }
    }
}

/// Run the demo. `realtime` is called once the port is open, on the
/// calling thread, when the pacing is wall-clock (the CLI passes its
/// SCHED_FIFO/mlockall setup; `None`: no real-time settings). The robot
/// obeys the process's stop request ([`StopRequest::process`]).
pub fn run_demo(
    options: &DemoOptions,
    realtime: Option<&dyn Fn() -> RealtimeStatus>,
    progress: impl FnMut(DemoProgress),
) -> Result<DemoReport, TestbedError> {
    run_demo_until(options, &StopRequest::process(), realtime, progress)
}

/// [`run_demo`], the robot obeying `stop` (e.g. Python's Ctrl-C): once it
/// is set, the loop returns [`RunnerError::Stopped`](firelink_control::runner::RunnerError::Stopped) at its next cycle and
/// the boards the run energised are powered down as the robot is dropped.
///
/// # Errors
/// As [`run_demo`]; [`RunnerError::Stopped`](firelink_control::runner::RunnerError::Stopped) once `stop` is set.
pub fn run_demo_until(
    options: &DemoOptions,
    stop: &StopRequest,
    realtime: Option<&dyn Fn() -> RealtimeStatus>,
    mut progress: impl FnMut(DemoProgress),
) -> Result<DemoReport, TestbedError> {
    check_run(options.duration_s)?;
    let config = &options.config;
    // Boards 0..=the highest board ID the configuration uses.
    let boards = config.board_slots();
    if options.fault != DemoFault::None && options.faults.is_some() {
        return Err(TestbedError::Config(format!(
            "fault {} and a fault script: give one of the two",
            options.fault
        )));
    }
    // Any other link: only what the host's side can do.
    let link = FaultTarget::link();
    match &options.port {
        PortSpec::Sim(_) => {
            let boards = ports::sim_boards(&options.port, config, options.firmware);
            let rig = rig::RigBuilder::qla(boards).build()?;
            let target = rig.fault_target();
            let mut port = rig.sim_port();
            port.bus_mut().set_detail(options.detail);
            run_robot(
                port,
                &target,
                options,
                "sim".into(),
                stop,
                realtime,
                &mut progress,
            )
        }
        PortSpec::Emulate => {
            let emu = rig::Emulator::start(rig::board_configs(config, options.firmware, boards))?;
            let name = format!("udp:{} (in-process firelink emulate)", emu.addr);
            let mut port = emu.port_with(options.udp_wait)?;
            port.set_timeout(options.timeout);
            let report = run_robot(
                port,
                &emu.fault_target(),
                options,
                name,
                stop,
                realtime,
                &mut progress,
            );
            emu.stop()?;
            report
        }
        PortSpec::Udp(addr) | PortSpec::UdpFw(addr) => {
            let force_bridge = matches!(options.port, PortSpec::UdpFw(_));
            let port = firelink_host::eth::UdpNetPort::open(
                *addr,
                force_bridge,
                options.timeout,
                options.udp_wait,
            )?;
            let name = port.name().to_string();
            run_robot(port, &link, options, name, stop, realtime, &mut progress)
        }
        PortSpec::Fw(card) => {
            let port = ports::fw_port(
                *card,
                &PortOptions {
                    timeout: options.timeout,
                    ..PortOptions::default()
                },
            )?;
            let name = options.port.to_string();
            run_robot(port, &link, options, name, stop, realtime, &mut progress)
        }
    }
}

impl<P: Port + 'static> DemoIo for IoSystem<P> {
    type Port = P;
    fn port_mut(&mut self) -> &mut P {
        IoSystem::port_mut(self)
    }
    fn board_nodes(&self) -> Vec<(u8, u8)> {
        IoSystem::boards(self)
            .iter()
            .map(|b| (b.info().board_id, b.info().node))
            .collect()
    }
    fn firmware(&self) -> Option<u32> {
        IoSystem::boards(self).first().map(|b| b.info().firmware)
    }
    fn protocol(&self) -> String {
        IoSystem::protocol(self).name().to_string()
    }
    fn detail_report(&self) -> Option<DetailReport> {
        sim_detail_report(IoSystem::port(self))
    }
}

/// What ran at which level of detail, when `port` is the simulated bus
/// itself (`None` for any other port, a wrapper around a simulated port
/// included: the demo's simulated port is never wrapped).
pub(crate) fn sim_detail_report<P: Port + 'static>(port: &P) -> Option<DetailReport> {
    (port as &dyn std::any::Any)
        .downcast_ref::<SimPort>()
        .map(|p| p.bus().detail_report())
}

/// Run the demo on any port (paced as `options` say, else as the port's
/// default), its faults applied by `target`.
fn run_robot<P: Port + 'static>(
    port: P,
    target: &FaultTarget,
    options: &DemoOptions,
    port_name: String,
    stop: &StopRequest,
    realtime: Option<&dyn Fn() -> RealtimeStatus>,
    progress: &mut dyn FnMut(DemoProgress),
) -> Result<DemoReport, TestbedError> {
    let pacing = options
        .pacing
        .unwrap_or_else(|| options.port.default_pacing());
    let rt = realtime_status(pacing, realtime);
    let wall = Instant::now();
    // The faults are checked before the boards are touched (and again
    // with the boards the scan found).
    demo_plan(options, pacing).check_faults(target, &port, None)?;
    let (mut robot, plan) = open_robot(port, options, pacing, |io, scan| {
        progress(DemoProgress::Found {
            boards: scan.boards.len(),
            port: port_name.clone(),
            reason: scan.protocol_reason.to_string(),
            protocol: io.protocol().name(),
        });
    })?;
    robot.set_stop_request(stop.clone());
    let done = run_program(robot, &plan, target, port_name, rt, wall, progress)?;
    Ok(done.report)
}

/// The demo plan of `options` with `pacing`.
fn demo_plan(options: &DemoOptions, pacing: Pacing) -> DemoPlan<'_> {
    DemoPlan {
        config: &options.config,
        period: options.period,
        duration_s: options.duration_s,
        fault: options.fault,
        script: options.faults.as_ref(),
        watchdog: options.watchdog,
        pacing,
    }
}

/// Scan `port`, set up its boards for `options`' protocol (`found` is
/// told what the scan found) and make the robot of `options`' plan with
/// `pacing`.
pub(crate) fn open_robot<'a, P: Port>(
    port: P,
    options: &'a DemoOptions,
    pacing: Pacing,
    found: impl FnOnce(&IoSystem<P>, &ScanReport),
) -> Result<(Robot<IoSystem<P>>, DemoPlan<'a>), TestbedError> {
    let (io, scan) = IoSystem::open(
        port,
        IoOptions {
            protocol: Some(options.protocol),
            ..IoOptions::default()
        },
    )?;
    found(&io, &scan);
    let plan = demo_plan(options, pacing);
    let robot = Robot::new(io, &options.config, plan.settings())?;
    Ok((robot, plan))
}
