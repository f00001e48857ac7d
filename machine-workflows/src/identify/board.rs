//! `identify --board --qemu | --port PATH`: the two measurements run by the board in its
//! own loops (`pil_link::board::identify`), the records fed to the same estimation as the
//! simulated machine's ([`super::identify_records`]: H1/Welch, the two-inertia fit, the
//! lost-motion fit, the twin's bias correction).
//!
//! - The frequency-response run: the PRBS of `[identify]` on the torque reference, the rig
//!   preload `identify.preload_pu` on the load, `prbs_ticks` current ticks; the first
//!   `identify.settle_s` are cut as on the host.
//! - The lost-motion test: no excitation, ±`identify.reversal_torque_pu` reversed every
//!   `identify.reversal_hold_s`, three holds.
//!
//! The board streams each record while it takes it and holds only what the link is behind
//! (a ring of 65,536 ticks on the QEMU board), so the runs are identify's own, at their
//! default length too: the same PRBS, bit for bit, as the simulated measurement. A link
//! that falls a ring behind ends the run, and the command fails saying so.
//!
//! Both in speed mode at zero speed, acceleration feedback off, the velocity loop at
//! `identify.velocity_bandwidth_rad_s`. The rig's load torque exists on QEMU (the `board`
//! image's virtual machine takes it); a real board has no rig and ignores it, so there the
//! lost-motion test shows nothing and the preload must come from the machine itself.
//!
//! On a PMSM machine the board first calibrates its motor ([`crate::calibrate::board`]:
//! the sequence in the board's own current loop, the estimation identify's own), sets the
//! calibration on the board and saves it in the settings sector; the two measurements then
//! run on the calibrated drive, as identify's do on the simulated machine, and the
//! calibration is in `identify.json` and `identify.md`.
//!
//! With `--qemu` the image is built with the machine file, so its virtual machine is the
//! file's `[plant]` (and for a PMSM its `[electrics]`; `firmware/build.rs`) and its drive
//! the file's `[drive]`. The board's
//! drive must be the file's where the estimation uses it (rates, encoder, counter, base
//! speed): checked over the console before anything runs. `--set` may change `identify.`
//! keys only: the board's machine and drive are what it carries.

use super::measure::{frequency_response_setup, frequency_response_tail, reversal_load, Record};
use super::{identify_records, load, motor, spec::IdentifySpec, write, Identification};
use crate::calibrate::board::{calibrate_on_board, save_on_board};
use pil_host::board::{with_board, BoardTarget, Machine};
use pil_host::board_identify::{run_identify, BoardRecord};
use pil_link::board::client::BoardClient;
use pil_link::board::identify::IdentifyRun;
use pil_link::host::Stream;
use sim_engine::config::RunConfig;
use sim_engine::error::{HarnessError, Result};
use sim_engine::output::Staging;
use std::path::Path;
use std::time::Duration;

/// The wait for each console reply.
const REPLY_TIMEOUT: Duration = Duration::from_secs(5);

/// The two runs of `spec` on a drive whose current loop runs at `rate_hz`: the
/// frequency response and the lost-motion test.
///
/// # Errors
/// A run longer than a `u32` of ticks.
pub fn board_runs(spec: &IdentifySpec, rate_hz: u32) -> Result<(IdentifyRun, IdentifyRun)> {
    let too_long = |key: &str| HarnessError::config(key, "more current ticks than 2^32");
    let bandwidth = spec.velocity_bandwidth_rad_s as f32;
    let frequency = IdentifyRun {
        amplitude_pu: spec.amplitude_pu as f32,
        prbs_bits: spec.prbs_bits,
        prbs_hold_ticks: spec.prbs_hold_ticks,
        prbs_periods: spec.prbs_periods,
        velocity_bandwidth_rad_s: bandwidth,
        load_pu: spec.preload_pu as f32,
        reverse_every_ticks: 0,
        ticks: u32::try_from(spec.prbs_ticks()).map_err(|_| too_long("identify.prbs_periods"))?,
    };
    let (_, duration_s) = reversal_load(spec);
    let hold = (spec.reversal_hold_s * f64::from(rate_hz)).round() as u32;
    let reversal = IdentifyRun {
        amplitude_pu: 0.0,
        reverse_every_ticks: hold,
        load_pu: spec.reversal_torque_pu as f32,
        ticks: (duration_s * f64::from(rate_hz)) as u32,
        ..frequency
    };
    Ok((frequency, reversal))
}

