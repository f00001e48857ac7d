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
//!
//! With a [`Coupling`] (the `board` image's machine, `firmware::drive::coupling`) the motor
//! inertia drives a load inertia through a shaft with lost motion, the two-inertia model of
//! `plant-host/README.md` with its dead zone:
//! ```text
//! Jm·dωm/dt = i − Ts − Bm·ωm     Jl·dωl/dt = Ts − T_load − Bl·ωl     dδ/dt = ωb·(ωm − ωl)
//! Ts = K·dz(δ) + D·(ωm − ωl) while |δ| > g, else 0
//! ```
//! stepped by semi-implicit Euler (the speeds first, then the twist and the position from
//! the new speeds) in as many substeps of the current-loop period as keep ωr·h ≤ 0.05
//! ([`Coupling::substeps`]), the winding by forward Euler once per period as above.

/// Settings of the virtual motor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VirtualMotorConfig {
    /// Winding resistance \[pu\].
    pub resistance_pu: f32,
    /// Winding inductance [pu·s].
    pub inductance_pu_s: f32,
    /// Total inertia \[s\].
    pub inertia_s: f32,
    /// Encoder counts per pu·s of position.
    pub counts_per_pu_s: f32,
    /// Step period \[s\].
    pub period_s: f32,
    /// A load behind a shaft (`inertia_s` is then the motor's alone); `None`: rigid.
    pub coupling: Option<Coupling>,
}

/// The load side of a two-inertia machine, in the constants of `plant-host`'s
/// `MechanicsConfig::derived` (the firmware's build script computes them from the machine
/// file's `[plant]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coupling {
    /// Load inertia, reflected to the motor \[s\].
    pub load_inertia_s: f32,
    /// Shaft stiffness K [pu torque per rad of twist].
    pub stiffness_pu_per_rad: f32,
    /// Shaft damping D [pu torque per pu speed difference].
    pub damping_pu: f32,
    /// Half the lost motion g [rad at the motor].
    pub half_gap_rad: f32,
    /// ω_b [rad/s per pu speed].
    pub base_speed_rad_s: f32,
    /// Viscous friction of the motor Bm [pu torque per pu speed].
    pub motor_viscous_pu: f32,
    /// Viscous friction of the load Bl [pu torque per pu speed].
    pub load_viscous_pu: f32,
}

/// Largest ωr·h of a substep: the semi-implicit Euler's frequency error is then below
/// (ωr·h)²/24 ≈ 1e-4.
const MAX_PHASE_PER_SUBSTEP: f32 = 0.05;
/// Most substeps per period.
const MAX_SUBSTEPS: u16 = 64;

impl Coupling {
    /// Substeps of `period_s` with motor inertia `motor_inertia_s`: the fewest that keep
    /// ωr·h ≤ 0.05 (and the shaft damping's rate·h as small), at most 64. ωr² = K·ωb·(1/Jm +
    /// 1/Jl), compared squared (no square root on the target).
    #[must_use]
    pub fn substeps(&self, motor_inertia_s: f32, period_s: f32) -> u16 {
        let inv_j = 1.0 / motor_inertia_s + 1.0 / self.load_inertia_s;
        let w2 = self.stiffness_pu_per_rad * self.base_speed_rad_s * inv_j;
        let rate = self.damping_pu * inv_j;
        let mut n: u16 = 1;
        while n < MAX_SUBSTEPS {
            let h = period_s / f32::from(n);
            let limit = MAX_PHASE_PER_SUBSTEP * MAX_PHASE_PER_SUBSTEP;
            if w2 * h * h <= limit && rate * h <= MAX_PHASE_PER_SUBSTEP {
                break;
            }
            n += 1;
        }
        n
    }

    /// The shaft torque at twist `twist_rad` and speed difference `slip_pu` (dead zone).
    pub(crate) fn shaft_torque(&self, twist_rad: f32, slip_pu: f32) -> f32 {
        let g = self.half_gap_rad;
        let dz = if twist_rad > g {
            twist_rad - g
        } else if twist_rad < -g {
            twist_rad + g
        } else {
            return 0.0;
        };
        self.stiffness_pu_per_rad * dz + self.damping_pu * slip_pu
    }
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
            coupling: None,
        }
    }

    /// The same winding and encoder driving `coupling`'s load through its shaft; the motor
    /// inertia is then `motor_inertia_s`.
    #[must_use]
    pub const fn with_coupling(mut self, motor_inertia_s: f32, coupling: Coupling) -> Self {
        self.inertia_s = motor_inertia_s;
        self.coupling = Some(coupling);
        self
    }
}

/// The load side's state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct LoadState {
    /// Load speed \[pu\].
    speed_pu: f32,
    /// Twist θm − θl [rad at the motor].
    twist_rad: f32,
    /// Substeps per period.
    substeps: u16,
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
    /// With a coupling: the load side.
    load: Option<LoadState>,
}

impl VirtualMotor {
    /// A motor at rest (with a coupling: the load at rest, the shaft in the middle of its
    /// lost motion).
    #[must_use]
    pub fn new(config: VirtualMotorConfig) -> Self {
        let load = config.coupling.map(|c| LoadState {
            substeps: c.substeps(config.inertia_s, config.period_s),
            ..LoadState::default()
        });
        Self {
            config,
            current_pu: 0.0,
            speed_pu: 0.0,
            counts: 0,
            count_frac: 0.0,
            load_torque_pu: 0.0,
            load,
        }
    }

    /// The same motor with its encoder counter preset to `counts` (e.g. near a wrap).
    #[must_use]
    pub const fn with_counts(mut self, counts: u32) -> Self {
        self.counts = counts;
        self
    }

