//! Each block against an f64 reference with stated tolerances.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use crate::common;
use controller_core::differentiator::{Differentiator, DifferentiatorState};
use controller_core::filter::{LowPass, LowPassDesign, LowPassState, design_low_pass};
use controller_core::observer::{Observer, ObserverState};
use controller_core::per_unit::{Coef, Gain, Pu, TickGain};
use controller_core::pi::{PiCoefficients, PiState};
use controller_core::ranges::{AFB_FILTER_CORNER_HZ as AFB_CORNER, AFB_FILTER_Q as AFB_Q};
use controller_core::{DriveConfig, FilterConfig, Profile, ProfileConfig, ProfileKind, design};

/// Deterministic pseudo-random numbers in [−1, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// PI against f64 (unsaturated): |u − u_ref| ≤ 2e-4 pu over 5000 random steps.
#[test]
fn pi_matches_f64_reference() {
    let (kp, ki_ts, limit) = (3.7f64, 0.013f64, 100.0f64);
    let c = PiCoefficients {
        kp: Gain::from_num(kp),
        ki_ts: TickGain::from_num(ki_ts),
        limit: Pu::from_num(limit),
    };
    let (kp, ki_ts) = (c.kp.to_num::<f64>(), c.ki_ts.to_num::<f64>());
    let mut s = PiState::default();
    let mut i_ref = 0.0f64;
    let mut rng = Lcg(1);
    let mut worst = 0.0f64;
    for _ in 0..5000 {
        let e = Pu::from_num(rng.next() * 0.5 + 0.01);
        let ef = e.to_num::<f64>();
        i_ref += ki_ts * ef;
        let u_ref = kp * ef + i_ref;
        let u = c.update(&mut s, e, Pu::ZERO).to_num::<f64>();
        worst = worst.max((u - u_ref).abs());
    }
    println!("PI worst error {worst:e} pu");
    assert!(worst <= 2e-4, "{worst}");
}

/// Saturation and anti-windup: the output never exceeds the limit, the integral never
/// exceeds it either, and the output leaves saturation on the first reversed error.
#[test]
fn pi_saturates_and_does_not_wind_up() {
    let c = PiCoefficients {
        kp: Gain::from_num(2),
        ki_ts: TickGain::from_num(0.05),
        limit: Pu::from_num(1.5),
    };
    let mut s = PiState::default();
    for _ in 0..10_000 {
        let u = c.update(&mut s, Pu::from_num(1), Pu::ZERO);
        assert!(u <= c.limit);
    }
    assert!(s.saturated);
    assert!(s.integral.to_num::<f64>() <= 1.5 + 1e-9);
    let u = c.update(&mut s, Pu::from_num(-0.1), Pu::ZERO);
    assert!(u < c.limit, "still saturated after reversal: {u}");
    // Negative side, with feed-forward pushing into the limit.
    let mut s = PiState::default();
    for _ in 0..10_000 {
        let u = c.update(&mut s, Pu::from_num(-3), Pu::from_num(-1));
        assert!(u >= -c.limit);
    }
    assert!(s.integral.to_num::<f64>() >= -1.5 - 1e-9);
}

fn run_filter(d: &LowPassDesign, inputs: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let q = LowPass::quantize(d, "test").unwrap();
    let mut s = LowPassState::default();
    let fixed: Vec<f64> = inputs
        .iter()
        .map(|&x| q.process(&mut s, Pu::from_num(x)).to_num::<f64>())
        .collect();
    // f64 reference with the same (quantized) coefficients.
    let mut reference = Vec::new();
    match q {
        LowPass::None => reference.extend_from_slice(inputs),
        LowPass::FirstOrder { alpha } => {
            let a = alpha.to_num::<f64>();
            let mut y = 0.0;
            for &x in inputs {
                let x = Pu::from_num(x).to_num::<f64>();
                y += a * (x - y);
                reference.push(y);
            }
        }
        LowPass::SecondOrder { b0, a1, a2 } => {
            let (b0, a1, a2) = (b0.to_num::<f64>(), a1.to_num::<f64>(), a2.to_num::<f64>());
            let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
            for &x in inputs {
                let x = Pu::from_num(x).to_num::<f64>();
                let y = b0 * (x + 2.0 * x1 + x2) - a1 * y1 - a2 * y2;
                x2 = x1;
                x1 = x;
                y2 = y1;
                y1 = y;
                reference.push(y);
            }
        }
    }
    (fixed, reference)
}

