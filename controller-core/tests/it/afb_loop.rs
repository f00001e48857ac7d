//! The acceleration loop in the linear model of the whole discrete loop that `tune` designs
//! with (`loop-model/`): the controller's ticks in f64 with its
//! quantized coefficients (observer, closed-form acceleration feedback, differentiators,
//! velocity, position and current regulators) around plant-host's exactly sampled Table 1
//! plant (RL winding, 0.18 ms delay), with the gears apart (the motor alone, Jm) or engaged
//! through the 65 Hz shaft. Stability is the spectral radius of the one-period map (ρ < 1).
//! `cargo test -p controller-core --release --test it afb_loop:: -- --nocapture`
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use crate::common;
use controller_core::{AfbMode, AfbRate, DriveConfig, Estimator, FilterConfig, design};
use loop_model::{Coefficients, LoopModel};
use plant_host::analysis::Gears;

const JM: f64 = 0.117;
const JT: f64 = 0.98;

/// The linear loop of `cfg` with Ka scaled by `ka_scale` from its design (beyond the
/// settings' range where the scale asks for it), with the gears `gears`.
fn model(cfg: &DriveConfig, ka_scale: f64, gears: Gears) -> LoopModel {
    model_with(cfg, ka_scale, gears, true)
}

/// [`model`], with the position loop or in speed mode (no position loop).
fn model_with(cfg: &DriveConfig, ka_scale: f64, gears: Gears, position_loop: bool) -> LoopModel {
    let mut g = design(cfg).unwrap();
    g.ka = (f64::from(g.ka) * ka_scale) as f32;
    if !position_loop {
        g.kpp = 0.0;
        g.k_pos_pu_per_count = 0.0;
    }
    let coef = Coefficients::new(cfg, &g).unwrap();
    LoopModel::new(
        coef,
        &common::table1_plant(),
        f64::from(cfg.current_rate_hz),
        gears,
    )
}

fn radius(cfg: &DriveConfig, gears: Gears) -> f64 {
    model(cfg, 1.0, gears).spectral_radius()
}

