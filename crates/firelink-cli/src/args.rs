//! Every value the command line accepts, checked at the boundary by clap:
//! the number rules are [`firelink_testbed::limits`] (out of range, not
//! finite or not a number is a usage error, exit status 2, with one line
//! naming the option, the value and the range); the named choices
//! (firmware, FPGA, hardware) are the value parsers of
//! [`firelink_testbed::cli_args`]; the protocol and the UDP wait are the
//! host library's own (`firelink_host::qla::scan::Protocol`,
//! `firelink_host::udp::WaitMode`, clap's `ValueEnum` behind its `clap`
//! feature). The options of a request the testbed owns (such as `demo`'s)
//! name these rules themselves.

pub use firelink_testbed::limits::{
    WatchdogSetting, board_id, cycles, measured, node_id, parse_number, quadlets, rate_hz_or_max,
    servo_period_us, servo_rate_hz, timeout_ms, watchdog,
};

/// Whether the default run should be quiet about progress (tests).
pub fn quiet() -> bool {
    std::env::var_os("FIRELINK_QUIET").is_some()
}
