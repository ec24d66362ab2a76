//! Motor power, safety relay, amplifier enables, the watchdog and the
//! safety checks (`fpga-board.md` sections 2 and 7).
//!
//! Every state change is computed at its exact virtual time: an amplifier
//! turns on at `max(request, supply good + 40 ms hold) + enable delay`, the
//! watchdog expires at `last write + period * 256 clocks`, the current check
//! runs every [`SAFETY_TICK`] while an amplifier is on.

use firelink_wire::qla::registers::{ENC_NEUTRAL, Watchdog as WatchdogWord};

use crate::plant::QLA_AMPS_PER_BIT;
use crate::time::{SimDuration, SimTime};

/// Watchdog period after power-up: 0x1680 ticks, 30 ms (section 2).
pub const WATCHDOG_POWER_UP_TICKS: u16 = WatchdogWord::POWER_UP.0 as u16;

/// Amplifiers stay off this long after the motor supply becomes good
/// (section 7).
pub const SUPPLY_HOLD: SimDuration = SimDuration::from_millis(40);

/// Measured and commanded current may differ by this much (A) ...
pub const MISMATCH_AMPS: f64 = 0.44;

/// ... for this long before the amplifier is disabled (section 7).
pub const MISMATCH_TIME: SimDuration = SimDuration::from_millis(50);

/// How often the current check runs while an amplifier is on.
pub const SAFETY_TICK: SimDuration = SimDuration::from_micros(100);

/// One unit of the amplifier enable delay: a 48 kHz clock (1024 system
/// clocks, 20.83 us).
pub const ENABLE_DELAY_UNIT_CLOCKS: u64 = 1024;

/// The enable delay of each MOTOR_CONFIG delay code (`from_clocks` of the
/// code's clocks, worked out once at compile time: the amplifiers' enable
/// times are asked for several times per packet).
#[allow(clippy::indexing_slicing)] // `units` stays below the length.
const ENABLE_DELAYS: [SimDuration; 256] = {
    let mut delays = [SimDuration::ZERO; 256];
    let mut units = 0;
    while units < delays.len() {
        delays[units] = SimDuration::from_clocks(units as u64 * ENABLE_DELAY_UNIT_CLOCKS);
        units += 1;
    }
    delays
};

/// Default enable delay: 120 units, 2.5 ms (section 7).
pub const DEFAULT_ENABLE_DELAY: u8 = 120;

/// MOTOR_CONFIG's current limit at power-up: `0x0418` DAC counts, 200 mA
/// (Rev 8 MotorChannelQLA.v l.61). The firmware applies it only in voltage
/// control; in current control it is stored and read back.
pub const DEFAULT_CURRENT_LIMIT: u16 = 0x0418;

/// The mismatch threshold in ADC/DAC counts.
pub(crate) fn mismatch_counts() -> f64 {
    MISMATCH_AMPS / QLA_AMPS_PER_BIT
}

/// Board-wide power state.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Power {
    /// Motor power enable requested (STATUS bit 18).
    pub enabled: bool,
    /// Safety relay switched on (STATUS bit 16).
    pub relay: bool,
    /// The motor supply is connected.
    pub supply_present: bool,
    /// Since when power has been enabled with a supply present.
    pub supply_on_since: Option<SimTime>,
    /// Time from that to motor supply good.
    pub supply_rise: SimDuration,
}

impl Power {
    pub fn new(supply_present: bool, supply_rise: SimDuration) -> Power {
        Power {
            enabled: false,
            relay: false,
            supply_present,
            supply_on_since: None,
            supply_rise,
        }
    }

    /// Follow a change of `enabled` or `supply_present` made at `now`.
    pub fn update_supply(&mut self, now: SimTime) {
        let on = self.enabled && self.supply_present;
        match (on, self.supply_on_since) {
            (true, None) => self.supply_on_since = Some(now),
            (false, _) => self.supply_on_since = None,
            (true, Some(_)) => {}
        }
    }

