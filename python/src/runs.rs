//! The demo and the benchmark as calls that return their JSON reports
//! (`run_demo_json`, `run_bench_json`).

use pyo3::prelude::*;
use pyo3::types::PyString;

use firelink_bus::Detail;
use firelink_control::config::presets;
use firelink_control::runner::Pacing;
use firelink_control::{ServoPeriod, ServoPeriodError};
use firelink_host::udp::WaitMode;
use firelink_testbed::demo::DemoFault;
use firelink_testbed::dvrk::bench::{BenchOptions, BenchTransport};
use firelink_testbed::dvrk::demo::DemoOptions;
use firelink_testbed::port_spec;

use crate::args;
use crate::args::watchdog_setting;
use crate::config::{config_arg, path_arg};
use crate::errors::{bad, error, testbed_error, warn};
use crate::interrupt;
use crate::io_system::{PROTOCOLS, protocol};
use crate::ports::parse_port_spec;
use firelink_testbed::limits;

pub(crate) fn to_json_text(py: Python<'_>, value: &impl serde::Serialize) -> PyResult<String> {
    serde_json::to_string(value).map_err(|e| error(py, "FirelinkError", e.to_string()))
}

/// The most cycles per benchmark point.
const MAX_BENCH_CYCLES: i64 = 1_000_000;

/// Run the demo; the report as JSON text (wrapped by `firelink.run_demo`).
/// Ctrl-C stops the robot at its next cycle (the boards it powered are
/// powered down) and raises `KeyboardInterrupt`.
#[pyfunction]
#[pyo3(signature = (port, duration, period, rate, rate_given, protocol, firmware, fault, pacing, watchdog_ms, config, timeout = None, detail = None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn run_demo_json(
    py: Python<'_>,
    port: &Bound<'_, PyAny>,
    duration: &Bound<'_, PyAny>,
    period: Option<&Bound<'_, PyAny>>,
    rate: &Bound<'_, PyAny>,
    rate_given: bool,
    protocol: &Bound<'_, PyAny>,
    firmware: &Bound<'_, PyAny>,
    fault: &Bound<'_, PyAny>,
    pacing: Option<&Bound<'_, PyAny>>,
    watchdog_ms: &Bound<'_, PyAny>,
    config: Option<&Bound<'_, PyAny>>,
    timeout: Option<&Bound<'_, PyAny>>,
    detail: Option<&Bound<'_, PyAny>>,
) -> PyResult<String> {
    let port = args::text(port, "port", port_spec::EXPECTED)?;
    let detail = match args::opt_text(detail, "detail", "fast or packet")? {
        None => Detail::Fast,
        Some(d) => d.parse::<Detail>().map_err(|e| bad(py, e.to_string()))?,
    };
    let timeout = match timeout.filter(|t| !t.is_none()) {
        None => firelink_testbed::rig::UDP_TIMEOUT,
        Some(t) => std::time::Duration::from_secs_f64(args::real(
            t,
            "timeout",
            args::Span::above(0.0, 60.0, " s"),
        )?),
    };
    let duration_s = args::real(duration, "duration", limits::RUN_SECONDS)?;
    let period = servo_period(period, rate, rate_given)?;
    let protocol = self::protocol(py, &args::text(protocol, "protocol", PROTOCOLS)?)?;
    let firmware = args::firmware(firmware)?;
    let faults = "none, stop-host, corrupt-query, board-loss or following-error";
    let fault = args::text(fault, "fault", faults)?
        .parse::<DemoFault>()
        .map_err(|e| bad(py, e.to_string()))?;
    let pacing = match args::opt_text(pacing, "pacing", "virtual or realtime")?.as_deref() {
        None => None,
        Some("virtual") => Some(Pacing::Virtual),
        Some("realtime") => Some(Pacing::WallClock),
        Some(p) => {
            return Err(bad(
                py,
                format!("unknown pacing {p:?}: virtual or realtime"),
            ));
        }
    };
    let watchdog = watchdog_setting(py, watchdog_ms)?;
    let config = config_arg(py, config)?;
    let options = DemoOptions {
        config: config.unwrap_or_else(presets::dvrk_seed000),
        period,
        protocol,
        duration_s,
        port: parse_port_spec(py, &port)?,
        firmware,
        fault,
        faults: None,
        pacing,
        watchdog,
        udp_wait: WaitMode::Blocking,
        timeout,
        detail,
    };
    if let Some(w) = watchdog.warning() {
        warn(py, w)?;
    }
    let report = interrupt::until_interrupted(py, |stop| {
        firelink_testbed::dvrk::demo::run_demo_until(&options, stop, None, |_| {})
    })?
    .map_err(|e| testbed_error(py, e))?;
    let mut value =
        serde_json::to_value(&report).map_err(|e| error(py, "FirelinkError", e.to_string()))?;
    if let Some(map) = value.as_object_mut() {
        let verdict = report.verdict().err().unwrap_or_else(|| "ok".to_string());
        map.insert("verdict".into(), verdict.into());
    }
    to_json_text(py, &value)
}

