//! A virtual three-phase inverter and PMSM for boards without one (QEMU): the PMSM of a
//! machine file's `[electrics]` with the equations of `plant_host::PmsmPlant`
//! (`plant-host/src/pmsm/machine.rs`), behind three duties and two phase-current readings,
//! driving the rigid inertia or the two-inertia coupling of [`crate::virtual_motor`].
//!
//! Per unit, as plant-host (Ω = p·ω_b·ωm the electrical speed, θe = p·θm + offset):
//! ```text
//! Ld·di_d/dt = v_d − R·i_d + Ω·Lq·i_q
//! Lq·di_q/dt = v_q − R·i_q − Ω·Ld·i_d − λ·ωm
//! Tm = λ·i_q + p·ω_b·(Ld − Lq)·i_d·i_q
//! ```
//! The averaged inverter: each duty clamped to [0, 1] of the PWM period (the DC-bus limit),
//! the phase voltages `(d_x − mean d)·V_dc`, Clarke and Park at the rotor's angle. No dead
//! time. A tick's duties act after the machine file's `computational_delay_s`, the
//! previous tick's until then, as sim-engine applies them to the host plant; a tick that
//! switches the stage off opens the inverter after the same delay: the currents are zero
//! and stay there (plant-host's open inverter, the diodes' decay taken as instantaneous).
//!
//! Each period is stepped in substeps short enough that Ω·h ≤ 0.05 up to 2 pu of speed and
//! R·h/L ≤ 0.05 (and as [`Coupling::substeps`] asks of the shaft), each a classical
//! Runge-Kutta step of order 4 of the currents, the mechanics of [`crate::virtual_motor`]
//! (its shaft law with the lost motion) and the rotor angle together. The encoder counts
//! the motor shaft as the DC
//! virtual motor's does; the electrical angle is taken from the same position (the
//! machine's true encoder offset added) at the start of each period. The two phase
//! currents a and b are read through the machine file's current ADC (`current_adc_bits`
//! over ±`current_full_scale_pu`, rounded to the nearest code and clamped), as plant-host's
//! sensors read them. `f32` throughout, as the Cortex-M4F's FPU.

use crate::virtual_motor::{floor, Coupling};

/// The PMSM of a machine file's `[electrics]` (`motor = "pmsm"`): the machine's truth, as
/// plant-host reads it (not the drive's settings, which a calibration may get wrong).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PmsmMachine {
    /// Pole pairs p.
    pub pole_pairs: u32,
    /// Phase resistance R \[pu\].
    pub resistance_pu: f32,
    /// Ld \[pu·s\].
    pub d_inductance_pu_s: f32,
    /// Lq \[pu·s\].
    pub q_inductance_pu_s: f32,
    /// λ \[pu\].
    pub flux_linkage_pu: f32,
    /// V_dc \[pu\].
    pub dc_bus_pu: f32,
    /// The true electrical angle at count 0 \[deg\], in the drive's phase order.
    pub encoder_offset_elec_deg: f32,
    /// The encoder counts while the electrical angle falls: as plant-host, two motor leads
    /// swapped (the drive's phases b and c are the motor's c and b).
    pub encoder_reversed: bool,
    /// From the current sample to the new duties \[s\].
    pub computational_delay_s: f32,
    /// Current ADC resolution \[bits\] (clamped to 2..=30, as plant-host does).
    pub current_adc_bits: u32,
    /// Current ADC full scale \[±pu\].
    pub current_full_scale_pu: f32,
}

/// Settings of the virtual PMSM.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VirtualPmsmConfig {
    /// The motor.
    pub machine: PmsmMachine,
    /// ω_b: rad/s of the shaft per pu of speed.
    pub base_speed_rad_s: f32,
    /// Encoder counts per revolution.
    pub counts_per_rev: u32,
    /// Total inertia \[s\] (the motor's alone with a coupling).
    pub inertia_s: f32,
    /// Step period: the current loop's \[s\].
    pub period_s: f32,
    /// The duties' full scale \[timer counts\] (`[drive.pmsm] pwm_period_counts`).
    pub pwm_period_counts: u16,
    /// A load behind a shaft; `None`: rigid.
    pub coupling: Option<Coupling>,
}

