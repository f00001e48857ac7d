//! The PMSM's field-oriented current loop: one current tick from two phase currents and
//! the encoder to three duties.
//!
//! 1. angle: θe from the count ([`AngleCoefficients`]);
//! 2. measurement: Clarke, then Park at θe;
//! 3. references: maximum torque per ampere within the current circle ([`Mtpa`]): for
//!    `L_d = L_q`, `i_q* = clamp(T*/λ, ±i_max)` and `i_d* = 0`;
//! 4. d and q PIs (`kp = ω_c·L`, `ki = ω_c·R` per axis) with the feed-forward of the
//!    cross-coupling and the back-EMF: `v_d,ff = −ω_e·L_q·i_q`, `v_q,ff = ω_e·L_d·i_d + ω·λ`,
//!    on the measured currents. On the references instead, a q current that the voltage
//!    circle keeps below its reference leaves a d feed-forward that the d integrator must
//!    cancel; when the demand drops, that cancelled part becomes a d-voltage step, and the
//!    cross-coupling drives i_q far past its new reference (measured: 0.44 pu below a
//!    0.2 pu reference after a drop from 1 pu at base speed on a 1.8 pu bus). The measured
//!    currents' noise enters through ω_e·L, no more than it enters through kp = ω_c·L
//!    wherever ω_e < ω_c;
//! 5. the voltage circle, d first. The anti-windup clamps each integrator so that the
//!    integral plus the feed-forward stays within the axis's bound (`I + ff ∈ [−b, b]`):
//!    while the circle limits, the integral keeps the part of the voltage the
//!    feed-forward lacks (the resistive drop) instead of stopping wherever it was when
//!    the limit came, so the regulator leaves the limit where the new demand needs it;
//! 6. inverse Park at θe + ω_e·t_delay, then space-vector modulation into three duties;
//! 7. the commutation check ([`CommutationCheck`]) on the back-EMF the drive sees.

use super::angle::{AngleCoefficients, AngleState};
use super::commutation::{CommutationCheck, CommutationState};
use super::mtpa::Mtpa;
use super::svpwm::Svpwm;
use super::transforms::{CosSin, Dq, clarke, inverse_park, park};
use super::voltage_limit::VoltageCircle;
use crate::error::ConfigError;
use crate::per_unit::{Gain, Pu, TickGain, mul_gain, quantize, sat_round_shr, sat_shr};
use crate::pi::{PiCoefficients, PiState};
use fixed::types::I32F32;

/// 1/√3: the linear range of space-vector modulation per volt of DC bus.
const FRAC_1_SQRT_3: f32 = 0.577_350_26;

/// The settings of the FOC current loop (plain data, `f32`, checked by
/// [`FocCoefficients::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FocSettings {
    /// Pole pairs, 1..cpr.
    pub pole_pairs: u32,
    /// Encoder counts per mechanical revolution (after quadrature).
    pub encoder_cpr: u32,
    /// The electrical angle at encoder count 0 \[deg\], from calibration.
    pub encoder_offset_elec_deg: f32,
    /// Counts that rise while the electrical angle falls.
    pub encoder_reversed: bool,
    /// Base speed \[rpm\]: 1 pu of speed.
    pub base_speed_rpm: f32,
    /// Phase resistance \[pu\].
    pub resistance_pu: f32,
    /// d-axis inductance \[pu·s\].
    pub d_inductance_pu_s: f32,
    /// q-axis inductance \[pu·s\].
    pub q_inductance_pu_s: f32,
    /// Magnet flux linkage \[pu\].
    pub flux_linkage_pu: f32,
    /// DC-bus voltage \[pu\]; the linear range is `dc_bus_pu/√3`.
    pub dc_bus_pu: f32,
    /// Current-loop bandwidth ω_c \[rad/s\].
    pub current_bandwidth_rad_s: f32,
    /// Current tick rate \[Hz\].
    pub current_rate_hz: f32,
    /// Time from the current sample to the middle of the voltage it sets \[current ticks\]
    /// (1.5 when the duties take effect at the next period).
    pub delay_ticks: f32,
    /// Radius of the current circle \[pu\].
    pub current_limit_pu: f32,
    /// Timer counts of a PWM period.
    pub pwm_period: u16,
    /// The speed \[pu\] above which the commutation check judges the angle, > 0.
    pub commutation_min_speed_pu: f32,
    /// How long \[s\] the angle must look more than 30° off before the check latches.
    pub commutation_trip_s: f32,
}

