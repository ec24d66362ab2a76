//! What the dVRK console's configuration reader requires of a
//! saw-robot-io v6 file, checked on the file's JSON as that reader sees
//! it, independently of Firelink's own parser.
//!
//! sawRobotIO1394 2.x reads the file into classes generated from its data
//! description (`osaConfiguration1394.cdg`): a member declared without a
//! default is required, and a required member that is absent, `null`, an
//! empty list or an empty object (jsoncpp's `empty()`) stops the console
//! with "empty JSON value for: KEY < PARENT". A member is read with
//! jsoncpp's conversions: a number reads as a number or a boolean (a
//! boolean as 0/1), a string as a string, number or boolean (written as
//! text), an integer or size from a number (a size not negative), an enum
//! from one of its names. Keys the reader does not know are read past.
//! Before that, `mtsRobotIO1394::Configure` requires `"$id":
//! "saw-robot-io.schema.json"` and `"$version"` reading as `"6"`.
//!
//! [`check`] returns every place where that reader would stop, so a file
//! that passes here loads in the console as far as its reader goes (the
//! console checks more later: board IDs against the bus, calibrations).

use core::fmt;

use serde_json::Value;

/// A JSON value's type as the reader converts it.
#[derive(Debug, Clone, Copy)]
enum Ty {
    /// `double`: a number or a boolean.
    Double,
    /// `int`: a number or a boolean.
    Int,
    /// `size_t`: a non-negative number.
    Size,
    /// `bool`: a boolean or a number.
    Bool,
    /// `std::string`: a string, number or boolean.
    Str,
    /// A cisst enum: one of these names.
    Enum(&'static [&'static str]),
    /// A nested class.
    Object(&'static [Member]),
    /// `std::vector` of a class.
    List(&'static [Member]),
    /// `std::vector<std::string>`.
    StrList,
    /// A matrix (rows of numbers).
    Matrix,
}

/// One member of a generated class.
#[derive(Debug, Clone, Copy)]
struct Member {
    name: &'static str,
    ty: Ty,
    /// Declared without a default.
    required: bool,
}

const fn req(name: &'static str, ty: Ty) -> Member {
    Member {
        name,
        ty,
        required: true,
    }
}

const fn opt(name: &'static str, ty: Ty) -> Member {
    Member {
        name,
        ty,
        required: false,
    }
}

/// `osaLinearFunction`: both members default to 0.
const LINEAR: &[Member] = &[opt("scale", Ty::Double), opt("offset", Ty::Double)];
/// `osaLimits`.
const LIMITS: &[Member] = &[req("lower", Ty::Double), req("upper", Ty::Double)];
/// `osaDrive1394Configuration`.
const DRIVE: &[Member] = &[
    opt("effort_to_current", Ty::Object(LINEAR)),
    req("current_to_bits", Ty::Object(LINEAR)),
    req("bits_to_current", Ty::Object(LINEAR)),
    opt("maximum_current", Ty::Double),
];
/// `osaEncoder1394Configuration`.
const ENCODER: &[Member] = &[
    req("bits_to_position", Ty::Object(LINEAR)),
    req("position_limits_soft", Ty::Object(LIMITS)),
    req("velocity_source", Ty::Enum(&["FIRMWARE", "SOFTWARE"])),
];
/// `osaPotentiometer1394Configuration`.
const POTENTIOMETER: &[Member] = &[
    req("bits_to_voltage", Ty::Object(LINEAR)),
    opt("voltage_to_position", Ty::Object(LINEAR)),
];
/// `osaBrake1394Configuration`.
const BRAKE: &[Member] = &[
    req("board_id", Ty::Int),
    opt("axis_id", Ty::Int),
    req("drive", Ty::Object(DRIVE)),
    req("release_current", Ty::Double),
    req("release_time", Ty::Double),
    req("released_current", Ty::Double),
    req("engaged_current", Ty::Double),
];
/// `cmnJointType` names.
const JOINT_TYPES: &[&str] = &["REVOLUTE", "PRISMATIC", "CONTINUOUS", "FIXED", "UNDEFINED"];
/// `osaActuator1394Configuration`.
const ACTUATOR: &[Member] = &[
    req("board_id", Ty::Int),
    opt("axis_id", Ty::Int),
    opt("joint_type", Ty::Enum(JOINT_TYPES)),
    req("drive", Ty::Object(DRIVE)),
    opt("encoder", Ty::Object(ENCODER)),
    opt("potentiometer", Ty::Object(POTENTIOMETER)),
];
/// `osaPotentiometerTolerance1394Configuration`.
const TOLERANCE: &[Member] = &[
    opt("axis_id", Ty::Int),
    req("distance", Ty::Double),
    req("latency", Ty::Double),
];
/// `prmActuatorJointCoupling`: the matrices Firelink's files use.
const COUPLING: &[Member] = &[
    opt("JointToActuatorPosition", Ty::Matrix),
    opt("ActuatorToJointPosition", Ty::Matrix),
    opt("JointToActuatorEffort", Ty::Matrix),
    opt("ActuatorToJointEffort", Ty::Matrix),
];
/// `osaPotentiometers1394Configuration`.
const POTENTIOMETERS: &[Member] = &[
    req(
        "potentiometers_type",
        Ty::Enum(&["UNDEFINED", "NONE", "ANALOG", "DIGITAL"]),
    ),
    opt("tolerances", Ty::List(TOLERANCE)),
    opt("coupling", Ty::Object(COUPLING)),
    opt("lookup_table_file", Ty::Str),
];
/// `osaRobot1394Configuration`.
const ROBOT: &[Member] = &[
    req("name", Ty::Str),
    opt(
        "hardware_version",
        Ty::Enum(&["HARDWARE_UNDEFINED", "QLA1", "DQLA", "dRA1"]),
    ),
    req("serial_number", Ty::Str),
    opt("path", Ty::StrList),
    opt("only_IO", Ty::Bool),
    opt("has_encoder_preload", Ty::Bool),
    req("number_of_actuators", Ty::Size),
    req("actuators", Ty::List(ACTUATOR)),
    req("number_of_brakes", Ty::Size),
    opt("brakes", Ty::List(BRAKE)),
    opt("potentiometers", Ty::Object(POTENTIOMETERS)),
];
/// `osaDigitalInput1394Configuration`.
const DIGITAL_INPUT: &[Member] = &[
    req("name", Ty::Str),
    req("board_id", Ty::Int),
    req("bit_id", Ty::Int),
    req("trigger_when_pressed", Ty::Bool),
    req("trigger_when_released", Ty::Bool),
    req("pressed_value", Ty::Bool),
    opt("skip_first_run", Ty::Bool),
    opt("debounce_time", Ty::Double),
    opt("debounce_time_click", Ty::Double),
];
/// `osaDigitalOutput1394Configuration`.
const DIGITAL_OUTPUT: &[Member] = &[
    req("name", Ty::Str),
    req("board_id", Ty::Int),
    req("bit_id", Ty::Int),
    opt("high_duration", Ty::Double),
    opt("low_duration", Ty::Double),
    opt("is_PWM", Ty::Bool),
    opt("PWM_frequency", Ty::Double),
];
/// `osaDallasChip1394Configuration`.
const DALLAS: &[Member] = &[req("name", Ty::Str), req("board_id", Ty::Int)];
/// `osaPort1394Configuration`: the whole file.
const PORT: &[Member] = &[
    opt("robots", Ty::List(ROBOT)),
    opt("digital_inputs", Ty::List(DIGITAL_INPUT)),
    opt("digital_outputs", Ty::List(DIGITAL_OUTPUT)),
    opt("dallas_chips", Ty::List(DALLAS)),
];

/// Why the console's reader would stop at a place.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ConsoleProblem {
    /// A required key is absent, null, `[]` or `{}`.
    Missing,
    /// The value does not convert to what the reader wants.
    WrongType {
        /// What it wants, in words.
        expected: String,
    },
    /// `$id` or `$version` is not the one the console reads.
    Header {
        /// What it wants.
        expected: &'static str,
    },
}

