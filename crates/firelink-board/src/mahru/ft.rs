//! A MAHRU force/torque sensor module: six axes with bias, noise and a
//! load model driven by the robot's motion.
//!
//! A reading is `load + offset + noise - bias`:
//! - the *load* is what the robot's motion puts on the sensor (below);
//! - the *offset* is the strain gauges' own zero error (per axis, fixed);
//! - the *noise* is seeded and counter-addressed: reading `k` of a sensor
//!   always gets the same noise, whatever else happened;
//! - the *bias* is what SETBIAS captured: the mean of 16 readings at that
//!   instant (offset, the load of that moment, and noise), removed from
//!   every later reading until the next SETBIAS.
//!
//! # The load model
//! Every node hears every broadcast, so the sensor module hears QWRITE
//! and knows the set-points the joints follow (position, velocity and
//! acceleration of each); the joints track them closely, so the load is
//! computed from them:
//! - a **foot** sensor carries its share of the body weight once the
//!   robot stands (START lowers it to the ground; before, it hangs in its
//!   frame and the feet carry nothing). The share moves to the other foot
//!   as this leg's knee bends (swing) relative to the other knee; the
//!   fore-aft force brakes the body's acceleration (hip acceleration x leg
//!   length), the centre of pressure moves from heel to toe with the hip
//!   angle (pitch torque), and sits a little inside the foot (roll torque);
//! - a **wrist** sensor carries the hand: its weight turned into the
//!   forearm's frame by the shoulder and elbow angles, plus the hand's
//!   tangential and centripetal accelerations, and the moments of both
//!   about the sensor.
//!
//! Axes: x forward (along the forearm for a wrist), y left, z up; forces
//! in N, torques in Nm, reported in mN and mNm.

use firelink_bus::SimTime;
use firelink_wire::mahru::{
    Command, FtBlock, ModId, ModuleState, QWRITE_LEN, QWRITE_SLOTS, SetpointSlot,
};

use crate::plant::noise::{Noise, NoiseChannel};

/// Standard gravity, m/s^2.
const G: f64 = 9.81;

/// Where the sensor sits and which joints move it (by ModID).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FtLoad {
    /// Under an ankle.
    Foot {
        /// The leg's hip pitch joint.
        hip: ModId,
        /// The leg's knee.
        knee: ModId,
        /// The other leg's knee.
        other_knee: ModId,
        /// Left foot (the centre of pressure sits to its right).
        left: bool,
    },
    /// Between a forearm and its hand.
    Wrist {
        /// The arm's shoulder pitch joint.
        shoulder: ModId,
        /// The arm's elbow.
        elbow: ModId,
    },
}

/// The body the load model uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyParams {
    /// Whole robot, kg (MAHRU: about 67 kg).
    pub mass: f64,
    /// Hip to ankle, m.
    pub leg_length: f64,
    /// Hand (beyond the wrist sensor), kg.
    pub hand_mass: f64,
    /// Elbow to hand centre of mass, m.
    pub forearm_length: f64,
    /// Wrist sensor to hand centre of mass, m.
    pub hand_offset: f64,
}

impl Default for BodyParams {
    fn default() -> Self {
        BodyParams {
            mass: 67.0,
            leg_length: 0.75,
            hand_mass: 1.2,
            forearm_length: 0.28,
            hand_offset: 0.08,
        }
    }
}

/// A sensor's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct FtParams {
    /// Where it sits.
    pub load: FtLoad,
    /// The body.
    pub body: BodyParams,
    /// Zero error per axis: N, N, N, Nm, Nm, Nm.
    pub offset: [f64; 6],
    /// Noise standard deviation: forces (N) and torques (Nm).
    pub noise: [f64; 2],
    /// Seed of the noise.
    pub seed: u64,
    /// The joints' angles at power-up, by ModID (what the load model
    /// assumes until the first QWRITE).
    pub initial_pose: [f64; QWRITE_SLOTS],
}

