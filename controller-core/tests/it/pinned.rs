//! Behaviours pinned down one by one, each written against a mutant of the tick path that
//! the other tests did not catch (a sign flipped, a comparison loosened, an arm deleted).
//! Each test is named after the behaviour it guarantees.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use crate::common;
use controller_core::differentiator::{Differentiator, DifferentiatorState};
use controller_core::per_unit::{CountsErr, Gain, Pu, TickGain, checked_q};
use controller_core::pi::{PiCoefficients, PiState};
use controller_core::{
    AfbMode, Controller, CurrentInputs, DriveConfig, Estimator, Fault, FilterConfig, Setpoint,
    VelocityInputs,
};

fn pi(kp: f64, ki_ts: f64, limit: f64) -> PiCoefficients {
    PiCoefficients {
        kp: Gain::from_num(kp),
        ki_ts: TickGain::from_num(ki_ts),
        limit: Pu::from_num(limit),
    }
}

#[test]
fn the_pi_feed_forward_adds_to_the_output_with_its_sign() {
    let c = pi(1.0, 0.0, 10.0);
    for ff in [0.3, -0.7] {
        let mut s = PiState::default();
        let u = c.update(&mut s, Pu::ZERO, Pu::from_num(ff));
        assert_eq!(u, Pu::from_num(ff), "ff = {ff}");
    }
}

#[test]
fn the_anti_windup_counts_the_feed_forward_with_its_sign() {
    // Kp·e = 0.5 and ff = 0.6: the trial sum 1.1 is past the limit 1 and the error pushes
    // further out, so the integrator holds. With ff taken as −0.6 it would integrate.
    let c = pi(1.0, 0.1, 1.0);
    let mut s = PiState::default();
    c.update(&mut s, Pu::from_num(0.5), Pu::from_num(0.6));
    assert_eq!(
        s.integral, 0,
        "integrated while saturated by the feed-forward"
    );
    // Mirror image.
    let mut s = PiState::default();
    c.update(&mut s, Pu::from_num(-0.5), Pu::from_num(-0.6));
    assert_eq!(s.integral, 0);
    // Without the feed-forward the same error integrates.
    let mut s = PiState::default();
    c.update(&mut s, Pu::from_num(0.5), Pu::ZERO);
    assert!(s.integral > 0);
}

#[test]
fn the_differentiator_outputs_nothing_until_it_has_two_and_three_samples() {
    let d = Differentiator {
        k_vel: TickGain::from_num(0.5),
        k_acc: Gain::from_num(10),
    };
    let mut s = DifferentiatorState::default();
    // First sample far from 0: no velocity from the jump out of the reset state.
    assert_eq!(d.update(&mut s, 1000), (Pu::ZERO, Pu::ZERO));
    // Second: velocity from one difference, but no acceleration yet (no previous delta).
    let (v, a) = d.update(&mut s, 1004);
    assert_eq!((v, a), (Pu::from_num(2), Pu::ZERO));
    // Third: both.
    let (v, a) = d.update(&mut s, 1010);
    assert_eq!((v, a), (Pu::from_num(3), Pu::from_num(20)));
}

/// Table 1 with velocity from differentiation and no filter, so the velocity estimate is
/// exactly Δcounts · k_vel.
fn differentiating(overspeed_pu: f32) -> DriveConfig {
    let mut c = common::table1();
    c.velocity_estimator = Estimator::Differentiation;
    c.velocity_filter = FilterConfig::None;
    c.accel_feedback.mode = AfbMode::Off;
    c.faults.overspeed_pu = overspeed_pu;
    c
}

/// Runs velocity ticks with the encoder moving `step` counts per velocity tick; returns
/// the last velocity estimate and the fault.
fn move_at(c: &mut Controller, step: u32, ticks: u32) -> (Pu, Option<Fault>) {
    let mut out = None;
    for k in 0..ticks {
        let count = (k * step) & 0xFFFF;
        out = Some(c.velocity_tick(VelocityInputs {
            encoder_count: count,
            ..VelocityInputs::default()
        }));
    }
    let o = out.unwrap();
    (o.velocity_est_pu, o.fault)
}

#[test]
fn overspeed_trips_above_the_limit_and_not_at_it() {
    // The velocity estimate of 20 counts per tick, read off the controller itself.
    let mut probe = Controller::new(&differentiating(100.0)).unwrap();
    let (v, fault) = move_at(&mut probe, 20, 3);
    assert!(fault.is_none() && v > Pu::ZERO);
    // A limit of exactly that velocity (Q16.16 → f32 is exact): no trip.
    let at: f32 = v.to_num();
    let mut c = Controller::new(&differentiating(at)).unwrap();
    assert_eq!(move_at(&mut c, 20, 3).1, None, "tripped at the limit");
    // One LSB below it: trip.
    let below: f32 = (v - Pu::from_bits(1)).to_num();
    let mut c = Controller::new(&differentiating(below)).unwrap();
    assert_eq!(move_at(&mut c, 20, 3).1, Some(Fault::Overspeed));
}

