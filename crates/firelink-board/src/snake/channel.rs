//! One amplifier channel of the Snake node: the analog side (bridge
//! amplifier in torque or speed mode, current limit, current feedback
//! through the digital potentiometer's gain), the digital potentiometer
//! itself (wiper, two outputs, 14-word EEPROM with write protection) and
//! the FPGA's encoder counter (24 bits, overflow flag, preload, period).
//!
//! The amplifier (seed 001 §5.2 describes it in words; the circuit values
//! are Firelink's, in [`AmplifierModel`]): the DAC's motor channel gives a
//! command `v = V_dac - 1.25 V`.
//! - *Torque mode* (pot output O1 low): the amplifier regulates the motor
//!   current so that the sensed current, scaled by the pot's feedback
//!   gain `G` (eq. 1), equals the command: `i = v / (G R_sense)`.
//! - *Speed mode* (O1 high): the amplifier drives the motor voltage
//!   `V_m = A_v v + G R_sense i` (the current fed back compensates the
//!   winding's resistive drop, so the speed holds under load); the current
//!   then follows the motor's own electrical equation.
//!
//! In both modes the current never exceeds the limit set by the DAC's
//! second channel, nor what the supply can push. The plant's existing
//! current-driven axis model does the rest (its current loop, motor,
//! load, encoder, pot, noise).

use firelink_wire::snake::analog::command_volts;
use firelink_wire::snake::registers::{
    ENCODER_MAX, EncoderData, EncoderPeriod, PotOutputs, Wiper, dac_to_volts,
};
use firelink_wire::snake::{EEPROM_WORDS, analog};

use crate::plant::encoder::VelocityFields;

/// The analog circuit of every channel (Firelink's values: a small
/// bridge amplifier for low-power motors such as the Snake robot's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AmplifierModel {
    /// Motor supply, V; the bridge puts at most this across the motor.
    pub supply_volts: f64,
    /// Speed mode: motor volts per volt of command.
    pub volts_per_command_volt: f64,
    /// The current-sense resistor, ohm (multiplied by the pot's gain).
    pub sense_ohms: f64,
    /// Current limit: amperes per volt of the DAC's limit channel.
    pub limit_amps_per_volt: f64,
    /// The current monitor the ADC reads: volts per ampere around 1.25 V.
    pub monitor_volts_per_amp: f64,
    /// Hardware ceiling of the bridge's current, A.
    pub max_amps: f64,
    /// Temperature at which the op amp's thermal fault line asserts, C.
    pub fault_celsius: f64,
}

impl Default for AmplifierModel {
    /// The values of [`firelink_wire::snake::analog`] (which the host's
    /// conversions use): 12 V bridge, 9.6 V/V (full command = full
    /// supply), 0.5 ohm sense (1.25 A full scale in torque mode at the
    /// nominal gain of 2), limit 0.8 A/V (2 A at 2.5 V), monitor 0.5 V/A
    /// (+-2.5 A), 85 C thermal fault.
    fn default() -> Self {
        AmplifierModel {
            supply_volts: analog::MOTOR_SUPPLY_VOLTS,
            volts_per_command_volt: analog::BRIDGE_GAIN,
            sense_ohms: analog::SENSE_OHMS,
            limit_amps_per_volt: analog::LIMIT_AMPS_PER_VOLT,
            monitor_volts_per_amp: analog::MONITOR_VOLTS_PER_AMP,
            max_amps: analog::MAX_AMPS,
            fault_celsius: analog::FAULT_CELSIUS,
        }
    }
}

impl AmplifierModel {
    /// The current limit a DAC code sets, A.
    pub fn limit_amps(&self, limit_code: u16) -> f64 {
        (dac_to_volts(limit_code) * self.limit_amps_per_volt).min(self.max_amps)
    }

    /// Torque mode: the current a motor command asks for at `gain`, A.
    pub fn torque_amps(&self, command: u16, gain: f64) -> f64 {
        command_volts(command) / (gain * self.sense_ohms)
    }

    /// Speed mode: the current the motor draws with the compensated drive
    /// voltage (`current` now, back-EMF `emf`, winding `resistance`), A.
    pub fn speed_amps(
        &self,
        command: u16,
        gain: f64,
        current: f64,
        emf: f64,
        resistance: f64,
    ) -> f64 {
        let drive =
            self.volts_per_command_volt * command_volts(command) + gain * self.sense_ohms * current;
        let volts = drive.clamp(-self.supply_volts, self.supply_volts);
        (volts - emf) / resistance.max(1e-3)
    }

    /// The ADC sample of the current monitor for `amps` (14-bit, signed).
    pub fn monitor_sample(&self, amps: f64) -> i16 {
        volts_to_sample(self.monitor_volts_per_amp * amps)
    }
}

/// The 14-bit signed sample of a voltage around 1.25 V (saturating).
pub fn volts_to_sample(volts_from_mid: f64) -> i16 {
    if !volts_from_mid.is_finite() {
        return 0;
    }
    (volts_from_mid / 2.5 * 16384.0)
        .round()
        .clamp(-8192.0, 8191.0) as i16
}

/// The digital potentiometer of one channel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DigitalPot {
    /// The wiper.
    pub wiper: Wiper,
    /// The two digital outputs.
    pub outputs: PotOutputs,
    /// The user EEPROM.
    pub eeprom: [u16; EEPROM_WORDS],
    /// EEPROM writes refused while set.
    pub write_protect: bool,
}

