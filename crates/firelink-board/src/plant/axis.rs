//! One axis: amplifier, motor, transmission and load, integrated over
//! whole steps of a fixed grid; the encoder and temperature follow the
//! motion.
//!
//! # Time
//! The axis keeps its state at one instant and is integrated forward, in
//! spans of constant inputs at most one step long, whenever it is looked at
//! (the plant advanced to a time) or its inputs change: an input set at the
//! plant's clock (a new DAC code, an amplifier turning on or off, an
//! external torque) takes effect at that exact instant, and an observation
//! sees the state exactly at the time asked. The current loop is integrated
//! exactly, so where the spans break changes the motion only through the
//! load and friction held over each span (the tests bound it), and the
//! current alone is known at any instant without integrating the motion
//! (what the firmware's current check samples every 100 us).
//!
//! # One span of constant inputs
//! [`Integrator::Exact`] (the default), per span of length `h`:
//! 1. Current: the commanded current `I` (DAC code, current limit, and what
//!    the supply can push against resistance and back-EMF at the span's
//!    start; zero while disabled) is approached with the exact first-order
//!    response of the current loop, `i(t) = I + (i0 - I) exp(-t / tau)`.
//! 2. Velocity and position: the motor torque `kt i(t)` is integrated
//!    exactly, once into the velocity and twice into the position; the
//!    joint load (gravity, spring, bias, external) reflected through the
//!    gear ratio and the Coulomb friction are held at their values at the
//!    span's start, viscous friction is treated implicitly. At rest the
//!    motor breaks away at the instant the driving torque first exceeds
//!    the friction (stiction); a velocity that would cross zero stops
//!    there.
//! 3. Mechanical stops: a joint that reaches a stop stays there with zero
//!    velocity (an inelastic, rigid stop) while the drive pushes into it,
//!    and leaves it freely when the drive pulls away; the encoder records
//!    the edges crossed with interpolated times.
//! 4. Temperature: exact first-order response to the dissipated power.
//!
//! [`Integrator::SemiImplicitEuler`] is the integration this crate used
//! before (and the reference the exact one is tested against at a 5 us
//! step): the same current loop, then the velocity from the current at the
//! end of the step and the position from the new velocity.

use core::f64::consts::PI;

use super::encoder::Encoder;
use super::params::{AxisParams, DAC_ZERO};
use crate::time::SimTime;

/// Current below which the amplifier is considered to carry none, A.
const CURRENT_EPSILON: f64 = 1e-9;

/// How an axis integrates one span of constant inputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Integrator {
    /// The current loop's exponential integrated exactly into velocity
    /// and position; stiction breakaway at its instant. Accurate with
    /// steps of tens of microseconds (see the module docs).
    #[default]
    Exact,
    /// Semi-implicit Euler (velocity from the end-of-step current,
    /// position from the new velocity): first order, needs steps of a few
    /// microseconds. Kept as the reference.
    SemiImplicitEuler,
}

/// The inputs of an axis: amplifier and external load.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Inputs {
    dac: u16,
    enabled: bool,
    external_torque: f64,
    /// A brake holds the joint: it does not move, whatever drives it.
    braked: bool,
}

/// What changes as the axis moves.
#[derive(Debug, Clone, PartialEq)]
struct State {
    current: f64,
    motor_angle: f64,
    motor_velocity: f64,
    temperature: f64,
    encoder: Encoder,
}

/// Constants of one span of `ps` picoseconds.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Span {
    ps: u64,
    /// Length, s.
    h: f64,
    /// `1 - exp(-h / tau)`: how much of the way the current goes to its
    /// target.
    alpha: f64,
    /// `tau * alpha`, the integral of `exp(-t / tau)` over the span.
    decay: f64,
    /// `tau * (h - tau * alpha)`, its double integral.
    decay2: f64,
    /// `1 / (1 + h b / J)`: the implicit viscous friction.
    viscous: f64,
    /// `1 - exp(-h / tau_thermal)`.
    alpha_thermal: f64,
}