#[test]
fn an_encoder_jump_trips_above_the_largest_plausible_step_and_not_at_it() {
    let cfg = common::table1();
    let probe = Controller::new(&cfg).unwrap();
    let max_step: i32 = checked_q::<CountsErr>(probe.gains().max_count_step)
        .unwrap()
        .to_num();
    assert!(max_step > 2);
    for (step, trips) in [(max_step, false), (max_step + 1, true)] {
        let mut c = Controller::new(&cfg).unwrap();
        let tick = |c: &mut Controller, count: i32| {
            c.current_tick(CurrentInputs {
                encoder_count: (count as u32) & 0xFFFF,
                current_pu: Pu::ZERO,
            })
        };
        tick(&mut c, 0);
        let out = tick(&mut c, step);
        assert_eq!(
            out.fault == Some(Fault::EncoderJump),
            trips,
            "step {step} (largest plausible {max_step})"
        );
    }
}

#[test]
fn a_following_error_trips_above_the_limit_and_not_at_it() {
    // Position mode: command 100 counts away from a motor that stays at 0.
    let sp = Setpoint {
        position_counts: controller_core::Counts::from_num(100),
        ..Setpoint::default()
    };
    // The limit in revolutions of Table 1's 4096-count encoder: 100 counts = 100/4096 rev.
    let run = |limit_counts: f32| {
        let mut cfg = common::table1();
        cfg.faults.following_error_rev = limit_counts / 4096.0;
        let mut c = Controller::new(&cfg).unwrap();
        c.velocity_tick(VelocityInputs {
            encoder_count: 0,
            setpoint: sp,
            fault_input: false,
        })
    };
    let err = run(4096.0).position_error_counts;
    assert_eq!(err, CountsErr::from_num(100));
    assert_eq!(run(100.0).fault, None, "tripped at the limit");
    assert_eq!(run(99.99).fault, Some(Fault::FollowingError));
}

#[test]
fn differentiated_velocity_feeds_the_loop_when_the_afb_takes_the_observer() {
    // Velocity from differentiation, AFB on from the observer: the differentiator must
    // still run, or the velocity feedback reads 0.
    let mut cfg = differentiating(100.0);
    cfg.accel_feedback.mode = AfbMode::Plain;
    cfg.accel_feedback.source = Estimator::Observer;
    let mut c = Controller::new(&cfg).unwrap();
    let (v, fault) = move_at(&mut c, 20, 3);
    assert!(fault.is_none());
    assert!(v > Pu::from_num(0.1), "velocity feedback {v}");
}

#[test]
fn the_observer_reports_a_braking_load_as_positive_torque() {
    // Faulted (external fault), so the torque command is 0; the motor decelerates from
    // 40 counts per current tick by one count per tick: a load brakes forward motion.
    let mut c = Controller::new(&common::table1()).unwrap();
    c.velocity_tick(VelocityInputs {
        fault_input: true,
        ..VelocityInputs::default()
    });
    let mut pos: i64 = 0;
    let mut speed: i64 = 40;
    let mut last = None;
    for k in 0..400 {
        pos += speed;
        if k % 4 == 0 {
            speed -= 1;
        }
        let count = (pos as u32) & 0xFFFF;
        c.current_tick(CurrentInputs {
            encoder_count: count,
            current_pu: Pu::ZERO,
        });
        if k % 2 == 1 {
            last = Some(c.velocity_tick(VelocityInputs {
                encoder_count: count,
                fault_input: true,
                ..VelocityInputs::default()
            }));
        }
        if speed < 10 {
            break;
        }
    }
    let d = last.unwrap().disturbance_est_pu;
    assert!(d > Pu::from_num(0.01), "load-torque estimate {d}");
}

#[test]
fn the_error_form_feeds_the_commanded_acceleration_through_the_controller() {
    // Same gains, same inputs, error form against plain form: with a commanded
    // acceleration and the shaft at rest, the error form's AFB term is the plain one plus
    // g·Ka·F(a_cmd), so it is larger. A controller that drops a_cmd gives the two equal.
    let error_cfg = common::table1();
    assert_eq!(error_cfg.accel_feedback.mode, AfbMode::Error);
    let mut plain_cfg = error_cfg;
    plain_cfg.accel_feedback.mode = AfbMode::Plain;
    let gains = controller_core::design(&error_cfg).unwrap();
    let afb_term = |cfg: &DriveConfig| {
        // The error run's gains with the form switched: every gain bit-identical.
        let mut g = gains;
        g.cfg = *cfg;
        let mut c = Controller::from_gains(&g).unwrap();
        c.current_tick(CurrentInputs::default());
        c.velocity_tick(VelocityInputs {
            setpoint: Setpoint {
                acceleration_pu_s: Pu::from_num(2),
                ..Setpoint::default()
            },
            ..VelocityInputs::default()
        });
        let out = c.current_tick(CurrentInputs::default());
        assert!(out.fault.is_none());
        out.accel_fb_pu
    };
    let (error, plain) = (afb_term(&error_cfg), afb_term(&plain_cfg));
    assert!(error > plain, "error form {error}, plain form {plain}");
}