/// The board's record as the estimators take it: per-unit values from their Q16.16 bits,
/// the encoder counter (`counter_bits` wide) unwrapped.
pub fn to_record(board: &BoardRecord, counter_bits: u8) -> Record {
    let pu = |bits: i32| f64::from(bits) / 65_536.0;
    let span = 1_i64 << counter_bits.clamp(1, 32);
    let mut rec = Record::default();
    let mut unwrapped: Option<(i64, i64)> = None;
    for &[excitation, current, torque_ref, counter] in &board.samples {
        let raw = i64::from(counter as u32) & (span - 1);
        let count = match unwrapped {
            None => raw,
            Some((last_raw, last)) => {
                // The step to the nearest alias: |step| < span / 2 per tick.
                let step = (raw - last_raw).rem_euclid(span);
                last + if step >= span / 2 { step - span } else { step }
            }
        };
        unwrapped = Some((raw, count));
        rec.excitation.push(pu(excitation));
        rec.current.push(pu(current));
        rec.torque_ref.push(pu(torque_ref));
        rec.counts.push(count as f64);
    }
    rec
}

/// Checks that the board's drive is `base`'s where the estimation uses it.
fn check_drive(client: &mut BoardClient<Stream>, base: &RunConfig) -> Result<()> {
    let d = &base.drive;
    let wanted = [
        ("drive.current_rate_hz", f64::from(d.current_rate_hz)),
        ("drive.velocity_rate_hz", f64::from(d.velocity_rate_hz)),
        ("drive.encoder_cpr", f64::from(d.encoder_cpr)),
        ("drive.counter_bits", f64::from(d.counter_bits)),
        ("drive.base_speed_rpm", f64::from(d.base_speed_rpm)),
    ];
    for (key, value) in wanted {
        let on_board = client
            .get(key)
            .map_err(|e| HarnessError::Backend(format!("board identify: get {key}: {e}")))?;
        if on_board != value {
            return Err(HarnessError::config(
                key,
                format!(
                    "the board runs {on_board}, {} has {value}: identify the board with the \
                     machine file of its drive",
                    base.config_path.display()
                ),
            ));
        }
    }
    Ok(())
}

/// What the board measured: a PMSM's calibration, the drive calibrated by it, the two
/// records.
struct OnBoard {
    motor: Option<crate::calibrate::MotorEstimates>,
    base: RunConfig,
    rec: Record,
    reversal: Record,
}

/// On the board: a PMSM's motor calibration (set and saved), then the two records with the
/// drive calibrated by it.
fn on_board(
    client: &mut BoardClient<Stream>,
    base: &RunConfig,
    spec: &IdentifySpec,
) -> Result<OnBoard> {
    client
        .wait_ready(Duration::from_secs(10), Duration::from_millis(300))
        .map_err(|e| HarnessError::Backend(format!("board identify: {e}")))?;
    check_drive(client, base)?;
    let motor = match base.drive.pmsm {
        Some(_) => {
            let est = calibrate_on_board(client)?;
            save_on_board(client, &est)?;
            Some(est)
        }
        None => None,
    };
    let base = motor::with_calibration(base, motor.as_ref())?;
    let (rec, reversal) = measure_on_board(client, &base, spec)?;
    Ok(OnBoard {
        motor,
        base,
        rec,
        reversal,
    })
}

