//! The per-cycle safety monitor.
//!
//! Each cycle, after the controllers ran and before the outputs are
//! written, the runner hands the monitor one [`JointSample`] per joint. The
//! monitor checks, joint by joint in configuration order and in this order
//! per joint:
//!
//! 1. every value is finite ([`FaultKind::InvalidValue`]);
//! 2. position within the soft limits widened by `position_margin`, if set
//!    ([`FaultKind::PositionLimit`]);
//! 3. |velocity| <= the velocity limit ([`FaultKind::Velocity`]);
//! 4. |setpoint - position| <= the following-error limit, or over it for no
//!    longer than the grace period ([`FaultKind::FollowingError`]);
//! 5. |current command| below `maximum_current`, or at it for no longer than
//!    the saturation time ([`FaultKind::CurrentSaturation`]);
//! 6. pot and encoder within the v6 tolerance `distance`, or apart for no
//!    longer than its `latency` ([`FaultKind::PotentiometerMismatch`]).
//!
//! and returns the first fault found, so the report is deterministic. Once
//! tripped the monitor latches: it returns the same report until
//! [`SafetyMonitor::reset`]. Buffers are allocated at construction;
//! [`SafetyMonitor::check`] never allocates.

use crate::config::IoConfig;
use crate::fault::{FaultKind, FaultReport};
use crate::label::Label;

/// Limits of one joint. `None` disables a check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Name for reports.
    pub label: Label,
    /// Largest |velocity|.
    pub velocity: Option<f64>,
    /// Largest |setpoint - position|.
    pub following_error: Option<f64>,
    /// How long the following error may be over its limit, seconds.
    pub following_error_grace: f64,
    /// The drive's maximum current, A (a command at or above it counts as
    /// saturated).
    pub maximum_current: f64,
    /// How long the current may stay saturated, seconds.
    pub saturation_time: Option<f64>,
    /// Soft position limits and the margin past them that trips a fault.
    pub position: Option<(f64, f64, f64)>,
    /// Pot/encoder tolerance (distance, latency).
    pub potentiometer: Option<(f64, f64)>,
}

impl JointLimits {
    /// Only the finiteness check.
    pub fn unchecked(label: Label) -> JointLimits {
        JointLimits {
            label,
            velocity: None,
            following_error: None,
            following_error_grace: 0.0,
            maximum_current: f64::INFINITY,
            saturation_time: None,
            position: None,
            potentiometer: None,
        }
    }
}

/// One joint's values this cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointSample {
    /// Commanded position.
    pub setpoint: f64,
    /// Measured (encoder) position.
    pub position: f64,
    /// Measured velocity.
    pub velocity: f64,
    /// Current command about to be written, A.
    pub current: f64,
    /// Pot-derived position, if the joint has a pot and it was read
    /// (NaN here is reported as an invalid value).
    pub potentiometer: Option<f64>,
}

impl JointSample {
    /// Whether every value is finite (a missing pot counts as finite),
    /// all at once: `x * 0` is ±0 for a finite `x` and NaN otherwise, and
    /// NaN spreads.
    #[inline]
    fn all_finite(&self) -> bool {
        let pot = self.potentiometer.unwrap_or(0.0);
        let probe = (self.setpoint * 0.0 + self.position * 0.0)
            + (self.velocity * 0.0 + self.current * 0.0)
            + pot * 0.0;
        probe == 0.0
    }
}

/// Running timers of one joint: when each condition started.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Timers {
    following_since: Option<f64>,
    saturated_since: Option<f64>,
    pot_since: Option<f64>,
}

impl Timers {
    /// No condition is being timed.
    #[inline]
    fn idle(&self) -> bool {
        self.following_since.is_none() & self.saturated_since.is_none() & self.pot_since.is_none()
    }
}

