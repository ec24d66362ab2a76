//! QWRITE's set-points: the 320-byte broadcast of ten 32-byte slots, one per
//! motor controller, each found by module ID.

use super::*;

/// Set-point slots in one QWRITE (one per motor controller).
pub const QWRITE_SLOTS: usize = 10;
/// Bytes of one QWRITE.
pub const QWRITE_LEN: usize = QWRITE_SLOTS * SetpointSlot::LEN;

/// One motor controller's slice of QWRITE: 32 bytes at `32 x ModID`.
///
/// | quadlet | content |
/// |---|---|
/// | 0 | `31:24` module ID, `23:16` flags (bit 16: valid), `15:0` sequence |
/// | 1 | position, urad (i32) |
/// | 2 | velocity, urad/s (i32) |
/// | 3 | acceleration, mrad/s^2 (i32) |
/// | 4 | torque feed-forward, mNm (i32) |
/// | 5..7 | zero |
///
/// A slot is taken only when it is valid and names the module whose
/// ModID is its index; anything else leaves the module's set-point as it
/// was (and counts as a missed set-point for its watchdog).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct SetpointSlot {
    /// The module the slot is for.
    pub mod_id: u8,
    /// Whether the slot carries a set-point.
    pub valid: bool,
    /// Sequence number (the host's cycle counter).
    pub sequence: u16,
    /// Position, urad.
    pub position_urad: i32,
    /// Velocity, urad/s.
    pub velocity_urad_s: i32,
    /// Acceleration, mrad/s^2.
    pub acceleration_mrad_s2: i32,
    /// Torque feed-forward, mNm.
    pub torque_mnm: i32,
}

mod slot_field {
    use super::Field;
    pub const MOD_ID: Field = Field::new(0, 31, 24);
    pub const FLAGS: Field = Field::new(0, 23, 16);
    pub const SEQUENCE: Field = Field::new(0, 15, 0);
    pub const POSITION: Field = Field::quadlet(1);
    pub const VELOCITY: Field = Field::quadlet(2);
    pub const ACCELERATION: Field = Field::quadlet(3);
    pub const TORQUE: Field = Field::quadlet(4);
}

impl SetpointSlot {
    /// Bytes of one slot.
    pub const LEN: usize = 32;
    const VALID: u32 = 1;

    /// Decode one slot (exactly [`SetpointSlot::LEN`] bytes). Unknown flag
    /// bits and the zero quadlets are not checked: a newer host may use them.
    ///
    /// # Errors
    /// [`Error::Truncated`] / [`Error::TrailingBytes`].
    pub fn parse(buf: &[u8]) -> Result<SetpointSlot> {
        use slot_field as f;
        check_len("QWRITE slot", buf, Self::LEN)?;
        Ok(SetpointSlot {
            mod_id: f::MOD_ID.get(buf) as u8,
            valid: f::FLAGS.get(buf) & Self::VALID != 0,
            sequence: f::SEQUENCE.get(buf) as u16,
            position_urad: f::POSITION.get(buf) as i32,
            velocity_urad_s: f::VELOCITY.get(buf) as i32,
            acceleration_mrad_s2: f::ACCELERATION.get(buf) as i32,
            torque_mnm: f::TORQUE.get(buf) as i32,
        })
    }

    /// Encode into the first [`SetpointSlot::LEN`] bytes of `buf` (the
    /// zero quadlets included).
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`].
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        use slot_field as f;
        let buf = out_slice("QWRITE slot", buf, Self::LEN)?;
        buf.fill(0);
        f::MOD_ID.set(buf, u32::from(self.mod_id));
        f::FLAGS.set(buf, if self.valid { Self::VALID } else { 0 });
        f::SEQUENCE.set(buf, u32::from(self.sequence));
        f::POSITION.set(buf, self.position_urad as u32);
        f::VELOCITY.set(buf, self.velocity_urad_s as u32);
        f::ACCELERATION.set(buf, self.acceleration_mrad_s2 as u32);
        f::TORQUE.set(buf, self.torque_mnm as u32);
        Ok(Self::LEN)
    }

    /// The slot of module `id` in a QWRITE payload: `None` when the
    /// payload is not exactly [`QWRITE_LEN`] bytes or `id` has no slot.
    ///
    /// # Errors
    /// [`Error::Truncated`] / [`Error::TrailingBytes`] for a payload of the
    /// wrong size; [`Error::Index`] for an ID without a slot.
    pub fn slice(payload: &[u8], id: ModId) -> Result<SetpointSlot> {
        check_len("QWRITE payload", payload, QWRITE_LEN)?;
        let i = usize::from(id.0);
        let start = i * Self::LEN;
        let bytes = payload.get(start..start + Self::LEN).ok_or(Error::Index {
            what: "QWRITE slot",
            index: i,
            count: QWRITE_SLOTS,
        })?;
        Self::parse(bytes)
    }

    /// Position in radians.
    pub fn position(&self) -> f64 {
        f64::from(self.position_urad) * 1e-6
    }

    /// Velocity in radians per second.
    pub fn velocity(&self) -> f64 {
        f64::from(self.velocity_urad_s) * 1e-6
    }

    /// Acceleration in radians per second squared.
    pub fn acceleration(&self) -> f64 {
        f64::from(self.acceleration_mrad_s2) * 1e-3
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn qwrite_slices_by_mod_id() {
        let mut payload = [0xA5u8; QWRITE_LEN];
        for i in 0..QWRITE_SLOTS {
            let slot = SetpointSlot {
                mod_id: i as u8,
                valid: true,
                sequence: 7,
                position_urad: 1000 * i as i32 - 3000,
                velocity_urad_s: -(i as i32),
                acceleration_mrad_s2: 5,
                torque_mnm: 0,
            };
            slot.emit(&mut payload[i * 32..]).unwrap();
        }
        for i in 0..QWRITE_SLOTS as u8 {
            let s = SetpointSlot::slice(&payload, ModId(i)).unwrap();
            assert_eq!(s.mod_id, i);
            assert_eq!(s.position_urad, 1000 * i32::from(i) - 3000);
            // The zero quadlets were written over the 0xA5 fill.
            let start = usize::from(i) * 32;
            assert_eq!(&payload[start + 20..start + 32], &[0; 12]);
        }
    }
}
