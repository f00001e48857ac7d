//! Linear analysis of the plant with nalgebra: the engaged plant's state-space model and
//! modes, its sampled forms, the PI stiffness of Eq. 1 (Fig. 2), and the frequency-response
//! measurement (feature `frf`, on by default) and two-inertia fit of identification. This
//! crate does not depend on the controller: the closed loop's one linear model (poles,
//! margins, stability, the model `tune` designs on) is the harness's, which mirrors the
//! controller's tick.

mod engaged;
mod fit;
#[cfg(feature = "frf")]
mod frf;
mod response;
mod sampled;
mod stiffness;

pub use engaged::{EngagedPlant, Modes, PlantResponse};
pub use fit::{FitError, FitResult, TwoInertiaFit, fit_two_inertia};
#[cfg(feature = "frf")]
pub use frf::{FrfError, closed_loop_response, h1};
pub use response::MeasuredResponse;
pub use sampled::{Gears, SampledPlant, continuous, state};
pub use stiffness::{PiStiffness, StiffnessPoint};

/// `n` frequencies log-spaced from `lo` to `hi` (rad/s), both included.
pub fn log_space(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let n = n.max(2);
    let (a, b) = (lo.ln(), hi.ln());
    (0..n)
        .map(|k| (a + (b - a) * k as f64 / (n - 1) as f64).exp())
        .collect()
}
