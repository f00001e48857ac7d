//! Sensors: the motor (and optional load) encoder, the current ADC, and their optional noise.
//! Noise is a pure function of (seed, channel, sample time), so sampling needs no `&mut` and a
//! run is reproducible.

use crate::config::{ElectricsConfig, PlantConfig, SensorsConfig};
use crate::rounding::{floor_i64, round_i64};
use std::f64::consts::PI;

/// Encoder count of an angle: floor(θ·cpr/2π), saturating at the i64 range.
#[inline]
pub fn encoder_count(angle_rad: f64, cpr: u32) -> i64 {
    // Saturates for out-of-range floats and maps NaN to 0: no panic path.
    floor_i64(angle_rad * f64::from(cpr) / (2.0 * PI))
}

/// The current ADC: round to the nearest code over ±full scale, clamped to the code range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurrentAdc {
    lsb_pu: f64,
    min_code: i32,
    max_code: i32,
}

impl CurrentAdc {
    /// From the electrics config (bits, full scale).
    pub fn new(e: &ElectricsConfig) -> Self {
        let bits = e.current_adc_bits.clamp(2, 30);
        let half = 1_i32 << (bits - 1);
        Self {
            lsb_pu: 2.0 * e.current_full_scale_pu / f64::from(half) / 2.0,
            min_code: -half,
            max_code: half - 1,
        }
    }
    /// One code in pu.
    pub fn lsb_pu(&self) -> f64 {
        self.lsb_pu
    }
    /// The code for a current.
    #[inline]
    pub fn code(&self, current_pu: f64) -> i32 {
        let c = round_i64(current_pu / self.lsb_pu);
        // Inside the code range, so the narrowing cannot wrap. `max` then `min` is `clamp`
        // (min_code < max_code by construction) without its bounds check.
        c.max(i64::from(self.min_code))
            .min(i64::from(self.max_code)) as i32
    }
    /// The quantized current, pu.
    #[inline]
    pub fn sample(&self, current_pu: f64) -> f64 {
        f64::from(self.code(current_pu)) * self.lsb_pu
    }
}

/// Which noise stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Channel {
    MotorEncoder = 1,
    Current = 2,
    /// A PMSM's phase a current.
    PhaseA = 3,
    /// A PMSM's phase b current.
    PhaseB = 4,
}

