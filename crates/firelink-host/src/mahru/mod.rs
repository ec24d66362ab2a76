//! The MAHRU humanoid's MotionController (seed 002): its module protocol
//! over any [`Port`], and seed 002's computer as an overhead model.
//!
//! Seed 002 splits the robot program in two: the *MainController* decides
//! what the robot does (the control algorithm); the *MotionController*
//! talks to the 14 modules on the 1394 bus. [`MotionController`] is the
//! latter, port-independent:
//!
//! - **bring-up** ([`MotionController::bring_up`]), after power-up and
//!   after every bus reset: IDREQUEST to every node maps module IDs to the
//!   node IDs of this bus generation, IDCHECK confirms each mapping
//!   (checkControllers, Table I's `T_a`), PARAMETER gives each motor
//!   controller its gear ratio, gains and limits (`T_b`), SETBIAS zeroes
//!   the force/torque sensors (first bring-up only: the robot hangs in its
//!   frame), READY (`T_c`), START (`T_d`);
//! - **each period**: [`read_all`](MotionController::read_all) reads every
//!   module (QREAD or FTREAD, `T_e`), the caller computes, and
//!   [`write_setpoints`](MotionController::write_setpoints) broadcasts one
//!   QWRITE with every controller's set-point (`T_g`);
//! - **stop** ([`stop`](MotionController::stop), `T_h`): on exit (also when
//!   the controller is dropped while running), and at once when any
//!   module misses a cycle or reports a fault: one STOP broadcast, every
//!   amplifier off, and the controller refuses motion until brought up
//!   again.
//!
//! A bus reset during a cycle is not a missed module: node IDs moved, so
//! the controller maps the modules again, brings them back to running
//! and reads the cycle again. If a module is then missing, the robot stops.
//!
//! The cycle allocates nothing: blocks are read into and written from
//! buffers made at construction.
//!
//! `rtos::RtosModel` (cargo feature `sim`) is the seed's computer (Xenomai
//! or RTLinux) as an overhead model for the simulated port.

mod error;
#[cfg(feature = "sim")]
pub mod rtos;

use std::time::Duration;

use firelink_wire::mahru::{
    Command, FtBlock, IdCheck, Identity, JointBlock, ModId, ModMask, ModuleKind, ModuleState,
    ParameterRecord, QWRITE_LEN, QWRITE_SLOTS, SetpointSlot,
};

use crate::error::HostError;
use crate::port::{Dest, Port};

pub use error::{MissReason, MotionError};

/// One module the robot has.
#[derive(Debug, Clone, PartialEq)]
pub struct ModuleSpec {
    /// Its module ID.
    pub mod_id: ModId,
    /// What it is.
    pub kind: ModuleKind,
    /// A name for reports.
    pub name: String,
    /// Motor controllers: the parameters PARAMETER sends.
    pub parameters: Option<ParameterRecord>,
}

/// Every module the robot has. Motor controllers need a module ID below
/// [`QWRITE_SLOTS`] (their slot) and parameters naming them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RobotLayout {
    /// The modules, in the order they are read each cycle.
    pub modules: Vec<ModuleSpec>,
}

impl RobotLayout {
    /// Check the layout.
    ///
    /// # Errors
    /// [`MotionError::Layout`] naming the first problem.
    pub fn validate(&self) -> Result<(), MotionError> {
        let mut seen = ModMask(0);
        for m in &self.modules {
            let bad = |what| {
                Err(MotionError::Layout {
                    what,
                    mod_id: m.mod_id,
                })
            };
            if m.mod_id.check().is_err() {
                return bad("module ID past 31");
            }
            if seen.contains(m.mod_id) {
                return bad("module ID used twice");
            }
            seen = seen.with(m.mod_id);
            match m.kind {
                ModuleKind::MotorController => {
                    if usize::from(m.mod_id.0) >= QWRITE_SLOTS {
                        return bad("a motor controller needs a QWRITE slot (module ID 0..9)");
                    }
                    match m.parameters {
                        Some(p) if p.mod_id == m.mod_id && p.validate().is_ok() => {}
                        _ => return bad("motor controller without valid parameters for it"),
                    }
                }
                ModuleKind::ForceTorque => {}
                ModuleKind::Unknown(_) => return bad("unknown module kind"),
            }
        }
        if self.modules.is_empty() {
            return Err(MotionError::Layout {
                what: "no modules",
                mod_id: ModId(0),
            });
        }
        Ok(())
    }

