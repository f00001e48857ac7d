//! The cascaded regulators of the paper's Fig. 5, split into the two ticks.
//!
//! The cascade is composed of blocks, each a module holding its quantized coefficients,
//! its state and its step: the position loop (`position.rs`), the velocity loop
//! (`velocity.rs`), the current loop (the DC winding's PI, `current.rs`; a PMSM's
//! field-oriented loop, [`crate::foc`] through `pmsm.rs`) and the acceleration feedback
//! (`afb.rs`, on [`crate::accel_feedback`] and the observer). Each block's linear form is
//! its coefficients' stored bits ([`Controller::blocks`], `linear()`); each tick record's
//! word layout is written once in [`crate::words`].
//!
//! Current tick (every 1/current_rate_hz):
//! ```text
//! position ← unwrap(encoder_count)                       (encoder-jump check)
//! observer ← (position, torque of the last tick: command or measured current)
//! afb      ← AccelerationFeedback(â, a_cmd)               (if AFB runs at this rate;
//!            with the observer's â solved in closed form for this tick's torque)
//! i_sum    = clamp(i_vel + afb + r, ±torque_limit)        (0 when faulted; r the
//!            torque-reference excitation, 0 unless one is set)
//! i_ref    = clamp(N(i_sum), ±torque_limit)               (N the notch if one is set,
//!            else i_ref = i_sum; 0 when faulted)
//! v_cmd    = CurrentRegulator(i_ref − i_meas)             (PI, ±voltage_limit)
//! protection ← i_meas                                    (overcurrent check; a trip
//!            zeroes this tick's i_ref output and latches the fault)
//! ```
//! The notch N ([`crate::notch`]) shapes everything that reaches the current loop (the
//! velocity PI, the AFB term and the excitation) and runs only in the current tick; its
//! output is clamped again because its transient can overshoot. The AFB's closed form
//! solves for i_sum, the torque before the notch; the observer's torque input (`command`)
//! is i_ref, the torque the current loop is asked for. A fault clears the notch's state.
//! Velocity tick (every 1/velocity_rate_hz):
//! ```text
//! ω_cmd = vff·ω_sp + k_pos·(θ_sp − θ) + r                  (position P; ω_sp in velocity mode;
//!                                                          r a velocity-reference excitation)
//! i_vel = VelocityRegulator(ω_cmd − ω_fb) + k_aff·a_sp     (PI, ±torque_limit)
//! afb   ← AccelerationFeedback(...)                         (if AFB runs at this rate)
//! I²t, stall ← (i_meas of the last current tick; clamp(i_vel + afb + r, ±torque_limit), ω_fb)
//! ```
//! In a period where both ticks run, call `velocity_tick` before `current_tick` so the
//! current tick applies the new torque reference at once; the other order adds one current
//! period of delay to the velocity loop and is otherwise equally valid. The velocity tick
//! reads the observer state left by the latest current tick.

mod afb;
mod coefficients;
mod current;
mod excite;
mod io;
mod pmsm;
mod position;
#[cfg(test)]
mod tests;
mod velocity;

pub use io::{Blocks, CurrentInputs, CurrentOutputs, Setpoint, VelocityInputs, VelocityOutputs};
pub use pmsm::{PmsmInputs, PmsmOutputs};

use crate::config::{DriveConfig, Estimator, ObserverTorque};
use crate::design::{Gains, design};
use crate::differentiator::DifferentiatorState;
use crate::error::ConfigError;
use crate::excitation::{Excitation, ExcitationState, Injection};
use crate::fault::Fault;
use crate::filter::LowPassState;
use crate::notch::NotchState;
use crate::observer::ObserverState;
use crate::per_unit::{Pu, PuPerS, count_diff_by, count_signed, sat_shr};
use crate::pi::PiState;
use crate::protection::ProtectionState;
use coefficients::Coefficients;

/// All regulator and estimator state (plain data; reset = default).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct State {
    primed: bool,
    last_raw: u32,
    position: i64,
    /// The velocity loop's integrator and feedback filter.
    velocity: velocity::VelocityState,
    current_regulator: PiState,
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
    /// The excitation's state and its latest sample \[pu\] (zero without one).
    excitation: ExcitationState,
    excitation_pu: Pu,
    /// The torque-reference notch's state (untouched without a notch).
    notch: NotchState,
    /// Overcurrent and stall counts, the I²t heat (kept across [`Controller::reset`]).
    protection: ProtectionState,
    fault: Option<Fault>,
    /// A PMSM drive's FOC state (untouched on a DC drive).
    foc: crate::foc::FocState,
    /// Whether the FOC angle has been set from a count, and the raw counter it was last
    /// moved to. Both, and the angle, outlive [`Controller::reset`]: the angle follows
    /// the shaft from the first reading on ([`Controller::pmsm_track`] while no tick
    /// runs), since the counter's wraps are not whole turns of an encoder whose counts
    /// per turn do not divide them.
    foc_primed: bool,
    foc_last_raw: u32,
    /// A PMSM drive's measured torque λ·i_q of the last tick (the DC drive's is
    /// `last_current`).
    pmsm_torque: Pu,
    /// A PMSM drive's i_d² + i_q² of the last tick (raw Q32.32, at most 2^62): the I²t
    /// model's input in place of `last_current`'s square (0 on a DC drive).
    pmsm_current_sq: i64,
}

