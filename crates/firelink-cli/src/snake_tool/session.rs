//! The test and configuration program's model: one session with the Snake
//! nodes behind a port, the channel selected, what the tool commanded,
//! the conversion factors, and the commands (the same for scripts and the
//! terminal UI's prompt).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use firelink_control::config::{IoConfig, JointType};
use firelink_host::snake::SnakeSystem;
use firelink_host::{Port, WatchdogSetting};
use firelink_wire::snake::analog;
use firelink_wire::snake::registers::{
    DAC_MIDPOINT, PotOutputs, PowerControl, Wiper, adc_api_to_volts,
};
use firelink_wire::snake::{CHANNELS, EEPROM_WORDS};

use crate::CliError;

/// Format version of the state files.
pub const STATE_VERSION: u32 = 1;

/// How a channel's readouts convert to units (Fig. 19's "Conversion
/// Factors" tab).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Factors {
    /// Encoder: units per count.
    pub encoder_per_count: f64,
    /// Encoder unit ("deg", "mm").
    pub encoder_unit: String,
    /// Potentiometer: units per volt.
    pub pot_per_volt: f64,
    /// Potentiometer: units at 0 V.
    pub pot_offset: f64,
    /// Potentiometer unit.
    pub pot_unit: String,
}

impl Default for Factors {
    /// Motor-side degrees of a 2048-count encoder; the pot in volts.
    fn default() -> Self {
        Factors {
            encoder_per_count: 360.0 / 2048.0,
            encoder_unit: "deg".into(),
            pot_per_volt: 1.0,
            pot_offset: 0.0,
            pot_unit: "V".into(),
        }
    }
}

impl Factors {
    /// The factors a configuration gives the actuator on `(board, axis)`:
    /// joint degrees (or millimetres) per count and per volt.
    pub fn from_config(config: &IoConfig, board: u8, axis: u8) -> Option<Factors> {
        let j = config
            .joints()
            .find(|j| j.actuator.board_id == board && j.actuator.axis_id == axis)?;
        let a = j.actuator;
        let (scale, unit) = if a.joint_type == Some(JointType::Prismatic) {
            (1e3, "mm")
        } else {
            (180.0 / std::f64::consts::PI, "deg")
        };
        let pot = a.potentiometer?.voltage_to_position;
        Some(Factors {
            encoder_per_count: scale * a.encoder.bits_to_position.scale,
            encoder_unit: unit.into(),
            pot_per_volt: scale * pot.scale,
            pot_offset: scale * pot.offset,
            pot_unit: unit.into(),
        })
    }
}

/// One channel as the tool sets it and as a state file keeps it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChannelState {
    /// Board ID of the node.
    pub board: u8,
    /// Channel 1..=7.
    pub channel: u8,
    /// Amplifier enabled.
    pub enabled: bool,
    /// Motor DAC code.
    pub motor_code: u16,
    /// Current-limit DAC code.
    pub current_limit_code: u16,
    /// Digital pot wiper.
    pub wiper: u16,
    /// Torque (false) or speed (true) mode: pot output O1.
    pub speed_mode: bool,
    /// Pot output O2.
    pub o2: bool,
    /// EEPROM write protection.
    pub write_protect: bool,
    /// The 14 EEPROM words.
    pub eeprom: Vec<u16>,
    /// Conversion factors.
    pub factors: Factors,
}

impl ChannelState {
    /// "Send Defaults": disabled, motor at the midpoint, a 100 mA limit,
    /// the nominal wiper, torque mode, write-protected, EEPROM untouched.
    fn defaults(board: u8, channel: u8, factors: Factors) -> ChannelState {
        ChannelState {
            board,
            channel,
            enabled: false,
            motor_code: DAC_MIDPOINT,
            current_limit_code: analog::limit_code(0.1),
            wiper: Wiper::NOMINAL.value(),
            speed_mode: false,
            o2: false,
            write_protect: true,
            eeprom: Vec::new(),
            factors,
        }
    }
}

