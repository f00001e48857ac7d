//! Gain design from drive settings (f32, once, at configuration), with validation.
//!
//! * Velocity PI: Kp = ω_v·J_loop, Ki = Kp·ω_v/(4ζ²), with J_loop chosen by
//!   [`DriveConfig::velocity_pi_inertia`]: [`PiInertia::Total`] J_loop = J_total (the
//!   regulator is tuned for the machine; AFB adds inertia electrically on top, and the
//!   velocity gains do not depend on Ka), [`PiInertia::TotalPlusAfb`]
//!   J_loop = J_total + Ka (below the filter corner the loop sees J_total + Ka, so the
//!   velocity bandwidth is kept with the gears engaged, at the price of most of the
//!   disturbance benefit).
//! * Acceleration feed-forward: k_aff = aff·J_ff with J_ff the inertia the commanded
//!   acceleration actually meets: J_total in the error form (the AFB itself supplies
//!   Ka·a_sp) and with AFB off, J_total + Ka in the plain form. It does not depend on
//!   `velocity_pi_inertia`.
//! * Position P: Kpp = ω_pos \[rad/s\] → k_pos = Kpp/counts_per_pu_s \[pu per count\].
//! * Current PI: Kp = L·ω_c, Ki = R·ω_c.
//! * Filters and observer from their corners (see [`crate::filter`], [`crate::observer`]).

use crate::config::{AfbMode, AfbRate, DriveConfig, ObserverInertia, PiInertia};
use crate::error::ConfigError;
use crate::filter::{design_low_pass, LowPassDesign};
use crate::per_unit::counts_per_pu_s;

/// Designed gains and coefficients (f32, before quantization). Units in the names.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gains {
    /// Total inertia J_total = Jm + Jl \[s\].
    pub j_total_s: f32,
    /// Inertia the velocity PI is designed for \[s\]: J_total, or J_total + Ka
    /// (`DriveConfig::velocity_pi_inertia`).
    pub j_loop_s: f32,
    /// Position gain Kpp \[rad/s = pu speed per pu·s of position error\]; 0 = velocity mode.
    pub kpp: f32,
    /// Position gain in pu speed per count of position error.
    pub k_pos_pu_per_count: f32,
    /// Velocity Kp \[pu torque per pu speed\].
    pub kp_vel: f32,
    /// Velocity Ki \[pu torque per pu speed per s\].
    pub ki_vel: f32,
    /// Current Kp \[pu voltage per pu current\].
    pub kp_cur: f32,
    /// Current Ki \[pu voltage per pu current per s\].
    pub ki_cur: f32,
    /// Acceleration-feedback gain Ka \[s = pu torque per pu/s\]; 0 when off.
    pub ka: f32,
    /// Acceleration feed-forward \[pu torque per pu/s of commanded acceleration\].
    pub k_accel_ff: f32,
    /// The feed-forward fraction `accel_ff_gain` k_accel_ff was made from (kept so that
    /// [`Gains::without_afb`] can give the AFB-off feed-forward).
    pub accel_ff_gain: f32,
    /// Velocity per count of position change per velocity tick \[pu\].
    pub vel_tick_pu_per_count: f32,
    /// Acceleration per count of second difference per velocity tick \[pu/s\].
    pub vel_tick_pu_s_per_count: f32,
    /// Velocity per count of position change per current tick \[pu\].
    pub cur_tick_pu_per_count: f32,
    /// Acceleration per count of second difference per current tick \[pu/s\].
    pub cur_tick_pu_s_per_count: f32,
    /// Velocity feedback filter (at the velocity rate).
    pub velocity_filter: LowPassDesign,
    /// Acceleration-feedback filter (at the AFB rate).
    pub afb_filter: LowPassDesign,
    /// AFB tick rate \[Hz\].
    pub afb_rate_hz: f32,
    /// Observer model inertia \[s\].
    pub observer_inertia_s: f32,
    /// Observer pole θ = e^(−2π·f_o·Ts).
    pub observer_pole: f32,
    /// Observer correction gains \[l1, l2, l3\].
    pub observer_l: [f32; 3],
    /// Observer torque-to-acceleration factor \[counts/tick² per pu\].
    pub observer_k_u: f32,
    /// Largest plausible change of counts between current ticks (encoder-jump trip).
    pub max_count_step: f32,
    /// Current ticks per velocity tick.
    pub ticks_per_velocity: u32,
}