/// The quantized coefficients of the FOC current loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FocCoefficients {
    /// The electrical angle.
    pub angle: AngleCoefficients,
    /// d-axis PI (its limit is set per tick by the voltage circle).
    pub d: PiCoefficients,
    /// q-axis PI.
    pub q: PiCoefficients,
    /// ω_e,b·L_d: the cross-coupling into q per pu speed and pu d current.
    pub wl_d: Gain,
    /// ω_e,b·L_q: the cross-coupling into d per pu speed and pu q current.
    pub wl_q: Gain,
    /// λ: the back-EMF per pu speed.
    pub flux: Gain,
    /// The current references of a torque reference, and the torque of the currents.
    pub mtpa: Mtpa,
    /// The voltage circle.
    pub circle: VoltageCircle,
    /// The modulator.
    pub svpwm: Svpwm,
    /// The commutation check.
    pub commutation: CommutationCheck,
}

/// The FOC current loop's state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FocState {
    /// The count within one revolution.
    pub angle: AngleState,
    /// d-axis integrator.
    pub d: PiState,
    /// q-axis integrator.
    pub q: PiState,
    /// The commutation check's residual and count.
    pub commutation: CommutationState,
}

/// One current tick's inputs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FocInputs {
    /// Phase currents a and b \[pu\], sampled together.
    pub phase_current_pu: [Pu; 2],
    /// Encoder counts moved since the last tick.
    pub count_delta: i32,
    /// Motor speed estimate \[pu\].
    pub speed_pu: Pu,
    /// Torque reference \[pu\].
    pub torque_ref_pu: Pu,
}

/// One current tick's outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FocOutputs {
    /// Duties of phases a, b, c \[timer counts\], each in `[0, period]`.
    pub duties: [u16; 3],
    /// The measured currents in the rotor frame.
    pub current: Dq,
    /// The current references.
    pub current_ref: Dq,
    /// The voltage set, in the rotor frame.
    pub voltage: Dq,
    /// The electrical phase of the sample (2^32 per turn).
    pub phase: u32,
    /// The commutation check has judged the angle more than 30° off for its trip time.
    pub commutation_off: bool,
}

/// `x` checked against `[min, max]` for the key `param` (NaN gets the range, as every key).
fn in_range(param: &'static str, x: f32, min: f32, max: f32) -> Result<f32, ConfigError> {
    crate::ranges::Range::real(param, min, max, false).check(x)
}

/// One axis's PI (Q32.32 inside), its output within `±bound` (raw Q16.16, ≥ 0):
///
/// ```text
/// I ← clamp(I + Ki·Ts·e, −b − ff, b − ff)
/// v = clamp(Kp·e + I + ff, −b, b)
/// ```
#[inline(always)]
fn axis(c: &PiCoefficients, st: &mut PiState, e: Pu, ff: Pu, bound: i32) -> Pu {
    let b = i64::from(bound.max(0)) << 16;
    let ff = i64::from(ff.to_bits()) << 16;
    let e = i64::from(e.to_bits());
    // Q16.16 · Q8.24 = Q.40 → Q.32; |e·ki| < 2^54.
    let inc = (e * i64::from(c.ki_ts.to_bits())) >> 8;
    // |ff| < 2^47 and b < 2^47: the bounds are exact, and lo ≤ hi. The integral this
    // function keeps is within them (|I| < 2^48), so the sums below cannot wrap: plain
    // adds (wrapping, so that a state set from outside cannot panic).
    let i = st
        .integral
        .to_bits()
        .wrapping_add(inc)
        .clamp(-b - ff, b - ff);
    st.integral = I32F32::from_bits(i);
    // Q16.16 · Q16.16 = Q.32: |e·kp| < 2^62, |I + ff| < 2^49.
    let v = (e * i64::from(c.kp.to_bits()))
        .wrapping_add(i)
        .wrapping_add(ff);
    let out = v.clamp(-b, b);
    st.saturated = out != v;
    Pu::from_bits(sat_round_shr::<16>(out))
}

