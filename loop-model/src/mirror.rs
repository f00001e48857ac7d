//! The controller's ticks in f64 with its quantized coefficients and without its clamps:
//! the linear system the fixed-point code implements while no signal saturates.
//!
//! Every block follows its controller-core module equation for equation (observer,
//! acceleration feedback in closed form, filters, PI regulators, differentiators, position
//! loop, the torque-reference notch in its two-state form). The order is the same, and so
//! is the torque the observer is fed. The coefficients are not quantized here: each is the
//! linear form (`linear()`) of the block the controller itself builds
//! ([`Controller::blocks`]), the stored fixed-point value as f64. What is left out is
//! nonlinear or a start-up effect: the clamps, the 1-LSB rounding, the observer's count
//! interval, the faults and the priming of the estimators.
//! `tests/it/workflows/linear_model.rs` runs this mirror and the fixed-point controller on
//! the same inputs, so a drift between the two fails a test.

use controller_core::differentiator::Differentiator;
use controller_core::filter::LowPassLinear;
use controller_core::notch::NotchDesign;
use controller_core::per_unit::Counts;
use controller_core::{
    AfbMode, AfbRate, ConfigError, Controller, DriveConfig, Estimator, Gains, ObserverTorque,
};

/// The quantized coefficients of a controller, as f64.
#[derive(Debug, Clone, PartialEq)]
pub struct Coefficients {
    /// Current ticks per velocity tick.
    pub ticks_per_velocity: usize,
    /// Position loop on.
    pub position_loop: bool,
    /// k_pos \[pu per count\] (Q1.31).
    pub k_pos: f64,
    /// Velocity feed-forward gain (Q16.16).
    pub velocity_ff: f64,
    /// Acceleration feed-forward (Q16.16).
    pub k_accel_ff: f64,
    /// Velocity PI Kp (Q16.16), Ki·Ts (Q8.24).
    pub vel_kp: f64,
    /// Velocity PI Ki·Ts.
    pub vel_ki_ts: f64,
    /// Current PI Kp, Ki·Ts.
    pub cur_kp: f64,
    /// Current PI Ki·Ts.
    pub cur_ki_ts: f64,
    /// Velocity feedback filter.
    pub velocity_filter: LowPassLinear,
    /// AFB filter.
    pub afb_filter: LowPassLinear,
    /// AFB form.
    pub afb_mode: AfbMode,
    /// Ka (Q16.16) and the closed-form g·Ka (Q16.16).
    pub ka: f64,
    /// g·Ka.
    pub ka_closed: f64,
    /// AFB at the current rate (else the velocity rate).
    pub afb_at_current_rate: bool,
    /// Sources.
    pub afb_source: Estimator,
    /// Velocity source.
    pub velocity_source: Estimator,
    /// Observer torque input.
    pub observer_torque: ObserverTorque,
    /// Observer l1, l2, l3 (Q2.30).
    pub l: [f64; 3],
    /// Observer k_u (Q8.24), velocity and acceleration scales (Q8.24, Q16.16).
    pub k_u: f64,
    /// pu per count per current tick.
    pub obs_k_vel: f64,
    /// pu/s per count per current tick².
    pub obs_k_acc: f64,
    /// Differentiators: velocity-rate and current-rate scales (k_vel Q8.24, k_acc Q16.16).
    pub diff_vel: (f64, f64),
    /// Current-rate scales.
    pub diff_cur: (f64, f64),
    /// The torque-reference notch, `None` without one; run as its two-state realization
    /// ([`NotchDesign::transposed_step`]).
    pub notch: Option<NotchDesign>,
}

