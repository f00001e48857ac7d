//! Per-unit conventions and the Q-format of every signal.
//!
//! * Speed in pu of base speed: ω_pu = ω / ω_b, ω_b = 2π·base_speed_rpm/60 rad/s.
//! * Torque and current in pu of rated; torque = current (k_t = 1 pu).
//! * Inertia in seconds: J·dω_pu/dt = T_pu.
//! * Acceleration in pu/s (pu of base speed per second).
//! * Positions as integer encoder counts; the hardware counter wraps at `counter_bits` and
//!   [`count_diff`] gives the wrap-safe signed difference of two raw readings.
//!
//! | Signal / coefficient                       | Type        | Range            | Resolution |
//! |--------------------------------------------|-------------|------------------|------------|
//! | speed, current, voltage, torque \[pu\]       | [`Pu`]      | ±32768           | 1.5e-5     |
//! | acceleration \[pu/s\]                        | [`PuPerS`]  | ±32768           | 1.5e-5     |
//! | commanded position \[counts, unwrapped\]     | [`Counts`]  | ±1.4e14          | 1/65536    |
//! | position error \[counts\]                    | [`CountsErr`] | ±8.4e6         | 1/256      |
//! | large gains (Kp_vel, Ka, Kp_cur, J)        | [`Gain`]    | ±32768           | 1.5e-5     |
//! | per-tick gains (Ki·Ts, count→pu scales)    | [`TickGain`]| ±128             | 6.0e-8     |
//! | position gain \[pu per count\]               | [`PosGain`] | ±1               | 4.7e-10    |
//! | filter / observer coefficients             | [`Coef`]    | ±2               | 9.3e-10    |
//!
//! Products are formed in 64 bits, rounded to nearest and saturated to the 32-bit result
//! type, so no tick can overflow: a saturated signal is the worst case, never a wrap.

use fixed::types::{I1F31, I2F30, I8F24, I16F16, I24F8, I48F16};

/// Per-unit signal: speed, current, torque, voltage (Q16.16).
pub type Pu = I16F16;
/// Acceleration in pu of base speed per second (Q16.16).
pub type PuPerS = I16F16;
/// Unwrapped encoder position in counts with a fraction (Q48.16), for commanded positions.
pub type Counts = I48F16;
/// Position error in counts (Q24.8): ±8.4 million counts, 1/256 count resolution.
pub type CountsErr = I24F8;
/// Large gain (Q16.16): velocity Kp \[pu torque per pu speed\], Ka and inertias \[s\],
/// current Kp \[pu voltage per pu current\].
pub type Gain = I16F16;
/// Per-tick gain (Q8.24): Ki·Ts, counts-per-tick to pu scale factors.
pub type TickGain = I8F24;
/// Position gain (Q1.31): velocity command in pu per count of position error.
pub type PosGain = I1F31;
/// Filter and observer coefficient (Q2.30).
pub type Coef = I2F30;

/// Base angular speed in rad/s for a base speed in rpm: ω_b = 2π·rpm/60.
///
/// ```
/// let wb = controller_core::per_unit::base_speed_rad_s(1000.0);
/// assert!((wb - 104.719_76).abs() < 1e-3);
/// ```
#[must_use]
pub fn base_speed_rad_s(base_speed_rpm: f32) -> f32 {
    base_speed_rpm * core::f32::consts::TAU / 60.0
}

/// Encoder counts per pu·s of position (one pu·s is the angle turned in one second at base
/// speed): cpr·ω_b/(2π).
///
/// ```
/// let c = controller_core::per_unit::counts_per_pu_s(4096, 1000.0);
/// assert!((c - 68_266.67).abs() < 0.1);
/// ```
#[must_use]
pub fn counts_per_pu_s(encoder_cpr: u32, base_speed_rpm: f32) -> f32 {
    encoder_cpr as f32 * base_speed_rpm / 60.0
}