impl Gains {
    /// These gains with the acceleration feedback taken out, for "the same gains without
    /// AFB": `ka = 0` and the acceleration feed-forward as `design()` gives it with AFB off
    /// (`accel_ff_gain·J_total`, the inertia the commanded acceleration then meets); every
    /// other field (the velocity and current PI, position gain, filters, observer, scales,
    /// limits) is bit-identical. In the error form and with AFB off the feed-forward is
    /// unchanged too, so the result differs from `self` only in `ka`. Build the comparison
    /// drive with [`crate::Controller::with_gains`] and the config with
    /// `accel_feedback.mode = AfbMode::Off`.
    ///
    /// ```
    /// use controller_core::{design, AfbMode, Controller, DriveConfig};
    /// let cfg = DriveConfig::table1();
    /// let g = design(&cfg).unwrap();
    /// let off_gains = g.without_afb();
    /// assert_eq!((off_gains.ka, off_gains.kp_vel.to_bits()), (0.0, g.kp_vel.to_bits()));
    /// let mut off = cfg;
    /// off.accel_feedback.mode = AfbMode::Off;
    /// assert!(Controller::with_gains(&off, &off_gains).is_ok());
    /// ```
    #[must_use]
    pub fn without_afb(&self) -> Self {
        Self {
            ka: 0.0,
            k_accel_ff: self.accel_ff_gain * self.j_total_s,
            ..*self
        }
    }
}

fn finite(v: f32, param: &'static str) -> Result<f32, ConfigError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ConfigError::NotFinite { param })
    }
}

