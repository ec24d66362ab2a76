//! The validation rules. Each broken rule becomes one [`ConfigError`] with
//! the JSON path of the offending value; all are collected.
//!
//! Every number has an upper bound as well as a lower one: a value that
//! later becomes a duration, a loop count or a current must not be able to
//! overflow, hang a move or saturate everything. The bounds are generous
//! (orders of magnitude beyond any arm) and written once, below; a value
//! outside one is refused with the range, the number as written
//! ([`Number`]) and the path of the field it breaks.

use firelink_wire::human::Number;

use super::error::round_sig;
use super::{
    ConfigError, ConfigErrors, DriveConfig, EncoderConfig, FpgaGeneration, HardwareVersion,
    IoConfig, Limits, LimitsConfig, LinearFunction, PotentiometerConfig, Problem, RobotConfig,
    RobotSimulation, SCHEMA_ID, SCHEMA_VERSION, SimulationConfig,
};
use crate::config::MAX_BOARD_ID;
use crate::pid::PidGains;

/// The bounds every configuration's numbers are checked against.
pub mod bounds {
    /// Largest |position|, span or distance anywhere in a file: soft
    /// limits, stops, home, travel, tolerances (rad or m).
    pub const POSITION: f64 = 1e4;
    /// Largest velocity limit or homing speed (rad/s or m/s).
    pub const VELOCITY: f64 = 1e4;
    /// Largest acceleration (rad/s² or m/s²).
    pub const ACCELERATION: f64 = 1e6;
    /// Longest grace time, saturation time or pot latency, seconds: a
    /// check that waits longer is in effect off.
    pub const CHECK_SECONDS: f64 = 60.0;
    /// Longest move a configuration may imply (homing, a stop search, a
    /// move across the soft limits at the velocity limit), seconds: the
    /// loops that run it end.
    pub const MOVE_SECONDS: f64 = 600.0;
    /// Largest motor current, amperes (`maximum_current`, what the current
    /// feedback can read).
    pub const CURRENT: f64 = 100.0;
    /// Largest |current_to_bits.scale|, DAC codes per ampere: beyond it the
    /// 16-bit DAC would span less than ±3.3 mA.
    pub const DAC_CODES_PER_AMPERE: f64 = 1e7;
    /// Largest |effort_to_current.scale| and smallest non-zero one, A per
    /// N m (or N).
    pub const EFFORT_SCALE: (f64, f64) = (1e-6, 1e6);
    /// Largest |bits_to_position.scale|, rad or m per encoder count.
    pub const POSITION_PER_COUNT: f64 = 1.0;
    /// Largest voltage the potentiometer ADC's range may read as, volts.
    pub const VOLTS: f64 = 1e3;
    /// Largest PID gain, feed-forward or integral limit (SI in, A out).
    pub const GAIN: f64 = 1e6;
    /// Largest |element| of a coupling matrix.
    pub const COUPLING: f64 = 1e6;
}

/// Collects problems for one file.
struct Checker<'a> {
    file: &'a str,
    errors: Vec<ConfigError>,
}