/// Filters against f64: first order |e| ≤ 5e-5 pu, biquad |e| ≤ 2e-4 pu (random input of
/// ±1 pu and a step), and the designed corner has the −3 dB gain within 1 %.
#[test]
fn filters_match_f64_reference() {
    let mut rng = Lcg(7);
    let mut inputs: Vec<f64> = (0..4000).map(|_| rng.next()).collect();
    inputs.extend(std::iter::repeat_n(0.75, 4000));
    for (cfg, tol) in [
        (FilterConfig::FirstOrder { corner_hz: 5.0 }, 5e-5),
        (FilterConfig::FirstOrder { corner_hz: 100.0 }, 5e-5),
        (
            FilterConfig::SecondOrder {
                corner_hz: 20.0,
                q: 0.707,
            },
            2e-4,
        ),
        (
            FilterConfig::SecondOrder {
                corner_hz: 300.0,
                q: 2.0,
            },
            2e-4,
        ),
    ] {
        let d = design_low_pass(&cfg, 4000.0, &AFB_CORNER, &AFB_Q).unwrap();
        let (fx, rf) = run_filter(&d, &inputs);
        let worst = fx
            .iter()
            .zip(&rf)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        println!("{cfg:?}: worst {worst:e}");
        assert!(worst <= tol, "{cfg:?}: {worst}");
        // Step settles exactly (no dead band): the last output equals the input to 2 LSB.
        // (4 LSB: the biquad's recursion at a low corner may park a couple of LSB off.)
        assert!(
            (fx.last().unwrap() - 0.75).abs() <= 6.2e-5,
            "{cfg:?} settles at {}",
            fx.last().unwrap()
        );
    }
    // Magnitude at the corner of the biquad (Butterworth: −3.01 dB) from the f32 design.
    let d = design_low_pass(
        &FilterConfig::SecondOrder {
            corner_hz: 100.0,
            q: std::f32::consts::FRAC_1_SQRT_2,
        },
        4000.0,
        &AFB_CORNER,
        &AFB_Q,
    )
    .unwrap();
    if let LowPassDesign::SecondOrder { b0, a1, a2 } = d {
        let w = std::f64::consts::TAU * 100.0 / 4000.0;
        let (b0, a1, a2) = (f64::from(b0), f64::from(a1), f64::from(a2));
        let num = |re: f64, im: f64| (re * re + im * im).sqrt();
        let (c1, s1, c2, s2) = (w.cos(), w.sin(), (2.0 * w).cos(), (2.0 * w).sin());
        let n = num(b0 * (1.0 + 2.0 * c1 + c2), -b0 * (2.0 * s1 + s2));
        let den = num(1.0 + a1 * c1 + a2 * c2, -(a1 * s1 + a2 * s2));
        let g = n / den;
        assert!(
            (g - std::f64::consts::FRAC_1_SQRT_2).abs() < 0.01 * std::f64::consts::FRAC_1_SQRT_2,
            "gain {g}"
        );
    }
}

