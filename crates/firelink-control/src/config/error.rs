//! Configuration errors: file, JSON path, problem.

use core::fmt;

use firelink_wire::human::Number;

/// A computed or measured figure in a message: 4 significant digits,
/// written as a person writes it through [`Number`] (`0.01734`, `2e300`,
/// `-1.5e-7`), never a 300-digit integer or 17 digits of noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured(pub f64);

impl fmt::Display for Measured {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = round_sig(self.0);
        if f.sign_plus() && x >= 0.0 {
            f.write_str("+")?;
        }
        write!(f, "{}", Number(x))
    }
}

/// `x` to 4 significant digits (non-finite values unchanged).
pub(crate) fn round_sig(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    format!("{x:.3e}").parse().unwrap_or(x)
}

/// Something a configuration file says that the loader accepted but its
/// user should hear about.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigWarning {
    /// The file, as given to the loader.
    pub file: String,
    /// JSON path inside it.
    pub path: String,
    /// What it is.
    pub warning: Warning,
}

/// Kinds of [`ConfigWarning`].
#[derive(Debug, Clone, PartialEq)]
pub enum Warning {
    /// A key Firelink does not use: read past, nothing done with it.
    Ignored,
    /// The file has no `$id` (the dVRK console refuses it; Firelink reads
    /// it as a v6 file).
    NoSchemaId,
    /// What the dVRK console's configuration reader would refuse.
    Console(super::console::ConsoleProblem),
}

impl ConfigWarning {
    /// A warning at `path` in `file`.
    pub fn new(file: &str, path: impl Into<String>, warning: Warning) -> ConfigWarning {
        ConfigWarning {
            file: file.to_string(),
            path: path.into(),
            warning,
        }
    }
}

impl fmt::Display for ConfigWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}: ", self.file, self.path)?;
        match &self.warning {
            Warning::Ignored => write!(f, "ignored (a key Firelink does not use)"),
            Warning::NoSchemaId => write!(
                f,
                "missing: read as saw-robot-io v6 (the dVRK console refuses a file without \"$id\": \"saw-robot-io.schema.json\")"
            ),
            Warning::Console(p) => write!(f, "{p} (the dVRK console's reader refuses this)"),
        }
    }
}

/// One problem in a configuration file.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    /// The file, as given to the loader.
    pub file: String,
    /// JSON path inside it, e.g. `robots[1].actuators[3].drive.current_to_bits.scale`;
    /// empty for the whole document.
    pub path: String,
    /// What is wrong.
    pub problem: Problem,
}

impl ConfigError {
    /// A problem at `path` in `file`.
    pub fn new(file: &str, path: impl Into<String>, problem: Problem) -> ConfigError {
        ConfigError {
            file: file.to_string(),
            path: path.into(),
            problem,
        }
    }

    pub(crate) fn from_serde(file: &str, e: serde_path_to_error::Error<serde_json::Error>) -> Self {
        let path = e.path().to_string();
        // serde_path_to_error prints the root as ".".
        let path = if path == "." { String::new() } else { path };
        let inner = e.into_inner();
        let problem = match inner.classify() {
            serde_json::error::Category::Data => Problem::Type(inner.to_string()),
            serde_json::error::Category::Io => Problem::Io(inner.to_string()),
            serde_json::error::Category::Syntax | serde_json::error::Category::Eof => {
                Problem::Syntax(inner.to_string())
            }
        };
        ConfigError::new(file, path, problem)
    }
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.path.is_empty() {
            write!(f, "{}: {}", self.file, self.problem)
        } else {
            write!(f, "{}: {}: {}", self.file, self.path, self.problem)
        }
    }
}

impl std::error::Error for ConfigError {}