impl Checker<'_> {
    fn push(&mut self, path: impl Into<String>, problem: Problem) {
        self.errors
            .push(ConfigError::new(self.file, path.into(), problem));
    }

    /// `value` at `path` is outside `expected` (in words).
    fn out_of_range(&mut self, path: impl Into<String>, value: f64, expected: impl Into<String>) {
        self.push(
            path,
            Problem::OutOfRange {
                value,
                expected: expected.into(),
            },
        );
    }

    /// A value that repeats an earlier one: `what` names the value, `first`
    /// is the path of the earlier one.
    fn duplicate(&mut self, path: impl Into<String>, what: String, first: String) {
        self.push(path, Problem::Duplicate { what, first });
    }

    /// A board ID the 4-bit rotary switch can set. Returns whether it is
    /// one.
    fn board_id(&mut self, path: String, id: u8) -> bool {
        if id <= MAX_BOARD_ID {
            return true;
        }
        self.out_of_range(
            path,
            f64::from(id),
            format!("0..={MAX_BOARD_ID} (4-bit rotary switch)"),
        );
        false
    }

    /// A finite number.
    fn finite(&mut self, path: &str, v: f64) -> bool {
        if v.is_finite() {
            true
        } else {
            self.push(path, Problem::NotFinite);
            false
        }
    }

    /// A finite number in `0 < v <= hi` (`unit` after `hi`). Returns
    /// whether it is one.
    fn positive(&mut self, path: &str, v: f64, hi: f64, unit: &str) -> bool {
        if !self.finite(path, v) {
            return false;
        }
        if v <= 0.0 || v > hi {
            self.out_of_range(path, v, format!("> 0 and at most {}{unit}", Number(hi)));
            return false;
        }
        true
    }

    /// A finite number in `0 <= v <= hi`. Returns whether it is one.
    fn non_negative(&mut self, path: &str, v: f64, hi: f64, unit: &str) -> bool {
        if !self.finite(path, v) {
            return false;
        }
        if v < 0.0 || v > hi {
            self.out_of_range(path, v, format!(">= 0 and at most {}{unit}", Number(hi)));
            return false;
        }
        true
    }

    /// A finite number with `|v| <= hi`. Returns whether it is one.
    fn magnitude(&mut self, path: &str, v: f64, hi: f64, unit: &str) -> bool {
        if !self.finite(path, v) {
            return false;
        }
        if v.abs() > hi {
            self.out_of_range(
                path,
                v,
                format!("from {} to {}{unit}", Number(-hi), Number(hi)),
            );
            return false;
        }
        true
    }

    /// A position (rad or m): finite, within ±[`bounds::POSITION`].
    fn position(&mut self, path: &str, v: f64) -> bool {
        self.magnitude(path, v, bounds::POSITION, " (rad or m)")
    }

    /// A linear function with a finite, non-zero scale and a finite offset.
    /// Returns whether it is usable.
    fn linear(&mut self, path: &str, f: &LinearFunction) -> bool {
        let scale_path = format!("{path}.scale");
        let mut ok = self.finite(&scale_path, f.scale);
        if ok && f.scale == 0.0 {
            self.push(scale_path, Problem::ZeroScale);
            ok = false;
        }
        ok & self.finite(&format!("{path}.offset"), f.offset)
    }

    /// A linear function over a 16-bit ADC's codes (0..=65535) whose
    /// results must stay within ±`hi` (`unit`): when they do not, the
    /// offset is named if it alone is beyond, else the scale.
    fn adc_reading(&mut self, path: &str, f: &LinearFunction, hi: f64, unit: &str, what: &str) {
        let worst = f.apply(0.0).abs().max(f.apply(65535.0).abs());
        if worst <= hi {
            return;
        }
        let (field, value) = if f.offset.abs() > hi {
            ("offset", f.offset)
        } else {
            ("scale", f.scale)
        };
        self.out_of_range(
            format!("{path}.{field}"),
            value,
            format!(
                "{what} within ±{}{unit} over the 16-bit ADC's codes (0..=65535); \
                 this one reads up to {}{unit}",
                Number(hi),
                Number(round_sig(worst))
            ),
        );
    }
}

/// How long a trapezoidal move over `distance` lasts at most with these
/// limits (`distance / velocity + velocity / acceleration`, which is at
/// least the triangular profile's `2 sqrt(distance / acceleration)`).
fn move_seconds(distance: f64, velocity: f64, acceleration: f64) -> f64 {
    distance.abs() / velocity + velocity / acceleration
}

/// A move over `distance` at `velocity` (at `vp`) and `acceleration` (at
/// `ap`, or `None` when the acceleration is derived from the velocity)
/// must end within [`bounds::MOVE_SECONDS`]; `what` says which move. The
/// field that makes it long is named.
fn bounded_move(
    c: &mut Checker<'_>,
    what: &str,
    distance: f64,
    (vp, velocity): (&str, f64),
    (ap, acceleration): (Option<&str>, f64),
) {
    let t = move_seconds(distance, velocity, acceleration);
    if t <= bounds::MOVE_SECONDS {
        return;
    }
    let cruise = distance.abs() / velocity;
    let (path, value) = match ap {
        Some(ap) if cruise <= velocity / acceleration => (ap, acceleration),
        _ => (vp, velocity),
    };
    c.push(
        path,
        Problem::TooLong {
            value,
            what: format!("{what} ({} rad or m)", Number(round_sig(distance.abs()))),
            seconds: round_sig(t),
        },
    );
}

/// The index of the first of `items[..index]` for which `same` holds: where
/// an earlier entry already used the value `items[index]` repeats.
fn earlier_match<T>(items: &[T], index: usize, same: impl Fn(&T) -> bool) -> Option<usize> {
    items.iter().take(index).position(same)
}

