//! The inverter switched off: all six switches open, as a drive leaves it once a fault has
//! latched.
//!
//! With the switches open a phase current can only flow through the free-wheeling diodes,
//! which connect its phase to the rail that opposes it: the winding's energy returns to the
//! bus and the currents fall to zero in about `L·|i|/(V_dc − √3·λ·|ωm|)` (1 ms or less on
//! `configs/machines/table1-pmsm.toml` from its overcurrent level). Then the diodes block
//! and the phases are open, **as long as the line-to-line back-EMF's peak stays below the
//! bus**:
//!
//! ```text
//! √3·λ·|ωm| < dc_bus_pu        (plant per unit: back-EMF λ·ωm pu per phase, peak)
//! ```
//!
//! Here the decay is taken as instantaneous: the currents are set to zero when the switches
//! open, and held there (their equations are switched off, the torque is zero) while the
//! mechanics run on. The torque of the decay left out is at most λ·|i|/2 over that
//! millisecond. Above the limit the diodes would conduct as an uncontrolled rectifier and
//! brake the motor; that is not modelled, so the plant records the first time it happened
//! ([`PmsmPlant::diode_limit_exceeded_s`]) and its user must report it (sim-engine's runner
//! stops the run with an error naming the speed and the bus).

use super::PmsmPlant;

/// The switches' state and what the plant saw while they were open.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Switches {
    /// Whether the inverter switches (the duties act).
    pub enabled: bool,
    /// The plant time at which the back-EMF first reached the diode limit while off.
    pub exceeded_s: Option<f64>,
}

impl Default for Switches {
    fn default() -> Self {
        Self {
            enabled: true,
            exceeded_s: None,
        }
    }
}

impl PmsmPlant {
    /// Opens (`false`) or closes (`true`) the inverter's switches. Open: the duties no
    /// longer act, the currents are zero (the diodes' decay taken as instantaneous; see the
    /// module text for what that leaves out and for the speed limit of the model).
    pub fn set_enabled(&mut self, enabled: bool) {
        self.switches.enabled = enabled;
        if !enabled {
            self.open_phases();
        }
    }

    /// Whether the inverter switches.
    pub fn enabled(&self) -> bool {
        self.switches.enabled
    }

    /// The line-to-line back-EMF's peak over the bus, √3·λ·|ωm| / dc_bus_pu: below 1 the
    /// diodes of an open inverter block.
    pub fn back_emf_over_bus(&self) -> f64 {
        3.0_f64.sqrt() * self.motor.flux_linkage_pu * self.x.w_m.abs() / self.inverter.dc_bus_pu()
    }

    /// The first time \[s\] the back-EMF reached the bus while the switches were open
    /// (from then on the diodes would conduct, which the plant does not model); `None`
    /// if it never did.
    pub fn diode_limit_exceeded_s(&self) -> Option<f64> {
        self.switches.exceeded_s
    }

    /// With the switches open: the currents at zero, and the diode limit checked.
    pub(super) fn open_phases(&mut self) {
        if self.switches.enabled {
            return;
        }
        self.x.i_d = 0.0;
        self.x.i_q = 0.0;
        self.signs = [0; 3];
        if self.switches.exceeded_s.is_none() && self.back_emf_over_bus() >= 1.0 {
            self.switches.exceeded_s = Some(self.time_s);
        }
    }

    /// 1 while the switches conduct, 0 while open (the currents' equations are off).
    pub(super) fn conducting(&self) -> f64 {
        if self.switches.enabled { 1.0 } else { 0.0 }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use crate::{PlantConfig, PmsmPlant};

    fn plant() -> PmsmPlant {
        let mut doc: toml::Table = include_str!("../../../configs/machines/table1-pmsm.toml")
            .parse()
            .unwrap();
        doc.remove("drive");
        let cfg = PlantConfig::from_machine_toml(&toml::to_string(&doc).unwrap()).unwrap();
        PmsmPlant::new(&cfg, 20e3).unwrap()
    }

    /// Open switches: no current, no torque, the mechanics coast (no friction on
    /// table1-pmsm, so the speeds keep their sum of momenta); below the limit nothing is
    /// recorded, and at 1.3 pu (√3·1.3/2.0785 = 1.08 > 1) the first step records it.
    #[test]
    fn open_switches_hold_the_currents_at_zero_and_record_the_diode_limit() {
        let mut p = plant();
        p.set_state(0.0, 0.0, 1.0, 1.0, 0.3, 1.5);
        p.set_enabled(false);
        assert!(!p.enabled());
        assert_eq!((p.i_d_pu(), p.i_q_pu()), (0.0, 0.0));
        for _ in 0..400 {
            p.try_advance(250e-6, [1.0, 0.0, 0.0], 0.0).unwrap();
            assert_eq!(
                (p.i_d_pu(), p.i_q_pu(), p.motor_torque_pu()),
                (0.0, 0.0, 0.0)
            );
        }
        assert_eq!(p.phase_voltages_pu(), [0.0; 3]);
        assert!(
            (p.motor_vel_pu() - 1.0).abs() < 1e-9,
            "{}",
            p.motor_vel_pu()
        );
        let bus = p.inverter().dc_bus_pu();
        assert!((p.back_emf_over_bus() - 3f64.sqrt() / bus).abs() < 1e-9);
        assert_eq!(p.diode_limit_exceeded_s(), None);
        p.set_state(0.0, 0.0, 1.3, 1.3, 0.0, 0.0);
        p.try_advance(250e-6, [0.5; 3], 0.0).unwrap();
        let t = p.diode_limit_exceeded_s().unwrap();
        assert!((t - 0.1).abs() < 1e-12, "{t}");
        // Closed again, the duties act: a q voltage drives the current.
        p.set_enabled(true);
        let v = crate::inverse_park([0.0, 1.5], p.electrical_angle_rad());
        let duties = p.inverter().duties_for(v);
        p.try_advance(250e-6, duties, 0.0).unwrap();
        assert!(p.i_q_pu() > 0.01, "{}", p.i_q_pu());
    }
}
