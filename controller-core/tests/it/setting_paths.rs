//! Settings that send a tick down another path than the Table 1 defaults, each checked
//! against what that path must compute: the closed-form AFB gain on more than one filter and
//! Ka, the tick the AFB runs in, a velocity feed-forward gain below 1, the differentiator
//! feeding the AFB while the observer gives the velocity, the measured-current torque
//! input of the observer, and velocity mode, which quantizes no position gain.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use crate::common;
use controller_core::observer::ObserverState;
use controller_core::{
    AfbMode, AfbRate, Controller, Counts, CurrentInputs, DriveConfig, Estimator, FilterConfig,
    ObserverInertia, ObserverTorque, Pu, Setpoint, VelocityInputs, design,
};

/// A velocity tick at `raw` with the position setpoint on it (no following error) and the
/// velocity setpoint `velocity_pu`.
fn velocity_at(raw: i64, velocity_pu: Pu) -> VelocityInputs {
    VelocityInputs {
        encoder_count: raw as u32,
        setpoint: Setpoint {
            position_counts: Counts::from_num(raw),
            velocity_pu,
            acceleration_pu_s: Pu::ZERO,
        },
        fault_input: false,
    }
}

fn current_at(raw: i64, current_pu: Pu) -> CurrentInputs {
    CurrentInputs {
        encoder_count: raw as u32,
        current_pu,
    }
}

/// The closed-form AFB gain is g·Ka with g = 1/(1 + b0·Ka/J_model) (accel_feedback module
/// docs), b0 the quantized filter's feed-through: for three filters (b0 = 1, α, the
/// biquad's b0), four Ka and both observer models it is that formula to one Q16.16 step
/// (plus the f32 rounding of the design), and with the acceleration from differentiation
/// (no model to solve through) it is zero.
#[test]
fn closed_form_afb_gain_is_ka_over_one_plus_b0_ka_over_j_model() {
    let filters = [
        FilterConfig::None,
        FilterConfig::FirstOrder { corner_hz: 100.0 },
        FilterConfig::SecondOrder {
            corner_hz: 300.0,
            q: 0.7,
        },
    ];
    let mut checked = 0;
    for filter in filters {
        for fraction in [0.25f32, 1.0, 3.0, 8.0] {
            for model in [ObserverInertia::Motor, ObserverInertia::Total] {
                let mut cfg = common::table1();
                cfg.accel_feedback.filter = filter;
                cfg.accel_feedback.gain_fraction = fraction;
                cfg.observer.model_inertia = model;
                let g = design(&cfg).unwrap();
                let afb = Controller::from_gains(&g).unwrap().blocks().accel_feedback;
                let b0 = afb.filter.feedthrough().to_num::<f64>();
                let (ka, j) = (f64::from(g.ka), f64::from(g.observer_inertia_s));
                let want = ka / (1.0 + b0 * ka / j);
                let got = afb.ka_closed.to_num::<f64>();
                let tol = 2f64.powi(-16) + 1e-6 * want;
                assert!(
                    (got - want).abs() <= tol,
                    "{filter:?} fraction {fraction} {model:?}: ka_closed {got}, \
                     Ka/(1 + b0·Ka/J) = {want} (Ka {ka}, b0 {b0}, J_model {j})"
                );
                // Not Ka itself: the gain is the closed loop's, visibly below Ka here.
                assert!(got < 0.99 * ka, "{filter:?} {fraction} {model:?}");
                checked += 1;

                cfg.accel_feedback.source = Estimator::Differentiation;
                let c = Controller::new(&cfg).unwrap();
                assert_eq!(c.blocks().accel_feedback.ka_closed.to_bits(), 0);
            }
        }
    }
    assert_eq!(checked, 24);
}

