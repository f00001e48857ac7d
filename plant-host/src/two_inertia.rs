//! The plant of Fig. 3: two inertias coupled by a damped shaft through lost motion, with the
//! motor encoder(s) and current ADC around it, and optionally the motor winding in front.
//!
//! Without a winding ([`TwoInertiaPlant::torque_driven`]) the input is the motor torque.
//! With it ([`TwoInertiaPlant::voltage_driven`]) the input is the winding voltage (the PWM
//! average, held between calls): L·di/dt = v − R·i − ωm (back-EMF = speed in pu),
//! Tm = i (torque = current in pu). The harness applies each new command
//! `computational_delay_s` after its sampling instant ([`TwoInertiaPlant::advance_period`]
//! does it for callers that do not schedule events themselves).

use crate::config::{MechanicsDerived, PlantConfig};
use crate::error::PlantError;
use crate::load::{LoadTorque, for_each_load_piece};
use crate::model::{Contact, Model, Vec3, Vec5, Winding};
use crate::piecewise::{Piecewise, Split};
use crate::sensors::Sensors;

/// Two inertias, lost motion, sensors, and the winding when the electrics are modelled, in
/// per unit. Starts at rest with zero twist and zero current.
///
/// ```
/// use plant_host::{PlantConfig, TwoInertiaPlant};
/// # let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/machines/table1.toml");
/// let cfg = PlantConfig::from_machine_file(path.as_ref()).unwrap();
/// let mut plant = TwoInertiaPlant::torque_driven(&cfg);
/// // 1 pu torque for 10 ms: the motor crosses the half-gap alone, then drags the load.
/// for _ in 0..40 {
///     plant.advance(250e-6, 1.0, 0.0);
/// }
/// assert!(plant.motor_pos_rad() > plant.load_pos_rad());
/// assert!(plant.shaft_torque_pu() > 0.0);
///
/// // Volts into the winding: the current rises with L/R while the back-EMF pushes back.
/// let mut drive = TwoInertiaPlant::voltage_driven(&cfg);
/// drive.advance(10e-3, 0.05, 0.0);
/// assert!(drive.current_pu() > 0.1 && drive.current_pu() < 1.0);
/// assert!((drive.current_sample() - drive.current_pu()).abs() < 1e-3);
/// ```
#[derive(Debug, Clone)]
pub struct TwoInertiaPlant {
    core: Piecewise,
    sensors: Sensors,
    config: PlantConfig,
    winding: Option<Winding>,
    derived: MechanicsDerived,
    time_s: f64,
    /// The input [`TwoInertiaPlant::advance_period`] is applying now, pu.
    applied_input_pu: f64,
}

impl TwoInertiaPlant {
    /// The mechanics alone: the input is the motor torque (pu); the current stays 0.
    pub fn torque_driven(config: &PlantConfig) -> Self {
        Self::new(config, None)
    }

    /// The winding in front of the mechanics (`[electrics]`): the input is the winding
    /// voltage (pu).
    pub fn voltage_driven(config: &PlantConfig) -> Self {
        Self::new(config, Some(Winding::from(&config.electrics)))
    }

    /// A plant at rest with `winding` (voltage in) or without (torque in).
    pub fn new(config: &PlantConfig, winding: Option<Winding>) -> Self {
        let model = Model::new(&config.mechanics, config.backlash(), winding);
        Self {
            core: Piecewise::new(&model),
            sensors: Sensors::new(config),
            config: *config,
            winding,
            derived: config.mechanics.derived(),
            time_s: 0.0,
            applied_input_pu: 0.0,
        }
    }

    /// The same plant with its load locked (a locked-rotor test): the load speed stays at
    /// zero, the motor turns only as far as the lost motion and the shaft's twist let it.
    /// Starts at rest, like [`Self::new`].
    #[must_use]
    pub fn with_locked_load(self) -> Self {
        let mut model = Model::new(&self.config.mechanics, self.config.backlash(), self.winding);
        model.load_locked = true;
        Self {
            // The sensors are a function of the state and the time: nothing to restart.
            core: Piecewise::new(&model),
            time_s: 0.0,
            applied_input_pu: 0.0,
            ..self
        }
    }

    /// Advances `dt_s` seconds with the input (torque or voltage, pu) and the load torque
    /// held. Invalid input (negative or non-finite `dt_s`, non-finite values) leaves the
    /// plant unchanged; use [`Self::try_advance`] to see the error.
    pub fn advance(&mut self, dt_s: f64, input_pu: f64, load_torque_pu: f64) {
        // The error is the caller's contract violation; the plant stays as it was.
        let _ = self.try_advance(dt_s, input_pu, load_torque_pu);
    }

