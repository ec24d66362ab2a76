//! A MAHRU motor controller module: one joint, its local PID servo at its
//! own rate, and the joint's mechanics.
//!
//! The DSP runs the servo every `1 / servo_hz` seconds of virtual time.
//! Ticks are computed when something happens (a packet, a timer): the
//! module catches up tick by tick to the present, so the result is the
//! same as a free-running servo and costs no events on the bus.
//!
//! Lifecycle (the [`ModuleState`] the module reports):
//! - `Idle` at power-up, `Parameterized` once PARAMETER gave it a valid
//!   record: amplifier off, brake on (the joint does not move).
//! - READY (from `Parameterized`, `Ready`, `Running` or `Stopped`, with
//!   parameters): amplifier on, the servo holds the position of that
//!   instant.
//! - START (from `Ready`): the servo follows QWRITE set-points, each
//!   extrapolated with its velocity until the next one arrives.
//! - STOP, the joint leaving its position limits, or no valid set-point
//!   for the watchdog period while running: `Stopped`, amplifier off,
//!   brake on, the reason in the flags.
//!
//! The servo: `torque = kp e + ki integral(e) + kd de/dt + feed-forward`,
//! limited to the torque limit (the integral stops growing while the
//! torque is saturated); the joint: `J a = torque - b v - g sin(q + q0)`,
//! integrated semi-implicitly at the servo rate; motor current =
//! `torque / (gear ratio x torque constant)`.

use firelink_bus::{SimDuration, SimTime};
use firelink_wire::mahru::{
    Command, JointBlock, ModId, ModuleState, ParameterRecord, QWRITE_LEN, SetpointSlot,
};

/// The joint's physics and the module's fixed settings (not sent by the
/// host: they are the hardware).
#[derive(Debug, Clone, PartialEq)]
pub struct JointParams {
    /// Inertia at the joint (link and reflected rotor), kg m^2.
    pub inertia: f64,
    /// Viscous friction at the joint, Nm s/rad.
    pub damping: f64,
    /// Largest gravity torque on the joint (m g l), Nm.
    pub gravity_torque: f64,
    /// Joint angle at which gravity pulls hardest minus pi/2 (the
    /// gravity torque is `gravity_torque x sin(q + gravity_offset)`), rad.
    pub gravity_offset: f64,
    /// Motor torque constant, Nm/A.
    pub torque_constant: f64,
    /// Servo rate of the DSP, Hz.
    pub servo_hz: f64,
    /// Longest time without a valid set-point while running.
    pub watchdog: SimDuration,
    /// Joint angle at power-up, rad.
    pub initial_position: f64,
}

impl Default for JointParams {
    fn default() -> Self {
        JointParams {
            inertia: 0.25,
            damping: 2.0,
            gravity_torque: 10.0,
            gravity_offset: 0.0,
            torque_constant: 0.05,
            servo_hz: 5000.0,
            watchdog: SimDuration::from_millis(10),
            initial_position: 0.0,
        }
    }
}

/// The set-point being followed.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Setpoint {
    position: f64,
    velocity: f64,
    torque: f64,
    sequence: u16,
    at: SimTime,
}

/// Samples kept in the trace buffer (one quadlet each: the position).
const TRACE_SAMPLES: usize = 512;

/// One motor controller's DSP and joint. See the module docs.
#[derive(Debug, Clone)]
pub struct MotorController {
    mod_id: ModId,
    params: JointParams,
    record: Option<ParameterRecord>,
    state: ModuleState,
    flags: u32,
    dt: f64,
    tick: SimDuration,
    next_tick: SimTime,
    ticks: u32,
    position: f64,
    velocity: f64,
    integral: f64,
    torque: f64,
    target: f64,
    hold: f64,
    setpoint: Option<Setpoint>,
    trace: Vec<u32>,
    setpoints_taken: u64,
}

