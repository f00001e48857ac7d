//! The whole discrete loop as one linear map over a velocity period: the exactly sampled
//! plant ([`plant_host::analysis::SampledPlant`]), the computational delay and the
//! controller mirror ([`super::mirror`]), in the runner's order within each current tick:
//!
//! 1. sample the encoder and the current;
//! 2. on every n-th tick, the velocity tick;
//! 3. the current tick;
//! 4. the plant over the tick, with the previous voltage for the delay's remainder and the
//!    new one after it (a delay of whole ticks shifts the commands first).
//!
//! Stacking the plant (5), the delayed commands and the controller
//! ([`Coefficients::state_len`]: the notch's two states only with a notch),
//! one velocity period is z⁺ = M·z + inputs. M is read off the mirror by probing it with
//! unit vectors: the mirror is exactly linear, so this is exact. The poles are the
//! eigenvalues of M, and the damping of each is that of s = ln(λ)/T_v.
//!
//! Two invariances are removed before the damping is judged, because they are not
//! dynamics of the loop:
//! - In speed mode (no position loop), shifting every position at once leaves the loop
//!   unchanged, so M has an eigenvalue exactly 1 on that direction. It is deflated.
//! - With the gears apart, the load coasts on its own. Its states are dropped.

use super::hessenberg::HessenbergResponse;
use super::margins::{Margins, margin_grid, margins_of, refined};
use super::mirror::{Break, Coefficients, Inputs, State};
use super::reduce::{deflate, drop_unused};
use nalgebra::{Complex, DMatrix, DVector};
use plant_host::PlantConfig;
use plant_host::analysis::{Gears, SampledPlant, state};
use std::f64::consts::PI;
use std::sync::OnceLock;

/// The period map with the loop opened at one break: M, the break input column B_w, the
/// break output row C and the feed-through D (reported = C·z + D·w).
type Maps = (DMatrix<f64>, DVector<f64>, DVector<f64>, f64);

/// The linear loop of one drive, plant and contact state.
#[derive(Debug, Clone)]
pub struct LoopModel {
    coef: Coefficients,
    plant: SampledPlant,
    gears: Gears,
    /// Encoder counts per motor radian (as the drive reads them).
    counts_per_rad: f64,
    /// Whole ticks of computational delay.
    whole_delay: usize,
    /// Velocity period \[s\].
    period_s: f64,
    /// ω_b \[rad/s per pu\].
    base_speed_rad_s: f64,
    /// The period maps, computed on first use: one per [`Break`] (closed, velocity
    /// regulator, acceleration feedback), each probed once however often it is queried.
    maps: [OnceLock<Maps>; 3],
    /// The poles (invariances removed), computed on first use.
    poles: OnceLock<Vec<Complex<f64>>>,
}

/// Exogenous signals of one period, per current tick (missing entries are zero).
struct Exogenous<'a> {
    /// Load torque \[pu\].
    load: &'a [f64],
    /// Error added to the encoder reading \[counts\].
    encoder: &'a [f64],
}

impl Exogenous<'_> {
    const NONE: Exogenous<'static> = Exogenous {
        load: &[],
        encoder: &[],
    };
}

/// What one period produced.
struct Period {
    next: Vec<f64>,
    reported: f64,
    torque: Vec<f64>,
}

fn unit(n: usize, i: usize) -> Vec<f64> {
    (0..n).map(|k| if k == i { 1.0 } else { 0.0 }).collect()
}

impl LoopModel {
    /// The model for a controller's coefficients and a plant with the gears `gears`.
    #[must_use]
    pub fn new(
        coef: Coefficients,
        plant: &PlantConfig,
        current_rate_hz: f64,
        gears: Gears,
    ) -> Self {
        let tick = 1.0 / current_rate_hz;
        let delay = plant.electrics.computational_delay_s.max(0.0);
        let whole_delay = (delay / tick + 1e-9).floor() as usize;
        let remainder = (delay - whole_delay as f64 * tick).max(0.0);
        let sampled = SampledPlant::new(&plant.mechanics, &plant.electrics, gears, tick, remainder);
        let ratio = coef.ticks_per_velocity;
        Self {
            coef,
            plant: sampled,
            gears,
            counts_per_rad: f64::from(plant.counts_per_rev()) / (2.0 * PI),
            whole_delay,
            period_s: tick * ratio as f64,
            base_speed_rad_s: plant.mechanics.derived().base_speed_rad_s,
            maps: Default::default(),
            poles: OnceLock::new(),
        }
    }

    /// Length of the stacked state.
    #[must_use]
    pub fn state_len(&self) -> usize {
        state::COUNT + self.whole_delay + 1 + self.coef.state_len()
    }

