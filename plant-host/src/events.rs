//! The event search: the guards that leave each contact mode, the cheap test of whether a
//! step may have crossed one, and, when it may have, the crossing time from the mode's Taylor
//! series (bracketed on [`SEARCH_SAMPLES`] samples, closed by bracketed Newton steps to
//! [`TIME_TOL_S`]).

use crate::config::BacklashModel;
use crate::model::{Contact, Mat5, Mat53, Shaft, Vec3, Vec5};
use short::{ShortGuards, TwistForm, finite};

mod short;

/// Most Taylor terms kept (‖A‖·h ≤ 0.5 needs ~20 for 1e-16).
const MAX_TERMS: usize = 28;
/// Samples per step when searching a polynomial for the first guard crossing.
const SEARCH_SAMPLES: u32 = 16;
/// Bisection stops when the crossing time is bracketed this tightly (s).
const TIME_TOL_S: f64 = 1e-15;

/// a·x for five terms: summed left to right from 0.0, the order nalgebra's `dot` uses for
/// this size, so the guard values are bit for bit those of the matrix form.
#[inline]
fn dot5(a: &[f64; 5], x: &Vec5) -> f64 {
    let [a0, a1, a2, a3, a4] = a;
    0.0 + a0 * x.x + a1 * x.y + a2 * x.z + a3 * x.w + a4 * x.a
}

/// a·x for three terms, as nalgebra sums them: a₀x₀ + a₁x₁ + a₂x₂ (no leading zero).
#[inline]
fn dot3(a: &[f64; 3], x: &Vec3) -> f64 {
    let [a0, a1, a2] = a;
    a0 * x.x + a1 * x.y + a2 * x.z
}

/// A linear function of the state, l(x) = c·x + k, and its rate l̇ = cA·x + cB·u in one mode.
#[derive(Debug, Clone, Copy)]
struct Linear {
    c: [f64; 5],
    k: f64,
    c_a: [f64; 5],
    c_b: [f64; 3],
}

impl Linear {
    fn new(c: [f64; 5], k: f64, a: &Mat5, b: &Mat53) -> Self {
        let cv = Vec5::from(c);
        let (c_a, c_b) = (a.transpose() * cv, b.transpose() * cv);
        Self {
            c,
            k,
            c_a: [c_a.x, c_a.y, c_a.z, c_a.w, c_a.a],
            c_b: [c_b.x, c_b.y, c_b.z],
        }
    }
    #[inline]
    fn value(&self, x: &Vec5) -> f64 {
        dot5(&self.c, x) + self.k
    }
    #[inline]
    fn rate(&self, x: &Vec5, u: &Vec3) -> f64 {
        dot5(&self.c_a, x) + dot3(&self.c_b, u)
    }
}

/// A mode change that fires when min(l₁, l₂) > 0 (one or two linear functions).
#[derive(Debug, Clone, Copy)]
struct Guard {
    lins: [Linear; 2],
    two: bool,
    target: Contact,
    /// The one part in [`TwistForm`], when it has that form.
    twist: Option<TwistForm>,
}

impl Guard {
    fn lins(&self) -> &[Linear] {
        let n = if self.two { 2 } else { 1 };
        self.lins.get(..n).unwrap_or(&[])
    }

    /// Could the guard fire within the step x0 → x1 of length h? Yes if it is positive at
    /// the end, or if some linear part has an interior maximum whose tangent-line bound
    /// reaches zero.
    #[inline]
    fn suspect(&self, x0: &Vec5, x1: &Vec5, u: &Vec3, h: f64) -> bool {
        let [l, m] = &self.lins;
        // min over the parts, from +∞ (a NaN part is skipped, as `f64::min` skips it).
        let mut end = f64::INFINITY.min(l.value(x1));
        if self.two {
            end = end.min(m.value(x1));
        }
        if end > 0.0 {
            return true;
        }
        l.peak_may_cross(x0, x1, u, h) || (self.two && m.peak_may_cross(x0, x1, u, h))
    }
}

impl Linear {
    /// An interior maximum within the step (the rate points out at the start and back in at
    /// the end) whose tangent-line bound reaches zero.
    #[inline]
    fn peak_may_cross(&self, x0: &Vec5, x1: &Vec5, u: &Vec3, h: f64) -> bool {
        let d0 = self.rate(x0, u);
        if d0 <= 0.0 {
            return false;
        }
        let d1 = self.rate(x1, u);
        if d1 >= 0.0 {
            return false;
        }
        peak_reaches_zero(self.value(x0), self.value(x1), d0, d1, h)
    }
}

/// Whether the tangent-line bound of an interior maximum reaches zero: l0, l1 the values at
/// the step's ends, d0 > 0 > d1 the rates there.
#[inline]
fn peak_reaches_zero(l0: f64, l1: f64, d0: f64, d1: f64, h: f64) -> bool {
    // Tangents at both ends meet above a concave arc: their intersection bounds the peak.
    let t = ((l1 - l0 - d1 * h) / (d0 - d1)).clamp(0.0, h);
    let peak = l0 + d0 * t;
    // Margin: the arc is only nearly concave over one step.
    peak > -0.5 * l0.abs().min(l1.abs())
}