impl fmt::Display for ConsoleProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConsoleProblem::Missing => write!(f, "required key missing or empty"),
            ConsoleProblem::WrongType { expected } => write!(f, "not {expected}"),
            ConsoleProblem::Header { expected } => write!(f, "must read {expected:?}"),
        }
    }
}

/// One place the console's reader would stop.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConsoleIssue {
    /// JSON path (`robots[0].number_of_brakes`).
    pub path: String,
    /// Why.
    pub problem: ConsoleProblem,
}

impl fmt::Display for ConsoleIssue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path, self.problem)
    }
}

/// Every place where the dVRK console's reader (sawRobotIO1394 2.x) would
/// refuse `doc`, in document order; empty when it reads the whole file.
/// A missing `$id` is not reported here (the loader says it once).
pub fn check(doc: &Value) -> Vec<ConsoleIssue> {
    let mut out = Vec::new();
    if let Some(id) = doc.get("$id") {
        if as_text(id).as_deref() != Some(super::SCHEMA_ID) {
            out.push(ConsoleIssue {
                path: "$id".into(),
                problem: ConsoleProblem::Header {
                    expected: super::SCHEMA_ID,
                },
            });
        }
    }
    if doc.get("$version").and_then(as_text).as_deref() != Some(super::SCHEMA_VERSION) {
        out.push(ConsoleIssue {
            path: "$version".into(),
            problem: ConsoleProblem::Header {
                expected: super::SCHEMA_VERSION,
            },
        });
    }
    check_members(doc, PORT, "", &mut out);
    out
}

/// jsoncpp's `asString`: strings, numbers and booleans; `None` otherwise.
fn as_text(v: &Value) -> Option<String> {
    match v {
        Value::String(s) => Some(s.clone()),
        Value::Number(n) => Some(n.to_string()),
        Value::Bool(b) => Some(b.to_string()),
        _ => None,
    }
}