/// The two records from the board: the frequency response after its settling, the
/// lost-motion test whole.
fn measure_on_board(
    client: &mut BoardClient<Stream>,
    base: &RunConfig,
    spec: &IdentifySpec,
) -> Result<(Record, Record)> {
    let (cfg, _) = frequency_response_setup(base, spec)?;
    let (frequency, reversal) = board_runs(spec, base.drive.current_rate_hz)?;
    let bits = base.drive.counter_bits;
    let rec = to_record(&run_identify(client, &frequency)?, bits);
    let rev = to_record(&run_identify(client, &reversal)?, bits);
    Ok((frequency_response_tail(&cfg, spec, &rec), rev))
}

/// Where `target` is, as `identify.md` says it.
fn describe(target: &BoardTarget) -> String {
    match target {
        BoardTarget::Qemu { .. } => {
            "the board: the `board` image in QEMU mps2-an386, its virtual machine built from \
             the machine file (`stiffdrive identify --board --qemu`)"
                .into()
        }
        BoardTarget::Port { path, .. } => format!("the board at {}", path.display()),
    }
}

/// `stiffdrive identify --board`: measures on the board at `target` (for `Qemu`, its
/// `drive` is set to `config`'s file), fits, writes `out` as `identify` does.
///
/// # Errors
/// A `--set` of another key than `identify.`, the board's drive not the file's, a refused
/// or broken run, and identify's own.
pub fn identify_board(
    config: &str,
    sets: &[String],
    out: &Path,
    target: &BoardTarget,
) -> Result<String> {
    if let Some(s) = sets
        .iter()
        .find(|s| !s.trim_start().starts_with("identify."))
    {
        return Err(HarnessError::config(
            "--set",
            format!("{s}: with --board only identify.* keys may be set (the board carries its own machine and drive)"),
        ));
    }
    let (base, spec) = load(config, sets)?;
    let staging = Staging::new(out)?;
    let target = match target {
        // The `board` image on mps2-an386: the QEMU board with a rig.
        BoardTarget::Qemu { elf, qemu, .. } => BoardTarget::Qemu {
            machine: Machine::Mps2An386,
            elf: elf.clone(),
            drive: Some(crate::flash::drive_file(config)?),
            qemu: qemu.clone(),
        },
        port => port.clone(),
    };
    let m = with_board(&target, REPLY_TIMEOUT, |client| {
        on_board(client, &base, &spec)
    })?;
    let ident = identify_records(&m.base, &spec, &m.rec, &m.reversal, &describe(&target))?;
    let ident = Identification {
        motor: m.motor,
        ..ident
    };
    write::write_all(staging.dir(), &base, &spec, &ident)?;
    staging.commit()?;
    Ok(super::summary(&base, &ident, out))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_counter_unwraps_across_its_wrap_both_ways() {
        let samples = [65_534, 65_535, 0, 2, 65_533, 1]
            .iter()
            .map(|&c| [65_536, 0, 0, c])
            .collect();
        let rec = to_record(
            &BoardRecord {
                rate_hz: 4000,
                samples,
            },
            16,
        );
        assert_eq!(
            rec.counts,
            [65_534.0, 65_535.0, 65_536.0, 65_538.0, 65_533.0, 65_537.0]
        );
        assert_eq!(rec.excitation.first(), Some(&1.0));
    }

    #[test]
    fn the_runs_are_identify_s_measurements() {
        let spec = IdentifySpec::default();
        let (f, r) = board_runs(&spec, 4000).unwrap();
        assert_eq!(u64::from(f.ticks), spec.prbs_ticks());
        assert_eq!((f.load_pu, f.reverse_every_ticks), (0.8, 0));
        assert!(f.excitation().is_some() && r.excitation().is_none());
        // ±0.2 pu reversed every 0.5 s, three holds.
        assert_eq!((r.reverse_every_ticks, r.ticks), (2000, 6000));
        assert_eq!(
            (r.load_at(1999), r.load_at(2000), r.load_at(4000)),
            (0.2, -0.2, 0.2)
        );
    }
}
