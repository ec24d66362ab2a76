//! Teleoperation of a PSM by an MTM, as the dVRK console's
//! `mtsTeleOperationPSM` does it: a state machine that reads the MTM's
//! measured pose and gripper and the PSM's setpoint pose and jaw, and
//! commands the PSM's tip pose (`servo_cp`) and jaw (`jaw/servo_jp`).
//!
//! ```text
//!  Disabled ──enable──▶ Aligning ──aligned and operator present──▶ Enabled
//!      ▲                   ▲  │                                      │  ▲
//!      └──────disable──────┘  └── the MTM is oriented like the PSM   │  │
//!                          └────────── clutch released ── Clutched ◀─┘  │
//!                                                            └──────────┘
//! ```
//!
//! - **Aligning**: the MTM is asked to turn its gripper to the PSM tip's
//!   orientation ([`TeleopCommand::mtm_orientation`]); teleoperation starts
//!   once the angle between them is within
//!   [`TeleopSettings::start_orientation_tolerance`] (5 degrees) and the
//!   operator has shown they hold the MTM: the gripper pinched by
//!   [`start_gripper_threshold`](TeleopSettings::start_gripper_threshold)
//!   (5 degrees), or the gripper rolled by
//!   [`start_roll_threshold`](TeleopSettings::start_roll_threshold)
//!   (3 degrees), or 80 % of both together.
//! - **Enabled**: at entry the MTM's pose, the PSM's pose and the rotation
//!   between them (the alignment offset) are kept; every cycle the PSM's
//!   goal is its initial position plus the MTM's translation since then,
//!   scaled by [`scale`](TeleopSettings::scale) (0.2), and the MTM's
//!   rotation times the alignment offset. The jaw follows a *ghost* of the
//!   gripper that moves towards the gripper at most
//!   [`jaw_rate`](TeleopSettings::jaw_rate) (720 degrees/s; 36 degrees/s
//!   after a clutch until it has caught up), mapped linearly: gripper 0 is
//!   a closed jaw, [`gripper_max`](TeleopSettings::gripper_max) (60
//!   degrees) the jaw's upper limit; never below the jaw's lower limit.
//! - **Clutched**: the PSM holds; the MTM may move. Releasing the clutch
//!   goes back to Aligning (the operator is still present), then to
//!   Enabled with new initial poses: the PSM does not jump.
//!
//! The defaults are the console's (`mtsIntuitiveResearchKit.h`,
//! `TeleOperationPSM`; `mtsTeleOperationPSM.h` for the gripper's 0 to 60
//! degrees). [`Teleop::update`] takes the time as an argument and does not
//! allocate.

use crate::dvrk::kinematics::frame::{add, scale, sub};
use crate::dvrk::kinematics::{Frame, Rotation, Vec3};

const DEG: f64 = core::f64::consts::PI / 180.0;

/// The console's teleoperation settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TeleopSettings {
    /// PSM translation per MTM translation.
    pub scale: f64,
    /// Largest MTM-to-PSM orientation error to start following, rad.
    pub start_orientation_tolerance: f64,
    /// Gripper range that shows the operator is present, rad.
    pub start_gripper_threshold: f64,
    /// Roll range that shows the operator is present, rad.
    pub start_roll_threshold: f64,
    /// Fastest the jaw's goal moves, rad/s.
    pub jaw_rate: f64,
    /// Fastest the jaw's goal moves after a clutch until it has caught up
    /// with the gripper, rad/s.
    pub jaw_rate_after_clutch: f64,
    /// Gripper-to-ghost distance under which the jaw has caught up, rad.
    pub jaw_caught_up: f64,
    /// The gripper's reading fully open, rad (mapped to `jaw_limits.1`).
    pub gripper_max: f64,
    /// The gripper's reading for a closed jaw, rad.
    pub gripper_zero: f64,
    /// The PSM jaw's range, rad (`jaw/configuration_js`).
    pub jaw_limits: (f64, f64),
}

