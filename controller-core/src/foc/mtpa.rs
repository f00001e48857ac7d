//! The current references of a torque reference: maximum torque per ampere (MTPA).
//!
//! In per unit the motor's torque is `T = λ·i_q + k·i_d·i_q`, with the saliency
//! `k = x_d − x_q = ω_e,b·(L_d − L_q)`.
//!
//! - `k = 0` (surface magnets, `L_d = L_q`): `i_d = 0`, `i_q = T/λ`, within the current
//!   circle `|i_q| ≤ i_max`.
//! - `k ≠ 0`: the d current that gives a q current's torque at the least |i|. With
//!   `∂T/∂i_d·i_q = ∂T/∂i_q·i_d`, `k·i_q² = λ·i_d + k·i_d²`, whose root of the sign of `k`
//!   (where the reluctance torque adds to the magnet's) is
//!
//!   ```text
//!   i_d = 2k·i_q² / (λ + √(λ² + 4k²·i_q²))
//!   ```
//!
//!   (the form without `1/k`: its denominator is at least 2λ). One step from
//!   `i_q,0 = T/λ`: `i_d` of `i_q,0`, then `i_q = T/(λ + k·i_d)`, so the torque is the
//!   reference's exactly and the point is within a second-order distance of the curve
//!   (`i_d` is taken at `|i_q,0| ≥ |i_q|`). The current circle: the curve's point at
//!   `|i| = i_max`, `i_d,max = 2k·i_max² / (λ + √(λ² + 8k²·i_max²))`, and its torque
//!   `T_max`; a larger reference gets that point.

use super::transforms::Dq;
use crate::cfgmath::sqrt;
use crate::error::ConfigError;
use crate::per_unit::{Gain, Pu, mul_gain, quantize};

/// The quantized references (see the module's text).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mtpa {
    /// λ: the magnet torque per pu of q current.
    pub flux: Gain,
    /// 1/λ.
    inv_flux: Gain,
    /// The saliency `k = ω_e,b·(L_d − L_q)` (0: surface magnets).
    pub saliency: Gain,
    /// The circle's radius `i_max`.
    limit: Pu,
    /// The curve's point at `|i| = i_max` (`d` has the sign of `k`, `q` ≥ 0).
    at_limit: Dq,
    /// Its torque.
    torque_max: Pu,
}

/// `(n << 16) / den` in Q16.16, `den > 0`, saturated.
#[inline(always)]
fn div(n: i64, den: i64) -> Pu {
    let q = n.saturating_mul(1 << 16) / den.max(1);
    Pu::from_bits(i32::try_from(q).unwrap_or(if q < 0 { i32::MIN } else { i32::MAX }))
}

impl Mtpa {
    /// `flux` λ \[pu\], `saliency` ω_e,b·(L_d − L_q) \[pu\] (already quantized, so that
    /// `L_d = L_q` gives exactly 0), `limit` the current circle's radius \[pu\].
    pub fn new(flux: f32, saliency: Gain, limit: f32) -> Result<Self, ConfigError> {
        let k = f64::from(saliency.to_num::<f32>());
        let (l, i) = (f64::from(flux), f64::from(limit));
        let d = 2.0 * k * i * i / (l + sqrt(l * l + 8.0 * k * k * i * i));
        let q = sqrt((i * i - d * d).max(0.0));
        let key = "torque_limit_pu / pmsm.flux_linkage_pu";
        Ok(Self {
            flux: quantize(flux, "pmsm.flux_linkage_pu")?,
            inv_flux: quantize(1.0 / flux, "1/pmsm.flux_linkage_pu")?,
            saliency,
            limit: quantize(limit, key)?,
            at_limit: Dq {
                d: quantize(d as f32, key)?,
                q: quantize(q as f32, key)?,
            },
            torque_max: quantize((q * (l + k * d)) as f32, key)?,
        })
    }