/// Deterministic Gaussian noise N(0, 1) for (seed, channel, time).
#[inline(never)]
pub(crate) fn gaussian(seed: u64, channel: Channel, time_s: f64) -> f64 {
    // Sample index: time in ns (sampling instants are distinct to far better than 1 ns).
    let index = round_i64(time_s * 1e9) as u64;
    let mut s = seed ^ (channel as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.rotate_left(17);
    let u1 = unit(splitmix(&mut s));
    let u2 = unit(splitmix(&mut s));
    // Box–Muller; u1 in (0, 1] so ln is finite.
    (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
}

fn splitmix(s: &mut u64) -> u64 {
    *s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *s;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// (0, 1] from 53 random bits.
fn unit(z: u64) -> f64 {
    ((z >> 11) as f64 + 1.0) / (1_u64 << 53) as f64
}

/// Sensor models bound to a config.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensors {
    /// The sensor config.
    pub config: SensorsConfig,
    /// Motor encoder counts per revolution as the drive reads them (after interpolation).
    pub counts_per_rev: u32,
    /// The current ADC.
    pub adc: CurrentAdc,
}

impl Sensors {
    /// The sensors of a plant config.
    pub fn new(config: &PlantConfig) -> Self {
        Self::from_parts(config.counts_per_rev(), &config.sensors, &config.electrics)
    }

    /// From a motor encoder of `counts_per_rev` (as the drive reads it), the sensor and the
    /// electrics configs.
    pub fn from_parts(counts_per_rev: u32, s: &SensorsConfig, e: &ElectricsConfig) -> Self {
        Self {
            config: *s,
            counts_per_rev,
            adc: CurrentAdc::new(e),
        }
    }

    /// Motor encoder count at `time_s` as the drive reads it: with sin/cos interpolation
    /// the angle is resolved into `encoder_cpr × encoder_interpolation` counts per
    /// revolution and floored like a plain count (an ideal interpolator: no amplitude or
    /// phase error of the sin/cos tracks). Noise, if any, is in those counts and is added
    /// before the floor.
    #[inline]
    pub fn motor_count(&self, motor_pos_rad: f64, time_s: f64) -> i64 {
        let c = &self.config;
        let cpr = self.counts_per_rev;
        if c.encoder_noise_counts > 0.0 {
            let noise_rad = c.encoder_noise_counts
                * gaussian(c.noise_seed, Channel::MotorEncoder, time_s)
                * 2.0
                * PI
                / f64::from(cpr);
            encoder_count(motor_pos_rad + noise_rad, cpr)
        } else {
            encoder_count(motor_pos_rad, cpr)
        }
    }

    /// Load encoder count (physical load shaft = reflected angle / gear ratio), if fitted.
    pub fn load_count(&self, load_pos_rad: f64) -> Option<i64> {
        let c = &self.config;
        c.load_encoder()
            .map(|cpr| encoder_count(load_pos_rad / c.gear_ratio, cpr))
    }

    /// ADC-quantized current (with noise, if any) at `time_s`, pu.
    #[inline]
    pub fn current(&self, current_pu: f64, time_s: f64) -> f64 {
        let c = &self.config;
        let noisy = if c.current_noise_pu > 0.0 {
            current_pu + c.current_noise_pu * gaussian(c.noise_seed, Channel::Current, time_s)
        } else {
            current_pu
        };
        self.adc.sample(noisy)
    }

    /// A PMSM's two sampled phase currents, a and b, through the same ADC (each with its
    /// own noise stream, if any) at `time_s`, pu. The drive takes c = −a − b.
    #[inline]
    pub fn phase_currents(&self, [a, b]: [f64; 2], time_s: f64) -> [f64; 2] {
        let c = &self.config;
        let noise = |channel| {
            if c.current_noise_pu > 0.0 {
                c.current_noise_pu * gaussian(c.noise_seed, channel, time_s)
            } else {
                0.0
            }
        };
        [
            self.adc.sample(a + noise(Channel::PhaseA)),
            self.adc.sample(b + noise(Channel::PhaseB)),
        ]
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn counts_floor_towards_minus_infinity() {
        let one = 2.0 * PI / 2048.0;
        assert_eq!(encoder_count(0.0, 2048), 0);
        assert_eq!(encoder_count(0.999 * one, 2048), 0);
        assert_eq!(encoder_count(1.001 * one, 2048), 1);
        assert_eq!(encoder_count(-0.001 * one, 2048), -1);
        assert_eq!(encoder_count(2.0 * PI, 1_000_000), 1_000_000);
    }

    #[test]
    fn interpolation_multiplies_the_counts_and_keeps_the_floor() {
        let e = ElectricsConfig::with_delay(0.0);
        let sensors = Sensors::from_parts(1024 * 16, &SensorsConfig::default(), &e);
        let fine = 2.0 * PI / 16_384.0;
        // One plain count is 16 interpolated counts; a sixteenth of a count is resolved.
        assert_eq!(sensors.motor_count(2.0 * PI / 1024.0 + 0.5 * fine, 0.0), 16);
        assert_eq!(sensors.motor_count(1.001 * fine, 0.0), 1);
        assert_eq!(sensors.motor_count(0.999 * fine, 0.0), 0);
        assert_eq!(sensors.motor_count(-0.001 * fine, 0.0), -1);
        // Factor 1 is the plain encoder.
        let plain = Sensors::from_parts(1024, &SensorsConfig::default(), &e);
        assert_eq!(plain.motor_count(1.001 * fine, 0.0), 0);
        assert_eq!(plain.motor_count(2.0 * PI, 0.0), 1024);
    }

    #[test]
    fn adc_quantizes_and_clamps() {
        let adc = CurrentAdc::new(&ElectricsConfig::with_delay(0.0));
        assert!((adc.lsb_pu() - 8.0 / 4096.0).abs() < 1e-15);
        assert_eq!(adc.code(10.0), 2047);
        assert_eq!(adc.code(-10.0), -2048);
        let x = 0.123_456;
        assert!((adc.sample(x) - x).abs() <= 0.5 * adc.lsb_pu() + 1e-15);
    }

    #[test]
    fn noise_is_reproducible_and_unit_variance() {
        let n = 20_000;
        let v: Vec<f64> = (0..n)
            .map(|k| gaussian(7, Channel::Current, k as f64 * 250e-6))
            .collect();
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.03, "mean {mean}");
        assert!((var - 1.0).abs() < 0.05, "var {var}");
        assert_eq!(v[5], gaussian(7, Channel::Current, 5.0 * 250e-6));
        assert_ne!(v[5], gaussian(8, Channel::Current, 5.0 * 250e-6));
    }
}
