//! The ticks' inputs and outputs as raw 32-bit words, and the fault codes: the one layout
//! that the firmware's loop-in-the-loop check, its trace, the PIL link and the harness
//! share, written once here ([`tick_words!`](crate::tick_words)) for every tick type.
//! Fixed-point values are their two's-complement bits (a Q48.16 count is two words, low
//! first); a fault is its [`Fault::code`] (0 = none); a flag is 0 or 1.
//!
//! ```text
//! CurrentInputs   (2 words): encoder_count | current_pu
//! CurrentOutputs  (4 words): voltage_cmd | current_ref | accel_fb | fault
//! VelocityInputs  (7 words): encoder_count | position_counts (lo, hi) | velocity_pu |
//!                            acceleration_pu_s | fault_input
//! VelocityOutputs (8 words): current_ref | accel_fb | velocity_cmd | velocity_est |
//!                            acceleration_est | position_error (Q24.8) | disturbance_est | fault
//! PmsmInputs      (3 words): encoder_count | i_a | i_b
//! PmsmOutputs    (13 words): duty_a | duty_b | duty_c | enabled | i_d | i_q | i_d* | i_q* |
//!                            v_d | v_q | torque_ref | accel_fb | fault
//! ```

use crate::controller::{
    CurrentInputs, CurrentOutputs, PmsmInputs, PmsmOutputs, Setpoint, VelocityInputs,
    VelocityOutputs,
};
use crate::fault::Fault;
use crate::foc::Dq;
use crate::per_unit::{Counts, CountsErr, Pu, PuPerS};

impl Fault {
    /// Every fault, in code order (codes 1, 2, ...).
    pub const ALL: [Self; 8] = [
        Self::Overspeed,
        Self::FollowingError,
        Self::EncoderJump,
        Self::External,
        Self::Overcurrent,
        Self::Overload,
        Self::Stall,
        Self::Commutation,
    ];

    /// The fault's code, 1..=8 (0 is "no fault"). Stable across versions.
    #[must_use]
    pub const fn code(self) -> u8 {
        match self {
            Self::Overspeed => 1,
            Self::FollowingError => 2,
            Self::EncoderJump => 3,
            Self::External => 4,
            Self::Overcurrent => 5,
            Self::Overload => 6,
            Self::Stall => 7,
            Self::Commutation => 8,
        }
    }

    /// The fault of a code 1..=8; `None` for any other code.
    ///
    /// ```
    /// use controller_core::Fault;
    /// for f in Fault::ALL {
    ///     assert_eq!(Fault::from_code(f.code()), Some(f));
    /// }
    /// assert_eq!(Fault::from_code(0), None);
    /// ```
    #[must_use]
    pub const fn from_code(code: u8) -> Option<Self> {
        match code {
            1 => Some(Self::Overspeed),
            2 => Some(Self::FollowingError),
            3 => Some(Self::EncoderJump),
            4 => Some(Self::External),
            5 => Some(Self::Overcurrent),
            6 => Some(Self::Overload),
            7 => Some(Self::Stall),
            8 => Some(Self::Commutation),
            _ => None,
        }
    }
}

/// The code of a latched fault state: 0 = none, else [`Fault::code`].
#[must_use]
pub const fn fault_code(fault: Option<Fault>) -> u8 {
    match fault {
        None => 0,
        Some(f) => f.code(),
    }
}

/// Inverse of [`fault_code`]: `Ok(None)` for 0, `Err(code)` for a code that names no fault.
pub const fn fault_from_code(code: u8) -> Result<Option<Fault>, u8> {
    match (code, Fault::from_code(code)) {
        (0, _) => Ok(None),
        (_, Some(f)) => Ok(Some(f)),
        (c, None) => Err(c),
    }
}

/// A word that names no value of its field: a fault code or a flag out of range, or a
/// record too short.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BadWord {
    /// The index of the word.
    pub index: usize,
    /// The word.
    pub word: u32,
}

