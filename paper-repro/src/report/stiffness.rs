//! Fig. 2 and Eq. 1: the dynamic stiffness with and without acceleration feedback.

use super::section::{pct, Section};
use super::{STIFFNESS_HIGH_MIN, STIFFNESS_LOW_BAND, STIFFNESS_MODEL_TOLERANCE};
use machine_workflows::stiffness::StiffnessPoint;
use sim_engine::error::Result;

/// Stiffness ratios (with AFB / without) at each frequency; `None` where the AFB run was
/// unstable.
pub(super) type Ratios = Vec<(f64, Option<f64>)>;

/// What the stiffness measurement shows, against the criteria.
pub(super) struct Findings {
    pub(super) low: Ratios,
    pub(super) high: Ratios,
    pub(super) observer: Ratios,
    differentiation: Ratios,
    pub(super) model_dev: Vec<(f64, f64)>,
    pub(super) eq1_err: f64,
    est_ratios: Vec<String>,
    pub(super) ok_model: bool,
    pub(super) ok_low: bool,
    pub(super) ok_high: bool,
}

pub(super) fn findings(stiff: &[StiffnessPoint], bw: f64, w_obs: f64) -> Findings {
    let ratio_at = |source: &str, w: f64| -> Option<f64> {
        let a = stiff
            .iter()
            .find(|p| p.source == "none" && p.freq_rad_s == w)?;
        let b = stiff
            .iter()
            .find(|p| p.source == source && p.freq_rad_s == w && p.stable)?;
        Some(b.measured / a.measured)
    };
    let freqs: Vec<f64> = stiff
        .iter()
        .filter(|p| p.source == "none")
        .map(|p| p.freq_rad_s)
        .collect();
    let ratios = |source: &str, keep: &dyn Fn(f64) -> bool| -> Ratios {
        freqs
            .iter()
            .filter(|w| keep(**w))
            .map(|w| (*w, ratio_at(source, *w)))
            .collect()
    };
    let low = ratios("observer", &|w| w < bw / 3.0);
    let high = ratios("observer", &|w| w >= 3.0 * bw && w < w_obs);
    let model_dev: Vec<(f64, f64)> = stiff
        .iter()
        .filter(|p| p.source == "observer" && p.stable && p.freq_rad_s < w_obs)
        .map(|p| (p.freq_rad_s, p.measured / p.analytic - 1.0))
        .collect();
    let missing = stiff
        .iter()
        .filter(|p| p.source == "observer" && p.freq_rad_s < w_obs)
        .any(|p| !p.stable);
    let ok_model = !missing
        && !model_dev.is_empty()
        && model_dev
            .iter()
            .all(|(_, d)| d.abs() <= STIFFNESS_MODEL_TOLERANCE);
    let ok_low = !low.is_empty()
        && low.iter().all(|(_, r)| {
            r.is_some_and(|x| (STIFFNESS_LOW_BAND.0..=STIFFNESS_LOW_BAND.1).contains(&x))
        });
    let ok_high = !high.is_empty()
        && high
            .iter()
            .all(|(_, r)| r.is_some_and(|x| x > STIFFNESS_HIGH_MIN));
    Findings {
        observer: ratios("observer", &|_| true),
        differentiation: ratios("differentiation", &|_| true),
        eq1_err: stiff
            .iter()
            .filter(|p| p.source == "none")
            .map(|p| (p.measured / p.analytic - 1.0).abs())
            .fold(0.0, f64::max),
        est_ratios: stiff
            .iter()
            .filter(|p| p.source == "observer" && p.freq_rad_s >= bw)
            .map(|p| format!("{:.2} at {} rad/s", p.accel_est_ratio, p.freq_rad_s))
            .collect(),
        low,
        high,
        model_dev,
        ok_model,
        ok_low,
        ok_high,
    }
}

impl Findings {
    /// (a) and (b): agrees; (b) alone: partly agrees; else does not agree.
    pub(super) fn verdict(&self) -> &'static str {
        match (self.ok_model, self.ok_low && self.ok_high) {
            (true, true) => "**agrees**",
            (false, true) => "**partly agrees**",
            _ => "**does not agree**",
        }
    }
}

