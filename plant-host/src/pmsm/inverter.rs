//! The averaged three-phase inverter: the PWM period's mean of each half-bridge.
//!
//! Each leg's pole voltage (against the DC bus's negative rail) is duty·V_dc, less the dead
//! time's loss: during t_d per switching edge neither switch conducts, and the current's
//! freewheeling diode clamps the pole to the rail it flows from, so over a PWM period
//! the pole loses ΔV = V_dc·t_d·f_pwm·sign(i) (a phase current flowing out of the leg,
//! i > 0, lowers its voltage). The star point floats, so the motor's phase voltages are
//! the pole voltages less their mean: v_x = (d_x − mean d)·V_dc − (ΔV_x − mean ΔV). Duties
//! are clamped to [0, 1]: that is the DC-bus limit (the hexagon whose inscribed circle,
//! the linear range, has radius V_dc/√3).

use crate::error::PlantError;
use crate::pmsm::machine::clarke;

/// Largest dead time per PWM period, t_d·f_pwm (10 %: beyond that the averaged model of
/// the dead time is no longer a small correction).
pub const MAX_DEAD_TIME_FRACTION: f64 = 0.1;

/// The averaged inverter: the DC bus, the dead time and the PWM frequency.
///
/// ```
/// # use plant_host::Inverter;
/// let inv = Inverter::new(1.8, 0.0, 20e3).unwrap();
/// // Centred duties: no voltage; phase a high alone: 2/3 of the bus on a.
/// assert_eq!(inv.phase_voltages([0.5; 3], [0.0; 3]), [0.0; 3]);
/// let [va, vb, vc] = inv.phase_voltages([1.0, 0.0, 0.0], [0.0; 3]);
/// assert!((va - 1.2).abs() < 1e-12 && (vb + 0.6).abs() < 1e-12 && (vc + 0.6).abs() < 1e-12);
/// // The duties a voltage vector needs (min-max injection) give it back.
/// let v = [0.9, -0.5];
/// let [al, be] = inv.voltage_ab(inv.duties_for(v), [0.0; 3]);
/// assert!((al - v[0]).abs() < 1e-12 && (be - v[1]).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inverter {
    dc_bus_pu: f64,
    dead_time_s: f64,
    pwm_frequency_hz: f64,
    /// V_dc·t_d·f_pwm, pu.
    dead_time_loss_pu: f64,
}

impl Inverter {
    /// An inverter on a bus of `dc_bus_pu` with `dead_time_s` per edge, switching at
    /// `pwm_frequency_hz`. Refused: a bus that is not positive and finite, a negative or
    /// non-finite dead time, a PWM frequency that is not positive and finite, and
    /// t_d·f_pwm above [`MAX_DEAD_TIME_FRACTION`].
    pub fn new(
        dc_bus_pu: f64,
        dead_time_s: f64,
        pwm_frequency_hz: f64,
    ) -> Result<Self, PlantError> {
        let bad = |what: &str, value: f64| PlantError::BadInverter {
            message: format!("{what} = {value}"),
        };
        if !(dc_bus_pu.is_finite() && dc_bus_pu > 0.0) {
            return Err(bad(
                "electrics.dc_bus_pu must be positive and finite",
                dc_bus_pu,
            ));
        }
        if !(dead_time_s.is_finite() && dead_time_s >= 0.0) {
            return Err(bad(
                "electrics.dead_time_s must be finite and >= 0",
                dead_time_s,
            ));
        }
        if !(pwm_frequency_hz.is_finite() && pwm_frequency_hz > 0.0) {
            return Err(bad(
                "the PWM frequency (Hz) must be positive and finite",
                pwm_frequency_hz,
            ));
        }
        let fraction = dead_time_s * pwm_frequency_hz;
        if fraction > MAX_DEAD_TIME_FRACTION {
            return Err(PlantError::BadInverter {
                message: format!(
                    "electrics.dead_time_s = {dead_time_s} s at {pwm_frequency_hz} Hz PWM is \
                     {fraction:.3} of a period; at most {MAX_DEAD_TIME_FRACTION}"
                ),
            });
        }
        Ok(Self {
            dc_bus_pu,
            dead_time_s,
            pwm_frequency_hz,
            dead_time_loss_pu: dc_bus_pu * fraction,
        })
    }