fn urad(x: f64) -> i32 {
    (x * 1e6)
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

fn milli(x: f64) -> i32 {
    (x * 1e3)
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

impl MotorController {
    /// The module `mod_id` at power-up: idle, at `initial_position`.
    pub fn new(mod_id: ModId, params: JointParams) -> MotorController {
        let hz = if params.servo_hz.is_finite() && params.servo_hz > 0.0 {
            params.servo_hz
        } else {
            1000.0
        };
        let tick = SimDuration::from_micros_f64(1e6 / hz).max(SimDuration(1));
        MotorController {
            mod_id,
            record: None,
            state: ModuleState::Idle,
            flags: 0,
            dt: tick.as_micros_f64() * 1e-6,
            tick,
            next_tick: SimTime::ZERO + tick,
            ticks: 0,
            position: params.initial_position,
            velocity: 0.0,
            integral: 0.0,
            torque: 0.0,
            target: params.initial_position,
            hold: params.initial_position,
            setpoint: None,
            trace: vec![0; TRACE_SAMPLES],
            setpoints_taken: 0,
            params,
        }
    }

    /// Its lifecycle state.
    pub fn state(&self) -> ModuleState {
        self.state
    }

    /// Status flags as the joint block reports them.
    pub fn flags(&self) -> u32 {
        let mut f = self.flags;
        if self.amplifier_on() {
            f |= JointBlock::AMPLIFIER_ON;
        }
        if self.record.is_some() {
            f |= JointBlock::PARAMETERS_VALID;
        }
        f
    }

    /// Whether the amplifier is on (Ready or Running).
    pub fn amplifier_on(&self) -> bool {
        matches!(self.state, ModuleState::Ready | ModuleState::Running)
    }

    /// Joint position, rad.
    pub fn position(&self) -> f64 {
        self.position
    }

    /// Joint velocity, rad/s.
    pub fn velocity(&self) -> f64 {
        self.velocity
    }

    /// The position the servo tracked at its last tick, rad.
    pub fn target(&self) -> f64 {
        self.target
    }

    /// Joint torque commanded at the last tick, Nm.
    pub fn torque(&self) -> f64 {
        self.torque
    }

    /// The parameters PARAMETER gave it.
    pub fn parameters_record(&self) -> Option<&ParameterRecord> {
        self.record.as_ref()
    }

    /// The physics and fixed settings.
    pub fn joint_params(&self) -> &JointParams {
        &self.params
    }

    /// Servo ticks run so far.
    pub fn ticks(&self) -> u32 {
        self.ticks
    }

    /// Valid set-points taken from QWRITE so far.
    pub fn setpoints_taken(&self) -> u64 {
        self.setpoints_taken
    }

    /// Sequence of the last set-point taken.
    pub fn sequence(&self) -> Option<u16> {
        self.setpoint.map(|s| s.sequence)
    }

    /// When the module must look at itself even if nothing arrives (the
    /// watchdog while running).
    pub fn deadline(&self) -> Option<SimTime> {
        match (self.state, self.setpoint) {
            (ModuleState::Running, Some(s)) => Some(s.at + self.params.watchdog + self.tick),
            _ => None,
        }
    }

    /// Run every servo tick up to `now`.
    pub fn advance(&mut self, now: SimTime) {
        while self.next_tick <= now {
            let t = self.next_tick;
            self.step(t);
            self.next_tick = t + self.tick;
        }
    }

    fn stop(&mut self, why: u32) {
        self.state = ModuleState::Stopped;
        self.flags |= why;
        self.torque = 0.0;
        self.integral = 0.0;
        self.velocity = 0.0;
    }

    /// One servo tick at `t`.
    fn step(&mut self, t: SimTime) {
        self.ticks = self.ticks.wrapping_add(1);
        let slot = (self.ticks as usize) % TRACE_SAMPLES;
        if let Some(s) = self.trace.get_mut(slot) {
            *s = urad(self.position) as u32;
        }
        let Some(record) = self.record else {
            return;
        };
        let (target, target_velocity, feed_forward) = match (self.state, self.setpoint) {
            (ModuleState::Running, Some(sp)) => {
                let age = t.saturating_since(sp.at);
                if age > self.params.watchdog {
                    self.stop(JointBlock::WATCHDOG);
                    return;
                }
                let dt = age.as_micros_f64() * 1e-6;
                (sp.position + sp.velocity * dt, sp.velocity, sp.torque)
            }
            (ModuleState::Running | ModuleState::Ready, _) => (self.hold, 0.0, 0.0),
            // Amplifier off, brake on: the joint stays where it is.
            _ => return,
        };
        self.target = target;
        let kp = f64::from(record.kp);
        let ki = f64::from(record.ki);
        let kd = f64::from(record.kd);
        let limit = f64::from(record.torque_max);
        let error = target - self.position;
        let wanted = kp * error
            + ki * (self.integral + error * self.dt)
            + kd * (target_velocity - self.velocity)
            + feed_forward;
        let torque = wanted.clamp(-limit, limit);
        if torque == wanted {
            self.integral += error * self.dt;
            self.flags &= !JointBlock::SATURATED;
        } else {
            self.flags |= JointBlock::SATURATED;
        }
        self.torque = torque;
        let p = &self.params;
        let gravity = p.gravity_torque * (self.position + p.gravity_offset).sin();
        let acceleration = (torque - p.damping * self.velocity - gravity) / p.inertia.max(1e-6);
        self.velocity += acceleration * self.dt;
        self.position += self.velocity * self.dt;
        if self.position < f64::from(record.position_min)
            || self.position > f64::from(record.position_max)
        {
            self.stop(JointBlock::LIMIT);
        }
    }

    /// STOP, READY, START (SETBIAS means nothing to a motor). Returns
    /// whether the command applied.
    pub fn command(&mut self, now: SimTime, command: Command) -> bool {
        self.advance(now);
        match command {
            Command::Stop => {
                if self.amplifier_on() {
                    self.stop(0);
                } else if self.state != ModuleState::Idle {
                    self.state = ModuleState::Stopped;
                }
                true
            }
            Command::Ready if self.record.is_some() => {
                self.state = ModuleState::Ready;
                self.flags &= !JointBlock::FAULTS;
                self.hold = self.position;
                self.target = self.position;
                self.integral = 0.0;
                self.setpoint = None;
                true
            }
            Command::Start if self.state == ModuleState::Ready => {
                self.state = ModuleState::Running;
                // Until the first set-point arrives, hold; the watchdog
                // counts from START.
                self.setpoint = Some(Setpoint {
                    position: self.hold,
                    velocity: 0.0,
                    torque: 0.0,
                    sequence: 0,
                    at: now,
                });
                true
            }
            _ => false,
        }
    }

    /// PARAMETER: take this module's record from the block. The block is
    /// checked whole; a bad block changes nothing.
    ///
    /// # Errors
    /// What [`ParameterRecord::find`] finds.
    pub fn parameters(&mut self, now: SimTime, block: &[u8]) -> firelink_wire::Result<bool> {
        self.advance(now);
        let Some(record) = ParameterRecord::find(block, self.mod_id)? else {
            return Ok(false);
        };
        self.record = Some(record);
        if self.state == ModuleState::Idle {
            self.state = ModuleState::Parameterized;
        }
        Ok(true)
    }

    /// QWRITE: take this module's slot. Only a valid slot that names this
    /// module, while running, is a set-point.
    ///
    /// # Errors
    /// A payload that is not [`QWRITE_LEN`] bytes.
    pub fn setpoints(&mut self, now: SimTime, payload: &[u8]) -> firelink_wire::Result<bool> {
        self.advance(now);
        if payload.len() != QWRITE_LEN {
            return Err(firelink_wire::Error::BlockSize {
                what: "QWRITE payload",
                expected: QWRITE_LEN / 4,
                found: payload.len() / 4,
            });
        }
        let slot = SetpointSlot::slice(payload, self.mod_id)?;
        if !slot.valid || slot.mod_id != self.mod_id.0 || self.state != ModuleState::Running {
            return Ok(false);
        }
        self.setpoint = Some(Setpoint {
            position: slot.position(),
            velocity: slot.velocity(),
            torque: f64::from(slot.torque_mnm) * 1e-3,
            sequence: slot.sequence,
            at: now,
        });
        self.setpoints_taken += 1;
        Ok(true)
    }

    /// The QREAD answer now.
    pub fn joint_block(&self) -> JointBlock {
        let gear = self.record.map_or(1.0, |r| f64::from(r.gear_ratio));
        let current = self.torque / (gear * self.params.torque_constant).max(1e-9);
        JointBlock {
            mod_id: self.mod_id,
            state: self.state,
            sequence: self.setpoint.map_or(0, |s| s.sequence),
            position_urad: urad(self.position),
            velocity_urad_s: urad(self.velocity),
            current_ma: milli(current),
            target_urad: urad(self.target),
            torque_mnm: milli(self.torque),
            servo_ticks: self.ticks,
            flags: self.flags(),
        }
    }

    /// Quadlet `i` of the trace buffer (positions, oldest first).
    pub fn trace_quadlet(&self, i: usize) -> u32 {
        let start = (self.ticks as usize + 1) % TRACE_SAMPLES;
        self.trace
            .get((start + i) % TRACE_SAMPLES)
            .copied()
            .unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(id: u8) -> ParameterRecord {
        ParameterRecord {
            mod_id: ModId(id),
            gear_ratio: 100.0,
            kp: 600.0,
            ki: 200.0,
            kd: 25.0,
            position_min: -2.0,
            position_max: 2.0,
            torque_max: 80.0,
        }
    }

    fn params_block(id: u8) -> [u8; 32] {
        let mut b = [0u8; 32];
        record(id).emit(&mut b).unwrap();
        b
    }

    fn qwrite(id: u8, pos: f64, seq: u16) -> Vec<u8> {
        let mut p = vec![0u8; QWRITE_LEN];
        SetpointSlot {
            mod_id: id,
            valid: true,
            sequence: seq,
            position_urad: urad(pos),
            ..SetpointSlot::default()
        }
        .emit(&mut p[usize::from(id) * 32..])
        .unwrap();
        p
    }

    fn ms(n: u64) -> SimTime {
        SimTime::ZERO + SimDuration::from_millis(n)
    }

    #[test]
    fn lifecycle_and_tracking() {
        let mut m = MotorController::new(ModId(3), JointParams::default());
        assert_eq!(m.state(), ModuleState::Idle);
        // No parameters: READY refused, brake holds the joint.
        assert!(!m.command(ms(1), Command::Ready));
        assert!(m.parameters(ms(2), &params_block(3)).unwrap());
        assert_eq!(m.state(), ModuleState::Parameterized);
        assert!(!m.command(ms(3), Command::Start), "START needs READY first");
        assert!(m.command(ms(3), Command::Ready));
        assert!(m.command(ms(4), Command::Start));
        // Follow 0.3 rad, refreshed every 2 ms.
        for k in 0..500u64 {
            m.setpoints(ms(4 + 2 * k), &qwrite(3, 0.3, k as u16))
                .unwrap();
        }
        m.advance(ms(1004));
        assert_eq!(m.state(), ModuleState::Running);
        assert!((m.position() - 0.3).abs() < 1e-3, "{}", m.position());
        assert_eq!(m.sequence(), Some(499));
        // Gravity is held by the integral: the torque balances it.
        let g = 10.0 * 0.3f64.sin();
        assert!((m.torque() - g).abs() < 0.5, "{} vs {g}", m.torque());
        let block = m.joint_block();
        assert_eq!(block.mod_id, ModId(3));
        assert_ne!(block.flags & JointBlock::AMPLIFIER_ON, 0);
        // Current = torque / (gear x kt).
        assert!((f64::from(block.current_ma) * 1e-3 - m.torque() / 5.0).abs() < 1e-3);
    }

    #[test]
    fn watchdog_and_limits_stop_the_joint() {
        let mut m = MotorController::new(ModId(0), JointParams::default());
        m.parameters(ms(0), &params_block(0)).unwrap();
        m.command(ms(1), Command::Ready);
        m.command(ms(1), Command::Start);
        m.setpoints(ms(2), &qwrite(0, 0.1, 1)).unwrap();
        assert_eq!(m.deadline(), Some(ms(12) + SimDuration::from_micros(200)));
        m.advance(ms(30));
        assert_eq!(m.state(), ModuleState::Stopped);
        assert_ne!(m.flags() & JointBlock::WATCHDOG, 0);
        assert_eq!(m.flags() & JointBlock::AMPLIFIER_ON, 0);
        let held = m.position();
        m.advance(ms(100));
        assert_eq!(m.position(), held, "brake on");
        // READY clears the fault; a set-point beyond the limit stops it.
        assert!(m.command(ms(100), Command::Ready));
        assert_eq!(m.flags() & JointBlock::FAULTS, 0);
        m.command(ms(100), Command::Start);
        for k in 0..200u64 {
            m.setpoints(ms(100 + 2 * k), &qwrite(0, 2.5, k as u16))
                .unwrap();
        }
        m.advance(ms(600));
        assert_eq!(m.state(), ModuleState::Stopped);
        assert_ne!(m.flags() & JointBlock::LIMIT, 0);
    }

    #[test]
    fn qwrite_takes_only_its_own_valid_slot() {
        let mut m = MotorController::new(ModId(4), JointParams::default());
        m.parameters(ms(0), &params_block(4)).unwrap();
        m.command(ms(0), Command::Ready);
        m.command(ms(0), Command::Start);
        // Slot 4 empty (not valid), slot 5 has a set-point: not taken.
        assert!(!m.setpoints(ms(1), &qwrite(5, 0.5, 9)).unwrap());
        // Slot 4 claiming ModID 6: not taken.
        let mut p = qwrite(4, 0.5, 9);
        p[4 * 32] = 6;
        assert!(!m.setpoints(ms(1), &p).unwrap());
        assert!(m.setpoints(ms(1), &qwrite(4, 0.5, 9)).unwrap());
        assert!(m.setpoints(ms(1), &[0u8; 316]).is_err());
        assert_eq!(m.setpoints_taken(), 1);
    }
}
