//! The MAHRU humanoid's modules (seed 002) as nodes on the simulated bus.
//!
//! Seed 002's robot has 14 modules on one 1394 bus: 10 motor controllers
//! (a TMS320VC33 DSP behind an Actel FPGA, one joint each) and 4
//! force/torque sensor modules (the same DSP with an ADC). They speak the
//! custom protocol of [`firelink_wire::mahru`]: command codes in the
//! destination offset, a module ID ([`ModId`]) that survives bus resets.
//!
//! [`ModuleNode`] is one module: the FPGA's link rules and the DSP's
//! command handling are common; what the module serves is its device, a
//! [`joint::MotorController`] (position and velocity, a local PID servo at
//! its own rate, gear ratio, gains and limits from PARAMETER, a watchdog)
//! or a [`ft::FtSensor`] (six axes with bias, noise and a load model driven
//! by the robot's motion).
//!
//! # Timing: a slow responder dominates
//! The seed's point (section II.B) is that the responder's processing
//! power decides a read's time. Here the FPGA acks a read request at once
//! (`ack_pending`); the DSP notices it at its next poll of the FPGA (every
//! [`ResponderTiming::poll`], a phase of its own per module), works
//! [`ResponderTiming::fixed`] plus [`ResponderTiming::per_byte`] per byte
//! of the answer, and hands the response to the link, which arbitrates
//! for the bus (a split transaction). With all three zero the FPGA answers
//! by itself, concatenated to the ack. Writes are acked complete at once
//! (the FPGA buffers them) and applied.
//!
//! # Commands
//! Every command of Table II is handled; P2P quadlet commands (STOP,
//! READY, START, SETBIAS sent to one node) work like their broadcasts. A
//! broadcast with an unknown code or of the wrong kind is ignored (and
//! counted); a P2P request with an unknown code is answered with
//! `resp_address_error` and changes nothing. Packets with a bad CRC are
//! dropped and reported. Every bus reset flushes the requests waiting for
//! the DSP (as 1394 flushes transactions) and gives the module its new
//! node ID; its ModID stays.

pub mod ft;
pub mod joint;

use std::collections::VecDeque;

use firelink_bus::{
    ArbitrationClass, Node, NodeCtx, ResetInfo, RxReply, SimDuration, SimTime, TransmitRequest,
};
use firelink_wire::mahru::{
    Command, IdCheck, Identity, ModId, ModMask, ModuleKind, ModuleState, TRACE_BUFFER_LEN,
    TRACE_BUFFER_OFFSET,
};
use firelink_wire::packet::{Ack, AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Speed, Tcode};

use crate::qla::emit;

pub use ft::{BodyParams, FtLoad, FtParams, FtSensor};
pub use joint::{JointParams, MotorController};

/// How long the module's DSP takes to answer a read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResponderTiming {
    /// Time from the DSP noticing the request to the response going to the
    /// link, whatever its size.
    pub fixed: SimDuration,
    /// Extra time per byte of the answer (the DSP copying it into the
    /// FPGA's transmit FIFO).
    pub per_byte: SimDuration,
    /// The DSP polls the FPGA for requests this often (zero: at once).
    pub poll: SimDuration,
}

impl ResponderTiming {
    /// An FPGA that answers by itself: concatenated responses.
    pub const IMMEDIATE: ResponderTiming = ResponderTiming {
        fixed: SimDuration::ZERO,
        per_byte: SimDuration::ZERO,
        poll: SimDuration::ZERO,
    };

    /// Whether the FPGA answers by itself (concatenated to the ack).
    pub fn is_immediate(&self) -> bool {
        self.fixed == SimDuration::ZERO
            && self.per_byte == SimDuration::ZERO
            && self.poll == SimDuration::ZERO
    }

    /// Processing time of an answer of `bytes` bytes, once noticed.
    pub fn processing(&self, bytes: usize) -> SimDuration {
        self.fixed + self.per_byte * bytes as u64
    }
}

