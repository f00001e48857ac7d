//! The files `tune` writes into its folder: the figures, `tune.md` and `tune.json`, the
//! machine file with the chosen drive and the one with the runner-up's ([`write_pair`]),
//! named and headed by [`PairFiles`].

use super::{has_lost_motion, output, pair, plots, Candidate, TuneResult, Tuned};
use crate::linear::{for_gains, LoopModel};
use plant_host::analysis::Gears;
use serde::Serialize;
use sim_engine::config::RunConfig;
use sim_engine::engine::runner::regulator_gains;
use sim_engine::error::{HarnessError, Result};
use std::path::Path;

/// Writes the design's files into `dir` (module docs, and `write_files`).
pub fn write_design(dir: &Path, t: &Tuned) -> Result<()> {
    write_design_with(dir, t, "", &TUNE_FILES, serde_json::to_string_pretty)
}

/// The files of a design with AFB where no design without AFB meets the constraints
/// (`why`, the search's account): [`write_design`]'s, `tune.md` saying why there is no
/// runner-up.
pub fn write_afb_only(dir: &Path, t: &Tuned, why: &str) -> Result<()> {
    let extra = format!(
        "\n## No design without AFB\n\nThe search without acceleration feedback found no \
         design: {why}. On this machine only the design with AFB meets the constraints, so \
         it is not compared with one without AFB and there is no `runner-up.toml`.\n"
    );
    write_design_with(dir, t, &extra, &TUNE_FILES, serde_json::to_string_pretty)
}

/// [`write_design`], with `extra` appended to `tune.md`, the chosen drive file named and
/// headed by `names`, and `tune.json` from `json`.
fn write_design_with(
    dir: &Path,
    t: &Tuned,
    extra: &str,
    names: &PairFiles,
    json: impl Fn(&TuneResult) -> serde_json::Result<String>,
) -> Result<()> {
    let gains = regulator_gains(&t.tuned)?;
    let engaged = for_gains(&t.tuned, &gains, Gears::Engaged)?;
    let apart = if has_lost_motion(&t.tuned) {
        Some(for_gains(&t.tuned, &gains, Gears::Apart)?)
    } else {
        None
    };
    let json = json(&t.result).map_err(|e| HarnessError::io(dir.join("tune.json"), e))?;
    let files = Files {
        json,
        extra,
        base: &t.base,
        tuned: &t.tuned,
        names,
    };
    write_files(dir, &t.result, &files, &engaged, apart.as_ref())
}

/// What [`write_files`] writes besides the figures.
struct Files<'a> {
    json: String,
    extra: &'a str,
    base: &'a RunConfig,
    tuned: &'a RunConfig,
    names: &'a PairFiles,
}

/// The names of the two drive files of a pair, and what they are.
#[derive(Clone, Copy, Debug)]
pub struct PairFiles {
    /// The chosen design's file.
    pub chosen: &'static str,
    /// The runner-up's (the best design of the other kind).
    pub runner_up: &'static str,
    /// Written inside `commission`'s folder on the identified model: the files are the
    /// model with the designs, not verified on the machine (`commission` writes the
    /// machine file with each drive beside them).
    pub model_only: bool,
}

/// `tune`'s own drive files: verified in the nonlinear loop on the file tuned.
pub const TUNE_FILES: PairFiles = PairFiles {
    chosen: "drive.toml",
    runner_up: "runner-up.toml",
    model_only: false,
};

