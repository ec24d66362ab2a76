//! The MAHRU humanoid's module protocol (seed 002): custom commands carried
//! in standard 1394 asynchronous packets.
//!
//! Facts: `seed-systems.md` section C and seed 002 section III.C, Fig. 7,
//! Table II. The destination offset of a request is the *command field*:
//! its value is the command code ([`Command`]). Point-to-point commands go
//! to a module's node ID; broadcast commands go to node 63 on the local
//! bus (`0xFFFF`). Because node IDs change at every bus reset, each module
//! has a module ID ([`ModId`]) of its own, which the host maps to the
//! current node ID with IDREQUEST and IDCHECK after every reset.
//!
//! | code | command | sent as | payload |
//! |---|---|---|---|
//! | 0 | STOP | broadcast quadlet write | [`ModMask`] |
//! | 11 | IDREQUEST | P2P quadlet read | answer: [`Identity`] |
//! | 12 | IDCHECK | P2P quadlet read | answer: [`IdCheck`] |
//! | 13 | PARAMETER | P2P or broadcast block write | [`ParameterRecord`]s |
//! | 14 | SETBIAS | broadcast quadlet write | [`ModMask`] |
//! | 15 | READY | broadcast quadlet write | [`ModMask`] |
//! | 16 | START | broadcast quadlet write | [`ModMask`] |
//! | 17 | QREAD | P2P block read, 32 bytes | answer: [`JointBlock`] |
//! | 18 | QWRITE | broadcast block write, 320 bytes | 10 [`SetpointSlot`]s |
//! | 19 | FTREAD | P2P block read, 24 bytes | answer: [`FtBlock`] |
//!
//! **Source ID.** Seed 002 fills the source ID with the node ID or the
//! ModID "depending on the type of operation", and with 0x3F (the local
//! bus's broadcast physical ID) in the computer's broadcasts. Here a
//! module's *responses* carry its node ID, because that is what the
//! computer's link matches responses by (with the transaction label), as
//! an OHCI link does; the ModID travels in the data of every answer that
//! identifies a module (IDREQUEST, IDCHECK, QREAD). Modules take broadcast
//! commands from any source, so a computer that writes 0xFFFF (bus 0x3FF,
//! node 0x3F) there, as the seed's does, is obeyed like one that writes its
//! own node ID.
//!
//! The seed gives the codes, the transaction types and the sizes (24 B
//! from a sensor module, 32 B from a motor controller, 320 B of set-points
//! for 10 controllers); it does not print the field layouts inside the
//! blocks. The layouts here are Firelink's, chosen to carry what the seed
//! says each block holds (joint position and velocity, force and torque,
//! gear ratio and PID gains) in whole quadlets, big-endian like every 1394
//! payload. Physical quantities are fixed-point integers: positions in
//! microradians, velocities in microradians per second, accelerations in
//! milliradians per second squared, currents in milliamperes, forces in
//! millinewtons, torques in millinewton-metres. Parameters are IEEE 754
//! single-precision floats (the modules' TMS320VC33 is a floating-point DSP).
//!
//! Every parser checks the length first and rejects values without meaning
//! with an [`Error`] naming the field; after a successful parse nothing
//! panics. Unknown command codes and states are data ([`Command::Unknown`],
//! [`ModuleState::Unknown`]): a module ignores a command it does not know.
//!
//! ```
//! use firelink_wire::mahru::{Command, JointBlock, ModId, ModuleState};
//! assert_eq!(Command::from_offset(17), Some(Command::QRead));
//! assert!(Command::QWrite.is_broadcast());
//! let block = JointBlock {
//!     mod_id: ModId(3),
//!     state: ModuleState::Running,
//!     sequence: 42,
//!     position_urad: -150_000,
//!     velocity_urad_s: 20_000,
//!     current_ma: 1200,
//!     target_urad: -149_000,
//!     torque_mnm: 3500,
//!     servo_ticks: 1000,
//!     flags: JointBlock::AMPLIFIER_ON,
//! };
//! let mut buf = [0xA5u8; JointBlock::LEN];
//! block.emit(&mut buf).unwrap();
//! assert_eq!(JointBlock::parse(&buf).unwrap(), block);
//! ```

use crate::field::{Field, read_quadlet, write_quadlet};
use crate::open_enum::open_enum;
use crate::{Error, Result};

