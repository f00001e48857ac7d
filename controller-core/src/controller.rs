//! The cascaded regulators of the paper's Fig. 5, split into the two ticks.
//!
//! Current tick (every 1/current_rate_hz):
//! ```text
//! position ← unwrap(encoder_count)                       (encoder-jump check)
//! observer ← (position, torque of the last tick: command or measured current)
//! afb      ← AccelerationFeedback(â, a_cmd)               (if AFB runs at this rate;
//!            with the observer's â solved in closed form for this tick's torque)
//! i_ref    = clamp(i_vel + afb, ±torque_limit)            (0 when faulted)
//! v_cmd    = CurrentRegulator(i_ref − i_meas)             (PI, ±voltage_limit)
//! ```
//! Velocity tick (every 1/velocity_rate_hz):
//! ```text
//! ω_cmd = vff·ω_sp + k_pos·(θ_sp − θ)                      (position P; ω_sp in velocity mode)
//! i_vel = VelocityRegulator(ω_cmd − ω_fb) + k_aff·a_sp     (PI, ±torque_limit)
//! afb   ← AccelerationFeedback(...)                         (if AFB runs at this rate)
//! ```
//! In a period where both ticks run, call `velocity_tick` before `current_tick` so the
//! current tick applies the new torque reference at once; the other order adds one current
//! period of delay to the velocity loop and is otherwise equally valid. The velocity tick
//! reads the observer state left by the latest current tick.

use crate::accel_feedback::AccelerationFeedback;
use crate::config::{AfbMode, AfbRate, DriveConfig, Estimator, ObserverTorque};
use crate::design::{design, Gains};
use crate::differentiator::{Differentiator, DifferentiatorState};
use crate::error::ConfigError;
use crate::fault::Fault;
use crate::filter::{LowPass, LowPassState};
use crate::observer::{Observer, ObserverState};
use crate::per_unit::{
    checked_q, count_diff_shifted, count_signed, counter_shift, mul_bits, mul_gain, sat_i32, Coef,
    Counts, CountsErr, Gain, PosGain, Pu, PuPerS, TickGain,
};
use crate::pi::{PiCoefficients, PiState};

/// Inputs of the current tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurrentInputs {
    /// Raw encoder counter, wraps at `counter_bits`.
    pub encoder_count: u32,
    /// Measured current \[pu\].
    pub current_pu: Pu,
}

/// Outputs of the current tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CurrentOutputs {
    /// Voltage command \[pu\], within ±voltage_limit_pu.
    pub voltage_cmd_pu: Pu,
    /// Current (= torque) reference \[pu\], within ±torque_limit_pu; 0 when faulted.
    pub current_ref_pu: Pu,
    /// Acceleration-feedback term added to the torque reference \[pu\].
    pub accel_fb_pu: Pu,
    /// Latched fault, if any.
    pub fault: Option<Fault>,
}

/// A motion command for one velocity tick (from [`crate::Profile::next`] or elsewhere).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Setpoint {
    /// Commanded position \[counts, unwrapped, Q48.16\].
    pub position_counts: Counts,
    /// Commanded velocity \[pu\].
    pub velocity_pu: Pu,
    /// Commanded acceleration \[pu/s\].
    pub acceleration_pu_s: PuPerS,
}

/// Inputs of the velocity tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VelocityInputs {
    /// Raw encoder counter, wraps at `counter_bits`.
    pub encoder_count: u32,
    /// Motion command.
    pub setpoint: Setpoint,
    /// External fault input (latches [`Fault::External`]).
    pub fault_input: bool,
}

/// Outputs of the velocity tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VelocityOutputs {
    /// Torque reference from the velocity regulator plus feed-forward, plus the AFB term
    /// held at that moment, clamped \[pu\].
    pub current_ref_pu: Pu,
    /// Acceleration-feedback term \[pu torque\].
    pub accel_fb_pu: Pu,
    /// Velocity reference into the velocity regulator \[pu\].
    pub velocity_cmd_pu: Pu,
    /// Velocity feedback used by the regulator \[pu\].
    pub velocity_est_pu: Pu,
    /// Acceleration estimate from the AFB source at this rate \[pu/s\].
    pub acceleration_est_pu_s: PuPerS,
    /// Commanded minus measured position \[counts\] (0 in velocity mode).
    pub position_error_counts: CountsErr,
    /// Observer load-torque estimate \[pu\].
    pub disturbance_est_pu: Pu,
    /// Latched fault, if any.
    pub fault: Option<Fault>,
}

