//! One demo request for every robot: what `firelink demo` asks for,
//! whichever robot it names. [`DemoRequest::run`] picks the run (the
//! dVRK's [`run_demo`], the Snake system's [`run_snake_demo`], MAHRU's
//! [`run_mahru_demo`] or the teleoperation session [`run_teleop`]), hands
//! it the options that robot takes, and returns a [`DemoOutcome`] that
//! prints itself as JSON or as a table and gives the verdict.
//!
//! The servo period is one [`ServoPeriod`] for every robot: `None` is the
//! robot's own default (the dVRK 6 kHz, the Snake system 1 kHz, MAHRU its
//! configuration's period).

use firelink_board::qla::config::Profile;
use firelink_bus::Detail;
use firelink_control::ServoPeriod;
use firelink_control::config::{IoConfig, presets};
use firelink_control::runner::Pacing;
use firelink_host::WatchdogSetting;
use firelink_host::qla::scan::Protocol;
use firelink_host::udp::WaitMode;

use crate::TestbedError;
use crate::demo::{DemoFault, DemoProgress, DemoReport, PortSpec, RealtimeStatus};
use crate::demo_text::render;
use crate::dvrk::demo::{DemoOptions, run_demo};
use crate::dvrk::teleop::{TeleopOptions, TeleopReport, run_teleop};
use crate::fault_script::FaultScript;
use crate::mahru::{MahruConfig, MahruDemoOptions, MahruDemoReport, run_mahru_demo};
use crate::port_spec::PortKind;
use crate::rig::RobotKind;
use crate::snake::demo::{SnakeDemoOptions, SnakeDemoReport, run_snake_demo};
use crate::snake::is_snake_config;

/// The robot's configuration.
#[derive(Debug, Clone, Default)]
pub enum DemoConfig {
    /// The robot's own seed configuration.
    #[default]
    Builtin,
    /// A saw-robot-io configuration (the dVRK or a Snake system: its
    /// boards say which).
    Io(IoConfig),
    /// A MAHRU configuration.
    Mahru(MahruConfig),
}

