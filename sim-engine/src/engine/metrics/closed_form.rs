//! The metrics against closed forms: a rigid inertia under a PI regulator with a load
//! step, a damped second-order ring, and a tone with quantization.

#![allow(clippy::unwrap_used, clippy::indexing_slicing)]
use super::*;
use std::f64::consts::PI;

const STEP_S: f64 = 0.2;

fn windows(end: f64) -> MetricWindows {
    MetricWindows {
        step_time_s: Some(STEP_S),
        step_end_s: None,
        ramp_end_s: None,
        ripple_window_s: (STEP_S + 0.1, end),
        overshoot_window_s: None,
        stable_window_s: (end - 0.5, end),
        ripple_average_s: 0.1,
        settle_band_pu: 0.0,
        stable_oscillation_pu: 0.02,
        stable_saturation_fraction: 0.2,
        torque_limit_pu: 2.0,
        machine: None,
        excitation_hz: None,
    }
}

/// J·dω/dt = Kp·e + Ki·∫e − T_L, e = ω* − ω, a load step T_L at `STEP_S`; Kp = 2·J·ωn,
/// Ki = J·ωn² (critically damped). Then e(t) = (T_L/J)·t·e^(−ωn·t) from the step: the peak
/// T_L/(J·ωn·e) at t = 1/ωn, and |e| falls under 10 % of it at ωn·t = u with u·e^(−u) =
/// 0.1/e, u > 1.
#[test]
fn a_rigid_inertia_under_a_pi_has_the_analytic_droop_its_time_and_recovery() {
    let (j, wn, tl, dt) = (0.5, 20.0, 0.5, 1e-5);
    let (kp, ki) = (2.0 * j * wn, j * wn * wn);
    let (mut w, mut integral) = (1.0, 0.0);
    let mut rows = Vec::new();
    for k in 0..120_000 {
        let t = k as f64 * dt;
        let load = if t >= STEP_S { tl } else { 0.0 };
        let e = 1.0 - w;
        rows.push(TraceRow {
            t_s: t,
            vel_cmd_pu: 1.0,
            motor_vel_pu: w,
            load_torque_pu: load,
            current_pu: kp * e + ki * integral,
            ..Default::default()
        });
        // Exact for the error's linear dynamics to O(dt²): midpoint of the step.
        let torque = |w: f64, i: f64| kp * (1.0 - w) + ki * i - load;
        let (w_mid, i_mid) = (
            w + 0.5 * dt * torque(w, integral) / j,
            integral + 0.5 * dt * e,
        );
        w += dt * torque(w_mid, i_mid) / j;
        integral += dt * (1.0 - w_mid);
    }
    let end = rows.last().unwrap().t_s;
    let m = compute(&Trace { rows }, &windows(end));
    let peak = tl / (j * wn * std::f64::consts::E);
    let mut lo_hi = (1.0, 20.0);
    let f = |u: f64| u * (-u).exp() - 0.1 / std::f64::consts::E;
    for _ in 0..100 {
        let mid = 0.5 * (lo_hi.0 + lo_hi.1);
        lo_hi = if f(mid) > 0.0 {
            (mid, lo_hi.1)
        } else {
            (lo_hi.0, mid)
        };
    }
    let recovery = lo_hi.0 / wn;
    let close = |got: f64, want: f64| (got / want - 1.0).abs() < 0.01;
    let (d, td, r) = (
        m.peak_droop_pu.unwrap(),
        m.peak_droop_time_s.unwrap(),
        m.recovery_s.unwrap(),
    );
    assert!(close(d, peak), "droop {d} vs {peak}");
    assert!(close(td, 1.0 / wn), "time {td} vs {}", 1.0 / wn);
    assert!(close(r, recovery), "recovery {r} vs {recovery}");
    // The settling band is 5 % of the peak: u·e^(−u) = 0.05/e, later than the recovery.
    assert!(m.settling_s.unwrap() > r, "{m:?}");
}

/// Shaft torque T_L·(1 − e^(−ζωn·t)(cos ωd·t + ζωn/ωd·sin ωd·t)) after a step: the
/// coupling's second-order ring. Its frequency ωd/2π and ζ come back from the metrics.
#[test]
fn a_damped_second_order_ring_has_its_frequency_and_damping() {
    let (fn_hz, zeta, dt): (f64, f64, f64) = (24.0, 0.05, 1e-4);
    let wn = 2.0 * PI * fn_hz;
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    let rows: Vec<TraceRow> = (0..20_000)
        .map(|k| {
            let t = k as f64 * dt;
            let s = (t - STEP_S).max(0.0);
            let env = (-zeta * wn * s).exp();
            TraceRow {
                t_s: t,
                shaft_torque_pu: 0.5
                    * (1.0 - env * ((wd * s).cos() + zeta * wn / wd * (wd * s).sin())),
                ..Default::default()
            }
        })
        .collect();
    let end = rows.last().unwrap().t_s;
    let m = compute(&Trace { rows }, &windows(end));
    let (f, z) = (m.shaft_ring_freq_hz.unwrap(), m.shaft_ring_damping.unwrap());
    let fd = wd / (2.0 * PI);
    assert!((f / fd - 1.0).abs() < 0.01, "ring {f} Hz vs {fd}");
    assert!((z / zeta - 1.0).abs() < 0.05, "damping {z} vs {zeta}");
    assert!(
        (m.peak_shaft_torque_pu.unwrap()
            - 0.5 * (1.0 + (-PI * zeta / (1.0 - zeta * zeta).sqrt()).exp()))
        .abs()
            < 1e-3
    );
    assert!((m.shaft_ripple_freq_hz - fd).abs() < 1.0, "{m:?}");
}

