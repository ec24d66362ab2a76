//! The boards `firelink emulate` (and `firelink fw-run`) serves, assembled
//! from typed options ([`ServedBoards`]): a robot configuration's boards
//! or generic ones, each board's own settings, the bus faults, and the
//! front end that serves them: the Ethernet bridge ([`ServedBoards::bridge`]),
//! the /dev/fw* twin ([`ServedBoards::twin`]) or the Ethernet-only
//! network's chain ([`ServedBoards::chain`]).
//!
//! Rules:
//! - every bus of boards is the one [`RigBuilder`]'s; this module only
//!   turns options into its calls;
//! - an option naming a board the rig does not have is an error naming
//!   that option ([`ServedError::NoSuchBoard`] with a [`BoardOption`]),
//!   never ignored;
//! - a board's own settings (`board_set`) win over every board's
//!   (`fpga`), and the result is checked before anything is built;
//! - nothing here prints or reads a clock: the timed faults wait for the
//!   moment the options give, in emulated time.

use firelink_bus::Detail;
use firelink_control::config::IoConfig;
use firelink_emulate::Bridge;
use firelink_emulate::fw_cdev::Twin;

use super::builder::{Rig, RigBuilder, RobotKind};
use super::{board_configs, generic_boards};
use crate::TestbedError;
use crate::emulated::{
    BoardConfig, BoardSettings, ConfigError, FpgaVersion, Hardware, Profile, SimDuration,
};
use crate::fault_script::BoardFault;
use crate::fault_script::{
    FaultMoment, FaultScript, Occurrence, PacketEffect, PacketSelector, ScriptedFault,
};

/// The option that named a board the rig does not have.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoardOption {
    /// One board's settings.
    BoardSet,
    /// The board whose Ethernet port the bridge uses.
    BridgeBoard,
    /// The board whose cable is unplugged.
    UnplugBoard,
    /// The board that stops answering.
    MuteBoard,
    /// A board a fault script names.
    FaultScript,
    /// A board of the Ethernet-only network's chain.
    Chain,
    /// A board left out of the Ethernet-only network's chain.
    ChainMissing,
}

impl BoardOption {
    /// The command-line option that names a board of this kind.
    pub fn flag(self) -> &'static str {
        match self {
            BoardOption::BoardSet => "--board-set",
            BoardOption::BridgeBoard => "--bridge-board",
            BoardOption::UnplugBoard => "--unplug-board",
            BoardOption::MuteBoard => "--mute-board",
            BoardOption::FaultScript => "--faults",
            BoardOption::Chain => "--chain",
            BoardOption::ChainMissing => "--chain (every emulated board, once; missing)",
        }
    }
}

