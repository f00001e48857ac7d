//! Notch filter on the torque reference, against a resonance the loop cannot damp.
//!
//! The analog prototype has a zero pair and a pole pair at the same centre ω0:
//!
//!   H(s) = (s² + 2·ζz·ω0·s + ω0²) / (s² + 2·ζp·ω0·s + ω0²)
//!
//! - `width_hz` is the distance between the two −3 dB edges of a deep notch. In the
//!   prototype the edges Ω_lo < Ω0 < Ω_hi satisfy Ω_lo·Ω_hi = Ω0² and
//!   Ω_hi − Ω_lo = 2·ζp·Ω0;
//! - `depth_db` is the attenuation at the centre, |H(jω0)| = ζz/ζp, so
//!   ζz = ζp·10^(−depth/20);
//! - the DC and high-frequency gains are exactly 1.
//!
//! It is discretized by the bilinear transform, pre-warped at the centre and at the edges:
//! K = tan(π·f0/fs), and the digital edges f_lo, f_hi = f_lo + width are the pair with
//! tan(π·f_lo/fs)·tan(π·f_hi/fs) = K² (found by bisection at configuration time), so
//! ζp = (tan(π·f_hi/fs) − tan(π·f_lo/fs))/(2·K). The centre, its depth and the width then
//! land exactly where configured at the tick rate fs:
//!
//!   a0 = 1 + 2·ζp·K + K²
//!   b0 = (1 + 2·ζz·K + K²)/a0,  b1 = a1 = 2·(K² − 1)/a0,  b2 = (1 − 2·ζz·K + K²)/a0
//!   a2 = (1 − 2·ζp·K + K²)/a0
//!
//! Q-formats: signals Q16.16 ([`Pu`]); coefficients Q2.30 ([`Coef`]), with b0, b2 and a2
//! in [−1, 1] (every design has |b0|, |b2| ≤ 1, |a2| < 1 and |b1| < 2; [`Notch::quantize`]
//! refuses others); the accumulator is Q.46 in an `i64`, Direct Form I, with the truncated
//! bits fed back into the next sample (first-order error feedback), so a slow signal has no
//! dead band and no DC error.
//!
//! The sum b0·x0 + b2·x2 − a2·y2 + residual is below 3·2^61 + 2^30 and b1·(x1 − y1) below
//! 2^31·(2^32 − 1) in magnitude for any i32 signals, so each is exact in an `i64` and only
//! their sum saturates (one saturating add per sample: what fits the tick's budget).

use crate::error::ConfigError;
use crate::per_unit::{Coef, Pu, checked_q, sat_shr};

/// The settings of a notch (configuration, not state): defined with the drive settings,
/// `[drive.notch]`.
pub use crate::config::NotchConfig;

/// Largest depth accepted \[dB\] (a gain of 1e-4 at the centre).
pub const MAX_DEPTH_DB: f32 = 80.0;

/// The f64 coefficients of a notch: its design before quantization (for references and
/// logging), or a quantized notch's linear form ([`Notch::linear`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NotchDesign {
    /// b0.
    pub b0: f64,
    /// b1 (= a1).
    pub b1: f64,
    /// b2.
    pub b2: f64,
    /// a2.
    pub a2: f64,
}

