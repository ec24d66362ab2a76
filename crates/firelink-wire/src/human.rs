//! Numbers in messages, as a person would write them.
//!
//! Rust's `Display` for `f64` writes every digit: `1e300` comes out as a
//! 301-character integer and `1e-7` as `0.0000001`. Error messages echo
//! what a person typed (a flag, a configuration value), so they go through
//! [`Number`]: plain decimals in the everyday range, scientific notation
//! outside it, and the words for the values that are not numbers.

use core::fmt;

/// An `f64` shown as a person writes it: `20`, `0.5`, `1e300`, `1e-7`,
/// `NaN`, `inf`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Number(pub f64);

impl fmt::Display for Number {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        if x.is_nan() {
            return f.write_str("NaN");
        }
        if x.is_infinite() {
            return f.write_str(if x > 0.0 { "inf" } else { "-inf" });
        }
        let a = x.abs();
        if a != 0.0 && !(1e-4..1e9).contains(&a) {
            write!(f, "{x:e}")
        } else {
            write!(f, "{x}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::format;

    #[test]
    fn numbers_read_as_written() {
        let shown = |x: f64| format!("{}", Number(x));
        assert_eq!(shown(20.0), "20");
        assert_eq!(shown(0.5), "0.5");
        assert_eq!(shown(-3.25), "-3.25");
        assert_eq!(shown(1e300), "1e300");
        assert_eq!(shown(1e-7), "1e-7");
        assert_eq!(shown(1.5e12), "1.5e12");
        assert_eq!(shown(f64::NAN), "NaN");
        assert_eq!(shown(f64::NEG_INFINITY), "-inf");
        assert_eq!(shown(0.0), "0");
        assert_eq!(shown(341.0), "341");
    }
}