    /// The mask of every module of `kind`.
    pub fn mask(&self, kind: ModuleKind) -> ModMask {
        self.modules
            .iter()
            .filter(|m| m.kind == kind)
            .fold(ModMask(0), |mask, m| mask.with(m.mod_id))
    }
}

/// The controller's lifecycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ControllerState {
    /// Not brought up (or a bring-up failed).
    Unmapped,
    /// Running: every module follows the set-points.
    Running,
    /// STOP sent (on request or after a fault); bring up again to move.
    Stopped,
}

/// What one cycle read: one entry per module, in layout order.
#[derive(Debug, Clone, PartialEq)]
pub struct Feedback {
    /// Joint blocks of the motor controllers (`None` for sensors).
    pub joints: Vec<Option<JointBlock>>,
    /// Force/torque blocks of the sensors (`None` for motors).
    pub wrenches: Vec<Option<FtBlock>>,
    /// How long each module's read took (port time, call to return).
    pub read_times: Vec<Duration>,
}

/// The set-points of one QWRITE: a slot per motor controller, indexed by
/// module ID.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Setpoints {
    slots: [SetpointSlot; QWRITE_SLOTS],
}

fn fixed(x: f64, scale: f64) -> i32 {
    (x * scale)
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

impl Setpoints {
    /// Set module `id`'s set-point: position (rad), velocity (rad/s),
    /// acceleration (rad/s^2), torque feed-forward (Nm). IDs without a slot
    /// are ignored (and reported by `false`).
    pub fn set(
        &mut self,
        id: ModId,
        position: f64,
        velocity: f64,
        acceleration: f64,
        torque: f64,
    ) -> bool {
        let Some(slot) = self.slots.get_mut(usize::from(id.0)) else {
            return false;
        };
        *slot = SetpointSlot {
            mod_id: id.0,
            valid: true,
            sequence: 0,
            position_urad: fixed(position, 1e6),
            velocity_urad_s: fixed(velocity, 1e6),
            acceleration_mrad_s2: fixed(acceleration, 1e3),
            torque_mnm: fixed(torque, 1e3),
        };
        true
    }

    /// Module `id`'s slot.
    pub fn slot(&self, id: ModId) -> Option<&SetpointSlot> {
        self.slots.get(usize::from(id.0))
    }
}

/// What the controller counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MotionStats {
    /// Cycles read completely.
    pub cycles: u64,
    /// QWRITE broadcasts sent.
    pub setpoint_writes: u64,
    /// Bring-ups done (the first and one after each bus reset).
    pub bring_ups: u64,
    /// Bus resets met during a cycle and recovered from.
    pub resets_recovered: u64,
    /// STOP broadcasts sent.
    pub stops: u64,
    /// Cycles in which a module was missed (each stopped the robot).
    pub missed: u64,
}

/// The MotionController. See the module docs.
pub struct MotionController<P: Port> {
    port: P,
    layout: RobotLayout,
    nodes: Vec<Option<u8>>,
    generation: Option<u32>,
    state: ControllerState,
    biased: bool,
    feedback: Feedback,
    qwrite: [u8; QWRITE_LEN],
    sequence: u16,
    stats: MotionStats,
    fault: Option<MotionError>,
}

impl<P: Port> MotionController<P> {
    /// A controller for `layout` on `port`; nothing is sent yet.
    ///
    /// # Errors
    /// [`MotionError::Layout`].
    pub fn new(port: P, layout: RobotLayout) -> Result<MotionController<P>, MotionError> {
        layout.validate()?;
        let n = layout.modules.len();
        Ok(MotionController {
            port,
            nodes: vec![None; n],
            generation: None,
            state: ControllerState::Unmapped,
            biased: false,
            feedback: Feedback {
                joints: vec![None; n],
                wrenches: vec![None; n],
                read_times: vec![Duration::ZERO; n],
            },
            qwrite: [0; QWRITE_LEN],
            sequence: 0,
            stats: MotionStats::default(),
            fault: None,
            layout,
        })
    }

