//! The conversions between plant-host's f64 per-unit values and the controller's
//! fixed-point signals (the runner drives `plant_host::TwoInertiaPlant` or
//! `plant_host::PmsmPlant` directly), and what a trace row reads of either ([`PlantView`]).

use crate::error::HarnessError;
use controller_core::per_unit::{Counts, Pu, PuPerS};
use plant_host::rounding::{round_i64, round_ties_even_i64};
use plant_host::PlantError;

/// What a trace row reads from the plant: the same columns for either motor.
pub trait PlantView {
    /// Motor angle \[rad\].
    fn motor_pos_rad(&self) -> f64;
    /// Load angle, reflected to the motor side \[rad\].
    fn load_pos_rad(&self) -> f64;
    /// Motor speed \[pu\].
    fn motor_vel_pu(&self) -> f64;
    /// Load speed \[pu\].
    fn load_vel_pu(&self) -> f64;
    /// The torque-producing current \[pu\]: the DC winding's current; a PMSM's true q
    /// current (in the rotor's own frame).
    fn current_pu(&self) -> f64;
    /// Shaft torque \[pu\].
    fn shaft_torque_pu(&self) -> f64;
}

macro_rules! plant_view {
    ($plant:ty, $current:ident) => {
        impl PlantView for $plant {
            #[inline]
            fn motor_pos_rad(&self) -> f64 {
                <$plant>::motor_pos_rad(self)
            }
            #[inline]
            fn load_pos_rad(&self) -> f64 {
                <$plant>::load_pos_rad(self)
            }
            #[inline]
            fn motor_vel_pu(&self) -> f64 {
                <$plant>::motor_vel_pu(self)
            }
            #[inline]
            fn load_vel_pu(&self) -> f64 {
                <$plant>::load_vel_pu(self)
            }
            #[inline]
            fn current_pu(&self) -> f64 {
                <$plant>::$current(self)
            }
            #[inline]
            fn shaft_torque_pu(&self) -> f64 {
                <$plant>::shaft_torque_pu(self)
            }
        }
    };
}
plant_view!(plant_host::TwoInertiaPlant, current_pu);
plant_view!(plant_host::PmsmPlant, i_q_pu);

/// A plant-host error (an invalid step or input) as the harness reports it.
pub fn plant_error(e: PlantError) -> HarnessError {
    HarnessError::Backend(format!("plant: {e}"))
}

/// Q16.16 and Q48.16: 2^16 LSBs per unit. Scaling by it is exact in f64.
const ONE_Q16: f64 = 65536.0;

/// f64 pu → the controller's Q16.16, to the nearest LSB (ties away from zero), saturating;
/// NaN maps to 0. Hand-written: the generic conversion and the `round` call were 7 % of a
/// closed-loop run.
pub fn pu(x: f64) -> Pu {
    let bits = round_i64(x * ONE_Q16).clamp(i64::from(i32::MIN), i64::from(i32::MAX));
    // Clamped to the i32 range just above.
    Pu::from_bits(bits as i32)
}

/// f64 pu/s → Q16.16, saturating, rounded as `fixed`'s `saturating_from_num` rounds (to
/// the nearest LSB, ties to even); NaN maps to 0.
pub fn pu_s(x: f64) -> PuPerS {
    let bits = round_ties_even_i64(x * ONE_Q16).clamp(i64::from(i32::MIN), i64::from(i32::MAX));
    // Clamped to the i32 range just above.
    PuPerS::from_bits(bits as i32)
}

/// f64 counts → Q48.16 counts, saturating, rounded as `fixed`'s `saturating_from_num`
/// (ties to even); NaN maps to 0.
pub fn counts(x: f64) -> Counts {
    // The i64 rounding saturates exactly at Q48.16's bit range.
    Counts::from_bits(round_ties_even_i64(x * ONE_Q16))
}

/// A Q16.16 signal → f64, exactly (an i32 fits f64's mantissa; the scaling is a power of 2).
pub fn f(x: Pu) -> f64 {
    f64::from(x.to_bits()) * (1.0 / ONE_Q16)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// Values around ties and the saturation limits, and a spread of magnitudes.
    fn samples() -> Vec<f64> {
        let lsb = 1.0 / ONE_Q16;
        let mut v = vec![
            0.0,
            -0.0,
            32767.99998,
            -32768.0,
            40000.0,
            -40000.0,
            1e300,
            -1e300,
        ];
        for k in -2000..2000 {
            let base = f64::from(k) * 0.5 * lsb;
            v.extend([
                base,
                base * (1.0 + 1e-15),
                base * (1.0 - 1e-15),
                f64::from(k) * 0.37,
            ]);
        }
        v.extend([f64::INFINITY, f64::NEG_INFINITY]);
        v
    }

    #[test]
    fn the_hand_written_conversions_match_the_fixed_crate_and_round_to_nearest() {
        for x in samples() {
            let nearest = (x * 65536.0)
                .round()
                .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32;
            assert_eq!(pu(x).to_bits(), nearest, "pu {x:e}");
            assert_eq!(pu_s(x), PuPerS::saturating_from_num(x), "pu_s {x:e}");
            assert_eq!(
                counts(x * 1e9),
                Counts::saturating_from_num(x * 1e9),
                "counts {x:e}"
            );
            assert_eq!(counts(x), Counts::saturating_from_num(x), "counts {x:e}");
            let q = pu(x);
            assert_eq!(f(q), q.to_num::<f64>());
        }
        assert_eq!(pu(f64::NAN).to_bits(), 0);
        assert_eq!(
            (pu_s(f64::NAN).to_bits(), counts(f64::NAN).to_bits()),
            (0, 0)
        );
    }
}
