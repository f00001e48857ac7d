//! Property tests: arbitrary counts, jumps, currents and setpoints never panic (the test
//! profile keeps overflow checks on, so a wrap would panic) and keep every command within
//! its limit; arbitrary settings never panic the design.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use crate::common;
use controller_core::per_unit::count_diff;
use controller_core::{
    AfbMode, AfbRate, Controller, Counts, CurrentInputs, DriveConfig, Estimator, FilterConfig, Pu,
    Setpoint, VelocityInputs, design,
};
use proptest::prelude::*;

fn config(bits: u8, mode: u8, rate: bool, src: bool, vel_src: bool, filter: u8) -> DriveConfig {
    let mut c = common::table1();
    c.counter_bits = bits;
    c.accel_feedback.mode = [AfbMode::Off, AfbMode::Plain, AfbMode::Error][usize::from(mode % 3)];
    c.accel_feedback.rate = if rate {
        AfbRate::Current
    } else {
        AfbRate::Velocity
    };
    c.accel_feedback.source = if src {
        Estimator::Observer
    } else {
        Estimator::Differentiation
    };
    c.velocity_estimator = if vel_src {
        Estimator::Observer
    } else {
        Estimator::Differentiation
    };
    c.accel_feedback.filter = match filter % 3 {
        0 => FilterConfig::None,
        1 => FilterConfig::FirstOrder { corner_hz: 80.0 },
        _ => FilterConfig::SecondOrder {
            corner_hz: 150.0,
            q: 0.9,
        },
    };
    c
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn ticks_never_panic_and_respect_limits(
        bits in prop_oneof![Just(16u8), Just(20u8), Just(32u8)],
        mode in 0u8..3, rate: bool, src: bool, vel_src: bool, filter in 0u8..3,
        steps in proptest::collection::vec(
            (any::<u32>(), any::<i32>(), any::<bool>(), any::<i64>(), any::<i32>(), any::<i32>(), any::<bool>(), any::<bool>()),
            1..300),
    ) {
        let cfg = config(bits, mode, rate, src, vel_src, filter);
        let mut c = Controller::new(&cfg).unwrap();
        let tlim = Pu::from_num(cfg.torque_limit_pu);
        let vlim = Pu::from_num(cfg.voltage_limit_pu);
        let mut raw = 0u32;
        for (count, cur, jump, pos, vel, acc, vtick, fault_in) in steps {
            // Mostly small moves, sometimes arbitrary jumps.
            raw = if jump { count } else { raw.wrapping_add(count % 64) };
            let o = c.current_tick(CurrentInputs { encoder_count: raw, current_pu: Pu::from_bits(cur) });
            prop_assert!(o.current_ref_pu.abs() <= tlim);
            prop_assert!(o.voltage_cmd_pu.abs() <= vlim);
            prop_assert!(o.accel_fb_pu.abs() <= tlim);
            if o.fault.is_some() { prop_assert_eq!(o.current_ref_pu, Pu::ZERO); }
            if vtick {
                let v = c.velocity_tick(VelocityInputs {
                    encoder_count: raw,
                    setpoint: Setpoint { position_counts: Counts::from_bits(pos), velocity_pu: Pu::from_bits(vel), acceleration_pu_s: Pu::from_bits(acc) },
                    fault_input: fault_in && (pos % 7 == 0),
                });
                prop_assert!(v.current_ref_pu.abs() <= tlim);
                prop_assert!(v.accel_fb_pu.abs() <= tlim);
                if v.fault.is_some() { prop_assert_eq!(v.current_ref_pu, Pu::ZERO); }
            }
        }
    }

    #[test]
    fn blocks_never_panic_on_extreme_inputs(
        xs in proptest::collection::vec((any::<i32>(), any::<i64>(), any::<i32>()), 1..200),
    ) {
        use controller_core::filter::{design_low_pass, LowPass, LowPassState};
        use controller_core::observer::{Observer, ObserverState};
        use controller_core::differentiator::{Differentiator, DifferentiatorState};
        use controller_core::pi::{PiCoefficients, PiState};
        use controller_core::per_unit::{Coef, Gain, TickGain};
        let filters: Vec<LowPass> = [
            FilterConfig::FirstOrder { corner_hz: 1.0 },
            FilterConfig::SecondOrder { corner_hz: 5.0, q: 10.0 },
            FilterConfig::SecondOrder { corner_hz: 1900.0, q: 0.1 },
        ].iter().map(|f| LowPass::quantize(&design_low_pass(f, 4000.0, &controller_core::ranges::AFB_FILTER_CORNER_HZ, &controller_core::ranges::AFB_FILTER_Q).unwrap(), "t").unwrap()).collect();
        let mut fs = [LowPassState::default(); 3];
        let obs = Observer { l1: Coef::from_num(1.9), l2: Coef::from_num(1.9), l3: Coef::from_num(1.9),
            k_u: TickGain::MAX, k_vel: TickGain::MAX, k_acc: Gain::MAX, k_load: Gain::MIN,
            count_interval: controller_core::observer::CountInterval { lo: fixed::types::I16F16::MAX, hi: fixed::types::I16F16::MIN } };
        let mut os = ObserverState::default();
        let diff = Differentiator { k_vel: TickGain::MAX, k_acc: Gain::MAX };
        let mut ds = DifferentiatorState::default();
        let pi = PiCoefficients { kp: Gain::MAX, ki_ts: TickGain::MAX, limit: Pu::MAX };
        let mut ps = PiState::default();
        for (x, p, t) in xs {
            for (f, s) in filters.iter().zip(fs.iter_mut()) {
                let _ = f.process(s, Pu::from_bits(x));
            }
            obs.update(&mut os, p, Pu::from_bits(t));
            let _ = obs.estimate(&os);
            let _ = diff.update(&mut ds, p);
            let u = pi.update(&mut ps, Pu::from_bits(x), Pu::from_bits(t));
            prop_assert!(u.abs() <= Pu::MAX);
        }
    }

    #[test]
    fn profiles_never_panic(
        v in prop_oneof![any::<f32>(), -12.0f32..12.0],
        ta in prop_oneof![any::<f32>(), 0.0f32..3.0],
        th in prop_oneof![any::<f32>(), 0.0f32..3.0, Just(f32::INFINITY)],
        td in prop_oneof![any::<f32>(), 0.0f32..3.0],
        delay in prop_oneof![any::<f32>(), 0.0f32..1.0],
        tj in prop_oneof![any::<f32>(), 0.0f32..1.0],
        scurve: bool, start: i64, cpr in prop_oneof![Just(4096u32), Just(1_000_000u32)],
    ) {
        use controller_core::{Profile, ProfileConfig, ProfileKind};
        let cfg = ProfileConfig {
            kind: if scurve { ProfileKind::SCurve { jerk_time_s: tj } } else { ProfileKind::Trapezoid },
            peak_velocity_pu: v,
            accel_time_s: ta,
            hold_time_s: th,
            decel_time_s: td,
            start_delay_s: delay,
        };
        let mut drive = common::table1();
        drive.encoder_cpr = cpr;
        drive.counter_bits = 32;
        if let Ok(p) = Profile::new(&cfg, &drive) {
            let mut p = p.with_start_position(Counts::from_bits(start >> 8));
            for _ in 0..2000 {
                let sp = p.next();
                prop_assert!(sp.velocity_pu.abs() <= Pu::from_num(10.01));
            }
        }
    }

    #[test]
    fn count_diff_recovers_any_motion_below_half_range(
        bits in 16u8..=32, start: u32, delta in any::<i32>(),
    ) {
        let half = if bits == 32 { i64::from(i32::MAX) } else { (1i64 << (bits - 1)) - 1 };
        let d = (i64::from(delta) % half) as i32;
        let m = if bits == 32 { u64::from(u32::MAX) } else { (1u64 << bits) - 1 };
        let a = (u64::from(start) & m) as u32;
        let b = ((i64::from(a) + i64::from(d)) as u64 & m) as u32;
        prop_assert_eq!(count_diff(b, a, bits), d);
    }

    #[test]
    fn design_never_panics(
        v in proptest::collection::vec(prop_oneof![any::<f32>(), -10.0f32..10_000.0], 12),
        cpr: u32, bits: u8, fc: u32, fv: u32,
    ) {
        let mut c = common::table1();
        c.base_speed_rpm = v[0];
        c.motor_inertia_s = v[1];
        c.load_inertia_s = v[2];
        c.position_bandwidth_rad_s = v[3];
        c.velocity_bandwidth_rad_s = v[4];
        c.current_bandwidth_rad_s = v[5];
        c.winding_inductance_pu_s = v[6];
        c.accel_feedback.gain_fraction = v[7];
        c.accel_feedback.filter = FilterConfig::SecondOrder { corner_hz: v[8], q: v[9] };
        c.observer.bandwidth_hz = v[10];
        c.faults.following_error_rev = v[11];
        c.encoder_cpr = cpr;
        c.counter_bits = bits;
        c.current_rate_hz = fc % 200_000;
        c.velocity_rate_hz = fv % 200_000;
        let _ = design(&c);
        if let Ok(mut ctl) = Controller::new(&c) {
            let o = ctl.current_tick(CurrentInputs { encoder_count: 12345, current_pu: Pu::from_num(1) });
            prop_assert!(o.current_ref_pu.abs() <= Pu::saturating_from_num(c.torque_limit_pu));
        }
    }
}

