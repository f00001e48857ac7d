//! The inertia the velocity PI is sized for (`DriveConfig::velocity_pi_inertia`) and "the
//! same gains without acceleration feedback" (`Gains::without_afb`).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use crate::common;
use controller_core::filter::LowPassDesign;
use controller_core::{
    AfbMode, Controller, CurrentInputs, DriveConfig, FilterConfig, Gains, PiInertia, Pu, Setpoint,
    VelocityInputs, design,
};

fn cfg(pi: PiInertia, mode: AfbMode, frac: f32) -> DriveConfig {
    let mut c = common::table1();
    c.velocity_pi_inertia = pi;
    c.accel_feedback.mode = mode;
    c.accel_feedback.gain_fraction = frac;
    c
}

/// Relative comparison of two f32 with a stated tolerance (the products are f32).
fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-6 * b.abs().max(1e-6)
}

/// Total: Kp = ω·J_total whatever Ka and the AFB form; TotalPlusAfb: Kp = ω·(J_total + Ka).
#[test]
fn velocity_pi_inertia_decides_kp() {
    let w = common::table1().velocity_bandwidth_rad_s;
    let jt = 0.117f32 + 0.863;
    for mode in [AfbMode::Plain, AfbMode::Error] {
        for frac in [0.0f32, 0.25, 0.5, 1.0, 3.0] {
            let t = design(&cfg(PiInertia::Total, mode, frac)).unwrap();
            assert!(close(t.kp_vel, w * jt), "{mode:?} {frac}: {}", t.kp_vel);
            assert!(close(t.j_loop_s, jt));
            assert!(close(t.ki_vel, t.kp_vel * w / 4.0));
            let p = design(&cfg(PiInertia::TotalPlusAfb, mode, frac)).unwrap();
            let ka = frac * jt;
            assert!(close(p.ka, ka));
            assert!(
                close(p.kp_vel, w * (jt + ka)),
                "{mode:?} {frac}: {}",
                p.kp_vel
            );
            assert!(close(p.ki_vel, p.kp_vel * w / 4.0));
            // The feed-forward meets the inertia the commanded acceleration sees, whatever
            // the PI is sized for: J_total in the error form, J_total + Ka in the plain form.
            let j_ff = if mode == AfbMode::Plain { jt + ka } else { jt };
            assert!(close(t.k_accel_ff, j_ff) && close(p.k_accel_ff, j_ff));
        }
    }
    // AFB off: both settings give ω·J_total (Ka = 0).
    for pi in [PiInertia::Total, PiInertia::TotalPlusAfb] {
        let g = design(&cfg(pi, AfbMode::Off, 0.5)).unwrap();
        assert_eq!(g.ka, 0.0);
        assert!(close(g.kp_vel, w * jt));
    }
    // The Table 1 default is Total.
    assert_eq!(common::table1().velocity_pi_inertia, PiInertia::Total);
}

fn filter_bits(f: &LowPassDesign) -> Vec<u32> {
    match *f {
        LowPassDesign::None => vec![],
        LowPassDesign::FirstOrder { alpha } => vec![alpha.to_bits()],
        LowPassDesign::SecondOrder { b0, a1, a2 } => vec![b0.to_bits(), a1.to_bits(), a2.to_bits()],
    }
}

/// Every field of `Gains` except `ka` and `k_accel_ff`, as bits.
fn regulator_bits(g: &Gains) -> Vec<u32> {
    let mut v = vec![
        g.j_total_s.to_bits(),
        g.j_loop_s.to_bits(),
        g.kpp.to_bits(),
        g.k_pos_pu_per_count.to_bits(),
        g.kp_vel.to_bits(),
        g.ki_vel.to_bits(),
        g.kp_cur.to_bits(),
        g.ki_cur.to_bits(),
        g.cfg.accel_ff_gain.to_bits(),
        g.vel_tick_pu_per_count.to_bits(),
        g.vel_tick_pu_s_per_count.to_bits(),
        g.cur_tick_pu_per_count.to_bits(),
        g.cur_tick_pu_s_per_count.to_bits(),
        g.afb_rate_hz.to_bits(),
        g.observer_inertia_s.to_bits(),
        g.observer_pole.to_bits(),
        g.observer_k_u.to_bits(),
        g.max_count_step.to_bits(),
        g.ticks_per_velocity,
    ];
    v.extend(g.observer_l.map(f32::to_bits));
    v.extend(filter_bits(&g.velocity_filter));
    v.extend(filter_bits(&g.afb_filter));
    v
}

/// `without_afb`: Ka = 0, every regulator, filter and observer coefficient bit-identical to
/// the AFB run; the feed-forward is the AFB-off design's (bit-identical to `design()` of the
/// AFB-off config). With the PI sized for J_total the whole result equals that design.
#[test]
fn without_afb_keeps_every_other_gain_bit_identical() {
    for pi in [PiInertia::Total, PiInertia::TotalPlusAfb] {
        for mode in [AfbMode::Plain, AfbMode::Error] {
            let mut on = cfg(pi, mode, 0.7);
            on.velocity_filter = FilterConfig::SecondOrder {
                corner_hz: 120.0,
                q: 0.8,
            };
            let g = design(&on).unwrap();
            let off_g = g.without_afb();
            assert_ne!(g.ka, 0.0);
            assert_eq!(off_g.ka, 0.0);
            assert_eq!(
                regulator_bits(&off_g),
                regulator_bits(&g),
                "{pi:?} {mode:?}"
            );
            let mut off = on;
            off.accel_feedback.mode = AfbMode::Off;
            let own = design(&off).unwrap();
            assert_eq!(off_g.k_accel_ff.to_bits(), own.k_accel_ff.to_bits());
            if mode == AfbMode::Error {
                assert_eq!(off_g.k_accel_ff.to_bits(), g.k_accel_ff.to_bits());
            }
            if pi == PiInertia::Total {
                assert_eq!(off_g, own, "{mode:?}");
            } else {
                assert_ne!(off_g.kp_vel, own.kp_vel);
            }
        }
    }
}

/// The controller built with `from_gains(&design(cfg_on)?.without_afb())` runs bit for bit
/// like `Controller::new(cfg_off)` when the PI is sized for J_total (same gains), and with
/// the AFB run's larger Kp when sized for J_total + Ka.
#[test]
fn from_gains_of_the_afb_run_drives_like_the_same_design() {
    let run = |c: &mut Controller| {
        let mut out = Vec::new();
        for k in 0..400i32 {
            let raw = ((k * k / 97) & 0xFFFF) as u32;
            if k % 2 == 0 {
                c.velocity_tick(VelocityInputs {
                    encoder_count: raw,
                    setpoint: Setpoint {
                        velocity_pu: Pu::from_num(0.1),
                        ..Setpoint::default()
                    },
                    fault_input: false,
                });
            }
            out.push(
                c.current_tick(CurrentInputs {
                    encoder_count: raw,
                    current_pu: Pu::ZERO,
                })
                .current_ref_pu,
            );
        }
        out
    };
    for pi in [PiInertia::Total, PiInertia::TotalPlusAfb] {
        let on = cfg(pi, AfbMode::Error, 0.5);
        let mut off = on;
        off.accel_feedback.mode = AfbMode::Off;
        let g = design(&on).unwrap().without_afb();
        assert_eq!(g.cfg, off);
        let a = run(&mut Controller::from_gains(&g).unwrap());
        let b = run(&mut Controller::new(&off).unwrap());
        if pi == PiInertia::Total {
            assert_eq!(a, b);
        } else {
            assert_ne!(a, b);
        }
    }
}
