//! The paper on a PMSM: the `fig6` and `shock` pairs (with AFB, and without it at the AFB
//! run's gains) and the stiffness measurement on `configs/machines/table1-pmsm.toml` (Table
//! 1's mechanics on a three-phase permanent-magnet motor under field-oriented control),
//! beside the same on the DC `table1.toml`, read by the criteria of the DC sections
//! ([`super::fig6`], [`super::load`], [`super::stiffness`]) and one more, fixed before the
//! runs ([`PMSM_RATIO_TOLERANCE`]): the PMSM's shaft-ripple ratio with AFB / without is
//! within 15 % of the DC model's on the same scenario. Each pair also runs with its load step
//! moved over commission's offsets ([`OFFSETS_S`]), so that the ratio's spread over the
//! step's timing stands beside the difference between the motors.

use super::fig6::fig6_failures;
use super::load::shock_calmer;
use super::section::{pct, verdict, Section};
use super::step_timing::{Spread, OFFSETS_S};
use super::stiffness::{findings, holds, list, Findings};
use super::{PMSM_RATIO_TOLERANCE, SLIGHT_OVERSHOOT_PU};
use machine_workflows::commission::shifted;
use machine_workflows::stiffness::machine::{machine_base, measure_machine};
use machine_workflows::stiffness::StiffnessPoint;
use ratio::{both, fine_sets, fine_text, pairs_table, ratio, ratio_lines};
use rayon::prelude::*;
use sim_engine::config::{resolve, RunConfig};
use sim_engine::engine::metrics::Metrics;
use sim_engine::engine::runner::{regulator_gains, run_scenario, same_regulator_gains};
use sim_engine::error::{HarnessError, Result};
use sim_engine::run::write_run;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

mod ratio;
pub use ratio::{within_tolerance, FINE_ENCODER_CPR};

/// The DC machine file and the PMSM one (names under `configs/machines/`).
pub const MACHINES: [&str; 2] = ["table1", "table1-pmsm"];

/// Which DC section's criterion a pair is read by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Criterion {
    /// Fig. 6/7's ([`super::fig6`]): stable, slight overshoot, no more shaft ripple with AFB.
    Fig6,
    /// Fig. 11/12's ([`super::load`]): less shaft ripple with AFB.
    Shock,
}

/// The pairs: the AFB scenario (its run without AFB at its gains is `<scenario>-no-afb`)
/// and its criterion.
pub const PAIRS: [(&str, Criterion); 2] = [("fig6", Criterion::Fig6), ("shock", Criterion::Shock)];

/// Where the pairs' runs at the scenario's own timing are written, under the report's
/// directory: `<this>/<machine>/<scenario>/`.
pub const RUN_DIR: &str = "on-pmsm";

/// One pair on one machine file, at each offset of [`OFFSETS_S`].
pub struct PairRuns {
    /// The AFB scenario.
    pub scenario: &'static str,
    /// Its criterion.
    pub criterion: Criterion,
    /// The machine file.
    pub machine: &'static str,
    /// (with AFB, without) at each offset.
    pub by_offset: Vec<(Metrics, Metrics)>,
    /// Whether the run without AFB has the AFB run's regulator gains, bit for bit.
    pub same_gains: bool,
}

impl PairRuns {
    fn at_scenario(&self) -> Option<&(Metrics, Metrics)> {
        let zero = OFFSETS_S.iter().position(|&d| d == 0.0)?;
        self.by_offset.get(zero)
    }

    /// The ratio at the scenario's own timing.
    pub fn ratio(&self) -> f64 {
        self.at_scenario().map_or(f64::NAN, ratio)
    }

    fn spread(&self) -> Spread {
        Spread::of(self.by_offset.iter().map(ratio).collect(), self.ratio())
    }

    /// What fails of the DC section's criterion at the scenario's timing (empty: agrees).
    pub fn failures(&self) -> Vec<&'static str> {
        let Some((a, b)) = self.at_scenario() else {
            return vec!["did not run"];
        };
        match self.criterion {
            Criterion::Fig6 => fig6_failures(a, b),
            Criterion::Shock if shock_calmer(a, b) => Vec::new(),
            Criterion::Shock => vec!["no less shaft-torque ripple with AFB than without"],
        }
    }
}