/// The quantized blocks of a [`Controller`] ([`Controller::blocks`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blocks {
    /// The state observer (current rate).
    pub observer: Observer,
    /// The velocity-feedback filter (velocity rate).
    pub velocity_filter: LowPass,
    /// Acceleration feedback with its filter.
    pub accel_feedback: AccelerationFeedback,
    /// Velocity PI.
    pub velocity_regulator: PiCoefficients,
    /// Current PI.
    pub current_regulator: PiCoefficients,
}

/// Quantized coefficients (fixed point), built once from [`Gains`].
#[derive(Clone, Copy, Debug, PartialEq)]
struct Coefficients {
    counter_bits: u8,
    /// [`counter_shift`] of `counter_bits`, for the per-tick wrap-safe difference.
    counter_shift: u32,
    position_loop: bool,
    k_pos: PosGain,
    velocity_ff: Gain,
    k_accel_ff: Gain,
    velocity_regulator: PiCoefficients,
    current_regulator: PiCoefficients,
    velocity_filter: LowPass,
    diff_velocity_rate: Differentiator,
    diff_current_rate: Differentiator,
    observer: Observer,
    afb: AccelerationFeedback,
    afb_source: Estimator,
    velocity_source: Estimator,
    observer_torque: ObserverTorque,
    /// The AFB step of the current tick (none unless the mode is on at rate Current).
    afb_current: AfbStep,
    /// The AFB step of the velocity tick (none unless the mode is on at rate Velocity).
    afb_velocity: AfbStep,
    /// The velocity-rate differentiator is used (velocity or acceleration source).
    diff_in_velocity_tick: bool,
    torque_limit: Pu,
    overspeed: Pu,
    following_error: CountsErr,
    max_count_step: i32,
}

/// Which acceleration-feedback step a tick runs: source and form resolved once, when the
/// coefficients are built, so the tick makes one branch instead of testing the mode, the
/// rate and the source every time.
#[derive(Clone, Copy, Debug, PartialEq)]
enum AfbStep {
    /// No AFB in this tick.
    None,
    /// `AccelerationFeedback::update` on the differentiated acceleration.
    Measured,
    /// The closed form on the observer, plain form (filter input −â).
    ClosedPlain,
    /// The closed form on the observer, error form (filter input a_cmd − â).
    ClosedError,
}

impl AfbStep {
    fn select(cfg: &DriveConfig, rate: AfbRate) -> Self {
        let afb = &cfg.accel_feedback;
        if afb.rate != rate {
            return Self::None;
        }
        match (afb.mode, afb.source) {
            (AfbMode::Off, _) => Self::None,
            (_, Estimator::Differentiation) => Self::Measured,
            (AfbMode::Plain, Estimator::Observer) => Self::ClosedPlain,
            (AfbMode::Error, Estimator::Observer) => Self::ClosedError,
        }
    }
}

/// All regulator and estimator state (plain data; reset = default).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct State {
    primed: bool,
    last_raw: u32,
    position: i64,
    velocity_regulator: PiState,
    current_regulator: PiState,
    velocity_filter: LowPassState,
    afb_filter: LowPassState,
    diff_velocity_rate: DifferentiatorState,
    diff_current_rate: DifferentiatorState,
    observer: ObserverState,
    i_vel: Pu,
    afb: Pu,
    current_ref: Pu,
    /// Measured current of the last current tick \[pu\] (observer torque input).
    last_current: Pu,
    accel_cmd: PuPerS,
    fault: Option<Fault>,
}

/// The drive controller: coefficients plus state.
#[derive(Clone, Copy, Debug)]
pub struct Controller {
    gains: Gains,
    coef: Coefficients,
    state: State,
}

fn q<T: fixed::traits::Fixed>(
    v: f32,
    param: &'static str,
    q_format: &'static str,
) -> Result<T, ConfigError> {
    let overflow = ConfigError::CoefficientOverflow {
        param,
        value: v,
        q_format,
    };
    let x: T = checked_q::<T>(v).ok_or(overflow)?;
    // A non-zero coefficient must keep at least ~1 % relative precision.
    let back: f32 = x.to_num();
    if v != 0.0 && ((back - v) / v).abs() > 0.01 {
        return Err(ConfigError::CoefficientUnderflow {
            param,
            value: v,
            q_format,
        });
    }
    Ok(x)
}