/// A field of a tick record: its width in words, how it is written and read back.
pub trait WordField: Sized {
    /// Words it takes.
    const WIDTH: usize;
    /// Writes the field at `at`; returns the index after it. A record too short for it
    /// keeps the words that fit (the records are sized by [`tick_words!`](crate::tick_words)).
    fn put(&self, out: &mut [u32], at: usize) -> usize;
    /// Reads the field at `at`; returns it and the index after it.
    fn take(words: &[u32], at: usize) -> Result<(Self, usize), BadWord>;
}

/// The word at `at`, or the error naming it.
fn word(words: &[u32], at: usize) -> Result<u32, BadWord> {
    words.get(at).copied().ok_or(BadWord { index: at, word: 0 })
}

/// Writes `w` at `at` if the record has room.
fn set(out: &mut [u32], at: usize, w: u32) {
    if let Some(slot) = out.get_mut(at) {
        *slot = w;
    }
}

macro_rules! i32_field {
    ($($t:ty),*) => {$(
        impl WordField for $t {
            const WIDTH: usize = 1;
            fn put(&self, out: &mut [u32], at: usize) -> usize {
                set(out, at, self.to_bits() as u32);
                at + 1
            }
            fn take(words: &[u32], at: usize) -> Result<(Self, usize), BadWord> {
                Ok((Self::from_bits(word(words, at)? as i32), at + 1))
            }
        }
    )*};
}
i32_field!(Pu, CountsErr);

// `PuPerS` is the same type as `Pu` (both Q16.16); the assertion keeps it so.
const _: fn(PuPerS) -> Pu = |x| x;

impl WordField for u32 {
    const WIDTH: usize = 1;
    fn put(&self, out: &mut [u32], at: usize) -> usize {
        set(out, at, *self);
        at + 1
    }
    fn take(words: &[u32], at: usize) -> Result<(Self, usize), BadWord> {
        Ok((word(words, at)?, at + 1))
    }
}

impl WordField for u16 {
    const WIDTH: usize = 1;
    fn put(&self, out: &mut [u32], at: usize) -> usize {
        set(out, at, u32::from(*self));
        at + 1
    }
    fn take(words: &[u32], at: usize) -> Result<(Self, usize), BadWord> {
        let w = word(words, at)?;
        u16::try_from(w)
            .map(|v| (v, at + 1))
            .map_err(|_| BadWord { index: at, word: w })
    }
}

impl WordField for bool {
    const WIDTH: usize = 1;
    fn put(&self, out: &mut [u32], at: usize) -> usize {
        set(out, at, u32::from(*self));
        at + 1
    }
    fn take(words: &[u32], at: usize) -> Result<(Self, usize), BadWord> {
        match word(words, at)? {
            0 => Ok((false, at + 1)),
            1 => Ok((true, at + 1)),
            w => Err(BadWord { index: at, word: w }),
        }
    }
}

impl WordField for Option<Fault> {
    const WIDTH: usize = 1;
    fn put(&self, out: &mut [u32], at: usize) -> usize {
        set(out, at, u32::from(fault_code(*self)));
        at + 1
    }
    fn take(words: &[u32], at: usize) -> Result<(Self, usize), BadWord> {
        let w = word(words, at)?;
        let bad = BadWord { index: at, word: w };
        let code = u8::try_from(w).map_err(|_| bad)?;
        fault_from_code(code).map(|f| (f, at + 1)).map_err(|_| bad)
    }
}

impl WordField for Counts {
    const WIDTH: usize = 2;
    fn put(&self, out: &mut [u32], at: usize) -> usize {
        let bits = self.to_bits() as u64;
        set(out, at, bits as u32);
        set(out, at + 1, (bits >> 32) as u32);
        at + 2
    }
    fn take(words: &[u32], at: usize) -> Result<(Self, usize), BadWord> {
        let lo = u64::from(word(words, at)?);
        let hi = u64::from(word(words, at + 1)?);
        Ok((Self::from_bits((hi << 32 | lo) as i64), at + 2))
    }
}