/// The stiffness measurement on one machine file.
pub struct MachineStiffness {
    /// The machine file.
    pub machine: &'static str,
    /// Its findings by the DC section's criteria.
    findings: Findings,
    /// The measured points.
    points: Vec<StiffnessPoint>,
    /// Its velocity bandwidth and observer bandwidth \[rad/s\].
    bands: (f64, f64),
}

/// What the section reads.
pub struct Measured {
    /// Per pair, per machine (in [`PAIRS`] then [`MACHINES`] order).
    pub pairs: Vec<PairRuns>,
    /// The same with the hypothesis test's fine encoder ([`FINE_ENCODER_CPR`]).
    pub fine: Vec<PairRuns>,
    /// Per machine.
    pub stiffness: Vec<MachineStiffness>,
    /// `fig6` on each machine, for the motor values.
    configs: Vec<RunConfig>,
    /// Wall time of the section's runs \[s\].
    pub wall_s: f64,
}

/// A pair's AFB and no-AFB configurations on a machine.
type Base = (&'static str, Criterion, &'static str, RunConfig, RunConfig);

/// Every pair on every machine at every offset, with `sets` applied, in parallel; with a
/// `dir`, the runs at the scenario's own timing are written to `dir/RUN_DIR/<machine>/<scenario>`.
fn run_pairs(dir: Option<&Path>, sets: &[String]) -> Result<Vec<PairRuns>> {
    let mut bases: Vec<Base> = Vec::new();
    for (scenario, criterion) in PAIRS {
        for machine in MACHINES {
            let afb = resolve(scenario, Some(machine), sets)?;
            let off = resolve(&format!("{scenario}-no-afb"), Some(machine), sets)?;
            bases.push((scenario, criterion, machine, afb, off));
        }
    }
    let jobs: Vec<(usize, f64, bool)> = (0..bases.len())
        .flat_map(|i| {
            OFFSETS_S
                .iter()
                .flat_map(move |&dt| [(i, dt, true), (i, dt, false)])
        })
        .collect();
    let pb = sim_engine::progress::bar(jobs.len() as u64, "on a PMSM");
    let outs: Vec<Metrics> = jobs
        .par_iter()
        .map(|&(i, dt, with)| {
            let (scenario, _, machine, afb, off) = bases
                .get(i)
                .ok_or_else(|| HarnessError::Backend("pair index".to_string()))?;
            let cfg = shifted(if with { afb } else { off }.clone(), dt);
            let out = run_scenario(&cfg)?;
            pb.inc(1);
            if let (Some(dir), 0.0) = (dir, dt) {
                let name = if with {
                    scenario.to_string()
                } else {
                    format!("{scenario}-no-afb")
                };
                write_run(&dir.join(RUN_DIR).join(machine).join(name), &cfg, &out)?;
            }
            Ok(out.metrics)
        })
        .collect::<Result<_>>()?;
    pb.finish_and_clear();
    let mut outs = outs.into_iter();
    bases
        .into_iter()
        .map(|(scenario, criterion, machine, afb, off)| {
            let by_offset = OFFSETS_S
                .iter()
                .map(|_| Some((outs.next()?, outs.next()?)))
                .collect::<Option<Vec<_>>>()
                .ok_or_else(|| HarnessError::Backend(format!("{scenario} on {machine}")))?;
            let same_gains = same_regulator_gains(&regulator_gains(&afb)?, &regulator_gains(&off)?);
            Ok(PairRuns {
                scenario,
                criterion,
                machine,
                by_offset,
                same_gains,
            })
        })
        .collect()
}

/// The stiffness measurement on each machine file as it describes its plant and drive
/// (what `stiffness --config FILE` measures).
fn run_stiffness() -> Result<Vec<MachineStiffness>> {
    MACHINES
        .iter()
        .map(|&machine| {
            let (base, _) = machine_base(machine, &[])?;
            let bw = f64::from(base.drive.velocity_bandwidth_rad_s);
            let w_obs = std::f64::consts::TAU * f64::from(base.drive.observer.bandwidth_hz);
            let points = measure_machine(machine, &[])?;
            Ok(MachineStiffness {
                machine,
                findings: findings(&points, bw, w_obs),
                points,
                bands: (bw, w_obs),
            })
        })
        .collect()
}