    /// The port.
    pub fn port(&self) -> &P {
        &self.port
    }

    /// The port, mutably (waiting, faults on a simulated bus).
    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// The layout.
    pub fn layout(&self) -> &RobotLayout {
        &self.layout
    }

    /// The lifecycle state.
    pub fn state(&self) -> ControllerState {
        self.state
    }

    /// What stopped the robot, if a fault did.
    pub fn fault(&self) -> Option<MotionError> {
        self.fault
    }

    /// What it counted.
    pub fn stats(&self) -> MotionStats {
        self.stats
    }

    /// The last cycle's data.
    pub fn feedback(&self) -> &Feedback {
        &self.feedback
    }

    /// The node each module (layout order) is at in this bus generation.
    pub fn nodes(&self) -> &[Option<u8>] {
        &self.nodes
    }

    /// The node module `id` is at, if mapped.
    pub fn node_of(&self, id: ModId) -> Option<u8> {
        let i = self.layout.modules.iter().position(|m| m.mod_id == id)?;
        self.nodes.get(i).copied().flatten()
    }

    /// IDREQUEST to every candidate node: which module is where. Nodes that
    /// do not answer, or answer something else, are not modules.
    ///
    /// # Errors
    /// [`MotionError::MissingModule`], [`MotionError::DuplicateModule`],
    /// [`MotionError::WrongKind`].
    pub fn map_modules(&mut self) -> Result<(), MotionError> {
        self.nodes.fill(None);
        self.generation = Some(self.port.generation());
        for node in self.port.candidate_nodes() {
            let dest = Dest::node(node);
            let answer = match self.port.read_quadlet(dest, Command::IdRequest.offset()) {
                Ok(q) => q,
                Err(HostError::BusReset { .. }) => return self.map_modules_again(),
                Err(_) => continue,
            };
            let Ok(identity) = Identity::from_quadlet(answer) else {
                continue;
            };
            let Some(i) = self
                .layout
                .modules
                .iter()
                .position(|m| m.mod_id == identity.mod_id)
            else {
                continue;
            };
            let spec = &self.layout.modules[i];
            if spec.kind != identity.kind {
                return Err(MotionError::WrongKind {
                    mod_id: spec.mod_id,
                    expected: spec.kind,
                    found: identity.kind,
                });
            }
            if let Some(first) = self.nodes[i] {
                return Err(MotionError::DuplicateModule {
                    mod_id: spec.mod_id,
                    first,
                    second: node,
                });
            }
            self.nodes[i] = Some(node);
        }
        match self.nodes.iter().position(Option::is_none) {
            Some(i) => Err(MotionError::MissingModule {
                mod_id: self.layout.modules[i].mod_id,
            }),
            None => Ok(()),
        }
    }

    /// A reset came while mapping: start over once in the new generation.
    fn map_modules_again(&mut self) -> Result<(), MotionError> {
        if self.generation == Some(self.port.generation()) {
            return Err(MotionError::Host(HostError::BusReset {
                old: self.port.generation(),
                new: self.port.generation(),
            }));
        }
        self.map_modules()
    }

    /// IDCHECK every mapped module (Table I's checkControllers): the right
    /// module answers at its node, and knows this bus generation.
    ///
    /// # Errors
    /// [`MotionError::IdCheck`], [`MotionError::MissingModule`] for an
    /// unmapped module, port errors.
    pub fn check_modules(&mut self) -> Result<(), MotionError> {
        for (i, spec) in self.layout.modules.iter().enumerate() {
            let node = self.nodes[i].ok_or(MotionError::MissingModule {
                mod_id: spec.mod_id,
            })?;
            let q = self
                .port
                .read_quadlet(Dest::node(node), Command::IdCheck.offset())?;
            let fail = |what| MotionError::IdCheck {
                mod_id: spec.mod_id,
                node,
                what,
            };
            let check = IdCheck::from_quadlet(q).map_err(|_| fail("malformed answer"))?;
            if check.mod_id != spec.mod_id {
                return Err(fail("another module answered"));
            }
            if check.phy_id != node {
                return Err(fail("the module has another node ID"));
            }
            let generation = (self.port.generation() & IdCheck::GENERATION_MASK) as u16;
            if check.generation != generation {
                return Err(fail("the module did not see this bus reset"));
            }
        }
        Ok(())
    }