impl Span {
    /// `inv_tau_thermal` is `1 / tau_thermal`; `damping` the viscous
    /// friction over the inertia.
    fn new(ps: u64, tau: f64, inv_tau_thermal: f64, damping: f64) -> Span {
        let h = ps as f64 * 1e-12;
        let x = h / tau;
        // 1 - exp(-x); the series where the subtraction would lose digits.
        let alpha = if x < 1e-4 {
            x * (1.0 - 0.5 * x * (1.0 - x / 3.0))
        } else {
            1.0 - (-x).exp()
        };
        let decay = tau * alpha;
        // Thermal time constants are seconds and viscous damping a few per
        // second: both products are tiny, where these series are exact to
        // the last bit.
        let y = h * inv_tau_thermal;
        let alpha_thermal = if y < 1e-4 {
            y * (1.0 - 0.5 * y)
        } else {
            1.0 - (-y).exp()
        };
        let z = h * damping;
        let viscous = if z < 1e-4 {
            1.0 - z * (1.0 - z)
        } else {
            1.0 / (1.0 + z)
        };
        Span {
            ps,
            h,
            alpha,
            decay,
            decay2: tau * (h - decay),
            viscous,
            alpha_thermal,
        }
    }
}

/// What does not change as the axis moves: parameters and constants
/// derived from them once.
#[derive(Debug, Clone)]
struct Model {
    params: AxisParams,
    integrator: Integrator,
    /// Current-loop time constant, s.
    tau: f64,
    /// One over the thermal time constant, 1/s.
    inv_tau_thermal: f64,
    /// Viscous friction over inertia, 1/s.
    damping: f64,
    /// Constants of a whole grid step.
    grid: Span,
    inertia: f64,
    inv_inertia: f64,
    inv_gear: f64,
    counts_per_rad: f64,
    /// The mechanical stops as motor angles (lower, upper), rad.
    motor_stops: (f64, f64),
}

/// State and parameters of one axis.
#[derive(Debug, Clone)]
pub struct Axis {
    model: Model,
    /// The constants of the last partial spans: spans of the same lengths
    /// recur (a cycle's sample and its command split it at the same
    /// places), and each is computed once.
    memo: SpanMemo,
    /// The same for the rest of a span after a breakaway from rest (kept
    /// apart, so that the span being integrated can be read in place
    /// while one is looked up).
    breakaways: SpanMemo,
    /// The inputs since `time`.
    inputs: Inputs,
    /// The state at `time`.
    state: State,
    /// The current the amplifier drives towards from `time` on, once
    /// worked out (see [`TargetMemo`]).
    target: TargetMemo,
    /// Whether the state was found at rest with its temperature settled
    /// (see [`RestMemo`]).
    rest: RestMemo,
    /// The instant the state is at.
    time: SimTime,
    /// The plant's clock, as the plant last handed it over (before it
    /// lends the axis out to be changed and before it integrates it):
    /// inputs set now take effect then, and the state is integrated up to
    /// it before they do (or when it is looked at).
    clock: SimTime,
}

impl Axis {
    /// An axis at rest at its initial position, amplifier off, at ambient
    /// temperature; `step_ps` is the longest span integrated at once, in
    /// picoseconds.
    pub fn new(params: &AxisParams, step_ps: u64, integrator: Integrator) -> Axis {
        let params = params.sanitized();
        let counts_per_rad = {
            let sign = if params.encoder.reversed { -1.0 } else { 1.0 };
            sign * f64::from(params.encoder.counts_per_rev) / (2.0 * PI)
        };
        let motor_angle = params.load.initial_position * params.load.gear_ratio;
        let encoder = Encoder::new(params.encoder.counts_per_rev, motor_angle * counts_per_rad);
        let motor_stops = {
            let n = params.load.gear_ratio;
            let from_lower = params.stops.lower.map(|l| l * n);
            let from_upper = params.stops.upper.map(|u| u * n);
            // A negative gear ratio swaps which motor angle is the lower stop.
            let (lo, hi) = if n > 0.0 {
                (from_lower, from_upper)
            } else {
                (from_upper, from_lower)
            };
            (lo.unwrap_or(f64::NEG_INFINITY), hi.unwrap_or(f64::INFINITY))
        };
        let tau = 1.0 / (2.0 * PI * params.amplifier.bandwidth_hz);
        let tau_thermal = params.thermal.time_constant;
        let inertia = params.motor_side_inertia();
        let damping = params.motor.viscous_friction / inertia;
        let grid = Span::new(step_ps, tau, 1.0 / tau_thermal, damping);
        let state = State {
            current: 0.0,
            motor_angle,
            motor_velocity: 0.0,
            temperature: params.thermal.ambient_c,
            encoder,
        };
        Axis {
            model: Model {
                inertia,
                inv_inertia: 1.0 / inertia,
                inv_gear: 1.0 / params.load.gear_ratio,
                damping,
                params,
                integrator,
                tau,
                inv_tau_thermal: 1.0 / tau_thermal,
                grid,
                counts_per_rad,
                motor_stops,
            },
            memo: SpanMemo {
                spans: [grid; SpanMemo::LEN],
                next: 0,
            },
            breakaways: SpanMemo {
                spans: [grid; SpanMemo::LEN],
                next: 0,
            },
            inputs: Inputs {
                dac: DAC_ZERO,
                enabled: false,
                external_torque: 0.0,
                braked: false,
            },
            state,
            target: TargetMemo(None),
            rest: RestMemo(false),
            time: SimTime::ZERO,
            clock: SimTime::ZERO,
        }
    }

