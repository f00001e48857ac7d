//! The current tick of a PMSM drive (`[drive.pmsm]`): the same torque side as the DC
//! drive's (encoder, observer, acceleration feedback, notch), then the field-oriented
//! current loop ([`crate::foc`]) in place of the DC winding's current PI.
//!
//! ```text
//! position ← unwrap(encoder_count)                 (encoder-jump check)
//! θe, (i_d, i_q) ← FOC measure(i_a, i_b, Δcount)
//! i_ref ← torque side, as the DC tick, with the measured torque λ·i_q + k·i_d·i_q
//! duties ← FOC regulate(θe, (i_d, i_q), ω̂ (observer), i_ref)
//! protection ← |i|² = i_d² + i_q²                    (overcurrent on the current vector)
//! commutation ← the FOC's check                      (latches `commutation`)
//! ```
//! The torque side works in the counts' direction, the FOC in the electrical angle's. With
//! `encoder_reversed` the two are opposite, so the torque and the speed change sign between
//! them: the torque reference for i_q, the measured torque back, and the speed of the
//! feed-forward, the angle's advance and the commutation check. Without that a reversed
//! encoder would turn the velocity loop's feedback positive: torque one way, counts the other.
//!
//! The velocity tick's I²t model takes |i|² too (no square root on either path). A fault turns the
//! inverter off (`enabled = false`, the duties at half the period): the currents then
//! decay through the free-wheeling diodes while the back-EMF stays below the bus.

use super::Controller;
use crate::fault::Fault;
use crate::foc::{Dq, FocCoefficients};
use crate::per_unit::{Pu, count_signed};

/// Inputs of a PMSM current tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PmsmInputs {
    /// Raw encoder counter, wraps at `counter_bits`.
    pub encoder_count: u32,
    /// Phase currents a and b \[pu\], sampled together (c = −a − b).
    pub phase_current_pu: [Pu; 2],
}

/// Outputs of a PMSM current tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PmsmOutputs {
    /// Duties of phases a, b, c \[timer counts\], each within `[0, pwm_period_counts]`.
    pub duties: [u16; 3],
    /// Whether the inverter switches (false once a fault latched: all six switches off).
    pub enabled: bool,
    /// The measured currents in the rotor frame \[pu\].
    pub current: Dq,
    /// The current references \[pu\] (zero when faulted).
    pub current_ref: Dq,
    /// The voltage set in the rotor frame \[pu\].
    pub voltage: Dq,
    /// Torque reference \[pu\] after the notch (the velocity loop's, plus AFB).
    pub torque_ref_pu: Pu,
    /// Acceleration-feedback term \[pu torque\].
    pub accel_fb_pu: Pu,
    /// Latched fault, if any.
    pub fault: Option<Fault>,
}

/// |(d, q)|² in Q32.32 (d², q² ≤ 2^62 each: their sum fits u64).
#[inline(always)]
fn magnitude_sq(i: Dq) -> u64 {
    let d = i64::from(i.d.to_bits());
    let q = i64::from(i.q.to_bits());
    (d * d) as u64 + (q * q) as u64
}

/// |(d, q)| in Q16.16, saturating at the format's top: what the protections judged before
/// they took the square (the tests' reference).
#[cfg(test)]
fn magnitude(i: Dq) -> Pu {
    let d = i64::from(i.d.to_bits());
    let q = i64::from(i.q.to_bits());
    // d², q² ≤ 2^62 each: their sum fits u64.
    let sq = (d * d) as u64 + (q * q) as u64;
    Pu::from_bits(i32::try_from(crate::per_unit::isqrt_u64(sq)).unwrap_or(i32::MAX))
}

impl Controller {
    /// The FOC coefficients of a PMSM drive; `None` for a DC drive.
    #[must_use]
    pub fn foc(&self) -> Option<&FocCoefficients> {
        self.foc.as_ref()
    }

