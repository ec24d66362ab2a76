//! PARAMETER's records: the gear ratio, PID gains and limits a module needs
//! before READY, as single-precision floats in one record per module, sent
//! point-to-point or as a broadcast block of records.

use super::*;

/// One motor controller's parameters in PARAMETER: 32 bytes.
///
/// | quadlet | content |
/// |---|---|
/// | 0 | `31:24` module ID, `23:0` zero |
/// | 1 | gear ratio (f32, motor turns per joint turn) |
/// | 2..4 | PID gains kp (Nm/rad), ki (Nm/(rad s)), kd (Nm s/rad) (f32) |
/// | 5, 6 | position limits, rad (f32, lower < upper) |
/// | 7 | torque limit, Nm (f32, above 0) |
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParameterRecord {
    /// The module the record is for.
    pub mod_id: ModId,
    /// Gear ratio (motor turns per joint turn), above 0.
    pub gear_ratio: f32,
    /// Proportional gain, Nm/rad.
    pub kp: f32,
    /// Integral gain, Nm/(rad s).
    pub ki: f32,
    /// Derivative gain, Nm s/rad.
    pub kd: f32,
    /// Lower position limit, rad.
    pub position_min: f32,
    /// Upper position limit, rad.
    pub position_max: f32,
    /// Joint torque limit, Nm.
    pub torque_max: f32,
}

mod parameter_field {
    use super::Field;
    pub const MOD_ID: Field = Field::new(0, 31, 24);
    pub const RESERVED: Field = Field::new(0, 23, 0);
    pub const GEAR: Field = Field::quadlet(1);
    pub const KP: Field = Field::quadlet(2);
    pub const KI: Field = Field::quadlet(3);
    pub const KD: Field = Field::quadlet(4);
    pub const POSITION_MIN: Field = Field::quadlet(5);
    pub const POSITION_MAX: Field = Field::quadlet(6);
    pub const TORQUE_MAX: Field = Field::quadlet(7);
}

impl ParameterRecord {
    /// Bytes of one record.
    pub const LEN: usize = 32;
    /// Most records in one PARAMETER block.
    pub const MAX_RECORDS: usize = ModId::LIMIT as usize;

