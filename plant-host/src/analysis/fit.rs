//! Fitting the two-inertia model to a measured frequency response from motor torque to
//! motor position.
//!
//! The model is the engaged plant of [`super::EngagedPlant`], in per unit, with a pure
//! delay τ for what lies between the recorded torque and position: the zero-order hold,
//! the sampling instant of the current, and the computational delay. With
//! Z(s) = K·ω_b/s + D, the shaft's impedance on the speed difference:
//!
//!   ωm/Tm = (Jl·s + Bl + Z) / ((Jm·s + Bm)·(Jl·s + Bl + Z) + Z·(Jl·s + Bl))
//!   θm/Tm = e^(−s·τ)·ω_b·(ωm/Tm)/s          \[rad per pu torque\]
//!
//! with K = Jl·ω_ar²/ω_b and D = 2·ζ·Jl·ω_ar (the design notes' formulas). Only the sum
//! Bm + Bl of the viscous frictions shows in motor-side data, so the fit reports it as
//! one figure, `viscous_pu`.
//!
//! The fit is Levenberg–Marquardt on the complex log ratio ln(H_measured/H_model): its
//! real part is the magnitude error in nepers and its imaginary part the phase error in
//! radians. Each bin is weighted by √(2·n·γ²/(1 − γ²)) for n averaged segments, the inverse
//! of the estimate's standard error (Bendat and Piersol).
//! Bins with γ² below `min_coherence` are left out. The parameters are Jm, Jl, f_ar and
//! ζ (fitted as logarithms, so they stay positive), Bm + Bl and τ. Their standard errors
//! come from the covariance s²·(JᵀJ)⁻¹ at the optimum.

use super::frf::MeasuredResponse;
use nalgebra::{Complex, DMatrix, DVector};
use std::f64::consts::PI;

/// The two-inertia parameters of a fit (or a starting point).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoInertiaFit {
    /// Motor inertia Jm \[s\].
    pub motor_inertia_s: f64,
    /// Load inertia Jl \[s\].
    pub load_inertia_s: f64,
    /// Anti-resonance f_ar \[Hz\].
    pub anti_resonance_hz: f64,
    /// Shaft damping ratio ζ.
    pub shaft_damping_ratio: f64,
    /// Bm + Bl \[pu torque per pu speed\].
    pub viscous_pu: f64,
    /// Delay between the recorded torque and position \[s\].
    pub delay_s: f64,
}

impl TwoInertiaFit {
    /// The engaged resonance f_r = f_ar·√(1 + Jl/Jm) \[Hz\].
    #[must_use]
    pub fn resonance_hz(&self) -> f64 {
        self.anti_resonance_hz * (1.0 + self.load_inertia_s / self.motor_inertia_s).sqrt()
    }

    /// θm/Tm at `freq_hz` \[rad per pu torque\], for base speed ω_b \[rad/s per pu\].
    #[must_use]
    pub fn response(&self, freq_hz: f64, base_speed_rad_s: f64) -> Complex<f64> {
        let w = 2.0 * PI * freq_hz;
        let s = Complex::new(0.0, w);
        let war = 2.0 * PI * self.anti_resonance_hz;
        let (jm, jl) = (self.motor_inertia_s, self.load_inertia_s);
        let k = jl * war * war / base_speed_rad_s;
        let d = 2.0 * self.shaft_damping_ratio * jl * war;
        let z = k * base_speed_rad_s / s + d;
        // The friction is split evenly for the model; only its sum is observable here.
        let (bm, bl) = (0.5 * self.viscous_pu, 0.5 * self.viscous_pu);
        let load = s * jl + bl + z;
        let speed = load / ((s * jm + bm) * load + z * (s * jl + bl));
        Complex::from_polar(1.0, -w * self.delay_s) * speed * base_speed_rad_s / s
    }

    fn to_params(self) -> [f64; 6] {
        [
            self.motor_inertia_s.ln(),
            self.load_inertia_s.ln(),
            self.anti_resonance_hz.ln(),
            self.shaft_damping_ratio.ln(),
            self.viscous_pu,
            self.delay_s,
        ]
    }

    fn from_params(p: &[f64; 6]) -> Self {
        Self {
            motor_inertia_s: p[0].exp(),
            load_inertia_s: p[1].exp(),
            anti_resonance_hz: p[2].exp(),
            shaft_damping_ratio: p[3].exp(),
            viscous_pu: p[4],
            delay_s: p[5],
        }
    }
}