impl NotchDesign {
    /// Design for a tick rate `rate_hz`. Errors name `param` (e.g. `"notch"`) with the
    /// field: `notch.centre_hz`, `notch.width_hz`, `notch.depth_db`.
    pub fn new(cfg: &NotchConfig, rate_hz: f32, param: NotchParams) -> Result<Self, ConfigError> {
        let nyquist = rate_hz / 2.0;
        let f0 = cfg.centre_hz;
        in_range(f0, 0.0, nyquist, true, param.centre_hz)?;
        if f0 >= nyquist {
            return Err(ConfigError::AboveNyquist {
                param: param.centre_hz,
                value: f0,
                nyquist,
            });
        }
        in_range(cfg.width_hz, 0.0, f0, true, param.width_hz)?;
        in_range(cfg.depth_db, 0.0, MAX_DEPTH_DB, false, param.depth_db)?;
        let warp = |f: f64| crate::cfgmath::tan(core::f64::consts::PI * f / f64::from(rate_hz));
        let (f0, w) = (f64::from(f0), f64::from(cfg.width_hz));
        let k = warp(f0);
        // g(f_lo) = tan·tan − K² rises from −K² at 0 to > 0 at min(f0, fs/2 − w), where
        // w ≤ f0 < fs/2 keeps both ends inside (0, fs/2).
        let (mut lo, mut hi) = (0.0, f0.min(f64::from(nyquist) - w));
        let mut i = 0;
        while i < 60 {
            let mid = 0.5 * (lo + hi);
            if warp(mid) * warp(mid + w) < k * k {
                lo = mid;
            } else {
                hi = mid;
            }
            i += 1;
        }
        let f_lo = 0.5 * (lo + hi);
        let zeta_p = (warp(f_lo + w) - warp(f_lo)) / (2.0 * k);
        let zeta_z = zeta_p * crate::cfgmath::exp(-f64::from(cfg.depth_db) / 20.0 * LN_10);
        let k2 = k * k;
        let a0 = 1.0 + 2.0 * zeta_p * k + k2;
        Ok(Self {
            b0: (1.0 + 2.0 * zeta_z * k + k2) / a0,
            b1: 2.0 * (k2 - 1.0) / a0,
            b2: (1.0 - 2.0 * zeta_z * k + k2) / a0,
            a2: (1.0 - 2.0 * zeta_p * k + k2) / a0,
        })
    }

    /// The f64 reference of one step, Direct Form I: `x` = [x0, x1, x2], `y` = [y1, y2].
    #[must_use]
    pub fn reference_step(&self, x: [f64; 3], y: [f64; 2]) -> f64 {
        // y0 = b0·x0 + b1·x1 + b2·x2 − a1·y1 − a2·y2, a1 = b1.
        self.b0 * x[0] + self.b1 * x[1] + self.b2 * x[2] - self.b1 * y[0] - self.a2 * y[1]
    }

    /// One step of the minimal realization, the transposed direct form II, with input `x`
    /// and state `s` = \[s1, s2\]: the transfer function [`Notch::process`] runs in Direct
    /// Form I (four delayed signals), in two states, so a loop model gains only the notch's
    /// own pole pair. Same input, same output as [`NotchDesign::reference_step`] (up to the
    /// f64 roundings); no output clamp, no error feedback.
    ///
    /// ```text
    /// y   = b0·x + s1
    /// s1⁺ = b1·x − a1·y + s2        (a1 = b1)
    /// s2⁺ = b2·x − a2·y
    /// ```
    #[must_use]
    pub fn transposed_step(&self, s: &mut [f64; 2], x: f64) -> f64 {
        let y = self.b0 * x + s[0];
        *s = [self.b1 * x - self.b1 * y + s[1], self.b2 * x - self.a2 * y];
        y
    }

    /// |H(e^{jωT})| at `freq_hz` for a tick rate `rate_hz`.
    #[must_use]
    pub fn gain_at(&self, freq_hz: f64, rate_hz: f64) -> f64 {
        let w = core::f64::consts::TAU * freq_hz / rate_hz;
        // |b0 + b1·z⁻¹ + b2·z⁻²| / |1 + a1·z⁻¹ + a2·z⁻²| on the unit circle.
        let mag = |c0: f64, c1: f64, c2: f64| {
            let (s1, c1w) = crate::cfgmath::sin_cos(w);
            let (s2, c2w) = crate::cfgmath::sin_cos(2.0 * w);
            let re = c0 + c1 * c1w + c2 * c2w;
            let im = -(c1 * s1 + c2 * s2);
            crate::cfgmath::sqrt(re * re + im * im)
        };
        mag(self.b0, self.b1, self.b2) / mag(1.0, self.b1, self.a2)
    }
}

/// ln 10.
const LN_10: f64 = core::f64::consts::LN_10;

/// The bits of the accumulator below the output's LSB (Q.46 → Q16.16 drops 30).
const RESIDUAL_MASK: i64 = (1 << 30) - 1;

/// The field paths a notch's errors name.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NotchParams {
    /// Path of `centre_hz`.
    pub centre_hz: &'static str,
    /// Path of `width_hz`.
    pub width_hz: &'static str,
    /// Path of `depth_db`.
    pub depth_db: &'static str,
}