pub(super) fn validate(config: &IoConfig, file: &str) -> Result<(), ConfigErrors> {
    let mut c = Checker {
        file,
        errors: Vec::new(),
    };
    // No `$id` at all is a warning (the loader's); another one is not v6.
    if !config.id.is_empty() && config.id != SCHEMA_ID {
        c.push(
            "$id",
            Problem::Unsupported {
                found: config.id.clone(),
                expected: SCHEMA_ID,
            },
        );
    }
    if config.version != SCHEMA_VERSION {
        c.push(
            "$version",
            Problem::Unsupported {
                found: config.version.clone(),
                expected: SCHEMA_VERSION,
            },
        );
    }
    // A file may hold only inputs (the foot pedals'), not nothing.
    if config.robots.is_empty() && config.digital_inputs.as_ref().is_none_or(Vec::is_empty) {
        c.push("robots", Problem::Empty);
    }
    for (i, d) in config.digital_inputs.iter().flatten().enumerate() {
        let dp = format!("digital_inputs[{i}]");
        c.board_id(format!("{dp}.board_id"), d.board_id);
        if d.bit_id >= 32 {
            c.out_of_range(
                format!("{dp}.bit_id"),
                f64::from(d.bit_id),
                "0..=31 (a bit of DIGITAL_IN)",
            );
        }
        for (key, t) in [
            ("debounce_time", d.debounce_time),
            ("debounce_time_click", d.debounce_time_click),
        ] {
            if let Some(t) = t {
                c.non_negative(&format!("{dp}.{key}"), t, bounds::CHECK_SECONDS, " s");
            }
        }
    }

    // (board_id, axis_id) -> first path; board_id -> (hardware, robot path).
    let mut axis_users: Vec<((u8, u8), String)> = Vec::new();
    let mut board_types: Vec<(u8, HardwareVersion, String)> = Vec::new();

    for (ri, robot) in config.robots.iter().enumerate() {
        let rp = format!("robots[{ri}]");
        if robot.name.is_empty() {
            c.push(format!("{rp}.name"), Problem::Empty);
        } else if let Some(first) = earlier_match(&config.robots, ri, |r| r.name == robot.name) {
            c.duplicate(
                format!("{rp}.name"),
                format!("robot name {:?}", robot.name),
                format!("robots[{first}].name"),
            );
        }
        check_robot(&mut c, &rp, robot);

        for (ai, a) in robot.actuators.iter().enumerate() {
            let ap = format!("{rp}.actuators[{ai}]");
            if let Some(id) = a.actuator_id.filter(|&id| id != ai) {
                c.push(
                    format!("{ap}.actuator_id"),
                    Problem::Mismatch(format!(
                        "actuator_id {id} does not match its position {ai} in the list"
                    )),
                );
            }
            let mut wiring_ok = true;
            if !c.board_id(format!("{ap}.board_id"), a.board_id) {
                wiring_ok = false;
            }
            let hw = robot.hardware_version;
            if a.axis_id >= hw.axes() {
                c.push(
                    format!("{ap}.axis_id"),
                    Problem::AxisBeyondBoard {
                        axis_id: a.axis_id,
                        board_id: a.board_id,
                        axes: hw.axes(),
                        hardware: hw.name(),
                    },
                );
                wiring_ok = false;
            }
            if wiring_ok {
                match board_types.iter().find(|(b, _, _)| *b == a.board_id) {
                    Some((_, other, where_)) if *other != hw => c.push(
                        format!("{ap}.board_id"),
                        Problem::Mismatch(format!(
                            "board {} is {} here but {} at {where_}",
                            a.board_id,
                            hw.name(),
                            other.name()
                        )),
                    ),
                    Some(_) => {}
                    None => board_types.push((a.board_id, hw, format!("{rp}.hardware_version"))),
                }
                let key = (a.board_id, a.axis_id);
                if let Some((_, first)) = axis_users.iter().find(|(k, _)| *k == key) {
                    c.duplicate(
                        ap.clone(),
                        format!("(board_id {}, axis_id {})", key.0, key.1),
                        first.clone(),
                    );
                } else {
                    axis_users.push((key, ap.clone()));
                }
            }
            check_drive(&mut c, &format!("{ap}.drive"), &a.drive);
            let soft = check_encoder(&mut c, &format!("{ap}.encoder"), &a.encoder);
            if let Some(p) = &a.potentiometer {
                check_pot(&mut c, &format!("{ap}.potentiometer"), p);
            }
            if let Some(l) = &a.limits {
                check_limits(&mut c, &format!("{ap}.limits"), l, soft);
            }
            if let Some(s) = &a.simulation {
                check_simulation(&mut c, &format!("{ap}.simulation"), s, soft);
            }
        }
    }

    match ConfigErrors::from_vec(c.errors) {
        None => Ok(()),
        Some(e) => Err(e),
    }
}

