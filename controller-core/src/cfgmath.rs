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

fn sin_cos(x: f64) -> (f64, f64) {
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
    }
}