/// Why the served boards cannot be assembled.
#[derive(Debug, thiserror::Error)]
pub enum ServedError {
    /// An option names a board that is not emulated (naming the option
    /// by its flag).
    #[error("{} {board}: no such board", option.flag())]
    NoSuchBoard {
        /// The option.
        option: BoardOption,
        /// The board ID given.
        board: u8,
    },
    /// A board's settings are inconsistent.
    #[error(transparent)]
    Settings(#[from] ConfigError),
    /// Assembling the rig failed.
    #[error(transparent)]
    Testbed(#[from] TestbedError),
}

/// The faults of the simulated bus (none by default).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BusFaults {
    /// Each packet on the bus dropped with this probability.
    pub drop_rate: f64,
    /// A bit flipped in each packet on the bus with this probability.
    pub corrupt_rate: f64,
    /// Each response a board sends dropped with this probability.
    pub drop_response_rate: f64,
    /// The addressed board busy for each request with this probability.
    pub busy_rate: f64,
    /// Bus resets in a row, 1 ms apart, from the fault moment.
    pub reset_storm: u32,
    /// This board's cable unplugged at the fault moment.
    pub unplug_board: Option<u8>,
    /// This board stops answering at the fault moment.
    pub mute_board: Option<u8>,
    /// Further faults, as a script (after the ones above).
    pub plan: FaultScript,
}

impl BusFaults {
    /// The faults as one script: `firelink emulate`'s `--drop-rate`,
    /// `--corrupt-rate` (from the start, on every packet), `--unplug-board`
    /// and `--mute-board` (at the fault moment), then [`plan`](Self::plan)'s
    /// (`--faults`).
    pub fn script(&self) -> FaultScript {
        let mut script = FaultScript::new();
        for (rate, effect) in [
            (self.drop_rate, PacketEffect::Drop),
            (self.corrupt_rate, PacketEffect::Corrupt),
        ] {
            if rate > 0.0 {
                script = script.with(
                    FaultMoment::Start,
                    ScriptedFault::Packets {
                        effect,
                        select: PacketSelector::default(),
                        occurrence: Occurrence::Rate(rate.min(1.0)),
                    },
                );
            }
        }
        let boards = [
            self.unplug_board.map(BoardFault::Unplug),
            self.mute_board.map(BoardFault::Mute),
        ];
        for b in boards.into_iter().flatten() {
            script = script.with(
                FaultMoment::After(SimDuration::ZERO),
                ScriptedFault::Board(b),
            );
        }
        script.entries.extend(self.plan.entries.iter().copied());
        script
    }
}

/// What to serve: the boards, their faults and the front end's settings.
#[derive(Debug, Clone)]
pub struct ServedBoards {
    /// A robot configuration's boards (Snake nodes for a Snake
    /// configuration); `None`: `boards` generic boards.
    pub config: Option<IoConfig>,
    /// Generic boards (IDs 0..N) when there is no configuration.
    pub boards: u8,
    /// Companion board of the generic boards.
    pub hardware: Hardware,
    /// Firmware of every QLA-family board.
    pub firmware: Profile,
    /// FPGA of every board without its own in `board_set`.
    pub fpga: Option<FpgaVersion>,
    /// Boards' own settings.
    pub board_set: Vec<BoardSettings>,
    /// Commit damaged writes as real Rev 8 boards do.
    pub commit_corrupt_writes: bool,
    /// Seed of the measurement noise and the fault injector.
    pub seed: u64,
    /// The bus faults.
    pub faults: BusFaults,
    /// When the timed faults happen, in emulated time.
    pub fault_at: SimDuration,
    /// The twin only: start the timed faults after this many requests
    /// instead of at `fault_at`.
    pub fault_after_requests: Option<u64>,
    /// The board whose Ethernet port the bridge uses (`None`: the first).
    pub bridge_board: Option<u8>,
    /// The twin only: the split time-out.
    pub split_timeout: SimDuration,
    /// The bus's level of detail (the same answer either way).
    pub detail: Detail,
}

impl Default for ServedBoards {
    /// Eight generic QLA1 boards at Rev 8, seed 0, no faults, faults (if
    /// any) at 5 s, the kernel's 2 s split time-out.
    fn default() -> Self {
        ServedBoards {
            config: None,
            boards: 8,
            hardware: Hardware::Qla1,
            firmware: Profile::Rev8,
            fpga: None,
            board_set: Vec::new(),
            commit_corrupt_writes: false,
            seed: 0,
            faults: BusFaults::default(),
            fault_at: SimDuration::from_millis(5000),
            fault_after_requests: None,
            bridge_board: None,
            split_timeout: SimDuration::from_millis(2000),
            detail: Detail::Fast,
        }
    }
}

/// The bridge to serve, with what a front end says about it.
pub struct ServedBridge {
    /// The bridge.
    pub bridge: Bridge,
    /// The robot kind of the rig.
    pub kind: RobotKind,
    /// The board IDs.
    pub ids: Vec<u8>,
    /// The configurations of its QLA-family boards (none for Snake nodes).
    pub boards: Vec<BoardConfig>,
}

impl ServedBoards {
    /// The robot kind the boards are.
    pub fn kind(&self) -> RobotKind {
        self.config
            .as_ref()
            .map_or(RobotKind::Dvrk, RobotKind::of_config)
    }