/// A fit and the standard error of each parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitResult {
    /// The fitted parameters.
    pub fit: TwoInertiaFit,
    /// Standard errors of the parameters (same units; for the four positive parameters,
    /// from their relative error in the log fit).
    pub std_error: TwoInertiaFit,
    /// Root mean square of the weighted residuals (about 1 for a model that explains the
    /// data to within its noise).
    pub weighted_rms: f64,
    /// Bins used.
    pub bins: usize,
    /// Levenberg–Marquardt iterations taken.
    pub iterations: usize,
}

/// Why a fit failed.
#[derive(Debug, Clone, PartialEq)]
pub enum FitError {
    /// Fewer than 12 bins pass the coherence threshold.
    TooFewBins {
        /// Bins that passed.
        usable: usize,
    },
    /// The measured response shows no anti-resonance dip followed by a resonance peak.
    NoResonance,
    /// The normal equations were singular (the data do not determine the parameters).
    Singular,
}

impl std::fmt::Display for FitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TooFewBins { usable } => write!(
                f,
                "only {usable} frequency bins have enough coherence; at least 12 are needed \
                 (raise the excitation amplitude or its length)"
            ),
            Self::NoResonance => write!(
                f,
                "no anti-resonance and resonance found in the measured band \
                 (widen the excitation band)"
            ),
            Self::Singular => write!(f, "the data do not determine the model's parameters"),
        }
    }
}

impl std::error::Error for FitError {}

struct Bin {
    freq_hz: f64,
    h: Complex<f64>,
    weight: f64,
}

/// A starting point from the response's shape, through the apparent inertia
/// J(f) = ω_b/(|H|·ω²): its peak is the anti-resonance f_ar (the motor seems immovable),
/// the dip after it the resonance f_r, and its level below f_ar the total inertia. Then
/// Jm = J_total·(f_ar/f_r)², from f_r² = f_ar²·(1 + Jl/Jm).
fn initial_guess(bins: &[Bin], base_speed_rad_s: f64) -> Result<TwoInertiaFit, FitError> {
    let inertia: Vec<f64> = bins
        .iter()
        .map(|b| base_speed_rad_s / (b.h.norm() * (2.0 * PI * b.freq_hz).powi(2)))
        .collect();
    let arg_best = |range: std::ops::Range<usize>, better: fn(f64, f64) -> bool| {
        range.fold(None, |best: Option<usize>, i| {
            match (best, inertia.get(i)) {
                (Some(b), Some(&v)) if !better(v, inertia.get(b).copied().unwrap_or(v)) => Some(b),
                (_, Some(_)) => Some(i),
                (b, None) => b,
            }
        })
    };
    let ar = arg_best(0..bins.len(), |v, best| v > best).ok_or(FitError::NoResonance)?;
    let r = arg_best(ar + 1..bins.len(), |v, best| v < best).ok_or(FitError::NoResonance)?;
    let (f_ar, f_r) = match (bins.get(ar), bins.get(r)) {
        (Some(a), Some(b)) if ar > 0 && r + 1 < bins.len() => (a.freq_hz, b.freq_hz),
        _ => return Err(FitError::NoResonance),
    };
    // Total inertia: the median apparent inertia below f_ar/2 (or the lowest bin).
    let mut low: Vec<f64> = bins
        .iter()
        .zip(&inertia)
        .filter(|(b, _)| b.freq_hz < 0.5 * f_ar)
        .map(|(_, j)| *j)
        .collect();
    low.sort_by(f64::total_cmp);
    let j_total = low
        .get(low.len() / 2)
        .or(inertia.first())
        .copied()
        .ok_or(FitError::NoResonance)?;
    let jm = j_total * (f_ar / f_r).powi(2);
    if !(jm > 0.0 && j_total > jm && j_total.is_finite()) {
        return Err(FitError::NoResonance);
    }
    Ok(TwoInertiaFit {
        motor_inertia_s: jm,
        load_inertia_s: j_total - jm,
        anti_resonance_hz: f_ar,
        shaft_damping_ratio: 0.05,
        viscous_pu: 0.0,
        delay_s: 0.0,
    })
}

