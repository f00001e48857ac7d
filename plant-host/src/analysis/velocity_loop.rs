//! The closed velocity loop around the engaged plant, with and without acceleration feedback.
//!
//! Controller (two rates, all signals pu). The PI runs every Tv = `velocity_period_s`, the
//! acceleration path and the torque command update every Ta = `accel_period_s` (Tv = N·Ta):
//!   ω̂v[k] = (θm[k] − θm[k−N]) / (ω_b·Tv)          velocity: difference over one PI period
//!   PI[k] = kp·e + ki·Tv·Σe, e = ω_ref − ω̂v         (held between PI updates)
//!   ω̂a[k] = (θm[k] − θm[k−1]) / (ω_b·Ta)
//!   â[k] = LPF( (ω̂a[k] − ω̂a[k−1]) / Ta )           first-order filter, corner `accel_filter_hz`
//!   T*[k] = PI[k] − ka·â[k]
//! T*[k] is applied `delay_s` after the sample and held (ZOH); the current loop is a
//! first-order lag at `current_bandwidth_hz` (None: ideal). Ta = Tv gives the single-rate loop.
//!
//! Frequency responses use the usual continuous approximations of the sampled elements
//! (valid below the Nyquist frequency π/Tv): difference (1 − e^{−sT})/T, hold
//! H(T) = (1 − e^{−sT})/(sT), delay e^{−s·delay}. The loop is broken at the torque command
//! (every feedback path goes through it):
//! L(s) = Delay·Current·P(s)·[H(Tv)·PI(s)·H(Tv) + H(Ta)·ka·s·H(Ta)²·F(s)].
//! Stability is ALSO decided exactly, without approximation, from the eigenvalues of the
//! sampled-data closed loop over one PI period (`sampled_spectral_radius`).

use super::engaged::EngagedPlant;
use crate::expm::expm;
use nalgebra::{Complex, SMatrix, SVector};
use std::f64::consts::PI;

/// Velocity loop parameters (plain numbers, so this crate needs no controller).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityLoop {
    /// The engaged plant.
    pub plant: EngagedPlant,
    /// Proportional gain, pu torque per pu speed.
    pub kp: f64,
    /// Integral gain, pu torque per pu speed per second.
    pub ki: f64,
    /// Acceleration feedback gain, s (pu torque per pu/s of acceleration); 0 = off.
    pub ka: f64,
    /// First-order filter corner on the acceleration estimate, Hz.
    pub accel_filter_hz: f64,
    /// Velocity (PI) sample period Tv, s.
    pub velocity_period_s: f64,
    /// Acceleration path and torque-command update period Ta, s; Tv must be a whole multiple
    /// (rounded to the nearest). Ta = Tv: single rate.
    pub accel_period_s: f64,
    /// Computational delay from sample to applied torque command, s (< Ta).
    pub delay_s: f64,
    /// Closed current loop as a first-order lag at this bandwidth (Hz); None = ideal.
    pub current_bandwidth_hz: Option<f64>,
}

/// The loop at one frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopPoint {
    /// Frequency, rad/s.
    pub omega_rad_s: f64,
    /// Loop gain broken at the torque command.
    pub loop_gain: Complex<f64>,
    /// Inner acceleration loop alone (ka path), broken at the same point.
    pub accel_loop_gain: Complex<f64>,
    /// Closed loop ωm/ω_ref.
    pub reference_to_speed: Complex<f64>,
    /// Closed loop ωm/TL, pu speed per pu torque.
    pub load_to_speed: Complex<f64>,
    /// Dynamic stiffness at the motor, −TL/θm with θm in pu·s (rad/ω_b), as in Eq. 1.
    pub motor_stiffness: Complex<f64>,
    /// Dynamic stiffness at the load, −TL/θl (pu·s).
    pub load_stiffness: Complex<f64>,
}

