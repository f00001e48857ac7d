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
//! * The torque-reference notch from its centre, width and depth at the current rate
//!   ([`crate::notch`]), if the settings have one.

use crate::config::{AfbMode, AfbRate, DriveConfig, ObserverInertia, PiInertia};
use crate::error::ConfigError;
use crate::filter::{LowPassDesign, design_low_pass};
use crate::notch::{NotchDesign, NotchParams};
use crate::per_unit::counts_per_pu_s;
use crate::ranges;
use crate::validate::max_count_step;

/// Designed gains and coefficients (f32, before quantization), with the validated settings
/// they were designed from ([`Gains::cfg`]), so that [`crate::Controller::from_gains`]
/// builds a controller without designing again. Units in the names.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gains {
    /// The settings these gains come from (validated by [`design()`]); they also supply the
    /// controller's limits, modes and rates.
    pub cfg: DriveConfig,
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
    /// The torque-reference notch, designed at the current rate (f64); `None` without one.
    pub notch: Option<NotchDesign>,
}

/// The keys a notch's design errors name.
const NOTCH_PARAMS: NotchParams = NotchParams {
    centre_hz: ranges::NOTCH_CENTRE_HZ.key,
    width_hz: ranges::NOTCH_WIDTH_HZ.key,
    depth_db: ranges::NOTCH_DEPTH_DB.key,
};

impl Gains {
    /// These gains with the acceleration feedback taken out, for "the same gains without
    /// AFB": `ka = 0`, the acceleration feed-forward as `design()` gives it with AFB off
    /// (`accel_ff_gain·J_total`, the inertia the commanded acceleration then meets) and the
    /// carried config's `accel_feedback.mode = Off`; every other field (the velocity and
    /// current PI, position gain, filters, observer, scales, limits) is bit-identical. In the
    /// error form and with AFB off the feed-forward is unchanged too. Build the comparison
    /// drive with [`crate::Controller::from_gains`].
    ///
    /// ```
    /// use controller_core::{design, AfbMode, Controller};
    /// # let cfg: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
    /// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
    /// let g = design(&cfg).unwrap();
    /// let off = g.without_afb();
    /// assert_eq!((off.ka, off.kp_vel.to_bits()), (0.0, g.kp_vel.to_bits()));
    /// assert_eq!(off.cfg.accel_feedback.mode, AfbMode::Off);
    /// assert!(Controller::from_gains(&off).is_ok());
    /// ```
    #[must_use]
    pub fn without_afb(&self) -> Self {
        let mut cfg = self.cfg;
        cfg.accel_feedback.mode = AfbMode::Off;
        Self {
            cfg,
            ka: 0.0,
            k_accel_ff: self.cfg.accel_ff_gain * self.j_total_s,
            ..*self
        }
    }
}

/// The observer pole θ = e^(−2π·f_o/f_cur) and its correction gains \[l1, l2, l3\] (three
/// poles at θ).
pub(crate) fn observer_poles(f_obs: f32, f_cur: f32) -> (f32, [f32; 3]) {
    let theta =
        crate::cfgmath::exp(-2.0 * core::f64::consts::PI * f64::from(f_obs) / f64::from(f_cur))
            as f32;
    let one_m = 1.0 - theta;
    let l = [
        1.0 - theta * theta * theta,
        1.5 * one_m * one_m * (1.0 + theta),
        one_m * one_m * one_m,
    ];
    (theta, l)
}

/// The torque-reference notch of `cfg` at the current rate `f_cur`, if it has one.
fn notch_design(cfg: &DriveConfig, f_cur: f32) -> Result<Option<NotchDesign>, ConfigError> {
    cfg.notch
        .map(|n| NotchDesign::new(&n, f_cur, NOTCH_PARAMS))
        .transpose()
}

/// Design all gains from the drive settings, after [`DriveConfig::validate`].
///
/// ```
/// # let cfg: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
/// #     env!("CARGO_MANIFEST_DIR"), "/doc/example-drive.toml"))).unwrap();
/// let g = controller_core::design(&cfg).unwrap();
/// assert!(g.kp_vel > 0.0 && g.ki_vel > 0.0);
/// let mut bad = cfg;
/// bad.motor_inertia_s = 0.0;
/// assert_eq!(controller_core::design(&bad).unwrap_err().param(), "motor_inertia_s");
/// ```
pub fn design(cfg: &DriveConfig) -> Result<Gains, ConfigError> {
    cfg.validate()?;
    let (f_cur, f_vel) = (cfg.current_rate_hz as f32, cfg.velocity_rate_hz as f32);
    let (ts_cur, ts_vel) = (1.0 / f_cur, 1.0 / f_vel);
    let (jm, j_total) = (cfg.motor_inertia_s, cfg.total_inertia_s());
    let afb = &cfg.accel_feedback;
    let ka = if afb.mode == AfbMode::Off {
        0.0
    } else {
        afb.gain_fraction * j_total
    };
    let afb_rate_hz = match afb.rate {
        AfbRate::Current => f_cur,
        AfbRate::Velocity => f_vel,
    };
    let afb_filter = design_low_pass(
        &afb.filter,
        afb_rate_hz,
        &ranges::AFB_FILTER_CORNER_HZ,
        &ranges::AFB_FILTER_Q,
    )?;
    let velocity_filter = design_low_pass(
        &cfg.velocity_filter,
        f_vel,
        &ranges::VELOCITY_FILTER_CORNER_HZ,
        &ranges::VELOCITY_FILTER_Q,
    )?;
    let notch = notch_design(cfg, f_cur)?;
    let j_obs = match cfg.observer.model_inertia {
        ObserverInertia::Total => j_total,
        ObserverInertia::Motor => jm,
    };
    let (theta, observer_l) = observer_poles(cfg.observer.bandwidth_hz, f_cur);
    let cpps = counts_per_pu_s(cfg.encoder_cpr, cfg.base_speed_rpm);
    let j_loop = match cfg.velocity_pi_inertia {
        PiInertia::Total => j_total,
        PiInertia::TotalPlusAfb => j_total + ka,
    };
    let (w_vel, w_pos, w_cur) = (
        cfg.velocity_bandwidth_rad_s,
        cfg.position_bandwidth_rad_s,
        cfg.current_bandwidth_rad_s,
    );
    let kp_vel = w_vel * j_loop;
    let zeta = cfg.velocity_damping;
    let k_accel_ff = cfg.accel_ff_gain
        * match afb.mode {
            AfbMode::Plain => j_total + ka,
            AfbMode::Off | AfbMode::Error => j_total,
        };
    Ok(Gains {
        cfg: *cfg,
        j_total_s: j_total,
        j_loop_s: j_loop,
        kpp: w_pos,
        k_pos_pu_per_count: w_pos / cpps,
        kp_vel,
        ki_vel: kp_vel * w_vel / (4.0 * zeta * zeta),
        kp_cur: cfg.winding_inductance_pu_s * w_cur,
        ki_cur: cfg.winding_resistance_pu * w_cur,
        ka,
        k_accel_ff,
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
        max_count_step: max_count_step(cfg),
        ticks_per_velocity: (f_cur / f_vel) as u32,
        notch,
    })
}
