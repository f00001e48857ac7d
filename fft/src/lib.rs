//! The discrete Fourier transforms of stiffdrive's spectra: the Welch segments of
//! plant-host's frequency-response measurement and the metrics' spectra in sim-engine. One planner per thread keeps the plan of each
//! length and direction it has made: planning is most of a transform's cost, and the runs
//! one thread makes (a sweep, `tune`, the benchmark) ask for the same few lengths again and
//! again.
//!
//! These functions are not generic, so rustfft's generic planner and its butterflies (most of
//! the code the two crates above used to generate) are compiled once, in this crate, not
//! again in each crate that takes a spectrum and in each of its test builds.

pub use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::cell::RefCell;
use std::sync::Arc;

thread_local! {
    static PLANNER: RefCell<FftPlanner<f64>> = RefCell::new(FftPlanner::new());
}

/// The transform of `n` points, forward or inverse, from this thread's planner.
fn plan(n: usize, inverse: bool) -> Arc<dyn Fft<f64>> {
    PLANNER.with(|p| {
        let mut p = p.borrow_mut();
        if inverse {
            p.plan_fft_inverse(n)
        } else {
            p.plan_fft_forward(n)
        }
    })
}

/// `buf` replaced by its discrete Fourier transform X_k = Σ x_n·e^(−2πikn/N), unscaled.
#[inline(never)]
pub fn forward(buf: &mut [Complex<f64>]) {
    plan(buf.len(), false).process(buf);
}

/// `buf` replaced by its inverse transform Σ X_k·e^(+2πikn/N), unscaled (divide by N to
/// undo [`forward`]).
#[inline(never)]
pub fn inverse(buf: &mut [Complex<f64>]) {
    plan(buf.len(), true).process(buf);
}
