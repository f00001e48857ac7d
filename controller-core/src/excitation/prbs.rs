//! The maximal-length PRBS: its design (LFSR taps, mask and length) and its tick (one
//! Fibonacci step every `hold` ticks).

use super::{ExcitationParams, ExcitationState, Kind, check};
use crate::error::ConfigError;

/// Primitive polynomials x^n + Σ x^e + 1 for n = 7..=20, by their middle exponents e
/// (the standard tables of primitive trinomials and pentanomials; 0 ends a list).
const PRIMITIVE: [[u32; 3]; 14] = [
    [6, 0, 0],   // 7
    [6, 5, 4],   // 8
    [5, 0, 0],   // 9
    [7, 0, 0],   // 10
    [9, 0, 0],   // 11
    [6, 4, 1],   // 12
    [4, 3, 1],   // 13
    [5, 3, 1],   // 14
    [14, 0, 0],  // 15
    [15, 13, 4], // 16
    [14, 0, 0],  // 17
    [11, 0, 0],  // 18
    [6, 2, 1],   // 19
    [17, 0, 0],  // 20
];

/// The feedback mask of a right-shifting Fibonacci LFSR of `n` bits for a polynomial:
/// the output bit 0 stands for x^n, and each middle exponent e taps bit n − e.
fn taps(n: u32, middle: [u32; 3]) -> u32 {
    let tap = |e: u32| if e == 0 { 0 } else { 1 << (n - e) };
    let [a, b, c] = middle;
    1 | tap(a) | tap(b) | tap(c)
}

/// Design a PRBS of `bits` bits, each held `hold_ticks` ticks, for `periods` periods.
pub(super) fn design(
    bits: u8,
    hold_ticks: u16,
    periods: u16,
    p: ExcitationParams,
) -> Result<Kind, ConfigError> {
    let taps = bits
        .checked_sub(7)
        .and_then(|i| PRIMITIVE.get(usize::from(i)))
        .map(|m| taps(u32::from(bits), *m))
        .ok_or(ConfigError::OutOfRange {
            param: p.start_or_bits,
            value: f32::from(bits),
            min: 7.0,
            max: 20.0,
            min_exclusive: false,
        })?;
    check(f32::from(hold_ticks), 0.0, 1000.0, p.end_or_hold)?;
    check(f32::from(periods), 0.0, 1000.0, p.duration_or_periods)?;
    let length = (1u64 << bits) - 1;
    let ticks = length * u64::from(hold_ticks) * u64::from(periods);
    let ticks = u32::try_from(ticks).map_err(|_| ConfigError::OutOfRange {
        param: p.duration_or_periods,
        value: f32::from(periods),
        min: 1.0,
        max: (f64::from(u32::MAX) / (length as f64 * f64::from(hold_ticks))) as f32,
        min_exclusive: false,
    })?;
    Ok(Kind::Prbs {
        taps,
        mask: (1u32 << bits) - 1,
        hold: hold_ticks,
        ticks,
    })
}

/// One PRBS tick: ±1 in Q1.30 from the register's output bit, and a Fibonacci step of the
/// register once the bit has been held `hold` ticks.
#[inline(always)]
pub(super) fn step(s: &mut ExcitationState, taps: u32, mask: u32, hold: u16) -> i32 {
    if s.phase_or_register == 0 {
        s.phase_or_register = mask; // any non-zero seed; all ones
    }
    let out = if s.phase_or_register & 1 == 1 {
        1 << 30
    } else {
        -(1 << 30)
    };
    s.increment_or_held += 1;
    if s.increment_or_held >= u64::from(hold) {
        s.increment_or_held = 0;
        // Fibonacci step: the new top bit is the parity of the tapped bits.
        let r = s.phase_or_register;
        let fb = (r & taps).count_ones() & 1;
        s.phase_or_register = ((r >> 1) | (fb << (mask.count_ones() - 1))) & mask;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::tests::{NAMES, ok};
    use super::super::*;

    /// Every tap set is maximal: the register returns to its seed after exactly 2^n − 1
    /// steps and not before.
    #[test]
    fn every_prbs_length_is_maximal() {
        for bits in 7u8..=20 {
            let cfg = ExcitationConfig {
                waveform: Waveform::Prbs {
                    bits,
                    hold_ticks: 1,
                    periods: 1,
                },
                amplitude_pu: 1.0,
                injection: Injection::VelocityReference,
            };
            let e = ok(Excitation::new(&cfg, 4000.0, NAMES));
            let mut s = ExcitationState::default();
            let _ = e.next(&mut s);
            let seed = (1u32 << bits) - 1;
            let mut period = 1u32;
            while s.phase_or_register != seed {
                let _ = e.next(&mut s);
                period += 1;
                assert!(period <= e.ticks(), "{bits} bits: no return to the seed");
            }
            assert_eq!(period, (1 << bits) - 1, "{bits} bits");
        }
    }
}