    /// The rig's brake: the machine at rest where it is (no current, no speed, the shaft in
    /// the middle of its lost motion, no load torque); the encoder keeps its count.
    pub fn stop(&mut self) {
        *self = Self::new(self.config).with_counts(self.counts);
    }

    /// Apply a load torque \[pu\] from now on.
    pub fn set_load_torque_pu(&mut self, load_pu: f32) {
        self.load_torque_pu = load_pu;
    }

    /// Advance one period with the winding voltage `voltage_pu` (0 with the stage disabled).
    pub fn step(&mut self, voltage_pu: f32) {
        let c = self.config;
        let di =
            (voltage_pu - c.resistance_pu * self.current_pu - self.speed_pu) / c.inductance_pu_s;
        let torque_pu = self.current_pu;
        self.current_pu += di * c.period_s;
        let advance = match (c.coupling, self.load.as_mut()) {
            (Some(k), Some(load)) => {
                let moved_pu_s = step_coupled(
                    &c,
                    &k,
                    load,
                    &mut self.speed_pu,
                    torque_pu,
                    self.load_torque_pu,
                );
                self.count_frac + moved_pu_s * c.counts_per_pu_s
            }
            _ => {
                let dw = (torque_pu - self.load_torque_pu) / c.inertia_s;
                self.speed_pu += dw * c.period_s;
                self.count_frac + self.speed_pu * c.counts_per_pu_s * c.period_s
            }
        };
        let whole = floor(advance);
        self.count_frac = advance - whole;
        // `whole` is a few counts per step; the counter wraps like the hardware one.
        self.counts = self.counts.wrapping_add(whole as i32 as u32);
    }

    /// Load speed \[pu\] (the motor's without a coupling).
    #[must_use]
    pub fn load_speed_pu(&self) -> f32 {
        self.load.map_or(self.speed_pu, |l| l.speed_pu)
    }

    /// Shaft twist θm − θl [rad at the motor] (0 without a coupling).
    #[must_use]
    pub fn twist_rad(&self) -> f32 {
        self.load.map_or(0.0, |l| l.twist_rad)
    }

    /// Winding current \[pu\].
    #[must_use]
    pub const fn current_pu(&self) -> f32 {
        self.current_pu
    }

    /// Speed \[pu\].
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

/// One period of the two-inertia mechanics under the motor torque `torque_pu` and the load
/// torque `load_pu`; returns the motor's travel in pu·s (speed integrated over the period).
fn step_coupled(
    c: &VirtualMotorConfig,
    k: &Coupling,
    load: &mut LoadState,
    motor_speed_pu: &mut f32,
    torque_pu: f32,
    load_pu: f32,
) -> f32 {
    let n = load.substeps.max(1);
    let h = c.period_s / f32::from(n);
    let mut moved = 0.0;
    for _ in 0..n {
        let ts = k.shaft_torque(load.twist_rad, *motor_speed_pu - load.speed_pu);
        *motor_speed_pu +=
            h * (torque_pu - ts - k.motor_viscous_pu * *motor_speed_pu) / c.inertia_s;
        load.speed_pu += h * (ts - load_pu - k.load_viscous_pu * load.speed_pu) / k.load_inertia_s;
        load.twist_rad += h * k.base_speed_rad_s * (*motor_speed_pu - load.speed_pu);
        moved += h * *motor_speed_pu;
    }
    moved
}

/// `floor` without libm (no_std): truncate and correct negatives.
pub(crate) fn floor(x: f32) -> f32 {
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
            coupling: None,
        })
    }

    /// A light motor (0.05 s) on a 12x load through a 2 %-damped shaft, anti-resonance at
    /// 30 Hz, 0.2° of lost motion, 1000 rpm base speed; K, D, g as plant-host derives them.
    fn light() -> VirtualMotor {
        let war = 2.0 * core::f32::consts::PI * 30.0;
        let wb = 2.0 * core::f32::consts::PI * 1000.0 / 60.0;
        let coupling = Coupling {
            load_inertia_s: 0.6,
            stiffness_pu_per_rad: 0.6 * war * war / wb,
            damping_pu: 2.0 * 0.02 * 0.6 * war,
            half_gap_rad: 0.1_f32.to_radians(),
            base_speed_rad_s: wb,
            motor_viscous_pu: 0.0,
            load_viscous_pu: 0.0,
        };
        VirtualMotor::new(motor().config.with_coupling(0.05, coupling))
    }

    #[test]
    fn the_coupled_load_follows_the_motor_and_the_shaft_takes_the_load_torque() {
        let mut m = light();
        // ωr = 2π·30 Hz·√13 = 680 rad/s, ωr·T = 0.17: four substeps keep ωr·h ≤ 0.05.
        assert_eq!(m.load.map(|l| l.substeps), Some(4));
        for _ in 0..16_000 {
            m.step(0.5);
        }
        // Both inertias at the no-load speed; the shaft carries no torque (inside the gap).
        assert!((m.speed_pu() - 0.5).abs() < 1e-3, "speed {}", m.speed_pu());
        assert!((m.load_speed_pu() - 0.5).abs() < 1e-3);
        assert!(m.twist_rad().abs() <= 0.1_f32.to_radians() + 1e-5);
        // A load torque: at the new steady state the shaft transmits it, twisted past the
        // gap by T/K.
        m.set_load_torque_pu(0.2);
        for _ in 0..16_000 {
            m.step(0.5);
        }
        let k = m.config.coupling.map_or(0.0, |c| c.stiffness_pu_per_rad);
        let expected = 0.1_f32.to_radians() + 0.2 / k;
        assert!(
            (m.twist_rad() - expected).abs() < 1e-3 * expected,
            "twist {} expected {expected}",
            m.twist_rad()
        );
        assert!(
            (m.current_pu() - 0.2).abs() < 1e-3,
            "current {}",
            m.current_pu()
        );
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