impl Coefficients {
    /// From a drive and the gains its controller runs with: every coefficient is the
    /// linear form (`linear()`) of the block the controller built from `g` runs with
    /// ([`Controller::blocks`]), so it is the stored fixed-point value itself. Fails where
    /// the controller refuses the gains ([`Controller::from_gains`]).
    pub fn new(cfg: &DriveConfig, g: &Gains) -> Result<Self, ConfigError> {
        let b = Controller::from_gains(g)?.blocks();
        let (vel, cur) = (b.velocity_regulator.linear(), b.current_regulator.linear());
        let (obs, afb) = (b.observer.linear(), b.accel_feedback.linear());
        let diff = |d: Differentiator| {
            let l = d.linear();
            (l.k_vel, l.k_acc)
        };
        Ok(Self {
            ticks_per_velocity: g.ticks_per_velocity.max(1) as usize,
            position_loop: g.kpp > 0.0,
            k_pos: b.k_pos.to_num(),
            velocity_ff: b.velocity_ff.to_num(),
            k_accel_ff: b.k_accel_ff.to_num(),
            vel_kp: vel.kp,
            vel_ki_ts: vel.ki_ts,
            cur_kp: cur.kp,
            cur_ki_ts: cur.ki_ts,
            velocity_filter: b.velocity_filter.linear(),
            afb_filter: afb.filter,
            afb_mode: cfg.accel_feedback.mode,
            ka: afb.ka,
            ka_closed: afb.ka_closed,
            afb_at_current_rate: cfg.accel_feedback.rate == AfbRate::Current,
            afb_source: cfg.accel_feedback.source,
            velocity_source: cfg.velocity_estimator,
            observer_torque: cfg.observer.torque_input,
            l: obs.l,
            k_u: obs.k_u,
            obs_k_vel: obs.k_vel,
            obs_k_acc: obs.k_acc,
            diff_vel: diff(b.diff_velocity_rate),
            diff_cur: diff(b.diff_current_rate),
            notch: b.notch.map(|n| n.linear()),
        })
    }

    /// Length of this controller's state vector ([`State::to_vec`] cut to it): the notch's
    /// two states only when there is a notch, so a drive without one has the same loop
    /// model, entry for entry, as before the notch existed.
    #[must_use]
    pub fn state_len(&self) -> usize {
        STATE_LEN + self.notch.map_or(0, |_| NOTCH_LEN)
    }
}

/// The controller's state, every entry linear in the signals.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct State {
    /// Observer position \[counts\], velocity \[counts/tick\], disturbance \[counts/tick²\].
    pub obs: [f64; 3],
    /// Observer acceleration over the last tick and its residual \[counts/tick²\].
    pub obs_acc: [f64; 2],
    /// Velocity and current PI integrals \[pu\].
    pub integral: [f64; 2],
    /// Velocity filter state.
    pub velocity_filter: [f64; 4],
    /// AFB filter state.
    pub afb_filter: [f64; 4],
    /// Velocity-rate differentiator: last position \[counts\], last difference.
    pub diff_velocity: [f64; 2],
    /// Current-rate differentiator: last position, last difference.
    pub diff_current: [f64; 2],
    /// Held velocity PI output, AFB term, last torque reference, last current sample \[pu\].
    pub held: [f64; 4],
    /// The torque-reference notch's two states (last in the layout;
    /// [`NotchDesign::transposed_step`]).
    pub notch: [f64; 2],
}

/// Number of f64 entries of [`State`] without the notch's.
pub const STATE_LEN: usize = 3 + 2 + 2 + 4 + 4 + 4 + 4;
/// Number of the notch's entries, after the others.
pub const NOTCH_LEN: usize = 2;

impl State {
    /// Flattened, the notch's states last (a controller without a notch uses the first
    /// [`STATE_LEN`] entries: [`Coefficients::state_len`]).
    #[must_use]
    pub fn to_vec(&self) -> Vec<f64> {
        let mut v = Vec::with_capacity(STATE_LEN + NOTCH_LEN);
        v.extend_from_slice(&self.obs);
        v.extend_from_slice(&self.obs_acc);
        v.extend_from_slice(&self.integral);
        v.extend_from_slice(&self.velocity_filter);
        v.extend_from_slice(&self.afb_filter);
        v.extend_from_slice(&self.diff_velocity);
        v.extend_from_slice(&self.diff_current);
        v.extend_from_slice(&self.held);
        v.extend_from_slice(&self.notch);
        v
    }

    /// The state of a shift of every position by `counts`: the entries that hold a
    /// position (observer, differentiators' last readings).
    #[must_use]
    pub fn position_shift(counts: f64) -> Self {
        Self {
            obs: [counts, 0.0, 0.0],
            diff_velocity: [counts, 0.0],
            diff_current: [counts, 0.0],
            ..Self::default()
        }
    }

    /// From [`State::to_vec`]'s layout (missing entries are zero).
    #[must_use]
    pub fn from_slice(v: &[f64]) -> Self {
        let mut it = v.iter().copied().chain(std::iter::repeat(0.0));
        let mut take = |out: &mut [f64]| {
            for o in out.iter_mut() {
                *o = it.next().unwrap_or(0.0);
            }
        };
        let mut s = Self::default();
        take(&mut s.obs);
        take(&mut s.obs_acc);
        take(&mut s.integral);
        take(&mut s.velocity_filter);
        take(&mut s.afb_filter);
        take(&mut s.diff_velocity);
        take(&mut s.diff_current);
        take(&mut s.held);
        take(&mut s.notch);
        s
    }
}

