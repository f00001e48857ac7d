//! Protections of the motor and the power stage: the overcurrent trip, the I²t thermal model
//! of the winding, and the stall trip. [`Protection`] holds the `faults.*` settings quantized
//! once; [`ProtectionState`] is what runs. The [`crate::Controller`] calls the overcurrent
//! check ([`Protection::current_tick`]) at the end of every current tick, and the I²t model
//! and the stall check ([`Protection::velocity_tick`]) in every velocity tick; a trip latches
//! the drive's safe state like every other [`Fault`].
//!
//! * **Overcurrent**: |measured current| > `overcurrent_ratio × torque_limit_pu` for
//!   `overcurrent_ticks` current ticks in a row. A sample at or under the level restarts
//!   the count.
//! * **I²t overload**: the heat H = ∫ (i² − i_cont²) dt, held at 0 from below (the winding
//!   cools down to ambient, not under it), trips when it reaches
//!   H_trip = (i_ol² − i_cont²)·t_ol, the overload class "i_ol for t_ol from cold". At a
//!   constant current i > i_cont the trip comes after t = t_ol·(i_ol² − i_cont²)/(i² − i_cont²)
//!   ([`Protection::trip_time_s`]). It warns from `thermal_warning_fraction · H_trip` on.
//!   The model runs at the velocity rate, on the latest current sample (a winding's thermal
//!   time constant is seconds; the overcurrent trip is the fast one).
//!   The integral is exact integer arithmetic: each tick adds (i² − i_cont²) in Q32.32 pu²
//!   (the Q16.16 current squared, exactly), so hours of running accumulate no drift at all. [`crate::Controller::reset`] keeps H: clearing
//!   a fault does not cool the winding.
//! * **Stall**: |torque reference| at or above `stall_torque_fraction × torque_limit_pu`
//!   with |velocity estimate| under `stall_speed_pu` for `stall_time_s` (velocity ticks in
//!   a row); `stall_time_s = 0` turns it off.

use crate::config::DriveConfig;
use crate::error::ConfigError;
use crate::fault::Fault;
use crate::per_unit::Pu;

/// The protections' settings, quantized (built once by [`Protection::new`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Protection {
    /// Overcurrent level: raw Q16.16 magnitude.
    overcurrent_abs: u32,
    /// Consecutive current ticks over the level that trip (≥ 1).
    overcurrent_ticks: u32,
    /// i_cont² in Q32.32 (the square of its Q16.16 bits).
    continuous_sq: i64,
    /// H_trip in Q32.32 pu²·velocity ticks (at most 2^61).
    heat_trip: i64,
    /// The warning level of H, same units.
    heat_warn: i64,
    /// Stall speed: raw Q16.16 magnitude.
    stall_speed_abs: u32,
    /// Velocity ticks in a row that trip a stall (`u32::MAX`: off).
    stall_ticks: u32,
    /// The stall torque `stall_torque_fraction × torque_limit_pu`: raw magnitude.
    stall_torque_abs: u32,
    /// Ticks of the I²t model (velocity ticks) per second, for the times reported.
    thermal_rate_hz: u32,
}

/// The protections' running state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProtectionState {
    /// Current ticks in a row over the overcurrent level.
    over_count: u32,
    /// The I²t heat H in Q32.32 pu²·velocity ticks, within [0, H_trip].
    heat: i64,
    /// Velocity ticks in a row stalled.
    stall_count: u32,
}

impl ProtectionState {
    /// The state after a fault reset: the counters cleared, the heat kept.
    #[must_use]
    pub const fn after_reset(&self) -> Self {
        Self {
            over_count: 0,
            heat: self.heat,
            stall_count: 0,
        }
    }

    /// The heat H in Q32.32 pu²·velocity ticks.
    #[must_use]
    pub const fn heat(&self) -> i64 {
        self.heat
    }
}

