//! The stability verdict's evidence: what the motor torque does in the stability window.
//!
//! # The rule
//!
//! Over the stability window (normally the last 0.5 s), on the motor torque (the measured
//! current, k_t = 1) detrended by its least-squares line:
//!
//! - `amplitude_pu` = half its peak-to-peak; `freq_hz` = the peak of its Hann-windowed,
//!   zero-padded spectrum above [`F_MIN_HZ`]; `narrowband_fraction` = the share of that
//!   energy within ±max([`HALF_BAND_HZ`], 2/T) of the peak (T the window's length: the
//!   Hann main lobe); `saturated_fraction` = the share of the window's rows whose torque
//!   command is at the torque limit; `growth` = the torque's RMS in the last quarter of
//!   the window over that in the first quarter.
//! - The **count-rate tone** `tone_hz`: an encoder turning at n rev/s with N counts/rev
//!   (after interpolation), sampled at f_s, steps its count by n·N/f_s per sample; the
//!   fractional part of that makes the quantization error a sawtooth at (n·N mod f_s),
//!   folded into [0, f_s/2]. Its harmonics 2 and 3 (folded the same way) count as the tone
//!   too. n is the mean motor speed over the window.
//!
//! - **A forced sine is not an oscillation.** When the scenario injects a sine load at
//!   f_x (`scenario.sine_load`), the loop's forced response at f_x and its harmonics 2 and
//!   3 is taken out first: a least-squares sine at each is subtracted from the detrended
//!   torque (so `amplitude_pu` and `growth` measure what is left), and the peak search and
//!   both energies of `narrowband_fraction` skip ±[`EXCITATION_BINS`]/T around each (T the
//!   window's length: that many bins of its spectrum), so the rest of the rule judges only
//!   what the loop does by itself. `excitation_hz` records f_x.
//!
//! The kind, first match wins:
//!
//! 1. `diverging`: a value is not finite, the speed error leaves ±0.5 pu, or a narrowband
//!    (`narrowband_fraction` ≥ [`NARROWBAND`]) torque's envelope grows (`growth` ≥
//!    [`GROWTH_DIVERGING`]) with `amplitude_pu` ≥ [`A_NOISE_PU`].
//! 2. `limit_cycle` (self-excited): `amplitude_pu` ≥ [`A_NOISE_PU`] and any of
//!    - the torque sits at its limit for ≥ [`SAT_LIMIT_CYCLE`] of the window;
//!    - the speed error's oscillation (`oscillation_pu`) reaches the scenario's
//!      `stable_oscillation_pu`;
//!    - the torque is narrowband (`narrowband_fraction` ≥ [`NARROWBAND`]) at a frequency
//!      that is **not** the count-rate tone (within ±max([`TONE_TOL_HZ`], 2/T)) with
//!      `amplitude_pu` ≥ [`A_LIMIT_CYCLE_PU`].
//! 3. `quantization`: `amplitude_pu` ≥ [`A_NOISE_PU`] otherwise: chatter at the count-rate
//!    tone, broadband chatter, or a narrowband ripple too small to be a limit cycle.
//! 4. `none`: `amplitude_pu` < [`A_NOISE_PU`].
//!
//! 5. **Confirmation** (`engine::runner::confirm_limit_cycle`, after every host run and
//!    every PIL run that ends without a link fault; the rerun is always on the host build):
//!    a `limit_cycle` is run again with the encoder interpolated [`CONFIRM_INTERPOLATION`]
//!    times more (its following-error limit in counts scaled with it); if that run has no
//!    limit cycle, does not diverge and does not fault, the oscillation came from the
//!    counts: it is `quantization`. `interpolated_amplitude_pu` records the rerun's
//!    amplitude; `null` on a `limit_cycle` means the verdict is unconfirmed.
//!
//! 6. **A trip ends the question** (`engine::runner::run_recorded`, after the rest): a run
//!    whose drive latched a fault is `tripped`, naming the fault (`oscillation.fault`, the
//!    name `controller_core::Fault::name` gives, as in `summary.json`'s `fault.cause`),
//!    whatever the window showed: after a trip the drive's torque is off, so the window
//!    says nothing of the loop, and a run cut short by its protection is neither a limit
//!    cycle nor diverging.
//!
//! `stable` is false for `diverging`, `limit_cycle` and `tripped`.
//!
//! Measured on table1 (`summary.json`): the velocity-mode drive at 30 rad/s with error-form
//! AFB (gain 0.5, 100 Hz 2nd-order filter, differentiated encoder) oscillates at 178 Hz,
//! ±2 pu, 19 % of the window at the limit (which decides it: the window's count-rate tone,
//! 182 Hz, is within the tolerance of the peak): `limit_cycle`, which the 256× rerun
//! confirms (±1.8 pu).
//! `fig6` chatters at 266.7 Hz, the tone of 1 pu × 4096 counts at 2 kHz: `quantization`.