fn residuals(bins: &[Bin], p: &[f64; 6], wb: f64) -> DVector<f64> {
    let model = TwoInertiaFit::from_params(p);
    let mut r = DVector::zeros(2 * bins.len());
    for (i, b) in bins.iter().enumerate() {
        let ratio = b.h / model.response(b.freq_hz, wb);
        let l = ratio.ln();
        if let Some(v) = r.get_mut(2 * i) {
            *v = b.weight * l.re;
        }
        if let Some(v) = r.get_mut(2 * i + 1) {
            *v = b.weight * l.im;
        }
    }
    r
}

/// Fit the two-inertia model to `measured` (θm/Tm in rad per pu torque) over the bins
/// with γ² ≥ `min_coherence` and frequency ≤ `max_freq_hz`.
pub fn fit_two_inertia(
    measured: &MeasuredResponse,
    base_speed_rad_s: f64,
    min_coherence: f64,
    max_freq_hz: f64,
) -> Result<FitResult, FitError> {
    let segments = measured.segments as f64;
    let bins: Vec<Bin> = measured
        .freq_hz
        .iter()
        .zip(&measured.h)
        .zip(&measured.coherence)
        .filter(|((f, h), g)| {
            **g >= min_coherence && **f <= max_freq_hz && h.re.is_finite() && h.im.is_finite()
        })
        .map(|((&freq_hz, &h), &g)| Bin {
            freq_hz,
            h,
            weight: (2.0 * segments * g / (1.0 - g).max(1e-6)).sqrt(),
        })
        .collect();
    if bins.len() < 12 {
        return Err(FitError::TooFewBins { usable: bins.len() });
    }
    let wb = base_speed_rad_s;
    let mut p = initial_guess(&bins, wb)?.to_params();
    let mut r = residuals(&bins, &p, wb);
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut jac = DMatrix::zeros(r.len(), 6);
    while iterations < 200 {
        iterations += 1;
        // Forward-difference Jacobian, steps scaled to each parameter.
        for j in 0..6 {
            let mut q = p;
            let h = match j {
                4 => 1e-6 * (1.0 + p[4].abs()),
                5 => 1e-8,
                _ => 1e-6,
            };
            if let Some(v) = q.get_mut(j) {
                *v += h;
            }
            let rj = residuals(&bins, &q, wb);
            jac.set_column(j, &((rj - &r) / h));
        }
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * &r;
        let mut improved = false;
        while lambda < 1e12 {
            // Marquardt's scaling: λ times the diagonal of JᵀJ.
            let mut a = jtj.clone();
            a.set_diagonal(&jtj.diagonal().map(|d| d + lambda * d.max(1e-12)));
            let Some(step) = a.lu().solve(&(-&jtr)) else {
                lambda *= 10.0;
                continue;
            };
            let mut q = p;
            for (qj, sj) in q.iter_mut().zip(step.iter()) {
                *qj += sj;
            }
            let rq = residuals(&bins, &q, wb);
            let cq = rq.norm_squared();
            if cq.is_finite() && cq < cost {
                let rel = (cost - cq) / cost;
                p = q;
                r = rq;
                cost = cq;
                lambda = (lambda * 0.3).max(1e-9);
                improved = rel > 1e-12;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let jtj = jac.transpose() * &jac;
    let cov = jtj.try_inverse().ok_or(FitError::Singular)?;
    let dof = (r.len() as f64 - 6.0).max(1.0);
    let s2 = cost / dof;
    let var = cov.diagonal();
    let sd = |j: usize| (s2 * var.get(j).copied().unwrap_or(0.0)).max(0.0).sqrt();
    let fit = TwoInertiaFit::from_params(&p);
    Ok(FitResult {
        fit,
        std_error: TwoInertiaFit {
            motor_inertia_s: fit.motor_inertia_s * sd(0),
            load_inertia_s: fit.load_inertia_s * sd(1),
            anti_resonance_hz: fit.anti_resonance_hz * sd(2),
            shaft_damping_ratio: fit.shaft_damping_ratio * sd(3),
            viscous_pu: sd(4),
            delay_s: sd(5),
        },
        weighted_rms: (cost / r.len() as f64).sqrt(),
        bins: bins.len(),
        iterations,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing)]
    use super::*;
    use crate::analysis::EngagedPlant;
    use crate::MechanicsConfig;

    fn table1_like() -> MechanicsConfig {
        MechanicsConfig {
            base_speed_rpm: 1000.0,
            motor_inertia_s: 0.12,
            load_inertia_s: 0.86,
            anti_resonance_hz: 22.0,
            shaft_damping_ratio: 0.05,
            backlash_deg: 0.0,
            motor_viscous_pu: 0.01,
            load_viscous_pu: 0.01,
        }
    }

    /// The closed form above is the engaged plant's state-space response.
    #[test]
    fn model_matches_the_state_space_plant() {
        let m = table1_like();
        let wb = m.derived().base_speed_rad_s;
        let fit = TwoInertiaFit {
            motor_inertia_s: m.motor_inertia_s,
            load_inertia_s: m.load_inertia_s,
            anti_resonance_hz: m.anti_resonance_hz,
            shaft_damping_ratio: m.shaft_damping_ratio,
            viscous_pu: m.motor_viscous_pu + m.load_viscous_pu,
            delay_s: 0.0,
        };
        let plant = EngagedPlant::new(&m);
        for f in [0.5, 5.0, 21.0, 22.0, 60.0, 65.0, 300.0] {
            let w = 2.0 * PI * f;
            let Some(r) = plant.response(w) else {
                unreachable!("pole at {f} Hz")
            };
            let want = r.motor_speed_per_motor_torque * wb / Complex::new(0.0, w);
            let got = fit.response(f, wb);
            assert!((got / want - 1.0).norm() < 1e-9, "{f}: {got} vs {want}");
        }
    }

    /// Exact model data with coherence-weighted noise: the fit recovers every parameter.
    #[test]
    fn fit_recovers_a_known_plant() {
        let wb = 2.0 * PI * 1000.0 / 60.0;
        let truth = TwoInertiaFit {
            motor_inertia_s: 0.117,
            load_inertia_s: 0.863,
            anti_resonance_hz: 22.5,
            shaft_damping_ratio: 0.04,
            viscous_pu: 0.02,
            delay_s: 3.7e-4,
        };
        let mut seed = 7u64;
        let mut noise = || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let freq_hz: Vec<f64> = (1..=400).map(|k| f64::from(k) * 0.5).collect();
        let h = freq_hz
            .iter()
            .map(|&f| {
                let e = Complex::new(0.02 * noise(), 0.02 * noise());
                truth.response(f, wb) * e.exp()
            })
            .collect();
        let measured = MeasuredResponse {
            coherence: vec![0.99; freq_hz.len()],
            freq_hz,
            h,
            segments: 50,
        };
        let r = fit_two_inertia(&measured, wb, 0.8, 1000.0).unwrap_or_else(|e| unreachable!("{e}"));
        let rel = |a: f64, b: f64| (a / b - 1.0).abs();
        assert!(
            rel(r.fit.motor_inertia_s, truth.motor_inertia_s) < 0.005,
            "{r:?}"
        );
        assert!(
            rel(r.fit.load_inertia_s, truth.load_inertia_s) < 0.005,
            "{r:?}"
        );
        assert!(
            rel(r.fit.anti_resonance_hz, truth.anti_resonance_hz) < 0.002,
            "{r:?}"
        );
        assert!(
            rel(r.fit.shaft_damping_ratio, truth.shaft_damping_ratio) < 0.05,
            "{r:?}"
        );
        assert!((r.fit.delay_s - truth.delay_s).abs() < 2e-5, "{r:?}");
        assert!(
            rel(r.fit.resonance_hz(), truth.resonance_hz()) < 0.002,
            "{r:?}"
        );
        // The stated errors are consistent with the actual ones.
        assert!(
            (r.fit.motor_inertia_s - truth.motor_inertia_s).abs()
                < 5.0 * r.std_error.motor_inertia_s
        );
        assert!(
            (r.fit.load_inertia_s - truth.load_inertia_s).abs() < 5.0 * r.std_error.load_inertia_s
        );
    }

    #[test]
    fn too_little_coherence_is_an_error() {
        let measured = MeasuredResponse {
            freq_hz: vec![1.0; 30],
            h: vec![Complex::new(1.0, 0.0); 30],
            coherence: vec![0.5; 30],
            segments: 2,
        };
        assert_eq!(
            fit_two_inertia(&measured, 100.0, 0.8, 1000.0),
            Err(FitError::TooFewBins { usable: 0 })
        );
    }
}