impl Default for DigitalPot {
    /// Power-up: the nominal wiper, torque mode, an empty EEPROM,
    /// write-protected.
    fn default() -> Self {
        DigitalPot {
            wiper: Wiper::NOMINAL,
            outputs: PotOutputs::default(),
            eeprom: [0; EEPROM_WORDS],
            write_protect: true,
        }
    }
}

/// The FPGA's encoder counter of one channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EncoderCounter {
    /// Raw plant count at the last preload.
    pub base_raw: i64,
    /// Value preloaded then.
    pub preload: u32,
    /// Count went outside 0..=0xFFFFFF since the preload.
    pub overflow: bool,
}

impl EncoderCounter {
    /// The counter after a preload of `value` when the plant's raw count
    /// is `raw`.
    pub fn preloaded(raw: i64, value: u32) -> EncoderCounter {
        EncoderCounter {
            base_raw: raw,
            preload: value & ENCODER_MAX,
            overflow: false,
        }
    }

    /// The unwrapped count for a raw plant count.
    fn unwrapped(&self, raw: i64) -> i64 {
        i64::from(self.preload) + (raw - self.base_raw)
    }

    /// Note the count at `raw` (sets the sticky overflow flag when it is
    /// outside the 24-bit range).
    pub fn observe(&mut self, raw: i64) {
        let c = self.unwrapped(raw);
        if !(0..=i64::from(ENCODER_MAX)).contains(&c) {
            self.overflow = true;
        }
    }

    /// The encoder data register at `raw`.
    pub fn data(&self, raw: i64) -> EncoderData {
        let c = self.unwrapped(raw).rem_euclid(1 << 24) as u32;
        let overflow =
            self.overflow || !(0..=i64::from(ENCODER_MAX)).contains(&self.unwrapped(raw));
        EncoderData::default().with_count(c).with_overflow(overflow)
    }
}

/// The encoder period register from the encoder's edge timing: the last
/// interval between edges (or, while none comes, the time since the last
/// edge, so a stopping motor shows a growing period) in 768 kHz ticks,
/// signed by the direction, saturating at +-32767.
pub fn period_register(fields: &VelocityFields) -> EncoderPeriod {
    const CLOCKS_PER_TICK: u32 = 64;
    let q = fields.qtr1;
    if q.overflow || q.clocks == 0 {
        return EncoderPeriod::from_ticks(i16::MAX);
    }
    let clocks = q.clocks.max(if fields.run.overflow {
        u32::MAX
    } else {
        fields.run.clocks
    });
    let ticks = (clocks / CLOCKS_PER_TICK).clamp(1, i16::MAX as u32) as i16;
    EncoderPeriod::from_ticks(if q.up { ticks } else { -ticks })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::encoder::{QuarterField, RunField};
    use firelink_wire::snake::registers::DAC_MIDPOINT;

    #[test]
    fn torque_mode_scales_with_the_gain() {
        let m = AmplifierModel::default();
        // Full positive command at the nominal gain: ~1.24 A.
        let i = m.torque_amps(0xFFFF, Wiper::NOMINAL.feedback_gain());
        assert!((i - 1.242).abs() < 0.01, "{i}");
        assert_eq!(m.torque_amps(DAC_MIDPOINT, 2.0), 0.0);
        assert!(m.torque_amps(0, 2.0) < 0.0);
        assert!((m.limit_amps(0xFFFF) - 2.0).abs() < 1e-3);
        assert_eq!(m.limit_amps(0), 0.0);
    }

    #[test]
    fn speed_mode_compensates_the_resistance() {
        let m = AmplifierModel::default();
        // At standstill with no current: V/R.
        let i0 = m.speed_amps(0xC000, 2.0, 0.0, 0.0, 10.0);
        assert!((i0 - 9.6 * 0.625 / 10.0).abs() < 1e-3);
        // Current already flowing raises the drive (positive feedback).
        assert!(m.speed_amps(0xC000, 2.0, 0.5, 0.0, 10.0) > i0);
        // Back-EMF reduces it.
        assert!(m.speed_amps(0xC000, 2.0, 0.0, 3.0, 10.0) < i0);
    }

    #[test]
    fn encoder_counter_wraps_and_flags() {
        let mut c = EncoderCounter::preloaded(100, 0x80_0000);
        assert_eq!(c.data(105).count(), 0x80_0005);
        assert!(!c.data(105).overflow());
        c = EncoderCounter::preloaded(0, 2);
        assert_eq!(c.data(-3).count(), 0xFF_FFFF);
        assert!(c.data(-3).overflow());
        c.observe(-3);
        // Sticky after coming back.
        assert!(c.data(0).overflow());
        assert!(!EncoderCounter::preloaded(0, 2).data(0).overflow());
    }

    #[test]
    fn period_in_768_khz_ticks() {
        let mut f = VelocityFields {
            qtr1: QuarterField {
                clocks: 64 * 100,
                overflow: false,
                up: false,
                edge_mask: 1,
            },
            run: RunField {
                clocks: 10,
                overflow: false,
            },
            ..VelocityFields::default()
        };
        assert_eq!(period_register(&f).ticks(), -100);
        // No edge for longer than the last interval: the running count.
        f.run.clocks = 64 * 300;
        assert_eq!(period_register(&f).ticks(), -300);
        f.qtr1.overflow = true;
        assert_eq!(period_register(&f).ticks(), i16::MAX);
    }
}
