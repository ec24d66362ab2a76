//! The model of a live view of every board (`firelink monitor`): the
//! running figures a front end shows, the operator's switches (motor
//! power, safety relay, amplifiers, the watchdog) and what they do to the
//! [`IoSystem`], and what a board's STATUS says in words.
//!
//! Rules:
//! - a switch only changes the output buffers of every board (or, for the
//!   watchdog, writes its register); the next cycle sends them;
//! - each switch answers with the one line a front end shows;
//! - nothing here reads a clock: the front end measures and records each
//!   cycle's I/O time and the achieved rate.

use firelink_wire::human::Number;
use firelink_wire::qla::address::{BoardRegister, Register};
use firelink_wire::qla::registers::{StatusRead, Watchdog};

use crate::qla::io::IoSystem;
use crate::{Port, WatchdogSetting};

/// The watchdog period the `Watchdog` switch sets, ms.
pub const SWITCHED_WATCHDOG_MS: f64 = 50.0;

/// Running figures a live view shows.
#[derive(Debug, Default, Clone)]
pub struct MonitorFigures {
    /// Cycles run.
    pub cycles: u64,
    /// Achieved cycle rate over the last display period, Hz.
    pub rate_hz: f64,
    /// I/O time of the last cycle, us.
    pub last_io_us: f64,
    /// Largest I/O time over the last display period, us.
    pub max_io_us: f64,
    /// A one-line message from the last switch.
    pub message: String,
    /// Each board's watchdog period as read from its WATCHDOG register,
    /// ms (0: off), by board ID; absent when it could not be read.
    pub watchdog_ms: Vec<(u8, f64)>,
}

impl MonitorFigures {
    /// Count one cycle that took `io_us` microseconds of I/O.
    pub fn record_cycle(&mut self, io_us: f64) {
        self.cycles += 1;
        self.last_io_us = io_us;
        self.max_io_us = self.max_io_us.max(io_us);
    }

    /// The watchdog period read for `board_id`, ms.
    pub fn watchdog_of(&self, board_id: u8) -> Option<f64> {
        self.watchdog_ms
            .iter()
            .find(|(id, _)| *id == board_id)
            .map(|&(_, ms)| ms)
    }
}

/// Every board's watchdog period from its WATCHDOG register, ms (0: off);
/// boards whose register cannot be read are left out.
pub fn watchdog_periods<P: Port>(io: &mut IoSystem<P>) -> Vec<(u8, f64)> {
    let Ok(offset) = Register::board(BoardRegister::Watchdog).offset() else {
        return Vec::new();
    };
    let ids: Vec<u8> = io.boards().iter().map(|b| b.board_id()).collect();
    ids.into_iter()
        .filter_map(|id| {
            let raw = io.read_register(id, offset).ok()?;
            Some((id, Watchdog(raw).period().as_secs_f64() * 1e3))
        })
        .collect()
}

/// What a board's STATUS says about its motor supply and its watchdog,
/// in words, for the lines under the board (none when all is well): why
/// the supply is not good, and what an expired watchdog means
/// (`watchdog_ms`: its period as read, if known).
pub fn explain_status(st: StatusRead, watchdog_ms: Option<f64>) -> Vec<String> {
    let mut lines = Vec::new();
    if !st.motor_supply_good() {
        lines.push(if !st.motor_power_enabled() {
            "supply off: motor power is not enabled (normal for idle boards)".to_string()
        } else if st.motor_supply_fault() {
            "supply FAULT: motor power is enabled but no motor supply is present".to_string()
        } else {
            "supply BAD: motor power is enabled but the motor supply is not up (still rising, \
             or too low)"
                .to_string()
        });
    }
    if st.watchdog_timeout() {
        let period = match watchdog_ms {
            Some(ms) if ms > 0.0 => {
                format!("its {} ms period", Number((ms * 1000.0).round() / 1000.0))
            }
            _ => "its period".to_string(),
        };
        lines.push(format!(
            "watchdog expired: at some point the host wrote nothing for longer than {period} \
             (normal for idle boards); it turned the amplifiers off and stays set until power \
             or an amplifier is enabled"
        ));
    }
    lines
}

