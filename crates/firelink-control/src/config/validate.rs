//! The validation rules. Each broken rule becomes one [`ConfigError`] with
//! the JSON path of the offending value; all are collected.

use super::{
    ConfigError, ConfigErrors, DriveConfig, EncoderConfig, HardwareVersion, IoConfig, LimitsConfig,
    LinearFunction, PotentiometerConfig, Problem, RobotConfig, RobotSimulation, SCHEMA_ID,
    SCHEMA_VERSION, SimulationConfig,
};
use crate::config::MAX_BOARD_ID;
use crate::pid::PidGains;

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
        self.push(
            path,
            Problem::OutOfRange {
                value: f64::from(id),
                expected: format!("0..={MAX_BOARD_ID} (4-bit rotary switch)"),
            },
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

    /// A finite number > 0.
    fn positive(&mut self, path: &str, v: f64) {
        if self.finite(path, v) && v <= 0.0 {
            self.push(
                path,
                Problem::OutOfRange {
                    value: v,
                    expected: "> 0".into(),
                },
            );
        }
    }

    /// A finite number >= 0.
    fn non_negative(&mut self, path: &str, v: f64) {
        if self.finite(path, v) && v < 0.0 {
            self.push(
                path,
                Problem::OutOfRange {
                    value: v,
                    expected: ">= 0".into(),
                },
            );
        }
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
    if config.id != SCHEMA_ID {
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
    if config.robots.is_empty() {
        c.push("robots", Problem::Empty);
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
            check_encoder(&mut c, &format!("{ap}.encoder"), &a.encoder);
            if let Some(p) = &a.potentiometer {
                check_pot(&mut c, &format!("{ap}.potentiometer"), p);
            }
            if let Some(l) = &a.limits {
                check_limits(&mut c, &format!("{ap}.limits"), l);
            }
            if let Some(s) = &a.simulation {
                check_simulation(&mut c, &format!("{ap}.simulation"), s, &a.encoder);
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
        check_robot_simulation(c, &format!("{rp}.simulation"), sim);
    }
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
            c.push(
                format!("{tp}.axis_id"),
                Problem::OutOfRange {
                    value: t.axis_id as f64,
                    expected: format!(
                        "an actuator index below {} (v6 axis_id is the actuator index)",
                        robot.actuators.len()
                    ),
                },
            );
        } else if let Some(first) = earlier_match(&pots.tolerances, ti, |o| o.axis_id == t.axis_id)
        {
            c.duplicate(
                format!("{tp}.axis_id"),
                format!("tolerance for actuator {}", t.axis_id),
                format!("{rp}.potentiometers.tolerances[{first}]"),
            );
        }
        c.non_negative(&format!("{tp}.distance"), t.distance);
        c.non_negative(&format!("{tp}.latency"), t.latency);
    }
}

fn check_robot_simulation(c: &mut Checker<'_>, sp: &str, sim: &RobotSimulation) {
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
    let c2b = c.linear(&format!("{dp}.current_to_bits"), &d.current_to_bits);
    let zero_code_ok = (0.0..=65535.0).contains(&d.current_to_bits.offset);
    if c2b && !zero_code_ok {
        c.push(
            format!("{dp}.current_to_bits.offset"),
            Problem::OutOfRange {
                value: d.current_to_bits.offset,
                expected: "0..=65535 (the 16-bit DAC code for 0 A)".into(),
            },
        );
    }
    let b2c = c.linear(&format!("{dp}.bits_to_current"), &d.bits_to_current);
    if c2b && b2c && (d.current_to_bits.scale > 0.0) != (d.bits_to_current.scale > 0.0) {
        c.push(
            format!("{dp}.bits_to_current.scale"),
            Problem::Mismatch(format!(
                "sign of bits_to_current.scale ({}) differs from current_to_bits.scale ({}): \
                 feedback would read the command backwards",
                d.bits_to_current.scale, d.current_to_bits.scale
            )),
        );
    }
    c.linear(&format!("{dp}.effort_to_current"), &d.effort_to_current);
    let mp = format!("{dp}.maximum_current");
    c.positive(&mp, d.maximum_current);
    if c2b && zero_code_ok && d.maximum_current.is_finite() && d.maximum_current > 0.0 {
        let hi = d.current_to_bits.apply(d.maximum_current);
        let lo = d.current_to_bits.apply(-d.maximum_current);
        if !(0.0..=65535.0).contains(&hi) || !(0.0..=65535.0).contains(&lo) {
            let reach = d
                .current_to_bits
                .offset
                .min(65535.0 - d.current_to_bits.offset)
                / d.current_to_bits.scale.abs();
            c.push(
                mp,
                Problem::OutOfRange {
                    value: d.maximum_current,
                    expected: format!("at most {reach:.4} A, the 16-bit DAC's reach"),
                },
            );
        }
    }
}

fn check_encoder(c: &mut Checker<'_>, ep: &str, e: &EncoderConfig) {
    let ok = c.linear(&format!("{ep}.bits_to_position"), &e.bits_to_position);
    let lp = format!("{ep}.position_limits_soft");
    let lo = c.finite(&format!("{lp}.lower"), e.position_limits_soft.lower);
    let hi = c.finite(&format!("{lp}.upper"), e.position_limits_soft.upper);
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
        } else if ok {
            let reach = f64::from(EncoderConfig::MAX_COUNT) * e.bits_to_position.scale.abs();
            let off = e.bits_to_position.offset;
            for (name, v) in [("lower", l.lower), ("upper", l.upper)] {
                if (v - off).abs() > reach {
                    c.push(
                        format!("{lp}.{name}"),
                        Problem::OutOfRange {
                            value: v,
                            expected: format!(
                                "within {:.6} +- {reach:.6}, the 24-bit encoder's reach",
                                off
                            ),
                        },
                    );
                }
            }
        }
    }
    if e.counts_per_turn == Some(0) {
        c.push(
            format!("{ep}.counts_per_turn"),
            Problem::OutOfRange {
                value: 0.0,
                expected: "> 0".into(),
            },
        );
    }
}