/// The drive controller: coefficients plus state.
///
/// Laid out in declaration order (`repr(C)`): the state and the coefficients the ticks
/// read first, the designed gains and a PMSM drive's FOC loop last, so that the DC ticks
/// reach their fields within the Cortex-M4's short load offsets whatever those sizes.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct Controller {
    state: State,
    coef: Coefficients,
    /// The identification excitation, if any ([`Controller::with_excitation`]); none by
    /// default, and then every output is what it is without this feature.
    excitation: Option<Excitation>,
    /// Whether `excitation` is set and enters at the torque reference (at the velocity
    /// reference): decided when it is set, so a tick tests one flag instead of matching the
    /// option and the injection point.
    torque_excited: bool,
    velocity_excited: bool,
    /// Whether the closed-form AFB step's clamped torque is the total torque reference
    /// itself (see [`Controller::closed_total_exact`]): decided at configuration and when an
    /// excitation is set, so the current tick does not add and clamp the same sum twice.
    closed_total: bool,
    gains: Gains,
    /// A PMSM drive's field-oriented current loop (`[drive.pmsm]`); `None` for DC.
    foc: Option<crate::foc::FocCoefficients>,
}

impl Controller {
    /// Validate the settings, design the gains and build a controller in its reset state:
    /// `Controller::from_gains(&design(cfg)?)`.
    ///
    /// ```
    /// # let cfg: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// let c = controller_core::Controller::new(&cfg).unwrap();
    /// assert!(c.fault().is_none());
    /// ```
    pub fn new(cfg: &DriveConfig) -> Result<Self, ConfigError> {
        Self::from_gains(&design(cfg)?)
    }

    /// Build a controller from designed gains without designing again: [`design()`] output,
    /// e.g. [`Gains::without_afb`] for "the same gains" with acceleration feedback off, or
    /// with some gains changed. The settings [`Gains::cfg`] carries supply the limits, modes
    /// and rates; every coefficient is taken from `gains` and checked against its Q-format.
    ///
    /// ```
    /// use controller_core::{design, Controller};
    /// # let cfg: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// let g = design(&cfg).unwrap().without_afb();
    /// let c = Controller::from_gains(&g).unwrap();
    /// assert_eq!(c.gains(), &g);
    /// ```
    pub fn from_gains(gains: &Gains) -> Result<Self, ConfigError> {
        let coef = Coefficients::from_gains(gains)?;
        let foc = pmsm::foc_of(&gains.cfg)?;
        Ok(Self {
            foc,
            gains: *gains,
            closed_total: Self::closed_total_exact(&coef, false),
            coef,
            excitation: None,
            torque_excited: false,
            velocity_excited: false,
            state: State::default(),
        })
    }

    /// Whether the torque `t` the closed-form AFB step forms, t = clamp(p + afb, ±|lim|)
    /// with p = i_vel + r, is bit for bit [`Controller::total_ref`] =
    /// clamp((i_vel + afb) + r, ±torque_limit) (saturating adds) on a tick without a fault:
    /// * the AFB's limit is the torque limit (`accel_feedback(g, lim)`), so the clamps are
    ///   the same when torque_limit ≥ 0 (|lim| = lim; a hand-made negative limit is refused
    ///   here, and 0 clamps both to 0);
    /// * without a torque-reference excitation r = 0, and with saturating adds too
    ///   (i_vel + 0) + afb equals (i_vel + afb) + 0. With one, the two orders of the
    ///   saturating adds could differ at the i32 bounds, so the tick then forms the sum
    ///   again.
    fn closed_total_exact(coef: &Coefficients, torque_excited: bool) -> bool {
        coef.afb.limit == coef.torque_limit && coef.torque_limit >= Pu::ZERO && !torque_excited
    }

    /// The designed gains (f32).
    #[must_use]
    pub fn gains(&self) -> &Gains {
        &self.gains
    }

