//! Drive settings: plain `Copy` data, all in SI or per-unit as the field names say.
//! [`crate::design()`] validates them and turns them into gains once.

/// Source of a velocity or acceleration estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Estimator {
    /// Backward differences of the encoder counts at the consuming loop's rate
    /// (velocity = Δcounts/Ts, acceleration = Δ²counts/Ts²), with their quantization.
    Differentiation,
    /// The Luenberger state observer (position and torque command in), run every current tick.
    Observer,
}

/// A low-pass filter on an estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FilterConfig {
    /// No filter.
    None,
    /// First-order low-pass, corner in Hz (matched pole: α = 1 − e^(−2π·f_c·Ts)).
    FirstOrder {
        /// Corner frequency \[Hz\], 0 < f_c < rate/2.
        corner_hz: f32,
    },
    /// Second-order (biquad) low-pass, bilinear with pre-warped corner.
    SecondOrder {
        /// Corner frequency \[Hz\], 0 < f_c < rate/2.
        corner_hz: f32,
        /// Quality factor (0.707 = Butterworth), 0.1..=10.
        q: f32,
    },
}

/// How the acceleration feedback term is formed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AfbMode {
    /// No acceleration feedback.
    Off,
    /// Plain form: torque reference −= Ka·LPF(measured acceleration).
    Plain,
    /// Acceleration-error form (Rockwell US 7,141,946):
    /// torque reference += Ka·LPF(commanded − measured acceleration).
    Error,
}

/// Which tick runs the acceleration feedback path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AfbRate {
    /// Every current tick (`current_rate_hz`).
    Current,
    /// Every velocity tick (`velocity_rate_hz`).
    Velocity,
}

/// Acceleration feedback ("inertia stabilization") settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccelFeedbackConfig {
    /// Form of the feedback.
    pub mode: AfbMode,
    /// Ka as a fraction of the total inertia (Ka = fraction·J_total, in s), 0..=20.
    pub gain_fraction: f32,
    /// Low-pass filter on the acceleration (or acceleration error).
    pub filter: FilterConfig,
    /// Tick that runs the path.
    pub rate: AfbRate,
    /// Source of the measured acceleration.
    pub source: Estimator,
}

/// Inertia the observer's model uses to turn the torque command into acceleration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObserverInertia {
    /// Motor plus load (`motor_inertia_s + load_inertia_s`): right while the gears are engaged.
    Total,
    /// Motor alone (`motor_inertia_s`): right inside the lost motion.
    Motor,
}

/// Inertia the velocity PI is sized for (Kp = ω_v·J, Ki = Kp·ω_v/(4ζ²)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PiInertia {
    /// J = J_total: the regulator is tuned for the machine and acceleration feedback adds
    /// inertia electrically on top of it (the paper's reading, Fig. 2). With AFB off or on,
    /// the velocity gains are the same.
    Total,
    /// J = J_total + Ka: the velocity loop keeps its bandwidth with AFB on, at the price of
    /// most of the disturbance benefit (the regulator gains grow with Ka).
    TotalPlusAfb,
}

/// Torque the observer's model is driven with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ObserverTorque {
    /// The torque (current) reference of the last current tick.
    Command,
    /// The measured current: the mean of this and the last current tick's sample.
    MeasuredCurrent,
}

/// Luenberger observer settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObserverConfig {
    /// Observer bandwidth \[Hz\]: the three observer poles sit at z = e^(−2π·f·Ts_current).
    /// 0 < f < current_rate_hz/2.
    pub bandwidth_hz: f32,
    /// Model inertia.
    pub model_inertia: ObserverInertia,
    /// Torque input of the model (see `controller-core/README.md` for the measurement
    /// behind the default, `Command`).
    pub torque_input: ObserverTorque,
}

/// Fault thresholds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultLimits {
    /// Overspeed trip on the velocity estimate \[pu\], > 0.
    pub overspeed_pu: f32,
    /// Following-error trip on |commanded − measured position| \[counts\], > 0; only while
    /// the position loop is on. At most 8,000,000.
    pub following_error_counts: f32,
    /// Encoder jump trip: a change of counts between two current ticks larger than
    /// `margin × overspeed_pu × counts per current tick at 1 pu + 2` counts. ≥ 1.
    pub encoder_jump_margin: f32,
}