/// What a demo run is asked to do, for any robot: also `firelink demo`'s
/// options (clap's `Args` behind the `clap` feature; the configuration and
/// the teleoperation session are the front end's to fill in).
#[derive(Debug, Clone)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct DemoRequest {
    /// Which robot: `dvrk` (seed 000's 28 axes on QLA boards), `snake`
    /// (seed 001's 36 axes on its own 7-channel nodes; also chosen by a
    /// `--config` whose boards are SNAKE nodes) or `mahru` (seed 002's
    /// humanoid; it uses --duration, --period, --config, --json,
    /// --quiet).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = RobotKind::Dvrk))]
    pub robot: RobotKind,
    /// Instead of the trajectories: the dVRK's teleoperation session.
    #[cfg_attr(feature = "clap", arg(skip))]
    pub teleop: bool,
    /// The configuration (a [`DemoConfig::Io`] on Snake nodes is the Snake
    /// system whatever `robot` says, unless it is MAHRU).
    #[cfg_attr(feature = "clap", arg(skip))]
    pub config: DemoConfig,
    /// The servo period for every robot, as a period or a rate: `1ms`,
    /// `250us`, `6kHz` (10 us to 1 s; default: the dVRK 6 kHz, the Snake
    /// robot 1 kHz, MAHRU its configuration's 2 ms).
    #[cfg_attr(feature = "clap", arg(long))]
    pub period: Option<ServoPeriod>,
    /// The Snake system and MAHRU: after the run, search for the fastest
    /// rate or period that holds.
    #[cfg_attr(
        feature = "clap",
        arg(
            long = "no-rate-search",
            action = clap::ArgAction::SetFalse,
            help = "Snake robot and MAHRU: skip the search for the fastest rate or period that holds"
        )
    )]
    pub search_fastest: bool,
    /// I/O protocol.
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = Protocol::Broadcast))]
    pub protocol: Protocol,
    /// Seconds of motion after homing (above 0, at most a day).
    #[cfg_attr(
        feature = "clap",
        arg(
            long = "duration",
            value_name = "DURATION",
            default_value_t = 3.0,
            value_parser = crate::limits::run_seconds
        )
    )]
    pub duration_s: f64,
    /// Where the boards are: `sim` (the robot's emulated boards on the
    /// simulated bus, in-process; `sim:N[:FW]`: boards 0..N at firmware
    /// FW), `emulate` (the same boards behind an in-process `firelink
    /// emulate`, over loopback UDP), `udp:HOST[:PORT]` (a running
    /// `firelink emulate` or a real bridge board) or `fw` / `fw:N`
    /// (FireWire card 0 / N). MAHRU runs on plain `sim` only.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value = "sim", value_parser = crate::port_spec::parse_port)
    )]
    pub port: PortSpec,
    /// Over UDP (`emulate`, `udp:...`): how the port's reads wait for the
    /// answer, `block` (sleep in the kernel, low CPU) or `spin` (poll the
    /// socket, low latency, one core busy while waiting).
    #[cfg_attr(
        feature = "clap",
        arg(long = "udp-wait", value_enum, default_value_t = WaitMode::Blocking)
    )]
    pub udp_wait: WaitMode,
    /// Over UDP or FireWire (`emulate`, `udp:...`, `fw`): the read
    /// time-out in milliseconds (1..=60000). A servo cycle whose answer
    /// takes longer counts the board as missed (a fault); the scan waits
    /// that long for each absent node.
    #[cfg_attr(
        feature = "clap",
        arg(long = "timeout-ms", default_value_t = 20, value_parser = crate::limits::timeout_ms)
    )]
    pub timeout_ms: u64,
    /// Board firmware of the emulated boards.
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value = "rev8", value_parser = crate::cli_args::firmware())
    )]
    pub firmware: Profile,
    /// On the simulated bus (`sim`): its level of detail, `fast` (a
    /// packet's deliveries in one batch where that is exact) or `packet`
    /// (every delivery an event of its own); the same answer either way,
    /// and the report counts the cycles each way ran.
    #[cfg_attr(feature = "clap", arg(long, default_value = "fast"))]
    pub detail: Detail,
    /// Inject a fault half-way (a named preset: its fault script).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = DemoFault::None))]
    pub fault: DemoFault,
    /// Instead of --fault: faults as a plan, entries separated by `;`.
    /// `start` is the motion's first cycle, `cycle=N` counts the motion's
    /// cycles, `t=` counts from half way: `mute@cycle=300:id=4`,
    /// `host-pause@t=0us:for=60000us`,
    /// `corrupt@t=0us:tcode=0x0,offset=0x1800,count=1`,
    /// `drop@cycle=100:dest=2,rate=0.1` (a port that cannot apply an entry
    /// refuses it by name before the run).
    #[cfg_attr(
        feature = "clap",
        arg(long = "faults", value_name = "SCRIPT", conflicts_with = "fault")
    )]
    pub faults: Option<FaultScript>,
    /// Pacing; default: virtual for sim, realtime over UDP.
    #[cfg_attr(feature = "clap", arg(long, value_parser = crate::cli_args::pacing()))]
    pub pacing: Option<Pacing>,
    /// Board watchdog period in ms (above 0, at most 341), or `off`
    /// (a stopped host then leaves the amplifiers on: say so explicitly).
    #[cfg_attr(
        feature = "clap",
        arg(long = "watchdog-ms", default_value = "20", value_parser = crate::limits::watchdog)
    )]
    pub watchdog: WatchdogSetting,
    /// The options the user gave, by clap's argument ID (the field's name:
    /// `duration_s`, `port`, ...; the front end's own, as `config`, too),
    /// whatever their value: the front end fills it from clap's value
    /// sources. A run that would ignore one refuses it by these, so an
    /// option given with its default value is refused as well.
    #[cfg_attr(feature = "clap", arg(skip))]
    pub given: Vec<String>,
}

/// The options the teleoperation session does not use, by clap's argument
/// ID: the option as written, and why it cannot be honoured.
const TELEOP_IGNORES: &[(&str, &str, &str)] = &[
    ("robot", "--robot", "the session is the dVRK's"),
    (
        "config",
        "--config",
        "the session runs seed 000's MTMR and PSM1",
    ),
    (
        "duration_s",
        "--duration",
        "the session follows for its own 60 s",
    ),
    ("port", "--port", "the session runs on the simulated bus"),
    (
        "protocol",
        "--protocol",
        "the session's I/O picks its protocol itself",
    ),
    (
        "udp_wait",
        "--udp-wait",
        "the session runs on the simulated bus",
    ),
    (
        "timeout_ms",
        "--timeout-ms",
        "the session runs on the simulated bus",
    ),
    ("pacing", "--pacing", "the session runs in virtual time"),
    ("no_rt", "--no-rt", "the session runs in virtual time"),
    (
        "watchdog",
        "--watchdog-ms",
        "the session keeps the runner's default watchdog",
    ),
    (
        "search_fastest",
        "--no-rate-search",
        "the session searches no rate",
    ),
];

