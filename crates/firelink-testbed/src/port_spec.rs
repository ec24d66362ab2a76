//! Where the robot is: the one grammar of port strings that every front end
//! (the CLI's `--port`, the web console, the ROS 2 node, Python's
//! `firelink.open` and `Port`) parses, so that a port string means the same
//! everywhere.
//!
//! | String              | Meaning |
//! |---------------------|---------|
//! | `sim`               | the robot's emulated boards on an in-process simulated bus (virtual time) |
//! | `sim:N`             | boards 0..N of that robot (N 1..=16) |
//! | `sim:N:FW`          | the same at firmware FW: `7` (or `rev7`), `8` (or `rev8`), `seed` |
//! | `emulate`           | the robot's boards behind an in-process `firelink emulate`, over loopback UDP |
//! | `udp:HOST[:PORT]`   | the best way to the boards answering at HOST (port 1394 by default): the Ethernet-only network when the board answering is an FPGA V3 at Rev 9 or later (HOST a board's address or the group's: `udp:127.255.255.255` for `firelink emulate --network eth`), else the bridge (a bridge board, or a running `firelink emulate`) |
//! | `udpfw:HOST[:PORT]` | the bridge protocol whatever answers (the dVRK's `udpfw`) |
//! | `fw` / `fw:N`       | FireWire card 0 / N through Linux /dev/fw* (or the twin of `firelink fw-run`) |
//!
//! **What `sim` holds.** The boards of the robot the command runs: for a
//! robot program (demo, web console, ROS 2 node, Python's `IoSystem` and
//! demo) the boards its configuration uses (IDs 0 to the highest), each
//! joint driving the plant its configuration names; for the bus tools
//! (`scan`, `read`, `write`, `monitor`, Python's `Port`), which run no
//! robot, seed 000's dVRK (`configs/dvrk-seed000.json`: 8 QLA1 boards,
//! MTML, MTMR, PSM1, PSM2). `sim:N` keeps boards 0..N of it; an ID the
//! robot does not use is a QLA1 with generic motors. The firmware is Rev 8
//! unless the string (or, without one, the command's own firmware option)
//! says otherwise. Seed 001's Snake nodes and seed 002's MAHRU modules come
//! from their configurations and have no QLA firmware: those robots take
//! plain `sim`.
//!
//! The name of a transport is the text before the first `:`; an unknown
//! one is refused with the list above. Leading and trailing spaces are ignored.
//!
//! A front end that cannot use a kind of port refuses it with
//! [`PortSpec::refuse_unless`], naming the command and the port.

use std::fmt;
use std::net::SocketAddr;
use std::str::FromStr;

use firelink_board::qla::config::Profile;
use firelink_host::udp::UdpPort;

/// What every front end accepts, as its error messages say it.
pub const EXPECTED: &str = "sim, sim:N, sim:N:FW (N 1..=16, FW 7, 8, 9 or seed), emulate, udp:HOST[:PORT], udpfw:HOST[:PORT], fw or fw:N";

/// The largest board count of `sim:N` (the board-ID space of one bus).
pub const MAX_SIM_BOARDS: u8 = 16;

/// The boards of `sim:N[:FW]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimBoards {
    /// Boards 0..count of the robot (1..=[`MAX_SIM_BOARDS`]).
    pub count: u8,
    /// Their firmware, when the string names one.
    pub firmware: Option<Profile>,
}

/// A parsed port string (see the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PortSpec {
    /// `sim` (`None`: the robot's own boards) or `sim:N[:FW]`.
    Sim(Option<SimBoards>),
    /// `emulate`.
    Emulate,
    /// `udp:HOST[:PORT]`, resolved: the Ethernet-only network or the
    /// bridge, whichever the board answering calls for.
    Udp(SocketAddr),
    /// `udpfw:HOST[:PORT]`, resolved: the bridge protocol.
    UdpFw(SocketAddr),
    /// `fw` (card 0) or `fw:N`.
    Fw(u32),
}

impl Default for PortSpec {
    fn default() -> Self {
        PortSpec::Sim(None)
    }
}

