//! The motor supply voltage, measured through the QLA 1.5's comparator
//! (`fpga-board-extras.md` §7): the reference host's
//! `MeasureMotorSupplyVoltage`, for a QLA1 and for each QLA of a DQLA
//! (MotorVoltage.cpp's `index` 1 and 2: DAC 4 or DAC 8, the expander in
//! STATUS bit `index - 1`, the comparator in STATUS bit `index << 4`,
//! AmpIO.cpp).

use std::time::Duration;

use firelink_wire::qla::address::{AxisRegister, BoardRegister, Register};
use firelink_wire::qla::registers::{
    DigitalIn, STATUS_POWER_OFF, STATUS_POWER_ON, STATUS_RELAY_ON, StatusCommand, StatusRead,
};

use super::{FeatureError, Result, board_register};
use crate::port::{Dest, Port};

/// Volts per count of the axis-4 DAC at the comparator (2.5 V over 16
/// bits, divider 21).
pub const VOLTS_PER_COUNT: f64 = 2.5 / 65535.0 * 21.0;
/// The nominal supply `dvrktest` expects of board `board_id` (0 = not
/// checked).
pub fn nominal_volts(board_id: u8) -> f64 {
    match board_id {
        1 | 3 => 12.0,
        4 | 5 => 36.0,
        0 | 2 | 6..=11 => 24.0,
        12 => 48.0,
        _ => 0.0,
    }
}

/// Measure the motor supply of one board: relay and power on, amplifiers
/// off, 1 s; then step the axis-4 DAC (valid bit, no enable) up from 0 by
/// `0x1000` while the comparator (DIGIN bit 28) says the DAC is below the
/// supply, stepping back and halving the step each time it is not, down
/// to 1 count; 1 ms after each write. Ends with the DAC at zero current
/// and power off. Returns volts.
///
/// # Errors
/// Transaction failures; [`FeatureError::Unavailable`] before firmware
/// Rev 8, without the I/O expander (QLA 1.5), or when the supply is not
/// good after 1 s.
pub fn measure_motor_supply_voltage<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<f64> {
    measure(port, dest, Comparator::Qla1)
}

/// [`measure_motor_supply_voltage`] for QLA `qla` (1 or 2) of a DQLA:
/// its last DAC (axis 4 or 8) against its supply, read in STATUS.
///
/// # Errors
/// As [`measure_motor_supply_voltage`]; [`FeatureError::Invalid`] for a
/// QLA other than 1 or 2.
pub fn measure_dqla_supply_voltage<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    qla: u8,
) -> Result<f64> {
    if !matches!(qla, 1 | 2) {
        return Err(FeatureError::Invalid {
            what: "DQLA QLA index (1 or 2)",
            value: u32::from(qla),
        });
    }
    measure(port, dest, Comparator::Dqla(qla))
}

/// Where a board's supply comparator is: a QLA1's DIGIN bit 28 behind DAC
/// 4, or a DQLA's QLA `n` in STATUS behind DAC `4n`.
#[derive(Debug, Clone, Copy)]
enum Comparator {
    Qla1,
    Dqla(u8),
}

impl Comparator {
    /// The DAC the search steps (axis 4, or 8 for a DQLA's QLA 2).
    fn dac(self) -> u64 {
        let axis = match self {
            Comparator::Qla1 | Comparator::Dqla(1) => 4,
            Comparator::Dqla(_) => 8,
        };
        Register::axis(axis, AxisRegister::Dac)
            .offset()
            .unwrap_or(u64::from(axis) << 4 | 1)
    }

    /// Whether STATUS says the QLA has its I/O expander.
    fn expanded(self, status: u32) -> bool {
        match self {
            Comparator::Qla1 => StatusRead(status).io_expander(),
            Comparator::Dqla(n) => status & (1 << (n - 1)) != 0,
        }
    }

    /// Whether the DAC is below the supply now.
    fn below<P: Port + ?Sized>(self, port: &mut P, dest: Dest) -> Result<bool> {
        Ok(match self {
            Comparator::Qla1 => {
                let din = board_register(BoardRegister::DigitalIn);
                DigitalIn(port.read_quadlet(dest, din)?).supply_comparator()
            }
            Comparator::Dqla(n) => {
                let status = board_register(BoardRegister::Status);
                port.read_quadlet(dest, status)? & (u32::from(n) << 4) != 0
            }
        })
    }
}

fn measure<P: Port + ?Sized>(port: &mut P, dest: Dest, comparator: Comparator) -> Result<f64> {
    let fw = port.read_quadlet(dest, board_register(BoardRegister::FwVersion))?;
    if fw < 8 {
        return Err(FeatureError::Unavailable {
            what: "motor supply measurement",
            why: "needs firmware Rev 8",
        });
    }
    let status = board_register(BoardRegister::Status);
    if !comparator.expanded(port.read_quadlet(dest, status)?) {
        return Err(FeatureError::Unavailable {
            what: "motor supply measurement",
            why: "needs a QLA 1.5+ (I/O expander)",
        });
    }
    port.write_quadlet(dest, status, STATUS_RELAY_ON)?;
    port.write_quadlet(dest, status, STATUS_POWER_ON)?;
    port.write_quadlet(
        dest,
        status,
        StatusCommand::amplifiers(0xF, 0).to_word().raw(),
    )?;
    port.wait(Duration::from_secs(1));
    let result = search(port, dest, comparator);
    // Whatever happened: zero current, power off.
    let _ = port.write_quadlet(dest, comparator.dac(), 0x8000_8000);
    let _ = port.write_quadlet(dest, status, STATUS_POWER_OFF);
    result
}

fn search<P: Port + ?Sized>(port: &mut P, dest: Dest, comparator: Comparator) -> Result<f64> {
    let status = board_register(BoardRegister::Status);
    if !StatusRead(port.read_quadlet(dest, status)?).motor_supply_good() {
        return Err(FeatureError::Unavailable {
            what: "motor supply measurement",
            why: "the motor supply is not good after 1 s",
        });
    }
    let dac = comparator.dac();
    let mut v: u32 = 0;
    let mut step: u32 = 0x1000;
    loop {
        port.write_quadlet(dest, dac, 0x8000_0000 | v)?;
        port.wait(Duration::from_millis(1));
        let below = comparator.below(port, dest)?;
        if below {
            if v >= 0xFFFF {
                return Err(FeatureError::Result {
                    what: "motor supply above the DAC's range",
                    expected: 0xFFFF,
                    found: v,
                });
            }
            v = (v + step).min(0xFFFF);
        } else {
            if step == 1 || v == 0 {
                break;
            }
            v = v.saturating_sub(step);
            step /= 2;
            v += step;
        }
    }
    Ok(f64::from(v) * VOLTS_PER_COUNT)
}
