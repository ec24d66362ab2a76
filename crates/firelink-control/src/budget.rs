//! Does one servo cycle fit in its period? The time budget of seed 002
//! (Table I and inequality (1)) and a general check over protocol cost
//! models.
//!
//! Seed 002 (MAHRU humanoid, 14 modules on IEEE 1394) writes the budget of
//! a period `P` as
//!
//! ```text
//! t(Te) + t(Tf) + t(Tg) + 2 t(Ts) < P                                    (1)
//! Te = (Nm + Ns) x t(PRB) + 2 t(Ts)     read all modules   (Table I)
//! Tf = compute
//! Tg = t(BWB) + t(Ts)                   broadcast the new set-points
//! ```
//!
//! **Note on the paper's example.** Its text computes `t(Te)` as
//! `14 x 75 us = 1050 us` (Xenomai) and `14 x 70 us = 980 us` (RTLinux) and
//! takes `t(Tg)` as the measured worst case, 50 us and 40 us; with
//! `t(Tf) = 500 us` and `t(Ts) = 20 us`, (1) then gives the printed
//! **1.64 ms** and **1.56 ms**. Applying Table I's formulas literally adds the
//! slack terms inside `Te` (2 x 20 us) and `Tg` (20 us), giving 1.70 ms and
//! 1.62 ms. Both fit in 2 ms. [`CycleBudget`] takes the four terms as given (the
//! paper's arithmetic); [`TableI`] applies the formulas. The tests reproduce
//! both.
//!
//! [`CycleModel`] generalises this to the protocols of seeds 000 and 001:
//! sequential per-board read and write, sequential reads with one broadcast
//! write (seed 002), and seed 000's broadcast query / hub read / broadcast
//! write. Everything is `Duration` arithmetic (whole nanoseconds), so the
//! results are exact and deterministic.

use core::fmt;
use core::time::Duration;

/// The four terms of inequality (1), taken as given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CycleBudget {
    /// `t(Te)`: reading every module.
    pub t_e: Duration,
    /// `t(Tf)`: computing the new set-points.
    pub t_f: Duration,
    /// `t(Tg)`: sending them.
    pub t_g: Duration,
    /// `t(Ts)`: slack between two consecutive events (counted twice).
    pub t_s: Duration,
}

impl CycleBudget {
    /// `t(Te) + t(Tf) + t(Tg) + 2 t(Ts)` (saturating).
    pub fn total(&self) -> Duration {
        self.t_e
            .saturating_add(self.t_f)
            .saturating_add(self.t_g)
            .saturating_add(self.t_s.saturating_mul(2))
    }

    /// Inequality (1) against `period`.
    pub fn check(&self, period: Duration) -> BudgetReport {
        BudgetReport {
            io: self.t_e.saturating_add(self.t_g),
            compute: self.t_f,
            slack: self.t_s.saturating_mul(2),
            total: self.total(),
            period,
        }
    }
}

/// Table I of seed 002, with its formulas applied literally.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TableI {
    /// `Nm`: motor-controller modules.
    pub motor_controllers: u32,
    /// `Ns`: sensor modules.
    pub sensor_modules: u32,
    /// `t(PRB)`: one peer-to-peer block read (worst case).
    pub t_prb: Duration,
    /// `t(Tf)`: computation.
    pub t_f: Duration,
    /// `t(BWB)`: one broadcast block write.
    pub t_bwb: Duration,
    /// `t(Ts)`: slack between events.
    pub t_s: Duration,
}

impl TableI {
    /// `Te = (Nm + Ns) x t(PRB) + 2 t(Ts)`.
    pub fn t_e(&self) -> Duration {
        self.t_prb
            .saturating_mul(self.motor_controllers.saturating_add(self.sensor_modules))
            .saturating_add(self.t_s.saturating_mul(2))
    }

    /// `Tg = t(BWB) + t(Ts)`.
    pub fn t_g(&self) -> Duration {
        self.t_bwb.saturating_add(self.t_s)
    }