/// A state file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StateFile {
    /// [`STATE_VERSION`].
    pub version: u32,
    /// Every channel of every node.
    pub channels: Vec<ChannelState>,
}

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

/// A session with the nodes.
pub struct Session<P: Port> {
    system: SnakeSystem<P>,
    board: u8,
    channel: u8,
    commanded: BTreeMap<(u8, u8), ChannelState>,
    config: Option<IoConfig>,
}

fn bad(what: impl Into<String>) -> CliError {
    CliError::ToolCommand(what.into())
}

fn parse_on_off(word: Option<&str>, what: &str) -> Result<bool, CliError> {
    match word {
        Some("on" | "1" | "true" | "yes") => Ok(true),
        Some("off" | "0" | "false" | "no") => Ok(false),
        other => Err(bad(format!("{what}: expected on or off, got {other:?}"))),
    }
}

fn parse_num<T: std::str::FromStr>(word: Option<&str>, what: &str) -> Result<T, CliError> {
    let w = word.ok_or_else(|| bad(format!("{what}: a value is missing")))?;
    let parsed = match w.strip_prefix("0x") {
        Some(hex) => u64::from_str_radix(hex, 16)
            .ok()
            .and_then(|v| v.to_string().parse().ok()),
        None => w.parse().ok(),
    };
    parsed.ok_or_else(|| bad(format!("{what}: {w:?} is not a valid number")))
}

fn parse_f64(word: Option<&str>, what: &str, lo: f64, hi: f64) -> Result<f64, CliError> {
    let x: f64 = parse_num(word, what)?;
    if !(x.is_finite() && (lo..=hi).contains(&x)) {
        return Err(bad(format!(
            "{what}: {} is out of range: {} to {}",
            word.unwrap_or("").trim(),
            firelink_wire::human::Number(lo),
            firelink_wire::human::Number(hi)
        )));
    }
    Ok(x)
}

impl<P: Port> Session<P> {
    /// A session on `system`; `config` (if any) gives the conversion
    /// factors of the channels it maps.
    ///
    /// # Errors
    /// Reading a node failed.
    pub fn new(system: SnakeSystem<P>, config: Option<IoConfig>) -> Result<Session<P>, CliError> {
        let board = system.nodes().first().map_or(0, |n| n.board_id());
        let mut s = Session {
            system,
            board,
            channel: 1,
            commanded: BTreeMap::new(),
            config,
        };
        s.system.latch_all_inputs();
        Ok(s)
    }

    /// The board selected.
    pub fn board(&self) -> u8 {
        self.board
    }

    /// The channel selected.
    pub fn channel(&self) -> u8 {
        self.channel
    }

    /// Board IDs of the nodes.
    pub fn boards(&self) -> Vec<u8> {
        self.system.nodes().iter().map(|n| n.board_id()).collect()
    }

    /// Turn off every amplifier the tool turned on (at the end of a
    /// session: a tool that exits leaves no motor powered). Returns the
    /// boards it told.
    ///
    /// # Errors
    /// The node refused or did not answer.
    pub fn finish(&mut self) -> Result<Vec<u8>, CliError> {
        let mut boards: Vec<u8> = self
            .commanded
            .values()
            .filter(|c| c.enabled)
            .map(|c| c.board)
            .collect();
        boards.dedup();
        for &b in &boards {
            self.system.set_power_control(b, PowerControl::all(false))?;
        }
        for c in self.commanded.values_mut() {
            c.enabled = false;
        }
        Ok(boards)
    }

    /// Select a board.
    ///
    /// # Errors
    /// No such node.
    pub fn select_board(&mut self, board: u8) -> Result<(), CliError> {
        if self.system.node(board).is_none() {
            return Err(bad(format!(
                "board {board}: no such node (nodes {:?})",
                self.boards()
            )));
        }
        self.board = board;
        Ok(())
    }