impl Coefficients {
    fn from_gains(cfg: &DriveConfig, g: &Gains) -> Result<Self, ConfigError> {
        let lim: Pu = q(cfg.torque_limit_pu, "torque_limit_pu", "Q16.16")?;
        let vlim: Pu = q(cfg.voltage_limit_pu, "voltage_limit_pu", "Q16.16")?;
        let filter = LowPass::quantize(&g.afb_filter, "accel_feedback.filter coefficients")?;
        // Closed form of the loop through the observer's model (accel_feedback module docs):
        // g·Ka with g = 1/(1 + b0·Ka/J_model); b0 from the quantized filter, so that the
        // solved loop is the one the tick runs.
        let ka_closed = if cfg.accel_feedback.source == Estimator::Observer {
            let b0: f32 = filter.feedthrough().to_num();
            let gain = 1.0 / (1.0 + b0 * g.ka / g.observer_inertia_s);
            q::<Gain>(
                g.ka * gain,
                "ka/(1 + b0·Ka/J_model) (accel_feedback.gain_fraction, filter, observer inertia)",
                "Q16.16",
            )?
        } else {
            Gain::ZERO
        };
        let afb = AccelerationFeedback {
            mode: cfg.accel_feedback.mode,
            ka: q(
                g.ka,
                "ka (accel_feedback.gain_fraction × total inertia)",
                "Q16.16",
            )?,
            filter,
            limit: lim,
            ka_closed,
        };
        let diff = |v: f32,
                    a: f32,
                    pv: &'static str,
                    pa: &'static str|
         -> Result<Differentiator, ConfigError> {
            Ok(Differentiator {
                k_vel: q(v, pv, "Q8.24")?,
                k_acc: q(a, pa, "Q16.16")?,
            })
        };
        let [l1, l2, l3] = g.observer_l;
        let observer = Observer {
            l1: q::<Coef>(l1, "observer l1 (observer.bandwidth_hz)", "Q2.30")?,
            l2: q::<Coef>(l2, "observer l2 (observer.bandwidth_hz)", "Q2.30")?,
            l3: q::<Coef>(l3, "observer l3 (observer.bandwidth_hz)", "Q2.30")?,
            k_u: q(
                g.observer_k_u,
                "observer k_u (inertia, encoder_cpr, current_rate_hz)",
                "Q8.24",
            )?,
            k_vel: q(
                g.cur_tick_pu_per_count,
                "pu per count per current tick (encoder_cpr, base_speed_rpm, current_rate_hz)",
                "Q8.24",
            )?,
            k_acc: q(
                g.cur_tick_pu_s_per_count,
                "pu/s per count per current tick² (encoder_cpr, base_speed_rpm, current_rate_hz)",
                "Q16.16",
            )?,
            k_load: q(-g.observer_inertia_s, "observer model inertia", "Q16.16")?,
        };
        Ok(Self {
            counter_bits: cfg.counter_bits,
            counter_shift: counter_shift(cfg.counter_bits),
            position_loop: g.kpp > 0.0,
            k_pos: if g.kpp > 0.0 {
                q(
                    g.k_pos_pu_per_count,
                    "k_pos (position_bandwidth_rad_s / counts per pu·s)",
                    "Q1.31",
                )?
            } else {
                PosGain::ZERO
            },
            velocity_ff: q(cfg.velocity_ff_gain, "velocity_ff_gain", "Q16.16")?,
            k_accel_ff: q(
                g.k_accel_ff,
                "k_accel_ff (accel_ff_gain × inertia)",
                "Q16.16",
            )?,
            velocity_regulator: PiCoefficients {
                kp: q(
                    g.kp_vel,
                    "kp_vel (velocity_bandwidth_rad_s × inertia)",
                    "Q16.16",
                )?,
                ki_ts: q::<TickGain>(
                    g.ki_vel / cfg.velocity_rate_hz as f32,
                    "ki_vel·Ts (velocity_bandwidth_rad_s, velocity_damping)",
                    "Q8.24",
                )?,
                limit: lim,
            },
            current_regulator: PiCoefficients {
                kp: q(
                    g.kp_cur,
                    "kp_cur (winding_inductance_pu_s × current_bandwidth_rad_s)",
                    "Q16.16",
                )?,
                ki_ts: q::<TickGain>(
                    g.ki_cur / cfg.current_rate_hz as f32,
                    "ki_cur·Ts (winding_resistance_pu × current_bandwidth_rad_s)",
                    "Q8.24",
                )?,
                limit: vlim,
            },
            velocity_filter: LowPass::quantize(&g.velocity_filter, "velocity_filter coefficients")?,
            diff_velocity_rate: diff(
                g.vel_tick_pu_per_count,
                g.vel_tick_pu_s_per_count,
                "pu per count per velocity tick (encoder_cpr, base_speed_rpm, velocity_rate_hz)",
                "pu/s per count per velocity tick² (encoder_cpr, base_speed_rpm, velocity_rate_hz)",
            )?,
            diff_current_rate: diff(
                g.cur_tick_pu_per_count,
                g.cur_tick_pu_s_per_count,
                "pu per count per current tick (encoder_cpr, base_speed_rpm, current_rate_hz)",
                "pu/s per count per current tick² (encoder_cpr, base_speed_rpm, current_rate_hz)",
            )?,
            observer,
            afb,
            afb_source: cfg.accel_feedback.source,
            velocity_source: cfg.velocity_estimator,
            observer_torque: cfg.observer.torque_input,
            afb_current: AfbStep::select(cfg, AfbRate::Current),
            afb_velocity: AfbStep::select(cfg, AfbRate::Velocity),
            diff_in_velocity_tick: cfg.velocity_estimator == Estimator::Differentiation
                || cfg.accel_feedback.source == Estimator::Differentiation,
            torque_limit: lim,
            overspeed: q(cfg.faults.overspeed_pu, "faults.overspeed_pu", "Q16.16")?,
            following_error: q(
                cfg.faults.following_error_counts,
                "faults.following_error_counts",
                "Q24.8",
            )?,
            max_count_step: q::<CountsErr>(
                g.max_count_step,
                "max count step (faults.encoder_jump_margin × overspeed)",
                "Q24.8",
            )?
            .to_num::<i32>(),
        })
    }
}