/// Where the loop may be opened for margins: the signal used downstream is the external
/// `w` instead of the computed one, which is reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Break {
    /// Closed.
    None,
    /// At the velocity regulator's output (torque reference without AFB).
    VelocityRegulator,
    /// At the acceleration-feedback term.
    AccelerationFeedback,
}

/// Exogenous inputs of one tick.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Inputs {
    /// Commanded position \[counts\], velocity \[pu\], acceleration \[pu/s\].
    pub setpoint: [f64; 3],
    /// The break signal `w`.
    pub w: f64,
}

/// What one current tick produced.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TickOutputs {
    /// Voltage command \[pu\].
    pub voltage: f64,
    /// Torque reference \[pu\].
    pub torque_ref: f64,
    /// The computed signal at the break (0 without one).
    pub at_break: f64,
}

impl Coefficients {
    fn predicted(&self, s: &State, torque: f64) -> f64 {
        (torque * self.k_u + s.obs_acc[1]) * self.obs_k_acc
    }

    /// The AFB step: closed form with the observer, or the plain update with a measured
    /// acceleration `a_meas`. `p` is the torque reference without the AFB term.
    fn afb(&self, s: &mut State, p: f64, a_cmd: f64, a_meas: f64) -> f64 {
        let c = match self.afb_mode {
            AfbMode::Off => return 0.0,
            AfbMode::Plain => 0.0,
            AfbMode::Error => a_cmd,
        };
        if self.afb_source == Estimator::Observer {
            let (h, b0) = self.afb_filter.begin(&s.afb_filter);
            let afb = self.ka_closed * (h + b0 * (c - self.predicted(s, p)));
            let x_t = c - self.predicted(s, p + afb);
            self.afb_filter.finish(&mut s.afb_filter, h, x_t);
            afb
        } else {
            self.ka * self.afb_filter.process(&mut s.afb_filter, c - a_meas)
        }
    }

    fn differentiate(slot: &mut [f64; 2], k: (f64, f64), position: f64) -> (f64, f64) {
        let [last, last_delta] = *slot;
        let delta = position - last;
        *slot = [position, delta];
        (delta * k.0, (delta - last_delta) * k.1)
    }

    /// The velocity tick with the position `position` \[counts\].
    pub fn velocity_tick(&self, s: &mut State, position: f64, inp: &Inputs, brk: Break) -> f64 {
        let [sp_pos, sp_vel, sp_acc] = inp.setpoint;
        let uses_diff = self.velocity_source == Estimator::Differentiation
            || self.afb_source == Estimator::Differentiation;
        let (v_diff, a_diff) = if uses_diff {
            Self::differentiate(&mut s.diff_velocity, self.diff_vel, position)
        } else {
            (0.0, 0.0)
        };
        let v_raw = match self.velocity_source {
            Estimator::Differentiation => v_diff,
            Estimator::Observer => s.obs[1] * self.obs_k_vel,
        };
        let v_fb = self.velocity_filter.process(&mut s.velocity_filter, v_raw);
        let v_cmd = if self.position_loop {
            self.velocity_ff * sp_vel + self.k_pos * (sp_pos - position)
        } else {
            sp_vel
        };
        let e = v_cmd - v_fb;
        s.integral[0] += e * self.vel_ki_ts;
        let pi = self.vel_kp * e + self.k_accel_ff * sp_acc + s.integral[0];
        let mut reported = 0.0;
        s.held[0] = if brk == Break::VelocityRegulator {
            reported = pi;
            inp.w
        } else {
            pi
        };
        if !self.afb_at_current_rate {
            let a_est = match self.afb_source {
                Estimator::Differentiation => a_diff,
                Estimator::Observer => s.obs_acc[0] * self.obs_k_acc,
            };
            let afb = self.afb(s, s.held[0], sp_acc, a_est);
            s.held[1] = self.at_afb_break(afb, inp, brk, &mut reported);
        }
        reported
    }

    fn at_afb_break(&self, afb: f64, inp: &Inputs, brk: Break, reported: &mut f64) -> f64 {
        if brk == Break::AccelerationFeedback {
            *reported = afb;
            inp.w
        } else {
            afb
        }
    }