/// What kind of module, with its device parameters.
#[derive(Debug, Clone, PartialEq)]
pub enum DeviceConfig {
    /// A motor controller and its joint.
    Motor(JointParams),
    /// A force/torque sensor module.
    ForceTorque(FtParams),
}

/// One module.
#[derive(Debug, Clone, PartialEq)]
pub struct ModuleConfig {
    /// Its module ID (motor controllers: their QWRITE slot, 0..10).
    pub mod_id: ModId,
    /// A name for traces ("l_knee", "r_foot_ft").
    pub name: String,
    /// Firmware revision reported by IDREQUEST (0..=15).
    pub firmware: u8,
    /// How long its DSP takes to answer.
    pub timing: ResponderTiming,
    /// Speed of its responses.
    pub speed: Speed,
    /// The device behind the FPGA.
    pub device: DeviceConfig,
}

/// The module's device.
#[derive(Debug, Clone)]
pub enum Device {
    /// A motor controller.
    Motor(Box<MotorController>),
    /// A force/torque sensor.
    ForceTorque(Box<FtSensor>),
}

impl Device {
    fn kind(&self) -> ModuleKind {
        match self {
            Device::Motor(_) => ModuleKind::MotorController,
            Device::ForceTorque(_) => ModuleKind::ForceTorque,
        }
    }

    fn state(&self) -> ModuleState {
        match self {
            Device::Motor(m) => m.state(),
            Device::ForceTorque(f) => f.state(),
        }
    }

    fn advance(&mut self, now: SimTime) {
        match self {
            Device::Motor(m) => m.advance(now),
            Device::ForceTorque(f) => f.advance(now),
        }
    }

    /// A quadlet command (STOP, READY, START, SETBIAS) for this module.
    fn quadlet_command(&mut self, now: SimTime, command: Command) -> bool {
        match self {
            Device::Motor(m) => m.command(now, command),
            Device::ForceTorque(f) => f.command(now, command),
        }
    }

    fn trace_quadlet(&self, i: usize) -> u32 {
        match self {
            Device::Motor(m) => m.trace_quadlet(i),
            Device::ForceTorque(f) => f.trace_quadlet(i),
        }
    }
}

/// What a module counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ModuleStats {
    /// Commands handled, by code (index = code, 0..=19).
    pub commands: [u32; 20],
    /// Requests or broadcasts with a code the module does not know, or of
    /// a kind the command does not take; ignored.
    pub ignored: u32,
    /// Packets dropped for a bad CRC or a malformed header.
    pub crc_errors: u32,
    /// Blocks refused (bad size or content): nothing of them applied.
    pub refused: u32,
    /// Read responses sent.
    pub responses: u32,
    /// Requests waiting for the DSP that a bus reset flushed.
    pub flushed: u32,
    /// Bus resets seen.
    pub resets: u32,
}

impl ModuleStats {
    fn count(&mut self, command: Command) {
        if let Some(c) = self.commands.get_mut(usize::from(u8::from(command))) {
            *c += 1;
        }
    }
}