impl Default for TeleopSettings {
    /// The dVRK console's values, the jaw range of a Large Needle Driver.
    fn default() -> Self {
        TeleopSettings {
            scale: 0.2,
            start_orientation_tolerance: 5.0 * DEG,
            start_gripper_threshold: 5.0 * DEG,
            start_roll_threshold: 3.0 * DEG,
            jaw_rate: 720.0 * DEG,
            jaw_rate_after_clutch: 36.0 * DEG,
            jaw_caught_up: 2.0 * DEG,
            gripper_max: 60.0 * DEG,
            gripper_zero: 0.0,
            jaw_limits: crate::dvrk::kinematics::psm::JAW_LIMITS,
        }
    }
}

/// Where the teleoperation is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum TeleopState {
    /// Not teleoperating; the PSM is left alone.
    Disabled,
    /// The MTM is being oriented like the PSM; waiting for the operator.
    Aligning,
    /// The PSM follows the MTM.
    Enabled,
    /// The clutch is pressed: the PSM holds, the MTM moves freely.
    Clutched,
}

/// What the teleoperation reads each cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TeleopInput {
    /// Seconds, on the caller's clock.
    pub now: f64,
    /// The MTM's measured gripper frame (`measured_cp`).
    pub mtm: Frame,
    /// The MTM gripper's measured angle, rad (`gripper/measured_js`).
    pub gripper: f64,
    /// The PSM tip's setpoint frame (`setpoint_cp`).
    pub psm: Frame,
    /// The PSM jaw's setpoint, rad (`jaw/setpoint_js`).
    pub psm_jaw: f64,
    /// Whether the operator's clutch pedal is pressed.
    pub clutch: bool,
}

/// What the teleoperation asks for after a cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TeleopCommand {
    /// The state after the cycle.
    pub state: TeleopState,
    /// The PSM tip's goal (`servo_cp`), while following.
    pub psm: Option<Frame>,
    /// The PSM jaw's goal (`jaw/servo_jp`), while following.
    pub jaw: Option<f64>,
    /// Whether the PSM should hold where it is (`hold`): on entering the
    /// clutch.
    pub psm_hold: bool,
    /// The orientation the MTM's gripper is asked to take, while aligning
    /// or clutched (`move_cp` / `lock_orientation`).
    pub mtm_orientation: Option<Rotation>,
    /// The angle between the MTM's and the PSM's orientations, rad
    /// (meaningful while aligning).
    pub alignment_error: f64,
}

/// The teleoperation of one PSM by one MTM.
#[derive(Debug, Clone, PartialEq)]
pub struct Teleop {
    settings: TeleopSettings,
    state: TeleopState,
    /// Whether teleoperation is wanted (console "enable").
    wanted: bool,
    operator_active: bool,
    /// Gripper and roll ranges seen while aligning: (min, max).
    gripper_range: (f64, f64),
    roll_range: (f64, f64),
    mtm_initial: Frame,
    psm_initial: Frame,
    alignment_offset: Rotation,
    ghost: f64,
    caught_up: bool,
    back_from_clutch: bool,
    last_now: Option<f64>,
    /// The MTM orientation to hold while clutched.
    clutch_orientation: Rotation,
    enabled_count: u32,
}

impl Teleop {
    /// A disabled teleoperation with `settings`.
    pub fn new(settings: TeleopSettings) -> Teleop {
        Teleop {
            settings,
            state: TeleopState::Disabled,
            wanted: false,
            operator_active: false,
            gripper_range: (f64::INFINITY, f64::NEG_INFINITY),
            roll_range: (f64::INFINITY, f64::NEG_INFINITY),
            mtm_initial: Frame::IDENTITY,
            psm_initial: Frame::IDENTITY,
            alignment_offset: Rotation::IDENTITY,
            ghost: 0.0,
            caught_up: false,
            back_from_clutch: false,
            last_now: None,
            clutch_orientation: Rotation::IDENTITY,
            enabled_count: 0,
        }
    }

    /// Its settings.
    pub fn settings(&self) -> &TeleopSettings {
        &self.settings
    }

    /// The state now.
    pub fn state(&self) -> TeleopState {
        self.state
    }

    /// How many times following started (the first enable and every
    /// return from the clutch).
    pub fn times_enabled(&self) -> u32 {
        self.enabled_count
    }

    /// Ask for teleoperation (the console's "enable"): from Disabled the
    /// next update starts aligning; the operator must show presence again.
    pub fn enable(&mut self) {
        self.wanted = true;
        self.operator_active = false;
        if self.state == TeleopState::Disabled {
            self.enter_aligning();
        }
    }

