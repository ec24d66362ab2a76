//! A walking-like joint trajectory for MAHRU's ten joints.
//!
//! With the stride phase `phi = 2 pi t / stride`:
//! - the hips swing in opposition, `+-hip sin(phi)`;
//! - each knee bends while its leg swings forward, `knee max(0, +-cos(phi))^2`
//!   (smooth, zero during stance);
//! - the shoulders swing against the legs, the elbows a little with them,
//!   the hands at twice the stride rate.
//!
//! Every joint moves about the angle it had at power-up (the centre), and
//! the amplitudes ramp in smoothly over `ramp` seconds from standing
//! still, so the first set-point equals the position READY held.
//! Velocities and accelerations are the exact derivatives (central
//! differences of the smooth position, step 0.1 ms).

use std::f64::consts::PI;

use firelink_wire::mahru::{ModId, QWRITE_SLOTS};

use super::config::{GaitJson, MahruConfig};

/// One joint's role in the gait.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    Hip { left: bool },
    Knee { left: bool },
    Shoulder { left: bool },
    Elbow { left: bool },
    Hand { left: bool },
    Still,
}

/// A joint's set-point at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointSetpoint {
    /// Position, rad.
    pub position: f64,
    /// Velocity, rad/s.
    pub velocity: f64,
    /// Acceleration, rad/s^2.
    pub acceleration: f64,
}

/// The gait of one robot configuration.
#[derive(Debug, Clone)]
pub struct Gait {
    params: GaitJson,
    roles: [Role; QWRITE_SLOTS],
    centres: [f64; QWRITE_SLOTS],
}

/// Roles by the joint names of the seed's robot ("l_knee", "r_hip_pitch").
fn role_of(name: &str) -> Role {
    let left = name.starts_with('l');
    if name.contains("hip") {
        Role::Hip { left }
    } else if name.contains("knee") {
        Role::Knee { left }
    } else if name.contains("shoulder") {
        Role::Shoulder { left }
    } else if name.contains("elbow") {
        Role::Elbow { left }
    } else if name.contains("hand") {
        Role::Hand { left }
    } else {
        Role::Still
    }
}

impl Gait {
    /// The gait of `config`: roles from the joints' names, centres from
    /// their power-up angles.
    pub fn new(config: &MahruConfig) -> Gait {
        let mut roles = [Role::Still; QWRITE_SLOTS];
        let mut centres = [0.0; QWRITE_SLOTS];
        for m in config.modules() {
            let i = usize::from(m.mod_id);
            if let (Some(r), Some(c), Some(j)) = (
                roles.get_mut(i),
                centres.get_mut(i),
                config.motor(ModId(m.mod_id)),
            ) {
                *r = role_of(&m.name);
                *c = j.initial_position_rad;
            }
        }
        Gait {
            params: config.gait,
            roles,
            centres,
        }
    }

    /// The amplitude ramp: 0 at the start, 1 after `ramp` (smoothstep).
    fn ramp(&self, t: f64) -> f64 {
        if self.params.ramp_s <= 0.0 {
            return 1.0;
        }
        let x = (t / self.params.ramp_s).clamp(0.0, 1.0);
        x * x * (3.0 - 2.0 * x)
    }

    /// Joint `id`'s position at `t` seconds after START.
    pub fn position(&self, id: ModId, t: f64) -> f64 {
        let i = usize::from(id.0);
        let (Some(role), Some(centre)) = (self.roles.get(i), self.centres.get(i)) else {
            return 0.0;
        };
        let g = &self.params;
        let phi = 2.0 * PI * t.max(0.0) / g.stride_s;
        let sign = |left: bool| if left { 1.0 } else { -1.0 };
        let swing = match *role {
            Role::Hip { left } => sign(left) * g.hip_rad * phi.sin(),
            Role::Knee { left } => g.knee_rad * (sign(left) * phi.cos()).max(0.0).powi(2),
            Role::Shoulder { left } => -sign(left) * g.shoulder_rad * phi.sin(),
            Role::Elbow { left } => -sign(left) * g.elbow_rad * phi.sin(),
            Role::Hand { left } => sign(left) * g.hand_rad * (2.0 * phi).sin(),
            Role::Still => 0.0,
        };
        centre + self.ramp(t) * swing
    }

    /// Joint `id`'s set-point at `t`.
    pub fn setpoint(&self, id: ModId, t: f64) -> JointSetpoint {
        const H: f64 = 1e-4;
        let p0 = self.position(id, t);
        let p1 = self.position(id, t + H);
        let pm = self.position(id, t - H);
        JointSetpoint {
            position: p0,
            velocity: (p1 - pm) / (2.0 * H),
            acceleration: (p1 - 2.0 * p0 + pm) / (H * H),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn starts_still_at_the_centres_and_walks() {
        let c = MahruConfig::seed002();
        let g = Gait::new(&c);
        for id in 0..10u8 {
            let centre = c.motor(ModId(id)).unwrap().initial_position_rad;
            let s = g.setpoint(ModId(id), 0.0);
            assert!((s.position - centre).abs() < 1e-9);
            assert!(s.velocity.abs() < 1e-3);
        }
        // After the ramp the hips swing in opposition with the full amplitude.
        let t = 1.2 * 2.25; // a quarter stride after two strides
        let l = g.position(ModId(0), t);
        let r = g.position(ModId(2), t);
        assert!((l + r).abs() < 1e-9);
        assert!((l.abs() - 0.25).abs() < 1e-6);
        // Knees: one bends while the other is straight (at its centre).
        let lk = g.position(ModId(1), 2.4) - 0.2;
        let rk = g.position(ModId(3), 2.4) - 0.2;
        assert!(lk > 0.4 && rk.abs() < 1e-9, "{lk} {rk}");
        // The derivative is the derivative.
        let s = g.setpoint(ModId(0), 2.1);
        let w = 2.0 * PI / 1.2;
        assert!((s.velocity - 0.25 * w * (w * 2.1).cos()).abs() < 1e-4);
        assert!((s.acceleration + 0.25 * w * w * (w * 2.1).sin()).abs() < 1e-2);
    }
}