use super::spectrum::{detrended, peak, Band};
use serde::Serialize;

/// Lowest frequency of the oscillation's spectrum (Hz): below it is the slow part of the
/// response, not an oscillation of the loop.
pub const F_MIN_HZ: f64 = 5.0;
/// Smallest half-width of the band counted as "near the peak" (Hz).
pub const HALF_BAND_HZ: f64 = 3.0;
/// Smallest tolerance of the match with the count-rate tone (Hz).
pub const TONE_TOL_HZ: f64 = 3.0;
/// Share of the energy near the peak from which an oscillation is narrowband.
pub const NARROWBAND: f64 = 0.5;
/// Torque amplitude below which nothing oscillates (pu).
pub const A_NOISE_PU: f64 = 0.02;
/// Narrowband torque amplitude, away from the tone, from which it is a limit cycle (pu).
pub const A_LIMIT_CYCLE_PU: f64 = 0.1;
/// Share of the window at the torque limit from which it is a limit cycle.
pub const SAT_LIMIT_CYCLE: f64 = 0.05;
/// Growth of the torque's RMS across the window (last / first quarter) that diverges.
pub const GROWTH_DIVERGING: f64 = 2.0;
/// Half-width, in spectral bins (1/T), of the band around an injected sine's frequency and
/// its harmonics 2 and 3 that the peak search skips.
pub const EXCITATION_BINS: f64 = 3.0;
/// Extra encoder interpolation of the confirming rerun (step 5).
pub const CONFIRM_INTERPOLATION: u32 = 256;

/// What the loop does at the end of the run. Written to JSON as its [`word`](Self::word).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OscillationKind {
    /// No torque oscillation above [`A_NOISE_PU`].
    None,
    /// Chatter from the encoder's quantization (stable).
    Quantization,
    /// A self-excited oscillation of bounded amplitude (unstable).
    LimitCycle,
    /// Growing or unbounded (unstable).
    Diverging,
    /// The drive latched a fault (step 6): the protection stopped the run.
    Tripped {
        /// The fault's name (`controller_core::Fault::name`: `overcurrent`, `overload`, ...).
        fault: &'static str,
    },
}

impl OscillationKind {
    /// The kind as `summary.json` writes it (`limit_cycle` ...).
    #[must_use]
    pub const fn word(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Quantization => "quantization",
            Self::LimitCycle => "limit_cycle",
            Self::Diverging => "diverging",
            Self::Tripped { .. } => "tripped",
        }
    }

    /// The fault that ended the run, for a `tripped` verdict.
    #[must_use]
    pub const fn fault(self) -> Option<&'static str> {
        match self {
            Self::Tripped { fault } => Some(fault),
            _ => None,
        }
    }

    /// The verdict as a reader sees it: the word, and for a trip its fault
    /// (`tripped (overcurrent)`).
    #[must_use]
    pub fn verdict(self) -> String {
        match self.fault() {
            Some(f) => format!("{} ({f})", self.word()),
            None => self.word().to_string(),
        }
    }
}

impl Serialize for OscillationKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.word())
    }
}

/// `summary.json`'s `oscillation` object: the verdict and its evidence (module docs). A
/// `tripped` verdict adds `fault`, the fault's name, after `kind`.
#[derive(Clone, Debug, PartialEq)]
pub struct Oscillation {
    /// The verdict.
    pub kind: OscillationKind,
    /// Spectral peak of the motor torque in the stability window (Hz).
    pub freq_hz: f64,
    /// Half the peak-to-peak of the detrended motor torque (pu).
    pub amplitude_pu: f64,
    /// Share of the torque's energy above 5 Hz near the peak.
    pub narrowband_fraction: f64,
    /// Share of the stability window with the torque command at its limit.
    pub saturated_fraction: f64,
    /// The encoder's count-rate tone at the window's mean speed (Hz); `null` without the
    /// machine's encoder.
    pub tone_hz: Option<f64>,
    /// RMS of the torque in the last quarter of the window over the first quarter.
    pub growth: f64,
    /// The amplitude of the confirming rerun with the encoder interpolated (step 5);
    /// `null` when there was none.
    pub interpolated_amplitude_pu: Option<f64>,
    /// The injected sine's frequency, taken out of the verdict (Hz); `null` without one.
    pub excitation_hz: Option<f64>,
}

