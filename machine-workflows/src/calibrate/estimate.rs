//! The motor's constants from a calibration [`Record`], by least squares, each with its
//! standard error.
//!
//! - **R**: the two current levels' mean α voltage against their mean α current,
//!   `R = Δv̄/Δī`; a constant voltage error (the inverter's dead time at one current sign)
//!   cancels. Its standard error is the spread of the same ratio over 10 blocks of each
//!   level's record, over √10.
//! - **L_d, L_q**: the α and β currents' steps over each tick of the pseudo-random square
//!   wave, each regressed on both axes' voltages of that tick and of the one before, both
//!   currents and a constant: `Δi_x = Σ_y (a₀ˣʸ·v_y(k) + a₁ˣʸ·v_y(k−1)) + …`. The volt-seconds
//!   of one tick reach the currents through `G = [a₀ˣʸ + a₁ˣʸ] = Ts·L⁻¹` (the computational
//!   delay splits a tick between the two voltages); with the rotor at an angle θ,
//!   `L = R(θ)·diag(L_d, L_q)·R(θ)ᵀ`, so the eigenvalues g of G's symmetric part belong to
//!   L_d and L_q (L_d the smaller inductance of a PMSM, L_d ≤ L_q). Over a tick the current
//!   also decays through R: the exact step of `L·di/dt = v − R·i` gives the voltage's weight
//!   `g = (1 − e^(−R·Ts/L))/R`, not Ts/L (4 % apart at R·Ts/L = 0.08), so
//!   `L = R·Ts/(−ln(1 − g·R))` with the R of step 1. Errors: from the regression's
//!   covariance, bounded by the sum of the two weights' errors.
//! - **Direction and pole pairs**: on each sweep, over the whole turns at full speed after
//!   its first turn (the same span of angle both ways), the encoder count is regressed on the
//!   commanded angle, `count = c₀ + s·φ` (φ in turns). s is the counts per electrical
//!   turn, signed: its sign is the direction; `encoder_cpr/|s|` must be within 0.1 of a
//!   whole number, the pole pairs.
//! - **Offset**: the electrical angle at count 0, `−c₀/s` turns on each sweep. The rotor
//!   lags the turning vector one way going forwards and the other way going back, so the
//!   two sweeps' offsets are averaged (on the circle); half their difference is the lag.
//!   Its standard error combines the two intercepts' errors.

use super::record::{Record, Row};
use controller_core::foc::calibration::Stage;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use sim_engine::error::{HarnessError, Result};

/// An estimate and its standard error.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Estimate {
    /// The estimate.
    pub value: f64,
    /// Its standard error.
    pub std_error: f64,
}

/// What the calibration measured, under the machine-file keys that take it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MotorEstimates {
    /// Phase resistance \[pu\].
    pub winding_resistance_pu: Estimate,
    /// d-axis inductance \[pu·s\].
    pub d_inductance_pu_s: Estimate,
    /// q-axis inductance \[pu·s\].
    pub q_inductance_pu_s: Estimate,
    /// The electrical angle at encoder count 0 \[deg\], in \[0, 360).
    pub encoder_offset_elec_deg: Estimate,
    /// Counts that rise while the electrical angle falls.
    pub encoder_reversed: bool,
    /// Pole pairs.
    pub pole_pairs: u32,
    /// Encoder counts per electrical turn (its magnitude).
    pub counts_per_electrical_turn: Estimate,
    /// Half the difference of the two sweeps' offsets \[deg\]: the rotor's lag behind the
    /// turning vector.
    pub sweep_lag_elec_deg: f64,
}

impl MotorEstimates {
    /// The calibration in one line (what `identify` and the board's `calibrate` print).
    #[must_use]
    pub fn describe(&self) -> String {
        format!(
            "R = {:.4} pu, Ld = {:.3e} pu·s, Lq = {:.3e} pu·s, {} pole pairs, encoder offset \
             {:.2} deg electrical{}",
            self.winding_resistance_pu.value,
            self.d_inductance_pu_s.value,
            self.q_inductance_pu_s.value,
            self.pole_pairs,
            self.encoder_offset_elec_deg.value,
            if self.encoder_reversed {
                " (reversed)"
            } else {
                ""
            }
        )
    }
}