impl Default for DemoRequest {
    fn default() -> Self {
        let dvrk = DemoOptions::default();
        DemoRequest {
            robot: RobotKind::Dvrk,
            teleop: false,
            config: DemoConfig::Builtin,
            period: None,
            duration_s: dvrk.duration_s,
            port: dvrk.port,
            protocol: dvrk.protocol,
            firmware: dvrk.firmware,
            fault: dvrk.fault,
            faults: None,
            pacing: dvrk.pacing,
            watchdog: dvrk.watchdog,
            udp_wait: dvrk.udp_wait,
            timeout_ms: u64::try_from(dvrk.timeout.as_millis()).unwrap_or(u64::MAX),
            detail: dvrk.detail,
            search_fastest: true,
            given: Vec::new(),
        }
    }
}

/// What a demo run returned.
#[derive(Debug, Clone)]
pub enum DemoOutcome {
    /// The dVRK demo, with the configuration its table reads.
    Dvrk(Box<DemoReport>, Box<IoConfig>),
    /// The Snake demo.
    Snake(Box<SnakeDemoReport>),
    /// MAHRU walking.
    Mahru(Box<MahruDemoReport>),
    /// The teleoperation session.
    Teleop(Box<TeleopReport>),
}

impl DemoRequest {
    /// The run the request picks, as a robot and whether it is the
    /// teleoperation session: that session (the dVRK's, whatever the
    /// robot), MAHRU, the Snake system (asked for, or a configuration on
    /// Snake nodes), else the dVRK.
    pub fn chosen(&self) -> (RobotKind, bool) {
        if self.teleop {
            return (RobotKind::Dvrk, true);
        }
        match (&self.config, self.robot) {
            (_, RobotKind::Mahru) => (RobotKind::Mahru, false),
            (DemoConfig::Io(c), _) if is_snake_config(c) => (RobotKind::Snake, false),
            (_, kind) => (kind, false),
        }
    }

    fn io_config(&self, builtin: fn() -> IoConfig) -> Result<IoConfig, TestbedError> {
        match &self.config {
            DemoConfig::Builtin => Ok(builtin()),
            DemoConfig::Io(c) => Ok(c.clone()),
            DemoConfig::Mahru(_) => Err(TestbedError::Config(
                "a MAHRU configuration drives only --robot mahru".into(),
            )),
        }
    }

    /// The dVRK demo's options.
    ///
    /// # Errors
    /// A MAHRU configuration.
    pub fn dvrk_options(&self) -> Result<DemoOptions, TestbedError> {
        let default = DemoOptions::default();
        Ok(DemoOptions {
            config: self.io_config(presets::dvrk_seed000)?,
            period: self.period.unwrap_or(default.period),
            protocol: self.protocol,
            duration_s: self.duration_s,
            port: self.port,
            firmware: self.firmware,
            fault: self.fault,
            faults: self.faults.clone(),
            pacing: self.pacing,
            watchdog: self.watchdog,
            udp_wait: self.udp_wait,
            timeout: std::time::Duration::from_millis(self.timeout_ms),
            detail: self.detail,
        })
    }

    /// The Snake demo's options.
    ///
    /// # Errors
    /// A MAHRU configuration.
    pub fn snake_options(&self) -> Result<SnakeDemoOptions, TestbedError> {
        let default = SnakeDemoOptions::default();
        Ok(SnakeDemoOptions {
            config: self.io_config(presets::snake_seed001)?,
            period: self.period.unwrap_or(default.period),
            duration_s: self.duration_s,
            port: self.port,
            fault: self.fault,
            faults: self.faults.clone(),
            pacing: self.pacing,
            watchdog: self.watchdog,
            find_max_rate: self.search_fastest,
            udp_wait: self.udp_wait,
            timeout: std::time::Duration::from_millis(self.timeout_ms),
            detail: self.detail,
            ..default
        })
    }

