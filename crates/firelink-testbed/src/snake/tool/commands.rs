//! The command language: one command per line or between `;`, the same
//! for scripts and the terminal UI's prompt ([`HELP`] lists them). Each
//! command returns what it prints.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

use firelink_host::{Port, WatchdogSetting};
use firelink_wire::snake::analog;
use firelink_wire::snake::registers::{PotOutputs, PowerControl, Wiper};

use super::error::{ToolError, refused};
use super::session::Session;
use super::state::ChannelState;
use super::view::render;

/// The commands, one line each.
pub const HELP: &str = "\
commands (separate with ; or new lines):
  board ID | channel N              select the node and the channel (1..7)
  enable on|off                     amplifier of the channel
  voltage V | motor-code CODE       motor command: volts from the midpoint (+-1.25) or the DAC code
  current-limit MA                  current limit, mA (0..2500)
  reset-encoder | preload COUNT     encoder to the midpoint, or to COUNT
  switch torque|speed               the pot's O1 output
  wiper N                           digital pot wiper 0..1023 (prints the feedback gain)
  write-protect on|off              EEPROM write protection
  eeprom-read W | eeprom-write W V  EEPROM word W (0..13) of the channel, raw
  eeprom-read-float W | eeprom-write-float W X   a float in words W and W+1
  factors encoder=U pot=U pot-offset=U encoder-unit=deg pot-unit=mm
  watchdog MS|off | wait MS         node watchdogs; let time pass
  send-state | send-defaults | all-off
  save FILE | load FILE             every channel of every node, EEPROM included
  show [json]                       the node's readouts
";

fn parse_on_off(word: Option<&str>, what: &str) -> Result<bool, ToolError> {
    match word {
        Some("on" | "1" | "true" | "yes") => Ok(true),
        Some("off" | "0" | "false" | "no") => Ok(false),
        other => Err(refused(format!(
            "{what}: expected on or off, got {other:?}"
        ))),
    }
}

fn parse_num<T: std::str::FromStr>(word: Option<&str>, what: &str) -> Result<T, ToolError> {
    let w = word.ok_or_else(|| refused(format!("{what}: a value is missing")))?;
    let parsed = match w.strip_prefix("0x") {
        Some(hex) => u64::from_str_radix(hex, 16)
            .ok()
            .and_then(|v| v.to_string().parse().ok()),
        None => w.parse().ok(),
    };
    parsed.ok_or_else(|| refused(format!("{what}: {w:?} is not a valid number")))
}

fn parse_f64(word: Option<&str>, what: &str, lo: f64, hi: f64) -> Result<f64, ToolError> {
    let x: f64 = parse_num(word, what)?;
    if !(x.is_finite() && (lo..=hi).contains(&x)) {
        return Err(refused(format!(
            "{what}: {} is out of range: {} to {}",
            word.unwrap_or("").trim(),
            firelink_wire::human::Number(lo),
            firelink_wire::human::Number(hi)
        )));
    }
    Ok(x)
}

