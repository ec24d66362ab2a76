//! The digital outputs (`fpga-board-extras.md` §3): register 6, DOUT_CTRL
//! per output (PWM and one-shot timers) and the 1024-entry waveform table
//! with its playback.
//!
//! Everything is kept raw, exactly as written: the pins invert it, the
//! host complements on write and on read. The state is a pure function of
//! time between writes (a PWM output toggles, a table plays), so reads
//! compute it at `now` and every write first settles it to `now`; nothing
//! needs a timer.

use firelink_wire::qla::registers::{DigitalOutRead, DigitalOutWrite, DoutCtrl, WaveformEntry};

use crate::time::SimTime;

/// Digital outputs of a QLA.
pub const OUTPUTS: usize = 4;
/// Entries of the waveform table (space 8, address bits 9:0).
pub const WAVEFORM_ENTRIES: usize = 1024;

/// One output: its stored value, since when, and its timer setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Output {
    raw: bool,
    /// Clock count at which `raw` was taken (write or toggle).
    since: u64,
    ctrl: DoutCtrl,
}

impl Output {
    /// Clocks the output holds `level` before it toggles; `None`: forever.
    /// The firmware toggles when its counter exceeds the time.
    fn hold(&self, level: bool) -> Option<u64> {
        let t = if level {
            self.ctrl.high_time()
        } else {
            self.ctrl.low_time()
        };
        (t != 0).then(|| u64::from(t) + 1)
    }

    /// The stored value and when it was taken, at clock `now`.
    fn at(&self, now: u64) -> (bool, u64) {
        let (mut level, mut since) = (self.raw, self.since);
        let Some(first) = self.hold(level) else {
            return (level, since);
        };
        if now < since + first {
            return (level, since);
        }
        level = !level;
        since += first;
        let Some(second) = self.hold(level) else {
            return (level, since); // one-shot: toggled once, stays
        };
        // PWM from here on: skip whole periods, then at most one toggle.
        let period = first + second;
        since += (now - since) / period * period;
        if now >= since + second {
            level = !level;
            since += second;
        }
        (level, since)
    }

    fn settle(&mut self, now: u64) {
        (self.raw, self.since) = self.at(now);
    }
}

/// Waveform playback in progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Playback {
    /// Outputs the table drives.
    mask: u8,
    /// Current entry.
    index: u16,
    /// Clock count at which it started.
    started: u64,
}

/// Where playback stands at some moment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct PlayState {
    playback: Option<Playback>,
    /// Index of the current (or, stopped, the last) entry.
    index: u16,
}

/// Register 6, the four DOUT_CTRL registers and the waveform table.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct DigitalOutputs {
    outputs: [Output; OUTPUTS],
    table: Vec<u32>,
    playback: Option<Playback>,
    /// The entry playback stopped at (register 6 bits 25:16 once stopped).
    last_index: u16,
}

impl DigitalOutputs {
    /// Power-up: outputs raw 0, timers off, table zero, nothing playing.
    pub fn new() -> DigitalOutputs {
        DigitalOutputs {
            outputs: [Output::default(); OUTPUTS],
            table: vec![0; WAVEFORM_ENTRIES],
            playback: None,
            last_index: 0,
        }
    }

    fn entry(&self, index: u16) -> WaveformEntry {
        WaveformEntry(
            self.table
                .get(usize::from(index) % WAVEFORM_ENTRIES)
                .copied()
                .unwrap_or(0),
        )
    }

    /// Playback as it stands at clock `now`: entries advance after their
    /// time; the first invalid entry stops playback.
    fn play_state(&self, now: u64) -> PlayState {
        let Some(mut p) = self.playback else {
            return PlayState {
                playback: None,
                index: self.last_index,
            };
        };
        // A table of only valid entries plays for ever: skip whole rounds.
        let mut steps = 0usize;
        loop {
            let e = self.entry(p.index);
            if !e.valid() {
                return PlayState {
                    playback: None,
                    index: p.index,
                };
            }
            let end = p.started + e.clocks();
            if now < end {
                return PlayState {
                    playback: Some(p),
                    index: p.index,
                };
            }
            p.started = end;
            p.index = (p.index + 1) % WAVEFORM_ENTRIES as u16;
            steps += 1;
            if steps == WAVEFORM_ENTRIES && p.index == 0 {
                let round: u64 = (0..WAVEFORM_ENTRIES as u16)
                    .map(|i| self.entry(i).clocks())
                    .sum();
                p.started += (now - p.started) / round * round;
            }
        }
    }