    /// The four terms of (1).
    pub fn budget(&self) -> CycleBudget {
        CycleBudget {
            t_e: self.t_e(),
            t_f: self.t_f,
            t_g: self.t_g(),
            t_s: self.t_s,
        }
    }
}

/// How long one cycle's I/O takes under a protocol, from per-transaction
/// costs measured or modelled elsewhere.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IoCost {
    /// One block read and one block write per board (seed 000's baseline,
    /// seed 001): `(read + write) x boards`.
    Sequential {
        /// Boards on the bus.
        boards: u32,
        /// One block read.
        read: Duration,
        /// One block write.
        write: Duration,
    },
    /// One block read per board, then one broadcast write of every command
    /// (seed 002): `read x boards + broadcast_write`.
    SequentialReadBroadcastWrite {
        /// Boards (modules) on the bus.
        boards: u32,
        /// One block read.
        read: Duration,
        /// The broadcast block write.
        broadcast_write: Duration,
    },
    /// Seed 000's broadcast protocol: `query + slot x boards + hub_read +
    /// broadcast_write`.
    Broadcast {
        /// Boards on the bus.
        boards: u32,
        /// The broadcast query (quadlet write).
        query: Duration,
        /// The wait per board while boards broadcast their state (TDMA slot
        /// or chained transmission; seed 000: ~5 us).
        slot_per_board: Duration,
        /// The block read of the hub.
        hub_read: Duration,
        /// The broadcast block write of all commands.
        broadcast_write: Duration,
    },
}

impl IoCost {
    /// Number of boards in the model.
    pub fn boards(&self) -> u32 {
        match *self {
            IoCost::Sequential { boards, .. }
            | IoCost::SequentialReadBroadcastWrite { boards, .. }
            | IoCost::Broadcast { boards, .. } => boards,
        }
    }

    /// The same model with `n` boards.
    #[must_use]
    pub fn with_boards(mut self, n: u32) -> IoCost {
        match &mut self {
            IoCost::Sequential { boards, .. }
            | IoCost::SequentialReadBroadcastWrite { boards, .. }
            | IoCost::Broadcast { boards, .. } => *boards = n,
        }
        self
    }

    /// The I/O time of one cycle (saturating).
    pub fn io_time(&self) -> Duration {
        match *self {
            IoCost::Sequential {
                boards,
                read,
                write,
            } => read.saturating_add(write).saturating_mul(boards),
            IoCost::SequentialReadBroadcastWrite {
                boards,
                read,
                broadcast_write,
            } => read.saturating_mul(boards).saturating_add(broadcast_write),
            IoCost::Broadcast {
                boards,
                query,
                slot_per_board,
                hub_read,
                broadcast_write,
            } => query
                .saturating_add(slot_per_board.saturating_mul(boards))
                .saturating_add(hub_read)
                .saturating_add(broadcast_write),
        }
    }
}

/// A whole cycle: I/O, computation and slack.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CycleModel {
    /// The protocol's I/O cost.
    pub io: IoCost,
    /// Computation per cycle (all servo loops).
    pub compute: Duration,
    /// Slack per gap between events (seed 002's `t(Ts)`).
    pub slack: Duration,
    /// How many such gaps a cycle has (seed 002's inequality (1): 2).
    pub slack_events: u32,
}

impl CycleModel {
    /// The cycle's breakdown against `period`.
    pub fn check(&self, period: Duration) -> BudgetReport {
        let io = self.io.io_time();
        let slack = self.slack.saturating_mul(self.slack_events);
        BudgetReport {
            io,
            compute: self.compute,
            slack,
            total: io.saturating_add(self.compute).saturating_add(slack),
            period,
        }
    }