/// Wrap-safe signed difference `now − before` of two raw readings of a counter that is
/// `counter_bits` wide (16..=32). The result is correct while the true motion between the
/// readings is below half the counter range.
///
/// ```
/// use controller_core::per_unit::count_diff;
/// assert_eq!(count_diff(2, 0xFFFE, 16), 4);
/// assert_eq!(count_diff(0xFFFE, 2, 16), -4);
/// assert_eq!(count_diff(1, u32::MAX, 32), 2);
/// ```
#[must_use]
#[inline]
pub fn count_diff(now: u32, before: u32, counter_bits: u8) -> i32 {
    count_diff_shifted(now, before, counter_shift(counter_bits))
}

/// The shift that puts a `counter_bits`-wide counter's MSB at bit 31 (0..=16), for
/// [`count_diff_shifted`]: computed once per configuration instead of every tick.
///
/// ```
/// assert_eq!(controller_core::per_unit::counter_shift(16), 16);
/// assert_eq!(controller_core::per_unit::counter_shift(32), 0);
/// ```
#[must_use]
#[inline]
pub fn counter_shift(counter_bits: u8) -> u32 {
    32u32.saturating_sub(u32::from(counter_bits)).min(16)
}

/// [`count_diff`] with the counter's [`counter_shift`] already computed.
///
/// ```
/// use controller_core::per_unit::{count_diff_shifted, counter_shift};
/// assert_eq!(count_diff_shifted(2, 0xFFFE, counter_shift(16)), 4);
/// ```
#[must_use]
#[inline]
pub fn count_diff_shifted(now: u32, before: u32, shift: u32) -> i32 {
    count_diff_by(now, before, shift.min(16))
}

/// [`count_diff_shifted`] for a shift known to be 0..=16 (a [`counter_shift`], computed
/// when the coefficients were built): no clamp of the shift on the tick path.
#[inline(always)]
pub(crate) fn count_diff_by(now: u32, before: u32, shift: u32) -> i32 {
    // Shift the counter's MSB to bit 31, subtract with wrap, shift back arithmetically.
    let d = (now << shift).wrapping_sub(before << shift) as i32;
    d >> shift
}

/// Raw reading of a `counter_bits`-wide counter interpreted as a signed position, so a
/// counter that starts at zero and moves backwards reads as small negative counts.
///
/// ```
/// use controller_core::per_unit::count_signed;
/// assert_eq!(count_signed(0xFFFF, 16), -1);
/// assert_eq!(count_signed(5, 16), 5);
/// ```
#[must_use]
#[inline]
pub fn count_signed(raw: u32, counter_bits: u8) -> i32 {
    let shift = 32u32.saturating_sub(u32::from(counter_bits)).min(16);
    ((raw << shift) as i32) >> shift
}