    /// The (sanitized) parameters.
    pub fn params(&self) -> &AxisParams {
        &self.model.params
    }

    /// How this axis integrates.
    pub fn integrator(&self) -> Integrator {
        self.model.integrator
    }

    /// The inputs in effect at the plant's clock.
    fn latest(&self) -> Inputs {
        self.inputs
    }

    /// Inputs `new` from the plant's clock on: the motion up to the clock
    /// is integrated with the inputs before.
    fn set_inputs(&mut self, new: Inputs) {
        if new == self.inputs {
            return;
        }
        self.catch_up();
        self.inputs = new;
        self.target = TargetMemo(None);
        self.rest = RestMemo(false);
    }

    /// Set the amplifier inputs, from the plant's clock on: DAC code and
    /// whether it is enabled.
    pub fn set_drive(&mut self, dac: u16, enabled: bool) {
        let latest = self.latest();
        self.set_inputs(Inputs {
            dac,
            enabled,
            ..latest
        });
    }

    /// An external torque (force) applied at the joint from the plant's
    /// clock on, e.g. a hand pushing the arm; joint units.
    pub fn set_external_torque(&mut self, torque: f64) {
        let latest = self.latest();
        self.set_inputs(Inputs {
            external_torque: if torque.is_finite() { torque } else { 0.0 },
            ..latest
        });
    }

    /// Engage (`true`) or release a brake on the joint, from the plant's
    /// clock on: an engaged brake holds the joint where it is (the motor
    /// still carries its current; the emulated brake never slips).
    pub fn set_brake(&mut self, engaged: bool) {
        let latest = self.latest();
        self.set_inputs(Inputs {
            braked: engaged,
            ..latest
        });
    }

    /// Whether a brake holds the joint.
    pub fn braked(&self) -> bool {
        self.latest().braked
    }

    /// The DAC code currently applied.
    pub fn dac(&self) -> u16 {
        self.latest().dac
    }

    /// Whether the amplifier is enabled.
    pub fn enabled(&self) -> bool {
        self.latest().enabled
    }

    /// The current the DAC code commands (before limits), A.
    pub fn commanded_current(&self) -> f64 {
        self.model.commanded(self.latest().dac)
    }

    /// The state as last integrated (at the clock once the plant was
    /// advanced there).
    fn observed(&self) -> &State {
        &self.state
    }

    /// The true motor current, A.
    pub fn current(&self) -> f64 {
        self.observed().current
    }

    /// Motor shaft angle, rad.
    pub fn motor_angle(&self) -> f64 {
        self.observed().motor_angle
    }

    /// Motor shaft velocity, rad/s.
    pub fn motor_velocity(&self) -> f64 {
        self.observed().motor_velocity
    }

    /// Joint position, joint units.
    pub fn joint_position(&self) -> f64 {
        self.motor_angle() / self.model.params.load.gear_ratio
    }

    /// Joint velocity, joint units per second.
    pub fn joint_velocity(&self) -> f64 {
        self.motor_velocity() / self.model.params.load.gear_ratio
    }

    /// Amplifier temperature, deg C.
    pub fn temperature(&self) -> f64 {
        self.observed().temperature
    }

    /// The encoder.
    pub fn encoder(&self) -> &Encoder {
        &self.observed().encoder
    }

    /// The potentiometer voltage without noise when the pot measures this
    /// joint: linear in the position, held at the ends of its electrical
    /// range (see [`AxisParams::pot_volts_at`]).
    pub fn pot_voltage(&self) -> f64 {
        self.model.params.pot_volts_at(self.joint_position())
    }

    /// Which mechanical stop the joint rests against, if any: `Some(false)`
    /// the lower, `Some(true)` the upper.
    pub fn at_stop(&self) -> Option<bool> {
        let angle = self.motor_angle();
        let gear = self.model.params.load.gear_ratio;
        if angle <= self.model.motor_stops.0 {
            Some(gear < 0.0)
        } else if angle >= self.model.motor_stops.1 {
            Some(gear > 0.0)
        } else {
            None
        }
    }

