//! What the runner does per joint and per cycle, whatever the boards:
//! one joint's conversions, velocity, trajectory,
//! PID and tracking ([`Joint::update`]), and the pacing of cycles
//! ([`Pacer`]), for [`Robot`](super::Robot).

use std::time::{Duration, Instant};

use super::velocity::VelocityEstimator;
use super::{ArmAcc, CycleTimes, Pacing};
use crate::config::{DriveConfig, EncoderConfig, JointRef, JointType, PotentiometerConfig};
use crate::label::Label;
use crate::pid::{Measurement, Pid, Setpoint};
use crate::safety::JointSample;
use crate::trajectory::{Motion, SinCosMemo};

/// One joint: where its owner finds its axis, its conversions and its
/// control state.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Joint {
    pub label: Label,
    pub arm: usize,
    /// The board ID.
    pub board: usize,
    /// The I/O system's axis (over all boards).
    pub axis: usize,
    pub drive: DriveConfig,
    /// `drive.current_limit()`, kept.
    pub current_limit: f64,
    pub encoder: EncoderConfig,
    pub pot: Option<PotentiometerConfig>,
    pub prismatic: bool,
    pub motion: Motion,
    pub motion_start: f64,
    pub offset: f64,
    /// Homed: the encoder was biased from the pot (`Robot::home`). Only
    /// from then does the safety monitor compare the two: before, the
    /// encoder counts from wherever the board started.
    pub homed: bool,
    /// `pot.is_some() && homed`, kept with `homed`: whether the safety
    /// monitor is given this joint's pot (while Active, a finite one).
    pub pot_watched: bool,
    pub position: f64,
    pub velocity: VelocityEstimator,
    pub setpoint: f64,
    /// The setpoint's velocity (0 unless Active), rad/s or m/s.
    pub setpoint_velocity: f64,
    pub current: f64,
}

impl Joint {
    /// A joint of the configuration, found at `(board, axis)`, holding
    /// still.
    pub fn new(j: &JointRef<'_>, board: usize, axis: usize) -> Joint {
        let a = j.actuator;
        Joint {
            label: j.label,
            arm: j.robot_index,
            board,
            axis,
            drive: a.drive,
            current_limit: a.drive.current_limit(),
            encoder: a.encoder,
            pot: a.potentiometer,
            prismatic: a.joint_type == Some(JointType::Prismatic),
            motion: Motion::Hold(0.0),
            motion_start: 0.0,
            offset: 0.0,
            homed: false,
            pot_watched: false,
            position: 0.0,
            velocity: VelocityEstimator::default(),
            setpoint: 0.0,
            setpoint_velocity: 0.0,
            current: 0.0,
        }
    }

    /// One cycle's measurement, the first half of the joint's cycle: the
    /// encoder `counts` latched and the boards' sample clock `sampled`
    /// (s) give the position (homed) and the velocity, into the joint and
    /// its safety `sample`. Returns the encoder position before the homing
    /// offset. Allocation-free. (Like the other steps of a joint's cycle,
    /// inlined into the cycle's loop over the joints: a call per joint
    /// and step cost more than its arithmetic.)
    #[inline(always)]
    pub fn measure(&mut self, counts: i32, sampled: f64, sample: &mut JointSample) -> f64 {
        let raw = self.encoder.counts_to_position(i64::from(counts));
        let pos = raw + self.offset;
        let velocity = self.velocity.update(sampled, pos);
        self.position = pos;
        sample.position = pos;
        sample.velocity = velocity;
        raw
    }

    /// Then the setpoint: Active, the trajectory's at the port's time
    /// `now` (a sinusoid's sine and cosine through `memo`, which the
    /// runner passes to every joint of the cycle: the same bits as
    /// [`Motion::sample`]); otherwise the joint's position, at rest.
    /// (Active, it reads nothing [`measure`](Self::measure) writes: the
    /// runner plans every joint's setpoint before measuring them.)
    #[inline(always)]
    pub fn plan(&mut self, now: f64, active: bool, memo: &mut SinCosMemo) {
        if active {
            let sp = self.motion.sample_memo(now - self.motion_start, memo);
            self.setpoint = sp.position;
            self.setpoint_velocity = sp.velocity;
        } else {
            self.setpoint = self.position;
            self.setpoint_velocity = 0.0;
        }
    }