/// Motor torque of the stability window: `mean + chatter`, at 2 kHz, 1 pu speed; the
/// machine's count-rate tone at 68 266.7 counts/s is 266.7 Hz.
fn torque_run(chatter: impl Fn(f64) -> f64) -> Metrics {
    torque_run_with(None, chatter)
}

/// [`torque_run`] of a scenario that injects a sine load at `excitation_hz`.
fn torque_run_with(excitation_hz: Option<f64>, chatter: impl Fn(f64) -> f64) -> Metrics {
    let rows: Vec<TraceRow> = (0..5000)
        .map(|k| {
            let t = k as f64 * 5e-4;
            TraceRow {
                t_s: t,
                vel_cmd_pu: 1.0,
                motor_vel_pu: 1.0,
                current_pu: 0.5 + chatter(t),
                torque_cmd_pu: 0.5 + chatter(t),
                ..Default::default()
            }
        })
        .collect();
    let mut w = windows(rows.last().unwrap().t_s);
    w.machine = Some(MachineBands {
        counts_per_s_per_pu: 1000.0 / 60.0 * 4096.0,
        velocity_bandwidth_hz: 15.0,
        resonance_band_hz: (15.0, 90.0),
    });
    w.excitation_hz = excitation_hz;
    compute(&Trace { rows }, &w)
}

/// The quantization step of a tone's torque: the error of a count rounded at each sample.
fn quantized(x: f64, lsb: f64) -> f64 {
    (x / lsb).round() * lsb
}

#[test]
fn chatter_at_the_count_rate_tone_is_quantization_and_stable() {
    // A sawtooth at the tone (the fractional count of each sample), 0.2 pu peak to peak.
    let m = torque_run(|t| 0.2 * ((266.666_67 * t).fract() - 0.5));
    let o = &m.oscillation;
    assert_eq!(o.kind, OscillationKind::Quantization, "{o:?}");
    assert!((o.freq_hz - 266.67).abs() < 3.0 && m.stable, "{o:?}");
    assert!((o.tone_hz.unwrap() - 266.67).abs() < 0.1, "{o:?}");
}

#[test]
fn a_tone_off_the_count_rate_with_quantization_is_a_limit_cycle() {
    // ±1 pu at 178 Hz, read through a current ADC of 4 pu / 2048, plus the tone's sawtooth.
    let m = torque_run(|t| {
        quantized((2.0 * PI * 178.0 * t).sin(), 4.0 / 2048.0)
            + 0.05 * ((266.666_67 * t).fract() - 0.5)
    });
    let o = &m.oscillation;
    assert_eq!(o.kind, OscillationKind::LimitCycle, "{o:?}");
    assert!((o.freq_hz - 178.0).abs() < 1.0 && !m.stable, "{o:?}");
    assert!(o.narrowband_fraction > 0.9, "{o:?}");
    // The same tone too small to matter is quantization-sized chatter: stable.
    let small = torque_run(|t| 0.04 * (2.0 * PI * 178.0 * t).sin());
    assert!(small.stable, "{:?}", small.oscillation);
    // And a growing one diverges.
    let grow = torque_run(|t| 0.05 * (4.0 * t).exp() * (2.0 * PI * 178.0 * t).sin());
    assert_eq!(grow.oscillation.kind, OscillationKind::Diverging);
}

#[test]
fn an_injected_sine_is_not_an_oscillation_but_one_riding_on_it_is() {
    let fx = 47.0;
    let forced = |t: f64| 0.5 * (2.0 * PI * fx * t + 0.3).sin();
    // Not knowing the excitation, ±0.5 pu narrowband off the count-rate tone is a limit cycle.
    let blind = torque_run(forced);
    assert_eq!(blind.oscillation.kind, OscillationKind::LimitCycle);
    // Knowing it, the forced response is taken out: nothing is left.
    let m = torque_run_with(Some(fx), forced);
    let o = &m.oscillation;
    assert_eq!(o.kind, OscillationKind::None, "{o:?}");
    assert!(m.stable && o.amplitude_pu < 1e-6, "{o:?}");
    assert_eq!(o.excitation_hz, Some(fx));
    // Its harmonics are the forced response too (a sine through the lost motion).
    let harmonic = torque_run_with(Some(fx), |t| {
        forced(t) + 0.2 * (2.0 * PI * 2.0 * fx * t).sin()
    });
    assert_eq!(harmonic.oscillation.kind, OscillationKind::None);
    // A limit cycle riding on the forced response is still found, at its own frequency.
    let both = torque_run_with(Some(fx), |t| forced(t) + 0.3 * (2.0 * PI * 178.0 * t).sin());
    let o = &both.oscillation;
    assert_eq!(o.kind, OscillationKind::LimitCycle, "{o:?}");
    assert!((o.freq_hz - 178.0).abs() < 1.0 && !both.stable, "{o:?}");
}