/// What is wrong at a path.
#[derive(Debug, Clone, PartialEq)]
pub enum Problem {
    /// The file could not be read.
    Io(String),
    /// The text is not JSON (serde_json's message, with line and column).
    Syntax(String),
    /// Wrong type, missing or unknown field, unknown enum value (serde's
    /// message, with line and column).
    Type(String),
    /// `$id` or `$version` is not the supported one.
    Unsupported {
        /// What was found.
        found: String,
        /// What is supported.
        expected: &'static str,
    },
    /// A number is NaN or infinite.
    NotFinite,
    /// A conversion scale is zero: the conversion could not be inverted.
    ZeroScale,
    /// A number is outside its allowed range.
    OutOfRange {
        /// The value found.
        value: f64,
        /// The allowed range, in words.
        expected: String,
    },
    /// A value makes a move the configuration implies (homing, a stop
    /// search, a move across the soft limits) last longer than
    /// [`bounds::MOVE_SECONDS`](super::bounds::MOVE_SECONDS).
    TooLong {
        /// The value found.
        value: f64,
        /// The move, in words.
        what: String,
        /// How long it would take, seconds.
        seconds: f64,
    },
    /// `lower >= upper`.
    EmptyRange {
        /// Lower bound found.
        lower: f64,
        /// Upper bound found.
        upper: f64,
    },
    /// A (board_id, axis_id) pair, robot name or tolerance entry used twice.
    Duplicate {
        /// What is duplicated, in words.
        what: String,
        /// Path of the first use.
        first: String,
    },
    /// `axis_id` is not below the number of axes of the board.
    AxisBeyondBoard {
        /// The axis.
        axis_id: u8,
        /// The board.
        board_id: u8,
        /// Axes on that board.
        axes: u8,
        /// Board type.
        hardware: &'static str,
    },
    /// Two values that must agree do not.
    Mismatch(String),
    /// A list or name that must not be empty is.
    Empty,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Problem::Io(m) => write!(f, "cannot read: {m}"),
            Problem::Syntax(m) => write!(f, "not valid JSON: {m}"),
            Problem::Type(m) => write!(f, "{m}"),
            Problem::Unsupported { found, expected } => {
                write!(f, "unsupported value {found:?}, expected {expected:?}")
            }
            Problem::NotFinite => write!(f, "not a finite number"),
            Problem::ZeroScale => write!(f, "zero scale (the conversion cannot be inverted)"),
            Problem::OutOfRange { value, expected } => {
                write!(f, "out of range: {} (expected {expected})", Number(*value))
            }
            Problem::TooLong {
                value,
                what,
                seconds,
            } => write!(
                f,
                "out of range: {} makes {what} take {} s (at most {} s)",
                Number(*value),
                Number(*seconds),
                Number(super::bounds::MOVE_SECONDS)
            ),
            Problem::EmptyRange { lower, upper } => write!(
                f,
                "empty range: lower {} is not below upper {}",
                Number(*lower),
                Number(*upper)
            ),
            Problem::Duplicate { what, first } => {
                write!(f, "duplicate {what} (first used at {first})")
            }
            Problem::AxisBeyondBoard {
                axis_id,
                board_id,
                axes,
                hardware,
            } => write!(
                f,
                "axis_id {axis_id} is beyond board {board_id}'s axes ({hardware} has {axes}: 0..={})",
                axes.saturating_sub(1)
            ),
            Problem::Mismatch(m) => write!(f, "{m}"),
            Problem::Empty => write!(f, "must not be empty"),
        }
    }
}

/// One or more configuration errors (never zero).
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigErrors(Vec<ConfigError>);

impl ConfigErrors {
    pub(crate) fn one(e: ConfigError) -> Self {
        ConfigErrors(vec![e])
    }

    /// The errors of `v`, or `None` when it is empty (other configuration
    /// formats, such as MAHRU's, report through this type too).
    pub fn from_vec(v: Vec<ConfigError>) -> Option<Self> {
        if v.is_empty() {
            None
        } else {
            Some(ConfigErrors(v))
        }
    }

    /// The errors, in file order.
    pub fn errors(&self) -> &[ConfigError] {
        &self.0
    }

    /// The first error.
    pub fn first(&self) -> &ConfigError {
        // Never empty by construction.
        &self.0[0]
    }

    /// Whether some error is at exactly `path`.
    pub fn has_path(&self, path: &str) -> bool {
        self.0.iter().any(|e| e.path == path)
    }
}

impl fmt::Display for ConfigErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

impl std::error::Error for ConfigErrors {}

impl IntoIterator for ConfigErrors {
    type Item = ConfigError;
    type IntoIter = std::vec::IntoIter<ConfigError>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.into_iter()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measured_figures_read_as_written() {
        let shown = |x: f64| Measured(x).to_string();
        assert_eq!(shown(0.0017337178605651982), "0.001734");
        assert_eq!(shown(2.5249096380004967e301), "2.525e301");
        assert_eq!(shown(6.25), "6.25");
        assert_eq!(shown(-1.487016908477783e-7), "-1.487e-7");
        assert_eq!(shown(f64::NAN), "NaN");
        assert_eq!(format!("{:+}", Measured(0.0123)), "+0.0123");
        assert_eq!(format!("{:+}", Measured(-0.0123)), "-0.0123");
    }
}