    /// (negative limit, positive limit, home) switch states.
    pub fn switches(&self) -> (bool, bool, bool) {
        let q = self.joint_position();
        let s = &self.model.params.switches;
        (
            s.negative_limit.is_some_and(|l| q <= l),
            s.positive_limit.is_some_and(|l| q >= l),
            s.home.is_some_and(|h| q >= h),
        )
    }

    /// Whether the state is at rest with nothing to move it.
    #[cfg(test)]
    pub(crate) fn is_quiescent(&self) -> bool {
        self.model.quiescent(&self.state, self.inputs)
    }

    /// Move the clock to `clock` (never back); the state follows when it
    /// is looked at or the inputs change.
    pub(crate) fn set_clock(&mut self, clock: SimTime) {
        if clock > self.clock {
            self.clock = clock;
        }
    }

    /// Integrate the state from its instant up to the clock, in spans of
    /// at most one step of constant inputs. Inlined: a state already at
    /// the clock, or found at rest and settled before (nothing to
    /// integrate until the inputs change), takes a test or two.
    #[inline]
    pub(crate) fn catch_up(&mut self) {
        if self.time >= self.clock {
            return;
        }
        if self.rest.0 {
            self.time = self.clock;
            return;
        }
        self.integrate_to_clock();
    }

    /// [`catch_up`](Self::catch_up) with time to integrate.
    #[inline(never)]
    fn integrate_to_clock(&mut self) {
        let step = self.model.grid.ps;
        while self.time < self.clock {
            let left = self.clock.0 - self.time.0;
            let len = left.min(step);
            if self.model.quiescent(&self.state, self.inputs) {
                // Nothing moves until the inputs change: only the
                // temperature settles, all the way to the clock at once.
                let steady = steady_temperature(&self.model.params, 0.0, self.inputs.enabled);
                let settled = self.state.temperature;
                // Already settled (a finite, non-zero temperature, and a
                // decay that cannot overflow): the step below adds +0,
                // which leaves it as it is; no exp() to find that out.
                let unchanged = steady == settled
                    && settled.is_finite()
                    && settled != 0.0
                    && self.model.inv_tau_thermal >= 0.0;
                if unchanged {
                    // And so it stays until the inputs change.
                    self.rest = RestMemo(true);
                } else {
                    let keep = (-(left as f64) * 1e-12 * self.model.inv_tau_thermal).exp();
                    self.state.temperature += (steady - self.state.temperature) * (1.0 - keep);
                }
                self.time = self.clock;
                return;
            }
            let target = self.target_now();
            let span = span_of(&self.model, &mut self.memo, len);
            self.model.integrate(
                &mut self.state,
                self.inputs,
                target,
                span,
                self.time,
                &mut self.breakaways,
            );
            // The velocity moved: the next span's target is worked out
            // again.
            self.target = TargetMemo(None);
            self.time = SimTime(self.time.0 + len);
        }
    }

    /// The current the amplifier drives towards from the state's instant
    /// with the inputs since: remembered, or worked out (and not
    /// remembered).
    #[inline]
    fn target(&self) -> f64 {
        match self.target.0 {
            Some(target) => target,
            None => self
                .model
                .target_current(self.inputs, self.state.motor_velocity),
        }
    }

    /// [`target`](Self::target), remembered until the state or the inputs
    /// change.
    #[inline]
    fn target_now(&mut self) -> f64 {
        let target = self.target();
        self.target = TargetMemo(Some(target));
        target
    }

    /// The true current at the plant's clock `clock` (not before the
    /// axis's), A, without integrating the motion: the current loop's
    /// response from the state's instant (the supply's headroom taken at
    /// the state's velocity).
    pub(crate) fn current_at_clock(&self, clock: SimTime) -> f64 {
        if self.time >= clock {
            return self.state.current;
        }
        self.current_at_clock_by(clock, self.target(), f64::exp)
    }

    /// [`current_at_clock`](Self::current_at_clock) with the loop's decay
    /// looked up in `decay` (the same value: `exp` of the same exponent),
    /// the target remembered for the next span integrated (the same
    /// value: the state and the inputs are the same until then).
    pub(crate) fn current_at_clock_memo(&mut self, clock: SimTime, decay: &mut DecayMemo) -> f64 {
        if self.time >= clock {
            return self.state.current;
        }
        let target = self.target_now();
        self.current_at_clock_by(clock, target, |x| decay.exp(x))
    }