/// The safety monitor for a set of joints.
#[derive(Debug, Clone, PartialEq)]
pub struct SafetyMonitor {
    limits: Vec<JointLimits>,
    /// The limits as the cycle compares with them, per joint.
    bounds: Vec<Bounds>,
    /// `bounds` with every infinite bound made the largest finite one
    /// ([`Bounds::finite_only`]), per joint: the quiet pass's, a sample
    /// inside them is finite.
    quiet_bounds: Vec<Bounds>,
    timers: Vec<Timers>,
    /// Per joint: following-error and saturation checks suspended (a
    /// stop search pushes a joint into its stop on purpose).
    stalling: Vec<bool>,
    /// Whether any joint may stall (the common case, none, costs nothing).
    any_stalling: bool,
    /// Whether a timer may be running: false only when every joint's
    /// timers are idle (set when a joint-by-joint check may start one,
    /// found again after every joint-by-joint pass that ends without a
    /// fault, cleared with the timers), so that the quiet pass of the
    /// common cycle need not look at them.
    timing: bool,
    latched: Option<FaultReport>,
}

/// What a joint's sample is compared with, worked out from its
/// [`JointLimits`] once: a check that is off compares with an infinite
/// bound (the sample is finite by then).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bounds {
    /// The soft limits widened by the margin.
    lowest: f64,
    highest: f64,
    /// Largest |velocity|.
    velocity: f64,
    /// Largest |setpoint - position| that starts no following-error timer.
    following: f64,
    /// |current| from which the saturation timer runs.
    saturated_from: f64,
    /// Largest |pot - position| that starts no pot timer.
    pot: f64,
}

impl Bounds {
    fn of(l: &JointLimits) -> Bounds {
        let (lowest, highest) = l.position.map_or(
            (f64::NEG_INFINITY, f64::INFINITY),
            |(lower, upper, margin)| (lower - margin, upper + margin),
        );
        Bounds {
            lowest,
            highest,
            velocity: l.velocity.unwrap_or(f64::INFINITY),
            following: l.following_error.unwrap_or(f64::INFINITY),
            saturated_from: match l.saturation_time {
                Some(_) => l.maximum_current - SATURATION_SLACK,
                None => f64::INFINITY,
            },
            pot: l
                .potentiometer
                .map_or(f64::INFINITY, |(tolerance, _)| tolerance),
        }
    }

    /// The bounds of the quiet pass: these with an infinite bound (a check
    /// that is off) made the largest finite value, the others as they are
    /// (`saturated_from` too). A sample inside them
    /// ([`all_clear`](Self::all_clear)) is finite: a position between
    /// bounds no wider than the finite range, a velocity, a following
    /// error and a pot offset at most a finite bound are finite, and so
    /// the setpoint and the pot; the strict `<` of the current is false
    /// for an infinite or NaN current whatever its bound. A finite sample
    /// inside them is inside `self` (they are no wider), so the quiet pass
    /// needs no finiteness test of its own: a sample they leave out (not
    /// finite, or a following error or pot offset too large for an `f64`)
    /// goes to the joint-by-joint checks, which decide as before.
    fn finite_only(&self) -> Bounds {
        let at_most = |x: f64| if x == f64::INFINITY { f64::MAX } else { x };
        Bounds {
            lowest: if self.lowest == f64::NEG_INFINITY {
                f64::MIN
            } else {
                self.lowest
            },
            highest: at_most(self.highest),
            velocity: at_most(self.velocity),
            following: at_most(self.following),
            saturated_from: self.saturated_from,
            pot: at_most(self.pot),
        }
    }

    /// Whether sample `s` is inside every bound: for a finite sample, no
    /// check of a joint that is not stalling can fire and none of its
    /// timers starts. (The common case, tested without branches on each
    /// check; anything else takes the checks one by one.)
    #[inline]
    fn all_clear(&self, s: &JointSample) -> bool {
        let pot_off = s.potentiometer.map_or(0.0, |p| (p - s.position).abs());
        (self.lowest <= s.position)
            & (s.position <= self.highest)
            & (s.velocity.abs() <= self.velocity)
            & ((s.setpoint - s.position).abs() <= self.following)
            & (s.current.abs() < self.saturated_from)
            & (pot_off <= self.pot)
    }
}

