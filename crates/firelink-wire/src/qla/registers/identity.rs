//! What the board says about itself: HW_VERSION (the companion board), the FPGA
//! generation told by ETH_STATUS, the IP_ADDR word, TEMPERATURE and the
//! firmware's git description (`fpga-board.md` §2).

use super::*;

open_enum! {
    /// HW_VERSION: the companion board, a four-character code
    /// (`fpga-board.md` §2).
    pub enum HardwareVersion(u32) {
        /// "QLA1": quad linear amplifier, 4 axes.
        Qla1 = 0x514C_4131,
        /// "DQLA": dual QLA, 8 axes.
        Dqla = 0x4451_4C41,
        /// "dRA1": the dRA1 board.
        Dra1 = 0x6452_4131,
    }
}

impl HardwareVersion {
    /// The four characters of the code (big-endian bytes of the register).
    pub fn fourcc(self) -> [u8; 4] {
        u32::from(self).to_be_bytes()
    }

    /// The code from its four characters.
    pub fn from_fourcc(code: [u8; 4]) -> HardwareVersion {
        HardwareVersion::from(u32::from_be_bytes(code))
    }

    /// The name of a known board ("QLA1", "DQLA", "dRA1"), `"unknown"` otherwise.
    pub fn name(self) -> &'static str {
        match self {
            HardwareVersion::Qla1 => "QLA1",
            HardwareVersion::Dqla => "DQLA",
            HardwareVersion::Dra1 => "dRA1",
            HardwareVersion::Unknown(_) => "unknown",
        }
    }
}

// ----------------------------------------------------------- ETH_STATUS ---

/// The FPGA board generation, told by ETH_STATUS (`fpga-board.md` §2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FpgaVersion {
    /// FPGA V1: no Ethernet; ETH_STATUS reads 0.
    V1,
    /// FPGA V2: ETH_STATUS bit 31 set.
    V2,
    /// FPGA V3: ETH_STATUS bits 31:30 = 01.
    V3,
}

impl FpgaVersion {
    /// The version number: 1, 2 or 3.
    pub fn number(self) -> u8 {
        match self {
            FpgaVersion::V1 => 1,
            FpgaVersion::V2 => 2,
            FpgaVersion::V3 => 3,
        }
    }

    /// Tell the version from an ETH_STATUS value.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] for a nonzero value with bits 31:30 = 00.
    pub fn from_eth_status(eth_status: u32) -> Result<FpgaVersion> {
        if eth_status == 0 {
            Ok(FpgaVersion::V1)
        } else if field::ETH_V2.extract(eth_status) == 1 {
            Ok(FpgaVersion::V2)
        } else if field::ETH_VERSION_BITS.extract(eth_status) == 0b01 {
            Ok(FpgaVersion::V3)
        } else {
            Err(Error::InvalidValue {
                what: "ETH_STATUS FPGA version bits",
                value: eth_status,
            })
        }
    }

    /// The version bits of ETH_STATUS for this version (other status bits
    /// zero): 0, `0x8000_0000` or `0x4000_0000`.
    pub fn eth_status_bits(self) -> u32 {
        let f = field::ETH_VERSION_BITS;
        match self {
            FpgaVersion::V1 => 0,
            FpgaVersion::V2 => f.insert(0, 0b10),
            FpgaVersion::V3 => f.insert(0, 0b01),
        }
    }

    /// Whether the board has Ethernet (V2 and V3).
    pub fn has_ethernet(self) -> bool {
        self != FpgaVersion::V1
    }
}

// -------------------------------------------------------------- IP_ADDR ---

/// The IP_ADDR word of an IPv4 address: written little-endian
/// (`fpga-board.md` §2: 169.254.0.100 -> `0x6400FEA9`).
pub fn ip_to_register(ip: Ipv4Addr) -> u32 {
    u32::from_le_bytes(ip.octets())
}

