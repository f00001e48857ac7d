//! The drive files `tune` and `commission` write are the design, whole: composed back
//! through the machine-file composer, each gives exactly the `DriveConfig` written and the
//! same settings CRC (the one the board logs at boot), for every kind of design `tune`
//! makes and for 1,000 random valid drives, on machine files whose own `[drive]` differs
//! from the design in every way (AFB on against off, a notch against none, for a PMSM
//! another `[drive.pmsm]`: the calibration `commission` writes replaces the file's, and
//! a drive without the encoder offset stays without it).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use controller_core::{
    AfbFilterAtLimit, AfbMode, AfbRate, DriveConfig, Estimator, FilterConfig, NotchConfig,
    ObserverInertia, ObserverTorque, PiInertia,
};
use machine_workflows::tune::{self, output};
use pil_link::board::session::settings_crc;
use std::path::Path;
use toml::{Table, Value};

/// The shipped machine files' trees, each also with a notch and AFB off in its own
/// `[drive]` (what a written file must not keep).
fn machine_docs() -> Vec<(String, Table)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut v = Vec::new();
    for name in [
        "table1",
        "dyno",
        "printing-press",
        "table1-pmsm",
        "../../tests/fixtures/pmsm-odd",
    ] {
        let path = root.join("configs/machines").join(format!("{name}.toml"));
        let text = std::fs::read_to_string(path).unwrap();
        let doc: Table = text.parse().unwrap();
        let mut odd = doc.clone();
        let drive = odd["drive"].as_table_mut().unwrap();
        drive.insert(
            "notch".into(),
            toml::toml! { centre_hz = 40.0
            width_hz = 8.0
            depth_db = 20.0 }
            .into(),
        );
        let afb = drive
            .entry("accel_feedback")
            .or_insert_with(|| Value::Table(Table::new()))
            .as_table_mut()
            .unwrap();
        afb.insert("mode".into(), Value::String("off".into()));
        afb.insert("gain_fraction".into(), Value::Float(0.3));
        v.push((name.to_string(), doc));
        v.push((format!("{name} with a notch, AFB off"), odd));
    }
    v
}

/// The text of the file written for `design` on the machine file `doc`, by the function
/// `tune` and `commission` write their drive files with.
fn written(doc: &Table, design: &DriveConfig) -> String {
    output::drive_file(doc.clone(), design, "a test's header").unwrap()
}

/// Writes `design` on `doc`, composes the file back, and checks the drive and its CRC.
fn round_trip(what: &str, doc: &Table, design: &DriveConfig) {
    let text = written(doc, design);
    let back = machine_file::from_text(&text)
        .unwrap_or_else(|e| panic!("{what}: {e}\n{text}"))
        .drive;
    assert_eq!(back, *design, "{what}:\n{text}");
    assert_eq!(settings_crc(&back), settings_crc(design), "{what}");
    // Every key of the design is stated: the file's [drive] table alone composes to it,
    // whatever the plant.
    let table: Table = text.parse().unwrap();
    let drive = table["drive"].as_table().unwrap();
    for key in machine_file::MACHINE_KEYS {
        assert!(drive.contains_key(key), "{what}: {key} not stated\n{text}");
    }
    assert_eq!(
        drive.contains_key("notch"),
        design.notch.is_some(),
        "{what}"
    );
    assert_eq!(drive.contains_key("pmsm"), design.pmsm.is_some(), "{what}");
    if let Some(p) = &design.pmsm {
        let pmsm = drive["pmsm"].as_table().unwrap();
        for key in PMSM_KEYS {
            assert!(
                pmsm.contains_key(key),
                "{what}: pmsm.{key} not stated\n{text}"
            );
        }
        assert_eq!(
            pmsm.contains_key("encoder_offset_elec_deg"),
            p.encoder_offset_elec_deg.is_some(),
            "{what}"
        );
    }
}

/// The `[drive.pmsm]` keys a drive file states whatever the design (the offset only when
/// the design has one).
const PMSM_KEYS: [&str; 10] = [
    "pole_pairs",
    "d_inductance_pu_s",
    "q_inductance_pu_s",
    "flux_linkage_pu",
    "dc_bus_pu",
    "encoder_reversed",
    "angle_advance_ticks",
    "pwm_period_counts",
    "commutation_min_speed_pu",
    "commutation_trip_s",
];

/// A calibration as `commission` writes it, none of it the file's own: 7 pole pairs, a
/// salient motor, an offset with a long mantissa, the encoder reversed.
fn calibrated(mut d: DriveConfig) -> DriveConfig {
    if let Some(p) = d.pmsm.as_mut() {
        p.pole_pairs = 7;
        p.d_inductance_pu_s = 3.0137e-4;
        p.q_inductance_pu_s = 4.5327e-4;
        p.encoder_offset_elec_deg = Some(137.146_21);
        p.encoder_reversed = true;
        d.winding_resistance_pu = 0.059_748_3;
    }
    d
}

