//! The controller's ticks against their general paths.
#![allow(clippy::indexing_slicing, clippy::unwrap_used, clippy::panic)]

use super::coefficients::AfbStep;
use super::*;
use crate::config::AfbMode;

fn drive() -> DriveConfig {
    toml::from_str(include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/doc/example-drive.toml"
    )))
    .unwrap()
}

/// Inputs that drive the example drive's references into the torque limit both ways: the
/// position swings by up to ±40 counts a tick around a ramp that reverses every 2000 ticks,
/// with current noise, and each velocity tick (every second current tick) asks a random
/// setpoint acceleration. Per current tick: its inputs, and the velocity tick's after it.
struct LimitInputs {
    k: u32,
    raw: u32,
    seed: u32,
}

impl LimitInputs {
    fn new(seed: u32) -> Self {
        Self { k: 0, raw: 0, seed }
    }
}

impl Iterator for LimitInputs {
    type Item = (CurrentInputs, Option<VelocityInputs>);

    fn next(&mut self) -> Option<Self::Item> {
        let k = self.k;
        self.k += 1;
        let seed = self
            .seed
            .wrapping_mul(1_664_525)
            .wrapping_add(1_013_904_223);
        self.seed = seed;
        let step = ((seed >> 8) % 81) as i32 - 40 + if k % 4000 < 2000 { 9 } else { -9 };
        self.raw = self.raw.wrapping_add_signed(step);
        let current = CurrentInputs {
            encoder_count: self.raw,
            current_pu: Pu::from_bits(((seed >> 3) % (1 << 19)) as i32 - (1 << 18)),
        };
        let velocity = k.is_multiple_of(2).then(|| VelocityInputs {
            encoder_count: self.raw,
            setpoint: Setpoint {
                acceleration_pu_s: Pu::from_bits((seed % (1 << 22)) as i32 - (1 << 21)),
                ..Setpoint::default()
            },
            fault_input: false,
        });
        Some((current, velocity))
    }
}

/// The current tick with the closed-form AFB step's torque taken as the total torque
/// reference equals the tick that forms the sum again (`total_ref`), bit for bit, on
/// inputs that drive the references into the torque limit both ways.
#[test]
fn closed_form_torque_is_the_total_reference() {
    for mode in [AfbMode::Plain, AfbMode::Error] {
        let mut cfg = drive();
        cfg.accel_feedback.mode = mode;
        let fast = Controller::new(&cfg).unwrap();
        assert!(fast.closed_total, "{mode:?}");
        let mut general = fast;
        general.closed_total = false;
        let mut fast = fast;
        let mut at_limit = 0u32;
        for (k, (ci, vi)) in LimitInputs::new(12345).take(20_000).enumerate() {
            let out = fast.current_tick(ci);
            assert_eq!(out, general.current_tick(ci), "{mode:?} {k}");
            if out.current_ref_pu.abs() == fast.coef.torque_limit {
                at_limit += 1;
            }
            if let Some(vi) = vi {
                assert_eq!(fast.velocity_tick(vi), general.velocity_tick(vi));
            }
            if fast.fault().is_some() {
                fast.reset();
                general.reset();
            }
        }
        assert!(
            at_limit > 100,
            "{mode:?}: {at_limit} ticks at the torque limit"
        );
    }
}

/// `accel_feedback.filter_at_limit`: the tick runs the held AFB step only when the setting
/// asks for it, in either form. Driven into the torque limit both ways, the held step is
/// the tracking one bit for bit (output and state) on every tick whose torque is not at
/// the limit; on the ticks at the limit the held filter's state does not move, where the
/// tracking step, from the same state and inputs, moves it.
#[test]
fn a_held_afb_filter_moves_only_off_the_limit() {
    use crate::config::AfbFilterAtLimit;
    for (mode, track, hold) in [
        (
            AfbMode::Plain,
            AfbStep::ClosedPlain,
            AfbStep::ClosedPlainHold,
        ),
        (
            AfbMode::Error,
            AfbStep::ClosedError,
            AfbStep::ClosedErrorHold,
        ),
    ] {
        let mut cfg = drive();
        cfg.accel_feedback.mode = mode;
        assert_eq!(cfg.accel_feedback.filter_at_limit, AfbFilterAtLimit::Track);
        assert_eq!(Controller::new(&cfg).unwrap().coef.afb_current, track);
        cfg.accel_feedback.filter_at_limit = AfbFilterAtLimit::Hold;
        let mut held = Controller::new(&cfg).unwrap();
        assert_eq!(held.coef.afb_current, hold, "{mode:?}");
        let lim = held.coef.torque_limit;
        let (mut at_limit, mut tracking_moved, mut off_limit) = (0u32, 0u32, 0u32);
        for (k, (ci, vi)) in LimitInputs::new(777).take(20_000).enumerate() {
            let mut tracking = held;
            tracking.coef.afb_current = track;
            let before = held.state.afb_filter;
            let out = held.current_tick(ci);
            let out_tracking = tracking.current_tick(ci);
            if out.current_ref_pu.abs() == lim {
                at_limit += 1;
                assert_eq!(held.state.afb_filter, before, "{mode:?} {k}");
                tracking_moved += u32::from(tracking.state.afb_filter != before);
            } else {
                off_limit += 1;
                assert_eq!(out, out_tracking, "{mode:?} {k}");
                assert_eq!(held.state, tracking.state, "{mode:?} {k}");
            }
            if let Some(vi) = vi {
                held.velocity_tick(vi);
            }
            if held.fault().is_some() {
                held.reset();
            }
        }
        assert!(
            at_limit > 100 && tracking_moved > at_limit / 2 && off_limit > 1000,
            "{mode:?}: {at_limit} ticks at the limit ({tracking_moved} moved by the \
             tracking step), {off_limit} off it"
        );
    }
}