    /// One velocity period from `z` with the load torque `ex.load[i]` and the encoder
    /// error `ex.encoder[i]` \[counts\] in tick i, and the inputs `inp`. Returns z⁺, the
    /// break signal computed in the period's first tick that has one (the velocity tick for
    /// [`Break::VelocityRegulator`]) and the torque reference of each tick.
    fn period(&self, z: &[f64], ex: &Exogenous, inp: &Inputs, brk: Break) -> Period {
        let load = ex.load;
        let n_plant = state::COUNT;
        let n_delay = self.whole_delay + 1;
        let mut x = DVector::from_iterator(n_plant, z.iter().copied().take(n_plant));
        let mut queue: Vec<f64> = z.iter().copied().skip(n_plant).take(n_delay).collect();
        let mut c = State::from_slice(z.get(n_plant + n_delay..).unwrap_or(&[]));
        let mut reported = None;
        let mut torque = Vec::with_capacity(self.coef.ticks_per_velocity);
        for tick in 0..self.coef.ticks_per_velocity {
            let position = x.get(state::MOTOR_ANGLE).copied().unwrap_or(0.0) * self.counts_per_rad
                + ex.encoder.get(tick).copied().unwrap_or(0.0);
            let current = x.get(state::CURRENT).copied().unwrap_or(0.0);
            if tick == 0 {
                let r = self.coef.velocity_tick(&mut c, position, inp, brk);
                if brk == Break::VelocityRegulator {
                    reported = Some(r);
                }
            }
            let out = self.coef.current_tick(&mut c, position, current, inp, brk);
            torque.push(out.torque_ref);
            if brk == Break::AccelerationFeedback && reported.is_none() {
                reported = Some(out.at_break);
            }
            // queue = [v[k−1], …, v[k−n−1]]: applied old = v[k−n−1], new = v[k−n].
            let old = queue.last().copied().unwrap_or(0.0);
            let new = if self.whole_delay == 0 {
                out.voltage
            } else {
                queue.get(self.whole_delay - 1).copied().unwrap_or(0.0)
            };
            let tl = load.get(tick).copied().unwrap_or(0.0);
            x = self.plant.step(&x, new, old, tl);
            queue.rotate_right(1);
            if let Some(first) = queue.first_mut() {
                *first = out.voltage;
            }
        }
        let mut next: Vec<f64> = x.iter().copied().collect();
        next.extend(queue);
        next.extend(c.to_vec().into_iter().take(self.coef.state_len()));
        Period {
            next,
            reported: reported.unwrap_or(0.0),
            torque,
        }
    }

    /// The period map opened at `brk` ([`Maps`]), probed on the first query only.
    fn matrices(&self, brk: Break) -> &Maps {
        let slot = match brk {
            Break::None => &self.maps[0],
            Break::VelocityRegulator => &self.maps[1],
            Break::AccelerationFeedback => &self.maps[2],
        };
        slot.get_or_init(|| self.probe(brk))
    }

    /// M, the break input column B_w, and the break output row C (reported = C·z + D·w),
    /// read off the mirror with unit vectors.
    fn probe(&self, brk: Break) -> Maps {
        let n = self.state_len();
        let quiet = Inputs::default();
        let none = Exogenous::NONE;
        let mut m = DMatrix::zeros(n, n);
        let mut c = DVector::zeros(n);
        let mut e = vec![0.0; n];
        for j in 0..n {
            if let Some(v) = e.get_mut(j) {
                *v = 1.0;
            }
            let out = self.period(&e, &none, &quiet, brk);
            m.set_column(j, &DVector::from_vec(out.next));
            if let Some(v) = c.get_mut(j) {
                *v = out.reported;
            }
            if let Some(v) = e.get_mut(j) {
                *v = 0.0;
            }
        }
        let w = Inputs { w: 1.0, ..quiet };
        let out = self.period(&vec![0.0; n], &none, &w, brk);
        (m, DVector::from_vec(out.next), c, out.reported)
    }

    /// The closed loop's one-period map.
    #[must_use]
    pub fn closed_loop(&self) -> DMatrix<f64> {
        self.matrices(Break::None).0.clone()
    }

    /// The direction of a shift of every position by one motor radian.
    fn shift(&self) -> DVector<f64> {
        let mut v = vec![0.0; state::COUNT + self.whole_delay + 1];
        for i in [state::MOTOR_ANGLE, state::LOAD_ANGLE] {
            if let Some(x) = v.get_mut(i) {
                *x = 1.0;
            }
        }
        v.extend(
            State::position_shift(self.counts_per_rad)
                .to_vec()
                .into_iter()
                .take(self.coef.state_len()),
        );
        DVector::from_vec(v)
    }