/// `run_demo`'s servo period: `period` (text as `--period` takes it, or a
/// number of seconds), or the older `rate` (Hz; 6 kHz when neither is
/// given). Both given is refused, naming both.
fn servo_period(
    period: Option<&Bound<'_, PyAny>>,
    rate: &Bound<'_, PyAny>,
    rate_given: bool,
) -> PyResult<ServoPeriod> {
    let py = rate.py();
    let refused = |e: ServoPeriodError| bad(py, e.to_string());
    let Some(period) = period else {
        let hz = args::real(rate, "rate", limits::RATE_HZ)?;
        return ServoPeriod::from_rate_hz(hz).map_err(refused);
    };
    if rate_given {
        return Err(bad(
            py,
            "give period= or rate=, not both (rate= is the older spelling of period=)",
        ));
    }
    if let Ok(text) = period.cast::<PyString>() {
        return args::string(text)?.parse().map_err(refused);
    }
    match period.extract::<f64>() {
        Ok(secs) if !args::is_bool(period) => ServoPeriod::from_secs_f64(secs).map_err(refused),
        // An integer too big for a float: out of range by the same rule.
        Err(e) if e.is_instance_of::<pyo3::exceptions::PyOverflowError>(py) => {
            ServoPeriod::from_secs_f64(f64::INFINITY).map_err(refused)
        }
        _ => Err(bad(
            py,
            format!(
                "period must be a string with its unit (\"1ms\", \"250us\", \"6kHz\") \
                 or a number of seconds, not {}",
                args::type_name(period)
            ),
        )),
    }
}

/// The items of a list argument (any iterable but a string; a string is
/// one item), at most `max` of them: an endless iterator is refused, not
/// followed.
fn items<'py>(
    value: &Bound<'py, PyAny>,
    what: &str,
    max: usize,
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    if value.is_instance_of::<PyString>() {
        return Ok(vec![value.clone()]);
    }
    let iter = value.try_iter().map_err(|_| {
        bad(
            value.py(),
            format!("{what} must be a list, not {}", args::type_name(value)),
        )
    })?;
    let mut out = Vec::new();
    for item in iter {
        if out.len() == max {
            return Err(bad(
                value.py(),
                format!("{what} has more than {max} entries"),
            ));
        }
        out.push(item?);
    }
    Ok(out)
}

/// Run the benchmark; the report as JSON text (wrapped by `firelink.run_bench`).
/// Ctrl-C returns at once with `KeyboardInterrupt` (the benchmark's thread,
/// on emulated boards only, finishes its work on its own).
#[pyfunction]
#[pyo3(signature = (transports, boards, protocols, cycles, firmware, plot))]
pub(crate) fn run_bench_json(
    py: Python<'_>,
    transports: &Bound<'_, PyAny>,
    boards: &Bound<'_, PyAny>,
    protocols: &Bound<'_, PyAny>,
    cycles: &Bound<'_, PyAny>,
    firmware: &Bound<'_, PyAny>,
    plot: Option<&Bound<'_, PyAny>>,
) -> PyResult<String> {
    let transports = items(transports, "transports", 8)?
        .iter()
        .map(|t| {
            let name = args::text(t, "a transport", BenchTransport::NAMES)?;
            BenchTransport::from_name(&name).ok_or_else(|| {
                bad(
                    py,
                    format!("unknown transport {name:?}: {}", BenchTransport::NAMES),
                )
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let boards = items(boards, "boards", 64)?
        .iter()
        .map(|b| args::int_in::<usize>(b, "a board count", limits::BENCH_BOARD_COUNT))
        .collect::<PyResult<Vec<_>>>()?;
    let protocols = items(protocols, "protocols", 8)?
        .iter()
        .map(|p| protocol(py, &args::text(p, "a protocol", PROTOCOLS)?))
        .collect::<PyResult<Vec<_>>>()?;
    let cycles: u64 = args::int_as(cycles, "cycles", 1, MAX_BENCH_CYCLES)?;
    let plot = match plot.filter(|p| !p.is_none()) {
        None => None,
        Some(p) => Some(path_arg(p, "plot")?),
    };
    let options = BenchOptions {
        transports,
        boards,
        protocols,
        cycles,
        firmware: args::firmware(firmware)?,
        ..BenchOptions::default()
    };
    // Checked here too, so that a refusal is not left to the worker.
    firelink_testbed::dvrk::bench::check_board_counts(&options.boards).map_err(|e| bad(py, e))?;
    if options.transports.is_empty() || options.protocols.is_empty() {
        return Err(bad(
            py,
            "run_bench needs at least one transport and one protocol",
        ));
    }
    let outcome = interrupt::abandon_on_interrupt(py, move || {
        let report = firelink_testbed::dvrk::bench::run_bench(&options, |_, _, _| {})
            .map_err(|e| e.to_string())?;
        if let Some(path) = plot {
            firelink_plot::fig11(&report, &path).map_err(|e| e.to_string())?;
        }
        serde_json::to_string(&report).map_err(|e| e.to_string())
    })?;
    outcome.map_err(|e| error(py, "FirelinkError", e))
}
