//! The calibration on PMSM machines that no shipped config describes: odd pole pairs, a
//! salient rotor, an encoder offset and direction of the test's choosing, dead time and
//! current noise. Targets fixed before the runs: R within 3 %, L_d and L_q within 5 %, the
//! offset within 2° electrical, the direction and the pole pairs exact.
#![allow(clippy::expect_used, clippy::panic)]

use super::{estimate, record_on_plant};
use controller_core::foc::calibration::CalibrationSettings;
use plant_host::PlantConfig;

/// A light motor on a soft coupling with 1° of lost motion and a 16384-count encoder,
/// driven by a PMSM of `pole_pairs` whose encoder zero is `offset_deg` electrical, counting
/// against the electrical angle when `reversed` (two motor leads swapped at the inverter).
fn machine(pole_pairs: u32, offset_deg: f64, reversed: bool) -> PlantConfig {
    let text = format!(
        r#"
[plant]
base_speed_rpm = 3000.0
motor_inertia_s = 0.03
load_inertia_s = 0.2
anti_resonance_hz = 12.0
shaft_damping_ratio = 0.03
backlash_deg = 1.0
motor_viscous_pu = 0.002
load_viscous_pu = 0.0
encoder_cpr = 16384

[electrics]
motor = "pmsm"
pole_pairs = {pole_pairs}
winding_resistance_pu = 0.08
d_inductance_pu_s = 2.5e-4
q_inductance_pu_s = 4.2e-4
flux_linkage_pu = 1.0
dc_bus_pu = 2.0
encoder_offset_elec_deg = {offset_deg}
encoder_reversed = {reversed}
dead_time_s = 1e-6
computational_delay_s = 180e-6
current_adc_bits = 12
current_full_scale_pu = 4.0

[sensors]
load_encoder_cpr = 0
gear_ratio = 1.0
encoder_noise_counts = 0.0
current_noise_pu = 0.002
noise_seed = 7

[lost_motion]
model = "dead_zone"
"#
    );
    PlantConfig::from_machine_toml(&text).expect("the test machine is valid")
}

#[test]
fn calibration_recovers_the_motor_of_a_machine_no_config_describes() {
    for (pp, offset, reversed) in [
        (7u32, 211.5f64, false),
        (5, 33.0, false),
        (11, 300.0, false),
        (7, 211.5, true),
    ] {
        let cfg = machine(pp, offset, reversed);
        let settings = CalibrationSettings {
            current_rate_hz: 4000.0,
            voltage_limit_pu: 1.0,
            ..CalibrationSettings::default()
        };
        let rec = record_on_plant(&cfg, &settings).expect("the calibration runs");
        let est = estimate(&rec).expect("the record gives estimates");
        let rel = |e: f64, t: f64| (e - t).abs() / t;
        let off_err =
            ((est.encoder_offset_elec_deg.value - offset + 180.0).rem_euclid(360.0) - 180.0).abs();
        eprintln!(
            "pp {pp}, offset {offset}: R {:.5} ± {:.1e} ({:.2} %), Ld {:.3e} ± {:.1e} ({:.2} %), \
             Lq {:.3e} ± {:.1e} ({:.2} %), offset {:.2}° ± {:.2} ({off_err:.2}° off), lag \
             {:.2}°, pole pairs {}, reversed {}",
            est.winding_resistance_pu.value,
            est.winding_resistance_pu.std_error,
            100.0 * rel(est.winding_resistance_pu.value, 0.08),
            est.d_inductance_pu_s.value,
            est.d_inductance_pu_s.std_error,
            100.0 * rel(est.d_inductance_pu_s.value, 2.5e-4),
            est.q_inductance_pu_s.value,
            est.q_inductance_pu_s.std_error,
            100.0 * rel(est.q_inductance_pu_s.value, 4.2e-4),
            est.encoder_offset_elec_deg.value,
            est.encoder_offset_elec_deg.std_error,
            est.sweep_lag_elec_deg,
            est.pole_pairs,
            est.encoder_reversed,
        );
        assert_eq!(est.pole_pairs, pp);
        assert_eq!(est.encoder_reversed, reversed);
        assert!(rel(est.winding_resistance_pu.value, 0.08) <= 0.03);
        assert!(rel(est.d_inductance_pu_s.value, 2.5e-4) <= 0.05);
        assert!(rel(est.q_inductance_pu_s.value, 4.2e-4) <= 0.05);
        assert!(off_err <= 2.0);
    }
}
