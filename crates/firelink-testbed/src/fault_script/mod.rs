//! Faults as a plan: a [`FaultScript`] says what goes wrong and when
//! (a board by ID stops answering or is unplugged, matching packets are
//! corrupted or dropped, the host pauses), as data, before the run starts.
//! The rig turns it into the simulated bus's fault plan
//! ([`RigBuilder::fault_script`](crate::rig::RigBuilder::fault_script));
//! on any other port (UDP to the emulator, and whatever transport shows its
//! packets) it becomes a link filter ([`ScriptFilter`]), so corruption and
//! drops work there too. A servo loop that runs a script hands each entry,
//! when due, to its port's [`FaultTarget`] (made by whoever built the
//! port), which applies it there or refuses it by name.
//!
//! The text form is one entry per fault, `;` between entries:
//!
//! ```text
//! mute@t=0us:id=4                       board 4 stops answering at the fault moment
//! unplug@t=5000000us:id=7               board 7's cable is pulled 5 s after it
//! corrupt@start:tcode=0x0,offset=0x1800,count=1
//! drop@cycle=300:dest=4,rate=0.25       a quarter of the packets to board 4, from cycle 300
//! host-pause@cycle=500:for=30000us      the host stops for 30 ms at cycle 500
//! ```
//!
//! Rules:
//! - boards are named by their board ID, never by their place on the bus;
//!   whoever applies a script looks the board up (the rig, or the host's
//!   scan) and refuses an ID it does not have;
//! - a moment is the run's start (`start`), a time after the fault moment
//!   (`t=`, whole microseconds, the rig's fault moment on the simulated
//!   bus, the port's clock at the filter's creation elsewhere) or a servo
//!   cycle (`cycle=`, counted by whoever runs the servo loop);
//! - a packet rule fires at random with `rate` (seeded) or on the first
//!   `count` matching packets, exactly one of the two;
//! - parsing never panics; every error names the entry and what in it was
//!   wrong ([`FaultScriptError`]); [`Display`](fmt::Display) gives back
//!   text that parses to the same script.

mod filter;
pub(crate) mod target;

use std::fmt;
use std::str::FromStr;
use std::time::Duration;

use firelink_bus::{NodeHandle, SimDuration, TimedFault};
use firelink_wire::packet::Tcode;

pub use filter::{ScriptCounts, ScriptFilter, ScriptHandle};
pub(crate) use target::apply_on_bus;
pub use target::{BoardFaultChannel, FaultTarget};

/// A fault on one board, named by its board ID.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoardFault {
    /// Its cable is unplugged for good (a bus reset follows).
    Unplug(u8),
    /// It stops answering for good.
    Mute(u8),
}

impl BoardFault {
    /// The simulated bus's fault for it, on the board's `node`.
    pub(crate) fn on_node(self, node: NodeHandle) -> TimedFault {
        match self {
            BoardFault::Unplug(_) => TimedFault::Disconnect {
                node,
                reconnect_after: None,
            },
            BoardFault::Mute(_) => TimedFault::StopAnswering {
                node,
                duration: None,
            },
        }
    }

    /// The board it names.
    pub fn board_id(self) -> u8 {
        match self {
            BoardFault::Unplug(id) | BoardFault::Mute(id) => id,
        }
    }

    /// What it does, for messages.
    pub fn role(self) -> &'static str {
        match self {
            BoardFault::Unplug(_) => "unplugged board",
            BoardFault::Mute(_) => "muted board",
        }
    }
}

/// When a scripted fault starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultMoment {
    /// From the start of the run (`start`).
    Start,
    /// This long after the fault moment (`t=Nus`).
    After(SimDuration),
    /// At this servo cycle (`cycle=N`), counted by the servo loop.
    Cycle(u64),
}

/// What happens to a matching packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PacketEffect {
    /// One bit of it is flipped (its CRCs then disagree).
    Corrupt,
    /// It is lost.
    Drop,
}

/// How often a packet rule fires.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Occurrence {
    /// Each matching packet with this probability (0 to 1), seeded.
    Rate(f64),
    /// The first this many matching packets.
    Count(u32),
}

/// Which packets a packet rule applies to; every field left `None`
/// matches anything.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PacketSelector {
    /// Transaction code.
    pub tcode: Option<Tcode>,
    /// The board the packet is addressed to, by board ID.
    pub dest: Option<u8>,
    /// The low 16 bits of the destination offset.
    pub offset: Option<u16>,
}

/// One kind of scripted fault.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ScriptedFault {
    /// A board stops answering or is unplugged, for good.
    Board(BoardFault),
    /// Matching packets are corrupted or dropped.
    Packets {
        /// Corrupted or dropped.
        effect: PacketEffect,
        /// Which packets.
        select: PacketSelector,
        /// How often.
        occurrence: Occurrence,
    },
    /// The host stops sending for this long (the servo loop does it).
    HostPause(Duration),
}

/// One entry of a script: a fault and its moment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScriptEntry {
    /// When it starts.
    pub at: FaultMoment,
    /// What it is.
    pub fault: ScriptedFault,
}

