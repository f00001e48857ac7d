//! Test support: the shipped machine files (Table 1 lives only in `configs/machines/table1.toml`), and an
//! independent reference integrator for the accuracy tests: fine fixed-step classical RK4 on the
//! equations as `plant-host/README.md` writes them, with the contact law classified from the state
//! (memoryless) and frozen within a step; when the classification changes across a step, the step
//! is bisected (re-integrated from its start) to locate the switching instant. It shares no code
//! with the crate's exact piecewise-linear integrator.
#![allow(
    dead_code,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    clippy::too_many_arguments,
    missing_docs
)]

use plant_host::PlantConfig;
use std::f64::consts::PI;
use std::path::PathBuf;

/// `configs/NAME` of the workspace.
pub fn config_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../configs/machines")
        .join(name)
}

/// The text of `configs/NAME`.
pub fn config_text(name: &str) -> String {
    std::fs::read_to_string(config_path(name)).unwrap()
}

/// The plant of `configs/NAME` (its `[drive]` table ignored).
pub fn config(name: &str) -> PlantConfig {
    PlantConfig::from_machine_file(&config_path(name)).unwrap()
}

/// The paper's Table 1 plant, from `configs/machines/table1.toml`.
pub fn table1() -> PlantConfig {
    config("table1.toml")
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefParams {
    pub wb: f64,
    pub jm: f64,
    pub jl: f64,
    pub k: f64,
    pub d: f64,
    pub g: f64,
    pub bm: f64,
    pub bl: f64,
    pub clamped: bool,
    /// Some((R, L)): voltage drives a winding; None: the input is the motor torque.
    pub winding: Option<(f64, f64)>,
}

impl RefParams {
    /// From the raw Table-1-style numbers, re-deriving K and D from the formulas in
    /// `plant-host/README.md`.
    pub fn from_raw(
        base_rpm: f64,
        jm: f64,
        jl: f64,
        f_ar_hz: f64,
        zeta: f64,
        backlash_deg: f64,
        clamped: bool,
        winding: Option<(f64, f64)>,
    ) -> Self {
        let wb = 2.0 * PI * base_rpm / 60.0;
        let war = 2.0 * PI * f_ar_hz;
        Self {
            wb,
            jm,
            jl,
            k: jl * war * war / wb,
            d: 2.0 * zeta * jl * war,
            g: backlash_deg * PI / 180.0 / 2.0,
            bm: 0.0,
            bl: 0.0,
            clamped,
            winding,
        }
    }
}

/// State: θm, θl (rad), ωm, ωl (pu), i (pu).
pub type S = [f64; 5];

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Law {
    Open,
    Pos,
    Neg,
}

pub fn classify(p: &RefParams, x: &S) -> Law {
    let delta = x[0] - x[1];
    let rel = x[2] - x[3];
    if delta > p.g {
        let f = p.k * (delta - p.g) + p.d * rel;
        if p.clamped && f <= 0.0 {
            Law::Open
        } else {
            Law::Pos
        }
    } else if delta < -p.g {
        let f = p.k * (delta + p.g) + p.d * rel;
        if p.clamped && f >= 0.0 {
            Law::Open
        } else {
            Law::Neg
        }
    } else {
        Law::Open
    }
}

pub fn shaft(p: &RefParams, x: &S, law: Law) -> f64 {
    let delta = x[0] - x[1];
    let rel = x[2] - x[3];
    match law {
        Law::Open => 0.0,
        Law::Pos => p.k * (delta - p.g) + p.d * rel,
        Law::Neg => p.k * (delta + p.g) + p.d * rel,
    }
}

fn deriv(p: &RefParams, x: &S, law: Law, u: f64, tl: f64) -> S {
    let ts = shaft(p, x, law);
    let (tm, di) = match p.winding {
        Some((r, l)) => (x[4], (u - r * x[4] - x[2]) / l),
        None => (u, 0.0),
    };
    [
        p.wb * x[2],
        p.wb * x[3],
        (tm - ts - p.bm * x[2]) / p.jm,
        (ts - tl - p.bl * x[3]) / p.jl,
        di,
    ]
}

fn rk4(p: &RefParams, x: &S, law: Law, u: f64, tl: f64, h: f64) -> S {
    let add = |a: &S, b: &S, s: f64| -> S { std::array::from_fn(|i| a[i] + s * b[i]) };
    let k1 = deriv(p, x, law, u, tl);
    let k2 = deriv(p, &add(x, &k1, h / 2.0), law, u, tl);
    let k3 = deriv(p, &add(x, &k2, h / 2.0), law, u, tl);
    let k4 = deriv(p, &add(x, &k3, h), law, u, tl);
    std::array::from_fn(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
}

pub struct Reference {
    pub p: RefParams,
    pub x: S,
    pub h: f64,
    pub switches: u64,
    /// false: step straight over the edges (to show what edge location buys).
    pub locate: bool,
}

impl Reference {
    pub fn new(p: RefParams, h: f64) -> Self {
        Self {
            p,
            x: [0.0; 5],
            h,
            switches: 0,
            locate: true,
        }
    }

    pub fn law(&self) -> Law {
        classify(&self.p, &self.x)
    }

    pub fn shaft_torque(&self) -> f64 {
        shaft(&self.p, &self.x, self.law())
    }

    /// Integrates `dt` with inputs held.
    pub fn advance(&mut self, dt: f64, u: f64, tl: f64) {
        let mut left = dt;
        while left > 1e-15 {
            let h = self.h.min(left);
            let law = classify(&self.p, &self.x);
            let x1 = rk4(&self.p, &self.x, law, u, tl, h);
            if !self.locate || classify(&self.p, &x1) == law {
                self.x = x1;
                left -= h;
                continue;
            }
            // Bisect for the switching instant, re-integrating from the step's start.
            let (mut lo, mut hi) = (0.0, h);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if classify(&self.p, &rk4(&self.p, &self.x, law, u, tl, mid)) == law {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            self.x = rk4(&self.p, &self.x, law, u, tl, hi);
            self.switches += 1;
            left -= hi;
        }
    }
}
