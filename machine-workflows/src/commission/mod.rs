//! `hil-harness commission --config CFG --out DIR`: from measurement to a verified design,
//! as a drive engineer commissions a machine whose parameters nobody gave them.
//!
//! 1. **Identify** the machine of `CFG` in the closed loop ([`super::identify`]): the
//!    estimator reads only the recorded signals. `DIR/identify/` gets its files.
//! 2. **The identified machine file**, `DIR/identified.toml`: `CFG` (with `--set` applied)
//!    with its `[plant]` table replaced by the identified one. Everything the drive knows of
//!    the machine now comes from the measurement.
//! 3. **Tune** on the identified file ([`super::tune`]), with AFB and without by the same
//!    constraints ([`tune::pair`]), each chosen by the objective; `DIR/tune/` as `tune`
//!    writes it.
//!    **The automatic notch** ([`notch`]): when no candidate meets the constraints because
//!    the least-damped mode of the best one is the identified resonance, a notch is placed
//!    on it, `DIR/notched.toml` is `identified.toml` with that `[drive.notch]`, and both
//!    designs are tuned on it instead (so `tune/drive.toml` carries the notch). Otherwise
//!    nothing changes.
//! 4. **Verify on the machine itself**: the first [`ON_MACHINE_PER_KIND`] designs of each
//!    kind that the model ranks within its budgets run `fig6` on the machine; of each kind,
//!    the one the machine ranks first that passes `tune`'s verification on the model
//!    becomes that kind's design ([`tune::retarget`]); `commission.md` puts each one's
//!    prediction beside the machine's figures. Then both drives run `fig6` (a move with a load step)
//!    against the plant of `CFG`, not the identified one, and are scored by `tune`'s
//!    objective ([`tune::objective`]) against `CFG`'s own drive on the machine. The machine
//!    chooses: of the two designs stable, without a fault and within the noise budget there,
//!    one no worse than `CFG`'s own drive in peak droop and peak shaft torque before one
//!    that is worse, then the lower objective on the machine, is `DIR/tune/drive.toml`, the
//!    other `DIR/tune/runner-up.toml` (the model's choice stands only when neither
//!    qualifies). The commissioning passes by [`CRITERION`] (the chosen design qualifies,
//!    is no worse than the file's own drive in peak droop and peak shaft torque, and its
//!    objective on the machine is lower) and, with a notch
//!    placed, by [`NOTCH_CRITERION`] (less ripple than the chosen design with the notch
//!    taken out, run too for the comparison).
//!    `DIR/drive.toml` is `CFG` as given with the chosen `[drive]` (what `run --config` and
//!    `flash --config` take on this machine), `DIR/runner-up.toml` with the other kind's.
//!    `DIR/commission.md` and `DIR/commission.json` hold the figures and the notch
//!    decision with its reason; the command fails (after writing them) when it does not
//!    pass: with the no-design code, and without `drive.toml` and `runner-up.toml`, when
//!    no design tried beats the file's own drive on the machine (keep that drive).
//!
//! Everything is staged: on an error before the verification nothing is written.

mod no_design;
pub mod notch;
mod write;

use crate::identify::{self, lost_motion::identified_mechanics};
use crate::tune::objective::better_first;
use crate::tune::{self, Constraints};
use controller_core::{DriveConfig, NotchConfig};
use notch::Decision;
use sim_engine::config::{config_path, overrides, read_table, resolve, RunConfig};
use sim_engine::error::{HarnessError, Result};
use sim_engine::output::Staging;
use std::path::Path;
use toml::{Table, Value};

/// The verification of one drive on the machine itself.
pub use crate::tune::pair::LoopRun as OnMachine;

/// The second criterion with a notch placed, fixed before any run.
pub const NOTCH_CRITERION: &str =
    "less shaft-torque ripple than the same chosen design with the notch taken out";

/// The criterion on the machine itself, fixed before any run.
pub const CRITERION: &str = "the chosen design (of the two, the one stable without a fault \
    and within the torque-noise budget on the machine, no worse than the machine file's own \
    drive in peak droop and peak shaft torque before one that is worse, then the lower \
    objective there, against the machine file's own drive on the machine) is stable without \
    a fault, within the budget, no worse than the file's own drive in peak droop and in peak \
    shaft torque, and its objective on the machine is lower than the file's own drive's (3); \
    worse means worse beyond the noise: a design is worse than the file's own drive in a \
    figure only by more than that figure's run-to-run spread, measured as its range over the \
    file's own drive run with the load step moved by -0.1 to +0.1 s every 20 ms";

