//! What the modules report: the 32-byte joint block a motor controller answers
//! to QREAD and the 24-byte force/torque block a sensor module answers to
//! FTREAD.

use super::*;

/// The QREAD answer of a motor controller: 32 bytes.
///
/// | quadlet | content |
/// |---|---|
/// | 0 | `31:24` module ID, `23:20` state, `19:16` zero, `15:0` sequence of the last set-point applied |
/// | 1 | position, urad (i32) |
/// | 2 | velocity, urad/s (i32) |
/// | 3 | motor current, mA (i32) |
/// | 4 | position the servo tracks, urad (i32) |
/// | 5 | joint torque commanded, mNm (i32) |
/// | 6 | servo ticks since power-up (u32) |
/// | 7 | status flags (`AMPLIFIER_ON`, ...) |
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct JointBlock {
    /// The module's ID.
    pub mod_id: ModId,
    /// Its state.
    pub state: ModuleState,
    /// Sequence of the last QWRITE set-point applied.
    pub sequence: u16,
    /// Joint position, urad.
    pub position_urad: i32,
    /// Joint velocity, urad/s.
    pub velocity_urad_s: i32,
    /// Motor current, mA.
    pub current_ma: i32,
    /// The position the servo tracks, urad.
    pub target_urad: i32,
    /// Joint torque commanded, mNm.
    pub torque_mnm: i32,
    /// Servo ticks since power-up.
    pub servo_ticks: u32,
    /// Status flags.
    pub flags: u32,
}

mod joint_field {
    use super::Field;
    pub const MOD_ID: Field = Field::new(0, 31, 24);
    pub const STATE: Field = Field::new(0, 23, 20);
    pub const RESERVED: Field = Field::new(0, 19, 16);
    pub const SEQUENCE: Field = Field::new(0, 15, 0);
    pub const POSITION: Field = Field::quadlet(1);
    pub const VELOCITY: Field = Field::quadlet(2);
    pub const CURRENT: Field = Field::quadlet(3);
    pub const TARGET: Field = Field::quadlet(4);
    pub const TORQUE: Field = Field::quadlet(5);
    pub const TICKS: Field = Field::quadlet(6);
    pub const FLAGS: Field = Field::quadlet(7);
}

impl JointBlock {
    /// Bytes of a QREAD answer.
    pub const LEN: usize = 32;
    /// Flag: the amplifier is on.
    pub const AMPLIFIER_ON: u32 = 1 << 0;
    /// Flag: parameters received and valid.
    pub const PARAMETERS_VALID: u32 = 1 << 1;
    /// Flag: the joint left its position limits (the module stopped).
    pub const LIMIT: u32 = 1 << 2;
    /// Flag: no set-point arrived within the watchdog period (the module
    /// stopped).
    pub const WATCHDOG: u32 = 1 << 3;
    /// Flag: the servo's torque is at its limit.
    pub const SATURATED: u32 = 1 << 4;
    /// Flags that mean the module stopped itself.
    pub const FAULTS: u32 = Self::LIMIT | Self::WATCHDOG;

    /// Decode a QREAD answer.
    ///
    /// # Errors
    /// [`Error::Truncated`] / [`Error::TrailingBytes`] unless exactly
    /// [`JointBlock::LEN`] bytes; [`Error::Malformed`] with reserved bits
    /// set; [`Error::FieldRange`] for a module ID past [`ModId::LIMIT`].
    pub fn parse(buf: &[u8]) -> Result<JointBlock> {
        use joint_field as f;
        check_len("QREAD joint block", buf, Self::LEN)?;
        if f::RESERVED.get(buf) != 0 {
            return Err(Error::Malformed {
                what: "QREAD joint block quadlet 0",
                value: read_quadlet(buf, 0),
            });
        }
        Ok(JointBlock {
            mod_id: ModId(f::MOD_ID.get(buf) as u8).check()?,
            state: state_from_bits(f::STATE.get(buf)),
            sequence: f::SEQUENCE.get(buf) as u16,
            position_urad: f::POSITION.get(buf) as i32,
            velocity_urad_s: f::VELOCITY.get(buf) as i32,
            current_ma: f::CURRENT.get(buf) as i32,
            target_urad: f::TARGET.get(buf) as i32,
            torque_mnm: f::TORQUE.get(buf) as i32,
            servo_ticks: f::TICKS.get(buf),
            flags: f::FLAGS.get(buf),
        })
    }