/// An operator's switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Switch {
    /// Motor power of every board, on/off.
    Power,
    /// The safety relay of every board, on/off.
    Relay,
    /// Every amplifier, on/off.
    Amplifiers,
    /// Every DAC to zero and every amplifier off.
    ZeroDacs,
    /// The watchdog: [`SWITCHED_WATCHDOG_MS`] / off.
    Watchdog,
}

/// The operator's switches, as last set (all off at the start).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Switches {
    /// Motor power.
    pub power: bool,
    /// Safety relay.
    pub relay: bool,
    /// Amplifiers.
    pub amplifiers: bool,
    /// Watchdog set by the switch.
    pub watchdog: bool,
}

impl Switches {
    /// Flip `switch` on every board of `io`; the line to show. The
    /// watchdog's switch reads the periods back into `figures`.
    pub fn flip<P: Port>(
        &mut self,
        switch: Switch,
        io: &mut IoSystem<P>,
        figures: &mut MonitorFigures,
    ) -> String {
        match switch {
            Switch::Power => {
                self.power = !self.power;
                let on = self.power;
                io.boards_mut().iter_mut().for_each(|b| b.set_power(on));
                format!("power {}", on_off(on))
            }
            Switch::Relay => {
                self.relay = !self.relay;
                let on = self.relay;
                io.boards_mut().iter_mut().for_each(|b| b.set_relay(on));
                format!("relay {}", on_off(on))
            }
            Switch::Amplifiers => {
                self.amplifiers = !self.amplifiers;
                let on = self.amplifiers;
                io.boards_mut().iter_mut().for_each(|b| b.set_all_amps(on));
                format!("amplifiers {}", on_off(on))
            }
            Switch::ZeroDacs => {
                io.boards_mut().iter_mut().for_each(|b| b.safe_outputs());
                self.amplifiers = false;
                "DACs zeroed, amplifiers off".into()
            }
            Switch::Watchdog => {
                self.watchdog = !self.watchdog;
                let setting = if self.watchdog {
                    WatchdogSetting::from_ms(SWITCHED_WATCHDOG_MS).unwrap_or_default()
                } else {
                    WatchdogSetting::Off
                };
                match io.set_watchdog(setting) {
                    Ok(()) => {
                        figures.watchdog_ms = watchdog_periods(io);
                        let warn = setting
                            .warning()
                            .map_or(String::new(), |w| format!(" ({w})"));
                        format!("watchdog {setting}{warn}")
                    }
                    Err(e) => format!("watchdog: {e}"),
                }
            }
        }
    }
}

/// `on ` / `off`, three characters wide.
pub fn on_off(b: bool) -> &'static str {
    if b { "on " } else { "off" }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn idle_boards_are_explained() {
        // Power off, watchdog expired: what an idle board reports.
        let idle = StatusRead::default().with_watchdog_timeout(true);
        let lines = explain_status(idle, Some(20.0));
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert!(lines[0].starts_with("supply off: motor power is not enabled"));
        assert!(
            lines[1].contains("longer than its 20 ms period"),
            "{lines:?}"
        );
        assert!(lines[1].contains("turned the amplifiers off"), "{lines:?}");
        // Power on without a supply, and a supply still rising.
        let no_supply = StatusRead::default()
            .with_motor_power_enabled(true)
            .with_motor_supply_fault(true);
        assert!(explain_status(no_supply, None)[0].starts_with("supply FAULT"));
        let rising = StatusRead::default().with_motor_power_enabled(true);
        assert!(explain_status(rising, None)[0].starts_with("supply BAD"));
        // All well: nothing to explain.
        let good = StatusRead::default()
            .with_motor_power_enabled(true)
            .with_motor_supply_good(true);
        assert!(explain_status(good, Some(20.0)).is_empty());
    }

    #[test]
    fn figures_keep_the_largest_io_time() {
        let mut f = MonitorFigures::default();
        for us in [12.0, 40.0, 20.0] {
            f.record_cycle(us);
        }
        assert_eq!((f.cycles, f.last_io_us, f.max_io_us), (3, 20.0, 40.0));
        f.watchdog_ms = vec![(2, 20.0)];
        assert_eq!(f.watchdog_of(2), Some(20.0));
        assert_eq!(f.watchdog_of(3), None);
    }
}
