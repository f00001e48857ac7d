//! Sec. III-D with `tune`: each machine's design with AFB and the no-AFB design by the same
//! constraints, as the linear model predicts them and as the nonlinear loop measures them.

use super::section::Section;
use super::{SWEEP_NO_AFB_MAX_RAD_S, SWEEP_RATIO_MIN};
use controller_core::{AfbMode, FilterConfig};
use machine_workflows::sweep::grid::word;
use machine_workflows::tune::machines::{Bandwidth, MachineTune, LOOP_SCENARIO};
use machine_workflows::tune::pair::{LoopRun, CRITERION};
use machine_workflows::tune::{Constraints, Judged};
use sim_engine::error::Result;
use std::fmt::Write as _;

fn filter_text(f: FilterConfig) -> String {
    match f {
        FilterConfig::None => "none".into(),
        FilterConfig::FirstOrder { corner_hz } => format!("1st order {corner_hz} Hz"),
        FilterConfig::SecondOrder { corner_hz, q } => {
            format!("2nd order {corner_hz} Hz, Q {q:.3}")
        }
    }
}

fn opt(x: Option<f64>, digits: usize) -> String {
    x.map_or_else(|| "-".into(), |v| format!("{v:.digits$}"))
}

/// A damping that is infinite (no lost motion: no gears-apart model) as "-".
fn finite(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.3}")
    } else {
        "-".into()
    }
}

/// One row of the designs table.
fn design_row(s: &mut String, machine: &str, which: &str, j: &Judged, fitted: Option<f64>) {
    let a = &j.candidate.afb;
    let (ka, filter, source) = if a.mode == AfbMode::Off {
        ("-".to_string(), "-".to_string(), "-".to_string())
    } else {
        (
            format!("{}", a.gain_fraction),
            filter_text(a.filter),
            word(a.source),
        )
    };
    let _ = writeln!(
        s,
        "| {machine} | {which} | {} | {} | {ka} | {filter} | {source} | {} | {} | {} | {} | {:.1} \
         | {:.1} | {:.3} |",
        j.candidate.bandwidth_rad_s,
        word(a.mode),
        a.observer_hz,
        finite(j.damping[0]),
        finite(j.damping[1]),
        opt(fitted, 3),
        j.margins[0],
        j.margins[1],
        j.noise_pu,
    );
}

fn loop_row(s: &mut String, machine: &str, r: &LoopRun) {
    let _ = writeln!(s, "| {machine} |{}", r.row());
}

/// Why a machine passed or failed, in its figures.
fn finding(t: &MachineTune) -> String {
    let [a, b] = &t.runs;
    let how = if t.passed { "passes" } else { "**fails**" };
    let mut why = format!(
        "{}: {how}: with AFB at {} rad/s {}{}, ripple {:.4} pu at {:.1} Hz against {:.4} pu at \
         {:.1} Hz without AFB at {} rad/s ({}; predicted quantization torque noise {:.3} \
         against {:.3} pu)",
        t.machine,
        a.bandwidth_rad_s,
        if a.stable {
            "stable".to_string()
        } else {
            format!("unstable ({})", a.verdict())
        },
        if a.faulted { ", faulted" } else { "" },
        a.shaft_torque_ripple_rms_pu,
        a.shaft_ripple_freq_hz,
        b.shaft_torque_ripple_rms_pu,
        b.shaft_ripple_freq_hz,
        b.bandwidth_rad_s,
        super::section::change(a.shaft_torque_ripple_rms_pu, b.shaft_torque_ripple_rms_pu),
        t.with.noise_pu,
        t.without.noise_pu
    );
    if let (Some(da), Some(db)) = (a.load_step_droop_pu, b.load_step_droop_pu) {
        let _ = write!(why, "; droop {da:.4} pu against {db:.4} pu");
    }
    why.push('.');
    why
}

fn how_tuned(tunes: &[MachineTune]) -> String {
    let mut s = String::new();
    for t in tunes {
        let bw = match t.bandwidth {
            Bandwidth::Max => "the highest velocity bandwidth of the grid that meets them \
                               (`--max-bandwidth`)"
                .to_string(),
            Bandwidth::FromConfig => format!(
                "the machine's own velocity bandwidth, {} rad/s (`--target-bandwidth`)",
                opt(t.target_bandwidth_rad_s, 2)
            ),
        };
        let _ = write!(
            s,
            "{}: {bw}; {} candidates judged with AFB, {} without; {:.1} s. ",
            t.machine, t.judged[0], t.judged[1], t.wall_s
        );
    }
    s
}

