//! Sec. II: without acceleration feedback the system becomes unstable, with the drive's
//! observer and with the paper's differentiation; and the 1-2 rad/s loop.

use super::facts::{fill, stable_window};
use super::runs::gains_line;
use super::section::{verdict, Section};
use super::{get, Runs, HIGHLY_OSCILLATORY_PU};
use crate::sec2::{at, summarize, summary_text, table, MapPoint, ENCODER_INTERPOLATIONS};
use sim_engine::error::Result;
use sim_engine::run::fmt_opt;
use std::fmt::Write as _;

/// Sec. II with the drive's own estimator (fig6 without AFB).
pub fn observer(runs: &Runs) -> Result<Section> {
    let (c6, n6) = get(runs, "fig6-no-afb")?;
    let m = &n6.metrics;
    let okn = !m.stable;
    Ok(Section::claim(
        "Sec. II: without acceleration feedback the system becomes unstable (the drive's \
         observer estimator)",
        &["fig6-no-afb/trace.png"],
        "If the acceleration signal was not fed back, the system would become unstable.",
        format!(
            "same gains as fig6, AFB off, velocity from the drive's observer: stable {} \
             (oscillation verdict {} at {:.1} Hz, ±{:.3} pu); speed-error oscillation in the \
             stability window ({}) {:.4} pu; motor-torque ripple {:.3} pu RMS; droop {} pu; \
             twist up to {:.1} counts. {}.",
            m.stable,
            m.oscillation.kind.word(),
            m.oscillation.freq_hz,
            m.oscillation.amplitude_pu,
            stable_window(c6),
            m.oscillation_pu,
            m.torque_ripple_rms_pu,
            fmt_opt(m.load_step_droop_pu),
            m.max_twist_counts,
            gains_line(runs, "fig6", "fig6-no-afb")?
        ),
        format!(
            "{} (criterion: the `stable` metric is false). {}",
            verdict(okn),
            if okn {
                "The model reproduces the instability with the observer."
            } else {
                "With the observer's velocity the loop without AFB stays stable: the paper \
                 found velocity and acceleration by differentiation, and the next section \
                 repeats the claim with that estimator."
            }
        ),
    )
    .row(
        "Sec. II: without AFB the loop is unstable (drive's observer)",
        "unstable without AFB",
        format!(
            "stable {}; verdict {} at {:.1} Hz, ±{:.3} pu",
            m.stable,
            m.oscillation.kind.word(),
            m.oscillation.freq_hz,
            m.oscillation.amplitude_pu
        ),
        verdict(okn),
    ))
}