impl VirtualPmsmConfig {
    /// `machine` stepped at the current-loop period of `cfg`, counting as its encoder does,
    /// its duties in `cfg`'s PWM period, the total inertia rigid; `None` for a drive
    /// without `[drive.pmsm]`.
    #[must_use]
    pub fn for_drive(cfg: &controller_core::DriveConfig, machine: PmsmMachine) -> Option<Self> {
        let pmsm = cfg.pmsm?;
        Some(Self {
            machine,
            base_speed_rad_s: cfg.base_speed_rpm * core::f32::consts::TAU / 60.0,
            counts_per_rev: cfg.encoder_cpr,
            inertia_s: cfg.total_inertia_s(),
            period_s: 1.0 / cfg.current_rate_hz.max(1) as f32,
            pwm_period_counts: pmsm.pwm_period_counts,
            coupling: None,
        })
    }

    /// The same motor driving `coupling`'s load; the motor inertia is `motor_inertia_s`.
    #[must_use]
    pub const fn with_coupling(mut self, motor_inertia_s: f32, coupling: Coupling) -> Self {
        self.inertia_s = motor_inertia_s;
        self.coupling = Some(coupling);
        self
    }
}

/// Speed \[pu\] up to which a substep turns the rotor by at most 0.05 rad electrical.
const MAX_SPEED_PU: f32 = 2.0;
/// Largest Ω·h and R·h/L of a substep.
const MAX_PHASE_PER_SUBSTEP: f32 = 0.05;
/// Most substeps per period.
const MAX_SUBSTEPS: u16 = 64;
/// √3/2.
const SQRT3_2: f32 = 0.866_025_4;

/// One part of a period with one command: its substeps and their length.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Segment {
    substeps: u16,
    h: f32,
}

impl Segment {
    fn new(length_s: f32, substeps: u16) -> Self {
        if substeps == 0 || length_s <= 0.0 {
            return Self::default();
        }
        Self {
            substeps,
            h: length_s / f32::from(substeps),
        }
    }
}

/// Constants the steps use, worked out once.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Derived {
    /// p·ω_b \[rad/s per pu\].
    pw: f32,
    /// p·ω_b·(Ld − Lq) \[pu\].
    saliency: f32,
    offset_rad: f32,
    /// Encoder counts per pu·s of travel.
    counts_per_pu_s: f32,
    /// [delay, rest of the period].
    segments: [Segment; 2],
    adc_lsb_pu: f32,
    adc_max_code: i32,
}

impl Derived {
    fn new(c: &VirtualPmsmConfig) -> Self {
        let m = &c.machine;
        let pw = m.pole_pairs as f32 * c.base_speed_rad_s;
        let l_min = m.d_inductance_pu_s.min(m.q_inductance_pu_s);
        let period = c.period_s.max(0.0);
        let mut n: u16 = 1;
        while n < MAX_SUBSTEPS {
            let h = period / f32::from(n);
            if pw * MAX_SPEED_PU * h <= MAX_PHASE_PER_SUBSTEP
                && m.resistance_pu * h <= MAX_PHASE_PER_SUBSTEP * l_min
            {
                break;
            }
            n += 1;
        }
        if let Some(k) = c.coupling {
            n = n.max(k.substeps(c.inertia_s, period));
        }
        let delay = m.computational_delay_s.clamp(0.0, period);
        let share = |len: f32| -> u16 {
            if len <= 0.0 || period <= 0.0 {
                return 0;
            }
            let x = f32::from(n) * len / period;
            let whole = floor(x);
            let up = if whole < x { whole + 1.0 } else { whole };
            (up as u16).max(1)
        };
        let bits = m.current_adc_bits.clamp(2, 30);
        let half = 1_i32 << (bits - 1);
        Self {
            pw,
            saliency: pw * (m.d_inductance_pu_s - m.q_inductance_pu_s),
            // In the motor's own phase order (plant-host's `PmsmParams::encoder_offset_rad`).
            offset_rad: if m.encoder_reversed {
                -m.encoder_offset_elec_deg.to_radians()
            } else {
                m.encoder_offset_elec_deg.to_radians()
            },
            counts_per_pu_s: c.counts_per_rev as f32 * c.base_speed_rad_s / core::f32::consts::TAU,
            segments: [
                Segment::new(delay, share(delay)),
                Segment::new(period - delay, share(period - delay)),
            ],
            adc_lsb_pu: m.current_full_scale_pu / half as f32,
            adc_max_code: half,
        }
    }
}

