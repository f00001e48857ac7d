//! Loop-in-the-loop on the host: the firmware's tick code (App with its board stand-in)
//! must reproduce, bit for bit, the bare host controller-core on the recorded sequence.
//! The same comparison runs on the Cortex-M4F under QEMU in `cargo fw-lil`.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use firmware::app::{App, DEFAULT_TRACE};
use firmware::lil::{self, words};

#[test]
fn app_path_matches_host_core_bit_for_bit() {
    let report = lil::replay_embedded().unwrap();
    assert_eq!(report.periods, 4400, "recording length");
    // 4 words per current tick, 8 per velocity tick (every 2nd period).
    assert_eq!(report.words, 4400 * 4 + 2200 * 8);
    assert_eq!(report.missing_words, 0);
    assert_eq!(report.mismatches, 0, "first: {:?}", report.first_mismatch);
    // The run is not trivial: the stage ran, and the recorded fault input latched at the end.
    assert!(
        report.enabled_ticks > 4000,
        "enabled {}",
        report.enabled_ticks
    );
    assert_eq!(controller_core::words::fault_code(report.final_fault), 4);
}

#[test]
fn a_single_flipped_bit_is_caught() {
    let cfg = firmware::drive::baked().unwrap();
    let mut app = App::new(&cfg, cfg.counter_bits, DEFAULT_TRACE).unwrap();
    app.set_enable_request(true);
    let mut profile = controller_core::Profile::new(&words::profile_config(), &cfg).unwrap();
    let mut expected = lil::EXPECTED.to_vec();
    // Flip the LSB of the voltage command of period 2000's current tick.
    let word = 2000 * 4 + 1000 * 8;
    expected[word * 4] ^= 1;
    let report = lil::replay(&mut app, &mut profile, 2, lil::INPUTS, &expected);
    assert_eq!(report.mismatches, 1);
    let m = report.first_mismatch.unwrap();
    assert_eq!((m.period, m.word), (2000, word as u32));
    assert_eq!(m.expected ^ m.actual, 1);
}

#[test]
fn records_round_trip() {
    let rec = words::LilInput {
        encoder_count: 0xFFFE,
        current_pu: controller_core::Pu::from_bits(-12345),
        fault_input: true,
    };
    assert_eq!(words::LilInput::from_bytes(&rec.to_bytes()), Ok(rec));
    // The same bytes as before the words were shared: encoder, current, fault input, LE.
    let b = rec.to_bytes();
    assert_eq!(b[..4], 0xFFFE_u32.to_le_bytes());
    assert_eq!(b[4..8], (-12345_i32).to_le_bytes());
    assert_eq!(b[8..], 1_u32.to_le_bytes());
    let mut bad = b;
    bad[8] = 2;
    assert!(words::LilInput::from_bytes(&bad).is_err());
}

#[test]
fn the_baked_drive_decodes_and_a_corrupt_one_is_an_error_not_a_panic() {
    let cfg = firmware::drive::baked().unwrap();
    assert!(controller_core::design(&cfg).is_ok());
    assert_eq!(firmware::drive::BAKED.len(), pil_link::settings::LEN);
    // A truncated or garbled payload is rejected.
    let bytes = firmware::drive::BAKED;
    assert!(pil_link::settings::decode(&bytes[..bytes.len() - 1]).is_err());
    let mut bad = bytes.to_vec();
    // The velocity_pi_inertia enum byte (after 5 + 5 scalar fields): no such variant.
    bad[4 + 4 + 1 + 4 + 4 + 5 * 4] = 7;
    assert!(pil_link::settings::decode(&bad).is_err());
}