impl Protection {
    /// Quantize the `faults.*` protection settings of validated settings `cfg`; an error
    /// names the setting whose value has no representation.
    pub fn new(cfg: &DriveConfig) -> Result<Self, ConfigError> {
        let f = &cfg.faults;
        use crate::ranges as r;
        use crate::validate::{Scales, fit, fit_setting};
        let of_torque_limit = |range, setting| Scales {
            cap: f32::INFINITY,
            range,
            setting,
            power: 1.0,
            given: "torque_limit_pu: the level (× torque_limit_pu) must fit Q16.16 within 1 %",
        };
        let q16 = "its format Q16.16 (within 1 %)";
        let oc: Pu = fit(
            f.overcurrent_ratio * cfg.torque_limit_pu,
            of_torque_limit(&r::OVERCURRENT_RATIO, f.overcurrent_ratio),
            |x| x * cfg.torque_limit_pu,
        )?;
        let ic: Pu = fit_setting(&r::CONTINUOUS_CURRENT_PU, f.continuous_current_pu, q16)?;
        let iol: Pu = fit_setting(&r::OVERLOAD_CURRENT_PU, f.overload_current_pu, q16)?;
        let stall_torque: Pu = fit(
            f.stall_torque_fraction * cfg.torque_limit_pu,
            of_torque_limit(&r::STALL_TORQUE_FRACTION, f.stall_torque_fraction),
            |x| x * cfg.torque_limit_pu,
        )?;
        let stall: Pu = fit_setting(
            &r::STALL_SPEED_PU,
            f.stall_speed_pu,
            "its format Q16.16 (0, or within 1 %)",
        )?;
        let sq = |p: Pu| i64::from(p.to_bits()) * i64::from(p.to_bits());
        let continuous_sq = sq(ic);
        // (i_ol² − i_cont²) in Q32.32 × t_ol × ticks per second. At most 2^61, so that a
        // tick's i² (≤ 2^62) added to it cannot wrap; a longer class is refused with the
        // longest overload time that fits.
        let class = (sq(iol) - continuous_sq) as f64;
        let rate = f64::from(cfg.velocity_rate_hz);
        let ticks = f64::from(f.overload_time_s) * rate;
        let heat_trip = class * ticks;
        let max_trip = (1u64 << 61) as f64;
        if heat_trip > max_trip || class < 1.0 {
            let r = &crate::ranges::OVERLOAD_TIME_S;
            return Err(ConfigError::OutOfRange {
                param: r.key,
                value: f.overload_time_s,
                min: r.min,
                max: (max_trip / (class.max(1.0) * rate)) as f32,
                min_exclusive: r.min_exclusive,
            });
        }
        let heat_trip = heat_trip as i64;
        let heat_warn = (heat_trip as f64 * f64::from(f.thermal_warning_fraction)) as i64;
        // Rounded to the nearest tick (no_std: no `round`; the time is ≥ 0).
        let stall_ticks = f.stall_time_s * cfg.velocity_rate_hz as f32 + 0.5;
        Ok(Self {
            overcurrent_abs: oc.to_bits().unsigned_abs(),
            overcurrent_ticks: f.overcurrent_ticks.max(1),
            continuous_sq,
            heat_trip,
            heat_warn,
            stall_speed_abs: stall.to_bits().unsigned_abs(),
            stall_ticks: if f.stall_time_s > 0.0 {
                (stall_ticks as u32).max(1)
            } else {
                u32::MAX
            },
            stall_torque_abs: stall_torque.to_bits().unsigned_abs(),
            thermal_rate_hz: cfg.velocity_rate_hz,
        })
    }

    /// One current tick on the measured current: the overcurrent count. Returns whether the
    /// overcurrent trips now.
    #[inline(always)]
    pub fn current_tick(&self, s: &mut ProtectionState, current: Pu) -> bool {
        s.over_count = if current.to_bits().unsigned_abs() > self.overcurrent_abs {
            s.over_count.saturating_add(1)
        } else {
            0
        };
        s.over_count >= self.overcurrent_ticks
    }

    /// [`Self::current_tick`] on a current vector's squared magnitude `sq` (raw Q32.32, a
    /// PMSM's `i_d² + i_q²`), without its root: `⌊√sq⌋ > L` exactly when `sq ≥ (L + 1)²`,
    /// so the count is the one `current_tick` keeps on `⌊√sq⌋`.
    #[inline(always)]
    pub fn current_tick_sq(&self, s: &mut ProtectionState, sq: u64) -> bool {
        // L ≤ 2^31, so (L + 1)² < 2^63.
        let above = u64::from(self.overcurrent_abs) + 1;
        s.over_count = if sq >= above * above {
            s.over_count.saturating_add(1)
        } else {
            0
        };
        s.over_count >= self.overcurrent_ticks
    }

    /// One velocity tick: the I²t model on `current` (the latest current sample), then the
    /// stall check on `torque` (this tick's torque reference) and `speed` (the velocity
    /// estimate). Returns the fault that trips now, overload first.
    #[inline(always)]
    pub fn velocity_tick(
        &self,
        s: &mut ProtectionState,
        current: Pu,
        torque: Pu,
        speed: Pu,
    ) -> Option<Fault> {
        let bits = i64::from(current.to_bits());
        self.velocity_tick_sq(s, bits * bits, torque, speed)
    }