    /// Select a channel.
    ///
    /// # Errors
    /// Outside 1..=7.
    pub fn select_channel(&mut self, channel: u8) -> Result<(), CliError> {
        firelink_host::snake::channel(channel)?;
        self.channel = channel;
        Ok(())
    }

    fn factors(&self, board: u8, channel: u8) -> Factors {
        self.commanded
            .get(&(board, channel))
            .map(|c| c.factors.clone())
            .or_else(|| {
                self.config
                    .as_ref()
                    .and_then(|c| Factors::from_config(c, board, channel - 1))
            })
            .unwrap_or_default()
    }

    /// What the tool commanded on the selected channel so far (starting
    /// from the node's own state).
    fn state_mut(&mut self) -> Result<&mut ChannelState, CliError> {
        let key = (self.board, self.channel);
        if !self.commanded.contains_key(&key) {
            let s = self.read_channel_state(self.board, self.channel, false)?;
            self.commanded.insert(key, s);
        }
        self.commanded
            .get_mut(&key)
            .ok_or_else(|| bad("internal: channel state"))
    }

    /// A channel's state as the node holds it (with the EEPROM when
    /// `eeprom`).
    fn read_channel_state(
        &mut self,
        board: u8,
        channel: u8,
        eeprom: bool,
    ) -> Result<ChannelState, CliError> {
        let factors = self.factors(board, channel);
        let s = &mut self.system;
        let dac = s.dac(board, channel)?;
        let wiper = s.digital_pot_wiper(board, channel)?.value();
        let outputs = s.analog_switches(board, channel)?;
        let write_protect = s.write_protect(board, channel)?;
        let mut words = Vec::new();
        if eeprom {
            for w in 0..EEPROM_WORDS as u32 {
                words.push(s.eeprom_raw(board, (u32::from(channel) << 4) | w)?);
            }
        }
        s.latch_all_inputs();
        let enabled = s
            .node(board)
            .is_some_and(|n| n.amplifier_enabled(channel).unwrap_or(false));
        Ok(ChannelState {
            board,
            channel,
            enabled,
            motor_code: dac.motor_voltage(),
            current_limit_code: dac.current_limit(),
            wiper,
            speed_mode: outputs.speed_mode,
            o2: outputs.o2,
            write_protect,
            eeprom: words,
            factors,
        })
    }

    /// Write a channel state to the node (EEPROM words too, if the state
    /// has them: write protection is lifted for them and set as saved).
    fn apply_state(&mut self, st: &ChannelState) -> Result<(), CliError> {
        let (b, ch) = (st.board, st.channel);
        let s = &mut self.system;
        s.set_motor_current(b, ch, st.current_limit_code)?;
        s.set_digital_pot_wiper(b, ch, st.wiper)?;
        s.set_analog_switches(
            b,
            ch,
            PotOutputs {
                speed_mode: st.speed_mode,
                o2: st.o2,
            },
        )?;
        if !st.eeprom.is_empty() {
            if st.eeprom.len() != EEPROM_WORDS {
                return Err(bad(format!(
                    "board {b} channel {ch}: {} EEPROM words in the state, expected {EEPROM_WORDS}",
                    st.eeprom.len()
                )));
            }
            s.set_write_protect(b, ch, false)?;
            for (w, v) in st.eeprom.iter().enumerate() {
                s.set_eeprom_raw(b, (u32::from(ch) << 4) | w as u32, *v)?;
            }
        }
        s.set_write_protect(b, ch, st.write_protect)?;
        let node = s
            .node_mut(b)
            .ok_or_else(|| bad(format!("board {b}: no such node")))?;
        node.set_motor_voltage(ch, st.motor_code)?;
        node.set_amplifier_enable(ch, st.enabled)?;
        s.apply_all_outputs();
        self.commanded.insert((b, ch), st.clone());
        Ok(())
    }

