//! The robot lifecycle, after ros2_control's hardware lifecycle.
//!
//! ```text
//!               configure(found)            activate(status)
//!  Unconfigured ───────────────▶ Configured ───────────────▶ Active
//!       ▲        ◀───────────────    │  ▲     ◀───────────────  │
//!       │            cleanup()       │  │        deactivate()   │
//!       │                            ▼  │                       ▼
//!       └──────── clear_fault() ─── Fault ◀──── fault(report) ───┘
//!                                   (from any state)
//! ```
//!
//! State meanings:
//!
//! | state | meaning | reads | power / amplifiers | motion commands |
//! |---|---|---|---|---|
//! | Unconfigured | nothing known about the bus | no | off | refused |
//! | Configured | every expected board was found; states are read each cycle | yes | may be requested (activation in progress) | refused |
//! | Active | power on and every amplifier enabled | yes | on | accepted |
//! | Fault | something went wrong (see the [`FaultReport`]) | yes, if possible | must be off | refused |
//!
//! Transitions check their evidence (which boards answered, which are
//! powered) and refuse with a [`LifecycleError`] otherwise. The lifecycle
//! never does I/O: the runner gathers the evidence, calls the transition and
//! acts on the new state. All methods are allocation-free.

use crate::config::IoConfig;
use crate::fault::{FaultKind, FaultReport};
use crate::label::{BoardSet, Label};
use core::fmt;

/// Lifecycle states.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum State {
    /// Nothing known about the bus yet.
    Unconfigured,
    /// All expected boards found; inputs are read every cycle; no motion.
    Configured,
    /// Powered, amplifiers enabled, motion commands accepted.
    Active,
    /// A fault was detected; outputs must be off until the fault is cleared.
    Fault,
}

impl fmt::Display for State {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            State::Unconfigured => "unconfigured",
            State::Configured => "configured",
            State::Active => "active",
            State::Fault => "fault",
        })
    }
}

/// Transitions, named for error messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Transition {
    /// Unconfigured -> Configured.
    Configure,
    /// Configured -> Active.
    Activate,
    /// Active -> Configured.
    Deactivate,
    /// Configured -> Unconfigured.
    Cleanup,
    /// Fault -> Unconfigured.
    ClearFault,
}

impl fmt::Display for Transition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Transition::Configure => "configure",
            Transition::Activate => "activate",
            Transition::Deactivate => "deactivate",
            Transition::Cleanup => "cleanup",
            Transition::ClearFault => "clear_fault",
        })
    }
}

/// A refused transition or command.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum LifecycleError {
    /// The transition does not start from the current state.
    #[error("cannot {transition} from state {from}")]
    InvalidTransition {
        /// Current state.
        from: State,
        /// The transition asked for.
        transition: Transition,
    },
    /// An expected board was not found on the bus.
    #[error("board {board_id} ({robot}) was not found")]
    MissingBoard {
        /// Board ID.
        board_id: u8,
        /// Robot using it.
        robot: Label,
    },
    /// A board's motor power is not on.
    #[error("board {board_id} ({robot}) has no motor power")]
    NotPowered {
        /// Board ID.
        board_id: u8,
        /// Robot using it.
        robot: Label,
    },
    /// A board's amplifiers are not all enabled.
    #[error("board {board_id} ({robot}) amplifiers are not enabled")]
    AmplifiersDisabled {
        /// Board ID.
        board_id: u8,
        /// Robot using it.
        robot: Label,
    },
    /// A motion command outside the Active state.
    #[error("motion refused: the robot is {state}, not active")]
    NotActive {
        /// Current state.
        state: State,
    },
    /// Motor power and amplifiers are switched on only from Configured.
    #[error("power on refused: the robot is {state}, not configured")]
    NotConfigured {
        /// Current state.
        state: State,
    },
}

/// Evidence for [`Lifecycle::activate`]: which boards report motor power and
/// which have every used amplifier enabled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PowerStatus {
    /// Boards whose STATUS says motor power is on and good.
    pub powered: BoardSet,
    /// Boards whose used axes all have their amplifier enabled.
    pub amplifiers_enabled: BoardSet,
}

/// The lifecycle of one bus's robots.
#[derive(Debug, Clone, PartialEq)]
pub struct Lifecycle {
    state: State,
    expected: BoardSet,
    owners: [Label; 16],
    fault: Option<FaultReport>,
}

impl Lifecycle {
    /// A lifecycle expecting the boards in `expected`, with no names.
    pub fn new(expected: BoardSet) -> Lifecycle {
        Lifecycle {
            state: State::Unconfigured,
            expected,
            owners: [Label::EMPTY; 16],
            fault: None,
        }
    }