    /// Bring the stored state to clock `now` (before any change).
    fn settle(&mut self, now: u64) {
        for o in &mut self.outputs {
            o.settle(now);
        }
        let s = self.play_state(now);
        self.playback = s.playback;
        self.last_index = s.index;
    }

    /// The raw outputs at `now` (bit i = DOUT i+1): the table's values on
    /// the outputs it drives, the stored (timed) values elsewhere.
    pub fn raw_outputs(&self, now: SimTime) -> u8 {
        let now = now.clocks();
        let play = self.play_state(now);
        let table = play
            .playback
            .map(|p| (p.mask, self.entry(p.index).outputs()));
        (0..OUTPUTS).fold(0u8, |acc, i| {
            let bit = 1u8 << i;
            let on = match table {
                Some((mask, values)) if mask & bit != 0 => values & bit != 0,
                _ => self.outputs.get(i).is_some_and(|o| o.at(now).0),
            };
            acc | (u8::from(on) << i)
        })
    }

    /// Whether the table drives any output at `now` (register 6 bit 31,
    /// DIGIN bit 29).
    pub fn table_active(&self, now: SimTime) -> bool {
        self.play_state(now.clocks()).playback.is_some()
    }

    /// Register 6 as read at `now`.
    pub fn read(&self, now: SimTime) -> DigitalOutRead {
        let play = self.play_state(now.clocks());
        let active = play.playback.is_some();
        DigitalOutRead::default()
            .with_table_active(active)
            .with_table_valid(active && self.entry(play.index).valid())
            .with_table_index(play.index)
            .with_outputs(self.raw_outputs(now))
    }

    /// A register-6 write at `now`: the masked outputs take their raw
    /// values (restarting their timers); the table restarts at index 0 on
    /// the masked outputs (bit 31) or stops on all of them.
    pub fn write(&mut self, now: SimTime, w: DigitalOutWrite) {
        let now = now.clocks();
        self.settle(now);
        for (i, o) in self.outputs.iter_mut().enumerate() {
            if w.mask & (1 << i) != 0 {
                o.raw = w.raw & (1 << i) != 0;
                o.since = now;
            }
        }
        self.playback = w.play_waveform.then_some(Playback {
            mask: w.mask,
            index: 0,
            started: now,
        });
        self.last_index = 0;
    }

    /// DOUT_CTRL of output `i` (0-based) as read back.
    pub fn ctrl(&self, i: usize) -> Option<DoutCtrl> {
        self.outputs.get(i).map(|o| o.ctrl)
    }

    /// Write DOUT_CTRL of output `i` at `now` (the output's timer restarts).
    pub fn write_ctrl(&mut self, now: SimTime, i: usize, ctrl: DoutCtrl) {
        let now = now.clocks();
        self.settle(now);
        if let Some(o) = self.outputs.get_mut(i) {
            o.ctrl = ctrl;
            o.since = now;
        }
    }

    /// Space 8 read of entry `index` (bits 9:0) at `now`: while the table
    /// plays, the current playback entry whatever the address.
    pub fn read_table(&self, now: SimTime, index: u16) -> u32 {
        let play = self.play_state(now.clocks());
        let at = if play.playback.is_some() {
            play.index
        } else {
            index
        };
        self.entry(at).raw()
    }

