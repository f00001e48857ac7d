//! The construction of a [`super::Profile`] by phase: the settings validated
//! ([`Settings::validate`]), then the constant-jerk segments planned from their exact f64
//! start states and quantized to Q32.32 ([`Planner::plan`]).

use super::{MAX_SEGMENTS, ProfileConfig, ProfileKind, Q32, Segment};
use crate::error::ConfigError;

/// Split an f64 position \[counts\] into whole counts and a Q0.32 fraction.
fn split_counts(p: f64) -> (i64, i64) {
    let whole = p as i64;
    let whole = if (whole as f64) > p { whole - 1 } else { whole };
    let frac = ((p - whole as f64) * Q32) as i64;
    (whole, frac.clamp(0, (1 << 32) - 1))
}

fn to_q32(x: f64) -> i64 {
    (x * Q32) as i64
}

fn check(
    v: f32,
    param: &'static str,
    min: f32,
    max: f32,
    min_exclusive: bool,
) -> Result<f32, ConfigError> {
    if !v.is_finite() {
        return Err(ConfigError::NotFinite { param });
    }
    let ok_low = if min_exclusive { v > min } else { v >= min };
    if ok_low && v <= max {
        Ok(v)
    } else {
        Err(ConfigError::OutOfRange {
            param,
            value: v,
            min,
            max,
            min_exclusive,
        })
    }
}

/// The validated settings of a [`ProfileConfig`], in the order [`super::Profile::new`]
/// checks them.
#[derive(Clone, Copy, Debug)]
pub(super) struct Settings {
    /// Peak velocity \[pu\].
    v_pu: f32,
    /// Acceleration time \[s\].
    ta: f32,
    /// Deceleration time \[s\].
    td: f32,
    /// Start delay \[s\].
    delay: f32,
    /// Hold time \[s\]; `None` = hold forever.
    hold: Option<f32>,
    /// Jerk time \[s\]; 0 for a trapezoid.
    tj: f32,
}

impl Settings {
    /// Check every setting of `cfg` (the first bad one is the error).
    pub(super) fn validate(cfg: &ProfileConfig) -> Result<Self, ConfigError> {
        let v_pu = check(
            cfg.peak_velocity_pu,
            "profile.peak_velocity_pu",
            -10.0,
            10.0,
            false,
        )?;
        let ta = check(
            cfg.accel_time_s,
            "profile.accel_time_s",
            0.0,
            10_000.0,
            true,
        )?;
        let td = check(
            cfg.decel_time_s,
            "profile.decel_time_s",
            0.0,
            10_000.0,
            true,
        )?;
        let delay = check(
            cfg.start_delay_s,
            "profile.start_delay_s",
            0.0,
            10_000.0,
            false,
        )?;
        let hold = if cfg.hold_time_s == f32::INFINITY {
            None
        } else {
            Some(check(
                cfg.hold_time_s,
                "profile.hold_time_s",
                0.0,
                10_000.0,
                false,
            )?)
        };
        let tj = match cfg.kind {
            ProfileKind::Trapezoid => 0.0,
            ProfileKind::SCurve { jerk_time_s } => check(
                jerk_time_s,
                "profile.kind.jerk_time_s",
                0.0,
                ta.min(td) / 2.0,
                true,
            )?,
        };
        Ok(Self {
            v_pu,
            ta,
            td,
            delay,
            hold,
            tj,
        })
    }
}

/// The segment list under construction, with the exact (f64) state at its end.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Planner {
    /// The segments, the first `count` of them planned.
    pub(super) segs: [Segment; MAX_SEGMENTS],
    /// Number of segments planned.
    pub(super) count: usize,
    /// Position \[counts\].
    p: f64,
    /// Velocity \[counts/tick\].
    v: f64,
    /// Acceleration \[counts/tick²\].
    a: f64,
}

impl Planner {
    /// Append a segment of `n` ticks starting at acceleration `a_start` with jerk `j`
    /// (none if `n` is 0), and advance the exact state over it.
    fn push(&mut self, n: u32, a_start: f64, j: f64) {
        if n == 0 {
            return;
        }
        self.a = a_start;
        if let Some(s) = self.segs.get_mut(self.count) {
            let (p0_int, p0_frac) = split_counts(self.p);
            *s = Segment {
                ticks: n,
                p0_int,
                p0_frac,
                v0: to_q32(self.v),
                a0: to_q32(self.a),
                jerk: to_q32(j),
                jerk_over_6: to_q32(j / 6.0),
            };
            self.count += 1;
        }
        let nf = f64::from(n);
        self.p += self.v * nf + self.a * nf * nf / 2.0 + j * nf * nf * nf / 6.0;
        self.v += self.a * nf + j * nf * nf / 2.0;
        self.a += j * nf;
    }

    /// A velocity change of `dv` counts/tick: `nj` jerk ticks, `nc` constant-acceleration
    /// ticks, `nj` jerk ticks, with the peak acceleration that reaches `dv` exactly after
    /// nc + 2·nj ticks. (Negating `dv` negates the acceleration and jerk exactly.)
    fn ramp(&mut self, nj: u32, nc: u32, dv: f64) {
        let acc = dv / f64::from(nc + nj);
        let jerk = if nj > 0 { acc / f64::from(nj) } else { 0.0 };
        if nj > 0 {
            self.push(nj, 0.0, jerk);
        }
        self.push(nc, acc, 0.0);
        if nj > 0 {
            self.push(nj, acc, -jerk);
        }
    }

    /// The segments of the settings `s` at `f` velocity ticks per second, with `cpps`
    /// counts per pu·s.
    pub(super) fn plan(s: &Settings, f: f64, cpps: f64) -> Self {
        let ticks = |t: f32| (f64::from(t) * f + 0.5) as u32;
        let v_cpt = f64::from(s.v_pu) * cpps / f; // counts per tick at the peak

        // Phase tick counts: the ramp of a phase of n ticks with n_j jerk ticks at each end.
        let nj = ticks(s.tj);
        let ramp = |t: f32| -> (u32, u32) {
            let n = ticks(t).max(1);
            let nj = nj.min(n / 2);
            (nj, n - 2 * nj)
        };
        let (nja, nca) = ramp(s.ta);
        let (njd, ncd) = ramp(s.td);
        let mut pl = Self::default();
        pl.push(ticks(s.delay), 0.0, 0.0);
        pl.ramp(nja, nca, v_cpt);
        pl.v = v_cpt;
        match s.hold {
            None => pl.push(u32::MAX, 0.0, 0.0),
            Some(h) => {
                pl.push(ticks(h), 0.0, 0.0);
                pl.ramp(njd, ncd, -v_cpt);
                pl.v = 0.0;
                pl.push(u32::MAX, 0.0, 0.0);
            }
        }
        pl
    }
}
