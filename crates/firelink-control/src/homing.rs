//! Homing against the potentiometers, as a pure state machine.
//!
//! Quadrature encoders only count relative motion, so at power-up they read
//! wherever their counter starts. The potentiometers are absolute but noisy.
//! Homing makes the encoders agree with the pots:
//!
//! 1. **Averaging**: for `averaging_samples` cycles, average each joint's pot
//!    position and encoder position. The joints must be still: a pot that
//!    wanders more than the joint's tolerance fails homing.
//! 2. **Preload ready**: [`Homing::targets`] holds, per joint, the position
//!    the encoder should read now (the mean pot position, moved by any
//!    encoder motion since). The runner either writes it to the board as an
//!    encoder preload ([`EncoderConfig::position_to_preload_bits`]) and calls
//!    [`Homing::preload_written`], or keeps the encoders as they are and adds
//!    [`Homing::offsets`] in software ([`Homing::use_software_offsets`]).
//! 3. **Verifying**: for `verify_samples` cycles, compare pot and corrected
//!    encoder; if their mean difference exceeds the tolerance the joint is
//!    named in a [`HomingError::Mismatch`].
//! 4. **Done**.
//!
//! A joint whose tolerance is 0 (v6: `distance` 0) is preloaded but not
//! checked; a joint without a potentiometer keeps its encoder (target = its
//! encoder position, offset 0) and is not checked.
//!
//! Buffers are allocated by [`Homing::new`]; [`Homing::step`] never
//! allocates and never panics (wrong slice lengths and NaN readings are
//! errors).
//!
//! [`EncoderConfig::position_to_preload_bits`]: crate::config::EncoderConfig::position_to_preload_bits

use crate::config::{IoConfig, Measured};
use crate::label::Label;

/// One joint as homing sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HomingJoint {
    /// Name for errors.
    pub label: Label,
    /// Largest allowed |pot - encoder| after homing, and largest pot wander
    /// while averaging (rad or m); 0 disables both checks.
    pub tolerance: f64,
    /// Whether the joint has a potentiometer.
    pub has_potentiometer: bool,
}

/// How many samples each phase takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HomingSettings {
    /// Cycles of averaging before the preload (>= 1).
    pub averaging_samples: u32,
    /// Cycles of verification after it (>= 1).
    pub verify_samples: u32,
}

impl Default for HomingSettings {
    /// 50 cycles each (50 ms at 1 kHz).
    fn default() -> Self {
        HomingSettings {
            averaging_samples: 50,
            verify_samples: 50,
        }
    }
}

/// Why homing failed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum HomingError {
    /// The slices passed to [`Homing::step`] do not have one entry per joint.
    #[error(
        "homing expects one reading per joint ({expected}), got {pot} potentiometer and {encoder} encoder readings"
    )]
    WrongJointCount {
        /// Joints configured.
        expected: usize,
        /// Pot values given.
        pot: usize,
        /// Encoder values given.
        encoder: usize,
    },
    /// A reading is NaN or infinite.
    #[error("{joint}: {what} reading is not a finite number")]
    InvalidReading {
        /// The joint.
        joint: Label,
        /// `"potentiometer"` or `"encoder"`.
        what: &'static str,
    },
    /// The pot moved too much while averaging: the joint is not still or the
    /// pot is noisy.
    #[error(
        "{joint}: the potentiometer moved {} while homing averaged it, more than its tolerance of {} (rad or m): the joint is not still, or its potentiometer is noisy",
        Measured(*.spread),
        Measured(*.tolerance)
    )]
    PotUnsteady {
        /// The joint.
        joint: Label,
        /// Max - min of the pot over the averaging window.
        spread: f64,
        /// The tolerance.
        tolerance: f64,
    },
    /// After homing, pot and encoder still disagree.
    #[error(
        "{joint}: after homing the potentiometer reads {} and the encoder {}: they differ by {:+}, more than the tolerance of {} (rad or m)",
        Measured(*.potentiometer),
        Measured(*.encoder),
        Measured(*.difference),
        Measured(*.tolerance)
    )]
    Mismatch {
        /// The joint.
        joint: Label,
        /// Mean pot position over the verification window.
        potentiometer: f64,
        /// Mean corrected encoder position over it.
        encoder: f64,
        /// Their difference.
        difference: f64,
        /// The tolerance.
        tolerance: f64,
    },
    /// A method was called in the wrong phase.
    #[error("homing: {action} is not possible while {phase}")]
    OutOfOrder {
        /// What was asked.
        action: &'static str,
        /// The phase homing was in.
        phase: HomingPhase,
    },
}