impl FocCoefficients {
    /// Designs and quantizes the loop: every bad setting is an error naming its key.
    pub fn new(s: &FocSettings) -> Result<Self, ConfigError> {
        let rate = in_range("current_rate_hz", s.current_rate_hz, 100.0, 200_000.0)?;
        let rpm = in_range("base_speed_rpm", s.base_speed_rpm, 1.0, 100_000.0)?;
        let r = in_range("winding_resistance_pu", s.resistance_pu, 0.0, 10.0)?;
        let ld = in_range("pmsm.d_inductance_pu_s", s.d_inductance_pu_s, 1e-6, 10.0)?;
        let lq = in_range("pmsm.q_inductance_pu_s", s.q_inductance_pu_s, 1e-6, 10.0)?;
        let flux = in_range("pmsm.flux_linkage_pu", s.flux_linkage_pu, 0.05, 10.0)?;
        let wc = in_range(
            "current_bandwidth_rad_s",
            s.current_bandwidth_rad_s,
            1.0,
            core::f32::consts::PI * rate,
        )?;
        let delay = in_range("pmsm.angle_advance_ticks", s.delay_ticks, 0.0, 4.0)?;
        let i_max = in_range("torque_limit_pu", s.current_limit_pu, 0.01, 100.0)?;
        let ts = 1.0 / rate;
        let angle = AngleCoefficients::new(
            s.pole_pairs,
            s.encoder_cpr,
            s.encoder_offset_elec_deg,
            s.encoder_reversed,
            rpm,
            delay * ts,
        )?;
        let svpwm = Svpwm::new(s.dc_bus_pu, s.pwm_period)?;
        let circle = VoltageCircle::new(s.dc_bus_pu * FRAC_1_SQRT_3)?;
        let limit = Pu::from_bits(circle.d_bound());
        let pi = |l: f32, kp_key, ki_key| -> Result<PiCoefficients, ConfigError> {
            Ok(PiCoefficients {
                kp: quantize::<Gain>(wc * l, kp_key)?,
                ki_ts: quantize::<TickGain>(wc * r * ts, ki_key)?,
                limit,
            })
        };
        let w_e_base = s.pole_pairs as f32 * rpm * core::f32::consts::TAU / 60.0;
        let min_speed: Pu = quantize(
            in_range(
                "pmsm.commutation_min_speed_pu",
                s.commutation_min_speed_pu,
                0.001,
                10.0,
            )?,
            "pmsm.commutation_min_speed_pu",
        )?;
        let trip = in_range("pmsm.commutation_trip_s", s.commutation_trip_s, 1e-4, 1.0)?;
        // The residual's filter: a time constant of about 2 ms, 2^k ticks.
        let mut shift = 0;
        while shift < 15 && ((1u32 << shift) as f32) < 0.002 * rate {
            shift += 1;
        }
        let wl_d: Gain = quantize(
            w_e_base * ld,
            "ω_e·L_d (pole_pairs, base_speed_rpm, d_inductance_pu_s)",
        )?;
        let wl_q: Gain = quantize(
            w_e_base * lq,
            "ω_e·L_q (pole_pairs, base_speed_rpm, q_inductance_pu_s)",
        )?;
        Ok(Self {
            angle,
            d: pi(
                ld,
                "d current kp (current_bandwidth_rad_s × d_inductance_pu_s)",
                "d current ki·Ts (current_bandwidth_rad_s × winding_resistance_pu / current_rate_hz)",
            )?,
            q: pi(
                lq,
                "q current kp (current_bandwidth_rad_s × q_inductance_pu_s)",
                "q current ki·Ts (current_bandwidth_rad_s × winding_resistance_pu / current_rate_hz)",
            )?,
            wl_d,
            wl_q,
            flux: quantize(flux, "pmsm.flux_linkage_pu")?,
            mtpa: Mtpa::new(flux, wl_d.saturating_sub(wl_q), i_max)?,
            circle,
            svpwm,
            commutation: CommutationCheck {
                resistance: quantize(r, "winding_resistance_pu")?,
                wl_d,
                wl_q,
                min_speed: min_speed.to_bits(),
                shift,
                trip_ticks: (trip * rate) as u32,
            },
        })
    }