/// jsoncpp's `empty()`: null, an empty list or an empty object.
fn is_empty(v: &Value) -> bool {
    match v {
        Value::Null => true,
        Value::Array(a) => a.is_empty(),
        Value::Object(o) => o.is_empty(),
        _ => false,
    }
}

fn join(parent: &str, key: &str) -> String {
    if parent.is_empty() {
        key.to_string()
    } else {
        format!("{parent}.{key}")
    }
}

fn check_members(v: &Value, members: &[Member], path: &str, out: &mut Vec<ConsoleIssue>) {
    if !v.is_object() {
        out.push(ConsoleIssue {
            path: path.to_string(),
            problem: ConsoleProblem::WrongType {
                expected: "an object".into(),
            },
        });
        return;
    }
    for m in members {
        let p = join(path, m.name);
        match v.get(m.name) {
            Some(x) if !is_empty(x) => check_value(x, m.ty, &p, out),
            // An optional member that is present but empty keeps its
            // default.
            _ if !m.required => {}
            _ => out.push(ConsoleIssue {
                path: p,
                problem: ConsoleProblem::Missing,
            }),
        }
    }
}

fn check_value(v: &Value, ty: Ty, path: &str, out: &mut Vec<ConsoleIssue>) {
    let wrong = |expected: &str, out: &mut Vec<ConsoleIssue>| {
        out.push(ConsoleIssue {
            path: path.to_string(),
            problem: ConsoleProblem::WrongType {
                expected: expected.to_string(),
            },
        });
    };
    match ty {
        Ty::Double | Ty::Int | Ty::Bool => {
            if !(v.is_number() || v.is_boolean()) {
                wrong("a number", out);
            }
        }
        Ty::Size => {
            if !v.as_f64().is_some_and(|x| x >= 0.0) {
                wrong("a number >= 0", out);
            }
        }
        Ty::Str => {
            if as_text(v).is_none() {
                wrong("a string", out);
            }
        }
        Ty::Enum(names) => {
            if !v.as_str().is_some_and(|s| names.contains(&s)) {
                wrong(&format!("one of {}", names.join(", ")), out);
            }
        }
        Ty::Object(members) => check_members(v, members, path, out),
        Ty::List(members) => match v.as_array() {
            Some(items) => {
                for (i, item) in items.iter().enumerate() {
                    check_members(item, members, &format!("{path}[{i}]"), out);
                }
            }
            None => wrong("a list", out),
        },
        Ty::StrList => {
            if !v
                .as_array()
                .is_some_and(|a| a.iter().all(|s| as_text(s).is_some()))
            {
                wrong("a list of strings", out);
            }
        }
        Ty::Matrix => {
            let rows = v.as_array();
            if !rows.is_some_and(|r| {
                r.iter().all(|row| {
                    row.as_array()
                        .is_some_and(|c| c.iter().all(Value::is_number))
                })
            }) {
                wrong("rows of numbers", out);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn paths(doc: &Value) -> Vec<String> {
        check(doc).into_iter().map(|i| i.to_string()).collect()
    }

    #[test]
    fn a_minimal_file_the_console_reads() {
        let doc = json!({
            "$id": "saw-robot-io.schema.json", "$version": 6,
            "robots": [{
                "name": "R", "serial_number": 12345, "number_of_actuators": 1,
                "number_of_brakes": 0, "brakes": [],
                "actuators": [{ "board_id": 0, "drive": {
                    "current_to_bits": { "scale": 1 }, "bits_to_current": { "offset": 2 } } }]
            }]
        });
        assert_eq!(paths(&doc), Vec::<String>::new());
    }

    #[test]
    fn what_stops_the_reader() {
        let doc = json!({
            "$id": "saw-robot-io.schema.json", "$version": "5",
            "robots": [{
                "name": "R", "serial_number": "1", "number_of_actuators": -1,
                "actuators": [{ "board_id": "zero", "drive": {} ,
                                "encoder": { "bits_to_position": { "scale": 1 },
                                             "position_limits_soft": { "lower": 0 },
                                             "velocity_source": "GUESS" } }],
                "potentiometers": { "tolerances": [] }
            }],
            "digital_inputs": [{ "name": "x", "board_id": 0, "bit_id": 1, "pressed_value": true }]
        });
        assert_eq!(
            paths(&doc),
            [
                "$version: must read \"6\"",
                "robots[0].number_of_actuators: not a number >= 0",
                "robots[0].actuators[0].board_id: not a number",
                "robots[0].actuators[0].drive: required key missing or empty",
                "robots[0].actuators[0].encoder.position_limits_soft.upper: required key missing or empty",
                "robots[0].actuators[0].encoder.velocity_source: not one of FIRMWARE, SOFTWARE",
                "robots[0].number_of_brakes: required key missing or empty",
                "robots[0].potentiometers.potentiometers_type: required key missing or empty",
                "digital_inputs[0].trigger_when_pressed: required key missing or empty",
                "digital_inputs[0].trigger_when_released: required key missing or empty",
            ]
        );
    }
}