/// Tolerance for "at the maximum current" (commands are clamped to exactly
/// the maximum, so compare with a tiny slack).
const SATURATION_SLACK: f64 = 1e-9;

impl SafetyMonitor {
    /// A monitor for joints with `limits`, in the order samples will come.
    pub fn new(limits: Vec<JointLimits>) -> SafetyMonitor {
        let timers = vec![Timers::default(); limits.len()];
        let stalling = vec![false; limits.len()];
        let bounds: Vec<Bounds> = limits.iter().map(Bounds::of).collect();
        let quiet_bounds = bounds.iter().map(Bounds::finite_only).collect();
        SafetyMonitor {
            limits,
            bounds,
            quiet_bounds,
            timers,
            stalling,
            any_stalling: false,
            timing: false,
            latched: None,
        }
    }

    /// A monitor for every actuator of `config`, in joint order: limits
    /// from the actuator's `limits` section, `drive.maximum_current`,
    /// `encoder.position_limits_soft` and the robot's v6 pot tolerances
    /// (a `distance` of 0 disables that check, as in sawRobotIO1394).
    pub fn from_config(config: &IoConfig) -> SafetyMonitor {
        let limits = config
            .joints()
            .map(|j| {
                let a = j.actuator;
                let l = a.limits;
                let soft = a.encoder.position_limits_soft;
                JointLimits {
                    label: j.label,
                    velocity: l.map(|l| l.velocity),
                    following_error: l.map(|l| l.following_error),
                    following_error_grace: l.map_or(0.0, |l| l.following_error_grace),
                    maximum_current: a.drive.maximum_current,
                    saturation_time: l.map(|l| l.saturation_time),
                    position: l
                        .and_then(|l| l.position_margin)
                        .map(|m| (soft.lower, soft.upper, m)),
                    potentiometer: match (a.potentiometer, j.potentiometer_tolerance()) {
                        (Some(_), Some(t)) if t.distance > 0.0 => Some((t.distance, t.latency)),
                        _ => None,
                    },
                }
            })
            .collect();
        SafetyMonitor::new(limits)
    }

    /// The joints' limits.
    pub fn limits(&self) -> &[JointLimits] {
        &self.limits
    }

    /// The latched fault, if tripped.
    pub fn tripped(&self) -> Option<&FaultReport> {
        self.latched.as_ref()
    }

    /// Clears the latch and every timer (after the fault was handled).
    pub fn reset(&mut self) {
        self.latched = None;
        self.timers.fill(Timers::default());
        self.timing = false;
    }

    /// Restarts the grace timers without clearing a latched fault (call when
    /// a new motion starts or the robot is activated).
    pub fn restart_timers(&mut self) {
        self.timers.fill(Timers::default());
        self.timing = false;
    }

    /// Lets joint `joint` stall on purpose, or stops letting it: while
    /// allowed, its position-limit, following-error and current-saturation
    /// checks are off (every other check stays). A stop search needs it: it
    /// drives the joint past its soft limit into a mechanical stop until
    /// the following error is large (the dVRK console likewise stops
    /// enforcing position limits and tracking errors then). Out-of-range
    /// joints are ignored.
    pub fn allow_stall(&mut self, joint: usize, allowed: bool) {
        if let Some(s) = self.stalling.get_mut(joint) {
            *s = allowed;
        }
        self.any_stalling = self.stalling.iter().any(|&s| s);
        if let Some(t) = self.timers.get_mut(joint) {
            *t = Timers::default();
        }
    }

    /// Checks one cycle at time `now` (seconds) and cycle number `cycle`;
    /// `samples[i]` is joint *i*. Returns the first fault, or the latched one.
    /// A sample list of the wrong length is checked as far as it goes and the
    /// missing joints are reported as invalid.
    pub fn check(&mut self, now: f64, cycle: u64, samples: &[JointSample]) -> Option<FaultReport> {
        if let Some(r) = self.latched {
            return Some(r);
        }
        let found = self.first_fault(now, samples);
        self.latched = found.map(|kind| FaultReport::new(now, cycle, kind));
        self.latched
    }