    /// The current tick of a PMSM drive: run every 1/current_rate_hz, in place of
    /// [`Controller::current_tick`]. On a DC drive (no `[drive.pmsm]`) it commands nothing
    /// and returns the inverter off.
    ///
    /// ```
    /// use controller_core::{Controller, PmsmInputs};
    /// # let mut cfg: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// cfg.pmsm = Some(toml::from_str("pole_pairs = 4\nd_inductance_pu_s = 5e-4\n\
    ///     q_inductance_pu_s = 5e-4\ndc_bus_pu = 2.0\nencoder_offset_elec_deg = 0.0").unwrap());
    /// let mut c = Controller::new(&cfg).unwrap();
    /// let out = c.pmsm_tick(PmsmInputs::default());
    /// assert!(out.enabled);
    /// assert_eq!(out.duties, [2100; 3]);
    /// ```
    #[inline]
    pub fn pmsm_tick(&mut self, inp: PmsmInputs) -> PmsmOutputs {
        if self.foc.is_none() {
            return PmsmOutputs {
                fault: self.state.fault,
                ..PmsmOutputs::default()
            };
        }
        self.read_encoder(inp.encoder_count);
        let (phase, current, torque) = self.foc_measure(inp.encoder_count, inp.phase_current_pu);
        let observed = self.observer_torque(self.state.pmsm_torque, torque);
        self.state.pmsm_torque = torque;
        let i_ref = self.torque_stage(observed);
        let speed = self.coef.observer.velocity_pu(&self.state.observer);
        // The coefficients by reference (a copy would move their 160 bytes every tick).
        let (out, half) = match self.foc.as_ref() {
            Some(foc) => {
                let (speed, i_ref) = if foc.angle.reversed() {
                    (speed.saturating_neg(), i_ref.saturating_neg())
                } else {
                    (speed, i_ref)
                };
                (
                    foc.regulate(&mut self.state.foc, phase, current, speed, i_ref),
                    foc.svpwm.period() / 2,
                )
            }
            None => (crate::foc::FocOutputs::default(), 0),
        };
        // The protections on the current vector's square (no root): overcurrent here, the
        // velocity tick's I²t model (its input held within 2^62).
        let size_sq = magnitude_sq(current);
        self.state.pmsm_current_sq = size_sq.min(1 << 62) as i64;
        if out.commutation_off {
            self.trip(Fault::Commutation);
        }
        if self
            .coef
            .protection
            .current_tick_sq(&mut self.state.protection, size_sq)
        {
            self.trip(Fault::Overcurrent);
        }
        let enabled = self.state.fault.is_none();
        if !enabled {
            self.state.current_ref = Pu::ZERO;
            self.state.foc.d = crate::pi::PiState::default();
            self.state.foc.q = crate::pi::PiState::default();
        }
        PmsmOutputs {
            duties: if enabled { out.duties } else { [half; 3] },
            enabled,
            current,
            current_ref: if enabled {
                out.current_ref
            } else {
                Dq::default()
            },
            voltage: if enabled { out.voltage } else { Dq::default() },
            torque_ref_pu: self.state.current_ref,
            accel_fb_pu: self.state.afb,
            fault: self.state.fault,
        }
    }

    /// The FOC's measurement of a tick, after the encoder's read: the electrical phase,
    /// the currents in the rotor frame and their torque.
    #[inline(always)]
    fn foc_measure(&mut self, raw: u32, phase_current_pu: [Pu; 2]) -> (u32, Dq, Pu) {
        let delta = self.foc_follow(raw);
        let Some(foc) = self.foc.as_ref() else {
            return (0, Dq::default(), Pu::ZERO);
        };
        let (phase, current) = foc.measure(&mut self.state.foc, phase_current_pu, delta);
        let torque = foc.mtpa.torque(current);
        let torque = if foc.angle.reversed() {
            torque.saturating_neg()
        } else {
            torque
        };
        (phase, current, torque)
    }

    /// The counts the rotor moved since the angle's last update, from the raw counter (the
    /// velocity tick reads the encoder too, and a reset takes the position again from the
    /// counter, so neither the last reading nor the position will do). The first reading
    /// of all sets the angle from the count itself and moves it by 0.
    #[inline(always)]
    fn foc_follow(&mut self, raw: u32) -> i32 {
        let delta = if self.state.foc_primed {
            crate::per_unit::count_diff_by(raw, self.state.foc_last_raw, self.coef.counter_shift)
        } else {
            if let Some(foc) = self.foc.as_ref() {
                let count = i64::from(count_signed(raw, self.coef.counter_bits));
                self.state.foc = foc.state_at(count);
            }
            self.state.foc_primed = true;
            0
        };
        self.state.foc_last_raw = raw;
        delta
    }

