//! Fig. 11 as a PNG: a real image of the stated size from a real
//! benchmark report; no report, no figure.

use firelink_host::qla::scan::Protocol;
use firelink_testbed::dvrk::bench::{BenchOptions, BenchTransport, run_bench};

fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "not a PNG");
    assert_eq!(&bytes[12..16], b"IHDR");
    let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    (w, h)
}

#[test]
fn fig11_is_drawn_from_a_benchmark_report() {
    let report = run_bench(
        &BenchOptions {
            transports: vec![BenchTransport::Sim],
            boards: vec![2, 4, 8, 62],
            protocols: vec![Protocol::Sequential, Protocol::Broadcast],
            cycles: 10,
            ..BenchOptions::default()
        },
        |_, _, _| {},
    )
    .unwrap();
    let path = std::env::temp_dir().join(format!("firelink-fig11-{}.png", std::process::id()));
    firelink_plot::fig11(&report, &path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(png_size(&bytes), (1000, 640));
    // A plot with lines, markers and text is far from a blank image.
    assert!(bytes.len() > 20_000, "{} bytes", bytes.len());
}

#[test]
fn an_empty_report_draws_nothing() {
    let mut report = run_bench(
        &BenchOptions {
            transports: vec![BenchTransport::Sim],
            boards: vec![1],
            protocols: vec![Protocol::Sequential],
            cycles: 1,
            ..BenchOptions::default()
        },
        |_, _, _| {},
    )
    .unwrap();
    report.results.clear();
    let path = std::env::temp_dir().join("firelink-never-written.png");
    let e = firelink_plot::fig11(&report, &path).unwrap_err();
    assert!(e.to_string().contains("nothing to plot"), "{e}");
    assert!(!path.exists());
}
