//! The permanent-magnet synchronous motor (PMSM) and its averaged inverter in front of the
//! two-inertia mechanics of Fig. 3 (`electrics.motor = "pmsm"`).
//!
//! - [`machine`]: the motor's constants and per-unit convention, Clarke and Park.
//! - [`inverter`]: three duties → phase voltages, with the DC-bus limit and dead time.
//! - `series`: the Taylor-series step of the coupled system in one contact mode.
//!
//! [`PmsmPlant`] integrates the d/q currents and the mechanics together, in one state: the
//! system is nonlinear (ωm·i, i_d·i_q, the rotating voltage), so the exact linear maps of
//! the DC plant do not apply. Each internal step sums the Taylor series of the solution
//! to round-off (see `series`), and, as the DC plant does, looks for a lost-motion edge
//! (or, with dead time, a phase current's zero crossing) inside the step: a rigorous
//! bound on each guard polynomial first, then 16 samples of the series and a bisection of
//! the crossing to 2^-60 of the step. The mode (or the dead time's sign) switches there.

mod inverter;
mod machine;
mod off;
mod series;

use crate::config::{BacklashModel, MechanicsDerived, PlantConfig};
use crate::error::PlantError;
use crate::model::{Contact, Model, row_sum_norm};
use crate::sensors::Sensors;
use inverter::sign;
pub use inverter::{Inverter, MAX_DEAD_TIME_FRACTION};
pub use machine::{PmsmParams, clarke, inverse_clarke, inverse_park, park};
use series::{Equations, Series, Vars};

/// Longest internal step, s (as the DC plant's).
const MAX_STEP_S: f64 = 250e-6;
/// Samples of a step's series when a guard may have crossed.
const SEARCH_SAMPLES: u32 = 16;
/// Bisections of a bracketed crossing (the bracket ends 2^-60 of a step wide).
const BISECTIONS: u32 = 60;
/// Mode or sign changes inside one call before the rest of it is stepped without guards
/// (a chattering contact, or a phase current the dead time holds at zero: each side's
/// loss drives it back across, which the averaged model does not resolve; past the cap
/// each step takes the signs at its start).
const MAX_CHANGES_PER_CALL: u32 = 32;
/// Halvings of a step whose series does not converge before it is taken as it is.
const MAX_HALVINGS: u32 = 40;

/// A PMSM behind an averaged inverter, driving the two-inertia mechanics with lost motion,
/// with its sensors: the motor encoder (the electrical offset is the plant's own, unseen)
/// and two phase currents through the current ADC. The input is the inverter's three
/// duties, held between calls like the DC plant's voltage. Starts at rest, zero current.
///
/// ```
/// use plant_host::{Inverter, PlantConfig, PmsmPlant};
/// # let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/machines/table1.toml");
/// # let mut text = std::fs::read_to_string(path).unwrap();
/// # text = text.replace("winding_inductance_pu_s = 5e-4", "motor = \"pmsm\"\npole_pairs = 4\n\
/// #     d_inductance_pu_s = 4e-4\nq_inductance_pu_s = 6e-4\ndc_bus_pu = 1.8\n\
/// #     encoder_offset_elec_deg = 30.0");
/// let cfg = PlantConfig::from_machine_toml(&text).unwrap();
/// let mut plant = PmsmPlant::new(&cfg, 4000.0).unwrap();
/// // 0.05 pu on the q axis of the rotor at rest (θe = 30°), held: the q current rises
/// // with Lq/R and the motor starts to turn forwards.
/// let v_ab = plant_host::inverse_park([0.0, 0.05], 30f64.to_radians());
/// let duties = plant.inverter().duties_for(v_ab);
/// for _ in 0..40 {
///     plant.advance(250e-6, duties, 0.0);
/// }
/// assert!(plant.i_q_pu() > 0.1);
/// assert!(plant.motor_vel_pu() > 0.0);
/// let [a, b] = plant.phase_current_samples();
/// let [ta, tb, _] = plant.phase_currents_pu();
/// assert!((a - ta).abs() < 2e-3 && (b - tb).abs() < 2e-3);
/// ```
#[derive(Debug, Clone)]
pub struct PmsmPlant {
    motor: PmsmParams,
    inverter: Inverter,
    model: Model,
    sensors: Sensors,
    config: PlantConfig,
    derived: MechanicsDerived,
    h_max_s: f64,
    x: Vars,
    contact: Contact,
    /// With dead time, the phase currents' signs the inverter applies now (else zeros).
    /// Carried, like the contact, and changed only where a crossing is located: the state
    /// a located crossing leaves is within round-off of zero current, and recomputing the
    /// angle's cosine and sine at the next step can put it back on the old side.
    signs: [i8; 3],
    time_s: f64,
    /// The duties [`PmsmPlant::advance_period`] is applying now.
    applied_duties: [f64; 3],
    /// The duties of the last step in the motor's phase order (what
    /// [`PmsmPlant::phase_voltages_pu`] reports).
    last_duties: [f64; 3],
    /// `electrics.encoder_reversed`: the drive's phases b and c are the motor's c and b.
    swapped: bool,
    events: u64,
    sign_changes: u64,
    searches: u64,
    /// The switches (open once the drive turns the inverter off: `off`).
    switches: off::Switches,
    /// The series of the step in progress, refilled by each step (scratch).
    series: Series,
}

