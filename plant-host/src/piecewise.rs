//! The integrator: the plant is linear inside each contact mode (gap open, driving contact,
//! braking contact), so each mode is stepped EXACTLY by its zero-order-hold discretisation
//! (matrix exponential, cached per step length). After every step the mode's guards (the
//! dead-zone edges, or the clamp's force sign) are checked at the end points, with a tangent
//! bound for a crossing hidden between them; when a guard fires, the step is redone from its
//! start with the mode's Taylor series (exact to ~1e-16 for ‖A‖·h ≤ 0.5), the crossing time is
//! bracketed on 16 samples of that polynomial and closed by bracketed Newton steps, the mode
//! switches there and the rest of the step continues in the new mode. Errors are set by
//! round-off and the root tolerance (1e-15 s), not by a step size.
//!
//! A step length not seen before costs one 8×8 matrix exponential (a few µs); callers that
//! repeat the same few lengths (a harness's delay and remainder) hit the cache.
//!
//! State x = [δ (rad), θl (rad), ωm (pu), ωl (pu), i (pu)], input u = [u_motor, TL (pu), 1].
//! u_motor is the winding voltage (pu) when the winding is modelled, else the motor torque.

use crate::config::{BacklashModel, MechanicsConfig};
use crate::expm::expm;
use nalgebra::{SMatrix, SVector};

pub(crate) type Vec5 = SVector<f64, 5>;
pub(crate) type Vec3 = SVector<f64, 3>;
type Mat5 = SMatrix<f64, 5, 5>;
type Mat53 = SMatrix<f64, 5, 3>;

/// Which side of the lost motion the gears are on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Contact {
    /// Inside the gap (or, for the clamped law, released): no shaft torque.
    Free,
    /// Motor ahead of the load beyond +g: the shaft law with the dead zone's +g edge.
    Driving,
    /// Motor behind the load beyond −g: the shaft law with the −g edge.
    Braking,
}

/// Winding parameters when the electrics are modelled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Winding {
    pub r_pu: f64,
    pub l_pu_s: f64,
}

/// A linear function of the state, l(x) = c·x + k, and its rate l̇ = cA·x + cB·u in one mode.
#[derive(Debug, Clone, Copy)]
struct Linear {
    c: Vec5,
    k: f64,
    c_a: Vec5,
    c_b: Vec3,
}

impl Linear {
    fn new(c: Vec5, k: f64, a: &Mat5, b: &Mat53) -> Self {
        Self {
            c,
            k,
            c_a: a.transpose() * c,
            c_b: b.transpose() * c,
        }
    }
    fn value(&self, x: &Vec5) -> f64 {
        self.c.dot(x) + self.k
    }
    fn rate(&self, x: &Vec5, u: &Vec3) -> f64 {
        self.c_a.dot(x) + self.c_b.dot(u)
    }
}

/// A mode change that fires when min(l₁, l₂) > 0 (one or two linear functions).
#[derive(Debug, Clone, Copy)]
struct Guard {
    lins: [Linear; 2],
    two: bool,
    target: Contact,
}

impl Guard {
    fn lins(&self) -> &[Linear] {
        if self.two {
            &self.lins
        } else {
            self.lins
                .split_first()
                .map_or(&[], |(first, _)| core::slice::from_ref(first))
        }
    }
}

const CACHE_SLOTS: usize = 6;

/// The exact discretisation for one step length, as rows of [Φ | Γ] acting on [x; u]
/// (plain arrays: eight-wide dot products the compiler vectorises).
#[derive(Debug, Clone, Copy)]
struct Discrete {
    rows: [[f64; 8]; 5],
}

impl Discrete {
    fn apply(&self, x: &Vec5, u: &Vec3) -> Vec5 {
        let z = [x.x, x.y, x.z, x.w, x.a, u.x, u.y, u.z];
        let dot = |r: &[f64; 8]| r.iter().zip(z.iter()).map(|(a, b)| a * b).sum::<f64>();
        let [r0, r1, r2, r3, r4] = &self.rows;
        Vec5::new(dot(r0), dot(r1), dot(r2), dot(r3), dot(r4))
    }
}

