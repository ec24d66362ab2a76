//! Arguments at the Python boundary.
//!
//! Every number, flag, string, byte string and array a caller passes is
//! converted here, with its name and its range, before anything runs: a
//! wrong type or an out-of-range value raises `InvalidRequest` with one
//! sentence naming the argument, what was given and what is allowed. No
//! `TypeError` or `OverflowError` from a conversion, no `Duration` built
//! from `1e300`, no loop count or allocation the caller did not bound.
//! Numbers in messages read as a person writes them
//! ([`firelink_wire::human::Number`]: `1e300`, not 301 digits).
//!
//! The functions take the argument as PyO3 hands it over (`&Bound<PyAny>`),
//! so the class methods declare no Rust types that PyO3 would check first
//! with its own `TypeError`.
//!
//! Python strings become Rust strings through [`string`], never through
//! `Display` (`to_string()`): CPython's `str()` runs pending signal handlers
//! first, and PyO3's `Display` reports their exception as "unraisable" and
//! drops it, which loses a Ctrl-C that arrives while arguments are checked.

use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyByteArray, PyBytes, PyString};

use firelink_host::WatchdogSetting;
use firelink_testbed::emulated::Profile;
use firelink_testbed::port_spec;
use firelink_wire::human::Number;

use crate::errors::bad;

/// A Python string as a Rust string (without `str()`: see the module's
/// docs).
///
/// # Errors
/// The string cannot be encoded (a lone surrogate).
pub(crate) fn string(s: &Bound<'_, PyString>) -> PyResult<String> {
    Ok(s.to_cow()?.into_owned())
}

/// The name of `value`'s type, for messages (`str`, `float`, `NoneType`).
pub(crate) fn type_name(value: &Bound<'_, PyAny>) -> String {
    value
        .get_type()
        .name()
        .and_then(|n| string(&n))
        .unwrap_or_else(|_| "object".to_string())
}

/// Whether `value` is a bool: Python's, or numpy's `bool_`.
pub(crate) fn is_bool(value: &Bound<'_, PyAny>) -> bool {
    value.is_instance_of::<PyBool>() || matches!(type_name(value).as_str(), "bool_" | "bool")
}

/// An integer as given.
enum Integer {
    /// It fits in 64 bits.
    Fits(i64),
    /// Beyond 64 bits: how to show it.
    Huge(String),
    /// Not an integer at all (a bool counts as none).
    Not,
    /// Asking raised what is not an `Exception` (a `KeyboardInterrupt`
    /// from a signal handler that ran meanwhile): passed on as it is.
    Raised(PyErr),
}

/// Whether `e` must be passed on rather than reported as a bad argument:
/// `KeyboardInterrupt`, `SystemExit` and the like.
fn passes_through(py: Python<'_>, e: &PyErr) -> bool {
    !e.is_instance_of::<pyo3::exceptions::PyException>(py)
}

/// `value` as an integer: a Python int or anything with `__index__`
/// (numpy's integer scalars), never a bool or a float.
fn integer(value: &Bound<'_, PyAny>) -> Integer {
    if is_bool(value) {
        return Integer::Not;
    }
    match value.extract::<i64>() {
        Ok(v) => Integer::Fits(v),
        Err(e) if e.is_instance_of::<pyo3::exceptions::PyOverflowError>(value.py()) => {
            Integer::Huge(huge(value))
        }
        Err(e) if passes_through(value.py(), &e) => Integer::Raised(e),
        Err(_) => Integer::Not,
    }
}

/// An integer beyond 64 bits, shown whole while that stays readable (its
/// size in bits otherwise; no `str()`, which runs signal handlers and
/// refuses ints over 4300 digits).
pub(crate) fn huge(value: &Bound<'_, PyAny>) -> String {
    let bits = value
        .call_method0("bit_length")
        .and_then(|b| b.extract::<u64>())
        .unwrap_or(u64::MAX);
    if bits <= 127 {
        if let Ok(v) = value.extract::<i128>() {
            return v.to_string();
        }
    }
    if bits == u64::MAX {
        "(a very large integer)".to_string()
    } else {
        format!("(an integer of {bits} bits)")
    }
}

/// `lo` to `hi`, in hexadecimal when `hi` is a register-sized mask.
fn int_range(lo: i64, hi: i64) -> String {
    let mask = hi > 0xFFFF && (hi as u64).wrapping_add(1).is_power_of_two();
    if mask {
        format!("{lo} to {hi:#X}")
    } else {
        format!("{lo} to {hi}")
    }
}