/// Classical margins of a loop gain over (0.01 rad/s, Nyquist). With a resonance |L| may
/// cross 1 several times; all crossings are listed, and stability is decided by the exact
/// sampled-data eigenvalues ([`VelocityLoop::is_stable`]), not by these numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct Margins {
    /// Phase margin at the lowest gain crossover (the bandwidth), degrees in (−180, 180]
    /// (∞ if |L| never crosses 1).
    pub phase_margin_deg: f64,
    /// The lowest gain crossover, rad/s.
    pub gain_crossover_rad_s: f64,
    /// Smallest gain margin over the phase crossovers (−180°) above the lowest gain
    /// crossover, dB; negative when a resonance peak exceeds 1 at −180° (∞ if none).
    pub gain_margin_db: f64,
    /// That phase crossover, rad/s.
    pub phase_crossover_rad_s: f64,
    /// Every gain crossover: (rad/s, phase margin in degrees).
    pub crossovers: Vec<(f64, f64)>,
}

impl VelocityLoop {
    /// A copy with the acceleration feedback removed (ka = 0).
    pub fn without_acceleration_feedback(&self) -> Self {
        Self { ka: 0.0, ..*self }
    }

    /// π/Tv, rad/s: the approximations hold below it.
    pub fn nyquist_rad_s(&self) -> f64 {
        PI / self.velocity_period_s
    }

    /// N = Tv/Ta rounded, at least 1; and Ta = Tv/N exactly.
    fn rates(&self) -> (usize, f64) {
        let n = (self.velocity_period_s / self.accel_period_s)
            .round()
            .max(1.0);
        (n as usize, self.velocity_period_s / n)
    }

    fn elements(&self, omega: f64) -> Option<Elements> {
        let tv = self.velocity_period_s;
        let (_, ta) = self.rates();
        let one = Complex::new(1.0, 0.0);
        let s = Complex::new(0.0, omega);
        let hold = |t: f64| (one - (-s * t).exp()) / (s * t);
        let (hv, ha) = (hold(tv), hold(ta));
        let delay = (-s * self.delay_s).exp();
        let current = match self.current_bandwidth_hz {
            Some(f) => one / (one + s / (2.0 * PI * f)),
            None => one,
        };
        let filter = one / (one + s / (2.0 * PI * self.accel_filter_hz));
        let pi = Complex::new(self.kp, 0.0) + self.ki * tv / (one - (-s * tv).exp());
        let p = self.plant.response(omega)?;
        Some(Elements {
            s,
            out: delay * current,
            pi: pi * hv,
            vel_path: hv * pi * hv,
            acc_path: ha * s * ha * ha * filter * self.ka,
            p,
        })
    }

    /// The loop at `omega_rad_s` (None only exactly at a plant pole on the axis, e.g. ω = 0).
    pub fn point(&self, omega_rad_s: f64) -> Option<LoopPoint> {
        let el = self.elements(omega_rad_s)?;
        let pm = el.p.motor_speed_per_motor_torque;
        let loop_gain = el.out * pm * (el.vel_path + el.acc_path);
        let one = Complex::new(1.0, 0.0);
        let wm_per_tl = el.p.motor_speed_per_load_torque / (one + loop_gain);
        // Torque actually applied per unit ωm: −out·(vel_path + acc_path).
        let tm_per_tl = -el.out * (el.vel_path + el.acc_path) * wm_per_tl;
        let wl_per_tl =
            el.p.load_speed_per_motor_torque * tm_per_tl + el.p.load_speed_per_load_torque;
        // θ (pu·s) = ω/s.
        Some(LoopPoint {
            omega_rad_s,
            loop_gain,
            accel_loop_gain: el.out * pm * el.acc_path,
            reference_to_speed: el.out * pm * el.pi / (one + loop_gain),
            load_to_speed: wm_per_tl,
            motor_stiffness: -el.s / wm_per_tl,
            load_stiffness: -el.s / wl_per_tl,
        })
    }

    /// Margins of the full loop gain.
    pub fn margins(&self) -> Margins {
        margins(
            |w| self.point(w).map(|p| p.loop_gain),
            0.01,
            self.nyquist_rad_s(),
        )
    }

    /// Margins of the acceleration loop alone (a loop of its own: `docs/design.md`).
    pub fn accel_margins(&self) -> Margins {
        margins(
            |w| self.point(w).map(|p| p.accel_loop_gain),
            0.01,
            self.nyquist_rad_s(),
        )
    }

