//! A measured frequency response: what identification's H1 estimate (`frf.rs`, feature
//! `frf`) returns and the two-inertia fit (`fit.rs`) reads.

use nalgebra::Complex;

/// A measured frequency response.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredResponse {
    /// Frequencies \[Hz\], bins 1 .. segment_len/2 (DC left out).
    pub freq_hz: Vec<f64>,
    /// The response at each frequency.
    pub h: Vec<Complex<f64>>,
    /// Coherence γ² in [0, 1]. For `closed_loop_response`, the smaller of γ²(r, y) and
    /// γ²(r, u).
    pub coherence: Vec<f64>,
    /// Number of averaged segments.
    pub segments: usize,
}
