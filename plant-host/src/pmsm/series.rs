//! The Taylor-series step of the PMSM and the mechanics in one contact mode, with the
//! inverter's voltage vector and the load torque held.
//!
//! Inside a mode the equations are a polynomial (quadratic) system once the rotor's
//! cos θe and sin θe are states (d/dt cos θe = −Ω·sin θe, d/dt sin θe = Ω·cos θe,
//! Ω = p·ω_b·ωm): the products are ωm·i_q, ωm·i_d, i_d·i_q, ωm·sin θe and ωm·cos θe. The
//! Taylor coefficients of the solution then follow exactly from the recursion
//! (k+1)·x_{k+1} = f_k, where the k-th coefficient of a product is the Cauchy sum
//! Σ_j a_j·b_{k−j}. The series is summed until two successive terms are below
//! [`TOLERANCE`] of their variable (plus 1), so the truncation error is under round-off
//! ("order" is chosen per step, at most [`MAX_TERMS`] − 1); a step whose series has not
//! converged by then is halved. The series is also the dense output the event search
//! samples.

/// Most Taylor terms (order + 1).
pub(crate) const MAX_TERMS: usize = 28;
/// A term this small against its variable (plus 1) is below round-off: 2^-60.
const TOLERANCE: f64 = 8.673_617_379_884_035e-19;

/// The state with the rotor's cosine and sine: twist δ (rad), load angle θl (rad), motor
/// and load speed (pu), d and q current (pu), cos θe, sin θe.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Vars {
    pub delta: f64,
    pub theta_l: f64,
    pub w_m: f64,
    pub w_l: f64,
    pub i_d: f64,
    pub i_q: f64,
    pub cos: f64,
    pub sin: f64,
}

impl Vars {
    /// Each variable mapped.
    fn map(&self, f: impl Fn(f64) -> f64) -> Self {
        Self {
            delta: f(self.delta),
            theta_l: f(self.theta_l),
            w_m: f(self.w_m),
            w_l: f(self.w_l),
            i_d: f(self.i_d),
            i_q: f(self.i_q),
            cos: f(self.cos),
            sin: f(self.sin),
        }
    }

    /// `self·t + next`, each variable (one Horner step). A product and a sum, not
    /// `f64::mul_add`: without the target's FMA instructions (x86-64's baseline has none)
    /// `mul_add` is a software call, and it was 40 % of a PMSM run.
    fn horner(&self, t: f64, next: &Self) -> Self {
        let h = |a: f64, b: f64| a * t + b;
        Self {
            delta: h(self.delta, next.delta),
            theta_l: h(self.theta_l, next.theta_l),
            w_m: h(self.w_m, next.w_m),
            w_l: h(self.w_l, next.w_l),
            i_d: h(self.i_d, next.i_d),
            i_q: h(self.i_q, next.i_q),
            cos: h(self.cos, next.cos),
            sin: h(self.sin, next.sin),
        }
    }

    /// Whether every variable's |self| is at most its `limit`.
    fn within(&self, limit: &Self) -> bool {
        let ok = |a: f64, l: f64| a.abs() <= l;
        ok(self.delta, limit.delta)
            && ok(self.theta_l, limit.theta_l)
            && ok(self.w_m, limit.w_m)
            && ok(self.w_l, limit.w_l)
            && ok(self.i_d, limit.i_d)
            && ok(self.i_q, limit.i_q)
            && ok(self.cos, limit.cos)
            && ok(self.sin, limit.sin)
    }

    /// Phase currents (a, b, c) of the d/q current at this angle (amplitude-invariant).
    pub fn phase_currents(&self) -> [f64; 3] {
        let alpha = self.cos * self.i_d - self.sin * self.i_q;
        let beta = self.sin * self.i_d + self.cos * self.i_q;
        crate::pmsm::machine::inverse_clarke([alpha, beta])
    }
}