pub(super) fn list(v: &[(f64, Option<f64>)]) -> String {
    v.iter()
        .map(|(w, r)| match r {
            Some(x) => format!("{x:.2} at {w} rad/s"),
            None => format!("unstable at {w} rad/s"),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

pub(super) fn holds(ok: bool) -> &'static str {
    if ok {
        "holds"
    } else {
        "fails"
    }
}

/// The stiffness section, from the measured points and the stiffness scenario's config.
pub fn section(stiff: &[StiffnessPoint]) -> Result<Section> {
    let cfg = machine_workflows::stiffness::stiffness_config(
        Some(controller_core::Estimator::Observer),
        &[],
    )?;
    let bw = f64::from(cfg.drive.velocity_bandwidth_rad_s);
    let w_obs = std::f64::consts::TAU * f64::from(cfg.drive.observer.bandwidth_hz);
    let f = findings(stiff, bw, w_obs);
    let verdict = f.verdict();
    let g0 = sim_engine::engine::runner::regulator_gains(&cfg)?;
    let afb = &cfg.drive.accel_feedback;
    let model_dev = f
        .model_dev
        .iter()
        .map(|(w, d)| format!("{:+.1} % at {w} rad/s", 100.0 * d))
        .collect::<Vec<_>>()
        .join(", ");
    Ok(Section::claim(
        "Fig. 2 and Eq. 1: dynamic stiffness; acceleration feedback adds stiffness above the \
         velocity bandwidth",
        &["stiffness/stiffness.png"],
        "Stiffness tau_L/theta = Jp s^2 + Kp s + Ki (Eq. 1) with breaks at 1 and 10 rad/s \
         (Fig. 2); acceleration feedback improves stiffness in the high-frequency region, \
         typically above the velocity loop bandwidth.",
        format!(
            "Fig. 2 gains on the dyno plant with a stiff coupling (anti-resonance {} Hz): \
             velocity bandwidth {bw} rad/s, damping {}, Kp = {:.4}, Ki = {:.4} with and without \
             AFB (the run without AFB borrows the AFB design's gains); default AFB Ka = {:.4} s \
             ({} x J_total), filter {:?}, observer {} Hz ({w_obs:.0} rad/s). Without AFB the \
             measured stiffness follows Eq. 1 within {:.0} % over the whole grid. Stiffness with \
             AFB / without (observer acceleration): {}. With differentiated acceleration: {}. \
             Measured AFB stiffness against J + Ka*F*G below the observer bandwidth: {}. \
             Observer acceleration estimate / true motor acceleration: {}.",
            cfg.plant.mechanics.anti_resonance_hz,
            cfg.drive.velocity_damping,
            g0.kp_vel,
            g0.ki_vel,
            g0.ka,
            afb.gain_fraction,
            afb.filter,
            cfg.drive.observer.bandwidth_hz,
            100.0 * f.eq1_err,
            list(&f.observer),
            list(&f.differentiation),
            model_dev,
            f.est_ratios.join(", ")
        ),
        format!(
            "{verdict} (criteria: (a) the measured AFB stiffness is within {} of Eq. 1 with J + \
             Ka*F*G at every frequency below the observer bandwidth, G the estimator's transfer \
             function: {}; (b) Fig. 2's shape: the ratio with / without is within {}-{} below a \
             third of the velocity bandwidth ({}): {}, and above {STIFFNESS_HIGH_MIN} from 3x \
             the velocity bandwidth up to the observer bandwidth ({}): {}. All: agrees; (b) \
             alone: partly agrees).",
            pct(STIFFNESS_MODEL_TOLERANCE),
            holds(f.ok_model),
            STIFFNESS_LOW_BAND.0,
            STIFFNESS_LOW_BAND.1,
            list(&f.low),
            holds(f.ok_low),
            list(&f.high),
            holds(f.ok_high)
        ),
    )
    .row(
        "Fig. 2/Eq. 1: AFB adds stiffness above the velocity bandwidth",
        "J s^2 + Kp s + Ki without AFB; higher with AFB above the velocity bandwidth",
        format!(
            "without AFB within {:.0} % of Eq. 1; with AFB / without, from 3x the velocity \
             bandwidth to the observer bandwidth: {}",
            100.0 * f.eq1_err,
            list(&f.high)
        ),
        verdict,
    ))
}