fn bad(what: impl Into<String>) -> HarnessError {
    HarnessError::Backend(format!("calibration: {}", what.into()))
}

/// Ordinary least squares of `y` on the columns of `x`: the coefficients and their
/// standard errors.
fn ols(x: &DMatrix<f64>, y: &DVector<f64>) -> Result<(DVector<f64>, DVector<f64>)> {
    let (n, p) = x.shape();
    if n <= p {
        return Err(bad(format!("{n} samples for {p} unknowns")));
    }
    let xtx = x.transpose() * x;
    let inv = xtx
        .try_inverse()
        .ok_or_else(|| bad("the regression's normal matrix is singular"))?;
    let beta = &inv * (x.transpose() * y);
    let resid = y - x * &beta;
    let s2 = resid.norm_squared() / (n - p) as f64;
    let se = inv.diagonal().map(|d| (s2 * d).max(0.0).sqrt());
    Ok((beta, se))
}

/// Instrumental-variable least squares of `y` on the columns of `x`, with as many
/// instruments `z`: `β = (ZᵀX)⁻¹·Zᵀy`, with standard errors from `s²·(ZᵀX)⁻¹·ZᵀZ·(XᵀZ)⁻¹`.
/// Consistent where a regressor carries noise that `y` shares (a sampled current in its
/// own step), so long as the instruments carry none.
fn iv(
    x: &DMatrix<f64>,
    z: &DMatrix<f64>,
    y: &DVector<f64>,
) -> Result<(DVector<f64>, DVector<f64>)> {
    let (n, p) = x.shape();
    if n <= p || z.shape() != (n, p) {
        return Err(bad(format!("{n} samples for {p} unknowns")));
    }
    let inv = (z.transpose() * x)
        .try_inverse()
        .ok_or_else(|| bad("the voltages do not determine the currents' regression"))?;
    let beta = &inv * (z.transpose() * y);
    let resid = y - x * &beta;
    let s2 = resid.norm_squared() / (n - p) as f64;
    let cov = &inv * (z.transpose() * z) * inv.transpose();
    let se = cov.diagonal().map(|d| (s2 * d).max(0.0).sqrt());
    Ok((beta, se))
}

/// Coefficient `i` of `v` (NaN past its end, which the callers' finiteness checks refuse).
fn at(v: &DVector<f64>, i: usize) -> f64 {
    v.get(i).copied().unwrap_or(f64::NAN)
}

fn i_alpha(r: &Row) -> f64 {
    r.i_a
}
fn i_beta(r: &Row) -> f64 {
    (r.i_a + 2.0 * r.i_b) / 3f64.sqrt()
}

/// The rows of a level's recorded part.
fn level(rows: &[Row], index: u8) -> Vec<&Row> {
    rows.iter()
        .filter(|r| {
            r.stage
                == Stage::Level {
                    index,
                    recording: true,
                }
        })
        .collect()
}

fn mean(it: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = it.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    s / n.max(1) as f64
}

fn resistance(rows: &[Row]) -> Result<Estimate> {
    let (l0, l1) = (level(rows, 0), level(rows, 1));
    if l0.len() < 20 || l1.len() < 20 {
        return Err(bad("the current levels recorded fewer than 20 ticks each"));
    }
    let ratio = |a: &[&Row], b: &[&Row]| -> f64 {
        let dv = mean(b.iter().map(|r| r.v_alpha)) - mean(a.iter().map(|r| r.v_alpha));
        let di = mean(b.iter().map(|r| i_alpha(r))) - mean(a.iter().map(|r| i_alpha(r)));
        dv / di
    };
    let value = ratio(&l0, &l1);
    const BLOCKS: usize = 10;
    let (b0, b1) = (l0.len() / BLOCKS, l1.len() / BLOCKS);
    let blocks: Vec<f64> = (0..BLOCKS)
        .filter_map(|k| {
            let a = l0.get(k * b0..(k + 1) * b0)?;
            let b = l1.get(k * b1..(k + 1) * b1)?;
            Some(ratio(a, b))
        })
        .collect();
    let m = mean(blocks.iter().copied());
    let sd = (blocks.iter().map(|x| (x - m).powi(2)).sum::<f64>()
        / (blocks.len().max(2) - 1) as f64)
        .sqrt();
    if !(value.is_finite() && value > 0.0) {
        return Err(bad(format!(
            "the resistance came out as {value} pu: the two current levels did not differ"
        )));
    }
    Ok(Estimate {
        value,
        std_error: sd / (blocks.len() as f64).sqrt(),
    })
}