    /// The current at `clock` (after the state's instant), going to
    /// `target`, with `exp` for the decay.
    #[inline]
    fn current_at_clock_by(
        &self,
        clock: SimTime,
        target: f64,
        exp: impl FnOnce(f64) -> f64,
    ) -> f64 {
        let i0 = self.state.current;
        if target == i0 {
            return i0;
        }
        let dt = (clock.0 - self.time.0) as f64 * 1e-12;
        target + (i0 - target) * exp(-dt / self.model.tau)
    }

    /// Encoder counts per motor radian (signed by the encoder direction).
    pub fn counts_per_rad(&self) -> f64 {
        self.model.counts_per_rad
    }
}

/// `exp(x)` for the last few exponents `x` asked for: a board's current
/// check asks for the current of each of its axes at one instant, and the
/// axes commanded together (the same time since their state, the same
/// time constant) need the same decay. A value is `exp` of the very same
/// exponent, bit for bit, so it is the value `exp` would give again.
#[derive(Clone)]
pub(crate) struct DecayMemo {
    /// The exponents' bit patterns.
    exponents: [u64; DecayMemo::LEN],
    values: [f64; DecayMemo::LEN],
    /// The slot the next new exponent takes (the oldest).
    next: usize,
}

impl DecayMemo {
    const LEN: usize = 4;

    /// Every slot holds `exp(0)`, computed.
    pub(crate) fn new() -> DecayMemo {
        let zero = 0.0_f64;
        DecayMemo {
            exponents: [zero.to_bits(); DecayMemo::LEN],
            values: [zero.exp(); DecayMemo::LEN],
            next: 0,
        }
    }

    /// `x.exp()`, remembered.
    fn exp(&mut self, x: f64) -> f64 {
        let key = x.to_bits();
        for (k, v) in self.exponents.iter().zip(&self.values) {
            if *k == key {
                return *v;
            }
        }
        let value = x.exp();
        let slot = self.next % DecayMemo::LEN;
        if let (Some(k), Some(v)) = (self.exponents.get_mut(slot), self.values.get_mut(slot)) {
            *k = key;
            *v = value;
        }
        self.next = (slot + 1) % DecayMemo::LEN;
        value
    }
}

/// What is remembered only makes the lookups faster: two plants in the
/// same state may hold different values here (a board's state digest
/// leaves it out).
impl core::fmt::Debug for DecayMemo {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("DecayMemo")
    }
}

/// The target current of an axis's next span, once worked out: a pure
/// function of the inputs and the state's velocity, so a remembered value
/// is the value worked out again (`None` once either changed). The
/// current check at a safety tick and the span integrated next need the
/// same one.
#[derive(Clone, Copy)]
struct TargetMemo(Option<f64>);

/// What is remembered only makes the lookups faster: two axes in the
/// same state may hold different values here (a board's state digest
/// leaves it out).
impl core::fmt::Debug for TargetMemo {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("TargetMemo")
    }
}

/// Whether an axis's state was found at rest, with nothing to move it
/// ([`Model::quiescent`]), and its temperature settled (a span would add
/// +0 to it): then integrating up to any later clock only moves the
/// state's instant, until the inputs change (the state does not change
/// without integrating, and the inputs only through `set_inputs`, which
/// forgets this). `false` is always right: the state is then looked at.
#[derive(Clone, Copy)]
struct RestMemo(bool);

/// Like [`TargetMemo`]'s, a lookup aid only (left out of the digest).
impl core::fmt::Debug for RestMemo {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("RestMemo")
    }
}

/// The constants of the last few partial spans an axis integrated.
#[derive(Debug, Clone)]
struct SpanMemo {
    spans: [Span; SpanMemo::LEN],
    /// The slot the next new span takes (the oldest).
    next: usize,
}

impl SpanMemo {
    /// Spans remembered: the partial spans of a cycle (sample to command,
    /// command to sample, sample to sample) with room for one more.
    const LEN: usize = 4;
}

/// The constants of a span of `ps` picoseconds: the grid step's, a
/// remembered partial span's, or new ones (which are then remembered in
/// place of the oldest). Inlined: every span integrated looks, and
/// almost every look finds; the span is read where it is kept.
#[inline]
fn span_of<'a>(model: &'a Model, memo: &'a mut SpanMemo, ps: u64) -> &'a Span {
    if ps == model.grid.ps {
        return &model.grid;
    }
    let slot = match memo.spans.iter().position(|s| s.ps == ps) {
        Some(slot) => slot,
        None => new_span(model, memo, ps),
    };
    // (`slot` is one of the memo's.)
    memo.spans.get(slot).unwrap_or(&model.grid)
}