/// Differentiator against f64: velocity = Δcounts·k_vel and acceleration = Δ²counts·k_acc
/// to 1e-6 relative plus 1 LSB; one count at Table 1 is 0.0293 pu and 58.6 pu/s.
#[test]
fn differentiator_matches_f64_and_shows_quantization() {
    let g = design(&common::table1()).unwrap();
    let d = Differentiator {
        k_vel: TickGain::from_num(g.vel_tick_pu_per_count),
        k_acc: Gain::from_num(g.vel_tick_pu_s_per_count),
    };
    assert!((g.vel_tick_pu_per_count - 0.029_297).abs() < 1e-5);
    assert!((g.vel_tick_pu_s_per_count - 58.59).abs() < 0.01);
    let mut s = DifferentiatorState::default();
    let mut rng = Lcg(3);
    let mut p = 0i64;
    let mut last_delta = 0i64;
    d.update(&mut s, p);
    for k in 0..3000 {
        let delta = (rng.next() * 40.0) as i64;
        p += delta;
        let (v, a) = d.update(&mut s, p);
        let v_ref = delta as f64 * d.k_vel.to_num::<f64>();
        assert!(
            (v.to_num::<f64>() - v_ref).abs() <= 1e-6 * v_ref.abs() + 2e-5,
            "v {k}"
        );
        if k > 0 {
            let a_ref = (delta - last_delta) as f64 * d.k_acc.to_num::<f64>();
            assert!(
                (a.to_num::<f64>() - a_ref).abs() <= 1e-6 * a_ref.abs() + 2e-5,
                "a {k}"
            );
        }
        last_delta = delta;
    }
}

fn observer_from_table1(cfg: &DriveConfig) -> (Observer, controller_core::Gains) {
    let g = design(cfg).unwrap();
    let o = Observer {
        l1: Coef::from_num(g.observer_l[0]),
        l2: Coef::from_num(g.observer_l[1]),
        l3: Coef::from_num(g.observer_l[2]),
        k_u: TickGain::from_num(g.observer_k_u),
        k_vel: TickGain::from_num(g.cur_tick_pu_per_count),
        k_acc: Gain::from_num(g.cur_tick_pu_s_per_count),
        k_load: Gain::from_num(-g.observer_inertia_s),
        count_interval: controller_core::observer::CountInterval::PLAIN,
    };
    (o, g)
}

/// The observer gains place all three poles at θ: det(zI − (I − L·C)·A) = (z − θ)³.
#[test]
fn observer_poles_are_where_designed() {
    for f_obs in [20.0f32, 75.0, 150.0, 500.0] {
        let mut cfg = common::table1();
        cfg.observer.bandwidth_hz = f_obs;
        let g = design(&cfg).unwrap();
        let [l1, l2, l3] = g.observer_l.map(f64::from);
        let th = f64::from(g.observer_pole);
        // A = [[1,1,1/2],[0,1,1],[0,0,1]], C·A = [1,1,1/2]; M = A − L·(C·A).
        let a = [[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]];
        let l = [l1, l2, l3];
        let ca = [1.0, 1.0, 0.5];
        let mut m = [[0.0f64; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = a[i][j] - l[i] * ca[j];
            }
        }
        for z in [0.0, 0.3, -1.0, 2.0] {
            let b = |i: usize, j: usize| if i == j { z - m[i][j] } else { -m[i][j] };
            let det = b(0, 0) * (b(1, 1) * b(2, 2) - b(1, 2) * b(2, 1))
                - b(0, 1) * (b(1, 0) * b(2, 2) - b(1, 2) * b(2, 0))
                + b(0, 2) * (b(1, 0) * b(2, 1) - b(1, 1) * b(2, 0));
            let want = (z - th).powi(3);
            assert!(
                (det - want).abs() < 1e-5,
                "f_obs {f_obs} z {z}: {det} vs {want}"
            );
        }
    }
}

