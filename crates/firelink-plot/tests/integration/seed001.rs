//! Seed 001's Fig. 20 and 21 as a PNG, drawn from a real (short)
//! reproduction of its measurements.

use firelink_testbed::snake::bench::{Seed001Options, run_seed001_bench};

#[test]
fn seed001_figures_are_drawn_from_the_reproduction() {
    let mut report = run_seed001_bench(&Seed001Options {
        iterations: 500,
        sweep_step: 16,
        sweep_repeats: 1,
        cycles: 10,
        seed: 3,
    })
    .unwrap();
    let path = std::env::var_os("FIRELINK_KEEP_PLOT")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::env::temp_dir().join(format!("firelink-seed001-{}.png", std::process::id()))
        });
    firelink_plot::seed001(&report, &path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    if std::env::var_os("FIRELINK_KEEP_PLOT").is_none() {
        std::fs::remove_file(&path).unwrap();
    }
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    assert_eq!((w, h), (1400, 620));
    assert!(bytes.len() > 20_000, "{} bytes", bytes.len());
    // No measurements, no figure.
    report.block_read.clear();
    assert!(firelink_plot::seed001(&report, &path).is_err());
}
