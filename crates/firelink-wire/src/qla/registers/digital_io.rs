//! Digital I/O (`fpga-board.md` §2): DIGITAL_IN's per-axis masks, the
//! DIGITAL_OUT write and read words, DOUT_CTRL and the waveform table entries.

use super::*;

quadlet_register! {
    /// DIGITAL_IN (`fpga-board.md` §2): 4-bit masks, bit i = axis i + 1.
    pub struct DigitalIn {
        /// Motor supply voltage fault, bit 31.
        v_fault, set_v_fault, with_v_fault: bool = field::DIN_V_FAULT;
        /// The waveform table drives outputs (register 6 bit 31), bit 29
        /// (`fpga-board-extras.md` §3).
        waveform_active, set_waveform_active, with_waveform_active: bool = field::DIN_WAVEFORM;
        /// Motor-supply comparator, bit 28: 1 = the axis 4 DAC voltage is
        /// below the motor supply (`fpga-board-extras.md` §7).
        supply_comparator, set_supply_comparator, with_supply_comparator: bool =
            field::DIN_SUPPLY_COMPARATOR;
        /// Encoder A lines, bits 27:24.
        enc_a, set_enc_a, with_enc_a: u8 = field::DIN_ENC_A;
        /// Encoder B lines, bits 23:20.
        enc_b, set_enc_b, with_enc_b: u8 = field::DIN_ENC_B;
        /// Encoder index lines, bits 19:16.
        index, set_index, with_index: u8 = field::DIN_INDEX;
        /// Digital outputs as stored (raw, not inverted), bits 15:12.
        outputs, set_outputs, with_outputs: u8 = field::DIN_OUTPUTS;
        /// Negative limit switches, bits 11:8.
        neg_limits, set_neg_limits, with_neg_limits: u8 = field::DIN_NEG_LIMITS;
        /// Positive limit switches, bits 7:4.
        pos_limits, set_pos_limits, with_pos_limits: u8 = field::DIN_POS_LIMITS;
        /// Home switches, bits 3:0.
        home, set_home, with_home: u8 = field::DIN_HOME;
    }
}

/// A DIGITAL_OUT write (register 6, `fpga-board-extras.md` §3): bits 11:8
/// the outputs to change, bits 3:0 their new values *as stored* (the
/// firmware keeps exactly the bits written), bit 31 play the waveform table
/// on the masked outputs. Output pins invert the stored value, so the
/// reference host writes the complement of the levels it means
/// ([`levels`](Self::levels)): raw 1 = output low.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct DigitalOutWrite {
    /// Outputs to change (bit i = DOUT i+1), 4 bits.
    pub mask: u8,
    /// Their stored (raw) values, 4 bits; bits outside `mask` are ignored
    /// by the board.
    pub raw: u8,
    /// Play the waveform table on the masked outputs (bit 31).
    pub play_waveform: bool,
}

impl DigitalOutWrite {
    /// Decode the written word; bits outside the encoding are ignored.
    pub fn parse(word: u32) -> DigitalOutWrite {
        DigitalOutWrite {
            mask: field::DOUT_MASK.extract(word) as u8,
            raw: field::DOUT_RAW.extract(word) as u8,
            play_waveform: field::DOUT_PLAY.extract(word) != 0,
        }
    }

    /// Encode as the written word (mask and values cut to 4 bits).
    pub fn to_word(self) -> u32 {
        let w = field::DOUT_MASK.insert(0, u32::from(self.mask));
        let w = field::DOUT_RAW.insert(w, u32::from(self.raw));
        field::DOUT_PLAY.insert(w, u32::from(self.play_waveform))
    }

    /// Set the masked outputs to `levels` as the reference host means them
    /// (`WriteDigitalOutput`): it sends `mask<<8 | (~levels & mask)`.
    pub fn levels(mask: u8, levels: u8) -> DigitalOutWrite {
        DigitalOutWrite {
            mask: mask & 0xF,
            raw: !levels & mask & 0xF,
            play_waveform: false,
        }
    }

    /// Start the waveform table on the masked outputs, leaving them at
    /// `levels` when it stops (`WriteWaveformControl`: `0x80000000 |
    /// mask<<8 | (~levels & mask)`; a zero mask sends no bit 31, which
    /// stops playback).
    pub fn waveform(mask: u8, levels: u8) -> DigitalOutWrite {
        DigitalOutWrite {
            play_waveform: mask & 0xF != 0,
            ..DigitalOutWrite::levels(mask, levels)
        }
    }