/// Fixed-point observer against the same observer in f64 fed with the same quantized
/// counts and torque: velocity within 2e-4 pu, acceleration within 0.05 pu/s. Against the
/// true rigid-body motion (model inertia right, 0.3 pu load), after settling: RMS velocity
/// error ≤ 0.005 pu (one count per current tick is 0.0146 pu) and the mean load estimate
/// within 0.01 pu (its count-quantization noise is ±0.1 pu at 75 Hz and 4096 CPR).
#[test]
fn observer_matches_f64_reference_and_tracks_a_rigid_body() {
    let mut cfg = common::table1();
    cfg.observer.model_inertia = controller_core::ObserverInertia::Total;
    let (o, g) = observer_from_table1(&cfg);
    let j = f64::from(g.observer_inertia_s);
    let ts = 1.0 / 4000.0;
    let cpps = 4096.0 * 1000.0 / 60.0;
    let (l1, l2, l3) = (
        o.l1.to_num::<f64>(),
        o.l2.to_num::<f64>(),
        o.l3.to_num::<f64>(),
    );
    let k_u = o.k_u.to_num::<f64>();
    let mut s = ObserverState::default();
    let (mut p, mut v, mut d) = (0.0f64, 0.0f64, 0.0f64);
    let (mut theta_pu_s, mut w) = (0.0f64, 0.0f64);
    let load = 0.3;
    let mut worst_v = 0.0f64;
    let mut worst_a = 0.0f64;
    let (mut v_sq, mut load_sum, mut n) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..16_000 {
        let t = k as f64 * ts;
        let torque = Pu::from_num(0.5 + 0.8 * (t * 9.0).sin());
        let tq = torque.to_num::<f64>();
        // Plant over one tick with the torque of the previous tick.
        let counts = (theta_pu_s * cpps).floor() as i64;
        o.update(&mut s, counts, torque_prev(k, tq));
        let est = o.estimate(&s);
        // f64 reference observer.
        if k == 0 {
            p = counts as f64;
        }
        let u = torque_prev(k, tq).to_num::<f64>() * k_u;
        let acc = u + d;
        let pp = p + v + acc / 2.0;
        let vp = v + acc;
        let e = counts as f64 - pp;
        p = pp + l1 * e;
        v = vp + l2 * e;
        // Ellis: â = v[n] − v[n−1] = u + d⁻ + l2·e.
        let a_ref = (u + d + l2 * e) / (cpps * ts * ts);
        d += l3 * e;
        let v_ref = v / (cpps * ts);
        worst_v = worst_v.max((est.velocity_pu.to_num::<f64>() - v_ref).abs());
        worst_a = worst_a.max((est.acceleration_pu_s.to_num::<f64>() - a_ref).abs());
        if k > 8000 {
            let ev = est.velocity_pu.to_num::<f64>() - w;
            v_sq += ev * ev;
            load_sum += est.load_torque_pu.to_num::<f64>();
            n += 1.0;
        }
        // True rigid body, exact for constant torque over the tick.
        let a_true = (tq - load) / j;
        theta_pu_s += w * ts + a_true * ts * ts / 2.0;
        w += a_true * ts;
    }
    println!("observer: worst |v − v_f64| = {worst_v:e} pu, |a − a_f64| = {worst_a:e} pu/s");
    let v_rms = (v_sq / n).sqrt();
    let load_mean = load_sum / n;
    println!(
        "observer vs rigid body: velocity RMS error {v_rms:e} pu, mean load {load_mean} pu (true {load})"
    );
    assert!(v_rms < 0.005, "{v_rms}");
    assert!((load_mean - load).abs() < 0.01, "{load_mean}");
    assert!(worst_v < 2e-4, "{worst_v}");
    assert!(worst_a < 0.05, "{worst_a}");
}

/// The torque that acted over the tick before sample k (the observer's input convention).
fn torque_prev(k: usize, _tq: f64) -> Pu {
    if k == 0 {
        return Pu::ZERO;
    }
    let t = (k - 1) as f64 / 4000.0;
    Pu::from_num(0.5 + 0.8 * (t * 9.0).sin())
}

