//! Issue 33's two levels of detail give one answer: the soak (its faulted
//! cycles at the packet level, the fault-free stretches fast), the Snake
//! system and MAHRU report the same at `--detail fast` as at `--detail
//! packet`, and the report counts which level ran. (The dVRK demo is
//! compared cycle by cycle in `cycle_compare`'s tests; `firelink sim`'s
//! phase tables at both levels in the CLI's `sim_phases`.)

use firelink_bus::Detail;
use firelink_testbed::demo::DemoFault;
use firelink_testbed::dvrk::soak::{self, SoakSettings};
use firelink_testbed::mahru::{MahruConfig, MahruDemoOptions, run_mahru_demo};
use firelink_testbed::snake::demo::{SnakeDemoOptions, run_snake_demo};
use serde_json::Value;

/// `report` as JSON without the keys named in `drop` (anywhere).
fn without(report: &impl serde::Serialize, drop: &[&str]) -> Value {
    fn strip(v: &mut Value, drop: &[&str]) {
        match v {
            Value::Object(map) => {
                map.retain(|k, _| !drop.contains(&k.as_str()));
                map.values_mut().for_each(|x| strip(x, drop));
            }
            Value::Array(items) => items.iter_mut().for_each(|x| strip(x, drop)),
            _ => {}
        }
    }
    let mut v = serde_json::to_value(report).expect("a report serialises");
    strip(&mut v, drop);
    v
}

#[test]
fn the_soak_reports_the_same_at_both_levels_its_faulted_cycles_at_the_packet_level() {
    let at = |detail: Detail| {
        let settings = SoakSettings {
            cycles: 3_000,
            seed: 5,
            detail,
            ..SoakSettings::default()
        };
        soak::run(&settings, |_, _| {}).expect("the soak runs")
    };
    let (fast, packet) = (at(Detail::Fast), at(Detail::Packet));
    assert_eq!(without(&fast, &["detail"]), without(&packet, &["detail"]));
    assert!(fast.injected > 0, "faults were injected");
    let d = fast.detail;
    assert!(d.fast_cycles > d.packet_level_cycles, "{d}");
    assert!(d.packet_level_cycles_why.fault > 0, "{d}");
    assert_eq!(d.packet_level_cycles_why.chosen, 0, "{d}");
    let p = packet.detail;
    assert_eq!(p.fast_cycles, 0, "{p}");
    assert_eq!(p.fast_packets, 0, "{p}");
    assert_eq!(
        p.packet_level_cycles_why.chosen, p.packet_level_cycles,
        "{p}"
    );
    // Every cycle is counted at both levels alike.
    assert_eq!(
        d.fast_cycles + d.packet_level_cycles,
        p.packet_level_cycles,
        "{d} / {p}"
    );
}

#[test]
fn the_snake_system_runs_the_same_at_both_levels() {
    let at = |detail: Detail, fault: DemoFault| {
        let options = SnakeDemoOptions {
            duration_s: 0.3,
            fault,
            find_max_rate: false,
            detail,
            ..SnakeDemoOptions::default()
        };
        run_snake_demo(&options, None, |_| {}).expect("the demo runs")
    };
    // Wall-clock figures and the count of what ran differ; nothing else.
    let wall = [
        "wall_time_s",
        "speed_vs_real_time",
        "cycle_time_us",
        "compute_time_us",
        "late_cycles",
        "detail",
    ];
    for fault in [DemoFault::None, DemoFault::BoardLoss] {
        let (fast, packet) = (at(Detail::Fast, fault), at(Detail::Packet, fault));
        assert_eq!(without(&fast, &wall), without(&packet, &wall), "{fault}");
        let d = fast.demo.detail.expect("a simulated bus");
        if fault == DemoFault::None {
            assert!(d.fast_cycles >= 300, "{d}");
            assert_eq!(d.packet_level_cycles, 0, "{d}");
        } else {
            // The lost board's packets (a muted node) ran at the packet
            // level, the cycles before it fast.
            assert!(d.fast_cycles > 0, "{fault}: {d}");
            assert!(d.packet_level_cycles_why.fault > 0, "{fault}: {d}");
        }
        let p = packet.demo.detail.expect("a simulated bus");
        assert_eq!(p.fast_cycles, 0, "{fault}: {p}");
        assert_eq!(d.fast_cycles + d.packet_level_cycles, p.packet_level_cycles);
    }
}

#[test]
fn mahru_walks_the_same_at_both_levels() {
    let at = |detail: Detail| {
        let options = MahruDemoOptions {
            config: MahruConfig::seed002(),
            duration_s: 0.2,
            period: None,
            find_fastest: false,
            detail,
        };
        run_mahru_demo(&options, |_| {}).expect("the demo runs")
    };
    let (fast, packet) = (at(Detail::Fast), at(Detail::Packet));
    assert_eq!(without(&fast, &["detail"]), without(&packet, &["detail"]));
    assert_eq!(fast.detail.fast_cycles, fast.periods, "{}", fast.detail);
    assert_eq!(packet.detail.packet_level_cycles, packet.periods);
    assert!(fast.detail.batched_deliveries > 0);
}

#[test]
fn the_bench_measures_the_same_sim_points_at_both_levels_and_counts_them() {
    use firelink_host::qla::scan::Protocol;
    use firelink_testbed::dvrk::bench::{BenchOptions, BenchReport, BenchTransport, run_bench};
    let at = |detail: Detail| {
        let options = BenchOptions {
            transports: vec![BenchTransport::Sim],
            boards: vec![2, 8],
            protocols: vec![Protocol::Sequential, Protocol::Broadcast],
            cycles: 30,
            detail,
            ..BenchOptions::default()
        };
        run_bench(&options, |_, _, _| {}).expect("the bench runs")
    };
    let (fast, packet) = (at(Detail::Fast), at(Detail::Packet));
    // The I/O figures are the simulated bus's times: the same to the bit.
    let io = |r: &BenchReport| {
        r.results
            .iter()
            .map(|p| {
                (
                    p.boards,
                    p.protocol,
                    p.io_time_us,
                    p.read_us,
                    p.write_us,
                    p.errors,
                )
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(io(&fast), io(&packet));
    assert_eq!((fast.detail, packet.detail), (Detail::Fast, Detail::Packet));
    for (f, p) in fast.results.iter().zip(&packet.results) {
        let (f, p) = (
            f.detail.expect("a sim point"),
            p.detail.expect("a sim point"),
        );
        // 20 warm-up cycles and the measured ones, every one counted.
        assert_eq!(f.fast_cycles, 50, "{f}");
        assert_eq!(p.packet_level_cycles_why.chosen, 50, "{p}");
        assert_eq!(f.fast_packets, p.packet_level_packets(), "{f} / {p}");
    }
    let text = packet.to_string();
    assert!(
        text.contains("Level of detail of the simulated buses (--detail packet"),
        "{text}"
    );
    assert!(
        text.contains("cycles 0 fast, 50 at the packet level (chosen 50)"),
        "{text}"
    );
}
