//! Every value the command line accepts, checked at the boundary by clap:
//! the number rules are [`firelink_testbed::limits`] (out of range, not
//! finite or not a number is a usage error, exit status 2, with one line
//! naming the option, the value and the range); the named choices
//! (firmware, FPGA, hardware) are the enums here; the protocol and the UDP
//! wait are the host library's own (`firelink_host::qla::scan::Protocol`,
//! `firelink_host::udp::WaitMode`, clap's `ValueEnum` behind its `clap`
//! feature).

pub use firelink_testbed::cli_args::{arbitration, firmware, fpga, hardware, speed};
pub use firelink_testbed::limits::{
    CpuLatencyRequest as CpuLatencyArg, WatchdogSetting, board_count, board_id, can_cycles,
    cpu_latency, cycles, mahru_servo_period, measured, node_id, parse_number, period_us,
    probability, quadlets, rate_hz_or_max, seconds_or_forever, servo_period_us, servo_rate,
    timeout_ms, timings, wait_us, watchdog,
};

/// Whether the default run should be quiet about progress (tests).
pub fn quiet() -> bool {
    std::env::var_os("FIRELINK_QUIET").is_some()
}