    /// The current tick with the position \[counts\] and the current sample \[pu\].
    pub fn current_tick(
        &self,
        s: &mut State,
        position: f64,
        current: f64,
        inp: &Inputs,
        brk: Break,
    ) -> TickOutputs {
        let torque = match self.observer_torque {
            ObserverTorque::Command => s.held[2],
            ObserverTorque::MeasuredCurrent => 0.5 * (s.held[3] + current),
        };
        s.held[3] = current;
        // Observer (controller-core observer.rs), in counts and ticks.
        let [p, v, d] = s.obs;
        let u = torque * self.k_u;
        let acc = u + d;
        let p_pred = p + v + 0.5 * acc;
        let v_pred = v + acc;
        let e = position - p_pred;
        let [l1, l2, l3] = self.l;
        s.obs = [p_pred + l1 * e, v_pred + l2 * e, d + l3 * e];
        let residual = d + l2 * e;
        s.obs_acc = [u + residual, residual];
        let mut reported = 0.0;
        if self.afb_mode == AfbMode::Off {
            // The controller never writes its AFB term: it stays zero.
            s.held[1] = 0.0;
        } else if self.afb_at_current_rate {
            let a_meas = if self.afb_source == Estimator::Differentiation {
                Self::differentiate(&mut s.diff_current, self.diff_cur, position).1
            } else {
                0.0
            };
            let afb = self.afb(s, s.held[0], inp.setpoint[2], a_meas);
            s.held[1] = self.at_afb_break(afb, inp, brk, &mut reported);
        }
        // The notch shapes the sum (velocity PI + AFB) on its way to the current loop; the
        // AFB's closed form above solved for the sum, the observer sees the notched torque.
        let i_sum = s.held[0] + s.held[1];
        let i_ref = match &self.notch {
            Some(n) => n.transposed_step(&mut s.notch, i_sum),
            None => i_sum,
        };
        s.held[2] = i_ref;
        let e = i_ref - current;
        s.integral[1] += e * self.cur_ki_ts;
        TickOutputs {
            voltage: self.cur_kp * e + s.integral[1],
            torque_ref: i_ref,
            at_break: reported,
        }
    }
}