/// The state a substep integrates: the d/q currents \[pu\], the motor and load speeds
/// \[pu\], the twist \[rad\], the electrical angle \[rad\] and the travel \[pu·s\].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Vars {
    i_d: f32,
    i_q: f32,
    w_m: f32,
    w_l: f32,
    twist: f32,
    theta: f32,
    moved: f32,
}

impl Vars {
    /// `self + a·k`, each variable.
    fn plus(&self, a: f32, k: &Self) -> Self {
        Self {
            i_d: self.i_d + a * k.i_d,
            i_q: self.i_q + a * k.i_q,
            w_m: self.w_m + a * k.w_m,
            w_l: self.w_l + a * k.w_l,
            twist: self.twist + a * k.twist,
            theta: self.theta + a * k.theta,
            moved: self.moved + a * k.moved,
        }
    }
}

/// The voltage vector (α, β) \[pu\] a tick applies; `None`: the switches open.
type Command = Option<[f32; 2]>;

/// The virtual PMSM's state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VirtualPmsm {
    config: VirtualPmsmConfig,
    d: Derived,
    i_d: f32,
    i_q: f32,
    speed_pu: f32,
    /// With a coupling: load speed \[pu\] and twist θm − θl \[rad\].
    load_speed_pu: f32,
    twist_rad: f32,
    /// Whole counts (wrapping, as a hardware counter).
    counts: u32,
    /// Whole counts within one revolution, 0..counts_per_rev (for the angle).
    rev_counts: u32,
    /// Fraction of a count not yet reached, in [0, 1).
    count_frac: f32,
    load_torque_pu: f32,
    /// The command acting now (until the next tick's arrives).
    applied: Command,
}

impl VirtualPmsm {
    /// A motor at rest, no current, the inverter switching at duties of 1/2 (no voltage);
    /// with a coupling, the load at rest and the shaft in the middle of its lost motion.
    #[must_use]
    pub fn new(config: VirtualPmsmConfig) -> Self {
        Self {
            config,
            d: Derived::new(&config),
            i_d: 0.0,
            i_q: 0.0,
            speed_pu: 0.0,
            load_speed_pu: 0.0,
            twist_rad: 0.0,
            counts: 0,
            rev_counts: 0,
            count_frac: 0.0,
            load_torque_pu: 0.0,
            applied: Some([0.0; 2]),
        }
    }

    /// The same motor with its encoder counter preset to `counts` (the shaft's angle with
    /// it: θm = 2π·counts/cpr, the counter read as signed).
    #[must_use]
    pub fn with_counts(mut self, counts: u32) -> Self {
        let cpr = i64::from(self.config.counts_per_rev.max(1));
        self.counts = counts;
        self.rev_counts = i64::from(counts as i32).rem_euclid(cpr) as u32;
        self
    }

    /// The rig's brake: at rest where it is, no current, no load torque; the encoder keeps
    /// its count.
    pub fn stop(&mut self) {
        let (counts, rev) = (self.counts, self.rev_counts);
        *self = Self::new(self.config);
        self.counts = counts;
        self.rev_counts = rev;
    }

    /// Apply a load torque \[pu\] from now on.
    pub fn set_load_torque_pu(&mut self, load_pu: f32) {
        self.load_torque_pu = load_pu;
    }

    /// The voltage vector of three duties \[timer counts\].
    fn voltage_ab(&self, duties: [u16; 3]) -> [f32; 2] {
        let full = f32::from(self.config.pwm_period_counts.max(1));
        let [a, b, c] = duties.map(|x| (f32::from(x) / full).min(1.0));
        // The drive's phase order to the motor's.
        let (b, c) = if self.config.machine.encoder_reversed {
            (c, b)
        } else {
            (b, c)
        };
        let bus = self.config.machine.dc_bus_pu;
        // Clarke of (d − mean)·V_dc: the mean drops out.
        [
            bus * (2.0 * a - b - c) / 3.0,
            bus * (b - c) / (2.0 * SQRT3_2),
        ]
    }

    /// Advance one period: the previous command for the computational delay, then
    /// `duties` \[timer counts\] (`None`: all six switches open).
    pub fn step(&mut self, duties: Option<[u16; 3]>) {
        let new = duties.map(|d| self.voltage_ab(d));
        let mut theta = self.electrical_angle_rad();
        let mut moved = 0.0;
        let [first, rest] = self.d.segments;
        for (segment, command) in [(first, self.applied), (rest, new)] {
            moved += self.run_segment(&segment, command, &mut theta);
        }
        self.applied = new;
        let advance = self.count_frac + moved * self.d.counts_per_pu_s;
        let whole = floor(advance);
        self.count_frac = advance - whole;
        // A few counts per step; the counter wraps like the hardware one.
        let step = whole as i32;
        self.counts = self.counts.wrapping_add(step as u32);
        let cpr = self.config.counts_per_rev.max(1) as i64;
        self.rev_counts = (i64::from(self.rev_counts) + i64::from(step)).rem_euclid(cpr) as u32;
    }