/// Runs the section's experiments, writing the pairs' runs under `dir`.
pub fn measure(dir: &Path) -> Result<Measured> {
    let t0 = Instant::now();
    let ((pairs, fine), stiffness) = rayon::join(
        || {
            rayon::join(
                || run_pairs(Some(dir), &[]),
                || run_pairs(None, &fine_sets()),
            )
        },
        run_stiffness,
    );
    let configs = MACHINES
        .iter()
        .map(|m| resolve("fig6", Some(m), &[]))
        .collect::<Result<_>>()?;
    Ok(Measured {
        pairs: pairs?,
        fine: fine?,
        stiffness: stiffness?,
        configs,
        wall_s: t0.elapsed().as_secs_f64(),
    })
}

/// The PMSM's motor values, from the machine file, and why they are what they are.
fn motor_text(m: &Measured) -> String {
    let (Some(dc), Some(pm)) = (m.configs.first(), m.configs.get(1)) else {
        return String::new();
    };
    let e = &pm.plant.electrics;
    let opt = |x: Option<f64>| x.map_or_else(|| "unset".to_string(), |v| format!("{v}"));
    let bus = e.dc_bus_pu.unwrap_or(f64::NAN);
    let drive = pm.drive.pmsm.as_ref();
    format!(
        "`configs/machines/table1-pmsm.toml` is `table1.toml` (Table 1's mechanics, encoder, \
         loop rates and bandwidths) with a three-phase PMSM under field-oriented control: {} \
         pole pairs, phase resistance {} pu, Ld {} and Lq {} pu·s, flux linkage {} pu, DC bus \
         {} pu (linear limit {:.3} pu), true encoder offset {}° electrical (the drive's \
         calibrated value {}°), angle advance {} current ticks. Why (the file's comments): R \
         and L are the DC winding's ({} pu, {} pu·s, L/R = 10 ms) and Ld = Lq is a surface \
         magnet rotor, for which i_d = 0 is maximum torque per ampere; λ = 1 pu gives 1 pu \
         torque per pu of q current, as the DC motor's per pu of current; the bus gives the \
         DC drive's voltage limit ({} pu); the advance is Table 1's 0.18 ms delay plus half a \
         tick; 4 pole pairs is a common servo motor. So the two drives differ by the current \
         loop alone.",
        e.pole_pairs
            .map_or_else(|| "unset".to_string(), |p| p.to_string()),
        e.winding_resistance_pu,
        opt(e.d_inductance_pu_s),
        opt(e.q_inductance_pu_s),
        opt(e.flux_linkage_pu),
        bus,
        bus / 3f64.sqrt(),
        opt(e.encoder_offset_elec_deg),
        drive
            .and_then(|p| p.encoder_offset_elec_deg)
            .map_or_else(|| "unset".to_string(), |v| v.to_string()),
        drive.map_or_else(
            || "unset".to_string(),
            |p| p.angle_advance_ticks.to_string()
        ),
        dc.plant.electrics.winding_resistance_pu,
        dc.plant.electrics.winding_inductance_pu_s,
        dc.drive.voltage_limit_pu,
    )
}

/// The largest relative difference of the measured stiffness between the motors, AFB off
/// and on, over the grid.
fn motors_apart(m: &Measured) -> String {
    let (Some(dc), Some(pm)) = (m.stiffness.first(), m.stiffness.get(1)) else {
        return String::new();
    };
    let apart = |afb: bool| {
        dc.points
            .iter()
            .filter(|p| p.afb == afb)
            .filter_map(|d| {
                let p = pm
                    .points
                    .iter()
                    .find(|p| p.afb == afb && p.freq_rad_s == d.freq_rad_s)?;
                Some((p.measured / d.measured - 1.0).abs())
            })
            .fold(0.0, f64::max)
    };
    format!(
        "The PMSM's measured stiffness differs from the DC model's by at most {:.1} % without \
         AFB and {:.1} % with it, over the {} frequencies.",
        100.0 * apart(false),
        100.0 * apart(true),
        dc.points.iter().filter(|p| !p.afb).count()
    )
}