/// (L_d, L_q) from the square wave's rows, with the phase resistance `r`.
fn inductances(rows: &[Row], rate_hz: f64, r: f64) -> Result<(Estimate, Estimate)> {
    // Row k holds i(k) sampled before v(k) is set; v(k) acts from sample k on (part of
    // tick k+1 with the delay), so Δi(k) = i(k+1) − i(k) sees v(k−1) and v(k).
    let idx: Vec<usize> = (1..rows.len().saturating_sub(1))
        .filter(|&k| rows.get(k).is_some_and(|r| r.stage == Stage::Square))
        .filter(|&k| rows.get(k - 1).is_some_and(|r| r.stage == Stage::Square))
        .collect();
    let mut feats: Vec<[f64; 7]> = Vec::with_capacity(idx.len());
    let mut ya = Vec::with_capacity(idx.len());
    let mut yb = Vec::with_capacity(idx.len());
    for &k in &idx {
        let (Some(prev), Some(now), Some(next)) = (rows.get(k - 1), rows.get(k), rows.get(k + 1))
        else {
            continue;
        };
        feats.push(regressors(prev, now, [i_alpha(now), i_beta(now)]));
        ya.push(i_alpha(next) - i_alpha(now));
        yb.push(i_beta(next) - i_beta(now));
    }
    let x = DMatrix::from_row_iterator(feats.len(), 7, feats.iter().flatten().copied());
    let (ya, yb) = (DVector::from_vec(ya), DVector::from_vec(yb));
    // G = Ts·L⁻¹ in (α, β) (each entry the sum of a tick's two weights); its symmetric part.
    let pair = |v: &DVector<f64>, i: usize| at(v, i) + at(v, i + 1);
    // The sampled current i(k) is a regressor, and its noise is in the step i(k+1) − i(k)
    // too, with the opposite sign: least squares then takes the noise for a decay and
    // moves the voltages' weights with it (Lq 33 % high at 0.005 pu of current noise on a
    // light motor). Instead, instrumental variables: for the two currents, the currents the
    // voltages alone give. First each axis's voltages summed with the decay e = 1 − R·Ts/L
    // of a least-squares pass; then, stronger, the currents the first fit's model gives for
    // the recorded voltages (the instruments' strength, not the estimate, depends on them).
    let (b0, _) = ols(&x, &ya)?;
    let (b1, _) = ols(&x, &yb)?;
    let decay = (1.0 - r * 0.5 * (pair(&b0, 0) + pair(&b1, 2))).clamp(0.0, 1.0);
    let matrix = |z: Vec<[f64; 7]>| DMatrix::from_row_iterator(z.len(), 7, z.into_iter().flatten());
    let sums = leaky_sums(rows, decay);
    let z = matrix(instruments(rows, &idx, |k| sums.get(k).copied()));
    let (b0, _) = iv(&x, &z, &ya)?;
    let (b1, _) = iv(&x, &z, &yb)?;
    let z = match model_currents(rows, &b0, &b1) {
        Some(m) => matrix(instruments(rows, &idx, |k| m.get(k).copied())),
        None => z,
    };
    let (ba, sa) = iv(&x, &z, &ya)?;
    let (bb, sb) = iv(&x, &z, &yb)?;
    let (gaa, gbb) = (pair(&ba, 0), pair(&bb, 2));
    let gab = 0.5 * (pair(&ba, 2) + pair(&bb, 0));
    let mean = 0.5 * (gaa + gbb);
    let half = (0.25 * (gaa - gbb).powi(2) + gab * gab).sqrt();
    let (g_d, g_q) = (mean + half, mean - half);
    if !(g_q.is_finite() && g_q > 0.0) {
        return Err(bad(format!(
            "the currents did not follow the square wave (Ts/L of {g_d:.4} and {g_q:.4})"
        )));
    }
    // Each eigenvalue's error: at most the largest of the entries' errors.
    let g_se = pair(&sa, 0)
        .max(pair(&sb, 2))
        .max(0.5 * (pair(&sa, 2) + pair(&sb, 0)));
    let ts = 1.0 / rate_hz;
    // L(g) = R·Ts/(−ln(1 − g·R)), Ts/g as R → 0; dL/dg by the difference over its error.
    let l_of = |g: f64| {
        let gr = g * r;
        if gr < 1e-9 {
            ts / g
        } else {
            r * ts / -(1.0 - gr).ln()
        }
    };
    let est = |g: f64| -> Result<Estimate> {
        if (g * r).is_nan() || g * r >= 1.0 {
            return Err(bad(format!(
                "the current stepped more than one tick's decay allows (R·g = {:.3})",
                g * r
            )));
        }
        let value = l_of(g);
        let lo = l_of((g - g_se).max(g * 0.5));
        Ok(Estimate {
            value,
            std_error: (lo - value).abs(),
        })
    };
    Ok((est(g_d)?, est(g_q)?))
}

