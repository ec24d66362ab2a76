//! Setpoint generators: point-to-point moves and sinusoids.
//!
//! Every generator is a small `Copy` value built once (where its inputs are
//! checked) and then sampled each cycle with [`sample(t)`](Motion::sample),
//! where `t` is the time since the motion started, seconds, on the caller's
//! clock. Sampling never allocates, never panics and always returns finite
//! values: a NaN or `-inf` time counts as the start, `+inf` as the end.
//!
//! - [`PointToPoint`]: trapezoidal velocity (triangular when the distance is
//!   short), respecting a velocity and an acceleration limit, minimum time.
//! - [`Quintic`]: a fifth-order polynomial, zero velocity and acceleration at
//!   both ends (smoother: continuous acceleration), for a given duration or the
//!   shortest one within limits.
//! - [`Sinusoid`]: `offset + amplitude · sin(2π f t + phase)`, faded in with
//!   a smooth (C²) ramp so it starts at `offset` with zero velocity.
//! - [`Motion`]: any of them, or holding still, as one enum for the servo loop.
//!
//! Moves end *exactly* on their final position (it is returned as given, not
//! recomputed) and never overshoot it.

use core::f64::consts::PI;

/// Position, velocity and acceleration at one instant (rad, rad/s, rad/s²,
/// or metres).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample {
    /// Position.
    pub position: f64,
    /// Velocity.
    pub velocity: f64,
    /// Acceleration.
    pub acceleration: f64,
}

impl Sample {
    /// At rest at `position`.
    pub fn at_rest(position: f64) -> Sample {
        Sample {
            position,
            velocity: 0.0,
            acceleration: 0.0,
        }
    }
}

/// Why a trajectory could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum TrajectoryError {
    /// The named parameter is NaN or infinite.
    #[error("trajectory parameter {0} is not finite")]
    NotFinite(&'static str),
    /// The named parameter must be > 0 (or >= 0 where zero is allowed).
    #[error("trajectory parameter {0} is out of range")]
    OutOfRange(&'static str),
}

fn finite(name: &'static str, v: f64) -> Result<f64, TrajectoryError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(TrajectoryError::NotFinite(name))
    }
}

fn positive(name: &'static str, v: f64) -> Result<f64, TrajectoryError> {
    if finite(name, v)? > 0.0 {
        Ok(v)
    } else {
        Err(TrajectoryError::OutOfRange(name))
    }
}

fn non_negative(name: &'static str, v: f64) -> Result<f64, TrajectoryError> {
    if finite(name, v)? >= 0.0 {
        Ok(v)
    } else {
        Err(TrajectoryError::OutOfRange(name))
    }
}

/// Where a sample time falls.
enum Phase {
    Before,
    During(f64),
    After,
}

fn phase(t: f64, duration: f64) -> Phase {
    if t.is_nan() || t <= 0.0 {
        Phase::Before
    } else if t >= duration {
        Phase::After
    } else {
        Phase::During(t)
    }
}

/// A minimum-time move from `start` to `end` with a trapezoidal velocity
/// profile: accelerate at the limit, cruise at the velocity limit, decelerate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointToPoint {
    start: f64,
    end: f64,
    /// +1 or -1.
    direction: f64,
    acceleration: f64,
    /// Peak speed actually reached (<= the limit).
    peak_velocity: f64,
    /// Duration of the acceleration (and of the deceleration) phase.
    t_accel: f64,
    duration: f64,
}

