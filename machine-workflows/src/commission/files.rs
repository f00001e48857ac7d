//! The machine files `commission` writes besides its report: `identified.toml`,
//! `notched.toml` (with a notch placed), `drive.toml` and `runner-up.toml`, each with the
//! settings CRC of the drive it composes to ([`WrittenFile`]).

use crate::identify::{self, lost_motion::identified_mechanics};
use crate::tune;
use controller_core::{DriveConfig, NotchConfig};
use sim_engine::config::{config_path, overrides, read_table, RunConfig};
use sim_engine::error::{HarnessError, Result};
use std::path::Path;
use toml::{Table, Value};

/// A machine file `commission` wrote, with the drive it composes to.
#[derive(Clone, Debug, serde::Serialize)]
pub struct WrittenFile {
    /// Its path below the output folder.
    pub name: String,
    /// The settings CRC of the drive it composes to, as the board logs it at boot
    /// (`settings crc …`, 8 hex digits).
    pub settings_crc: String,
    /// The file, plant and drive, is the machine's and its drive ran there (section 3).
    pub verified_on_machine: bool,
    /// What it is.
    pub what: String,
}

impl WrittenFile {
    pub(super) fn new(
        name: &str,
        drive: &DriveConfig,
        verified_on_machine: bool,
        what: String,
    ) -> Self {
        Self {
            name: name.into(),
            settings_crc: format!("{:08x}", tune::output::settings_crc(drive)),
            verified_on_machine,
            what,
        }
    }
}

/// The files `commission` tells the user about: `drive.toml` and `runner-up.toml`, the
/// machine file `config` as given (with `sets` applied) with the whole `[drive]` of the
/// chosen design and of the other kind's ([`tune::output::drive_file`]): what `run
/// --config` and `flash --config` take on this machine, composing to the drive verified
/// there. Their names, texts and entries for `commission.md`.
pub(super) fn drive_files(
    machine: &Table,
    config: &Path,
    pair: &tune::pair::Pair,
    passed: bool,
) -> Result<Vec<(&'static str, String, WrittenFile)>> {
    let (chosen, other) = pair.chosen();
    let label = |t: &tune::Tuned| {
        let c = &t.result.design.candidate;
        format!("{} rad/s, {}", c.bandwidth_rad_s, c.afb.label())
    };
    let config = config.display();
    let verdict = if passed {
        "it passed there: the drive to flash (commission.md)"
    } else {
        "it did NOT pass there: do not flash it (commission.md)"
    };
    [
        (
            "drive.toml",
            chosen,
            format!(
                "Verified on the machine: `hil-harness commission`: {config} as given with \
                 the whole [drive] of the chosen design ({}); {verdict}.",
                label(chosen)
            ),
            format!(
                "the machine file with the chosen design ({})",
                label(chosen)
            ),
        ),
        (
            "runner-up.toml",
            other,
            format!(
                "Verified on the machine, not chosen: `hil-harness commission`: {config} as \
                 given with the whole [drive] of the best design of the other kind ({}); \
                 commission.md compares it with drive.toml.",
                label(other)
            ),
            format!(
                "the machine file with the best design of the other kind ({})",
                label(other)
            ),
        ),
    ]
    .into_iter()
    .map(|(name, t, header, what)| {
        let drive = &t.tuned.drive;
        let text = tune::output::drive_file(machine.clone(), drive, &header)?;
        Ok((name, text, WrittenFile::new(name, drive, true, what)))
    })
    .collect()
}

/// The machine file `config` as given, with `sets` applied.
pub(super) fn machine_doc(config: &str, sets: &[String]) -> Result<Table> {
    let mut doc = read_table(&config_path(config)?)?;
    overrides::apply_all(&mut doc, sets)?;
    Ok(doc)
}

/// `machine` ([`machine_doc`]) with its `[plant]` table replaced by the identified one.
pub(super) fn identified_doc(
    mut doc: Table,
    base: &RunConfig,
    ident: &identify::Identification,
) -> Result<Table> {
    // The measurement's own settings are not part of the machine.
    doc.remove("identify");
    let plant = identified_mechanics(base, &ident.fit.fit, ident.lost_motion.backlash_deg);
    let table = Value::try_from(plant)
        .map_err(|e| HarnessError::Backend(format!("identified.toml: {e}")))?;
    doc.insert("plant".into(), table);
    if let Some(m) = &ident.motor {
        set_calibration(&mut doc, m)?;
    }
    Ok(doc)
}

/// The `[drive.pmsm]` keys a calibration sets (each also allowed straight in `[drive]`).
const CALIBRATED_PMSM_KEYS: [&str; 5] = [
    "pole_pairs",
    "d_inductance_pu_s",
    "q_inductance_pu_s",
    "encoder_offset_elec_deg",
    "encoder_reversed",
];