    /// The boards on a simulated bus with the faults; the timed faults not
    /// yet scheduled.
    ///
    /// # Errors
    /// A board's settings are inconsistent; an option names a board that
    /// is not there; the rig cannot be built.
    pub fn rig(&self) -> Result<Rig, ServedError> {
        let builder = match &self.config {
            Some(c) if self.kind() == RobotKind::Snake => {
                RigBuilder::snake(crate::snake::node_configs(c, self.seed)?)
            }
            _ => RigBuilder::qla(self.qla_boards()?),
        };
        let f = &self.faults;
        let mut builder = builder
            .seed(self.seed)
            .detail(self.detail)
            .fault_script(&f.script());
        if f.drop_response_rate > 0.0 {
            builder = builder.drop_responses(f.drop_response_rate);
        }
        if f.busy_rate > 0.0 {
            builder = builder.busy_requests(f.busy_rate);
        }
        builder = builder.reset_storm(f.reset_storm);
        builder.build().map_err(|e| match e {
            TestbedError::NoSuchBoard { role, board } => ServedError::NoSuchBoard {
                option: if role == BoardFault::Mute(board).role() && f.mute_board == Some(board) {
                    BoardOption::MuteBoard
                } else if role == BoardFault::Unplug(board).role() && f.unplug_board == Some(board)
                {
                    BoardOption::UnplugBoard
                } else {
                    BoardOption::FaultScript
                },
                board,
            },
            other => other.into(),
        })
    }

    /// The QLA-family boards: the configuration's (or generic ones), with
    /// the boards' own settings, `fpga` and `commit_corrupt_writes`
    /// applied and checked.
    ///
    /// # Errors
    /// A board's settings name a board that is not there, or are
    /// inconsistent.
    pub fn qla_boards(&self) -> Result<Vec<BoardConfig>, ServedError> {
        let mut boards = match &self.config {
            Some(config) => board_configs(config, self.firmware, config.board_slots()),
            None => generic_boards(self.boards, self.hardware, self.firmware, self.seed),
        };
        for set in &self.board_set {
            let board = boards
                .iter_mut()
                .find(|b| b.board_id == set.board_id)
                .ok_or(ServedError::NoSuchBoard {
                    option: BoardOption::BoardSet,
                    board: set.board_id,
                })?;
            *board = set.apply(board.clone());
        }
        // `fpga` is every board's FPGA unless its own settings name one
        // (so a DQLA asked for on a V2 is refused by the check below).
        if let Some(fpga) = self.fpga {
            for b in &mut boards {
                let own = self
                    .board_set
                    .iter()
                    .any(|s| s.board_id == b.board_id && s.fpga.is_some());
                if !own {
                    b.fpga = fpga;
                }
            }
        }
        for b in &mut boards {
            b.commit_corrupt_writes = self.commit_corrupt_writes;
        }
        for b in &boards {
            b.check()?;
        }
        Ok(boards)
    }

    /// The Ethernet bridge: the rig with its timed faults scheduled at
    /// `fault_at`, its Ethernet port on `bridge_board`.
    ///
    /// # Errors
    /// As [`rig`](Self::rig); the bridge board is not there.
    pub fn bridge(&self) -> Result<ServedBridge, ServedError> {
        let mut rig = self.rig()?;
        rig.schedule_pending(self.fault_at);
        let (kind, ids, boards) = (rig.kind, rig.ids(), rig.configs.clone());
        let bridge = rig.bridge(self.bridge_board).map_err(|e| match e {
            TestbedError::NoSuchBoard { board, .. } => ServedError::NoSuchBoard {
                option: BoardOption::BridgeBoard,
                board,
            },
            other => other.into(),
        })?;
        Ok(ServedBridge {
            bridge,
            kind,
            ids,
            boards,
        })
    }