fn check_pot(c: &mut Checker<'_>, pp: &str, p: &PotentiometerConfig) {
    c.linear(&format!("{pp}.bits_to_voltage"), &p.bits_to_voltage);
    c.linear(&format!("{pp}.voltage_to_position"), &p.voltage_to_position);
}

fn check_limits(c: &mut Checker<'_>, lp: &str, l: &LimitsConfig) {
    c.positive(&format!("{lp}.velocity"), l.velocity);
    if let Some(a) = l.acceleration {
        c.positive(&format!("{lp}.acceleration"), a);
    }
    c.positive(&format!("{lp}.following_error"), l.following_error);
    c.non_negative(
        &format!("{lp}.following_error_grace"),
        l.following_error_grace,
    );
    c.non_negative(&format!("{lp}.saturation_time"), l.saturation_time);
    if let Some(m) = l.position_margin {
        c.non_negative(&format!("{lp}.position_margin"), m);
    }
}

fn check_simulation(c: &mut Checker<'_>, sp: &str, s: &SimulationConfig, e: &EncoderConfig) {
    if let Some(g) = &s.pid {
        check_pid(c, &format!("{sp}.pid"), g);
    }
    if let Some(h) = &s.hard_stops {
        let hp = format!("{sp}.hard_stops");
        let lo = c.finite(&format!("{hp}.lower"), h.lower);
        let hi = c.finite(&format!("{hp}.upper"), h.upper);
        let soft = e.position_limits_soft;
        if lo && hi && (h.lower > soft.lower || h.upper < soft.upper) {
            let value = if h.lower > soft.lower {
                h.lower
            } else {
                h.upper
            };
            c.push(
                hp,
                Problem::OutOfRange {
                    value,
                    expected: format!(
                        "stops at or beyond encoder.position_limits_soft [{}, {}]",
                        soft.lower, soft.upper
                    ),
                },
            );
        }
    }
    if let Some(search) = s.homing.as_ref().and_then(|h| h.stop_search.as_ref()) {
        let p = format!("{sp}.homing.stop_search");
        c.positive(&format!("{p}.velocity"), search.velocity);
        c.positive(&format!("{p}.acceleration"), search.acceleration);
        c.positive(&format!("{p}.stall_error"), search.stall_error);
        c.positive(&format!("{p}.max_travel"), search.max_travel);
        c.finite(&format!("{p}.stop_position"), search.stop_position);
    }
    if let Some(h) = &s.homing {
        let hp = format!("{sp}.homing");
        c.positive(&format!("{hp}.velocity"), h.velocity);
        c.positive(&format!("{hp}.acceleration"), h.acceleration);
        let pp = format!("{hp}.position");
        let l = e.position_limits_soft;
        if c.finite(&pp, h.position) && !(l.lower <= h.position && h.position <= l.upper) {
            c.push(
                pp,
                Problem::OutOfRange {
                    value: h.position,
                    expected: format!(
                        "inside encoder.position_limits_soft [{}, {}]",
                        l.lower, l.upper
                    ),
                },
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
        ("deadband", g.deadband),
    ] {
        c.non_negative(&format!("{pp}.{name}"), v);
    }
    if let Some(i) = g.integral_limit {
        c.non_negative(&format!("{pp}.integral_limit"), i);
    }
}