impl PointToPoint {
    /// A move from `start` to `end` at no more than `max_velocity` and
    /// `max_acceleration` (both > 0).
    ///
    /// # Errors
    /// A parameter is not finite, or a limit is not > 0.
    pub fn new(
        start: f64,
        end: f64,
        max_velocity: f64,
        max_acceleration: f64,
    ) -> Result<PointToPoint, TrajectoryError> {
        finite("start", start)?;
        finite("end", end)?;
        let v = positive("max_velocity", max_velocity)?;
        let a = positive("max_acceleration", max_acceleration)?;
        let distance = (end - start).abs();
        finite("end - start", distance)?;
        let direction = if end >= start { 1.0 } else { -1.0 };
        let (t_accel, peak, duration) = if distance == 0.0 {
            (0.0, 0.0, 0.0)
        } else if distance <= v * v / a {
            // Triangular: the velocity limit is never reached.
            let ta = (distance / a).sqrt();
            (ta, a * ta, 2.0 * ta)
        } else {
            let ta = v / a;
            let cruise = (distance - v * ta) / v;
            (ta, v, 2.0 * ta + cruise)
        };
        if !duration.is_finite() {
            return Err(TrajectoryError::OutOfRange("duration"));
        }
        Ok(PointToPoint {
            start,
            end,
            direction,
            acceleration: a,
            peak_velocity: peak,
            t_accel,
            duration,
        })
    }

    /// Total time, seconds.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// Start position.
    pub fn start(&self) -> f64 {
        self.start
    }

    /// Final position.
    pub fn end(&self) -> f64 {
        self.end
    }

    /// Highest speed reached.
    pub fn peak_velocity(&self) -> f64 {
        self.peak_velocity
    }

    /// Whether the move is over at time `t`.
    pub fn is_done(&self, t: f64) -> bool {
        t >= self.duration
    }

    /// The setpoint at time `t` since the start.
    #[inline]
    pub fn sample(&self, t: f64) -> Sample {
        let t = match phase(t, self.duration) {
            Phase::Before => return Sample::at_rest(self.start),
            Phase::After => return Sample::at_rest(self.end),
            Phase::During(t) => t,
        };
        let (a, vp, ta, dir) = (
            self.acceleration,
            self.peak_velocity,
            self.t_accel,
            self.direction,
        );
        let (travel, speed, acc) = if t < ta {
            (0.5 * a * t * t, a * t, a)
        } else if t <= self.duration - ta {
            (0.5 * vp * ta + vp * (t - ta), vp, 0.0)
        } else {
            let tau = self.duration - t;
            let total = (self.end - self.start).abs();
            (total - 0.5 * a * tau * tau, a * tau, -a)
        };
        let lo = self.start.min(self.end);
        let hi = self.start.max(self.end);
        Sample {
            position: (self.start + dir * travel).max(lo).min(hi),
            velocity: dir * speed,
            acceleration: dir * acc,
        }
    }
}

/// Normalised quintic `s(u) = 10u³ - 15u⁴ + 6u⁵` on `[0, 1]` and its first
/// two derivatives with respect to `u`.
fn smoothstep5(u: f64) -> (f64, f64, f64) {
    let u2 = u * u;
    let u3 = u2 * u;
    let s = u3 * (10.0 - 15.0 * u + 6.0 * u2);
    let ds = 30.0 * u2 * (1.0 - u) * (1.0 - u);
    let dds = 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u);
    (s, ds, dds)
}

/// Peak of `ds/du` of [`smoothstep5`] (at `u = 1/2`).
const QUINTIC_PEAK_VELOCITY: f64 = 15.0 / 8.0;
/// Peak of `|d²s/du²|` of [`smoothstep5`] (at `u = 1/2 ± √3/6`): `10/√3`.
const QUINTIC_PEAK_ACCELERATION: f64 = 5.773_502_691_896_258;

/// A rest-to-rest quintic move: position, velocity and acceleration are
/// continuous, and velocity and acceleration are zero at both ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quintic {
    start: f64,
    end: f64,
    duration: f64,
}

impl Quintic {
    /// A move from `start` to `end` taking `duration` seconds (> 0, or 0 for
    /// a jump when `start == end`).
    ///
    /// # Errors
    /// A parameter is not finite, or the duration is negative, or zero for a
    /// move of non-zero length.
    pub fn new(start: f64, end: f64, duration: f64) -> Result<Quintic, TrajectoryError> {
        finite("start", start)?;
        finite("end", end)?;
        non_negative("duration", duration)?;
        finite("end - start", end - start)?;
        if duration == 0.0 && start != end {
            return Err(TrajectoryError::OutOfRange("duration"));
        }
        Ok(Quintic {
            start,
            end,
            duration,
        })
    }