fn check_robot(c: &mut Checker<'_>, rp: &str, robot: &RobotConfig) {
    if robot.actuators.is_empty() {
        c.push(format!("{rp}.actuators"), Problem::Empty);
    }
    if robot.number_of_actuators != robot.actuators.len() {
        c.push(
            format!("{rp}.number_of_actuators"),
            Problem::Mismatch(format!(
                "number_of_actuators is {} but {} actuators are listed",
                robot.number_of_actuators,
                robot.actuators.len()
            )),
        );
    }
    if let Some(sim) = &robot.simulation {
        check_robot_simulation(c, &format!("{rp}.simulation"), sim, robot.hardware_version);
    }
    check_brakes(c, rp, robot);
    let Some(pots) = &robot.potentiometers else {
        return;
    };
    if let Some(coupling) = &pots.coupling {
        let cp = format!("{rp}.potentiometers.coupling");
        let n = robot.actuators.len();
        for (name, m) in [
            (
                "JointToActuatorPosition",
                &coupling.joint_to_actuator_position,
            ),
            (
                "ActuatorToJointPosition",
                &coupling.actuator_to_joint_position,
            ),
        ] {
            let Some(m) = m else { continue };
            let mp = format!("{cp}.{name}");
            if m.len() != n || m.iter().any(|r| r.len() != n) {
                c.push(
                    mp,
                    Problem::Mismatch(format!(
                        "must be {n} x {n} (one row and column per actuator)"
                    )),
                );
            } else if m.iter().flatten().any(|v| !v.is_finite()) {
                c.push(mp, Problem::NotFinite);
            } else if let Some(v) = m
                .iter()
                .flatten()
                .copied()
                .find(|v| v.abs() > bounds::COUPLING)
            {
                c.out_of_range(
                    mp,
                    v,
                    format!(
                        "elements from {} to {}",
                        Number(-bounds::COUPLING),
                        Number(bounds::COUPLING)
                    ),
                );
            } else if super::Matrix::from_rows(m)
                .and_then(|m| m.inverse())
                .is_none()
            {
                c.push(
                    mp,
                    Problem::Mismatch("cannot be inverted (singular)".into()),
                );
            }
        }
    }
    for (ti, t) in pots.tolerances.iter().enumerate() {
        let tp = format!("{rp}.potentiometers.tolerances[{ti}]");
        if t.axis_id >= robot.actuators.len() {
            c.out_of_range(
                format!("{tp}.axis_id"),
                t.axis_id as f64,
                format!(
                    "an actuator index below {} (v6 axis_id is the actuator index)",
                    robot.actuators.len()
                ),
            );
        } else if let Some(first) = earlier_match(&pots.tolerances, ti, |o| o.axis_id == t.axis_id)
        {
            c.duplicate(
                format!("{tp}.axis_id"),
                format!("tolerance for actuator {}", t.axis_id),
                format!("{rp}.potentiometers.tolerances[{first}]"),
            );
        }
        c.non_negative(
            &format!("{tp}.distance"),
            t.distance,
            bounds::POSITION,
            " (rad or m)",
        );
        c.non_negative(
            &format!("{tp}.latency"),
            t.latency,
            bounds::CHECK_SECONDS,
            " s",
        );
    }
}

/// A robot's brakes: as many as `number_of_brakes` says, each on a board
/// the switch can set, with currents the QLA can drive and a release time
/// that ends.
fn check_brakes(c: &mut Checker<'_>, rp: &str, robot: &RobotConfig) {
    let brakes = robot.brakes.as_deref().unwrap_or(&[]);
    if let Some(n) = robot.number_of_brakes {
        if n != brakes.len() {
            c.push(
                format!("{rp}.number_of_brakes"),
                Problem::Mismatch(format!(
                    "number_of_brakes is {n} but {} brakes are listed",
                    brakes.len()
                )),
            );
        }
    }
    for (bi, b) in brakes.iter().enumerate() {
        let bp = format!("{rp}.brakes[{bi}]");
        c.board_id(format!("{bp}.board_id"), b.board_id);
        for (key, f) in [
            ("current_to_bits", b.drive.current_to_bits),
            ("bits_to_current", b.drive.bits_to_current),
        ] {
            let p = format!("{bp}.drive.{key}");
            c.finite(&format!("{p}.scale"), f.scale);
            c.finite(&format!("{p}.offset"), f.offset);
        }
        for (key, v) in [
            ("drive.maximum_current", b.drive.maximum_current),
            ("release_current", b.release_current),
            ("released_current", b.released_current),
            ("engaged_current", b.engaged_current),
        ] {
            if let Some(v) = v {
                c.non_negative(&format!("{bp}.{key}"), v, bounds::CURRENT, " A");
            }
        }
        if let Some(t) = b.release_time {
            c.non_negative(&format!("{bp}.release_time"), t, bounds::MOVE_SECONDS, " s");
        }
    }
}

