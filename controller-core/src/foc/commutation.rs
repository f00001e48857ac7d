//! The commutation check: is the electrical angle the drive uses the rotor's?
//!
//! With the angle off by δ, the rotor's back-EMF `ω·λ` appears in the drive's frame turned
//! by δ: on the q axis `ω·λ·cos δ`, on the d axis `−ω·λ·sin δ` (the sign of δ aside). The
//! check forms the residual of the voltage equations in the drive's frame, the back-EMF
//! seen by the drive,
//!
//! ```text
//! e_d = v_d − R·i_d + ω_e·L_q·i_q     (≈ −ω·λ·sin δ)
//! e_q = v_q − R·i_q − ω_e·L_d·i_d     (≈  ω·λ·cos δ)
//! ```
//!
//! low-passes both (a first-order filter by a shift, so the L·di/dt of transients averages
//! out), and counts the ticks whose residual lies more than 30° from where the speed puts
//! it: `e_q·sgn ω < 0` (more than 90°) or `3·e_d² > e_q²` (tan² 30° = 1/3). It judges only
//! above a minimum speed, where the back-EMF outweighs the errors of R and of the inverter;
//! a run of `trip_ticks` such ticks latches. A wrong pole-pair count turns the angle error
//! with the position, so the residual turns too and the check sees it whenever it is more
//! than 30° off. At standstill there is no back-EMF to judge: there the check says nothing.
//!
//! The voltage in the residual is the one set in the previous tick, which is the one that
//! acted over the interval the present sample closes.

use super::transforms::Dq;
use crate::per_unit::{Gain, Pu, mul_gain, sat_shr};

/// The check's coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommutationCheck {
    /// Phase resistance R \[pu\].
    pub resistance: Gain,
    /// ω_e,b·L_d.
    pub wl_d: Gain,
    /// ω_e,b·L_q.
    pub wl_q: Gain,
    /// The speed below which the check does not judge, raw Q16.16, > 0.
    pub min_speed: i32,
    /// The filter's shift k: `e ← e + (x − e)/2^k` (time constant 2^k ticks), 0..=15.
    pub shift: u32,
    /// Consecutive ticks off by more than 30° that latch the fault, ≥ 1.
    pub trip_ticks: u32,
}

/// The check's state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CommutationState {
    /// The filtered residual (e_d, e_q), raw Q16.16.
    pub residual: [i32; 2],
    /// The voltage set in the previous tick.
    pub last_voltage: Dq,
    /// Consecutive ticks judged off.
    pub count: u32,
}

impl CommutationCheck {
    /// One tick on the measured currents `i` at speed `w`; `v` is the voltage this tick sets
    /// (kept for the next). Returns whether the angle has been judged off for `trip_ticks`
    /// ticks in a row.
    #[inline]
    pub fn update(&self, st: &mut CommutationState, i: Dq, w: Pu, v: Dq) -> bool {
        let wi = |x: Pu| {
            Pu::from_bits(sat_shr::<16>(
                i64::from(w.to_bits()) * i64::from(x.to_bits()),
            ))
        };
        let coupling = Dq {
            d: mul_gain(wi(i.q), self.wl_q),
            q: mul_gain(wi(i.d), self.wl_d),
        };
        self.update_with(st, i, w, coupling, v)
    }

    /// [`Self::update`] with the cross-coupling terms already formed:
    /// `coupling = (ω_e·L_q·i_q, ω_e·L_d·i_d)`, each as `mul_gain(ω·i, ω_e,b·L)` (the
    /// current loop's feed-forward has them).
    #[inline(always)]
    pub fn update_with(
        &self,
        st: &mut CommutationState,
        i: Dq,
        w: Pu,
        coupling: Dq,
        v: Dq,
    ) -> bool {
        let last = st.last_voltage;
        st.last_voltage = v;
        let e_d = last
            .d
            .saturating_sub(mul_gain(i.d, self.resistance))
            .saturating_add(coupling.d);
        let e_q = last
            .q
            .saturating_sub(mul_gain(i.q, self.resistance))
            .saturating_sub(coupling.q);
        let k = self.shift.min(15);
        for (f, x) in st.residual.iter_mut().zip([e_d, e_q]) {
            // 32-bit words: the step has the sign of x − f and at most its size, so f plus
            // the step lies between f and x (the difference saturates only beyond ±2^31).
            let step = x.to_bits().saturating_sub(*f) >> k;
            *f = f.wrapping_add(step);
        }
        let [fd, fq] = st.residual;
        let speed = w.to_bits();
        let off = if speed.unsigned_abs() < self.min_speed.unsigned_abs() {
            false
        } else {
            let q = if speed < 0 {
                -i64::from(fq)
            } else {
                i64::from(fq)
            };
            let d = i64::from(fd);
            q < 0 || 3 * d * d > q * q
        };
        st.count = if off { st.count.saturating_add(1) } else { 0 };
        st.count >= self.trip_ticks.max(1)
    }
}