    /// [`Self::velocity_tick`] with the I²t model fed the current's square `sq` (raw
    /// Q32.32, in `[0, 2^62]`; a PMSM's `i_d² + i_q²`).
    #[inline(always)]
    pub fn velocity_tick_sq(
        &self,
        s: &mut ProtectionState,
        sq: i64,
        torque: Pu,
        speed: Pu,
    ) -> Option<Fault> {
        // i² ≤ 2^62; H ≤ H_trip ≤ 2^61 (`new`): the sum does not wrap.
        let heat = (s.heat + (sq - self.continuous_sq)).max(0);
        let overload = heat >= self.heat_trip;
        s.heat = if overload { self.heat_trip } else { heat };
        let stalled = torque.to_bits().unsigned_abs() >= self.stall_torque_abs
            && speed.to_bits().unsigned_abs() < self.stall_speed_abs;
        s.stall_count = if stalled {
            s.stall_count.saturating_add(1)
        } else {
            0
        };
        if overload {
            Some(Fault::Overload)
        } else if s.stall_count >= self.stall_ticks {
            Some(Fault::Stall)
        } else {
            None
        }
    }

    /// Whether the heat has reached the warning level.
    #[must_use]
    pub const fn warning(&self, s: &ProtectionState) -> bool {
        s.heat >= self.heat_warn
    }

    /// The heat as a fraction of its trip level (1 = tripped).
    #[must_use]
    pub fn load_fraction(&self, s: &ProtectionState) -> f32 {
        (s.heat as f64 / self.heat_trip as f64) as f32
    }

    /// The I²t model's trip time \[s\] from cold at a constant current `current_pu` (the
    /// same quantization as the tick: the Q16.16 current); `None` at or under the
    /// continuous current.
    #[must_use]
    pub fn trip_time_s(&self, current_pu: f32) -> Option<f64> {
        let bits = i64::from(Pu::saturating_from_num(current_pu).to_bits());
        let per_tick = bits * bits - self.continuous_sq;
        if per_tick <= 0 {
            return None;
        }
        let ticks = (self.heat_trip + per_tick - 1) / per_tick;
        Some(ticks as f64 / f64::from(self.thermal_rate_hz))
    }

    /// The overcurrent level \[pu\].
    #[must_use]
    pub fn overcurrent_pu(&self) -> f32 {
        (f64::from(self.overcurrent_abs) / 65536.0) as f32
    }

