//! The exact zero-order-hold maps x(t+h) = Φ(h)·x + Γ(h)·u of the three contact modes,
//! cached per step length: a harness that repeats the same few lengths (its delay and the
//! rest of the tick) pays one matrix exponential per length and mode, then one lookup and
//! one 5×8 product per step.

use crate::expm::expm;
use crate::model::{Contact, Mat5, Mat53, Vec3, Vec5};
use nalgebra::SMatrix;

/// Rows kept per column: the five states and one zero row, so that a column is three
/// pairs for two-wide SIMD.
const PADDED: usize = 6;

/// The exact discretisation for one step length: the columns of [Φ | Γ] acting on [x; u].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Discrete {
    cols: [[f64; PADDED]; 8],
}

impl Discrete {
    /// [Φ | Γ] = the top rows of exp([[A, B], [0, 0]]·h).
    pub(crate) fn new(a: &Mat5, b: &Mat53, h: f64) -> Self {
        let mut m = SMatrix::<f64, 8, 8>::zeros();
        m.fixed_view_mut::<5, 5>(0, 0).copy_from(&(a * h));
        m.fixed_view_mut::<5, 3>(0, 5).copy_from(&(b * h));
        let e = expm(&m);
        let mut cols = [[0.0; PADDED]; 8];
        for (j, col) in cols.iter_mut().enumerate() {
            for (i, v) in col.iter_mut().take(5).enumerate() {
                *v = e.get((i, j)).copied().unwrap_or(0.0);
            }
        }
        Self { cols }
    }

    /// Φ·x + Γ·u. Each state's sum runs over the eight terms left to right from −0.0, as
    /// `Iterator::sum` over a row does, so the result is bit for bit that of the row form;
    /// taking it column by column lets the five sums go two at a time.
    #[inline(always)]
    pub(crate) fn apply(&self, x: &Vec5, u: &Vec3) -> Vec5 {
        let z = [x.x, x.y, x.z, x.w, x.a, u.x, u.y, u.z];
        let mut acc = [-0.0; PADDED];
        for (col, zj) in self.cols.iter().zip(z) {
            for (a, c) in acc.iter_mut().zip(col) {
                *a += c * zj;
            }
        }
        let [a0, a1, a2, a3, a4, _] = acc;
        Vec5::new(a0, a1, a2, a3, a4)
    }
}

/// Step lengths kept at once (a harness uses two or three; a load profile's pieces more).
const SLOTS: usize = 6;

/// The maps of the three modes for the last [`SLOTS`] step lengths (bit-exact keys, filled
/// mode by mode as the modes are met), replaced round robin.
#[derive(Debug, Clone)]
pub(crate) struct MapCache {
    systems: [(Mat5, Mat53); 3],
    /// The step lengths' bits; 0 (h = +0.0, never stepped) marks an empty slot.
    keys: [u64; SLOTS],
    maps: [[Option<Discrete>; 3]; SLOTS],
    next_free: usize,
}

impl MapCache {
    /// An empty cache for the modes' (A, B), indexed by [`Contact::index`].
    pub(crate) fn new(systems: [(Mat5, Mat53); 3]) -> Self {
        Self {
            systems,
            keys: [0; SLOTS],
            maps: [[None; 3]; SLOTS],
            next_free: 0,
        }
    }

    /// A and B of a mode.
    pub(crate) fn system(&self, contact: Contact) -> (&Mat5, &Mat53) {
        let [free, driving, braking] = &self.systems;
        let (a, b) = match contact {
            Contact::Free => free,
            Contact::Driving => driving,
            Contact::Braking => braking,
        };
        (a, b)
    }

    /// x(t+h) in mode `contact` with u held: a scan of six keys (the lengths a harness
    /// repeats sit in the first slots), a matrix exponential for a length or mode not met
    /// before.
    #[inline]
    pub(crate) fn step(&mut self, contact: Contact, h: f64, x: &Vec5, u: &Vec3) -> Vec5 {
        let key = h.to_bits();
        if let Some(i) = self.keys.iter().position(|k| *k == key)
            && let Some(Some(d)) = self.maps.get(i).and_then(|m| m.get(contact.index()))
        {
            return d.apply(x, u);
        }
        self.step_slow(contact, key, h, x, u)
    }

    /// The slot of step length `h` (> 0), claimed round robin if it has none. A caller that
    /// repeats `h` keeps the slot and passes it to [`Self::step_in`], which skips the scan.
    pub(crate) fn slot(&mut self, h: f64) -> usize {
        self.slot_of(h.to_bits())
    }

    fn slot_of(&mut self, key: u64) -> usize {
        match self.keys.iter().position(|k| *k == key) {
            Some(i) => i,
            None => {
                let i = self.next_free;
                self.next_free = (i + 1) % SLOTS;
                if let (Some(k), Some(m)) = (self.keys.get_mut(i), self.maps.get_mut(i)) {
                    *k = key;
                    *m = [None; 3];
                }
                i
            }
        }
    }

    /// [`Self::step`] for a length whose slot the caller holds ([`Self::slot`]): the map
    /// directly while the slot still holds `h` (the scan when it was reused since).
    #[inline(always)]
    pub(crate) fn step_in(
        &mut self,
        slot: usize,
        contact: Contact,
        h: f64,
        x: &Vec5,
        u: &Vec3,
    ) -> Vec5 {
        let key = h.to_bits();
        if self.keys.get(slot) == Some(&key)
            && let Some(Some(d)) = self.maps.get(slot).and_then(|m| m.get(contact.index()))
        {
            return d.apply(x, u);
        }
        self.step_slow(contact, key, h, x, u)
    }