    /// A q-axis quantity of the FOC's frame (current, reference, voltage) signed by the
    /// counts' direction, the torque side's: negated with `encoder_reversed`, as is
    /// for a forward encoder or a DC drive. What a record of the drive's torque-making
    /// current (a trace, an identification) takes.
    #[must_use]
    pub fn q_in_count_direction(&self, q: Pu) -> Pu {
        if self.encoder_reversed() {
            q.saturating_neg()
        } else {
            q
        }
    }

    /// The torque of the last PMSM tick's measured currents in the drive's motor model,
    /// `λ·i_q + k·i_d·i_q` \[pu\], in the counts' direction: what the observer took, and what
    /// a record of the motor's torque (an identification's) takes. Zero on a DC drive.
    #[must_use]
    pub fn pmsm_measured_torque(&self) -> Pu {
        self.state.pmsm_torque
    }

    /// Whether a PMSM drive's encoder counts against its electrical angle
    /// (`[drive.pmsm] encoder_reversed`); false for a DC drive.
    #[must_use]
    pub fn encoder_reversed(&self) -> bool {
        self.foc.as_ref().is_some_and(|f| f.angle.reversed())
    }

    /// Keeps a PMSM drive's electrical angle on the rotor while no tick runs (the drive
    /// held, the inverter off): call it with the encoder counter every current period in
    /// which [`Controller::pmsm_tick`] is not called, so that the angle is right when the
    /// ticks start again, however far the shaft turned and the counter wrapped meanwhile.
    /// Nothing else moves. A DC drive ignores it.
    pub fn pmsm_track(&mut self, encoder_count: u32) {
        let delta = self.foc_follow(encoder_count);
        if let Some(foc) = self.foc.as_ref() {
            let _ = foc.angle.update(&mut self.state.foc.angle, delta);
        }
    }
}

