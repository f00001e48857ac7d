//! Controller-level behaviour: counter wrap, saturation, faults and reset.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use crate::common;
use controller_core::per_unit::count_diff;
use controller_core::{Controller, Counts, CurrentInputs, Fault, Pu, Setpoint, VelocityInputs};

fn mask(bits: u8) -> u64 {
    if bits >= 32 {
        u64::from(u32::MAX)
    } else {
        (1u64 << bits) - 1
    }
}

/// Move the encoder at `step` counts per current tick through the counter's wrap, with a
/// setpoint that follows exactly: the position error stays zero and no fault trips.
fn run_through_wrap(bits: u8, start_raw: u64) {
    let mut cfg = common::table1();
    cfg.counter_bits = bits;
    let mut c = Controller::new(&cfg).unwrap();
    let step = 7i64;
    let m = mask(bits);
    let start_signed = {
        let shift = 64 - u32::from(bits);
        ((start_raw << shift) as i64) >> shift
    };
    for k in 0..4000i64 {
        let true_pos = start_signed + k * step;
        let raw = (true_pos as u64 & m) as u32;
        c.current_tick(CurrentInputs {
            encoder_count: raw,
            current_pu: Pu::ZERO,
        });
        if k % 2 == 0 {
            let out = c.velocity_tick(VelocityInputs {
                encoder_count: raw,
                setpoint: Setpoint {
                    position_counts: Counts::from_num(true_pos),
                    velocity_pu: Pu::ZERO,
                    acceleration_pu_s: Pu::ZERO,
                },
                fault_input: false,
            });
            assert_eq!(out.position_error_counts, 0, "bits {bits} k {k}");
            assert_eq!(out.fault, None, "bits {bits} k {k}");
        }
    }
}

#[test]
fn counter_wraps_at_its_width() {
    run_through_wrap(16, 0xFFFF - 3000);
    run_through_wrap(24, 0xFF_FFFF - 3000);
    run_through_wrap(32, u64::from(u32::MAX) - 3000);
    // Backwards through zero.
    assert_eq!(count_diff(0xFFF0, 0x0010, 16), -0x20);
    assert_eq!(count_diff(0x10, 0xFFFF_FFF0, 32), 0x20);
}

#[test]
fn torque_and_voltage_saturate_at_their_limits() {
    let cfg = common::table1();
    let mut c = Controller::new(&cfg).unwrap();
    for k in 0..2000 {
        let out = c.current_tick(CurrentInputs {
            encoder_count: 0,
            current_pu: Pu::ZERO,
        });
        if k % 2 == 0 {
            c.velocity_tick(VelocityInputs {
                encoder_count: 0,
                setpoint: Setpoint {
                    position_counts: Counts::from_num(500),
                    velocity_pu: Pu::from_num(1),
                    acceleration_pu_s: Pu::ZERO,
                },
                fault_input: false,
            });
        }
        assert!(out.current_ref_pu.abs() <= Pu::from_num(cfg.torque_limit_pu));
        assert!(out.voltage_cmd_pu.abs() <= Pu::from_num(cfg.voltage_limit_pu));
    }
    let out = c.current_tick(CurrentInputs {
        encoder_count: 0,
        current_pu: Pu::ZERO,
    });
    assert_eq!(out.current_ref_pu, Pu::from_num(cfg.torque_limit_pu));
    assert_eq!(out.voltage_cmd_pu, Pu::from_num(cfg.voltage_limit_pu));
    // Anti-windup: once the error reverses the torque reference leaves the limit at once.
    let out = c.velocity_tick(VelocityInputs {
        encoder_count: 0,
        setpoint: Setpoint {
            position_counts: Counts::from_num(0),
            velocity_pu: Pu::from_num(-0.05),
            acceleration_pu_s: Pu::ZERO,
        },
        fault_input: false,
    });
    assert!(
        out.current_ref_pu < Pu::from_num(cfg.torque_limit_pu),
        "{:?}",
        out.current_ref_pu
    );
}

fn vel_in(raw: u32, sp_counts: i64, fault_input: bool) -> VelocityInputs {
    VelocityInputs {
        encoder_count: raw,
        setpoint: Setpoint {
            position_counts: Counts::from_num(sp_counts),
            velocity_pu: Pu::ZERO,
            acceleration_pu_s: Pu::ZERO,
        },
        fault_input,
    }
}