/// ⌊√x⌋, the same as `u64::isqrt` for every `x`, with 32-bit divides only: core's `isqrt`
/// divides 64-bit numbers, a library call of some hundred instructions on a Cortex-M4.
///
/// Below 2^32 it is `u32::isqrt`. Above, one step of Zimmermann's Karatsuba square root on
/// `x` normalized by an even shift (`x·4^k ≥ 2^62`, digits of 16 bits): the root `s'` and
/// remainder `r'` of the top 32 bits (`u32::isqrt`), then `q = ⌊(r'·2^16 + a1)/(2s')⌋` —
/// a 33-bit numerator, so taken as `⌊⌊n/2⌋/s'⌋`, which is the same — and
/// `s = s'·2^16 + q`, less one where the remainder `u·2^16 + a0 − q²` is negative; then
/// `s/2^k`.
///
/// ```
/// use controller_core::per_unit::isqrt_u64;
/// assert_eq!(isqrt_u64((1 << 62) - 1), (1 << 31) - 1);
/// assert_eq!(isqrt_u64(u64::MAX), u64::from(u32::MAX));
/// ```
#[must_use]
#[inline]
pub fn isqrt_u64(x: u64) -> u64 {
    let (hi, lo) = ((x >> 32) as u32, x as u32);
    if hi == 0 {
        if lo == 0 {
            return 0;
        }
        // Normalized by an even shift k: ⌊√(lo·2^k)⌋ >> k/2 = ⌊√lo⌋.
        let k = lo.leading_zeros() & !1;
        return u64::from(isqrt_top(lo << k) >> (k / 2));
    }
    // x ≥ 2^32: the even shift k2 ≤ 30 puts x's top two bits into the high word of
    // xn = x << k2, formed in 32-bit words (`(lo >> 1) >> (31 − k2)` is `lo >> (32 − k2)`,
    // 0 for k2 = 0).
    let k2 = hi.leading_zeros() & !1;
    let top = (hi << k2) | ((lo >> 1) >> (31 - k2));
    let low = lo << k2;
    // top ≥ 2^30: s1 ∈ [2^15, 2^16), r1 ≤ 2·s1.
    let s1 = isqrt_top(top);
    let r1 = top - s1 * s1;
    // n = r1·2^16 + (low >> 16) < 2^33; ⌊n/(2·s1)⌋ = ⌊⌊n/2⌋/s1⌋, and ⌊n/2⌋ < 2^32.
    let half = (r1 << 15) | (low >> 17);
    let q = half / s1;
    // u = n − 2·q·s1 = 2·(⌊n/2⌋ mod s1) + (n mod 2) < 2·s1 < 2^17.
    let u = ((half - q * s1) << 1) | ((low >> 16) & 1);
    let s = (u64::from(s1) << 16) + u64::from(q);
    // q ≤ 2^16: both sides fit.
    let rest = (u64::from(u) << 16) | u64::from(low & 0xFFFF);
    let s = if rest < u64::from(q) * u64::from(q) {
        s - 1
    } else {
        s
    };
    // s < 2^32 after the correction.
    u64::from((s as u32) >> (k2 / 2))
}

/// √ at the middle of each 2^24-wide slice of `[2^30, 2^32)` (index: the top byte),
/// rounded; the first 64 entries (below 2^30) are never read. (Evaluated by the compiler:
/// an index out of range would fail the build, not a tick.)
#[allow(clippy::indexing_slicing)]
const ISQRT_SEED: [u16; 256] = {
    let mut t = [0u16; 256];
    let mut i = 64;
    while i < 256 {
        t[i] = ((((i as u64) << 24) + (1 << 23)).isqrt()) as u16;
        i += 1;
    }
    t
};

/// `⌊√t⌋` of a normalized `t` in `[2^30, 2^32)`: the slice's seed s0 (within 2^-8 of the
/// root, relatively), one Newton step `⌊(s0 + ⌊t/s0⌋)/2⌋`, which is at least `⌊√t⌋` and
/// within (2^-8)²/2·2^16 < 1 above the root, then one correction.
#[inline(always)]
fn isqrt_top(t: u32) -> u32 {
    let s0 = u32::from(
        ISQRT_SEED
            .get((t >> 24) as usize)
            .copied()
            .unwrap_or(1 << 15),
    )
    .max(1);
    // s0 ≥ 2^15 and t/s0 < 2^17: the sum fits.
    let s = (s0 + t / s0) >> 1;
    // s ≤ 2^16: s² fits u64 (and u32 unless s = 2^16).
    if u64::from(s) * u64::from(s) > u64::from(t) {
        s - 1
    } else {
        s
    }
}

/// Saturate an `i64` to `i32`.
#[inline(always)]
pub(crate) fn sat_i32(x: i64) -> i32 {
    // In range exactly when the high word is the sign extension of the low word: one
    // compare on a 32-bit core instead of two 64-bit range compares; the saturated value is
    // formed out of line (`saturated`), so the usual path is the compare and a branch.
    let lo = x as i32;
    if (x >> 32) as i32 == lo >> 31 {
        lo
    } else {
        saturated((x >> 32) as i32)
    }
}

/// `x >> N` (arithmetic) saturated to `i32`, for `N` = 1..=32. `x >> N` is in range exactly
/// when `x` is in \[−2^(31+N), 2^(31+N)), i.e. when the high word `hi` = ⌊x / 2^32⌋ is in
/// \[−2^(N−1), 2^(N−1)): when `hi >> (N−1)` is its own sign. One compare of the high word,
/// and no 64-bit shift of the high half on the usual path (the result is the low word of
/// `x >> N`).
#[inline(always)]
pub(crate) fn sat_shr<const N: u32>(x: i64) -> i32 {
    sat_shr_by(x, N)
}