/// The kinds of port, for a front end to say which it can use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PortKind {
    /// `sim[...]`.
    Sim,
    /// `emulate`.
    Emulate,
    /// `udp:...` and `udpfw:...`.
    Udp,
    /// `fw[:N]`.
    Fw,
}

impl PortKind {
    /// Its name in port strings.
    pub fn name(self) -> &'static str {
        match self {
            PortKind::Sim => "sim",
            PortKind::Emulate => "emulate",
            PortKind::Udp => "udp",
            PortKind::Fw => "fw",
        }
    }
}

/// A port string that is not one (see [`EXPECTED`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PortSpecError {
    /// The transport's name is not known.
    #[error("unknown port {port:?}: expected {EXPECTED}")]
    Unknown {
        /// The string given.
        port: String,
    },
    /// The transport is known, the rest of the string is wrong.
    #[error("port {port:?}: {problem} (expected {EXPECTED})")]
    Malformed {
        /// The string given.
        port: String,
        /// What is wrong with it.
        problem: String,
    },
    /// A `udp:` address that cannot be used (bad syntax, port 0, a name
    /// that does not resolve).
    #[error("port {port:?}: {error}")]
    Address {
        /// The string given.
        port: String,
        /// Why the address cannot be used.
        error: firelink_host::HostError,
    },
}

/// A well-formed port that a front end cannot use.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{command}: port {port} cannot be used: {reason}")]
pub struct PortRefused {
    /// The command (`firelink bench --port`, `firelink.SnakeSystem`).
    pub command: String,
    /// The port, as [`PortSpec`] writes it.
    pub port: String,
    /// Why, and what it takes instead.
    pub reason: String,
}

impl PortSpec {
    /// The plain `sim`.
    pub const SIM: PortSpec = PortSpec::Sim(None);

    /// Its kind.
    pub fn kind(&self) -> PortKind {
        match self {
            PortSpec::Sim(_) => PortKind::Sim,
            PortSpec::Emulate => PortKind::Emulate,
            PortSpec::Udp(_) | PortSpec::UdpFw(_) => PortKind::Udp,
            PortSpec::Fw(_) => PortKind::Fw,
        }
    }

    /// Whether the boards are on the in-process simulated bus (virtual
    /// time).
    pub fn is_sim(&self) -> bool {
        matches!(self, PortSpec::Sim(_))
    }

    /// The pacing that suits the port when the caller does not choose:
    /// virtual time on `sim`, the wall clock everywhere else.
    pub fn default_pacing(&self) -> firelink_control::runner::Pacing {
        use firelink_control::runner::Pacing;
        if self.is_sim() {
            Pacing::Virtual
        } else {
            Pacing::WallClock
        }
    }

    /// `Ok` when this port is of one of the `accepted` kinds, else why
    /// `command` refuses it (naming the command, the port and the kinds
    /// it takes).
    ///
    /// # Errors
    /// [`PortRefused`].
    pub fn refuse_unless(&self, command: &str, accepted: &[PortKind]) -> Result<(), PortRefused> {
        if accepted.contains(&self.kind()) {
            return Ok(());
        }
        let names: Vec<&str> = accepted.iter().map(|k| k.name()).collect();
        Err(self.refused(command, format!("it takes {}", names.join(", "))))
    }

    /// `Ok` for plain `sim` and every other kind; `sim:N[:FW]` refused by
    /// `command`, whose boards come from its configuration.
    ///
    /// # Errors
    /// [`PortRefused`].
    pub fn refuse_board_count(&self, command: &str, why: &str) -> Result<(), PortRefused> {
        match self {
            PortSpec::Sim(Some(_)) => Err(self.refused(
                command,
                format!("{why}: use plain sim (the board count and firmware come from there)"),
            )),
            _ => Ok(()),
        }
    }

    /// The refusal of this port by `command`, for `reason`.
    pub fn refused(&self, command: &str, reason: String) -> PortRefused {
        PortRefused {
            command: command.to_string(),
            port: self.to_string(),
            reason,
        }
    }