    /// Last, after [`plan`](Self::plan): Active, the PID's current over the
    /// period `dt` and the tracking error into `acc`; otherwise no current.
    /// `pot` is the joint's pot position in actuator space (NaN: none).
    /// The rest of the safety `sample`. Allocation-free. (Inlined into
    /// the cycle's loop over the joints: a call per joint cost more than
    /// its arithmetic.)
    #[inline(always)]
    pub fn control(
        &mut self,
        dt: f64,
        active: bool,
        pot: f64,
        pid: Option<&mut Pid>,
        acc: Option<&mut ArmAcc>,
        sample: &mut JointSample,
    ) {
        let pos = self.position;
        let mut amps = 0.0;
        if active {
            if let Some(pid) = pid {
                amps = pid.update(
                    Setpoint {
                        position: self.setpoint,
                        velocity: self.setpoint_velocity,
                        feedforward: 0.0,
                    },
                    Measurement {
                        position: pos,
                        velocity: sample.velocity,
                    },
                    dt,
                );
            }
            if let Some(acc) = acc {
                acc.add((self.setpoint - pos).abs(), self.prismatic);
            }
        }
        self.current = amps;
        sample.setpoint = self.setpoint;
        sample.current = amps;
        sample.potentiometer = (self.pot_watched && active && pot.is_finite()).then_some(pot);
    }

    /// The pot position from the pot's ADC bits (NaN without a pot or a
    /// reading).
    #[inline(always)]
    pub fn pot_position(&self, bits: Option<u16>) -> f64 {
        match (&self.pot, bits) {
            (Some(p), Some(bits)) => p.bits_to_position(bits),
            _ => f64::NAN,
        }
    }

    /// The DAC code to write: the current while active, else zero current.
    #[inline(always)]
    pub fn command(&self, active: bool) -> u16 {
        if active {
            self.drive
                .current_to_bits_within(self.current, self.current_limit)
        } else {
            self.drive.zero_current_bits()
        }
    }
}

/// Every joint holds where it is, its PID restarted; a motion set later
/// starts at `now`.
pub(crate) fn hold_all(joints: &mut [Joint], pids: &mut [Pid], now: f64) {
    for (j, pid) in joints.iter_mut().zip(pids.iter_mut()) {
        j.motion = Motion::Hold(j.position);
        j.motion_start = now;
        // The setpoint is the hold from now on, not what the last cycle
        // planned (a move planned from the setpoint before the next cycle
        // would start from a stale one and step).
        j.setpoint = j.position;
        j.setpoint_velocity = 0.0;
        pid.reset();
    }
}

/// Homing is done: each joint takes its offset; positions are the raw
/// encoder positions `raw` plus the offsets, velocities start again.
pub(crate) fn apply_offsets(joints: &mut [Joint], offsets: &[f64], raw: &[f64]) {
    for ((j, off), raw) in joints.iter_mut().zip(offsets).zip(raw) {
        j.offset = *off;
        j.homed = true;
        j.pot_watched = j.pot.is_some();
        j.position = raw + off;
        // Not active: the setpoint follows the (now homed) position.
        j.setpoint = j.position;
        j.setpoint_velocity = 0.0;
        j.velocity.reset();
    }
}

/// Start `motion` on joint `i` at `now`.
///
/// # Errors
/// [`RunnerError::Config`](super::RunnerError::Config) for a joint that
/// does not exist.
pub(crate) fn start_motion(
    joints: &mut [Joint],
    i: usize,
    motion: Motion,
    now: f64,
) -> Result<(), super::RunnerError> {
    let j = joints
        .get_mut(i)
        .ok_or_else(|| super::RunnerError::Config(format!("no joint {i}")))?;
    j.motion = motion;
    j.motion_start = now;
    Ok(())
}

/// Paces cycles on the machine's clock ([`Pacing::WallClock`]); with
/// [`Pacing::Virtual`] the port waits out the rest of each period instead
/// ([`Pacer::rest`]).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Pacer {
    next_deadline: Option<Instant>,
}

impl Pacer {
    /// Start a new run: the next cycle starts at once.
    pub fn restart(&mut self) {
        self.next_deadline = None;
    }

    /// Before a cycle: with wall-clock pacing, sleep until its deadline;
    /// a cycle more than half a period late counts as an overrun and
    /// restarts the schedule from now.
    pub fn before_cycle(&mut self, pacing: Pacing, period: Duration, times: &mut CycleTimes) {
        if pacing != Pacing::WallClock {
            return;
        }
        let deadline = self.next_deadline.unwrap_or_else(Instant::now);
        let now = Instant::now();
        if now > deadline + period / 2 {
            times.overruns += 1;
            self.next_deadline = Some(now + period);
        } else {
            firelink_host::pacing::sleep_until(deadline);
            self.next_deadline = Some(deadline + period);
        }
    }

    /// After a cycle that took `spent` on the port's clock: how long the
    /// port should wait with virtual pacing (none if the period is over).
    pub fn rest(pacing: Pacing, period: Duration, spent: Duration) -> Option<Duration> {
        if pacing != Pacing::Virtual {
            return None;
        }
        period.checked_sub(spent).filter(|d| !d.is_zero())
    }
}
