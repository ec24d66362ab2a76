//! Configurations (`Config`, `load_config`, `parse_config`): loaded and
//! checked by `firelink_control::config`, errors as `ConfigError`.

use pyo3::prelude::*;
use pyo3::types::PyBytes;

use firelink_control::config::IoConfig;

use crate::args;
use crate::errors::{bad, config_error, error};

/// A validated robot configuration.
#[pyclass(frozen, module = "firelink._firelink")]
pub(crate) struct Config {
    inner: IoConfig,
}

#[pymethods]
impl Config {
    /// Robot names, in file order.
    #[getter]
    fn robots(&self) -> Vec<String> {
        self.inner.robots.iter().map(|r| r.name.clone()).collect()
    }

    /// Number of joints (actuators) over all robots.
    #[getter]
    fn joints(&self) -> usize {
        self.inner.joints().count()
    }

    /// Board IDs used, in first-use order.
    #[getter]
    fn boards(&self) -> Vec<u8> {
        self.inner.boards().iter().map(|b| b.board_id).collect()
    }

    /// The configuration as JSON text (what `load_config` reads back).
    fn to_json(&self) -> String {
        self.inner.to_json_pretty()
    }

    fn __repr__(&self) -> String {
        format!(
            "Config(robots={:?}, joints={})",
            self.robots(),
            self.joints()
        )
    }
}

/// A path argument: a `str` or an `os.PathLike`.
pub(crate) fn path_arg(value: &Bound<'_, PyAny>, what: &str) -> PyResult<std::path::PathBuf> {
    if value.is_instance_of::<PyBytes>() {
        return Err(bad(
            value.py(),
            format!("{what} must be a str or os.PathLike, not bytes"),
        ));
    }
    value.extract::<std::path::PathBuf>().map_err(|_| {
        bad(
            value.py(),
            format!(
                "{what} must be a str or os.PathLike, not {}",
                args::type_name(value)
            ),
        )
    })
}

/// A configuration argument: a `Config`, or a file's path (loaded here,
/// `ConfigError` when invalid); `None`: absent.
pub(crate) fn config_arg(
    py: Python<'_>,
    value: Option<&Bound<'_, PyAny>>,
) -> PyResult<Option<IoConfig>> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    if let Ok(c) = value.cast::<Config>() {
        return Ok(Some(c.get().inner.clone()));
    }
    let path = path_arg(value, "config (a firelink.Config or a configuration file)")?;
    IoConfig::load(&path)
        .map(Some)
        .map_err(|e| config_error(py, &e))
}

/// Load and validate a configuration file; raises `ConfigError`.
#[pyfunction]
pub(crate) fn load_config(py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<Config> {
    let path = path_arg(path, "path")?;
    IoConfig::load(&path)
        .map(|inner| Config { inner })
        .map_err(|e| config_error(py, &e))
}

/// Parse and validate configuration text (a `str`, or UTF-8 `bytes`);
/// raises `ConfigError`.
#[pyfunction]
#[pyo3(signature = (text, file=None))]
pub(crate) fn parse_config(
    py: Python<'_>,
    text: &Bound<'_, PyAny>,
    file: Option<&Bound<'_, PyAny>>,
) -> PyResult<Config> {
    let file = args::opt_text(file, "file", "the name errors give")?
        .unwrap_or_else(|| "<string>".to_string());
    let text = match text.cast::<PyBytes>() {
        Ok(b) => String::from_utf8(b.as_bytes().to_vec()).map_err(|e| {
            error(
                py,
                "ConfigError",
                format!("{file}: the configuration is not UTF-8 text ({e})"),
            )
        })?,
        Err(_) => args::text(text, "text", "the configuration's JSON")?,
    };
    IoConfig::from_json_str(&text, &file)
        .map(|inner| Config { inner })
        .map_err(|e| config_error(py, &e))
}