/// The guards leaving one mode (none, one or two).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Guards {
    list: [Option<Guard>; 2],
    /// The same guards in short form, when they all have it.
    short: Option<ShortGuards>,
}

impl Guards {
    /// The guards leaving `contact` under `law`, for the mode's (A, B).
    pub(crate) fn new(
        contact: Contact,
        law: BacklashModel,
        s: &Shaft,
        a: &Mat5,
        b: &Mat53,
    ) -> Self {
        let list = guard_list(contact, law, s, a, b);
        Self {
            list,
            short: ShortGuards::of(&list),
        }
    }

    /// The cheap test after every step: may any guard have fired between x0 and x1?
    ///
    /// x1 must be the dense image of x0 (the exact map, or the Taylor series), so that a
    /// non-finite x0 leaves no component of x1 finite: then x1 finite means both are, and
    /// the guards in [`TwistForm`] take their short form.
    #[inline(always)]
    pub(crate) fn suspect(&self, x0: &Vec5, x1: &Vec5, u: &Vec3, h: f64) -> bool {
        match &self.short {
            Some(short) if finite(x1) => short.suspect(x0, x1, h),
            _ => self.suspect_dense(x0, x1, u, h),
        }
    }

    /// [`Self::suspect`] from the guards' full sums.
    #[inline(never)]
    fn suspect_dense(&self, x0: &Vec5, x1: &Vec5, u: &Vec3, h: f64) -> bool {
        let [g0, g1] = &self.list;
        g0.as_ref().is_some_and(|g| g.suspect(x0, x1, u, h))
            || g1.as_ref().is_some_and(|g| g.suspect(x0, x1, u, h))
    }

    /// The earliest crossing of any guard within (0, h] along `taylor`, and the mode it
    /// leads to.
    pub(crate) fn first_crossing(&self, taylor: &Taylor, h: f64) -> Option<(f64, Contact)> {
        let mut best: Option<(f64, Contact)> = None;
        for g in self.list.iter().flatten() {
            if let Some(t) = first_crossing(taylor, g, h)
                && best.is_none_or(|(tb, _)| t < tb)
            {
                best = Some((t, g.target));
            }
        }
        best
    }
}

/// Taylor coefficients of x(τ) = Σ d_k τ^k / k! in one mode from one start state.
pub(crate) struct Taylor {
    d: [Vec5; MAX_TERMS],
    n: usize,
}

impl Taylor {
    pub(crate) fn new(a: &Mat5, b: &Mat53, x0: &Vec5, u: &Vec3, horizon: f64) -> Self {
        let mut d = [Vec5::zeros(); MAX_TERMS];
        let scale = x0.amax().max(1.0);
        let mut n = 1;
        let mut prev = *x0;
        let mut fact_pow = 1.0; // horizon^k / k!
        for (k, slot) in d.iter_mut().enumerate() {
            *slot = if k == 0 {
                *x0
            } else if k == 1 {
                a * x0 + b * u
            } else {
                a * prev
            };
            prev = *slot;
            n = k + 1;
            if k > 0 {
                fact_pow *= horizon / k as f64;
                if slot.amax() * fact_pow < 1e-18 * scale && k > 2 {
                    break;
                }
            }
        }
        Self { d, n }
    }

    pub(crate) fn state(&self, tau: f64) -> Vec5 {
        // Horner: x = d0 + τ(d1 + τ/2 (d2 + τ/3 (...)))
        let mut acc = Vec5::zeros();
        for (k, dk) in self.d.iter().take(self.n).enumerate().rev() {
            acc = dk + acc * (tau / (k as f64 + 1.0));
        }
        acc
    }
}

/// The guard's linear parts as power series in τ (p_k = c·d_k / k!), so the crossing search
/// evaluates scalars only.
struct GuardPoly {
    coef: [[f64; MAX_TERMS]; 2],
    parts: usize,
    n: usize,
}

impl GuardPoly {
    fn new(t: &Taylor, g: &Guard) -> Self {
        let mut coef = [[0.0; MAX_TERMS]; 2];
        for (row, l) in coef.iter_mut().zip(g.lins()) {
            let c = Vec5::from(l.c);
            let mut inv_fact = 1.0;
            for (k, (p, dk)) in row.iter_mut().zip(t.d.iter().take(t.n)).enumerate() {
                if k > 0 {
                    inv_fact /= k as f64;
                }
                *p = c.dot(dk) * inv_fact;
            }
            if let Some(c0) = row.first_mut() {
                *c0 += l.k;
            }
        }
        Self {
            coef,
            parts: g.lins().len(),
            n: t.n,
        }
    }