    /// Space 8 write of entry `index` (bits 9:0) at `now`.
    pub fn write_table(&mut self, now: SimTime, index: u16, value: u32) {
        self.settle(now.clocks());
        if let Some(e) = self.table.get_mut(usize::from(index) % WAVEFORM_ENTRIES) {
            *e = value;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time::SimDuration;

    fn at_clocks(c: u64) -> SimTime {
        SimTime::from_clocks(c)
    }

    #[test]
    fn stored_raw_as_written() {
        let mut d = DigitalOutputs::new();
        d.write(SimTime::ZERO, DigitalOutWrite::parse(0x0F0E));
        assert_eq!(d.raw_outputs(SimTime::from_micros(1)), 0xE);
        assert_eq!(d.read(SimTime::from_micros(1)).raw(), 0xE);
        // Only masked outputs change.
        d.write(SimTime::from_micros(2), DigitalOutWrite::parse(0x0101));
        assert_eq!(d.raw_outputs(SimTime::from_micros(3)), 0xF);
    }

    #[test]
    fn pwm_and_one_shot() {
        let mut d = DigitalOutputs::new();
        // Output 1: raw 1 for 10 clocks (+1), raw 0 for 20 (+1).
        d.write_ctrl(
            SimTime::ZERO,
            0,
            DoutCtrl::default().with_high_time(10).with_low_time(20),
        );
        d.write(SimTime::ZERO, DigitalOutWrite::parse(0x0101));
        let t0 = SimTime::ZERO.clocks();
        let level = |d: &DigitalOutputs, c: u64| d.raw_outputs(at_clocks(t0 + c)) & 1;
        assert_eq!(level(&d, 0), 1);
        assert_eq!(level(&d, 10), 1);
        assert_eq!(level(&d, 11), 0);
        assert_eq!(level(&d, 31), 0);
        assert_eq!(level(&d, 32), 1);
        // Far ahead: whole periods skipped, phase kept.
        assert_eq!(level(&d, 32 * 1_000_000 + 5), 1);
        assert_eq!(level(&d, 32 * 1_000_000 + 11), 0);
        // One-shot on output 2: raw 0 stays 100 (+1) clocks, then 1 for ever.
        d.write_ctrl(SimTime::ZERO, 1, DoutCtrl::default().with_low_time(100));
        d.write(SimTime::ZERO, DigitalOutWrite::parse(0x0200));
        let level2 = |d: &DigitalOutputs, c: u64| (d.raw_outputs(at_clocks(c)) >> 1) & 1;
        assert_eq!(level2(&d, 100), 0);
        assert_eq!(level2(&d, 101), 1);
        assert_eq!(level2(&d, 10_000_000), 1);
        assert_eq!(d.ctrl(1), Some(DoutCtrl(100)));
    }

    #[test]
    fn waveform_plays_and_stops() {
        let mut d = DigitalOutputs::new();
        // fpgatest 'w': entries 0x80C0000x (0xC000 + 1 clocks each, ~1 ms).
        for i in 0..4u16 {
            d.write_table(SimTime::ZERO, i, 0x80C0_0000 | u32::from(i));
        }
        d.write_table(SimTime::ZERO, 4, 0);
        // Stopped: space 8 reads the addressed entry.
        assert_eq!(d.read_table(SimTime::ZERO, 2), 0x80C0_0002);
        let start = SimTime::from_micros(10);
        d.write(start, DigitalOutWrite::waveform(0x3, 0x3));
        assert!(d.table_active(start));
        let entry = SimDuration::from_clocks(0xC001);
        let mid = |k: u64| start + SimDuration(entry.0 * k + entry.0 / 2);
        for k in 0..4u64 {
            let r = d.read(mid(k));
            assert!(r.table_active() && r.table_valid());
            assert_eq!(u64::from(r.table_index()), k);
            // Outputs 1-2 follow the table; 3-4 keep their stored 0.
            assert_eq!(r.outputs(), (k as u8) & 0x3);
            // Reading space 8 while playing gives the current entry.
            assert_eq!(d.read_table(mid(k), 100), 0x80C0_0000 | k as u32);
        }
        // After entry 3: entry 4 is invalid, playback stops, outputs are
        // released to the values written with the start (raw 0).
        let r = d.read(mid(5));
        assert!(!r.table_active());
        assert_eq!(r.table_index(), 4);
        assert_eq!(r.outputs(), 0);
        assert_eq!(d.read_table(mid(5), 1), 0x80C0_0001);
        // A write without bit 31 stops playback at once.
        d.write(mid(6), DigitalOutWrite::waveform(0x3, 0x3));
        d.write(
            mid(6) + SimDuration::from_micros(1),
            DigitalOutWrite::levels(0, 0),
        );
        assert!(!d.table_active(mid(7)));
    }

    #[test]
    fn a_table_of_valid_entries_plays_for_ever() {
        let mut d = DigitalOutputs::new();
        for i in 0..WAVEFORM_ENTRIES as u16 {
            d.write_table(SimTime::ZERO, i, 0x8000_0000 | u32::from(i & 1));
        }
        d.write(SimTime::ZERO, DigitalOutWrite::waveform(0x1, 0));
        // One clock per entry: after 10 rounds + 3 clocks, entry 3.
        let t = at_clocks(SimTime::ZERO.clocks() + 10 * 1024 + 3);
        assert_eq!(d.read(t).table_index(), 3);
        assert_eq!(d.raw_outputs(t) & 1, 1);
        let far = SimTime::from_millis(60_000);
        assert!(d.table_active(far));
    }
}
