//! Fig. 18's top layer: abstract robot I/O, the same for every kind of
//! board, so that one controller drives a QLA robot and a Snake robot.
//!
//! [`RobotIo`] has seed 001's shape: `latch_all_inputs` samples every
//! board at once, per-axis getters read the latched values, per-axis
//! setters fill local buffers, `apply_all_outputs` writes every board at
//! once. Values are primitive and raw, in the board's own units (DAC and
//! ADC codes, encoder counts); a robot's configuration converts them to
//! SI (`firelink_control::config`). Axes are numbered from 0 over all
//! boards in the order the system lists them; [`RobotIo::axis_index`]
//! finds the axis of a `(board ID, axis on the board)` pair once, at
//! setup, so the cycle indexes directly.
//!
//! Implemented in each robot's wing: for the QLA family's
//! [`IoSystem`](crate::qla::io::IoSystem) in `crate::qla::io` and for the
//! Snake node's [`SnakeSystem`](crate::snake::SnakeSystem) in
//! [`crate::snake`].
//!
//! | seed 001 (Fig. 18) | [`RobotIo`] |
//! |---|---|
//! | `LatchAllInputs` | [`latch_all_inputs`](RobotIo::latch_all_inputs) |
//! | `ApplyAllOutputs` | [`apply_all_outputs`](RobotIo::apply_all_outputs) |
//! | `GetStatus` | [`board_answered`](RobotIo::board_answered), [`powered`](RobotIo::powered), [`watchdog_expired`](RobotIo::watchdog_expired) |
//! | `GetTimestamp` | [`timestamp`](RobotIo::timestamp) |
//! | `GetEncoderPosition` / `GetEncoderVelocity` | [`encoder_position`](RobotIo::encoder_position) / [`encoder_velocity`](RobotIo::encoder_velocity) |
//! | `GetAnalogPosition` / `GetMotorCurrent` | [`analog_position`](RobotIo::analog_position) / [`motor_current`](RobotIo::motor_current) |
//! | `SetMotorVoltage` | [`set_motor_command`](RobotIo::set_motor_command) |
//! | `SetPowerControl` | [`set_power`](RobotIo::set_power), [`set_amplifier_enable`](RobotIo::set_amplifier_enable) |

use std::time::Duration;

use firelink_wire::qla::registers::WatchdogSetting;

use crate::cycle_report::{CycleReport, IoStats};
use crate::error::{HostError, Result};

/// Abstract robot I/O: see the module docs.
///
/// # Errors
/// Per-axis methods fail with [`HostError::InvalidRequest`] for an axis
/// the system does not have; I/O errors of a cycle are in its
/// [`CycleReport`], never raised.
pub trait RobotIo {
    /// A short name of the port ("sim", "udp:127.0.0.1:1394").
    fn port_name(&self) -> &str;
    /// The port's clock (virtual on the simulated bus).
    fn now(&self) -> Duration;
    /// Let `duration` pass on the port's clock.
    fn wait(&mut self, duration: Duration);

    /// Board IDs present (bit i = board ID i).
    fn boards(&self) -> u16;
    /// Axes over all boards.
    fn axis_count(&self) -> usize;
    /// The axis of `(board ID, axis on that board, from 0)`.
    fn axis_index(&self, board_id: u8, axis: u8) -> Option<usize>;
    /// The `(board ID, axis on that board)` of an axis.
    fn axis_location(&self, axis: usize) -> Option<(u8, u8)>;

    /// `LatchAllInputs`: sample every board; the cycle's report says who
    /// answered.
    fn latch_all_inputs(&mut self) -> &CycleReport;
    /// `ApplyAllOutputs`: write every board's buffered outputs.
    fn apply_all_outputs(&mut self) -> &CycleReport;
    /// Error counters over all cycles.
    fn stats(&self) -> &IoStats;

    /// Whether board `board_id` answered the last latch.
    fn board_answered(&self, board_id: u8) -> bool;
    /// Whether board `board_id`'s motor power was on at the last latch
    /// (boards without a switched motor supply: whenever they answered).
    fn powered(&self, board_id: u8) -> bool;
    /// Whether board `board_id`'s watchdog had expired at the last latch.
    fn watchdog_expired(&self, board_id: u8) -> bool;
    /// 49.152 MHz clocks between board `board_id`'s last two samples
    /// (`None` if it did not answer; 0 if the board does not say).
    fn timestamp(&self, board_id: u8) -> Option<u32>;