impl Controller {
    /// Validate the settings, design the gains and build a controller in its reset state.
    ///
    /// ```
    /// let c = controller_core::Controller::new(&controller_core::DriveConfig::table1()).unwrap();
    /// assert!(c.fault().is_none());
    /// ```
    pub fn new(cfg: &DriveConfig) -> Result<Self, ConfigError> {
        let gains = design(cfg)?;
        Self::build(cfg, &gains)
    }

    /// Build a controller from explicitly given gains (e.g. [`design()`] output with some
    /// gains changed; for "the same gains" with acceleration feedback off use
    /// [`Gains::without_afb`] with a config whose `accel_feedback.mode` is `Off`). The
    /// settings still supply limits, modes and rates and are validated (`design(cfg)` must
    /// succeed); every coefficient is taken from `gains` and checked against its Q-format.
    ///
    /// ```
    /// use controller_core::{design, AfbMode, Controller, DriveConfig};
    /// let cfg = DriveConfig::table1();
    /// let mut off = cfg;
    /// off.accel_feedback.mode = AfbMode::Off;
    /// let g = design(&cfg).unwrap().without_afb();
    /// let c = Controller::with_gains(&off, &g).unwrap();
    /// assert_eq!(c.gains(), &g);
    /// ```
    pub fn with_gains(cfg: &DriveConfig, gains: &Gains) -> Result<Self, ConfigError> {
        // Validation only: the designed gains themselves are not used.
        design(cfg)?;
        Self::build(cfg, gains)
    }

    /// Quantize `gains` for the (already validated) settings `cfg`.
    fn build(cfg: &DriveConfig, gains: &Gains) -> Result<Self, ConfigError> {
        let coef = Coefficients::from_gains(cfg, gains)?;
        Ok(Self {
            gains: *gains,
            coef,
            state: State::default(),
        })
    }

    /// The designed gains (f32).
    #[must_use]
    pub fn gains(&self) -> &Gains {
        &self.gains
    }

    /// The quantized blocks the ticks run, to time or test one block on its own (e.g.
    /// `cargo fw-bench`'s per-block table). Copies: the controller is not affected.
    #[must_use]
    pub fn blocks(&self) -> Blocks {
        let c = &self.coef;
        Blocks {
            observer: c.observer,
            velocity_filter: c.velocity_filter,
            accel_feedback: c.afb,
            velocity_regulator: c.velocity_regulator,
            current_regulator: c.current_regulator,
        }
    }

    /// The latched fault, if any.
    #[must_use]
    pub fn fault(&self) -> Option<Fault> {
        self.state.fault
    }

    /// Clear a latched fault and all regulator and estimator state. The next encoder
    /// reading becomes the position reference again (the raw counter read as signed).
    pub fn reset(&mut self) {
        self.state = State::default();
    }