/// The constants of the equations in one mode, with the inputs held.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Equations {
    /// ω_b, rad/s per pu.
    pub wb: f64,
    /// 1/Jm, 1/Jl (0 when the load is locked), 1/s.
    pub inv_jm: f64,
    pub inv_jl: f64,
    /// Bm, Bl, pu.
    pub bm: f64,
    pub bl: f64,
    /// The shaft law in this mode: Ts = k·δ + d·(ωm − ωl) + ts0.
    pub k: f64,
    pub d: f64,
    pub ts0: f64,
    /// Load torque, pu.
    pub tl: f64,
    /// R, pu; Ld, Lq, pu·s; λ, pu; p·ω_b, rad/s per pu; p·ω_b·(Ld − Lq), pu.
    pub r: f64,
    pub ld: f64,
    pub lq: f64,
    pub flux: f64,
    pub pw: f64,
    pub saliency: f64,
    /// The voltage vector (α, β), pu.
    pub v_alpha: f64,
    pub v_beta: f64,
    /// 1 while the inverter's switches conduct; 0 while they are open and the currents
    /// are held at zero (`off`).
    pub conducting: f64,
}

impl Equations {
    /// The k-th Taylor coefficient of the right-hand side, from the coefficients 0..=k
    /// of the solution (`done`, last one k).
    fn rate(&self, done: &[Vars], first: bool) -> Vars {
        // The five Cauchy sums Σ_j a_j·b_{k−j}, each summed in j order from −0.0 (as
        // `Iterator::sum` does), in one pass.
        let (mut wm_iq, mut wm_id, mut id_iq, mut wm_sin, mut wm_cos) =
            (-0.0, -0.0, -0.0, -0.0, -0.0);
        for (a, b) in done.iter().zip(done.iter().rev()) {
            wm_iq += a.w_m * b.i_q;
            wm_id += a.w_m * b.i_d;
            id_iq += a.i_d * b.i_q;
            wm_sin += a.w_m * b.sin;
            wm_cos += a.w_m * b.cos;
        }
        let x = done.last().copied().unwrap_or_default();
        let once = |c: f64| if first { c } else { 0.0 };
        let rel = x.w_m - x.w_l;
        let ts = self.k * x.delta + self.d * rel + once(self.ts0);
        let te = self.flux * x.i_q + self.saliency * id_iq;
        // The voltage in the rotor frame: v_dq = Park(θe)·v_αβ, linear in (cos, sin).
        let v_d = self.v_alpha * x.cos + self.v_beta * x.sin;
        let v_q = self.v_beta * x.cos - self.v_alpha * x.sin;
        Vars {
            delta: self.wb * rel,
            theta_l: self.wb * x.w_l,
            w_m: (te - ts - self.bm * x.w_m) * self.inv_jm,
            w_l: (ts - once(self.tl) - self.bl * x.w_l) * self.inv_jl,
            i_d: self.conducting * (v_d - self.r * x.i_d + self.pw * self.lq * wm_iq) / self.ld,
            i_q: self.conducting
                * (v_q - self.r * x.i_q - self.pw * self.ld * wm_id - self.flux * x.w_m)
                / self.lq,
            cos: -self.pw * wm_sin,
            sin: self.pw * wm_cos,
        }
    }
}

/// The Taylor series of one step from `x0` over `h`.
#[derive(Debug, Clone)]
pub(crate) struct Series {
    terms: [Vars; MAX_TERMS],
    len: usize,
    h: f64,
    converged: bool,
}

impl Default for Series {
    fn default() -> Self {
        Self {
            terms: [Vars::default(); MAX_TERMS],
            len: 1,
            h: 0.0,
            converged: false,
        }
    }
}

impl Series {
    /// The series of `eq` from `x0` over a step of `h`, summed until two successive terms
    /// (times h^k) are below round-off, or [`MAX_TERMS`] (then [`Self::converged`] is
    /// false).
    #[cfg(test)]
    pub fn new(eq: &Equations, x0: &Vars, h: f64) -> Self {
        let mut series = Self::default();
        series.fill(eq, x0, h);
        series
    }