    /// The shortest quintic from `start` to `end` whose speed and
    /// acceleration stay within the limits (both > 0).
    ///
    /// # Errors
    /// As [`Quintic::new`], or a limit is not > 0.
    pub fn with_limits(
        start: f64,
        end: f64,
        max_velocity: f64,
        max_acceleration: f64,
    ) -> Result<Quintic, TrajectoryError> {
        let v = positive("max_velocity", max_velocity)?;
        let a = positive("max_acceleration", max_acceleration)?;
        let d = (finite("end", end)? - finite("start", start)?).abs();
        let t_v = QUINTIC_PEAK_VELOCITY * d / v;
        let t_a = (QUINTIC_PEAK_ACCELERATION * d / a).sqrt();
        Quintic::new(start, end, t_v.max(t_a))
    }

    /// Total time, seconds.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// Final position.
    pub fn end(&self) -> f64 {
        self.end
    }

    /// Highest speed reached.
    pub fn peak_velocity(&self) -> f64 {
        if self.duration > 0.0 {
            QUINTIC_PEAK_VELOCITY * (self.end - self.start).abs() / self.duration
        } else {
            0.0
        }
    }

    /// Highest |acceleration| reached.
    pub fn peak_acceleration(&self) -> f64 {
        if self.duration > 0.0 {
            QUINTIC_PEAK_ACCELERATION * (self.end - self.start).abs()
                / (self.duration * self.duration)
        } else {
            0.0
        }
    }

    /// Whether the move is over at time `t`.
    pub fn is_done(&self, t: f64) -> bool {
        t >= self.duration
    }

    /// The setpoint at time `t` since the start.
    #[inline]
    pub fn sample(&self, t: f64) -> Sample {
        let t = match phase(t, self.duration) {
            Phase::Before => return Sample::at_rest(self.start),
            Phase::After => return Sample::at_rest(self.end),
            Phase::During(t) => t,
        };
        let d = self.end - self.start;
        let (s, ds, dds) = smoothstep5(t / self.duration);
        let lo = self.start.min(self.end);
        let hi = self.start.max(self.end);
        Sample {
            position: (self.start + d * s).max(lo).min(hi),
            velocity: d * ds / self.duration,
            acceleration: d * dds / (self.duration * self.duration),
        }
    }
}

/// `offset + amplitude · r(t) · sin(2π · frequency · t + phase)`, where the
/// ramp `r` rises smoothly (quintic, C²) from 0 to 1 over `ramp_time`. With a
/// ramp the motion starts at `offset` at rest; it never ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sinusoid {
    amplitude: f64,
    /// rad/s.
    omega: f64,
    phase: f64,
    offset: f64,
    ramp_time: f64,
}

impl Sinusoid {
    /// A sinusoid of `amplitude` (rad or m), `frequency` (Hz, >= 0), `phase`
    /// (rad) around `offset`, faded in over `ramp_time` seconds (>= 0; 0 starts
    /// at full amplitude, possibly with a jump).
    ///
    /// # Errors
    /// A parameter is not finite, or the frequency or ramp time is negative.
    pub fn new(
        amplitude: f64,
        frequency: f64,
        phase: f64,
        offset: f64,
        ramp_time: f64,
    ) -> Result<Sinusoid, TrajectoryError> {
        finite("amplitude", amplitude)?;
        non_negative("frequency", frequency)?;
        finite("phase", phase)?;
        finite("offset", offset)?;
        non_negative("ramp_time", ramp_time)?;
        let omega = 2.0 * PI * frequency;
        finite("frequency", omega * amplitude)?;
        Ok(Sinusoid {
            amplitude,
            omega,
            phase,
            offset,
            ramp_time,
        })
    }

    /// An upper bound of |velocity| over all time.
    pub fn peak_velocity(&self) -> f64 {
        let ramp = if self.ramp_time > 0.0 {
            QUINTIC_PEAK_VELOCITY / self.ramp_time
        } else {
            0.0
        };
        self.amplitude.abs() * (self.omega + ramp)
    }