/// Where homing is (shown in words: `averaging`, ...).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HomingPhase {
    /// Not started.
    Idle,
    /// Averaging pots and encoders.
    Averaging,
    /// Targets ready; waiting for the preload (or the software offsets).
    PreloadReady,
    /// Checking pot against encoder.
    Verifying,
    /// Homed.
    Done,
    /// Failed; see the error returned by `step`.
    Failed,
}

impl core::fmt::Display for HomingPhase {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            HomingPhase::Idle => "not started",
            HomingPhase::Averaging => "averaging",
            HomingPhase::PreloadReady => "waiting for the encoder preload",
            HomingPhase::Verifying => "verifying",
            HomingPhase::Done => "done",
            HomingPhase::Failed => "failed",
        })
    }
}

/// What [`Homing::step`] says after each cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HomingStep {
    /// Not started: call [`Homing::start`].
    Idle,
    /// Averaging; `remaining` more cycles.
    Averaging {
        /// Cycles left.
        remaining: u32,
    },
    /// Write [`Homing::targets`] as preloads, then call
    /// [`Homing::preload_written`] (or call [`Homing::use_software_offsets`]).
    PreloadReady,
    /// Verifying; `remaining` more cycles.
    Verifying {
        /// Cycles left.
        remaining: u32,
    },
    /// Homed: encoders agree with the pots.
    Done,
    /// Homing failed (the error is latched; call [`Homing::start`] to retry).
    Failed(HomingError),
}

/// The homing state machine for a set of joints.
#[derive(Debug, Clone, PartialEq)]
pub struct Homing {
    joints: Vec<HomingJoint>,
    settings: HomingSettings,
    phase: HomingPhase,
    error: Option<HomingError>,
    count: u32,
    pot_sum: Vec<f64>,
    pot_min: Vec<f64>,
    pot_max: Vec<f64>,
    enc_sum: Vec<f64>,
    last_enc: Vec<f64>,
    targets: Vec<f64>,
    offsets: Vec<f64>,
    applied: Vec<f64>,
}

impl Homing {
    /// Homing for `joints`; sample counts below 1 are raised to 1.
    pub fn new(joints: Vec<HomingJoint>, settings: HomingSettings) -> Homing {
        let n = joints.len();
        Homing {
            joints,
            settings: HomingSettings {
                averaging_samples: settings.averaging_samples.max(1),
                verify_samples: settings.verify_samples.max(1),
            },
            phase: HomingPhase::Idle,
            error: None,
            count: 0,
            pot_sum: vec![0.0; n],
            pot_min: vec![0.0; n],
            pot_max: vec![0.0; n],
            enc_sum: vec![0.0; n],
            last_enc: vec![0.0; n],
            targets: vec![0.0; n],
            offsets: vec![0.0; n],
            applied: vec![0.0; n],
        }
    }

    /// Homing for every actuator of `config`, in joint order, with the v6
    /// `potentiometers.tolerances[].distance` as tolerance (0 when absent).
    pub fn from_config(config: &IoConfig, settings: HomingSettings) -> Homing {
        let joints = config
            .joints()
            .map(|j| HomingJoint {
                label: j.label,
                tolerance: j.potentiometer_tolerance().map_or(0.0, |t| {
                    if t.distance.is_finite() {
                        t.distance
                    } else {
                        0.0
                    }
                }),
                has_potentiometer: j.actuator.potentiometer.is_some(),
            })
            .collect();
        Homing::new(joints, settings)
    }

    /// The joints.
    pub fn joints(&self) -> &[HomingJoint] {
        &self.joints
    }

    /// The current phase.
    pub fn phase(&self) -> HomingPhase {
        self.phase
    }

    /// The error that failed homing, if it failed.
    pub fn error(&self) -> Option<HomingError> {
        self.error
    }

    /// Per joint, the position the encoder should read now (valid from
    /// [`HomingStep::PreloadReady`] on).
    pub fn targets(&self) -> &[f64] {
        &self.targets
    }

    /// Per joint, `pot - encoder` from the averaging: what to add to the
    /// encoder position when homing in software.
    pub fn offsets(&self) -> &[f64] {
        &self.offsets
    }

    /// Per joint, what the runner must add to encoder positions from now on:
    /// zeros after a hardware preload, [`offsets`](Self::offsets) in
    /// software mode.
    pub fn applied_offsets(&self) -> &[f64] {
        &self.applied
    }