/// What the sensor knows of one joint's set-point.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct JointMotion {
    position: f64,
    velocity: f64,
    acceleration: f64,
}

/// Readings averaged by SETBIAS.
const BIAS_SAMPLES: u64 = 16;
/// Readings kept in the trace buffer (six quadlets each).
const TRACE_READINGS: usize = 64;

/// One force/torque sensor module. See the module docs.
#[derive(Debug, Clone)]
pub struct FtSensor {
    mod_id: ModId,
    params: FtParams,
    noise: Noise,
    samples: u64,
    bias: [f64; 6],
    biased: bool,
    standing: bool,
    state: ModuleState,
    joints: [JointMotion; QWRITE_SLOTS],
    trace: Vec<[i32; 6]>,
}

fn milli(x: f64) -> i32 {
    (x * 1e3)
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

impl FtSensor {
    /// The sensor `mod_id` at power-up: robot hanging, no bias taken.
    pub fn new(mod_id: ModId, params: FtParams) -> FtSensor {
        FtSensor {
            mod_id,
            noise: Noise::new(params.seed),
            joints: params.initial_pose.map(|position| JointMotion {
                position,
                ..JointMotion::default()
            }),
            params,
            samples: 0,
            bias: [0.0; 6],
            biased: false,
            standing: false,
            state: ModuleState::Idle,
            trace: vec![[0; 6]; TRACE_READINGS],
        }
    }

    /// Its module ID.
    pub fn mod_id(&self) -> ModId {
        self.mod_id
    }

    /// Its lifecycle state (`Idle`, `Ready` after READY, `Running` after
    /// START, `Stopped` after STOP: readings are served in every state).
    pub fn state(&self) -> ModuleState {
        self.state
    }

    /// Its settings.
    pub fn params(&self) -> &FtParams {
        &self.params
    }

    /// Whether SETBIAS has been taken.
    pub fn biased(&self) -> bool {
        self.biased
    }

    /// The bias SETBIAS captured (N, Nm).
    pub fn bias(&self) -> [f64; 6] {
        self.bias
    }

    /// Whether the robot stands on the ground (START lowered it).
    pub fn standing(&self) -> bool {
        self.standing
    }

    /// Readings taken so far.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Nothing runs on its own in the sensor: readings are taken on
    /// demand.
    pub fn advance(&mut self, _now: SimTime) {}

    fn joint(&self, id: ModId) -> JointMotion {
        self.joints
            .get(usize::from(id.0))
            .copied()
            .unwrap_or_default()
    }

    /// The true load now, without offset, noise or bias: N, N, N, Nm, Nm,
    /// Nm.
    pub fn load(&self) -> [f64; 6] {
        let b = &self.params.body;
        match self.params.load {
            FtLoad::Foot {
                hip,
                knee,
                other_knee,
                left,
            } => {
                if !self.standing {
                    return [0.0; 6];
                }
                let hip = self.joint(hip);
                let bend = self.joint(knee).position - self.joint(other_knee).position;
                // The swing leg bends its knee: its foot unloads.
                let share = 0.5 - 0.5 * (8.0 * bend).tanh();
                let fz = b.mass * G * share;
                // The body's centre of mass moves about a third as much as
                // the swinging foot.
                let fx = -b.mass * 0.3 * b.leg_length * hip.acceleration * share;
                let side = if left { -1.0 } else { 1.0 };
                let fy = side * 0.04 * fz;
                let x_cop = (0.3 * b.leg_length * hip.position.sin()).clamp(-0.08, 0.12);
                let y_cop = side * 0.02;
                [fx, fy, fz, fz * y_cop, -fz * x_cop, 0.02 * fx]
            }
            FtLoad::Wrist { shoulder, elbow } => {
                let s = self.joint(shoulder);
                let e = self.joint(elbow);
                let phi = s.position + e.position;
                let omega = s.velocity + e.velocity;
                let alpha = s.acceleration + e.acceleration;
                let m = b.hand_mass;
                let r = b.forearm_length;
                let tangential = m * (G * phi.sin() + r * alpha);
                let axial = -m * (G * phi.cos() + r * omega * omega);
                [
                    tangential,
                    0.0,
                    axial,
                    0.0,
                    b.hand_offset * tangential,
                    0.01 * tangential,
                ]
            }
        }
    }

    /// One raw reading (load + offset + noise), consuming one noise sample.
    fn raw(&mut self) -> [f64; 6] {
        let load = self.load();
        let k = self.samples;
        self.samples += 1;
        let [force_sigma, torque_sigma] = self.params.noise;
        let mut out = load;
        for (axis, (v, offset)) in out.iter_mut().zip(self.params.offset).enumerate() {
            let sigma = if axis < 3 { force_sigma } else { torque_sigma };
            let n = self.noise.gaussian(axis, NoiseChannel::ForceTorque, k);
            *v += offset + sigma * n;
        }
        out
    }

    /// Take one reading as FTREAD returns it (bias removed).
    pub fn take_reading(&mut self, _now: SimTime) -> FtBlock {
        let raw = self.raw();
        let mut v = [0i32; 6];
        for ((x, r), b) in v.iter_mut().zip(raw).zip(self.bias) {
            *x = milli(r - b);
        }
        let slot = (self.samples as usize) % TRACE_READINGS;
        if let Some(t) = self.trace.get_mut(slot) {
            *t = v;
        }
        FtBlock {
            force_mn: [v[0], v[1], v[2]],
            torque_mnm: [v[3], v[4], v[5]],
        }
    }

    /// SETBIAS, READY, START, STOP. Returns whether the command applied.
    pub fn command(&mut self, _now: SimTime, command: Command) -> bool {
        match command {
            Command::SetBias => {
                let mut sum = [0.0; 6];
                for _ in 0..BIAS_SAMPLES {
                    let r = self.raw();
                    for (s, x) in sum.iter_mut().zip(r) {
                        *s += x;
                    }
                }
                self.bias = sum.map(|s| s / BIAS_SAMPLES as f64);
                self.biased = true;
                true
            }
            Command::Ready => {
                self.state = ModuleState::Ready;
                true
            }
            Command::Start => {
                self.state = ModuleState::Running;
                self.standing = true;
                true
            }
            Command::Stop => {
                self.state = ModuleState::Stopped;
                true
            }
            _ => false,
        }
    }

    /// Hear a QWRITE (meant for the joints): remember every valid slot's
    /// set-point for the load model.
    ///
    /// # Errors
    /// A payload that is not [`QWRITE_LEN`] bytes.
    pub fn observe_setpoints(&mut self, payload: &[u8]) -> firelink_wire::Result<bool> {
        if payload.len() != QWRITE_LEN {
            return Err(firelink_wire::Error::BlockSize {
                what: "QWRITE payload",
                expected: QWRITE_LEN / 4,
                found: payload.len() / 4,
            });
        }
        for (i, joint) in self.joints.iter_mut().enumerate() {
            let slot = SetpointSlot::slice(payload, ModId(i as u8))?;
            if slot.valid && usize::from(slot.mod_id) == i {
                *joint = JointMotion {
                    position: slot.position(),
                    velocity: slot.velocity(),
                    acceleration: slot.acceleration(),
                };
            }
        }
        Ok(true)
    }

    /// Quadlet `i` of the trace buffer (recent readings, six quadlets
    /// each).
    pub fn trace_quadlet(&self, i: usize) -> u32 {
        let reading = (i / 6) % TRACE_READINGS;
        self.trace
            .get(reading)
            .and_then(|r| r.get(i % 6))
            .map_or(0, |v| *v as u32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn foot() -> FtParams {
        FtParams {
            load: FtLoad::Foot {
                hip: ModId(0),
                knee: ModId(1),
                other_knee: ModId(3),
                left: true,
            },
            body: BodyParams::default(),
            offset: [3.0, -2.0, 5.0, 0.2, -0.1, 0.05],
            noise: [0.3, 0.02],
            seed: 7,
            initial_pose: [0.0; QWRITE_SLOTS],
        }
    }

    fn mean_of(s: &mut FtSensor, n: usize) -> [f64; 6] {
        let mut sum = [0.0; 6];
        for _ in 0..n {
            let w = s.take_reading(SimTime::ZERO).wrench();
            for (a, b) in sum.iter_mut().zip(w) {
                *a += b;
            }
        }
        sum.map(|x| x / n as f64)
    }

    #[test]
    fn setbias_removes_the_offset() {
        let mut s = FtSensor::new(ModId(10), foot());
        let before = mean_of(&mut s, 400);
        for (m, o) in before.iter().zip(foot().offset) {
            assert!((m - o).abs() < 0.1, "{m} vs offset {o}");
        }
        assert!(s.command(SimTime::ZERO, Command::SetBias));
        let after = mean_of(&mut s, 400);
        // Bias of 16 noisy samples: within 4 sigma / sqrt(16) of zero.
        for (i, m) in after.iter().enumerate() {
            let sigma = foot().noise[usize::from(i >= 3)];
            assert!(m.abs() < sigma, "axis {i}: {m}");
        }
    }

    #[test]
    fn standing_loads_the_feet_and_the_swing_leg_unloads() {
        let mut s = FtSensor::new(ModId(10), foot());
        s.command(SimTime::ZERO, Command::SetBias);
        assert_eq!(s.load(), [0.0; 6], "hanging: no load");
        s.command(SimTime::ZERO, Command::Start);
        let w = 67.0 * G;
        assert!((s.load()[2] - w / 2.0).abs() < 1e-9);
        // Left knee bent 0.4 rad more than the right: the left foot swings.
        let mut q = vec![0u8; QWRITE_LEN];
        SetpointSlot {
            mod_id: 1,
            valid: true,
            position_urad: 400_000,
            ..SetpointSlot::default()
        }
        .emit(&mut q[32..])
        .unwrap();
        s.observe_setpoints(&q).unwrap();
        assert!(s.load()[2] < 0.05 * w, "{}", s.load()[2]);
        // The mean reading is the load up to the bias's own noise (one
        // reading when SETBIAS came): within four of its sigmas.
        let r = mean_of(&mut s, 200);
        let sigma = foot().noise[0];
        assert!(
            (r[2] - s.load()[2]).abs() < 4.0 * sigma,
            "{r:?} {:?}",
            s.load()
        );
    }

    #[test]
    fn wrist_sees_the_hand_weight_turn_with_the_arm() {
        let mut s = FtSensor::new(
            ModId(12),
            FtParams {
                load: FtLoad::Wrist {
                    shoulder: ModId(4),
                    elbow: ModId(5),
                },
                ..foot()
            },
        );
        let m = BodyParams::default().hand_mass;
        assert!((s.load()[2] + m * G).abs() < 1e-9, "hanging arm");
        let mut q = vec![0u8; QWRITE_LEN];
        SetpointSlot {
            mod_id: 5,
            valid: true,
            position_urad: 1_570_796,
            ..SetpointSlot::default()
        }
        .emit(&mut q[160..])
        .unwrap();
        s.observe_setpoints(&q).unwrap();
        assert!((s.load()[0] - m * G).abs() < 1e-3, "forearm horizontal");
        assert!(s.observe_setpoints(&q[..100]).is_err());
    }

    #[test]
    fn readings_are_seeded() {
        let mut a = FtSensor::new(ModId(10), foot());
        let mut b = FtSensor::new(ModId(10), foot());
        let mut c = FtSensor::new(ModId(10), FtParams { seed: 8, ..foot() });
        let ra = a.take_reading(SimTime::ZERO);
        assert_eq!(ra, b.take_reading(SimTime::ZERO));
        assert_ne!(ra, c.take_reading(SimTime::ZERO));
    }
}