/// An integer argument in `lo..=hi`.
///
/// # Errors
/// `InvalidRequest` naming `what`: not an integer (bools and floats are
/// not), or out of range.
pub(crate) fn int(value: &Bound<'_, PyAny>, what: &str, lo: i64, hi: i64) -> PyResult<i64> {
    let range = int_range(lo, hi);
    let py = value.py();
    match integer(value) {
        Integer::Fits(v) if (lo..=hi).contains(&v) => Ok(v),
        Integer::Fits(v) => Err(bad(
            py,
            format!("{what} {v} is out of range: it must be {range}"),
        )),
        Integer::Huge(shown) => Err(bad(
            py,
            format!("{what} {shown} is out of range: it must be {range}"),
        )),
        Integer::Not => Err(bad(
            py,
            format!(
                "{what} must be an integer from {range}, not {}",
                type_name(value)
            ),
        )),
        Integer::Raised(e) => Err(e),
    }
}

/// An integer argument that fits `T`, in `lo..=hi`.
///
/// # Errors
/// As [`int`].
pub(crate) fn int_as<T: TryFrom<i64>>(
    value: &Bound<'_, PyAny>,
    what: &str,
    lo: i64,
    hi: i64,
) -> PyResult<T> {
    let v = int(value, what, lo, hi)?;
    T::try_from(v).map_err(|_| {
        bad(
            value.py(),
            format!(
                "{what} {v} is out of range: it must be {}",
                int_range(lo, hi)
            ),
        )
    })
}

/// An optional integer argument in one of `firelink_testbed::limits`'s
/// integer ranges (`None`: absent).
///
/// # Errors
/// As [`int_in`].
pub(crate) fn opt_int_in<T: TryFrom<i64>>(
    value: Option<&Bound<'_, PyAny>>,
    what: &str,
    range: std::ops::RangeInclusive<u64>,
) -> PyResult<Option<T>> {
    match value {
        Some(v) if !v.is_none() => int_in(v, what, range).map(Some),
        _ => Ok(None),
    }
}

/// The range a real argument must lie in, and its unit: the command
/// line's own type, so a rule the two share is stated once
/// (`firelink_testbed::limits`'s constants).
pub(crate) use firelink_testbed::limits::Span;

/// What `span` allows, for messages ("from 1 to 100000 Hz", "above 0 s
/// and at most 86400 s").
fn allowed(span: Span) -> String {
    let (lo, hi, unit) = (Number(span.lo), Number(span.hi), span.unit);
    if span.above {
        format!("above {lo}{unit} and at most {hi}{unit}")
    } else {
        format!("from {lo} to {hi}{unit}")
    }
}

/// An integer argument in one of `firelink_testbed::limits`'s integer
/// ranges (`NODE_ID`, `BOARD_ID`, ...).
///
/// # Errors
/// As [`int`].
pub(crate) fn int_in<T: TryFrom<i64>>(
    value: &Bound<'_, PyAny>,
    what: &str,
    range: std::ops::RangeInclusive<u64>,
) -> PyResult<T> {
    let bound = |n: u64| i64::try_from(n).unwrap_or(i64::MAX);
    int_as(value, what, bound(*range.start()), bound(*range.end()))
}

/// A real argument (an int or a float, numpy's scalars included; never a
/// bool or a string) in `span`.
///
/// # Errors
/// `InvalidRequest` naming `what`: not a number, not a number at all
/// (NaN), or out of range.
pub(crate) fn real(value: &Bound<'_, PyAny>, what: &str, span: Span) -> PyResult<f64> {
    let py = value.py();
    let unit = span.unit;
    let span_text = allowed(span);
    if is_bool(value) || value.is_instance_of::<PyString>() {
        return Err(bad(
            py,
            format!(
                "{what} must be a number {span_text}, not {}",
                type_name(value)
            ),
        ));
    }
    match value.extract::<f64>() {
        Ok(x) if x.is_nan() => Err(bad(
            py,
            format!("{what} is NaN: it must be a number {span_text}"),
        )),
        Ok(x) if span.contains(x) => Ok(x),
        Ok(x) => Err(bad(
            py,
            format!(
                "{what} {}{unit} is out of range: it must be {span_text}",
                Number(x)
            ),
        )),
        Err(e) if e.is_instance_of::<pyo3::exceptions::PyOverflowError>(py) => Err(bad(
            py,
            format!(
                "{what} {}{unit} is out of range: it must be {span_text}",
                huge(value)
            ),
        )),
        Err(e) if passes_through(py, &e) => Err(e),
        Err(_) => Err(bad(
            py,
            format!(
                "{what} must be a number {span_text}, not {}",
                type_name(value)
            ),
        )),
    }
}