    /// V_dc, pu.
    pub fn dc_bus_pu(&self) -> f64 {
        self.dc_bus_pu
    }
    /// t_d, s.
    pub fn dead_time_s(&self) -> f64 {
        self.dead_time_s
    }
    /// f_pwm, Hz.
    pub fn pwm_frequency_hz(&self) -> f64 {
        self.pwm_frequency_hz
    }
    /// ΔV = V_dc·t_d·f_pwm, the dead time's loss of one pole's mean voltage, pu.
    pub fn dead_time_loss_pu(&self) -> f64 {
        self.dead_time_loss_pu
    }
    /// The radius of the linear range (the hexagon's inscribed circle), V_dc/√3, pu.
    pub fn linear_limit_pu(&self) -> f64 {
        self.dc_bus_pu / 3.0_f64.sqrt()
    }

    /// The phase voltages (star point referred, summing to zero) of `duties` (clamped to
    /// [0, 1]; a NaN duty counts as 0) with the phase currents `currents_pu` (only their
    /// signs matter, for the dead time; 0 gives no loss), pu.
    pub fn phase_voltages(&self, duties: [f64; 3], currents_pu: [f64; 3]) -> [f64; 3] {
        let poles = duties.map(|d| if d > 0.0 { d.min(1.0) } else { 0.0 });
        let poles = std::array::from_fn::<f64, 3, _>(|k| {
            let duty = poles.get(k).copied().unwrap_or(0.0);
            let current = currents_pu.get(k).copied().unwrap_or(0.0);
            duty * self.dc_bus_pu - self.dead_time_loss_pu * sign(current)
        });
        let [a, b, c] = poles;
        let mean = (a + b + c) / 3.0;
        [a - mean, b - mean, c - mean]
    }

    /// The voltage vector (α, β) of [`Self::phase_voltages`], pu.
    pub fn voltage_ab(&self, duties: [f64; 3], currents_pu: [f64; 3]) -> [f64; 2] {
        clarke(self.phase_voltages(duties, currents_pu))
    }

    /// The duties that apply the voltage vector `[α, β]` (pu) without dead time:
    /// space-vector modulation by min-max (zero-sequence) injection around 1/2. A vector
    /// beyond the hexagon gets duties clamped to [0, 1].
    pub fn duties_for(&self, voltage_ab: [f64; 2]) -> [f64; 3] {
        let [a, b, c] = crate::pmsm::machine::inverse_clarke(voltage_ab);
        let zero = -0.5 * (a.max(b).max(c) + a.min(b).min(c));
        [a, b, c].map(|v| (0.5 + (v + zero) / self.dc_bus_pu).clamp(0.0, 1.0))
    }
}

/// sign(x): −1, 0 or +1.
pub(crate) fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn duties_are_clamped_to_the_bus_and_the_dead_time_is_refused_beyond_a_tenth() {
        let inv = Inverter::new(2.0, 0.0, 10e3).unwrap();
        assert_eq!(
            inv.phase_voltages([2.0, -1.0, 0.0], [0.0; 3]),
            inv.phase_voltages([1.0, 0.0, 0.0], [0.0; 3])
        );
        // The hexagon's inscribed circle: a vector of that length needs duties 0..1 exactly.
        let r = inv.linear_limit_pu();
        let d = inv.duties_for([0.0, r]);
        let (lo, hi) = (
            d.iter().copied().fold(1.0, f64::min),
            d.iter().copied().fold(0.0, f64::max),
        );
        assert!(lo.abs() < 1e-12 && (hi - 1.0).abs() < 1e-12, "{d:?}");
        assert!(Inverter::new(2.0, 11e-6, 10e3).is_err());
        assert!(Inverter::new(2.0, 10e-6, 10e3).is_ok());
        assert!(Inverter::new(0.0, 0.0, 10e3).is_err());
        assert!(Inverter::new(2.0, 0.0, f64::NAN).is_err());
    }
}