/// A value spread over `[min, max]` by its logarithm (`u` in 0..=1), for a range that
/// spans decades.
fn log_between(min: f32, max: f32, u: f64) -> f32 {
    let (a, b) = (f64::from(min).ln(), f64::from(max).ln());
    (a + (b - a) * u).exp() as f32
}

/// The settings the refusal property draws: `u` (14 numbers in [0, 1]) placed across each
/// setting's range on a log scale.
fn drawn(u: &[f64], cpr_bits: u32, bits: u8, ratio: u32, mode: u8) -> DriveConfig {
    let mut c = common::table1();
    c.base_speed_rpm = log_between(1.0, 100_000.0, u[0]);
    c.encoder_cpr = 1 << cpr_bits;
    c.counter_bits = bits;
    c.current_rate_hz = (log_between(100.0, 100_000.0, u[1]) as u32 / ratio).max(10) * ratio;
    c.velocity_rate_hz = c.current_rate_hz / ratio;
    c.motor_inertia_s = log_between(1e-5, 1000.0, u[2]);
    c.load_inertia_s = log_between(1e-5, 1000.0, u[3]);
    let f_vel = c.velocity_rate_hz as f32;
    c.velocity_bandwidth_rad_s = log_between(1e-3, 0.999 * std::f32::consts::PI * f_vel, u[4]);
    c.current_bandwidth_rad_s = log_between(
        1e-3,
        0.999 * std::f32::consts::PI * c.current_rate_hz as f32,
        u[5],
    );
    c.position_bandwidth_rad_s = if u[6] < 0.2 {
        0.0
    } else {
        log_between(1e-3, 0.999 * std::f32::consts::PI * f_vel, u[6])
    };
    c.winding_inductance_pu_s = log_between(1e-5, 100.0, u[7]);
    c.winding_resistance_pu = log_between(1e-5, 100.0, u[8]);
    c.accel_feedback.mode = [AfbMode::Off, AfbMode::Plain, AfbMode::Error][usize::from(mode)];
    c.accel_feedback.gain_fraction = log_between(1e-6, 20.0, u[9]);
    c.observer.bandwidth_hz = log_between(1e-3, c.current_rate_hz as f32 / 2.01, u[10]);
    c.faults.following_error_rev = log_between(1e-6, 1000.0, u[11]);
    c.torque_limit_pu = log_between(1e-5, 1000.0, u[12]);
    c.velocity_ff_gain = log_between(1e-6, 1.0, u[13]);
    c
}