    /// The largest number of boards, up to `limit`, for which the cycle
    /// still fits in `period` (0 if not even one fits).
    pub fn max_boards(&self, period: Duration, limit: u32) -> u32 {
        // The cost grows with the board count, so the first failure ends it.
        (1..=limit)
            .take_while(|&n| {
                CycleModel {
                    io: self.io.with_boards(n),
                    ..*self
                }
                .check(period)
                .fits()
            })
            .last()
            .unwrap_or(0)
    }
}

/// The outcome of a budget check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BudgetReport {
    /// I/O time.
    pub io: Duration,
    /// Computation time.
    pub compute: Duration,
    /// Slack time.
    pub slack: Duration,
    /// Everything.
    pub total: Duration,
    /// The period it must fit in.
    pub period: Duration,
}

impl BudgetReport {
    /// Whether the cycle fits: `total < period` (strict, as in (1)).
    pub fn fits(&self) -> bool {
        self.total < self.period
    }

    /// `Ok(spare time)` if it fits, `Err(overrun)` if not (an overrun of zero
    /// means `total == period`, which does not fit).
    pub fn headroom(&self) -> Result<Duration, Duration> {
        if self.fits() {
            Ok(self.period - self.total)
        } else {
            Err(self.total - self.period)
        }
    }

    /// Signed margin in microseconds: positive spare, negative overrun.
    pub fn margin_us(&self) -> f64 {
        match self.headroom() {
            Ok(d) => d.as_secs_f64() * 1e6,
            Err(d) => -d.as_secs_f64() * 1e6,
        }
    }

    /// `total / period` (infinite for a zero period).
    pub fn utilisation(&self) -> f64 {
        if self.period.is_zero() {
            f64::INFINITY
        } else {
            self.total.as_secs_f64() / self.period.as_secs_f64()
        }
    }

    /// The highest cycle rate at which this cycle would fit, Hz (the
    /// reciprocal of the total; infinite for a zero total).
    pub fn max_rate_hz(&self) -> f64 {
        if self.total.is_zero() {
            f64::INFINITY
        } else {
            1.0 / self.total.as_secs_f64()
        }
    }
}

