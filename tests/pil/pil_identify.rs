//! The identification's frequency-response measurement through the firmware in QEMU:
//! the PRBS on the torque reference, as `identify` runs it on
//! `configs/machines/table1.toml` (one PRBS period instead of 32, Welch segments of 2048 samples),
//! travels to the firmware in the `Config` frame, the firmware's own controller adds it,
//! and the record (excitation, torque reference, measured current, encoder counts) is the
//! host loop's bit for bit, tick for tick; so are every controller output and the fitted
//! estimates. Like the `pil` module, this builds the ARM image and runs QEMU (never skipped); its
//! cases run in `qemu_sessions` (`cargo test --test pil`), with the binary's other QEMU cases.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use controller_core::excitation::Waveform;
use machine_workflows::identify::measure::{
    excited_controller, frequency_response_setup, frequency_response_tail, record, Record,
    FREQUENCY_RESPONSE,
};
use machine_workflows::identify::{fit_response, load};
use pil_host::{build_pil_image, with_firmware, PilRun, Recorder, TickLog};

/// The `identify` settings of the shortened run.
const SETS: [&str; 2] = ["identify.prbs_periods=1", "identify.segment_len=2048"];

/// Every recorded signal as raw f64 bits, tick by tick: the first index that differs.
fn first_difference(host: &Record, pil: &Record) -> Option<(&'static str, usize)> {
    let signals = [
        ("excitation", &host.excitation, &pil.excitation),
        ("current", &host.current, &pil.current),
        ("torque_ref", &host.torque_ref, &pil.torque_ref),
        ("counts", &host.counts, &pil.counts),
    ];
    signals.into_iter().find_map(|(name, h, p)| {
        let n = h.len().max(p.len());
        (0..n)
            .find(|&i| h.get(i).map(|x| x.to_bits()) != p.get(i).map(|x| x.to_bits()))
            .map(|i| (name, i))
    })
}

pub(crate) fn the_frequency_response_record_through_the_firmware_is_the_host_record_bit_for_bit() {
    fw_runner::provision::ensure_qemu().unwrap();
    let (base, spec) = load("configs/machines/table1.toml", &SETS.map(String::from)).unwrap();
    let (cfg, excitation) = frequency_response_setup(&base, &spec).unwrap();
    // 8191 PRBS bits of one tick each at 4 kHz.
    let ticks = 8191;
    assert_eq!(spec.prbs_ticks(), ticks);

    let mut host = Recorder {
        inner: excited_controller(&cfg, &excitation).unwrap(),
        log: TickLog::default(),
    };
    let host_rec = record(&cfg, &mut host, FREQUENCY_RESPONSE).unwrap();

    let dir = tempfile::tempdir().unwrap();
    let mut args = PilRun::new("identify", dir.path());
    args.elf = Some(build_pil_image().unwrap());
    let (pil_rec, pil_log) = with_firmware(&args, &cfg, Some(&excitation), |fw| {
        let rec = record(&cfg, fw, FREQUENCY_RESPONSE)?;
        Ok((rec, fw.log().clone()))
    })
    .unwrap();

    // Every current tick recorded on both sides, and the excitation really on.
    assert_eq!(host_rec.counts.len(), ticks as usize);
    assert_eq!(pil_rec.counts.len(), ticks as usize);
    let amplitude = spec.amplitude_pu;
    assert!(
        pil_rec
            .excitation
            .iter()
            .all(|&e| (e.abs() - amplitude).abs() < 1e-4),
        "the PRBS is ±{amplitude} pu on every tick"
    );
    assert!(
        pil_rec.excitation.iter().any(|&e| e > 0.0) && pil_rec.excitation.iter().any(|&e| e < 0.0)
    );
    assert_eq!(first_difference(&host_rec, &pil_rec), None);
    // Every controller input and output of every tick, raw fixed-point bits.
    assert_eq!(pil_log.current.len(), ticks as usize);
    assert_eq!(pil_log.velocity.len(), host.log.velocity.len());
    assert!(pil_log == host.log, "controller ticks differ");

    // The estimates from the two records (after the settling, as identify takes them).
    let host_fit = fit_response(
        &base,
        &spec,
        &frequency_response_tail(&cfg, &spec, &host_rec),
    );
    let pil_fit = fit_response(
        &base,
        &spec,
        &frequency_response_tail(&cfg, &spec, &pil_rec),
    );
    let (response, fit) = pil_fit.as_ref().expect("the PIL record fits");
    assert!(!response.freq_hz.is_empty());
    assert!(fit.fit.motor_inertia_s.is_finite());
    assert_eq!(format!("{host_fit:?}"), format!("{pil_fit:?}"));

    let log = std::fs::read(dir.path().join("firmware.defmt")).unwrap();
    assert!(!log.is_empty());
}

pub(crate) fn the_firmware_refuses_a_bad_excitation_with_a_config_fault() {
    fw_runner::provision::ensure_qemu().unwrap();
    let (base, spec) = load("configs/machines/table1.toml", &SETS.map(String::from)).unwrap();
    let (cfg, mut excitation) = frequency_response_setup(&base, &spec).unwrap();
    // A 3-bit LFSR is outside 7..=20: controller-core refuses it, and so must the firmware.
    excitation.waveform = Waveform::Prbs {
        bits: 3,
        hold_ticks: 1,
        periods: 1,
    };
    assert!(excited_controller(&cfg, &excitation).is_err());
    let dir = tempfile::tempdir().unwrap();
    let mut args = PilRun::new("identify", dir.path());
    args.elf = Some(build_pil_image().unwrap());
    let mut ran = false;
    let e = with_firmware(&args, &cfg, Some(&excitation), |_| {
        ran = true;
        Ok(())
    })
    .expect_err("a bad excitation was accepted");
    assert!(!ran, "the run started on a refused configuration");
    let text = e.to_string();
    assert!(
        text.starts_with("PIL config: firmware latched its safe state: Config"),
        "{text}"
    );
}
