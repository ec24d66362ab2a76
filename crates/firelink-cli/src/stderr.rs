//! Lines for the person at the terminal (progress, warnings, the final
//! error), written to stderr without ever panicking: when stderr is a pipe
//! whose reader has gone (`firelink demo 2>&1 | head`), the line is lost
//! and the program goes on, where `eprintln!` would panic mid-run and leave
//! the robot's power-down to the boards' watchdogs.

/// `eprintln!` that ignores a failed write (see the module docs).
macro_rules! say {
    () => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr());
    }};
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

/// `eprint!` that ignores a failed write (see the module docs).
macro_rules! say_no_newline {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let mut err = std::io::stderr();
        let _ = write!(err, $($arg)*);
        let _ = err.flush();
    }};
}