    /// How many joints from the first are quiet: their samples inside
    /// every bound of `quiet_bounds` ([`Bounds::all_clear`], tested
    /// without a branch per check; finite, then, with no test of its own:
    /// [`Bounds::finite_only`]) with no timer running (not tested while no timer can
    /// be: `timing` false); 0 if a joint may stall or the
    /// samples are not one per joint. The joint-by-joint checks of a quiet
    /// joint find nothing and change nothing, so they start after these
    /// (in the common cycle, every joint: no check at all).
    #[inline]
    fn quiet_joints(&self, samples: &[JointSample]) -> usize {
        if self.any_stalling
            || samples.len() != self.quiet_bounds.len()
            || samples.len() != self.timers.len()
        {
            return 0;
        }
        if !self.timing {
            // No timer runs: the samples alone decide.
            let joints = self.quiet_bounds.iter().zip(samples);
            return joints.take_while(|(b, s)| b.all_clear(s)).count();
        }
        let joints = self.quiet_bounds.iter().zip(&self.timers).zip(samples);
        joints
            .take_while(|((b, t), s)| t.idle() && b.all_clear(s))
            .count()
    }

    fn first_fault(&mut self, now: f64, samples: &[JointSample]) -> Option<FaultKind> {
        // Time must be usable for the duration checks.
        let now_ok = now.is_finite();
        // The joints before the first that is not quiet need no check.
        let quiet = if now_ok {
            self.quiet_joints(samples)
        } else {
            0
        };
        if quiet == samples.len() && quiet == self.limits.len() {
            return None;
        }
        // Whether a timer runs after this cycle's checks: the quiet joints'
        // do not, a joint's checked below may (a fault latches the monitor
        // with `timing` left set).
        let mut running = false;
        let joints = self.limits.iter().zip(&self.bounds);
        let joints = joints.zip(self.timers.iter_mut()).enumerate().skip(quiet);
        for (i, ((lim, b), timers)) in joints {
            // (The label is copied into a fault only.)
            let joint = &lim.label;
            let stalling = self.any_stalling && self.stalling.get(i).copied().unwrap_or(false);
            let Some(s) = samples.get(i) else {
                return Some(FaultKind::InvalidValue {
                    joint: *joint,
                    what: "sample (missing)",
                });
            };
            let invalid = |what| {
                Some(FaultKind::InvalidValue {
                    joint: *joint,
                    what,
                })
            };
            let pot = s.potentiometer.unwrap_or(0.0);
            // Which value is not finite, only if one is not.
            if !s.all_finite() {
                for (what, v) in [
                    ("setpoint", s.setpoint),
                    ("position", s.position),
                    ("velocity", s.velocity),
                    ("current command", s.current),
                    ("potentiometer", pot),
                ] {
                    if !v.is_finite() {
                        return invalid(what);
                    }
                }
            }
            if !now_ok {
                return invalid("time");
            }
            // Inside every bound with no timer running: nothing below can
            // fire or change.
            if !stalling && timers.idle() && b.all_clear(s) {
                continue;
            }
            // The checks below may start a timer.
            self.timing = true;
            // (Off: infinite bounds, never out of them.)
            let within = b.lowest <= s.position && s.position <= b.highest;
            if !stalling && !within {
                if let Some((lower, upper, _)) = lim.position {
                    return Some(FaultKind::PositionLimit {
                        joint: *joint,
                        position: s.position,
                        lower,
                        upper,
                    });
                }
            }
            if s.velocity.abs() > b.velocity {
                return Some(FaultKind::Velocity {
                    joint: *joint,
                    velocity: s.velocity,
                    limit: b.velocity,
                });
            }
            if let Some(limit) = lim.following_error.filter(|_| !stalling) {
                let error = s.setpoint - s.position;
                if lasting(
                    &mut timers.following_since,
                    error.abs() > limit,
                    now,
                    lim.following_error_grace,
                )
                .is_some()
                {
                    return Some(FaultKind::FollowingError {
                        joint: *joint,
                        error,
                        limit,
                    });
                }
            }
            if let Some(limit) = lim.saturation_time.filter(|_| !stalling) {
                let saturated = s.current.abs() >= lim.maximum_current - SATURATION_SLACK;
                if let Some(duration) = lasting(&mut timers.saturated_since, saturated, now, limit)
                {
                    return Some(FaultKind::CurrentSaturation {
                        joint: *joint,
                        duration,
                        limit,
                    });
                }
            }
            if let (Some((tolerance, latency)), Some(pot)) = (lim.potentiometer, s.potentiometer) {
                let difference = pot - s.position;
                if lasting(
                    &mut timers.pot_since,
                    difference.abs() > tolerance,
                    now,
                    latency,
                )
                .is_some()
                {
                    return Some(FaultKind::PotentiometerMismatch {
                        joint: *joint,
                        difference,
                        tolerance,
                    });
                }
            }
            running |= !timers.idle();
        }
        self.timing = running;
        if samples.len() > self.limits.len() {
            // More samples than joints: a wiring mistake in the runner.
            let joint = Label::new("(extra joint)");
            return Some(FaultKind::InvalidValue {
                joint,
                what: "sample (unexpected)",
            });
        }
        None
    }
}