/// [`span_of`] for a length not remembered: its constants, in place of
/// the oldest; returns their slot.
#[inline(never)]
fn new_span(model: &Model, memo: &mut SpanMemo, ps: u64) -> usize {
    let slot = memo.next % SpanMemo::LEN;
    if let Some(kept) = memo.spans.get_mut(slot) {
        *kept = Span::new(ps, model.tau, model.inv_tau_thermal, model.damping);
    }
    memo.next = (slot + 1) % SpanMemo::LEN;
    slot
}

impl Model {
    fn commanded(&self, dac: u16) -> f64 {
        (f64::from(dac) - f64::from(self.params.amplifier.zero_code))
            * self.params.amplifier.amps_per_bit
    }

    /// Joint load torque at motor angle `angle` (gravity, spring, bias,
    /// external), joint units. Inlined into the span's integration.
    #[inline]
    fn load_torque(&self, angle: f64, external: f64) -> f64 {
        let load = &self.params.load;
        let q = angle * self.inv_gear;
        let gravity = load
            .gravity
            .as_ref()
            .map_or(0.0, |g| -g.amplitude * sin(q + g.phase));
        let spring = load
            .spring
            .as_ref()
            .map_or(0.0, |s| -s.stiffness * (q - s.rest));
        gravity + spring + load.bias + external
    }

    /// The current the amplifier drives towards with `inputs` at motor
    /// velocity `w`, A.
    fn target_current(&self, inputs: Inputs, w: f64) -> f64 {
        if !inputs.enabled || !self.params.has_motor {
            return 0.0;
        }
        let amp = &self.params.amplifier;
        let motor = &self.params.motor;
        let mut i = self
            .commanded(inputs.dac)
            .clamp(-amp.current_limit, amp.current_limit);
        // Voltage headroom: R i + ke w must stay within the supply.
        let emf = motor.torque_constant * w;
        let v = motor.resistance * i + emf;
        if v > amp.supply_voltage {
            i = (amp.supply_voltage - emf) / motor.resistance;
        } else if v < -amp.supply_voltage {
            i = (-amp.supply_voltage - emf) / motor.resistance;
        }
        i
    }

    /// Whether a span would change nothing but the temperature: at rest,
    /// no current, and the load either held by friction or pressing the
    /// joint into the stop it rests against.
    fn quiescent(&self, s: &State, inputs: Inputs) -> bool {
        if s.current != 0.0 || s.motor_velocity != 0.0 || self.target_current(inputs, 0.0) != 0.0 {
            return false;
        }
        if inputs.braked {
            return true;
        }
        let push = self.load_torque(s.motor_angle, inputs.external_torque) * self.inv_gear;
        push.abs() <= self.params.motor.coulomb_friction
            || (push < 0.0 && s.motor_angle <= self.motor_stops.0)
            || (push > 0.0 && s.motor_angle >= self.motor_stops.1)
    }

    /// Integrate one span of constant `inputs` starting at `start`;
    /// `target` is [`target_current`](Self::target_current) of the inputs
    /// at the state's velocity; `breakaways` remembers the rest of a span
    /// after a breakaway.
    #[allow(clippy::too_many_arguments)]
    fn integrate(
        &self,
        s: &mut State,
        inputs: Inputs,
        target: f64,
        span: &Span,
        start: SimTime,
        breakaways: &mut SpanMemo,
    ) {
        let i0 = s.current;
        let w0 = s.motor_velocity;
        let angle0 = s.motor_angle;
        let mut i1 = i0 + (target - i0) * span.alpha;
        if i1.abs() < CURRENT_EPSILON && target == 0.0 {
            i1 = 0.0;
        }
        let load = self.load_torque(angle0, inputs.external_torque) * self.inv_gear;
        if inputs.braked {
            // Held: the current flows, nothing moves.
            s.current = i1;
            s.motor_velocity = 0.0;
            let steady = steady_temperature(&self.params, i1, inputs.enabled);
            s.temperature += (steady - s.temperature) * span.alpha_thermal;
            return;
        }
        let (w1, angle1) = match self.integrator {
            Integrator::SemiImplicitEuler => self.euler(w0, angle0, i1, load, span.h),
            Integrator::Exact => self.exact(w0, angle0, i0, target, i1, load, span, breakaways),
        };
        s.current = i1;
        s.motor_velocity = if w1.is_finite() { w1 } else { 0.0 };
        // Position inside the stops, and the encoder.
        let (lo, hi) = self.motor_stops;
        let angle = if angle1.is_finite() { angle1 } else { angle0 };
        if angle <= lo {
            s.motor_angle = lo;
            s.motor_velocity = s.motor_velocity.max(0.0);
        } else if angle >= hi {
            s.motor_angle = hi;
            s.motor_velocity = s.motor_velocity.min(0.0);
        } else {
            s.motor_angle = angle;
        }
        if s.motor_angle != angle0 {
            s.encoder.track(
                angle0 * self.counts_per_rad,
                s.motor_angle * self.counts_per_rad,
                start,
                span.ps,
            );
        }
        let steady = steady_temperature(&self.params, i1, inputs.enabled);
        s.temperature += (steady - s.temperature) * span.alpha_thermal;
    }