    /// The eigenvalues of the loop's dynamics (invariances removed, module docs).
    #[must_use]
    pub fn poles(&self) -> Vec<Complex<f64>> {
        self.poles.get_or_init(|| self.eigenvalues()).clone()
    }

    fn eigenvalues(&self) -> Vec<Complex<f64>> {
        let mut m = self.closed_loop();
        let mut shift = self.shift();
        // (The load states go first, then the states this configuration never uses.)
        if self.gears == Gears::Apart {
            // Drop θl and ωl: the coasting load does not act on the motor.
            m = m
                .remove_row(state::LOAD_SPEED)
                .remove_column(state::LOAD_SPEED)
                .remove_row(state::LOAD_ANGLE)
                .remove_column(state::LOAD_ANGLE);
            shift = shift
                .remove_row(state::LOAD_SPEED)
                .remove_row(state::LOAD_ANGLE);
        }
        let (m_used, shift_used) = drop_unused(&m, &shift);
        let (mut m, shift) = (m_used, shift_used);
        let invariant = (&m * &shift - &shift).norm() <= 1e-9 * shift.norm();
        if invariant {
            m = deflate(&m, &shift);
        }
        m.complex_eigenvalues().iter().copied().collect()
    }

    /// The damping ratio of a pole λ of the period map: that of s = ln(λ)/T_v. Poles at
    /// the origin (pure delays) count as ζ = 1.
    #[must_use]
    pub fn damping(&self, lambda: Complex<f64>) -> f64 {
        if lambda.norm() < 1e-12 {
            return 1.0;
        }
        let s = lambda.ln() / self.period_s;
        if s.norm() == 0.0 {
            return 0.0;
        }
        -s.re / s.norm()
    }

    /// The smallest damping over the poles; negative means unstable.
    #[must_use]
    pub fn smallest_damping(&self) -> f64 {
        self.poles()
            .into_iter()
            .map(|p| self.damping(p))
            .fold(f64::INFINITY, f64::min)
    }

    /// The natural frequency |s|/2π \[Hz\] of a pole λ, s = ln(λ)/T_v (0 at the origin).
    #[must_use]
    pub fn natural_hz(&self, lambda: Complex<f64>) -> f64 {
        if lambda.norm() < 1e-12 {
            return 0.0;
        }
        (lambda.ln() / self.period_s).norm() / (2.0 * PI)
    }

