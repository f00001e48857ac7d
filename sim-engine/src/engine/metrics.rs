//! Metrics computed from a trace. Each definition here is repeated in `sim-engine/README.md`; the
//! windows come from the scenario's `[scenario.metrics]` table.

pub mod oscillation;
mod pass;
mod response;
mod spectrum;

use crate::engine::trace::{Trace, TraceRow};
pub use oscillation::{Oscillation, OscillationKind};
use pass::{hp_inputs, Pass, HP_SIGNALS};
use serde::Serialize;

/// Time windows and thresholds of the metrics (all times in s of simulated time).
#[derive(Clone, Debug, PartialEq)]
pub struct MetricWindows {
    /// Time of the load step the droop and settling refer to, if any.
    pub step_time_s: Option<f64>,
    /// Time of the next load change after the step: the step response ends there.
    pub step_end_s: Option<f64>,
    /// Time the velocity ramp ends (overshoot is measured from here), if any.
    pub ramp_end_s: Option<f64>,
    /// Window over which torque ripple is measured.
    pub ripple_window_s: (f64, f64),
    /// Window over which overshoot is measured.
    pub overshoot_window_s: Option<(f64, f64)>,
    /// Window over which stability is judged (normally the last 0.5 s).
    pub stable_window_s: (f64, f64),
    /// Length of the centred moving average removed before taking the ripple (s).
    pub ripple_average_s: f64,
    /// Smallest settling band on the motor speed deviation (pu); the band is otherwise
    /// a share of the peak deviation (`response` module).
    pub settle_band_pu: f64,
    /// Stability threshold on the standard deviation of the speed error (pu).
    pub stable_oscillation_pu: f64,
    /// Largest fraction of the stability window the torque may spend saturated.
    pub stable_saturation_fraction: f64,
    /// Torque limit of the drive (pu), to count saturation.
    pub torque_limit_pu: f64,
    /// The machine the bands and the count-rate tone come from; `None` = unknown (no
    /// tone, the noise band from 5 Hz, the shaft band 5 Hz to Nyquist).
    pub machine: Option<MachineBands>,
    /// Frequency of the scenario's injected sine load (Hz), which the oscillation verdict
    /// leaves out (the `oscillation` module's rule); `None` without one.
    pub excitation_hz: Option<f64>,
}

/// What the spectral metrics need of the machine and the drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachineBands {
    /// Encoder counts per second at 1 pu motor speed, after interpolation.
    pub counts_per_s_per_pu: f64,
    /// Velocity-loop bandwidth (Hz): `torque_noise_rms_pu` counts the torque above it.
    pub velocity_bandwidth_hz: f64,
    /// Band of `shaft_oscillation_rms_pu` (Hz): 0.7 × the anti-resonance to 1.4 × the
    /// locked-rotor resonance f_ar·√(1 + J_L/J_M).
    pub resonance_band_hz: (f64, f64),
}

