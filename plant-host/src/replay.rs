//! Replay a motor/load torque profile through the mechanical plant (the `replay` subcommand).
//!
//! IN.csv: header `t_s,motor_torque_pu,load_torque_pu`; each row's torques act from its time
//! until the next row's. OUT.csv: one row per input row with the state at that row's time,
//! before its torques act. The plant starts at rest with zero twist at the first row's time.

use crate::config::PlantConfig;
use crate::error::PlantError;
use crate::sensors::encoder_count;
use crate::two_inertia::TwoInertiaPlant;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Largest time span of a replay, s (10 simulated minutes; about 2.4 million sub-steps).
pub const MAX_SPAN_S: f64 = 600.0;
/// Allowed range of each input column: time in s, torques in pu (the drive's torque limit
/// is at most 1000 pu, and the plant's state stays finite for any torque in this range over
/// [`MAX_SPAN_S`]).
pub const COLUMN_RANGES: [(&str, f64, f64); 3] = [
    ("t_s", -1.0e6, 1.0e6),
    ("motor_torque_pu", -1000.0, 1000.0),
    ("load_torque_pu", -1000.0, 1000.0),
];

/// The input header, exactly.
pub const REPLAY_INPUT_HEADER: &str = "t_s,motor_torque_pu,load_torque_pu";
/// The output header, exactly.
pub const REPLAY_OUTPUT_HEADER: &str =
    "t_s,motor_pos_rad,load_pos_rad,motor_vel_pu,load_vel_pu,shaft_torque_pu,encoder_count";

/// One input row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TorqueRow {
    /// Time, s.
    pub t_s: f64,
    /// Motor torque from this time on, pu.
    pub motor_torque_pu: f64,
    /// Load torque from this time on, pu.
    pub load_torque_pu: f64,
}

/// One output row: the state at `t_s` before that row's torques act.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StateRow {
    /// Time, s.
    pub t_s: f64,
    /// θm, rad.
    pub motor_pos_rad: f64,
    /// θl (motor side), rad.
    pub load_pos_rad: f64,
    /// ωm, pu.
    pub motor_vel_pu: f64,
    /// ωl, pu.
    pub load_vel_pu: f64,
    /// Ts, pu.
    pub shaft_torque_pu: f64,
    /// floor(θm·cpr/2π).
    pub encoder_count: i64,
}

/// What a replay did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplaySummary {
    /// Rows read and written.
    pub rows: usize,
    /// Simulated span, s.
    pub duration_s: f64,
    /// Lost-motion edge crossings located.
    pub edge_crossings: u64,
}

/// Reads the config and torque profile, simulates, and writes OUT.csv atomically (temporary file
/// + rename). On any error nothing is written.
pub fn replay(
    config_path: &Path,
    torque_csv: &Path,
    out_csv: &Path,
) -> Result<ReplaySummary, PlantError> {
    let config = PlantConfig::from_machine_file(config_path)?;
    let text = std::fs::read_to_string(torque_csv).map_err(|e| io_err(torque_csv, &e))?;
    let rows = parse_torque_csv(&text, torque_csv)?;
    let (states, crossings) = simulate(&config, &rows);
    if let Some(bad) = states.iter().find(|s| !state_is_finite(s)) {
        return Err(PlantError::Csv {
            path: torque_csv.to_path_buf(),
            line: 0,
            message: format!(
                "the plant state is not finite at t_s = {} (nothing written)",
                bad.t_s
            ),
        });
    }
    let mut out = String::with_capacity(states.len() * 120);
    out.push_str(REPLAY_OUTPUT_HEADER);
    out.push('\n');
    for s in &states {
        // `{}` on f64 prints the shortest text that parses back to the same value.
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{}",
            s.t_s,
            s.motor_pos_rad,
            s.load_pos_rad,
            s.motor_vel_pu,
            s.load_vel_pu,
            s.shaft_torque_pu,
            s.encoder_count
        );
    }
    write_atomically(out_csv, out.as_bytes())?;
    Ok(ReplaySummary {
        rows: states.len(),
        duration_s: match (rows.first(), rows.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        },
        edge_crossings: crossings,
    })
}

fn state_is_finite(s: &StateRow) -> bool {
    [
        s.motor_pos_rad,
        s.load_pos_rad,
        s.motor_vel_pu,
        s.load_vel_pu,
        s.shaft_torque_pu,
    ]
    .iter()
    .all(|x| x.is_finite())
}