    /// Send the selected channel's motor code and enable (the buffered
    /// outputs).
    fn send_outputs(&mut self) -> Result<(), CliError> {
        let (b, ch) = (self.board, self.channel);
        let st = self.state_mut()?.clone();
        let node = self
            .system
            .node_mut(b)
            .ok_or_else(|| bad(format!("board {b}: no such node")))?;
        node.set_motor_voltage(ch, st.motor_code)?;
        node.set_amplifier_enable(ch, st.enabled)?;
        let r = *self.system.apply_all_outputs();
        match r.error {
            Some(e) => Err(e.into()),
            None => Ok(()),
        }
    }

    /// Latch the inputs and build the selected node's frame.
    ///
    /// # Errors
    /// The latch failed for this node; reading the pots failed.
    pub fn view(&mut self) -> Result<NodeView, CliError> {
        let b = self.board;
        let mut pots = Vec::with_capacity(CHANNELS);
        for ch in 1..=CHANNELS as u8 {
            let s = &mut self.system;
            let wiper = s.digital_pot_wiper(b, ch)?;
            let outputs = s.analog_switches(b, ch)?;
            let wp = s.write_protect(b, ch)?;
            let dac = s.dac(b, ch)?;
            pots.push((wiper, outputs, wp, dac));
        }
        let report = *self.system.latch_all_inputs();
        let node = self
            .system
            .node(b)
            .ok_or_else(|| bad(format!("board {b}: no such node")))?;
        if !node.is_valid() {
            return Err(report.error.map_or_else(
                || bad(format!("board {b} did not answer the block read")),
                CliError::from,
            ));
        }
        let mut channels = Vec::with_capacity(CHANNELS);
        for (ch, (wiper, outputs, wp, dac)) in (1..=CHANNELS as u8).zip(pots) {
            let f = self.factors(b, ch);
            let pot_api = node.analog_position(ch)?;
            let pot_volts = adc_api_to_volts(pot_api);
            let current_api = node.motor_current(ch)?;
            channels.push(ChannelView {
                channel: ch,
                enabled: node.amplifier_enabled(ch)?,
                fault: node.amplifier_fault(ch)?,
                motor_code: dac.motor_voltage(),
                motor_volts: analog::command_volts(dac.motor_voltage()),
                current_limit_code: dac.current_limit(),
                current_limit_ma: 1e3 * analog::limit_amps(dac.current_limit()),
                encoder_count: node.encoder_position(ch)?,
                encoder_overflow: node.encoder_overflow(ch)?,
                encoder_position: f64::from(node.encoder_counts(ch)?) * f.encoder_per_count,
                encoder_velocity: node.encoder_velocity(ch)? * f.encoder_per_count,
                encoder_unit: f.encoder_unit.clone(),
                motor_current_api: current_api,
                motor_current_ma: 1e3 * analog::monitor_amps(current_api),
                pot_api,
                pot_volts,
                pot_position: f.pot_offset + f.pot_per_volt * pot_volts,
                pot_unit: f.pot_unit.clone(),
                speed_mode: outputs.speed_mode,
                wiper: wiper.value(),
                feedback_gain: wiper.feedback_gain(),
                write_protect: wp,
            });
        }
        Ok(NodeView {
            board: b,
            status: node.status().raw(),
            watchdog_timeout: node.status().watchdog_timeout(),
            timestamp_delta_ms: node.timestamp_seconds() * 1e3,
            channels,
        })
    }

    /// Save every channel of every node (EEPROM included) to `path`.
    ///
    /// # Errors
    /// Reading the nodes; writing the file.
    pub fn save(&mut self, path: &Path) -> Result<usize, CliError> {
        let mut channels = Vec::new();
        for b in self.boards() {
            for ch in 1..=CHANNELS as u8 {
                let mut st = self.read_channel_state(b, ch, true)?;
                if let Some(c) = self.commanded.get(&(b, ch)) {
                    st.factors = c.factors.clone();
                }
                channels.push(st);
            }
        }
        let n = channels.len();
        let file = StateFile {
            version: STATE_VERSION,
            channels,
        };
        let text = serde_json::to_string_pretty(&file)?;
        std::fs::write(path, text + "\n")?;
        Ok(n)
    }