/// The AFB term of `cfg` after 200 current ticks of an accelerating encoder with no
/// velocity tick, and whether any velocity tick of a second run (one per two current
/// ticks, the same motion) changed the term the current tick before it had left.
fn afb_by_tick(cfg: &DriveConfig) -> (Pu, bool) {
    let pos = |n: i64| n * n / 16;
    let mut c = Controller::new(cfg).unwrap();
    let mut afb = Pu::ZERO;
    for n in 0..200 {
        let out = c.current_tick(current_at(pos(n), Pu::ZERO));
        assert_eq!(out.fault, None, "tick {n}");
        afb = out.accel_fb_pu;
    }
    let mut c = Controller::new(cfg).unwrap();
    let mut held = Pu::ZERO;
    let mut velocity_tick_moved_it = false;
    for n in 0..200 {
        if n % 2 == 0 {
            let out = c.velocity_tick(velocity_at(pos(n), Pu::ZERO));
            assert_eq!(out.fault, None, "tick {n}");
            velocity_tick_moved_it |= out.accel_fb_pu != held;
        }
        held = c.current_tick(current_at(pos(n), Pu::ZERO)).accel_fb_pu;
    }
    (afb, velocity_tick_moved_it)
}

/// `accel_feedback.rate` picks the tick the AFB runs in, for both sources: at rate Current
/// the current tick alone forms the term and a velocity tick never changes it; at rate
/// Velocity current ticks alone leave it at zero and the velocity tick forms it.
#[test]
fn afb_runs_in_the_tick_its_rate_names() {
    for source in [Estimator::Observer, Estimator::Differentiation] {
        let mut cfg = common::table1();
        cfg.accel_feedback.source = source;
        cfg.accel_feedback.mode = AfbMode::Plain;
        cfg.accel_feedback.rate = AfbRate::Current;
        let (afb, moved) = afb_by_tick(&cfg);
        assert_ne!(afb, Pu::ZERO, "{source:?} at Current: no AFB");
        assert!(!moved, "{source:?} at Current: moved by a velocity tick");

        cfg.accel_feedback.rate = AfbRate::Velocity;
        let (afb, moved) = afb_by_tick(&cfg);
        assert_eq!(
            afb,
            Pu::ZERO,
            "{source:?} at Velocity: AFB in current ticks"
        );
        assert!(moved, "{source:?} at Velocity: no AFB");
    }
}

/// With the position loop on and no position error, the velocity command is vff·ω_sp
/// rounded (Q16.16): for gains below 1 the product, not ω_sp, and ω_sp itself for 1.
#[test]
fn velocity_command_is_the_feed_forward_gain_times_the_setpoint() {
    let sp = Pu::from_num(0.4);
    for vff in [0.0f32, 0.25, 0.5, 0.9, 1.0] {
        let mut cfg = common::table1();
        cfg.velocity_ff_gain = vff;
        let mut c = Controller::new(&cfg).unwrap();
        c.current_tick(current_at(0, Pu::ZERO));
        let out = c.velocity_tick(velocity_at(0, sp));
        assert_eq!(out.position_error_counts.to_bits(), 0);
        let want = (sp.to_num::<f64>() * f64::from(vff) * 65536.0).round() / 65536.0;
        assert!(
            (out.velocity_cmd_pu.to_num::<f64>() - want).abs() <= 2f64.powi(-16),
            "vff {vff}: ω_cmd {} for vff·ω_sp {want}",
            out.velocity_cmd_pu
        );
    }
}