/// A read waiting for the DSP.
#[derive(Debug, Clone, Copy)]
struct PendingRead {
    header: AsyncHeader,
    what: ReadKind,
    due: SimTime,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ReadKind {
    Identity,
    IdCheck,
    Joint,
    Ft,
    Trace {
        len: u16,
    },
    /// Answered with this error rcode (in a block or quadlet response,
    /// as the request was).
    Refused {
        rcode: Rcode,
        block: bool,
    },
}

impl ReadKind {
    fn answer_len(self) -> usize {
        match self {
            ReadKind::Identity | ReadKind::IdCheck => 4,
            ReadKind::Joint => firelink_wire::mahru::JointBlock::LEN,
            ReadKind::Ft => firelink_wire::mahru::FtBlock::LEN,
            ReadKind::Trace { len } => usize::from(len),
            ReadKind::Refused { .. } => 0,
        }
    }
}

/// Timer token of the DSP's next answer.
const ANSWER_TIMER: u64 = 1;
/// Timer token of the device's own deadline (the motor watchdog).
const DEVICE_TIMER: u64 = 2;

/// One MAHRU module on the simulated bus. See the module docs.
#[derive(Debug, Clone)]
pub struct ModuleNode {
    config: ModuleConfig,
    device: Device,
    phy_id: u8,
    generation: u32,
    queue: VecDeque<PendingRead>,
    /// Phase of the DSP's polling loop (derived from the ModID so that
    /// modules do not poll in lock step).
    poll_phase: SimDuration,
    device_timer: Option<SimTime>,
    next_token: u64,
    stats: ModuleStats,
}

impl ModuleNode {
    /// A module with `config`, at rest at time zero.
    pub fn new(config: ModuleConfig) -> ModuleNode {
        let device = match &config.device {
            DeviceConfig::Motor(p) => {
                Device::Motor(Box::new(MotorController::new(config.mod_id, p.clone())))
            }
            DeviceConfig::ForceTorque(p) => {
                Device::ForceTorque(Box::new(FtSensor::new(config.mod_id, p.clone())))
            }
        };
        // 0.37 of a poll period per ModID step, wrapped.
        let poll = config.timing.poll.0;
        let poll_phase = if poll == 0 {
            SimDuration::ZERO
        } else {
            SimDuration((u64::from(config.mod_id.0) * poll * 37 / 100) % poll)
        };
        ModuleNode {
            config,
            device,
            phy_id: NodeId::BROADCAST_PHY,
            generation: 0,
            queue: VecDeque::new(),
            poll_phase,
            device_timer: None,
            next_token: 0,
            stats: ModuleStats::default(),
        }
    }

    /// The module's ID.
    pub fn mod_id(&self) -> ModId {
        self.config.mod_id
    }

    /// Its configuration.
    pub fn config(&self) -> &ModuleConfig {
        &self.config
    }

    /// Its lifecycle state.
    pub fn state(&self) -> ModuleState {
        self.device.state()
    }

    /// Its physical ID (63 before the first reset).
    pub fn phy_id(&self) -> u8 {
        self.phy_id
    }

    /// What it counted.
    pub fn stats(&self) -> &ModuleStats {
        &self.stats
    }

    /// The device.
    pub fn device(&self) -> &Device {
        &self.device
    }

    /// The motor controller, if this is one.
    pub fn motor(&self) -> Option<&MotorController> {
        match &self.device {
            Device::Motor(m) => Some(m),
            Device::ForceTorque(_) => None,
        }
    }

    /// The force/torque sensor, if this is one.
    pub fn force_torque(&self) -> Option<&FtSensor> {
        match &self.device {
            Device::ForceTorque(f) => Some(f),
            Device::Motor(_) => None,
        }
    }

    /// Bring the device up to `now` (servo ticks, watchdog). Nodes do this
    /// on every event; a test reading state between events calls it
    /// through [`Bus::with_node`](firelink_bus::Bus::with_node).
    pub fn advance(&mut self, now: SimTime) {
        self.device.advance(now);
    }

    /// The DSP's next poll instant at or after `t`.
    fn next_poll(&self, t: SimTime) -> SimTime {
        let poll = self.config.timing.poll.0;
        if poll == 0 {
            return t;
        }
        let phase = self.poll_phase.0;
        let k = t.0.saturating_sub(phase).div_ceil(poll);
        SimTime(phase + k * poll).max(t)
    }

    /// Queue a read for the DSP; returns when it will be answered.
    fn enqueue(&mut self, now: SimTime, header: AsyncHeader, what: ReadKind) -> SimTime {
        // The DSP handles one request at a time, in order.
        let start = self.queue.back().map_or(now, |p| p.due.max(now));
        let due = self.next_poll(start) + self.config.timing.processing(what.answer_len());
        self.queue.push_back(PendingRead { header, what, due });
        due
    }

