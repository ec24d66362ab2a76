//! Stop-search homing, as the dVRK console homes the MTM roll: the joint
//! is driven at constant velocity into its mechanical stop with its stall
//! checks off, and the encoder is declared to read the stop's position
//! when the following error says it has stalled.

use firelink_host::RobotIo;

use super::{Pacing, Robot, RunnerError};
use crate::config::{StopSearchConfig, StopSide};
use crate::label::Label;
use crate::trajectory::{Motion, PointToPoint};

/// Why a stop search failed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum StopSearchProblem {
    /// The joint's configuration has no `simulation.homing.stop_search`.
    #[error("not configured for this joint")]
    NotConfigured,
    /// The joint travelled the whole search without stalling: there is no
    /// stop where one was expected (the dVRK console's "went past roll
    /// lower limit").
    #[error("no stop within {travel:.3} of travel")]
    NoStop {
        /// How far the setpoint travelled.
        travel: f64,
    },
}

/// What a stop search found: the joint stalled against its stop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StopFound {
    /// The joint.
    pub joint: Label,
    /// Where the encoder (homed from the pot) said the joint was when the
    /// stall was declared, before it was set to `stop_position`.
    pub stalled_at: f64,
    /// From the start of the search to there.
    pub travel: f64,
    /// |setpoint - position| then.
    pub following_error: f64,
    /// Current commanded then, A.
    pub commanded_current: f64,
    /// Current the amplifier measured then, A.
    pub measured_current: f64,
    /// Seconds from the start of the search.
    pub duration: f64,
    /// Where the encoder reads from now on (the configured stop position).
    pub stop_position: f64,
}

impl<R: RobotIo> Robot<R> {
    /// The joints whose configuration homes them by a stop search.
    pub fn stop_search_joints(&self) -> impl Iterator<Item = usize> + '_ {
        self.stop_searches
            .iter()
            .enumerate()
            .filter(|(_, s)| s.is_some())
            .map(|(i, _)| i)
    }

    /// Home joint `i` by its stop search: see
    /// [`search_stop_observed`](Self::search_stop_observed).
    ///
    /// # Errors
    /// As [`search_stop_observed`](Self::search_stop_observed).
    pub fn search_stop(&mut self, i: usize) -> Result<StopFound, RunnerError> {
        self.search_stop_observed(i, &mut |_| {})
    }

    /// Home joint `i` by a stop search, as the dVRK console homes the MTM
    /// roll: from where it is, its setpoint moves towards the stop at the
    /// configured constant velocity, reached with the configured
    /// acceleration (the other joints hold), with its position-limit,
    /// following-error and current-saturation checks off, until the
    /// following error passes `stall_error`: the joint has stalled against
    /// the stop. The encoder is then declared to read `stop_position` (the
    /// joint's offset changes), the joint holds there and its checks are
    /// back on; a move away from the stop is free. `each` is called after
    /// every cycle.
    ///
    /// # Errors
    /// Not Active; no such joint; [`StopSearchProblem::NotConfigured`];
    /// [`StopSearchProblem::NoStop`] when the whole travel passes without a
    /// stall; a fault while searching (the checks are back on in any case).
    pub fn search_stop_observed(
        &mut self,
        i: usize,
        each: &mut dyn FnMut(&Self),
    ) -> Result<StopFound, RunnerError> {
        self.life.require_motion()?;
        let j = *self
            .joints
            .get(i)
            .ok_or_else(|| RunnerError::Config(format!("no joint {i}")))?;
        let Some(search) = self.stop_searches.get(i).copied().flatten() else {
            return Err(RunnerError::StopSearch {
                joint: j.label,
                problem: StopSearchProblem::NotConfigured,
            });
        };
        let direction = match search.side {
            StopSide::Lower => -1.0,
            StopSide::Upper => 1.0,
        };
        let start = j.position;
        let search_move = PointToPoint::new(
            start,
            start + direction * search.max_travel,
            search.velocity,
            search.acceleration,
        )
        .map_err(|e| RunnerError::Config(format!("{}: stop search: {e}", j.label)))?;
        let horizon = search_move.duration();
        let started = self.now();
        self.safety.allow_stall(i, true);
        let found = self
            .set_motion(i, Motion::PointToPoint(search_move))
            .and_then(|()| self.run_search(i, &search, started, horizon, each));
        self.safety.allow_stall(i, false);
        let (stalled_at, following_error, commanded_current, duration) = found?;
        let measured_current = self.measured_current(i).unwrap_or(f64::NAN);
        let now = self.now();
        if let Some(j) = self.joints.get_mut(i) {
            j.offset += search.stop_position - stalled_at;
            j.position = search.stop_position;
            j.setpoint = search.stop_position;
            j.motion = Motion::Hold(search.stop_position);
            j.motion_start = now;
            j.velocity.reset();
        }
        if let Some(pid) = self.pids.get_mut(i) {
            pid.reset();
        }
        self.safety.restart_timers();
        Ok(StopFound {
            joint: j.label,
            stalled_at,
            travel: (stalled_at - start).abs(),
            following_error,
            commanded_current,
            measured_current,
            duration,
            stop_position: search.stop_position,
        })
    }

    /// Cycles until joint `i` stalls: (position, following error, current
    /// command, seconds since `started`).
    fn run_search(
        &mut self,
        i: usize,
        search: &StopSearchConfig,
        started: f64,
        horizon: f64,
        each: &mut dyn FnMut(&Self),
    ) -> Result<(f64, f64, f64, f64), RunnerError> {
        // Past the end of the travel, give the joint a moment to catch up.
        let give_up = horizon + 1.0;
        loop {
            let r = self.step_unless_stopped(Pacing::Virtual);
            each(self);
            r?;
            let Some(j) = self.joints.get(i) else {
                return Err(RunnerError::Config(format!("no joint {i}")));
            };
            let error = (j.setpoint - j.position).abs();
            let elapsed = self.now() - started;
            if error > search.stall_error {
                return Ok((j.position, error, j.current, elapsed));
            }
            if elapsed > give_up {
                return Err(RunnerError::StopSearch {
                    joint: j.label,
                    problem: StopSearchProblem::NoStop {
                        travel: search.max_travel,
                    },
                });
            }
        }
    }
}