    /// The state at encoder count `count`, the regulators at rest.
    #[must_use]
    pub fn state_at(&self, count: i64) -> FocState {
        FocState {
            angle: self.angle.state_at(count),
            ..FocState::default()
        }
    }

    /// One current tick: [`Self::measure`], then [`Self::regulate`].
    #[inline]
    pub fn tick(&self, state: &mut FocState, inp: FocInputs) -> FocOutputs {
        let (phase, current) = self.measure(state, inp.phase_current_pu, inp.count_delta);
        self.regulate(state, phase, current, inp.speed_pu, inp.torque_ref_pu)
    }

    /// Steps 1 and 2: the electrical phase after `count_delta` counts, and the phase
    /// currents a and b in the rotor frame at that phase.
    #[inline(always)]
    pub fn measure(
        &self,
        state: &mut FocState,
        phase_current_pu: [Pu; 2],
        count_delta: i32,
    ) -> (u32, Dq) {
        let phase = self.angle.update(&mut state.angle, count_delta);
        let [i_a, i_b] = phase_current_pu;
        (phase, park(clarke(i_a, i_b), CosSin::of(phase)))
    }

    /// Steps 3 to 7 on a measured sample: the references from the torque reference, the
    /// d and q PIs within the voltage circle, the duties at the advanced angle, and the
    /// commutation check. `speed_pu` is the motor speed estimate.
    #[inline(always)]
    pub fn regulate(
        &self,
        state: &mut FocState,
        phase: u32,
        current: Dq,
        speed_pu: Pu,
        torque_ref_pu: Pu,
    ) -> FocOutputs {
        let current_ref = self.mtpa.references(torque_ref_pu);
        let w = speed_pu;
        // ω·i in Q16.16 (64-bit product, saturated), then times ω_e,b·L.
        let w_times = |i: Pu| {
            Pu::from_bits(sat_shr::<16>(
                i64::from(w.to_bits()) * i64::from(i.to_bits()),
            ))
        };
        // The cross-coupling ω_e·L_q·i_q and ω_e·L_d·i_d: the feed-forward's, and the
        // commutation check's (its `update` forms the same products).
        let coupling = Dq {
            d: mul_gain(w_times(current.q), self.wl_q),
            q: mul_gain(w_times(current.d), self.wl_d),
        };
        let ff_d = coupling.d.saturating_neg();
        let ff_q = coupling.q.saturating_add(mul_gain(w, self.flux));
        let v_d = axis(
            &self.d,
            &mut state.d,
            current_ref.d.saturating_sub(current.d),
            ff_d,
            self.circle.d_bound(),
        );
        let v_q = axis(
            &self.q,
            &mut state.q,
            current_ref.q.saturating_sub(current.q),
            ff_q,
            self.circle.q_bound(v_d),
        );
        let voltage = Dq { d: v_d, q: v_q };
        let applied = CosSin::of(self.angle.advanced(phase, w));
        let commutation_off =
            self.commutation
                .update_with(&mut state.commutation, current, w, coupling, voltage);
        FocOutputs {
            duties: self.svpwm.duties(inverse_park(voltage, applied)),
            current,
            current_ref,
            voltage,
            phase,
            commutation_off,
        }
    }
}