/// The offsets of the load step \[s\] at which the machine file's own drive runs `fig6` on
/// the machine, to measure each figure's run-to-run spread (its range over them): every
/// 20 ms within ±0.1 s of the scenario's step (0 is the scenario itself). With lost motion
/// and a quantized encoder the machine at speed is never quite at rest, so the state a step
/// meets depends on when it comes.
pub const STEP_OFFSETS_S: [f64; 11] = [
    -0.10, -0.08, -0.06, -0.04, -0.02, 0.0, 0.02, 0.04, 0.06, 0.08, 0.10,
];

/// The file's own drive's figures over the load step's timing ([`STEP_OFFSETS_S`]).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Spread {
    /// The offsets of the load step \[s\].
    pub offsets_s: Vec<f64>,
    /// The figures of the file's own drive on the machine at each offset.
    pub runs: Vec<tune::objective::Figures>,
    /// The range (largest − smallest) of peak droop \[pu\], peak shaft torque \[pu\],
    /// recovery time \[s\] and torque noise \[pu RMS\] over the offsets.
    pub range: [f64; 4],
}

impl Spread {
    /// Runs `fig6` (the machine file's own drive on the machine) at each offset.
    fn measure(fig6: &RunConfig) -> Result<Self> {
        use rayon::prelude::*;
        let runs = STEP_OFFSETS_S
            .par_iter()
            .map(|&dt| tune::objective::Figures::run(&shifted(fig6.clone(), dt)))
            .collect::<Result<Vec<_>>>()?;
        let range = |f: &dyn Fn(&tune::objective::Figures) -> Option<f64>| {
            let v: Vec<f64> = runs
                .iter()
                .filter_map(f)
                .filter(|x| x.is_finite())
                .collect();
            let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
            if hi >= lo {
                hi - lo
            } else {
                0.0
            }
        };
        let range = [
            range(&|f| f.peak_droop_pu),
            range(&|f| f.peak_shaft_torque_pu),
            range(&|f| f.recovery_s),
            range(&|f| Some(f.torque_noise_rms_pu)),
        ];
        Ok(Self {
            offsets_s: STEP_OFFSETS_S.to_vec(),
            runs,
            range,
        })
    }
}

/// `cfg` with its load steps `dt` later (and a profile that starts late, the explicit
/// metric windows and the run's end with them).
fn shifted(mut cfg: RunConfig, dt: f64) -> RunConfig {
    let s = &mut cfg.scenario;
    for l in &mut s.load {
        l.t_s += dt;
    }
    if s.profile.start_s > 0.0 {
        s.profile.start_s += dt;
    }
    for w in [
        &mut s.metrics.ripple_window_s,
        &mut s.metrics.overshoot_window_s,
        &mut s.metrics.stable_window_s,
    ]
    .into_iter()
    .flatten()
    {
        w.iter_mut().for_each(|t| *t += dt);
    }
    s.duration_s += dt;
    cfg
}

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
    fn new(name: &str, drive: &DriveConfig, verified_on_machine: bool, what: String) -> Self {
        Self {
            name: name.into(),
            settings_crc: format!("{:08x}", tune::output::settings_crc(drive)),
            verified_on_machine,
            what,
        }
    }
}

/// The machine file's own drive judged on the identified model by the linear constraints
/// the designs must meet (as `tune` judges each candidate).
#[derive(Clone, Debug, serde::Serialize)]
pub struct ReferenceDrive {
    /// Its figures on the linear model of the identified machine.
    pub judged: tune::Judged,
    /// The constraints it fails, each with its figure and the bound (empty: it meets them).
    pub fails: Vec<String>,
}