/// A faulted drive commands zero torque and stays faulted until reset.
fn assert_latched(c: &mut Controller, fault: Fault) {
    for _ in 0..50 {
        let o = c.current_tick(CurrentInputs {
            encoder_count: 0,
            current_pu: Pu::ZERO,
        });
        assert_eq!(o.fault, Some(fault));
        assert_eq!(o.current_ref_pu, Pu::ZERO);
        assert_eq!(o.accel_fb_pu, Pu::ZERO);
        let v = c.velocity_tick(vel_in(0, 0, false));
        assert_eq!(v.fault, Some(fault));
        assert_eq!(v.current_ref_pu, Pu::ZERO);
    }
    c.reset();
    assert_eq!(c.fault(), None);
    let o = c.current_tick(CurrentInputs {
        encoder_count: 0,
        current_pu: Pu::ZERO,
    });
    assert_eq!(o.fault, None);
}

#[test]
fn encoder_jump_trips_and_latches() {
    let mut c = Controller::new(&common::table1()).unwrap();
    c.current_tick(CurrentInputs {
        encoder_count: 100,
        current_pu: Pu::ZERO,
    });
    // 1.5 pu overspeed × 2 margin at 4 kHz and 4096 CPR is 53 counts per tick: 60 trips.
    let max_step = c.gains().max_count_step;
    assert!((max_step - 53.2).abs() < 0.1, "{max_step}");
    let o = c.current_tick(CurrentInputs {
        encoder_count: 150,
        current_pu: Pu::ZERO,
    });
    assert_eq!(o.fault, None);
    let o = c.current_tick(CurrentInputs {
        encoder_count: 210,
        current_pu: Pu::ZERO,
    });
    assert_eq!(o.fault, Some(Fault::EncoderJump));
    assert_latched(&mut c, Fault::EncoderJump);
}

#[test]
fn overspeed_trips_and_latches() {
    let mut c = Controller::new(&common::table1()).unwrap();
    // 30 counts per 0.25 ms = 1.76 pu, above the 1.5 pu trip, below the jump limit.
    let mut tripped = None;
    for k in 0..400u32 {
        let raw = (k * 30) & 0xFFFF;
        c.current_tick(CurrentInputs {
            encoder_count: raw,
            current_pu: Pu::ZERO,
        });
        if k % 2 == 0 {
            let v = c.velocity_tick(VelocityInputs {
                encoder_count: raw,
                setpoint: Setpoint::default(),
                fault_input: false,
            });
            if v.fault.is_some() {
                tripped = v.fault;
                break;
            }
        }
    }
    assert_eq!(tripped, Some(Fault::Overspeed));
    assert_latched(&mut c, Fault::Overspeed);
}

#[test]
fn following_error_trips_and_latches() {
    // The default limit, a quarter revolution, is 1024 counts on Table 1's 4096-count
    // encoder.
    let mut c = Controller::new(&common::table1()).unwrap();
    let v = c.velocity_tick(vel_in(0, 1000, false));
    assert_eq!(v.fault, None);
    assert_eq!(v.position_error_counts, 1000);
    let v = c.velocity_tick(vel_in(0, 1025, false));
    assert_eq!(v.fault, Some(Fault::FollowingError));
    assert_latched(&mut c, Fault::FollowingError);
    // In velocity mode there is no following-error check.
    let mut cfg = common::table1();
    cfg.position_bandwidth_rad_s = 0.0;
    let mut c = Controller::new(&cfg).unwrap();
    let v = c.velocity_tick(vel_in(0, 1_000_000, false));
    assert_eq!(v.fault, None);
    assert_eq!(v.position_error_counts, 0);
}

#[test]
fn external_fault_trips_and_latches() {
    let mut c = Controller::new(&common::table1()).unwrap();
    let v = c.velocity_tick(vel_in(0, 0, true));
    assert_eq!(v.fault, Some(Fault::External));
    assert_eq!(Fault::External.to_string(), "external fault input");
    assert_latched(&mut c, Fault::External);
}