    /// Ask for motor power on or off with the next apply, on the boards in
    /// `boards` (bit i = board ID i; boards without a switched motor
    /// supply: off disables every amplifier, on does nothing).
    fn set_power(&mut self, boards: u16, on: bool);
    /// Program every board's watchdog (off only by
    /// [`WatchdogSetting::Off`]).
    ///
    /// # Errors
    /// Port errors.
    fn set_watchdog(&mut self, setting: WatchdogSetting) -> Result<()>;
    /// The fault path's backstop: tell each board in `boards` directly to
    /// turn every amplifier off; returns those that acknowledged.
    fn disable_amplifiers_acknowledged(&mut self, boards: u16) -> u16;
    /// Between cycles: after a bus reset, find the boards again.
    ///
    /// # Errors
    /// The discovery failed (the next call tries again).
    fn recover(&mut self) -> Result<()>;

    /// `GetEncoderPosition`: counts relative to the midpoint preload.
    ///
    /// # Errors
    /// See the trait docs.
    fn encoder_position(&self, axis: usize) -> Result<i32>;
    /// Every axis's latched inputs at once, for a cycle that reads them
    /// all: `counts[i]` becomes
    /// [`encoder_position`](Self::encoder_position)`(i)`, 0 where there is
    /// no reading, and `pots[i]`
    /// [`analog_position`](Self::analog_position)`(i).ok()`, for every `i`
    /// below the shorter slice's length (0 and `None` past the last axis).
    /// The default asks axis by axis; a system that can walk its latched
    /// blocks once, board by board, does that instead.
    fn axis_inputs(&self, counts: &mut [i32], pots: &mut [Option<u16>]) {
        for (i, (c, p)) in counts.iter_mut().zip(pots.iter_mut()).enumerate() {
            *c = self.encoder_position(i).unwrap_or(0);
            *p = self.analog_position(i).ok();
        }
    }
    /// `GetEncoderVelocity`: counts per second from the board's period
    /// measurement (0 when too slow to measure).
    ///
    /// # Errors
    /// See the trait docs.
    fn encoder_velocity(&self, axis: usize) -> Result<f64>;
    /// `GetAnalogPosition`: the potentiometer ADC code.
    ///
    /// # Errors
    /// See the trait docs.
    fn analog_position(&self, axis: usize) -> Result<u16>;
    /// `GetMotorCurrent`: the current-feedback ADC code.
    ///
    /// # Errors
    /// See the trait docs.
    fn motor_current(&self, axis: usize) -> Result<u16>;
    /// Whether the axis's amplifier was on at the last latch.
    ///
    /// # Errors
    /// See the trait docs.
    fn amplifier_enabled(&self, axis: usize) -> Result<bool>;
    /// Board `board_id` at the last latch, what the cycle's checks read of
    /// it in one call: [`board_answered`](Self::board_answered),
    /// [`powered`](Self::powered), [`watchdog_expired`](Self::watchdog_expired),
    /// [`timestamp`](Self::timestamp) and the amplifiers of its axes that
    /// were on. The default asks each of those, and
    /// [`amplifier_enabled`](Self::amplifier_enabled) axis by axis.
    fn board_status(&self, board_id: u8) -> BoardStatus {
        let amplifiers = (0..64u8)
            .map_while(|a| Some((a, self.axis_index(board_id, a)?)))
            .filter(|&(_, axis)| self.amplifier_enabled(axis).unwrap_or(false))
            .fold(0, |mask, (a, _)| mask | 1 << a);
        BoardStatus {
            answered: self.board_answered(board_id),
            powered: self.powered(board_id),
            watchdog_expired: self.watchdog_expired(board_id),
            timestamp: self.timestamp(board_id),
            amplifiers,
        }
    }
    /// `SetMotorVoltage` / the motor command: the DAC code the next apply
    /// writes.
    ///
    /// # Errors
    /// See the trait docs.
    fn set_motor_command(&mut self, axis: usize, code: u16) -> Result<()>;
    /// [`set_motor_command`](Self::set_motor_command)`(i, code)` for each
    /// axis `i` whose `codes[i]` is `Some(code)`, for a cycle that sets
    /// them all (axes with `None`, and codes past the last axis, are left
    /// alone). The default sets axis by axis; a system that can walk its
    /// boards' command blocks once does that instead.
    fn set_motor_commands(&mut self, codes: &[Option<u16>]) {
        for (axis, code) in codes.iter().enumerate() {
            if let Some(code) = *code {
                let _ = self.set_motor_command(axis, code);
            }
        }
    }
    /// Ask for the axis's amplifier on or off with the next apply.
    ///
    /// # Errors
    /// See the trait docs.
    fn set_amplifier_enable(&mut self, axis: usize, on: bool) -> Result<()>;
    /// Every axis to its neutral command and every amplifier off with the
    /// next apply.
    fn set_all_safe(&mut self);