open_enum! {
    /// A command code: the value of a request's destination offset
    /// (seed 002, Table II).
    pub enum Command(u8) {
        /// Broadcast: amplifiers off, servo off, every module stops.
        Stop = 0,
        /// P2P quadlet read: "who are you?" (module ID and kind).
        IdRequest = 11,
        /// P2P quadlet read: confirm the mapping (module ID, state, node ID).
        IdCheck = 12,
        /// Block write: motor parameters (gear ratio, gains, limits).
        Parameter = 13,
        /// Broadcast: force/torque sensors take the present reading as bias.
        SetBias = 14,
        /// Broadcast: amplifiers on, hold the present position.
        Ready = 15,
        /// Broadcast: follow the set-points of QWRITE.
        Start = 16,
        /// P2P block read: joint data (32 bytes).
        QRead = 17,
        /// Broadcast block write: set-points of 10 controllers (320 bytes).
        QWrite = 18,
        /// P2P block read: force/torque data (24 bytes).
        FtRead = 19,
    }
}

/// Offsets below this are command codes; everything above is not part of
/// the command space.
pub const COMMAND_SPACE: u64 = 0x100;

/// The modules' trace buffer: block reads of any length (whole quadlets,
/// up to [`TRACE_BUFFER_LEN`] bytes) at this offset return the DSP's
/// recent samples. Not a seed-002 command: Firelink's addition, used to
/// measure read-transaction time by payload as the seed's Table III does.
pub const TRACE_BUFFER_OFFSET: u64 = 0x0001_0000_0000;
/// Size of the trace buffer in bytes.
pub const TRACE_BUFFER_LEN: usize = 2048;

impl Command {
    /// The command a request's destination offset carries, or `None` when
    /// the offset lies outside the command space.
    pub fn from_offset(offset: u64) -> Option<Command> {
        (offset < COMMAND_SPACE).then(|| Command::from(offset as u8))
    }

    /// The destination offset that carries this command.
    pub fn offset(self) -> u64 {
        u64::from(u8::from(self))
    }

    /// Whether the seed sends this command to every module (node 63).
    pub fn is_broadcast(self) -> bool {
        matches!(
            self,
            Command::Stop
                | Command::Parameter
                | Command::SetBias
                | Command::Ready
                | Command::Start
                | Command::QWrite
        )
    }

    /// Whether the seed sends this command point to point.
    pub fn is_point_to_point(self) -> bool {
        matches!(
            self,
            Command::IdRequest
                | Command::IdCheck
                | Command::QRead
                | Command::FtRead
                | Command::Parameter
        )
    }

    /// The seed's name (Table II).
    pub fn name(self) -> &'static str {
        match self {
            Command::Stop => "STOP",
            Command::IdRequest => "IDREQUEST",
            Command::IdCheck => "IDCHECK",
            Command::Parameter => "PARAMETER",
            Command::SetBias => "SETBIAS",
            Command::Ready => "READY",
            Command::Start => "START",
            Command::QRead => "QREAD",
            Command::QWrite => "QWRITE",
            Command::FtRead => "FTREAD",
            Command::Unknown(_) => "unknown",
        }
    }
}

/// A module ID: fixed per module (set in its firmware), independent of the
/// node ID that changes at every bus reset. Motor controllers use
/// 0..[`QWRITE_SLOTS`] (their QWRITE slot); sensors any other value below
/// [`ModId::LIMIT`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ModId(pub u8);

impl ModId {
    /// Module IDs are 0..32 (one bit each in a [`ModMask`]).
    pub const LIMIT: u8 = 32;

    /// Check that the ID fits a [`ModMask`].
    ///
    /// # Errors
    /// [`Error::FieldRange`].
    pub fn check(self) -> Result<ModId> {
        if self.0 < Self::LIMIT {
            Ok(self)
        } else {
            Err(Error::FieldRange {
                field: "module ID",
                value: u64::from(self.0),
                max: u64::from(Self::LIMIT - 1),
            })
        }
    }
}

impl core::fmt::Display for ModId {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "ModID {}", self.0)
    }
}

/// Which modules a quadlet command applies to: bit `i` selects ModID `i`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ModMask(pub u32);

impl ModMask {
    /// Every module.
    pub const ALL: ModMask = ModMask(u32::MAX);

    /// Whether the mask selects `id`.
    pub fn contains(self, id: ModId) -> bool {
        id.0 < ModId::LIMIT && self.0 & (1 << id.0) != 0
    }

    /// The mask with `id` added (IDs past the limit are ignored).
    #[must_use]
    pub fn with(self, id: ModId) -> ModMask {
        if id.0 < ModId::LIMIT {
            ModMask(self.0 | 1 << id.0)
        } else {
            self
        }
    }
}

