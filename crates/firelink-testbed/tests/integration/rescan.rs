//! The scan the tests share against an emulator in this process.

use std::time::Duration;

use firelink_host::qla::scan::{ScanReport, scan};
use firelink_host::udp::UdpPort;

/// Scan `port` until `boards` boards are found (at most 20 scans; asserts
/// that they were). Absent node IDs cost a time-out each, so the port's is
/// made short here; a board whose answer came later (the server thread
/// kept waiting for a CPU) is found by a later scan: bounded by attempts,
/// not by time.
pub fn until_all_found(port: &mut UdpPort, boards: usize) -> ScanReport {
    port.set_timeout(Duration::from_millis(50));
    let mut scans = 0;
    let report = loop {
        let report = scan(port).expect("scan");
        scans += 1;
        if report.boards.len() == boards || scans == 20 {
            break report;
        }
    };
    assert_eq!(report.boards.len(), boards, "{scans} scans");
    report
}