impl Serialize for Oscillation {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let fault = self.kind.fault();
        let mut o = s.serialize_struct("Oscillation", 9 + usize::from(fault.is_some()))?;
        o.serialize_field("kind", &self.kind)?;
        if let Some(f) = fault {
            o.serialize_field("fault", f)?;
        }
        o.serialize_field("freq_hz", &self.freq_hz)?;
        o.serialize_field("amplitude_pu", &self.amplitude_pu)?;
        o.serialize_field("narrowband_fraction", &self.narrowband_fraction)?;
        o.serialize_field("saturated_fraction", &self.saturated_fraction)?;
        o.serialize_field("tone_hz", &self.tone_hz)?;
        o.serialize_field("growth", &self.growth)?;
        o.serialize_field("interpolated_amplitude_pu", &self.interpolated_amplitude_pu)?;
        o.serialize_field("excitation_hz", &self.excitation_hz)?;
        o.end()
    }
}

/// What the classification needs besides the torque.
#[derive(Clone, Copy, Debug)]
pub(super) struct Evidence {
    /// Trace sample rate (Hz).
    pub fs_hz: f64,
    /// Counts per second at 1 pu motor speed (after interpolation); 0 = unknown.
    pub counts_per_s_per_pu: f64,
    /// Mean motor speed over the window (pu).
    pub mean_speed_pu: f64,
    /// Share of the window at the torque limit.
    pub saturated_fraction: f64,
    /// Finite, speed error within ±0.5 pu.
    pub finite_and_bounded: bool,
    /// The speed oscillation reached the scenario's threshold.
    pub speed_oscillates: bool,
    /// The frequency of the scenario's injected sine load (Hz), if any.
    pub excitation_hz: Option<f64>,
}

/// `f` folded into [0, fs/2] as sampling at `fs` aliases it.
fn folded(f: f64, fs: f64) -> f64 {
    let r = f.rem_euclid(fs);
    r.min(fs - r)
}

/// The count-rate tone (Hz) and whether `freq_hz` is it or one of its first harmonics.
fn tone(e: &Evidence, freq_hz: f64, tol_hz: f64) -> (Option<f64>, bool) {
    if e.counts_per_s_per_pu <= 0.0 {
        return (None, false);
    }
    let rate = (e.mean_speed_pu * e.counts_per_s_per_pu).abs();
    let f1 = folded(rate, e.fs_hz);
    let hit = (1..=3).any(|h| (folded(f64::from(h) * rate, e.fs_hz) - freq_hz).abs() <= tol_hz);
    (Some(f1), hit)
}

fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// The frequencies the forced response of an injected sine at `f_x` lies at: the sine's
/// and its harmonics 2 and 3, those below Nyquist.
fn forced(f_x: Option<f64>, fs: f64) -> Vec<f64> {
    f_x.filter(|f| f.is_finite() && *f > 0.0)
        .map(|f| {
            (1..=3)
                .map(|h| f64::from(h) * f)
                .filter(|f| *f < fs / 2.0)
                .collect()
        })
        .unwrap_or_default()
}

