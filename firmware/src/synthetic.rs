//! Synthetic sensor inputs for the instruction benchmark: an encoder that tracks a motion
//! profile (so the drive follows without a following-error fault and every regulator runs
//! its full path) with a ±1 count dither, and a current with a ±4 LSB pseudo-random ripple
//! around a small torque. The generator advances between ticks, outside the measured code;
//! the I/O handles the ticks read are plain loads, as register reads would be.

use core::sync::atomic::{AtomicI32, AtomicU32, Ordering};

use controller_core::{Pu, Setpoint};

use crate::board::{CurrentLoopIo, VelocityLoopIo};

/// Latest synthetic encoder count.
static ENCODER: AtomicU32 = AtomicU32::new(0);
/// Latest synthetic current, Q16.16 bits.
static CURRENT_BITS: AtomicI32 = AtomicI32::new(0);
/// Last voltage command the current loop applied, Q16.16 bits.
static APPLIED_BITS: AtomicI32 = AtomicI32::new(0);

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

    /// Last voltage command the current loop applied [pu].
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