#[test]
fn afb_output_is_a_named_signal_and_follows_the_mode() {
    // Error form: with the motor still (differentiated acceleration 0) and a commanded
    // acceleration the AFB term pushes forwards (Ka·LPF(a_cmd − 0) > 0); plain form gives
    // zero for a still motor. (The observer would see the torque and predict motion.)
    for (mode, positive) in [
        (controller_core::AfbMode::Error, true),
        (controller_core::AfbMode::Plain, false),
    ] {
        let mut cfg = common::table1();
        cfg.accel_feedback.mode = mode;
        cfg.accel_feedback.source = controller_core::Estimator::Differentiation;
        let mut c = Controller::new(&cfg).unwrap();
        let mut last = Pu::ZERO;
        for k in 0..40 {
            if k % 2 == 0 {
                c.velocity_tick(VelocityInputs {
                    encoder_count: 0,
                    setpoint: Setpoint {
                        position_counts: Counts::ZERO,
                        velocity_pu: Pu::ZERO,
                        acceleration_pu_s: Pu::from_num(1),
                    },
                    fault_input: false,
                });
            }
            last = c
                .current_tick(CurrentInputs {
                    encoder_count: 0,
                    current_pu: Pu::ZERO,
                })
                .accel_fb_pu;
        }
        if positive {
            assert!(last > Pu::ZERO, "{mode:?}: {last}");
        } else {
            assert!(last <= Pu::ZERO, "{mode:?}: {last}");
        }
    }
}

/// "The same gains without acceleration feedback": design with AFB on, take the AFB out of
/// those gains and build with AFB off; the regulator gains stay bit-identical, also when the
/// PI is sized for J_total + Ka (where AFB off would design a smaller Kp of its own).
#[test]
fn from_gains_runs_the_same_gains_with_afb_off() {
    let mut on = common::table1();
    on.velocity_pi_inertia = controller_core::PiInertia::TotalPlusAfb;
    let gains = controller_core::design(&on).unwrap();
    let w = on.velocity_bandwidth_rad_s;
    assert!(
        (gains.kp_vel - w * (0.98 + 0.49)).abs() < 1e-3,
        "{}",
        gains.kp_vel
    );
    assert!((gains.ki_vel - gains.kp_vel * w / 4.0).abs() < 1e-2);
    let mut off = on;
    off.accel_feedback.mode = controller_core::AfbMode::Off;
    let own = controller_core::design(&off).unwrap();
    assert!((own.kp_vel - w * 0.98).abs() < 1e-3);
    let c = Controller::from_gains(&gains.without_afb()).unwrap();
    assert_eq!(c.gains().kp_vel.to_bits(), gains.kp_vel.to_bits());
    assert_eq!(c.gains().ka, 0.0);
    // The carried settings are the AFB-off drive.
    assert_eq!(c.gains().cfg, off);
    // Bad gains are still validated against their Q-formats: the error names the setting
    // the gain scales with, and the format.
    let mut bad = gains.without_afb();
    bad.kp_vel = 1e9;
    let e = Controller::from_gains(&bad).unwrap_err();
    assert_eq!(e.param(), "velocity_bandwidth_rad_s");
    assert!(e.to_string().contains("Q16.16"), "{e}");
}

/// Anti-windup on the final torque reference: when the velocity regulator's output plus the
/// AFB term sits at the torque limit, the velocity integrator holds even though the
/// regulator's own output is inside its limit.
#[test]
fn velocity_integrator_holds_when_the_sum_with_afb_saturates() {
    use controller_core::per_unit::{Gain, TickGain};
    use controller_core::pi::{PiCoefficients, PiState};
    let c = PiCoefficients {
        kp: Gain::from_num(10),
        ki_ts: TickGain::from_num(0.5),
        limit: Pu::from_num(2),
    };
    let mut s = PiState::default();
    for _ in 0..100 {
        let u = c.update_with_offset(&mut s, Pu::from_num(0.1), Pu::ZERO, Pu::from_num(1.5));
        assert!(u <= Pu::from_num(2));
    }
    // Kp·e = 1, offset 1.5: the sum is past the limit from the first step; nothing integrates.
    assert_eq!(s.integral, 0);
    // Without the offset the same error winds the integral up to the limit.
    let mut s2 = PiState::default();
    for _ in 0..100 {
        c.update(&mut s2, Pu::from_num(0.1), Pu::ZERO);
    }
    assert!(s2.integral > 0.9);
}