/// A flag: `True` or `False` (numpy's bools too), never a truthy object:
/// `set_power("off")` must not switch the power on.
///
/// # Errors
/// `InvalidRequest` naming `what`.
pub(crate) fn flag(value: &Bound<'_, PyAny>, what: &str) -> PyResult<bool> {
    if is_bool(value) {
        if let Ok(b) = value.extract::<bool>() {
            return Ok(b);
        }
    }
    Err(bad(
        value.py(),
        format!("{what} must be True or False, not {}", type_name(value)),
    ))
}

/// A string argument; `choices` says what it may be, for the message.
///
/// # Errors
/// `InvalidRequest` naming `what`.
pub(crate) fn text(value: &Bound<'_, PyAny>, what: &str, choices: &str) -> PyResult<String> {
    match value.cast::<PyString>() {
        Ok(s) => string(s),
        Err(_) => Err(bad(
            value.py(),
            format!(
                "{what} must be a string ({choices}), not {}",
                type_name(value)
            ),
        )),
    }
}

/// An optional string argument (`None`: absent).
///
/// # Errors
/// As [`text`].
pub(crate) fn opt_text(
    value: Option<&Bound<'_, PyAny>>,
    what: &str,
    choices: &str,
) -> PyResult<Option<String>> {
    match value {
        Some(v) if !v.is_none() => text(v, what, choices).map(Some),
        _ => Ok(None),
    }
}

/// A firmware argument: `"7"`, `"8"`, `"seed"` (or `"rev7"`...), or the
/// int 7 or 8.
///
/// # Errors
/// `PortError` for anything else.
pub(crate) fn firmware(value: &Bound<'_, PyAny>) -> PyResult<firelink_testbed::emulated::Profile> {
    let name = match integer(value) {
        Integer::Fits(v) => v.to_string(),
        Integer::Raised(e) => return Err(e),
        _ => match value.cast::<PyString>() {
            Ok(s) => string(s)?,
            Err(_) => {
                return Err(crate::errors::error(
                    value.py(),
                    "PortError",
                    format!(
                        "firmware must be 7, 8 or \"seed\", not {}",
                        type_name(value)
                    ),
                ));
            }
        },
    };
    profile(value.py(), &name)
}

/// A byte string: `bytes`, `bytearray` or a `memoryview`.
///
/// # Errors
/// `InvalidRequest` naming `what`.
pub(crate) fn bytes(value: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<u8>> {
    if let Ok(b) = value.cast::<PyBytes>() {
        return Ok(b.as_bytes().to_vec());
    }
    if let Ok(b) = value.cast::<PyByteArray>() {
        return Ok(b.to_vec());
    }
    if type_name(value) == "memoryview" {
        if let Ok(b) = value.call_method0("tobytes") {
            if let Ok(b) = b.cast::<PyBytes>() {
                return Ok(b.as_bytes().to_vec());
            }
        }
    }
    Err(bad(
        value.py(),
        format!(
            "{what} must be bytes (or bytearray, memoryview), not {}",
            type_name(value)
        ),
    ))
}

/// What an array argument holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Values {
    /// Integers (numpy kinds `i` and `u`).
    Integers,
    /// Real numbers (numpy kinds `f`, `i` and `u`: integers convert).
    Reals,
}

/// `value` as a one-dimensional numpy array of `len` values of the kind
/// `kind` allows, converted to `dtype`; anything `numpy.asarray` takes
/// (arrays of any integer or float type, lists, tuples).
fn array<'py>(
    value: &Bound<'py, PyAny>,
    what: &str,
    len: usize,
    kind: Values,
) -> PyResult<Bound<'py, PyAny>> {
    let py = value.py();
    let expected = match kind {
        Values::Integers => "integers",
        Values::Reals => "numbers",
    };
    let not_array = || {
        bad(
            py,
            format!(
                "{what} takes an array of {len} {expected}, not {}",
                type_name(value)
            ),
        )
    };
    let numpy = py.import("numpy")?;
    let arr = numpy.call_method1("asarray", (value,)).map_err(|e| {
        if passes_through(py, &e) {
            e
        } else {
            not_array()
        }
    })?;
    let ndim: usize = arr.getattr("ndim")?.extract()?;
    if ndim != 1 {
        if ndim == 0 {
            return Err(not_array());
        }
        let shape = string(&arr.getattr("shape")?.str()?)?;
        return Err(bad(
            py,
            format!(
                "{what} takes a one-dimensional array of {len} {expected}, not one of shape {shape}"
            ),
        ));
    }
    let n: usize = arr.len()?;
    if n != len {
        return Err(bad(py, format!("{what} got {n} values for {len} axes")));
    }
    let dtype = arr.getattr("dtype")?;
    let code: String = dtype.getattr("kind")?.extract()?;
    let name = string(&dtype.str()?)?;
    let target = match (kind, code.as_str()) {
        (Values::Integers, "i") => "int64",
        (Values::Integers, "u") => "uint64",
        (Values::Reals, "f" | "i" | "u") => "float64",
        (Values::Integers, "f") => {
            return Err(bad(
                py,
                format!(
                    "{what} takes integers, not {name} values (round them first, e.g. numpy.rint(x).astype(int))"
                ),
            ));
        }
        _ => {
            return Err(bad(
                py,
                format!("{what} takes {expected}, not {name} values"),
            ));
        }
    };
    numpy.call_method1("ascontiguousarray", (arr, target))
}