fn in_range(
    value: f32,
    min: f32,
    max: f32,
    min_exclusive: bool,
    param: &'static str,
) -> Result<(), ConfigError> {
    if !value.is_finite() {
        return Err(ConfigError::NotFinite { param });
    }
    let low = if min_exclusive {
        value <= min
    } else {
        value < min
    };
    if low || value > max {
        return Err(ConfigError::OutOfRange {
            param,
            value,
            min,
            max,
            min_exclusive,
        });
    }
    Ok(())
}

/// A quantized notch: the coefficients, Q2.30.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Notch {
    b0: Coef,
    b1: Coef,
    b2: Coef,
    a2: Coef,
}

/// The notch's state (plain data, loggable, reset = default).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NotchState {
    /// x\[n−1\], x\[n−2\] (Q16.16 bits).
    pub x: [i32; 2],
    /// y\[n−1\], y\[n−2\] (Q16.16 bits).
    pub y: [i32; 2],
    /// Truncated bits of the last output, below its LSB (Q.46, in [0, 2^30)).
    pub residual: i64,
}

impl Notch {
    /// Quantize a design to Q2.30; b0, b2 and a2 must lie in [−1, 1] (module docs). `param`
    /// names the coefficient set in an error.
    pub fn quantize(d: &NotchDesign, param: &'static str) -> Result<Self, ConfigError> {
        let q = |v: f64| {
            checked_q::<Coef>(v as f32).ok_or(ConfigError::overflow::<Coef>(param, v as f32))
        };
        let unit = |v: f64| {
            let c = q(v)?;
            if c.unsigned_abs() <= Coef::ONE.unsigned_abs() {
                Ok(c)
            } else {
                Err(ConfigError::OutOfRange {
                    param,
                    value: v as f32,
                    min: -1.0,
                    max: 1.0,
                    min_exclusive: false,
                })
            }
        };
        Ok(Self {
            b0: unit(d.b0)?,
            b1: q(d.b1)?,
            b2: unit(d.b2)?,
            a2: unit(d.a2)?,
        })
    }

    /// The linear form: the Q2.30 coefficients [`Notch::process`] uses, as f64, exactly the
    /// stored values (for loop models: [`NotchDesign::transposed_step`]).
    ///
    /// ```
    /// use controller_core::notch::{Notch, NotchDesign};
    /// let d = NotchDesign { b0: 0.5, b1: -1.5, b2: 0.25, a2: 0.75 };
    /// assert_eq!(Notch::quantize(&d, "notch")?.linear(), d);
    /// # Ok::<(), controller_core::ConfigError>(())
    /// ```
    #[must_use]
    pub fn linear(&self) -> NotchDesign {
        let f = |c: Coef| c.to_num::<f64>();
        NotchDesign {
            b0: f(self.b0),
            b1: f(self.b1),
            b2: f(self.b2),
            a2: f(self.a2),
        }
    }