/// The metrics written to `summary.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// Stable: [`Metrics::stable_by_speed`] and the oscillation verdict neither
    /// `limit_cycle`, `diverging` nor `tripped`.
    pub stable: bool,
    /// The criterion of [`MetricWindows`] alone, without the oscillation verdict (the
    /// `stable` of earlier versions): no fault, all signals finite, speed error bounded by
    /// 0.5 pu, its oscillation (`oscillation_pu`) below the threshold and the torque not
    /// stuck at its limit in the stability window.
    pub stable_by_speed: bool,
    /// The controller reported a fault at some point of the run.
    pub faulted: bool,
    /// RMS of the motor speed error minus its centred moving average (the ripple
    /// high-pass), in the stability window (pu): the limit-cycle amplitude.
    pub oscillation_pu: f64,
    /// RMS of the motor torque (measured current) minus its centred moving average in the
    /// stability window (pu): torque chatter / limit cycle that the speed may not show.
    pub limit_cycle_torque_pu: f64,
    /// RMS of the motor torque (the measured current, k_t = 1) minus its centred moving
    /// average, in the ripple window (pu).
    pub torque_ripple_rms_pu: f64,
    /// The same for the shaft (transducer) torque (pu).
    pub shaft_torque_ripple_rms_pu: f64,
    /// Dominant ripple frequency of the shaft torque in the ripple window: the peak of its
    /// spectrum in the machine's resonance band ([`MachineBands::resonance_band_hz`]; above
    /// 5 Hz for an unknown machine), so the shaft's ring and not the encoder's count-rate
    /// tone (Hz).
    pub shaft_ripple_freq_hz: f64,
    /// Largest drop of motor speed below command after the load step, less the error
    /// just before it (pu). `None` without a step.
    pub load_step_droop_pu: Option<f64>,
    /// Largest excess of load speed over the command in the overshoot window (pu).
    pub overshoot_pu: Option<f64>,
    /// Time from the step (or ramp end) until the speed deviation stays inside the band,
    /// 5 % of its peak (the `response` module's definition) (s); `None` if it never
    /// settles.
    pub settling_s: Option<f64>,
    /// Largest |motor speed deviation| after the step, less the error just before it
    /// (pu); `None` without a step.
    pub peak_droop_pu: Option<f64>,
    /// Time from the step to that peak (s).
    pub peak_droop_time_s: Option<f64>,
    /// Time from the step until the deviation stays under 10 % of its peak (s).
    pub recovery_s: Option<f64>,
    /// Largest |shaft torque| after the step, until the next load change (pu).
    pub peak_shaft_torque_pu: Option<f64>,
    /// RMS of the motor torque above the velocity bandwidth in the stability window (pu).
    pub torque_noise_rms_pu: f64,
    /// RMS of the shaft torque in the machine's resonance band
    /// ([`MachineBands::resonance_band_hz`]) in the ripple window (pu): the ringing,
    /// without the slow recovery.
    pub shaft_oscillation_rms_pu: f64,
    /// Frequency of the shaft's ring after the step (Hz), from its successive maxima.
    pub shaft_ring_freq_hz: Option<f64>,
    /// Damping ratio of that ring, from their log decrement.
    pub shaft_ring_damping: Option<f64>,
    /// The stability verdict and its evidence (the `oscillation` module's rule).
    pub oscillation: Oscillation,
    /// Time the torque command spends at its limit (s).
    pub torque_saturated_s: f64,
    /// Mean motor torque (measured current) in the ripple window (pu).
    pub mean_torque_pu: f64,
    /// Mean motor speed error (command − motor) in the ripple window (pu).
    pub mean_speed_error_pu: f64,
    /// Largest |command − motor position| (counts).
    pub max_following_error_counts: f64,
    /// Largest |motor − load position| (counts).
    pub max_twist_counts: f64,
    /// Why the value metrics above are not finite (`null` in JSON), when they are not: the
    /// trace holds non-finite values from the time named. `None` for a valid run.
    pub invalid_reason: Option<String>,
}

fn in_window(r: &TraceRow, w: (f64, f64)) -> bool {
    r.t_s >= w.0 && r.t_s <= w.1
}

/// `x − centred moving average of x` over `half` samples each side (clipped at the ends):
/// keeps the ripple above about 1/(2·average length) and removes slow trends. [`compute`]
/// forms the same values as it goes; this is the definition, whole-signal form.
pub fn high_pass(x: &[f64], half: usize) -> Vec<f64> {
    let mut prefix = Vec::with_capacity(x.len() + 1);
    prefix.push(0.0);
    let mut acc = 0.0;
    for v in x {
        acc += v;
        prefix.push(acc);
    }
    (0..x.len())
        .map(|i| {
            let at = |k: usize| prefix.get(k).copied().unwrap_or(0.0);
            centred(at, i, half, x.len(), x.get(i).copied().unwrap_or(0.0))
        })
        .collect()
}