/// Profiles against their continuous-time definition sampled at the velocity ticks:
/// position within 0.01 counts, velocity within 2e-5 pu, acceleration within 1e-3 pu/s.
#[test]
fn profiles_match_f64_reference() {
    let drive = common::table1();
    let cpps = 4096.0 * 1000.0 / 60.0;
    let ts = 1.0 / 2000.0;
    for kind in [
        ProfileKind::Trapezoid,
        ProfileKind::SCurve { jerk_time_s: 0.1 },
    ] {
        let cfg = ProfileConfig {
            kind,
            peak_velocity_pu: 0.8,
            accel_time_s: 0.5,
            hold_time_s: 0.3,
            decel_time_s: 0.4,
            start_delay_s: 0.05,
        };
        let mut prof = Profile::new(&cfg, &drive).unwrap();
        let tj = match kind {
            ProfileKind::Trapezoid => 0.0,
            ProfileKind::SCurve { jerk_time_s } => f64::from(jerk_time_s),
        };
        // Acceleration as a function of time, integrated by fine steps for the reference.
        let accel = |t: f64| -> f64 {
            let ramp = |t: f64, dur: f64, peak: f64| -> f64 {
                if t < 0.0 || t >= dur {
                    0.0
                } else if tj == 0.0 {
                    peak
                } else if t < tj {
                    peak * t / tj
                } else if t < dur - tj {
                    peak
                } else {
                    peak * (dur - t) / tj
                }
            };
            let a_peak = 0.8 / (0.5 - tj);
            let d_peak = 0.8 / (0.4 - tj);
            ramp(t - 0.05, 0.5, a_peak) - ramp(t - 0.85, 0.4, d_peak)
        };
        let sub = 200;
        let h = ts / f64::from(sub);
        let (mut v, mut p) = (0.0f64, 0.0f64);
        let (mut wp, mut wv, mut wa) = (0.0f64, 0.0f64, 0.0f64);
        for k in 0..3000 {
            let t = k as f64 * ts;
            let sp = prof.next();
            let a_ref = accel(t + 1e-9);
            let edge = (t - 0.05).abs() < 1e-9
                || (t - 0.55).abs() < 1e-9
                || (t - 0.85).abs() < 1e-9
                || (t - 1.25).abs() < 1e-9;
            wp = wp.max((sp.position_counts.to_num::<f64>() - p * cpps).abs());
            wv = wv.max((sp.velocity_pu.to_num::<f64>() - v).abs());
            if !edge {
                wa = wa.max((sp.acceleration_pu_s.to_num::<f64>() - a_ref).abs());
            }
            for i in 0..sub {
                // Midpoint rule on a, trapezoid on v.
                let tm = t + (f64::from(i) + 0.5) * h;
                let a = accel(tm);
                p += v * h + a * h * h / 2.0;
                v += a * h;
            }
        }
        println!(
            "{kind:?}: worst position {wp:e} counts, velocity {wv:e} pu, acceleration {wa:e} pu/s"
        );
        assert!(wp < 0.01, "{kind:?} position {wp}");
        assert!(wv < 2e-5, "{kind:?} velocity {wv}");
        assert!(wa < 1e-3, "{kind:?} acceleration {wa}");
        assert!(prof.is_done());
    }
}

/// A reverse move from a fractional start position lands where the f64 kinematics say:
/// start − v·(t_a/2 + t_h + t_d/2)·counts_per_pu_s, within 0.01 counts, and then holds.
#[test]
fn reverse_profile_from_a_start_position() {
    let drive = common::table1();
    let cpps = 4096.0 * 1000.0 / 60.0;
    let cfg = ProfileConfig {
        kind: ProfileKind::SCurve { jerk_time_s: 0.05 },
        peak_velocity_pu: -0.5,
        accel_time_s: 0.2,
        hold_time_s: 0.25,
        decel_time_s: 0.3,
        start_delay_s: 0.0,
    };
    let start = controller_core::Counts::from_num(-1234.5);
    let mut prof = Profile::new(&cfg, &drive)
        .unwrap()
        .with_start_position(start);
    assert_eq!(prof.next().position_counts, start);
    let mut last = start;
    for _ in 0..2000 {
        last = prof.next().position_counts;
    }
    let want = -1234.5 - 0.5 * (0.1 + 0.25 + 0.15) * cpps;
    println!("reverse profile end {last} want {want}");
    assert!(
        (last.to_num::<f64>() - want).abs() < 0.01,
        "{last} vs {want}"
    );
    assert_eq!(prof.next().velocity_pu, Pu::ZERO);
}