/// The highest bandwidths with and without AFB, and the sweep section's verdict on them
/// for the printing press (judged only when its bandwidth was searched, not given).
/// The sweep section's verdict on the printing press's tuned bandwidths (judged only when
/// its bandwidth was searched, not given).
fn bandwidth_verdict(tunes: &[MachineTune]) -> &'static str {
    tunes
        .iter()
        .find(|t| t.machine == "printing-press" && t.bandwidth == Bandwidth::Max)
        .map_or(
            "not judged (the printing press's bandwidth was not searched)",
            |t| {
                super::sweep::bandwidth_verdict(Some((
                    t.without.candidate.bandwidth_rad_s,
                    t.with.candidate.bandwidth_rad_s,
                )))
            },
        )
}

fn bandwidths(tunes: &[MachineTune]) -> String {
    let per: Vec<String> = tunes
        .iter()
        .map(|t| {
            let (a, b) = (
                t.with.candidate.bandwidth_rad_s,
                t.without.candidate.bandwidth_rad_s,
            );
            format!("{} {a} / {b} rad/s ({:.1}x)", t.machine, a / b.max(1e-12))
        })
        .collect();
    let verdict = bandwidth_verdict(tunes);
    format!(
        "Bandwidth, by the sweep section's criteria on the printing press (with AFB at least \
         {SWEEP_RATIO_MIN} times the bandwidth without, and without at most \
         {SWEEP_NO_AFB_MAX_RAD_S} rad/s; one of the two: partly): {verdict}. With / without AFB: \
         {}.",
        per.join(", ")
    )
}

/// The runs whose `stable` the oscillation verdict decided, one paragraph each.
fn moved_by_verdict(tunes: &[MachineTune]) -> String {
    let mut s = String::new();
    for t in tunes {
        for line in t.runs.iter().filter_map(LoopRun::moved_by_verdict) {
            let _ = write!(s, "\n{}: {line}.\n", t.machine);
        }
    }
    s
}

/// The section: both designs per machine, their runs, and the verdict by [`CRITERION`].
pub fn section(tunes: &[MachineTune], k: &Constraints) -> Result<Section> {
    let mut m = format!(
        "`hil-harness tune` on each machine with AFB, and the no-AFB design by the same \
         constraints (smallest damping {} engaged and apart, except near a resonance the \
         machine damps less, where the machine's own; phase margin {} deg, gain margin \
         {} dB, quantization torque noise at most {} pu RMS; the no-AFB design at the AFB \
         search's bandwidths or the highest below them that meets the constraints). {}Files: \
         `tune/<machine>/` (the AFB design, as `tune` writes it) and `tune/<machine>/no-afb/`; \
         `tune/machines.json` holds the figures below.\n\n\
         | machine | design | bandwidth (rad/s) | AFB | Ka/J_total | filter | estimator | \
         observer (Hz) | damping engaged | damping apart | damping fitted in the loop | PM \
         (deg) | GM (dB) | noise (pu) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
        k.min_damping,
        k.min_phase_margin_deg,
        k.min_gain_margin_db,
        k.max_noise_pu,
        how_tuned(tunes)
    );
    for t in tunes {
        design_row(
            &mut m,
            &t.machine,
            "with AFB",
            &t.with,
            t.with_fitted_damping,
        );
        design_row(&mut m, &t.machine, "without AFB", &t.without, None);
    }
    let _ = write!(
        m,
        "\nBoth designs on `{LOOP_SCENARIO}` with the machine's own plant:\n\n\
         | machine | {} \n|---|{}\n",
        LoopRun::HEADER,
        LoopRun::RULE
    );
    for t in tunes {
        for r in &t.runs {
            loop_row(&mut m, &t.machine, r);
        }
    }
    m.push_str(&moved_by_verdict(tunes));
    let _ = write!(
        m,
        "\nBy `tune`'s objective (after `{LOOP_SCENARIO}`'s load step, peak droop + peak shaft \
         torque + recovery time, each against the machine file's own drive: 3 is the file's \
         drive, lower is better; docs/tuning.md), the design `tune` writes as `drive.toml`:\n\n\
         | machine | J with AFB | J without AFB | chosen |\n|---|---|---|---|\n"
    );
    for t in tunes {
        let _ = writeln!(
            m,
            "| {} | {:.3} | {:.3} | {} |",
            t.machine, t.objective[0], t.objective[1], t.chosen
        );
    }
    let passed = tunes.iter().filter(|t| t.passed).count();
    let verdict = match passed {
        n if n == tunes.len() && n > 0 => "**agrees**",
        0 => "**does not agree**",
        _ => "**partly agrees**",
    };
    let findings: Vec<String> = tunes.iter().map(finding).collect();
    let droop_lower = tunes
        .iter()
        .filter(|t| {
            let [a, b] = &t.runs;
            matches!((a.load_step_droop_pu, b.load_step_droop_pu), (Some(x), Some(y)) if x < y)
        })
        .count();
    let section = Section::claim(
        "Sec. III-D with `tune`: designed with and without AFB by the same constraints",
        &[],
        "Acceleration feedback lets the velocity loop be tuned higher (140 against 30 rad/s on \
         the printing press) and makes the drive stiffer against load torque.",
        m,
        format!(
            "{} Load-step ripple: {verdict}: {passed} of {} machines pass (criterion, fixed \
             before the runs: on each machine, {CRITERION}; all pass: agrees, none: does not \
             agree). {} Beside the \
             criterion: the speed droop at the load step is lower with AFB on {droop_lower} of {} \
             machines. The ripple is the shaft torque's content above about 5 Hz from 0.1 s \
             after the step to the end of the run (`sim-engine/README.md`): the ringing the \
             step excites and the chatter that stays.",
            bandwidths(tunes),
            tunes.len(),
            findings.join(" "),
            tunes.len()
        ),
    );
    Ok(claim_rows(section, tunes, passed, verdict))
}