#[derive(Debug, Clone)]
struct Mode {
    a: Mat5,
    b: Mat53,
    guards: [Option<Guard>; 2],
    /// Step lengths (as bits) of the cached discretisations; 0 = empty slot.
    cache_keys: [u64; CACHE_SLOTS],
    cache: [Discrete; CACHE_SLOTS],
    next_slot: usize,
    last_hit: usize,
}

impl Mode {
    fn new(a: Mat5, b: Mat53, guards: [Option<Guard>; 2]) -> Self {
        Self {
            a,
            b,
            guards,
            cache_keys: [0; CACHE_SLOTS],
            cache: [Discrete {
                rows: [[0.0; 8]; 5],
            }; CACHE_SLOTS],
            next_slot: 0,
            last_hit: 0,
        }
    }

    /// x(t+h) = Φ(h)·x + Γ(h)·u, Φ and Γ cached per step length (bit-exact key): a harness
    /// that repeats the same few step lengths pays one matrix exponential per length.
    fn step(&mut self, h: f64, x: &Vec5, u: &Vec3) -> Vec5 {
        let key = h.to_bits();
        // Harness steps alternate between a few lengths: try the slot that hit last first.
        if self.cache_keys.get(self.last_hit) == Some(&key) {
            if let Some(d) = self.cache.get(self.last_hit) {
                return d.apply(x, u);
            }
        }
        if let Some(i) = self.cache_keys.iter().position(|k| *k == key) {
            if let Some(d) = self.cache.get(i) {
                self.last_hit = i;
                return d.apply(x, u);
            }
        }
        let mut m = SMatrix::<f64, 8, 8>::zeros();
        m.fixed_view_mut::<5, 5>(0, 0).copy_from(&(self.a * h));
        m.fixed_view_mut::<5, 3>(0, 5).copy_from(&(self.b * h));
        let e = expm(&m);
        let mut d = Discrete {
            rows: [[0.0; 8]; 5],
        };
        for (i, row) in d.rows.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = e.get((i, j)).copied().unwrap_or(0.0);
            }
        }
        let slot = self.next_slot;
        if let (Some(k), Some(c)) = (self.cache_keys.get_mut(slot), self.cache.get_mut(slot)) {
            *k = key;
            *c = d;
        }
        self.next_slot = (slot + 1) % CACHE_SLOTS;
        d.apply(x, u)
    }
}

/// Most Taylor terms kept (‖A‖·h ≤ 0.5 needs ~20 for 1e-16).
const MAX_TERMS: usize = 28;
/// Samples per step when searching a polynomial for the first guard crossing.
const SEARCH_SAMPLES: u32 = 16;
/// Mode changes allowed inside one step before the rest is stepped without guards
/// (protects against chattering at a grazing contact).
const MAX_EVENTS_PER_STEP: u32 = 32;
/// Bisection stops when the crossing time is bracketed this tightly (s).
const TIME_TOL_S: f64 = 1e-15;

/// Taylor coefficients of x(τ) = Σ d_k τ^k / k! in one mode from one start state.
struct Taylor {
    d: [Vec5; MAX_TERMS],
    n: usize,
}

impl Taylor {
    fn new(a: &Mat5, b: &Mat53, x0: &Vec5, u: &Vec3, horizon: f64) -> Self {
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

    fn state(&self, tau: f64) -> Vec5 {
        // Horner: x = d0 + τ(d1 + τ/2 (d2 + τ/3 (...)))
        let mut acc = Vec5::zeros();
        for (k, dk) in self.d.iter().take(self.n).enumerate().rev() {
            acc = dk + acc * (tau / (k as f64 + 1.0));
        }
        acc
    }
}

/// Shaft law constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Shaft {
    pub k: f64,
    pub d: f64,
    pub g: f64,
}

/// The piecewise-linear two-inertia plant (optionally with its winding).
#[derive(Debug, Clone)]
pub(crate) struct Piecewise {
    modes: [Mode; 3],
    shaft: Shaft,
    law: BacklashModel,
    h_max_s: f64,
    x: Vec5,
    contact: Contact,
    events: u64,
    searches: u64,
}

