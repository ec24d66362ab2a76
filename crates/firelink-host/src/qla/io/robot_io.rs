//! The QLA boards' I/O system as the abstract robot I/O: [`RobotIo`] for
//! [`IoSystem`], each per-axis call answered from the board that holds
//! the axis (the Snake system's is in `crate::snake`).

use std::time::Duration;

use firelink_wire::qla::registers::WatchdogSetting;

use super::IoSystem;
use crate::cycle_report::{CycleReport, IoStats};
use crate::error::Result;
use crate::port::Port;
use crate::qla::board::BoardIo;
use crate::robot_io::{BoardStatus, RobotIo, bad_axis};

impl<P: Port> IoSystem<P> {
    /// (index in `boards()`, axis on it) of a flat axis number.
    fn locate(&self, axis: usize) -> Result<(usize, usize)> {
        self.axis_slot(axis).ok_or_else(|| bad_axis(axis))
    }

    fn board_at(&self, axis: usize) -> Result<(&BoardIo, usize)> {
        let (b, a) = self.locate(axis)?;
        let board = self.boards().get(b).ok_or_else(|| bad_axis(axis))?;
        Ok((board, a))
    }
}

impl<P: Port> RobotIo for IoSystem<P> {
    fn port_name(&self) -> &str {
        self.port().name()
    }

    fn now(&self) -> Duration {
        self.port().now()
    }

    fn wait(&mut self, duration: Duration) {
        self.port_mut().wait(duration);
    }

    fn boards(&self) -> u16 {
        IoSystem::boards(self)
            .iter()
            .fold(0, |m, b| m | (1 << (b.board_id() & 0xF)))
    }

    fn axis_count(&self) -> usize {
        IoSystem::boards(self).iter().map(|b| b.axes()).sum()
    }

    fn axis_index(&self, board_id: u8, axis: u8) -> Option<usize> {
        let mut base = 0;
        for b in IoSystem::boards(self) {
            if b.board_id() == board_id {
                return (usize::from(axis) < b.axes()).then_some(base + usize::from(axis));
            }
            base += b.axes();
        }
        None
    }

    fn axis_location(&self, axis: usize) -> Option<(u8, u8)> {
        let (b, a) = self.board_at(axis).ok()?;
        Some((b.board_id(), a as u8))
    }

    fn latch_all_inputs(&mut self) -> &CycleReport {
        self.read_all()
    }

    fn apply_all_outputs(&mut self) -> &CycleReport {
        self.write_all()
    }

    fn stats(&self) -> &IoStats {
        IoSystem::stats(self)
    }

    fn board_answered(&self, board_id: u8) -> bool {
        self.board(board_id).is_some_and(|b| b.is_valid())
    }

    fn powered(&self, board_id: u8) -> bool {
        self.board(board_id)
            .is_some_and(|b| b.is_valid() && b.power_enabled())
    }

    fn watchdog_expired(&self, board_id: u8) -> bool {
        self.board(board_id).is_some_and(|b| b.watchdog_expired())
    }

    fn timestamp(&self, board_id: u8) -> Option<u32> {
        self.board(board_id)
            .filter(|b| b.is_valid())
            .map(|b| b.timestamp())
    }

    fn set_power(&mut self, boards: u16, on: bool) {
        for b in self.boards_mut() {
            if boards & (1 << (b.board_id() & 0xF)) != 0 {
                b.set_power(on);
                b.set_relay(on);
            }
        }
    }

    fn set_watchdog(&mut self, setting: WatchdogSetting) -> Result<()> {
        IoSystem::set_watchdog(self, setting)
    }

    fn energised(&self) -> u16 {
        IoSystem::energised(self)
    }

    fn clear_energised(&mut self) {
        IoSystem::clear_energised(self);
    }

    fn watchdog_programmed(&self) -> Option<WatchdogSetting> {
        IoSystem::watchdog_programmed(self)
    }

    fn disable_amplifiers_acknowledged(&mut self, boards: u16) -> u16 {
        IoSystem::disable_amplifiers_acknowledged(self, boards)
    }

    fn recover(&mut self) -> Result<()> {
        IoSystem::recover(self).map(|_| ())
    }

    fn encoder_position(&self, axis: usize) -> Result<i32> {
        let (b, a) = self.board_at(axis)?;
        b.encoder_counts(a).ok_or_else(|| bad_axis(axis))
    }

    fn axis_inputs(&self, counts: &mut [i32], pots: &mut [Option<u16>]) {
        IoSystem::axis_inputs(self, counts, pots);
    }

    fn encoder_velocity(&self, axis: usize) -> Result<f64> {
        let (b, a) = self.board_at(axis)?;
        b.encoder_velocity(a).ok_or_else(|| bad_axis(axis))
    }

    fn analog_position(&self, axis: usize) -> Result<u16> {
        let (b, a) = self.board_at(axis)?;
        b.pot_bits(a).ok_or_else(|| bad_axis(axis))
    }

    fn motor_current(&self, axis: usize) -> Result<u16> {
        let (b, a) = self.board_at(axis)?;
        b.current_bits(a).ok_or_else(|| bad_axis(axis))
    }

    fn amplifier_enabled(&self, axis: usize) -> Result<bool> {
        let (b, a) = self.board_at(axis)?;
        Ok(b.is_valid() && b.amp_enabled(a))
    }

    #[inline]
    fn board_status(&self, board_id: u8) -> BoardStatus {
        // One look-up for all (the per-call methods each find the board).
        let Some(b) = self.board(board_id) else {
            return BoardStatus::default();
        };
        let answered = b.is_valid();
        BoardStatus {
            answered,
            powered: answered && b.power_enabled(),
            watchdog_expired: b.watchdog_expired(),
            timestamp: answered.then(|| b.timestamp()),
            amplifiers: if answered { b.amp_mask() } else { 0 },
        }
    }

    fn set_motor_command(&mut self, axis: usize, code: u16) -> Result<()> {
        let (b, a) = self.locate(axis)?;
        let board = self.boards_mut().get_mut(b).ok_or_else(|| bad_axis(axis))?;
        board.set_dac(a, code)
    }

    fn set_motor_commands(&mut self, codes: &[Option<u16>]) {
        IoSystem::set_motor_commands(self, codes);
    }

    fn set_amplifier_enable(&mut self, axis: usize, on: bool) -> Result<()> {
        let (b, a) = self.locate(axis)?;
        let board = self.boards_mut().get_mut(b).ok_or_else(|| bad_axis(axis))?;
        board.set_amp_enable(a, on)
    }

    fn set_all_safe(&mut self) {
        for b in self.boards_mut() {
            b.safe_outputs();
        }
    }
}