    /// The quantized blocks the ticks run, to time or test one block on its own (e.g.
    /// `cargo fw-bench`'s per-block table) or to read their linear forms (each block's
    /// `linear()`, e.g. loop-model's mirror). Copies: the controller is not affected.
    #[must_use]
    pub fn blocks(&self) -> Blocks {
        let c = &self.coef;
        Blocks {
            observer: c.observer,
            velocity_filter: c.velocity.filter,
            accel_feedback: c.afb,
            velocity_regulator: c.velocity.regulator,
            current_regulator: c.current.regulator,
            notch: c.notch,
            k_pos: c.position.k_pos,
            velocity_ff: c.position.velocity_ff,
            k_accel_ff: c.velocity.k_accel_ff,
            diff_velocity_rate: c.diff_velocity_rate,
            diff_current_rate: c.diff_current_rate,
        }
    }

    /// The latched fault, if any.
    #[must_use]
    pub fn fault(&self) -> Option<Fault> {
        self.state.fault
    }

    /// Whether the I²t model of the winding is at or above its warning level
    /// (`faults.thermal_warning_fraction` of the trip level; [`crate::protection`]).
    #[must_use]
    pub fn thermal_warning(&self) -> bool {
        self.coef.protection.warning(&self.state.protection)
    }

    /// The I²t model's heat as a fraction of its trip level (0 cold, 1 tripped).
    #[must_use]
    pub fn thermal_load(&self) -> f32 {
        self.coef.protection.load_fraction(&self.state.protection)
    }

    /// The quantized protection settings (overcurrent level, I²t trip time at a current).
    #[must_use]
    pub fn protection(&self) -> &crate::protection::Protection {
        &self.coef.protection
    }

    /// Clear a latched fault and all regulator and estimator state. The next encoder
    /// reading becomes the position reference again (the raw counter read as signed).
    /// The I²t model's heat is kept: clearing a fault does not cool the winding. A PMSM
    /// drive's electrical angle is kept too: it is where the rotor stands, not a state of
    /// a regulator.
    pub fn reset(&mut self) {
        let protection = self.state.protection.after_reset();
        let angle = (
            self.state.foc_primed,
            self.state.foc_last_raw,
            self.state.foc.angle,
        );
        self.state = State::default();
        self.state.protection = protection;
        (
            self.state.foc_primed,
            self.state.foc_last_raw,
            self.state.foc.angle,
        ) = angle;
    }

    /// Latch a fault (the first one wins) and drop every torque-producing state.
    fn trip(&mut self, fault: Fault) {
        if self.state.fault.is_none() {
            self.state.fault = Some(fault);
        }
        let s = &mut self.state;
        s.velocity.regulator = PiState::default();
        s.afb_filter = LowPassState::default();
        s.i_vel = Pu::ZERO;
        s.afb = Pu::ZERO;
        s.notch = NotchState::default();
    }

    /// Update the unwrapped position from a raw counter reading; trips on a count jump.
    #[inline]
    fn read_encoder(&mut self, raw: u32) {
        let bits = self.coef.counter_bits;
        if self.state.primed {
            // counter_shift ≤ 16 (per_unit::counter_shift), so no clamp here.
            let d = count_diff_by(raw, self.state.last_raw, self.coef.counter_shift);
            self.state.position = self.state.position.wrapping_add(i64::from(d));
            if self.coef.max_count_step_abs.exceeded_by(d) {
                self.trip(Fault::EncoderJump);
            }
        } else {
            self.state.position = i64::from(count_signed(raw, bits));
            self.state.primed = true;
        }
        self.state.last_raw = raw;
    }

    fn total_ref(&self) -> Pu {
        if self.state.fault.is_some() {
            Pu::ZERO
        } else {
            let lim = self.coef.torque_limit;
            self.state
                .i_vel
                .saturating_add(self.state.afb)
                .saturating_add(self.torque_excitation())
                .max(-lim)
                .min(lim)
        }
    }

    /// The torque reference of a current tick: [`Self::total_ref`] through the notch and
    /// clamped again, advancing the notch's state; without a notch (or when faulted),
    /// `total_ref` itself. `closed` is the closed-form AFB step's torque of this tick, if
    /// it ran: `total_ref` itself when [`Self::closed_total_exact`] held.
    #[inline(always)]
    fn notched_ref(&mut self, closed: Option<Pu>) -> Pu {
        let t = match closed {
            Some(t) if self.closed_total => t,
            _ => self.total_ref(),
        };
        match self.coef.notch {
            Some(n) if self.state.fault.is_none() => {
                let lim = self.coef.torque_limit;
                n.process(&mut self.state.notch, t).max(-lim).min(lim)
            }
            _ => t,
        }
    }