    /// Latch a fault (the first one wins) and drop every torque-producing state.
    fn trip(&mut self, fault: Fault) {
        if self.state.fault.is_none() {
            self.state.fault = Some(fault);
        }
        let s = &mut self.state;
        s.velocity_regulator = PiState::default();
        s.afb_filter = LowPassState::default();
        s.i_vel = Pu::ZERO;
        s.afb = Pu::ZERO;
    }

    /// Update the unwrapped position from a raw counter reading; trips on a count jump.
    #[inline]
    fn read_encoder(&mut self, raw: u32) {
        let bits = self.coef.counter_bits;
        if self.state.primed {
            let d = count_diff_shifted(raw, self.state.last_raw, self.coef.counter_shift);
            self.state.position = self.state.position.wrapping_add(i64::from(d));
            if d.unsigned_abs() > self.coef.max_count_step.unsigned_abs() {
                self.trip(Fault::EncoderJump);
            }
        } else {
            self.state.position = i64::from(count_signed(raw, bits));
            self.state.primed = true;
        }
        self.state.last_raw = raw;
    }

    /// Acceleration-feedback step with a measured acceleration (differentiation).
    #[inline]
    fn afb_step(&mut self, a_meas: PuPerS) {
        if self.state.fault.is_none() {
            let a_cmd = self.state.accel_cmd;
            self.state.afb = self
                .coef
                .afb
                .update(&mut self.state.afb_filter, a_meas, a_cmd);
        }
    }

    /// Acceleration-feedback step with the observer's acceleration, the loop through its
    /// model solved in closed form for the torque reference `i_vel` + afb; `c` is the
    /// command part of the filter input (0 in the plain form, a_cmd in the error form).
    #[inline]
    fn afb_closed_step(&mut self, c: PuPerS) {
        if self.state.fault.is_none() {
            let obs = &self.coef.observer;
            let os = &self.state.observer;
            self.state.afb = self.coef.afb.update_closed_from(
                &mut self.state.afb_filter,
                self.state.i_vel,
                c,
                |t| obs.predicted_acceleration_pu_s(os, t),
            );
        }
    }

    /// The AFB step `step` of a tick; `a_meas` is that tick's differentiated acceleration
    /// (used by [`AfbStep::Measured`] only).
    #[inline]
    fn run_afb(&mut self, step: AfbStep, a_meas: impl FnOnce(&mut Self) -> PuPerS) {
        match step {
            AfbStep::None => {}
            AfbStep::Measured => {
                let a = a_meas(self);
                self.afb_step(a);
            }
            AfbStep::ClosedPlain => self.afb_closed_step(PuPerS::ZERO),
            AfbStep::ClosedError => self.afb_closed_step(self.state.accel_cmd),
        }
    }

    fn total_ref(&self) -> Pu {
        if self.state.fault.is_some() {
            Pu::ZERO
        } else {
            let lim = self.coef.torque_limit;
            self.state
                .i_vel
                .saturating_add(self.state.afb)
                .max(-lim)
                .min(lim)
        }
    }

    /// The current tick: run every 1/current_rate_hz.
    ///
    /// ```
    /// use controller_core::{Controller, CurrentInputs, DriveConfig, Pu};
    /// let mut c = Controller::new(&DriveConfig::table1()).unwrap();
    /// let out = c.current_tick(CurrentInputs { encoder_count: 0, current_pu: Pu::ZERO });
    /// assert_eq!(out.current_ref_pu, Pu::ZERO);
    /// ```
    pub fn current_tick(&mut self, inp: CurrentInputs) -> CurrentOutputs {
        self.read_encoder(inp.encoder_count);
        let position = self.state.position;
        // The observer sees the torque that acted over the last tick: the command, or the
        // mean of the current sampled at its start and now (Q16.16, halved sum in i64).
        let torque = match self.coef.observer_torque {
            ObserverTorque::Command => self.state.current_ref,
            ObserverTorque::MeasuredCurrent => Pu::from_bits(sat_i32(
                (i64::from(self.state.last_current.to_bits())
                    + i64::from(inp.current_pu.to_bits()))
                    >> 1,
            )),
        };
        self.state.last_current = inp.current_pu;
        self.coef
            .observer
            .update(&mut self.state.observer, position, torque);
        // The current-rate differentiator runs only when it feeds the AFB here.
        self.run_afb(self.coef.afb_current, |c| {
            c.coef
                .diff_current_rate
                .update(&mut c.state.diff_current_rate, position)
                .1
        });
        let i_ref = self.total_ref();
        self.state.current_ref = i_ref;
        let e = i_ref.saturating_sub(inp.current_pu);
        let v = self
            .coef
            .current_regulator
            .update(&mut self.state.current_regulator, e, Pu::ZERO);
        CurrentOutputs {
            voltage_cmd_pu: v,
            current_ref_pu: i_ref,
            accel_fb_pu: self.state.afb,
            fault: self.state.fault,
        }
    }