    /// Consecutive current ticks over the level that trip.
    #[must_use]
    pub const fn overcurrent_ticks(&self) -> u32 {
        self.overcurrent_ticks
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::config::DriveConfig;

    fn cfg() -> DriveConfig {
        toml::from_str(include_str!("../doc/example-drive.toml")).unwrap()
    }

    fn pu(x: f32) -> Pu {
        Pu::from_num(x)
    }

    /// One velocity tick of the I²t model alone (no torque, so no stall).
    fn heat(p: &Protection, s: &mut ProtectionState, current: Pu) -> Option<Fault> {
        p.velocity_tick(s, current, Pu::ZERO, Pu::ZERO)
    }

    /// Velocity ticks from cold until `current` trips the I²t model (None within `max`).
    fn ticks_to_trip(p: &Protection, current: f32, max: u64) -> Option<u64> {
        let mut s = ProtectionState::default();
        (1..=max).find(|_| heat(p, &mut s, pu(current)) == Some(Fault::Overload))
    }

    /// A stall tick alone: the I²t model at its continuous current (neither heats nor cools).
    fn stall(p: &Protection, s: &mut ProtectionState, torque: Pu, speed: Pu) -> Option<Fault> {
        p.velocity_tick(s, pu(1.0), torque, speed)
    }

    /// The squared entry judges as the plain one on the square's root: at, around and
    /// between the squares of the level and the level plus one LSB, and on scattered
    /// squares, for several levels.
    #[test]
    fn the_squared_overcurrent_entry_judges_as_the_root() {
        for level in [0.01f32, 1.0, 2.5, 3.0, 1000.0] {
            let mut c = cfg();
            c.torque_limit_pu = level;
            c.faults.overcurrent_ratio = 1.0;
            c.faults.overcurrent_ticks = 1;
            let p = Protection::new(&c).unwrap();
            let l = u64::from(p.overcurrent_abs);
            let mut xs: Vec<u64> = [l * l, (l + 1) * (l + 1), (l + 2) * (l + 2)]
                .iter()
                .flat_map(|&x| [x - 1, x, x + 1])
                .collect();
            xs.extend((0..10_000u64).map(|k| k.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 2));
            for sq in xs {
                let root = i32::try_from(sq.isqrt()).unwrap_or(i32::MAX);
                let (mut a, mut b) = (ProtectionState::default(), ProtectionState::default());
                assert_eq!(
                    p.current_tick_sq(&mut a, sq),
                    p.current_tick(&mut b, Pu::from_bits(root)),
                    "level {level}, sq {sq}"
                );
            }
        }
    }

    #[test]
    fn overcurrent_trips_on_the_nth_sample_in_a_row_over_the_level_and_not_at_it() {
        let mut c = cfg();
        c.torque_limit_pu = 2.0;
        c.faults.overcurrent_ratio = 1.5;
        c.faults.overcurrent_ticks = 3;
        let p = Protection::new(&c).unwrap();
        assert_eq!((p.overcurrent_pu(), p.overcurrent_ticks()), (3.0, 3));
        let over = Pu::from_bits(pu(3.0).to_bits() + 1);
        let mut s = ProtectionState::default();
        // At the level: never counts.
        for _ in 0..10 {
            assert!(!p.current_tick(&mut s, pu(3.0)));
            assert!(!p.current_tick(&mut s, pu(-3.0)));
        }
        // Two over, one under: the count restarts.
        assert!(!p.current_tick(&mut s, over));
        assert!(!p.current_tick(&mut s, -over));
        assert!(!p.current_tick(&mut s, pu(2.9)));
        assert!(!p.current_tick(&mut s, over));
        assert!(!p.current_tick(&mut s, over));
        assert!(p.current_tick(&mut s, -over));
    }

    #[test]
    fn overcurrent_with_one_tick_trips_at_once() {
        let mut c = cfg();
        c.faults.overcurrent_ticks = 1;
        let p = Protection::new(&c).unwrap();
        let mut s = ProtectionState::default();
        let over = Pu::from_bits(Pu::from_num(p.overcurrent_pu()).to_bits() + 1);
        assert!(p.current_tick(&mut s, over));
    }

    #[test]
    fn i2t_trips_at_the_closed_form_time_of_the_overload_class() {
        let c = cfg();
        let p = Protection::new(&c).unwrap();
        let rate = f64::from(c.velocity_rate_hz);
        let (ic, iol, tol) = (1.0f64, 1.5f64, 60.0f64);
        for i in [1.5f32, 2.0, 3.0, 1.1] {
            let i64_ = f64::from(i);
            let closed = tol * (iol * iol - ic * ic) / (i64_ * i64_ - ic * ic);
            let max = (closed * rate * 1.01) as u64;
            let ticks = ticks_to_trip(&p, i, max).expect("trips");
            let t = ticks as f64 / rate;
            assert!(
                (t - closed).abs() <= 1e-4 * closed + 1.0 / rate,
                "{i} pu: {t} s against {closed} s"
            );
            assert_eq!(p.trip_time_s(i), Some(t), "{i} pu");
        }
    }

    #[test]
    fn a_class_too_long_for_the_integer_range_is_refused_with_its_limit() {
        let mut c = cfg();
        c.faults.continuous_current_pu = 0.01;
        c.faults.overload_current_pu = 100.0;
        c.faults.overload_time_s = 3600.0;
        let e = Protection::new(&c).unwrap_err();
        assert_eq!(e.param(), "faults.overload_time_s");
    }

    #[test]
    fn i2t_at_or_below_the_continuous_current_never_trips_and_cools_to_zero() {
        let c = cfg();
        let rate = c.velocity_rate_hz;
        let p = Protection::new(&c).unwrap();
        assert_eq!(p.trip_time_s(1.0), None);
        assert_eq!(p.trip_time_s(0.5), None);
        let mut s = ProtectionState::default();
        // Heat up to half the trip level at 2 pu, then run at 1 pu for an hour.
        let half = (p.trip_time_s(2.0).unwrap() * f64::from(rate) / 2.0) as u32;
        for _ in 0..half {
            assert_eq!(heat(&p, &mut s, pu(2.0)), None);
        }
        let hot = s.heat();
        assert!(hot > 0 && p.load_fraction(&s) > 0.49 && p.load_fraction(&s) < 0.51);
        for _ in 0..rate * 3600 {
            assert_eq!(heat(&p, &mut s, pu(1.0)), None);
        }
        assert_eq!(s.heat(), hot, "i = i_cont exactly neither heats nor cools");
        for _ in 0..rate * 600 {
            assert_eq!(heat(&p, &mut s, pu(0.0)), None);
        }
        assert_eq!(s.heat(), 0, "cools to ambient and is held there");
    }

    #[test]
    fn i2t_warns_at_its_fraction_before_it_trips() {
        let mut c = cfg();
        c.faults.thermal_warning_fraction = 0.5;
        let p = Protection::new(&c).unwrap();
        let trip = (p.trip_time_s(3.0).unwrap() * f64::from(c.velocity_rate_hz)).round() as u64;
        let mut s = ProtectionState::default();
        let mut warned_at = None;
        for k in 1..trip {
            assert_eq!(heat(&p, &mut s, pu(3.0)), None);
            if warned_at.is_none() && p.warning(&s) {
                warned_at = Some(k);
            }
        }
        let w = warned_at.expect("warns") as f64 / trip as f64;
        assert!((w - 0.5).abs() < 1e-3, "warned at {w} of the trip time");
        assert_eq!(heat(&p, &mut s, pu(3.0)), Some(Fault::Overload));
    }

    #[test]
    fn the_heat_survives_a_fault_reset_and_the_counters_do_not() {
        let p = Protection::new(&cfg()).unwrap();
        let mut s = ProtectionState::default();
        let over = Pu::from_bits(Pu::from_num(p.overcurrent_pu()).to_bits() + 1);
        p.current_tick(&mut s, over);
        heat(&p, &mut s, over);
        assert!(s.heat() > 0 && s.over_count == 1);
        let r = s.after_reset();
        assert_eq!((r.heat(), r.over_count, r.stall_count), (s.heat(), 0, 0));
    }

    #[test]
    fn stall_trips_after_its_time_at_the_stall_torque_under_the_speed() {
        let mut c = cfg();
        c.torque_limit_pu = 2.0;
        c.faults.stall_torque_fraction = 1.0;
        c.faults.stall_speed_pu = 0.02;
        c.faults.stall_time_s = 0.01;
        let p = Protection::new(&c).unwrap();
        let n = (0.01 * c.velocity_rate_hz as f32).round() as u32;
        let mut s = ProtectionState::default();
        let slow = Pu::from_bits(pu(0.02).to_bits() - 1);
        // At the speed threshold, or under the torque limit: no count.
        for _ in 0..3 * n {
            assert_eq!(stall(&p, &mut s, pu(2.0), pu(0.02)), None);
        }
        for _ in 0..3 * n {
            assert_eq!(stall(&p, &mut s, pu(1.99), slow), None);
        }
        for _ in 1..n {
            assert_eq!(stall(&p, &mut s, pu(-2.0), -slow), None);
        }
        assert_eq!(stall(&p, &mut s, pu(2.0), slow), Some(Fault::Stall));
    }

    #[test]
    fn the_stall_torque_is_its_fraction_of_the_limit() {
        let mut c = cfg();
        c.torque_limit_pu = 2.0;
        c.faults.stall_torque_fraction = 0.7;
        c.faults.stall_time_s = 1.0 / c.velocity_rate_hz as f32;
        let p = Protection::new(&c).unwrap();
        let mut s = ProtectionState::default();
        let under = Pu::from_bits(pu(1.4).to_bits() - 1);
        assert_eq!(stall(&p, &mut s, under, pu(0.0)), None);
        assert_eq!(stall(&p, &mut s, -pu(1.4), pu(0.0)), Some(Fault::Stall));
    }

    #[test]
    fn stall_time_zero_turns_the_stall_trip_off() {
        let mut c = cfg();
        c.faults.stall_time_s = 0.0;
        let p = Protection::new(&c).unwrap();
        let mut s = ProtectionState::default();
        for _ in 0..100_000 {
            assert_eq!(stall(&p, &mut s, pu(c.torque_limit_pu), pu(0.0)), None);
        }
    }

    #[test]
    fn an_overload_is_reported_before_a_stall_of_the_same_tick() {
        let mut c = cfg();
        c.faults.stall_time_s = 1.0 / c.velocity_rate_hz as f32;
        c.faults.overload_time_s = 1.0 / c.velocity_rate_hz as f32;
        let p = Protection::new(&c).unwrap();
        let mut s = ProtectionState::default();
        let lim = pu(c.torque_limit_pu);
        assert_eq!(
            p.velocity_tick(&mut s, pu(3.0), lim, pu(0.0)),
            Some(Fault::Overload)
        );
    }
}