    /// The current tick: run every 1/current_rate_hz.
    ///
    /// ```
    /// use controller_core::{Controller, CurrentInputs, Pu};
    /// # let cfg: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// let mut c = Controller::new(&cfg).unwrap();
    /// let out = c.current_tick(CurrentInputs { encoder_count: 0, current_pu: Pu::ZERO });
    /// assert_eq!(out.current_ref_pu, Pu::ZERO);
    /// ```
    #[inline(always)]
    pub fn current_tick(&mut self, inp: CurrentInputs) -> CurrentOutputs {
        self.read_encoder(inp.encoder_count);
        let torque = self.observer_torque(self.state.last_current, inp.current_pu);
        self.state.last_current = inp.current_pu;
        let i_ref = self.torque_stage(torque);
        let e = i_ref.saturating_sub(inp.current_pu);
        let v = self
            .coef
            .current
            .regulate(&mut self.state.current_regulator, e);
        // The protections last, on this tick's sample: a trip latches now, and this tick's
        // outputs already carry it (the board drops the enable in this tick).
        let mut i_ref = i_ref;
        if self
            .coef
            .protection
            .current_tick(&mut self.state.protection, inp.current_pu)
        {
            self.trip(Fault::Overcurrent);
            i_ref = Pu::ZERO;
            self.state.current_ref = Pu::ZERO;
        }
        CurrentOutputs {
            voltage_cmd_pu: v,
            current_ref_pu: i_ref,
            accel_fb_pu: self.state.afb,
            fault: self.state.fault,
        }
    }

    /// The torque the observer sees as having acted over the last tick: the command, or
    /// the mean of the torque measured at its start, `last`, and now, `now` (Q16.16, the
    /// halved sum in i64).
    #[inline(always)]
    fn observer_torque(&self, last: Pu, now: Pu) -> Pu {
        match self.coef.observer_torque {
            ObserverTorque::Command => self.state.current_ref,
            ObserverTorque::MeasuredCurrent => Pu::from_bits(sat_shr::<1>(
                i64::from(last.to_bits()) + i64::from(now.to_bits()),
            )),
        }
    }

    /// The torque side of a current tick, after the encoder is read: the observer on
    /// `torque` ([`Self::observer_torque`]), the AFB where it runs at this rate, and the
    /// torque reference through the notch. Returns the reference the current loop is to
    /// follow.
    #[inline(always)]
    fn torque_stage(&mut self, torque: Pu) -> Pu {
        let position = self.state.position;
        let _ = self.excite(Injection::TorqueReference);
        self.coef
            .observer
            .update(&mut self.state.observer, position, torque);
        // The current-rate differentiator runs only when it feeds the AFB here.
        let closed = self.run_afb(self.coef.afb_current, |c| {
            c.coef
                .diff_current_rate
                .update(&mut c.state.diff_current_rate, position)
                .1
        });
        let i_ref = self.notched_ref(closed);
        self.state.current_ref = i_ref;
        i_ref
    }

    /// The velocity tick: run every 1/velocity_rate_hz (every n-th current tick).
    ///
    /// ```
    /// use controller_core::{Controller, VelocityInputs};
    /// # let cfg: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// let mut c = Controller::new(&cfg).unwrap();
    /// let out = c.velocity_tick(VelocityInputs::default());
    /// assert!(out.fault.is_none());
    /// ```
    #[inline(always)]
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
        let v_fb = self.coef.velocity.feedback(&mut self.state.velocity, v_raw);
        let a_est = match self.coef.afb_source {
            Estimator::Differentiation => a_diff,
            Estimator::Observer => obs.acceleration_pu_s(&self.state.observer),
        };
        let disturbance = obs.load_torque_pu(&self.state.observer);
        if self.coef.overspeed_abs.exceeded_by(v_fb.to_bits()) {
            self.trip(Fault::Overspeed);
        }

        let (pos_err, v_cmd, following) = self.coef.position.command(position, &sp);
        if following {
            self.trip(Fault::FollowingError);
        }
        let v_cmd = v_cmd.saturating_add(self.excite(Injection::VelocityReference));

        if self.state.fault.is_none() {
            let e = v_cmd.saturating_sub(v_fb);
            // Anti-windup judged on the final torque reference (PI + AFB term held now).
            self.state.i_vel = self.coef.velocity.regulate(
                &mut self.state.velocity,
                e,
                sp.acceleration_pu_s,
                self.state.afb,
            );
            let _ = self.run_afb(self.coef.afb_velocity, |_| a_est);
        }
        // The I²t model on the latest current sample; the stall check on this tick's torque
        // reference, formed by the speed regulator just now (at the limit exactly when the
        // regulator is), and the speed.
        let mut current_ref = self.total_ref();
        // One of the two terms is zero: a DC drive never sets `pmsm_current_sq`, a PMSM
        // drive never sets `last_current` (its tick replaces the DC one). No branch.
        let bits = i64::from(self.state.last_current.to_bits());
        let current_sq = bits * bits + self.state.pmsm_current_sq;
        if let Some(f) = self.coef.protection.velocity_tick_sq(
            &mut self.state.protection,
            current_sq,
            current_ref,
            v_fb,
        ) {
            self.trip(f);
            current_ref = Pu::ZERO;
        }
        VelocityOutputs {
            current_ref_pu: current_ref,
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