    /// One segment's substeps under `command` (classical Runge-Kutta of order 4 on the
    /// currents, the mechanics and the angle); returns the motor's travel \[pu·s\].
    fn run_segment(&mut self, s: &Segment, command: Command, theta: &mut f32) -> f32 {
        if command.is_none() {
            // Open: the currents fall to zero at once and stay there.
            self.i_d = 0.0;
            self.i_q = 0.0;
        }
        let mut x = Vars {
            i_d: self.i_d,
            i_q: self.i_q,
            w_m: self.speed_pu,
            w_l: self.load_speed_pu,
            twist: self.twist_rad,
            theta: *theta,
            moved: 0.0,
        };
        let h = s.h;
        for _ in 0..s.substeps {
            let k1 = self.rate(&x, command);
            let k2 = self.rate(&x.plus(0.5 * h, &k1), command);
            let k3 = self.rate(&x.plus(0.5 * h, &k2), command);
            let k4 = self.rate(&x.plus(h, &k3), command);
            let slope = k1.plus(2.0, &k2).plus(2.0, &k3).plus(1.0, &k4);
            x = x.plus(h / 6.0, &slope);
        }
        self.i_d = x.i_d;
        self.i_q = x.i_q;
        self.speed_pu = x.w_m;
        self.load_speed_pu = x.w_l;
        self.twist_rad = x.twist;
        *theta = x.theta;
        x.moved
    }

    /// The time derivative of `x` under `command`.
    fn rate(&self, x: &Vars, command: Command) -> Vars {
        let m = &self.config.machine;
        let d = &self.d;
        let omega = d.pw * x.w_m;
        let (di_d, di_q) = match command {
            Some([va, vb]) => {
                let (sin, cos) = sin_cos(x.theta);
                let v_d = cos * va + sin * vb;
                let v_q = cos * vb - sin * va;
                (
                    (v_d - m.resistance_pu * x.i_d + omega * m.q_inductance_pu_s * x.i_q)
                        / m.d_inductance_pu_s,
                    (v_q - m.resistance_pu * x.i_q
                        - omega * m.d_inductance_pu_s * x.i_d
                        - m.flux_linkage_pu * x.w_m)
                        / m.q_inductance_pu_s,
                )
            }
            None => (0.0, 0.0),
        };
        let torque = m.flux_linkage_pu * x.i_q + d.saliency * x.i_d * x.i_q;
        let c = &self.config;
        let (dw_m, dw_l, dtwist) = match c.coupling {
            Some(k) => {
                let ts = k.shaft_torque(x.twist, x.w_m - x.w_l);
                (
                    (torque - ts - k.motor_viscous_pu * x.w_m) / c.inertia_s,
                    (ts - self.load_torque_pu - k.load_viscous_pu * x.w_l) / k.load_inertia_s,
                    k.base_speed_rad_s * (x.w_m - x.w_l),
                )
            }
            None => {
                let dw = (torque - self.load_torque_pu) / c.inertia_s;
                (dw, dw, 0.0)
            }
        };
        Vars {
            i_d: di_d,
            i_q: di_q,
            w_m: dw_m,
            w_l: dw_l,
            twist: dtwist,
            theta: omega,
            moved: x.w_m,
        }
    }

    /// The true electrical angle θe = p·θm + offset \[rad\], in [offset, offset + 2π).
    #[must_use]
    pub fn electrical_angle_rad(&self) -> f32 {
        let cpr = self.config.counts_per_rev.max(1) as f32;
        let x = (self.rev_counts as f32 + self.count_frac) * self.config.machine.pole_pairs as f32;
        let within = x - cpr * floor(x / cpr);
        self.d.offset_rad + core::f32::consts::TAU * within / cpr
    }