/// The IPv4 address of an IP_ADDR word (`fpga-board.md` §2).
pub fn ip_from_register(word: u32) -> Ipv4Addr {
    Ipv4Addr::from(word.to_le_bytes())
}

// --------------------------------------------------- TEMPERATURE, GIT ---

quadlet_register! {
    /// TEMPERATURE: two 8-bit amplifier temperatures (`fpga-board.md` §2).
    pub struct Temperature {
        /// The temperature in bits 15:8.
        upper, set_upper, with_upper: u8 = field::TEMPERATURE_UPPER;
        /// The temperature in bits 7:0.
        lower, set_lower, with_lower: u8 = field::TEMPERATURE_LOWER;
    }
}

quadlet_register! {
    /// GIT_DESC: the firmware's source version (`fpga-board.md` §2).
    pub struct GitDesc {
        /// Short commit id, bits 31:4 (28 bits, seven hex digits).
        commit, set_commit, with_commit: u32 = field::GIT_COMMIT;
        /// The build had uncommitted changes, bit 3.
        dirty, set_dirty, with_dirty: bool = field::GIT_DIRTY;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hardware_versions() {
        assert_eq!(HardwareVersion::from(0x514C_4131), HardwareVersion::Qla1);
        assert_eq!(&HardwareVersion::Qla1.fourcc(), b"QLA1");
        assert_eq!(&HardwareVersion::Dqla.fourcc(), b"DQLA");
        assert_eq!(&HardwareVersion::Dra1.fourcc(), b"dRA1");
        assert_eq!(
            HardwareVersion::from_fourcc(*b"DQLA"),
            HardwareVersion::Dqla
        );
        assert_eq!(HardwareVersion::Dra1.name(), "dRA1");
        assert_eq!(HardwareVersion::from(7).name(), "unknown");
    }

    #[test]
    fn fpga_versions() {
        assert_eq!(FpgaVersion::from_eth_status(0), Ok(FpgaVersion::V1));
        assert_eq!(
            FpgaVersion::from_eth_status(0x8000_1234),
            Ok(FpgaVersion::V2)
        );
        assert_eq!(
            FpgaVersion::from_eth_status(0xC000_0000),
            Ok(FpgaVersion::V2)
        );
        assert_eq!(
            FpgaVersion::from_eth_status(0x4000_0001),
            Ok(FpgaVersion::V3)
        );
        assert!(FpgaVersion::from_eth_status(0x0000_0001).is_err());
        for v in [FpgaVersion::V1, FpgaVersion::V2, FpgaVersion::V3] {
            assert_eq!(FpgaVersion::from_eth_status(v.eth_status_bits()), Ok(v));
        }
        assert!(!FpgaVersion::V1.has_ethernet() && FpgaVersion::V3.has_ethernet());
    }

    #[test]
    fn ip_addr_is_little_endian() {
        let ip = Ipv4Addr::new(169, 254, 0, 100);
        assert_eq!(ip_to_register(ip), 0x6400_FEA9);
        assert_eq!(ip_from_register(0x6400_FEA9), ip);
    }

    #[test]
    fn small_words() {
        let d = DigitalIn::default()
            .with_v_fault(true)
            .with_enc_a(1)
            .with_enc_b(2)
            .with_index(3)
            .with_outputs(4)
            .with_neg_limits(5)
            .with_pos_limits(6)
            .with_home(7);
        assert_eq!(d.raw(), 0x8123_4567);
        let t = Temperature::default().with_upper(40).with_lower(41);
        assert_eq!(t.raw(), 0x2829);
        let g = GitDesc::default().with_commit(0x0ab_cdef).with_dirty(true);
        assert_eq!(g.raw(), 0x0ABC_DEF8);
        let a = AdcWord(0x1234_5678);
        assert_eq!((a.pot(), a.current()), (0x1234, 0x5678));
        assert_eq!(u32::from(a), 0x1234_5678);
        assert_eq!(AdcWord::from(7), AdcWord(7));
    }
}