impl<T: WordField + Copy + Default, const N: usize> WordField for [T; N] {
    const WIDTH: usize = T::WIDTH * N;
    fn put(&self, out: &mut [u32], at: usize) -> usize {
        self.iter().fold(at, |i, x| x.put(out, i))
    }
    fn take(words: &[u32], at: usize) -> Result<(Self, usize), BadWord> {
        let mut v = [T::default(); N];
        let mut i = at;
        for x in &mut v {
            let (y, j) = T::take(words, i)?;
            *x = y;
            i = j;
        }
        Ok((v, i))
    }
}

/// The word layout of a tick record, written once: the fields in order. Gives the type
/// `WORDS` (its width), `FIELDS` (the fields' names), `to_words` and `from_words`, and makes
/// it a [`WordField`] itself (to nest, as a [`Setpoint`] in [`VelocityInputs`]).
#[macro_export]
macro_rules! tick_words {
    ($ty:ty { $($f:ident: $ft:ty),* $(,)? }) => {
        impl $ty {
            /// Words of the record.
            pub const WORDS: usize = 0 $(+ <$ft as $crate::words::WordField>::WIDTH)*;
            /// The fields' names, in order.
            pub const FIELDS: &'static [&'static str] = &[$(stringify!($f)),*];
            /// The record as words.
            #[must_use]
            pub fn to_words(&self) -> [u32; Self::WORDS] {
                let mut out = [0_u32; Self::WORDS];
                <Self as $crate::words::WordField>::put(self, &mut out, 0);
                out
            }
            /// The record from its words; a word that names no value is an error.
            pub fn from_words(
                words: &[u32; Self::WORDS],
            ) -> Result<Self, $crate::words::BadWord> {
                <Self as $crate::words::WordField>::take(words, 0).map(|(v, _)| v)
            }
        }
        impl $crate::words::WordField for $ty {
            const WIDTH: usize = 0 $(+ <$ft as $crate::words::WordField>::WIDTH)*;
            #[allow(unused_mut)]
            fn put(&self, out: &mut [u32], at: usize) -> usize {
                let mut i = at;
                $( i = <$ft as $crate::words::WordField>::put(&self.$f, out, i); )*
                i
            }
            #[allow(unused_mut)]
            fn take(
                words: &[u32],
                at: usize,
            ) -> Result<(Self, usize), $crate::words::BadWord> {
                let mut i = at;
                Ok((
                    Self {
                        $($f: {
                            let (v, j) = <$ft as $crate::words::WordField>::take(words, i)?;
                            i = j;
                            v
                        },)*
                    },
                    i,
                ))
            }
        }
    };
}

tick_words!(CurrentInputs {
    encoder_count: u32,
    current_pu: Pu,
});
tick_words!(CurrentOutputs {
    voltage_cmd_pu: Pu,
    current_ref_pu: Pu,
    accel_fb_pu: Pu,
    fault: Option<Fault>,
});
tick_words!(Setpoint {
    position_counts: Counts,
    velocity_pu: Pu,
    acceleration_pu_s: Pu,
});
tick_words!(VelocityInputs {
    encoder_count: u32,
    setpoint: Setpoint,
    fault_input: bool,
});
tick_words!(VelocityOutputs {
    current_ref_pu: Pu,
    accel_fb_pu: Pu,
    velocity_cmd_pu: Pu,
    velocity_est_pu: Pu,
    acceleration_est_pu_s: Pu,
    position_error_counts: CountsErr,
    disturbance_est_pu: Pu,
    fault: Option<Fault>,
});
tick_words!(Dq { d: Pu, q: Pu });
tick_words!(PmsmInputs {
    encoder_count: u32,
    phase_current_pu: [Pu; 2],
});
tick_words!(PmsmOutputs {
    duties: [u16; 3],
    enabled: bool,
    current: Dq,
    current_ref: Dq,
    voltage: Dq,
    torque_ref_pu: Pu,
    accel_fb_pu: Pu,
    fault: Option<Fault>,
});

