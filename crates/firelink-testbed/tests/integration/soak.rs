//! The fault soak and the watchdog proof, short versions: every injected
//! fault accounted for, no corrupted command ever applied, amplifiers off
//! whenever the safety chain says so, every board's watchdog within its
//! bound; and the same seed gives the same report.

use firelink_testbed::dvrk::soak::{self, SoakSettings};
use firelink_testbed::dvrk::watchdog;

fn settings(cycles: u64, seed: u64) -> SoakSettings {
    SoakSettings {
        cycles,
        seed,
        ..SoakSettings::default()
    }
}

#[test]
fn twenty_thousand_cycles_with_one_packet_in_a_hundred_faulted() {
    let r = soak::run(&settings(20_000, 7), |_, _| {}).unwrap();
    assert!(r.cycles >= 20_000);
    // About 1 % of everything on the bus was faulted, of every kind.
    assert!(
        r.packet_fault_share > 0.006 && r.packet_fault_share < 0.014,
        "{}",
        r.packet_fault_share
    );
    for kind in [
        "drop",
        "bit_flip",
        "short_delay",
        "long_delay",
        "duplicate",
        "truncate",
    ] {
        let o = r.by_kind.get(kind).copied().unwrap_or_default();
        assert!(o.injected > 50, "{kind}: {o:?}");
    }
    assert!(
        r.by_kind
            .keys()
            .any(|k| k == "bus_reset" || k == "babble" || k == "unplug")
    );
    assert_eq!(r.injected, r.detected + r.harmless + r.undetected);
    assert_eq!(r.undetected, 0, "{:#?}", r.undetected_examples);
    assert_eq!(r.bad_commands_applied, 0);
    assert_eq!(r.amplifier_on_after_off, 0);
    // The fault paths ran, and the robot came back every time.
    assert!(r.robot_faults > 100, "{}", r.robot_faults);
    assert!(r.rearms + 1 >= r.robot_faults);
    assert!(r.passed());
}

#[test]
fn the_same_seed_gives_the_same_report() {
    let a = serde_json::to_string(&soak::run(&settings(3_000, 11), |_, _| {}).unwrap()).unwrap();
    let b = serde_json::to_string(&soak::run(&settings(3_000, 11), |_, _| {}).unwrap()).unwrap();
    assert_eq!(a, b);
    let c = serde_json::to_string(&soak::run(&settings(3_000, 12), |_, _| {}).unwrap()).unwrap();
    assert_ne!(a, c);
}

#[test]
fn the_period_sets_the_virtual_time_and_a_rate_gives_the_same_soak() {
    let at = |period: &str| {
        let s = SoakSettings {
            period: period.parse().unwrap(),
            ..settings(3_000, 11)
        };
        soak::run(&s, |_, _| {}).unwrap()
    };
    let by_period = at("1ms");
    assert_eq!(by_period.period_us, 1000.0);
    // 3000 cycles of 1 ms (re-arming included): at least 3 s of virtual time.
    assert!(by_period.virtual_s >= 3.0, "{}", by_period.virtual_s);
    let by_rate = at("1kHz");
    assert_eq!(
        serde_json::to_string(&by_period).unwrap(),
        serde_json::to_string(&by_rate).unwrap()
    );
    // The default is 6 kHz, as before the period was a setting.
    let default = soak::run(&settings(3_000, 11), |_, _| {}).unwrap();
    assert_eq!(default.period_us, 1e6 / 6000.0);
    assert!(default.virtual_s < by_period.virtual_s);
}

#[test]
fn amplifiers_go_off_within_the_watchdog_period_every_time() {
    let r = watchdog::run(40, 3, SoakSettings::default().period).unwrap();
    assert_eq!(r.observations, 40 * 8);
    assert_eq!(r.within_bound, r.observations, "{r:?}");
    assert!(r.passed());
    // Off no later than one tick after the period, and not early.
    assert!(r.over_period_us[3] <= r.tick_us, "{r:?}");
    assert!(r.over_period_us[0] > -1.0, "{r:?}");
}

/// The proof runs the robot at the period it is given (the soak's
/// `--period`), and its table says so: at 1 ms the host can stop up to a
/// whole millisecond after its last write, which a 6 kHz loop (a write
/// every 167 us) never shows.
#[test]
fn the_watchdog_proof_runs_at_the_period_it_is_given() {
    let r = watchdog::run(40, 3, "1ms".parse().unwrap()).unwrap();
    assert!(r.passed(), "{r:?}");
    assert_eq!(r.servo_period_us, 1000.0);
    let six_khz = 1e6 / 6000.0;
    assert!(r.after_stop_us[0] < r.period_us - 2.0 * six_khz, "{r:?}");
    assert!(r.to_string().contains("servo period 1000.000 us"), "{r}");
    let default = watchdog::run(40, 3, SoakSettings::default().period).unwrap();
    assert!(
        default.after_stop_us[0] > default.period_us - 2.0 * six_khz,
        "{default:?}"
    );
}