fn range(
    v: f32,
    param: &'static str,
    min: f32,
    max: f32,
    min_exclusive: bool,
) -> Result<f32, ConfigError> {
    let v = finite(v, param)?;
    let low_ok = if min_exclusive { v > min } else { v >= min };
    if low_ok && v <= max {
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

fn below_nyquist(v: f32, param: &'static str, nyquist: f32) -> Result<f32, ConfigError> {
    if v < nyquist {
        Ok(v)
    } else {
        Err(ConfigError::AboveNyquist {
            param,
            value: v,
            nyquist,
        })
    }
}

fn int_range(v: u32, param: &'static str, min: u32, max: u32) -> Result<u32, ConfigError> {
    if (min..=max).contains(&v) {
        Ok(v)
    } else {
        Err(ConfigError::OutOfRange {
            param,
            value: v as f32,
            min: min as f32,
            max: max as f32,
            min_exclusive: false,
        })
    }
}

/// Design all gains from the drive settings, validating every setting.
///
/// ```
/// let g = controller_core::design(&controller_core::DriveConfig::table1()).unwrap();
/// assert!(g.kp_vel > 0.0 && g.ki_vel > 0.0);
/// let mut bad = controller_core::DriveConfig::table1();
/// bad.motor_inertia_s = 0.0;
/// assert_eq!(controller_core::design(&bad).unwrap_err().param(), "motor_inertia_s");
/// ```
pub fn design(cfg: &DriveConfig) -> Result<Gains, ConfigError> {
    let rpm = range(cfg.base_speed_rpm, "base_speed_rpm", 0.0, 100_000.0, true)?;
    int_range(cfg.encoder_cpr, "encoder_cpr", 4, 1 << 30)?;
    int_range(u32::from(cfg.counter_bits), "counter_bits", 16, 32)?;
    let f_cur = int_range(cfg.current_rate_hz, "current_rate_hz", 100, 100_000)?;
    let f_vel = int_range(cfg.velocity_rate_hz, "velocity_rate_hz", 10, f_cur)?;
    if f_cur % f_vel != 0 || f_cur / f_vel > 16 {
        return Err(ConfigError::RateRatio {
            current_rate_hz: f_cur,
            velocity_rate_hz: f_vel,
        });
    }
    let (f_cur, f_vel) = (f_cur as f32, f_vel as f32);
    let (ts_cur, ts_vel) = (1.0 / f_cur, 1.0 / f_vel);
    let pi = core::f32::consts::PI;

    let jm = range(cfg.motor_inertia_s, "motor_inertia_s", 0.0, 1000.0, true)?;
    let jl = range(cfg.load_inertia_s, "load_inertia_s", 0.0, 1000.0, false)?;
    let j_total = jm + jl;

    let w_pos = range(
        cfg.position_bandwidth_rad_s,
        "position_bandwidth_rad_s",
        0.0,
        f32::MAX,
        false,
    )?;
    below_nyquist(w_pos, "position_bandwidth_rad_s", pi * f_vel)?;
    let w_vel = range(
        cfg.velocity_bandwidth_rad_s,
        "velocity_bandwidth_rad_s",
        0.0,
        f32::MAX,
        true,
    )?;
    below_nyquist(w_vel, "velocity_bandwidth_rad_s", pi * f_vel)?;
    let zeta = range(cfg.velocity_damping, "velocity_damping", 0.1, 10.0, false)?;
    let w_cur = range(
        cfg.current_bandwidth_rad_s,
        "current_bandwidth_rad_s",
        0.0,
        f32::MAX,
        true,
    )?;
    below_nyquist(w_cur, "current_bandwidth_rad_s", pi * f_cur)?;
    let r = range(
        cfg.winding_resistance_pu,
        "winding_resistance_pu",
        0.0,
        100.0,
        true,
    )?;
    let l = range(
        cfg.winding_inductance_pu_s,
        "winding_inductance_pu_s",
        0.0,
        100.0,
        true,
    )?;
    range(cfg.torque_limit_pu, "torque_limit_pu", 0.0, 1000.0, true)?;
    range(cfg.voltage_limit_pu, "voltage_limit_pu", 0.0, 1000.0, true)?;
    range(cfg.velocity_ff_gain, "velocity_ff_gain", 0.0, 1.0, false)?;
    let aff = range(cfg.accel_ff_gain, "accel_ff_gain", 0.0, 1.0, false)?;

    let afb = &cfg.accel_feedback;
    let frac = range(
        afb.gain_fraction,
        "accel_feedback.gain_fraction",
        0.0,
        20.0,
        false,
    )?;
    let ka = if afb.mode == AfbMode::Off {
        0.0
    } else {
        frac * j_total
    };
    let afb_rate_hz = match afb.rate {
        AfbRate::Current => f_cur,
        AfbRate::Velocity => f_vel,
    };
    let afb_filter = design_low_pass(
        &afb.filter,
        afb_rate_hz,
        "accel_feedback.filter.corner_hz",
        "accel_feedback.filter.q",
    )?;
    let velocity_filter = design_low_pass(
        &cfg.velocity_filter,
        f_vel,
        "velocity_filter.corner_hz",
        "velocity_filter.q",
    )?;

    let obs = &cfg.observer;
    let f_obs = range(
        obs.bandwidth_hz,
        "observer.bandwidth_hz",
        0.0,
        f32::MAX,
        true,
    )?;
    below_nyquist(f_obs, "observer.bandwidth_hz", f_cur / 2.0)?;
    let j_obs = match obs.model_inertia {
        ObserverInertia::Total => j_total,
        ObserverInertia::Motor => jm,
    };
    let theta =
        crate::cfgmath::exp(-2.0 * core::f64::consts::PI * f64::from(f_obs) / f64::from(f_cur))
            as f32;
    let one_m = 1.0 - theta;
    let observer_l = [
        1.0 - theta * theta * theta,
        1.5 * one_m * one_m * (1.0 + theta),
        one_m * one_m * one_m,
    ];

    let faults = &cfg.faults;
    let overspeed = range(faults.overspeed_pu, "faults.overspeed_pu", 0.0, 100.0, true)?;
    range(
        faults.following_error_counts,
        "faults.following_error_counts",
        0.0,
        8_000_000.0,
        true,
    )?;
    let margin = range(
        faults.encoder_jump_margin,
        "faults.encoder_jump_margin",
        1.0,
        1000.0,
        false,
    )?;

    let cpps = counts_per_pu_s(cfg.encoder_cpr, rpm);
    // The counter must not wrap by half its range between two current ticks at the jump
    // limit, or a legal motion would read as a jump backwards.
    let max_count_step = margin * overspeed * cpps * ts_cur + 2.0;
    let mut bits_needed = 16u32;
    while bits_needed < 32 && max_count_step >= (1u64 << (bits_needed - 1)) as f32 {
        bits_needed += 1;
    }
    if u32::from(cfg.counter_bits) < bits_needed || max_count_step >= (1u64 << 31) as f32 {
        return Err(ConfigError::OutOfRange {
            param: "counter_bits",
            value: f32::from(cfg.counter_bits),
            min: bits_needed as f32,
            max: 32.0,
            min_exclusive: false,
        });
    }
    let j_loop = match cfg.velocity_pi_inertia {
        PiInertia::Total => j_total,
        PiInertia::TotalPlusAfb => j_total + ka,
    };
    let kp_vel = w_vel * j_loop;
    let ki_vel = kp_vel * w_vel / (4.0 * zeta * zeta);
    let k_accel_ff = aff
        * match afb.mode {
            AfbMode::Plain => j_total + ka,
            AfbMode::Off | AfbMode::Error => j_total,
        };

    Ok(Gains {
        j_total_s: j_total,
        j_loop_s: j_loop,
        kpp: w_pos,
        k_pos_pu_per_count: w_pos / cpps,
        kp_vel,
        ki_vel,
        kp_cur: l * w_cur,
        ki_cur: r * w_cur,
        ka,
        k_accel_ff,
        accel_ff_gain: aff,
        vel_tick_pu_per_count: 1.0 / (cpps * ts_vel),
        vel_tick_pu_s_per_count: 1.0 / (cpps * ts_vel * ts_vel),
        cur_tick_pu_per_count: 1.0 / (cpps * ts_cur),
        cur_tick_pu_s_per_count: 1.0 / (cpps * ts_cur * ts_cur),
        velocity_filter,
        afb_filter,
        afb_rate_hz,
        observer_inertia_s: j_obs,
        observer_pole: theta,
        observer_l,
        observer_k_u: ts_cur * ts_cur * cpps / j_obs,
        max_count_step,
        ticks_per_velocity: (f_cur / f_vel) as u32,
    })
}