/// What `commission` found.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Commissioning {
    /// The machine file.
    pub config: String,
    /// Every design tried on the machine, the model's prediction beside the machine's
    /// figures ([`ON_MACHINE_PER_KIND`] of each kind).
    pub tried: Vec<Tried>,
    /// The AFB design and the no-AFB design, verified on the machine.
    pub runs: [OnMachine; 2],
    /// Which of `runs` was chosen (the lower objective on the model it was tuned on):
    /// "with AFB" or "without AFB".
    pub chosen: &'static str,
    /// The machine file's own drive on the machine, and the budget: the reference of the
    /// objective on the machine.
    pub reference: tune::objective::Reference,
    /// The objective of `runs` on the machine.
    pub objective: [f64; 2],
    /// Whether a notch was placed, where and why ([`notch`]).
    pub notch: Decision,
    /// With a notch placed: the chosen design with the notch taken out, on the machine.
    pub without_notch: Option<OnMachine>,
    /// The chosen design passed ([`CRITERION`] and, with a notch placed,
    /// [`NOTCH_CRITERION`]).
    pub passed: bool,
    /// No design tried beats the file's own drive on the machine ([`CRITERION`] without
    /// the notch's part): the commissioning has no design, as when none meets the
    /// constraints on the model, and `drive.toml` is not written.
    pub no_design: bool,
    /// The machine file's own drive on the identified model, by the linear constraints.
    pub reference_drive: ReferenceDrive,
    /// The run-to-run spread of the file's own drive's figures on the machine, over the
    /// load step's timing: the noise a design must be worse by to count as worse.
    pub spread: Spread,
    /// The AFB design's gains without its AFB, on the machine: what the AFB itself adds on
    /// top of the bandwidth.
    pub same_gains_without_afb: Option<OnMachine>,
    /// Every machine file written, with its drive's settings CRC.
    pub files: Vec<WrittenFile>,
}

