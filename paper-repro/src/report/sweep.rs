//! Sec. III-D: the largest stable velocity bandwidth with and without acceleration feedback.

use super::section::Section;
use super::{SWEEP_NO_AFB_MAX_RAD_S, SWEEP_RATIO_MIN};
use machine_workflows::sweep::limits::{limit, moved, Limit};
use machine_workflows::sweep::{SweepPoint, SweepResult};
use sim_engine::error::Result;
use std::fmt::Write as _;

/// A point's oscillation verdict: `limit_cycle at 178.2 Hz, ±0.512 pu`.
pub fn verdict_of(p: &SweepPoint) -> String {
    match p.oscillation {
        Some(k) => format!(
            "{} at {:.1} Hz, ±{:.3} pu",
            k.word(),
            p.oscillation_freq_hz,
            p.oscillation_amplitude_pu
        ),
        None => "not run".into(),
    }
}

/// What ended one limit, and the limit without the oscillation verdict when that differs.
fn ended(l: &Limit) -> String {
    let side = if l.afb { "with AFB" } else { "without AFB" };
    let mut s = format!("{} {side}: {} rad/s", l.plant, l.limit_rad_s);
    if let Some(p) = l.ended_by {
        let _ = write!(
            s,
            "; at {} rad/s ({}) the verdict is {}{}",
            p.bandwidth_rad_s,
            p.design,
            verdict_of(p),
            if p.faulted { ", faulted" } else { "" }
        );
    }
    if l.by_speed_rad_s == l.limit_rad_s {
        s.push_str(" (the speed criterion alone gives the same limit)");
    } else {
        let _ = write!(
            s,
            " (the speed criterion alone, without the oscillation verdict: {} rad/s; this \
             point moved it)",
            l.by_speed_rad_s
        );
    }
    s
}

/// The paragraph on what decided the limits, and the points the oscillation verdict moved.
pub fn decided(points: &[SweepPoint], plants: &[&str]) -> String {
    let limits: Vec<String> = plants
        .iter()
        .flat_map(|p| [limit(points, p, false), limit(points, p, true)])
        .map(|l| ended(&l))
        .collect();
    let moved = moved(points);
    let mut kinds: Vec<&str> = Vec::new();
    for p in &moved {
        let k = p.oscillation.map_or("not run", |k| k.word());
        if !kinds.contains(&k) {
            kinds.push(k);
        }
    }
    format!(
        "What ended each limit (the first point above it judged unstable, with its \
         oscillation verdict from `summary.json`'s rule): {}. The oscillation verdict changed \
         {} of {} points from the speed criterion alone (`stable` ≠ `stable_by_speed` in \
         `sweep/sweep.csv`; verdicts {:?}).",
        limits.join("; "),
        moved.len(),
        points.iter().filter(|p| p.error.is_empty()).count(),
        kinds
    )
}

/// Sec. III-D's verdict on the printing press's largest bandwidths (without AFB, with AFB)
/// \[rad/s\]: the AFB design reaches at least [`SWEEP_RATIO_MIN`] times the bandwidth
/// without, and the bandwidth without is at most [`SWEEP_NO_AFB_MAX_RAD_S`]; one of the
/// two: partly. Used for the sweep and for `tune`'s designs ([`super::tune`]).
pub fn bandwidth_verdict(press: Option<(f64, f64)>) -> &'static str {
    let ratio_ok =
        press.is_some_and(|(without, with)| without > 0.0 && with >= SWEEP_RATIO_MIN * without);
    let level_ok = press.is_some_and(|(without, _)| without <= SWEEP_NO_AFB_MAX_RAD_S);
    match (ratio_ok, level_ok) {
        (true, true) => "**agrees**",
        (true, false) | (false, true) => "**partly agrees**",
        _ => "**does not agree**",
    }
}