/// Faults as a plan: entries in the order given. See the module docs.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FaultScript {
    /// The entries.
    pub entries: Vec<ScriptEntry>,
}

/// Why a script's text is not one. Every variant names the entry (its
/// text) it is about.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FaultScriptError {
    /// No `@` between the kind and the moment.
    #[error("fault {entry:?}: expected KIND@MOMENT[:FIELDS], e.g. mute@t=0us:id=4")]
    Shape {
        /// The entry.
        entry: String,
    },
    /// A kind this grammar does not have.
    #[error(
        "fault {entry:?}: unknown kind {kind:?}: expected mute, unplug, corrupt, drop or host-pause"
    )]
    Kind {
        /// The entry.
        entry: String,
        /// The kind given.
        kind: String,
    },
    /// A moment that is not `start`, `t=Nus` or `cycle=N`.
    #[error("fault {entry:?}: moment {moment:?}: expected start, t=MICROSECONDSus or cycle=N")]
    Moment {
        /// The entry.
        entry: String,
        /// The moment given.
        moment: String,
    },
    /// A field this kind does not take, or one given twice.
    #[error("fault {entry:?}: field {field:?}: {why}")]
    Field {
        /// The entry.
        entry: String,
        /// The field given.
        field: String,
        /// What is wrong with it.
        why: &'static str,
    },
    /// A field's value that does not parse or is out of range.
    #[error("fault {entry:?}: {field}={value:?}: {why}")]
    Value {
        /// The entry.
        entry: String,
        /// The field.
        field: &'static str,
        /// The value given.
        value: String,
        /// What it must be.
        why: &'static str,
    },
    /// A field the kind needs is missing.
    #[error("fault {entry:?}: {why}")]
    Missing {
        /// The entry.
        entry: String,
        /// What is missing.
        why: &'static str,
    },
}

impl FaultScript {
    /// No faults.
    pub fn new() -> FaultScript {
        FaultScript::default()
    }

    /// The script with `fault` added at `at`.
    pub fn with(mut self, at: FaultMoment, fault: ScriptedFault) -> FaultScript {
        self.entries.push(ScriptEntry { at, fault });
        self
    }

    /// Whether there are no entries.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

impl fmt::Display for FaultMoment {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FaultMoment::Start => f.write_str("start"),
            FaultMoment::After(d) => write!(f, "t={}us", d.as_nanos() / 1000),
            FaultMoment::Cycle(n) => write!(f, "cycle={n}"),
        }
    }
}

impl fmt::Display for ScriptEntry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.fault {
            ScriptedFault::Board(b) => {
                let kind = match b {
                    BoardFault::Mute(_) => "mute",
                    BoardFault::Unplug(_) => "unplug",
                };
                write!(f, "{kind}@{}:id={}", self.at, b.board_id())
            }
            ScriptedFault::Packets {
                effect,
                select,
                occurrence,
            } => {
                let kind = match effect {
                    PacketEffect::Corrupt => "corrupt",
                    PacketEffect::Drop => "drop",
                };
                write!(f, "{kind}@{}:", self.at)?;
                if let Some(t) = select.tcode {
                    write!(f, "tcode={:#x},", u8::from(t))?;
                }
                if let Some(d) = select.dest {
                    write!(f, "dest={d},")?;
                }
                if let Some(o) = select.offset {
                    write!(f, "offset={o:#x},")?;
                }
                match occurrence {
                    Occurrence::Rate(r) => write!(f, "rate={r}"),
                    Occurrence::Count(n) => write!(f, "count={n}"),
                }
            }
            ScriptedFault::HostPause(d) => {
                write!(f, "host-pause@{}:for={}us", self.at, d.as_micros())
            }
        }
    }
}

impl fmt::Display for FaultScript {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.entries.iter().enumerate() {
            if i > 0 {
                f.write_str(";")?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

/// A whole number, decimal or `0x` hexadecimal.
fn number(text: &str) -> Option<u64> {
    match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u64::from_str_radix(hex, 16).ok(),
        None => text.parse().ok(),
    }
}

/// Microseconds written `Nus`.
fn micros(text: &str) -> Option<u64> {
    text.strip_suffix("us").and_then(|n| n.parse().ok())
}

/// The fields of one entry, each taken at most once.
struct Fields<'a> {
    entry: &'a str,
    given: Vec<(&'a str, &'a str)>,
}

impl<'a> Fields<'a> {
    fn parse(
        entry: &'a str,
        text: Option<&'a str>,
        allowed: &[&str],
    ) -> Result<Self, FaultScriptError> {
        let mut given: Vec<(&str, &str)> = Vec::new();
        for field in text.into_iter().flat_map(|t| t.split(',')) {
            let field = field.trim();
            let bad = |why| FaultScriptError::Field {
                entry: entry.into(),
                field: field.into(),
                why,
            };
            let (name, value) = field
                .split_once('=')
                .ok_or_else(|| bad("expected NAME=VALUE"))?;
            if !allowed.contains(&name) {
                return Err(bad("this kind of fault has no such field"));
            }
            if given.iter().any(|(n, _)| *n == name) {
                return Err(bad("given twice"));
            }
            given.push((name, value));
        }
        Ok(Fields { entry, given })
    }

