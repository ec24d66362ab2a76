//! Who answers: the one-quadlet answers to IDREQUEST (magic, module kind,
//! firmware revision, module ID) and to IDCHECK (module ID, state and the node
//! ID it sits at), with which the host maps module IDs to node IDs after every
//! bus reset.

use super::*;

/// The answer to IDREQUEST: one quadlet.
///
/// `31:24` magic `0x4D` ('M'), `23:20` [`ModuleKind`], `19:16` firmware
/// revision, `15:8` zero, `7:0` module ID.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Identity {
    /// The module's ID.
    pub mod_id: ModId,
    /// What it is.
    pub kind: ModuleKind,
    /// Its firmware revision (0..=15).
    pub firmware: u8,
}

mod identity_field {
    use super::Field;
    pub const MAGIC: Field = Field::new(0, 31, 24);
    pub const KIND: Field = Field::new(0, 23, 20);
    pub const FIRMWARE: Field = Field::new(0, 19, 16);
    pub const RESERVED: Field = Field::new(0, 15, 8);
    pub const MOD_ID: Field = Field::new(0, 7, 0);
}

impl Identity {
    /// The magic byte of an IDREQUEST answer.
    pub const MAGIC: u8 = 0x4D;

    /// Decode an IDREQUEST answer.
    ///
    /// # Errors
    /// [`Error::Malformed`] without the magic byte or with reserved bits
    /// set; [`Error::FieldRange`] for a module ID past [`ModId::LIMIT`].
    pub fn from_quadlet(q: u32) -> Result<Identity> {
        use identity_field as f;
        let b = q.to_be_bytes();
        if f::MAGIC.get(&b) != u32::from(Self::MAGIC) || f::RESERVED.get(&b) != 0 {
            return Err(Error::Malformed {
                what: "IDREQUEST answer",
                value: q,
            });
        }
        Ok(Identity {
            mod_id: ModId(f::MOD_ID.get(&b) as u8).check()?,
            kind: ModuleKind::from(f::KIND.get(&b) as u8),
            firmware: f::FIRMWARE.get(&b) as u8,
        })
    }

    /// Encode as the answer quadlet.
    ///
    /// # Errors
    /// [`Error::FieldRange`] for a kind or firmware past 15 or a module ID
    /// past [`ModId::LIMIT`].
    pub fn to_quadlet(&self) -> Result<u32> {
        use identity_field as f;
        self.mod_id.check()?;
        let kind = u8::from(self.kind);
        crate::qla::check_max("module kind", u64::from(kind), 0xF)?;
        crate::qla::check_max("firmware revision", u64::from(self.firmware), 0xF)?;
        let mut b = [0u8; 4];
        f::MAGIC.set(&mut b, u32::from(Self::MAGIC));
        f::KIND.set(&mut b, u32::from(kind));
        f::FIRMWARE.set(&mut b, u32::from(self.firmware));
        f::MOD_ID.set(&mut b, u32::from(self.mod_id.0));
        Ok(u32::from_be_bytes(b))
    }
}

/// The answer to IDCHECK: one quadlet.
///
/// `31:24` module ID, `23:20` [`ModuleState`], `19:16` zero, `15:10` the
/// physical ID the module got at the last bus reset, `9:0` the low ten bits
/// of that reset's generation. The host checks all three: the right module
/// answers, at the node it was mapped to, and it saw the same reset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct IdCheck {
    /// The module's ID.
    pub mod_id: ModId,
    /// Its state.
    pub state: ModuleState,
    /// Its physical ID.
    pub phy_id: u8,
    /// Low ten bits of the bus generation it knows.
    pub generation: u16,
}

mod idcheck_field {
    use super::Field;
    pub const MOD_ID: Field = Field::new(0, 31, 24);
    pub const STATE: Field = Field::new(0, 23, 20);
    pub const RESERVED: Field = Field::new(0, 19, 16);
    pub const PHY_ID: Field = Field::new(0, 15, 10);
    pub const GENERATION: Field = Field::new(0, 9, 0);
}

impl IdCheck {
    /// Mask of the generation bits carried.
    pub const GENERATION_MASK: u32 = 0x3FF;

    /// Decode an IDCHECK answer.
    ///
    /// # Errors
    /// [`Error::Malformed`] with reserved bits set; [`Error::FieldRange`]
    /// for a module ID past [`ModId::LIMIT`].
    pub fn from_quadlet(q: u32) -> Result<IdCheck> {
        use idcheck_field as f;
        let b = q.to_be_bytes();
        if f::RESERVED.get(&b) != 0 {
            return Err(Error::Malformed {
                what: "IDCHECK answer",
                value: q,
            });
        }
        Ok(IdCheck {
            mod_id: ModId(f::MOD_ID.get(&b) as u8).check()?,
            state: state_from_bits(f::STATE.get(&b)),
            phy_id: f::PHY_ID.get(&b) as u8,
            generation: f::GENERATION.get(&b) as u16,
        })
    }

    /// Encode as the answer quadlet (the generation is truncated to ten
    /// bits).
    ///
    /// # Errors
    /// [`Error::FieldRange`] for a module ID, state or physical ID that
    /// does not fit.
    pub fn to_quadlet(&self) -> Result<u32> {
        use idcheck_field as f;
        self.mod_id.check()?;
        crate::qla::check_max("physical ID", u64::from(self.phy_id), 63)?;
        let mut b = [0u8; 4];
        f::MOD_ID.set(&mut b, u32::from(self.mod_id.0));
        f::STATE.set(&mut b, state_bits(self.state)?);
        f::PHY_ID.set(&mut b, u32::from(self.phy_id));
        f::GENERATION.set(&mut b, u32::from(self.generation));
        Ok(u32::from_be_bytes(b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identity_and_idcheck_quadlets() {
        let id = Identity {
            mod_id: ModId(12),
            kind: ModuleKind::ForceTorque,
            firmware: 3,
        };
        let q = id.to_quadlet().unwrap();
        assert_eq!(q, 0x4D23_000C);
        assert_eq!(Identity::from_quadlet(q).unwrap(), id);
        assert!(Identity::from_quadlet(0x0023_000C).is_err());
        assert!(Identity::from_quadlet(0x4D23_010C).is_err());
        assert!(Identity::from_quadlet(0x4D23_0020).is_err());
        let check = IdCheck {
            mod_id: ModId(5),
            state: ModuleState::Ready,
            phy_id: 9,
            generation: 0x155,
        };
        let q = check.to_quadlet().unwrap();
        assert_eq!(q, 0x0520_2555);
        assert_eq!(IdCheck::from_quadlet(q).unwrap(), check);
        assert!(IdCheck::from_quadlet(q | 0x1_0000).is_err());
        assert!(
            IdCheck {
                phy_id: 64,
                ..check
            }
            .to_quadlet()
            .is_err()
        );
    }
}
