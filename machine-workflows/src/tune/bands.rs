//! The bands of natural frequency where a design's poles are judged against the machine's
//! own damping rather than the absolute floor: a notch's band (what the notch leaves to the
//! machine), and without a notch the machine's engaged resonance when the machine damps it
//! less than the floor.

use crate::linear::LoopModel;
use sim_engine::config::RunConfig;

/// Share of the machine's own damping of its resonance that the poles in a notch's band
/// must keep: the loop may take at most half of it away.
pub const NOTCH_BAND_DAMPING_SHARE: f64 = 0.5;

/// The band of natural frequencies \[Hz\] where a notch (`centre_hz`, `width_hz`) leaves
/// the modes to the machine: the centre ± one width (twice its −3 dB band, so that a mode
/// a few per cent off the centre, where an identified resonance may be, still counts).
#[must_use]
pub fn notch_band(n: &controller_core::NotchConfig) -> (f64, f64) {
    let (c, w) = (f64::from(n.centre_hz), f64::from(n.width_hz));
    (c - w, c + w)
}

/// The damping ratio of the machine's engaged resonance mode on its own (motor free, no
/// loop): ζ·√(1 + Jl/Jm) for the shaft's ζ (defined at the anti-resonance).
#[must_use]
pub fn machine_resonance_damping(cfg: &RunConfig) -> f64 {
    let m = &cfg.plant.mechanics;
    m.shaft_damping_ratio * (1.0 + m.load_inertia_s / m.motor_inertia_s).sqrt()
}

/// Half-width of the band around the machine's engaged resonance, as a share of its
/// frequency, whose poles are judged against the machine's own damping ([`resonance_band`]).
pub const RESONANCE_BAND_SHARE: f64 = 0.25;

/// The machine's engaged resonance \[Hz\]: the anti-resonance × √(1 + Jl/Jm).
#[must_use]
pub fn machine_resonance_hz(cfg: &RunConfig) -> f64 {
    let m = &cfg.plant.mechanics;
    m.anti_resonance_hz * (1.0 + m.load_inertia_s / m.motor_inertia_s).sqrt()
}

/// Without a notch, the band of natural frequencies \[Hz\] around the machine's engaged
/// resonance (± [`RESONANCE_BAND_SHARE`]) whose poles need only keep the machine's own
/// damping of it ([`machine_resonance_damping`]) instead of reaching `min_damping`: a
/// lightly damped resonance is the machine's, and the loop must not take damping from it,
/// but cannot be asked to give it more than a margin's worth. `None` with a notch (its band
/// is judged instead), without a resonance, or when the machine's own damping already
/// reaches `min_damping`.
#[must_use]
pub fn resonance_band(cfg: &RunConfig, min_damping: f64) -> Option<(f64, f64)> {
    let f = machine_resonance_hz(cfg);
    (cfg.drive.notch.is_none()
        && f.is_finite()
        && f > 0.0
        && machine_resonance_damping(cfg) < min_damping)
        .then_some((
            f * (1.0 - RESONANCE_BAND_SHARE),
            f * (1.0 + RESONANCE_BAND_SHARE),
        ))
}

/// The smallest damping of `model`: of all poles without a notch; with one, (outside its
/// band, inside it).
pub(super) fn damping_of(cfg: &RunConfig, model: &LoopModel) -> (f64, Option<f64>) {
    match &cfg.drive.notch {
        None => (model.smallest_damping(), None),
        Some(n) => {
            let (outside, inside) = model.smallest_damping_split(notch_band(n));
            (outside, Some(inside))
        }
    }
}
