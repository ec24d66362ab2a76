//! The digital outputs (`fpga-board-extras.md` §3) as the reference host
//! means them: levels, not the raw bits the board stores. The host writes
//! the complement (`WriteDigitalOutput`), reads back and complements
//! again, swaps the PWM times, and XORs waveform entries with `0xF`; the
//! board keeps everything verbatim.

use firelink_wire::phy::SYSTEM_CLOCK_HZ;
use firelink_wire::qla::address::{AxisRegister, BoardRegister, Register};
use firelink_wire::qla::extras::WAVEFORM_TABLE_OFFSET;
use firelink_wire::qla::registers::{DigitalOutRead, DigitalOutWrite, DoutCtrl};

use super::{FeatureError, Result, board_register};
use crate::port::{Dest, Port};

/// Digital outputs of a QLA.
pub const OUTPUTS: u8 = 4;
/// Entries of the waveform table.
pub const WAVEFORM_ENTRIES: usize = 1024;
/// Quadlets per waveform block transfer: 1 KiB, within every limit (a
/// board takes writes of up to 2024 bytes; an Ethernet host with a 1500
/// MTU sends at most 1446).
const TABLE_CHUNK: usize = 256;
/// `WritePWM` refuses frequencies at or below this (the 16-bit times
/// would overflow).
pub const PWM_MIN_HZ: f64 = 375.0;

/// Set the outputs of `mask` to `levels` (bit i = DOUT i+1).
///
/// # Errors
/// Transaction failures.
pub fn write_digital_outputs<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    mask: u8,
    levels: u8,
) -> Result<()> {
    let w = DigitalOutWrite::levels(mask, levels);
    port.write_quadlet(dest, board_register(BoardRegister::DigitalOut), w.to_word())?;
    Ok(())
}

/// Register 6 as read: waveform status and the raw outputs.
///
/// # Errors
/// Transaction failures.
pub fn read_digital_out_register<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
) -> Result<DigitalOutRead> {
    Ok(DigitalOutRead(port.read_quadlet(
        dest,
        board_register(BoardRegister::DigitalOut),
    )?))
}

/// The output levels (the complement of the raw bits register 6 holds).
///
/// # Errors
/// Transaction failures.
pub fn read_digital_outputs<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<u8> {
    Ok(!read_digital_out_register(port, dest)?.outputs() & 0xF)
}

fn dout_ctrl_offset(output: u8) -> Result<u64> {
    if output >= OUTPUTS {
        return Err(FeatureError::Invalid {
            what: "digital output (0..=3)",
            value: u32::from(output),
        });
    }
    Ok(Register::axis(output + 1, AxisRegister::DoutCtrl).offset()?)
}

/// Set the times output `output` (0..=3) stays high and low, in clocks
/// (0 = forever; both non-zero = PWM, one = one-shot). The board counts
/// raw values, so the host swaps the halves: `low << 16 | high`.
///
/// # Errors
/// Transaction failures; an output beyond 3.
pub fn write_dout_control<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    output: u8,
    high_clocks: u16,
    low_clocks: u16,
) -> Result<()> {
    let word = DoutCtrl::default()
        .with_high_time(low_clocks)
        .with_low_time(high_clocks);
    port.write_quadlet(dest, dout_ctrl_offset(output)?, word.raw())?;
    Ok(())
}

/// The times output `output` stays high and low, in clocks.
///
/// # Errors
/// Transaction failures; an output beyond 3.
pub fn read_dout_control<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    output: u8,
) -> Result<(u16, u16)> {
    let w = DoutCtrl(port.read_quadlet(dest, dout_ctrl_offset(output)?)?);
    Ok((w.low_time(), w.high_time()))
}

