//! The guard test in short form: the dead zone's guards read the twist and the two speeds
//! only, so on finite states they are evaluated from those three components.

use super::{Guard, Linear, peak_reaches_zero};
use crate::model::Vec5;

/// The dead zone's guards in the form their coefficients take: l(x) = c₀·δ + k, l̇ = a₂·ωm +
/// a₃·ωl, every other coefficient of c, cA and cB zero. On a finite state each value is
/// that of [`Linear`]'s dense sums but for the sign of a zero (a zero coefficient adds ±0,
/// which changes only a zero partial sum), and the guard test only compares these values
/// with 0 or combines them where that sign cannot reach a comparison.
#[derive(Debug, Clone, Copy)]
pub(super) struct TwistForm {
    c0: f64,
    k: f64,
    a2: f64,
    a3: f64,
}

impl TwistForm {
    /// `l`'s coefficients in this form, if they have it.
    pub(super) fn of(l: &Linear) -> Option<Self> {
        let [c0, c1, c2, c3, c4] = l.c;
        let [a0, a1, a2, a3, a4] = l.c_a;
        let mut zeros = [c1, c2, c3, c4, a0, a1, a4].into_iter().chain(l.c_b);
        zeros
            .all(|v| v == 0.0)
            .then_some(Self { c0, k: l.k, a2, a3 })
    }
    #[inline]
    fn value(&self, x: &Vec5) -> f64 {
        self.c0 * x.x + self.k
    }
    #[inline]
    fn rate(&self, x: &Vec5) -> f64 {
        self.a2 * x.z + self.a3 * x.w
    }

    /// [`Guard::suspect`] of a one-part guard of this form, for finite x0 and x1.
    #[inline]
    fn suspect(&self, x0: &Vec5, x1: &Vec5, h: f64) -> bool {
        let l1 = self.value(x1);
        if l1 > 0.0 {
            return true;
        }
        let d0 = self.rate(x0);
        if d0 <= 0.0 {
            return false;
        }
        let d1 = self.rate(x1);
        if d1 >= 0.0 {
            return false;
        }
        peak_reaches_zero(self.value(x0), l1, d0, d1, h)
    }
}

/// Whether all five components are finite: x − x is +0 for a finite x and NaN otherwise,
/// so the sum of the five is 0 exactly when all are finite (paired to go two at a time;
/// cheaper than five `is_finite` tests).
#[inline]
#[allow(clippy::eq_op)] // x − x on purpose.
pub(super) fn finite(x: &Vec5) -> bool {
    let pairs = ((x.x - x.x) + (x.z - x.z)) + ((x.y - x.y) + (x.w - x.w));
    pairs + (x.a - x.a) == 0.0
}

/// The guards of a mode when all of them are in [`TwistForm`] (all of the dead zone's).
#[derive(Debug, Clone, Copy)]
pub(super) struct ShortGuards {
    forms: [TwistForm; 2],
    n: usize,
}

impl ShortGuards {
    pub(super) fn of(list: &[Option<Guard>; 2]) -> Option<Self> {
        let mut forms = [TwistForm {
            c0: 0.0,
            k: 0.0,
            a2: 0.0,
            a3: 0.0,
        }; 2];
        let mut n = 0;
        for g in list.iter().flatten() {
            *forms.get_mut(n)? = g.twist?;
            n += 1;
        }
        Some(Self { forms, n })
    }

    #[inline(always)]
    pub(super) fn suspect(&self, x0: &Vec5, x1: &Vec5, h: f64) -> bool {
        let [f0, f1] = &self.forms;
        (self.n > 0 && f0.suspect(x0, x1, h)) || (self.n > 1 && f1.suspect(x0, x1, h))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::super::Guards;
    use super::*;
    use crate::config::BacklashModel;
    use crate::config::PlantConfig;
    use crate::model::Model;
    use crate::model::{Contact, Vec3};

    /// The dead zone's guards in their short form give the dense test's answer on every
    /// finite pair of states (zeros and near-crossings included), and the dense form is
    /// kept when a state is not finite.
    #[test]
    fn the_short_guard_test_is_the_dense_one() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../configs/machines/table1.toml"
        );
        let cfg = PlantConfig::from_machine_file(path.as_ref()).unwrap();
        let model = Model::new(
            &cfg.mechanics,
            BacklashModel::DeadZone,
            Some((&cfg.electrics).into()),
        );
        let g = model.shaft.g;
        let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let v = [0.0, -0.0, g, -g, 1e-3, -1e-3, 0.5][(s % 7) as usize];
            v * (1.0 + ((s >> 8) % 5) as f64 * 1e-3) * if s & (1 << 40) != 0 { -1.0 } else { 1.0 }
        };
        let mut short = 0;
        for contact in Contact::ALL {
            let (a, b) = model.matrices(contact);
            let guards = Guards::new(contact, model.law, &model.shaft, &a, &b);
            assert!(guards.short.is_some());
            for _ in 0..20_000 {
                let x0 = Vec5::from_fn(|_, _| next());
                let x1 = Vec5::from_fn(|_, _| next());
                let u = Vec3::new(next(), next(), 1.0);
                let dense = guards.suspect_dense(&x0, &x1, &u, 1e-4);
                assert_eq!(guards.suspect(&x0, &x1, &u, 1e-4), dense, "{x0} {x1}");
                short += usize::from(dense);
            }
            // A NaN start spreads to the whole of x1 through the dense map: dense test.
            let nan = Vec5::new(0.0, f64::NAN, 0.0, 0.0, 0.0);
            let x1 = Vec5::repeat(f64::NAN);
            assert!(guards.suspect(&nan, &x1, &Vec3::new(0.0, 0.0, 1.0), 1e-4));
        }
        assert!(short > 1000, "{short}");
    }
}