    /// Check that the values mean something: finite, gear ratio and torque
    /// limit above 0, gains not negative, lower limit below upper.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &'static str, v: f32| Error::InvalidValue {
            what,
            value: v.to_bits(),
        };
        let fields = [
            ("gear ratio", self.gear_ratio),
            ("kp", self.kp),
            ("ki", self.ki),
            ("kd", self.kd),
            ("lower position limit", self.position_min),
            ("upper position limit", self.position_max),
            ("torque limit", self.torque_max),
        ];
        for (what, v) in fields {
            if !v.is_finite() {
                return Err(bad(what, v));
            }
        }
        if self.gear_ratio <= 0.0 {
            return Err(bad("gear ratio", self.gear_ratio));
        }
        for (what, v) in [("kp", self.kp), ("ki", self.ki), ("kd", self.kd)] {
            if v < 0.0 {
                return Err(bad(what, v));
            }
        }
        if self.position_min >= self.position_max {
            return Err(bad("lower position limit", self.position_min));
        }
        if self.torque_max <= 0.0 {
            return Err(bad("torque limit", self.torque_max));
        }
        Ok(())
    }

    /// Decode one record (exactly [`ParameterRecord::LEN`] bytes) and
    /// [validate](Self::validate) it.
    ///
    /// # Errors
    /// Length errors, [`Error::Malformed`] with reserved bits set,
    /// [`Error::FieldRange`] for a module ID past the limit, and what
    /// [`validate`](Self::validate) finds.
    pub fn parse(buf: &[u8]) -> Result<ParameterRecord> {
        use parameter_field as f;
        check_len("PARAMETER record", buf, Self::LEN)?;
        if f::RESERVED.get(buf) != 0 {
            return Err(Error::Malformed {
                what: "PARAMETER record quadlet 0",
                value: read_quadlet(buf, 0),
            });
        }
        let float = |field: Field| f32::from_bits(field.get(buf));
        let record = ParameterRecord {
            mod_id: ModId(f::MOD_ID.get(buf) as u8).check()?,
            gear_ratio: float(f::GEAR),
            kp: float(f::KP),
            ki: float(f::KI),
            kd: float(f::KD),
            position_min: float(f::POSITION_MIN),
            position_max: float(f::POSITION_MAX),
            torque_max: float(f::TORQUE_MAX),
        };
        record.validate()?;
        Ok(record)
    }

    /// Encode into the first [`ParameterRecord::LEN`] bytes of `buf`.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`], what [`validate`](Self::validate) finds,
    /// a module ID past the limit.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        use parameter_field as f;
        let buf = out_slice("PARAMETER record", buf, Self::LEN)?;
        self.mod_id.check()?;
        self.validate()?;
        f::MOD_ID.set(buf, u32::from(self.mod_id.0));
        f::RESERVED.set(buf, 0);
        f::GEAR.set(buf, self.gear_ratio.to_bits());
        f::KP.set(buf, self.kp.to_bits());
        f::KI.set(buf, self.ki.to_bits());
        f::KD.set(buf, self.kd.to_bits());
        f::POSITION_MIN.set(buf, self.position_min.to_bits());
        f::POSITION_MAX.set(buf, self.position_max.to_bits());
        f::TORQUE_MAX.set(buf, self.torque_max.to_bits());
        Ok(Self::LEN)
    }

    /// Find the record of module `id` in a PARAMETER block (1 to
    /// [`ParameterRecord::MAX_RECORDS`] records). Every record is checked,
    /// so a block with one bad record is refused as a whole (never half
    /// applied).
    ///
    /// # Errors
    /// [`Error::NotQuadletAligned`] / [`Error::BlockSize`] for a block that
    /// is not a whole number of records (or too many); the first record's
    /// error otherwise. `Ok(None)`: the block is good but has no record for
    /// `id`.
    pub fn find(block: &[u8], id: ModId) -> Result<Option<ParameterRecord>> {
        let n = block.len() / Self::LEN;
        if block.len() % Self::LEN != 0 || n == 0 || n > Self::MAX_RECORDS {
            return Err(Error::BlockSize {
                what: "PARAMETER block",
                expected: Self::LEN / 4,
                found: block.len() / 4,
            });
        }
        let mut found = None;
        for chunk in block.chunks_exact(Self::LEN) {
            let record = Self::parse(chunk)?;
            if record.mod_id == id && found.is_none() {
                found = Some(record);
            }
        }
        Ok(found)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameter_records_are_checked_as_a_block() {
        let good = ParameterRecord {
            mod_id: ModId(2),
            gear_ratio: 160.0,
            kp: 800.0,
            ki: 50.0,
            kd: 12.0,
            position_min: -1.5,
            position_max: 1.5,
            torque_max: 120.0,
        };
        let mut block = [0u8; 64];
        good.emit(&mut block).unwrap();
        ParameterRecord {
            mod_id: ModId(3),
            ..good
        }
        .emit(&mut block[32..])
        .unwrap();
        assert_eq!(ParameterRecord::find(&block, ModId(2)).unwrap(), Some(good));
        assert_eq!(ParameterRecord::find(&block, ModId(9)).unwrap(), None);
        // A NaN in the second record: the whole block is refused.
        block[32 + 8..32 + 12].copy_from_slice(&f32::NAN.to_bits().to_be_bytes());
        assert!(matches!(
            ParameterRecord::find(&block, ModId(2)),
            Err(Error::InvalidValue { what: "kp", .. })
        ));
        for bad in [
            ParameterRecord {
                gear_ratio: 0.0,
                ..good
            },
            ParameterRecord { kd: -1.0, ..good },
            ParameterRecord {
                position_min: 2.0,
                ..good
            },
            ParameterRecord {
                torque_max: f32::INFINITY,
                ..good
            },
        ] {
            assert!(bad.emit(&mut [0u8; 32]).is_err(), "{bad:?}");
        }
    }
}