    /// An upper bound of |acceleration| over all time.
    pub fn peak_acceleration(&self) -> f64 {
        let (r1, r2) = if self.ramp_time > 0.0 {
            (
                QUINTIC_PEAK_VELOCITY / self.ramp_time,
                QUINTIC_PEAK_ACCELERATION / (self.ramp_time * self.ramp_time),
            )
        } else {
            (0.0, 0.0)
        };
        self.amplitude.abs() * (r2 + 2.0 * r1 * self.omega + self.omega * self.omega)
    }

    /// The setpoint at time `t` since the start. Before the start (or for a
    /// NaN time) it holds the starting position at rest. (Inlined into
    /// [`Motion::sample`] and so into the servo cycle's loop over the
    /// joints: LLVM kept it a call per sinusoid joint and cycle.)
    #[inline(always)]
    pub fn sample(&self, t: f64) -> Sample {
        self.sample_by(t, libm::sincos)
    }

    /// [`sample`](Self::sample), the sine and cosine of its angle taken
    /// from `memo` (the same bits: see [`SinCosMemo`]).
    #[inline(always)]
    pub fn sample_memo(&self, t: f64, memo: &mut SinCosMemo) -> Sample {
        self.sample_by(t, |angle| memo.sincos(angle))
    }

    /// [`sample`](Self::sample) with `sincos` giving `libm::sincos` of the
    /// angle.
    #[inline(always)]
    fn sample_by(&self, t: f64, sincos: impl FnOnce(f64) -> (f64, f64)) -> Sample {
        let t = if t.is_nan() || t < 0.0 {
            return Sample::at_rest(self.position_at(0.0));
        } else if t == f64::INFINITY {
            // Past any ramp; the phase at infinity is meaningless, hold the
            // centre.
            return Sample::at_rest(self.offset);
        } else {
            t
        };
        let (r, dr, ddr) = if self.ramp_time > 0.0 && t < self.ramp_time {
            let (s, ds, dds) = smoothstep5(t / self.ramp_time);
            (
                s,
                ds / self.ramp_time,
                dds / (self.ramp_time * self.ramp_time),
            )
        } else {
            (1.0, 0.0, 0.0)
        };
        let angle = self.omega * t + self.phase;
        let (sin, cos) = sincos(angle);
        let a = self.amplitude;
        let w = self.omega;
        let s = Sample {
            position: self.offset + a * r * sin,
            velocity: a * (dr * sin + r * w * cos),
            acceleration: a * (ddr * sin + 2.0 * dr * w * cos - r * w * w * sin),
        };
        if s.position.is_finite() && s.velocity.is_finite() && s.acceleration.is_finite() {
            s
        } else {
            Sample::at_rest(self.offset)
        }
    }

    fn position_at(&self, t: f64) -> f64 {
        if self.ramp_time > 0.0 {
            self.offset
        } else {
            self.offset + self.amplitude * (self.omega * t + self.phase).sin()
        }
    }
}

/// Any motion the servo loop can follow.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Motion {
    /// Stay at a position.
    Hold(f64),
    /// Trapezoidal point-to-point move.
    PointToPoint(PointToPoint),
    /// Quintic point-to-point move.
    Quintic(Quintic),
    /// Endless sinusoid.
    Sinusoid(Sinusoid),
    /// A streamed servo point (CRTK `servo_jp`): the position moves on at
    /// `velocity` (fed forward to the controller) for at most `horizon`
    /// seconds, then holds, so a stream that stops leaves the joint still.
    Servo(ServoPoint),
}

/// One point of a servo stream: where the joint should be now, and how
/// fast it is moving there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoPoint {
    position: f64,
    velocity: f64,
    horizon: f64,
}

impl ServoPoint {
    /// A point at `position` moving at `velocity`, extrapolated for at most
    /// `horizon` seconds (> 0).
    ///
    /// # Errors
    /// A parameter that is not finite, or a horizon not above 0.
    pub fn new(position: f64, velocity: f64, horizon: f64) -> Result<ServoPoint, TrajectoryError> {
        finite("position", position)?;
        finite("velocity", velocity)?;
        if !(horizon.is_finite() && horizon > 0.0) {
            return Err(TrajectoryError::OutOfRange("horizon"));
        }
        Ok(ServoPoint {
            position,
            velocity,
            horizon,
        })
    }