    /// Build the response to a read, with the device's state now.
    fn answer(&mut self, now: SimTime, read: &PendingRead) -> Vec<u8> {
        self.device.advance(now);
        let header = read.header.response();
        let quadlet = |data: u32| PacketRepr::ReadQuadletResponse {
            header,
            rcode: Rcode::Complete,
            data,
        };
        let mut block = [0u8; TRACE_BUFFER_LEN];
        let repr = match read.what {
            ReadKind::Identity => {
                let id = Identity {
                    mod_id: self.config.mod_id,
                    kind: self.device.kind(),
                    firmware: self.config.firmware & 0xF,
                };
                match id.to_quadlet() {
                    Ok(q) => quadlet(q),
                    Err(_) => refused(header, Rcode::DataError, false),
                }
            }
            ReadKind::IdCheck => {
                let check = IdCheck {
                    mod_id: self.config.mod_id,
                    state: self.device.state(),
                    phy_id: self.phy_id & 0x3F,
                    generation: (self.generation & IdCheck::GENERATION_MASK) as u16,
                };
                match check.to_quadlet() {
                    Ok(q) => quadlet(q),
                    Err(_) => refused(header, Rcode::DataError, false),
                }
            }
            ReadKind::Joint | ReadKind::Ft => {
                let len = match &mut self.device {
                    Device::Motor(m) => m.joint_block().emit(&mut block),
                    Device::ForceTorque(f) => f.take_reading(now).emit(&mut block),
                };
                match len {
                    Ok(len) => block_response(header, block.get(..len).unwrap_or(&[])),
                    Err(_) => refused(header, Rcode::DataError, true),
                }
            }
            ReadKind::Trace { len } => {
                let len = usize::from(len).min(TRACE_BUFFER_LEN);
                for (i, q) in block.chunks_exact_mut(4).take(len / 4).enumerate() {
                    q.copy_from_slice(&self.device.trace_quadlet(i).to_be_bytes());
                }
                block_response(header, block.get(..len).unwrap_or(&[]))
            }
            ReadKind::Refused { rcode, block } => refused(header, rcode, block),
        };
        emit(&repr)
    }

    /// Arm the timer for the next answer, and the device's own deadline.
    fn arm(&mut self, now: SimTime, ctx: &mut NodeCtx<'_>) {
        match self.queue.front() {
            Some(p) => ctx.set_timer(p.due.max(now), ANSWER_TIMER),
            None => ctx.cancel_timer(ANSWER_TIMER),
        }
        let deadline = match &self.device {
            Device::Motor(m) => m.deadline(),
            Device::ForceTorque(_) => None,
        };
        if deadline != self.device_timer {
            match deadline {
                Some(at) => ctx.set_timer(at.max(now), DEVICE_TIMER),
                None => ctx.cancel_timer(DEVICE_TIMER),
            }
            self.device_timer = deadline;
        }
    }