    /// `sim:N`'s board count, or `default` (the robot's own).
    pub fn sim_board_count(&self, default: usize) -> usize {
        match self {
            PortSpec::Sim(Some(b)) => usize::from(b.count),
            _ => default,
        }
    }

    /// `sim:N:FW`'s firmware, or `default` (the command's own option).
    pub fn sim_firmware(&self, default: Profile) -> Profile {
        match self {
            PortSpec::Sim(Some(SimBoards {
                firmware: Some(f), ..
            })) => *f,
            _ => default,
        }
    }
}

/// A firmware's name in port strings.
fn firmware_name(profile: Profile) -> &'static str {
    match profile {
        Profile::Rev7 => "7",
        Profile::Rev8 => "8",
        Profile::Rev9 => "9",
        Profile::Seed => "seed",
    }
}

/// A firmware named in a port string (`7` or `rev7`, `8` or `rev8`,
/// `seed`).
pub fn firmware_of(name: &str) -> Option<Profile> {
    match name {
        "7" | "rev7" => Some(Profile::Rev7),
        "8" | "rev8" => Some(Profile::Rev8),
        "9" | "rev9" => Some(Profile::Rev9),
        "seed" => Some(Profile::Seed),
        _ => None,
    }
}

/// `--port` in every front end's command line (clap's `value_parser`): the
/// one grammar, [`PortSpec`]'s `FromStr`.
///
/// # Errors
/// What the grammar finds, naming the string and what is expected.
pub fn parse_port(text: &str) -> Result<PortSpec, PortSpecError> {
    text.parse()
}

impl FromStr for PortSpec {
    type Err = PortSpecError;

    fn from_str(text: &str) -> Result<PortSpec, PortSpecError> {
        let text = text.trim();
        let malformed = |problem: String| PortSpecError::Malformed {
            port: text.to_string(),
            problem,
        };
        let (kind, rest) = match text.split_once(':') {
            Some((kind, rest)) => (kind, Some(rest)),
            None => (text, None),
        };
        match (kind, rest) {
            ("sim", None) => Ok(PortSpec::SIM),
            ("sim", Some(rest)) => {
                let mut parts = rest.split(':');
                let count = parts.next().unwrap_or("");
                let count = count
                    .parse::<u8>()
                    .ok()
                    .filter(|n| (1..=MAX_SIM_BOARDS).contains(n))
                    .ok_or_else(|| {
                        malformed(format!(
                            "the board count is 1..={MAX_SIM_BOARDS}, not {count:?}"
                        ))
                    })?;
                let firmware = match parts.next() {
                    None => None,
                    Some(f) => Some(firmware_of(f).ok_or_else(|| {
                        malformed(format!("the firmware is 7, 8, 9 or seed, not {f:?}"))
                    })?),
                };
                if let Some(extra) = parts.next() {
                    return Err(malformed(format!(
                        "unexpected {extra:?} after the firmware"
                    )));
                }
                Ok(PortSpec::Sim(Some(SimBoards { count, firmware })))
            }
            ("emulate", None) => Ok(PortSpec::Emulate),
            ("emulate", Some(_)) => Err(malformed(
                "emulate takes nothing after it (its boards are the robot's)".into(),
            )),
            ("udp", _) => UdpPort::parse_address(text)
                .map(PortSpec::Udp)
                .map_err(|error| PortSpecError::Address {
                    port: text.to_string(),
                    error,
                }),
            ("udpfw", _) => UdpPort::parse_address(rest.unwrap_or(""))
                .map(PortSpec::UdpFw)
                .map_err(|error| PortSpecError::Address {
                    port: text.to_string(),
                    error,
                }),
            ("fw", None) => Ok(PortSpec::Fw(0)),
            ("fw", Some(card)) => card
                .parse::<u32>()
                .map(PortSpec::Fw)
                .map_err(|_| malformed(format!("the card is a number, not {card:?}"))),
            _ => Err(PortSpecError::Unknown {
                port: text.to_string(),
            }),
        }
    }
}