    /// (Re)starts homing: forget everything and begin averaging.
    pub fn start(&mut self) {
        self.phase = HomingPhase::Averaging;
        self.error = None;
        self.count = 0;
        for v in [
            &mut self.pot_sum,
            &mut self.enc_sum,
            &mut self.targets,
            &mut self.offsets,
            &mut self.applied,
        ] {
            v.fill(0.0);
        }
        self.pot_min.fill(f64::INFINITY);
        self.pot_max.fill(f64::NEG_INFINITY);
    }

    /// The preload was written: the encoders now read [`targets`](Self::targets)
    /// (plus motion since). Starts verification.
    ///
    /// # Errors
    /// Not in [`HomingPhase::PreloadReady`].
    pub fn preload_written(&mut self) -> Result<(), HomingError> {
        self.begin_verify("preload_written")?;
        self.applied.fill(0.0);
        Ok(())
    }

    /// Keep the encoders and add [`offsets`](Self::offsets) in software.
    /// Starts verification.
    ///
    /// # Errors
    /// Not in [`HomingPhase::PreloadReady`].
    pub fn use_software_offsets(&mut self) -> Result<(), HomingError> {
        self.begin_verify("use_software_offsets")?;
        self.applied.copy_from_slice(&self.offsets);
        Ok(())
    }

    fn begin_verify(&mut self, action: &'static str) -> Result<(), HomingError> {
        if self.phase != HomingPhase::PreloadReady {
            return Err(HomingError::OutOfOrder {
                action,
                phase: self.phase,
            });
        }
        self.phase = HomingPhase::Verifying;
        self.count = 0;
        self.pot_sum.fill(0.0);
        self.enc_sum.fill(0.0);
        Ok(())
    }

    fn fail(&mut self, e: HomingError) -> HomingStep {
        self.phase = HomingPhase::Failed;
        self.error = Some(e);
        HomingStep::Failed(e)
    }

    /// Feeds one cycle of readings: `pot[i]` and `encoder[i]` are joint *i*'s
    /// pot-derived and (raw, uncorrected) encoder-derived positions. Pot
    /// values of joints without a potentiometer are ignored.
    pub fn step(&mut self, pot: &[f64], encoder: &[f64]) -> HomingStep {
        match self.phase {
            HomingPhase::Idle => return HomingStep::Idle,
            HomingPhase::PreloadReady => return HomingStep::PreloadReady,
            HomingPhase::Done => return HomingStep::Done,
            HomingPhase::Failed => {
                return match self.error {
                    Some(e) => HomingStep::Failed(e),
                    None => HomingStep::Idle,
                };
            }
            HomingPhase::Averaging | HomingPhase::Verifying => {}
        }
        let n = self.joints.len();
        if pot.len() != n || encoder.len() != n {
            return self.fail(HomingError::WrongJointCount {
                expected: n,
                pot: pot.len(),
                encoder: encoder.len(),
            });
        }
        for (i, j) in self.joints.iter().enumerate() {
            let (p, e) = (pot[i], encoder[i]);
            if j.has_potentiometer && !p.is_finite() {
                let joint = j.label;
                return self.fail(HomingError::InvalidReading {
                    joint,
                    what: "potentiometer",
                });
            }
            if !e.is_finite() {
                let joint = j.label;
                return self.fail(HomingError::InvalidReading {
                    joint,
                    what: "encoder",
                });
            }
        }
        self.count += 1;
        if self.phase == HomingPhase::Averaging {
            self.accumulate_averaging(pot, encoder)
        } else {
            self.accumulate_verifying(pot, encoder)
        }
    }

    fn accumulate_averaging(&mut self, pot: &[f64], encoder: &[f64]) -> HomingStep {
        for i in 0..self.joints.len() {
            let p = if self.joints[i].has_potentiometer {
                pot[i]
            } else {
                encoder[i]
            };
            self.pot_sum[i] += p;
            self.pot_min[i] = self.pot_min[i].min(p);
            self.pot_max[i] = self.pot_max[i].max(p);
            self.enc_sum[i] += encoder[i];
            self.last_enc[i] = encoder[i];
        }
        let n = self.settings.averaging_samples;
        if self.count < n {
            return HomingStep::Averaging {
                remaining: n - self.count,
            };
        }
        let count = f64::from(self.count);
        for i in 0..self.joints.len() {
            let j = self.joints[i];
            let spread = self.pot_max[i] - self.pot_min[i];
            if j.has_potentiometer && j.tolerance > 0.0 && spread > j.tolerance {
                return self.fail(HomingError::PotUnsteady {
                    joint: j.label,
                    spread,
                    tolerance: j.tolerance,
                });
            }
            let offset = (self.pot_sum[i] - self.enc_sum[i]) / count;
            self.offsets[i] = offset;
            // Where the encoder should read now, given where it reads now.
            self.targets[i] = self.last_enc[i] + offset;
        }
        self.phase = HomingPhase::PreloadReady;
        HomingStep::PreloadReady
    }