/// The stiffness ratios per machine and the DC section's criteria on each.
fn stiffness_text(m: &Measured) -> String {
    let mut t = format!(
        "Stiffness: the `stiffness` scenario's sine load on each machine file's own plant \
         and drive (what `stiffness --config FILE` measures), AFB off at the AFB design's \
         gains, by the DC section's criteria. The DC section's run applies the scenario's \
         `set` table (Fig. 2's gains, a 200 Hz coupling), not applied here: the PMSM plant's \
         internal step is bounded by the stiff coupling's rate, and the grid would cost \
         several times the rest of the section. {}\n\n\
         | machine | with AFB / without (observer) | (a) within {} of J + Ka·F·G below the \
         observer bandwidth | (b) low band {}-{} below bw/3 | (b) above {} from 3 bw to the \
         observer bandwidth | verdict |\n|---|---|---|---|---|---|\n",
        motors_apart(m),
        pct(super::STIFFNESS_MODEL_TOLERANCE),
        super::STIFFNESS_LOW_BAND.0,
        super::STIFFNESS_LOW_BAND.1,
        super::STIFFNESS_HIGH_MIN,
    );
    for s in &m.stiffness {
        let f = &s.findings;
        let dev = f.model_dev.iter().map(|(_, d)| d.abs()).fold(0.0, f64::max);
        let _ = writeln!(
            t,
            "| {} (bw {} rad/s, observer {:.0} rad/s) | {} | {} (largest {:.0} %) | {} | {} | \
             {} |",
            s.machine,
            s.bands.0,
            s.bands.1,
            list(&f.observer),
            holds(f.ok_model),
            100.0 * dev,
            holds(f.ok_low),
            holds(f.ok_high),
            f.verdict()
        );
    }
    let same = |f: fn(&Findings) -> bool| {
        m.stiffness
            .windows(2)
            .all(|w| matches!(w, [a, b] if f(&a.findings) == f(&b.findings)))
    };
    if same(|f| f.ok_model) && same(|f| f.ok_low) && same(|f| f.ok_high) {
        t.push_str(
            "\nEach criterion reads the same on both motors: where one fails, it is the \
             machine's drive and coupling (table1's, not Fig. 2's rigid one), not the motor.\n",
        );
    }
    t
}

