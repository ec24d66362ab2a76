//! The servo cycle allocates nothing: setup may allocate, then thousands of
//! cycles of read -> compute -> check -> write for the 28-axis dVRK run
//! under a counting allocator and must not touch the heap.
//!
//! The counter is per thread (`allocation-counter`): it sees only what the
//! measured closure's own thread allocates. A process-wide counter is not
//! enough: libtest's main thread finishes its bookkeeping for the test it
//! just spawned (about 4 allocations, 900 bytes) while the test runs, and on
//! a loaded machine that lands inside the measured region. The last test
//! here proves that another thread's allocations are not counted.

use firelink_control::config::{EncoderConfig, presets};
use firelink_control::homing::{Homing, HomingSettings, HomingStep};
use firelink_control::pid::{Measurement, Pid, Setpoint};
use firelink_control::safety::{JointSample, SafetyMonitor};
use firelink_control::trajectory::{Motion, PointToPoint, Sinusoid};
use firelink_control::{FaultKind, FaultReport, Lifecycle, PowerStatus};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

#[test]
fn servo_cycle_does_not_allocate() {
    // ---- setup: allocation allowed ----
    let config = presets::dvrk_seed000();
    let joints: Vec<_> = config.joints().map(|j| *j.actuator).collect();
    let n = joints.len();
    let mut pids: Vec<Pid> = joints
        .iter()
        .map(|a| Pid::new(a.simulation.unwrap().pid.unwrap(), a.drive.maximum_current).unwrap())
        .collect();
    let motions: Vec<Motion> = joints
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let l = a.encoder.position_limits_soft;
            let lim = a.limits.unwrap();
            let (v, acc) = (0.5 * lim.velocity, lim.acceleration.unwrap());
            if i % 2 == 0 {
                Motion::PointToPoint(PointToPoint::new(0.0, 0.5 * l.upper, v, acc).unwrap())
            } else {
                Motion::Sinusoid(Sinusoid::new(0.1 * l.upper, 0.5, 0.0, 0.0, 0.5).unwrap())
            }
        })
        .collect();
    let mut life = Lifecycle::from_config(&config);
    let mut safety = SafetyMonitor::from_config(&config);
    let mut homing = Homing::from_config(
        &config,
        HomingSettings {
            averaging_samples: 20,
            verify_samples: 20,
        },
    );
    let boards = config.board_set();
    // Joint state of a toy plant that follows its setpoint closely (the
    // point here is the heap, not control quality).
    let mut position = vec![0.0f64; n];
    let mut encoder_bits = vec![EncoderConfig::MIDRANGE; n];
    let mut pot = vec![0.0f64; n];
    let mut enc = vec![0.0f64; n];
    let mut samples = vec![JointSample::default(); n];
    let mut dac = vec![0u16; n];
    let dt = 1e-3;

    // ---- the cycles: no allocation allowed ----
    let mut homed = false;
    let mut checksum = 0u64;
    let mut report = None;
    let stats = allocation_counter::measure(|| {
        life.configure(boards).unwrap();
        homing.start();
        for cycle in 0..3000u64 {
            let now = cycle as f64 * dt;
            life.check_cycle(boards, now, cycle).unwrap();
            // read: raw -> SI
            for i in 0..n {
                let a = &joints[i];
                enc[i] = a.encoder.bits_to_position(encoder_bits[i]);
                let pot_bits = a.potentiometer.unwrap().position_to_bits(position[i]);
                pot[i] = a.potentiometer.unwrap().bits_to_position(pot_bits);
            }
            if !homed {
                match homing.step(&pot, &enc) {
                    HomingStep::PreloadReady => {
                        for i in 0..n {
                            encoder_bits[i] = joints[i]
                                .encoder
                                .position_to_preload_bits(homing.targets()[i]);
                        }
                        homing.preload_written().unwrap();
                    }
                    HomingStep::Done => {
                        homed = true;
                        life.activate(PowerStatus {
                            powered: boards,
                            amplifiers_enabled: boards,
                        })
                        .unwrap();
                        safety.restart_timers();
                    }
                    HomingStep::Failed(e) => panic!("{e}"),
                    _ => {}
                }
                continue;
            }
            // update
            let t = now - 0.05;
            for i in 0..n {
                let s = motions[i].sample(t);
                let amps = pids[i].update(
                    Setpoint {
                        position: s.position,
                        velocity: s.velocity,
                        feedforward: 0.0,
                    },
                    Measurement {
                        position: enc[i],
                        // The toy plant tracks the setpoint's velocity.
                        velocity: s.velocity,
                    },
                    dt,
                );
                samples[i] = JointSample {
                    setpoint: s.position,
                    position: enc[i],
                    velocity: s.velocity,
                    current: amps,
                    potentiometer: Some(pot[i]),
                };
                dac[i] = joints[i].drive.current_to_bits(amps);
            }
            // check
            if let Some(report) = safety.check(now, cycle, &samples) {
                panic!("{report}");
            }
            life.require_motion().unwrap();
            // write: SI -> raw, and a toy plant moves the joint
            for i in 0..n {
                let amps = joints[i].drive.bits_to_commanded_current(dac[i]);
                position[i] += 0.9 * (samples[i].setpoint - position[i]) + 1e-3 * amps * dt;
                encoder_bits[i] = joints[i].encoder.position_to_preload_bits(position[i]);
                checksum = checksum.wrapping_add(u64::from(dac[i]));
            }
        }
        // A fault report is built and latched without allocating, too.
        let fault = FaultReport::new(
            3.0,
            3000,
            FaultKind::FollowingError {
                joint: safety.limits()[3].label,
                error: 0.5,
                limit: 0.35,
            },
        );
        life.fault(fault);
        report = Some(fault);
    });
    let report = report.unwrap();

    assert!(homed, "homing did not finish");
    assert!(checksum > 0);
    assert_eq!(stats.count_total, 0, "{stats:?}");
    assert_eq!(life.fault_report().unwrap().kind, report.kind);
}

/// The counter sees this thread's allocations (so a zero above is not
/// vacuous) and not another thread's, whatever the scheduler does.
#[test]
fn counter_sees_this_thread_only() {
    let own = allocation_counter::measure(|| {
        let v: Vec<u64> = std::hint::black_box(Vec::with_capacity(16));
        drop(v);
    });
    assert_eq!(own.count_total, 1);
    assert_eq!(own.bytes_total, 16 * 8);

    // The handshake uses atomics: blocking channels would allocate their
    // wait context on this thread.
    static GO: AtomicBool = AtomicBool::new(false);
    static ALLOCATED: AtomicUsize = AtomicUsize::new(0);
    let worker = std::thread::spawn(|| {
        while !GO.load(Ordering::Acquire) {
            std::thread::yield_now();
        }
        let v: Vec<u8> = std::hint::black_box(vec![7; 900]);
        ALLOCATED.store(v.len(), Ordering::Release);
    });
    let other = allocation_counter::measure(|| {
        // The other thread allocates while this thread is being measured.
        GO.store(true, Ordering::Release);
        while ALLOCATED.load(Ordering::Acquire) == 0 {
            std::thread::yield_now();
        }
    });
    worker.join().unwrap();
    assert_eq!(ALLOCATED.load(Ordering::Acquire), 900);
    assert_eq!(other.count_total, 0, "{other:?}");
}
