//! Motion profiles in fixed point: trapezoidal and S-curve velocity profiles with
//! position, velocity and acceleration outputs (the commands of the paper's Fig. 4 and 6).
//!
//! Durations are rounded to whole velocity ticks at construction and the peak acceleration
//! and jerk recomputed so the velocity lands exactly on the peak. Internally the profile
//! integrates in counts and ticks with constant jerk per segment:
//! ```text
//! p ← p + v + a/2 + j/6,   v ← v + a + j/2,   a ← a + j        (exact for constant jerk)
//! ```
//! p is whole counts (i64) plus a Q0.32 fraction (the fraction's carry moves into the whole
//! counts every tick, so the per-tick work stays in 64 bits), v Q32.32 counts/tick,
//! a Q32.32 counts/tick², j Q32.32 counts/tick³.
//! Each segment restarts from exact start values computed once (f64), so rounding never
//! accumulates across segments.

use crate::config::DriveConfig;
use crate::controller::Setpoint;
use crate::design::Gains;
use crate::error::ConfigError;
use crate::per_unit::{Counts, Gain, Pu, TickGain, counts_per_pu_s, mul_bits, sat_shr};

mod plan;
use plan::{Planner, Settings};

/// Shape of the acceleration phases.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ProfileKind {
    /// Constant acceleration (trapezoidal velocity).
    Trapezoid,
    /// Jerk-limited (S-curve velocity): each acceleration change takes `jerk_time_s`.
    SCurve {
        /// Duration of each jerk ramp \[s\], 0 < t_j ≤ half of the accel and decel times.
        jerk_time_s: f32,
    },
}

/// Profile settings (validated once by [`Profile::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProfileConfig {
    /// Acceleration shape.
    pub kind: ProfileKind,
    /// Peak (cruise) velocity \[pu\], signed, |v| ≤ 10.
    pub peak_velocity_pu: f32,
    /// Time from standstill to the peak velocity \[s\], 0 < t ≤ 10,000.
    pub accel_time_s: f32,
    /// Time at the peak velocity \[s\], ≥ 0; `f32::INFINITY` = never decelerate.
    pub hold_time_s: f32,
    /// Time from the peak velocity back to standstill \[s\], 0 < t ≤ 10,000.
    pub decel_time_s: f32,
    /// Standstill before the acceleration starts \[s\], 0..=10,000.
    pub start_delay_s: f32,
}

impl ProfileConfig {
    /// The paper's Fig. 6 command: standstill, ramp to 1 pu in 1 s, then hold.
    #[must_use]
    pub const fn fig6() -> Self {
        Self {
            kind: ProfileKind::Trapezoid,
            peak_velocity_pu: 1.0,
            accel_time_s: 1.0,
            hold_time_s: f32::INFINITY,
            decel_time_s: 1.0,
            start_delay_s: 0.0,
        }
    }
}

// delay, 3 accel, hold, 3 decel, final standstill = 9.
const MAX_SEGMENTS: usize = 9;

/// One constant-jerk segment with its exact start state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Segment {
    ticks: u32,
    /// Start position, whole counts.
    p0_int: i64,
    /// Start position, fraction of a count (Q0.32, 0 ≤ f < 2^32).
    p0_frac: i64,
    v0: i64,
    a0: i64,
    jerk: i64,
    /// j/6 in Q32.32 (precomputed: no division on the tick path).
    jerk_over_6: i64,
}

impl Segment {
    /// Whether every add of [`Profile::next`] stays below 2^62 in magnitude throughout this
    /// segment, so plain adds give exactly what the saturating ones give.
    ///
    /// Range argument: in the segment the integer state follows a_k = a0 + k·j exactly, so
    /// |a_k| ≤ A = |a0| + n·|j|, and v_k = v0 + Σ (a_i + j/2), so |v_k| ≤ V = |v0| + n·(A + |j|),
    /// for k ≤ n (the last segment, n = u32::MAX, has a = j = 0 and keeps v0). The adds form
    /// v + a/2 + j/6 and p_frac (< 2^32) plus that, v + a + j/2 and a + j: each is at most
    /// V + A + |j| + 2^32 in magnitude. The bound is evaluated in f64 with a factor-4 margin
    /// over its rounding (2^60 against 2^62).
    fn adds_are_bounded(&self) -> bool {
        let n = f64::from(self.ticks);
        let j = (self.jerk as f64).abs();
        let a = (self.a0 as f64).abs() + n * j;
        let v = (self.v0 as f64).abs() + n * (a + j);
        v + a + j + Q32 < 1_152_921_504_606_846_976.0 // 2^60
    }
}

