//! The real-time setup the demo takes before its servo loop (SCHED_FIFO,
//! locked memory, timer slack): [`firelink_testbed::realtime`].

pub use firelink_testbed::realtime::*;