/// A torque-reference excitation (two orders of the saturating adds) or a negative
/// hand-made limit turns the shortcut off.
#[test]
fn closed_form_torque_shortcut_is_off_where_it_may_differ() {
    use crate::excitation::{ExcitationConfig, ExcitationParams, Waveform};
    let c = Controller::new(&drive()).unwrap();
    let names = ExcitationParams {
        amplitude_pu: "a",
        start_or_bits: "b",
        end_or_hold: "h",
        duration_or_periods: "p",
    };
    let e = |injection| ExcitationConfig {
        waveform: Waveform::Prbs {
            bits: 7,
            hold_ticks: 1,
            periods: 1,
        },
        amplitude_pu: 0.1,
        injection,
    };
    let t = c
        .with_excitation(&e(Injection::TorqueReference), names)
        .unwrap();
    assert!(!t.closed_total);
    let v = c
        .with_excitation(&e(Injection::VelocityReference), names)
        .unwrap();
    assert!(v.closed_total);
    let mut coef = c.coef;
    coef.torque_limit = -coef.torque_limit;
    coef.afb.limit = coef.torque_limit;
    assert!(!Controller::closed_total_exact(&coef, false));
}

/// An overcurrent on the measured current latches the safe state in the tick that trips
/// (zero torque and voltage from that tick on); a reset clears the fault but keeps the
/// I²t model's heat, and the thermal warning follows the heat.
#[test]
fn protection_trips_latch_zero_torque_and_a_reset_keeps_the_heat() {
    let mut cfg = drive();
    cfg.faults.overcurrent_ticks = 2;
    // Two ticks at 3 pu heat 16 pu²·ticks of the 600,000 that trip: 2.7e-5 of the level.
    cfg.faults.thermal_warning_fraction = 1e-5;
    let mut c = Controller::new(&cfg).unwrap();
    assert!(
        !c.thermal_warning() && c.thermal_load() == 0.0,
        "cold at start"
    );
    let over = Pu::from_num(c.protection().overcurrent_pu() + 0.01);
    let sp = VelocityInputs {
        setpoint: Setpoint {
            velocity_pu: Pu::from_num(0.5),
            ..Setpoint::default()
        },
        ..VelocityInputs::default()
    };
    let _ = c.velocity_tick(sp);
    let first = c.current_tick(CurrentInputs {
        encoder_count: 0,
        current_pu: over,
    });
    assert_eq!(first.fault, None);
    assert_ne!(first.current_ref_pu, Pu::ZERO);
    let second = c.current_tick(CurrentInputs {
        encoder_count: 0,
        current_pu: over,
    });
    assert_eq!(second.fault, Some(Fault::Overcurrent));
    assert_eq!(
        (second.current_ref_pu, second.accel_fb_pu),
        (Pu::ZERO, Pu::ZERO)
    );
    assert!(c.velocity_tick(sp).current_ref_pu == Pu::ZERO);
    let heat = c.thermal_load();
    assert!(heat > 0.0 && heat < 1e-3 && c.thermal_warning(), "{heat}");
    c.reset();
    assert_eq!(c.fault(), None);
    assert_eq!(c.thermal_load(), heat);
    assert!(c.thermal_warning());
    // One sample over the level after the reset does not trip: the count restarted.
    let out = c.current_tick(CurrentInputs {
        encoder_count: 0,
        current_pu: over,
    });
    assert_eq!(out.fault, None);
}