    fn get(&self, name: &str) -> Option<&'a str> {
        self.given.iter().find(|(n, _)| *n == name).map(|(_, v)| *v)
    }

    /// Field `name` parsed with `parse`, which must give `Some`.
    fn value<T>(
        &self,
        name: &'static str,
        why: &'static str,
        parse: impl Fn(&str) -> Option<T>,
    ) -> Result<Option<T>, FaultScriptError> {
        self.get(name)
            .map(|v| {
                parse(v).ok_or_else(|| FaultScriptError::Value {
                    entry: self.entry.into(),
                    field: name,
                    value: v.into(),
                    why,
                })
            })
            .transpose()
    }

    fn missing(&self, why: &'static str) -> FaultScriptError {
        FaultScriptError::Missing {
            entry: self.entry.into(),
            why,
        }
    }
}

fn board_id(v: &str) -> Option<u8> {
    number(v).and_then(|n| u8::try_from(n).ok())
}

impl FromStr for ScriptEntry {
    type Err = FaultScriptError;
    fn from_str(entry: &str) -> Result<ScriptEntry, FaultScriptError> {
        let entry = entry.trim();
        let (kind, rest) = entry
            .split_once('@')
            .ok_or_else(|| FaultScriptError::Shape {
                entry: entry.into(),
            })?;
        let (moment, fields) = match rest.split_once(':') {
            Some((m, f)) => (m, Some(f)),
            None => (rest, None),
        };
        let bad_moment = || FaultScriptError::Moment {
            entry: entry.into(),
            moment: moment.into(),
        };
        let at = if moment == "start" {
            FaultMoment::Start
        } else if let Some(t) = moment.strip_prefix("t=") {
            FaultMoment::After(SimDuration::from_micros(micros(t).ok_or_else(bad_moment)?))
        } else if let Some(n) = moment.strip_prefix("cycle=") {
            FaultMoment::Cycle(n.parse().map_err(|_| bad_moment())?)
        } else {
            return Err(bad_moment());
        };
        let fault = match kind {
            "mute" | "unplug" => {
                let f = Fields::parse(entry, fields, &["id"])?;
                let id = f
                    .value("id", "a board ID, 0 to 255", board_id)?
                    .ok_or_else(|| f.missing("which board? give id=BOARD_ID"))?;
                ScriptedFault::Board(if kind == "mute" {
                    BoardFault::Mute(id)
                } else {
                    BoardFault::Unplug(id)
                })
            }
            "corrupt" | "drop" => {
                let f =
                    Fields::parse(entry, fields, &["tcode", "dest", "offset", "rate", "count"])?;
                let select = PacketSelector {
                    tcode: f.value("tcode", "a transaction code, 0 to 0xf", |v| {
                        number(v).filter(|&t| t < 16).map(|t| Tcode::from(t as u8))
                    })?,
                    dest: f.value("dest", "a board ID, 0 to 255", board_id)?,
                    offset: f.value("offset", "16 bits, 0 to 0xffff", |v| {
                        number(v).and_then(|o| u16::try_from(o).ok())
                    })?,
                };
                let rate = f.value("rate", "a probability, 0 to 1", |v| {
                    v.parse::<f64>().ok().filter(|r| (0.0..=1.0).contains(r))
                })?;
                let count = f.value("count", "a count, 1 or more", |v| {
                    v.parse::<u32>().ok().filter(|&n| n > 0)
                })?;
                let occurrence = match (rate, count) {
                    (Some(r), None) => Occurrence::Rate(r),
                    (None, Some(n)) => Occurrence::Count(n),
                    _ => return Err(f.missing("how often? give exactly one of rate=P or count=N")),
                };
                ScriptedFault::Packets {
                    effect: if kind == "drop" {
                        PacketEffect::Drop
                    } else {
                        PacketEffect::Corrupt
                    },
                    select,
                    occurrence,
                }
            }
            "host-pause" => {
                let f = Fields::parse(entry, fields, &["for"])?;
                let d = f
                    .value("for", "microseconds, e.g. 30000us", micros)?
                    .ok_or_else(|| f.missing("how long? give for=MICROSECONDSus"))?;
                ScriptedFault::HostPause(Duration::from_micros(d))
            }
            _ => {
                return Err(FaultScriptError::Kind {
                    entry: entry.into(),
                    kind: kind.into(),
                });
            }
        };
        Ok(ScriptEntry { at, fault })
    }
}

impl FromStr for FaultScript {
    type Err = FaultScriptError;
    /// Entries separated by `;`; an empty text is the empty script.
    fn from_str(text: &str) -> Result<FaultScript, FaultScriptError> {
        let entries = text
            .split(';')
            .filter(|e| !e.trim().is_empty())
            .map(str::parse)
            .collect::<Result<_, _>>()?;
        Ok(FaultScript { entries })
    }
}

#[cfg(test)]
mod tests;