/// `x` less its least-squares fit by a straight line and a sine at each frequency of
/// `freqs` (Hz, sampled at `fs`), fitted together (a sine is not orthogonal to a line over
/// a window of whole and part periods); without `freqs`, [`detrended`].
fn without_sines(x: &[f64], fs: f64, freqs: &[f64]) -> Vec<f64> {
    if freqs.is_empty() || x.len() < 2 + 2 * freqs.len() {
        return detrended(x);
    }
    let mid = (x.len() as f64 - 1.0) / 2.0;
    let basis = |k: usize| -> Vec<f64> {
        let t = k as f64;
        let mut b = vec![1.0, (t - mid) / mid.max(1.0)];
        for f in freqs {
            let (s, c) = (2.0 * std::f64::consts::PI * f / fs * t).sin_cos();
            b.extend([c, s]);
        }
        b
    };
    let m = 2 + 2 * freqs.len();
    // Normal equations [AᵀA | Aᵀx], solved by Gauss-Jordan elimination with partial pivoting.
    let mut a = vec![vec![0.0; m + 1]; m];
    for (k, v) in x.iter().enumerate() {
        let b = basis(k);
        for (row, bi) in a.iter_mut().zip(&b) {
            for (cell, bj) in row.iter_mut().zip(b.iter().chain([v])) {
                *cell += bi * bj;
            }
        }
    }
    for col in 0..m {
        let pivot = (col..m)
            .max_by(|p, q| {
                let at = |r: usize| {
                    a.get(r)
                        .and_then(|row| row.get(col))
                        .map_or(0.0, |v| v.abs())
                };
                at(*p).total_cmp(&at(*q))
            })
            .unwrap_or(col);
        a.swap(col, pivot);
        let Some(prow) = a.get(col).cloned() else {
            return detrended(x);
        };
        let p = prow.get(col).copied().unwrap_or(0.0);
        if p.abs() < 1e-12 {
            return detrended(x);
        }
        for (r, row) in a.iter_mut().enumerate() {
            let f = row.get(col).copied().unwrap_or(0.0) / p;
            if r != col {
                row.iter_mut().zip(&prow).for_each(|(c, pv)| *c -= f * pv);
            }
        }
    }
    let coef: Vec<f64> = a
        .iter()
        .enumerate()
        .map(|(r, row)| row.get(m).copied().unwrap_or(0.0) / row.get(r).copied().unwrap_or(1.0))
        .collect();
    x.iter()
        .enumerate()
        .map(|(k, v)| v - basis(k).iter().zip(&coef).map(|(b, c)| b * c).sum::<f64>())
        .collect()
}

/// The verdict on the motor torque `torque` of the stability window (module docs).
pub(super) fn classify(torque: &[f64], e: &Evidence) -> Oscillation {
    let span_s = torque.len() as f64 / e.fs_hz.max(f64::MIN_POSITIVE);
    let bin_hz = 1.0 / span_s.max(f64::MIN_POSITIVE);
    let lobe_hz = 2.0 * bin_hz;
    let forced_hz = forced(e.excitation_hz, e.fs_hz);
    let skip: Vec<(f64, f64)> = forced_hz
        .iter()
        .map(|f| (f - EXCITATION_BINS * bin_hz, f + EXCITATION_BINS * bin_hz))
        .collect();
    let d = without_sines(torque, e.fs_hz, &forced_hz);
    let (lo, hi) = d
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let amplitude_pu = if d.is_empty() { 0.0 } else { (hi - lo) / 2.0 };
    let band = Band {
        lo_hz: F_MIN_HZ,
        hi_hz: f64::INFINITY,
        skip: &skip,
    };
    let p = peak(&d, e.fs_hz, &band, HALF_BAND_HZ.max(lobe_hz));
    let (freq_hz, narrowband_fraction) =
        p.map_or((0.0, 0.0), |p| (p.freq_hz, p.narrowband_fraction));
    let (tone_hz, at_tone) = tone(e, freq_hz, TONE_TOL_HZ.max(lobe_hz));
    let q = d.len() / 4;
    let growth = rms(d.get(d.len() - q..).unwrap_or_default())
        / rms(d.get(..q).unwrap_or_default()).max(1e-12);
    let audible = amplitude_pu >= A_NOISE_PU;
    let kind = if !e.finite_and_bounded
        || !amplitude_pu.is_finite()
        || (audible && growth >= GROWTH_DIVERGING && narrowband_fraction >= NARROWBAND)
    {
        OscillationKind::Diverging
    } else if audible
        && (e.saturated_fraction >= SAT_LIMIT_CYCLE
            || e.speed_oscillates
            || (narrowband_fraction >= NARROWBAND && !at_tone && amplitude_pu >= A_LIMIT_CYCLE_PU))
    {
        OscillationKind::LimitCycle
    } else if audible {
        OscillationKind::Quantization
    } else {
        OscillationKind::None
    };
    Oscillation {
        kind,
        freq_hz,
        amplitude_pu,
        narrowband_fraction,
        saturated_fraction: e.saturated_fraction,
        tone_hz,
        growth,
        interpolated_amplitude_pu: None,
        excitation_hz: e.excitation_hz,
    }
}