    /// The semi-implicit Euler step: new velocity from the end-of-step
    /// current `i1`, new angle from the new velocity.
    fn euler(&self, w: f64, angle: f64, i1: f64, load: f64, h: f64) -> (f64, f64) {
        let motor = &self.params.motor;
        let drive = motor.torque_constant * i1 + load;
        let coulomb = motor.coulomb_friction;
        let new_w = if w == 0.0 && drive.abs() <= coulomb {
            0.0
        } else {
            let friction = if w != 0.0 {
                -coulomb * w.signum()
            } else {
                -coulomb * drive.signum()
            };
            let j = self.inertia;
            let candidate =
                (w + h * (drive + friction) / j) / (1.0 + h * motor.viscous_friction / j);
            if w != 0.0 && candidate.signum() != w.signum() {
                0.0
            } else {
                candidate
            }
        };
        let new_w = if new_w.is_finite() { new_w } else { 0.0 };
        (new_w, angle + h * new_w)
    }

    /// The exact span: the current `i(t) = target + (i0 - target)
    /// exp(-t / tau)` integrated into velocity and angle; the load torque
    /// `load` (motor side) and the friction held over the span.
    #[allow(clippy::too_many_arguments)]
    fn exact(
        &self,
        w0: f64,
        angle0: f64,
        i0: f64,
        target: f64,
        i1: f64,
        load: f64,
        span: &Span,
        breakaways: &mut SpanMemo,
    ) -> (f64, f64) {
        let kt = self.params.motor.torque_constant;
        let coulomb = self.params.motor.coulomb_friction;
        if w0 != 0.0 {
            let friction = -coulomb * w0.signum();
            let (w1, angle1) = self.free_motion(w0, angle0, i0, target, load + friction, span);
            if w1.signum() == w0.signum() && w1 != 0.0 {
                return (w1, angle1);
            }
            // The velocity reaches zero inside the span (friction never
            // reverses the motion): stop there, linearly interpolated.
            let stop = span.h * w0 / (w0 - w1);
            return (0.0, angle0 + 0.5 * w0 * stop.clamp(0.0, span.h));
        }
        // At rest: stiction holds while the driving torque stays within
        // the friction; the current moves monotonically towards its
        // target, so it is enough to look at the end of the span.
        let drive_end = kt * i1 + load;
        if drive_end.abs() <= coulomb {
            return (0.0, angle0);
        }
        let dir = drive_end.signum();
        let friction = -coulomb * dir;
        let drive_start = kt * i0 + load;
        if drive_start * dir > coulomb || kt * (i0 - target) == 0.0 {
            return self.free_motion(0.0, angle0, i0, target, load + friction, span);
        }
        // Breakaway when kt i(t) + load = dir * coulomb.
        let ratio = ((dir * coulomb - load) / kt - target) / (i0 - target);
        let breakaway = if ratio > 0.0 && ratio <= 1.0 {
            (-self.tau * ratio.ln()).clamp(0.0, span.h)
        } else {
            0.0
        };
        let breakaway_ps = ((breakaway * 1e12) as u64).min(span.ps);
        if breakaway_ps >= span.ps {
            return (0.0, angle0);
        }
        let i_b = target + (i0 - target) * (-breakaway / self.tau).exp();
        let rest = span_of(self, breakaways, span.ps - breakaway_ps);
        self.free_motion(0.0, angle0, i_b, target, load + friction, rest)
    }

    /// Velocity and angle after `span` from velocity `w0` and angle
    /// `angle0`, with the current going from `i0` towards `target` and a
    /// constant motor-side torque `torque` besides the motor's; viscous
    /// friction implicit.
    fn free_motion(
        &self,
        w0: f64,
        angle0: f64,
        i0: f64,
        target: f64,
        torque: f64,
        span: &Span,
    ) -> (f64, f64) {
        let kt = self.params.motor.torque_constant;
        let h = span.h;
        let di = i0 - target;
        // Integral and double integral of the current over the span.
        let charge = target * h + di * span.decay;
        let charge2 = 0.5 * target * h * h + di * span.decay2;
        let free_w = w0 + (kt * charge + torque * h) * self.inv_inertia;
        let w1 = free_w * span.viscous;
        let free_angle = angle0 + w0 * h + (kt * charge2 + 0.5 * torque * h * h) * self.inv_inertia;
        // The viscous loss grows over the span: about half of the end
        // velocity's loss, on average.
        (w1, free_angle - 0.5 * (free_w - w1) * h)
    }
}

