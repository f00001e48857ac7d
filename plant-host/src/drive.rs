//! The motor as the current loop sees it: a per-unit winding driving the two-inertia plant,
//! with its encoder(s) and current ADC.
//!
//! L·di/dt = v − R·i − ωm (back-EMF = speed in pu), Tm = i (torque = current in pu).
//! The voltage is the PWM average, held (zero-order hold) between calls to [`DrivePlant::advance`];
//! the harness applies each new command `computational_delay_s` after its sampling instant.

use crate::config::{MechanicsDerived, PlantConfig};
use crate::error::PlantError;
use crate::load::{for_each_load_piece, LoadTorque};
use crate::model::{Contact, Vec3, Vec5};
use crate::piecewise::Piecewise;
use crate::sensors::Sensors;
use crate::two_inertia::check_step;

/// Winding + mechanics + sensors. Starts at rest, zero twist, zero current.
///
/// ```
/// use plant_host::{DrivePlant, PlantConfig};
/// let mut drive = DrivePlant::new(&PlantConfig::table1());
/// // 0.05 pu volts into R = 0.05 pu: the current rises with L/R = 10 ms while the
/// // motor's back-EMF (= its speed) pushes back.
/// drive.advance(10e-3, 0.05, 0.0);
/// assert!(drive.current_pu() > 0.1 && drive.current_pu() < 1.0);
/// assert!(drive.motor_vel_pu() > 0.0);
/// assert!((drive.current_sample() - drive.current_pu()).abs() < 1e-3);
/// ```
#[derive(Debug, Clone)]
pub struct DrivePlant {
    core: Piecewise,
    sensors: Sensors,
    config: PlantConfig,
    derived: MechanicsDerived,
    time_s: f64,
    /// The voltage the PWM is producing now (for [`DrivePlant::advance_period`]), pu.
    applied_voltage_pu: f64,
}

impl DrivePlant {
    /// A drive at rest.
    pub fn new(config: &PlantConfig) -> Self {
        let e = &config.electrics;
        let model = config.mechanics.model(config.backlash, Some(e.winding()));
        Self {
            core: Piecewise::new(&model),
            sensors: Sensors::new(&config.sensors, e),
            config: *config,
            derived: config.mechanics.derived(),
            time_s: 0.0,
            applied_voltage_pu: 0.0,
        }
    }

    /// One sampling period with the computational delay, for callers that do not schedule
    /// events themselves: the voltage applied so far holds for `computational_delay_s`
    /// (clamped to the period), then `new_voltage_pu` (computed from samples taken at the
    /// start of the period) holds for the rest and stays applied.
    ///
    /// ```
    /// use plant_host::{DrivePlant, PlantConfig};
    /// let cfg = PlantConfig::table1();
    /// let (mut a, mut b) = (DrivePlant::new(&cfg), DrivePlant::new(&cfg));
    /// a.advance_period(250e-6, 0.3, 0.0).unwrap();
    /// b.advance(180e-6, 0.0, 0.0);
    /// b.advance(70e-6, 0.3, 0.0);
    /// assert_eq!(a.current_pu(), b.current_pu());
    /// assert_eq!(a.applied_voltage_pu(), 0.3);
    /// ```
    pub fn advance_period(
        &mut self,
        period_s: f64,
        new_voltage_pu: f64,
        load_torque_pu: f64,
    ) -> Result<(), PlantError> {
        check_step(period_s, &[new_voltage_pu, load_torque_pu])?;
        let delay_s = self.config.electrics.computational_delay_s.min(period_s);
        self.try_advance(delay_s, self.applied_voltage_pu, load_torque_pu)?;
        self.try_advance(period_s - delay_s, new_voltage_pu, load_torque_pu)?;
        self.applied_voltage_pu = new_voltage_pu;
        Ok(())
    }

    /// The voltage [`Self::advance_period`] is currently applying, pu.
    pub fn applied_voltage_pu(&self) -> f64 {
        self.applied_voltage_pu
    }

    /// Advances `dt_s` seconds with the winding voltage and load torque held (pu). Invalid
    /// input leaves the plant unchanged; see [`Self::try_advance`].
    pub fn advance(&mut self, dt_s: f64, voltage_pu: f64, load_torque_pu: f64) {
        // The error is the caller's contract violation; the plant stays as it was.
        let _ = self.try_advance(dt_s, voltage_pu, load_torque_pu);
    }

    /// Advances `dt_s` with `voltage_pu` held and the load torque following `load` (time from
    /// [`Self::time_s`]): steps end at the load's discontinuities and a sinusoid is held at
    /// midpoints of ≤ 50 µs pieces.
    pub fn advance_with_load(
        &mut self,
        dt_s: f64,
        voltage_pu: f64,
        load: &LoadTorque,
    ) -> Result<(), PlantError> {
        check_step(dt_s, &[voltage_pu])?;
        let mut result = Ok(());
        for_each_load_piece(self.time_s, dt_s, load, |h, tl| {
            if result.is_ok() {
                result = self.try_advance(h, voltage_pu, tl);
            }
        });
        result
    }

    /// As [`Self::advance`], reporting invalid input.
    pub fn try_advance(
        &mut self,
        dt_s: f64,
        voltage_pu: f64,
        load_torque_pu: f64,
    ) -> Result<(), PlantError> {
        check_step(dt_s, &[voltage_pu, load_torque_pu])?;
        self.core
            .advance(dt_s, &Vec3::new(voltage_pu, load_torque_pu, 1.0));
        self.time_s += dt_s;
        Ok(())
    }

    /// The config this drive was built from.
    pub fn config(&self) -> &PlantConfig {
        &self.config
    }
    /// K, D, g, ω_b...
    pub fn derived(&self) -> &MechanicsDerived {
        &self.derived
    }
    /// Simulated time since construction, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }
    /// The configured computational delay (sample → new voltage applied), s.
    pub fn computational_delay_s(&self) -> f64 {
        self.config.electrics.computational_delay_s
    }

    /// Motor encoder: floor(θm·cpr/2π) (+ noise if configured). The harness wraps it to the
    /// controller's counter width.
    pub fn encoder_count(&self) -> i64 {
        self.sensors.motor_count(self.motor_pos_rad(), self.time_s)
    }
    /// Load encoder count, if one is configured.
    pub fn load_encoder_count(&self) -> Option<i64> {
        self.sensors.load_count(self.load_pos_rad())
    }
    /// Winding current (= motor torque), pu, exact.
    pub fn current_pu(&self) -> f64 {
        self.core.state().a
    }
    /// Winding current as the ADC reports it (noise, quantization, clamping), pu.
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
    /// Load speed ωl, pu.
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
    /// Number of contact changes located so far.
    pub fn mode_changes(&self) -> u64 {
        self.core.mode_changes()
    }

    /// Puts the drive in a given state (positions rad, speeds pu, current pu).
    pub fn set_state(
        &mut self,
        motor_pos_rad: f64,
        load_pos_rad: f64,
        motor_vel_pu: f64,
        load_vel_pu: f64,
        current_pu: f64,
    ) {
        self.core.set_state(Vec5::new(
            motor_pos_rad - load_pos_rad,
            load_pos_rad,
            motor_vel_pu,
            load_vel_pu,
            current_pu,
        ));
    }
}