    /// PARAMETER to every motor controller, point to point (Table I's
    /// `N_m x t(PWB)`): each module acks its own record.
    ///
    /// # Errors
    /// Port errors.
    pub fn send_parameters(&mut self) -> Result<(), MotionError> {
        let mut block = [0u8; ParameterRecord::LEN];
        for (i, spec) in self.layout.modules.iter().enumerate() {
            let Some(record) = spec.parameters else {
                continue;
            };
            let node = self.nodes[i].ok_or(MotionError::MissingModule {
                mod_id: spec.mod_id,
            })?;
            record.emit(&mut block).map_err(HostError::Wire)?;
            self.port
                .write_block(Dest::node(node), Command::Parameter.offset(), &block)?;
        }
        Ok(())
    }

    /// Broadcast a quadlet command to the modules in `mask`.
    ///
    /// # Errors
    /// Port errors.
    pub fn broadcast(&mut self, command: Command, mask: ModMask) -> Result<(), MotionError> {
        self.port
            .write_quadlet(Dest::BROADCAST, command.offset(), mask.0)?;
        Ok(())
    }

    /// Bring the robot up: map, check, parameters, SETBIAS (the first time
    /// only), READY, START. Called after power-up and after a bus reset.
    ///
    /// # Errors
    /// What the steps find; the controller is then `Unmapped`.
    pub fn bring_up(&mut self) -> Result<(), MotionError> {
        self.state = ControllerState::Unmapped;
        self.fault = None;
        self.map_modules()?;
        self.check_modules()?;
        self.send_parameters()?;
        if !self.biased {
            let sensors = self.layout.mask(ModuleKind::ForceTorque);
            if sensors != ModMask(0) {
                self.broadcast(Command::SetBias, sensors)?;
            }
            self.biased = true;
        }
        self.broadcast(Command::Ready, ModMask::ALL)?;
        self.broadcast(Command::Start, ModMask::ALL)?;
        self.state = ControllerState::Running;
        self.stats.bring_ups += 1;
        Ok(())
    }

    /// STOP every module (on exit). Safe to call in any state.
    ///
    /// # Errors
    /// Port errors (the state is `Stopped` anyway).
    pub fn stop(&mut self) -> Result<(), MotionError> {
        self.state = ControllerState::Stopped;
        self.stats.stops += 1;
        self.broadcast(Command::Stop, ModMask::ALL)
    }

    /// Stop the robot because of `fault`, and hand the fault back.
    fn fail(&mut self, fault: MotionError) -> MotionError {
        self.stats.missed += u64::from(matches!(
            fault,
            MotionError::Missed { .. } | MotionError::ModuleFault { .. }
        ));
        // Best effort: the broadcast needs nobody's answer.
        let _ = self.stop();
        self.fault = Some(fault);
        fault
    }

    fn running(&self) -> Result<(), MotionError> {
        match self.state {
            ControllerState::Running => Ok(()),
            s => Err(MotionError::NotRunning(s)),
        }
    }

