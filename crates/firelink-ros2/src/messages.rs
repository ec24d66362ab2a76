//! The ROS 2 message types the node speaks, laid out field for field as
//! their IDL so that CDR serialisation matches any ROS 2 participant:
//! `builtin_interfaces/Time`, `std_msgs/Header`, `std_msgs/String`,
//! `sensor_msgs/JointState`, `crtk_msgs/OperatingState`,
//! `crtk_msgs/StringStamped`.

use serde::{Deserialize, Serialize};

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds, 0..1e9.
    pub nanosec: u32,
}

impl Time {
    /// From seconds since the Unix epoch.
    pub fn from_secs_f64(t: f64) -> Time {
        let t = t.max(0.0);
        let sec = t.floor();
        Time {
            sec: sec.min(f64::from(i32::MAX)) as i32,
            nanosec: ((t - sec) * 1e9).min(999_999_999.0) as u32,
        }
    }

    /// As seconds.
    pub fn as_secs_f64(self) -> f64 {
        f64::from(self.sec) + f64::from(self.nanosec) * 1e-9
    }

    /// Now, on the machine's real-time clock (what ROS 2 stamps with).
    pub fn now() -> Time {
        let d = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        Time::from_secs_f64(d.as_secs_f64())
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Time stamp.
    pub stamp: Time,
    /// Frame of reference.
    pub frame_id: String,
}

/// `std_msgs/msg/String`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StringMsg {
    /// The text.
    pub data: String,
}

/// `sensor_msgs/msg/JointState`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    /// Stamp and frame.
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions, rad or m.
    pub position: Vec<f64>,
    /// Velocities, rad/s or m/s.
    pub velocity: Vec<f64>,
    /// Efforts (here: commanded motor current, A).
    pub effort: Vec<f64>,
}

/// `crtk_msgs/msg/OperatingState`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct OperatingState {
    /// Stamp.
    pub header: Header,
    /// `DISABLED`, `ENABLED`, `PAUSED` or `FAULT`.
    pub state: String,
    /// Every joint homed.
    pub is_homed: bool,
    /// A motion or a state change is in progress.
    pub is_busy: bool,
}

/// `crtk_msgs/msg/StringStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StringStamped {
    /// Stamp.
    pub header: Header,
    /// The text (`enable`, `disable`, `home`, ...).
    pub string: String,
}