    fn accumulate_verifying(&mut self, pot: &[f64], encoder: &[f64]) -> HomingStep {
        for i in 0..self.joints.len() {
            let corrected = encoder[i] + self.applied[i];
            let p = if self.joints[i].has_potentiometer {
                pot[i]
            } else {
                corrected
            };
            self.pot_sum[i] += p;
            self.enc_sum[i] += corrected;
        }
        let n = self.settings.verify_samples;
        if self.count < n {
            return HomingStep::Verifying {
                remaining: n - self.count,
            };
        }
        let count = f64::from(self.count);
        for i in 0..self.joints.len() {
            let j = self.joints[i];
            let p = self.pot_sum[i] / count;
            let e = self.enc_sum[i] / count;
            let difference = p - e;
            if j.has_potentiometer && j.tolerance > 0.0 && difference.abs() > j.tolerance {
                return self.fail(HomingError::Mismatch {
                    joint: j.label,
                    potentiometer: p,
                    encoder: e,
                    difference,
                    tolerance: j.tolerance,
                });
            }
        }
        self.phase = HomingPhase::Done;
        HomingStep::Done
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn joints() -> Vec<HomingJoint> {
        vec![
            HomingJoint {
                label: Label::new("MTML[0]"),
                tolerance: 0.087,
                has_potentiometer: true,
            },
            HomingJoint {
                label: Label::new("MTML[1]"),
                tolerance: 0.087,
                has_potentiometer: true,
            },
            HomingJoint {
                label: Label::new("MTML[6]"),
                tolerance: 0.0,
                has_potentiometer: false,
            },
        ]
    }

    fn settings() -> HomingSettings {
        HomingSettings {
            averaging_samples: 10,
            verify_samples: 5,
        }
    }

    /// A tiny deterministic noise source (no RNG needed).
    fn noise(k: u32, i: usize) -> f64 {
        let x = (k as f64 * 12.9898 + i as f64 * 78.233).sin() * 43758.5453;
        (x - x.floor() - 0.5) * 0.01 // +-5 mrad
    }

    #[test]
    fn homes_with_a_hardware_preload() {
        let true_pos = [0.3, -0.7, 1.0];
        let mut enc_zero = [-5.0, 12.0, 0.25]; // arbitrary power-up counts
        let mut h = Homing::new(joints(), settings());
        assert_eq!(h.step(&[0.0; 3], &[0.0; 3]), HomingStep::Idle);
        h.start();
        let mut k = 0;
        let read = |k: u32, enc_zero: &[f64; 3]| {
            let pot: Vec<f64> = (0..3).map(|i| true_pos[i] + noise(k, i)).collect();
            let enc: Vec<f64> = (0..3).map(|i| true_pos[i] - enc_zero[i]).collect();
            (pot, enc)
        };
        let step = loop {
            let (pot, enc) = read(k, &enc_zero);
            k += 1;
            match h.step(&pot, &enc) {
                HomingStep::Averaging { .. } => continue,
                other => break other,
            }
        };
        assert_eq!(step, HomingStep::PreloadReady);
        assert_eq!(k, 10);
        for (target, truth) in h.targets().iter().zip(&true_pos).take(2) {
            assert!((target - truth).abs() < 5e-3);
        }
        // Joint without a pot keeps its encoder.
        assert_eq!(h.targets()[2], true_pos[2] - enc_zero[2]);
        assert_eq!(h.offsets()[2], 0.0);
        // Before the preload, stepping just repeats PreloadReady.
        assert_eq!(h.step(&[0.0; 3], &[0.0; 3]), HomingStep::PreloadReady);
        // The "board" applies the preload: encoders now read the targets.
        for i in 0..3 {
            enc_zero[i] = true_pos[i] - h.targets()[i];
        }
        h.preload_written().unwrap();
        assert!(h.preload_written().is_err());
        let step = loop {
            let (pot, enc) = read(k, &enc_zero);
            k += 1;
            match h.step(&pot, &enc) {
                HomingStep::Verifying { .. } => continue,
                other => break other,
            }
        };
        assert_eq!(step, HomingStep::Done);
        assert_eq!(h.applied_offsets(), &[0.0; 3]);
    }

    #[test]
    fn software_offsets() {
        let mut h = Homing::new(joints(), settings());
        h.start();
        for _ in 0..10 {
            h.step(&[0.5, 0.1, 0.0], &[2.5, -0.4, 7.0]);
        }
        assert_eq!(h.phase(), HomingPhase::PreloadReady);
        h.use_software_offsets().unwrap();
        let want = [-2.0, 0.5, 0.0];
        for (got, want) in h.applied_offsets().iter().zip(want) {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
        for _ in 0..5 {
            h.step(&[0.5, 0.1, 0.0], &[2.5, -0.4, 7.0]);
        }
        assert_eq!(h.phase(), HomingPhase::Done);
    }

    #[test]
    fn mismatch_names_the_joint() {
        let mut h = Homing::new(joints(), settings());
        h.start();
        for _ in 0..10 {
            h.step(&[0.5, 0.1, 0.0], &[0.0, 0.0, 0.0]);
        }
        // The preload did not take on joint 1 (encoder still reads 0).
        h.preload_written().unwrap();
        let mut last = HomingStep::Idle;
        for _ in 0..5 {
            last = h.step(&[0.5, 0.1, 0.0], &[0.5, 0.0, 0.0]);
        }
        let HomingStep::Failed(e) = last else {
            panic!("expected a failure, got {last:?}")
        };
        assert!(matches!(e, HomingError::Mismatch { joint, difference, .. }
                if joint.as_str() == "MTML[1]" && (difference - 0.1).abs() < 1e-12));
        assert!(e.to_string().contains("MTML[1]"));
        assert_eq!(h.phase(), HomingPhase::Failed);
        assert_eq!(h.step(&[0.0; 3], &[0.0; 3]), HomingStep::Failed(e));
        // Restart works.
        h.start();
        assert_eq!(h.phase(), HomingPhase::Averaging);
    }

    #[test]
    fn unsteady_pot_and_bad_input() {
        let mut h = Homing::new(joints(), settings());
        h.start();
        let mut last = HomingStep::Idle;
        for k in 0..10 {
            last = h.step(&[0.0, 0.02 * k as f64, 0.0], &[0.0; 3]);
        }
        assert!(matches!(
            last,
            HomingStep::Failed(HomingError::PotUnsteady { joint, .. }) if joint.as_str() == "MTML[1]"
        ));
        h.start();
        assert!(matches!(
            h.step(&[0.0, f64::NAN, 0.0], &[0.0; 3]),
            HomingStep::Failed(HomingError::InvalidReading {
                what: "potentiometer",
                ..
            })
        ));
        h.start();
        // A NaN pot on a joint without a pot is fine; a NaN encoder is not.
        assert!(matches!(
            h.step(&[0.0, 0.0, f64::NAN], &[0.0; 3]),
            HomingStep::Averaging { remaining: 9 }
        ));
        assert!(matches!(
            h.step(&[0.0; 3], &[0.0, 0.0, f64::INFINITY]),
            HomingStep::Failed(HomingError::InvalidReading {
                what: "encoder",
                ..
            })
        ));
        h.start();
        assert!(matches!(
            h.step(&[0.0; 2], &[0.0; 3]),
            HomingStep::Failed(HomingError::WrongJointCount {
                expected: 3,
                pot: 2,
                encoder: 3
            })
        ));
    }

    #[test]
    fn errors_read_as_sentences() {
        // What `firelink demo` printed as `homing: PotUnsteady { joint:
        // "BENCH[0]", spread: ... }`.
        let e = crate::runner::RunnerError::Homing(HomingError::PotUnsteady {
            joint: Label::joint("BENCH", 0),
            spread: 0.0017337178605651982,
            tolerance: 1e-300,
        });
        assert_eq!(
            e.to_string(),
            "homing: BENCH[0]: the potentiometer moved 0.001734 while homing averaged it, \
             more than its tolerance of 1e-300 (rad or m): the joint is not still, or its \
             potentiometer is noisy"
        );
        let m = HomingError::Mismatch {
            joint: Label::joint("MTML", 0),
            potentiometer: 1.0000000000000003e300,
            encoder: 1.0000000000000005e300,
            difference: -1.487016908477783e284,
            tolerance: 0.0872664626,
        };
        let shown = m.to_string();
        assert!(
            shown.contains("reads 1e300 and the encoder 1e300"),
            "{shown}"
        );
        assert!(shown.contains("differ by -1.487e284"), "{shown}");
        let o = HomingError::OutOfOrder {
            action: "preload_written",
            phase: HomingPhase::Averaging,
        };
        assert_eq!(
            o.to_string(),
            "homing: preload_written is not possible while averaging"
        );
        for shown in [e.to_string(), shown, o.to_string()] {
            assert!(!shown.contains('{') && !shown.contains('"'), "{shown}");
        }
    }
}