/// [`sat_shr`] with the shift as an argument (1..=32; a constant wherever it is inlined).
#[inline(always)]
fn sat_shr_by(x: i64, n: u32) -> i32 {
    let hi = (x >> 32) as i32;
    if hi >> (n - 1) == hi >> 31 {
        (x >> n) as i32
    } else {
        saturated(hi)
    }
}

/// The saturated `i32` of a value out of range whose high word is `hi`: `i32::MIN` below,
/// `i32::MAX` above. Cold and out of line, so the range tests above compile to a compare and
/// a branch that is not taken.
#[cold]
#[inline(never)]
fn saturated(hi: i32) -> i32 {
    (hi >> 31) ^ i32::MAX
}

/// `x / 2^N` rounded to nearest (halves up) for any `i64`, as `(x + 2^(N−1)) >> N` would
/// give without overflow, saturated to `i32`: halving first loses nothing, because
/// `(2q + b + 2^(N−1)) >> N` and `(q + 2^(N−2)) >> (N−1)` agree for b ∈ {0, 1} (the half
/// never carries past a multiple of 2^(N−1)), and `q + 2^(N−2)` cannot overflow. `N` is
/// 2..=33.
#[inline(always)]
pub(crate) fn sat_round_shr<const N: u32>(x: i64) -> i32 {
    sat_shr_by((x >> 1) + (1i64 << (N - 2)), N - 1)
}

/// Saturate an `i64` to the signed `B`-bit range \[−2^(B−1), 2^(B−1) − 1\] (`B` = 33..=63):
/// a state limited this way leaves 2^(63−B+1) of headroom for plain adds. In range exactly
/// when the bits from B−1 up are all the sign: one compare of the high word.
#[inline(always)]
pub(crate) fn sat_bits<const B: u32>(x: i64) -> i64 {
    if x >> (B - 1) == x >> 63 {
        x
    } else {
        saturated_bits::<B>(x)
    }
}

/// The `B`-bit limit on the side of `x` (out of line, as [`saturated`]).
#[cold]
#[inline(never)]
fn saturated_bits<const B: u32>(x: i64) -> i64 {
    if x < 0 {
        -(1i64 << (B - 1))
    } else {
        (1i64 << (B - 1)) - 1
    }
}

/// `x·c` with `x` and the result as raw Q16.16 bits and `c` as raw bits with `F`
/// fractional bits: 64-bit product, rounded to nearest, saturated.
#[inline]
pub(crate) fn mul_bits<const F: u32>(x: i32, c: i32) -> i32 {
    let p = i64::from(x) * i64::from(c);
    // |x·c| ≤ 2^62, so adding the rounding half cannot overflow.
    sat_shr::<F>(p + (1i64 << (F - 1)))
}

/// `x·k` for a Q16.16 signal and a Q16.16 gain, rounded, saturated.
#[inline]
#[must_use]
pub fn mul_gain(x: Pu, k: Gain) -> Pu {
    Pu::from_bits(mul_bits::<16>(x.to_bits(), k.to_bits()))
}

/// `x·k` for a Q16.16 signal and a Q8.24 per-tick gain, rounded, saturated.
#[inline]
#[must_use]
pub fn mul_tick(x: Pu, k: TickGain) -> Pu {
    Pu::from_bits(mul_bits::<24>(x.to_bits(), k.to_bits()))
}

/// `x·c` for a Q16.16 signal and a Q2.30 coefficient, rounded, saturated.
#[inline]
#[must_use]
pub fn mul_coef(x: Pu, c: Coef) -> Pu {
    Pu::from_bits(mul_bits::<30>(x.to_bits(), c.to_bits()))
}