    /// Encode into the first [`JointBlock::LEN`] bytes of `buf`.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`]; [`Error::FieldRange`] for a module ID or
    /// state that does not fit.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        use joint_field as f;
        let buf = out_slice("QREAD joint block", buf, Self::LEN)?;
        self.mod_id.check()?;
        let state = state_bits(self.state)?;
        f::MOD_ID.set(buf, u32::from(self.mod_id.0));
        f::STATE.set(buf, state);
        f::RESERVED.set(buf, 0);
        f::SEQUENCE.set(buf, u32::from(self.sequence));
        f::POSITION.set(buf, self.position_urad as u32);
        f::VELOCITY.set(buf, self.velocity_urad_s as u32);
        f::CURRENT.set(buf, self.current_ma as u32);
        f::TARGET.set(buf, self.target_urad as u32);
        f::TORQUE.set(buf, self.torque_mnm as u32);
        f::TICKS.set(buf, self.servo_ticks);
        f::FLAGS.set(buf, self.flags);
        Ok(Self::LEN)
    }

    /// Position in radians.
    pub fn position(&self) -> f64 {
        f64::from(self.position_urad) * 1e-6
    }

    /// Velocity in radians per second.
    pub fn velocity(&self) -> f64 {
        f64::from(self.velocity_urad_s) * 1e-6
    }
}

/// The FTREAD answer of a force/torque module: 24 bytes, six signed
/// quadlets: forces x, y, z in mN, then torques x, y, z in mNm, in the
/// sensor's frame, bias removed once SETBIAS has been taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct FtBlock {
    /// Forces x, y, z, mN.
    pub force_mn: [i32; 3],
    /// Torques x, y, z, mNm.
    pub torque_mnm: [i32; 3],
}

impl FtBlock {
    /// Bytes of an FTREAD answer.
    pub const LEN: usize = 24;

    /// Decode an FTREAD answer.
    ///
    /// # Errors
    /// [`Error::Truncated`] / [`Error::TrailingBytes`] unless exactly
    /// [`FtBlock::LEN`] bytes.
    pub fn parse(buf: &[u8]) -> Result<FtBlock> {
        check_len("FTREAD block", buf, Self::LEN)?;
        let q = |i| read_quadlet(buf, i) as i32;
        Ok(FtBlock {
            force_mn: [q(0), q(1), q(2)],
            torque_mnm: [q(3), q(4), q(5)],
        })
    }

    /// Encode into the first [`FtBlock::LEN`] bytes of `buf`.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`].
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        let buf = out_slice("FTREAD block", buf, Self::LEN)?;
        for (i, v) in self.force_mn.iter().chain(&self.torque_mnm).enumerate() {
            write_quadlet(buf, i, *v as u32);
        }
        Ok(Self::LEN)
    }

    /// The six components in SI units: N, N, N, Nm, Nm, Nm.
    pub fn wrench(&self) -> [f64; 6] {
        let f = |v: i32| f64::from(v) * 1e-3;
        [
            f(self.force_mn[0]),
            f(self.force_mn[1]),
            f(self.force_mn[2]),
            f(self.torque_mnm[0]),
            f(self.torque_mnm[1]),
            f(self.torque_mnm[2]),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_refuse_wrong_sizes() {
        assert!(matches!(
            JointBlock::parse(&[0; 28]),
            Err(Error::Truncated { needed: 32, .. })
        ));
        assert!(matches!(
            FtBlock::parse(&[0; 28]),
            Err(Error::TrailingBytes { extra: 4, .. })
        ));
        assert!(SetpointSlot::slice(&[0; 316], ModId(0)).is_err());
        assert!(matches!(
            SetpointSlot::slice(&[0; QWRITE_LEN], ModId(10)),
            Err(Error::Index { index: 10, .. })
        ));
        assert!(ParameterRecord::find(&[0; 33], ModId(0)).is_err());
        assert!(ParameterRecord::find(&[], ModId(0)).is_err());
        let mut small = [0u8; 31];
        assert!(FtBlock::default().emit(&mut small[..23]).is_err());
        assert!(SetpointSlot::default().emit(&mut small).is_err());
    }
}