impl fmt::Display for PortSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PortSpec::Sim(None) => f.write_str("sim"),
            PortSpec::Sim(Some(SimBoards {
                count,
                firmware: None,
            })) => write!(f, "sim:{count}"),
            PortSpec::Sim(Some(SimBoards {
                count,
                firmware: Some(fw),
            })) => write!(f, "sim:{count}:{}", firmware_name(*fw)),
            PortSpec::Emulate => f.write_str("emulate"),
            PortSpec::Udp(addr) => write!(f, "udp:{addr}"),
            PortSpec::UdpFw(addr) => write!(f, "udpfw:{addr}"),
            PortSpec::Fw(card) => write!(f, "fw:{card}"),
        }
    }
}

/// The table of port strings every front end is tested against
/// (`port-strings.tsv` beside this crate's manifest; Python's tests read
/// the same file).
pub const TABLE: &str = include_str!("../port-strings.tsv");

/// One row of [`TABLE`]: a string and what it means (the port written
/// back) or a text its refusal contains.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TableRow {
    /// The port string.
    pub text: &'static str,
    /// `Ok(written back)` or `Err(part of the refusal)`.
    pub meaning: Result<&'static str, &'static str>,
}

/// The rows of [`TABLE`] (comments and blank lines skipped).
pub fn table() -> Vec<TableRow> {
    TABLE
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .filter_map(|l| l.split_once('\t'))
        .map(|(text, meaning)| TableRow {
            text,
            meaning: match meaning.strip_prefix("refused:") {
                Some(says) => Err(says),
                None => Ok(meaning),
            },
        })
        .collect()
}