/// Simulates the rows (already validated) through the mechanics of `config`.
pub fn simulate(config: &PlantConfig, rows: &[TorqueRow]) -> (Vec<StateRow>, u64) {
    let mut plant = TwoInertiaPlant::torque_driven(config);
    let cpr = config.counts_per_rev();
    let mut out = Vec::with_capacity(rows.len());
    let mut prev: Option<&TorqueRow> = None;
    for row in rows {
        if let Some(p) = prev {
            plant.advance(row.t_s - p.t_s, p.motor_torque_pu, p.load_torque_pu);
        }
        out.push(StateRow {
            t_s: row.t_s,
            motor_pos_rad: plant.motor_pos_rad(),
            load_pos_rad: plant.load_pos_rad(),
            motor_vel_pu: plant.motor_vel_pu(),
            load_vel_pu: plant.load_vel_pu(),
            shaft_torque_pu: plant.shaft_torque_pu(),
            encoder_count: encoder_count(plant.motor_pos_rad(), cpr),
        });
        prev = Some(row);
    }
    (out, plant.mode_changes())
}

/// Parses and validates a torque CSV (the `csv` crate; fields trimmed, blank lines
/// skipped): exact header, three finite numbers per row within [`COLUMN_RANGES`], strictly
/// increasing times, at least one row, a span of at most [`MAX_SPAN_S`]. Errors name the
/// line and the column.
pub fn parse_torque_csv(text: &str, path: &Path) -> Result<Vec<TorqueRow>, PlantError> {
    let err = |line: u64, message: String| PlantError::Csv {
        path: path.to_path_buf(),
        line: usize::try_from(line).unwrap_or(usize::MAX),
        message,
    };
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let mut records = reader.records();
    let line_of = |r: &csv::StringRecord| r.position().map_or(0, csv::Position::line);
    let csv_err = |e: csv::Error| err(e.position().map_or(0, csv::Position::line), e.to_string());
    match records.next().transpose().map_err(csv_err)? {
        Some(h) if h.iter().collect::<Vec<_>>().join(",") == REPLAY_INPUT_HEADER => {}
        Some(h) => {
            let found = h.iter().collect::<Vec<_>>().join(",");
            return Err(err(
                line_of(&h),
                format!("header is `{found}`, expected `{REPLAY_INPUT_HEADER}`"),
            ));
        }
        None => {
            return Err(err(
                0,
                format!("empty file, expected header `{REPLAY_INPUT_HEADER}` and rows"),
            ));
        }
    }
    let mut rows = Vec::new();
    let mut prev_t = f64::NEG_INFINITY;
    for record in records {
        let record = record.map_err(csv_err)?;
        let n = line_of(&record);
        let row = parse_row(&record).map_err(|m| err(n, m))?;
        if row.t_s <= prev_t {
            return Err(err(
                n,
                format!(
                    "t_s = {} must be greater than the previous row's {prev_t}",
                    row.t_s
                ),
            ));
        }
        prev_t = row.t_s;
        rows.push(row);
    }
    let (Some(first), Some(last)) = (rows.first(), rows.last()) else {
        return Err(err(0, "no data rows".into()));
    };
    let span = last.t_s - first.t_s;
    if span > MAX_SPAN_S {
        return Err(err(
            0,
            format!(
                "t_s spans {span} s (from {} to {}); a replay is bounded to {MAX_SPAN_S} s",
                first.t_s, last.t_s
            ),
        ));
    }
    Ok(rows)
}

/// One data row: three finite numbers within their column's range.
fn parse_row(record: &csv::StringRecord) -> Result<TorqueRow, String> {
    if record.len() != 3 {
        return Err(format!(
            "{} fields, expected 3 ({REPLAY_INPUT_HEADER})",
            record.len()
        ));
    }
    let mut v = [0.0; 3];
    for ((slot, field), (name, lo, hi)) in v.iter_mut().zip(record).zip(COLUMN_RANGES) {
        let x = field
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("{name} = `{field}` is not a finite number"))?;
        if !(lo..=hi).contains(&x) {
            return Err(format!(
                "{name} = {x} is outside its allowed range [{lo}, {hi}]"
            ));
        }
        *slot = x;
    }
    let [t_s, motor_torque_pu, load_torque_pu] = v;
    Ok(TorqueRow {
        t_s,
        motor_torque_pu,
        load_torque_pu,
    })
}

fn io_err(path: &Path, e: &std::io::Error) -> PlantError {
    PlantError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Writes `bytes` to a temporary file beside `path`, then renames it over `path`.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), PlantError> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    // A failure names the file asked for (the temporary name means nothing to a user).
    std::fs::write(&tmp, bytes).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io_err(path, &e)
    })?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io_err(path, &e)
    })
}