    /// The drive's phase currents a and b \[pu\], true (not sampled): its b is the motor's
    /// c when the leads are swapped (`encoder_reversed`).
    #[must_use]
    pub fn phase_currents_pu(&self) -> [f32; 2] {
        let (sin, cos) = sin_cos(self.electrical_angle_rad());
        let alpha = cos * self.i_d - sin * self.i_q;
        let beta = sin * self.i_d + cos * self.i_q;
        if self.config.machine.encoder_reversed {
            [alpha, -0.5 * alpha - SQRT3_2 * beta]
        } else {
            [alpha, -0.5 * alpha + SQRT3_2 * beta]
        }
    }

    /// The ADC codes of phases a and b: the current over the LSB, to nearest (ties away
    /// from zero), clamped to the code range.
    #[must_use]
    pub fn phase_current_codes(&self) -> [i32; 2] {
        let d = &self.d;
        self.phase_currents_pu().map(|i| {
            let x = i / d.adc_lsb_pu;
            let r = if x < 0.0 {
                -floor(0.5 - x)
            } else {
                floor(x + 0.5)
            };
            let max = d.adc_max_code as f32;
            // Clamped first, so the conversion cannot saturate (NaN gives 0).
            r.clamp(-max, max - 1.0) as i32
        })
    }

    /// Phases a and b as the ADC reads them \[pu\] (code × LSB).
    #[must_use]
    pub fn phase_current_samples_pu(&self) -> [f32; 2] {
        self.phase_current_codes()
            .map(|c| c as f32 * self.d.adc_lsb_pu)
    }

    /// d current \[pu\].
    #[must_use]
    pub const fn i_d_pu(&self) -> f32 {
        self.i_d
    }

    /// q current \[pu\].
    #[must_use]
    pub const fn i_q_pu(&self) -> f32 {
        self.i_q
    }

    /// The motor's torque λ·i_q + p·ω_b·(Ld − Lq)·i_d·i_q \[pu\].
    #[must_use]
    pub fn torque_pu(&self) -> f32 {
        self.config.machine.flux_linkage_pu * self.i_q + self.d.saliency * self.i_d * self.i_q
    }

    /// Motor speed \[pu\].
    #[must_use]
    pub const fn speed_pu(&self) -> f32 {
        self.speed_pu
    }

    /// Load speed \[pu\] (the motor's without a coupling).
    #[must_use]
    pub const fn load_speed_pu(&self) -> f32 {
        self.load_speed_pu
    }

    /// Shaft twist θm − θl \[rad at the motor\] (0 without a coupling).
    #[must_use]
    pub const fn twist_rad(&self) -> f32 {
        self.twist_rad
    }

    /// Encoder counter value \[counts, wrapping at 2^32\].
    #[must_use]
    pub const fn counts(&self) -> u32 {
        self.counts
    }

    /// The motor position \[counts\] with its fraction: θm·cpr/2π, for a counter that
    /// has not wrapped.
    #[must_use]
    pub fn position_counts(&self) -> f32 {
        self.counts as i32 as f32 + self.count_frac
    }

    /// The substeps of a period ([delay, rest]).
    #[must_use]
    pub fn substeps(&self) -> [u16; 2] {
        self.d.segments.map(|s| s.substeps)
    }
}

/// sin x and cos x without libm: x reduced by multiples of π/2 (two-part π/2), then Taylor
/// polynomials on [−π/4, π/4] (truncation below 3e-9).
#[must_use]
pub fn sin_cos(x: f32) -> (f32, f32) {
    const PI_2_HI: f32 = 1.570_796_4;
    const PI_2_LO: f32 = -4.371_139e-8;
    let q = floor(x * core::f32::consts::FRAC_2_PI + 0.5);
    let r = (x - q * PI_2_HI) - q * PI_2_LO;
    let r2 = r * r;
    let s = r * (1.0 - r2 / 6.0 * (1.0 - r2 / 20.0 * (1.0 - r2 / 42.0 * (1.0 - r2 / 72.0))));
    let c = 1.0 - r2 / 2.0 * (1.0 - r2 / 12.0 * (1.0 - r2 / 30.0 * (1.0 - r2 / 56.0)));
    match (q as i32).rem_euclid(4) {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sin_cos_matches_std_over_several_turns() {
        let mut worst: f32 = 0.0;
        for k in -4000..=4000 {
            let x = k as f32 * 0.01;
            let (s, c) = sin_cos(x);
            worst = worst.max((s - x.sin()).abs()).max((c - x.cos()).abs());
        }
        assert!(worst < 2e-6, "worst {worst}");
    }
}