/// Run every row of [`TABLE`] through a front end's parser `parse` (its
/// error as text) and say where it disagrees: a string the table accepts
/// must give the same port, unless `accepts` says the front end cannot use
/// that port, when it must be refused naming the port and "cannot be
/// used"; a string the table refuses must be refused with the table's
/// text. Returns every disagreement (empty: the front end agrees).
pub fn disagreements_with_table(
    parse: impl Fn(&str) -> Result<PortSpec, String>,
    accepts: impl Fn(&PortSpec) -> bool,
) -> Vec<String> {
    let mut out = Vec::new();
    for row in table() {
        let got = parse(row.text);
        match (row.meaning, &got) {
            (Ok(written), Ok(spec)) if spec.to_string() == written && accepts(spec) => {}
            (Ok(written), Err(e)) => {
                let meant: Result<PortSpec, _> = written.parse();
                let refused_rightly = meant.as_ref().is_ok_and(|m| !accepts(m))
                    && e.contains("cannot be used")
                    && e.contains(written);
                if !refused_rightly {
                    out.push(format!(
                        "{:?}: refused ({e}), the table says {written}",
                        row.text
                    ));
                }
            }
            (Err(says), Err(e)) if e.contains(says) => {}
            (_, got) => out.push(format!(
                "{:?}: got {got:?}, the table says {:?}",
                row.text, row.meaning
            )),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::{IpAddr, Ipv4Addr};

    fn udp(port: u16) -> PortSpec {
        PortSpec::Udp(SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), port))
    }

    /// What each accepted string means, and that writing it back and
    /// parsing that gives the same port.
    #[test]
    fn accepted_strings_and_their_round_trip() {
        let sim = |count, firmware| PortSpec::Sim(Some(SimBoards { count, firmware }));
        for (text, meaning, written) in [
            ("sim", PortSpec::SIM, "sim"),
            (" sim ", PortSpec::SIM, "sim"),
            ("sim:1", sim(1, None), "sim:1"),
            ("sim:16:8", sim(16, Some(Profile::Rev8)), "sim:16:8"),
            ("sim:5:rev7", sim(5, Some(Profile::Rev7)), "sim:5:7"),
            ("sim:3:seed", sim(3, Some(Profile::Seed)), "sim:3:seed"),
            ("sim:2:rev9", sim(2, Some(Profile::Rev9)), "sim:2:9"),
            ("emulate", PortSpec::Emulate, "emulate"),
            ("udp:127.0.0.1", udp(1394), "udp:127.0.0.1:1394"),
            ("udp:localhost:1500", udp(1500), "udp:127.0.0.1:1500"),
            (
                "udpfw:127.0.0.1",
                PortSpec::UdpFw("127.0.0.1:1394".parse().unwrap()),
                "udpfw:127.0.0.1:1394",
            ),
            ("fw", PortSpec::Fw(0), "fw:0"),
            ("fw:3", PortSpec::Fw(3), "fw:3"),
        ] {
            let parsed: PortSpec = text.parse().unwrap_or_else(|e| panic!("{text}: {e}"));
            assert_eq!(parsed, meaning, "{text}");
            assert_eq!(parsed.to_string(), written, "{text}");
            assert_eq!(written.parse::<PortSpec>(), Ok(meaning), "{written}");
        }
        assert_eq!(PortSpec::default(), PortSpec::SIM);
    }

    /// Each refused string is refused with what was wrong and what is
    /// expected.
    #[test]
    fn refused_strings_say_what_is_wrong() {
        for (text, says) in [
            ("", "unknown port"),
            ("tcp:x", "unknown port"),
            ("udpfw:", "expected udp:HOST"),
            ("sim4", "unknown port"),
            ("sim:", "board count is 1..=16"),
            ("sim:0", "board count is 1..=16"),
            ("sim:17", "board count is 1..=16"),
            ("sim::7", "board count is 1..=16"),
            ("sim:4:10", "firmware is 7, 8, 9 or seed"),
            ("sim:4:8:x", "unexpected \"x\""),
            ("emulate:2", "takes nothing after it"),
            ("fw:x", "the card is a number"),
            ("fw:-1", "the card is a number"),
            ("udp:", "expected udp:HOST"),
            ("udp:localhost:99999", "from 1 to 65535"),
        ] {
            let e = text.parse::<PortSpec>().expect_err(text);
            let message = e.to_string();
            assert!(message.contains(says), "{text}: {message}");
            assert!(
                message.contains(&format!("port {:?}", text.trim())),
                "{text}: {message}"
            );
        }
    }

    /// The shared table through the parser itself: every row agrees, and
    /// a front end that takes only UDP refuses the rest by name.
    #[test]
    fn the_table_of_port_strings() {
        assert!(table().len() >= 30);
        let parse = |s: &str| s.parse::<PortSpec>().map_err(|e| e.to_string());
        assert_eq!(
            disagreements_with_table(parse, |_| true),
            Vec::<String>::new()
        );
        let udp_only = |s: &str| {
            let spec = s.parse::<PortSpec>().map_err(|e| e.to_string())?;
            spec.refuse_unless("u", &[PortKind::Udp])
                .map_err(|e| e.to_string())?;
            Ok(spec)
        };
        let is_udp = |p: &PortSpec| p.kind() == PortKind::Udp;
        assert_eq!(
            disagreements_with_table(udp_only, is_udp),
            Vec::<String>::new()
        );
        // A parser that accepts what it should refuse disagrees.
        let lax = |_: &str| Ok(PortSpec::SIM);
        assert!(!disagreements_with_table(lax, |_| true).is_empty());
    }

    #[test]
    fn refusals_name_the_command_and_the_port() {
        let fw = PortSpec::Fw(1);
        assert_eq!(fw.refuse_unless("x", &[PortKind::Fw]), Ok(()));
        let e = fw
            .refuse_unless("firelink bench --port", &[PortKind::Udp])
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "firelink bench --port: port fw:1 cannot be used: it takes udp"
        );
        let four: PortSpec = "sim:4".parse().unwrap();
        assert!(four.refuse_board_count("snake", "nodes").is_err());
        assert!(PortSpec::SIM.refuse_board_count("snake", "nodes").is_ok());
        assert_eq!(four.sim_board_count(8), 4);
        assert_eq!(PortSpec::SIM.sim_board_count(8), 8);
        assert_eq!(four.sim_firmware(Profile::Seed), Profile::Seed);
    }
}