/// The section's two rows of the claims table: the bandwidths and the load-step ripple.
fn claim_rows(s: Section, tunes: &[MachineTune], passed: usize, verdict: &str) -> Section {
    s.row(
        "Sec. III-D with `tune`: AFB allows a higher bandwidth under the same constraints",
        "printing press: 140 rad/s with AFB, 30 rad/s without",
        tunes
            .iter()
            .map(|t| {
                format!(
                    "{}: {} rad/s with AFB, {} rad/s without",
                    t.machine,
                    t.with.candidate.bandwidth_rad_s,
                    t.without.candidate.bandwidth_rad_s
                )
            })
            .collect::<Vec<_>>()
            .join("; "),
        bandwidth_verdict(tunes),
    )
    .row(
        "Sec. III-D with `tune`: the AFB design leaves less ripple after a load step",
        "AFB makes the drive stiffer against load torque",
        format!("{passed} of {} machines pass", tunes.len()),
        verdict,
    )
}

/// One console line per machine.
pub fn console_line(t: &MachineTune) -> String {
    let [a, b] = &t.runs;
    format!(
        "tune {}: with AFB {} rad/s ({}), ripple {:.4} pu, {}; without AFB {} rad/s, ripple \
         {:.4} pu, {} -> {}\n",
        t.machine,
        a.bandwidth_rad_s,
        a.afb,
        a.shaft_torque_ripple_rms_pu,
        a.verdict(),
        b.bandwidth_rad_s,
        b.shaft_torque_ripple_rms_pu,
        b.verdict(),
        if t.passed { "passes" } else { "fails" }
    )
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;
    use controller_core::Estimator;
    use machine_workflows::sweep::AfbDesign;
    use machine_workflows::tune::pair::afb_passes;
    use machine_workflows::tune::Candidate;

    fn judged(bandwidth_rad_s: f64, afb: AfbDesign) -> Judged {
        Judged {
            candidate: Candidate {
                bandwidth_rad_s,
                afb,
            },
            damping: [0.321, f64::INFINITY],
            margins: [45.6, 7.8],
            noise_pu: 0.0123,
            notch_band_damping: None,
            resonance_band_damping: None,
            stiffness: 1.0,
            feasible: true,
        }
    }

    fn run(design: &'static str, bw: f64, stable: bool, ripple: f64) -> LoopRun {
        LoopRun {
            design,
            bandwidth_rad_s: bw,
            afb: format!("label {bw}"),
            stable,
            oscillation: sim_engine::engine::metrics::OscillationKind::Quantization,
            oscillation_freq_hz: 266.7,
            oscillation_amplitude_pu: 0.05,
            stable_by_speed: stable,
            faulted: false,
            shaft_torque_ripple_rms_pu: ripple,
            shaft_ripple_freq_hz: 12.5,
            load_step_droop_pu: Some(ripple / 10.0),
            figures: machine_workflows::tune::objective::Figures {
                peak_droop_pu: None,
                peak_shaft_torque_pu: None,
                recovery_s: None,
                torque_noise_rms_pu: 0.0,
                stable,
                faulted: false,
            },
        }
    }

    /// A synthetic machine: AFB at 123 rad/s, no AFB at 45 rad/s, ripples as given.
    fn machine(name: &str, with_ripple: f64, without_ripple: f64) -> MachineTune {
        let afb = AfbDesign {
            mode: AfbMode::Error,
            gain_fraction: 0.75,
            filter: FilterConfig::FirstOrder { corner_hz: 321.0 },
            source: Estimator::Observer,
            observer_hz: 77.0,
        };
        let runs = [
            run("tuned with AFB", 123.0, true, with_ripple),
            run("tuned without AFB", 45.0, true, without_ripple),
        ];
        MachineTune {
            machine: name.into(),
            bandwidth: Bandwidth::Max,
            target_bandwidth_rad_s: None,
            with: judged(123.0, afb),
            with_fitted_damping: Some(0.345),
            without: judged(
                45.0,
                AfbDesign {
                    observer_hz: 88.0,
                    ..AfbDesign::OFF
                },
            ),
            judged: [4321, 43],
            passed: afb_passes(&runs[0], &runs[1]),
            runs,
            objective: [2.5, 3.5],
            chosen: "with AFB",
            wall_s: 1.5,
        }
    }

    #[test]
    fn the_section_is_built_from_the_designs_and_the_runs() {
        let k = Constraints::default();
        let tunes = [
            machine("alpha", 0.0111, 0.0222),
            machine("beta", 0.0333, 0.0222),
        ];
        let md = section(&tunes, &k).unwrap().markdown();
        for text in [
            "| alpha | with AFB | 123 | error | 0.75 | 1st order 321 Hz | observer | 77 | 0.321 | - \
             | 0.345 | 45.6 | 7.8 | 0.012 |",
            "| beta | without AFB | 45 | off | - | - | - | 88 |",
            "| alpha | tuned with AFB | 123 | label 123 | true | quantization at 266.7 Hz | false \
             | 0.0111 | 12.5 | 0.0011 |",
            "| beta | tuned without AFB | 45 | label 45 | true | quantization at 266.7 Hz | false \
             | 0.0222 | 12.5 | 0.0022 |",
            "Load-step ripple: **partly agrees**: 1 of 2 machines pass",
            "Bandwidth, by the sweep section's criteria on the printing press",
            "alpha 123 / 45 rad/s (2.7x), beta 123 / 45 rad/s (2.7x)",
            "not judged (the printing press's bandwidth was not searched)",
            "alpha: passes",
            "beta: **fails**: with AFB at 123 rad/s stable, ripple 0.0333 pu at 12.5 Hz against \
             0.0222 pu at 12.5 Hz without AFB at 45 rad/s (increased by 50 %; predicted \
             quantization torque noise 0.012 against 0.012 pu); droop 0.0033 pu against 0.0022 pu",
            "droop at the load step is lower with AFB on 1 of 2 machines",
            "4321 candidates judged with AFB, 43 without",
            CRITERION,
        ] {
            assert!(md.contains(text), "missing {text:?} in\n{md}");
        }
        let all = section(&tunes[..1], &k).unwrap().markdown();
        assert!(all.contains("**agrees**: 1 of 1"), "{all}");
        let none = section(&tunes[1..], &k).unwrap().markdown();
        assert!(none.contains("**does not agree**: 0 of 1"), "{none}");
        let press = section(&[machine("printing-press", 0.1, 0.2)], &k)
            .unwrap()
            .markdown();
        let v = crate::report::sweep::bandwidth_verdict(Some((45.0, 123.0)));
        assert!(
            press.contains(&format!("one of the two: partly): {v}.")),
            "{press}"
        );
    }
}