impl PmsmPlant {
    /// The PMSM of `config` (`electrics.motor = "pmsm"`), its inverter switching at
    /// `pwm_frequency_hz` (it scales the dead time's loss), at rest with the duties at 1/2.
    pub fn new(config: &PlantConfig, pwm_frequency_hz: f64) -> Result<Self, PlantError> {
        config.validate()?;
        let motor = PmsmParams::from_config(config)?;
        let e = &config.electrics;
        let inverter = Inverter::new(
            e.dc_bus_pu.unwrap_or(0.0),
            e.dead_time_s.unwrap_or(0.0),
            pwm_frequency_hz,
        )?;
        let model = Model::new(&config.mechanics, config.backlash(), None);
        // The mechanics' fastest rate, and the electrics' (R + λ)/L row.
        let mechanics_rate = row_sum_norm(&model.matrices(Contact::Driving).0);
        let l_min = motor.ld_pu_s.min(motor.lq_pu_s);
        let electrics_rate = (motor.r_pu + motor.flux_linkage_pu) / l_min;
        let rate = mechanics_rate.max(electrics_rate).clamp(1e-9, 1e6);
        let mut plant = Self {
            motor,
            inverter,
            model,
            sensors: Sensors::new(config),
            config: *config,
            derived: config.mechanics.derived(),
            h_max_s: (0.5 / rate).min(MAX_STEP_S),
            x: Vars::default(),
            contact: Contact::Free,
            signs: [0; 3],
            time_s: 0.0,
            applied_duties: [0.5; 3],
            last_duties: [0.5; 3],
            swapped: e.encoder_reversed.unwrap_or(false),
            events: 0,
            sign_changes: 0,
            searches: 0,
            switches: off::Switches::default(),
            series: Series::default(),
        };
        plant.set_state(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        Ok(plant)
    }

    /// The same plant with its load locked (its speed stays zero), at rest.
    #[must_use]
    pub fn with_locked_load(mut self) -> Self {
        self.model.load_locked = true;
        self.time_s = 0.0;
        self.applied_duties = [0.5; 3];
        self.last_duties = [0.5; 3];
        self.set_state(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        self
    }

    /// Advances `dt_s` with the duties and the load torque held; invalid input leaves the
    /// plant unchanged (see [`Self::try_advance`]).
    pub fn advance(&mut self, dt_s: f64, duties: [f64; 3], load_torque_pu: f64) {
        // The error is the caller's contract violation; the plant stays as it was.
        let _ = self.try_advance(dt_s, duties, load_torque_pu);
    }

    /// As [`Self::advance`], reporting invalid input: a step that is negative or not
    /// finite, a duty or load torque that is not finite. Duties outside [0, 1] are
    /// clamped (the DC-bus limit).
    pub fn try_advance(
        &mut self,
        dt_s: f64,
        duties: [f64; 3],
        load_torque_pu: f64,
    ) -> Result<(), PlantError> {
        if !(dt_s.is_finite() && dt_s >= 0.0) {
            return Err(PlantError::BadStep { dt_s });
        }
        if let Some(bad) = duties
            .iter()
            .chain([&load_torque_pu])
            .find(|v| !v.is_finite())
        {
            return Err(PlantError::BadInput { value: *bad });
        }
        // The drive's phase order to the motor's.
        let [a, b, c] = duties;
        let duties = if self.swapped { [a, c, b] } else { duties };
        self.open_phases();
        self.integrate(dt_s, duties, load_torque_pu);
        self.last_duties = duties;
        self.time_s += dt_s;
        self.open_phases();
        Ok(())
    }

    /// One sampling period with the computational delay, as
    /// [`crate::TwoInertiaPlant::advance_period`]: the duties applied so far hold for
    /// `electrics.computational_delay_s` (clamped to the period), then `new_duties` for
    /// the rest, and stay applied.
    pub fn advance_period(
        &mut self,
        period_s: f64,
        new_duties: [f64; 3],
        load_torque_pu: f64,
    ) -> Result<(), PlantError> {
        if !(period_s.is_finite() && period_s >= 0.0) {
            return Err(PlantError::BadStep { dt_s: period_s });
        }
        if let Some(bad) = new_duties.iter().find(|v| !v.is_finite()) {
            return Err(PlantError::BadInput { value: *bad });
        }
        let delay_s = self.config.electrics.computational_delay_s.min(period_s);
        self.try_advance(delay_s, self.applied_duties, load_torque_pu)?;
        self.try_advance(period_s - delay_s, new_duties, load_torque_pu)?;
        self.applied_duties = new_duties;
        Ok(())
    }

    /// The duties [`Self::advance_period`] is applying now.
    pub fn applied_duties(&self) -> [f64; 3] {
        self.applied_duties
    }

    /// The config this plant was built from.
    pub fn config(&self) -> &PlantConfig {
        &self.config
    }
    /// The motor's constants.
    pub fn motor(&self) -> &PmsmParams {
        &self.motor
    }
    /// The inverter.
    pub fn inverter(&self) -> &Inverter {
        &self.inverter
    }
    /// K, D, g, ω_b...
    pub fn derived(&self) -> &MechanicsDerived {
        &self.derived
    }
    /// Sensor models (ADC LSB etc.).
    pub fn sensors(&self) -> &Sensors {
        &self.sensors
    }
    /// Simulated time since construction, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }
    /// The configured computational delay (sample → new duties applied), s.
    pub fn computational_delay_s(&self) -> f64 {
        self.config.electrics.computational_delay_s
    }
    /// The longest internal step, s (0.5 over the fastest linear rate, at most 250 µs).
    pub fn max_substep_s(&self) -> f64 {
        self.h_max_s
    }

    /// Motor encoder: floor(θm·cpr/2π) (+ noise if configured), as the DC plant's.
    pub fn encoder_count(&self) -> i64 {
        self.sensors.motor_count(self.motor_pos_rad(), self.time_s)
    }
    /// Load encoder count, if one is configured.
    pub fn load_encoder_count(&self) -> Option<i64> {
        self.sensors.load_count(self.load_pos_rad())
    }
    /// The drive's phase currents a and b as the ADC reports them (noise, quantization,
    /// clamping), pu: with `encoder_reversed` its phase b is the motor's c.
    pub fn phase_current_samples(&self) -> [f64; 2] {
        let [a, b, c] = self.phase_currents_pu();
        let b = if self.swapped { c } else { b };
        self.sensors.phase_currents([a, b], self.time_s)
    }
    /// The true phase currents (a, b, c), pu (peak-value scale, summing to zero).
    pub fn phase_currents_pu(&self) -> [f64; 3] {
        self.x.phase_currents()
    }
    /// d current, pu.
    pub fn i_d_pu(&self) -> f64 {
        self.x.i_d
    }
    /// q current, pu.
    pub fn i_q_pu(&self) -> f64 {
        self.x.i_q
    }
    /// The true electrical angle θe = p·θm + offset, rad (not wrapped).
    pub fn electrical_angle_rad(&self) -> f64 {
        self.motor.electrical_angle_rad(self.motor_pos_rad())
    }
    /// The motor's torque λ·i_q + (x_d − x_q)·i_d·i_q, pu.
    pub fn motor_torque_pu(&self) -> f64 {
        self.motor.torque_pu(self.x.i_d, self.x.i_q)
    }
    /// The phase voltages the inverter applies now (the last step's duties, the dead
    /// time's loss at the present currents), pu.
    /// Zero while the switches are open.
    pub fn phase_voltages_pu(&self) -> [f64; 3] {
        if !self.switches.enabled {
            return [0.0; 3];
        }
        self.inverter
            .phase_voltages(self.last_duties, self.phase_currents_pu())
    }
    /// Motor angle θm, rad.
    pub fn motor_pos_rad(&self) -> f64 {
        self.x.theta_l + self.x.delta
    }
    /// Load angle θl reflected to the motor side, rad.
    pub fn load_pos_rad(&self) -> f64 {
        self.x.theta_l
    }
    /// Motor speed ωm, pu.
    pub fn motor_vel_pu(&self) -> f64 {
        self.x.w_m
    }
    /// Load speed ωl (motor side), pu.
    pub fn load_vel_pu(&self) -> f64 {
        self.x.w_l
    }
    /// Twist δ = θm − θl, rad.
    pub fn twist_rad(&self) -> f64 {
        self.x.delta
    }
    /// Shaft torque Ts, pu.
    pub fn shaft_torque_pu(&self) -> f64 {
        let s = &self.model.shaft;
        let rel = self.x.w_m - self.x.w_l;
        match self.contact {
            Contact::Free => 0.0,
            Contact::Driving => s.k * (self.x.delta - s.g) + s.d * rel,
            Contact::Braking => s.k * (self.x.delta + s.g) + s.d * rel,
        }
    }
    /// Which side of the lost motion the gears are on.
    pub fn contact(&self) -> Contact {
        self.contact
    }
    /// Contact changes located so far.
    pub fn mode_changes(&self) -> u64 {
        self.events
    }
    /// Phase-current sign changes located so far (with dead time; else 0).
    pub fn current_sign_changes(&self) -> u64 {
        self.sign_changes
    }
    /// Steps searched for a crossing (suspected or real): a cost diagnostic.
    pub fn crossing_searches(&self) -> u64 {
        self.searches
    }

    /// Puts the plant in a state (positions rad, speeds pu, d/q currents pu); the contact
    /// follows.
    pub fn set_state(
        &mut self,
        motor_pos_rad: f64,
        load_pos_rad: f64,
        motor_vel_pu: f64,
        load_vel_pu: f64,
        i_d_pu: f64,
        i_q_pu: f64,
    ) {
        self.x = Vars {
            delta: motor_pos_rad - load_pos_rad,
            theta_l: load_pos_rad,
            w_m: motor_vel_pu,
            w_l: load_vel_pu,
            i_d: i_d_pu,
            i_q: i_q_pu,
            cos: 0.0,
            sin: 0.0,
        };
        self.refresh_angle();
        (self.contact, self.signs) = self.pattern_of(&self.x, [0; 3]);
    }

    /// cos θe and sin θe from the motor angle (each step starts from them, so the carried
    /// pair never drifts from the angle).
    fn refresh_angle(&mut self) {
        let (s, c) = self.electrical_angle_rad().sin_cos();
        self.x.cos = c;
        self.x.sin = s;
    }

    /// The contact a state is in (as the DC plant classifies it).
    fn contact_of(&self, x: &Vars) -> Contact {
        let s = &self.model.shaft;
        let (delta, rel) = (x.delta, x.w_m - x.w_l);
        let law = self.model.law;
        if s.g == 0.0 && law == BacklashModel::DeadZone {
            return Contact::Driving;
        }
        let clamped = law == BacklashModel::Clamped;
        if delta > s.g {
            if clamped && s.k * (delta - s.g) + s.d * rel <= 0.0 {
                return Contact::Free;
            }
            Contact::Driving
        } else if delta < -s.g {
            if clamped && s.k * (delta + s.g) + s.d * rel >= 0.0 {
                return Contact::Free;
            }
            Contact::Braking
        } else {
            Contact::Free
        }
    }

    /// What a step holds fixed: the contact and, with dead time, the phase currents' signs,
    /// where a current exactly at zero keeps its sign in `carried` (only a strict crossing
    /// changes a sign: a bisection can end exactly on zero).
    fn pattern_of(&self, x: &Vars, carried: [i8; 3]) -> (Contact, [i8; 3]) {
        let signs = if self.inverter.dead_time_loss_pu() > 0.0 {
            let now = x.phase_currents().map(|i| sign(i) as i8);
            std::array::from_fn(|k| match now.get(k).copied().unwrap_or(0) {
                0 => carried.get(k).copied().unwrap_or(0),
                s => s,
            })
        } else {
            [0; 3]
        };
        (self.contact_of(x), signs)
    }

    /// The equations of the mode `contact` with the voltage vector and load torque.
    fn equations(&self, contact: Contact, v_ab: [f64; 2], tl: f64) -> Equations {
        let m = &self.model;
        let (on, sigma) = match contact {
            Contact::Free => (0.0, 0.0),
            Contact::Driving => (1.0, 1.0),
            Contact::Braking => (1.0, -1.0),
        };
        let p = &self.motor;
        let [v_alpha, v_beta] = v_ab;
        Equations {
            wb: m.base_speed_rad_s,
            inv_jm: 1.0 / m.motor_inertia_s,
            inv_jl: if m.load_locked {
                0.0
            } else {
                1.0 / m.load_inertia_s
            },
            bm: m.motor_viscous_pu,
            bl: m.load_viscous_pu,
            k: on * m.shaft.k,
            d: on * m.shaft.d,
            ts0: -sigma * m.shaft.k * m.shaft.g,
            tl,
            r: p.r_pu,
            ld: p.ld_pu_s,
            lq: p.lq_pu_s,
            flux: p.flux_linkage_pu,
            pw: p.electrical_rad_s_per_pu,
            saliency: p.saliency_pu(),
            v_alpha,
            v_beta,
            conducting: self.conducting(),
        }
    }

    /// The longest step to try from `x`: within the linear rates and 0.5 rad of the rotor.
    fn step_limit(&self, x: &Vars) -> f64 {
        let turn = self.motor.electrical_rad_s_per_pu * x.w_m.abs();
        if turn * self.h_max_s > 0.5 {
            0.5 / turn
        } else {
            self.h_max_s
        }
    }

    /// Integrates `dt_s` with the duties and load held.
    fn integrate(&mut self, dt_s: f64, duties: [f64; 3], tl: f64) {
        let mut remaining = dt_s;
        let mut changes = 0;
        // cos θe and sin θe are the angle's on entry (every method that moves the state
        // refreshes them); after a step they are the series', so they are refreshed then.
        let mut fresh = true;
        while remaining > 0.0 {
            if !fresh {
                self.refresh_angle();
            }
            fresh = false;
            let x0 = self.x;
            let pattern = (self.contact, self.signs);
            let currents = pattern.1.map(f64::from);
            let v_ab = self.inverter.voltage_ab(duties, currents);
            let eq = self.equations(self.contact, v_ab, tl);
            let mut h = remaining.min(self.step_limit(&x0));
            self.series.fill(&eq, &x0, h);
            for _ in 0..MAX_HALVINGS {
                if self.series.converged() {
                    break;
                }
                h *= 0.5;
                self.series.fill(&eq, &x0, h);
            }
            let whole = h >= remaining;
            let guarded = changes < MAX_CHANGES_PER_CALL;
            if guarded && self.suspect(&self.series, &x0) {
                self.searches += 1;
                if let Some(tau) = self.first_change(&self.series, pattern) {
                    self.x = self.series.at(tau);
                    let (contact, signs) = self.pattern_of(&self.x, self.signs);
                    if contact != self.contact {
                        self.events += 1;
                    }
                    if signs != self.signs {
                        self.sign_changes += 1;
                    }
                    (self.contact, self.signs) = (contact, signs);
                    changes += 1;
                    remaining -= tau;
                    continue;
                }
            }
            self.x = self.series.at(h);
            if !guarded {
                // Past the cap each step takes the signs its start has.
                self.signs = self.pattern_of(&self.x, self.signs).1;
            }
            remaining = if whole { 0.0 } else { remaining - h };
        }
        if !fresh {
            self.refresh_angle();
        }
    }

    /// Whether a guard may change sign within the step: the lost motion's edges (and, for
    /// the clamped law, the contact force), and with dead time the phase currents. Each
    /// guard is linear in the variables (the currents bilinear), so |guard(0)| against the
    /// spread of the series is a rigorous test of the polynomial.
    fn suspect(&self, series: &Series, x0: &Vars) -> bool {
        let spread = series.spread();
        let s = &self.model.shaft;
        let law = self.model.law;
        let mut suspect = false;
        if !(s.g == 0.0 && law == BacklashModel::DeadZone) {
            let twist = spread.delta;
            suspect |= (x0.delta - s.g).abs() <= twist || (x0.delta + s.g).abs() <= twist;
            if law == BacklashModel::Clamped {
                let rel = x0.w_m - x0.w_l;
                let force = s.k * twist + s.d * (spread.w_m + spread.w_l);
                suspect |= (s.k * (x0.delta - s.g) + s.d * rel).abs() <= force
                    || (s.k * (x0.delta + s.g) + s.d * rel).abs() <= force;
            }
        }
        if self.inverter.dead_time_loss_pu() > 0.0 && self.switches.enabled {
            // |Δ(c·i_d − s·i_q)| ≤ |c|·Δi_d + Δc·|i_d| + Δc·Δi_d + (the same for s, i_q);
            // β alike, and each phase is within |Δα| + |Δβ| of its start.
            let product = |a: f64, da: f64, b: f64, db: f64| a.abs() * db + da * b.abs() + da * db;
            let d_alpha = product(x0.cos, spread.cos, x0.i_d, spread.i_d)
                + product(x0.sin, spread.sin, x0.i_q, spread.i_q);
            let d_beta = product(x0.sin, spread.sin, x0.i_d, spread.i_d)
                + product(x0.cos, spread.cos, x0.i_q, spread.i_q);
            let bound = d_alpha + d_beta;
            suspect |= x0.phase_currents().iter().any(|i| i.abs() <= bound);
        }
        suspect
    }

    /// The earliest time in (0, h] at which the state leaves `pattern` (contact, signs):
    /// the first of [`SEARCH_SAMPLES`] samples that does, then [`BISECTIONS`] halvings of
    /// the bracket; the end of the bracket on the new side. None when no sample leaves.
    fn first_change(&self, series: &Series, pattern: (Contact, [i8; 3])) -> Option<f64> {
        let h = series.h();
        let left = |tau: f64| {
            let x = series.at(tau);
            self.pattern_of(&x, pattern.1) != pattern
        };
        let mut lo = 0.0;
        let mut hi = None;
        for j in 1..=SEARCH_SAMPLES {
            let tau = h * f64::from(j) / f64::from(SEARCH_SAMPLES);
            if left(tau) {
                hi = Some(tau);
                break;
            }
            lo = tau;
        }
        let mut hi = hi?;
        for _ in 0..BISECTIONS {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if left(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        Some(hi)
    }
}