    /// MAHRU's options; MAHRU runs on plain `sim` only.
    ///
    /// # Errors
    /// Another port, or a saw-robot-io configuration.
    pub fn mahru_options(&self) -> Result<MahruDemoOptions, TestbedError> {
        const COMMAND: &str = "firelink demo --robot mahru";
        self.refuse_faults(COMMAND)?;
        self.port.refuse_unless(COMMAND, &[PortKind::Sim])?;
        self.port.refuse_board_count(
            COMMAND,
            "the MAHRU modules come from its configuration (seed 002's own protocol)",
        )?;
        let config = match &self.config {
            DemoConfig::Builtin => MahruConfig::seed002(),
            DemoConfig::Mahru(c) => c.clone(),
            DemoConfig::Io(_) => {
                return Err(TestbedError::Config(
                    "MAHRU needs a MAHRU configuration (as configs/mahru-seed002.json)".into(),
                ));
            }
        };
        Ok(MahruDemoOptions {
            config,
            duration_s: self.duration_s,
            period: self.period,
            find_fastest: self.search_fastest,
            detail: self.detail,
        })
    }

    /// A fault (`--fault`, `--faults`) for a run that injects none: refused,
    /// naming the option and the run (`command`).
    fn refuse_faults(&self, command: &str) -> Result<(), TestbedError> {
        let given = if self.fault != DemoFault::None {
            Some(format!("--fault {}", self.fault))
        } else {
            self.faults.as_ref().map(|f| format!("--faults {f}"))
        };
        match given {
            Some(option) => Err(TestbedError::Config(format!(
                "{command} injects no faults: {option} cannot be honoured"
            ))),
            None => Ok(()),
        }
    }

    /// The teleoperation session's options: its own robot, configuration,
    /// length, port (the simulated bus), watchdog and pacing (virtual
    /// time), no faults; it takes only `--period` and `--firmware`. An
    /// option the session would ignore is refused by name when it was
    /// given ([`given`](Self::given)), whatever its value, or when its
    /// value is not the default's (a request made without a command line).
    ///
    /// # Errors
    /// `--fault`, `--faults`, or another option the session ignores given
    /// (`--robot`, `--config`, `--duration`, `--port`, `--protocol`,
    /// `--udp-wait`, `--timeout-ms`, `--pacing`, `--no-rt`, `--watchdog-ms`,
    /// `--no-rate-search`).
    pub fn teleop_options(&self) -> Result<TeleopOptions, TestbedError> {
        const COMMAND: &str = "firelink demo --teleop";
        if self.given.iter().any(|g| g == "fault") && self.fault == DemoFault::None {
            return Err(TestbedError::Config(format!(
                "{COMMAND} cannot honour --fault none (the session injects no faults)"
            )));
        }
        self.refuse_faults(COMMAND)?;
        let default = DemoRequest::default();
        let changed = |id: &str| match id {
            "robot" => self.robot != default.robot,
            "config" => !matches!(self.config, DemoConfig::Builtin),
            "duration_s" => self.duration_s != default.duration_s,
            "port" => self.port != default.port,
            "protocol" => self.protocol != default.protocol,
            "udp_wait" => self.udp_wait != default.udp_wait,
            "timeout_ms" => self.timeout_ms != default.timeout_ms,
            "pacing" => self.pacing.is_some(),
            "watchdog" => self.watchdog != default.watchdog,
            "search_fastest" => self.search_fastest != default.search_fastest,
            _ => false,
        };
        let ignored = TELEOP_IGNORES
            .iter()
            .find(|(id, _, _)| self.given.iter().any(|g| g == id) || changed(id))
            .map(|(_, option, why)| format!("{option} ({why})"));
        if let Some(option) = ignored {
            return Err(TestbedError::Config(format!(
                "{COMMAND} cannot honour {option}"
            )));
        }
        Ok(TeleopOptions {
            firmware: self.firmware,
            period: match self.period {
                Some(p) => p,
                None => TeleopOptions::default().period,
            },
            ..TeleopOptions::default()
        })
    }