    /// Largest |eigenvalue| of the exact sampled-data closed loop, excluding the structural
    /// eigenvalues at exactly 1 (free position of the shaft, and with the gears apart the
    /// coasting load: a velocity loop holds neither). Stable iff < 1.
    pub fn sampled_spectral_radius(&self) -> f64 {
        let m = self.sampled_closed_loop();
        let eig: Vec<Complex<f64>> = m.complex_eigenvalues().iter().copied().collect();
        // The free position mode is always there; the coasting load adds two more (θl, ωl)
        // when the shaft is removed. They are exact integrators: drop eigenvalues within
        // 1e-7 of 1 (a Jordan pair splits by ~√ε), at least one.
        let one = Complex::new(1.0, 0.0);
        let mut rest: Vec<Complex<f64>> = eig
            .iter()
            .copied()
            .filter(|l| (l - one).norm() > 1e-7)
            .collect();
        if rest.len() == eig.len() {
            // Not found within tolerance: drop the nearest one.
            if let Some((i, _)) = rest
                .iter()
                .enumerate()
                .min_by(|a, b| (a.1 - one).norm().total_cmp(&(b.1 - one).norm()))
            {
                rest.remove(i);
            }
        }
        rest.iter().map(|l| l.norm()).fold(0.0, f64::max)
    }

    /// Whether the sampled-data closed loop is asymptotically stable.
    pub fn is_stable(&self) -> bool {
        self.sampled_spectral_radius() < 1.0
    }

    /// The continuous plant and current lag, z = [θm, θl, ωm, ωl, Tact], with the torque
    /// command as the input column (the last), augmented for the exponential.
    fn plant_with_current_lag(&self, ta: f64) -> SMatrix<f64, 6, 6> {
        let mut ac = SMatrix::<f64, 6, 6>::zeros();
        ac.fixed_view_mut::<4, 4>(0, 0).copy_from(&self.plant.a);
        let b_tm = self.plant.b.column(0).into_owned();
        match self.current_bandwidth_hz {
            Some(f) => {
                let wc = 2.0 * PI * f;
                ac.fixed_view_mut::<4, 1>(0, 4).copy_from(&b_tm);
                set(&mut ac, 4, 4, -wc);
                set(&mut ac, 4, 5, wc);
            }
            None => {
                ac.fixed_view_mut::<4, 1>(0, 5).copy_from(&b_tm);
                // Tact is unused: make it a fast decaying, decoupled state so it adds no
                // eigenvalue at 1.
                set(&mut ac, 4, 4, -1.0 / ta.max(1e-9));
            }
        }
        ac
    }

    /// The map over one PI period, X ← M·X, with
    /// X = [θm, θl, ωm, ωl, Tact, u_prev, θa_prev, ω̂a_prev, â, θv_prev, I, PI_out]:
    /// one PI tick followed by N − 1 ticks that hold the PI output.
    fn sampled_closed_loop(&self) -> SMatrix<f64, 12, 12> {
        let (n, ta) = self.rates();
        let tv = self.velocity_period_s;
        let td = self.delay_s.clamp(0.0, ta);
        let wb = self.plant.base_speed_rad_s;
        let ac = self.plant_with_current_lag(ta);
        let disc = |h: f64| {
            let e = expm(&(ac * h));
            (
                e.fixed_view::<5, 5>(0, 0).into_owned(),
                e.fixed_view::<5, 1>(0, 5).into_owned(),
            )
        };
        let (phi1, gam1) = disc(td);
        let (phi2, gam2) = disc(ta - td);
        let alpha = (-2.0 * PI * self.accel_filter_hz * ta).exp();

        let unit = |i: usize| {
            let mut v = SVector::<f64, 12>::zeros();
            if let Some(x) = v.get_mut(i) {
                *x = 1.0;
            }
            v
        };
        // One tick as rows (linear functions of X); `pi_tick` updates the PI.
        let tick = |pi_tick: bool| {
            let (integ, pi_out, th_v) = if pi_tick {
                let w_v = (unit(0) - unit(9)) / (wb * tv);
                let integ = unit(10) - w_v * (self.ki * tv);
                (integ, -w_v * self.kp + integ, unit(0))
            } else {
                (unit(10), unit(11), unit(9))
            };
            let w_a = (unit(0) - unit(6)) / (wb * ta);
            let a_raw = (w_a - unit(7)) / ta;
            let a_f = unit(8) * alpha + a_raw * (1.0 - alpha);
            let u = pi_out - a_f * self.ka;
            let mut m = SMatrix::<f64, 12, 12>::zeros();
            m.fixed_view_mut::<5, 5>(0, 0).copy_from(&(phi2 * phi1));
            m.fixed_view_mut::<5, 1>(0, 5).copy_from(&(phi2 * gam1));
            // z[k+1] += Γ2·u[k]
            m.fixed_view_mut::<5, 12>(0, 0)
                .iter_mut()
                .zip((gam2 * u.transpose()).iter())
                .for_each(|(a, b)| *a += b);
            for (row, v) in [
                (5, u),
                (6, unit(0)),
                (7, w_a),
                (8, a_f),
                (9, th_v),
                (10, integ),
                (11, pi_out),
            ] {
                m.set_row(row, &v.transpose());
            }
            m
        };
        let hold = tick(false);
        let mut total = tick(true);
        for _ in 1..n {
            total = hold * total;
        }
        total
    }
}