fn check_robot_simulation(
    c: &mut Checker<'_>,
    sp: &str,
    sim: &RobotSimulation,
    hardware: HardwareVersion,
) {
    if let Some(t) = &sim.tool {
        if t.name.is_empty() {
            c.push(format!("{sp}.tool.name"), Problem::Empty);
        }
    }
    for (bi, b) in sim.boards.iter().enumerate() {
        let bp = format!("{sp}.boards[{bi}]");
        c.board_id(format!("{bp}.board_id"), b.board_id);
        if let Some(first) = earlier_match(&sim.boards, bi, |o| o.board_id == b.board_id) {
            c.duplicate(
                format!("{bp}.board_id"),
                format!("board {}", b.board_id),
                format!("{sp}.boards[{first}]"),
            );
        }
        // The firmware builds a DQLA only for an FPGA V3.
        if hardware == HardwareVersion::Dqla && b.fpga_version == Some(FpgaGeneration::V2) {
            c.push(
                format!("{bp}.fpga_version"),
                Problem::Mismatch(
                    "a DQLA exists only on an FPGA V3 (the firmware builds no FPGA V2 DQLA \
                     image): give \"V3\" or leave it out"
                        .to_string(),
                ),
            );
        }
        if let Some(fw) = b.firmware.filter(|fw| !(7..=9).contains(fw)) {
            c.push(
                format!("{bp}.firmware"),
                Problem::Mismatch(format!("firmware {fw}: the emulated boards run 7, 8 or 9")),
            );
        }
        // What the PROMs can hold after their "FPGA " and "QLA " prefixes.
        for (name, value) in [("fpga", &b.serial.fpga), ("qla", &b.serial.qla)] {
            let Some(v) = value else { continue };
            if v.is_empty() || v.len() > 8 || !v.bytes().all(|x| x.is_ascii_graphic()) {
                c.push(
                    format!("{bp}.serial.{name}"),
                    Problem::Mismatch(format!(
                        "serial number {v:?}: 1 to 8 printable ASCII characters (e.g. \"1234-56\")"
                    )),
                );
            }
        }
    }
}

fn check_drive(c: &mut Checker<'_>, dp: &str, d: &DriveConfig) {
    let cp = format!("{dp}.current_to_bits");
    let mut c2b = c.linear(&cp, &d.current_to_bits);
    let scale = d.current_to_bits.scale;
    if c2b && scale.abs() > bounds::DAC_CODES_PER_AMPERE {
        let reach = 32767.5 / scale.abs();
        c.out_of_range(
            format!("{cp}.scale"),
            scale,
            format!(
                "a magnitude of at most {} DAC codes per ampere; with this one the 16-bit \
                 DAC reaches only ±{} A",
                Number(bounds::DAC_CODES_PER_AMPERE),
                Number(round_sig(reach))
            ),
        );
        c2b = false;
    }
    let zero_code_ok = (0.0..=65535.0).contains(&d.current_to_bits.offset);
    if c2b && !zero_code_ok {
        c.out_of_range(
            format!("{cp}.offset"),
            d.current_to_bits.offset,
            "0..=65535 (the 16-bit DAC code for 0 A)",
        );
    }
    let fp = format!("{dp}.bits_to_current");
    let b2c = c.linear(&fp, &d.bits_to_current);
    if b2c {
        c.adc_reading(
            &fp,
            &d.bits_to_current,
            bounds::CURRENT,
            " A",
            "current feedback",
        );
    }
    if c2b && b2c && (d.current_to_bits.scale > 0.0) != (d.bits_to_current.scale > 0.0) {
        c.push(
            format!("{dp}.bits_to_current.scale"),
            Problem::Mismatch(format!(
                "sign of bits_to_current.scale ({}) differs from current_to_bits.scale ({}): \
                 feedback would read the command backwards",
                Number(d.bits_to_current.scale),
                Number(d.current_to_bits.scale)
            )),
        );
    }
    let ep = format!("{dp}.effort_to_current");
    if c.linear(&ep, &d.effort_to_current) {
        let (lo, hi) = bounds::EFFORT_SCALE;
        let s = d.effort_to_current.scale.abs();
        if !(lo..=hi).contains(&s) {
            c.out_of_range(
                format!("{ep}.scale"),
                d.effort_to_current.scale,
                format!(
                    "a magnitude from {} to {} A per N m (or N)",
                    Number(lo),
                    Number(hi)
                ),
            );
        }
        c.magnitude(
            &format!("{ep}.offset"),
            d.effort_to_current.offset,
            bounds::CURRENT,
            " A",
        );
    }
    let mp = format!("{dp}.maximum_current");
    let max_ok = c.positive(&mp, d.maximum_current, bounds::CURRENT, " A");
    if c2b && zero_code_ok && max_ok {
        check_dac_reach(c, dp, d);
    }
}