impl Piecewise {
    pub fn new(mech: &MechanicsConfig, law: BacklashModel, winding: Option<Winding>) -> Self {
        let dv = mech.derived();
        let shaft = Shaft {
            k: dv.stiffness_pu_per_rad,
            d: dv.damping_pu,
            g: dv.half_gap_rad,
        };
        let build = |contact: Contact| {
            let (on, sigma) = match contact {
                Contact::Free => (0.0, 0.0),
                Contact::Driving => (1.0, 1.0),
                Contact::Braking => (1.0, -1.0),
            };
            system_matrices(mech, &shaft, on, sigma, winding, dv.base_speed_rad_s)
        };
        let mats = [
            build(Contact::Free),
            build(Contact::Driving),
            build(Contact::Braking),
        ];
        let norm = mats
            .iter()
            .map(|(a, _)| {
                a.row_iter()
                    .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        // ‖A‖·h ≤ 0.5 keeps the Taylor series short and the tangent bound tight; 250 µs keeps
        // the crossing search (16 samples per step) fine even for slow plants.
        // Configs from TOML are checked to ‖A‖ ≤ 1e6 1/s; a hand-built absurd one is still
        // stepped (exactly between edges) with sub-steps no shorter than 0.5 µs, never hung.
        let h_max_s = (0.5 / norm.clamp(1e-9, 1e6)).min(250e-6);
        let contacts = [Contact::Free, Contact::Driving, Contact::Braking];
        let modes = core::array::from_fn(|i| {
            let c = contacts.get(i).copied().unwrap_or(Contact::Free);
            let (a, b) = mats.get(i).copied().unwrap_or_else(|| build(c));
            Mode::new(a, b, guards(c, law, &shaft, &a, &b))
        });
        let mut p = Self {
            modes,
            shaft,
            law,
            h_max_s,
            x: Vec5::zeros(),
            contact: Contact::Free,
            events: 0,
            searches: 0,
        };
        p.contact = p.contact_for(&p.x);
        p
    }

    /// The longest internal step, s.
    pub fn max_step_s(&self) -> f64 {
        self.h_max_s
    }

    pub fn state(&self) -> &Vec5 {
        &self.x
    }

    // The state vector is (x, y, z, w, a) = (twist δ rad, load angle θl rad, motor speed
    // ωm pu, load speed ωl pu, winding current pu); these name its parts once for both
    // plants.

    /// Motor angle θm = θl + δ, rad.
    pub fn motor_pos_rad(&self) -> f64 {
        self.x.y + self.x.x
    }

    /// Load angle θl (motor side), rad.
    pub fn load_pos_rad(&self) -> f64 {
        self.x.y
    }

    /// Motor speed ωm, pu.
    pub fn motor_vel_pu(&self) -> f64 {
        self.x.z
    }

    /// Load speed ωl (motor side), pu.
    pub fn load_vel_pu(&self) -> f64 {
        self.x.w
    }

    /// Twist δ = θm − θl, rad.
    pub fn twist_rad(&self) -> f64 {
        self.x.x
    }

    pub fn contact(&self) -> Contact {
        self.contact
    }

    pub fn mode_changes(&self) -> u64 {
        self.events
    }

    /// Steps redone with the Taylor series to search for a crossing (cost diagnostics).
    pub fn crossing_searches(&self) -> u64 {
        self.searches
    }

    /// Sets the state; the contact mode follows from the twist (and, clamped, the force sign).
    pub fn set_state(&mut self, x: Vec5) {
        self.x = x;
        self.contact = self.contact_for(&x);
    }

    fn contact_for(&self, x: &Vec5) -> Contact {
        let Shaft { k, d, g } = self.shaft;
        let (delta, rel) = (x.x, x.z - x.w);
        let dz_law = if g == 0.0 && self.law == BacklashModel::DeadZone {
            // No lost motion: one linear mode, never switching.
            return Contact::Driving;
        } else if delta > g {
            Contact::Driving
        } else if delta < -g {
            Contact::Braking
        } else {
            Contact::Free
        };
        match (self.law, dz_law) {
            (BacklashModel::Clamped, Contact::Driving) if k * (delta - g) + d * rel <= 0.0 => {
                Contact::Free
            }
            (BacklashModel::Clamped, Contact::Braking) if k * (delta + g) + d * rel >= 0.0 => {
                Contact::Free
            }
            _ => dz_law,
        }
    }

    /// Shaft torque Ts in pu for the current state and mode.
    pub fn shaft_torque_pu(&self) -> f64 {
        let Shaft { k, d, g } = self.shaft;
        let (delta, rel) = (self.x.x, self.x.z - self.x.w);
        match self.contact {
            Contact::Free => 0.0,
            Contact::Driving => k * (delta - g) + d * rel,
            Contact::Braking => k * (delta + g) + d * rel,
        }
    }

    /// Advances by `dt_s` with the inputs held. `dt_s` must be finite and ≥ 0 (checked by callers).
    pub fn advance(&mut self, dt_s: f64, u: &Vec3) {
        if dt_s <= 0.0 {
            return;
        }
        if dt_s <= self.h_max_s {
            // The usual case (a harness step is shorter than the longest sub-step).
            self.piece(dt_s, u);
            return;
        }
        let pieces = (dt_s / self.h_max_s).ceil().max(1.0);
        let h = dt_s / pieces;
        for _ in 0..pieces as u64 {
            self.piece(h, u);
        }
    }

    fn mode(&self) -> &Mode {
        let [free, driving, braking] = &self.modes;
        match self.contact {
            Contact::Free => free,
            Contact::Driving => driving,
            Contact::Braking => braking,
        }
    }

    fn mode_mut(&mut self) -> &mut Mode {
        let [free, driving, braking] = &mut self.modes;
        match self.contact {
            Contact::Free => free,
            Contact::Driving => driving,
            Contact::Braking => braking,
        }
    }

    fn piece(&mut self, h: f64, u: &Vec3) {
        let mut remaining = h;
        let mut first = true;
        let mut changes = 0;
        loop {
            let x0 = self.x;
            let x_end = if first {
                self.mode_mut().step(h, &x0, u)
            } else {
                let m = self.mode();
                Taylor::new(&m.a, &m.b, &x0, u, remaining).state(remaining)
            };
            first = false;
            let m = self.mode();
            if changes >= MAX_EVENTS_PER_STEP
                || !m
                    .guards
                    .iter()
                    .flatten()
                    .any(|g| suspect(g, &x0, &x_end, u, remaining))
            {
                self.x = x_end;
                return;
            }
            // Redo the step with the Taylor series and find the earliest crossing.
            let taylor = Taylor::new(&m.a, &m.b, &x0, u, remaining);
            let mut best: Option<(f64, Contact)> = None;
            for g in m.guards.iter().flatten() {
                if let Some(t) = first_crossing(&taylor, g, remaining) {
                    if best.is_none_or(|(tb, _)| t < tb) {
                        best = Some((t, g.target));
                    }
                }
            }
            self.searches += 1;
            let Some((tau, target)) = best else {
                self.x = x_end;
                return;
            };
            self.x = taylor.state(tau);
            self.contact = target;
            self.events += 1;
            changes += 1;
            remaining -= tau;
            if remaining <= 0.0 {
                return;
            }
        }
    }
}

/// Could the guard fire within the step? Yes if it is positive at the end, or if some linear
/// part has an interior maximum whose tangent-line bound reaches zero.
fn suspect(g: &Guard, x0: &Vec5, x1: &Vec5, u: &Vec3, h: f64) -> bool {
    let mut end = f64::INFINITY;
    for l in g.lins() {
        end = end.min(l.value(x1));
    }
    if end > 0.0 {
        return true;
    }
    g.lins().iter().any(|l| {
        // An interior maximum needs the rate to point out at the start and back in at the end.
        let d0 = l.rate(x0, u);
        if d0 <= 0.0 {
            return false;
        }
        let d1 = l.rate(x1, u);
        if d1 >= 0.0 {
            return false;
        }
        let (l0, l1) = (l.value(x0), l.value(x1));
        // Tangents at both ends meet above a concave arc: their intersection bounds the peak.
        let t = ((l1 - l0 - d1 * h) / (d0 - d1)).clamp(0.0, h);
        let peak = l0 + d0 * t;
        // Margin: the arc is only nearly concave over one step.
        peak > -0.5 * l0.abs().min(l1.abs())
    })
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
            let mut inv_fact = 1.0;
            for (k, (c, dk)) in row.iter_mut().zip(t.d.iter().take(t.n)).enumerate() {
                if k > 0 {
                    inv_fact /= k as f64;
                }
                *c = l.c.dot(dk) * inv_fact;
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
        let mut next = if df != 0.0 {
            x - f / df
        } else {
            0.5 * (lo + hi)
        };
        // Converged: step just across the root so the bracket closes.
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
        x = next;
    }
    Some(hi)
}

/// Fastest rate of the plant, ‖A‖∞ of the engaged mode with the winding (1/s): sets the
/// internal sub-step (‖A‖·h ≤ 0.5).
pub(crate) fn fastest_rate_per_s(mech: &MechanicsConfig, winding: Option<Winding>) -> f64 {
    let dv = mech.derived();
    let shaft = Shaft {
        k: dv.stiffness_pu_per_rad,
        d: dv.damping_pu,
        g: dv.half_gap_rad,
    };
    let (a, _) = system_matrices(mech, &shaft, 1.0, 1.0, winding, dv.base_speed_rad_s);
    a.row_iter()
        .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// A and B of one mode. `on` = 1 when the shaft transmits, `sigma` = ±1 selects the edge.
fn system_matrices(
    m: &MechanicsConfig,
    s: &Shaft,
    on: f64,
    sigma: f64,
    winding: Option<Winding>,
    wb: f64,
) -> (Mat5, Mat53) {
    let (jm, jl) = (m.motor_inertia_s, m.load_inertia_s);
    let (k, d) = (on * s.k, on * s.d);
    let offset = sigma * s.k * s.g; // Ts = K·δ − σ·K·g + D·(ωm − ωl)
    let (i_to_wm, u_to_wm, i_row, u_to_i) = match winding {
        // L·di/dt = v − R·i − ωm ; Tm = i.
        Some(w) => (
            1.0 / jm,
            0.0,
            [0.0, 0.0, -1.0 / w.l_pu_s, 0.0, -w.r_pu / w.l_pu_s],
            1.0 / w.l_pu_s,
        ),
        // Tm = u directly; the current state stays at zero.
        None => (0.0, 1.0 / jm, [0.0; 5], 0.0),
    };
    let [i0, i1, i2, i3, i4] = i_row;
    #[rustfmt::skip]
    let a = Mat5::new(
        0.0,      0.0, wb,                         -wb,                        0.0,
        0.0,      0.0, 0.0,                        wb,                         0.0,
        -k / jm,  0.0, (-d - m.motor_viscous_pu) / jm, d / jm,                 i_to_wm,
        k / jl,   0.0, d / jl,                     (-d - m.load_viscous_pu) / jl, 0.0,
        i0,       i1,  i2,                         i3,                         i4,
    );
    #[rustfmt::skip]
    let b = Mat53::new(
        0.0,     0.0,       0.0,
        0.0,     0.0,       0.0,
        u_to_wm, 0.0,       offset / jm,
        0.0,     -1.0 / jl, -offset / jl,
        u_to_i,  0.0,       0.0,
    );
    (a, b)
}

/// The guards leaving `contact` under `law`.
fn guards(
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
    let lin = |c: [f64; 5], off: f64| Linear::new(Vec5::from(c), off, a, b);
    let one = |l: Linear, target| {
        Some(Guard {
            lins: [l, l],
            two: false,
            target,
        })
    };
    let both = |l1: Linear, l2: Linear, target| {
        Some(Guard {
            lins: [l1, l2],
            two: true,
            target,
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
