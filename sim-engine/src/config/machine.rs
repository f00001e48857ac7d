//! A machine file's value tree into plant-host's `PlantConfig` and controller-core's
//! `DriveConfig`, through the one composer every user of a machine file shares
//! ([`machine_file::compose`]: the firmware build bakes its drive through it too).

use crate::error::Result;
use controller_core::DriveConfig;
use plant_host::PlantConfig;
use toml::Table;

pub use machine_file::MACHINE_KEYS;

/// The plant and the drive of a (merged) machine file. The `[drive]` table goes to
/// controller-core, the rest to plant-host; a table neither knows is an error naming it.
pub fn machine(doc: Table) -> Result<(PlantConfig, DriveConfig)> {
    let m = machine_file::compose(doc)?;
    Ok((m.plant, m.drive))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use controller_core::{AfbMode, Estimator, FilterConfig, ObserverInertia, ObserverTorque};
    use controller_core::{ObserverConfig, PiInertia};
    use toml::Value;

    /// configs/machines/table1.toml with `extra` TOML appended (a table given twice is merged key by
    /// key, the later value winning).
    fn parse(extra: &str) -> Result<DriveConfig> {
        let path = crate::config::configs_dir()
            .join("machines")
            .join("table1.toml");
        let mut doc = crate::config::read_table(&path).unwrap();
        let extra: Table = extra.parse().unwrap();
        merge(&mut doc, extra);
        machine(doc).map(|(_, d)| d)
    }

    fn merge(into: &mut Table, from: Table) {
        for (k, v) in from {
            match (into.get_mut(&k), v) {
                (Some(Value::Table(a)), Value::Table(b)) => merge(a, b),
                (_, v) => {
                    into.insert(k, v);
                }
            }
        }
    }

    #[test]
    fn machine_values_come_from_the_plant_and_keys_override_them() {
        let path = crate::config::configs_dir()
            .join("machines")
            .join("table1.toml");
        let (plant, _) = machine(crate::config::read_table(&path).unwrap()).unwrap();
        let cfg = parse("[drive]\nvelocity_bandwidth_rad_s = 50\n").unwrap();
        assert_eq!(cfg.velocity_bandwidth_rad_s, 50.0);
        assert_eq!(
            cfg.winding_inductance_pu_s,
            plant.electrics.winding_inductance_pu_s as f32
        );
        assert_eq!(cfg.encoder_cpr, plant.counts_per_rev());
        assert_eq!(cfg.motor_inertia_s, plant.mechanics.motor_inertia_s as f32);
        let cfg = parse("[drive]\nload_inertia_s = 0.5\n").unwrap();
        assert_eq!(cfg.load_inertia_s, 0.5);
    }

    #[test]
    fn nested_tables_and_words_map_onto_the_config() {
        let cfg = parse(
            "[drive.accel_feedback]\nmode = \"plain\"\nsource = \"differentiation\"\n\
             filter = { corner_hz = 40, kind = \"second_order\" }\n\
             [drive.observer]\nmodel_inertia = \"total\"\n",
        )
        .unwrap();
        assert_eq!(cfg.accel_feedback.mode, AfbMode::Plain);
        assert_eq!(cfg.accel_feedback.source, Estimator::Differentiation);
        // The kind is read wherever it is in the table; q takes its default.
        assert!(matches!(
            cfg.accel_feedback.filter,
            FilterConfig::SecondOrder { corner_hz, q }
                if corner_hz == 40.0 && q == core::f32::consts::FRAC_1_SQRT_2
        ));
        assert_eq!(cfg.observer.model_inertia, ObserverInertia::Total);
        // A key not given keeps the design default.
        let default = ObserverConfig::default();
        assert_eq!(cfg.observer.torque_input, default.torque_input);
        let cfg = parse("[drive.observer]\ntorque_input = \"measured_current\"\n").unwrap();
        assert_eq!(cfg.observer.torque_input, ObserverTorque::MeasuredCurrent);
        let e = parse("[drive.observer]\ntorque_input = \"current\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("drive.observer.torque_input") && e.contains("measured_current"),
            "{e}"
        );
    }

    #[test]
    fn velocity_pi_inertia_sizes_the_pi() {
        let plus = parse("[drive]\nvelocity_pi_inertia = \"total_plus_afb\"\n").unwrap();
        assert_eq!(plus.velocity_pi_inertia, PiInertia::TotalPlusAfb);
        let total = parse("[drive]\nvelocity_pi_inertia = \"total\"\n").unwrap();
        let (gt, gp) = (
            controller_core::design(&total).unwrap(),
            controller_core::design(&plus).unwrap(),
        );
        assert_eq!(
            gt.kp_vel,
            total.velocity_bandwidth_rad_s * total.total_inertia_s()
        );
        assert!(gp.kp_vel > gt.kp_vel, "Ka adds to the PI's inertia");
        for bad in ["\"motor\"", "1", "\"Total\""] {
            let e = parse(&format!("[drive]\nvelocity_pi_inertia = {bad}\n"))
                .unwrap_err()
                .to_string();
            assert!(e.contains("drive.velocity_pi_inertia"), "{bad}: {e}");
        }
    }

    #[test]
    fn counts_bits_and_rates_must_be_whole_numbers() {
        for text in [
            "[drive]\nencoder_cpr = 4096.5\n",
            "[drive]\ncounter_bits = 20.7\n",
            "[drive]\ncurrent_rate_hz = 4000.25\n",
            "[drive]\nvelocity_rate_hz = 1999.9\n",
        ] {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains("must be a whole number"), "{text}: {e}");
        }
        assert_eq!(
            parse("[drive]\ncounter_bits = 24.0\n")
                .unwrap()
                .counter_bits,
            24
        );
    }

    #[test]
    fn errors_name_the_key_and_the_range_or_the_allowed_keys() {
        let e = parse("[drive]\nvelocity_bandwith_rad_s = 5\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("drive.velocity_bandwith_rad_s") && e.contains("velocity_bandwidth_rad_s"),
            "{e}"
        );
        let e = parse("[drive]\nvelocity_damping = 20\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("drive.velocity_damping") && e.contains("0.1") && e.contains("10"),
            "{e}"
        );
        let e = parse("[drive.accel_feedback]\nmode = \"on\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("drive.accel_feedback.mode") && e.contains("error"),
            "{e}"
        );
        let e = parse("[drive.nosuch]\nx = 1\n").unwrap_err().to_string();
        assert!(e.contains("drive.nosuch"), "{e}");
        // A combination only the whole drive can judge: above the loop's Nyquist.
        let e = parse("[drive]\nvelocity_bandwidth_rad_s = 9000\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("drive.velocity_bandwidth_rad_s"), "{e}");
        // A misspelt table of the file: nothing reads it.
        let e = parse("[drivee]\nx = 1\n").unwrap_err().to_string();
        assert!(e.contains("drivee"), "{e}");
    }

    #[test]
    fn a_file_without_the_drives_loop_keys_is_an_error_naming_them() {
        let path = crate::config::configs_dir()
            .join("machines")
            .join("table1.toml");
        let mut doc = crate::config::read_table(&path).unwrap();
        if let Some(Value::Table(d)) = doc.get_mut("drive") {
            d.remove("current_rate_hz");
        }
        let e = machine(doc).unwrap_err().to_string();
        assert!(e.contains("current_rate_hz") && e.contains("drive"), "{e}");
    }
}