/// Every kind of design `tune` makes (its grid's candidates: AFB off and on, each form,
/// each estimator, each filter, each observer bandwidth), with a notch and without, with
/// the position loop on and off, on every machine file.
#[test]
fn every_kind_of_design_tune_makes_composes_back_to_itself() {
    let grid = sim_engine::config::tune_grid().unwrap();
    let candidates = tune::candidates(&grid, &grid.bandwidths_rad_s[..2]);
    let mut kinds = std::collections::BTreeSet::new();
    let (mut n, mut pmsm) = (0, 0);
    for (name, doc) in machine_docs() {
        let base = calibrated(machine_file::compose(doc.clone()).unwrap().drive);
        for c in &candidates {
            for notch in [None, Some((0.3, 0.2, 30.0))] {
                for position in [0.0, 12.5] {
                    let mut d = base;
                    c.apply(&mut d);
                    d.position_bandwidth_rad_s = position;
                    d.notch = notch.map(|(c, w, depth): (f32, f32, f32)| NotchConfig {
                        centre_hz: c * 0.5 * d.current_rate_hz as f32,
                        width_hz: w * c * 0.5 * d.current_rate_hz as f32,
                        depth_db: depth,
                    });
                    if d.validate().is_err() {
                        continue;
                    }
                    kinds.insert((
                        format!("{:?}", d.accel_feedback.mode),
                        format!("{:?}", d.accel_feedback.source),
                        d.notch.is_some(),
                        position > 0.0,
                    ));
                    round_trip(&format!("{name}: {c:?}"), &doc, &d);
                    n += 1;
                    pmsm += usize::from(d.pmsm.is_some());
                }
            }
        }
    }
    // Off (its source unused, the observer's), plain and error from each estimator, each
    // with and without a notch and the position loop.
    assert_eq!(kinds.len(), (1 + 2 * 2) * 2 * 2, "{kinds:?}");
    assert!(n > 1000, "{n}");
    // The two PMSM files' designs, each with the calibration.
    assert!(pmsm > 300, "{pmsm} of {n}");
}

/// SplitMix64: the test's seeded random numbers.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn uniform(&mut self, lo: f64, hi: f64) -> f32 {
        (lo + (hi - lo) * self.unit()) as f32
    }
    /// Log-uniform in [lo, hi].
    fn log(&mut self, lo: f64, hi: f64) -> f32 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.unit()).exp() as f32
    }
    fn pick<T: Copy>(&mut self, of: &[T]) -> T {
        of[(self.next() % of.len() as u64) as usize]
    }
    fn coin(&mut self) -> bool {
        self.next() & 1 == 1
    }
    fn filter(&mut self, max_hz: f64) -> FilterConfig {
        match self.next() % 3 {
            0 => FilterConfig::None,
            1 => FilterConfig::FirstOrder {
                corner_hz: self.log(1.0, max_hz),
            },
            _ => FilterConfig::SecondOrder {
                corner_hz: self.log(1.0, max_hz),
                q: self.log(0.1, 10.0),
            },
        }
    }
}

/// Every float of `v` (a table of fault limits) scaled by its own random factor, so that
/// the fault keys are random too, whatever they are named.
fn scale_floats(v: &mut Value, rng: &mut Rng) {
    match v {
        Value::Float(f) => *f = f64::from((*f as f32) * rng.log(0.5, 2.0)),
        Value::Table(t) => t.iter_mut().for_each(|(_, v)| scale_floats(v, rng)),
        _ => {}
    }
}