/// Tracks how long `condition` has held. Returns how long it has lasted when
/// that exceeds `allowed` seconds (so a 0 s allowance trips on the first
/// cycle the condition is seen).
#[inline]
fn lasting(since: &mut Option<f64>, condition: bool, now: f64, allowed: f64) -> Option<f64> {
    if !condition {
        *since = None;
        return None;
    }
    let start = *since.get_or_insert(now);
    let duration = now - start;
    if duration > allowed || (allowed <= 0.0 && duration >= 0.0) {
        Some(duration)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> JointLimits {
        JointLimits {
            label: Label::new("PSM2[4]"),
            velocity: Some(2.0),
            following_error: Some(0.1),
            // Durations end in 0.5 ms so that 1 ms cycles never tie with them.
            following_error_grace: 0.0505,
            maximum_current: 1.0,
            saturation_time: Some(0.2005),
            position: Some((-1.0, 1.0, 0.1)),
            potentiometer: Some((0.05, 0.0105)),
        }
    }

    /// [`limits`] with every check switched off.
    fn every_check_off() -> JointLimits {
        JointLimits {
            velocity: None,
            following_error: None,
            saturation_time: None,
            position: None,
            potentiometer: None,
            ..limits()
        }
    }

    fn ok() -> JointSample {
        JointSample {
            setpoint: 0.1,
            position: 0.1,
            velocity: 0.0,
            current: 0.0,
            potentiometer: Some(0.1),
        }
    }

    fn run(m: &mut SafetyMonitor, from: u64, to: u64, s: JointSample) -> Option<FaultReport> {
        for k in from..to {
            if let Some(r) = m.check(k as f64 * 1e-3, k, &[s]) {
                return Some(r);
            }
        }
        None
    }

    #[test]
    fn quiet_joint_never_trips() {
        let mut m = SafetyMonitor::new(vec![limits()]);
        assert_eq!(run(&mut m, 0, 1000, ok()), None);
    }

    /// A sample with an infinite value is invalid, with every bound
    /// finite (the bounds alone rule it out) or with every bound off
    /// (infinite: the quiet pass must test the sample's finiteness).
    #[test]
    fn an_infinite_value_is_invalid_with_or_without_bounds() {
        let off = every_check_off();
        let samples = [
            (
                "velocity",
                JointSample {
                    velocity: f64::INFINITY,
                    ..ok()
                },
            ),
            (
                "position",
                JointSample {
                    position: f64::NEG_INFINITY,
                    ..ok()
                },
            ),
            (
                "setpoint",
                JointSample {
                    setpoint: f64::INFINITY,
                    ..ok()
                },
            ),
            (
                "potentiometer",
                JointSample {
                    potentiometer: Some(f64::INFINITY),
                    ..ok()
                },
            ),
            (
                "position",
                JointSample {
                    position: f64::INFINITY,
                    ..ok()
                },
            ),
            (
                "setpoint",
                JointSample {
                    setpoint: f64::NEG_INFINITY,
                    ..ok()
                },
            ),
            (
                "velocity",
                JointSample {
                    velocity: f64::NAN,
                    ..ok()
                },
            ),
            (
                "current command",
                JointSample {
                    current: f64::NEG_INFINITY,
                    ..ok()
                },
            ),
            (
                "potentiometer",
                JointSample {
                    potentiometer: Some(f64::NAN),
                    ..ok()
                },
            ),
        ];
        for l in [limits(), off] {
            for (what, s) in samples {
                let mut m = SafetyMonitor::new(vec![l]);
                let r = m.check(0.0, 0, &[s]).map(|r| r.kind);
                let fault = match r {
                    Some(FaultKind::InvalidValue { what, .. }) => Some(what),
                    _ => None,
                };
                assert_eq!(fault, Some(what), "{l:?} {s:?}: {r:?}");
            }
        }
    }

    /// Finite values at the ends of the `f64` range, every check off: no
    /// fault, though the following error and the pot offset are too large
    /// for an `f64` (infinite; the quiet pass leaves such a sample to the
    /// checks one by one, which find nothing).
    #[test]
    fn extreme_finite_values_are_valid_with_every_check_off() {
        let off = every_check_off();
        let extreme = JointSample {
            setpoint: f64::MAX,
            position: f64::MIN,
            velocity: f64::MAX,
            current: f64::MIN,
            potentiometer: Some(f64::MAX),
        };
        let mut m = SafetyMonitor::new(vec![off, off]);
        for k in 0..3 {
            assert_eq!(m.check(k as f64, k, &[extreme, ok()]), None);
            assert_eq!(m.check(k as f64, k, &[ok(), extreme]), None);
        }
    }

    #[test]
    fn following_error_after_grace() {
        let mut m = SafetyMonitor::new(vec![limits()]);
        let bad = JointSample {
            setpoint: 0.3,
            potentiometer: None,
            ..ok()
        };
        // A short excursion (40 ms) is forgiven and resets the timer.
        assert_eq!(run(&mut m, 0, 40, bad), None);
        assert_eq!(run(&mut m, 40, 41, ok()), None);
        let r = run(&mut m, 41, 200, bad).unwrap();
        // Trips on the first cycle more than 50.5 ms after it started (cycle 41).
        assert_eq!(r.cycle, 92);
        assert_eq!(
            r.kind,
            FaultKind::FollowingError {
                joint: Label::new("PSM2[4]"),
                error: 0.3 - 0.1,
                limit: 0.1
            }
        );
        // Latched until reset.
        assert_eq!(m.check(1.0, 1000, &[ok()]), Some(r));
        m.reset();
        assert_eq!(m.check(1.0, 1000, &[ok()]), None);
    }

    #[test]
    fn a_joint_allowed_to_stall_keeps_its_other_checks() {
        let mut m = SafetyMonitor::new(vec![limits()]);
        m.allow_stall(0, true);
        m.allow_stall(7, true); // no such joint: ignored
        // Pushed into a stop past its soft limit: large following error,
        // saturated current, for a second.
        let stalled = JointSample {
            setpoint: -2.0,
            position: -1.15,
            current: -1.0,
            potentiometer: Some(-1.15),
            ..ok()
        };
        assert_eq!(run(&mut m, 0, 1000, stalled), None);
        // The velocity and pot checks still run.
        let fast = JointSample {
            velocity: 3.0,
            ..stalled
        };
        assert!(matches!(
            run(&mut m, 1000, 1001, fast).map(|r| r.kind),
            Some(FaultKind::Velocity { .. })
        ));
        // Allowed no more: the following error trips again.
        let mut m = SafetyMonitor::new(vec![limits()]);
        m.allow_stall(0, true);
        m.allow_stall(0, false);
        assert!(matches!(
            run(&mut m, 0, 1000, stalled).map(|r| r.kind),
            Some(FaultKind::PositionLimit { .. })
        ));
    }

    #[test]
    fn velocity_trips_at_once() {
        let mut m = SafetyMonitor::new(vec![limits()]);
        let r = m
            .check(
                0.0,
                0,
                &[JointSample {
                    velocity: -2.5,
                    ..ok()
                }],
            )
            .unwrap();
        assert!(matches!(r.kind, FaultKind::Velocity { velocity, .. } if velocity == -2.5));
    }

    #[test]
    fn saturation_duration() {
        let mut m = SafetyMonitor::new(vec![limits()]);
        let sat = JointSample {
            current: -1.0,
            ..ok()
        };
        let r = run(&mut m, 0, 1000, sat).unwrap();
        assert_eq!(r.cycle, 201);
        assert!(matches!(
            r.kind,
            FaultKind::CurrentSaturation { duration, limit, .. } if duration > 0.2 && limit == 0.2005
        ));
    }

    #[test]
    fn position_and_pot() {
        let mut m = SafetyMonitor::new(vec![limits()]);
        let out = JointSample {
            setpoint: 1.15,
            position: 1.15,
            potentiometer: Some(1.15),
            ..ok()
        };
        assert!(matches!(
            m.check(0.0, 0, &[out]).unwrap().kind,
            FaultKind::PositionLimit { .. }
        ));
        let mut m = SafetyMonitor::new(vec![limits()]);
        let pot_off = JointSample {
            potentiometer: Some(0.2),
            ..ok()
        };
        let r = run(&mut m, 0, 100, pot_off).unwrap();
        assert_eq!(r.cycle, 11);
        assert!(matches!(r.kind, FaultKind::PotentiometerMismatch { .. }));
    }

    #[test]
    fn invalid_values_and_first_fault_order() {
        let mut second = limits();
        second.label = Label::new("PSM2[5]");
        let mut m = SafetyMonitor::new(vec![limits(), second]);
        // Joint 1 has a NaN, joint 0 an over-speed: joint 0 is reported.
        let r = m
            .check(
                0.0,
                0,
                &[
                    JointSample {
                        velocity: 9.0,
                        ..ok()
                    },
                    JointSample {
                        position: f64::NAN,
                        ..ok()
                    },
                ],
            )
            .unwrap();
        assert!(matches!(r.kind, FaultKind::Velocity { joint, .. } if joint.as_str() == "PSM2[4]"));
        let mut m = SafetyMonitor::new(vec![limits(), second]);
        let r = m
            .check(
                0.0,
                0,
                &[
                    ok(),
                    JointSample {
                        current: f64::INFINITY,
                        ..ok()
                    },
                ],
            )
            .unwrap();
        assert_eq!(
            r.kind,
            FaultKind::InvalidValue {
                joint: Label::new("PSM2[5]"),
                what: "current command"
            }
        );
        let mut m = SafetyMonitor::new(vec![limits(), second]);
        assert!(matches!(
            m.check(0.0, 0, &[ok()]).unwrap().kind,
            FaultKind::InvalidValue {
                what: "sample (missing)",
                ..
            }
        ));
        let mut m = SafetyMonitor::new(vec![limits()]);
        assert!(matches!(
            m.check(f64::NAN, 0, &[ok()]).unwrap().kind,
            FaultKind::InvalidValue { what: "time", .. }
        ));
        let mut m = SafetyMonitor::new(vec![JointLimits::unchecked(Label::new("x"))]);
        assert_eq!(
            m.check(
                0.0,
                0,
                &[JointSample {
                    velocity: 1e9,
                    current: 1e9,
                    ..ok()
                }]
            ),
            None
        );
    }
}