    /// (value, d/dτ) of the smallest part (the guard is the minimum of its parts).
    fn eval(&self, tau: f64) -> (f64, f64) {
        self.coef
            .iter()
            .take(self.parts)
            .map(|row| {
                // Horner for p and p' together.
                let (mut p, mut dp) = (0.0, 0.0);
                for c in row.iter().take(self.n).rev() {
                    dp = dp * tau + p;
                    p = p * tau + c;
                }
                (p, dp)
            })
            .fold(
                (f64::INFINITY, 0.0),
                |best, x| if x.0 < best.0 { x } else { best },
            )
    }
}

/// Earliest τ in (0, h] where the guard is positive, to within [`TIME_TOL_S`]; returns the
/// right end of the final bracket so the state lands just past the edge. The first sign change
/// is bracketed on a grid of [`SEARCH_SAMPLES`], then closed by bracketed Newton steps.
fn first_crossing(t: &Taylor, g: &Guard, h: f64) -> Option<f64> {
    let poly = GuardPoly::new(t, g);
    let mut lo = 0.0;
    let mut hi = None;
    for j in 1..=SEARCH_SAMPLES {
        let tau = h * f64::from(j) / f64::from(SEARCH_SAMPLES);
        if poly.eval(tau).0 > 0.0 {
            hi = Some(tau);
            break;
        }
        lo = tau;
    }
    let mut hi = hi?;
    let mut x = 0.5 * (lo + hi);
    for _ in 0..100 {
        if hi - lo <= TIME_TOL_S {
            break;
        }
        let (f, df) = poly.eval(x);
        if f > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        x = next_point(x, f, df, lo, hi);
    }
    Some(hi)
}

/// The next point of the bracketed Newton search, from x (the guard's value f and slope df
/// there) in the bracket (lo, hi) that x has just narrowed: the Newton step x − f/df (the
/// midpoint where the slope is zero); when that moves less than half of [`TIME_TOL_S`], a
/// step of [`TIME_TOL_S`] across the root instead (down where f > 0, up otherwise), so the
/// bracket closes; and the midpoint wherever the point is not strictly inside the bracket.
fn next_point(x: f64, f: f64, df: f64, lo: f64, hi: f64) -> f64 {
    let mut next = if df != 0.0 {
        x - f / df
    } else {
        0.5 * (lo + hi)
    };
    if (next - x).abs() < 0.5 * TIME_TOL_S {
        next = if f > 0.0 {
            x - TIME_TOL_S
        } else {
            x + TIME_TOL_S
        };
    }
    if !(next > lo && next < hi) {
        next = 0.5 * (lo + hi);
    }
    next
}

/// The guards leaving `contact` under `law`.
fn guard_list(
    contact: Contact,
    law: BacklashModel,
    s: &Shaft,
    a: &Mat5,
    b: &Mat53,
) -> [Option<Guard>; 2] {
    let Shaft { k, d, g } = *s;
    if g == 0.0 && law == BacklashModel::DeadZone {
        return [None, None];
    }
    let lin = |c: [f64; 5], off: f64| Linear::new(c, off, a, b);
    let one = |l: Linear, target| {
        Some(Guard {
            lins: [l, l],
            two: false,
            target,
            twist: TwistForm::of(&l),
        })
    };
    let both = |l1: Linear, l2: Linear, target| {
        Some(Guard {
            lins: [l1, l2],
            two: true,
            target,
            twist: None,
        })
    };
    let delta = [1.0, 0.0, 0.0, 0.0, 0.0];
    let neg_delta = [-1.0, 0.0, 0.0, 0.0, 0.0];
    // F± = K·δ ∓ K·g + D·(ωm − ωl): the contact force with each edge.
    let force = [k, 0.0, d, -d, 0.0];
    let neg_force = [-k, 0.0, -d, d, 0.0];
    match (law, contact) {
        (BacklashModel::DeadZone, Contact::Free) => [
            one(lin(delta, -g), Contact::Driving),
            one(lin(neg_delta, -g), Contact::Braking),
        ],
        (BacklashModel::DeadZone, Contact::Driving) => {
            [one(lin(neg_delta, g), Contact::Free), None]
        }
        (BacklashModel::DeadZone, Contact::Braking) => [one(lin(delta, g), Contact::Free), None],
        (BacklashModel::Clamped, Contact::Free) => [
            both(lin(delta, -g), lin(force, -k * g), Contact::Driving),
            both(lin(neg_delta, -g), lin(neg_force, -k * g), Contact::Braking),
        ],
        // The force reaches zero no later than the twist reaches the edge (D ≥ 0).
        (BacklashModel::Clamped, Contact::Driving) => {
            [one(lin(neg_force, k * g), Contact::Free), None]
        }
        (BacklashModel::Clamped, Contact::Braking) => [one(lin(force, k * g), Contact::Free), None],
    }
}

#[cfg(test)]
mod tests;