/// A random drive from `base`: every setting drawn over (most of) its range, with random
/// mantissas; `None` when the draw is not a valid drive.
fn random_drive(base: &DriveConfig, rng: &mut Rng) -> Option<DriveConfig> {
    let mut d = *base;
    d.base_speed_rpm = rng.log(10.0, 30_000.0);
    d.encoder_cpr = if rng.coin() {
        1 << rng.pick(&[10u32, 12, 16, 20, 24])
    } else {
        (rng.log(16.0, 16_777_216.0) as u32).max(4)
    };
    d.counter_bits = rng.pick(&[16u8, 20, 24, 32]);
    let (cur, ratio) = (
        rng.pick(&[2000u32, 4000, 5000, 8000, 10_000, 16_000, 20_000]),
        rng.pick(&[1u32, 2, 4, 5, 8]),
    );
    d.current_rate_hz = cur;
    d.velocity_rate_hz = cur / ratio;
    let vel_nyq = std::f64::consts::PI * f64::from(d.velocity_rate_hz);
    let cur_nyq = std::f64::consts::PI * f64::from(d.current_rate_hz);
    d.motor_inertia_s = rng.log(0.005, 5.0);
    d.load_inertia_s = if rng.coin() {
        0.0
    } else {
        rng.log(0.001, 20.0)
    };
    d.position_bandwidth_rad_s = if rng.coin() { 0.0 } else { rng.log(0.5, 80.0) };
    d.velocity_bandwidth_rad_s = rng.log(5.0, 0.3 * vel_nyq);
    d.velocity_damping = rng.log(0.1, 10.0);
    d.velocity_pi_inertia = rng.pick(&[PiInertia::Total, PiInertia::TotalPlusAfb]);
    d.current_bandwidth_rad_s = rng.log(0.5 * f64::from(d.velocity_bandwidth_rad_s), 0.5 * cur_nyq);
    d.winding_resistance_pu = rng.log(0.005, 0.5);
    d.winding_inductance_pu_s = rng.log(1e-5, 1e-2);
    d.torque_limit_pu = rng.log(0.2, 5.0);
    d.voltage_limit_pu = rng.log(0.5, 3.0);
    d.velocity_ff_gain = rng.uniform(0.0, 1.0);
    d.accel_ff_gain = rng.uniform(0.0, 1.0);
    d.velocity_filter = rng.filter(0.45 * f64::from(d.velocity_rate_hz));
    d.velocity_estimator = rng.pick(&[Estimator::Observer, Estimator::Differentiation]);
    let afb = &mut d.accel_feedback;
    afb.mode = rng.pick(&[AfbMode::Off, AfbMode::Plain, AfbMode::Error]);
    afb.gain_fraction = rng.uniform(0.0, 5.0);
    afb.rate = rng.pick(&[AfbRate::Current, AfbRate::Velocity]);
    let afb_rate = match afb.rate {
        AfbRate::Current => d.current_rate_hz,
        AfbRate::Velocity => d.velocity_rate_hz,
    };
    afb.filter = rng.filter(0.45 * f64::from(afb_rate));
    afb.source = rng.pick(&[Estimator::Observer, Estimator::Differentiation]);
    afb.limit_headroom_fraction = if rng.coin() {
        0.0
    } else {
        rng.uniform(0.0, 1.0)
    };
    afb.filter_at_limit = rng.pick(&[AfbFilterAtLimit::Track, AfbFilterAtLimit::Hold]);
    let o = &mut d.observer;
    o.bandwidth_hz = rng.log(5.0, 0.2 * f64::from(d.current_rate_hz));
    o.model_inertia = rng.pick(&[ObserverInertia::Total, ObserverInertia::Motor]);
    o.torque_input = rng.pick(&[ObserverTorque::Command, ObserverTorque::MeasuredCurrent]);
    o.count_interval_counts = if rng.coin() {
        0.0
    } else {
        rng.uniform(0.0, 0.5)
    };
    let mut faults = Value::try_from(d.faults).unwrap();
    scale_floats(&mut faults, rng);
    d.faults = faults.try_into().ok()?;
    d.notch = rng.coin().then(|| {
        let centre_hz = rng.log(1.0, 0.45 * f64::from(d.current_rate_hz));
        NotchConfig {
            centre_hz,
            width_hz: centre_hz * rng.uniform(0.01, 1.0),
            depth_db: rng.uniform(0.0, 80.0),
        }
    });
    if let Some(p) = d.pmsm.as_mut() {
        p.pole_pairs = rng.log(1.0, 50.0) as u32;
        p.d_inductance_pu_s = rng.log(1e-5, 1e-2);
        p.q_inductance_pu_s = p.d_inductance_pu_s * rng.uniform(1.0, 3.0);
        p.flux_linkage_pu = rng.log(0.2, 5.0);
        p.dc_bus_pu = rng.uniform(1.0, 4.0);
        p.encoder_offset_elec_deg = rng.coin().then(|| rng.uniform(-360.0, 360.0));
        p.encoder_reversed = rng.coin();
        p.angle_advance_ticks = rng.uniform(0.0, 4.0);
        p.pwm_period_counts = rng.pick(&[1000u16, 2100, 4200, 8400]);
        p.commutation_min_speed_pu = rng.log(0.001, 1.0);
        p.commutation_trip_s = rng.log(1e-4, 1.0);
    }
    d.validate().is_ok().then_some(d)
}

/// 1,000 random valid drives (a seeded generator), each written on a machine file whose own
/// drive differs, compose back to themselves with the same settings CRC.
#[test]
fn a_thousand_random_valid_drives_compose_back_to_themselves() {
    let docs = machine_docs();
    let bases: Vec<DriveConfig> = docs
        .iter()
        .map(|(_, d)| machine_file::compose(d.clone()).unwrap().drive)
        .collect();
    let mut rng = Rng(0x5eed_d417e);
    let (mut valid, mut drawn, mut crcs, mut pmsm) = (0, 0, 0, 0);
    while valid < 1000 {
        drawn += 1;
        assert!(
            drawn < 200_000,
            "only {valid} valid drives in {drawn} draws"
        );
        let i = (rng.next() % docs.len() as u64) as usize;
        let Some(d) = random_drive(&bases[i], &mut rng) else {
            continue;
        };
        round_trip(
            &format!("random drive {valid} on {}", docs[i].0),
            &docs[i].1,
            &d,
        );
        crcs += usize::from(settings_crc(&d) != 0);
        pmsm += usize::from(d.pmsm.is_some());
        valid += 1;
    }
    eprintln!(
        "{valid} valid drives of {drawn} drawn; {crcs} with a settings encoding; {pmsm} PMSM"
    );
    assert!(pmsm > 200, "{pmsm} PMSM drives");
    // The CRC compared is of a real encoding for most of them (0: the drive has no
    // settings record, e.g. a gain out of the record's format).
    assert!(crcs > 500, "{crcs}");
}