/// A running profile: call [`Profile::next`] once per velocity tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Profile {
    segments: [Segment; MAX_SEGMENTS],
    count: usize,
    k_vel: TickGain,
    k_acc: Gain,
    index: usize,
    tick_in_segment: u32,
    p_int: i64,
    p_frac: i64,
    v: i64,
    a: i64,
    /// The tick's adds cannot overflow for this profile ([`Profile::adds_are_bounded`]):
    /// decided once at construction, so [`Profile::next`] takes the plain adds.
    bounded: bool,
    /// The running segment's jerk, j/6 and length, copied when it starts.
    jerk: i64,
    jerk_over_6: i64,
    segment_ticks: u32,
    /// The acceleration output of the running segment when its jerk is zero (then `a`
    /// stays a0 throughout, and so does the output): computed once when it starts.
    accel_out: Pu,
}

const Q32: f64 = 4_294_967_296.0;

/// The fixed-point scale factors of the outputs: velocity per Q32.32 count/tick and
/// acceleration per Q32.32 count/tick².
fn output_gains(g: &Gains) -> Result<(TickGain, Gain), ConfigError> {
    let k_vel = crate::per_unit::checked_q::<TickGain>(g.vel_tick_pu_per_count).ok_or(
        ConfigError::overflow::<TickGain>(
            "pu per count per velocity tick",
            g.vel_tick_pu_per_count,
        ),
    )?;
    let k_acc = crate::per_unit::checked_q::<Gain>(g.vel_tick_pu_s_per_count).ok_or(
        ConfigError::overflow::<Gain>(
            "pu/s per count per velocity tick²",
            g.vel_tick_pu_s_per_count,
        ),
    )?;
    Ok((k_vel, k_acc))
}

impl Profile {
    /// Build a profile for a drive, starting at position 0 counts.
    ///
    /// ```
    /// use controller_core::{Profile, ProfileConfig};
    /// # let drive: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// let mut p = Profile::new(&ProfileConfig::fig6(), &drive).unwrap();
    /// for _ in 0..2000 { p.next(); }          // 1 s at 2 kHz
    /// let sp = p.next();
    /// assert!((sp.velocity_pu.to_num::<f32>() - 1.0).abs() < 1e-3);
    /// ```
    pub fn new(cfg: &ProfileConfig, drive: &DriveConfig) -> Result<Self, ConfigError> {
        Self::from_gains(cfg, &crate::design(drive)?)
    }

    /// Build a profile from a drive's designed gains ([`crate::design()`], whose
    /// [`Gains::cfg`] supplies the rates and the encoder), starting at position 0 counts:
    /// the same profile as [`Profile::new`] without designing the drive again.
    ///
    /// ```
    /// use controller_core::{design, Profile, ProfileConfig};
    /// # let drive: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// let g = design(&drive).unwrap();
    /// let p = Profile::from_gains(&ProfileConfig::fig6(), &g).unwrap();
    /// assert_eq!(p, Profile::new(&ProfileConfig::fig6(), &drive).unwrap());
    /// ```
    pub fn from_gains(cfg: &ProfileConfig, g: &Gains) -> Result<Self, ConfigError> {
        let s = Settings::validate(cfg)?;
        let drive = &g.cfg;
        let f = f64::from(drive.velocity_rate_hz);
        let cpps = f64::from(counts_per_pu_s(drive.encoder_cpr, drive.base_speed_rpm));
        let Planner {
            segs: segments,
            count,
            ..
        } = Planner::plan(&s, f, cpps);
        let (k_vel, k_acc) = output_gains(g)?;
        let first = segments.first().copied().unwrap_or_default();
        let bounded = segments.iter().take(count).all(Segment::adds_are_bounded);
        let mut p = Self {
            segments,
            count,
            k_vel,
            k_acc,
            index: 0,
            tick_in_segment: 0,
            p_int: 0,
            p_frac: 0,
            v: 0,
            a: 0,
            bounded,
            jerk: 0,
            jerk_over_6: 0,
            segment_ticks: 0,
            accel_out: Pu::ZERO,
        };
        p.enter(&first);
        Ok(p)
    }

    /// Start segment `s`: its exact start state, and its jerk, length and (for zero jerk)
    /// acceleration output for the ticks in it.
    fn enter(&mut self, s: &Segment) {
        self.p_int = s.p0_int;
        self.p_frac = s.p0_frac;
        self.v = s.v0;
        self.a = s.a0;
        self.jerk = s.jerk;
        self.jerk_over_6 = s.jerk_over_6;
        self.segment_ticks = s.ticks;
        self.accel_out = self.accel_pu_s();
    }

