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
}