    /// [`Self::new`] in place: the plant keeps one series and refills it each step, so
    /// that no step clears or copies its [`MAX_TERMS`] terms.
    pub fn fill(&mut self, eq: &Equations, x0: &Vars, h: f64) {
        if let Some(t0) = self.terms.first_mut() {
            *t0 = *x0;
        }
        // |term·h^k| / (1 + |x0|) ≤ TOLERANCE, as |term·h^k| ≤ TOLERANCE·(1 + |x0|): a power
        // of two times the denominator, exact.
        let limit = x0.map(|v| TOLERANCE * (1.0 + v.abs()));
        let mut len = 1;
        let mut small_before = false;
        let mut converged = false;
        let mut hk = 1.0;
        for k in 0..MAX_TERMS - 1 {
            let (done, rest) = self.terms.split_at_mut(k + 1);
            let Some(next) = rest.first_mut() else { break };
            let f = eq.rate(done, k == 0);
            let inv = 1.0 / (k as f64 + 1.0);
            *next = f.map(|v| v * inv);
            len = k + 2;
            hk *= h;
            let small = next.map(|v| v * hk).within(&limit);
            if small && small_before {
                converged = true;
                break;
            }
            small_before = small;
        }
        self.len = len;
        self.h = h;
        self.converged = converged;
    }

    /// Whether the terms fell below round-off within [`MAX_TERMS`].
    pub fn converged(&self) -> bool {
        self.converged
    }

    /// The step length, s.
    pub fn h(&self) -> f64 {
        self.h
    }

    /// The number of terms summed (the order + 1).
    #[cfg(test)]
    pub fn terms(&self) -> usize {
        self.len
    }

    /// The state at `tau` (0 ≤ τ ≤ h), by Horner.
    pub fn at(&self, tau: f64) -> Vars {
        let used = self.terms.iter().take(self.len).rev();
        used.fold(None::<Vars>, |acc, term| {
            Some(acc.map_or(*term, |a| a.horner(tau, term)))
        })
        .unwrap_or_default()
    }

    /// For each variable, Σ_{k≥1} |x_k|·h^k: a bound of how far it moves from its start
    /// within the step (of the polynomial, which is the solution to round-off).
    pub fn spread(&self) -> Vars {
        let mut hk = 1.0;
        let mut out = Vars::default();
        for term in self.terms.iter().take(self.len).skip(1) {
            hk *= self.h;
            let a = term.map(|v| v.abs() * hk);
            out = Vars {
                delta: out.delta + a.delta,
                theta_l: out.theta_l + a.theta_l,
                w_m: out.w_m + a.w_m,
                w_l: out.w_l + a.w_l,
                i_d: out.i_d + a.i_d,
                i_q: out.i_q + a.i_q,
                cos: out.cos + a.cos,
                sin: out.sin + a.sin,
            };
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn still() -> Equations {
        Equations {
            wb: 100.0,
            inv_jm: 10.0,
            inv_jl: 2.0,
            bm: 0.0,
            bl: 0.0,
            k: 0.0,
            d: 0.0,
            ts0: 0.0,
            tl: 0.0,
            r: 0.05,
            ld: 5e-4,
            lq: 5e-4,
            flux: 1.0,
            pw: 400.0,
            saliency: 0.0,
            v_alpha: 0.0,
            v_beta: 0.0,
            conducting: 1.0,
        }
    }

    /// A spinning rotor with no current and no torque: the angle's cosine and sine rotate
    /// exactly (ωm is constant), and the q current rises against the back-EMF.
    #[test]
    fn a_free_rotor_turns_its_cosine_and_sine() {
        let eq = Equations {
            flux: 0.0,
            ..still()
        };
        let x0 = Vars {
            w_m: 1.0,
            cos: 1.0,
            ..Vars::default()
        };
        let h = 250e-6;
        let s = Series::new(&eq, &x0, h);
        assert!(s.converged() && s.terms() < MAX_TERMS, "{}", s.terms());
        let x = s.at(h);
        let th = 400.0 * h;
        assert!((x.cos - th.cos()).abs() < 1e-15 && (x.sin - th.sin()).abs() < 1e-15);
        assert!((x.theta_l).abs() < 1e-18 && (x.delta - 100.0 * h).abs() < 1e-16);
        // The spread bounds the motion: the cosine moves by 1 − cos(0.1) ≈ 5e-3.
        let spread = s.spread();
        assert!(
            spread.cos >= (1.0 - x.cos) && spread.cos < 0.01,
            "{}",
            spread.cos
        );
    }
}