/// The largest `x` in [lo, hi] with `stable(x)` (0 if `lo` is unstable, `hi` if `hi` is
/// stable), stability assumed to hold below the limit.
fn bisect(lo: f64, hi: f64, mut stable: impl FnMut(f64) -> bool) -> f64 {
    if !stable(lo) {
        return 0.0;
    }
    if stable(hi) {
        return hi;
    }
    let (mut lo, mut hi) = (lo, hi);
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        if stable(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The Table 1 default is stable with Ka halved and doubled, gears apart and engaged, and
/// so is the loop without acceleration feedback.
#[test]
fn default_design_and_its_ka_neighbours_are_stable() {
    let base = common::table1();
    for scale in [0.5f32, 1.0, 2.0] {
        let mut cfg = base;
        cfg.accel_feedback.gain_fraction *= scale;
        let (ra, re) = (radius(&cfg, Gears::Apart), radius(&cfg, Gears::Engaged));
        println!("default with Ka × {scale}: ρ apart {ra:.4}, engaged {re:.4}");
        assert!(ra < 1.0 && re < 1.0, "default × {scale}: {ra} {re}");
    }
    let mut off = base;
    off.accel_feedback.mode = AfbMode::Off;
    let (ra, re) = (radius(&off, Gears::Apart), radius(&off, Gears::Engaged));
    println!("AFB off: ρ apart {ra:.4}, engaged {re:.4}");
    assert!(ra < 1.0 && re < 1.0, "AFB off: {ra} {re}");
}

/// The closed form through the plant: the largest stable Ka/J_total (observer-fed, error
/// form, first-order filter, 25 to 400 Hz) up to 1000·J_total, gears apart and engaged. In
/// speed mode the closed form has no limit up to the search's end, as in the skeleton
/// (`afb_skeleton`). With the Table 1 position loop the limit is finite, a slow mode (about
/// 3 Hz) of the position loop around a velocity loop that Ka slows down, and still above
/// (2 − α)/α·Jm/J_total, the inner-loop limit of the one-tick-late structure.
#[test]
fn closed_form_ka_limits_through_the_plant() {
    let base = common::table1();
    println!("Observer-fed AFB, closed form, largest stable Ka/J_total (1000 = the search's end):");
    println!(
        "| filter corner [Hz] | (2 − α)/α·Jm/J_total | speed mode: apart | engaged | position loop: apart | engaged |"
    );
    println!("|---|---|---|---|---|---|");
    for fc in [25.0f32, 50.0, 100.0, 200.0, 400.0] {
        let mut c = base;
        c.accel_feedback.gain_fraction = 1.0;
        c.accel_feedback.filter = FilterConfig::FirstOrder { corner_hz: fc };
        // Bisect on a log scale: the limits span three decades.
        let limit = |gears, position_loop| {
            let l = bisect(0.01f64.ln(), 1000f64.ln(), |lf| {
                model_with(&c, lf.exp(), gears, position_loop).spectral_radius() < 1.0
            });
            if l == 0.0 { 0.0 } else { l.exp() }
        };
        let speed = [Gears::Apart, Gears::Engaged].map(|g| limit(g, false));
        let pos = [Gears::Apart, Gears::Engaged].map(|g| limit(g, true));
        let alpha = 1.0 - (-std::f64::consts::TAU * f64::from(fc) / 4000.0).exp();
        let inner = (2.0 - alpha) / alpha * JM / JT;
        println!(
            "| {fc} | {inner:.3} | {:.2} | {:.2} | {:.2} | {:.2} |",
            speed[0], speed[1], pos[0], pos[1]
        );
        for l in speed {
            assert!(l >= 999.0, "{fc} Hz: speed mode limited at {l}");
        }
        for l in pos {
            assert!(
                l > inner,
                "{fc} Hz: {l} vs the one-tick-late inner limit {inner}"
            );
        }
    }
}

/// Differentiated velocity and acceleration (no model term, no inner loop): the largest
/// stable first-order corner. Checks, for Ka = 0.5·J_total with the gears apart, that the
/// corners `afb_design::high_resolution_encoder_and_the_acceleration_loop_limit` runs as
/// stable (45 Hz at the 4 kHz AFB rate, 23 Hz at 2 kHz) lie below the limit and those it
/// runs as unstable (190 Hz, 93 Hz) above twice the limit.
#[test]
fn differentiated_acceleration_corner_limits() {
    let base = common::table1();
    println!(
        "Differentiated velocity and acceleration, largest stable first-order corner [Hz] (900 = the search's end):"
    );
    println!("| Ka/J_total | AFB at 4 kHz, apart | engaged | AFB at 2 kHz, apart | engaged |");
    println!("|---|---|---|---|---|");
    let diff_limit = |frac: f32, rate: AfbRate, gears: Gears| {
        bisect(1.0, 900.0, |fc| {
            let mut c = base;
            c.accel_feedback.source = Estimator::Differentiation;
            c.velocity_estimator = Estimator::Differentiation;
            c.accel_feedback.rate = rate;
            c.accel_feedback.gain_fraction = frac;
            c.accel_feedback.filter = FilterConfig::FirstOrder {
                corner_hz: fc as f32,
            };
            radius(&c, gears) < 1.0
        })
    };
    for frac in [0.25f32, 0.5, 1.0] {
        println!(
            "| {frac} | {:.1} | {:.1} | {:.1} | {:.1} |",
            diff_limit(frac, AfbRate::Current, Gears::Apart),
            diff_limit(frac, AfbRate::Current, Gears::Engaged),
            diff_limit(frac, AfbRate::Velocity, Gears::Apart),
            diff_limit(frac, AfbRate::Velocity, Gears::Engaged)
        );
    }
    let f4 = diff_limit(0.5, AfbRate::Current, Gears::Apart);
    let f2 = diff_limit(0.5, AfbRate::Velocity, Gears::Apart);
    println!("Ka = 0.5·J_total, gears apart: {f4:.1} Hz at 4 kHz, {f2:.1} Hz at 2 kHz");
    assert!(45.0 < f4 && 2.0 * f4 < 190.0, "4 kHz: {f4}");
    assert!(23.0 < f2 && 2.0 * f2 < 93.0, "2 kHz: {f2}");
}