/// Output words of a current tick ([`CurrentOutputs::WORDS`]).
pub const CURRENT_WORDS: usize = CurrentOutputs::WORDS;
/// Output words of a velocity tick ([`VelocityOutputs::WORDS`]).
pub const VELOCITY_WORDS: usize = VelocityOutputs::WORDS;
/// The name of each word of [`CurrentOutputs::to_words`].
pub const CURRENT_FIELDS: &[&str] = CurrentOutputs::FIELDS;
/// The name of each word of [`VelocityOutputs::to_words`].
pub const VELOCITY_FIELDS: &[&str] = VelocityOutputs::FIELDS;

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn pu(bits: i32) -> Pu {
        Pu::from_bits(bits)
    }

    /// Every record comes back from its words, and the words are the layout the module
    /// documents (the order of the fields, a count as low then high word).
    #[test]
    fn every_record_round_trips_through_its_documented_layout() {
        let v = VelocityInputs {
            encoder_count: 0xdead_beef,
            setpoint: Setpoint {
                position_counts: Counts::from_bits(-0x1_2345_6789),
                velocity_pu: pu(-3),
                acceleration_pu_s: pu(i32::MIN),
            },
            fault_input: true,
        };
        let w = v.to_words();
        let pos = (-0x1_2345_6789_i64) as u64;
        assert_eq!(
            w,
            [
                0xdead_beef,
                pos as u32,
                (pos >> 32) as u32,
                (-3_i32) as u32,
                i32::MIN as u32,
                1
            ]
        );
        assert_eq!(VelocityInputs::from_words(&w), Ok(v));
        let o = CurrentOutputs {
            voltage_cmd_pu: pu(7),
            current_ref_pu: pu(-8),
            accel_fb_pu: pu(9),
            fault: Some(Fault::Commutation),
        };
        assert_eq!(o.to_words(), [7, (-8_i32) as u32, 9, 8]);
        assert_eq!(CurrentOutputs::from_words(&o.to_words()), Ok(o));
        assert_eq!(CURRENT_FIELDS.len(), CURRENT_WORDS);
        assert_eq!(VELOCITY_FIELDS.len(), VELOCITY_WORDS);
        let p = PmsmOutputs {
            duties: [1, 2, 4200],
            enabled: true,
            current: Dq { d: pu(1), q: pu(2) },
            current_ref: Dq { d: pu(3), q: pu(4) },
            voltage: Dq { d: pu(5), q: pu(6) },
            torque_ref_pu: pu(-7),
            accel_fb_pu: pu(8),
            fault: None,
        };
        assert_eq!(PmsmOutputs::WORDS, 13);
        assert_eq!(PmsmOutputs::from_words(&p.to_words()), Ok(p));
        let i = PmsmInputs {
            encoder_count: 5,
            phase_current_pu: [pu(-1), pu(2)],
        };
        assert_eq!(i.to_words(), [5, u32::MAX, 2]);
        assert_eq!(PmsmInputs::from_words(&i.to_words()), Ok(i));
    }

    #[test]
    fn a_word_that_names_no_value_is_an_error_naming_it() {
        let mut w = VelocityInputs::default().to_words();
        w[5] = 2;
        assert_eq!(
            VelocityInputs::from_words(&w),
            Err(BadWord { index: 5, word: 2 })
        );
        let mut w = CurrentOutputs::default().to_words();
        w[3] = 9;
        assert_eq!(
            CurrentOutputs::from_words(&w),
            Err(BadWord { index: 3, word: 9 })
        );
        w[3] = 0x100 + 1;
        assert!(CurrentOutputs::from_words(&w).is_err());
        let mut w = PmsmOutputs::default().to_words();
        w[0] = 0x1_0000;
        assert_eq!(
            PmsmOutputs::from_words(&w),
            Err(BadWord {
                index: 0,
                word: 0x1_0000
            })
        );
    }
}