/// `x` as the drive reads it, an `f32`: its shortest decimal that reads back to that `f32`.
fn f32_value(x: f64) -> Value {
    let y = x as f32;
    Value::Float(y.to_string().parse::<f64>().unwrap_or(f64::from(y)))
}

/// The table `key` of `doc`, created when absent.
fn table_mut<'a>(doc: &'a mut Table, key: &str) -> Result<&'a mut Table> {
    match doc.entry(key).or_insert_with(|| Value::Table(Table::new())) {
        Value::Table(t) => Ok(t),
        _ => Err(HarnessError::config(key, "must be a table")),
    }
}

/// A PMSM's calibration into a machine file's tree: the model's `[electrics]` takes the
/// measured motor (R, L_d, L_q, pole pairs, encoder offset), the drive its
/// `winding_resistance_pu` and `[drive.pmsm]` keys (the file's own, in `[drive.pmsm]` or
/// straight in `[drive]`, replaced), so the drive composes to [`identify::motor::calibrated`].
pub(super) fn set_calibration(doc: &mut Table, m: &crate::calibrate::MotorEstimates) -> Result<()> {
    let electrics = table_mut(doc, "electrics")?;
    for (key, v) in [
        ("winding_resistance_pu", m.winding_resistance_pu.value),
        ("d_inductance_pu_s", m.d_inductance_pu_s.value),
        ("q_inductance_pu_s", m.q_inductance_pu_s.value),
        ("encoder_offset_elec_deg", m.encoder_offset_elec_deg.value),
    ] {
        electrics.insert(key.into(), Value::Float(v));
    }
    electrics.insert("pole_pairs".into(), Value::Integer(i64::from(m.pole_pairs)));
    let drive = table_mut(doc, "drive")?;
    drive.insert(
        "winding_resistance_pu".into(),
        f32_value(m.winding_resistance_pu.value),
    );
    for key in CALIBRATED_PMSM_KEYS {
        drive.remove(key);
    }
    let pmsm = table_mut(drive, "pmsm")?;
    pmsm.insert("pole_pairs".into(), Value::Integer(i64::from(m.pole_pairs)));
    pmsm.insert(
        "d_inductance_pu_s".into(),
        f32_value(m.d_inductance_pu_s.value),
    );
    pmsm.insert(
        "q_inductance_pu_s".into(),
        f32_value(m.q_inductance_pu_s.value),
    );
    pmsm.insert(
        "encoder_offset_elec_deg".into(),
        f32_value(m.encoder_offset_elec_deg.value),
    );
    pmsm.insert(
        "encoder_reversed".into(),
        Value::Boolean(m.encoder_reversed),
    );
    Ok(())
}

/// A model's machine file text (not verified on the machine): the comment line `header`,
/// the settings CRC of its drive, then `doc`; and the drive it composes to.
pub(super) fn render(name: &str, header: &str, doc: &Table) -> Result<(String, DriveConfig)> {
    let body = toml::to_string(doc).map_err(|e| HarnessError::Backend(format!("{name}: {e}")))?;
    let (_, drive) = sim_engine::config::machine(doc.clone())?;
    Ok((
        format!(
            "# NOT verified on the machine (a model only): `hil-harness commission`: {header}\n\
             # settings crc {:08x}: the board logs it at boot for the drive it runs.\n{body}",
            tune::output::settings_crc(&drive)
        ),
        drive,
    ))
}

/// `doc` with its whole `[drive]` stated, `[drive.notch]` set to `notch`; and that drive.
pub(super) fn with_notch(doc: Table, notch: &NotchConfig) -> Result<(Table, DriveConfig)> {
    let (_, mut drive) = sim_engine::config::machine(doc.clone())?;
    drive.notch = Some(*notch);
    Ok((tune::output::with_drive(doc, &drive)?, drive))
}

/// Every machine file written, in the order `commission.md` lists them: `identified.toml`
/// (`identified`), `notched.toml` (`notched`, with a notch placed), `tune/`'s copies of the
/// two designs in the identified model (`tuned_on`, its name), then the `drives`
/// ([`drive_files`]).
pub(super) fn listed(
    identified: &WrittenFile,
    notched: Option<&WrittenFile>,
    pair: &tune::pair::Pair,
    tuned_on: &str,
    drives: &[(&'static str, String, WrittenFile)],
) -> Vec<WrittenFile> {
    let (chosen, other) = pair.chosen();
    let mut files = vec![identified.clone()];
    files.extend(notched.cloned());
    for (name, t, what) in [
        (super::MODEL_FILES.chosen, chosen, "the chosen design"),
        (
            super::MODEL_FILES.runner_up,
            other,
            "the best design of the other kind",
        ),
    ] {
        files.push(WrittenFile::new(
            &format!("tune/{name}"),
            &t.tuned.drive,
            false,
            format!("the identified model ({tuned_on}) with {what}"),
        ));
    }
    files.extend(drives.iter().map(|(_, _, f)| f.clone()));
    files
}
