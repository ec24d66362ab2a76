//! The command field and the names it carries (seed 002, Table II): the command
//! codes and where they are sent, the command and trace-buffer spaces, module
//! IDs and masks, and a module's kind and lifecycle state.

use super::*;

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
    fn masks() {
        let m = ModMask(0).with(ModId(3)).with(ModId(40));
        assert!(m.contains(ModId(3)));
        assert!(!m.contains(ModId(4)));
        assert_eq!(m, ModMask(8));
        assert!(ModMask::ALL.contains(ModId(31)));
        assert!(!ModMask::ALL.contains(ModId(32)));
    }
}
