//! What went wrong, for the operator: the fault report.
//!
//! A [`FaultReport`] is `Copy` and allocation-free so the servo cycle can
//! create it, the [`Lifecycle`](crate::Lifecycle) can latch it and the runner
//! can print it later. Joints and boards are named by [`Label`]s taken from
//! the configuration at setup.

use crate::config::Measured;
use crate::label::Label;
use core::fmt;

/// One fault: when it was detected and what it was.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaultReport {
    /// Time of detection, seconds, on the caller's clock (virtual or real).
    pub time: f64,
    /// Servo cycle number at detection.
    pub cycle: u64,
    /// What happened.
    pub kind: FaultKind,
}

impl FaultReport {
    /// A report of `kind` at `time` (seconds) in servo cycle `cycle`.
    pub fn new(time: f64, cycle: u64, kind: FaultKind) -> FaultReport {
        FaultReport { time, cycle, kind }
    }
}

impl fmt::Display for FaultReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "fault at t = {:.6} s (cycle {}): {}",
            self.time, self.cycle, self.kind
        )
    }
}

/// The kinds of fault the control layer reports. Structured fields, no
/// strings on the heap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FaultKind {
    /// An expected board did not answer this cycle (the "working counter"
    /// check of `STYLE.md` point 14), or was not found at configuration.
    MissedBoard {
        /// Board ID (rotary switch).
        board_id: u8,
        /// The robot that uses the board.
        robot: Label,
    },
    /// A board's echoed sequence number did not match the query's (seed 000:
    /// 0xFFFF from a board that received a corrupt query).
    Sequence {
        /// Board ID.
        board_id: u8,
        /// Sequence number the host sent.
        expected: u16,
        /// Sequence number the board returned.
        received: u16,
    },
    /// A board's watchdog expired (STATUS bit 23): the host was too slow and
    /// the board turned its amplifiers off.
    Watchdog {
        /// Board ID.
        board_id: u8,
    },
    /// Motor power was lost or never came up on a board.
    Power {
        /// Board ID.
        board_id: u8,
    },
    /// An amplifier reported a fault or switched itself off.
    Amplifier {
        /// Board ID.
        board_id: u8,
        /// Axis on the board (0-based).
        axis_id: u8,
    },
    /// The joint is further from its setpoint than allowed, for longer than
    /// the grace period.
    FollowingError {
        /// The joint, `robot[index]`.
        joint: Label,
        /// Setpoint minus measured position (rad or m).
        error: f64,
        /// The configured limit (rad or m).
        limit: f64,
    },
    /// The joint moves faster than allowed.
    Velocity {
        /// The joint.
        joint: Label,
        /// Measured velocity (rad/s or m/s).
        velocity: f64,
        /// The configured limit.
        limit: f64,
    },
    /// The current command sat at the drive's maximum for too long.
    CurrentSaturation {
        /// The joint.
        joint: Label,
        /// How long it has been saturated, seconds.
        duration: f64,
        /// The allowed time, seconds.
        limit: f64,
    },
    /// The joint left its soft position limits by more than the margin.
    PositionLimit {
        /// The joint.
        joint: Label,
        /// Measured position.
        position: f64,
        /// Lower soft limit.
        lower: f64,
        /// Upper soft limit.
        upper: f64,
    },
    /// Potentiometer and encoder disagree by more than the tolerance for
    /// longer than the allowed latency (the dVRK's continuous pot check).
    PotentiometerMismatch {
        /// The joint.
        joint: Label,
        /// Potentiometer position minus encoder position.
        difference: f64,
        /// Tolerance (`potentiometers.tolerances[].distance`).
        tolerance: f64,
    },
    /// A measurement or command was NaN or infinite.
    InvalidValue {
        /// The joint.
        joint: Label,
        /// Which quantity (`"position"`, `"velocity"`, ...).
        what: &'static str,
    },
}

impl fmt::Display for FaultKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FaultKind::MissedBoard { board_id, robot } => {
                write!(f, "board {board_id} ({robot}) did not answer")
            }
            FaultKind::Sequence {
                board_id,
                expected,
                received,
            } => write!(
                f,
                "board {board_id} sequence error: expected {expected:#06x}, received {received:#06x}"
            ),
            FaultKind::Watchdog { board_id } => {
                write!(f, "board {board_id} watchdog timed out (amplifiers off)")
            }
            FaultKind::Power { board_id } => write!(f, "board {board_id} motor power lost"),
            FaultKind::Amplifier { board_id, axis_id } => {
                write!(f, "board {board_id} axis {axis_id} amplifier fault")
            }
            FaultKind::FollowingError {
                joint,
                error,
                limit,
            } => write!(
                f,
                "{joint} following error {:+} exceeds its limit of {} (rad or m)",
                Measured(*error),
                Measured(*limit)
            ),
            FaultKind::Velocity {
                joint,
                velocity,
                limit,
            } => write!(
                f,
                "{joint} velocity {:+} exceeds its limit of {} (rad/s or m/s)",
                Measured(*velocity),
                Measured(*limit)
            ),
            FaultKind::CurrentSaturation {
                joint,
                duration,
                limit,
            } => write!(
                f,
                "{joint} current sat at the maximum for {} s, longer than the {} s allowed",
                Measured(*duration),
                Measured(*limit)
            ),
            FaultKind::PositionLimit {
                joint,
                position,
                lower,
                upper,
            } => write!(
                f,
                "{joint} position {:+} is outside its limits [{}, {}]",
                Measured(*position),
                Measured(*lower),
                Measured(*upper)
            ),
            FaultKind::PotentiometerMismatch {
                joint,
                difference,
                tolerance,
            } => write!(
                f,
                "{joint} potentiometer and encoder differ by {:+}, more than the tolerance of {} (rad or m)",
                Measured(*difference),
                Measured(*tolerance)
            ),
            FaultKind::InvalidValue { joint, what } => {
                write!(f, "{joint} {what} is not a finite number")
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_names_joint_and_magnitude() {
        let r = FaultReport::new(
            1.5,
            1500,
            FaultKind::FollowingError {
                joint: Label::joint("PSM1", 2),
                error: 0.0123,
                limit: 0.01,
            },
        );
        let s = r.to_string();
        assert!(s.contains("PSM1[2]"), "{s}");
        assert!(
            s.contains("following error +0.0123 exceeds its limit of 0.01"),
            "{s}"
        );
        assert!(s.contains("cycle 1500"), "{s}");
        let m = FaultKind::MissedBoard {
            board_id: 5,
            robot: Label::new("PSM1"),
        };
        assert_eq!(m.to_string(), "board 5 (PSM1) did not answer");
    }

    #[test]
    fn huge_values_read_as_written() {
        let k = FaultKind::PositionLimit {
            joint: Label::joint("MTML", 0),
            position: 1e300,
            lower: -1.0,
            upper: 1.0,
        };
        assert_eq!(
            k.to_string(),
            "MTML[0] position +1e300 is outside its limits [-1, 1]"
        );
    }
}