    /// The levels the masked outputs are set to, as the host means them.
    pub fn output_levels(self) -> u8 {
        !self.raw & self.mask & 0xF
    }
}

quadlet_register! {
    /// DIGITAL_OUT as read (register 6, `fpga-board-extras.md` §3).
    pub struct DigitalOutRead {
        /// The waveform table drives at least one output, bit 31.
        table_active, set_table_active, with_table_active: bool = field::DOUT_TABLE_ACTIVE;
        /// Same, and the current entry is valid, bit 30.
        table_valid, set_table_valid, with_table_valid: bool = field::DOUT_TABLE_VALID;
        /// Current table index, bits 25:16.
        table_index, set_table_index, with_table_index: u16 = field::DOUT_TABLE_INDEX;
        /// Extra I/O, bits 11:8 (FPGA V3.1 only, else 0).
        extra_io, set_extra_io, with_extra_io: u8 = field::DOUT_EXTRA_IO;
        /// The outputs as stored (raw), bits 3:0.
        outputs, set_outputs, with_outputs: u8 = field::DOUT_RAW;
    }
}

quadlet_register! {
    /// DOUT_CTRL (axis offset 8, `fpga-board-extras.md` §3): how long the
    /// raw output stays 1 and 0, in 49.152 MHz clocks; 0 = forever. Both
    /// non-zero: PWM; one non-zero: one-shot.
    pub struct DoutCtrl {
        /// Clocks the raw output stays 1, bits 31:16.
        high_time, set_high_time, with_high_time: u16 = field::DOUT_CTRL_HIGH;
        /// Clocks the raw output stays 0, bits 15:0.
        low_time, set_low_time, with_low_time: u16 = field::DOUT_CTRL_LOW;
    }
}

quadlet_register! {
    /// One entry of the digital-output waveform table (space 8,
    /// `fpga-board-extras.md` §3). The entry lasts `end_count + 1` clocks;
    /// playback stops at the first entry without the valid bit.
    pub struct WaveformEntry {
        /// Valid (playback continues), bit 31.
        valid, set_valid, with_valid: bool = field::WAVE_VALID;
        /// End count, bits 30:8 (`0x7FFFFF` = 170.7 ms).
        end_count, set_end_count, with_end_count: u32 = field::WAVE_END_COUNT;
        /// Raw output values (bit i -> DOUT i+1), bits 7:0.
        outputs, set_outputs, with_outputs: u8 = field::WAVE_OUTPUTS;
    }
}

impl WaveformEntry {
    /// Clocks the entry lasts: `end_count + 1`.
    pub fn clocks(self) -> u64 {
        u64::from(self.end_count()) + 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digital_out_stores_raw_bits() {
        // The host's WriteDigitalOutput(0xF, levels 0b0101) sends the
        // complement; the board stores it as written.
        let w = DigitalOutWrite::levels(0x0F, 0b0101);
        assert_eq!(w.to_word(), 0x0F0A);
        assert_eq!(DigitalOutWrite::parse(0x0F0A), w);
        assert_eq!(w.raw, 0xA);
        assert_eq!(w.output_levels(), 0b0101);
        // Issue 13: writing 0x0F0E stores 0xE.
        assert_eq!(DigitalOutWrite::parse(0x0F0E).raw, 0xE);
        // Outputs outside the mask are not sent.
        assert_eq!(DigitalOutWrite::levels(0x01, 0xFF).to_word(), 0x0100);
        // WriteWaveformControl(0x03, 0x03).
        assert_eq!(DigitalOutWrite::waveform(0x3, 0x3).to_word(), 0x8000_0300);
        assert_eq!(DigitalOutWrite::waveform(0, 0xF).to_word(), 0);
        let r = DigitalOutRead::default()
            .with_table_active(true)
            .with_table_index(0x3FF)
            .with_outputs(0xE);
        assert_eq!(r.raw(), 0x83FF_000E);
        let e = WaveformEntry(0x80C0_0003);
        assert!(e.valid());
        assert_eq!(e.clocks(), 0xC000 + 1);
        assert_eq!(e.outputs(), 3);
        assert_eq!(DoutCtrl(0x0001_0002).high_time(), 1);
    }
}