/// `±maximum_current` must map inside the 16-bit DAC's codes. When it
/// does not, the field that breaks it is named: the offset when a centred
/// zero code would have fitted the current, else the maximum current.
fn check_dac_reach(c: &mut Checker<'_>, dp: &str, d: &DriveConfig) {
    let f = d.current_to_bits;
    let max = d.maximum_current;
    let (hi, lo) = (f.apply(max), f.apply(-max));
    if (0.0..=65535.0).contains(&hi) && (0.0..=65535.0).contains(&lo) {
        return;
    }
    let reach = f.offset.min(65535.0 - f.offset) / f.scale.abs();
    let centred_reach = 32767.0 / f.scale.abs();
    if max <= centred_reach {
        c.out_of_range(
            format!("{dp}.current_to_bits.offset"),
            f.offset,
            format!(
                "a zero-current code that leaves room for ±{} A (maximum_current) on both \
                 sides: from {:.0} to {:.0}",
                Number(max),
                (max * f.scale.abs()).ceil(),
                (65535.0 - max * f.scale.abs()).floor()
            ),
        );
    } else {
        c.out_of_range(
            format!("{dp}.maximum_current"),
            max,
            format!("at most {reach:.4} A, the 16-bit DAC's reach"),
        );
    }
}

/// Checks the encoder; returns its soft limits when they are usable (both
/// finite and bounded, lower below upper).
fn check_encoder(c: &mut Checker<'_>, ep: &str, e: &EncoderConfig) -> Option<Limits> {
    let bp = format!("{ep}.bits_to_position");
    let mut ok = c.linear(&bp, &e.bits_to_position);
    if ok {
        ok &= c.magnitude(
            &format!("{bp}.scale"),
            e.bits_to_position.scale,
            bounds::POSITION_PER_COUNT,
            " (rad or m per count)",
        );
        ok &= c.position(&format!("{bp}.offset"), e.bits_to_position.offset);
    }
    let lp = format!("{ep}.position_limits_soft");
    let lo = c.position(&format!("{lp}.lower"), e.position_limits_soft.lower);
    let hi = c.position(&format!("{lp}.upper"), e.position_limits_soft.upper);
    let mut usable = None;
    if lo && hi {
        let l = e.position_limits_soft;
        if l.lower >= l.upper {
            c.push(
                lp.clone(),
                Problem::EmptyRange {
                    lower: l.lower,
                    upper: l.upper,
                },
            );
        } else {
            usable = Some(l);
            if ok {
                let reach = f64::from(EncoderConfig::MAX_COUNT) * e.bits_to_position.scale.abs();
                let off = e.bits_to_position.offset;
                for (name, v) in [("lower", l.lower), ("upper", l.upper)] {
                    if (v - off).abs() > reach {
                        c.out_of_range(
                            format!("{lp}.{name}"),
                            v,
                            format!(
                                "within {} ± {}, the 24-bit encoder's reach",
                                Number(off),
                                Number(round_sig(reach))
                            ),
                        );
                    }
                }
            }
        }
    }
    if e.counts_per_turn == Some(0) {
        c.out_of_range(format!("{ep}.counts_per_turn"), 0.0, "> 0");
    }
    usable
}

fn check_pot(c: &mut Checker<'_>, pp: &str, p: &PotentiometerConfig) {
    let bp = format!("{pp}.bits_to_voltage");
    let volts = c.linear(&bp, &p.bits_to_voltage);
    if volts {
        c.adc_reading(
            &bp,
            &p.bits_to_voltage,
            bounds::VOLTS,
            " V",
            "potentiometer voltages",
        );
    }
    let vp = format!("{pp}.voltage_to_position");
    if c.linear(&vp, &p.voltage_to_position) && volts {
        // The positions the whole ADC range reads as.
        let worst = [0u16, 65535]
            .map(|b| p.bits_to_position(b).abs())
            .into_iter()
            .fold(0.0, f64::max);
        if worst > bounds::POSITION || worst.is_nan() {
            let (field, value) = if p.voltage_to_position.offset.abs() > bounds::POSITION {
                ("offset", p.voltage_to_position.offset)
            } else {
                ("scale", p.voltage_to_position.scale)
            };
            c.out_of_range(
                format!("{vp}.{field}"),
                value,
                format!(
                    "positions within ±{} (rad or m) over the ADC's range; this one reaches {}",
                    Number(bounds::POSITION),
                    Number(round_sig(worst))
                ),
            );
        }
    }
}