    /// The setpoint `t` seconds after the point arrived.
    #[inline]
    pub fn sample(&self, t: f64) -> Sample {
        if t < self.horizon {
            Sample {
                position: self.position + self.velocity * t.max(0.0),
                velocity: self.velocity,
                acceleration: 0.0,
            }
        } else {
            Sample::at_rest(self.position + self.velocity * self.horizon)
        }
    }
}

/// How many angles a [`SinCosMemo`] keeps.
const SINCOS_KEPT: usize = 4;

/// The last few angles whose sine and cosine a pass over the joints'
/// setpoints computed, with both values. `libm::sincos` is a function of
/// its argument's bits alone, so an angle met again (the same bits: `0.0`
/// and `-0.0` are two angles) is given the very values computed for it
/// before, without computing them again: the dVRK demo's 14 sinusoids
/// share two frequencies, no phase and one start, two angles per cycle.
/// Allocation-free; the oldest angle kept gives way to a new one.
#[derive(Debug, Clone, Copy, Default)]
pub struct SinCosMemo {
    /// The kept angles' bits; the first `kept` are in use.
    angles: [u64; SINCOS_KEPT],
    /// `libm::sincos` of each kept angle.
    values: [(f64, f64); SINCOS_KEPT],
    kept: usize,
    /// The slot the next new angle takes.
    next: usize,
}

impl SinCosMemo {
    /// `libm::sincos(angle)`, bit for bit: the kept values when `angle`'s
    /// bits are kept, else computed and kept.
    #[inline(always)]
    pub fn sincos(&mut self, angle: f64) -> (f64, f64) {
        let bits = angle.to_bits();
        let kept = self.angles.iter().zip(&self.values).take(self.kept);
        for (&a, &v) in kept {
            if a == bits {
                return v;
            }
        }
        let v = libm::sincos(angle);
        let slot = self.next % SINCOS_KEPT;
        if let (Some(a), Some(kept)) = (self.angles.get_mut(slot), self.values.get_mut(slot)) {
            *a = bits;
            *kept = v;
        }
        self.next = (slot + 1) % SINCOS_KEPT;
        self.kept = (self.kept + 1).min(SINCOS_KEPT);
        v
    }
}

impl Motion {
    /// The setpoint at time `t` since the motion started. (Inlined into
    /// the servo cycle's loop over the joints: a call per joint and cycle
    /// cost more than a hold's or a finished move's sample.)
    #[inline(always)]
    pub fn sample(&self, t: f64) -> Sample {
        match self {
            Motion::Hold(p) => Sample::at_rest(*p),
            Motion::PointToPoint(m) => m.sample(t),
            Motion::Quintic(m) => m.sample(t),
            Motion::Sinusoid(m) => m.sample(t),
            Motion::Servo(m) => m.sample(t),
        }
    }

    /// [`sample`](Self::sample), the same bits, a sinusoid's sine and
    /// cosine taken from `memo` (the servo cycle passes one memo over all
    /// its joints: sinusoids at the same angle compute it once).
    #[inline(always)]
    pub fn sample_memo(&self, t: f64, memo: &mut SinCosMemo) -> Sample {
        match self {
            Motion::Sinusoid(m) => m.sample_memo(t, memo),
            other => other.sample(t),
        }
    }

