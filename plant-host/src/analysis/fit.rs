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
//! with K = Jl·ω_ar²/ω_b and D = 2·ζ·Jl·ω_ar (the formulas in `plant-host/README.md`). Only the sum
//! Bm + Bl of the viscous frictions shows in motor-side data, so the fit reports it as
//! one figure, `viscous_pu`.
//!
//! The fit is Levenberg–Marquardt on the complex log ratio ln(H_measured/H_model): its
//! real part is the magnitude error in nepers and its imaginary part the phase error in
//! radians. Each bin is weighted by √(2·n·γ²/(1 − γ²)) for n averaged segments, the inverse
//! of the estimate's standard error (Bendat and Piersol).
//! Bins with γ² below `min_coherence` are left out. The parameters are Jm, Jl, f_ar and
//! ζ (fitted as logarithms, so they stay positive), Bm + Bl and τ, the last two held at
//! zero or above (a projected step: a bound parameter the step would take below zero is
//! fixed at zero for that step, [`NON_NEGATIVE`]). Their standard errors come from the
//! covariance s²·(JᵀJ)⁻¹ at the optimum.

use super::MeasuredResponse;
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

/// Where Levenberg–Marquardt stopped: parameters, residuals, cost, the last Jacobian.
struct Optimum {
    p: [f64; 6],
    r: DVector<f64>,
    cost: f64,
    jac: DMatrix<f64>,
    iterations: usize,
}

/// The parameters held at zero or above: Bm + Bl (a friction) and τ (a delay).
const NON_NEGATIVE: [usize; 2] = [4, 5];

/// The Levenberg–Marquardt step for the damped normal equations `a`·step = −`jtr`, with
/// the parameters of [`NON_NEGATIVE`] that the step would take below zero from `p` fixed
/// (their step 0, the others solved again without them). `None` if `a` is singular.
fn projected_step(a: &DMatrix<f64>, jtr: &DVector<f64>, p: &[f64; 6]) -> Option<DVector<f64>> {
    let mut fixed = [false; 6];
    let mut step = a.clone().lu().solve(&(-jtr))?;
    for _ in 0..NON_NEGATIVE.len() {
        let mut changed = false;
        for &j in &NON_NEGATIVE {
            let (pj, sj) = (p.get(j).copied()?, step.get(j).copied()?);
            let f = fixed.get_mut(j)?;
            if !*f && pj + sj < 0.0 {
                *f = true;
                changed = true;
            }
        }
        if !changed {
            break;
        }
        let mut b = a.clone();
        let mut rhs = -jtr;
        for (j, _) in fixed.iter().enumerate().filter(|(_, f)| **f) {
            b.fill_row(j, 0.0);
            b.fill_column(j, 0.0);
            *b.get_mut((j, j))? = 1.0;
            *rhs.get_mut(j)? = -p.get(j).copied()?;
        }
        step = b.lu().solve(&rhs)?;
    }
    Some(step)
}

/// Levenberg–Marquardt from `start` (at most 200 iterations, Marquardt's scaling, stops
/// when a step gains less than 1e-12 relative).
fn levenberg_marquardt(bins: &[Bin], start: [f64; 6], wb: f64) -> Optimum {
    let mut p = start;
    let mut r = residuals(bins, &p, wb);
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
            let rj = residuals(bins, &q, wb);
            jac.set_column(j, &((rj - &r) / h));
        }
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * &r;
        let mut improved = false;
        while lambda < 1e12 {
            // Marquardt's scaling: λ times the diagonal of JᵀJ.
            let mut a = jtj.clone();
            a.set_diagonal(&jtj.diagonal().map(|d| d + lambda * d.max(1e-12)));
            let Some(step) = projected_step(&a, &jtr, &p) else {
                lambda *= 10.0;
                continue;
            };
            let mut q = p;
            for (qj, sj) in q.iter_mut().zip(step.iter()) {
                *qj += sj;
            }
            let rq = residuals(bins, &q, wb);
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
    Optimum {
        p,
        r,
        cost,
        jac,
        iterations,
    }
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
    let mut start = initial_guess(&bins, wb)?.to_params();
    for &j in &NON_NEGATIVE {
        if let Some(v) = start.get_mut(j) {
            *v = v.max(0.0);
        }
    }
    let Optimum {
        p,
        r,
        cost,
        jac,
        iterations,
    } = levenberg_marquardt(&bins, start, wb);
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
    use super::*;

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