/// `x.sin()` to within 1e-12, without a call into libm: `x` reduced by
/// whole turns (two-part 2 pi, so the reduction is exact to the last bits
/// for the joint angles a plant sees) and folded into [-pi/2, pi/2], then
/// the Taylor series to x^17 (its remainder there is below 5e-14).
fn sin(x: f64) -> f64 {
    use core::f64::consts::{FRAC_PI_2, PI, TAU};
    // TAU's rounding error, for the second part of the reduction.
    const TAU_LO: f64 = 2.449_293_598_294_706_4e-16;
    // Not finite, or too large for the reduction: libm.
    if x.is_nan() || x.abs() >= 1e9 {
        return x.sin();
    }
    let turns = x * (0.5 / PI);
    let k = if turns >= 0.0 {
        (turns + 0.5) as i64
    } else {
        (turns - 0.5) as i64
    } as f64;
    let mut r = (x - k * TAU) - k * TAU_LO;
    if r > FRAC_PI_2 {
        r = PI - r;
    } else if r < -FRAC_PI_2 {
        r = -PI - r;
    }
    let r2 = r * r;
    // 1/3!, 1/5!, ..., 1/17!, alternating.
    let p = 2.811_457_254_345_521e-15;
    let p = p * r2 - 7.647_163_731_819_816e-13;
    let p = p * r2 + 1.605_904_383_682_161_3e-10;
    let p = p * r2 - 2.505_210_838_544_172e-8;
    let p = p * r2 + 2.755_731_922_398_589e-6;
    let p = p * r2 - 1.984_126_984_126_984e-4;
    let p = p * r2 + 8.333_333_333_333_333e-3;
    let p = p * r2 - 1.666_666_666_666_666_6e-1;
    r + r * r2 * p
}

/// The temperature an amplifier settles at with current `current` flowing,
/// deg C.
fn steady_temperature(params: &AxisParams, current: f64, enabled: bool) -> f64 {
    let th = &params.thermal;
    let power = current * current * th.heat_resistance + if enabled { th.idle_power } else { 0.0 };
    th.ambient_c + power * th.thermal_resistance
}

#[cfg(test)]
mod tests {
    use super::{Axis, Integrator, SimTime};
    use crate::plant::presets;

    /// An axis found at rest and settled skips its spans until its inputs
    /// change; then it moves exactly as one that never skipped them.
    #[test]
    fn an_axis_left_at_rest_moves_like_a_fresh_one_once_driven() {
        let params = presets::generic_motor();
        let step = 100_000_000;
        let mut rested = Axis::new(&params, step, Integrator::Exact);
        for k in 1..=20 {
            rested.set_clock(SimTime(k * 37_000_000));
            rested.catch_up();
        }
        assert!(rested.rest.0, "found at rest and settled");
        let mut fresh = Axis::new(&params, step, Integrator::Exact);
        fresh.set_clock(SimTime(20 * 37_000_000));
        for a in [&mut rested, &mut fresh] {
            a.set_drive(a.dac().wrapping_add(3000), true);
            a.set_clock(SimTime(50 * 37_000_000));
            a.catch_up();
        }
        assert!(rested.current() != 0.0 && rested.motor_velocity() != 0.0);
        assert_eq!(rested.state, fresh.state);
        assert_eq!(rested.time, fresh.time);
    }

    #[test]
    fn sin_matches_libm() {
        let mut worst: f64 = 0.0;
        for k in -200_000..=200_000 {
            let x = f64::from(k) * 1e-4;
            worst = worst.max((super::sin(x) - x.sin()).abs());
        }
        for x in [
            1e3,
            -1e3,
            12345.678,
            1e8,
            -1e8,
            1e10,
            f64::NAN,
            f64::INFINITY,
        ] {
            let (a, b) = (super::sin(x), x.sin());
            assert!(
                a == b || (a - b).abs() < 1e-9 || (a.is_nan() && b.is_nan()),
                "{x}"
            );
        }
        assert!(worst < 1e-12, "{worst}");
    }
}