    /// A lifecycle expecting the boards of `config`, naming each board after
    /// the robot that uses it.
    pub fn from_config(config: &IoConfig) -> Lifecycle {
        let mut l = Lifecycle::new(config.board_set());
        for b in config.boards() {
            if let Some(slot) = l.owners.get_mut(usize::from(b.board_id)) {
                *slot = b.robot;
            }
        }
        l
    }

    /// The current state.
    pub fn state(&self) -> State {
        self.state
    }

    /// The boards this lifecycle expects.
    pub fn expected(&self) -> BoardSet {
        self.expected
    }

    /// The latched fault, while in [`State::Fault`].
    pub fn fault_report(&self) -> Option<&FaultReport> {
        self.fault.as_ref()
    }

    /// The robot that uses `board_id` (empty if unknown).
    pub fn board_owner(&self, board_id: u8) -> Label {
        self.owners
            .get(usize::from(board_id))
            .copied()
            .unwrap_or_default()
    }

    fn refuse(&self, transition: Transition) -> LifecycleError {
        LifecycleError::InvalidTransition {
            from: self.state,
            transition,
        }
    }

    /// Unconfigured -> Configured, if every expected board is in `found`
    /// (the result of discovery).
    ///
    /// # Errors
    /// Not Unconfigured, or the lowest missing board.
    pub fn configure(&mut self, found: BoardSet) -> Result<(), LifecycleError> {
        if self.state != State::Unconfigured {
            return Err(self.refuse(Transition::Configure));
        }
        if let Some(board_id) = self.expected.minus(found).first() {
            return Err(LifecycleError::MissingBoard {
                board_id,
                robot: self.board_owner(board_id),
            });
        }
        self.state = State::Configured;
        Ok(())
    }

    /// Configured -> Active, if every expected board is powered and has its
    /// amplifiers enabled.
    ///
    /// # Errors
    /// Not Configured, or the lowest board without power, or without
    /// amplifiers.
    pub fn activate(&mut self, status: PowerStatus) -> Result<(), LifecycleError> {
        if self.state != State::Configured {
            return Err(self.refuse(Transition::Activate));
        }
        if let Some(board_id) = self.expected.minus(status.powered).first() {
            return Err(LifecycleError::NotPowered {
                board_id,
                robot: self.board_owner(board_id),
            });
        }
        if let Some(board_id) = self.expected.minus(status.amplifiers_enabled).first() {
            return Err(LifecycleError::AmplifiersDisabled {
                board_id,
                robot: self.board_owner(board_id),
            });
        }
        self.state = State::Active;
        Ok(())
    }

    /// Active -> Configured: stop accepting motion; the runner turns the
    /// amplifiers and power off.
    ///
    /// # Errors
    /// Not Active.
    pub fn deactivate(&mut self) -> Result<(), LifecycleError> {
        if self.state != State::Active {
            return Err(self.refuse(Transition::Deactivate));
        }
        self.state = State::Configured;
        Ok(())
    }

    /// Configured -> Unconfigured: forget the bus.
    ///
    /// # Errors
    /// Not Configured.
    pub fn cleanup(&mut self) -> Result<(), LifecycleError> {
        if self.state != State::Configured {
            return Err(self.refuse(Transition::Cleanup));
        }
        self.state = State::Unconfigured;
        Ok(())
    }

    /// Any state -> Fault. The first report is kept: later faults while
    /// already in Fault are consequences and are ignored. Returns the report
    /// in force.
    pub fn fault(&mut self, report: FaultReport) -> FaultReport {
        if self.state != State::Fault || self.fault.is_none() {
            self.fault = Some(report);
            self.state = State::Fault;
        }
        self.fault.unwrap_or(report)
    }

    /// Fault -> Unconfigured (the bus must be configured again), returning
    /// the cleared report.
    ///
    /// # Errors
    /// Not in Fault.
    pub fn clear_fault(&mut self) -> Result<FaultReport, LifecycleError> {
        match (self.state, self.fault) {
            (State::Fault, Some(report)) => {
                self.state = State::Unconfigured;
                self.fault = None;
                Ok(report)
            }
            _ => Err(self.refuse(Transition::ClearFault)),
        }
    }

    /// The per-cycle "working counter" check: in Configured or Active, every
    /// expected board must have answered this cycle. A miss moves to Fault
    /// and returns the report; other states ignore the check.
    ///
    /// # Errors
    /// The fault report for the lowest missing board.
    pub fn check_cycle(
        &mut self,
        answered: BoardSet,
        now: f64,
        cycle: u64,
    ) -> Result<(), FaultReport> {
        if !matches!(self.state, State::Configured | State::Active) {
            return Ok(());
        }
        match self.expected.minus(answered).first() {
            None => Ok(()),
            Some(board_id) => {
                let kind = FaultKind::MissedBoard {
                    board_id,
                    robot: self.board_owner(board_id),
                };
                Err(self.fault(FaultReport::new(now, cycle, kind)))
            }
        }
    }