fn check_limits(c: &mut Checker<'_>, lp: &str, l: &LimitsConfig, soft: Option<Limits>) {
    let vp = format!("{lp}.velocity");
    let v_ok = c.positive(&vp, l.velocity, bounds::VELOCITY, " rad/s or m/s");
    let ap = format!("{lp}.acceleration");
    let a_ok = match l.acceleration {
        Some(a) => c.positive(&ap, a, bounds::ACCELERATION, " rad/s² or m/s²"),
        None => true,
    };
    c.positive(
        &format!("{lp}.following_error"),
        l.following_error,
        bounds::POSITION,
        " (rad or m)",
    );
    c.non_negative(
        &format!("{lp}.following_error_grace"),
        l.following_error_grace,
        bounds::CHECK_SECONDS,
        " s",
    );
    c.non_negative(
        &format!("{lp}.saturation_time"),
        l.saturation_time,
        bounds::CHECK_SECONDS,
        " s",
    );
    if let Some(m) = l.position_margin {
        c.non_negative(
            &format!("{lp}.position_margin"),
            m,
            bounds::POSITION,
            " (rad or m)",
        );
    }
    // A move across the soft limits at the velocity limit (a console's
    // move to each limit; without an acceleration limit, 4 x velocity
    // per second).
    if let (Some(soft), true, true) = (soft, v_ok, a_ok) {
        let (acc_path, acc) = match l.acceleration {
            Some(a) => (Some(ap.as_str()), a),
            None => (None, 4.0 * l.velocity),
        };
        bounded_move(
            c,
            "a move across the soft limits",
            soft.span(),
            (&vp, l.velocity),
            (acc_path, acc),
        );
    }
}

fn check_simulation(c: &mut Checker<'_>, sp: &str, s: &SimulationConfig, soft: Option<Limits>) {
    if let Some(g) = &s.pid {
        check_pid(c, &format!("{sp}.pid"), g);
    }
    if let Some(h) = &s.hard_stops {
        let hp = format!("{sp}.hard_stops");
        let lo = c.position(&format!("{hp}.lower"), h.lower);
        let hi = c.position(&format!("{hp}.upper"), h.upper);
        if let (true, true, Some(soft)) = (lo, hi, soft) {
            if h.lower > soft.lower || h.upper < soft.upper {
                let value = if h.lower > soft.lower {
                    h.lower
                } else {
                    h.upper
                };
                c.out_of_range(
                    hp,
                    value,
                    format!(
                        "stops at or beyond encoder.position_limits_soft [{}, {}]",
                        Number(soft.lower),
                        Number(soft.upper)
                    ),
                );
            }
        }
    }
    if let Some(search) = s.homing.as_ref().and_then(|h| h.stop_search.as_ref()) {
        let p = format!("{sp}.homing.stop_search");
        let (vp, ap) = (format!("{p}.velocity"), format!("{p}.acceleration"));
        let v = c.positive(&vp, search.velocity, bounds::VELOCITY, " rad/s or m/s");
        let a = c.positive(
            &ap,
            search.acceleration,
            bounds::ACCELERATION,
            " rad/s² or m/s²",
        );
        c.positive(
            &format!("{p}.stall_error"),
            search.stall_error,
            bounds::POSITION,
            " (rad or m)",
        );
        let t = c.positive(
            &format!("{p}.max_travel"),
            search.max_travel,
            bounds::POSITION,
            " (rad or m)",
        );
        c.position(&format!("{p}.stop_position"), search.stop_position);
        if v && a && t {
            bounded_move(
                c,
                "the search over max_travel",
                search.max_travel,
                (&vp, search.velocity),
                (Some(&ap), search.acceleration),
            );
        }
    }
    if let Some(h) = &s.homing {
        let hp = format!("{sp}.homing");
        let (vp, ap) = (format!("{hp}.velocity"), format!("{hp}.acceleration"));
        let v = c.positive(&vp, h.velocity, bounds::VELOCITY, " rad/s or m/s");
        let a = c.positive(&ap, h.acceleration, bounds::ACCELERATION, " rad/s² or m/s²");
        let pp = format!("{hp}.position");
        if c.position(&pp, h.position) {
            if let Some(l) = soft {
                if !l.contains(h.position) {
                    c.out_of_range(
                        pp,
                        h.position,
                        format!(
                            "inside encoder.position_limits_soft [{}, {}]",
                            Number(l.lower),
                            Number(l.upper)
                        ),
                    );
                }
            }
        }
        if let (Some(l), true, true) = (soft, v, a) {
            bounded_move(
                c,
                "the homing move across the soft limits",
                l.span(),
                (&vp, h.velocity),
                (Some(&ap), h.acceleration),
            );
        }
    }
}

fn check_pid(c: &mut Checker<'_>, pp: &str, g: &PidGains) {
    for (name, v) in [
        ("kp", g.kp),
        ("ki", g.ki),
        ("kd", g.kd),
        ("velocity_feedforward", g.velocity_feedforward),
    ] {
        c.non_negative(&format!("{pp}.{name}"), v, bounds::GAIN, "");
    }
    c.non_negative(
        &format!("{pp}.deadband"),
        g.deadband,
        bounds::POSITION,
        " (rad or m)",
    );
    if let Some(i) = g.integral_limit {
        c.non_negative(&format!("{pp}.integral_limit"), i, bounds::CURRENT, " A");
    }
}

