//! The MAHRU demo walks at the seed's 2 ms period without an error.

use std::time::Duration;

use firelink_testbed::mahru::{MahruConfig, MahruDemoOptions, run_mahru_demo};

#[test]
fn walks_at_2_ms_with_no_error() {
    let options = MahruDemoOptions {
        config: MahruConfig::seed002(),
        duration_s: 2.0,
        period: Some(Duration::from_millis(2)),
        find_fastest: true,
    };
    let report = run_mahru_demo(&options, |p| eprintln!("{p}")).unwrap();
    eprintln!("{report}");
    report.verdict().unwrap();
}