    /// Stop teleoperating (the console's "disable").
    pub fn disable(&mut self) {
        self.wanted = false;
        self.state = TeleopState::Disabled;
    }

    /// The PSM jaw goal for a gripper angle.
    pub fn gripper_to_jaw(&self, gripper: f64) -> f64 {
        let (k, o) = self.jaw_map();
        k * gripper + o
    }

    /// The gripper angle for a PSM jaw angle.
    pub fn jaw_to_gripper(&self, jaw: f64) -> f64 {
        let (k, o) = self.jaw_map();
        (jaw - o) / k
    }

    /// `jaw = k gripper + o`: gripper zero is a closed jaw (0), the
    /// gripper's maximum the jaw's upper limit.
    fn jaw_map(&self) -> (f64, f64) {
        let s = &self.settings;
        let k = s.jaw_limits.1 / (s.gripper_max - s.gripper_zero);
        (k, -s.gripper_zero * k)
    }

    fn enter_aligning(&mut self) {
        self.state = TeleopState::Aligning;
        if self.back_from_clutch {
            self.back_from_clutch = false;
        } else {
            self.operator_active = false;
        }
        self.gripper_range = (f64::INFINITY, f64::NEG_INFINITY);
        self.roll_range = (f64::INFINITY, f64::NEG_INFINITY);
    }

    fn enter_enabled(&mut self, input: &TeleopInput) {
        self.state = TeleopState::Enabled;
        self.enabled_count = self.enabled_count.saturating_add(1);
        self.mtm_initial = input.mtm;
        self.psm_initial = input.psm;
        self.alignment_offset = input.mtm.rotation.transpose() * input.psm.rotation;
        self.ghost = self.jaw_to_gripper(input.psm_jaw);
        self.caught_up = false;
    }

    /// One cycle: read `input`, move between states, say what to command.
    pub fn update(&mut self, input: &TeleopInput) -> TeleopCommand {
        let dt = self.last_now.map_or(0.0, |t| (input.now - t).max(0.0));
        self.last_now = Some(input.now);
        let alignment_error = input.mtm.rotation.angle_to(&input.psm.rotation);
        let mut cmd = TeleopCommand {
            state: self.state,
            psm: None,
            jaw: None,
            psm_hold: false,
            mtm_orientation: None,
            alignment_error,
        };
        match self.state {
            TeleopState::Disabled => {}
            TeleopState::Aligning => {
                cmd.mtm_orientation = Some(input.psm.rotation);
                self.watch_operator(input);
                let aligned = alignment_error <= self.settings.start_orientation_tolerance;
                if aligned && self.operator_active && self.wanted && !input.clutch {
                    self.enter_enabled(input);
                    self.follow(input, dt, &mut cmd);
                }
            }
            TeleopState::Enabled => {
                if input.clutch {
                    self.state = TeleopState::Clutched;
                    self.clutch_orientation = input.mtm.rotation;
                    cmd.psm_hold = true;
                    cmd.mtm_orientation = Some(self.clutch_orientation);
                } else {
                    self.follow(input, dt, &mut cmd);
                }
            }
            TeleopState::Clutched => {
                if input.clutch {
                    cmd.mtm_orientation = Some(self.clutch_orientation);
                } else {
                    self.back_from_clutch = true;
                    self.enter_aligning();
                    cmd.mtm_orientation = Some(input.psm.rotation);
                }
            }
        }
        cmd.state = self.state;
        cmd
    }

    /// While aligning: has the operator pinched or rolled the gripper?
    fn watch_operator(&mut self, input: &TeleopInput) {
        if self.operator_active {
            return;
        }
        let g = input.gripper;
        if g.is_finite() {
            self.gripper_range = (self.gripper_range.0.min(g), self.gripper_range.1.max(g));
        }
        // The roll: the angle between the PSM's and the MTM's y axes.
        let y_psm = input.psm.rotation.column(1);
        let y_mtm = input.mtm.rotation.column(1);
        let c = crate::dvrk::kinematics::frame::dot(y_psm, y_mtm).clamp(-1.0, 1.0);
        let roll = libm::acos(c);
        self.roll_range = (self.roll_range.0.min(roll), self.roll_range.1.max(roll));
        let span = |r: (f64, f64)| if r.1 >= r.0 { r.1 - r.0 } else { 0.0 };
        let (gripper, roll) = (span(self.gripper_range), span(self.roll_range));
        let s = &self.settings;
        self.operator_active = gripper >= s.start_gripper_threshold
            || roll >= s.start_roll_threshold
            || gripper + roll > 0.8 * (s.start_gripper_threshold + s.start_roll_threshold);
    }

