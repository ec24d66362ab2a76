//! PHY access through PHY_CTRL and PHY_DATA (`fpga-board.md` §2): the request a
//! host writes to read or write a register of the board's FireWire PHY, and the
//! data word it reads back.

use super::*;

/// A PHY register access requested through PHY_CTRL (`fpga-board.md` §2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PhyRequest {
    /// Read PHY register `register` (0..=15): the word is the register number.
    Read {
        /// The PHY register.
        register: u8,
    },
    /// Write `data` to PHY register `register`: `0x1000 | reg<<8 | data`.
    Write {
        /// The PHY register (0..=15).
        register: u8,
        /// The value written.
        data: u8,
    },
}

impl PhyRequest {
    /// Decode a PHY_CTRL write.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] when bits are set that neither form carries
    /// (above bit 12 for a write; above bit 3 for a read).
    pub fn parse(word: u32) -> Result<PhyRequest> {
        let request = if field::PHY_CTRL_WRITE.extract(word) == 1 {
            PhyRequest::Write {
                register: field::PHY_CTRL_REGISTER.extract(word) as u8,
                data: field::PHY_CTRL_DATA.extract(word) as u8,
            }
        } else {
            PhyRequest::Read {
                register: field::PHY_CTRL_READ_REGISTER.extract(word) as u8,
            }
        };
        match request.to_word() {
            Ok(canonical) if canonical == word => Ok(request),
            _ => Err(Error::InvalidValue {
                what: "PHY_CTRL word",
                value: word,
            }),
        }
    }

    /// Encode as the PHY_CTRL word.
    ///
    /// # Errors
    /// [`Error::FieldRange`] for a register above 15.
    pub fn to_word(self) -> Result<u32> {
        match self {
            PhyRequest::Read { register } => {
                let f = field::PHY_CTRL_READ_REGISTER;
                check_max("PHY register", u64::from(register), u64::from(f.max()))?;
                Ok(f.insert(0, u32::from(register)))
            }
            PhyRequest::Write { register, data } => {
                let f = field::PHY_CTRL_REGISTER;
                check_max("PHY register", u64::from(register), u64::from(f.max()))?;
                let w = field::PHY_CTRL_WRITE.insert(0, 1);
                let w = f.insert(w, u32::from(register));
                Ok(field::PHY_CTRL_DATA.insert(w, u32::from(data)))
            }
        }
    }
}

quadlet_register! {
    /// PHY_DATA: the result of a PHY register read (`fpga-board.md` §2).
    pub struct PhyData {
        /// The PHY register read, bits 11:8.
        register, set_register, with_register: u8 = field::PHY_DATA_REGISTER;
        /// Its value, bits 7:0.
        data, set_data, with_data: u8 = field::PHY_DATA_DATA;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phy_ctrl_and_data() {
        let w = PhyRequest::Write {
            register: 1,
            data: 0x3F,
        };
        assert_eq!(w.to_word(), Ok(0x113F));
        assert_eq!(PhyRequest::parse(0x113F), Ok(w));
        let r = PhyRequest::Read { register: 1 };
        assert_eq!(r.to_word(), Ok(1));
        assert_eq!(PhyRequest::parse(0), Ok(PhyRequest::Read { register: 0 }));
        assert!(PhyRequest::parse(0x0100).is_err());
        assert!(PhyRequest::parse(0x2000).is_err());
        assert!(PhyRequest::Read { register: 16 }.to_word().is_err());
        let d = PhyData(0x0000_013F);
        assert_eq!((d.register(), d.data()), (1, 0x3F));
        assert_eq!(PhyData::default().with_register(1).with_data(0x3F), d);
    }
}