/// Differentiation as the AFB's source at the velocity rate, with the observer as the
/// velocity estimator: the velocity tick still differentiates, so on a position whose
/// second difference is one count per velocity tick² the acceleration estimate is
/// 1 count·(pu/s per count per velocity tick²) and the AFB term is not zero.
#[test]
fn differentiated_afb_runs_beside_the_observer_velocity() {
    for mode in [AfbMode::Plain, AfbMode::Error] {
        let mut cfg = common::table1();
        cfg.velocity_estimator = Estimator::Observer;
        cfg.accel_feedback.source = Estimator::Differentiation;
        cfg.accel_feedback.rate = AfbRate::Velocity;
        cfg.accel_feedback.mode = mode;
        let g = design(&cfg).unwrap();
        let one_count = f64::from(g.vel_tick_pu_s_per_count);
        let mut c = Controller::new(&cfg).unwrap();
        for k in 0i64..20 {
            let p = k * (k - 1) / 2;
            c.current_tick(current_at(p, Pu::ZERO));
            let out = c.velocity_tick(velocity_at(p, Pu::ZERO));
            c.current_tick(current_at(p, Pu::ZERO));
            assert_eq!(out.fault, None, "{mode:?} tick {k}");
            if k >= 2 {
                let a = out.acceleration_est_pu_s.to_num::<f64>();
                assert!(
                    (a - one_count).abs() <= 1e-3 * one_count,
                    "{mode:?} tick {k}: acceleration {a}, one count per tick² is {one_count}"
                );
                assert_ne!(out.accel_fb_pu, Pu::ZERO, "{mode:?} tick {k}");
            }
        }
    }
}

/// With `observer.torque_input = measured_current` the observer is driven, each current
/// tick, by the mean of the current sampled at the last tick and now, (i[n−1] + i[n])/2
/// rounded down in Q16.16 (i[−1] = 0): the controller's observer outputs are, bit for bit,
/// those of its own observer block stepped with that mean.
#[test]
fn measured_current_observer_input_is_the_mean_of_two_samples() {
    let mut cfg = common::table1();
    cfg.observer.torque_input = ObserverTorque::MeasuredCurrent;
    let mut c = Controller::new(&cfg).unwrap();
    let obs = c.blocks().observer;
    let mut s = ObserverState::default();
    let mut last = Pu::ZERO;
    for n in 0i64..400 {
        let p = (40.0 * (n as f64 / 30.0).sin()).round() as i64;
        let i = Pu::from_num(0.3 * (n as f64 / 7.0).sin() + 0.2);
        let mean =
            Pu::from_bits(((i64::from(last.to_bits()) + i64::from(i.to_bits())) >> 1) as i32);
        obs.update(&mut s, p, mean);
        last = i;
        let out = c.current_tick(current_at(p, i));
        assert_eq!(out.fault, None, "tick {n}");
        if n % 2 == 1 {
            let v = c.velocity_tick(velocity_at(p, Pu::ZERO));
            assert_eq!(v.fault, None, "tick {n}");
            assert_eq!(v.disturbance_est_pu, obs.load_torque_pu(&s), "tick {n}");
            assert_eq!(
                v.acceleration_est_pu_s,
                obs.acceleration_pu_s(&s),
                "tick {n}"
            );
        }
    }
}

/// In velocity mode (Kpp = 0) the position gain is not used, so it is not quantized: gains
/// whose k_pos would not fit its Q1.31 still build a controller without a position loop,
/// and with the position loop on the same k_pos is refused, naming it.
#[test]
fn velocity_mode_does_not_quantize_the_position_gain() {
    let mut g = design(&common::table1()).unwrap();
    g.k_pos_pu_per_count = 1e6;
    g.kpp = 0.0;
    let mut c = Controller::from_gains(&g).unwrap();
    c.current_tick(current_at(0, Pu::ZERO));
    let out = c.velocity_tick(VelocityInputs {
        setpoint: Setpoint {
            position_counts: Counts::from_num(500),
            velocity_pu: Pu::from_num(0.25),
            acceleration_pu_s: Pu::ZERO,
        },
        ..VelocityInputs::default()
    });
    assert_eq!(out.position_error_counts.to_bits(), 0, "no position loop");
    assert_eq!(out.velocity_cmd_pu, Pu::from_num(0.25));
    g.kpp = 1.0;
    let e = Controller::from_gains(&g).unwrap_err();
    assert!(format!("{e}").contains("k_pos"), "{e}");
}