    /// Load a state file and send it to the nodes.
    ///
    /// # Errors
    /// The file cannot be read or parsed, names another version or a node
    /// that is not there; sending failed.
    pub fn load(&mut self, path: &Path) -> Result<usize, CliError> {
        let text = std::fs::read_to_string(path)?;
        let file: StateFile =
            serde_json::from_str(&text).map_err(|e| bad(format!("{}: {e}", path.display())))?;
        if file.version != STATE_VERSION {
            return Err(bad(format!(
                "{}: state version {}, this tool reads {STATE_VERSION}",
                path.display(),
                file.version
            )));
        }
        for st in &file.channels {
            if self.system.node(st.board).is_none() {
                return Err(bad(format!(
                    "{}: board {} is not among the nodes {:?}",
                    path.display(),
                    st.board,
                    self.boards()
                )));
            }
            firelink_host::snake::channel(st.channel)?;
            Wiper::new(st.wiper).map_err(|e| bad(format!("{}: {e}", path.display())))?;
        }
        for st in &file.channels {
            self.apply_state(st)?;
        }
        Ok(file.channels.len())
    }

    /// Run a script: commands separated by `;` or new lines. Returns what
    /// they printed.
    ///
    /// # Errors
    /// The first command that failed, named with its position.
    pub fn run_script(&mut self, script: &str) -> Result<String, CliError> {
        let mut out = String::new();
        for (i, line) in script
            .split([';', '\n'])
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with('#'))
            .enumerate()
        {
            match self.command(line) {
                Ok(text) => out.push_str(&text),
                Err(e) => return Err(bad(format!("command {} ({line:?}): {e}", i + 1))),
            }
        }
        Ok(out)
    }

    /// Run one command; returns what it prints.
    ///
    /// # Errors
    /// A bad command or argument (named), or the node refused.
    pub fn command(&mut self, line: &str) -> Result<String, CliError> {
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
                    return Err(bad(format!("unknown command {verb:?} (try help)")));
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
    ) -> Result<Option<String>, CliError> {
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
                        return Err(bad(format!("switch: torque or speed, got {other:?}")));
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
    ) -> Result<String, CliError> {
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
    fn factors_command(&mut self, line: &str) -> Result<String, CliError> {
        let mut out = String::new();
        let (b, ch) = (self.board, self.channel);
        let mut f = self.factors(b, ch);
        for kv in line.split_whitespace().skip(1) {
            let (k, v) = kv
                .split_once('=')
                .ok_or_else(|| bad(format!("factors: {kv:?} is not key=value")))?;
            match k {
                "encoder" => f.encoder_per_count = parse_f64(Some(v), k, -1e9, 1e9)?,
                "encoder-unit" => f.encoder_unit = v.to_string(),
                "pot" => f.pot_per_volt = parse_f64(Some(v), k, -1e9, 1e9)?,
                "pot-offset" => f.pot_offset = parse_f64(Some(v), k, -1e9, 1e9)?,
                "pot-unit" => f.pot_unit = v.to_string(),
                _ => {
                    return Err(bad(format!(
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
    ) -> Result<Option<String>, CliError> {
        let mut out = String::new();
        let (b, ch) = (self.board, self.channel);
        match verb {
            "watchdog" => {
                let setting = WatchdogSetting::parse(arg.unwrap_or(""))
                    .map_err(|e| bad(format!("watchdog {}: {e}", arg.unwrap_or(""))))?;
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
                let path = arg.ok_or_else(|| bad("save: a file name is missing"))?;
                let n = self.save(Path::new(path))?;
                let _ = writeln!(out, "saved {n} channels to {path}");
            }
            "load" => {
                let path = arg.ok_or_else(|| bad("load: a file name is missing"))?;
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
