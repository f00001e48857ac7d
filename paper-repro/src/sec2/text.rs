//! The map as text: its Markdown table and what it shows, counted from its points.

use super::{summarize, MapPoint, MapSummary, AFB_CORNERS_HZ, VELOCITY_CORNERS_HZ};
use sim_engine::engine::metrics::OscillationKind;
use std::fmt::Write as _;

fn cell(p: Option<&MapPoint>) -> String {
    match p {
        None => "-".into(),
        Some(p) if !p.error.is_empty() => "rejected".into(),
        Some(p) if p.stable => format!("stable ({:.3})", p.oscillation_pu),
        Some(p) => format!(
            "**unstable** ({:.3}; {} at {:.0} Hz, ±{:.3} pu{}, {:.2} s at the limit)",
            p.oscillation_pu,
            p.oscillation.map_or("not run", OscillationKind::word),
            p.oscillation_freq_hz,
            p.oscillation_amplitude_pu,
            if p.faulted { ", tripped" } else { "" },
            p.torque_saturated_s
        ),
    }
}

/// The map as a Markdown table: one row per velocity corner, the run without AFB first.
pub fn table(points: &[MapPoint]) -> String {
    let mut t = String::from("| velocity filter (Hz) | without AFB |");
    for fa in AFB_CORNERS_HZ {
        let _ = write!(t, " AFB filter {fa} Hz |");
    }
    t.push_str("\n|---|---|");
    for _ in AFB_CORNERS_HZ {
        t.push_str("---|");
    }
    for fv in VELOCITY_CORNERS_HZ {
        let _ = write!(
            t,
            "\n| {fv} | {} |",
            cell(points.iter().find(|p| !p.afb && p.velocity_corner_hz == fv))
        );
        for fa in AFB_CORNERS_HZ {
            let _ = write!(
                t,
                " {} |",
                cell(
                    points
                        .iter()
                        .find(|p| p.afb && p.velocity_corner_hz == fv && p.afb_corner_hz == fa)
                )
            );
        }
    }
    t.push('\n');
    t
}

/// One paragraph of what the map of one encoder shows, counted from its points.
pub fn summary_text(points: &[MapPoint]) -> String {
    let s = summarize(points);
    format!(
        "Without AFB the loop is unstable at velocity-filter corners {:?} Hz (of {:?} Hz). \
         In those rows the loop with AFB is stable in {} of {} cells; in the rows where the \
         loop without AFB is stable, AFB makes it unstable in {} of {} cells.",
        s.unstable_without_hz,
        VELOCITY_CORNERS_HZ,
        s.stable_with_where_unstable_without,
        s.cells_where_unstable_without,
        s.unstable_with_where_stable_without,
        s.cells_where_stable_without
    ) + &moved_text(points, &s)
}

/// The cells whose verdict the oscillation rule changed (`stable` ≠ `stable_by_speed`),
/// each with the verdict that moved it.
fn moved_text(points: &[MapPoint], s: &MapSummary) -> String {
    let moved: Vec<String> = points
        .iter()
        .filter(|p| p.error.is_empty() && p.stable != p.stable_by_speed)
        .map(|p| {
            format!(
                "{} at velocity filter {} Hz{}: {} at {:.1} Hz, ±{:.3} pu",
                if p.afb { "AFB" } else { "without AFB" },
                p.velocity_corner_hz,
                if p.afb {
                    format!(", AFB filter {} Hz", p.afb_corner_hz)
                } else {
                    String::new()
                },
                p.oscillation.map_or("not run", OscillationKind::word),
                p.oscillation_freq_hz,
                p.oscillation_amplitude_pu
            )
        })
        .collect();
    if moved.is_empty() {
        return " The oscillation verdict changed no cell's verdict from the speed criterion \
                alone."
            .into();
    }
    format!(
        " The speed criterion alone (without the oscillation verdict) finds the loop without \
         AFB unstable at {:?} Hz. The oscillation verdict changed {} cells: {}.",
        s.unstable_without_by_speed_hz,
        moved.len(),
        moved.join("; ")
    )
}