    /// As [`Self::advance`], reporting invalid input.
    pub fn try_advance(
        &mut self,
        dt_s: f64,
        input_pu: f64,
        load_torque_pu: f64,
    ) -> Result<(), PlantError> {
        check_step(dt_s, &[input_pu, load_torque_pu])?;
        self.core
            .advance(dt_s, &Vec3::new(input_pu, load_torque_pu, 1.0));
        self.time_s += dt_s;
        Ok(())
    }

    /// A step length checked and prepared once, for a caller that repeats it every period
    /// (a harness's computational delay and the rest of its tick): [`Self::advance_fixed`]
    /// then steps it as [`Self::try_advance`] would, to the bit, without looking up its
    /// exact maps. An invalid length (negative, not finite) is the error `try_advance`
    /// reports.
    ///
    /// ```
    /// use plant_host::{PlantConfig, TwoInertiaPlant};
    /// # let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/machines/table1.toml");
    /// let cfg = PlantConfig::from_machine_file(path.as_ref()).unwrap();
    /// let (mut a, mut b) = (TwoInertiaPlant::voltage_driven(&cfg), TwoInertiaPlant::voltage_driven(&cfg));
    /// let step = a.fixed_step(180e-6).unwrap();
    /// for k in 0..100 {
    ///     let v = 0.01 * f64::from(k);
    ///     a.advance_fixed(&step, v, 0.1).unwrap();
    ///     b.try_advance(180e-6, v, 0.1).unwrap();
    /// }
    /// assert_eq!(a.motor_pos_rad().to_bits(), b.motor_pos_rad().to_bits());
    /// assert!(a.fixed_step(-1.0).is_err() && a.advance_fixed(&step, f64::NAN, 0.0).is_err());
    /// ```
    pub fn fixed_step(&mut self, dt_s: f64) -> Result<FixedStep, PlantError> {
        check_step(dt_s, &[])?;
        Ok(FixedStep {
            dt_s,
            split: self.core.split(dt_s),
        })
    }

    /// [`Self::try_advance`] by a step from [`Self::fixed_step`] of this plant.
    #[inline(always)]
    pub fn advance_fixed(
        &mut self,
        step: &FixedStep,
        input_pu: f64,
        load_torque_pu: f64,
    ) -> Result<(), PlantError> {
        check_step(step.dt_s, &[input_pu, load_torque_pu])?;
        self.core
            .advance_split(&step.split, &Vec3::new(input_pu, load_torque_pu, 1.0));
        self.time_s += step.dt_s;
        Ok(())
    }

    /// Advances `dt_s` with `input_pu` held and the load torque following `load` (time
    /// from [`Self::time_s`]): steps end at the load's discontinuities and a sinusoid is
    /// held at midpoints of ≤ 50 µs pieces.
    pub fn advance_with_load(
        &mut self,
        dt_s: f64,
        input_pu: f64,
        load: &LoadTorque,
    ) -> Result<(), PlantError> {
        check_step(dt_s, &[input_pu])?;
        let mut result = Ok(());
        for_each_load_piece(self.time_s, dt_s, load, |h, tl| {
            if result.is_ok() {
                result = self.try_advance(h, input_pu, tl);
            }
        });
        result
    }

    /// One sampling period with the computational delay: the input applied so far holds
    /// for `electrics.computational_delay_s` (clamped to the period), then `new_input_pu`
    /// (computed from samples taken at the start of the period) holds for the rest and
    /// stays applied.
    ///
    /// ```
    /// use plant_host::{PlantConfig, TwoInertiaPlant};
    /// # let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/machines/table1.toml");
    /// let cfg = PlantConfig::from_machine_file(path.as_ref()).unwrap();
    /// let (mut a, mut b) = (TwoInertiaPlant::voltage_driven(&cfg), TwoInertiaPlant::voltage_driven(&cfg));
    /// let delay = cfg.electrics.computational_delay_s;
    /// a.advance_period(250e-6, 0.3, 0.0).unwrap();
    /// b.advance(delay, 0.0, 0.0);
    /// b.advance(250e-6 - delay, 0.3, 0.0);
    /// assert_eq!(a.current_pu(), b.current_pu());
    /// assert_eq!(a.applied_input_pu(), 0.3);
    /// ```
    pub fn advance_period(
        &mut self,
        period_s: f64,
        new_input_pu: f64,
        load_torque_pu: f64,
    ) -> Result<(), PlantError> {
        check_step(period_s, &[new_input_pu, load_torque_pu])?;
        let delay_s = self.config.electrics.computational_delay_s.min(period_s);
        self.try_advance(delay_s, self.applied_input_pu, load_torque_pu)?;
        self.try_advance(period_s - delay_s, new_input_pu, load_torque_pu)?;
        self.applied_input_pu = new_input_pu;
        Ok(())
    }

    /// The input [`Self::advance_period`] is currently applying, pu.
    pub fn applied_input_pu(&self) -> f64 {
        self.applied_input_pu
    }