/// The closed form's error states the range by its branch: with b·m below 1 (b = b0/J_model,
/// m the 50-step floor of Q16.16) the gain fraction's, from m/((1 − b·m)·J_total); with b·m
/// at 1 no Ka fits, and it is the motor inertia's, from b0·m (with 0.1 % to spare).
#[test]
fn the_closed_form_error_states_the_range_of_its_branch() {
    use crate::ranges::{AFB_GAIN_FRACTION, MOTOR_INERTIA_S};
    use crate::validate::GAIN_MIN;
    let mut g = crate::design(&drive()).unwrap();
    let j = f64::from(g.j_total_s);
    // J_model = 2m (exact in f32): b·m = 1/2.
    g.observer_inertia_s = (2.0 * GAIN_MIN) as f32;
    let b = 1.0 / f64::from(g.observer_inertia_s);
    match coefficients::gain_fraction_error(&g, Some(1.0)) {
        ConfigError::OutOfRangeGiven { param, min, .. } => {
            assert_eq!(param, AFB_GAIN_FRACTION.key);
            assert_eq!(min, (GAIN_MIN / ((1.0 - b * GAIN_MIN) * j)) as f32);
            assert!((f64::from(min) - 2.0 * GAIN_MIN / j).abs() < 1e-6 * f64::from(min));
        }
        e => panic!("{e:?}"),
    }
    // The gain fraction's top where that is below its stated 20: the largest f32 whose Ka
    // (× J_total in f32, as the design computes it) fits Q16.16; the next one's does not.
    g.j_total_s = 2000.0;
    match coefficients::gain_fraction_error(&g, Some(1.0)) {
        ConfigError::OutOfRangeGiven { max, .. } => {
            assert!(crate::per_unit::quantize::<crate::per_unit::Gain>(max * 2000.0, "").is_ok());
            let above = max.next_up() * 2000.0;
            assert!(crate::per_unit::quantize::<crate::per_unit::Gain>(above, "").is_err());
        }
        e => panic!("{e:?}"),
    }
    g.j_total_s = j as f32;
    // J_model = m: b·m is exactly 1 in f64, the other branch.
    g.observer_inertia_s = GAIN_MIN as f32;
    assert_eq!(1.0 / f64::from(g.observer_inertia_s) * GAIN_MIN, 1.0);
    match coefficients::gain_fraction_error(&g, Some(1.0)) {
        ConfigError::OutOfRangeGiven { param, min, .. } => {
            assert_eq!(param, MOTOR_INERTIA_S.key);
            assert_eq!(min, (GAIN_MIN * 1.001) as f32);
        }
        e => panic!("{e:?}"),
    }
}

/// A PI whose Kp does not fit Q16.16: the bandwidth's range scales with Kp ∝ ω, so its top
/// is ω·(Q16.16's largest)/Kp.
#[test]
fn a_proportional_gain_too_large_gives_the_bandwidth_s_top() {
    use crate::ranges::CURRENT_BANDWIDTH_RAD_S;
    let e = coefficients::pi_gains(
        &CURRENT_BANDWIDTH_RAD_S,
        1000.0,
        (1.0e6, |w| w * 1000.0),
        (0.01, |w| w * 1e-5),
        1.0,
        "",
        1e9,
    );
    match e {
        Err(ConfigError::OutOfRangeGiven {
            param,
            max,
            min,
            min_exclusive,
            ..
        }) => {
            assert_eq!(param, CURRENT_BANDWIDTH_RAD_S.key);
            let want = 1000.0 * (32_768.0 - 2.0 / 65_536.0) / 1.0e6;
            assert!(
                (f64::from(max) - want).abs() < 1e-4 * want,
                "{max} against {want}"
            );
            // The range's own minimum (0, excluded) is not the bound: a closed one is.
            assert!(min > 0.0 && !min_exclusive);
        }
        other => panic!("{other:?}"),
    }
    // Ki·Ts ∝ ω² (the velocity PI's): too large, the top is ω·√(Q8.24's largest/Ki·Ts).
    let e = coefficients::pi_gains(
        &CURRENT_BANDWIDTH_RAD_S,
        100.0,
        (1.0, |w| w * 0.01),
        (1000.0, |w| w * w * 0.1),
        2.0,
        "",
        1e9,
    );
    match e {
        Err(ConfigError::OutOfRangeGiven { max, .. }) => {
            let want = 100.0 * ((128.0 - 2.0 / 16_777_216.0) / 1000.0f64).sqrt();
            assert!(
                (f64::from(max) - want).abs() < 1e-4 * want,
                "{max} against {want}"
            );
        }
        other => panic!("{other:?}"),
    }
}

/// A regulator whose gains are far too small for their formats: the bandwidth's range reaches up
/// to the loop's Nyquist limit, π·rate (just below it), and no further.
#[test]
fn a_regulator_s_bandwidth_range_stops_below_its_nyquist_limit() {
    let g = crate::design(&drive()).unwrap();
    let cfg = g.cfg;
    let (lim, vlim) = (Pu::from_num(2), Pu::from_num(2));
    for (velocity, rate) in [(true, cfg.velocity_rate_hz), (false, cfg.current_rate_hz)] {
        let mut g = g;
        // Both gains far below their formats, and the inertia or winding the range's top is
        // worked out from: their ranges reach far above the limit.
        if velocity {
            (g.kp_vel, g.ki_vel, g.j_loop_s) = (1e-9, 1e-9, 1e-9);
        } else {
            (g.kp_cur, g.ki_cur) = (1e-9, 1e-9);
            (g.cfg.winding_inductance_pu_s, g.cfg.winding_resistance_pu) = (1e-9, 1e-9);
        }
        match coefficients::regulators(&g, lim, vlim) {
            Err(ConfigError::OutOfRangeGiven { max, .. }) => {
                assert_eq!(max, (core::f32::consts::PI * rate as f32).next_down());
            }
            other => panic!("{other:?}"),
        }
    }
}