/// A downstream term that opposes a saturated regulator (the AFB term braking an
/// acceleration the drive is at its torque limit for) must not lower the torque reference:
/// the regulator's output is clamped so that the sum reaches the limit.
#[test]
fn opposing_afb_term_does_not_take_torque_away_at_the_limit() {
    use controller_core::per_unit::{Gain, TickGain};
    use controller_core::pi::{PiCoefficients, PiState};
    let c = PiCoefficients {
        kp: Gain::from_num(100),
        ki_ts: TickGain::from_num(0.5),
        limit: Pu::from_num(2),
    };
    let mut s = PiState::default();
    let offset = Pu::from_num(-0.6);
    let u = c.update_with_offset(&mut s, Pu::from_num(1), Pu::ZERO, offset);
    assert_eq!(u + offset, Pu::from_num(2));
    // An offset beyond the limit is bounded to it: the output stays within ±2·limit.
    let u = c.update_with_offset(&mut s, Pu::from_num(1), Pu::ZERO, Pu::from_num(-50));
    assert_eq!(u, Pu::from_num(4));
    let u = c.update_with_offset(&mut s, Pu::from_num(-1), Pu::ZERO, Pu::from_num(50));
    assert_eq!(u, Pu::from_num(-4));
}

/// Saturated with AFB on, the count noise swings the AFB term from one current tick to the
/// next. A rigid machine accelerating at the torque limit (the encoder counts of
/// ½·(T/J_total)·t², rounded, 4096 counts): with the plain clamp (headroom 0) the swings
/// take the torque reference off the limit on many ticks; with the dyno's headroom (0.15
/// of the limit) only the swings larger than it do, on some ticks but at most a tenth as
/// many; with
/// a headroom of the whole limit, on none.
#[test]
fn the_headroom_holds_a_saturated_torque_at_its_limit_through_afb_noise() {
    let ticks_below_limit = |headroom: f32| {
        let mut cfg = common::table1();
        cfg.accel_feedback.limit_headroom_fraction = headroom;
        cfg.position_bandwidth_rad_s = 0.0;
        let lim = Pu::from_num(cfg.torque_limit_pu);
        let accel_pu_s =
            f64::from(cfg.torque_limit_pu) / f64::from(cfg.motor_inertia_s + cfg.load_inertia_s);
        let counts_per_pu_s = f64::from(cfg.base_speed_rpm) / 60.0 * f64::from(cfg.encoder_cpr);
        let dt = 1.0 / f64::from(cfg.current_rate_hz);
        let mut c = Controller::new(&cfg).unwrap();
        let mut below = 0;
        for k in 0u32..600 {
            let t = f64::from(k) * dt;
            let count = (0.5 * accel_pu_s * counts_per_pu_s * t * t).round() as u32;
            if k % 2 == 0 {
                c.velocity_tick(VelocityInputs {
                    encoder_count: count,
                    setpoint: Setpoint {
                        position_counts: Counts::ZERO,
                        velocity_pu: Pu::from_num(1),
                        acceleration_pu_s: Pu::ZERO,
                    },
                    fault_input: false,
                });
            }
            let out = c.current_tick(CurrentInputs {
                encoder_count: count,
                current_pu: Pu::ZERO,
            });
            assert!(out.fault.is_none(), "{:?}", out.fault);
            if k >= 100 && out.current_ref_pu < lim {
                below += 1;
            }
        }
        below
    };
    // table1.toml leaves the setting to its default, the plain clamp.
    assert_eq!(common::table1().accel_feedback.limit_headroom_fraction, 0.0);
    let (with, plain, wide) = (
        ticks_below_limit(0.15),
        ticks_below_limit(0.0),
        ticks_below_limit(1.0),
    );
    eprintln!("ticks below the limit: {with} (0.15), {plain} (plain), {wide} (1.0)");
    assert!(
        with * 10 <= plain,
        "{with} with the headroom, {plain} without"
    );
    assert_eq!(wide, 0);
    // The headroom is 0.15 × the 2 pu limit = 0.3 pu: swings larger than that still reach
    // the torque.
    assert!(with > 0, "no tick below the limit with a 0.3 pu headroom");
}