    /// Motor supply good (STATUS bit 19) at `t`.
    pub fn supply_good(&self, t: SimTime) -> bool {
        self.supply_on_since
            .is_some_and(|s| t >= s + self.supply_rise)
    }

    /// Earliest time amplifiers may drive, if the supply is on.
    pub fn drive_allowed_from(&self) -> Option<SimTime> {
        self.supply_on_since
            .map(|s| s + self.supply_rise + SUPPLY_HOLD)
    }

    /// Motor supply fault (STATUS bit 15): power requested, no supply.
    pub fn supply_fault(&self) -> bool {
        self.enabled && !self.supply_present
    }
}

/// The watchdog (section 7).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Watchdog {
    /// Period in ticks of 256 clocks; 0 disables.
    pub ticks: u16,
    /// Register bit 31, the LED select: stored and read back, nothing
    /// else here (BoardRegs.v).
    pub led_select: bool,
    /// The last write to the board.
    pub last_write: SimTime,
    /// STATUS bit 23.
    pub timed_out: bool,
}

impl Watchdog {
    pub fn new(now: SimTime) -> Watchdog {
        Watchdog {
            ticks: WATCHDOG_POWER_UP_TICKS,
            led_select: false,
            last_write: now,
            timed_out: false,
        }
    }

    /// When the watchdog fires if nothing is written before.
    pub fn expiry(&self) -> Option<SimTime> {
        (self.ticks != 0 && !self.timed_out).then(|| {
            SimTime::from_clocks(
                self.last_write.clocks().saturating_add(
                    u64::from(self.ticks) * u64::from(WatchdogWord::CLOCKS_PER_TICK),
                ),
            )
        })
    }
}

/// Firmware state of one axis.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct AxisState {
    /// Current command, DAC code (MOTOR_STATUS 15:0).
    pub command: u16,
    /// Last ENC_PRELOAD value written.
    pub preload: u32,
    /// Reported count = raw plant count + offset (before the 24-bit wrap).
    pub count_offset: i64,
    /// Encoder counter overflow (ENC_POSITION bit 24), sticky until a
    /// preload.
    pub overflow: bool,
    /// Enable delay, 48 kHz units.
    pub enable_delay: u8,
    /// MOTOR_CONFIG 15:0 (bit 15 always 0): stored and read back; the
    /// firmware checks it only in voltage control.
    pub current_limit: u16,
    /// MOTOR_CONFIG bit 31: the current safety check is off for this axis.
    pub disable_safety: bool,
    /// MOTOR_CONFIG bit 30: the follower op amp forced on (stored).
    pub force_disable: bool,
    /// Rev 8 control mode (DAC bits 27:24 of the last accepted command):
    /// 0 current control, 1 voltage control (with an I/O expander).
    pub control_mode: u8,
    /// The plant encoder's edge count when the firmware's period
    /// measurement last started (power-up or reboot): until it moves on,
    /// the velocity words read their power-up values.
    pub edges_at_reset: u64,
    /// The host's amplifier request (cleared by safety events).
    pub requested: bool,
    /// When the request was made.
    pub requested_since: SimTime,
    /// Disabled by the current check (STATUS 7:4, MOTOR_STATUS 17).
    pub safety_disabled: bool,
    /// Since when measured and commanded current disagree.
    pub mismatch_since: Option<SimTime>,
}

impl AxisState {
    pub fn new(raw_count: i64) -> AxisState {
        AxisState {
            command: crate::plant::DAC_ZERO,
            preload: ENC_NEUTRAL,
            count_offset: i64::from(ENC_NEUTRAL) - raw_count,
            overflow: false,
            enable_delay: DEFAULT_ENABLE_DELAY,
            current_limit: DEFAULT_CURRENT_LIMIT,
            disable_safety: false,
            force_disable: false,
            control_mode: 0,
            edges_at_reset: 0,
            requested: false,
            requested_since: SimTime::ZERO,
            safety_disabled: false,
            mismatch_since: None,
        }
    }

