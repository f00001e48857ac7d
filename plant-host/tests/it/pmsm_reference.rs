//! An independent reference for the PMSM plant: the motor in the stator frame with the
//! stator flux linkages as states, dψ_αβ/dt = v_αβ − R·i_αβ, the current from
//! ψ_αβ = L(θe)·i_αβ + ψm·(cos θe, sin θe) with the rotor-angle-dependent inductance matrix
//! of a salient machine, and the torque p·ω_b·(ψα·iβ − ψβ·iα). No Park transform, no d/q
//! equations: it shares only the mechanics' contact law (`common`) with the other tests.
//! Fixed-step classical RK4; a contact change inside a step is located by bisection
//! (re-integrating from the step's start), as `common::Reference` does.
#![allow(
    dead_code,
    clippy::unwrap_used,
    clippy::indexing_slicing,
    clippy::too_many_arguments,
    missing_docs
)]

use crate::common::{Law, RefParams, classify, shaft};

/// The motor's constants, as the machine file writes them.
#[derive(Debug, Clone, Copy)]
pub struct RefMotor {
    pub pole_pairs: f64,
    pub r: f64,
    pub ld: f64,
    pub lq: f64,
    /// λ, pu: back-EMF at base speed.
    pub flux_pu: f64,
    pub offset_rad: f64,
    pub dc_bus: f64,
    /// The dead time's loss of a pole's mean voltage, V_dc·t_d·f_pwm, pu (0 = none).
    pub dead_loss: f64,
}

/// θm, θl (rad), ωm, ωl (pu), ψα, ψβ (pu·s).
pub type X = [f64; 6];

pub struct PmsmReference {
    pub p: RefParams,
    pub m: RefMotor,
    pub x: X,
    pub h: f64,
    /// Contact changes located.
    pub switches: u64,
    /// Phase-current sign changes located (with dead time).
    pub sign_changes: u64,
    /// The signs the dead time applies now: a current exactly at zero keeps its sign here,
    /// only a strict crossing changes it (all zero at the start, no current).
    pub signs: [i8; 3],
}

impl PmsmReference {
    /// At rest, no current (the flux is the magnet's alone).
    pub fn new(p: RefParams, m: RefMotor, h: f64) -> Self {
        let mut r = Self {
            p,
            m,
            x: [0.0; 6],
            h,
            switches: 0,
            sign_changes: 0,
            signs: [0; 3],
        };
        let th = m.offset_rad;
        let psi_m = r.psi_m();
        r.x[4] = psi_m * th.cos();
        r.x[5] = psi_m * th.sin();
        r
    }

    /// The magnet's flux ψm = λ/(p·ω_b), pu·s.
    fn psi_m(&self) -> f64 {
        self.m.flux_pu / (self.m.pole_pairs * self.p.wb)
    }

    fn theta_e(&self, x: &X) -> f64 {
        self.m.pole_pairs * x[0] + self.m.offset_rad
    }

    /// i_αβ of a state.
    pub fn current_ab(&self, x: &X) -> [f64; 2] {
        let th = self.theta_e(x);
        let (ls, ld) = (0.5 * (self.m.ld + self.m.lq), 0.5 * (self.m.ld - self.m.lq));
        let (s2, c2) = (2.0 * th).sin_cos();
        let (l11, l12, l22) = (ls + ld * c2, ld * s2, ls - ld * c2);
        let psi_m = self.psi_m();
        let (ra, rb) = (x[4] - psi_m * th.cos(), x[5] - psi_m * th.sin());
        let det = l11 * l22 - l12 * l12;
        [(l22 * ra - l12 * rb) / det, (l11 * rb - l12 * ra) / det]
    }

    /// Phase currents a, b.
    pub fn phase_ab(&self) -> [f64; 2] {
        let [ia, ib] = self.current_ab(&self.x);
        [ia, -0.5 * ia + 0.75_f64.sqrt() * ib]
    }

    pub fn torque(&self, x: &X) -> f64 {
        let [ia, ib] = self.current_ab(x);
        self.m.pole_pairs * self.p.wb * (x[4] * ib - x[5] * ia)
    }

    fn mech(x: &X) -> [f64; 5] {
        [x[0], x[1], x[2], x[3], 0.0]
    }

