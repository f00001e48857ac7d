//! f64 → integer rounding without the library calls: x86-64's baseline has no rounding
//! instruction (SSE4.1 `roundsd`), so `f64::round` and `f64::floor` are calls into
//! compiler-builtins on the hot path of every tick (ADC codes, encoder counts, fixed-point
//! conversions). These use the truncating conversion and one exact subtraction instead.
//!
//! Each returns what `y.round() as i64` (or `floor`, or round-ties-to-even) returns, for
//! every input: saturating at the i64 range, NaN → 0.

/// `y.round() as i64`: the nearest integer, ties away from zero.
///
/// ```
/// use plant_host::rounding::round_i64;
/// assert_eq!((round_i64(2.5), round_i64(-2.5), round_i64(0.49999999999999994)), (3, -3, 0));
/// ```
#[inline]
pub fn round_i64(y: f64) -> i64 {
    // t = trunc(y), saturating; for |y| < 2^52 the fraction y − t is exact, and above it
    // y is an integer (fraction 0) or t saturated (fraction of the same sign as the push).
    let t = y as i64;
    let frac = y - t as f64;
    if frac >= 0.5 {
        t.saturating_add(1)
    } else if frac <= -0.5 {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// The nearest integer with ties to even (the rounding of `fixed`'s `from_num` for
/// floats), saturating, NaN → 0.
///
/// ```
/// use plant_host::rounding::round_ties_even_i64;
/// assert_eq!((round_ties_even_i64(2.5), round_ties_even_i64(3.5), round_ties_even_i64(-2.5)), (2, 4, -2));
/// ```
#[inline]
pub fn round_ties_even_i64(y: f64) -> i64 {
    let t = y as i64;
    let frac = y - t as f64;
    let odd = t & 1 != 0;
    if frac > 0.5 || (frac == 0.5 && odd) {
        t.saturating_add(1)
    } else if frac < -0.5 || (frac == -0.5 && odd) {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// `y.floor() as i64`, saturating, NaN → 0.
///
/// ```
/// use plant_host::rounding::floor_i64;
/// assert_eq!((floor_i64(-0.5), floor_i64(1.999), floor_i64(-3.0)), (-1, 1, -3));
/// ```
#[inline]
pub fn floor_i64(y: f64) -> i64 {
    // trunc(y) is exact; it is above y only for a negative non-integer.
    let t = y as i64;
    if (t as f64) > y {
        t.saturating_sub(1)
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Edge cases and a deterministic spread of magnitudes, both signs.
    fn samples() -> Vec<f64> {
        let mut v = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            -2.5,
            0.49999999999999994,
            -0.49999999999999994,
            0.5000000000000001,
            4503599627370495.5,
            -4503599627370495.5,
            4503599627370496.0,
            9007199254740993.0,
            9.223372036854775e18,
            -9.223372036854775e18,
            9.3e18,
            -9.3e18,
            1e300,
            -1e300,
            f64::MIN_POSITIVE,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        let mut s: u64 = 0x2545_F491_4F6C_DD1D;
        for _ in 0..200_000 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let mag = f64::from((s >> 40) as u32 % 70) - 10.0;
            let m = (s & 0xF_FFFF) as f64 / f64::from(0x10_0000);
            let x = (1.0 + m) * 2f64.powf(mag) * if s & (1 << 30) != 0 { -1.0 } else { 1.0 };
            v.push(x);
            // Exact halves and their neighbours.
            let half = (x * 2.0).trunc() / 2.0;
            v.extend([
                half,
                f64::from_bits(half.to_bits() + 1),
                f64::from_bits(half.to_bits().saturating_sub(1)),
            ]);
        }
        v
    }

    #[test]
    fn each_matches_the_library_rounding_for_every_sample() {
        for y in samples() {
            assert_eq!(round_i64(y), y.round() as i64, "round {y:e}");
            assert_eq!(
                round_ties_even_i64(y),
                y.round_ties_even() as i64,
                "ties even {y:e}"
            );
            assert_eq!(floor_i64(y), y.floor() as i64, "floor {y:e}");
        }
    }
}
