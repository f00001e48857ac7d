//! Loop-in-the-loop of a PMSM drive on the host: the recording `lil/inputs-pmsm.csv`
//! (`lil-record` with table1-pmsm.toml baked: the App's PMSM tick around plant-host's PMSM)
//! is a real run, and the firmware's tick code (App::on_pmsm_tick with its board stand-in)
//! reproduces the bare host controller-core on it bit for bit. `cargo fw-lil` with
//! `STIFFDRIVE_DRIVE=configs/machines/table1-pmsm.toml` runs the same on the Cortex-M4F.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use controller_core::{DriveConfig, PmsmOutputs, Pu, VelocityOutputs};
use firmware::app::{App, DEFAULT_TRACE};
use firmware::lil::{self, words};
use words::PmsmLilInput;

const RECORDING: &str = include_str!("../lil/inputs-pmsm.csv");

fn records() -> Vec<PmsmLilInput> {
    RECORDING
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("period") && !l.trim().is_empty())
        .enumerate()
        .map(|(k, l)| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 5, "line {l}");
            assert_eq!(f[0].parse::<usize>().unwrap(), k, "periods in order");
            PmsmLilInput {
                encoder_count: f[1].parse().unwrap(),
                phase_current_pu: [
                    Pu::from_bits(f[2].parse().unwrap()),
                    Pu::from_bits(f[3].parse().unwrap()),
                ],
                fault_input: f[4] == "1",
            }
        })
        .collect()
}

fn drive() -> DriveConfig {
    firmware::drive::reference_pmsm().unwrap()
}

fn bytes(recs: &[PmsmLilInput]) -> Vec<u8> {
    recs.iter().flat_map(|r| r.to_bytes()).collect()
}

/// The host core's words on the recording, and each current tick's outputs.
fn reference(cfg: &DriveConfig, recs: &[PmsmLilInput]) -> (Vec<u8>, Vec<PmsmOutputs>) {
    let mut expected = Vec::new();
    let mut ticks = Vec::new();
    words::reference_run_pmsm(cfg, recs.iter().copied(), |w| {
        if w.len() == PmsmOutputs::WORDS {
            ticks.push(PmsmOutputs::from_words(w.try_into().unwrap()).unwrap());
        } else {
            assert_eq!(w.len(), VelocityOutputs::WORDS);
        }
        expected.extend(w.iter().flat_map(|x| x.to_le_bytes()));
    })
    .unwrap();
    (expected, ticks)
}

fn replay(cfg: &DriveConfig, inputs: &[u8], expected: &[u8]) -> lil::ReplayReport {
    let mut app = App::new_pmsm(cfg, cfg.counter_bits, DEFAULT_TRACE).unwrap();
    app.set_enable_request(true);
    let mut profile = controller_core::Profile::new(&words::profile_config(), cfg).unwrap();
    lil::replay_pmsm(
        &mut app,
        &mut profile,
        words::tick_ratio(cfg),
        inputs,
        expected,
    )
}

/// The recording is a run of the drive, not a still one: the stage on, the motor through a
/// few turns and across the counter's wrap, the q current to its limit both ways, and
/// the external fault at the end.
#[test]
fn the_pmsm_recording_is_a_real_run() {
    let recs = records();
    assert_eq!(recs.len(), 4400);
    let cfg = drive();
    let (_, ticks) = reference(&cfg, &recs);
    let enabled = ticks.iter().filter(|o| o.enabled).count();
    assert!(enabled >= 4300, "enabled {enabled}");
    let iq: Vec<f64> = ticks.iter().map(|o| o.current.q.to_num()).collect();
    let (lo, hi) = iq
        .iter()
        .fold((0.0_f64, 0.0_f64), |(l, h), &x| (l.min(x), h.max(x)));
    assert!(hi > 1.5 && lo < -1.5, "i_q spans {lo}..{hi} pu");
    // Every phase current code moves (no stuck channel), and i_d stays near zero.
    for ph in 0..2 {
        let distinct: std::collections::BTreeSet<i32> = recs
            .iter()
            .map(|r| r.phase_current_pu[ph].to_bits())
            .collect();
        assert!(distinct.len() > 500, "phase {ph}: {} codes", distinct.len());
    }
    let id_max = ticks
        .iter()
        .take(4300)
        .map(|o| o.current.d.to_num::<f64>().abs())
        .fold(0.0, f64::max);
    assert!(id_max < 0.1, "|i_d| up to {id_max} pu");
    // The counter wraps (65,535 → 0) and the motor turns more than four revolutions.
    let wraps = recs
        .windows(2)
        .filter(|w| w[0].encoder_count > 60_000 && w[1].encoder_count < 5_000)
        .count();
    assert!(wraps >= 1);
    let travel: i64 = recs
        .windows(2)
        .map(|w| i64::from(w[1].encoder_count.wrapping_sub(w[0].encoder_count) as u16 as i16))
        .sum();
    assert!(travel > 4 * 4096, "travel {travel} counts");
    assert!(recs[4300..].iter().all(|r| r.fault_input));
    assert!(recs[..4300].iter().all(|r| !r.fault_input));
    assert_eq!(
        ticks.last().unwrap().fault,
        Some(controller_core::Fault::External)
    );
    assert!(ticks.iter().take(4300).all(|o| o.fault.is_none()));
}

#[test]
fn the_app_pmsm_path_matches_the_host_core_bit_for_bit() {
    let recs = records();
    let cfg = drive();
    let (expected, _) = reference(&cfg, &recs);
    let report = replay(&cfg, &bytes(&recs), &expected);
    assert_eq!(report.periods, 4400);
    // 13 words per current tick, 8 per velocity tick (every 2nd period).
    assert_eq!(report.words, 4400 * 13 + 2200 * 8);
    assert_eq!(report.missing_words, 0);
    assert_eq!(report.mismatches, 0, "first: {:?}", report.first_mismatch);
    assert!(report.enabled_ticks >= 4300, "{}", report.enabled_ticks);
    assert_eq!(report.final_fault, Some(controller_core::Fault::External));
}

#[test]
fn a_flipped_duty_bit_is_caught() {
    let recs = records();
    let cfg = drive();
    let (mut expected, _) = reference(&cfg, &recs);
    // Period 2001's current tick: after 2001 current and 1000 velocity ticks; its duty b.
    let word = 2001 * 13 + 1000 * 8 + 1;
    expected[word * 4] ^= 1;
    let report = replay(&cfg, &bytes(&recs), &expected);
    assert_eq!(report.mismatches, 1);
    let m = report.first_mismatch.unwrap();
    assert_eq!((m.period, m.word), (2001, word as u32));
    assert_eq!(m.expected ^ m.actual, 1);
}

#[test]
fn pmsm_records_round_trip() {
    let rec = PmsmLilInput {
        encoder_count: 0xFFFE,
        phase_current_pu: [Pu::from_bits(-12345), Pu::from_bits(678)],
        fault_input: true,
    };
    assert_eq!(PmsmLilInput::from_bytes(&rec.to_bytes()), Ok(rec));
    let b = rec.to_bytes();
    assert_eq!(b[4..8], (-12345_i32).to_le_bytes());
    let mut bad = b;
    bad[12] = 2;
    assert!(PmsmLilInput::from_bytes(&bad).is_err());
}
