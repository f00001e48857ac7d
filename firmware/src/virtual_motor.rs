//! A virtual power stage and motor for boards without one (QEMU): the PWM voltage drives an
//! RL winding with back-EMF into a rigid inertia, whose angle feeds a virtual encoder. It
//! lets the QEMU firmware close its loops; it is not the plant model of the paper (that is
//! `plant-host`), only enough physics that the current and velocity loops see a load.
//!
//! Per unit, as the core (k_t = k_e = 1 pu):
//! ```text
//! L·di/dt = v − R·i − ω          J·dω/dt = i − T_load          dθ_counts/dt = c·ω
//! ```
//! with `c` = counts per pu·s. Forward Euler at the current-loop period (stable: R·Ts/L ≪ 1).

/// Settings of the virtual motor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VirtualMotorConfig {
    /// Winding resistance [pu].
    pub resistance_pu: f32,
    /// Winding inductance [pu·s].
    pub inductance_pu_s: f32,
    /// Total inertia [s].
    pub inertia_s: f32,
    /// Encoder counts per pu·s of position.
    pub counts_per_pu_s: f32,
    /// Step period [s].
    pub period_s: f32,
}

impl VirtualMotorConfig {
    /// The motor a drive is set up for: its winding and total inertia, stepped each current
    /// tick, counting as its encoder does.
    #[must_use]
    pub fn for_drive(cfg: &controller_core::DriveConfig) -> Self {
        Self {
            resistance_pu: cfg.winding_resistance_pu,
            inductance_pu_s: cfg.winding_inductance_pu_s,
            inertia_s: cfg.total_inertia_s(),
            counts_per_pu_s: controller_core::per_unit::counts_per_pu_s(
                cfg.encoder_cpr,
                cfg.base_speed_rpm,
            ),
            period_s: 1.0 / cfg.current_rate_hz.max(1) as f32,
        }
    }
}

/// The virtual motor's state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VirtualMotor {
    config: VirtualMotorConfig,
    current_pu: f32,
    speed_pu: f32,
    /// Whole counts (wrapping, as a hardware counter).
    counts: u32,
    /// Fraction of a count not yet reached, in [0, 1).
    count_frac: f32,
    load_torque_pu: f32,
}

impl VirtualMotor {
    /// A motor at rest.
    #[must_use]
    pub const fn new(config: VirtualMotorConfig) -> Self {
        Self {
            config,
            current_pu: 0.0,
            speed_pu: 0.0,
            counts: 0,
            count_frac: 0.0,
            load_torque_pu: 0.0,
        }
    }

    /// The same motor with its encoder counter preset to `counts` (e.g. near a wrap).
    #[must_use]
    pub const fn with_counts(mut self, counts: u32) -> Self {
        self.counts = counts;
        self
    }

    /// Apply a load torque [pu] from now on.
    pub fn set_load_torque_pu(&mut self, load_pu: f32) {
        self.load_torque_pu = load_pu;
    }

    /// Advance one period with the winding voltage `voltage_pu` (0 with the stage disabled).
    pub fn step(&mut self, voltage_pu: f32) {
        let c = &self.config;
        let di =
            (voltage_pu - c.resistance_pu * self.current_pu - self.speed_pu) / c.inductance_pu_s;
        let dw = (self.current_pu - self.load_torque_pu) / c.inertia_s;
        self.current_pu += di * c.period_s;
        self.speed_pu += dw * c.period_s;
        let advance = self.count_frac + self.speed_pu * c.counts_per_pu_s * c.period_s;
        let whole = floor(advance);
        self.count_frac = advance - whole;
        // `whole` is a few counts per step; the counter wraps like the hardware one.
        self.counts = self.counts.wrapping_add(whole as i32 as u32);
    }

    /// Winding current [pu].
    #[must_use]
    pub const fn current_pu(&self) -> f32 {
        self.current_pu
    }

    /// Speed [pu].
    #[must_use]
    pub const fn speed_pu(&self) -> f32 {
        self.speed_pu
    }

    /// Encoder counter value [counts, wrapping at 2^32].
    #[must_use]
    pub const fn counts(&self) -> u32 {
        self.counts
    }
}

/// `floor` without libm (no_std): truncate and correct negatives.
fn floor(x: f32) -> f32 {
    let t = x as i32 as f32;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motor() -> VirtualMotor {
        VirtualMotor::new(VirtualMotorConfig {
            resistance_pu: 0.05,
            inductance_pu_s: 0.0006,
            inertia_s: 0.98,
            counts_per_pu_s: 68_266.67,
            period_s: 2.5e-4,
        })
    }

    #[test]
    fn steady_state_speed_is_voltage_minus_ir_drop() {
        let mut m = motor();
        // 4 s at 0.5 pu: speed tends to v (no load, i → 0); τ_mech = J·R ≈ 0.05 s.
        for _ in 0..16_000 {
            m.step(0.5);
        }
        assert!((m.speed_pu() - 0.5).abs() < 1e-3, "speed {}", m.speed_pu());
        assert!(m.current_pu().abs() < 1e-3);
        // Counts advance at c·ω per second: ~17 counts per 250 µs step at 1 pu.
        let before = m.counts();
        for _ in 0..4000 {
            m.step(0.5);
        }
        let moved = m.counts().wrapping_sub(before) as i32;
        assert!((moved - 34_133).abs() < 40, "moved {moved}");
    }

    #[test]
    fn runs_backwards_with_wrapping_counter() {
        let mut m = motor();
        for _ in 0..4000 {
            m.step(-0.2);
        }
        assert!(m.speed_pu() < -0.1);
        assert!((m.counts() as i32) < 0);
        assert_eq!(floor(-0.5), -1.0);
        assert_eq!(floor(2.0), 2.0);
    }
}