/// The section.
pub fn section(m: &Measured) -> Result<Section> {
    let (ratios, verdicts) = ratio_lines(&m.pairs);
    let (fine, fine_holds) = fine_text(&m.fine);
    let (fine_dc, fine_pm) = both(&m.fine, "fig6").ok_or_else(|| {
        HarnessError::Backend("fig6 with the fine encoder did not run on both machines".into())
    })?;
    let (dc, pm) = both(&m.pairs, "fig6")
        .ok_or_else(|| HarnessError::Backend("fig6 did not run on both machines".to_string()))?;
    let fig6_ok = pm.failures().is_empty();
    let fig6_ratio = verdicts.iter().any(|(s, ok)| *s == "fig6" && *ok);
    let measured = format!(
        "{}\n\n{}\n{ratios}\n{fine}\n{}\nThe section's runs (the pairs at {} timings on both \
         machines with each encoder, the stiffness grid on both) took {:.1} s of wall time; the runs at the scenarios' own \
         timing are in `{RUN_DIR}/`.",
        motor_text(m),
        pairs_table(&m.pairs),
        stiffness_text(m),
        OFFSETS_S.len(),
        m.wall_s
    );
    let row_verdict = match (fig6_ok, fig6_ratio) {
        (true, true) => "**agrees**",
        (true, false) => "**partly agrees**",
        _ => "**does not agree**",
    };
    Ok(Section::claim(
        "The paper on a PMSM",
        &[&format!("{RUN_DIR}/table1-pmsm/fig6/trace.png")],
        "The claims above are the paper's on its motor model; the same drive on Table 1's \
         mechanics with a three-phase PMSM should keep them: fig6's slight overshoot and \
         calmer load step, less ripple after a shock, more stiffness above the velocity \
         bandwidth.",
        measured,
        format!(
            "each pair by its DC section's criterion (table; fig6: stable, overshoot above 0 \
             and at most {SLIGHT_OVERSHOOT_PU} pu, no more shaft ripple with AFB; shock: less \
             shaft ripple with AFB), the stiffness by the Fig. 2 section's, and one criterion \
             fixed before the runs: the PMSM's shaft-ripple ratio with AFB / without within {} \
             of the DC model's on the same scenario, at the scenario's timing ({}). The \
             spreads over the step's timing say how much of a difference is the moment of \
             the step.",
            pct(PMSM_RATIO_TOLERANCE),
            verdicts
                .iter()
                .map(|(s, ok)| format!("`{s}` {}", verdict(*ok)))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    )
    .row(
        "Fig. 6/7 on a PMSM (table1-pmsm): AFB calms the load step as on the DC model",
        format!(
            "slight overshoot; calmer load step; shaft-ripple ratio with / without AFB within \
             {} of the DC model's",
            pct(PMSM_RATIO_TOLERANCE)
        ),
        format!(
            "DC section's criterion {} on the PMSM; ratio {:.3} on the PMSM, {:.3} on the DC \
             model ({:+.0} %); over the step's timing {:.3}-{:.3} against {:.3}-{:.3}; with a \
             {FINE_ENCODER_CPR}-count encoder {:.3} against {:.3} ({:+.0} %, the limit-cycle \
             hypothesis {})",
            if pm.failures().is_empty() {
                "met"
            } else {
                "missed"
            },
            pm.ratio(),
            dc.ratio(),
            100.0 * (pm.ratio() / dc.ratio() - 1.0),
            pm.spread().min,
            pm.spread().max,
            dc.spread().min,
            dc.spread().max,
            fine_pm.ratio(),
            fine_dc.ratio(),
            100.0 * (fine_pm.ratio() / fine_dc.ratio() - 1.0),
            if fine_holds { "holds" } else { "refuted" },
        ),
        row_verdict,
    ))
}

#[cfg(test)]
#[allow(clippy::panic)]
mod tests {
    use super::*;

    /// The experiments are the DC sections' on the other machine file: each pair's run
    /// without AFB borrows its AFB run's gains on the same file, the PMSM file runs a PMSM
    /// drive with the DC file's mechanics and loop, and the stiffness runs differ between
    /// the files in the motor alone.
    #[test]
    fn the_pairs_and_the_stiffness_run_are_the_dc_sections_on_each_machine() {
        let ok = |r: Result<RunConfig>| r.unwrap_or_else(|e| panic!("{e}"));
        for (scenario, _) in PAIRS {
            let [dc, pm] = MACHINES.map(|m| {
                let afb = ok(resolve(scenario, Some(m), &[]));
                let off = ok(resolve(&format!("{scenario}-no-afb"), Some(m), &[]));
                let g = |c: &RunConfig| regulator_gains(c).unwrap_or_else(|e| panic!("{e}"));
                assert!(
                    same_regulator_gains(&g(&afb), &g(&off)),
                    "{scenario} on {m}"
                );
                assert_eq!(off.gains_of.map(|g| g.source), Some(scenario.to_string()));
                afb
            });
            assert!(
                dc.drive.pmsm.is_none() && pm.drive.pmsm.is_some(),
                "{scenario}"
            );
            assert_eq!(dc.plant.mechanics, pm.plant.mechanics, "{scenario}");
            assert_eq!(dc.scenario.load, pm.scenario.load, "{scenario}");
            assert_eq!(
                dc.drive.velocity_bandwidth_rad_s,
                pm.drive.velocity_bandwidth_rad_s
            );
        }
        let [dc, pm] = MACHINES.map(|m| machine_base(m, &[]).unwrap_or_else(|e| panic!("{e}")).0);
        assert!(dc.drive.pmsm.is_none() && pm.drive.pmsm.is_some());
        assert_eq!(dc.plant.mechanics, pm.plant.mechanics);
        assert_eq!(dc.drive.accel_feedback, pm.drive.accel_feedback);
        assert_eq!(dc.drive.observer, pm.drive.observer);
    }

    #[test]
    fn the_ratio_criterion_is_relative_to_the_dc_model_and_refuses_nan() {
        assert!(within_tolerance(0.70, 0.62));
        assert!(!within_tolerance(0.72, 0.62));
        assert!(within_tolerance(0.54, 0.62));
        assert!(!within_tolerance(0.52, 0.62));
        assert!(!within_tolerance(f64::NAN, 0.62));
        assert!(!within_tolerance(0.62, f64::NAN));
    }
}