/// An array argument of `len` integers (any numpy integer type, or a list).
///
/// # Errors
/// `InvalidRequest` naming `what`: not an array, not one-dimensional, the
/// wrong length, not integers.
pub(crate) fn int_array(value: &Bound<'_, PyAny>, what: &str, len: usize) -> PyResult<Vec<i64>> {
    if let Ok(a) = value.cast::<PyArray1<i64>>() {
        if let Ok(ro) = a.try_readonly() {
            if let Ok(s) = ro.as_slice() {
                if s.len() == len {
                    return Ok(s.to_vec());
                }
            }
        }
    }
    let arr = array(value, what, len, Values::Integers)?;
    if let Ok(a) = arr.cast::<PyArray1<i64>>() {
        return Ok(a.to_vec()?);
    }
    let a = arr.cast::<PyArray1<u64>>()?;
    Ok(a.to_vec()?
        .into_iter()
        .map(|v| i64::try_from(v).unwrap_or(i64::MAX))
        .collect())
}

/// An array argument of `len` real numbers (any numpy integer or float
/// type, or a list).
///
/// # Errors
/// `InvalidRequest` naming `what`: not an array, not one-dimensional, the
/// wrong length, not numbers.
pub(crate) fn real_array(value: &Bound<'_, PyAny>, what: &str, len: usize) -> PyResult<Vec<f64>> {
    if let Ok(a) = value.cast::<PyArray1<f64>>() {
        if let Ok(ro) = a.try_readonly() {
            if let Ok(s) = ro.as_slice() {
                if s.len() == len {
                    return Ok(s.to_vec());
                }
            }
        }
    }
    let arr = array(value, what, len, Values::Reals)?;
    Ok(arr.cast::<PyArray1<f64>>()?.to_vec()?)
}

/// The most cycles one call runs or measures (the command line's rule,
/// `firelink_testbed::limits::CYCLES`; a call may also run 0).
pub(crate) const MAX_CYCLES: i64 = *firelink_testbed::limits::CYCLES.end() as i64;

/// The emulated firmware a name gives (`7`, `8`, `9`, `seed`).
pub(crate) fn profile(py: Python<'_>, name: &str) -> PyResult<Profile> {
    port_spec::firmware_of(name).ok_or_else(|| {
        crate::errors::error(
            py,
            "PortError",
            format!("unknown firmware {name:?}: expected 7, 8, 9 or seed"),
        )
    })
}

/// A watchdog argument: a period in ms (int or float) or the string
/// `"off"`; the one rule is `WatchdogSetting` (one tick to 65535 ticks).
pub(crate) fn watchdog_setting(
    py: Python<'_>,
    value: &Bound<'_, PyAny>,
) -> PyResult<WatchdogSetting> {
    let range = WatchdogSetting::RANGE;
    if let Ok(text) = value.cast::<PyString>() {
        let text = string(text)?;
        return WatchdogSetting::parse(&text).map_err(|e| match e {
            firelink_wire::qla::registers::WatchdogParseError::NotANumber => bad(
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
                type_name(value)
            ),
        )
    };
    if is_bool(value) {
        return Err(not_a_period());
    }
    match value.extract::<f64>() {
        // NaN and every out-of-range period: the setting's own message.
        Ok(ms) => WatchdogSetting::from_ms(ms).map_err(|e| bad(py, e.to_string())),
        Err(e) if e.is_instance_of::<pyo3::exceptions::PyOverflowError>(py) => Err(bad(
            py,
            format!(
                "watchdog period {} ms is out of range: {range}, or \"off\"",
                huge(value)
            ),
        )),
        Err(_) => Err(not_a_period()),
    }
}
