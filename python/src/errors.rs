//! Errors and warnings: the library's errors as the package's exceptions
//! (`firelink/_errors.py`), and the watchdog argument every front door takes.

use pyo3::prelude::*;

use firelink_control::config::ConfigErrors;
use firelink_host::HostError;
use firelink_testbed::TestbedError;

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