    /// The least-damped pole's damping and natural frequency \[Hz\].
    #[must_use]
    pub fn least_damped(&self) -> (f64, f64) {
        self.poles()
            .into_iter()
            .map(|p| (self.damping(p), self.natural_hz(p)))
            .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a })
    }

    /// The smallest damping of the poles whose natural frequency lies outside the band
    /// `band_hz` (lo, hi) and of those inside it (infinite where there are none): the
    /// loop's own modes, and those a notch on that band leaves to the machine.
    #[must_use]
    pub fn smallest_damping_split(&self, band_hz: (f64, f64)) -> (f64, f64) {
        let (mut outside, mut inside) = (f64::INFINITY, f64::INFINITY);
        for p in self.poles() {
            let (d, f) = (self.damping(p), self.natural_hz(p));
            if f >= band_hz.0 && f <= band_hz.1 {
                inside = inside.min(d);
            } else {
                outside = outside.min(d);
            }
        }
        (outside, inside)
    }

    /// The spectral radius of the loop (stable below 1).
    #[must_use]
    pub fn spectral_radius(&self) -> f64 {
        self.poles().iter().map(|p| p.norm()).fold(0.0, f64::max)
    }

    /// L(e^{jωT_v}) with the loop opened at `brk`: L = −(C·(zI − M)⁻¹·B_w + D).
    #[must_use]
    pub fn loop_gain(&self, brk: Break, freq_hz: &[f64]) -> Vec<Complex<f64>> {
        let (m, bw, c, d) = self.matrices(brk);
        let d = *d;
        let form = HessenbergResponse::new(m, bw, c);
        freq_hz
            .iter()
            .map(|f| {
                let z = Complex::from_polar(1.0, 2.0 * PI * f * self.period_s);
                form.at(z)
                    .map_or(Complex::new(f64::INFINITY, 0.0), |g| -(g + d))
            })
            .collect()
    }

    /// Gain and phase margins of the loop opened at `brk`, from its response on the log grid
    /// [`margin_grid`] up to the velocity Nyquist frequency.
    ///
    /// The response is evaluated at every [`COARSE_STRIDE`](crate::margins::COARSE_STRIDE)-th point of the grid first, and
    /// at every point only in the coarse intervals (and their neighbours) where it turns:
    /// a phase change over [`TURN_RAD`](crate::margins::TURN_RAD), a change of ln |L| over it, a gain crossing of 1
    /// or a phase crossing of −180°. Elsewhere the response is smooth on the coarse
    /// points, and [`margins_of`] reads its crossings only in the intervals evaluated in
    /// full, so the margins are those of the whole grid ([`Self::margins_dense`]) at a
    /// fraction of the evaluations.
    #[must_use]
    pub fn margins(&self, brk: Break) -> Margins {
        let freqs = margin_grid(self.period_s);
        let (m, bw, c, d) = self.matrices(brk);
        let d = *d;
        let form = HessenbergResponse::new(m, bw, c);
        let at = |f: f64| {
            let z = Complex::from_polar(1.0, 2.0 * PI * f * self.period_s);
            form.at(z)
                .map_or(Complex::new(f64::INFINITY, 0.0), |g| -(g + d))
        };
        let (f, l) = refined(&freqs, at);
        margins_of(&f, &l)
    }

    /// The margins from the response at every point of [`margin_grid`]: what
    /// [`Self::margins`] reads from fewer points.
    #[must_use]
    pub fn margins_dense(&self, brk: Break) -> Margins {
        let freqs = margin_grid(self.period_s);
        let l = self.loop_gain(brk, &freqs);
        margins_of(&freqs, &l)
    }

    /// RMS torque-reference noise \[pu\] from encoder quantization: a white error of one
    /// count's variance, 1/12 count², on every reading, through the closed loop: the
    /// energy of the impulse response from the readings to the torque reference, times
    /// 1/12, averaged over the ticks of the period. Infinite for an unstable loop.
    #[must_use]
    pub fn quantization_torque_rms(&self) -> f64 {
        if self.spectral_radius() >= 1.0 {
            return f64::INFINITY;
        }
        let (m, _, _, _) = self.matrices(Break::None);
        let n = m.nrows();
        let ratio = self.coef.ticks_per_velocity;
        let zero = vec![0.0; n];
        let var = 1.0 / 12.0;
        // Per noise input i: the state it leaves, and the torque it adds in each tick.
        let (mut b, mut d) = (DMatrix::zeros(n, ratio), DMatrix::zeros(ratio, ratio));
        for i in 0..ratio {
            let enc = unit(ratio, i);
            let ex = Exogenous {
                load: &[],
                encoder: &enc,
            };
            let out = self.period(&zero, &ex, &Inputs::default(), Break::None);
            b.set_column(i, &DVector::from_vec(out.next));
            for (k, t) in out.torque.iter().enumerate() {
                if let Some(v) = d.get_mut((k, i)) {
                    *v = *t;
                }
            }
        }
        // C: the torque of each tick from the period's initial state.
        let mut c = DMatrix::zeros(ratio, n);
        let mut e = vec![0.0; n];
        for j in 0..n {
            if let Some(v) = e.get_mut(j) {
                *v = 1.0;
            }
            let out = self.period(&e, &Exogenous::NONE, &Inputs::default(), Break::None);
            for (k, t) in out.torque.iter().enumerate() {
                if let Some(v) = c.get_mut((k, j)) {
                    *v = *t;
                }
            }
            if let Some(v) = e.get_mut(j) {
                *v = 0.0;
            }
        }
        let cov = (&d * d.transpose() + impulse_energy(m, &b, &c)) * var;
        let mean_var = cov.diagonal().iter().sum::<f64>() / ratio as f64;
        mean_var.max(0.0).sqrt()
    }

    /// The load speed \[pu\] at the end of each of `periods`
    /// velocity periods after a load torque step of `step_pu` from rest: the linear loop's
    /// own step response, for checking a fit to the nonlinear loop's.
    #[must_use]
    pub fn load_step_response(&self, step_pu: f64, periods: usize) -> Vec<f64> {
        let load = vec![step_pu; self.coef.ticks_per_velocity];
        let ex = Exogenous {
            load: &load,
            encoder: &[],
        };
        let mut z = vec![0.0; self.state_len()];
        (0..periods)
            .map(|_| {
                z = self.period(&z, &ex, &Inputs::default(), Break::None).next;
                z.get(state::LOAD_SPEED).copied().unwrap_or(0.0)
            })
            .collect()
    }

    /// Dynamic stiffness |τ_L/θl| at each frequency \[pu torque per pu·s of load position\],
    /// the quantity `hil-harness stiffness` measures.
    #[must_use]
    pub fn stiffness(&self, freq_hz: &[f64]) -> Vec<f64> {
        let (m, _, _, _) = self.matrices(Break::None);
        let n = m.nrows();
        let ratio = self.coef.ticks_per_velocity;
        let tick = self.period_s / ratio as f64;
        // The response of z⁺ to a unit load torque in tick i alone.
        let columns: Vec<DVector<f64>> = (0..ratio)
            .map(|i| {
                let load = unit(ratio, i);
                let ex = Exogenous {
                    load: &load,
                    encoder: &[],
                };
                DVector::from_vec(
                    self.period(&vec![0.0; n], &ex, &Inputs::default(), Break::None)
                        .next,
                )
            })
            .collect();
        let mc = m.map(Complex::from);
        freq_hz
            .iter()
            .map(|f| {
                let w = 2.0 * PI * f;
                let z = Complex::from_polar(1.0, w * self.period_s);
                let mut b = DVector::<Complex<f64>>::zeros(n);
                for (i, col) in columns.iter().enumerate() {
                    b += col.map(Complex::from) * Complex::from_polar(1.0, w * tick * i as f64);
                }
                let a = DMatrix::<Complex<f64>>::identity(n, n) * z - &mc;
                match a.lu().solve(&b) {
                    Some(x) => {
                        let theta_rad = x.get(state::LOAD_ANGLE).copied().unwrap_or_default();
                        1.0 / (theta_rad.norm() / self.base_speed_rad_s)
                    }
                    None => 0.0,
                }
            })
            .collect()
    }
}