/// The commanded position of a setpoint in counts, as the controller reads it (Q48.16).
#[must_use]
pub fn setpoint_counts(counts: f64) -> f64 {
    Counts::saturating_from_num(counts).to_num()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::Coefficients;
    use controller_core::filter::{LowPass, LowPassLinear};
    use controller_core::notch::NotchConfig;
    use controller_core::per_unit::Coef;
    use controller_core::{
        AfbMode, AfbRate, Controller, DriveConfig, Estimator, FilterConfig, Gains, design,
    };

    /// The shipped machines' drives (`configs/machines/*.toml`), by file name.
    fn shipped() -> Vec<(String, DriveConfig)> {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/machines");
        let mut out: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .map(|p| {
                let drive = machine_file::load(&p).unwrap().drive;
                (p.file_name().unwrap().to_string_lossy().into_owned(), drive)
            })
            .collect();
        out.sort_by(|a, b| a.0.cmp(&b.0));
        out
    }

    /// Each shipped drive, and variants of it that take every other path of the mirror:
    /// the AFB from differentiation at the velocity rate, the error form with biquads, AFB
    /// off, no position loop, and a notch.
    fn drives() -> Vec<(String, DriveConfig, Gains)> {
        let mut out = Vec::new();
        for (name, d) in shipped() {
            let mut diff = d;
            diff.accel_feedback.source = Estimator::Differentiation;
            diff.velocity_estimator = Estimator::Differentiation;
            diff.accel_feedback.rate = AfbRate::Velocity;
            let mut biquads = d;
            biquads.accel_feedback.mode = AfbMode::Error;
            biquads.accel_feedback.filter = FilterConfig::SecondOrder {
                corner_hz: 150.0,
                q: 0.8,
            };
            biquads.velocity_filter = FilterConfig::SecondOrder {
                corner_hz: 300.0,
                q: 0.7,
            };
            let mut off = d;
            off.accel_feedback.mode = AfbMode::Off;
            let mut speed = d;
            speed.position_bandwidth_rad_s = 0.0;
            let mut notched = d;
            notched.notch = Some(NotchConfig {
                centre_hz: 180.0,
                width_hz: 50.0,
                depth_db: 25.0,
            });
            for (what, cfg) in [
                ("", d),
                (" (differentiation)", diff),
                (" (error form, biquads)", biquads),
                (" (AFB off)", off),
                (" (speed mode)", speed),
                (" (notch)", notched),
            ] {
                let g = design(&cfg).unwrap_or_else(|e| panic!("{name}{what}: {e}"));
                out.push((format!("{name}{what}"), cfg, g));
            }
        }
        out
    }

    /// `v` is the fixed-point value `raw` with `frac` fractional bits, exactly.
    fn is_bits(v: f64, raw: i32, frac: i32) -> bool {
        v * 2f64.powi(frac) == f64::from(raw)
    }

    /// A filter's linear form holds its Q2.30 bits.
    fn filter_is_bits(lin: LowPassLinear, f: LowPass) -> bool {
        let c = |v: f64, c: Coef| is_bits(v, c.to_bits(), 30);
        match (lin, f) {
            (LowPassLinear::None, LowPass::None) => true,
            (LowPassLinear::FirstOrder { alpha }, LowPass::FirstOrder { alpha: a }) => c(alpha, a),
            (
                LowPassLinear::SecondOrder { b0, a1, a2 },
                LowPass::SecondOrder {
                    b0: q0,
                    a1: q1,
                    a2: q2,
                },
            ) => c(b0, q0) && c(a1, q1) && c(a2, q2),
            _ => false,
        }
    }

    /// Every coefficient of the mirror is the fixed-point value of the block the controller
    /// runs, bit for bit (the value times 2^frac is the stored raw word), on every shipped
    /// machine and its variants; the notch's are whole Q2.30 words of its linear form.
    #[test]
    fn the_mirror_holds_the_blocks_fixed_point_bits() {
        let all = drives();
        assert!(all.len() >= 6 * 3, "{} drives", all.len());
        for (name, cfg, g) in all {
            let m = Coefficients::new(&cfg, &g).unwrap_or_else(|e| panic!("{name}: {e}"));
            let b = Controller::from_gains(&g).unwrap().blocks();
            let (o, afb) = (&b.observer, &b.accel_feedback);
            let (v, c) = (&b.velocity_regulator, &b.current_regulator);
            let (dv, dc) = (&b.diff_velocity_rate, &b.diff_current_rate);
            let words = [
                ("k_pos", m.k_pos, b.k_pos.to_bits(), 31),
                ("velocity_ff", m.velocity_ff, b.velocity_ff.to_bits(), 16),
                ("k_accel_ff", m.k_accel_ff, b.k_accel_ff.to_bits(), 16),
                ("vel_kp", m.vel_kp, v.kp.to_bits(), 16),
                ("vel_ki_ts", m.vel_ki_ts, v.ki_ts.to_bits(), 24),
                ("cur_kp", m.cur_kp, c.kp.to_bits(), 16),
                ("cur_ki_ts", m.cur_ki_ts, c.ki_ts.to_bits(), 24),
                ("ka", m.ka, afb.ka.to_bits(), 16),
                ("ka_closed", m.ka_closed, afb.ka_closed.to_bits(), 16),
                ("l1", m.l[0], o.l1.to_bits(), 30),
                ("l2", m.l[1], o.l2.to_bits(), 30),
                ("l3", m.l[2], o.l3.to_bits(), 30),
                ("k_u", m.k_u, o.k_u.to_bits(), 24),
                ("obs_k_vel", m.obs_k_vel, o.k_vel.to_bits(), 24),
                ("obs_k_acc", m.obs_k_acc, o.k_acc.to_bits(), 16),
                ("diff_vel.0", m.diff_vel.0, dv.k_vel.to_bits(), 24),
                ("diff_vel.1", m.diff_vel.1, dv.k_acc.to_bits(), 16),
                ("diff_cur.0", m.diff_cur.0, dc.k_vel.to_bits(), 24),
                ("diff_cur.1", m.diff_cur.1, dc.k_acc.to_bits(), 16),
            ];
            for (what, value, raw, frac) in words {
                assert!(is_bits(value, raw, frac), "{name}: {what} {value} vs {raw}");
            }
            assert!(
                filter_is_bits(m.velocity_filter, b.velocity_filter),
                "{name}"
            );
            assert!(filter_is_bits(m.afb_filter, afb.filter), "{name}");
            assert_eq!(m.notch, b.notch.map(|n| n.linear()), "{name}");
            assert_eq!(m.notch.is_some(), cfg.notch.is_some(), "{name}");
            if let Some(n) = m.notch {
                for x in [n.b0, n.b1, n.b2, n.a2] {
                    let w = x * 2f64.powi(30);
                    assert!(w.fract() == 0.0 && w.abs() <= 2f64.powi(31), "{name}: {x}");
                }
            }
        }
    }
}