/// Sec. II with the paper's estimator: the map over filter corners, per encoder.
pub fn differentiation(runs: &Runs, map: &[MapPoint]) -> Result<Section> {
    let (c, _) = get(runs, "fig6")?;
    let mut body = format!(
        "![Sec. II map](sec2/sec2-map.png)\n\n**Paper:** \"The velocity and acceleration \
         signals were found by differentiation\"; with acceleration feedback the system is \
         stable, and if the acceleration signal was not fed back the system would become \
         unstable.\n\n**Measured:** `{}` with differentiated velocity (first-order filter, \
         rows) and differentiated acceleration for the AFB path (first-order filter, columns), \
         the drive's default AFB gain and form, for the Table 1 encoder and the same encoder \
         interpolated (interpolation factors {:?}; the following-error trip kept at the same \
         angle). Each row's run without AFB is at the gains of that row's AFB design. Each \
         cell: fig6's `stable` metric, the speed-error oscillation in its stability window ({}, \
         pu), and for an unstable run whether the drive tripped and how long the torque sat at \
         its limit. Every cell is in `sec2/sec2.csv`. The criterion was fixed for the Table 1 map \
         before it ran; the interpolated map was added after the first map had been seen, and \
         is judged by the same criterion.\n",
        crate::sec2::SCENARIO,
        ENCODER_INTERPOLATIONS,
        stable_window(c)
    );
    let mut rows = Vec::new();
    for n in ENCODER_INTERPOLATIONS {
        let m = at(map, n);
        let ms = summarize(&m);
        let v = if ms.unstable_without_hz.is_empty() || ms.stable_with_where_unstable_without == 0 {
            "**does not agree**"
        } else if 2 * ms.stable_with_where_unstable_without >= ms.cells_where_unstable_without {
            "**agrees**"
        } else {
            "**partly agrees**"
        };
        let _ = write!(
            body,
            "\n### Encoder {} counts/rev x {n} = {} counts/rev\n\n{}\n{}\n\n**Assessment:** {v} \
             (criterion, over the whole map: the loop without AFB is unstable at one \
             velocity-filter corner or more, and in those rows the loop with AFB is stable in \
             at least half of the cells; \"partly agrees\" if it is stable in fewer than half \
             but in one or more; \"does not agree\" otherwise). The map, not one point of it, \
             is the result.\n",
            c.plant.mechanics.encoder_cpr,
            c.plant.mechanics.encoder_cpr.saturating_mul(n),
            table(&m),
            summary_text(&m)
        );
        rows.push(super::section::ClaimRow {
            claim: format!(
                "Sec. II with differentiation, encoder x{n}: unstable without AFB, stable with"
            ),
            paper: "unstable without AFB; stable with".into(),
            measured: format!(
                "without AFB unstable at velocity-filter corners {:?} Hz; with AFB stable in {} \
                 of {} cells of those rows",
                ms.unstable_without_hz,
                ms.stable_with_where_unstable_without,
                ms.cells_where_unstable_without
            ),
            verdict: v.into(),
        });
    }
    let mut s = Section::text(
        "Sec. II with the paper's estimator: velocity and acceleration by differentiation",
        body,
    );
    s.rows = rows;
    Ok(s)
}

/// Sec. II: at 1-2 rad/s the loop without AFB is stable but highly oscillatory.
pub fn low_bandwidth(runs: &Runs) -> Result<Section> {
    let (cl, l6) = get(runs, "fig6-low-bw")?;
    let m = &l6.metrics;
    let oscillatory = m.oscillation_pu > HIGHLY_OSCILLATORY_PU;
    let low_verdict = match (m.stable, oscillatory) {
        (true, true) => "**agrees**",
        (true, false) => "**partly agrees**",
        _ => "**does not agree**",
    };
    Ok(Section::claim(
        fill(
            "Sec. II: at {bw} rad/s velocity bandwidth (the paper's 1-2 rad/s) stable but \
             highly oscillatory",
            cl,
        ),
        &["fig6-low-bw/trace.png"],
        "With the velocity loop bandwidth reduced to 1-2 rad/s the system could be stabilized, \
         but would remain highly oscillatory.",
        format!(
            "AFB off, {} rad/s, speed mode: stable {}; droop after the 50 % step {} pu; settling \
             {} s; speed-error oscillation in the stability window {:.4} pu; load overshoot {} pu.",
            cl.drive.velocity_bandwidth_rad_s,
            m.stable,
            fmt_opt(m.load_step_droop_pu),
            fmt_opt(m.settling_s),
            m.oscillation_pu,
            fmt_opt(m.overshoot_pu)
        ),
        format!(
            "{low_verdict} (criteria: `stable`, and \"highly oscillatory\" as a speed-error \
             oscillation above {HIGHLY_OSCILLATORY_PU} pu in the stability window). {}",
            if oscillatory {
                "The loop is stable and rings."
            } else {
                "The loop is stable but not oscillatory in the model: a loop this slow droops \
                 and recovers over seconds (`fig6-compare.png`, bottom). The paper's \
                 oscillation at this bandwidth is not reproduced."
            }
        ),
    )
    .row(
        fill(
            "Sec. II: at {bw} rad/s stable but highly oscillatory",
            cl,
        ),
        "stable but highly oscillatory at 1-2 rad/s",
        format!(
            "stable {}; speed-error oscillation {:.4} pu (criterion above {HIGHLY_OSCILLATORY_PU} pu)",
            m.stable, m.oscillation_pu
        ),
        low_verdict,
    ))
}
