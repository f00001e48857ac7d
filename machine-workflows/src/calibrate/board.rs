//! The motor calibration on the board (`identify --board` on a PMSM machine, and
//! `stiffdrive board ... calibrate`): the board runs the sequence in its own current-loop
//! interrupt (`pil_link::board::calibrate`, controller-core's sequencer, the one
//! [`super::record_on_plant`] drives on the simulated machine) and streams every tick; the
//! record is estimated here by [`super::estimate()`], the host's one estimation. The
//! calibration is then set on the board's running settings, key by key over the console
//! (`drive.winding_resistance_pu`, `drive.pmsm.pole_pairs`, `.d_inductance_pu_s`,
//! `.q_inductance_pu_s`, `.encoder_reversed`, and last `.encoder_offset_elec_deg`, which
//! lets the drive run), and saved in its settings sector.
//!
//! The sequence's settings are `identify`'s ([`crate::identify::motor::settings_for`]: its
//! defaults at the board's current-loop rate, the voltage within its inverter's linear
//! range, the sweep's speed for the nominal motor), from the drive the board runs, read
//! over the console.

use super::{estimate, MotorEstimates, Record};
use crate::identify::motor::{settings_for, Nominal};
use pil_host::board_calibrate::run_calibrate;
use pil_link::board::client::{BoardClient, BoardError};
use pil_link::board::message::Request;
use pil_link::host::Stream;
use sim_engine::error::{HarnessError, Result};

fn link(what: &str) -> impl Fn(BoardError) -> HarnessError + '_ {
    move |e| match e {
        BoardError::Refused { message, .. } => {
            HarnessError::Backend(format!("board refused {what}: {message}"))
        }
        other => HarnessError::Backend(format!("board calibrate: {what}: {other}")),
    }
}

/// Calibrates the motor of the PMSM drive the board runs (module docs).
///
/// # Errors
/// The board's drive not a PMSM (its refusal says so), a refused or broken run, and the
/// estimation's own (a record that does not show the motor).
pub fn calibrate_on_board(client: &mut BoardClient<Stream>) -> Result<MotorEstimates> {
    let mut get = |key: &str| client.get(key).map_err(link(key));
    let cpr = get("drive.encoder_cpr")?;
    let bits = get("drive.counter_bits")?;
    let nominal = Nominal {
        current_rate_hz: get("drive.current_rate_hz")?,
        dc_bus_pu: get("drive.pmsm.dc_bus_pu")?,
        resistance_pu: get("drive.winding_resistance_pu")?,
        flux_linkage_pu: get("drive.pmsm.flux_linkage_pu")?,
        pole_pairs: get("drive.pmsm.pole_pairs")?,
        base_speed_rpm: get("drive.base_speed_rpm")?,
    };
    let settings = settings_for(&nominal);
    let board = run_calibrate(client, &settings)?;
    estimate(&Record::from_board(&board, cpr as u32, bits as u8))
}

/// Sets the calibration `est` on the board's running settings and saves them (module docs).
///
/// # Errors
/// A key refused (its message names the key and the range), the save refused or failed.
pub fn save_on_board(client: &mut BoardClient<Stream>, est: &MotorEstimates) -> Result<()> {
    let keys = [
        (
            "drive.winding_resistance_pu",
            est.winding_resistance_pu.value,
        ),
        ("drive.pmsm.pole_pairs", f64::from(est.pole_pairs)),
        ("drive.pmsm.d_inductance_pu_s", est.d_inductance_pu_s.value),
        ("drive.pmsm.q_inductance_pu_s", est.q_inductance_pu_s.value),
        (
            "drive.pmsm.encoder_reversed",
            f64::from(u8::from(est.encoder_reversed)),
        ),
        (
            "drive.pmsm.encoder_offset_elec_deg",
            est.encoder_offset_elec_deg.value,
        ),
    ];
    for (key, value) in keys {
        client.set(key, value).map_err(link(key))?;
    }
    client.request(&Request::Save).map_err(link("save"))?;
    Ok(())
}

/// `stiffdrive board ... calibrate`: calibrates, sets and saves; the line to print.
///
/// # Errors
/// As [`calibrate_on_board`] and [`save_on_board`].
pub fn calibrate_action(client: &mut BoardClient<Stream>) -> Result<String> {
    let est = calibrate_on_board(client)?;
    save_on_board(client, &est)?;
    Ok(format!(
        "motor calibrated on the board: {}; set and saved",
        est.describe()
    ))
}