/// The sweep's findings per plant, and the printing press against the paper.
pub fn section(points: &[SweepPoint], sweep: &[SweepResult]) -> Result<Section> {
    let mut found = String::new();
    for s in sweep {
        let _ = write!(
            found,
            "{}: stable up to {} rad/s without AFB and {} rad/s with (best: {}); quiet (torque \
             chatter below {} pu) up to {} rad/s without and {} rad/s with (best: {}). ",
            s.plant,
            s.without_afb_rad_s,
            s.with_afb_rad_s,
            s.best_design,
            machine_workflows::sweep::QUIET_TORQUE_PU,
            s.quiet_without_afb_rad_s,
            s.quiet_with_afb_rad_s,
            s.best_quiet_design
        );
    }
    let pp = sweep.iter().find(|s| s.plant == "printing-press");
    let sweep_verdict = bandwidth_verdict(pp.map(|s| (s.without_afb_rad_s, s.with_afb_rad_s)));
    let press = sim_engine::config::resolve("sweep", Some("printing-press"), &[])?;
    let grid = sim_engine::config::sweep_grid()?;
    let (mech, cpr) = (&press.plant.mechanics, press.plant.counts_per_rev());
    Ok(Section::claim(
        "Sec. III-D: largest stable velocity bandwidth, printing-press stand (and Table 1)",
        &["sweep/sweep.png"],
        "Printing-press stand (1e6 CPR, 3:1 gearbox, 8:1 reflected inertia, ~150 counts lost \
         motion): 140 rad/s with acceleration feedback, only 30 rad/s without before the system \
         went unstable.",
        format!(
            "{found}Probe run `configs/scenarios/sweep.toml` in speed mode; a bandwidth counts \
             only if every grid point below it passes too. Grid (`[sweep]` of \
             `configs/grids.toml`): {:?} rad/s; AFB designs: error form, Ka/J_total in {:?}, \
             filters {:?}, acceleration from differentiation or from \
             the observer at {:?} Hz (every point in `sweep/sweep.csv`; points whose gains do \
             not fit controller-core's fixed-point formats are rejected there and count as not \
             achievable). The runs without AFB use the gains of each plant's default AFB design \
             at the same bandwidth, one per observer bandwidth of the grid (the observer also \
             gives the velocity feedback); \"without AFB\" is the better of them. The modelled \
             press: {cpr} counts/rev, lost motion {} deg ({:.0} counts), Jm {} s, Jl {} s \
             (`configs/machines/printing-press.toml`). {}",
            grid.bandwidths_rad_s,
            grid.gains,
            grid.filter_configs(),
            grid.observer_hz,
            mech.backlash_deg,
            mech.backlash_deg / 360.0 * f64::from(cpr),
            mech.motor_inertia_s,
            mech.load_inertia_s,
            decided(points, &machine_workflows::sweep::PLANTS)
        ),
        format!(
            "{sweep_verdict} (criteria: on the printing press the best AFB design reaches at \
             least {SWEEP_RATIO_MIN} times the stable bandwidth reached without, as the paper's \
             140 against 30 rad/s; and the limit without AFB is of the paper's order, at most \
             {SWEEP_NO_AFB_MAX_RAD_S} rad/s; one of the two: partly). The modelled press has no \
             friction and no gear-tooth compliance, and its inertias and coupling are \
             assumptions; which of the real stand's effects set its limit is not something this \
             model can say. The next section applies the same criteria to the highest bandwidths \
             `tune` finds with and without AFB under its constraints."
        ),
    )
    .row(
        "Sec. III-D: AFB raises the largest stable velocity bandwidth (sweep)",
        "printing press: 140 rad/s with AFB, 30 rad/s without",
        sweep
            .iter()
            .map(|s| {
                format!(
                    "{}: {} rad/s with AFB, {} rad/s without",
                    s.plant, s.with_afb_rad_s, s.without_afb_rad_s
                )
            })
            .collect::<Vec<_>>()
            .join("; "),
        sweep_verdict,
    ))
}