    /// The current references of the torque reference `torque` \[pu\].
    #[inline(always)]
    pub fn references(&self, torque: Pu) -> Dq {
        let k = self.saliency;
        if k == Gain::ZERO {
            let lim = self.limit;
            return Dq {
                d: Pu::ZERO,
                q: mul_gain(torque, self.inv_flux).clamp(-lim, lim),
            };
        }
        let top = self.at_limit;
        if torque.unsigned_abs() >= self.torque_max.unsigned_abs() {
            let q = if torque < Pu::ZERO {
                top.q.saturating_neg()
            } else {
                top.q
            };
            return Dq { d: top.d, q };
        }
        let q0 = mul_gain(torque, self.inv_flux);
        // 2k·i_q,0 and λ in Q16.16; their squares in Q32.32 fit u64 together.
        let two_kq = mul_gain(q0, k).saturating_add(mul_gain(q0, k));
        let (a, b) = (i64::from(two_kq.to_bits()), i64::from(self.flux.to_bits()));
        let root = crate::per_unit::isqrt_u64((a * a) as u64 + (b * b) as u64);
        let den = b + i64::try_from(root).unwrap_or(i64::MAX);
        // 2k·i_q,0² in Q32.32 over λ + √(…) in Q16.16, then shifted back to Q16.16.
        let d = div((a * i64::from(q0.to_bits())) >> 16, den);
        let d = if k > Gain::ZERO {
            d.clamp(Pu::ZERO, top.d)
        } else {
            d.clamp(top.d, Pu::ZERO)
        };
        let den = i64::from(self.flux.to_bits()) + i64::from(mul_gain(d, k).to_bits());
        let q = div(i64::from(torque.to_bits()), den).clamp(top.q.saturating_neg(), top.q);
        Dq { d, q }
    }

    /// The torque of the currents `i` \[pu\]: `λ·i_q + k·i_d·i_q`.
    #[inline(always)]
    pub fn torque(&self, i: Dq) -> Pu {
        if self.saliency == Gain::ZERO {
            return mul_gain(i.q, self.flux);
        }
        mul_gain(i.q, self.flux.saturating_add(mul_gain(i.d, self.saliency)))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn mtpa(k: f32) -> Mtpa {
        Mtpa::new(1.0, quantize(k, "k").unwrap(), 2.0).unwrap()
    }

    /// The least |i| for a torque `t`, by a fine search over the current angle (f64).
    fn least_current(k: f64, t: f64) -> (f64, f64, f64) {
        let mut best = (f64::MAX, 0.0, 0.0);
        for n in 0..=200_000 {
            let d = -1.0 + 2.0 * f64::from(n) / 200_000.0;
            let q = t / (1.0 + k * d);
            let m = (d * d + q * q).sqrt();
            if m < best.0 {
                best = (m, d, q);
            }
        }
        best
    }

    #[test]
    fn surface_magnets_get_no_d_current_and_the_q_current_of_the_torque() {
        let m = mtpa(0.0);
        let r = m.references(Pu::from_num(0.75));
        assert_eq!(r.d, Pu::ZERO);
        assert_eq!(r.q, Pu::from_num(0.75));
        assert_eq!(m.references(Pu::from_num(-9.0)).q, Pu::from_num(-2.0));
        assert_eq!(
            m.torque(Dq {
                d: Pu::from_num(0.3),
                q: Pu::from_num(0.5)
            }),
            Pu::from_num(0.5)
        );
    }

    /// For both signs of the saliency and of the torque, the references give the torque
    /// within 1e-3 pu, and their |i| keeps at least 90 % of MTPA's gain: its excess over
    /// the least current that gives the torque is at most a tenth of i_d = 0's excess.
    #[test]
    fn salient_references_give_the_torque_at_the_least_current() {
        for k in [-0.3, -0.11, 0.05, 0.2] {
            let m = mtpa(k);
            let kq = f64::from(m.saliency.to_num::<f32>());
            for t in [0.05, 0.3, 0.8, 1.5, -0.6] {
                let r = m.references(Pu::from_num(t));
                let (d, q) = (r.d.to_num::<f64>(), r.q.to_num::<f64>());
                let torque = q * (1.0 + kq * d);
                assert!((torque - t).abs() < 1e-3, "k {k} t {t}: {torque}");
                let (least, ..) = least_current(kq, t.abs());
                let got = (d * d + q * q).sqrt();
                let plain = t.abs();
                assert!(
                    got - least <= 0.1 * (plain - least) + 1e-4,
                    "k {k} t {t}: {got} against the least {least} (i_d = 0: {plain})"
                );
                assert!(
                    d * kq >= 0.0,
                    "k {k} t {t}: d {d} adds no reluctance torque"
                );
                assert!(m.torque(r).to_num::<f64>() - torque < 1e-3);
            }
        }
    }

    /// A reference beyond the circle gets the curve's point on it, never more current.
    #[test]
    fn references_stay_within_the_current_circle() {
        for k in [-0.3, 0.2] {
            let m = mtpa(k);
            for t in [2.5f64, 10.0, -30.0, 32767.0] {
                let r = m.references(Pu::from_num(t));
                let (d, q) = (r.d.to_num::<f64>(), r.q.to_num::<f64>());
                assert!((d * d + q * q).sqrt() <= 2.0 + 1e-4, "k {k} t {t}");
                assert_eq!(q.signum(), t.signum());
            }
        }
    }
}