/// The regressors of row `k` of the square wave with the currents `i` in place of the
/// sampled ones.
fn regressors(prev: &Row, now: &Row, i: [f64; 2]) -> [f64; 7] {
    [
        now.v_alpha,
        prev.v_alpha,
        now.v_beta,
        prev.v_beta,
        i[0],
        i[1],
        1.0,
    ]
}

/// The square wave's instruments at the rows `idx`: the regressors with the two sampled
/// currents replaced by `currents(k)`, noise-free stand-ins formed from the voltages.
fn instruments(
    rows: &[Row],
    idx: &[usize],
    currents: impl Fn(usize) -> Option<[f64; 2]>,
) -> Vec<[f64; 7]> {
    idx.iter()
        .filter_map(|&k| {
            rows.get(k + 1)?;
            Some(regressors(rows.get(k - 1)?, rows.get(k)?, currents(k)?))
        })
        .collect()
}

/// Each axis's voltages summed over the square wave with the decay `e`:
/// `S(k) = e·S(k−1) + v(k−1)`, 0 at its start (and off it).
fn leaky_sums(rows: &[Row], decay: f64) -> Vec<[f64; 2]> {
    let mut sums = vec![[0.0; 2]; rows.len()];
    for k in 1..rows.len() {
        let (Some(prev), Some(now)) = (rows.get(k - 1), rows.get(k)) else {
            continue;
        };
        if now.stage == Stage::Square && prev.stage == Stage::Square {
            let last = sums.get(k - 1).copied().unwrap_or_default();
            if let Some(s) = sums.get_mut(k) {
                *s = [
                    decay * last[0] + prev.v_alpha,
                    decay * last[1] + prev.v_beta,
                ];
            }
        }
    }
    sums
}

/// The currents the fit `(ba, bb)` (the steps of α and β on the regressors) gives for the
/// square wave's voltages, from the first sample of it on; `None` if they run away (a fit
/// that grows, which the recorded currents did not).
fn model_currents(rows: &[Row], ba: &DVector<f64>, bb: &DVector<f64>) -> Option<Vec<[f64; 2]>> {
    let mut m = vec![[0.0; 2]; rows.len()];
    let mut cur: Option<[f64; 2]> = None;
    for k in 1..rows.len() {
        let (prev, now) = (rows.get(k - 1)?, rows.get(k)?);
        if now.stage != Stage::Square || prev.stage != Stage::Square {
            cur = None;
            continue;
        }
        let i = *cur.get_or_insert([i_alpha(now), i_beta(now)]);
        *m.get_mut(k)? = i;
        let f = DVector::from_row_slice(&regressors(prev, now, i));
        let next = [i[0] + ba.dot(&f), i[1] + bb.dot(&f)];
        if !next.iter().all(|x| x.is_finite() && x.abs() < 1e3) {
            return None;
        }
        cur = Some(next);
    }
    Some(m)
}

