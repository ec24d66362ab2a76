//! How the command lines spell the choices whose types live in crates
//! without clap (the board's firmware, FPGA and companion board, the
//! simulated bus's arbitration class and speed, the runner's pacing): one
//! clap value parser per choice, with each value's name, aliases and help,
//! so every front end offers the same words (behind the `clap` feature;
//! Python and the fuzzers leave it off). The choices whose types live in
//! the host and the testbed are those types' own `clap::ValueEnum`.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};

use firelink_control::runner::Pacing;
use firelink_wire::packet::Speed;

use crate::emulated::{ArbitrationClass, FpgaVersion, Hardware, Profile};

/// A parser of one of `choices`: what clap lists (name, aliases, help),
/// and the value each means.
fn one_of<T: Copy + Send + Sync + 'static>(
    choices: Vec<(PossibleValue, T)>,
) -> impl TypedValueParser<Value = T> {
    let values: Vec<PossibleValue> = choices.iter().map(|(v, _)| v.clone()).collect();
    PossibleValuesParser::new(values).try_map(move |text: String| {
        choices
            .iter()
            .find(|(v, _)| v.matches(&text, false))
            .map(|&(_, meaning)| meaning)
            .ok_or_else(|| format!("{text:?} is none of the choices"))
    })
}

/// `--firmware` (and `sim --profile`): the emulated boards' firmware.
pub fn firmware() -> impl TypedValueParser<Value = Profile> {
    one_of(vec![
        (
            PossibleValue::new("seed")
                .help("Seed 000's firmware: fixed TDMA slots, 0xFFFF for a corrupt query"),
            Profile::Seed,
        ),
        (
            PossibleValue::new("rev7")
                .alias("7")
                .help("Firmware Rev 7: chained broadcasts"),
            Profile::Rev7,
        ),
        (
            PossibleValue::new("rev8")
                .alias("8")
                .help("Firmware Rev 8: chained broadcasts, MOTOR_STATUS, write-block header"),
            Profile::Rev8,
        ),
        (
            PossibleValue::new("rev9")
                .alias("9")
                .help("Firmware Rev 9: Rev 8's blocks, GIT_DESC, the FPGA V3 Ethernet status"),
            Profile::Rev9,
        ),
    ])
}

/// `--fpga`: the FPGA board generation.
pub fn fpga() -> impl TypedValueParser<Value = FpgaVersion> {
    one_of(vec![
        (
            PossibleValue::new("V2")
                .aliases(["v2", "2"])
                .help("FPGA V2: Spartan-6, one 100 Mb/s Ethernet port (the bridge)"),
            FpgaVersion::V2,
        ),
        (
            PossibleValue::new("V3")
                .aliases(["v3", "3"])
                .help("FPGA V3: Zynq, two 1 Gb/s Ethernet ports (RTL8211F PHYs)"),
            FpgaVersion::V3,
        ),
    ])
}

/// `--hardware`: the companion board.
pub fn hardware() -> impl TypedValueParser<Value = Hardware> {
    one_of(vec![
        (
            PossibleValue::new("QLA1")
                .aliases(["qla1", "QLA", "qla"])
                .help("Quad linear amplifier: 4 axes"),
            Hardware::Qla1,
        ),
        (
            PossibleValue::new("DQLA")
                .alias("dqla")
                .help("Dual QLA: 8 axes"),
            Hardware::Dqla,
        ),
    ])
}

/// `--pacing`: virtual or wall-clock time.
pub fn pacing() -> impl TypedValueParser<Value = Pacing> {
    one_of(vec![
        (
            PossibleValue::new("virtual").help("As fast as the simulation goes, in virtual time"),
            Pacing::Virtual,
        ),
        (
            PossibleValue::new("realtime").help("The wall clock"),
            Pacing::WallClock,
        ),
    ])
}

/// `sim --arbitration`: the arbitration class of the boards' status
/// broadcasts.
pub fn arbitration() -> impl TypedValueParser<Value = ArbitrationClass> {
    one_of(vec![
        (
            PossibleValue::new("iso").help("Isochronous-style requests (0.04 us gap)"),
            ArbitrationClass::Isochronous,
        ),
        (
            PossibleValue::new("priority").help("Priority requests (subaction gap)"),
            ArbitrationClass::Priority,
        ),
        (
            PossibleValue::new("fair").help("Fair requests (subaction gap, fairness interval)"),
            ArbitrationClass::Fair,
        ),
    ])
}

/// `sim --speed`: the speed of every packet, Mb/s.
pub fn speed() -> impl TypedValueParser<Value = Speed> {
    one_of(vec![
        (PossibleValue::new("100").help("S100"), Speed::S100),
        (PossibleValue::new("200").help("S200"), Speed::S200),
        (PossibleValue::new("400").help("S400"), Speed::S400),
    ])
}