    /// Read every module once (QREAD / FTREAD), in layout order.
    fn read_once(&mut self) -> Result<(), (usize, MissReason)> {
        let mut block = [0u8; JointBlock::LEN];
        for i in 0..self.layout.modules.len() {
            let spec = &self.layout.modules[i];
            let Some(node) = self.nodes[i] else {
                return Err((
                    i,
                    MissReason::Transaction(HostError::UnknownBoard(spec.mod_id.0)),
                ));
            };
            let (command, len) = match spec.kind {
                ModuleKind::ForceTorque => (Command::FtRead, FtBlock::LEN),
                _ => (Command::QRead, JointBlock::LEN),
            };
            let buf = &mut block[..len];
            let t0 = self.port.now();
            self.port
                .read_block(Dest::node(node), command.offset(), buf)
                .map_err(|e| (i, MissReason::Transaction(e)))?;
            self.feedback.read_times[i] = self.port.now().saturating_sub(t0);
            match spec.kind {
                ModuleKind::ForceTorque => {
                    let w = FtBlock::parse(buf).map_err(|e| (i, MissReason::Malformed(e)))?;
                    self.feedback.wrenches[i] = Some(w);
                }
                _ => {
                    let j = JointBlock::parse(buf).map_err(|e| (i, MissReason::Malformed(e)))?;
                    if j.mod_id != spec.mod_id {
                        return Err((i, MissReason::WrongModule { found: j.mod_id }));
                    }
                    self.feedback.joints[i] = Some(j);
                }
            }
        }
        Ok(())
    }

    /// Read every module (Table I's `T_e`). A bus reset met on the way is
    /// recovered from (bring-up in the new generation, then the whole read
    /// again); anything else a module does wrong stops the robot.
    ///
    /// # Errors
    /// [`MotionError::NotRunning`]; [`MotionError::Missed`] or
    /// [`MotionError::ModuleFault`] (the robot has been stopped); a failed
    /// bring-up after a reset (stopped too).
    pub fn read_all(&mut self) -> Result<&Feedback, MotionError> {
        self.running()?;
        // A period's I/O begins (the port counts or bounds it); it ends with
        // the QWRITE, or here when the read fails (the stop that follows
        // is bounded by its own time-outs only).
        self.port.begin_cycle();
        let mut recovered = false;
        loop {
            match self.read_once() {
                Ok(()) => break,
                Err((_, MissReason::Transaction(HostError::BusReset { .. }))) if !recovered => {
                    recovered = true;
                    if let Err(e) = self.bring_up() {
                        self.port.end_cycle();
                        return Err(self.fail(e));
                    }
                    self.stats.resets_recovered += 1;
                }
                Err((i, reason)) => {
                    let mod_id = self.layout.modules[i].mod_id;
                    self.port.end_cycle();
                    return Err(self.fail(MotionError::Missed { mod_id, reason }));
                }
            }
        }
        // Every joint must be running with no fault of its own.
        for (i, spec) in self.layout.modules.iter().enumerate() {
            if let Some(j) = self.feedback.joints[i] {
                if j.state != ModuleState::Running || j.flags & JointBlock::FAULTS != 0 {
                    let fault = MotionError::ModuleFault {
                        mod_id: spec.mod_id,
                        state: j.state,
                        flags: j.flags,
                    };
                    self.port.end_cycle();
                    return Err(self.fail(fault));
                }
            }
        }
        self.stats.cycles += 1;
        Ok(&self.feedback)
    }

    /// Broadcast one QWRITE with `setpoints` (Table I's `T_g`); each slot
    /// carries the cycle's sequence number.
    ///
    /// # Errors
    /// [`MotionError::NotRunning`]; port errors (the robot is stopped).
    pub fn write_setpoints(&mut self, setpoints: &Setpoints) -> Result<(), MotionError> {
        self.running()?;
        self.sequence = self.sequence.wrapping_add(1);
        for (slot, out) in setpoints
            .slots
            .iter()
            .zip(self.qwrite.chunks_exact_mut(SetpointSlot::LEN))
        {
            let slot = SetpointSlot {
                sequence: self.sequence,
                ..*slot
            };
            // A slot always fits its 32 bytes.
            let _ = slot.emit(out);
        }
        match self
            .port
            .write_block(Dest::BROADCAST, Command::QWrite.offset(), &self.qwrite)
        {
            Ok(()) => {
                self.stats.setpoint_writes += 1;
                self.port.end_cycle();
                Ok(())
            }
            Err(e) => {
                self.port.end_cycle();
                Err(self.fail(MotionError::Host(e)))
            }
        }
    }
}

impl<P: Port> Drop for MotionController<P> {
    fn drop(&mut self) {
        if self.state == ControllerState::Running {
            let _ = self.stop();
        }
    }
}
