//! The analog side of every Snake channel, as the host must know it to
//! turn codes into volts and amperes: the DAC and ADC ranges of seed 001
//! §7.2, and the amplifier circuit's values.
//!
//! Seed 001 describes the amplifier in words (a bridge amplifier on one
//! motor supply, a current-sense path whose gain the digital pot sets,
//! torque or speed mode, a current limit from the DAC's second channel);
//! the component values are not given. These are Firelink's, chosen for a
//! small motor such as the Snake robot's, and used both by the emulated
//! node and by the host's conversions, so the two always agree.
//!
//! - Torque mode: the amplifier servoes the sensed current, scaled by the
//!   pot's gain `G`, to the command: `i = v / (G x SENSE_OHMS)`, with
//!   `v = V_dac - 1.25 V`.
//! - Speed mode: the motor voltage is `BRIDGE_GAIN x v + G x SENSE_OHMS x i`.
//! - Current limit: `LIMIT_AMPS_PER_VOLT x V_limit`, at most `MAX_AMPS`.
//! - Current monitor (ADC): `1.25 V + MONITOR_VOLTS_PER_AMP x i`.
//!
//! ```
//! use firelink_wire::snake::analog::{limit_code, limit_amps, torque_code, torque_amps};
//! use firelink_wire::snake::registers::Wiper;
//! let g = Wiper::NOMINAL.feedback_gain();
//! let code = torque_code(0.25, g);
//! assert!((torque_amps(code, g) - 0.25).abs() < 1e-4);
//! assert!((limit_amps(limit_code(0.5)) - 0.5).abs() < 1e-4);
//! ```

use crate::snake::registers::{DAC_MIDPOINT, adc_api_to_volts, dac_to_volts};

/// Motor supply of the bridge, V.
pub const MOTOR_SUPPLY_VOLTS: f64 = 12.0;
/// Speed mode: motor volts per volt of command (full command = supply).
pub const BRIDGE_GAIN: f64 = 9.6;
/// The current-sense resistor, ohm.
pub const SENSE_OHMS: f64 = 0.5;
/// Current limit per volt of the DAC's limit channel, A/V.
pub const LIMIT_AMPS_PER_VOLT: f64 = 0.8;
/// The current monitor the ADC reads, V/A around 1.25 V.
pub const MONITOR_VOLTS_PER_AMP: f64 = 0.5;
/// The bridge's own current ceiling, A.
pub const MAX_AMPS: f64 = 2.5;
/// The op amp's thermal fault threshold, C.
pub const FAULT_CELSIUS: f64 = 85.0;

/// Volts per DAC code.
const VOLTS_PER_CODE: f64 = 2.5 / 65536.0;

/// The nearest 16-bit code to `x` (not NaN), saturating (no `f64::round`
/// without std: clamp, then add a half and truncate).
fn round_code(x: f64) -> u16 {
    (x.clamp(0.0, 65535.0) + 0.5) as u16
}

/// The command voltage (around the 1.25 V midpoint) of a motor DAC code.
pub fn command_volts(code: u16) -> f64 {
    dac_to_volts(code) - dac_to_volts(DAC_MIDPOINT)
}

/// The motor DAC code nearest a command voltage (saturating; NaN gives
/// the midpoint).
pub fn command_code(volts: f64) -> u16 {
    if volts.is_nan() {
        return DAC_MIDPOINT;
    }
    round_code(f64::from(DAC_MIDPOINT) + volts / VOLTS_PER_CODE)
}

/// Torque mode: the current a motor code commands at feedback gain `gain`.
pub fn torque_amps(code: u16, gain: f64) -> f64 {
    command_volts(code) / (gain * SENSE_OHMS)
}

/// Torque mode: the motor code for `amps` at feedback gain `gain`.
pub fn torque_code(amps: f64, gain: f64) -> u16 {
    command_code(amps * gain * SENSE_OHMS)
}

/// Speed mode: the motor volts a code commands with no current flowing.
pub fn speed_volts(code: u16) -> f64 {
    BRIDGE_GAIN * command_volts(code)
}

/// The current limit a limit-DAC code sets, A.
pub fn limit_amps(code: u16) -> f64 {
    (dac_to_volts(code) * LIMIT_AMPS_PER_VOLT).min(MAX_AMPS)
}

/// The limit-DAC code for a current limit (saturating at the DAC's range).
pub fn limit_code(amps: f64) -> u16 {
    if amps.is_nan() || amps <= 0.0 {
        return 0;
    }
    round_code(amps / LIMIT_AMPS_PER_VOLT / VOLTS_PER_CODE)
}

/// The motor current an ADC API value (0..=16383) of the monitor means, A.
pub fn monitor_amps(api: u16) -> f64 {
    (adc_api_to_volts(api) - 1.25) / MONITOR_VOLTS_PER_AMP
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_round_trip() {
        assert_eq!(command_code(0.0), DAC_MIDPOINT);
        assert_eq!(command_code(f64::NAN), DAC_MIDPOINT);
        assert_eq!(command_code(5.0), 0xFFFF);
        assert_eq!(command_code(-5.0), 0);
        assert!((speed_volts(0xFFFF) - 12.0).abs() < 1e-3);
        assert_eq!(limit_code(-1.0), 0);
        assert!((limit_amps(0xFFFF) - 2.0).abs() < 1e-4);
        assert!((monitor_amps(8192)).abs() < 1e-12);
        assert!((monitor_amps(16383) - 2.5).abs() < 1e-3);
    }
}