/// Integer counts times a Q8.24 scale (e.g. pu per count-per-tick), rounded, saturated.
#[inline]
#[must_use]
pub fn counts_to_pu(counts: i32, k: TickGain) -> Pu {
    // counts (Q32.0) · k (Q8.24) = Q.24; to Q16.16: shift right by 8.
    Pu::from_bits(mul_bits::<8>(counts, k.to_bits()))
}

/// `value` quantized to `T` for the coefficient `param`: an error naming `T`'s Q-format if it
/// does not fit ([`ConfigError::CoefficientOverflow`](crate::ConfigError::CoefficientOverflow)) or, being non-zero, would lose more
/// than 1 % to the quantization ([`ConfigError::CoefficientUnderflow`](crate::ConfigError::CoefficientUnderflow)). Configuration code
/// only.
///
/// ```
/// use controller_core::per_unit::{quantize, Coef};
/// assert!(quantize::<Coef>(0.5, "alpha").is_ok());
/// let e = quantize::<Coef>(3.0, "alpha").unwrap_err();
/// assert!(e.to_string().contains("Q2.30"));
/// ```
pub fn quantize<T: fixed::traits::Fixed>(
    value: f32,
    param: &'static str,
) -> Result<T, crate::ConfigError> {
    let x: T = checked_q::<T>(value).ok_or(crate::ConfigError::overflow::<T>(param, value))?;
    // A non-zero coefficient must keep at least ~1 % relative precision.
    let back: f32 = x.to_num();
    if value != 0.0 && ((back - value) / value).abs() > 0.01 {
        return Err(crate::ConfigError::underflow::<T>(param, value));
    }
    Ok(x)
}

