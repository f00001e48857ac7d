//! The torque-reference notch as the controller runs it (`[drive.notch]`): its attenuation
//! measured through `Controller::current_tick`, its settings' errors, and a fault clearing
//! its state.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use crate::common;

use controller_core::excitation::{ExcitationConfig, ExcitationParams, Injection, Waveform};
use controller_core::notch::NotchDesign;
use controller_core::{
    AfbMode, Controller, CurrentInputs, DriveConfig, Estimator, NotchConfig, Pu, VelocityInputs,
    design,
};

const NAMES: ExcitationParams = ExcitationParams {
    amplitude_pu: "amplitude",
    start_or_bits: "start",
    end_or_hold: "end",
    duration_or_periods: "duration",
};

/// Table 1's drive with the notch `n`, acceleration feedback off and the velocity from the
/// encoder's differences: with the encoder standing still nothing feeds back, and the
/// torque reference is the notch's response to what enters before it.
fn open_loop_drive(n: Option<NotchConfig>) -> DriveConfig {
    let mut cfg = common::table1();
    cfg.accel_feedback.mode = AfbMode::Off;
    cfg.velocity_estimator = Estimator::Differentiation;
    cfg.notch = n;
    cfg
}

/// A tone at `f` Hz on the torque reference for `seconds`: a log chirp over a band of
/// 10^-5·f, i.e. one frequency.
fn tone(f: f32, amplitude: f32, seconds: f32) -> ExcitationConfig {
    ExcitationConfig {
        waveform: Waveform::Chirp {
            start_hz: f,
            end_hz: f * 1.000_01,
            duration_s: seconds,
        },
        amplitude_pu: amplitude,
        injection: Injection::TorqueReference,
    }
}

/// Amplitude of the `f` Hz component of `x` sampled at `rate` Hz (whole periods).
fn component(x: &[f64], f: f64, rate: f64) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        let ph = std::f64::consts::TAU * f * k as f64 / rate;
        s += v * ph.sin();
        c += v * ph.cos();
    }
    2.0 * (s * s + c * c).sqrt() / x.len() as f64
}

/// Runs the drive's ticks (velocity before current, at the file's ratio) with the encoder
/// at rest and the current at zero; returns (excitation added, torque reference) of each
/// current tick after `settle` ticks.
fn run_ticks(c: &mut Controller, ratio: u32, settle: usize, n: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut x, mut y) = (Vec::new(), Vec::new());
    for k in 0..settle + n {
        if (k as u32).is_multiple_of(ratio) {
            let out = c.velocity_tick(VelocityInputs::default());
            assert!(out.fault.is_none());
        }
        let out = c.current_tick(CurrentInputs::default());
        assert!(out.fault.is_none());
        if k >= settle {
            x.push(c.excitation_pu().to_num::<f64>());
            y.push(out.current_ref_pu.to_num::<f64>());
        }
    }
    (x, y)
}

/// The notch's acceptance criterion: a tone at the centre, put on the torque reference before the
/// notch, reaches the current loop attenuated by the configured depth within 1 dB; a tone
/// far below it (10 Hz) passes within 0.1 dB.
#[test]
fn the_notch_in_the_current_tick_attenuates_its_centre_by_its_depth() {
    let cfg0 = open_loop_drive(None);
    let rate = cfg0.current_rate_hz as f64;
    let ratio = cfg0.current_rate_hz / cfg0.velocity_rate_hz;
    for (centre_hz, width_hz, depth_db) in [(100.0, 30.0, 20.0), (62.5, 20.0, 40.0)] {
        let n = NotchConfig {
            centre_hz,
            width_hz,
            depth_db,
        };
        let cfg = open_loop_drive(Some(n));
        let g = design(&cfg).unwrap();
        let d: NotchDesign = g.notch.unwrap();
        for (f, want_db, tol_db) in [
            (f64::from(centre_hz), -f64::from(depth_db), 1.0),
            (10.0, 0.0, 0.1),
        ] {
            let mut c = Controller::from_gains(&g)
                .unwrap()
                .with_excitation(&tone(f as f32, 0.2, 3.0), NAMES)
                .unwrap();
            // 1 s to settle, then 1 s (whole periods of either tone) measured.
            let (x, y) = run_ticks(&mut c, ratio, 4000, 4000);
            let measured_db = 20.0 * (component(&y, f, rate) / component(&x, f, rate)).log10();
            let design_db = 20.0 * d.gain_at(f, rate).log10();
            eprintln!(
                "notch {centre_hz} Hz/{width_hz} Hz/{depth_db} dB, tone {f} Hz: measured \
                 {measured_db:.3} dB, design {design_db:.3} dB"
            );
            assert!(
                (measured_db - want_db).abs() < tol_db,
                "{f} Hz: {measured_db} dB, want {want_db} ± {tol_db}"
            );
        }
    }
}