/// The FOC loop of a drive's settings: `None` without `[drive.pmsm]`; an error naming
/// `pmsm.encoder_offset_elec_deg` when the offset has not been measured.
pub(super) fn foc_of(
    cfg: &crate::DriveConfig,
) -> Result<Option<FocCoefficients>, crate::ConfigError> {
    let Some(p) = &cfg.pmsm else {
        return Ok(None);
    };
    let offset = p
        .encoder_offset_elec_deg
        .ok_or(crate::ConfigError::Missing {
            param: "pmsm.encoder_offset_elec_deg",
            measure: "stiffdrive identify --config FILE (or commission, which writes it into drive.toml)",
        })?;
    FocCoefficients::new(&crate::foc::config::foc_settings(cfg, p, offset)).map(Some)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use crate::config::DriveConfig;
    use crate::controller::VelocityInputs;

    fn drive(offset: Option<f32>) -> DriveConfig {
        let mut cfg: DriveConfig = toml::from_str(include_str!(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/doc/example-drive.toml"
        )))
        .unwrap();
        cfg.pmsm = Some(
            toml::from_str(
                "pole_pairs = 4\nd_inductance_pu_s = 5e-4\nq_inductance_pu_s = 6e-4\ndc_bus_pu = 2.0",
            )
            .unwrap(),
        );
        if let Some(p) = cfg.pmsm.as_mut() {
            p.encoder_offset_elec_deg = offset;
        }
        cfg
    }

    fn pu(x: f64) -> Pu {
        Pu::from_num(x)
    }

    #[test]
    fn a_pmsm_drive_without_its_measured_offset_refuses_to_enable_naming_the_key() {
        let cfg = drive(None);
        assert_eq!(cfg.validate(), Ok(()));
        let e = Controller::new(&cfg).unwrap_err();
        assert_eq!(e.param(), "pmsm.encoder_offset_elec_deg");
        assert!(e.to_string().contains("stiffdrive identify"), "{e}");
        assert!(Controller::new(&drive(Some(12.5))).unwrap().foc().is_some());
    }

    #[test]
    fn a_dc_drive_commands_nothing_through_the_pmsm_tick() {
        let mut cfg = drive(None);
        cfg.pmsm = None;
        let mut c = Controller::new(&cfg).unwrap();
        assert!(c.foc().is_none());
        let inp = PmsmInputs {
            encoder_count: 7,
            phase_current_pu: [pu(1.0), pu(-0.5)],
        };
        let out = c.pmsm_tick(inp);
        assert!(!out.enabled);
        assert_eq!((out.duties, out.fault), ([0; 3], None));
        // A latched fault is reported all the same.
        let _ = c.velocity_tick(VelocityInputs {
            fault_input: true,
            ..VelocityInputs::default()
        });
        assert_eq!(c.pmsm_tick(inp).fault, Some(Fault::External));
    }

    /// The electrical angle follows the shaft through the counter's wraps, across a reset
    /// and while the drive is held (`pmsm_track`): the 16-bit counter wraps where the
    /// encoder's 10,000 counts per turn do not, so an angle taken again from the counter
    /// after a reset would be off (here by 128° electrical). A d-axis current at the true
    /// angle must read as d, before and after each reset.
    #[test]
    fn the_angle_survives_a_reset_after_the_counter_wrapped() {
        let mut cfg = drive(Some(0.0));
        cfg.encoder_cpr = 10_000;
        cfg.counter_bits = 16;
        let mut c = Controller::new(&cfg).unwrap();
        let raw = |total: i64| (total & 0xffff) as u32;
        let sample = |total: i64| {
            let th = core::f64::consts::TAU * 4.0 * total as f64 / 10_000.0;
            let b = th - core::f64::consts::TAU / 3.0;
            PmsmInputs {
                encoder_count: raw(total),
                phase_current_pu: [pu(0.5 * th.cos()), pu(0.5 * b.cos())],
            }
        };
        let on_d = |out: PmsmOutputs, when: &str| {
            let (d, q) = (out.current.d.to_num::<f64>(), out.current.q.to_num::<f64>());
            assert!(
                (d - 0.5).abs() < 0.01 && q.abs() < 0.01,
                "{when}: (d, q) = ({d}, {q})"
            );
        };
        let mut total = 0;
        for _ in 0..6_000 {
            total += 37;
            on_d(c.pmsm_tick(sample(total)), "turning");
        }
        c.reset();
        for _ in 0..3 {
            total += 37;
            on_d(c.pmsm_tick(sample(total)), "after a reset");
        }
        for _ in 0..3_000 {
            total += 37;
            c.pmsm_track(raw(total));
        }
        c.reset();
        total += 37;
        on_d(c.pmsm_tick(sample(total)), "after turning held and a reset");
    }

    /// The protections read the whole current vector's square, d and q alike: a current
    /// on the d axis alone (no torque, so nothing else notices it) trips `overcurrent`
    /// after `overcurrent_ticks`, and held above the continuous current the I²t model trips
    /// `overload` at its closed-form time.
    #[test]
    fn the_protections_judge_the_current_on_the_d_axis_too() {
        let mut cfg = drive(Some(0.0));
        cfg.torque_limit_pu = 2.0;
        cfg.faults.overcurrent_ratio = 1.5;
        cfg.faults.overcurrent_ticks = 3;
        cfg.faults.continuous_current_pu = 1.0;
        cfg.faults.overload_current_pu = 1.5;
        cfg.faults.overload_time_s = 0.05;
        cfg.faults.stall_time_s = 0.0;
        // Count 0, offset 0: the d axis is phase a's, so i_a = i and i_b = −i/2 is i_d = i.
        let on_d = |i: f64| PmsmInputs {
            encoder_count: 0,
            phase_current_pu: [pu(i), pu(-0.5 * i)],
        };
        let mut c = Controller::new(&cfg).unwrap();
        let faults: Vec<_> = (0..4).map(|_| c.pmsm_tick(on_d(3.3)).fault).collect();
        assert_eq!(
            faults,
            [
                None,
                None,
                Some(Fault::Overcurrent),
                Some(Fault::Overcurrent)
            ]
        );

        let mut c = Controller::new(&cfg).unwrap();
        let closed = c.protection().trip_time_s(1.3).unwrap();
        let ratio = cfg.current_rate_hz / cfg.velocity_rate_hz;
        let mut tripped = None;
        for k in 0..(2.0 * closed * f64::from(cfg.current_rate_hz)) as u32 {
            let _ = c.pmsm_tick(on_d(1.3));
            if k % ratio == 0 {
                let out = c.velocity_tick(VelocityInputs::default());
                if out.fault.is_some() {
                    tripped = Some((out.fault, f64::from(k) / f64::from(cfg.current_rate_hz)));
                    break;
                }
            }
        }
        assert!(tripped.is_some(), "the I²t model never tripped");
        let (fault, t) = tripped.unwrap();
        assert_eq!(fault, Some(Fault::Overload));
        assert!(
            (t / closed - 1.0).abs() < 0.02,
            "tripped at {t} s, closed form {closed} s"
        );
    }

    /// While enabled the d and q integrators act (a constant current error moves the
    /// voltage further every tick); a fault clears them.
    #[test]
    fn the_integrators_act_while_enabled_and_a_fault_clears_them() {
        let mut c = Controller::new(&drive(Some(0.0))).unwrap();
        // i_d = 0.2 pu at the d axis (count 0, offset 0): the d error is −0.2 every tick.
        let inp = PmsmInputs {
            encoder_count: 0,
            phase_current_pu: [pu(0.2), pu(-0.1)],
        };
        let v: Vec<f64> = (0..3)
            .map(|_| c.pmsm_tick(inp).voltage.d.to_num::<f64>())
            .collect();
        assert!(v[0] < 0.0 && v[1] < v[0] && v[2] < v[1], "{v:?}");
        assert_ne!(c.state.foc.d, crate::pi::PiState::default());
        let _ = c.velocity_tick(VelocityInputs {
            fault_input: true,
            ..VelocityInputs::default()
        });
        let _ = c.pmsm_tick(inp);
        assert_eq!(c.state.foc.d, crate::pi::PiState::default());
        assert_eq!(c.state.foc.q, crate::pi::PiState::default());
    }

    #[test]
    fn a_fault_turns_the_inverter_off_and_zeroes_the_references() {
        let mut c = Controller::new(&drive(Some(0.0))).unwrap();
        let inp = PmsmInputs {
            encoder_count: 0,
            phase_current_pu: [pu(0.1), pu(-0.05)],
        };
        assert!(c.pmsm_tick(inp).enabled);
        let _ = c.velocity_tick(VelocityInputs {
            fault_input: true,
            ..VelocityInputs::default()
        });
        let out = c.pmsm_tick(inp);
        assert_eq!(out.fault, Some(Fault::External));
        assert!(!out.enabled);
        assert_eq!(out.duties, [c.foc().unwrap().svpwm.period() / 2; 3]);
        assert_eq!(
            (out.current_ref, out.voltage),
            (Dq::default(), Dq::default())
        );
        assert_eq!(out.torque_ref_pu, Pu::ZERO);
    }

    /// Overcurrent judges the current vector: phase currents whose every sample is below
    /// the trip level, but whose vector is above it, trip after `overcurrent_ticks`.
    #[test]
    fn overcurrent_trips_on_the_current_vector() {
        let cfg = drive(Some(0.0));
        let mut c = Controller::new(&cfg).unwrap();
        let level = f64::from(cfg.faults.overcurrent_ratio * cfg.torque_limit_pu);
        // |i| = 1.05·level with the vector at 90° electrical: i_a = 0 and
        // i_b = −√3/2·|i|, so no phase sample reaches the level.
        let m = 1.05 * level;
        let samples = [pu(0.0), pu(-m * 3f64.sqrt() / 2.0)];
        let ticks = cfg.faults.overcurrent_ticks;
        for k in 1..=ticks {
            let out = c.pmsm_tick(PmsmInputs {
                encoder_count: 0,
                phase_current_pu: samples,
            });
            assert_eq!(out.fault.is_some(), k == ticks, "tick {k}: {:?}", out.fault);
        }
        assert_eq!(c.fault(), Some(Fault::Overcurrent));
        assert!(m * 3f64.sqrt() / 2.0 < level, "each sample below the level");
    }

    /// The angle follows every count, also those the velocity tick reads first: a d-axis
    /// current at the machine's true angle is measured as d, with no q, at every tick of a
    /// run where the shaft turns 3 counts a tick and the velocity tick runs every 4th.
    #[test]
    fn the_angle_follows_the_counts_the_velocity_tick_reads_first() {
        let cfg = drive(Some(30.0));
        let mut c = Controller::new(&cfg).unwrap();
        let (cpr, pp) = (f64::from(cfg.encoder_cpr), 4.0);
        let ratio = cfg.current_rate_hz / cfg.velocity_rate_hz;
        let mut worst: f64 = 0.0;
        for k in 0..2000_u32 {
            let count = 3 * k;
            let theta = pp * std::f64::consts::TAU * f64::from(count) / cpr + 30f64.to_radians();
            let ia = theta.cos();
            let ib = (theta - std::f64::consts::TAU / 3.0).cos();
            if k % ratio == 0 {
                let _ = c.velocity_tick(VelocityInputs {
                    encoder_count: count,
                    ..VelocityInputs::default()
                });
            }
            let out = c.pmsm_tick(PmsmInputs {
                encoder_count: count,
                phase_current_pu: [pu(ia), pu(ib)],
            });
            let q = out.current.q.to_num::<f64>();
            assert!(
                (out.current.d.to_num::<f64>() - 1.0).abs() < 1e-3,
                "tick {k}: {out:?}"
            );
            worst = worst.max(q.abs());
        }
        assert!(worst < 1e-3, "largest |i_q| {worst}");
    }

    /// With `encoder_reversed` the q axis turns against the counts: a q current at the
    /// drive's angle is torque against the counts' direction, for the torque side (the
    /// observer's torque input) and for a record (`q_in_count_direction`); a forward drive
    /// and a DC drive leave the sign.
    #[test]
    fn a_reversed_encoder_turns_the_q_axis_against_the_counts() {
        let mut cfg = drive(Some(0.0));
        let mut fwd = Controller::new(&cfg).unwrap();
        if let Some(p) = cfg.pmsm.as_mut() {
            p.encoder_reversed = true;
        }
        let mut rev = Controller::new(&cfg).unwrap();
        assert!(!fwd.encoder_reversed() && rev.encoder_reversed());
        let x = pu(0.3);
        assert_eq!(
            (fwd.q_in_count_direction(x), rev.q_in_count_direction(x)),
            (x, -x)
        );
        cfg.pmsm = None;
        let dc = Controller::new(&cfg).unwrap();
        assert!(!dc.encoder_reversed());
        assert_eq!(dc.q_in_count_direction(x), x);
        // Count 0, offset 0: the q axis is β, so i_a = 0 and i_b = (√3/2)·i_q.
        let on_q = PmsmInputs {
            encoder_count: 0,
            phase_current_pu: [pu(0.0), pu(0.5 * 3f64.sqrt() / 2.0)],
        };
        let _ = fwd.pmsm_tick(on_q);
        let _ = rev.pmsm_tick(on_q);
        let (tf, tr) = (fwd.state.pmsm_torque, rev.state.pmsm_torque);
        assert!((tf.to_num::<f64>() - 0.5).abs() < 1e-3, "{tf}");
        assert_eq!(tr, -tf);
        // What a record of the motor's torque reads: the observer's input.
        assert_eq!(
            (fwd.pmsm_measured_torque(), rev.pmsm_measured_torque()),
            (tf, tr)
        );
    }

    #[test]
    fn the_magnitude_is_the_rounded_down_root_and_saturates() {
        let pu = |x: f64| Pu::from_num(x);
        assert_eq!(
            magnitude(Dq {
                d: pu(3.0),
                q: pu(-4.0)
            }),
            pu(5.0)
        );
        assert_eq!(magnitude(Dq::default()), Pu::ZERO);
        let top = Dq {
            d: Pu::from_bits(i32::MIN),
            q: Pu::from_bits(i32::MIN),
        };
        assert_eq!(magnitude(top), Pu::MAX);
        let e = magnitude(Dq {
            d: pu(0.6),
            q: pu(0.8),
        });
        assert!((e.to_num::<f64>() - 1.0).abs() < 2e-5, "{e}");
    }
}