open_enum! {
    /// What a module is (IDREQUEST answer, bits 23:20).
    pub enum ModuleKind(u8) {
        /// A DSP + FPGA motor controller driving one joint.
        MotorController = 1,
        /// A six-axis force/torque sensor module.
        ForceTorque = 2,
    }
}

open_enum! {
    /// A module's lifecycle state (4 bits in IDCHECK answers and joint
    /// blocks). Only [`ModuleState::Running`] follows set-points.
    pub enum ModuleState(u8) {
        /// Powered, no parameters yet: amplifier off.
        Idle = 0,
        /// Parameters received: amplifier off.
        Parameterized = 1,
        /// READY: amplifier on, holding the position it had.
        Ready = 2,
        /// START: following the set-points of QWRITE.
        Running = 3,
        /// STOP, a limit or the watchdog: amplifier off until READY.
        Stopped = 4,
    }
}

/// Largest value of a 4-bit state field.
const STATE_MAX: u8 = 0xF;

fn state_from_bits(bits: u32) -> ModuleState {
    ModuleState::from(bits as u8)
}

fn state_bits(state: ModuleState) -> Result<u32> {
    let raw = u8::from(state);
    if raw > STATE_MAX {
        return Err(Error::FieldRange {
            field: "module state",
            value: u64::from(raw),
            max: u64::from(STATE_MAX),
        });
    }
    Ok(u32::from(raw))
}

/// Check that `buf` holds exactly `len` bytes of a block.
fn check_len(what: &'static str, buf: &[u8], len: usize) -> Result<()> {
    if buf.len() < len {
        return Err(Error::Truncated {
            what,
            needed: len,
            available: buf.len(),
        });
    }
    if buf.len() > len {
        return Err(Error::TrailingBytes {
            what,
            extra: buf.len() - len,
        });
    }
    Ok(())
}

/// The first `len` bytes of an output buffer.
fn out_slice<'a>(what: &'static str, buf: &'a mut [u8], len: usize) -> Result<&'a mut [u8]> {
    let available = buf.len();
    buf.get_mut(..len).ok_or(Error::BufferTooSmall {
        what,
        needed: len,
        available,
    })
}

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
        crate::board::check_max("module kind", u64::from(kind), 0xF)?;
        crate::board::check_max("firmware revision", u64::from(self.firmware), 0xF)?;
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
        crate::board::check_max("physical ID", u64::from(self.phy_id), 63)?;
        let mut b = [0u8; 4];
        f::MOD_ID.set(&mut b, u32::from(self.mod_id.0));
        f::STATE.set(&mut b, state_bits(self.state)?);
        f::PHY_ID.set(&mut b, u32::from(self.phy_id));
        f::GENERATION.set(&mut b, u32::from(self.generation));
        Ok(u32::from_be_bytes(b))
    }
}

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
    fn command_codes_match_table_ii() {
        let table = [
            (Command::Stop, 0, true),
            (Command::IdRequest, 11, false),
            (Command::IdCheck, 12, false),
            (Command::Parameter, 13, true),
            (Command::SetBias, 14, true),
            (Command::Ready, 15, true),
            (Command::Start, 16, true),
            (Command::QRead, 17, false),
            (Command::QWrite, 18, true),
            (Command::FtRead, 19, false),
        ];
        for (cmd, code, broadcast) in table {
            assert_eq!(u8::from(cmd), code);
            assert_eq!(Command::from_offset(u64::from(code)), Some(cmd));
            assert_eq!(cmd.offset(), u64::from(code));
            assert_eq!(cmd.is_broadcast(), broadcast, "{}", cmd.name());
            assert!(cmd.is_known());
        }
        assert_eq!(Command::from_offset(20), Some(Command::Unknown(20)));
        assert_eq!(Command::from_offset(COMMAND_SPACE), None);
        assert_eq!(Command::from_offset(TRACE_BUFFER_OFFSET), None);
        // PARAMETER goes both ways: P2P (Table I) and broadcast (Table II).
        assert!(Command::Parameter.is_point_to_point());
    }

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

    #[test]
    fn masks() {
        let m = ModMask(0).with(ModId(3)).with(ModId(40));
        assert!(m.contains(ModId(3)));
        assert!(!m.contains(ModId(4)));
        assert_eq!(m, ModMask(8));
        assert!(ModMask::ALL.contains(ModId(31)));
        assert!(!ModMask::ALL.contains(ModId(32)));
    }
}