/// The sweep `stage`'s fit: (slope in counts per turn, its se, offset in turns, its se).
fn sweep(rows: &[Row], stage: Stage) -> Result<(f64, f64, f64, f64)> {
    let s: Vec<&Row> = rows.iter().filter(|r| r.stage == stage).collect();
    // Each way ramps up over its first half turn and down over its last (the sequencer's
    // `sweep_step_at`). The first turn is left out (the ramp, then the rotor settling into
    // the turning vector at full speed), and the ramp down; of the rest, whole turns, over
    // which the inverter's dead time, whose distortion repeats six times a turn, averages
    // out. Both ways then use the same span of angle, at the same speed.
    let start = s.first().map_or(0.0, |r| r.phase_turns);
    let way = s.last().map_or(0.0, |r| (r.phase_turns - start).abs());
    let whole = (way - 1.5).floor();
    if whole < 1.0 {
        return Err(bad(format!(
            "the sweep turned {way:.2} electrical turns each way: the estimate needs at least \
             3 (a whole turn at full speed after the first)"
        )));
    }
    let s: Vec<&Row> = s
        .into_iter()
        .filter(|r| {
            let d = (r.phase_turns - start).abs();
            d > 1.0 && d <= 1.0 + whole
        })
        .collect();
    let x = DMatrix::from_row_iterator(s.len(), 2, s.iter().flat_map(|r| [1.0, r.phase_turns]));
    let y = DVector::from_iterator(s.len(), s.iter().map(|r| r.count as f64));
    let (beta, se) = ols(&x, &y)?;
    let (c0, slope) = (at(&beta, 0), at(&beta, 1));
    let (c0_se, slope_se) = (at(&se, 0), at(&se, 1));
    if !(slope.is_finite() && slope.abs() > 1e-9) {
        return Err(bad("the rotor did not follow the turning vector"));
    }
    // φ at count 0: −c0/s; its error to first order.
    let off = -c0 / slope;
    let off_se = ((c0_se / slope).powi(2) + (c0 * slope_se / slope.powi(2)).powi(2)).sqrt();
    Ok((slope, slope_se, off, off_se))
}

/// The motor's constants from `record`.
pub fn estimate(record: &Record) -> Result<MotorEstimates> {
    let rows = &record.rows;
    let r = resistance(rows)?;
    let (ld, lq) = inductances(rows, record.rate_hz, r.value)?;
    let (sf, sf_se, of, of_se) = sweep(rows, Stage::Forward)?;
    let (sb, sb_se, ob, ob_se) = sweep(rows, Stage::Backward)?;
    if sf.signum() != sb.signum() {
        return Err(bad(format!(
            "the two sweeps disagree on the direction ({sf:.1} and {sb:.1} counts per turn)"
        )));
    }
    let slope = 0.5 * (sf + sb);
    let per_turn = slope.abs();
    let cpr = f64::from(record.encoder_cpr);
    let pp_real = cpr / per_turn;
    let pole_pairs = pp_real.round();
    if !(pole_pairs >= 1.0 && (pp_real - pole_pairs).abs() <= 0.1) {
        return Err(bad(format!(
            "{per_turn:.2} counts per electrical turn on a {cpr}-count encoder is \
             {pp_real:.3} pole pairs, not a whole number"
        )));
    }
    // The two offsets on the circle: their mean angle, and half their difference.
    let diff = (ob - of + 0.5).rem_euclid(1.0) - 0.5;
    let mid = (of + 0.5 * diff).rem_euclid(1.0);
    Ok(MotorEstimates {
        winding_resistance_pu: r,
        d_inductance_pu_s: ld,
        q_inductance_pu_s: lq,
        encoder_offset_elec_deg: Estimate {
            value: mid * 360.0,
            std_error: 180.0 * (of_se.powi(2) + ob_se.powi(2)).sqrt(),
        },
        encoder_reversed: slope < 0.0,
        pole_pairs: pole_pairs as u32,
        counts_per_electrical_turn: Estimate {
            value: per_turn,
            std_error: 0.5 * (sf_se.powi(2) + sb_se.powi(2)).sqrt(),
        },
        sweep_lag_elec_deg: 180.0 * diff,
    })
}