    /// When this axis's amplifier turns (or turned) on, given the power
    /// state; `None` while it is not requested or the supply is off.
    /// Without an I/O expander (`delayed` false) the enable is not delayed
    /// (MotorChannelQLA.v).
    pub fn on_at(&self, power: &Power, delayed: bool) -> Option<SimTime> {
        if !self.requested {
            return None;
        }
        let allowed = power.drive_allowed_from()?;
        // `from_clocks(0)` is zero: no delay without an expander.
        let delay = if delayed {
            // Every u8 code has its entry.
            ENABLE_DELAYS
                .get(usize::from(self.enable_delay))
                .copied()
                .unwrap_or(SimDuration::ZERO)
        } else {
            SimDuration::ZERO
        };
        Some(self.requested_since.max(allowed) + delay)
    }

    /// Whether the amplifier drives the motor at `t`.
    pub fn is_on(&self, power: &Power, t: SimTime, delayed: bool) -> bool {
        self.on_at(power, delayed).is_some_and(|on| t >= on)
    }

    /// The DAC code reaching the amplifier: the command as written (the
    /// firmware passes it straight to the DAC; MOTOR_CONFIG's limit is no
    /// clamp).
    pub fn effective_command(&self) -> u16 {
        self.command
    }

    /// Current control (MOTOR_STATUS bit 20): any mode but 1, and mode 1
    /// only with an I/O expander (MotorChannelQLA.v l.87).
    pub fn current_control(&self, expander: bool) -> bool {
        !(expander && self.control_mode == 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table holds each delay code's duration as worked out from its
    /// clocks, and an axis with an expander waits exactly that long.
    #[test]
    fn enable_delays_are_the_codes_clocks() {
        let mut power = Power::new(true, SimDuration::from_millis(5));
        power.enabled = true;
        power.update_supply(SimTime::ZERO);
        let mut axis = AxisState::new(0);
        axis.requested = true;
        axis.requested_since = SimTime::from_millis(1000);
        let undelayed = axis.on_at(&power, false).unwrap();
        for units in 0..=u8::MAX {
            let delay = SimDuration::from_clocks(u64::from(units) * ENABLE_DELAY_UNIT_CLOCKS);
            assert_eq!(ENABLE_DELAYS[usize::from(units)], delay);
            axis.enable_delay = units;
            assert_eq!(axis.on_at(&power, true), Some(undelayed + delay));
        }
    }

    #[test]
    fn watchdog_power_up_is_30_ms() {
        let w = Watchdog::new(SimTime::ZERO);
        let e = w.expiry().unwrap();
        assert!((e.as_secs_f64() - 0.030).abs() < 1e-5, "{e:?}");
        let off = Watchdog {
            ticks: 0,
            ..Watchdog::new(SimTime::ZERO)
        };
        assert_eq!(off.expiry(), None);
    }

    #[test]
    fn amplifier_waits_for_supply_hold_and_delay() {
        let mut p = Power::new(true, SimDuration::from_millis(5));
        p.enabled = true;
        p.update_supply(SimTime::from_millis(1));
        let mut a = AxisState::new(0);
        a.requested = true;
        a.requested_since = SimTime::from_millis(1);
        let on = a.on_at(&p, true).unwrap();
        // 1 + 5 + 40 ms, then 2.5 ms delay.
        assert!((on.as_secs_f64() - 0.0485).abs() < 1e-6, "{on:?}");
        assert!(!a.is_on(&p, SimTime::from_millis(48), true));
        assert!(a.is_on(&p, SimTime::from_millis(49), true));
        p.enabled = false;
        p.update_supply(SimTime::from_millis(50));
        assert!(!a.is_on(&p, SimTime::from_millis(51), true));
    }
}