impl PairFiles {
    /// The first lines of the drive file of the design `c` tuned on `config`: the chosen
    /// design (`chosen`) or the runner-up.
    #[must_use]
    pub fn header(&self, config: &Path, c: &Candidate, chosen: bool) -> String {
        let what = format!(
            "the whole [drive] of {} ({} rad/s, {})",
            if chosen {
                "the chosen design"
            } else {
                "the best design of the other kind"
            },
            c.bandwidth_rad_s,
            c.afb.label()
        );
        if self.model_only {
            // The file tuned on lies beside this folder (its staged path is not the user's).
            let model = config.file_name().map_or_else(
                || config.display().to_string(),
                |n| n.to_string_lossy().into(),
            );
            format!(
                "NOT verified on the machine (a model only): `hil-harness commission`'s model of \
                 the machine, ../{model}, with {what}.\nThe machine file with this drive, and \
                 whether it passed on the machine, are in the folder above (commission.md); \
                 flash nothing from here."
            )
        } else {
            let over = if chosen {
                String::new()
            } else {
                format!("; tune chose {} over it", self.chosen)
            };
            let config = config.display();
            format!(
                "`hil-harness tune`: {config} with {what}, verified in the nonlinear loop on \
                 this file's plant (fig6, shock, sweep; tune.md{over}).\nEvery [drive] key is \
                 stated: the file's own [drive] is replaced, not merged."
            )
        }
    }
}

/// What `tune.json` holds: the chosen design's [`TuneResult`], which kind it is, and the
/// runner-up's.
#[derive(Serialize)]
struct PairJson<'a> {
    #[serde(flatten)]
    chosen: &'a TuneResult,
    /// "with AFB" or "without AFB".
    chosen_kind: &'static str,
    /// The objective with AFB, without, and the default drive's (3).
    objective: output::Comparison,
    runner_up: &'a TuneResult,
}

/// Writes a pair into `dir`: the chosen design's figures, `tune.md` (with the comparison of
/// both designs by the objective) and `tune.json`, `drive.toml` (the machine file with the
/// chosen drive) and `runner-up.toml` (with the other kind's).
pub fn write_pair(dir: &Path, p: &pair::Pair) -> Result<()> {
    write_pair_as(dir, p, &TUNE_FILES)
}

/// [`write_pair`], the two drive files named and headed by `names`.
pub fn write_pair_as(dir: &Path, p: &pair::Pair, names: &PairFiles) -> Result<()> {
    let (chosen, other) = p.chosen();
    let cmp = output::Comparison::of(p);
    let text = output::comparison_markdown(p, &cmp, names);
    write_design_with(dir, chosen, &text, names, |r| {
        serde_json::to_string_pretty(&PairJson {
            chosen: r,
            chosen_kind: cmp.chosen,
            objective: cmp.clone(),
            runner_up: &other.result,
        })
    })?;
    let path = dir.join(names.runner_up);
    let text = output::drive_file(
        sim_engine::config::read_table(&other.base.config_path)?,
        &other.tuned.drive,
        &names.header(
            &other.base.config_path,
            &other.result.design.candidate,
            false,
        ),
    )?;
    std::fs::write(&path, text).map_err(|e| HarnessError::io(&path, e))
}

/// The figures, the chosen drive file (the machine file with the tuned drive, every
/// `[drive]` key stated), `tune.md` and `tune.json` into `dir`.
fn write_files(
    dir: &Path,
    result: &TuneResult,
    f: &Files<'_>,
    engaged: &LoopModel,
    apart: Option<&LoopModel>,
) -> Result<()> {
    let (base, tuned, json) = (f.base, f.tuned, f.json.clone());
    let nyquist_hz = 0.5 * f64::from(tuned.drive.velocity_rate_hz);
    let images = plots::write(dir, engaged, apart, nyquist_hz)?;
    let drive = output::drive_toml(&tuned.drive)?;
    let files = [
        (
            "tune.md",
            output::markdown(result, &drive, &images) + f.extra,
        ),
        (
            f.names.chosen,
            output::drive_file(
                sim_engine::config::read_table(&base.config_path)?,
                &tuned.drive,
                &f.names
                    .header(&base.config_path, &result.design.candidate, true),
            )?,
        ),
        ("tune.json", json + "\n"),
    ];
    for (name, text) in files {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| HarnessError::io(&path, e))?;
    }
    Ok(())
}