/// The files `commission` tells the user about: `drive.toml` and `runner-up.toml`, the
/// machine file `config` as given (with `sets` applied) with the whole `[drive]` of the
/// chosen design and of the other kind's ([`tune::output::drive_file`]): what `run
/// --config` and `flash --config` take on this machine, composing to the drive verified
/// there. Their names, texts and entries for `commission.md`.
fn drive_files(
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
fn machine_doc(config: &str, sets: &[String]) -> Result<Table> {
    let mut doc = read_table(&config_path(config)?)?;
    overrides::apply_all(&mut doc, sets)?;
    Ok(doc)
}

/// `machine` ([`machine_doc`]) with its `[plant]` table replaced by the identified one.
fn identified_doc(
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
    Ok(doc)
}

/// A model's machine file text (not verified on the machine): the comment line `header`,
/// the settings CRC of its drive, then `doc`; and the drive it composes to.
fn render(name: &str, header: &str, doc: &Table) -> Result<(String, DriveConfig)> {
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
fn with_notch(doc: Table, notch: &NotchConfig) -> Result<(Table, DriveConfig)> {
    let (_, mut drive) = sim_engine::config::machine(doc.clone())?;
    drive.notch = Some(*notch);
    Ok((tune::output::with_drive(doc, &drive)?, drive))
}

/// The drive of the file it was tuned on (`identified.toml`, or `notched.toml` with a notch
/// placed) on the plant of the machine file `config` with `sets`: where the designs are
/// verified, resolved once for all of them.
fn verification_base(config: &str, sets: &[String], tuned_on: &str) -> Result<RunConfig> {
    let scenario = "fig6";
    let mut cfg = resolve(scenario, Some(tuned_on), &[])?;
    let machine = resolve(scenario, Some(config), sets)?;
    cfg.plant = machine.plant;
    cfg.config_path = machine.config_path;
    Ok(cfg)
}

/// `design`'s drive (`strip_notch`: with its notch taken out) on `base`
/// ([`verification_base`]).
fn on_machine(
    base: &RunConfig,
    label: &'static str,
    design: &tune::Candidate,
    strip_notch: bool,
) -> Result<OnMachine> {
    let mut cfg = base.clone();
    if strip_notch {
        cfg.drive.notch = None;
    }
    OnMachine::run(cfg, label, design)
}

/// What [`identify_into`] gives.
struct Identified {
    /// The machine as the identification ran it.
    base: RunConfig,
    ident: identify::Identification,
    /// `identified.toml`'s tree, its staged path and its entry.
    doc: Table,
    path: String,
    file: WrittenFile,
}

/// Identifies the machine into the staging directory: `identify/` and `identified.toml`
/// (steps 1 and 2).
fn identify_into(
    staging: &Staging,
    config: &str,
    sets: &[String],
    machine: &Table,
) -> Result<Identified> {
    let (base, spec) = identify::load(config, sets)?;
    let ident = identify::identify_machine(&base, &spec)?;
    let id_md = staging.path("identify/identify.md")?;
    identify::write::write_all(
        id_md.parent().unwrap_or(staging.dir()),
        &base,
        &spec,
        &ident,
    )?;
    let doc = identified_doc(machine.clone(), &base, &ident)?;
    let header = format!(
        "{} with the [plant] table `identify` measured: the model the designs are tuned on.",
        base.config_path.display()
    );
    let (text, drive) = render("identified.toml", &header, &doc)?;
    let path = staging.write("identified.toml", &text)?;
    let file = WrittenFile::new(
        "identified.toml",
        &drive,
        false,
        "the machine file with the identified [plant] (the file's own [drive] on it)".into(),
    );
    Ok(Identified {
        base,
        ident,
        doc,
        path: path.display().to_string(),
        file,
    })
}

/// Designs of each kind tried on the machine: the first this many that the model ranks
/// within its budgets (the design `tune` chose on the model first).
pub const ON_MACHINE_PER_KIND: usize = 4;

/// One design tried on the machine: what the identified model predicted beside what the
/// machine measured.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Tried {
    /// "with AFB" or "without AFB".
    pub kind: &'static str,
    /// The design.
    pub candidate: tune::Candidate,
    /// Its `fig6` figures and objective on the identified model (the prediction).
    pub model: tune::objective::Score,
    /// The same run on the machine.
    pub machine: OnMachine,
    /// Its objective on the machine, against the file's own drive there.
    pub objective: f64,
    /// How it qualifies on the machine ([`qualifies`]).
    pub qualifies: u8,
    /// It became the design of its kind.
    pub taken: bool,
}

impl Tried {
    /// Its key for [`better_first`]: how it qualifies, then J on the machine.
    fn rank(&self) -> (u8, f64) {
        (self.qualifies, self.objective)
    }
}

/// How a run on the machine qualifies: 2 stable without a fault, within the budgets and no
/// worse than the file's own drive in peak droop and peak shaft torque; 1 only the first
/// part; 0 neither.
fn qualifies(reference: &tune::objective::Reference, r: &OnMachine) -> u8 {
    let within = r.stable && !r.faulted && reference.broken(&r.figures).is_empty();
    u8::from(within) * (1 + u8::from(reference.worse(&r.figures).is_empty()))
}

/// Tries the first [`ON_MACHINE_PER_KIND`] designs of each kind the model ranks within its
/// budgets on the machine `m`, and makes the one the machine ranks first (by
/// [`qualifies`], then the objective there) the design of its kind, if it passes `tune`'s
/// verification on the model (`config`, the file it was tuned on); else the next.
fn try_on_machine(
    m: &RunConfig,
    config: &str,
    pair: &mut tune::pair::Pair,
    reference: &tune::objective::Reference,
    constraints: &Constraints,
) -> Result<Vec<Tried>> {
    let mut all = Vec::new();
    for (kind, t) in [
        ("with AFB", &mut pair.with),
        ("without AFB", &mut pair.without),
    ] {
        let r = &t.result;
        let refused = |c: &tune::Candidate| r.refused.iter().any(|(j, _)| j.candidate == *c);
        let mut tried = r
            .scored
            .iter()
            .filter(|s| s.score.within_budget && !refused(&s.candidate))
            .take(ON_MACHINE_PER_KIND)
            .map(|s| {
                let machine = on_machine(m, "tried", &s.candidate, false)?;
                Ok(Tried {
                    kind,
                    candidate: s.candidate,
                    model: s.score,
                    objective: reference.objective(&machine.figures),
                    qualifies: qualifies(reference, &machine),
                    machine,
                    taken: false,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let mut order: Vec<usize> = (0..tried.len()).collect();
        order.sort_by(|&a, &b| match (tried.get(a), tried.get(b)) {
            (Some(x), Some(y)) => better_first(x.rank(), y.rank()),
            _ => std::cmp::Ordering::Equal,
        });
        for i in order {
            let Some(x) = tried.get_mut(i) else { continue };
            if x.candidate == t.result.design.candidate {
                x.taken = true;
                break;
            }
            if let Ok(new) = tune::retarget(config, t, &x.candidate, constraints) {
                *t = new;
                x.taken = true;
                break;
            }
        }
        all.append(&mut tried);
    }
    Ok(all)
}

/// Both designs of `pair` on the machine `m` (the run [`try_on_machine`] made of a design
/// it took, else a new one), their objectives against `reference`, and the machine's choice
/// between them set on `pair` ([`tune::pair::Pair::on_machine_afb`]): of those stable,
/// without a fault and within the budget there, the better by [`better_first`]; the model's
/// choice only if neither is.
fn both_on_machine(
    m: &RunConfig,
    pair: &mut tune::pair::Pair,
    reference: &tune::objective::Reference,
    tried: &[Tried],
) -> Result<([OnMachine; 2], [f64; 2])> {
    let run = |kind: &str, label: &'static str, t: &tune::Tuned| -> Result<OnMachine> {
        let design = &t.result.design.candidate;
        let taken = tried
            .iter()
            .find(|x| x.taken && x.kind == kind && x.candidate == *design);
        Ok(match taken {
            Some(x) => OnMachine {
                design: label,
                ..x.machine.clone()
            },
            None => on_machine(m, label, design, false)?,
        })
    };
    let runs = [
        run("with AFB", "tuned with AFB", &pair.with)?,
        run("without AFB", "tuned without AFB", &pair.without)?,
    ];
    let objective = [
        reference.objective(&runs[0].figures),
        reference.objective(&runs[1].figures),
    ];
    let (a, b) = (
        qualifies(reference, &runs[0]),
        qualifies(reference, &runs[1]),
    );
    pair.on_machine_afb =
        (a > 0 || b > 0).then(|| better_first((a, objective[0]), (b, objective[1])).is_lt());
    Ok((runs, objective))
}

/// `hil-harness commission`.
pub fn commission(
    config: &str,
    sets: &[String],
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
    out: &Path,
) -> Result<String> {
    // One bar over the stages (hidden when stderr is not a terminal); `tune`'s own bar
    // shows the linear judging within its stage.
    let pb = sim_engine::progress::bar(STAGES.len() as u64, "commission");
    let stage = |i: usize| {
        pb.set_position(i as u64);
        pb.set_message(STAGES.get(i).copied().unwrap_or("commission"));
    };
    let result = run_stages(config, sets, target_bandwidth, constraints, out, &stage);
    pb.finish_and_clear();
    result
}

/// The stages the progress bar names.
const STAGES: [&str; 5] = ["identify", "judge", "tune", "on the machine", "write"];

/// The notch decision ([`notch::decide`]) on the identified file and the file both designs
/// are tuned on: `identified.toml` with the candidates already judged on it, or with a notch
/// placed `notched.toml` (written, its entry given) and nothing judged yet.
fn place_notch(
    staging: &Staging,
    id: &Identified,
    judged: Vec<tune::Judged>,
    constraints: &Constraints,
) -> Result<Placed> {
    let fig6 = resolve("fig6", Some(&id.path), &[])?;
    let decision = notch::decide(&fig6, id.ident.fit.fit.resonance_hz(), &judged, constraints)?;
    Ok(match &decision.notch {
        None => Placed {
            decision,
            tuned_on: id.path.clone(),
            name: "identified.toml",
            judged: Some(judged),
            file: None,
        },
        Some(n) => {
            let header = format!(
                "identified.toml with the notch commission placed ({}); every [drive] key \
                 stated.",
                decision.reason
            );
            let (doc, drive) = with_notch(id.doc.clone(), n)?;
            let text = tune::output::drive_file(
                doc,
                &drive,
                &format!("NOT verified on the machine (a model only): `hil-harness commission`: {header}"),
            )?;
            let path = staging.write("notched.toml", &text)?.display().to_string();
            let file = WrittenFile::new(
                "notched.toml",
                &drive,
                false,
                "identified.toml with the notch placed: the model the designs are tuned on".into(),
            );
            Placed {
                decision,
                tuned_on: path,
                name: "notched.toml",
                judged: None,
                file: Some(file),
            }
        }
    })
}

/// What [`place_notch`] decided and where the designs are tuned.
struct Placed {
    decision: Decision,
    /// The file tuned on (staged path) and its name in the output folder.
    tuned_on: String,
    name: &'static str,
    /// The candidates judged on it already (without a notch).
    judged: Option<Vec<tune::Judged>>,
    /// `notched.toml`'s entry, when written.
    file: Option<WrittenFile>,
}

/// `commission`'s copies of `tune`'s drive files in `DIR/tune/`: the identified model with
/// each design, named so as not to be taken for the drive to flash.
pub const MODEL_FILES: tune::PairFiles = tune::PairFiles {
    chosen: "model-chosen.toml",
    runner_up: "model-runner-up.toml",
    model_only: true,
};

/// The machine file's own drive (`own`) on the identified model the designs were tuned on
/// (`tuned_on`), judged by `constraints` as each candidate is.
fn judge_reference(
    own: &RunConfig,
    tuned_on: &str,
    constraints: &Constraints,
) -> Result<ReferenceDrive> {
    let mut cfg = resolve("fig6", Some(tuned_on), &[])?;
    cfg.drive = own.drive;
    let judged = tune::judge_drive(&cfg, constraints)?;
    let mut fails: Vec<String> = no_design::misses(&judged, constraints)
        .into_iter()
        .map(|(s, _)| s)
        .collect();
    let own_damping = tune::machine_resonance_damping(&cfg);
    if let Some(b) = judged.resonance_band_damping {
        if b < own_damping {
            fails.push(format!(
                "damping near the machine's resonance {b:.3} (needs ≥ the machine's own \
                 {own_damping:.3})"
            ));
        }
    }
    if let Some(b) = judged.notch_band_damping {
        let floor = tune::NOTCH_BAND_DAMPING_SHARE * own_damping;
        if b < floor {
            fails.push(format!(
                "damping in the notch's band {b:.3} (needs ≥ {floor:.3})"
            ));
        }
    }
    if fails.is_empty() && !judged.feasible {
        fails.push("a band-damping rule of `tune` (docs/tuning.md)".into());
    }
    Ok(ReferenceDrive { judged, fails })
}

fn run_stages(
    config: &str,
    sets: &[String],
    target_bandwidth: Option<f64>,
    constraints: &Constraints,
    out: &Path,
    stage: &dyn Fn(usize),
) -> Result<String> {
    tune::objective::check_budget(constraints.max_torque_noise_pu)?;
    let grid = sim_engine::config::tune_grid()?;
    let bws = tune::bandwidths(&grid, target_bandwidth)?;
    let machine = machine_doc(config, sets)?;
    let staging = Staging::new(out)?;
    stage(0);
    let id = identify_into(&staging, config, sets, &machine)?;
    stage(1);
    let judged = tune::judge_grid(&id.path, &tune::candidates(&grid, &bws), constraints)?;
    let all_judged = judged.clone();
    let placed = place_notch(&staging, &id, judged, constraints)?;
    let (base, ident) = (&id.base, &id.ident);
    stage(2);
    let pair = match tune::pair::design_both_from(
        &placed.tuned_on,
        placed.judged.clone(),
        target_bandwidth,
        constraints,
    ) {
        Ok(p) => p,
        Err(HarnessError::NoDesign(reason)) => {
            // The reason names the file tuned on where it is staged; the user finds it
            // under `out`.
            let staged = staging.dir().display().to_string();
            let reason = reason.replace(&staged, &out.display().to_string());
            // The identification stands on its own: keep it, say what failed, and exit
            // with the no-design code.
            let md = no_design::markdown(
                &base.config_path.display().to_string(),
                &all_judged,
                constraints,
                &reason,
            );
            staging.write("commission.md", &md)?;
            staging.commit()?;
            return Err(HarnessError::NoDesign(format!(
                "{reason}; the identification is in {} (identify/, identified.toml), the \
                 closest designs and what each misses in {}",
                out.display(),
                out.join("commission.md").display()
            )));
        }
        Err(e) => return Err(e),
    };
    let mut pair = pair;
    let m = verification_base(config, sets, &placed.tuned_on)?;
    let own = resolve("fig6", Some(config), sets)?;
    let spread = Spread::measure(&own)?;
    let [droop_spread, shaft_spread, ..] = spread.range;
    let reference = tune::objective::Reference::of(&own, constraints.max_torque_noise_pu)?
        .with_spread([droop_spread, shaft_spread]);
    let reference_drive = judge_reference(&own, &placed.tuned_on, constraints)?;
    stage(3);
    let tried = try_on_machine(&m, &placed.tuned_on, &mut pair, &reference, constraints)?;
    pair.with.result.config = placed.name.into();
    pair.without.result.config = placed.name.into();
    let (runs, objective) = both_on_machine(&m, &mut pair, &reference, &tried)?;
    let tune_md = staging.path("tune/tune.md")?;
    tune::write_pair_as(
        tune_md.parent().unwrap_or(staging.dir()),
        &pair,
        &MODEL_FILES,
    )?;
    let afb = pair.afb_chosen();
    let (chosen_tuned, other_tuned) = pair.chosen();
    let chosen_design = &chosen_tuned.result.design.candidate;
    let without_notch = match placed.decision.notch {
        Some(_) => Some(on_machine(
            &m,
            "chosen, notch taken out",
            chosen_design,
            true,
        )?),
        None => None,
    };
    // What AFB itself adds: the AFB design (chosen or not) at its gains without its AFB.
    let same_gains_without_afb = match pair.with.result.design.candidate {
        d if d.afb.mode != controller_core::AfbMode::Off => {
            Some(OnMachine::run_same_gains_without_afb(
                m.clone(),
                "AFB design, same gains without AFB",
                &d,
            )?)
        }
        _ => None,
    };
    let c_run = if afb { &runs[0] } else { &runs[1] };
    let c_j = if afb { objective[0] } else { objective[1] };
    let beats_the_file =
        qualifies(&reference, c_run) == 2 && c_j < reference.objective(&reference.default_drive);
    let passed = beats_the_file
        && without_notch
            .as_ref()
            .is_none_or(|n| c_run.shaft_torque_ripple_rms_pu < n.shaft_torque_ripple_rms_pu);
    let no_design = !beats_the_file;
    // Every machine file written, in the order commission.md lists them.
    let mut files = vec![id.file.clone()];
    files.extend(placed.file.clone());
    for (name, t, what) in [
        (MODEL_FILES.chosen, chosen_tuned, "the chosen design"),
        (
            MODEL_FILES.runner_up,
            other_tuned,
            "the best design of the other kind",
        ),
    ] {
        files.push(WrittenFile::new(
            &format!("tune/{name}"),
            &t.tuned.drive,
            false,
            format!("the identified model ({}) with {what}", placed.name),
        ));
    }
    let drives = if no_design {
        Vec::new()
    } else {
        drive_files(&machine, &base.config_path, &pair, passed)?
    };
    files.extend(drives.iter().map(|(_, _, f)| f.clone()));
    let c = Commissioning {
        config: base.config_path.display().to_string(),
        tried,
        runs,
        chosen: if afb { "with AFB" } else { "without AFB" },
        reference,
        objective,
        notch: placed.decision,
        without_notch,
        passed,
        no_design,
        reference_drive,
        spread,
        same_gains_without_afb,
        files,
    };
    stage(4);
    write::write_all(&staging, &c, base, ident, &pair)?;
    for (name, text, _) in &drives {
        staging.write(name, text)?;
    }
    staging.commit()?;
    finish(&c, &pair, out)
}

/// The command's line, or its error when the commissioning did not pass.
fn finish(c: &Commissioning, pair: &tune::pair::Pair, out: &Path) -> Result<String> {
    let notch = c.notch.notch.map_or_else(
        || "no notch".to_string(),
        |n| format!("notch at {:.1} Hz", n.centre_hz),
    );
    let line = format!(
        "commission {}: {}; {notch}; on the machine: J {:.3} with AFB, {:.3} without \
         (the file's own drive 3), ripple {:.4} pu with AFB ({}), {:.4} pu without ({}) -> {}",
        c.config,
        tune::pair_line(pair, &out.join("tune")),
        c.objective[0],
        c.objective[1],
        c.runs[0].shaft_torque_ripple_rms_pu,
        c.runs[0].verdict(),
        c.runs[1].shaft_torque_ripple_rms_pu,
        c.runs[1].verdict(),
        out.display()
    );
    if c.passed {
        Ok(line)
    } else if c.no_design {
        Err(HarnessError::NoDesign(format!(
            "{line}: none of the {} designs tried beats the machine file's own drive on the \
             machine; keep that drive (the identification is in identify/ and \
             identified.toml, every design tried in commission.md)",
            c.tried.len()
        )))
    } else {
        Err(HarnessError::NotPassed(format!(
            "{line}: the chosen design did not pass on the machine (commission.md)"
        )))
    }
}