fn set(m: &mut SMatrix<f64, 6, 6>, r: usize, c: usize, v: f64) {
    if let Some(x) = m.get_mut((r, c)) {
        *x = v;
    }
}

struct Elements {
    s: Complex<f64>,
    out: Complex<f64>,
    pi: Complex<f64>,
    vel_path: Complex<f64>,
    acc_path: Complex<f64>,
    p: super::PlantResponse,
}

/// Gain and phase margins of `l` on a log grid between `lo` and `hi`, crossings refined by
/// bisection in log frequency.
fn margins(l: impl Fn(f64) -> Option<Complex<f64>>, lo: f64, hi: f64) -> Margins {
    let grid = super::log_space(lo, hi * 0.999, 4000);
    let mag = |w: f64| l(w).map_or(f64::NAN, |z| z.norm().ln());
    let im_neg = |w: f64| l(w).map_or(f64::NAN, |z| z.im);
    let refine = |f: &dyn Fn(f64) -> f64, mut a: f64, mut b: f64| {
        let fa = f(a);
        for _ in 0..60 {
            let m = (a * b).sqrt();
            if (f(m) > 0.0) == (fa > 0.0) {
                a = m;
            } else {
                b = m;
            }
        }
        (a * b).sqrt()
    };
    let mut out = Margins {
        phase_margin_deg: f64::INFINITY,
        gain_crossover_rad_s: f64::NAN,
        gain_margin_db: f64::INFINITY,
        phase_crossover_rad_s: f64::NAN,
        crossovers: Vec::new(),
    };
    for pair in grid.windows(2) {
        let [a, b] = [pair.first().copied(), pair.get(1).copied()].map(|v| v.unwrap_or(lo));
        let (ma, mb) = (mag(a), mag(b));
        if ma.is_finite() && mb.is_finite() && (ma > 0.0) != (mb > 0.0) {
            let w = refine(&mag, a, b);
            // Distance in phase from −180°, wrapped to (−180°, 180°].
            let pm = l(w).map_or(f64::NAN, |z| {
                let p = 180.0 + z.arg().to_degrees();
                if p > 180.0 {
                    p - 360.0
                } else {
                    p
                }
            });
            out.crossovers.push((w, pm));
        }
    }
    let first_gc = out.crossovers.first().map_or(lo, |c| c.0);
    if let Some(&(w, pm)) = out.crossovers.first() {
        out.phase_margin_deg = pm;
        out.gain_crossover_rad_s = w;
    }
    for pair in grid.windows(2) {
        let [a, b] = [pair.first().copied(), pair.get(1).copied()].map(|v| v.unwrap_or(lo));
        if a < first_gc {
            continue;
        }
        let (ia, ib) = (im_neg(a), im_neg(b));
        if ia.is_finite() && ib.is_finite() && (ia > 0.0) != (ib > 0.0) {
            let w = refine(&im_neg, a, b);
            if let Some(z) = l(w) {
                let gm = -20.0 * z.norm().log10();
                if z.re < 0.0 && gm < out.gain_margin_db {
                    out.gain_margin_db = gm;
                    out.phase_crossover_rad_s = w;
                }
            }
        }
    }
    out
}