    #[cold]
    fn step_slow(&mut self, contact: Contact, key: u64, h: f64, x: &Vec5, u: &Vec3) -> Vec5 {
        let i = self.slot_of(key);
        let (a, b) = self.system(contact);
        let map = Discrete::new(a, b, h);
        if let Some(entry) = self
            .maps
            .get_mut(i)
            .and_then(|m| m.get_mut(contact.index()))
        {
            *entry = Some(map);
        }
        map.apply(x, u)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    /// nalgebra's exponential (Padé) against this crate's Taylor scaling and squaring,
    /// `expm`: they agree to round-off, but not bit for bit, and the closed loop amplifies
    /// the last bits, so the integrator uses `expm`, whose bits are this crate's own, for
    /// reproducibility.
    #[test]
    fn expm_agrees_with_nalgebra_exp_to_round_off() {
        let a = Mat5::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 * 37.0 - 150.0);
        let b = Mat53::from_fn(|i, j| ((i * 5 + j) % 7) as f64 * 11.0 - 30.0);
        for h in [1e-6, 7e-5, 1.8e-4, 2.5e-4] {
            let mut m = SMatrix::<f64, 8, 8>::zeros();
            m.fixed_view_mut::<5, 5>(0, 0).copy_from(&(a * h));
            m.fixed_view_mut::<5, 3>(0, 5).copy_from(&(b * h));
            let (pade, taylor) = (m.exp(), expm(&m));
            let err = (pade - taylor).amax() / taylor.amax();
            assert!(err < 1e-13, "h = {h}: {err:e}");
        }
    }

    #[test]
    fn the_column_product_is_the_row_sum_bit_for_bit() {
        let a = Mat5::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 * 0.37 - 1.5);
        let b = Mat53::from_fn(|i, j| ((i * 5 + j) % 7) as f64 * 0.11 - 0.3);
        let d = Discrete::new(&a, &b, 1.7e-4);
        for k in 0..200 {
            let s = f64::from(k);
            let x = Vec5::new(s.sin(), -s * 1e-3, 0.0, -0.0, (s * 0.3).cos() * 1e5);
            let u = Vec3::new(-(s * 0.7).sin(), 0.0, 1.0);
            let z = [x.x, x.y, x.z, x.w, x.a, u.x, u.y, u.z];
            let got = d.apply(&x, &u);
            for i in 0..5 {
                let row = d.cols.iter().map(|c| c[i]);
                let want: f64 = row.zip(z).map(|(r, z)| r * z).sum();
                assert_eq!(got[i].to_bits(), want.to_bits(), "state {i} at {k}");
            }
        }
    }

    /// The cache keeps the last [`SLOTS`] step lengths, round robin: a stepped length has
    /// its slot ([`MapCache::slot`]) holding its key and the map of the mode it was stepped
    /// in, a seventh length takes the slot of the first, and stepping a cached length again
    /// claims nothing.
    #[test]
    fn the_cache_keeps_the_last_six_lengths_round_robin() {
        let a = Mat5::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 * 0.37 - 1.5);
        let b = Mat53::from_fn(|i, j| ((i * 5 + j) % 7) as f64 * 0.11 - 0.3);
        let mut cache = MapCache::new([(a, b); 3]);
        let (x, u) = (Vec5::new(1.0, 0.0, 0.5, 0.0, 0.0), Vec3::new(0.2, 0.0, 1.0));
        let lengths: Vec<f64> = (1..=SLOTS + 1).map(|k| 1e-5 * k as f64).collect();
        for (k, &h) in lengths.iter().enumerate() {
            let want = Discrete::new(&a, &b, h).apply(&x, &u);
            assert_eq!(cache.step(Contact::Driving, h, &x, &u), want, "length {k}");
            assert_eq!(
                cache.step(Contact::Driving, h, &x, &u),
                want,
                "length {k} again"
            );
            let slot = cache.slot(h);
            assert_eq!(slot, k % SLOTS, "length {k}");
            assert_eq!(cache.keys[slot], h.to_bits(), "length {k}");
            assert!(
                cache.maps[slot][Contact::Driving.index()].is_some(),
                "length {k}"
            );
            assert!(
                cache.maps[slot][Contact::Free.index()].is_none(),
                "length {k}"
            );
        }
        let kept: Vec<u64> = lengths[1..].iter().map(|h| h.to_bits()).collect();
        let mut keys = cache.keys.to_vec();
        keys.sort_unstable();
        assert_eq!(keys, kept, "the first length evicted, the other six kept");
    }

    /// A row whose eight products are all −0.0 (each input a zero of the sign opposite to
    /// its coefficient's) sums to −0.0, as the row form's `Iterator::sum` does: the sums
    /// start from −0.0, not +0.0.
    #[test]
    fn a_row_of_negative_zero_products_sums_to_negative_zero() {
        let a = Mat5::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 * 0.37 - 1.5);
        let b = Mat53::from_fn(|i, j| ((i * 5 + j) % 7) as f64 * 0.11 - 0.3);
        let d = Discrete::new(&a, &b, 1.7e-4);
        for i in 0..5 {
            let z: [f64; 8] = core::array::from_fn(|j| if d.cols[j][i] < 0.0 { 0.0 } else { -0.0 });
            let x = Vec5::new(z[0], z[1], z[2], z[3], z[4]);
            let u = Vec3::new(z[5], z[6], z[7]);
            let want: f64 = d.cols.iter().zip(z).map(|(c, z)| c[i] * z).sum();
            assert_eq!(want.to_bits(), (-0.0f64).to_bits(), "row {i}");
            assert_eq!(d.apply(&x, &u)[i].to_bits(), want.to_bits(), "row {i}");
        }
    }
}
