//! The watchdog proof: stop the host at random moments and show that every
//! board turns its amplifiers off within the watchdog period plus one
//! watchdog tick of the last write it received, every time.
//!
//! The robot (the dVRK of seed 000 on its 8 boards) runs Active; at a
//! seeded random instant (a random number of cycles plus a random fraction
//! of a period) the host stops. The bus runs on alone and each board's
//! amplifiers are watched event by event: the instant the last one goes
//! off is compared with the instant that board last heard from the host.
//! The robot is then re-armed (it finds the watchdog fault itself) and the
//! next trial starts.

use std::time::Duration;

use firelink_board::qla::node::BoardNode;
use firelink_bus::{NodeHandle, SimDuration, SimTime};
use firelink_control::config::presets;
use firelink_control::runner::{Pacing, Robot};
use firelink_control::{ServoPeriod, State};
use firelink_host::qla::io::IoSystem;
use firelink_host::sim::SimPort;
use firelink_wire::qla::registers::Watchdog;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::TestbedError;
use crate::dvrk::soak::{RunningRobot, SoakSettings, bring_up_robot};

/// The result (`firelink soak --watchdog-trials N`).
#[derive(Debug, Clone, Serialize)]
pub struct WatchdogReport {
    /// Host stops tried.
    pub trials: u64,
    /// Board observations (trials x boards).
    pub observations: u64,
    /// The watchdog period, us.
    pub period_us: f64,
    /// The servo period the robot ran at, us (the soak's `--period`; in
    /// the JSON as the soak's `period_us`, so not repeated here).
    #[serde(skip)]
    pub servo_period_us: f64,
    /// One watchdog tick (256 clocks of 49.152 MHz), us.
    pub tick_us: f64,
    /// Observations where a board's amplifiers were off within period +
    /// one tick of its last write.
    pub within_bound: u64,
    /// Latest amplifier-off instant after the board's last write, minus
    /// the period, us: minimum, median, 99th percentile, maximum.
    pub over_period_us: [f64; 4],
    /// The same, from the instant the host stopped, us (what an operator
    /// sees): minimum, median, 99th percentile, maximum.
    pub after_stop_us: [f64; 4],
}

impl WatchdogReport {
    /// Whether every observation was within the bound.
    pub fn passed(&self) -> bool {
        self.observations > 0 && self.within_bound == self.observations
    }
}

fn quantiles(v: &mut [f64]) -> [f64; 4] {
    if v.is_empty() {
        return [0.0; 4];
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    [at(0.0), at(0.5), at(0.99), at(1.0)]
}

/// Run `trials` host stops, seeded by `seed`, the robot's servo loop at
/// `period` (the soak's).
///
/// # Errors
/// The robot could not be brought up.
pub fn run(trials: u64, seed: u64, period: ServoPeriod) -> Result<WatchdogReport, TestbedError> {
    let settings = SoakSettings {
        seed,
        period,
        ..SoakSettings::default()
    };
    let config = presets::dvrk_seed000();
    let RunningRobot {
        mut robot, boards, ..
    } = bring_up_robot(&config, &settings)?;
    let period = Watchdog::from_period(Duration::from_millis(20))
        .map_err(|e| TestbedError::Config(e.to_string()))?
        .period();
    let tick = Watchdog(1).period();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0057_A7C4);
    let cycle = SimDuration::from_micros_f64(settings.period.as_micros_f64());
    let mut over = Vec::new();
    let mut after_stop = Vec::new();
    let mut within = 0u64;
    for _ in 0..trials {
        // Run Active for a while, then stop at a random instant within a
        // period (the host may die between cycles or inside one's wait).
        let run_for = rng.random_range(1..200u32);
        for _ in 0..run_for {
            let _ = robot.step(Pacing::Virtual);
        }
        let offset = SimDuration::from_micros_f64(cycle.as_micros_f64() * rng.random::<f64>());
        let port = robot.io_mut().port_mut();
        port.bus_mut().run_for(offset);
        let stopped = port.bus().now();
        let off = amplifiers_off(port, &boards, stopped + SimDuration::from_millis(100));
        for (handle, off_at) in boards.iter().zip(off) {
            let last = port
                .bus()
                .node::<BoardNode>(*handle)
                .map_or(SimTime::ZERO, |b| b.firmware().last_host_write());
            let Some(off_at) = off_at else {
                continue; // never went off: not within the bound
            };
            let since_write = Duration::from_nanos(off_at.0.saturating_sub(last.0) / 1000);
            over.push((since_write.as_secs_f64() - period.as_secs_f64()) * 1e6);
            after_stop.push((off_at.0.saturating_sub(stopped.0)) as f64 / 1e6);
            if since_write <= period + tick {
                within += 1;
            }
        }
        rearm(&mut robot);
    }
    Ok(WatchdogReport {
        trials,
        observations: trials * boards.len() as u64,
        period_us: period.as_secs_f64() * 1e6,
        servo_period_us: settings.period.as_micros_f64(),
        tick_us: tick.as_secs_f64() * 1e6,
        within_bound: within,
        over_period_us: quantiles(&mut over),
        after_stop_us: quantiles(&mut after_stop),
    })
}

/// Run the bus alone until every board's amplifiers are off (or
/// `deadline`): when each board's last amplifier went off.
fn amplifiers_off(
    port: &mut SimPort,
    boards: &[NodeHandle],
    deadline: SimTime,
) -> Vec<Option<SimTime>> {
    let mut off: Vec<Option<SimTime>> = vec![None; boards.len()];
    let bus = port.bus_mut();
    let check = |bus: &firelink_bus::Bus, off: &mut Vec<Option<SimTime>>| {
        for (slot, handle) in off.iter_mut().zip(boards) {
            if slot.is_some() {
                continue;
            }
            let any_on = bus
                .node::<BoardNode>(*handle)
                .is_some_and(|b| (0..4).any(|a| b.firmware().amplifier_on(a)));
            if !any_on {
                *slot = Some(bus.now());
            }
        }
        off.iter().all(Option::is_some)
    };
    if !check(bus, &mut off) {
        bus.run_until_with(deadline, |bus| check(bus, &mut off));
    }
    off
}

/// The robot finds the watchdog fault on its next cycle; bring it back.
fn rearm(robot: &mut Robot<IoSystem<SimPort>>) {
    for _ in 0..4 {
        let _ = robot.step(Pacing::Virtual);
        if robot.state() == State::Fault {
            break;
        }
    }
    for _ in 0..20 {
        if robot.state() == State::Fault {
            let _ = robot.clear_fault();
        }
        let _ = robot.io_mut().recover();
        if robot.state() == State::Unconfigured && robot.configure().is_err() {
            let _ = robot.step(Pacing::Virtual);
            continue;
        }
        if robot.state() == State::Configured
            && robot.power_on().is_ok()
            && robot.activate().is_ok()
        {
            return;
        }
        let _ = robot.step(Pacing::Virtual);
    }
}