impl fmt::Display for BudgetReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let us = |d: Duration| d.as_secs_f64() * 1e6;
        write!(
            f,
            "io {:.1} us + compute {:.1} us + slack {:.1} us = {:.1} us of {:.1} us: ",
            us(self.io),
            us(self.compute),
            us(self.slack),
            us(self.total),
            us(self.period)
        )?;
        match self.headroom() {
            Ok(spare) => write!(
                f,
                "fits, {:.1} us spare ({:.1}% used)",
                us(spare),
                100.0 * self.utilisation()
            ),
            Err(over) => write!(f, "does NOT fit, {:.1} us over", us(over)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn us(n: u64) -> Duration {
        Duration::from_micros(n)
    }

    const P: Duration = Duration::from_millis(2);

    #[test]
    fn seed_002_example_as_printed() {
        // Seed 002, section 4: 14 modules, t(PRB) for 32 B = 75 us (Xenomai)
        // / 70 us (RTLinux), t(Tg) 50 / 40 us, t(Tf) 500 us, t(Ts) 20 us.
        let xenomai = CycleBudget {
            t_e: us(14 * 75),
            t_f: us(500),
            t_g: us(50),
            t_s: us(20),
        };
        let rtlinux = CycleBudget {
            t_e: us(14 * 70),
            t_g: us(40),
            ..xenomai
        };
        assert_eq!(xenomai.total(), us(1640));
        assert_eq!(rtlinux.total(), us(1560));
        let r = xenomai.check(P);
        assert!(r.fits());
        assert_eq!(r.headroom(), Ok(us(360)));
        assert_eq!(rtlinux.check(P).headroom(), Ok(us(440)));
        // The same through the general model: 14 reads + one broadcast write,
        // 500 us compute, two 20 us slacks.
        let model = CycleModel {
            io: IoCost::SequentialReadBroadcastWrite {
                boards: 14,
                read: us(75),
                broadcast_write: us(50),
            },
            compute: us(500),
            slack: us(20),
            slack_events: 2,
        };
        assert_eq!(model.check(P).total, us(1640));
        assert_eq!(model.check(P), r);
    }

    #[test]
    fn seed_002_table_i_literally() {
        // 10 motor controllers + 4 force/torque sensors.
        let xenomai = TableI {
            motor_controllers: 10,
            sensor_modules: 4,
            t_prb: us(75),
            t_f: us(500),
            t_bwb: us(50),
            t_s: us(20),
        };
        let rtlinux = TableI {
            t_prb: us(70),
            t_bwb: us(40),
            ..xenomai
        };
        assert_eq!(xenomai.t_e(), us(1090));
        assert_eq!(xenomai.t_g(), us(70));
        assert_eq!(xenomai.budget().total(), us(1700));
        assert_eq!(rtlinux.budget().total(), us(1620));
        assert!(xenomai.budget().check(P).fits());
        assert!(rtlinux.budget().check(P).fits());
        // How many modules would fit at 2 ms (Xenomai, literal Table I)?
        // 500 + 50 + 20 + 40 + 40 = 650 fixed; (2000 - 650) / 75 = 18 => 17
        // modules (18 gives exactly 2000, not < 2000).
        let model = CycleModel {
            io: IoCost::SequentialReadBroadcastWrite {
                boards: 14,
                read: us(75),
                broadcast_write: us(70),
            },
            compute: us(500),
            slack: us(20),
            slack_events: 4,
        };
        assert_eq!(model.check(P).total, us(1700));
        assert_eq!(model.max_boards(P, 64), 17);
    }

    #[test]
    fn seed_000_protocols() {
        // Baseline: (32 + 34) us per board, 8 boards = 528 us.
        let seq = CycleModel {
            io: IoCost::Sequential {
                boards: 8,
                read: us(32),
                write: us(34),
            },
            compute: us(40),
            slack: Duration::ZERO,
            slack_events: 0,
        };
        let r = seq.check(Duration::from_millis(1));
        assert_eq!(r.io, us(528));
        assert_eq!(r.headroom(), Ok(us(432)));
        // At 6 kHz it does not fit.
        let six_khz = Duration::from_nanos(166_667);
        let r6 = seq.check(six_khz);
        assert!(!r6.fits());
        assert_eq!(r6.headroom(), Err(Duration::from_nanos(568_000 - 166_667)));
        assert!(r6.to_string().contains("does NOT fit"));
        assert!(r6.margin_us() < 0.0);
        // Broadcast: a query, 5 us per board, a 20 us hub read, a 3 us write.
        let bc = CycleModel {
            io: IoCost::Broadcast {
                boards: 8,
                query: us(10),
                slot_per_board: us(5),
                hub_read: us(20),
                broadcast_write: us(3),
            },
            ..seq
        };
        let rb = bc.check(six_khz);
        assert_eq!(rb.io, us(73));
        assert!(rb.fits());
        assert!(rb.to_string().contains("fits"));
        assert_eq!(seq.max_boards(six_khz, 16), 1);
        assert_eq!(bc.max_boards(six_khz, 16), 16);
        assert!((rb.utilisation() - 113.0 / 166.667).abs() < 1e-6);
        assert!((rb.max_rate_hz() - 1e6 / 113.0).abs() < 1e-6);
    }

    #[test]
    fn edge_cases() {
        let zero = CycleBudget::default().check(Duration::ZERO);
        assert!(!zero.fits());
        assert_eq!(zero.headroom(), Err(Duration::ZERO));
        assert_eq!(zero.utilisation(), f64::INFINITY);
        assert_eq!(zero.max_rate_hz(), f64::INFINITY);
        let huge = IoCost::Sequential {
            boards: u32::MAX,
            read: Duration::MAX,
            write: Duration::MAX,
        };
        assert_eq!(huge.io_time(), Duration::MAX);
        assert_eq!(huge.with_boards(3).boards(), 3);
    }
}