    pub fn law(&self) -> Law {
        classify(&self.p, &Self::mech(&self.x))
    }

    /// The phase currents' signs, with dead time (else all 0); a current exactly at zero
    /// keeps its sign in `held`.
    fn signs(&self, x: &X, held: [i8; 3]) -> [i8; 3] {
        if self.m.dead_loss == 0.0 {
            return [0; 3];
        }
        let [ia, ib] = self.current_ab(x);
        let b = -0.5 * ia + 0.75_f64.sqrt() * ib;
        let c = -0.5 * ia - 0.75_f64.sqrt() * ib;
        let i = [ia, b, c];
        std::array::from_fn(|k| {
            if i[k] > 0.0 {
                1
            } else if i[k] < 0.0 {
                -1
            } else {
                held[k]
            }
        })
    }

    /// What a step holds: the contact law and the currents' signs.
    fn pattern(&self, x: &X) -> (Law, [i8; 3]) {
        (classify(&self.p, &Self::mech(x)), self.signs(x, self.signs))
    }

    /// The stator voltage of three duties: pole = duty·V_dc − ΔV·sign(i), phase = pole −
    /// mean, then Clarke.
    pub fn voltage(&self, duties: [f64; 3], signs: [i8; 3]) -> [f64; 2] {
        let poles: [f64; 3] = std::array::from_fn(|k| {
            duties[k] * self.m.dc_bus - self.m.dead_loss * f64::from(signs[k])
        });
        let mean = (poles[0] + poles[1] + poles[2]) / 3.0;
        let v = poles.map(|p| p - mean);
        [v[0], (v[1] - v[2]) / 3.0_f64.sqrt()]
    }

    fn deriv(&self, x: &X, law: Law, v: [f64; 2], tl: f64) -> X {
        let p = &self.p;
        let ts = shaft(p, &Self::mech(x), law);
        let tm = self.torque(x);
        let [ia, ib] = self.current_ab(x);
        [
            p.wb * x[2],
            p.wb * x[3],
            (tm - ts - p.bm * x[2]) / p.jm,
            (ts - tl - p.bl * x[3]) / p.jl,
            v[0] - self.m.r * ia,
            v[1] - self.m.r * ib,
        ]
    }

    fn rk4(&self, x: &X, law: Law, v: [f64; 2], tl: f64, h: f64) -> X {
        let add = |a: &X, b: &X, s: f64| -> X { std::array::from_fn(|i| a[i] + s * b[i]) };
        let k1 = self.deriv(x, law, v, tl);
        let k2 = self.deriv(&add(x, &k1, h / 2.0), law, v, tl);
        let k3 = self.deriv(&add(x, &k2, h / 2.0), law, v, tl);
        let k4 = self.deriv(&add(x, &k3, h), law, v, tl);
        std::array::from_fn(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
    }

    /// Integrates `dt` with the duties and load torque held.
    pub fn advance(&mut self, dt: f64, duties: [f64; 3], tl: f64) {
        let mut left = dt;
        // Located switches in a row that each advanced less than 1e-12 s: a current held at
        // zero by the dead time (the two sides' fields both point at zero), which this
        // reference does not model; it stops rather than chatter forever.
        let mut chatter = 0;
        while left > 1e-15 {
            let h = self.h.min(left);
            let (law, signs) = self.pattern(&self.x);
            self.signs = signs;
            let v = self.voltage(duties, signs);
            let x1 = self.rk4(&self.x, law, v, tl, h);
            if self.pattern(&x1) == (law, signs) {
                self.x = x1;
                left -= h;
                continue;
            }
            let (mut lo, mut hi) = (0.0, h);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                let xm = self.rk4(&self.x, law, v, tl, mid);
                if self.pattern(&xm) == (law, signs) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            self.x = self.rk4(&self.x, law, v, tl, hi);
            let (new_law, new_signs) = self.pattern(&self.x);
            self.switches += u64::from(new_law != law);
            self.sign_changes += u64::from(new_signs != signs);
            self.signs = new_signs;
            left -= hi;
            chatter = if hi < 1e-12 { chatter + 1 } else { 0 };
            assert!(
                chatter < 1000,
                "a phase current held at zero by the dead time (sliding) at θm {}",
                self.x[0]
            );
        }
    }
}