    /// Filter one sample of the torque reference.
    ///
    /// ```
    /// use controller_core::notch::{Notch, NotchConfig, NotchDesign, NotchParams, NotchState};
    /// use controller_core::Pu;
    /// let names = NotchParams { centre_hz: "c", width_hz: "w", depth_db: "d" };
    /// let cfg = NotchConfig { centre_hz: 200.0, width_hz: 60.0, depth_db: 20.0 };
    /// let n = Notch::quantize(&NotchDesign::new(&cfg, 4000.0, names)?, "notch")?;
    /// let mut s = NotchState::default();
    /// let mut y = Pu::ZERO;
    /// for _ in 0..4000 {
    ///     y = n.process(&mut s, Pu::from_num(0.5)); // DC passes with gain 1
    /// }
    /// assert_eq!(y, Pu::from_num(0.5));
    /// # Ok::<(), controller_core::ConfigError>(())
    /// ```
    #[inline]
    pub fn process(&self, s: &mut NotchState, x: Pu) -> Pu {
        // acc = b0·x0 + b1·(x1 − y1) + b2·x2 − a2·y2 + residual, Q.46 (a1 = b1).
        // With |b0|, |b2|, |a2| ≤ 2^30 (quantize) and the residual masked to its 30 bits,
        // `p` is below 3·2^61 + 2^30 and `q` below 2^63 in magnitude for any i32 signals
        // (module docs): both exact; their sum saturates, so a hand-made state or a
        // saturated input gives a clamped output, never a wrap.
        let x0 = x.to_bits();
        let [x1, x2] = s.x;
        let [y1, y2] = s.y;
        let c = |k: Coef, v: i32| i64::from(k.to_bits()) * i64::from(v);
        let p = c(self.b0, x0) + c(self.b2, x2) - c(self.a2, y2) + (s.residual & RESIDUAL_MASK);
        let q = i64::from(self.b1.to_bits()) * (i64::from(x1) - i64::from(y1));
        let acc = p.saturating_add(q);
        let y0 = sat_shr::<30>(acc);
        // The residual is the part the output dropped; after a saturation it is zero, so the
        // clamp does not wind up.
        s.residual = if i64::from(y0) == acc >> 30 {
            acc & RESIDUAL_MASK
        } else {
            0
        };
        s.x = [x0, x1];
        s.y = [y0, y1];
        Pu::from_bits(y0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A coefficient that must lie in [−1, 1] and does not is refused with that range and
    /// the coefficient set's name; b1 (= a1) may lie outside it.
    #[test]
    #[allow(clippy::panic)]
    fn quantize_refuses_a_unit_coefficient_outside_its_range_with_the_range() {
        let ok = NotchDesign {
            b0: 0.9,
            b1: -1.8,
            b2: 0.9,
            a2: 0.8,
        };
        assert!(Notch::quantize(&ok, "notch coefficients").is_ok());
        for bad in [
            NotchDesign { b0: 1.5, ..ok },
            NotchDesign { b2: -1.25, ..ok },
            NotchDesign { a2: 1.01, ..ok },
        ] {
            match Notch::quantize(&bad, "notch coefficients") {
                Err(ConfigError::OutOfRange {
                    param,
                    min,
                    max,
                    min_exclusive,
                    ..
                }) => {
                    assert_eq!(param, "notch coefficients");
                    assert_eq!((min, max, min_exclusive), (-1.0, 1.0, false));
                }
                other => panic!("{bad:?}: {other:?}"),
            }
        }
    }

    const RATE: f32 = 4000.0;
    const NAMES: NotchParams = NotchParams {
        centre_hz: "notch.centre_hz",
        width_hz: "notch.width_hz",
        depth_db: "notch.depth_db",
    };

    fn design(f0: f32, w: f32, d: f32) -> NotchDesign {
        let cfg = NotchConfig {
            centre_hz: f0,
            width_hz: w,
            depth_db: d,
        };
        match NotchDesign::new(&cfg, RATE, NAMES) {
            Ok(d) => d,
            Err(e) => unreachable!("{e}"),
        }
    }

    fn quantized(d: &NotchDesign) -> Notch {
        Notch::quantize(d, "notch").unwrap_or_else(|e| unreachable!("{e}"))
    }

    /// Steady-state amplitude of the fixed-point notch for a sine at `f` Hz and amplitude
    /// `a` pu, over whole periods after a settling time.
    fn measured_gain(n: &Notch, f: f64, a: f64) -> f64 {
        let mut s = NotchState::default();
        let settle = 8000;
        let len = 8000;
        let (mut ss, mut sc) = (0.0, 0.0);
        for k in 0..settle + len {
            let ph = core::f64::consts::TAU * f * f64::from(k) / f64::from(RATE);
            let y = n
                .process(&mut s, Pu::from_num(a * ph.sin()))
                .to_num::<f64>();
            if k >= settle {
                ss += y * ph.sin();
                sc += y * ph.cos();
            }
        }
        2.0 * (ss * ss + sc * sc).sqrt() / f64::from(len) / a
    }

    /// The design's own frequency response: the depth exactly at the centre, unit gain at
    /// DC and Nyquist, and −3 dB edges exactly `width_hz` apart, also close to Nyquist.
    #[test]
    fn design_has_the_configured_centre_depth_and_width() {
        for (f0, w, d) in [
            (200.0, 60.0, 20.0),
            (50.0, 10.0, 40.0),
            (1200.0, 300.0, 30.0),
        ] {
            let n = design(f0, w, d);
            let centre = n.gain_at(f64::from(f0), f64::from(RATE));
            let want = 10f64.powf(-f64::from(d) / 20.0);
            assert!(
                (centre / want - 1.0).abs() < 1e-9,
                "{f0}: {centre} vs {want}"
            );
            assert!((n.gain_at(0.0, f64::from(RATE)) - 1.0).abs() < 1e-12);
            assert!((n.gain_at(f64::from(RATE) / 2.0, f64::from(RATE)) - 1.0).abs() < 1e-9);
            // The −3 dB edges (|H|² = (1 + g0²)/2 for depth g0) are `w` apart.
            let target = ((1.0 + want * want) / 2.0).sqrt();
            // From the centre `a` outwards to `b`, the gain rises through the target once.
            let edge = |mut a: f64, mut b: f64| {
                for _ in 0..60 {
                    let m = 0.5 * (a + b);
                    if n.gain_at(m, f64::from(RATE)) < target {
                        a = m;
                    } else {
                        b = m;
                    }
                }
                0.5 * (a + b)
            };
            let lo = edge(f64::from(f0), 1e-6);
            let hi = edge(f64::from(f0), f64::from(RATE) / 2.0);
            let width = hi - lo;
            assert!(
                (width / f64::from(w) - 1.0).abs() < 1e-6,
                "{f0}: width {width}"
            );
        }
    }

    /// Fixed point against the f64 reference, sample by sample, on a multi-tone signal.
    #[test]
    fn fixed_point_follows_the_f64_reference() {
        let d = design(180.0, 50.0, 30.0);
        let n = quantized(&d);
        let mut s = NotchState::default();
        let (mut x, mut y) = ([0.0f64; 3], [0.0f64; 2]);
        let mut worst: f64 = 0.0;
        for k in 0..20_000 {
            let t = f64::from(k) / f64::from(RATE);
            let v = 0.8 * (core::f64::consts::TAU * 180.0 * t).sin()
                + 0.3 * (core::f64::consts::TAU * 17.0 * t).sin()
                + 0.1;
            let xq = Pu::from_num(v);
            x = [xq.to_num(), x[0], x[1]];
            let yr = d.reference_step(x, y);
            y = [yr, y[0]];
            let yf = n.process(&mut s, xq).to_num::<f64>();
            worst = worst.max((yf - yr).abs());
        }
        // Coefficients quantized to 2^-30 and one output LSB (1.5e-5) of rounding, shaped
        // by the error feedback: the difference stays within a few LSB.
        assert!(worst < 8e-5, "worst difference {worst}");
    }

    /// The fixed-point notch's measured sine response against the design's, at 6 frequencies.
    #[test]
    fn measured_response_matches_the_transfer_function() {
        let d = design(200.0, 60.0, 20.0);
        let n = quantized(&d);
        for f in [5.0, 100.0, 170.0, 200.0, 240.0, 900.0] {
            let want = d.gain_at(f, f64::from(RATE));
            let got = measured_gain(&n, f, 0.5);
            assert!((got - want).abs() < 2e-3, "{f} Hz: {got} vs {want}");
        }
    }

    #[test]
    fn saturated_input_clamps_without_wrap() {
        let d = design(200.0, 60.0, 20.0);
        let n = quantized(&d);
        let mut s = NotchState::default();
        for k in 0..1000 {
            let x = if k % 2 == 0 { Pu::MAX } else { Pu::MIN };
            let _ = n.process(&mut s, x);
            assert!(s.residual >= 0 && s.residual < 1 << 30);
        }
        // Back to a quiet input: the output returns to it.
        let mut y = Pu::ZERO;
        for _ in 0..4000 {
            y = n.process(&mut s, Pu::ZERO);
        }
        assert!(y.abs() < Pu::from_num(0.001), "{y}");
    }

    /// The bound behind the one saturating add: at every extreme of the coefficients quantize
    /// accepts and of the signals and the state, the step does not overflow (tests run with
    /// overflow checks) and the residual stays in its 30 bits.
    #[test]
    fn extreme_coefficients_and_states_do_not_overflow() {
        let one = 1.0;
        // The largest b1 below 2 an f32 holds (quantize goes through f32).
        let b1_max = 2.0 - f64::from(f32::EPSILON);
        let signals = [i32::MIN, -1, 0, 1, i32::MAX];
        for (b0, b1, b2, a2) in [
            (one, -2.0, one, -one),
            (-one, b1_max, -one, one),
            (one, b1_max, -one, -one),
            (-one, -2.0, one, one),
        ] {
            let d = NotchDesign { b0, b1, b2, a2 };
            let n = quantized(&d);
            for &x1 in &signals {
                for &y1 in &signals {
                    for &z in &signals {
                        let mut s = NotchState {
                            x: [x1, z],
                            y: [y1, z.saturating_neg()],
                            residual: i64::MAX,
                        };
                        let _ = n.process(&mut s, Pu::from_bits(z));
                        assert!((0..1 << 30).contains(&s.residual));
                    }
                }
            }
        }
        // A design outside [−1, 1] in b0, b2 or a2 is refused naming the set.
        for d in [
            NotchDesign {
                b0: 1.5,
                b1: 0.0,
                b2: 0.0,
                a2: 0.0,
            },
            NotchDesign {
                b0: 0.5,
                b1: 0.0,
                b2: -1.01,
                a2: 0.0,
            },
            NotchDesign {
                b0: 0.5,
                b1: 0.0,
                b2: 0.0,
                a2: 1.2,
            },
        ] {
            match Notch::quantize(&d, "notch coefficients") {
                Err(e) => assert_eq!(e.param(), "notch coefficients"),
                Ok(_) => unreachable!("{d:?} accepted"),
            }
        }
    }

    #[test]
    fn bad_settings_name_their_key() {
        let cfg = |c: f32, w: f32, d: f32| NotchConfig {
            centre_hz: c,
            width_hz: w,
            depth_db: d,
        };
        let cases = [
            (cfg(2000.0, 10.0, 20.0), "notch.centre_hz"),
            (cfg(0.0, 10.0, 20.0), "notch.centre_hz"),
            (cfg(f32::NAN, 10.0, 20.0), "notch.centre_hz"),
            (cfg(100.0, 0.0, 20.0), "notch.width_hz"),
            (cfg(100.0, 101.0, 20.0), "notch.width_hz"),
            (cfg(100.0, 20.0, -1.0), "notch.depth_db"),
            (cfg(100.0, 20.0, 81.0), "notch.depth_db"),
        ];
        for (c, key) in cases {
            match NotchDesign::new(&c, RATE, NAMES) {
                Err(e) => assert_eq!(e.param(), key, "{c:?}"),
                Ok(_) => unreachable!("{c:?} accepted"),
            }
        }
    }

    /// The linear form, stepped from the notch's own state (Direct Form I,
    /// [`NotchDesign::reference_step`]), is the fixed-point step to 1 LSB (the output
    /// truncated, the last one's residual fed back); and its two-state realization
    /// ([`NotchDesign::transposed_step`]) is that Direct Form I in f64 on a whole sequence.
    #[test]
    fn the_linear_step_is_the_fixed_point_step() {
        const LSB: f64 = 1.0 / 65536.0;
        for (f0, w, d) in [
            (180.0, 50.0, 30.0),
            (40.0, 15.0, 20.0),
            (1500.0, 400.0, 60.0),
        ] {
            let n = quantized(&design(f0, w, d));
            let lin = n.linear();
            let mut s = NotchState::default();
            let (mut tdf2, mut x, mut y) = ([0.0f64; 2], [0.0f64; 3], [0.0f64; 2]);
            let mut seed = 0x2545_F491_4F6C_DD1Du64;
            for _ in 0..20_000 {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                let xq = Pu::from_bits((seed as i32) >> 14);
                let f = |v: i32| f64::from(v) * LSB;
                let want = lin.reference_step([xq.to_num(), f(s.x[0]), f(s.x[1])], s.y.map(f));
                let got = n.process(&mut s, xq).to_num::<f64>();
                assert!((got - want).abs() <= LSB + 1e-12, "{f0}: {got} vs {want}");
                x = [xq.to_num(), x[0], x[1]];
                let df1 = lin.reference_step(x, y);
                y = [df1, y[0]];
                let t = lin.transposed_step(&mut tdf2, x[0]);
                assert!(
                    (t - df1).abs() <= 1e-9 * (1.0 + df1.abs()),
                    "{f0}: {t} vs {df1}"
                );
            }
        }
    }
}