    /// A request addressed to this node: what to ack, and the read (if
    /// any) the DSP must answer.
    fn request(
        &mut self,
        now: SimTime,
        view: &Packet<&[u8]>,
        repr: &PacketRepr<'_>,
    ) -> (Ack, Option<(AsyncHeader, ReadKind)>) {
        let command = Command::from_offset(view.offset());
        match *repr {
            PacketRepr::ReadQuadletRequest { header, .. } => {
                let what = match command {
                    Some(c @ Command::IdRequest) => {
                        self.stats.count(c);
                        ReadKind::Identity
                    }
                    Some(c @ Command::IdCheck) => {
                        self.stats.count(c);
                        ReadKind::IdCheck
                    }
                    _ => {
                        self.stats.ignored += 1;
                        ReadKind::Refused {
                            rcode: Rcode::AddressError,
                            block: false,
                        }
                    }
                };
                (Ack::Pending, Some((header, what)))
            }
            PacketRepr::ReadBlockRequest {
                header,
                offset,
                data_length,
                ..
            } => {
                let len = usize::from(data_length);
                let what = match (command, &self.device) {
                    (Some(c @ Command::QRead), Device::Motor(_))
                        if len == firelink_wire::mahru::JointBlock::LEN =>
                    {
                        self.stats.count(c);
                        ReadKind::Joint
                    }
                    (Some(c @ Command::FtRead), Device::ForceTorque(_))
                        if len == firelink_wire::mahru::FtBlock::LEN =>
                    {
                        self.stats.count(c);
                        ReadKind::Ft
                    }
                    (Some(Command::QRead | Command::FtRead), _) => {
                        self.stats.refused += 1;
                        ReadKind::Refused {
                            rcode: Rcode::TypeError,
                            block: true,
                        }
                    }
                    (None, _)
                        if offset == TRACE_BUFFER_OFFSET
                            && len % 4 == 0
                            && (4..=TRACE_BUFFER_LEN).contains(&len) =>
                    {
                        ReadKind::Trace { len: data_length }
                    }
                    _ => {
                        self.stats.ignored += 1;
                        ReadKind::Refused {
                            rcode: Rcode::AddressError,
                            block: true,
                        }
                    }
                };
                (Ack::Pending, Some((header, what)))
            }
            PacketRepr::WriteQuadletRequest { data, .. } => {
                match command {
                    Some(c) if is_quadlet_command(c) => {
                        self.quadlet_command(now, c, ModMask(data));
                    }
                    _ => self.stats.ignored += 1,
                }
                (Ack::Complete, None)
            }
            PacketRepr::WriteBlockRequest { data, .. } => {
                match command {
                    Some(c @ (Command::Parameter | Command::QWrite)) => {
                        self.block_command(now, c, data, false);
                    }
                    _ => self.stats.ignored += 1,
                }
                (Ack::Complete, None)
            }
            _ => {
                self.stats.ignored += 1;
                (Ack::TypeError, None)
            }
        }
    }

    /// A broadcast request (node 63): commands of the broadcast kind only.
    fn broadcast(&mut self, now: SimTime, view: &Packet<&[u8]>, repr: &PacketRepr<'_>) {
        let command = Command::from_offset(view.offset());
        match (*repr, command) {
            (PacketRepr::WriteQuadletRequest { data, .. }, Some(c)) if is_quadlet_command(c) => {
                self.quadlet_command(now, c, ModMask(data));
            }
            (
                PacketRepr::WriteBlockRequest { data, .. },
                Some(c @ (Command::Parameter | Command::QWrite)),
            ) => {
                self.block_command(now, c, data, true);
            }
            _ => self.stats.ignored += 1,
        }
    }

    fn quadlet_command(&mut self, now: SimTime, command: Command, mask: ModMask) {
        self.stats.count(command);
        if mask.contains(self.config.mod_id) && !self.device.quadlet_command(now, command) {
            self.stats.ignored += 1;
        }
    }

    fn block_command(&mut self, now: SimTime, command: Command, data: &[u8], broadcast: bool) {
        self.stats.count(command);
        let taken = match (&mut self.device, command) {
            (Device::Motor(m), Command::Parameter) => m.parameters(now, data),
            (Device::Motor(m), Command::QWrite) => m.setpoints(now, data),
            // Every node hears every broadcast: the sensors' load model
            // follows the set-points the joints are given.
            (Device::ForceTorque(f), Command::QWrite) => f.observe_setpoints(data),
            // A sensor takes no parameters: only refuse a P2P block meant
            // for it.
            (Device::ForceTorque(_), _) => Ok(broadcast),
            _ => Ok(false),
        };
        match taken {
            Ok(true) => {}
            Ok(false) => self.stats.ignored += 1,
            Err(_) => self.stats.refused += 1,
        }
    }
}

fn is_quadlet_command(c: Command) -> bool {
    matches!(
        c,
        Command::Stop | Command::SetBias | Command::Ready | Command::Start
    )
}

fn block_response<'a>(header: AsyncHeader, data: &'a [u8]) -> PacketRepr<'a> {
    PacketRepr::ReadBlockResponse {
        header,
        rcode: Rcode::Complete,
        extended_tcode: 0,
        data,
    }
}