    /// Refuses motion unless Active. Call before accepting any setpoint.
    ///
    /// # Errors
    /// [`LifecycleError::NotActive`].
    pub fn require_motion(&self) -> Result<(), LifecycleError> {
        if self.state == State::Active {
            Ok(())
        } else {
            Err(LifecycleError::NotActive { state: self.state })
        }
    }

    /// Whether motion commands are accepted (Active).
    pub fn accepts_motion(&self) -> bool {
        self.state == State::Active
    }

    /// Whether inputs are read each cycle (Configured, Active, Fault).
    pub fn reads_inputs(&self) -> bool {
        self.state != State::Unconfigured
    }

    /// Whether the runner may request motor power and amplifier enables
    /// (Configured, to activate; Active, to keep them).
    pub fn power_allowed(&self) -> bool {
        matches!(self.state, State::Configured | State::Active)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boards(ids: &[u8]) -> BoardSet {
        ids.iter().copied().collect()
    }

    fn powered(ids: &[u8]) -> PowerStatus {
        PowerStatus {
            powered: boards(ids),
            amplifiers_enabled: boards(ids),
        }
    }

    #[test]
    fn full_cycle() {
        let mut l = Lifecycle::new(boards(&[0, 1]));
        assert_eq!(l.state(), State::Unconfigured);
        assert!(!l.reads_inputs() && !l.power_allowed());
        l.configure(boards(&[0, 1, 5])).unwrap();
        assert_eq!(l.state(), State::Configured);
        assert!(l.reads_inputs() && l.power_allowed() && !l.accepts_motion());
        l.activate(powered(&[0, 1])).unwrap();
        assert!(l.accepts_motion());
        l.require_motion().unwrap();
        l.deactivate().unwrap();
        assert_eq!(l.state(), State::Configured);
        l.cleanup().unwrap();
        assert_eq!(l.state(), State::Unconfigured);
    }

    #[test]
    fn refusals() {
        let mut l = Lifecycle::new(boards(&[2, 3]));
        assert_eq!(
            l.require_motion(),
            Err(LifecycleError::NotActive {
                state: State::Unconfigured
            })
        );
        assert_eq!(
            l.activate(powered(&[2, 3])),
            Err(LifecycleError::InvalidTransition {
                from: State::Unconfigured,
                transition: Transition::Activate
            })
        );
        assert!(l.deactivate().is_err() && l.cleanup().is_err() && l.clear_fault().is_err());
        assert!(matches!(
            l.configure(boards(&[2])),
            Err(LifecycleError::MissingBoard { board_id: 3, .. })
        ));
        assert_eq!(l.state(), State::Unconfigured);
        l.configure(boards(&[2, 3])).unwrap();
        assert!(l.configure(boards(&[2, 3])).is_err());
        assert!(matches!(
            l.require_motion(),
            Err(LifecycleError::NotActive {
                state: State::Configured
            })
        ));
        let half = PowerStatus {
            powered: boards(&[2, 3]),
            amplifiers_enabled: boards(&[3]),
        };
        assert!(matches!(
            l.activate(half),
            Err(LifecycleError::AmplifiersDisabled { board_id: 2, .. })
        ));
        assert!(matches!(
            l.activate(powered(&[3])),
            Err(LifecycleError::NotPowered { board_id: 2, .. })
        ));
        assert_eq!(l.state(), State::Configured);
        let msg = LifecycleError::NotActive {
            state: State::Fault,
        }
        .to_string();
        assert_eq!(msg, "motion refused: the robot is fault, not active");
    }

    #[test]
    fn missed_board_faults_and_names_the_robot() {
        let mut l = Lifecycle::new(boards(&[4, 5]));
        l.owners[5] = Label::new("PSM1");
        l.configure(boards(&[4, 5])).unwrap();
        l.activate(powered(&[4, 5])).unwrap();
        assert_eq!(l.check_cycle(boards(&[4, 5]), 0.001, 1), Ok(()));
        let r = l.check_cycle(boards(&[4]), 0.002, 2).unwrap_err();
        assert_eq!(
            r.kind,
            FaultKind::MissedBoard {
                board_id: 5,
                robot: Label::new("PSM1")
            }
        );
        assert_eq!(l.state(), State::Fault);
        assert!(!l.accepts_motion() && !l.power_allowed() && l.reads_inputs());
        // A later fault does not replace the first one.
        l.fault(FaultReport::new(
            0.003,
            3,
            FaultKind::Watchdog { board_id: 4 },
        ));
        assert_eq!(l.fault_report().unwrap().cycle, 2);
        // Checks are ignored while in Fault.
        assert_eq!(l.check_cycle(BoardSet::EMPTY, 0.004, 4), Ok(()));
        let cleared = l.clear_fault().unwrap();
        assert_eq!(cleared.cycle, 2);
        assert_eq!(l.state(), State::Unconfigured);
        assert!(l.fault_report().is_none());
    }
}