    /// Run the chosen demo. `realtime` is the calling thread's real-time
    /// setup for wall-clock pacing (the dVRK and Snake runs); `progress`
    /// gets the runs' events, `say` plain lines (MAHRU's steps, what the
    /// teleoperation session is).
    ///
    /// # Errors
    /// Options the chosen robot cannot honour, and the run's own errors.
    pub fn run(
        &self,
        realtime: Option<&dyn Fn() -> RealtimeStatus>,
        progress: &mut dyn FnMut(DemoProgress),
        say: &mut dyn FnMut(&str),
    ) -> Result<DemoOutcome, TestbedError> {
        Ok(match self.chosen() {
            (_, true) => {
                // Refused before anything is said.
                let options = self.teleop_options()?;
                say(
                    "teleoperation MTMR -> PSM1, 60 s of virtual time on the simulated bus \
                     (the clutch pressed from 30 to 33 s)",
                );
                DemoOutcome::Teleop(Box::new(run_teleop(&options)?))
            }
            (RobotKind::Mahru, _) => {
                let report = run_mahru_demo(&self.mahru_options()?, |line| say(line))?;
                DemoOutcome::Mahru(Box::new(report))
            }
            (RobotKind::Snake, _) => {
                let report = run_snake_demo(&self.snake_options()?, realtime, progress)?;
                DemoOutcome::Snake(Box::new(report))
            }
            (RobotKind::Dvrk, _) => {
                let options = self.dvrk_options()?;
                let report = run_demo(&options, realtime, progress)?;
                DemoOutcome::Dvrk(Box::new(report), Box::new(options.config))
            }
        })
    }
}

impl DemoOutcome {
    /// The report as JSON, one line (the teleoperation session's
    /// indented, as it always was).
    ///
    /// # Errors
    /// Serialisation (not expected: the reports are plain data).
    pub fn json(&self) -> Result<String, serde_json::Error> {
        match self {
            DemoOutcome::Dvrk(r, _) => serde_json::to_string(r),
            DemoOutcome::Snake(r) => serde_json::to_string(r),
            DemoOutcome::Mahru(r) => serde_json::to_string(r),
            DemoOutcome::Teleop(r) => serde_json::to_string_pretty(r),
        }
    }

    /// The report as a table for a person.
    pub fn table(&self) -> String {
        match self {
            DemoOutcome::Dvrk(r, config) => render(r, config),
            DemoOutcome::Snake(r) => r.to_string(),
            DemoOutcome::Mahru(r) => r.to_string(),
            DemoOutcome::Teleop(r) => r.to_string(),
        }
    }