    /// The /dev/fw* twin and the board IDs: the rig's timed faults
    /// deferred to the `fault_after_requests`-th request, else scheduled
    /// at `fault_at`.
    ///
    /// # Errors
    /// As [`rig`](Self::rig).
    pub fn twin(&self) -> Result<(Twin, Vec<u8>), ServedError> {
        let mut rig = self.rig()?;
        let ids = rig.ids();
        let deferred = match self.fault_after_requests {
            Some(n) => Some((n, rig.take_pending())),
            None => {
                rig.schedule_pending(self.fault_at);
                None
            }
        };
        let mut twin = Twin::new(rig.bus, rig.host);
        twin.set_split_timeout(self.split_timeout);
        if let Some((n, faults)) = deferred {
            twin.defer_faults(n, faults);
        }
        Ok((twin, ids))
    }

    /// The QLA-family boards in the Ethernet-only network's chain order
    /// from the host (`chain`: board IDs, every board once; empty: as
    /// emulated).
    ///
    /// # Errors
    /// As [`qla_boards`](Self::qla_boards); the chain names a board that is
    /// not there, or leaves one out.
    pub fn chain(&self, chain: &[u8]) -> Result<Vec<BoardConfig>, ServedError> {
        let mut boards = self.qla_boards()?;
        if chain.is_empty() {
            return Ok(boards);
        }
        let mut ordered = Vec::with_capacity(boards.len());
        for &id in chain {
            let i =
                boards
                    .iter()
                    .position(|b| b.board_id == id)
                    .ok_or(ServedError::NoSuchBoard {
                        option: BoardOption::Chain,
                        board: id,
                    })?;
            ordered.push(boards.swap_remove(i));
        }
        if let Some(left) = boards.first() {
            return Err(ServedError::NoSuchBoard {
                option: BoardOption::ChainMissing,
                board: left.board_id,
            });
        }
        Ok(ordered)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each option that names a missing board is named in the error.
    #[test]
    fn a_missing_board_names_its_option() {
        let four = ServedBoards {
            boards: 4,
            ..ServedBoards::default()
        };
        let missing = |r: Result<(), ServedError>| match r {
            Err(ServedError::NoSuchBoard { option, board }) => Some((option, board)),
            _ => None,
        };
        let mut muted = four.clone();
        muted.faults.mute_board = Some(9);
        assert_eq!(
            missing(muted.rig().map(drop)),
            Some((BoardOption::MuteBoard, 9))
        );
        let mut unplugged = four.clone();
        unplugged.faults.unplug_board = Some(7);
        assert_eq!(
            missing(unplugged.rig().map(drop)),
            Some((BoardOption::UnplugBoard, 7))
        );
        let mut bridged = four.clone();
        bridged.bridge_board = Some(5);
        assert_eq!(
            missing(bridged.bridge().map(drop)),
            Some((BoardOption::BridgeBoard, 5))
        );
        let mut set = four.clone();
        set.board_set = vec!["6:qla-serial=1".parse().expect("settings")];
        assert_eq!(
            missing(set.qla_boards().map(drop)),
            Some((BoardOption::BoardSet, 6))
        );
        assert_eq!(
            missing(four.chain(&[0, 1, 8]).map(drop)),
            Some((BoardOption::Chain, 8))
        );
        assert_eq!(
            missing(four.chain(&[3, 1, 0]).map(drop)),
            Some((BoardOption::ChainMissing, 2))
        );
    }

    /// The chain orders the boards as given; a board's own FPGA wins over
    /// every board's.
    #[test]
    fn chain_order_and_own_settings() {
        let served = ServedBoards {
            boards: 3,
            fpga: Some(FpgaVersion::V3),
            firmware: Profile::Rev9,
            board_set: vec!["1:fpga=V2".parse().expect("settings")],
            ..ServedBoards::default()
        };
        let boards = served.chain(&[2, 0, 1]).expect("the chain");
        let ids: Vec<u8> = boards.iter().map(|b| b.board_id).collect();
        assert_eq!(ids, [2, 0, 1]);
        let fpgas: Vec<FpgaVersion> = boards.iter().map(|b| b.fpga).collect();
        assert_eq!(fpgas, [FpgaVersion::V3, FpgaVersion::V3, FpgaVersion::V2]);
        assert_eq!(served.chain(&[]).expect("as emulated").len(), 3);
    }
}