/// The ripple of one signal `f` inside the window `win` by the metrics' definition
/// ([`high_pass`] with the average `average_s`, then the RMS over the window), and the
/// frequency of its spectral peak above [`oscillation::F_MIN_HZ`] (`None` when the window
/// holds too few rows for a spectrum). For the report's look at where a ripple figure comes
/// from; [`compute`] forms the metrics themselves.
pub fn ripple_in(
    rows: &[TraceRow],
    win: (f64, f64),
    average_s: f64,
    f: impl Fn(&TraceRow) -> f64,
) -> (f64, Option<f64>) {
    let dt = match (rows.first(), rows.get(1)) {
        (Some(a), Some(b)) => b.t_s - a.t_s,
        _ => return (0.0, None),
    };
    if dt <= 0.0 {
        return (0.0, None);
    }
    let half = ((average_s / dt) / 2.0).round().max(1.0) as usize;
    let x: Vec<f64> = rows.iter().map(&f).collect();
    let inside: Vec<f64> = high_pass(&x, half)
        .into_iter()
        .zip(rows)
        .filter(|(_, r)| in_window(r, win))
        .map(|(v, _)| v)
        .collect();
    let n = inside.len().max(1) as f64;
    let rms = (inside.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
    let band = spectrum::Band::above(oscillation::F_MIN_HZ);
    let freq =
        spectrum::peak(&inside, 1.0 / dt, &band, oscillation::HALF_BAND_HZ).map(|p| p.freq_hz);
    (rms, freq)
}

/// v − (mean of the samples i−half ..= i+half, clipped to 0..len), from prefix sums
/// (`at(k)` = the sum of the first k samples).
fn centred(at: impl Fn(usize) -> f64, i: usize, half: usize, len: usize, v: f64) -> f64 {
    let (lo, hi, n) = window(i, half, len);
    v - (at(hi) - at(lo)) / n
}

/// The moving average's window at sample i: lo..hi, and its length as a divisor (≥ 1).
fn window(i: usize, half: usize, len: usize) -> (usize, usize, f64) {
    let lo = i.saturating_sub(half);
    let hi = (i + half + 1).min(len);
    (lo, hi, (hi - lo).max(1) as f64)
}

/// Computes every metric of a trace in one pass. The high pass of row j needs the samples up
/// to j + half, so the ripple sums run `half` rows behind the rest, on one vector of prefix
/// sums; every sum is taken in trace order, so the figures are those of the whole-signal
/// definitions ([`high_pass`], then the RMS over the window) bit for bit.
pub fn compute(trace: &Trace, w: &MetricWindows) -> Metrics {
    let rows = &trace.rows;
    let len = rows.len();
    let dt = match (rows.first(), rows.get(1)) {
        (Some(a), Some(b)) => b.t_s - a.t_s,
        _ => 0.0,
    };
    let mut pass = Pass::new(w);
    // Without a positive sample period there is no moving average: every ripple is 0.
    let Some(half) =
        (dt > 0.0).then(|| ((w.ripple_average_s / dt) / 2.0).round().max(1.0) as usize)
    else {
        rows.iter().for_each(|r| pass.row(r));
        pass.find_first_bad(rows);
        return finish(&pass, rows);
    };
    let mut prefix: Vec<[f64; HP_SIGNALS]> = Vec::with_capacity(len + 1);
    let mut acc = [0.0; HP_SIGNALS];
    prefix.push(acc);
    for (i, r) in rows.iter().enumerate() {
        pass.row(r);
        for (a, v) in acc.iter_mut().zip(hp_inputs(r)) {
            *a += v;
        }
        prefix.push(acc);
        // Row j = i − half has its window now: rows (j − half)⁺ ..= i, the last just summed.
        let Some(j) = i.checked_sub(half) else {
            continue;
        };
        if let Some(rj) = rows.get(j) {
            let lo = j.saturating_sub(half);
            let below = prefix.get(lo).copied().unwrap_or_default();
            pass.high_passed(rj, centred_row(rj, below, acc, (i + 1 - lo) as f64));
        }
    }
    // The last `half` rows: their windows end at the end of the trace.
    for (j, rj) in rows.iter().enumerate().skip(len.saturating_sub(half)) {
        let (lo, _, n) = window(j, half, len);
        let below = prefix.get(lo).copied().unwrap_or_default();
        pass.high_passed(rj, centred_row(rj, below, acc, n));
    }
    pass.find_first_bad(rows);
    finish(&pass, rows)
}

/// [`centred`] for the high-passed signals of row `r`, from the prefix sums below and at
/// the top of its window, `n` samples long.
#[inline]
fn centred_row(
    r: &TraceRow,
    below: [f64; HP_SIGNALS],
    upto: [f64; HP_SIGNALS],
    n: f64,
) -> [f64; HP_SIGNALS] {
    let x = hp_inputs(r);
    core::array::from_fn(|s| {
        let at = |p: &[f64; HP_SIGNALS]| p.get(s).copied().unwrap_or(0.0);
        at(&x) - (at(&upto) - at(&below)) / n
    })
}

/// The metrics of a trace that holds non-finite values from `bad_t_s`. Max/min folds skip
/// NaN, so these figures would read as plain numbers (0.0000): none of them means anything
/// for this run.
fn invalid(faulted: bool, bad_t_s: f64, fig: Metrics) -> Metrics {
    let nan = f64::NAN;
    let some_nan = |o: Option<f64>| o.map(|_| nan);
    Metrics {
        stable: false,
        stable_by_speed: false,
        faulted,
        oscillation_pu: nan,
        limit_cycle_torque_pu: nan,
        torque_ripple_rms_pu: nan,
        shaft_torque_ripple_rms_pu: nan,
        shaft_ripple_freq_hz: nan,
        load_step_droop_pu: some_nan(fig.load_step_droop_pu),
        overshoot_pu: some_nan(fig.overshoot_pu),
        settling_s: None,
        peak_droop_pu: some_nan(fig.peak_droop_pu),
        peak_droop_time_s: some_nan(fig.peak_droop_time_s),
        recovery_s: None,
        peak_shaft_torque_pu: some_nan(fig.peak_shaft_torque_pu),
        torque_noise_rms_pu: nan,
        shaft_oscillation_rms_pu: nan,
        shaft_ring_freq_hz: None,
        shaft_ring_damping: None,
        oscillation: Oscillation {
            kind: OscillationKind::Diverging,
            freq_hz: nan,
            amplitude_pu: nan,
            narrowband_fraction: nan,
            saturated_fraction: nan,
            tone_hz: None,
            growth: nan,
            interpolated_amplitude_pu: None,
            excitation_hz: fig.oscillation.excitation_hz,
        },
        torque_saturated_s: nan,
        mean_torque_pu: nan,
        mean_speed_error_pu: nan,
        max_following_error_counts: nan,
        max_twist_counts: nan,
        invalid_reason: Some(format!(
            "the trace holds non-finite values from t = {bad_t_s} s; no metric of this run is a number"
        )),
    }
}

impl Metrics {
    /// The verdict of a run whose drive latched the fault named `fault` (the `oscillation`
    /// module's step 6): `tripped`, naming it, and not stable.
    pub fn tripped(&mut self, fault: &'static str) {
        self.oscillation.kind = OscillationKind::Tripped { fault };
        self.stable = false;
    }

    /// A `limit_cycle` verdict checked against the same run with the encoder interpolated
    /// (`again`, the `oscillation` module's step 5): if that run has no limit cycle (and
    /// no fault), the oscillation came from the counts and is `quantization`; `stable` is
    /// then the scenario's own tests alone ([`Metrics::stable_by_speed`]).
    pub fn confirm(&mut self, again: &Metrics) {
        let o = &mut self.oscillation;
        o.interpolated_amplitude_pu = Some(again.oscillation.amplitude_pu);
        if o.kind != OscillationKind::LimitCycle
            || again.faulted
            || matches!(
                again.oscillation.kind,
                OscillationKind::LimitCycle | OscillationKind::Diverging
            )
        {
            return;
        }
        o.kind = OscillationKind::Quantization;
        self.stable = self.stable_by_speed && self.invalid_reason.is_none();
    }
}

/// `f` of the rows inside window `win`.
fn series(rows: &[TraceRow], win: (f64, f64), f: impl Fn(&TraceRow) -> f64) -> Vec<f64> {
    rows.iter().filter(|r| in_window(r, win)).map(f).collect()
}

/// The spectral figures: `(shaft_ripple_freq_hz, torque_noise_rms_pu,
/// shaft_oscillation_rms_pu)`.
fn spectral(rows: &[TraceRow], w: &MetricWindows, fs: f64) -> (f64, f64, f64) {
    let nyquist = fs / 2.0;
    let shaft = series(rows, w.ripple_window_s, |r| r.shaft_torque_pu);
    let (bw_hz, band) = w.machine.map_or(
        (oscillation::F_MIN_HZ, (oscillation::F_MIN_HZ, nyquist)),
        |m| (m.velocity_bandwidth_hz, m.resonance_band_hz),
    );
    let search = spectrum::Band {
        lo_hz: band.0.max(oscillation::F_MIN_HZ),
        hi_hz: band.1,
        skip: &[],
    };
    let freq =
        spectrum::peak(&shaft, fs, &search, oscillation::HALF_BAND_HZ).map_or(0.0, |p| p.freq_hz);
    let torque = series(rows, w.stable_window_s, |r| r.current_pu);
    (
        freq,
        spectrum::band_rms(&torque, fs, bw_hz, nyquist),
        spectrum::band_rms(&shaft, fs, band.0, band.1),
    )
}

/// The ring of the high-passed shaft torque from the step to the next load change.
fn shaft_ring(rows: &[TraceRow], w: &MetricWindows, dt: f64) -> Option<(f64, f64)> {
    let t0 = w.step_time_s?;
    let (post, _) = response::after(rows, t0, w.step_end_s);
    let shaft: Vec<f64> = post.iter().map(|r| r.shaft_torque_pu).collect();
    let hp = match w.machine {
        Some(m) => spectrum::band_passed(&shaft, 1.0 / dt, m.resonance_band_hz),
        None => high_pass(
            &shaft,
            ((w.ripple_average_s / dt) / 2.0).round().max(1.0) as usize,
        ),
    };
    response::ring(&hp, dt)
}

/// The oscillation verdict on the stability window's motor torque.
fn verdict(p: &Pass, rows: &[TraceRow], fs: f64, oscillation_pu: f64, sat: f64) -> Oscillation {
    let w = p.w;
    let speed = series(rows, w.stable_window_s, |r| r.motor_vel_pu);
    let evidence = oscillation::Evidence {
        fs_hz: fs,
        counts_per_s_per_pu: w.machine.map_or(0.0, |m| m.counts_per_s_per_pu),
        mean_speed_pu: speed.iter().sum::<f64>() / speed.len().max(1) as f64,
        saturated_fraction: sat,
        finite_and_bounded: p.first_bad_t_s.is_none() && p.bounded,
        speed_oscillates: oscillation_pu.is_nan() || oscillation_pu >= w.stable_oscillation_pu,
        excitation_hz: w.excitation_hz,
    };
    let torque = series(rows, w.stable_window_s, |r| r.current_pu);
    oscillation::classify(&torque, &evidence)
}

/// The metrics from the pass's sums.
fn finish(p: &Pass, rows: &[TraceRow]) -> Metrics {
    let w = p.w;
    let dt = match (rows.first(), rows.get(1)) {
        (Some(a), Some(b)) => b.t_s - a.t_s,
        _ => 0.0,
    };
    let fs = if dt > 0.0 { 1.0 / dt } else { 0.0 };
    // Oscillation: the speed error with its slow part (centred moving average over
    // `ripple_average_s`) removed, so a slow recovery from a step is not counted as a
    // limit cycle; growth beyond bounds is caught by `bounded`.
    let [osc, cycle] = p.stable_hp;
    let oscillation_pu = osc.rms();
    let sat_fraction = if p.stable_rows == 0 {
        1.0
    } else {
        p.saturated_in_window as f64 / p.stable_rows as f64
    };
    let oscillation = verdict(p, rows, fs, oscillation_pu, sat_fraction);
    let stable_by_speed = p.first_bad_t_s.is_none()
        && !p.faulted
        && p.stable_rows > 0
        && p.bounded
        && oscillation_pu.is_finite()
        && oscillation_pu < w.stable_oscillation_pu
        && sat_fraction <= w.stable_saturation_fraction;
    let stable = stable_by_speed
        && !matches!(
            oscillation.kind,
            OscillationKind::LimitCycle | OscillationKind::Diverging
        );
    let [torque_hp, shaft] = p.ripple_hp;
    let load_step_droop_pu = w
        .step_time_s
        .map(|_| (p.worst_after_step - p.before_step_err.unwrap_or(0.0)).max(0.0));
    let step = w
        .step_time_s
        .or(w.ramp_end_s)
        .map(|t0| response::step_response(rows, t0, w));
    let on_step = |f: fn(&response::StepResponse) -> f64| w.step_time_s.and(step.as_ref()).map(f);
    let (shaft_ripple_freq_hz, torque_noise_rms_pu, shaft_oscillation_rms_pu) =
        spectral(rows, w, fs);
    let ring = shaft_ring(rows, w, dt);
    let m = Metrics {
        stable,
        stable_by_speed,
        faulted: p.faulted,
        oscillation_pu,
        limit_cycle_torque_pu: cycle.rms(),
        torque_ripple_rms_pu: torque_hp.rms(),
        shaft_torque_ripple_rms_pu: shaft.rms(),
        shaft_ripple_freq_hz,
        load_step_droop_pu,
        overshoot_pu: w.overshoot_window_s.map(|_| p.overshoot),
        settling_s: step.and_then(|s| s.settling_s),
        peak_droop_pu: on_step(|s| s.peak_droop_pu),
        peak_droop_time_s: on_step(|s| s.peak_droop_time_s),
        recovery_s: w.step_time_s.and(step).and_then(|s| s.recovery_s),
        peak_shaft_torque_pu: on_step(|s| s.peak_shaft_torque_pu),
        torque_noise_rms_pu,
        shaft_oscillation_rms_pu,
        shaft_ring_freq_hz: ring.map(|r| r.0),
        shaft_ring_damping: ring.map(|r| r.1),
        oscillation,
        torque_saturated_s: p.saturated_rows as f64 * dt,
        mean_torque_pu: p.ripple_torque.get(),
        mean_speed_error_pu: p.ripple_speed_err.get(),
        max_following_error_counts: p.max_following,
        max_twist_counts: p.max_twist,
        invalid_reason: None,
    };
    match p.first_bad_t_s {
        Some(bad_t_s) => invalid(p.faulted, bad_t_s, m),
        None => m,
    }
}

#[cfg(test)]
mod closed_form;
#[cfg(test)]
mod tests;