    /// The config this plant was built from.
    pub fn config(&self) -> &PlantConfig {
        &self.config
    }
    /// The winding, when the input is a voltage.
    pub fn winding(&self) -> Option<&Winding> {
        self.winding.as_ref()
    }
    /// K, D, g, ω_b...
    pub fn derived(&self) -> &MechanicsDerived {
        &self.derived
    }
    /// Simulated time since construction, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }
    /// The configured computational delay (sample → new input applied), s.
    pub fn computational_delay_s(&self) -> f64 {
        self.config.electrics.computational_delay_s
    }
    /// The longest internal sub-step, s (steps are split so that ‖A‖·h ≤ 0.5 and
    /// h ≤ 250 µs).
    pub fn max_substep_s(&self) -> f64 {
        self.core.max_step_s()
    }

    /// Motor encoder: floor(θm·cpr/2π) (+ noise if configured). The harness wraps it to the
    /// controller's counter width.
    #[inline]
    pub fn encoder_count(&self) -> i64 {
        self.sensors.motor_count(self.motor_pos_rad(), self.time_s)
    }
    /// Load encoder count, if one is configured.
    pub fn load_encoder_count(&self) -> Option<i64> {
        self.sensors.load_count(self.load_pos_rad())
    }
    /// Winding current (= motor torque), pu, exact; 0 without a winding.
    pub fn current_pu(&self) -> f64 {
        self.core.state().a
    }
    /// Winding current as the ADC reports it (noise, quantization, clamping), pu.
    #[inline]
    pub fn current_sample(&self) -> f64 {
        self.sensors.current(self.current_pu(), self.time_s)
    }
    /// Sensor models (ADC LSB etc.).
    pub fn sensors(&self) -> &Sensors {
        &self.sensors
    }
    /// Motor angle θm, rad.
    pub fn motor_pos_rad(&self) -> f64 {
        self.core.motor_pos_rad()
    }
    /// Load angle θl reflected to the motor side, rad.
    pub fn load_pos_rad(&self) -> f64 {
        self.core.load_pos_rad()
    }
    /// Motor speed ωm, pu.
    pub fn motor_vel_pu(&self) -> f64 {
        self.core.motor_vel_pu()
    }
    /// Load speed ωl (motor side), pu.
    pub fn load_vel_pu(&self) -> f64 {
        self.core.load_vel_pu()
    }
    /// Twist δ = θm − θl, rad.
    pub fn twist_rad(&self) -> f64 {
        self.core.twist_rad()
    }
    /// Shaft torque Ts, pu.
    pub fn shaft_torque_pu(&self) -> f64 {
        self.core.shaft_torque_pu()
    }
    /// Which side of the lost motion the gears are on.
    pub fn contact(&self) -> Contact {
        self.core.contact()
    }
    /// Number of contact changes located so far (edge crossings).
    pub fn mode_changes(&self) -> u64 {
        self.core.mode_changes()
    }
    /// Steps redone to search for a crossing (suspected or real): a cost diagnostic.
    pub fn crossing_searches(&self) -> u64 {
        self.core.crossing_searches()
    }

    /// Puts the plant in a given state (positions rad, speeds pu, current pu; the current
    /// stays 0 without a winding); the contact follows.
    pub fn set_state(
        &mut self,
        motor_pos_rad: f64,
        load_pos_rad: f64,
        motor_vel_pu: f64,
        load_vel_pu: f64,
        current_pu: f64,
    ) {
        let current_pu = if self.winding.is_some() {
            current_pu
        } else {
            0.0
        };
        self.core.set_state(Vec5::new(
            motor_pos_rad - load_pos_rad,
            load_pos_rad,
            motor_vel_pu,
            load_vel_pu,
            current_pu,
        ));
    }
}

/// A step length checked and split once ([`TwoInertiaPlant::fixed_step`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedStep {
    dt_s: f64,
    split: Split,
}

impl FixedStep {
    /// The step's length, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }
}

/// A step must be finite and ≥ 0 and its inputs finite.
#[inline]
#[allow(clippy::eq_op)] // v − v on purpose: the finiteness test of every value in one sum.
fn check_step(dt_s: f64, inputs: &[f64]) -> Result<(), PlantError> {
    // The usual case in one test: v − v is +0 for a finite v and NaN otherwise.
    let finite = inputs.iter().fold(dt_s - dt_s, |acc, v| acc + (v - v)) == 0.0;
    if finite && dt_s >= 0.0 {
        return Ok(());
    }
    step_error(dt_s, inputs)
}

/// The error [`check_step`] reports.
#[cold]
fn step_error(dt_s: f64, inputs: &[f64]) -> Result<(), PlantError> {
    if !(dt_s.is_finite() && dt_s >= 0.0) {
        return Err(PlantError::BadStep { dt_s });
    }
    if let Some(bad) = inputs.iter().find(|v| !v.is_finite()) {
        return Err(PlantError::BadInput { value: *bad });
    }
    Ok(())
}