/// Σ_k C·M^k·B·Bᵀ·M^kᵀ·Cᵀ over the impulse response until it has died out, by doubling:
/// P ← P + A·P·Aᵀ, A ← A², so that after j steps P sums the first 2^j terms (at least 2^7,
/// at most 2^20). The invariant directions (eigenvalue 1, the speed mode) are not seen by
/// the torque, so the sum converges whenever the loop's own poles are stable.
fn impulse_energy(m: &DMatrix<f64>, b: &DMatrix<f64>, c: &DMatrix<f64>) -> DMatrix<f64> {
    let mut p = b * b.transpose();
    let mut a = m.clone();
    let mut sum = c * &p * c.transpose();
    for j in 0..20 {
        let add = &a * &p * a.transpose();
        let seen = c * &add * c.transpose();
        p += add;
        sum += &seen;
        a = &a * &a;
        if j >= 6 && seen.norm() < 1e-15 * sum.norm() {
            break;
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    #![allow(clippy::indexing_slicing)]
    use super::impulse_energy;
    use nalgebra::DMatrix;

    /// A matrix of pseudo-random entries in (−1, 1) (xorshift from `seed`).
    fn random(rows: usize, cols: usize, seed: &mut u64) -> DMatrix<f64> {
        DMatrix::from_fn(rows, cols, |_, _| {
            *seed ^= *seed << 13;
            *seed ^= *seed >> 7;
            *seed ^= *seed << 17;
            (*seed >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        })
    }

    /// The doubling sums what the impulse response sums term by term: on random stable
    /// matrices (spectral radius 0.97), and with an invariant direction (eigenvalue 1)
    /// that the output does not see.
    #[test]
    fn doubling_equals_the_term_by_term_sum() {
        let mut seed = 0x9e37_79b9_7f4a_7c15;
        for case in 0..20 {
            let n = 6 + case % 5;
            let mut s = random(n - 1, n - 1, &mut seed);
            let radius = s
                .complex_eigenvalues()
                .iter()
                .map(|l| l.norm())
                .fold(0.0, f64::max);
            s *= 0.97 / radius;
            let mut m = DMatrix::zeros(n, n);
            m.view_mut((1, 1), (n - 1, n - 1)).copy_from(&s);
            let b = random(n, 2, &mut seed);
            let mut c = random(2, n, &mut seed);
            if case % 2 == 1 {
                // State 0 holds itself and feeds nothing; the output does not see it.
                m[(0, 0)] = 1.0;
                c.column_mut(0).fill(0.0);
            }
            let mut direct = DMatrix::zeros(2, 2);
            let mut x = b.clone();
            for _ in 0..4000 {
                let y = &c * &x;
                direct += &y * y.transpose();
                x = &m * x;
            }
            let fast = impulse_energy(&m, &b, &c);
            let err = (&fast - &direct).norm() / direct.norm();
            assert!(err < 1e-9, "case {case}: relative error {err:e}");
        }
    }
}