impl<P: Port> Session<P> {
    /// Run a script: commands separated by `;` or new lines. Returns what
    /// they printed.
    ///
    /// # Errors
    /// The first command that failed, named with its position.
    pub fn run_script(&mut self, script: &str) -> Result<String, ToolError> {
        let mut out = String::new();
        for (i, line) in script
            .split([';', '\n'])
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with('#'))
            .enumerate()
        {
            match self.command(line) {
                Ok(text) => out.push_str(&text),
                Err(e) => return Err(refused(format!("command {} ({line:?}): {e}", i + 1))),
            }
        }
        Ok(out)
    }

    /// Run one command; returns what it prints.
    ///
    /// # Errors
    /// A bad command or argument (named), or the node refused.
    pub fn command(&mut self, line: &str) -> Result<String, ToolError> {
        let mut words = line.split_whitespace();
        let verb = words.next().unwrap_or("");
        let arg = words.next();
        let arg2 = words.next();
        let mut out = String::new();
        match verb {
            "board" => {
                self.select_board(parse_num(arg, "board")?)?;
                let _ = writeln!(out, "board {}", self.board);
            }
            "channel" | "axis" => {
                self.select_channel(parse_num(arg, "channel")?)?;
                let _ = writeln!(out, "channel {}", self.channel);
            }
            "eeprom-read" | "eeprom-read-float" | "eeprom-write" | "eeprom-write-float" => {
                out = self.eeprom_command(verb, arg, arg2)?;
            }
            "factors" => out = self.factors_command(line)?,
            "help" => out.push_str(HELP),
            "" => {}
            _ => {
                if let Some(text) = self.channel_command(verb, arg)? {
                    out = text;
                } else if let Some(text) = self.session_command(verb, arg)? {
                    out = text;
                } else {
                    return Err(refused(format!("unknown command {verb:?} (try help)")));
                }
            }
        }
        Ok(out)
    }

    /// The selected channel's settings (`None`: not one of them).
    fn channel_command(
        &mut self,
        verb: &str,
        arg: Option<&str>,
    ) -> Result<Option<String>, ToolError> {
        let mut out = String::new();
        let (b, ch) = (self.board, self.channel);
        match verb {
            "enable" => {
                let on = parse_on_off(arg, "enable")?;
                self.state_mut()?.enabled = on;
                self.send_outputs()?;
                let _ = writeln!(out, "board {b} channel {ch}: amplifier {}", on_off(on));
            }
            "voltage" => {
                let v = parse_f64(arg, "voltage (V from the 1.25 V midpoint)", -1.25, 1.25)?;
                let code = analog::command_code(v);
                self.state_mut()?.motor_code = code;
                self.send_outputs()?;
                let _ = writeln!(
                    out,
                    "board {b} channel {ch}: motor command {v:+.4} V (code {code:#06x})"
                );
            }
            "motor-code" => {
                let code: u16 = parse_num(arg, "motor code (0..=65535)")?;
                self.state_mut()?.motor_code = code;
                self.send_outputs()?;
                let _ = writeln!(out, "board {b} channel {ch}: motor code {code:#06x}");
            }
            "current-limit" => {
                let ma = parse_f64(arg, "current limit (mA)", 0.0, 1e3 * analog::MAX_AMPS)?;
                let code = analog::limit_code(ma / 1e3);
                self.system.set_motor_current(b, ch, code)?;
                self.state_mut()?.current_limit_code = code;
                let _ = writeln!(
                    out,
                    "board {b} channel {ch}: current limit {:.1} mA (code {code:#06x})",
                    1e3 * analog::limit_amps(code)
                );
            }
            "reset-encoder" => {
                self.system.reset_encoder(b, ch)?;
                let _ = writeln!(
                    out,
                    "board {b} channel {ch}: encoder preloaded with the midpoint"
                );
            }
            "preload" => {
                let count: u32 = parse_num(arg, "encoder preload")?;
                self.system.set_encoder_preload(b, ch, count)?;
                let _ = writeln!(
                    out,
                    "board {b} channel {ch}: encoder preloaded with {count}"
                );
            }
            "write-protect" => {
                let on = parse_on_off(arg, "write-protect")?;
                self.system.set_write_protect(b, ch, on)?;
                self.state_mut()?.write_protect = on;
                let _ = writeln!(
                    out,
                    "board {b} channel {ch}: EEPROM write protect {}",
                    on_off(on)
                );
            }
            "switch" => {
                let speed = match arg {
                    Some("torque") => false,
                    Some("speed") => true,
                    other => {
                        return Err(refused(format!("switch: torque or speed, got {other:?}")));
                    }
                };
                let st = self.state_mut()?;
                st.speed_mode = speed;
                let outputs = PotOutputs {
                    speed_mode: speed,
                    o2: st.o2,
                };
                self.system.set_analog_switches(b, ch, outputs)?;
                let _ = writeln!(
                    out,
                    "board {b} channel {ch}: {} mode",
                    if speed { "speed" } else { "torque" }
                );
            }
            "wiper" => {
                let w: u16 = parse_num(arg, "wiper")?;
                self.system.set_digital_pot_wiper(b, ch, w)?;
                self.state_mut()?.wiper = w;
                let g = Wiper::new(w).map_or(0.0, |w| w.feedback_gain());
                let _ = writeln!(
                    out,
                    "board {b} channel {ch}: wiper {w}, feedback gain {g:.5}"
                );
            }
            _ => return Ok(None),
        }
        Ok(Some(out))
    }

    /// The EEPROM word `arg` of the selected channel, raw or as a float:
    /// read, or written with `arg2`.
    fn eeprom_command(
        &mut self,
        verb: &str,
        arg: Option<&str>,
        arg2: Option<&str>,
    ) -> Result<String, ToolError> {
        let mut out = String::new();
        let (b, ch) = (self.board, self.channel);
        let word: u8 = parse_num(arg, "EEPROM word (0..=13)")?;
        let index = (u32::from(ch) << 4) | u32::from(word);
        let float = verb.ends_with("float");
        if verb.starts_with("eeprom-read") {
            if float {
                let v = self.system.eeprom_float(b, index)?;
                let _ = writeln!(out, "board {b} EEPROM {index:#04x}: {v} (float)");
            } else {
                let v = self.system.eeprom_raw(b, index)?;
                let _ = writeln!(out, "board {b} EEPROM {index:#04x}: {v:#06x} ({v})");
            }
        } else if float {
            let v: f32 = parse_num(arg2, "EEPROM float")?;
            self.system.set_eeprom_float(b, index, v)?;
            let _ = writeln!(out, "board {b} EEPROM {index:#04x}: wrote {v} (float)");
        } else {
            let v: u16 = parse_num(arg2, "EEPROM word value (0..=65535)")?;
            self.system.set_eeprom_raw(b, index, v)?;
            let _ = writeln!(out, "board {b} EEPROM {index:#04x}: wrote {v:#06x}");
        }
        Ok(out)
    }

    /// `factors key=value ...`: the selected channel's conversion factors.
    fn factors_command(&mut self, line: &str) -> Result<String, ToolError> {
        let mut out = String::new();
        let (b, ch) = (self.board, self.channel);
        let mut f = self.factors(b, ch);
        for kv in line.split_whitespace().skip(1) {
            let (k, v) = kv
                .split_once('=')
                .ok_or_else(|| refused(format!("factors: {kv:?} is not key=value")))?;
            match k {
                "encoder" => f.encoder_per_count = parse_f64(Some(v), k, -1e9, 1e9)?,
                "encoder-unit" => f.encoder_unit = v.to_string(),
                "pot" => f.pot_per_volt = parse_f64(Some(v), k, -1e9, 1e9)?,
                "pot-offset" => f.pot_offset = parse_f64(Some(v), k, -1e9, 1e9)?,
                "pot-unit" => f.pot_unit = v.to_string(),
                _ => {
                    return Err(refused(format!(
                        "factors: unknown {k:?} (encoder, encoder-unit, pot, pot-offset, pot-unit)"
                    )));
                }
            }
        }
        let _ = writeln!(
            out,
            "board {b} channel {ch}: encoder {} {}/count, pot {} {}/V + {}",
            f.encoder_per_count, f.encoder_unit, f.pot_per_volt, f.pot_unit, f.pot_offset
        );
        self.state_mut()?.factors = f;
        Ok(out)
    }

    /// Commands on the nodes and the session (`None`: not one of them).
    fn session_command(
        &mut self,
        verb: &str,
        arg: Option<&str>,
    ) -> Result<Option<String>, ToolError> {
        let mut out = String::new();
        let (b, ch) = (self.board, self.channel);
        match verb {
            "watchdog" => {
                let setting = WatchdogSetting::parse(arg.unwrap_or(""))
                    .map_err(|e| refused(format!("watchdog {}: {e}", arg.unwrap_or(""))))?;
                self.system.set_watchdog(setting)?;
                let _ = writeln!(out, "watchdog {setting} on every node");
                if let Some(w) = setting.warning() {
                    let _ = writeln!(out, "{w}");
                }
            }
            "wait" => {
                let ms = parse_f64(arg, "wait (ms)", 0.0, 60_000.0)?;
                self.system
                    .port_mut()
                    .wait(Duration::from_secs_f64(ms / 1e3));
                let _ = writeln!(out, "waited {ms} ms");
            }
            "send-state" => {
                let states: Vec<ChannelState> = self.commanded.values().cloned().collect();
                for st in &states {
                    self.apply_state(st)?;
                }
                let _ = writeln!(out, "sent the state of {} channel(s)", states.len());
            }
            "send-defaults" => {
                let st = ChannelState::defaults(b, ch, self.factors(b, ch));
                self.apply_state(&st)?;
                let _ = writeln!(out, "board {b} channel {ch}: defaults sent");
            }
            "all-off" => {
                self.system.set_power_control(b, PowerControl::all(false))?;
                for st in self.commanded.values_mut().filter(|s| s.board == b) {
                    st.enabled = false;
                }
                let _ = writeln!(out, "board {b}: every amplifier off");
            }
            "save" => {
                let path = arg.ok_or_else(|| refused("save: a file name is missing"))?;
                let n = self.save(Path::new(path))?;
                let _ = writeln!(out, "saved {n} channels to {path}");
            }
            "load" => {
                let path = arg.ok_or_else(|| refused("load: a file name is missing"))?;
                let n = self.load(Path::new(path))?;
                let _ = writeln!(out, "loaded and sent {n} channels from {path}");
            }
            "show" => {
                let view = self.view()?;
                if arg == Some("json") {
                    let _ = writeln!(out, "{}", serde_json::to_string(&view)?);
                } else {
                    out.push_str(&render(&view, self.channel));
                }
            }
            _ => return Ok(None),
        }
        Ok(Some(out))
    }
}

fn on_off(b: bool) -> &'static str {
    if b { "on" } else { "off" }
}
