//! The session: the nodes, the selection, what the tool commanded, and
//! the state file.

use std::collections::BTreeMap;
use std::path::Path;

use firelink_control::config::IoConfig;
use firelink_host::Port;
use firelink_host::snake::SnakeSystem;
use firelink_wire::snake::analog;
use firelink_wire::snake::registers::{PotOutputs, PowerControl, Wiper, adc_api_to_volts};
use firelink_wire::snake::{CHANNELS, EEPROM_WORDS};

use super::error::{ToolError, refused};
use super::state::{ChannelState, Factors, STATE_VERSION, StateFile};
use super::view::{ChannelView, NodeView};

/// A session with the nodes.
pub struct Session<P: Port> {
    pub(super) system: SnakeSystem<P>,
    pub(super) board: u8,
    pub(super) channel: u8,
    pub(super) commanded: BTreeMap<(u8, u8), ChannelState>,
    pub(super) config: Option<IoConfig>,
}

impl<P: Port> Session<P> {
    /// A session on `system`; `config` (if any) gives the conversion
    /// factors of the channels it maps.
    ///
    /// # Errors
    /// Reading a node failed.
    pub fn new(system: SnakeSystem<P>, config: Option<IoConfig>) -> Result<Session<P>, ToolError> {
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
    pub fn finish(&mut self) -> Result<Vec<u8>, ToolError> {
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
    pub fn select_board(&mut self, board: u8) -> Result<(), ToolError> {
        if self.system.node(board).is_none() {
            return Err(refused(format!(
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
    pub fn select_channel(&mut self, channel: u8) -> Result<(), ToolError> {
        firelink_host::snake::channel(channel)?;
        self.channel = channel;
        Ok(())
    }

    pub(super) fn factors(&self, board: u8, channel: u8) -> Factors {
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
    pub(super) fn state_mut(&mut self) -> Result<&mut ChannelState, ToolError> {
        let key = (self.board, self.channel);
        if !self.commanded.contains_key(&key) {
            let s = self.read_channel_state(self.board, self.channel, false)?;
            self.commanded.insert(key, s);
        }
        self.commanded
            .get_mut(&key)
            .ok_or_else(|| refused("internal: channel state"))
    }

    /// A channel's state as the node holds it (with the EEPROM when
    /// `eeprom`).
    pub(super) fn read_channel_state(
        &mut self,
        board: u8,
        channel: u8,
        eeprom: bool,
    ) -> Result<ChannelState, ToolError> {
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
    pub(super) fn apply_state(&mut self, st: &ChannelState) -> Result<(), ToolError> {
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
                return Err(refused(format!(
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
            .ok_or_else(|| refused(format!("board {b}: no such node")))?;
        node.set_motor_voltage(ch, st.motor_code)?;
        node.set_amplifier_enable(ch, st.enabled)?;
        s.apply_all_outputs();
        self.commanded.insert((b, ch), st.clone());
        Ok(())
    }

    /// Send the selected channel's motor code and enable (the buffered
    /// outputs).
    pub(super) fn send_outputs(&mut self) -> Result<(), ToolError> {
        let (b, ch) = (self.board, self.channel);
        let st = self.state_mut()?.clone();
        let node = self
            .system
            .node_mut(b)
            .ok_or_else(|| refused(format!("board {b}: no such node")))?;
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
    pub fn view(&mut self) -> Result<NodeView, ToolError> {
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
            .ok_or_else(|| refused(format!("board {b}: no such node")))?;
        if !node.is_valid() {
            return Err(report.error.map_or_else(
                || refused(format!("board {b} did not answer the block read")),
                ToolError::from,
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
    pub fn save(&mut self, path: &Path) -> Result<usize, ToolError> {
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
    pub fn load(&mut self, path: &Path) -> Result<usize, ToolError> {
        let text = std::fs::read_to_string(path)?;
        let file: StateFile =
            serde_json::from_str(&text).map_err(|e| refused(format!("{}: {e}", path.display())))?;
        if file.version != STATE_VERSION {
            return Err(refused(format!(
                "{}: state version {}, this tool reads {STATE_VERSION}",
                path.display(),
                file.version
            )));
        }
        for st in &file.channels {
            if self.system.node(st.board).is_none() {
                return Err(refused(format!(
                    "{}: board {} is not among the nodes {:?}",
                    path.display(),
                    st.board,
                    self.boards()
                )));
            }
            firelink_host::snake::channel(st.channel)?;
            Wiper::new(st.wiper).map_err(|e| refused(format!("{}: {e}", path.display())))?;
        }
        for st in &file.channels {
            self.apply_state(st)?;
        }
        Ok(file.channels.len())
    }
}