/// Clocks of a PWM: (high, low) for `freq_hz` and `duty` (0..=1), as
/// `WritePWM` computes them (rounded).
///
/// # Errors
/// [`FeatureError::Invalid`] for a frequency at or below 375 Hz, a duty
/// outside 0..=1, or times beyond 16 bits.
pub fn pwm_clocks(freq_hz: f64, duty: f64) -> Result<(u16, u16)> {
    if freq_hz.is_nan() || freq_hz <= PWM_MIN_HZ || !(0.0..=1.0).contains(&duty) {
        return Err(FeatureError::Invalid {
            what: "PWM frequency (> 375 Hz) or duty (0..=1)",
            value: freq_hz as u32,
        });
    }
    let clock = f64::from(SYSTEM_CLOCK_HZ);
    let high = (duty / freq_hz * clock + 0.5).floor();
    let low = ((1.0 - duty) / freq_hz * clock + 0.5).floor();
    if high > 65535.0 || low > 65535.0 {
        return Err(FeatureError::Invalid {
            what: "PWM time beyond 65535 clocks",
            value: high.max(low) as u32,
        });
    }
    Ok((high as u16, low as u16))
}

/// Run output `output` as a PWM of `freq_hz` with `duty` high (`WritePWM`):
/// the times, then a write that restarts the output's timer.
///
/// # Errors
/// As [`pwm_clocks`]; transaction failures.
pub fn write_pwm<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    output: u8,
    freq_hz: f64,
    duty: f64,
) -> Result<()> {
    let (high, low) = pwm_clocks(freq_hz, duty)?;
    write_dout_control(port, dest, output, high, low)?;
    write_digital_outputs(port, dest, 1 << output, 1 << output)
}

/// Write waveform entries from `offset` (`WriteWaveformTable`): each value
/// XOR `0xF` (levels to raw), in block writes of at most 256 quadlets.
///
/// # Errors
/// Transaction failures; entries beyond the table.
pub fn write_waveform_table<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    offset: usize,
    entries: &[u32],
) -> Result<()> {
    check_table(offset, entries.len())?;
    let mut bytes = Vec::with_capacity(TABLE_CHUNK * 4);
    for (k, chunk) in entries.chunks(TABLE_CHUNK).enumerate() {
        bytes.clear();
        bytes.extend(chunk.iter().flat_map(|e| (e ^ 0xF).to_be_bytes()));
        let at = WAVEFORM_TABLE_OFFSET + (offset + k * TABLE_CHUNK) as u64;
        port.write_block(dest, at, &bytes)?;
    }
    Ok(())
}

/// Read waveform entries from `offset` (`ReadWaveformTable`), XOR `0xF`.
/// While the table plays, the board answers every address with the
/// current entry.
///
/// # Errors
/// Transaction failures; entries beyond the table.
pub fn read_waveform_table<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    offset: usize,
    out: &mut [u32],
) -> Result<()> {
    check_table(offset, out.len())?;
    let mut bytes = vec![0u8; TABLE_CHUNK * 4];
    for (k, chunk) in out.chunks_mut(TABLE_CHUNK).enumerate() {
        let buf = &mut bytes[..chunk.len() * 4];
        let at = WAVEFORM_TABLE_OFFSET + (offset + k * TABLE_CHUNK) as u64;
        port.read_block(dest, at, buf)?;
        for (e, q) in chunk.iter_mut().zip(buf.chunks_exact(4)) {
            *e = u32::from_be_bytes([q[0], q[1], q[2], q[3]]) ^ 0xF;
        }
    }
    Ok(())
}

fn check_table(offset: usize, len: usize) -> Result<()> {
    if len == 0 || offset + len > WAVEFORM_ENTRIES {
        return Err(FeatureError::Invalid {
            what: "waveform entries beyond the 1024-entry table",
            value: (offset + len) as u32,
        });
    }
    Ok(())
}

/// Start the table on the outputs of `mask`, leaving them at `levels`
/// when it stops (`WriteWaveformControl`); a zero mask stops playback.
///
/// # Errors
/// Transaction failures.
pub fn start_waveform<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    mask: u8,
    levels: u8,
) -> Result<()> {
    let w = DigitalOutWrite::waveform(mask, levels);
    port.write_quadlet(dest, board_register(BoardRegister::DigitalOut), w.to_word())?;
    Ok(())
}

/// Whether the table is playing and its current index
/// (`ReadWaveformStatus`).
///
/// # Errors
/// Transaction failures.
pub fn waveform_status<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<(bool, u16)> {
    let r = read_digital_out_register(port, dest)?;
    Ok((r.table_active(), r.table_index()))
}
