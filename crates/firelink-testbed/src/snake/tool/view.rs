//! The selected node's frame: every channel's readouts, converted, as
//! data ([`NodeView`]) and as text ([`render`]).

use std::fmt::Write as _;

use serde::Serialize;

/// One channel's readouts, converted.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChannelView {
    /// Channel 1..=7.
    pub channel: u8,
    /// Amplifier enabled (STATUS).
    pub enabled: bool,
    /// Fault line (STATUS).
    pub fault: bool,
    /// Motor DAC code and its command, volts from the midpoint.
    pub motor_code: u16,
    /// See `motor_code`.
    pub motor_volts: f64,
    /// Current-limit DAC code and the limit, mA.
    pub current_limit_code: u16,
    /// See `current_limit_code`.
    pub current_limit_ma: f64,
    /// Encoder count (24 bits), overflow, position and velocity in units.
    pub encoder_count: u32,
    /// See `encoder_count`.
    pub encoder_overflow: bool,
    /// See `encoder_count`.
    pub encoder_position: f64,
    /// Per second.
    pub encoder_velocity: f64,
    /// Unit of the encoder figures.
    pub encoder_unit: String,
    /// Motor current: ADC + 8192, and mA.
    pub motor_current_api: u16,
    /// See `motor_current_api`.
    pub motor_current_ma: f64,
    /// Potentiometer: ADC + 8192, volts, position in units.
    pub pot_api: u16,
    /// See `pot_api`.
    pub pot_volts: f64,
    /// See `pot_api`.
    pub pot_position: f64,
    /// Unit of the pot position.
    pub pot_unit: String,
    /// Speed mode (O1).
    pub speed_mode: bool,
    /// Wiper and the feedback gain of eq. 1.
    pub wiper: u16,
    /// See `wiper`.
    pub feedback_gain: f64,
    /// EEPROM write protection.
    pub write_protect: bool,
}

/// One node's frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NodeView {
    /// Board ID.
    pub board: u8,
    /// STATUS (Table 2), raw.
    pub status: u32,
    /// Watchdog timed out.
    pub watchdog_timeout: bool,
    /// Time since the previous latch, ms ("Timestamp Delta").
    pub timestamp_delta_ms: f64,
    /// Channels 1-7.
    pub channels: Vec<ChannelView>,
}

/// A node's frame as text (Fig. 19's readouts for every channel).
pub fn render(view: &NodeView, selected: u8) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "board {}  status {:#010x}  watchdog {}  timestamp delta {:.3} ms",
        view.board,
        view.status,
        if view.watchdog_timeout {
            "TIMED OUT"
        } else {
            "ok"
        },
        view.timestamp_delta_ms
    );
    let _ = writeln!(
        s,
        "  ch  amp  motor[V]  limit[mA]  enc count   enc pos      enc vel/s   curr[mA]  pot[V]  pot pos     mode    wiper  gain     WP"
    );
    for c in &view.channels {
        let _ = writeln!(
            s,
            "{} {}  {:<4} {:+8.4}  {:9.1}  {:8}{} {:9.3} {:<3} {:9.3} {:9.2}  {:6.4}  {:9.3} {:<3} {:<6}  {:5}  {:7.4}  {}",
            if c.channel == selected { ">" } else { " " },
            c.channel,
            if c.fault {
                "FLT"
            } else if c.enabled {
                "on"
            } else {
                "off"
            },
            c.motor_volts,
            c.current_limit_ma,
            c.encoder_count,
            if c.encoder_overflow { "!" } else { " " },
            c.encoder_position,
            c.encoder_unit,
            c.encoder_velocity,
            c.motor_current_ma,
            c.pot_volts,
            c.pot_position,
            c.pot_unit,
            if c.speed_mode { "speed" } else { "torque" },
            c.wiper,
            c.feedback_gain,
            if c.write_protect { "on" } else { "off" }
        );
    }
    s
}