    /// Whether the motion has reached its end at `t` (holding is always
    /// done; a sinusoid never is).
    pub fn is_done(&self, t: f64) -> bool {
        match self {
            Motion::Hold(_) => true,
            Motion::PointToPoint(m) => m.is_done(t),
            Motion::Quintic(m) => m.is_done(t),
            Motion::Sinusoid(_) => false,
            Motion::Servo(m) => t >= m.horizon,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_servo_point_moves_on_then_holds() {
        let p = ServoPoint::new(1.0, 2.0, 0.05).unwrap();
        assert_eq!(p.sample(0.0).position, 1.0);
        assert!((p.sample(0.01).position - 1.02).abs() < 1e-12);
        assert_eq!(p.sample(0.01).velocity, 2.0);
        let after = Motion::Servo(p).sample(1.0);
        assert!((after.position - 1.1).abs() < 1e-12);
        assert_eq!(after.velocity, 0.0);
        assert!(Motion::Servo(p).is_done(0.05) && !Motion::Servo(p).is_done(0.04));
        assert!(ServoPoint::new(f64::NAN, 0.0, 0.05).is_err());
        assert!(ServoPoint::new(0.0, 0.0, 0.0).is_err());
    }

    fn check_profile(
        samples: impl Fn(f64) -> Sample,
        duration: f64,
        vmax: f64,
        amax: f64,
        start: f64,
        end: f64,
    ) -> Result<(), TestCaseError> {
        let n = 2000;
        let lo = start.min(end);
        let hi = start.max(end);
        let mut prev = samples(0.0);
        prop_assert_eq!(prev.position, start);
        let tol = 1e-9 * (1.0 + vmax + amax);
        for k in 1..=n {
            let t = duration * k as f64 / n as f64;
            let s = samples(t);
            prop_assert!(
                s.velocity.abs() <= vmax * (1.0 + 1e-9) + tol,
                "v {} > {}",
                s.velocity,
                vmax
            );
            prop_assert!(s.acceleration.abs() <= amax * (1.0 + 1e-9) + tol);
            prop_assert!(lo <= s.position && s.position <= hi);
            // Monotone towards the end.
            prop_assert!((s.position - prev.position) * (end - start) >= -tol);
            prev = s;
        }
        let last = samples(duration);
        prop_assert_eq!(last.position, end);
        prop_assert_eq!(last.velocity, 0.0);
        prop_assert_eq!(samples(duration * 2.0 + 1.0).position, end);
        Ok(())
    }

    #[test]
    fn trapezoid_shapes() {
        // Long move: cruises at the limit.
        let m = PointToPoint::new(0.0, 10.0, 2.0, 4.0).unwrap();
        assert!((m.duration() - (0.5 + 0.5 + 4.5)).abs() < 1e-12);
        assert_eq!(m.peak_velocity(), 2.0);
        assert!((m.sample(2.75).velocity - 2.0).abs() < 1e-12);
        assert!((m.sample(2.75).position - 5.0).abs() < 1e-12);
        // Short move: triangular.
        let m = PointToPoint::new(1.0, 0.0, 2.0, 4.0).unwrap();
        assert!((m.duration() - 1.0).abs() < 1e-12);
        assert!((m.peak_velocity() - 2.0).abs() < 1e-12);
        assert!((m.sample(0.5).position - 0.5).abs() < 1e-12);
        assert!(m.sample(0.25).velocity < 0.0);
        assert!(!m.is_done(0.99) && m.is_done(1.0));
        // Zero-length move is done at once.
        let m = PointToPoint::new(0.3, 0.3, 1.0, 1.0).unwrap();
        assert_eq!(m.duration(), 0.0);
        assert!(m.is_done(0.0));
        assert_eq!(m.sample(5.0), Sample::at_rest(0.3));
    }

    #[test]
    fn quintic_shapes() {
        let q = Quintic::new(0.0, 2.0, 1.0).unwrap();
        let mid = q.sample(0.5);
        assert!((mid.position - 1.0).abs() < 1e-12);
        assert!((mid.velocity - q.peak_velocity()).abs() < 1e-12);
        assert!((q.peak_velocity() - 3.75).abs() < 1e-12);
        let q = Quintic::with_limits(0.0, 1.0, 0.5, 100.0).unwrap();
        assert!((q.peak_velocity() - 0.5).abs() < 1e-12);
        let q = Quintic::with_limits(0.0, 1.0, 100.0, 2.0).unwrap();
        assert!((q.peak_acceleration() - 2.0).abs() < 1e-9);
        assert!(Quintic::new(0.0, 1.0, 0.0).is_err());
        assert!(Quintic::new(1.0, 1.0, 0.0).unwrap().is_done(0.0));
    }

    #[test]
    fn sinusoid_ramps_in_smoothly() {
        let s = Sinusoid::new(0.5, 2.0, 1.0, 0.1, 0.5).unwrap();
        let s0 = s.sample(0.0);
        assert_eq!(s0, Sample::at_rest(0.1));
        assert_eq!(s.sample(-1.0), Sample::at_rest(0.1));
        assert_eq!(s.sample(f64::NAN), Sample::at_rest(0.1));
        // After the ramp: the plain sinusoid.
        let t = 1.3;
        let want = 0.1 + 0.5 * (2.0 * PI * 2.0 * t + 1.0).sin();
        assert!((s.sample(t).position - want).abs() < 1e-12);
        // Velocity and acceleration match numerical derivatives, and stay
        // under the stated bounds.
        let h = 1e-6;
        let mut t = 0.0;
        while t < 2.0 {
            let a = s.sample(t);
            let b = s.sample(t + h);
            assert!(((b.position - a.position) / h - a.velocity).abs() < 1e-3);
            assert!(((b.velocity - a.velocity) / h - a.acceleration).abs() < 1e-1);
            assert!(a.velocity.abs() <= s.peak_velocity());
            assert!(a.acceleration.abs() <= s.peak_acceleration());
            t += 0.0137;
        }
        // Continuity at the end of the ramp.
        let before = s.sample(0.5 - 1e-9);
        let after = s.sample(0.5 + 1e-9);
        assert!((before.acceleration - after.acceleration).abs() < 1e-4);
        assert!(Sinusoid::new(1.0, -1.0, 0.0, 0.0, 0.0).is_err());
        assert!(Sinusoid::new(f64::NAN, 1.0, 0.0, 0.0, 0.0).is_err());
    }

    #[test]
    fn bad_parameters_are_refused() {
        assert_eq!(
            PointToPoint::new(f64::NAN, 1.0, 1.0, 1.0),
            Err(TrajectoryError::NotFinite("start"))
        );
        assert_eq!(
            PointToPoint::new(0.0, 1.0, 0.0, 1.0),
            Err(TrajectoryError::OutOfRange("max_velocity"))
        );
        assert_eq!(
            PointToPoint::new(-f64::MAX, f64::MAX, 1.0, 1.0),
            Err(TrajectoryError::NotFinite("end - start"))
        );
        assert!(PointToPoint::new(0.0, 1.0, 1.0, f64::INFINITY).is_err());
    }

    #[test]
    fn odd_times_are_safe() {
        let m = Motion::PointToPoint(PointToPoint::new(0.0, 1.0, 1.0, 1.0).unwrap());
        assert_eq!(m.sample(f64::NAN), Sample::at_rest(0.0));
        assert_eq!(m.sample(f64::NEG_INFINITY), Sample::at_rest(0.0));
        assert_eq!(m.sample(f64::INFINITY), Sample::at_rest(1.0));
        assert!(m.is_done(f64::INFINITY) && !m.is_done(f64::NAN));
        let q = Motion::Quintic(Quintic::new(0.0, 1.0, 1.0).unwrap());
        assert_eq!(q.sample(f64::NAN), Sample::at_rest(0.0));
        let s = Motion::Sinusoid(Sinusoid::new(1.0, 1.0, 0.0, 0.0, 1.0).unwrap());
        assert_eq!(s.sample(f64::INFINITY), Sample::at_rest(0.0));
        assert!(!s.is_done(1e9));
        assert!(Motion::Hold(2.0).is_done(0.0));
    }

    /// The bits of `libm::sincos`'s two values.
    fn sincos_bits(angle: f64) -> (u64, u64) {
        let (s, c) = libm::sincos(angle);
        (s.to_bits(), c.to_bits())
    }

    /// A memo gives `libm::sincos`'s bits for every angle: new, met again
    /// while kept, met again after it gave way to newer ones, 0 and -0,
    /// NaN and the infinities.
    #[test]
    fn a_sincos_memo_gives_libm_bits() {
        let angles = [
            0.0,
            -0.0,
            1.0,
            1.0,
            0.0,
            2.5e6,
            -3.0,
            f64::NAN,
            1.0,
            f64::INFINITY,
            -0.0,
            7.0,
            8.0,
            9.0,
            10.0,
            2.5e6,
            f64::NEG_INFINITY,
            -3.0,
            7.0,
            7.0,
        ];
        let mut memo = SinCosMemo::default();
        for a in angles {
            let (s, c) = memo.sincos(a);
            assert_eq!((s.to_bits(), c.to_bits()), sincos_bits(a), "angle {a:?}");
        }
    }

    /// Sinusoids sampled through one memo, some at the same angle, give
    /// the bits of sampling each alone; the other motions pass through.
    #[test]
    fn sampling_through_a_memo_gives_the_same_bits() {
        let motions = [
            Motion::Sinusoid(Sinusoid::new(0.1, 0.4, 0.0, 1.0, 0.5).unwrap()),
            Motion::PointToPoint(PointToPoint::new(0.0, 1.0, 1.0, 3.0).unwrap()),
            Motion::Sinusoid(Sinusoid::new(0.2, 0.4, 0.0, -1.0, 0.5).unwrap()),
            Motion::Sinusoid(Sinusoid::new(0.3, 0.6, 0.0, 0.0, 0.0).unwrap()),
            Motion::Quintic(Quintic::with_limits(1.0, 0.0, 1.0, 3.0).unwrap()),
            Motion::Sinusoid(Sinusoid::new(0.4, 0.4, 0.2, 0.0, 0.5).unwrap()),
            Motion::Sinusoid(Sinusoid::new(0.5, 0.6, 0.0, 2.0, 0.0).unwrap()),
            Motion::Hold(3.0),
            Motion::Sinusoid(Sinusoid::new(0.6, 0.8, 0.0, 0.0, 0.5).unwrap()),
            Motion::Sinusoid(Sinusoid::new(0.7, 1.0, 0.0, 0.0, 0.5).unwrap()),
            Motion::Sinusoid(Sinusoid::new(0.8, 1.2, 0.0, 0.0, 0.5).unwrap()),
            Motion::Sinusoid(Sinusoid::new(0.9, 0.4, 0.0, 0.0, 0.5).unwrap()),
        ];
        let bits = |s: Sample| {
            (
                s.position.to_bits(),
                s.velocity.to_bits(),
                s.acceleration.to_bits(),
            )
        };
        for t in [-1.0, 0.0, 0.1, 0.25, 0.7, 3.3, 1e7, f64::NAN, f64::INFINITY] {
            let mut memo = SinCosMemo::default();
            for m in &motions {
                let through = m.sample_memo(t, &mut memo);
                assert_eq!(bits(through), bits(m.sample(t)), "{m:?} at {t}");
            }
        }
    }

    proptest! {
        #[test]
        fn trapezoid_respects_limits_and_ends_exactly(
            start in -10.0..10.0f64, end in -10.0..10.0f64,
            vmax in 0.01..10.0f64, amax in 0.01..100.0f64,
        ) {
            let m = PointToPoint::new(start, end, vmax, amax).unwrap();
            prop_assert!(m.duration().is_finite());
            check_profile(|t| m.sample(t), m.duration(), vmax, amax, start, end)?;
            prop_assert!(m.is_done(m.duration()));
        }

        #[test]
        fn quintic_respects_limits_and_ends_exactly(
            start in -10.0..10.0f64, end in -10.0..10.0f64,
            vmax in 0.01..10.0f64, amax in 0.01..100.0f64,
        ) {
            let q = Quintic::with_limits(start, end, vmax, amax).unwrap();
            check_profile(|t| q.sample(t), q.duration(), vmax, amax, start, end)?;
        }

        #[test]
        fn sampling_any_time_is_finite(t in any::<f64>(), amp in -5.0..5.0f64, f in 0.0..50.0f64) {
            let motions = [
                Motion::PointToPoint(PointToPoint::new(0.0, amp, 1.0, 3.0).unwrap()),
                Motion::Quintic(Quintic::with_limits(amp, 0.0, 1.0, 3.0).unwrap()),
                Motion::Sinusoid(Sinusoid::new(amp, f, 0.3, 1.0, 0.2).unwrap()),
            ];
            for m in motions {
                let s = m.sample(t);
                prop_assert!(s.position.is_finite() && s.velocity.is_finite() && s.acceleration.is_finite());
            }
        }
    }
}