    /// The acceleration output of the present state \[pu/s\]: Q32.32 counts/tick² ≫ 12 =
    /// Q12.20, times k_acc (Q16.16) = Q.36 → Q16.16.
    #[inline(always)]
    fn accel_pu_s(&self) -> Pu {
        Pu::from_bits(mul_bits::<20>(sat_shr::<12>(self.a), self.k_acc.to_bits()))
    }

    /// Shift the whole profile by a start position \[counts\].
    ///
    /// ```
    /// use controller_core::{Counts, Profile, ProfileConfig};
    /// let start = Counts::from_num(-100.5);
    /// # let drive: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// let mut p = Profile::new(&ProfileConfig::fig6(), &drive)
    ///     .unwrap()
    ///     .with_start_position(start);
    /// assert_eq!(p.next().position_counts, start);
    /// ```
    #[must_use]
    pub fn with_start_position(mut self, start: Counts) -> Self {
        // start = whole + frac/2^16 counts; the fraction in Q0.32 is frac << 16.
        let bits = start.to_bits();
        let add = |int: &mut i64, frac: &mut i64| {
            let f = *frac + ((bits & 0xFFFF) << 16);
            *int = int.saturating_add(bits >> 16).saturating_add(f >> 32);
            *frac = f & 0xFFFF_FFFF;
        };
        for s in &mut self.segments {
            add(&mut s.p0_int, &mut s.p0_frac);
        }
        add(&mut self.p_int, &mut self.p_frac);
        self
    }

    /// Whether the profile has reached its final standstill (or endless hold).
    ///
    /// ```
    /// use controller_core::{Profile, ProfileConfig};
    /// let mut cfg = ProfileConfig::fig6();
    /// cfg.hold_time_s = 0.0;
    /// # let drive: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// let mut p = Profile::new(&cfg, &drive).unwrap();
    /// assert!(!p.is_done());
    /// for _ in 0..4000 { p.next(); } // 1 s up, 1 s down at 2 kHz
    /// assert!(p.is_done());
    /// ```
    #[must_use]
    pub fn is_done(&self) -> bool {
        self.index + 1 >= self.count
    }

    /// One tick of p += v + a/2 + j/6 ; v += a + j/2 ; a += j (Q32.32, the fraction carried
    /// into p_int), with plain adds when `BOUNDED` (the segment's range argument holds,
    /// [`Segment::adds_are_bounded`]) and saturating ones otherwise.
    /// Without `JERK` (a segment of zero jerk) the adds of j/6, j/2 and j are left out:
    /// adding zero, plain or saturating, changes nothing.
    #[inline(always)]
    fn integrate<const BOUNDED: bool, const JERK: bool>(&mut self) {
        let add = |x: i64, y: i64| {
            if BOUNDED {
                x.wrapping_add(y)
            } else {
                x.saturating_add(y)
            }
        };
        let (j, j6) = (self.jerk, self.jerk_over_6);
        let dp = add(self.v, self.a >> 1);
        let dp = if JERK { add(dp, j6) } else { dp };
        let f = add(self.p_frac, dp);
        self.p_int = self.p_int.wrapping_add(f >> 32);
        self.p_frac = f & 0xFFFF_FFFF;
        let v = add(self.v, self.a);
        self.v = if JERK { add(v, j >> 1) } else { v };
        if JERK {
            self.a = add(self.a, j);
        }
    }

    /// The setpoint for this velocity tick; advances the profile by one tick.
    /// Fixed point only, no division.
    #[allow(clippy::should_implement_trait)] // never ends, so not an `Iterator`
    pub fn next(&mut self) -> Setpoint {
        // Position Q48.16: whole counts << 16 plus the top 16 bits of the fraction
        // (wraps only beyond 2^47 counts, 2.7e5 years at 10^6 CPR and 1000 rpm).
        let sp = Setpoint {
            position_counts: Counts::from_bits(self.p_int.wrapping_shl(16) | (self.p_frac >> 16)),
            velocity_pu: Pu::from_bits(mul_bits::<24>(sat_shr::<16>(self.v), self.k_vel.to_bits())),
            acceleration_pu_s: if self.jerk == 0 {
                self.accel_out
            } else {
                self.accel_pu_s()
            },
        };
        match (self.bounded, self.jerk != 0) {
            (true, false) => self.integrate::<true, false>(),
            (true, true) => self.integrate::<true, true>(),
            (false, false) => self.integrate::<false, false>(),
            (false, true) => self.integrate::<false, true>(),
        }
        self.tick_in_segment = self.tick_in_segment.saturating_add(1);
        if self.tick_in_segment >= self.segment_ticks && self.index + 1 < self.count {
            self.index += 1;
            self.tick_in_segment = 0;
            if let Some(s) = self.segments.get(self.index).copied() {
                self.enter(&s);
            }
        }
        sp
    }
}
