//! Configuration-time transcendental functions in f64 (exp, tan) from plain arithmetic,
//! so the designed coefficients are identical on the host and on the Cortex-M (no libm,
//! no platform-dependent approximations). Never used on a tick path.

/// e^x for |x| ≲ 700, relative error ≈ 1e-15.
pub(crate) fn exp(x: f64) -> f64 {
    // e^x = 2^k · e^r, r = x − k·ln2 ∈ [−ln2/2, ln2/2]; e^r by its Taylor series.
    let ln2 = core::f64::consts::LN_2;
    let k = round(x / ln2);
    let r = x - k * ln2;
    let mut term = 1.0;
    let mut sum = 1.0;
    let mut n = 1.0;
    while n < 20.0 {
        term *= r / n;
        sum += term;
        n += 1.0;
    }
    let mut scale = 1.0;
    let (base, count) = if k >= 0.0 { (2.0, k) } else { (0.5, -k) };
    let mut i = 0.0;
    while i < count && i < 2000.0 {
        scale *= base;
        i += 1.0;
    }
    sum * scale
}

/// tan x for 0 ≤ x < π/2 (sin/cos by Taylor series on the reduced argument).
pub(crate) fn tan(x: f64) -> f64 {
    let (s, c) = sin_cos(x);
    s / c
}

/// (sin x, cos x) by their Taylor series (30 terms) on x reduced to [−π, π].
pub(crate) fn sin_cos(x: f64) -> (f64, f64) {
    // Reduction by whole turns only when needed, so |x| ≤ π (tan's range) is untouched.
    let x = if x.abs() > core::f64::consts::PI {
        let turns = round(x / core::f64::consts::TAU);
        x - turns * core::f64::consts::TAU
    } else {
        x
    };
    let mut s = 0.0;
    let mut c = 0.0;
    let mut term = 1.0; // x^n / n!
    let mut n = 0u32;
    while n < 30 {
        match n % 4 {
            0 => c += term,
            1 => s += term,
            2 => c -= term,
            _ => s -= term,
        }
        n += 1;
        term *= x / f64::from(n);
    }
    (s, c)
}

/// √x for x ≥ 0 (0 for anything else), by Newton's iteration from a power-of-two start.
pub(crate) fn sqrt(x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 || !x.is_finite() {
        return 0.0;
    }
    // Start at 2^⌈e/2⌉ ≥ √x, so the iteration falls monotonically onto the root.
    let mut r = 1.0;
    let mut v = x;
    while v > 1.0 {
        v *= 0.25;
        r *= 2.0;
    }
    while v < 0.25 {
        v *= 4.0;
        r *= 0.5;
    }
    r *= 2.0;
    let mut i = 0;
    while i < 8 {
        r = 0.5 * (r + x / r);
        i += 1;
    }
    r
}

/// ln x for x > 0 (−∞ for x = 0, NaN below): x = m·2^k with m ∈ [√½, √2), then
/// ln m = 2·atanh(u), u = (m − 1)/(m + 1), by its series in u².
pub(crate) fn ln(x: f64) -> f64 {
    if x.is_nan() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return f64::NEG_INFINITY;
    }
    if !x.is_finite() {
        return x;
    }
    let mut m = x;
    let mut k = 0.0;
    while m >= core::f64::consts::SQRT_2 {
        m *= 0.5;
        k += 1.0;
    }
    while m < core::f64::consts::FRAC_1_SQRT_2 {
        m *= 2.0;
        k -= 1.0;
    }
    let u = (m - 1.0) / (m + 1.0);
    let u2 = u * u;
    let mut term = u;
    let mut sum = 0.0;
    let mut n = 1.0;
    while n < 60.0 {
        sum += term / n;
        term *= u2;
        n += 2.0;
    }
    k * core::f64::consts::LN_2 + 2.0 * sum
}