/// Saturating conversion of an `f32` to a fixed-point type, for configuration code only.
#[must_use]
pub fn checked_q<T: fixed::traits::Fixed>(value: f32) -> Option<T> {
    if value.is_finite() {
        T::checked_from_num(value)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    /// `isqrt_top` is exact on `[2^30, 2^32)`, and `isqrt_u64` below 2^20.
    #[test]
    fn isqrt_top_is_the_exact_root_of_every_normalized_word() {
        // Every square and its neighbours in [2^30, 2^32), and a dense scatter.
        for r in (1u64 << 15)..(1 << 16) {
            for x in [r * r - 1, r * r, r * r + 1, r * r + r, r * r + 2 * r] {
                if ((1 << 30)..(1 << 32)).contains(&x) {
                    assert_eq!(u64::from(super::isqrt_top(x as u32)), x.isqrt(), "{x}");
                }
            }
        }
        for x in ((1u32 << 30)..=u32::MAX).step_by(997) {
            assert_eq!(super::isqrt_top(x), x.isqrt(), "{x}");
        }
        assert_eq!(super::isqrt_top(u32::MAX), u32::MAX.isqrt());
        // The normalizing path below 2^32, on every value below 2^20.
        for x in 0..(1u64 << 20) {
            assert_eq!(super::isqrt_u64(x), x.isqrt(), "{x}");
        }
    }

    /// `isqrt_u64` is `u64::isqrt` at and around every square and power of two, at the ends
    /// and on 200,000 scattered values.
    #[test]
    fn isqrt_u64_is_the_exact_root() {
        let mut xs = vec![
            0u64,
            1,
            2,
            3,
            u64::MAX,
            u64::MAX - 1,
            1 << 62,
            (1 << 62) - 1,
        ];
        for b in 0..64 {
            let p = 1u64 << b;
            xs.extend([p - 1, p, p + 1]);
        }
        for r in (0..=u64::from(u32::MAX)).step_by(65_537).chain([
            u64::from(u32::MAX),
            65_535,
            65_536,
            (1 << 31) - 1,
        ]) {
            let sq = r * r;
            xs.extend([
                sq.wrapping_sub(1),
                sq,
                sq.wrapping_add(1),
                sq.wrapping_add(2 * r),
                sq.wrapping_add(2 * r + 1),
            ]);
        }
        let mut z = 0x9E37_79B9_7F4A_7C15u64;
        for k in 0..200_000u32 {
            z = z
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            // All magnitudes: shift by 0..=63.
            xs.push(z >> (k % 64));
        }
        for x in xs {
            assert_eq!(super::isqrt_u64(x), x.isqrt(), "{x}");
        }
    }

    /// `sat_i32` against the plain range comparison, at and around every boundary.
    #[test]
    fn sat_i32_matches_the_range_definition() {
        let lim = |x: i64| x.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        let mut xs = vec![0i64, 1, -1, i64::MAX, i64::MIN, 1 << 32, -(1 << 32)];
        for b in [i64::from(i32::MAX), i64::from(i32::MIN)] {
            for d in -3..=3 {
                xs.push(b + d);
            }
        }
        for k in 0..2000i64 {
            xs.push(k.wrapping_mul(0x9E37_79B9_7F4A_7C15u64 as i64));
        }
        for x in xs {
            assert_eq!(super::sat_i32(x), lim(x), "{x}");
        }
    }

    /// `sat_shr` against the shift followed by the plain range clamp.
    #[test]
    fn sat_shr_matches_the_range_definition() {
        let lim = |x: i64| x.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        for x in samples() {
            assert_eq!(super::sat_shr::<1>(x), lim(x >> 1), "{x}");
            assert_eq!(super::sat_shr::<8>(x), lim(x >> 8), "{x}");
            assert_eq!(super::sat_shr::<12>(x), lim(x >> 12), "{x}");
            assert_eq!(super::sat_shr::<16>(x), lim(x >> 16), "{x}");
            assert_eq!(super::sat_shr::<20>(x), lim(x >> 20), "{x}");
            assert_eq!(super::sat_shr::<23>(x), lim(x >> 23), "{x}");
            assert_eq!(super::sat_shr::<24>(x), lim(x >> 24), "{x}");
            assert_eq!(super::sat_shr::<29>(x), lim(x >> 29), "{x}");
            assert_eq!(super::sat_shr::<30>(x), lim(x >> 30), "{x}");
            assert_eq!(super::sat_shr::<32>(x), lim(x >> 32), "{x}");
            for b in [i64::from(i32::MAX), i64::from(i32::MIN)] {
                for d in -3..=3 {
                    let y = (b + d) << 16;
                    assert_eq!(super::sat_shr::<16>(y), lim(y >> 16), "{y}");
                    assert_eq!(super::sat_shr::<16>(y + 0xFFFF), lim((y + 0xFFFF) >> 16));
                }
            }
        }
    }

    fn samples() -> Vec<i64> {
        let mut xs = vec![0i64, 1, -1, i64::MAX, i64::MIN, i64::MAX - 1, i64::MIN + 1];
        for b in 30..63 {
            for d in -3..=3 {
                xs.push((1i64 << b) + d);
                xs.push(-(1i64 << b) + d);
            }
        }
        for k in 0..4000i64 {
            let x = k.wrapping_mul(0x9E37_79B9_7F4A_7C15u64 as i64);
            xs.extend([x, x >> 3, x >> 17, x >> 33]);
        }
        xs
    }

    /// `sat_round_shr` against the widened (i128) rounded shift, clamped.
    #[test]
    fn sat_round_shr_matches_the_rounded_shift() {
        for x in samples() {
            let r = |n: u32| {
                ((i128::from(x) + (1i128 << (n - 1))) >> n)
                    .clamp(i128::from(i32::MIN), i128::from(i32::MAX)) as i32
            };
            assert_eq!(super::sat_round_shr::<14>(x), r(14), "{x}");
            assert_eq!(super::sat_round_shr::<16>(x), r(16), "{x}");
            assert_eq!(super::sat_round_shr::<30>(x), r(30), "{x}");
            assert_eq!(super::sat_round_shr::<33>(x), r(33), "{x}");
        }
    }

    /// `sat_bits` against the plain range clamp.
    #[test]
    fn sat_bits_matches_the_range_definition() {
        for x in samples() {
            let c = |b: u32| x.clamp(-(1i64 << (b - 1)), (1i64 << (b - 1)) - 1);
            assert_eq!(super::sat_bits::<61>(x), c(61), "{x}");
            assert_eq!(super::sat_bits::<49>(x), c(49), "{x}");
        }
    }
}