fn refused(header: AsyncHeader, rcode: Rcode, block: bool) -> PacketRepr<'static> {
    if block {
        PacketRepr::ReadBlockResponse {
            header,
            rcode,
            extended_tcode: 0,
            data: &[],
        }
    } else {
        PacketRepr::ReadQuadletResponse {
            header,
            rcode,
            data: 0,
        }
    }
}

impl Node for ModuleNode {
    fn name(&self) -> &str {
        &self.config.name
    }

    fn on_bus_reset(&mut self, now: SimTime, info: &ResetInfo, ctx: &mut NodeCtx<'_>) {
        self.device.advance(now);
        self.phy_id = info.phy_id;
        self.generation = info.generation;
        self.stats.resets += 1;
        self.stats.flushed += self.queue.len() as u32;
        self.queue.clear();
        self.arm(now, ctx);
    }

    fn on_receive(
        &mut self,
        now: SimTime,
        bytes: &[u8],
        _speed: Speed,
        ctx: &mut NodeCtx<'_>,
    ) -> RxReply {
        let Ok(view) = Packet::new_checked(bytes) else {
            self.stats.crc_errors += 1;
            ctx.report_error(format!("{}: malformed packet", self.config.name));
            return RxReply::Silent;
        };
        let tcode = view.tcode();
        if !tcode.is_request() || tcode == Tcode::LinkInternal {
            // Responses to others, PHY packets, cycle starts: not ours.
            return RxReply::Silent;
        }
        let destination = view.destination_id();
        let to_us = destination.phy() == self.phy_id;
        let broadcast = destination.is_broadcast();
        if !to_us && !broadcast {
            return RxReply::Silent;
        }
        let status = view.crc_status();
        if status.header_ok == Some(false) {
            self.stats.crc_errors += 1;
            ctx.report_error(format!("{}: header CRC error", self.config.name));
            return RxReply::Silent;
        }
        if status.data_ok == Some(false) {
            self.stats.crc_errors += 1;
            ctx.report_error(format!("{}: data CRC error", self.config.name));
            return if broadcast {
                RxReply::Silent
            } else {
                RxReply::Ack(Ack::DataError)
            };
        }
        let Ok(repr) = PacketRepr::parse(&view) else {
            self.stats.crc_errors += 1;
            return RxReply::Silent;
        };
        self.device.advance(now);
        if broadcast {
            self.broadcast(now, &view, &repr);
            self.arm(now, ctx);
            return RxReply::Silent;
        }
        let (ack, read) = self.request(now, &view, &repr);
        let reply = match read {
            Some((header, what)) if self.config.timing.is_immediate() => {
                // The FPGA answers by itself, concatenated to the ack.
                let pending = PendingRead {
                    header,
                    what,
                    due: now,
                };
                let response = self.answer(now, &pending);
                self.stats.responses += 1;
                RxReply::AckThenResponse {
                    ack: Ack::Pending,
                    response,
                    speed: self.config.speed,
                }
            }
            Some((header, what)) => {
                self.enqueue(now, header, what);
                RxReply::Ack(ack)
            }
            None => RxReply::Ack(ack),
        };
        self.arm(now, ctx);
        reply
    }

    fn on_timer(&mut self, now: SimTime, token: u64, ctx: &mut NodeCtx<'_>) {
        if token == DEVICE_TIMER {
            self.device_timer = None;
            self.device.advance(now);
        }
        while let Some(read) = self.queue.front().copied().filter(|p| p.due <= now) {
            self.queue.pop_front();
            let packet = self.answer(now, &read);
            if packet.is_empty() {
                continue;
            }
            self.next_token += 1;
            self.stats.responses += 1;
            ctx.transmit(TransmitRequest {
                packet,
                speed: self.config.speed,
                class: ArbitrationClass::Fair,
                token: self.next_token,
            });
        }
        self.arm(now, ctx);
    }
}