#[cfg(test)]
mod tests {
    use super::super::{IoConfig, Problem, presets};

    /// The one error `change` makes in PSM1's file: (path, text).
    fn one_error(change: impl FnOnce(&mut IoConfig)) -> (String, Problem, String) {
        let mut c = presets::stock_psm1();
        change(&mut c);
        let e = c.validate("psm1.json").unwrap_err();
        assert_eq!(e.errors().len(), 1, "{e}");
        let first = e.first();
        (first.path.clone(), first.problem.clone(), first.to_string())
    }

    #[test]
    fn a_huge_dac_scale_is_blamed_not_the_current() {
        // PSM1's insertion joint: the scale, not maximum_current, is wrong.
        let (path, _, shown) =
            one_error(|c| c.robots[0].actuators[2].drive.current_to_bits.scale = 1e308);
        assert_eq!(path, "robots[0].actuators[2].drive.current_to_bits.scale");
        assert!(shown.contains("out of range: 1e308"), "{shown}");
        assert!(shown.contains("3.277e-304 A"), "{shown}");
        // An offset at the edge of the DAC's codes leaves no room below 0 A:
        // the offset is named.
        let (path, _, shown) =
            one_error(|c| c.robots[0].actuators[0].drive.current_to_bits.offset = 1e-300);
        assert_eq!(path, "robots[0].actuators[0].drive.current_to_bits.offset");
        assert!(shown.contains("1e-300"), "{shown}");
        // A current the DAC cannot reach with a sound scale: the current.
        let (path, _, shown) = one_error(|c| c.robots[0].actuators[0].drive.maximum_current = 9.0);
        assert_eq!(path, "robots[0].actuators[0].drive.maximum_current");
        assert!(shown.contains("the 16-bit DAC's reach"), "{shown}");
    }

    #[test]
    fn numbers_are_echoed_as_written() {
        let (path, _, shown) =
            one_error(|c| c.robots[0].actuators[1].drive.maximum_current = 1e300);
        assert_eq!(path, "robots[0].actuators[1].drive.maximum_current");
        assert_eq!(
            shown,
            "psm1.json: robots[0].actuators[1].drive.maximum_current: out of range: 1e300 \
             (expected > 0 and at most 100 A)"
        );
        let (_, _, shown) = one_error(|c| {
            c.robots[0].actuators[1].encoder.position_limits_soft.lower = 1e300;
        });
        assert!(
            shown.contains("1e300") && !shown.contains("000000"),
            "{shown}"
        );
        let (_, _, shown) = one_error(|c| {
            c.robots[0].actuators[1].drive.bits_to_current.scale = 1e-300;
        });
        assert!(shown.contains("(1e-300)"), "{shown}");
    }

    #[test]
    fn moves_that_would_not_end_are_refused() {
        let (path, p, shown) = one_error(|c| {
            if let Some(l) = &mut c.robots[0].actuators[0].limits {
                l.velocity = 1e-300;
            }
        });
        assert_eq!(path, "robots[0].actuators[0].limits.velocity");
        assert!(matches!(p, Problem::TooLong { .. }), "{shown}");
        assert!(
            shown.contains("1e-300 makes a move across the soft limits"),
            "{shown}"
        );
        let (path, _, _) = one_error(|c| {
            if let Some(h) = c.robots[0].actuators[3]
                .simulation
                .as_mut()
                .and_then(|s| s.homing.as_mut())
            {
                h.acceleration = 1e-9;
            }
        });
        assert_eq!(
            path,
            "robots[0].actuators[3].simulation.homing.acceleration"
        );
        // A following-error grace of a lifetime turns the check off.
        let (path, _, shown) = one_error(|c| {
            if let Some(l) = &mut c.robots[0].actuators[0].limits {
                l.following_error_grace = 1e300;
            }
        });
        assert_eq!(path, "robots[0].actuators[0].limits.following_error_grace");
        assert!(shown.contains("at most 60 s"), "{shown}");
    }

    #[test]
    fn current_feedback_and_pots_read_within_bounds() {
        let (path, _, _) =
            one_error(|c| c.robots[0].actuators[0].drive.bits_to_current.scale = -1e300);
        assert_eq!(path, "robots[0].actuators[0].drive.bits_to_current.scale");
        let (path, _, _) = one_error(|c| {
            if let Some(p) = &mut c.robots[0].actuators[0].potentiometer {
                p.voltage_to_position.scale = 1e300;
            }
        });
        assert_eq!(
            path,
            "robots[0].actuators[0].potentiometer.voltage_to_position.scale"
        );
    }
}