/// `c` with the setting `param` (a key the refusal properties vary) at `v` (`encoder_cpr`:
/// its whole part); `None` for another key.
fn with_setting(c: &DriveConfig, param: &str, v: f32) -> Option<DriveConfig> {
    let mut d = *c;
    match param {
        "encoder_cpr" => d.encoder_cpr = v as u32,
        "velocity_bandwidth_rad_s" => d.velocity_bandwidth_rad_s = v,
        "current_bandwidth_rad_s" => d.current_bandwidth_rad_s = v,
        "position_bandwidth_rad_s" => d.position_bandwidth_rad_s = v,
        "observer.bandwidth_hz" => d.observer.bandwidth_hz = v,
        "accel_feedback.gain_fraction" => d.accel_feedback.gain_fraction = v,
        "accel_feedback.limit_headroom_fraction" => d.accel_feedback.limit_headroom_fraction = v,
        "faults.following_error_rev" => d.faults.following_error_rev = v,
        "faults.overcurrent_ratio" => d.faults.overcurrent_ratio = v,
        "faults.stall_torque_fraction" => d.faults.stall_torque_fraction = v,
        "torque_limit_pu" => d.torque_limit_pu = v,
        "velocity_ff_gain" => d.velocity_ff_gain = v,
        "accel_ff_gain" => d.accel_ff_gain = v,
        "motor_inertia_s" => d.motor_inertia_s = v,
        _ => return None,
    }
    Some(d)
}