    /// Boards this program asked for motor power or an amplifier since
    /// the last [`power_down`](Self::power_down) (bit i = board ID i).
    fn energised(&self) -> u16;
    /// Forget [`energised`](Self::energised) (after a power-down).
    fn clear_energised(&mut self);
    /// The watchdog this program last programmed, if it did.
    fn watchdog_programmed(&self) -> Option<WatchdogSetting>;
    /// Whether [`powered`](Self::powered) reports a switched motor supply
    /// (false for boards that answer "powered" whenever they answer).
    fn switches_power(&self) -> bool {
        true
    }

    /// The one power-down rule, for every way a program that powered a
    /// robot can end: every amplifier off (zero command, then each board
    /// told directly), then motor power and relay off, then the watchdog
    /// left running (a program that had turned it off sets the default
    /// period again, so a lost write still ends with the amplifiers off).
    /// Then one latch to see what the boards say. The I/O systems run it
    /// when dropped if they energised anything; a robot's shutdown runs
    /// it. Bounded: a handful of transactions, each with the port's
    /// time-out.
    fn power_down(&mut self) -> PowerDown {
        let all = self.boards();
        // After a bus reset nothing is written until the boards are found
        // again; try once.
        let _ = self.recover();
        self.set_all_safe();
        self.apply_all_outputs();
        self.disable_amplifiers_acknowledged(all);
        self.set_power(all, false);
        self.apply_all_outputs();
        let watchdog_restored = self.watchdog_programmed() == Some(WatchdogSetting::Off)
            && self.set_watchdog(WatchdogSetting::default()).is_ok();
        self.latch_all_inputs();
        let mut found = PowerDown {
            watchdog_restored,
            ..PowerDown::default()
        };
        for id in (0..16u8).filter(|id| all & (1 << id) != 0) {
            let s = self.board_status(id);
            let bit = 1u16 << id;
            if !s.answered {
                found.unknown |= bit;
            } else if s.amplifiers != 0 || (s.powered && self.switches_power()) {
                found.still_on |= bit;
            } else {
                found.off |= bit;
            }
        }
        self.clear_energised();
        found
    }
}

/// What [`RobotIo::power_down`] found afterwards, per board (bit i = board
/// ID i).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PowerDown {
    /// Answered with motor power and every amplifier off.
    pub off: u16,
    /// Did not answer: their state is unknown (their own watchdog turns
    /// their amplifiers off, if it runs).
    pub unknown: u16,
    /// Answered still powered or with an amplifier on.
    pub still_on: u16,
    /// The watchdog had been turned off and was set to the default period.
    pub watchdog_restored: bool,
}

impl PowerDown {
    /// Every board answered with everything off.
    pub fn all_off(&self) -> bool {
        self.unknown == 0 && self.still_on == 0
    }
}

/// Board IDs of a mask as `0-3, 6`.
pub fn board_list(mask: u16) -> String {
    let mut out = String::new();
    let mut id = 0u8;
    while id < 16 {
        if mask & (1 << id) == 0 {
            id += 1;
            continue;
        }
        let start = id;
        while id < 16 && mask & (1 << id) != 0 {
            id += 1;
        }
        if !out.is_empty() {
            out.push_str(", ");
        }
        let end = id - 1;
        out.push_str(&match end - start {
            0 => format!("{start}"),
            1 => format!("{start}, {end}"),
            _ => format!("{start}-{end}"),
        });
    }
    out
}

impl std::fmt::Display for PowerDown {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut parts = Vec::new();
        if self.off != 0 {
            parts.push(format!(
                "amplifiers and motor power off on boards {}",
                board_list(self.off)
            ));
        }
        if self.still_on != 0 {
            parts.push(format!(
                "boards {} still report power or an amplifier on",
                board_list(self.still_on)
            ));
        }
        if self.unknown != 0 {
            parts.push(format!(
                "boards {} did not answer: state unknown",
                board_list(self.unknown)
            ));
        }
        if parts.is_empty() {
            parts.push("no boards".into());
        }
        if self.watchdog_restored {
            parts.push("watchdog set back to its default period".into());
        }
        f.write_str(&parts.join("; "))
    }
}

/// One board at the last latch ([`RobotIo::board_status`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BoardStatus {
    /// It answered the last latch.
    pub answered: bool,
    /// Its motor power was on (see [`RobotIo::powered`]).
    pub powered: bool,
    /// Its watchdog had expired.
    pub watchdog_expired: bool,
    /// 49.152 MHz clocks between its last two samples (`None` if it did
    /// not answer; 0 if it does not say).
    pub timestamp: Option<u32>,
    /// Its amplifiers that were on, bit i = axis i on the board (none when
    /// it did not answer; axes from 64 on are not reported).
    pub amplifiers: u64,
}

/// The error for an axis a system does not have.
pub fn bad_axis(axis: usize) -> HostError {
    HostError::InvalidRequest {
        what: "axis (beyond the boards found)",
        value: u32::try_from(axis).unwrap_or(u32::MAX),
    }
}
