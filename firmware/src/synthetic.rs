//! Synthetic sensor inputs for the instruction benchmark: an encoder that tracks a motion
//! profile (so the drive follows without a following-error fault and every regulator runs
//! its full path) with a ±1 count dither, and a current with a ±4 LSB pseudo-random ripple
//! around a small torque. The generator advances between ticks, outside the measured code;
//! the I/O handles the ticks read are plain loads, as register reads would be.
//!
//! For a PMSM drive ([`SyntheticSensors::advance_pmsm`], [`SyntheticPmsmIo`]) the two phase
//! currents are those of a current vector at the drive's own electrical angle of the
//! encoder count: the q current its last reference (a current loop that follows), the d
//! current zero, each with the same ±4 LSB ripple. So the FOC loop, the commutation check
//! and the protections run their full path without a fault.

use core::sync::atomic::{AtomicI32, AtomicU32, Ordering};

use controller_core::foc::transforms::{inverse_park, CosSin, Dq};
use controller_core::foc::AngleCoefficients;
use controller_core::{Pu, Setpoint};

use crate::board::three_phase::PmsmLoopIo;
use crate::board::{CurrentLoopIo, VelocityLoopIo};

/// Latest synthetic encoder count.
static ENCODER: AtomicU32 = AtomicU32::new(0);
/// Latest synthetic current, Q16.16 bits.
static CURRENT_BITS: AtomicI32 = AtomicI32::new(0);
/// Last voltage command the current loop applied, Q16.16 bits.
static APPLIED_BITS: AtomicI32 = AtomicI32::new(0);
/// Latest synthetic phase currents a and b, Q16.16 bits.
static PHASE_A_BITS: AtomicI32 = AtomicI32::new(0);
static PHASE_B_BITS: AtomicI32 = AtomicI32::new(0);
/// Last duties the PMSM current loop applied (a, b, c packed in 16 bits each, c alone).
static DUTIES_AB: AtomicU32 = AtomicU32::new(0);
static DUTY_C: AtomicU32 = AtomicU32::new(0);

/// Deterministic sensor generator.
pub struct SyntheticSensors {
    seed: u32,
    tick: u32,
    counter_mask: u32,
}

impl SyntheticSensors {
    /// A generator for a `counter_bits`-wide encoder counter.
    #[must_use]
    pub const fn new(counter_bits: u8) -> Self {
        let counter_mask = if counter_bits >= 32 {
            u32::MAX
        } else {
            (1_u32 << counter_bits) - 1
        };
        Self {
            seed: 0x1234_5678,
            tick: 0,
            counter_mask,
        }
    }

    /// Publish the sensor values for the next tick, given the motion the drive should be
    /// following (`setpoint`, the profile's latest).
    pub fn advance(&mut self, setpoint: &Setpoint) {
        // xorshift32: cheap deterministic noise.
        let mut x = self.seed;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.seed = x;
        self.tick = self.tick.wrapping_add(1);
        let position = (setpoint.position_counts.to_bits() >> 16) as i32;
        let dither = (self.tick % 3) as i32 - 1;
        ENCODER.store(
            (position.wrapping_add(dither) as u32) & self.counter_mask,
            Ordering::Relaxed,
        );
        // 0.2 pu plus ±4 LSB of a 12-bit ADC (1/1024 pu per LSB = 64 Q16.16 bits).
        let ripple_bits = ((x % 9) as i32 - 4) * 64;
        CURRENT_BITS.store(13_107 + ripple_bits, Ordering::Relaxed);
    }

    /// Publish a PMSM drive's sensor values for the next tick: the encoder as
    /// [`SyntheticSensors::advance`], and the phase currents of `(0, i_q)` plus ripple at
    /// the electrical angle `angle` gives that count.
    pub fn advance_pmsm(&mut self, setpoint: &Setpoint, angle: &AngleCoefficients, i_q: Pu) {
        self.advance(setpoint);
        let count = ENCODER.load(Ordering::Relaxed);
        let ripple = CURRENT_BITS.load(Ordering::Relaxed) - 13_107;
        let rev = angle.state_at(i64::from(count)).count_in_rev;
        let cs = CosSin::of(angle.phase_at(rev));
        let ab = inverse_park(
            Dq {
                d: Pu::from_bits(ripple),
                q: i_q.saturating_add(Pu::from_bits(ripple)),
            },
            cs,
        );
        // Phase b of (α, β): −α/2 + (√3/2)·β.
        let half_sqrt3 = Pu::from_bits(56_756);
        let b = (ab.beta.saturating_mul(half_sqrt3)).saturating_sub(ab.alpha / 2);
        PHASE_A_BITS.store(ab.alpha.to_bits(), Ordering::Relaxed);
        PHASE_B_BITS.store(b.to_bits(), Ordering::Relaxed);
    }

    /// Last duties the PMSM current loop applied [timer counts].
    #[must_use]
    pub fn applied_duties() -> [u16; 3] {
        let ab = DUTIES_AB.load(Ordering::Relaxed);
        [
            (ab & 0xFFFF) as u16,
            (ab >> 16) as u16,
            DUTY_C.load(Ordering::Relaxed) as u16,
        ]
    }

    /// Last voltage command the current loop applied \[pu\].
    #[must_use]
    pub fn applied_voltage_pu() -> Pu {
        Pu::from_bits(APPLIED_BITS.load(Ordering::Relaxed))
    }
}

/// Current-loop I/O over the synthetic sensors.
#[derive(Debug, Default)]
pub struct SyntheticCurrentIo;

impl CurrentLoopIo for SyntheticCurrentIo {
    fn encoder_count(&mut self) -> u32 {
        ENCODER.load(Ordering::Relaxed)
    }
    fn current_pu(&mut self) -> Option<Pu> {
        Some(Pu::from_bits(CURRENT_BITS.load(Ordering::Relaxed)))
    }
    fn set_voltage_pu(&mut self, voltage_pu: Pu) -> bool {
        APPLIED_BITS.store(voltage_pu.to_bits(), Ordering::Relaxed);
        true
    }
    fn set_enable(&mut self, _enabled: bool) -> bool {
        true
    }
}

/// Velocity-loop I/O over the synthetic sensors (fault input inactive).
#[derive(Debug, Default)]
pub struct SyntheticVelocityIo;

impl VelocityLoopIo for SyntheticVelocityIo {
    fn encoder_count(&mut self) -> u32 {
        ENCODER.load(Ordering::Relaxed)
    }
    fn fault_input(&mut self) -> bool {
        false
    }
}

/// A PMSM drive's current-loop I/O over the synthetic sensors.
#[derive(Debug, Default)]
pub struct SyntheticPmsmIo;

impl PmsmLoopIo for SyntheticPmsmIo {
    fn encoder_count(&mut self) -> u32 {
        ENCODER.load(Ordering::Relaxed)
    }
    fn phase_currents_pu(&mut self) -> Option<[Pu; 2]> {
        Some([
            Pu::from_bits(PHASE_A_BITS.load(Ordering::Relaxed)),
            Pu::from_bits(PHASE_B_BITS.load(Ordering::Relaxed)),
        ])
    }
    fn set_duties(&mut self, duties: [u16; 3]) -> bool {
        let [a, b, c] = duties;
        DUTIES_AB.store(u32::from(a) | u32::from(b) << 16, Ordering::Relaxed);
        DUTY_C.store(u32::from(c), Ordering::Relaxed);
        true
    }
    fn set_enable(&mut self, _enabled: bool) -> bool {
        true
    }
    fn fault_input(&mut self) -> bool {
        false
    }
}