    /// What the dVRK run's real-time setup achieved, in one line (when it
    /// was asked for).
    pub fn realtime_line(&self) -> Option<String> {
        let DemoOutcome::Dvrk(report, _) = self else {
            return None;
        };
        let r = &report.realtime;
        r.requested.then(|| {
            format!(
                "real time: SCHED_FIFO {}, memory locked {}, timer slack 1 ns {}{}",
                r.sched_fifo_priority.is_some(),
                r.memory_locked,
                r.timer_slack_1ns,
                if r.errors.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", r.errors.join("; "))
                }
            )
        })
    }

    /// Whether the run did what it was asked (the teleoperation session
    /// reports; it has no verdict of its own).
    ///
    /// # Errors
    /// What went wrong, in one line.
    pub fn verdict(&self) -> Result<(), String> {
        match self {
            DemoOutcome::Dvrk(r, _) => r.verdict(),
            DemoOutcome::Snake(r) => r.verdict(),
            DemoOutcome::Mahru(r) => r.verdict(),
            DemoOutcome::Teleop(_) => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_robot_is_chosen_as_the_command_line_always_did() {
        use RobotKind::{Dvrk, Mahru, Snake};
        let chosen = |robot, teleop, config| {
            let request = DemoRequest {
                robot,
                teleop,
                config,
                ..DemoRequest::default()
            };
            request.chosen()
        };
        let snake = || DemoConfig::Io(presets::snake_seed001());
        let dvrk = || DemoConfig::Io(presets::dvrk_seed000());
        assert_eq!(chosen(Dvrk, false, DemoConfig::Builtin), (Dvrk, false));
        assert_eq!(chosen(Dvrk, true, DemoConfig::Builtin), (Dvrk, true));
        assert_eq!(chosen(Snake, false, DemoConfig::Builtin), (Snake, false));
        // A configuration on Snake nodes is the Snake system.
        assert_eq!(chosen(Dvrk, false, snake()), (Snake, false));
        assert_eq!(chosen(Dvrk, false, dvrk()), (Dvrk, false));
        assert_eq!(chosen(Mahru, false, DemoConfig::Builtin), (Mahru, false));
        // The teleoperation session is the dVRK's, whatever the robot.
        assert_eq!(chosen(Mahru, true, DemoConfig::Builtin), (Dvrk, true));
        assert_eq!(chosen(Snake, true, snake()), (Dvrk, true));
    }

    #[test]
    fn one_period_means_the_same_for_every_robot() {
        let period: ServoPeriod = "2ms".parse().unwrap();
        let r = DemoRequest {
            period: Some(period),
            ..DemoRequest::default()
        };
        assert_eq!(r.dvrk_options().unwrap().period, period);
        assert_eq!(r.snake_options().unwrap().period, period);
        assert_eq!(r.mahru_options().unwrap().period, Some(period));
        // Unset: each robot's own.
        let r = DemoRequest::default();
        assert_eq!(r.dvrk_options().unwrap().period.rate_hz(), 6000.0);
        assert_eq!(r.snake_options().unwrap().period.rate_hz(), 1000.0);
        assert_eq!(r.mahru_options().unwrap().period, None);
    }

    #[test]
    fn mahru_refuses_other_ports_and_configurations() {
        let r = DemoRequest {
            robot: RobotKind::Mahru,
            port: PortSpec::Emulate,
            ..DemoRequest::default()
        };
        assert!(r.mahru_options().is_err());
        let r = DemoRequest {
            robot: RobotKind::Mahru,
            config: DemoConfig::Io(presets::dvrk_seed000()),
            ..DemoRequest::default()
        };
        assert!(r.mahru_options().is_err());
        let r = DemoRequest {
            config: DemoConfig::Mahru(MahruConfig::seed002()),
            ..DemoRequest::default()
        };
        assert!(r.dvrk_options().is_err());
    }

    #[test]
    fn runs_that_inject_no_faults_refuse_the_options_they_would_ignore() {
        let script: FaultScript = "mute@t=0us:id=4".parse().unwrap();
        fn error<T>(r: Result<T, TestbedError>) -> String {
            r.map(|_| ()).unwrap_err().to_string()
        }
        let mahru = DemoRequest {
            robot: RobotKind::Mahru,
            ..DemoRequest::default()
        };
        assert!(mahru.mahru_options().is_ok());
        let e = error(
            DemoRequest {
                fault: DemoFault::BoardLoss,
                ..mahru.clone()
            }
            .mahru_options(),
        );
        assert!(e.contains("--fault board-loss"), "{e}");
        let e = error(
            DemoRequest {
                faults: Some(script.clone()),
                ..mahru
            }
            .mahru_options(),
        );
        assert!(e.contains("--faults mute@t=0us:id=4"), "{e}");
        let teleop = DemoRequest {
            teleop: true,
            ..DemoRequest::default()
        };
        assert!(teleop.teleop_options().is_ok());
        for (request, option) in [
            (
                DemoRequest {
                    fault: DemoFault::StopHost,
                    ..teleop.clone()
                },
                "--fault stop-host",
            ),
            (
                DemoRequest {
                    faults: Some(script),
                    ..teleop.clone()
                },
                "--faults",
            ),
            (
                DemoRequest {
                    duration_s: 5.0,
                    ..teleop.clone()
                },
                "--duration (",
            ),
            (
                DemoRequest {
                    port: PortSpec::Emulate,
                    ..teleop.clone()
                },
                "--port (",
            ),
            (
                DemoRequest {
                    pacing: Some(Pacing::WallClock),
                    ..teleop.clone()
                },
                "--pacing",
            ),
        ] {
            let e = error(request.teleop_options());
            assert!(e.contains(option), "{option}: {e}");
        }
        // Given on the command line, an option the session ignores is
        // refused even at its default value.
        for (id, option, _) in TELEOP_IGNORES {
            let request = DemoRequest {
                given: vec![(*id).to_string()],
                ..teleop.clone()
            };
            let e = error(request.teleop_options());
            assert!(
                e.contains(&format!("cannot honour {option} (")),
                "{id}: {e}"
            );
        }
        let e = error(
            DemoRequest {
                given: vec!["fault".into()],
                ..teleop.clone()
            }
            .teleop_options(),
        );
        assert!(e.contains("--fault none"), "{e}");
        // What it takes.
        let request = DemoRequest {
            given: ["period", "firmware", "teleop", "json", "quiet"]
                .map(String::from)
                .to_vec(),
            period: Some(ServoPeriod::from_rate_hz(2000.0).unwrap()),
            ..teleop
        };
        assert_eq!(request.teleop_options().unwrap().period.rate_hz(), 2000.0);
    }
}
