//! The tool's one-key actions, for any interactive front end (the
//! terminal UI; a web console may offer the same keys): the command a key
//! means from the channel's readouts now, and a command's outcome as one
//! status line.

use super::{NodeView, ToolError};

/// The keys and what they do, as one line.
pub const KEYS: &str = "keys: <- -> channel  up/down board  e enable  +/- voltage 0.05 V  [ ] limit 10 mA  \
< > wiper 10  t torque/speed  w write protect  r reset encoder  : command  q quit";

/// The command key `key` means on channel `channel` (1..=7) of `view`, or
/// `None` for a key that means nothing there.
pub fn key_command(view: &NodeView, channel: u8, key: char) -> Option<String> {
    let c = view.channels.get(usize::from(channel).checked_sub(1)?)?;
    Some(match key {
        'e' => format!("enable {}", if c.enabled { "off" } else { "on" }),
        '+' | '=' => format!("voltage {}", (c.motor_volts + 0.05).min(1.25)),
        '-' => format!("voltage {}", (c.motor_volts - 0.05).max(-1.25)),
        ']' => format!("current-limit {}", (c.current_limit_ma + 10.0).min(2000.0)),
        '[' => format!("current-limit {}", (c.current_limit_ma - 10.0).max(0.0)),
        '>' | '.' => format!("wiper {}", (c.wiper + 10).min(1023)),
        '<' | ',' => format!("wiper {}", c.wiper.saturating_sub(10)),
        't' => format!("switch {}", if c.speed_mode { "torque" } else { "speed" }),
        'w' => format!(
            "write-protect {}",
            if c.write_protect { "off" } else { "on" }
        ),
        'r' => "reset-encoder".into(),
        _ => return None,
    })
}

/// A command's outcome as one status line.
pub fn outcome_line(r: Result<String, ToolError>) -> String {
    match r {
        Ok(text) => text.trim().replace('\n', " | "),
        Err(e) => format!("error: {e}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outcomes_are_one_line() {
        assert_eq!(outcome_line(Ok("a\nb\n".into())), "a | b");
    }
}