fn round(x: f64) -> f64 {
    let t = x as i64 as f64;
    if x - t >= 0.5 {
        t + 1.0
    } else if x - t <= -0.5 {
        t - 1.0
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn matches_std() {
        for &x in &[-20.0, -3.3, -0.01, 0.0, 0.2, 1.0, 5.5] {
            let e = super::exp(x);
            assert!((e - f64::exp(x)).abs() <= 1e-14 * f64::exp(x), "exp({x})");
        }
        for &x in &[0.0, 0.001, 0.1, 0.7, 1.2, 1.5] {
            assert!(
                (super::tan(x) - f64::tan(x)).abs() <= 1e-12 * (1.0 + f64::tan(x)),
                "tan({x})"
            );
        }
        for &x in &[1e-9, 0.01, 0.5, 1.0, 2.0, 17.3, 1e7] {
            assert!(
                (super::sqrt(x) - x.sqrt()).abs() <= 1e-15 * x.sqrt(),
                "sqrt({x})"
            );
            assert!(
                (super::ln(x) - x.ln()).abs() <= 1e-14 * (1.0 + x.ln().abs()),
                "ln({x})"
            );
        }
        for &x in &[-9.0, -6.0, -1.0, 0.0, 0.3, 3.0, 6.2, 12.5] {
            let (s, c) = super::sin_cos(x);
            assert!(
                (s - x.sin()).abs() < 1e-12 && (c - x.cos()).abs() < 1e-12,
                "sin_cos({x})"
            );
        }
    }

    /// micromath (f32) against cfgmath (f64) over the arguments the coefficient design uses,
    /// as the largest relative error against std's f64, on the functions and on the derived
    /// coefficients. `cargo test -p controller-core --lib micromath -- --nocapture` prints
    /// the figures quoted in `docs/design.md`.
    #[test]
    fn micromath_against_cfgmath() {
        // Called through the trait: on the host, f32's inherent methods would shadow it.
        use micromath::F32Ext as M;
        let tau = core::f64::consts::TAU;
        let n = 20_000;
        // Error relative to max(|exact|, floor): floor 0 = relative, 1 = absolute (sin, whose
        // zeros make a relative error meaningless).
        let worst_with = |f: &dyn Fn(f64) -> (f64, f64, f64), lo: f64, hi: f64, floor: f64| {
            let (mut mm, mut cm) = (0.0_f64, 0.0_f64);
            for k in 0..=n {
                let x = lo + (hi - lo) * f64::from(k) / f64::from(n);
                let (exact, m, c) = f(x);
                let scale = exact.abs().max(floor);
                if scale != 0.0 {
                    mm = mm.max((m - exact).abs() / scale);
                    cm = cm.max((c - exact).abs() / scale);
                }
            }
            (mm, cm)
        };
        let worst =
            |f: &dyn Fn(f64) -> (f64, f64, f64), lo: f64, hi: f64| worst_with(f, lo, hi, 0.0);
        let rows: [(&str, (f64, f64)); 8] = [
            (
                "exp(x), x in [-pi, 0] (poles, first-order alpha)",
                worst(
                    &|x| (x.exp(), f64::from(M::exp(x as f32)), super::exp(x)),
                    -core::f64::consts::PI,
                    0.0,
                ),
            ),
            (
                "exp(x), x in [-7, 0] (notch depth)",
                worst(
                    &|x| (x.exp(), f64::from(M::exp(x as f32)), super::exp(x)),
                    -7.0,
                    0.0,
                ),
            ),
            (
                "tan(x), x in [1e-4, 1.5] (bilinear pre-warp)",
                worst(
                    &|x| (x.tan(), f64::from(M::tan(x as f32)), super::tan(x)),
                    1e-4,
                    1.5,
                ),
            ),
            (
                "sin(x), x in [0, 2 pi] (notch response; absolute error)",
                worst_with(
                    &|x| (x.sin(), f64::from(M::sin(x as f32)), super::sin_cos(x).0),
                    0.0,
                    tau,
                    1.0,
                ),
            ),
            (
                "sqrt(x), x in [1e-6, 100]",
                worst(
                    &|x| (x.sqrt(), f64::from(M::sqrt(x as f32)), super::sqrt(x)),
                    1e-6,
                    100.0,
                ),
            ),
            (
                "ln(x), x in [1.01, 1e4] (sweep ratio)",
                worst(
                    &|x| (x.ln(), f64::from(M::ln(x as f32)), super::ln(x)),
                    1.01,
                    1e4,
                ),
            ),
            // First-order alpha = 1 - e^(-2 pi fc/fs), corner 0.1 Hz .. fs/2 at 4 kHz.
            (
                "alpha = 1 - exp(-2 pi fc/fs), fc in [0.1 Hz, 2 kHz] at 4 kHz",
                worst(
                    &|f| {
                        let x = -tau * f / 4000.0;
                        (
                            1.0 - x.exp(),
                            1.0 - f64::from(M::exp(x as f32)),
                            1.0 - super::exp(x),
                        )
                    },
                    0.1,
                    2000.0,
                ),
            ),
            // Observer l3 = (1 - theta)^3, theta = e^(-2 pi fo/fs), 1..2000 Hz at 4 kHz.
            (
                "observer l3 = (1 - theta)^3, fo in [1 Hz, 2 kHz] at 4 kHz",
                worst(
                    &|f| {
                        let x = -tau * f / 4000.0;
                        let l3 = |t: f64| (1.0 - t).powi(3);
                        (
                            l3(x.exp()),
                            l3(f64::from(M::exp(x as f32))),
                            l3(super::exp(x)),
                        )
                    },
                    1.0,
                    2000.0,
                ),
            ),
        ];
        println!("| quantity | micromath (f32) max rel. error | cfgmath (f64) max rel. error |");
        println!("|---|---|---|");
        for (name, (mm, cm)) in rows {
            println!("| {name} | {mm:.1e} | {cm:.1e} |");
            // cfgmath must stay at f64 precision, far below the Q2.30 LSB (9.3e-10).
            assert!(cm < 1e-11, "{name}: cfgmath {cm:e}");
        }
    }
}
