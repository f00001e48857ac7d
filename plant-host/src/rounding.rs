//! f64 → integer rounding without the library calls: x86-64's baseline has no rounding
//! instruction (SSE4.1 `roundsd`), so `f64::round` and `f64::floor` are calls into
//! compiler-builtins on the hot path of every tick (ADC codes, encoder counts, fixed-point
//! conversions). These use the truncating conversion and one exact subtraction instead.
//!
//! Below 2^51 in magnitude (every value a run meets) they round with one addition of
//! 1.5·2^52 and read the integer from the bits, without the saturating conversion.
//!
//! Each returns what `y.round() as i64` (or `floor`, or round-ties-to-even) returns, for
//! every input: saturating at the i64 range, NaN → 0.

/// 1.5·2^52. For |y| < 2^51, y + 1.5·2^52 lies in [2^52, 2^53), where neighbouring doubles
/// are 1 apart: the addition rounds y to an integer (to nearest, ties to even, the
/// floating-point default; 1.5·2^52 is even, so the tie goes as y's own would), and the sum's
/// bits less those of 1.5·2^52 are that integer.
const SHIFTER: f64 = 6_755_399_441_055_744.0;
/// Below this magnitude [`nearest_small`] is exact.
const SMALL: f64 = 2_251_799_813_685_248.0;

/// The nearest integer to y (ties to even), as an integer and as a double, for |y| < 2^51.
#[inline(always)]
fn nearest_small(y: f64) -> (i64, f64) {
    let sum = y + SHIFTER;
    let n = sum.to_bits().wrapping_sub(SHIFTER.to_bits()) as i64;
    (n, sum - SHIFTER)
}

/// `y.round() as i64`: the nearest integer, ties away from zero.
///
/// ```
/// use plant_host::rounding::round_i64;
/// assert_eq!((round_i64(2.5), round_i64(-2.5), round_i64(0.49999999999999994)), (3, -3, 0));
/// ```
#[inline]
pub fn round_i64(y: f64) -> i64 {
    if y.abs() < SMALL {
        // n is y to nearest with ties to even; y − n is exact (|y − n| ≤ ½, both on y's
        // grid or within a factor 2 of each other). A tie that went towards zero goes away
        // from it instead.
        let (n, nf) = nearest_small(y);
        let frac = y - nf;
        if frac.abs() != 0.5 {
            return n;
        }
        return tie_away_from_zero(y, n, frac);
    }
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

/// y half-way between two integers, n the even one (y − n = `frac` = ±½): the one away from
/// zero.
#[cold]
fn tie_away_from_zero(y: f64, n: i64, frac: f64) -> i64 {
    if y > 0.0 {
        n + i64::from(frac > 0.0)
    } else {
        n - i64::from(frac < 0.0)
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
    if y.abs() < SMALL {
        return nearest_small(y).0;
    }
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
    if y.abs() < SMALL {
        // The nearest integer is above y by at most ½: then the one below it.
        let (n, nf) = nearest_small(y);
        return if nf > y { n - 1 } else { n };
    }
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
            2251799813685247.5,
            -2251799813685247.5,
            2251799813685248.0,
            -2251799813685248.0,
            2251799813685249.0,
            1125899906842623.5,
            -1125899906842624.5,
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