    /// The velocity tick: run every 1/velocity_rate_hz (every n-th current tick).
    ///
    /// ```
    /// use controller_core::{Controller, DriveConfig, VelocityInputs};
    /// let mut c = Controller::new(&DriveConfig::table1()).unwrap();
    /// let out = c.velocity_tick(VelocityInputs::default());
    /// assert!(out.fault.is_none());
    /// ```
    pub fn velocity_tick(&mut self, inp: VelocityInputs) -> VelocityOutputs {
        self.read_encoder(inp.encoder_count);
        if inp.fault_input {
            self.trip(Fault::External);
        }
        let position = self.state.position;
        let sp = inp.setpoint;
        self.state.accel_cmd = sp.acceleration_pu_s;

        // Differentiate only when a loop uses it (its state is then updated every tick).
        let (v_diff, a_diff) = if self.coef.diff_in_velocity_tick {
            self.coef
                .diff_velocity_rate
                .update(&mut self.state.diff_velocity_rate, position)
        } else {
            (Pu::ZERO, Pu::ZERO)
        };
        let obs = &self.coef.observer;
        let v_raw = match self.coef.velocity_source {
            Estimator::Differentiation => v_diff,
            Estimator::Observer => obs.velocity_pu(&self.state.observer),
        };
        let v_fb = self
            .coef
            .velocity_filter
            .process(&mut self.state.velocity_filter, v_raw);
        let a_est = match self.coef.afb_source {
            Estimator::Differentiation => a_diff,
            Estimator::Observer => obs.acceleration_pu_s(&self.state.observer),
        };
        let disturbance = obs.load_torque_pu(&self.state.observer);
        if v_fb.unsigned_abs() > self.coef.overspeed.unsigned_abs() {
            self.trip(Fault::Overspeed);
        }

        // Position loop: error in Q24.8 counts (saturating), ω_cmd = vff·ω_sp + k_pos·err.
        let (pos_err, v_cmd) = if self.coef.position_loop {
            // Q48.16 ≫ 8 is below 2^55 in magnitude; while |position| < 2^54 counts (the
            // bits from 2^54 up all the sign: one high-word compare) position·256 is below
            // 2^62 and the difference below 2^63, so plain arithmetic gives the exact value
            // the saturating form gives.
            let sp_q8 = sp.position_counts.to_bits() >> 8;
            let err_bits = if position >> 54 == position >> 63 {
                sp_q8 - (position << 8)
            } else {
                sp_q8.saturating_sub(position.saturating_mul(256))
            };
            let err = CountsErr::from_bits(sat_i32(err_bits));
            if err.unsigned_abs() > self.coef.following_error.unsigned_abs() {
                self.trip(Fault::FollowingError);
            }
            // Q24.8 · Q1.31 = Q.39 → Q16.16.
            let p_term = Pu::from_bits(mul_bits::<23>(err.to_bits(), self.coef.k_pos.to_bits()));
            (
                err,
                mul_gain(sp.velocity_pu, self.coef.velocity_ff).saturating_add(p_term),
            )
        } else {
            (CountsErr::ZERO, sp.velocity_pu)
        };

        if self.state.fault.is_none() {
            let ff = mul_gain(sp.acceleration_pu_s, self.coef.k_accel_ff);
            let e = v_cmd.saturating_sub(v_fb);
            // Anti-windup judged on the final torque reference (PI + AFB term held now).
            self.state.i_vel = self.coef.velocity_regulator.update_with_offset(
                &mut self.state.velocity_regulator,
                e,
                ff,
                self.state.afb,
            );
            self.run_afb(self.coef.afb_velocity, |_| a_est);
        }
        VelocityOutputs {
            current_ref_pu: self.total_ref(),
            accel_fb_pu: self.state.afb,
            velocity_cmd_pu: v_cmd,
            velocity_est_pu: v_fb,
            acceleration_est_pu_s: a_est,
            position_error_counts: pos_err,
            disturbance_est_pu: disturbance,
            fault: self.state.fault,
        }
    }
}
