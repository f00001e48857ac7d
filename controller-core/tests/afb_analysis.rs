//! Trap 1, analytically: the discrete-time characteristic polynomial of the acceleration
//! loop alone, with the gears separated (motor inertia Jm only, the worst case), the 0.18 ms
//! computational delay inside the tick, zero-order hold, the second difference of the
//! sampled position, a first-order filter and the current loop as a one-tick-delayed
//! first-order lag at its bandwidth. The closed-loop poles decide; the boundary is compared
//! with the closed-loop simulations of `afb_design.rs`.
//! `cargo test -p controller-core --release --test afb_analysis -- --nocapture`
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

/// Complex number (just enough for root finding).
#[derive(Clone, Copy, Debug)]
struct C(f64, f64);
impl C {
    fn add(self, o: C) -> C {
        C(self.0 + o.0, self.1 + o.1)
    }
    fn sub(self, o: C) -> C {
        C(self.0 - o.0, self.1 - o.1)
    }
    fn mul(self, o: C) -> C {
        C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
    fn div(self, o: C) -> C {
        let d = o.0 * o.0 + o.1 * o.1;
        C(
            (self.0 * o.0 + self.1 * o.1) / d,
            (self.1 * o.0 - self.0 * o.1) / d,
        )
    }
    fn abs(self) -> f64 {
        self.0.hypot(self.1)
    }
}

/// Roots of a monic-able polynomial p[0]·z^n + … + p[n] (Durand–Kerner).
fn roots(p: &[f64]) -> Vec<C> {
    let n = p.len() - 1;
    let lead = p[0];
    let q: Vec<f64> = p.iter().map(|c| c / lead).collect();
    let eval = |z: C| {
        q.iter()
            .fold(C(0.0, 0.0), |acc, &c| acc.mul(z).add(C(c, 0.0)))
    };
    let mut r: Vec<C> = (0..n)
        .map(|k| {
            let a = 0.4 + 0.9 * k as f64;
            C(0.9 * a.cos(), 0.9 * a.sin())
        })
        .collect();
    for _ in 0..2000 {
        for i in 0..n {
            let mut den = C(1.0, 0.0);
            for j in 0..n {
                if i != j {
                    den = den.mul(r[i].sub(r[j]));
                }
            }
            r[i] = r[i].sub(eval(r[i]).div(den));
        }
    }
    r
}

/// Polynomial product (coefficients in powers of z^-1, constant first).
fn pmul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// Largest closed-loop pole magnitude of the acceleration loop.
/// `ka_over_jm`: high-frequency loop gain; `fc_hz`: first-order filter corner;
/// `rate_hz`: tick rate of the AFB path; `delay_s`: computation delay; `current_bw_rad_s`.
fn spectral_radius(
    ka_over_jm: f64,
    fc_hz: f64,
    rate_hz: f64,
    delay_s: f64,
    current_bw_rad_s: f64,
) -> f64 {
    spectral_radius_with_velocity_p(ka_over_jm, 0.0, fc_hz, rate_hz, delay_s, current_bw_rad_s)
}

/// As [`spectral_radius`], with the velocity regulator's proportional path closed too
/// (`kp_over_jm` [1/s]: Kp/Jm, velocity by the first difference at the same rate; the
/// integral path is negligible at these frequencies).
fn spectral_radius_with_velocity_p(
    ka_over_jm: f64,
    kp_over_jm: f64,
    fc_hz: f64,
    rate_hz: f64,
    delay_s: f64,
    current_bw_rad_s: f64,
) -> f64 {
    let ts = 1.0 / rate_hz;
    let r = (delay_s / ts).min(1.0);
    // Second difference of the sampled position per unit torque (J = 1), divided by Ts²:
    // a[n] = c1·T[n−1] + c2·T[n−2] + c3·T[n−3] for a torque applied r·Ts after its sample.
    let c1 = (1.0 - r).powi(2) / 2.0;
    let c2 = 1.5 - r - (1.0 - r).powi(2);
    let c3 = r * r / 2.0;
    let alpha = 1.0 - (-std::f64::consts::TAU * fc_hz * ts).exp();
    let beta = (-current_bw_rad_s * ts).exp();
    // θ = Ts²/J·A/(1 − z⁻¹)²·T with A = c1 z⁻¹ + c2 z⁻² + c3 z⁻³, so a = A·T/J and
    // v = Ts/J·A/(1 − z⁻¹)·T. T = −Cur·(Kp·v + Ka·F·a), F = α/(1 − (1−α)z⁻¹),
    // Cur = (1−β)z⁻¹/(1 − βz⁻¹). Multiplying out by (1 − z⁻¹)(1 − (1−α)z⁻¹)(1 − βz⁻¹):
    // den + Cur_num·A·[Kp·Ts/Jm·(1 − (1−α)z⁻¹) + Ka/Jm·α·(1 − z⁻¹)] = 0 (powers of z⁻¹).
    // With Kp = 0 the free-velocity factor (1 − z⁻¹) is common to every term and cancels:
    // the acceleration loop alone leaves the velocity floating (a pole at z = 1).
    let free = if kp_over_jm == 0.0 {
        vec![1.0]
    } else {
        vec![1.0, -1.0]
    };
    let den = pmul(&pmul(&free, &[1.0, -(1.0 - alpha)]), &[1.0, -beta]);
    let ca = pmul(&[0.0, 1.0 - beta], &[0.0, c1, c2, c3]);
    let vel = pmul(&ca, &[kp_over_jm * ts, -kp_over_jm * ts * (1.0 - alpha)]);
    let acc = pmul(&ca, &pmul(&free, &[ka_over_jm * alpha]));
    let mut poly = vec![0.0; den.len().max(vel.len())];
    for (i, d) in den.iter().enumerate() {
        poly[i] += d;
    }
    for (i, x) in vel.iter().chain(std::iter::empty()).enumerate() {
        poly[i] += x;
    }
    for (i, x) in acc.iter().enumerate() {
        poly[i] += x;
    }
    // In powers of z^-1 constant first == polynomial in z with the leading coefficient first.
    while poly.last().is_some_and(|c| c.abs() < 1e-300) {
        poly.pop();
    }
    roots(&poly).iter().map(|z| z.abs()).fold(0.0, f64::max)
}

/// Largest first-order corner [Hz] that keeps the loop stable (bisection on 1..rate/2).
fn max_stable_corner(ka_over_jm: f64, kp_over_jm: f64, rate_hz: f64) -> f64 {
    let stable = |fc: f64| {
        spectral_radius_with_velocity_p(
            ka_over_jm,
            kp_over_jm,
            fc,
            rate_hz,
            0.18e-3,
            2.0 * std::f64::consts::PI * 318.0,
        ) < 1.0
    };
    let (mut lo, mut hi) = (0.1, rate_hz / 2.0 - 1.0);
    if stable(hi) {
        return hi;
    }
    if !stable(lo) {
        return 0.0;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if stable(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

#[test]
fn root_finder_works() {
    // (z − 0.5)(z + 0.25)(z − 0.9) = z³ − 1.15 z² + 0.1 z + 0.1125
    let r = roots(&[1.0, -1.15, 0.1, 0.1125]);
    let mut m: Vec<f64> = r.iter().map(|z| z.0).collect();
    m.sort_by(f64::total_cmp);
    assert!(
        (m[0] + 0.25).abs() < 1e-9 && (m[1] - 0.5).abs() < 1e-9 && (m[2] - 0.9).abs() < 1e-9,
        "{m:?}"
    );
}

/// The boundary of the acceleration loop with the gears separated. With the velocity
/// regulator's P path closed as designed (Kp = ω·(J_total + Ka), Table 1) the corner limit for
/// Ka/Jm = 4.2 lands between the closed-loop simulation's stable 25 Hz and unstable 50 Hz at
/// 4 kHz, and below 25 Hz at 2 kHz (simulation: 25 Hz unstable). The acceleration loop alone
/// is far more tolerant: the separated motor sees the velocity gain Kp/Jm (12.6× its design
/// bandwidth) together with Ka/Jm, and it is their combination that the delays limit.
#[test]
fn acceleration_loop_stability_boundary() {
    // No feedback at all: only the filter and current-loop poles (inside the unit circle).
    assert!(spectral_radius(0.0, 100.0, 4000.0, 0.18e-3, 1998.0) < 1.0);
    let w = std::f64::consts::TAU * 15.0;
    println!("| Ka/Jm | Kp/Jm [1/s] | max 1st-order corner, loop alone, 4 kHz | 2 kHz | with velocity P, 4 kHz | 2 kHz |");
    println!("|---|---|---|---|---|---|");
    for frac in [0.0, 0.25, 0.5, 1.0, 2.0] {
        let ka = frac * 0.98;
        let ka_over_jm = ka / 0.117;
        let kp_over_jm = w * (0.98 + ka) / 0.117;
        println!(
            "| {ka_over_jm:.2} | {kp_over_jm:.0} | {:.1} | {:.1} | {:.1} | {:.1} |",
            max_stable_corner(ka_over_jm, 0.0, 4000.0),
            max_stable_corner(ka_over_jm, 0.0, 2000.0),
            max_stable_corner(ka_over_jm, kp_over_jm, 4000.0),
            max_stable_corner(ka_over_jm, kp_over_jm, 2000.0),
        );
    }
    let ka_over_jm = 0.5 * 0.98 / 0.117;
    let kp_over_jm = w * (0.98 + 0.49) / 0.117;
    let f4 = max_stable_corner(ka_over_jm, kp_over_jm, 4000.0);
    let f2 = max_stable_corner(ka_over_jm, kp_over_jm, 2000.0);
    println!("Ka = 0.5·J_total: limit {f4:.1} Hz at 4 kHz, {f2:.1} Hz at 2 kHz");
    assert!(f4 > 25.0 && f4 < 50.0, "4 kHz limit {f4} Hz");
    assert!(f2 < 25.0, "2 kHz limit {f2} Hz");
}