/// The drive's settings. Every field is plain data; the units are in the names.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveConfig {
    /// Base (rated) speed \[rpm\], defines 1 pu of speed. > 0.
    pub base_speed_rpm: f32,
    /// Encoder counts per motor revolution (after quadrature), ≥ 4.
    pub encoder_cpr: u32,
    /// Width of the hardware counter that delivers `encoder_count` \[bits\], 16..=32.
    pub counter_bits: u8,
    /// Current-loop tick rate \[Hz\], 100..=100,000.
    pub current_rate_hz: u32,
    /// Velocity-loop tick rate \[Hz\]; must divide `current_rate_hz`.
    pub velocity_rate_hz: u32,
    /// Motor inertia \[s\], > 0.
    pub motor_inertia_s: f32,
    /// Load inertia reflected to the motor \[s\], ≥ 0.
    pub load_inertia_s: f32,
    /// Position-loop bandwidth \[rad/s\] (Kpp = ω_pos); 0 = position loop off (velocity mode).
    pub position_bandwidth_rad_s: f32,
    /// Velocity-loop bandwidth \[rad/s\]: Kp = ω·J, Ki = Kp·ω/(4ζ²). > 0, below π·velocity_rate_hz.
    pub velocity_bandwidth_rad_s: f32,
    /// Velocity-loop damping ζ, 0.1..=10 (1 = Ki = Kp·ω/4).
    pub velocity_damping: f32,
    /// Inertia the velocity PI is sized for (`[drive] velocity_pi_inertia`).
    pub velocity_pi_inertia: PiInertia,
    /// Current-loop bandwidth \[rad/s\]: Kp = L·ω_c, Ki = R·ω_c. > 0, below π·current_rate_hz.
    pub current_bandwidth_rad_s: f32,
    /// Winding resistance \[pu voltage per pu current\], > 0.
    pub winding_resistance_pu: f32,
    /// Winding inductance \[pu voltage per pu current per second, i.e. pu·s\], > 0.
    pub winding_inductance_pu_s: f32,
    /// Torque (= current) reference limit \[pu\], > 0.
    pub torque_limit_pu: f32,
    /// Voltage command limit \[pu\], > 0.
    pub voltage_limit_pu: f32,
    /// Fraction of the commanded velocity fed forward into the velocity reference, 0..=1
    /// (position mode; in velocity mode the setpoint velocity is the reference).
    pub velocity_ff_gain: f32,
    /// Fraction of the commanded acceleration times inertia fed forward as torque, 0..=1.
    pub accel_ff_gain: f32,
    /// Low-pass filter on the velocity feedback.
    pub velocity_filter: FilterConfig,
    /// Source of the velocity feedback.
    pub velocity_estimator: Estimator,
    /// Acceleration feedback.
    pub accel_feedback: AccelFeedbackConfig,
    /// State observer.
    pub observer: ObserverConfig,
    /// Fault thresholds.
    pub faults: FaultLimits,
}

impl DriveConfig {
    /// The paper's Table 1 drive: 1000 rpm, 4096 CPR, 4 kHz current / 2 kHz velocity ticks,
    /// Jm = 0.117 s, Jl = 0.863 s, bandwidths 3 Hz (position), 15 Hz (velocity),
    /// 318 Hz (current), velocity PI sized for J_total, with acceleration feedback on in the default design of
    /// `controller-core/README.md` (chosen by the closed-loop sweep in
    /// `tests/afb_design.rs`): error form, Ka = 0.5·J_total, acceleration from the observer
    /// (motor-inertia model, 75 Hz), first-order filter at 100 Hz, run every current tick;
    /// velocity feedback from the observer.
    ///
    /// ```
    /// let cfg = controller_core::DriveConfig::table1();
    /// assert!(controller_core::design(&cfg).is_ok());
    /// ```
    #[must_use]
    pub const fn table1() -> Self {
        Self {
            base_speed_rpm: 1000.0,
            encoder_cpr: 4096,
            counter_bits: 16,
            current_rate_hz: 4000,
            velocity_rate_hz: 2000,
            motor_inertia_s: 0.117,
            load_inertia_s: 0.863,
            position_bandwidth_rad_s: 2.0 * core::f32::consts::PI * 3.0,
            velocity_bandwidth_rad_s: 2.0 * core::f32::consts::PI * 15.0,
            velocity_damping: 1.0,
            velocity_pi_inertia: PiInertia::Total,
            current_bandwidth_rad_s: 2.0 * core::f32::consts::PI * 318.0,
            winding_resistance_pu: 0.05,
            winding_inductance_pu_s: 0.0006,
            torque_limit_pu: 2.0,
            voltage_limit_pu: 1.2,
            velocity_ff_gain: 1.0,
            accel_ff_gain: 1.0,
            velocity_filter: FilterConfig::None,
            velocity_estimator: Estimator::Observer,
            accel_feedback: AccelFeedbackConfig {
                mode: AfbMode::Error,
                gain_fraction: 0.5,
                filter: FilterConfig::FirstOrder { corner_hz: 100.0 },
                rate: AfbRate::Current,
                source: Estimator::Observer,
            },
            observer: ObserverConfig {
                bandwidth_hz: 75.0,
                model_inertia: ObserverInertia::Motor,
                torque_input: ObserverTorque::Command,
            },
            faults: FaultLimits {
                overspeed_pu: 1.5,
                following_error_counts: 4096.0,
                encoder_jump_margin: 2.0,
            },
        }
    }

    /// Total inertia J_total = motor + load \[s\].
    #[must_use]
    pub fn total_inertia_s(&self) -> f32 {
        self.motor_inertia_s + self.load_inertia_s
    }
}

impl Default for DriveConfig {
    fn default() -> Self {
        Self::table1()
    }
}