/// The refusal properties' claim for the drive `c`: a refusal names a setting of the range
/// table, the user's key, never a derived coefficient; a refusal with a range given the
/// others (`OutOfRangeGiven`) has the value outside that range; and at the range's bottom
/// (when it is closed), its geometric middle and its top, exactly as stated and the rest
/// unchanged, the same key is not refused again. A bound worked out in f64 but not an f32,
/// or not rounded towards the inside, fails at the ends.
fn stated_range_holds(c: &DriveConfig) -> Result<(), TestCaseError> {
    use controller_core::ConfigError;
    use controller_core::ranges::range_of;
    let Err(e) = Controller::new(c) else {
        return Ok(());
    };
    let key = e.param();
    prop_assert!(
        range_of(key).is_some() || key == "velocity_rate_hz",
        "not a user's key: {e}"
    );
    prop_assert!(
        !matches!(
            e,
            ConfigError::CoefficientOverflow { .. } | ConfigError::CoefficientUnderflow { .. }
        ),
        "no range: {e}"
    );
    if let ConfigError::OutOfRangeGiven {
        param,
        value,
        min,
        max,
        min_exclusive,
        ..
    } = e
    {
        prop_assert!(!(min..=max).contains(&value), "{e}");
        if min > max {
            // No value fits: another setting has to change (e.g. a current loop too slow
            // for any velocity loop the gains can hold).
            return Ok(());
        }
        let middle = if min > 0.0 {
            (min * max).sqrt()
        } else {
            max / 2.0
        };
        let bottom = (!min_exclusive).then_some(min);
        for inside in [bottom, Some(middle), Some(max)].into_iter().flatten() {
            let Some(d) = with_setting(c, param, inside) else {
                return Ok(());
            };
            if let Err(again) = Controller::new(&d) {
                prop_assert!(again.param() != param, "{e}\nthen at {inside}: {again}");
            }
        }
        // The top is tight: the next value up is refused by the same key (the top is the
        // largest value whose coefficients fit, or the key's own or the Nyquist bound).
        // Not `encoder_cpr`: a whole number, stated rounded inwards to an f32 above 2^24.
        let up = max.next_up();
        if param != "encoder_cpr"
            && let Some(d) = with_setting(c, param, up)
            && Controller::new(&with_setting(c, param, max).unwrap_or(*c)).is_ok()
        {
            match Controller::new(&d) {
                Err(above) => prop_assert!(above.param() == param, "{e}\nabove: {above}"),
                Ok(_) => prop_assert!(false, "{e}\naccepted above the top, at {up}"),
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// Settings drawn across their stated ranges (by decades): every refusal states a range
    /// that holds ([`stated_range_holds`]).
    #[test]
    fn every_refusal_names_the_users_key_and_a_range_that_holds(
        u in proptest::collection::vec(0.0f64..=1.0, 14),
        cpr_bits in 2u32..=30, bits in 16u8..=32, ratio in 1u32..=16, mode in 0u8..3,
    ) {
        stated_range_holds(&drawn(&u, cpr_bits, bits, ratio, mode))?;
    }

    /// As above, on drives with one coefficient drawn across its format's top
    /// ([`past_a_top`]), where a top worked out in f64 could round onto the format's bound.
    #[test]
    fn every_refusal_past_a_format_s_top_states_a_range_that_holds(
        case in 0usize..7, u in proptest::collection::vec(0.0f64..=1.0, 4),
    ) {
        stated_range_holds(&past_a_top(case, &u))?;
    }
}

/// Table 1's drive with the coefficient of `case` drawn across its format's top by `u` (four
/// numbers in [0, 1]), the other settings chosen so that its check is the one that refuses:
/// 0 the velocity PI's Kp = ω·J and Ki·Ts = Kp·ω/(4ζ²·f) (Q16.16, Q8.24); 1 the current
/// PI's Kp = L·ω and Ki·Ts = R·ω/f; 2 the position gain ω/cpps (Q1.31); 3 the acceleration
/// feed-forward accel_ff_gain × (J_total + Ka) in the plain form; 4 the overcurrent level
/// ratio × torque_limit_pu; 5 the observer's torque scale Ts²·cpps/J_model (Q8.24, the top
/// of `encoder_cpr`); 6 the count scale 1/(cpps·Ts²) (Q16.16, the bottom of `encoder_cpr`).
fn past_a_top(case: usize, u: &[f64]) -> DriveConfig {
    use controller_core::{ObserverInertia, PiInertia};
    let mut c = common::table1();
    c.counter_bits = 32;
    match case {
        0 => {
            c.current_bandwidth_rad_s = 12_000.0;
            c.motor_inertia_s = log_between(1e-3, 1000.0, u[0]);
            c.velocity_bandwidth_rad_s = log_between(1.0, 6000.0, u[1]);
            c.velocity_damping = log_between(0.1, 10.0, u[2]);
        }
        1 => {
            c.winding_inductance_pu_s = log_between(1e-3, 100.0, u[0]);
            c.winding_resistance_pu = log_between(1e-3, 100.0, u[1]);
            c.current_bandwidth_rad_s = log_between(100.0, 12_000.0, u[2]);
        }
        2 => {
            (c.current_rate_hz, c.velocity_rate_hz) = (1000, 1000);
            c.encoder_cpr = 1 << (2 + (u[0] * 10.0) as u32);
            c.base_speed_rpm = log_between(1.0, 1000.0, u[1]);
            c.position_bandwidth_rad_s = log_between(1.0, 3000.0, u[2]);
        }
        3 => {
            c.accel_feedback.mode = AfbMode::Plain;
            c.velocity_pi_inertia = PiInertia::Total;
            c.velocity_bandwidth_rad_s = 0.01;
            // Ka just below Q16.16's top, so that J_total + Ka is near it too.
            c.motor_inertia_s = log_between(820.0, 1000.0, u[1]);
            c.load_inertia_s = log_between(820.0, 1000.0, u[2]);
            let ka = log_between(0.9 * 32_768.0, 0.999 * 32_768.0, u[0]);
            c.accel_feedback.gain_fraction = ka / c.total_inertia_s();
            c.accel_ff_gain = log_between(0.9, 1.0, u[3]);
        }
        4 => {
            c.torque_limit_pu = log_between(300.0, 1000.0, u[0]);
            c.faults.overcurrent_ratio = log_between(10.0, 100.0, u[1]);
        }
        5 => {
            c.observer.model_inertia = ObserverInertia::Motor;
            c.motor_inertia_s = log_between(1e-5, 1e-2, u[0]);
            c.encoder_cpr = 1 << (10 + (u[1] * 20.0) as u32);
            c.base_speed_rpm = log_between(1.0, 100_000.0, u[2]);
        }
        _ => {
            (c.current_rate_hz, c.velocity_rate_hz) = (20_000, 10_000);
            c.encoder_cpr = 1 << (2 + (u[0] * 14.0) as u32);
            c.base_speed_rpm = log_between(1.0, 100_000.0, u[1]);
        }
    }
    c
}

/// The range a refusal of `c` states for `accel_feedback.gain_fraction` (`None` when `c`
/// is not refused by that key).
fn gain_fraction_range(c: &DriveConfig) -> Option<(f32, f32)> {
    match Controller::new(c) {
        Err(controller_core::ConfigError::OutOfRangeGiven {
            param: "accel_feedback.gain_fraction",
            min,
            max,
            ..
        }) => Some((min, max)),
        _ => None,
    }
}

/// `c` with the gain fraction `v` is refused by the gain fraction's key.
fn gain_fraction_refused(c: &DriveConfig, v: f32) -> bool {
    let mut d = *c;
    d.accel_feedback.gain_fraction = v;
    matches!(Controller::new(&d), Err(e) if e.param() == "accel_feedback.gain_fraction")
}

/// The refusal property's saved case (proptest-regressions/properties.txt): a light drive
/// (J_total ≈ 1.3·10⁻⁴) whose gain fraction 10⁻⁶ is refused. Ka alone fits from 5.90 on,
/// but the closed form's Ka/(1 + b0·Ka/J_model), which grows more slowly, only from 16.0:
/// the stated range starts there (it stated 5.90, and its middle 10.86 was refused again),
/// and holds at both ends and in the middle.
#[test]
fn the_gain_fraction_s_range_starts_where_the_closed_form_fits() {
    let u = [
        0.674_476_949_429_625_7,
        0.641_370_973_763_548,
        0.117_474_319_121_645_01,
        0.078_170_385_355_133_03,
        0.637_496_501_385_698_2,
        0.678_082_186_914_914_6,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.979_525_479_847_579_9,
        0.0,
    ];
    let c = drawn(&u, 6, 16, 1, 1);
    let (min, max) = gain_fraction_range(&c).unwrap();
    assert!(min > 16.0 && min < 16.1 && max == 20.0, "[{min}, {max}]");
    for v in [min, (min * max).sqrt(), max] {
        assert!(!gain_fraction_refused(&c, v), "{v} in [{min}, {max}]");
    }
    // The old range's middle is refused: it lies below the range now.
    assert!(gain_fraction_refused(&c, 10.864_952));
    // And the range is not loose. Quantizing keeps 1 % down to about 49.5 steps (with
    // gaps below 50, where a value half a step off is refused), and the closed form moves
    // by 1/(1 + b·Ka) = 0.37 of the gain fraction's change here: within 1 %/0.37 = 2.7 %
    // below the bottom, some value is refused.
    let mut v = min;
    let mut refused_below = None;
    for _ in 0..300 {
        v *= 0.9999;
        if gain_fraction_refused(&c, v) {
            refused_below = Some(v);
            break;
        }
    }
    assert!(refused_below.is_some(), "none refused from {v} to {min}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]

    /// Whatever derives from the gain fraction (Ka, with the observer the closed form's gain
    /// through the AFB filter's feed-through b0 and the model inertia), the range a refusal
    /// states holds at its bottom, its top and its middle. `heavy` draws inertias near the
    /// top of their ranges, where Ka = gain_fraction × J_total reaches Q16.16's top.
    #[test]
    fn the_gain_fraction_s_stated_range_holds_at_both_ends(
        motor in 0.0f64..=1.0, load in 0.0f64..=1.0, heavy: bool, fraction in 0.0f64..=1.0,
        observer: bool, motor_model: bool, error_form: bool, filter in 0u8..3,
        corner in 0.0f64..=1.0,
    ) {
        use controller_core::ObserverInertia;
        let mut c = common::table1();
        let (lo, hi) = if heavy { (800.0, 1000.0) } else { (1e-5, 1000.0) };
        c.motor_inertia_s = log_between(lo, hi, motor);
        c.load_inertia_s = log_between(lo, hi, load);
        if heavy {
            // A velocity loop slow enough for the velocity PI's Kp = ω·J_total·(1 + fraction)
            // to fit: otherwise its bandwidth is refused first.
            c.velocity_bandwidth_rad_s = 0.5;
        }
        c.accel_feedback.mode = if error_form { AfbMode::Error } else { AfbMode::Plain };
        c.accel_feedback.rate = AfbRate::Current;
        c.accel_feedback.source = if observer { Estimator::Observer } else { Estimator::Differentiation };
        c.observer.model_inertia = if motor_model { ObserverInertia::Motor } else { ObserverInertia::Total };
        let corner_hz = log_between(1.0, 0.49 * c.current_rate_hz as f32, corner);
        c.accel_feedback.filter = match filter {
            0 => FilterConfig::None,
            1 => FilterConfig::FirstOrder { corner_hz },
            _ => FilterConfig::SecondOrder { corner_hz, q: 0.7 },
        };
        c.accel_feedback.gain_fraction = log_between(1e-6, 20.0, fraction);
        if let Some((min, max)) = gain_fraction_range(&c) {
            prop_assert!(!(min..=max).contains(&c.accel_feedback.gain_fraction), "[{min}, {max}]");
            if min <= max {
                for v in [min, (min * max).sqrt(), max] {
                    prop_assert!(!gain_fraction_refused(&c, v), "{v} in [{min}, {max}]");
                }
            }
        }
    }
}

/// The range a refusal of `c` states for `key`: `Some((min, max))` when `c` is refused by
/// that key with a range given the others.
fn stated(c: &DriveConfig, key: &str) -> Option<(f32, f32)> {
    match Controller::new(c) {
        Err(controller_core::ConfigError::OutOfRangeGiven {
            param, min, max, ..
        }) if param == key => Some((min, max)),
        _ => None,
    }
}

/// Three stated ends worked out from a formula, each exact: the gain fraction's top where
/// Ka's top over J_total is an f32 (J_total = 1687 divides 2^24 − 1: 19.423828 exactly),
/// the acceleration feed-forward's top in the plain form (32768 / (J_total + Ka)), and the
/// motor inertia's bottom where the observer's model inertia keeps 1 % in Q16.16.
#[test]
fn stated_ends_worked_out_from_a_formula_are_exact() {
    use controller_core::{AfbMode, Estimator, ObserverInertia, PiInertia};
    let accepted = |c: &DriveConfig| Controller::new(c).is_ok();
    // Gain fraction: Ka = f × 1687 must stay at or below 2^15 − 2^−9.
    let mut c = common::table1();
    (c.motor_inertia_s, c.load_inertia_s) = (1000.0, 687.0);
    c.velocity_bandwidth_rad_s = 0.01;
    c.accel_feedback.source = Estimator::Differentiation;
    c.accel_feedback.gain_fraction = 20.0;
    let (_, max) = stated(&c, "accel_feedback.gain_fraction")
        .unwrap_or_else(|| panic!("{:?}", Controller::new(&c).err()));
    assert_eq!(max, 19.423_828, "{max}");
    c.accel_feedback.gain_fraction = max;
    assert!(accepted(&c));
    // J_total = 1640.36: the largest f32 at or below 32768 / J_total times J_total rounds
    // to 32768 in f32, which Q16.16 does not hold; the stated top is taken against
    // 2^15 − 2^−9 instead and holds.
    c.load_inertia_s = 640.36;
    c.accel_feedback.gain_fraction = 20.0;
    let (_, max) = stated(&c, "accel_feedback.gain_fraction").expect("refused");
    c.accel_feedback.gain_fraction = max;
    assert!(accepted(&c), "{max}");
    // Acceleration feed-forward, plain form: 1 × (2000 + 31500) does not fit Q16.16.
    let mut c = common::table1();
    c.accel_feedback.mode = AfbMode::Plain;
    c.velocity_pi_inertia = PiInertia::Total;
    c.velocity_bandwidth_rad_s = 0.01;
    (c.motor_inertia_s, c.load_inertia_s) = (1000.0, 1000.0);
    c.accel_feedback.gain_fraction = 15.75;
    c.accel_ff_gain = 1.0;
    let (_, max) = stated(&c, "accel_ff_gain").expect("refused");
    let want = 32_768.0 / 33_500.0;
    assert!(
        (f64::from(max) / want - 1.0).abs() < 1e-4,
        "{max} against {want}"
    );
    c.accel_ff_gain = max;
    assert!(accepted(&c));
    c.accel_ff_gain = max.next_up();
    assert!(!accepted(&c));
    // Motor inertia with the motor-inertia observer: J_model = 20.5 steps of Q16.16 rounds
    // by 2.4 %; the stated bottom is where every value keeps 1 % (50 steps, 7.63e-4 s).
    let mut c = common::table1();
    c.observer.model_inertia = ObserverInertia::Motor;
    c.motor_inertia_s = 20.5 / 65_536.0;
    let (min, _) =
        stated(&c, "motor_inertia_s").unwrap_or_else(|| panic!("{:?}", Controller::new(&c).err()));
    assert!(
        (f64::from(min) * 65_536.0 / 50.0 - 1.0).abs() < 1e-3,
        "{min}"
    );
    c.motor_inertia_s = min;
    assert!(accepted(&c), "{min}");
}