/// Without a notch the same tone reaches the torque reference unchanged, sample by sample.
#[test]
fn without_a_notch_the_torque_reference_is_the_sum_itself() {
    let cfg = open_loop_drive(None);
    assert!(design(&cfg).unwrap().notch.is_none());
    let mut c = Controller::new(&cfg)
        .unwrap()
        .with_excitation(&tone(100.0, 0.2, 1.0), NAMES)
        .unwrap();
    let (x, y) = run_ticks(&mut c, 2, 0, 2000);
    assert_eq!(x, y);
}

/// A fault drops the torque reference to zero and the notch's memory with it: after a reset
/// the controller repeats a fresh one's outputs bit for bit.
#[test]
fn a_fault_clears_the_notch_and_a_reset_starts_it_afresh() {
    let cfg = open_loop_drive(Some(NotchConfig {
        centre_hz: 80.0,
        width_hz: 40.0,
        depth_db: 30.0,
    }));
    let e = tone(80.0, 0.3, 1.0);
    let fresh = || {
        Controller::new(&cfg)
            .unwrap()
            .with_excitation(&e, NAMES)
            .unwrap()
    };
    let mut c = fresh();
    let _ = run_ticks(&mut c, 2, 0, 777);
    let out = c.velocity_tick(VelocityInputs {
        fault_input: true,
        ..VelocityInputs::default()
    });
    assert!(out.fault.is_some());
    let out = c.current_tick(CurrentInputs::default());
    assert_eq!(out.current_ref_pu, Pu::ZERO);
    c.reset();
    let mut f = fresh();
    assert_eq!(run_ticks(&mut c, 2, 0, 1500), run_ticks(&mut f, 2, 0, 1500));
}

/// Each bad `notch.*` value is refused naming its key, with the allowed range in the text.
#[test]
fn bad_notch_settings_name_the_key_and_the_range() {
    let base = NotchConfig {
        centre_hz: 100.0,
        width_hz: 30.0,
        depth_db: 20.0,
    };
    let with = |f: fn(&mut NotchConfig)| {
        let mut n = base;
        f(&mut n);
        open_loop_drive(Some(n))
    };
    let cases: [(DriveConfig, &str, &str); 8] = [
        (with(|n| n.centre_hz = 0.0), "notch.centre_hz", "(0, "),
        (with(|n| n.centre_hz = -5.0), "notch.centre_hz", "(0, "),
        (with(|n| n.centre_hz = 2000.0), "notch.centre_hz", "2000"),
        (
            with(|n| n.centre_hz = f32::NAN),
            "notch.centre_hz",
            "(0, 1999.9",
        ),
        (with(|n| n.width_hz = 0.0), "notch.width_hz", "(0, "),
        (with(|n| n.width_hz = 150.0), "notch.width_hz", "(0, 100]"),
        (with(|n| n.depth_db = -1.0), "notch.depth_db", "[0, 80]"),
        (with(|n| n.depth_db = 80.5), "notch.depth_db", "[0, 80]"),
    ];
    for (cfg, key, range) in cases {
        let e = cfg.validate().unwrap_err();
        assert_eq!(e.param(), key, "{:?}", cfg.notch);
        let text = e.to_string();
        assert!(text.contains(key) && text.contains(range), "{text}");
        // (By its text: a NaN value is not equal to itself.)
        assert_eq!(design(&cfg).unwrap_err().to_string(), text);
        assert!(Controller::new(&cfg).is_err());
    }
    // The edges of the ranges are accepted.
    for n in [
        NotchConfig {
            width_hz: 100.0,
            ..base
        },
        NotchConfig {
            depth_db: 0.0,
            ..base
        },
        NotchConfig {
            depth_db: 80.0,
            centre_hz: 1999.0,
            ..base
        },
    ] {
        assert!(Controller::new(&open_loop_drive(Some(n))).is_ok(), "{n:?}");
    }
}

/// `[notch]` in the drive's TOML: absent is no notch, present needs its three keys and
/// refuses any other.
#[test]
fn the_notch_table_in_toml() {
    let base = common::TABLE1_TOML;
    assert_eq!(common::table1().notch, None);
    let with = |t: &str| common::try_drive_of(&format!("{base}\n[drive.notch]\n{t}\n"));
    let cfg = with("centre_hz = 65.0\nwidth_hz = 25\ndepth_db = 30.0").unwrap();
    assert_eq!(
        cfg.notch,
        Some(NotchConfig {
            centre_hz: 65.0,
            width_hz: 25.0,
            depth_db: 30.0
        })
    );
    let e = with("centre_hz = 65.0\nwidth_hz = 25\ndepth_db = 30.0\nq = 2").unwrap_err();
    assert!(
        e.contains("unknown field `q`") && e.contains("centre_hz"),
        "{e}"
    );
    let e = with("centre_hz = 65.0\nwidth_hz = 25").unwrap_err();
    assert!(e.contains("depth_db"), "{e}");
    // It survives a round trip, and a drive without one writes no table.
    let text = toml::to_string(&cfg).unwrap();
    assert_eq!(toml::from_str::<DriveConfig>(&text).unwrap(), cfg);
    assert!(
        !toml::to_string(&common::table1())
            .unwrap()
            .contains("notch")
    );
}
