//! The plant's sensors: encoder counts (4096 and 1,000,000 CPR), the optional load encoder,
//! ADC quantization, and reproducible noise.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use crate::common;

use plant_host::{PlantConfig, TwoInertiaPlant};
use std::f64::consts::PI;

#[test]
fn encoder_counts_at_both_resolutions() {
    for cpr in [4096_u32, 1_000_000] {
        let mut cfg = common::table1();
        cfg.mechanics.encoder_cpr = cpr;
        let mut d = TwoInertiaPlant::voltage_driven(&cfg);
        assert_eq!(d.encoder_count(), 0);
        // Exactly 2.5 counts ahead (mid-count): floor gives 2; 2.5 counts back gives −3.
        let count_rad = 2.0 * PI / f64::from(cpr);
        d.set_state(2.5 * count_rad, 0.0, 0.0, 0.0, 0.0);
        assert_eq!(d.encoder_count(), 2);
        d.set_state(-2.5 * count_rad, 0.0, 0.0, 0.0, 0.0);
        assert_eq!(d.encoder_count(), -3);
        // Ten turns.
        d.set_state(20.0 * PI + 0.5 * count_rad, 20.0 * PI, 0.0, 0.0, 0.0);
        assert_eq!(d.encoder_count(), 10 * i64::from(cpr));
        assert_eq!(d.load_encoder_count(), None);
    }
}

#[test]
fn load_encoder_sees_the_physical_load_shaft() {
    let text = common::config_text("printing-press.toml")
        .replace("load_encoder_cpr = 0 ", "load_encoder_cpr = 10000 ");
    let cfg = PlantConfig::from_machine_toml(&text).unwrap();
    assert_eq!(cfg.sensors.load_encoder(), Some(10_000));
    let mut d = TwoInertiaPlant::voltage_driven(&cfg);
    // Three motor-side turns of the reflected load = one turn of the 3:1 load shaft.
    d.set_state(6.0 * PI + 1e-9, 6.0 * PI + 1e-9, 0.0, 0.0, 0.0);
    assert_eq!(d.load_encoder_count(), Some(10_000));
    assert_eq!(d.encoder_count(), 3_000_000);
}

#[test]
fn current_sample_is_quantized_and_noise_is_reproducible() {
    let mut cfg = common::table1();
    let mut d = TwoInertiaPlant::voltage_driven(&cfg);
    d.set_state(0.0, 0.0, 0.0, 0.0, 0.123_456);
    let lsb = 8.0 / 4096.0;
    assert!((d.current_sample() / lsb - (d.current_sample() / lsb).round()).abs() < 1e-9);
    assert!((d.current_sample() - 0.123_456).abs() <= 0.5 * lsb);

    cfg.sensors.current_noise_pu = 0.05;
    cfg.sensors.encoder_noise_counts = 3.0;
    let run = |cfg: &PlantConfig| {
        let mut d = TwoInertiaPlant::voltage_driven(cfg);
        let mut out = Vec::new();
        for _ in 0..400 {
            d.advance(250e-6, 0.01, 0.0);
            out.push((d.encoder_count(), d.current_sample()));
        }
        out
    };
    let a = run(&cfg);
    assert_eq!(a, run(&cfg), "same seed, same noise");
    let clean = run(&common::table1());
    let diffs: Vec<f64> = a.iter().zip(&clean).map(|(n, c)| n.1 - c.1).collect();
    let rms = (diffs.iter().map(|x| x * x).sum::<f64>() / diffs.len() as f64).sqrt();
    assert!((rms - 0.05).abs() < 0.01, "current noise rms {rms}");
    let count_diffs: Vec<f64> = a
        .iter()
        .zip(&clean)
        .map(|(n, c)| (n.0 - c.0) as f64)
        .collect();
    let crms = (count_diffs.iter().map(|x| x * x).sum::<f64>() / count_diffs.len() as f64).sqrt();
    assert!((crms - 3.0).abs() < 0.6, "encoder noise rms {crms} counts");
    cfg.sensors.noise_seed = 2;
    assert_ne!(a, run(&cfg), "another seed, other noise");
}