    /// While enabled: the PSM's goal and the jaw's.
    fn follow(&mut self, input: &TeleopInput, dt: f64, cmd: &mut TeleopCommand) {
        let moved: Vec3 = sub(input.mtm.translation, self.mtm_initial.translation);
        let position = add(
            self.psm_initial.translation,
            scale(self.settings.scale, moved),
        );
        let rotation = (input.mtm.rotation * self.alignment_offset).normalized();
        cmd.psm = Some(Frame::new(rotation, position));
        // The jaw: a ghost of the gripper, rate limited.
        let gap = input.gripper - self.ghost;
        if !self.caught_up && gap.abs() < self.settings.jaw_caught_up {
            self.caught_up = true;
        }
        let rate = if self.caught_up {
            self.settings.jaw_rate
        } else {
            self.settings.jaw_rate_after_clutch
        };
        if gap.is_finite() {
            self.ghost += gap.clamp(-rate * dt, rate * dt);
        }
        let mut jaw = self.gripper_to_jaw(self.ghost);
        if jaw < self.settings.jaw_limits.0 {
            jaw = self.settings.jaw_limits.0;
            self.ghost = self.jaw_to_gripper(jaw);
        }
        cmd.jaw = Some(jaw);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn input(now: f64, mtm: Frame, psm: Frame, gripper: f64, clutch: bool) -> TeleopInput {
        TeleopInput {
            now,
            mtm,
            gripper,
            psm,
            psm_jaw: 0.3,
            clutch,
        }
    }

    fn pose(v: Vec3, t: Vec3) -> Frame {
        Frame::new(Rotation::from_rotation_vector(v), t)
    }

    #[test]
    fn it_waits_for_alignment_and_the_operator_then_follows_scaled() {
        let mut t = Teleop::new(TeleopSettings::default());
        let psm = pose([0.1, -0.2, 0.3], [0.0, 0.0, -0.1]);
        // 10 degrees off: stays aligning, asks the MTM to turn.
        let off = Frame::new(
            psm.rotation * Rotation::about_y(10.0 * DEG),
            [0.1, 0.2, -0.3],
        );
        t.enable();
        let c = t.update(&input(0.0, off, psm, 1.0, false));
        assert_eq!(c.state, TeleopState::Aligning);
        assert_eq!(c.mtm_orientation, Some(psm.rotation));
        assert!((c.alignment_error - 10.0 * DEG).abs() < 1e-9);
        // Aligned within 5 degrees but nobody holds the MTM.
        let near = Frame::new(psm.rotation * Rotation::about_y(4.0 * DEG), off.translation);
        let c = t.update(&input(0.001, near, psm, 1.0, false));
        assert_eq!(c.state, TeleopState::Aligning);
        // A pinch of 6 degrees: enabled, the PSM's goal where it is.
        let c = t.update(&input(0.002, near, psm, 1.0 - 6.0 * DEG, false));
        assert_eq!(c.state, TeleopState::Enabled);
        let goal = c.psm.unwrap();
        assert!(
            crate::dvrk::kinematics::frame::norm(sub(goal.translation, psm.translation)) < 1e-15
        );
        assert!(goal.rotation.angle_to(&psm.rotation) < 1e-9);
        // The MTM moves 50 mm and turns: the PSM 10 mm, turned alike.
        let turn = Rotation::about_z(0.3);
        let moved = Frame::new(
            turn * near.rotation,
            add(near.translation, [0.05, 0.0, 0.0]),
        );
        let c = t.update(&input(0.003, moved, psm, 1.0, false));
        let goal = c.psm.unwrap();
        let want = add(psm.translation, [0.01, 0.0, 0.0]);
        assert!(crate::dvrk::kinematics::frame::norm(sub(goal.translation, want)) < 1e-12);
        assert!(goal.rotation.angle_to(&(turn * psm.rotation)) < 1e-9);
    }

    #[test]
    fn the_jaw_follows_the_gripper_at_its_rate_and_not_below_its_limit() {
        let s = TeleopSettings::default();
        let mut t = Teleop::new(s);
        let f = pose([0.0, 0.0, 0.0], [0.0; 3]);
        t.enable();
        // Enabled by a roll of the gripper's frame (4 degrees).
        t.update(&input(0.0, f, f, 0.5, false));
        let rolled = Frame::new(Rotation::about_z(4.0 * DEG), [0.0; 3]);
        let c = t.update(&input(0.001, rolled, f, 0.5, false));
        assert_eq!(c.state, TeleopState::Enabled);
        // 60 degrees of gripper is the jaw's upper limit; 0 is closed.
        assert!((t.gripper_to_jaw(s.gripper_max) - s.jaw_limits.1).abs() < 1e-12);
        assert_eq!(t.gripper_to_jaw(0.0), 0.0);
        // The ghost started at the jaw (0.3) and moves at the slow rate
        // until it has caught up.
        let ghost0 = t.jaw_to_gripper(c.jaw.unwrap());
        assert!((ghost0 - t.jaw_to_gripper(0.3)).abs() <= s.jaw_rate_after_clutch * 0.001 + 1e-12);
        let c = t.update(&input(0.011, rolled, f, ghost0 + 0.5, false));
        let moved = t.jaw_to_gripper(c.jaw.unwrap()) - ghost0;
        assert!(
            (moved - s.jaw_rate_after_clutch * 0.01).abs() < 1e-9,
            "{moved}"
        );
        // Caught up (within 2 degrees): then the fast rate.
        let here = t.jaw_to_gripper(c.jaw.unwrap());
        t.update(&input(0.012, rolled, f, here + 0.01, false));
        let before = t.jaw_to_gripper(t.gripper_to_jaw(t.ghost));
        let c = t.update(&input(0.022, rolled, f, before + 1.0, false));
        let moved = t.jaw_to_gripper(c.jaw.unwrap()) - before;
        assert!((moved - s.jaw_rate * 0.01).abs() < 1e-9, "{moved}");
        // Squeezed far past closed: the jaw stops at its lower limit.
        let mut jaw = 0.0;
        for k in 0..2000 {
            let c = t.update(&input(0.03 + 0.001 * f64::from(k), rolled, f, -3.0, false));
            jaw = c.jaw.unwrap();
        }
        assert_eq!(jaw, s.jaw_limits.0);
    }

    #[test]
    fn the_clutch_holds_the_psm_and_following_resumes_without_a_jump() {
        let mut t = Teleop::new(TeleopSettings::default());
        let psm = pose([0.0, 0.2, 0.0], [0.0, 0.0, -0.1]);
        let mtm = Frame::new(psm.rotation, [0.2, 0.0, -0.3]);
        t.enable();
        t.update(&input(0.0, mtm, psm, 0.5, false));
        let c = t.update(&input(0.001, mtm, psm, 0.4, false));
        assert_eq!(c.state, TeleopState::Enabled);
        let moved = Frame::new(psm.rotation, add(mtm.translation, [0.0, 0.05, 0.0]));
        let c = t.update(&input(0.002, moved, psm, 0.4, false));
        let held = c.psm.unwrap();
        // Clutch: hold, then the MTM moves back 100 mm; nothing follows.
        let c = t.update(&input(0.003, moved, held, 0.4, true));
        assert_eq!(c.state, TeleopState::Clutched);
        assert!(c.psm_hold && c.psm.is_none());
        let back = Frame::new(psm.rotation, add(moved.translation, [0.0, -0.1, 0.0]));
        let c = t.update(&input(0.004, back, held, 0.4, true));
        assert!(c.psm.is_none());
        // Released: aligning, the operator still present, enabled at once
        // with the PSM's goal where it was held.
        let c = t.update(&input(0.005, back, held, 0.4, false));
        assert_eq!(c.state, TeleopState::Aligning);
        let c = t.update(&input(0.006, back, held, 0.4, false));
        assert_eq!(c.state, TeleopState::Enabled);
        let goal = c.psm.unwrap();
        assert!(
            crate::dvrk::kinematics::frame::norm(sub(goal.translation, held.translation)) < 1e-15
        );
        assert_eq!(t.times_enabled(), 2);
        t.disable();
        assert_eq!(t.update(&input(0.007, back, held, 0.4, false)).psm, None);
    }
}
