//! Errors and warnings: the library's errors as the package's exceptions
//! (`firelink/_errors.py`), and the watchdog argument every front door takes.

use pyo3::prelude::*;
use pyo3::types::PyString;

use firelink_control::config::ConfigErrors;
use firelink_host::{HostError, WatchdogSetting};
use firelink_testbed::TestbedError;

use crate::args;

/// An exception of the package's own hierarchy (`firelink._errors`).
pub(crate) fn error<'py>(py: Python<'py>, class: &str, args: impl IntoPyObject<'py>) -> PyErr {
    let made = py
        .import("firelink._errors")
        .and_then(|m| m.getattr(class))
        .and_then(|c| c.call1((args,)));
    match made {
        Ok(instance) => PyErr::from_value(instance),
        Err(e) => e,
    }
}

pub(crate) fn host_error(py: Python<'_>, e: HostError) -> PyErr {
    let class = match e {
        HostError::Timeout { .. } | HostError::CycleDeadline { .. } => "BusTimeout",
        HostError::NoBoards { .. } => "NoBoardsError",
        HostError::InvalidRequest { .. } | HostError::UnknownBoard(_) => "InvalidRequest",
        _ => "BusError",
    };
    error(py, class, e.to_string())
}

pub(crate) fn testbed_error(py: Python<'_>, e: TestbedError) -> PyErr {
    match e {
        TestbedError::Host(h) => host_error(py, h),
        TestbedError::Config(text) => error(py, "FirelinkError", text),
        e @ (TestbedError::PortSpec(_) | TestbedError::PortRefused(_)) => {
            error(py, "PortError", e.to_string())
        }
        other => error(py, "FirelinkError", other.to_string()),
    }
}

pub(crate) fn config_error(py: Python<'_>, e: &ConfigErrors) -> PyErr {
    let first = e.first();
    let made = py
        .import("firelink._errors")
        .and_then(|m| m.getattr("ConfigError"))
        .and_then(|c| {
            c.call1((
                e.to_string(),
                first.file.clone(),
                first.path.clone(),
                first.problem.to_string(),
            ))
        });
    match made {
        Ok(instance) => PyErr::from_value(instance),
        Err(err) => err,
    }
}

pub(crate) fn bad(py: Python<'_>, text: impl Into<String>) -> PyErr {
    error(py, "InvalidRequest", text.into())
}

/// Issue a Python `UserWarning` (e.g. the watchdog is off).
pub(crate) fn warn(py: Python<'_>, text: &str) -> PyResult<()> {
    let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
    let text = std::ffi::CString::new(text).unwrap_or_default();
    PyErr::warn(py, &category, &text, 1)
}

/// A watchdog argument: a period in ms (int or float) or the string
/// `"off"`; the one rule is `WatchdogSetting` (one tick to 65535 ticks).
pub(crate) fn watchdog_setting(
    py: Python<'_>,
    value: &Bound<'_, PyAny>,
) -> PyResult<WatchdogSetting> {
    let range = WatchdogSetting::RANGE;
    if let Ok(text) = value.cast::<PyString>() {
        let text = args::string(text)?;
        return WatchdogSetting::parse(&text).map_err(|e| match e {
            firelink_wire::board::registers::WatchdogParseError::NotANumber => bad(
                py,
                format!("watchdog {text:?} is neither \"off\" nor a period in ms {range}"),
            ),
            range_error => bad(py, range_error.to_string()),
        });
    }
    let not_a_period = || {
        bad(
            py,
            format!(
                "watchdog must be a period in ms {range} or \"off\", not {}",
                args::type_name(value)
            ),
        )
    };
    if args::is_bool(value) {
        return Err(not_a_period());
    }
    match value.extract::<f64>() {
        // NaN and every out-of-range period: the setting's own message.
        Ok(ms) => WatchdogSetting::from_ms(ms).map_err(|e| bad(py, e.to_string())),
        Err(e) if e.is_instance_of::<pyo3::exceptions::PyOverflowError>(py) => Err(bad(
            py,
            format!(
                "watchdog period {} ms is out of range: {range}, or \"off\"",
                args::huge(value)
            ),
        )),
        Err(_) => Err(not_a_period()),
    }
}
