//! Linear analysis of the engaged plant (gears in contact, no lost motion) with nalgebra:
//! its state-space model and modes, the stiffness of Eq. 1 (Fig. 2), and the closed velocity
//! loop's frequency response, margins and sampled-data stability with and without
//! acceleration feedback. Controller gains are plain numbers: this crate does not depend on
//! the controller.

mod engaged;
mod fit;
mod frf;
mod sampled;
mod stiffness;
mod velocity_loop;

pub use engaged::{EngagedPlant, Modes, PlantResponse};
pub use fit::{fit_two_inertia, FitError, FitResult, TwoInertiaFit};
pub use frf::{closed_loop_response, h1, FrfError, MeasuredResponse};
pub use sampled::{continuous, state, Gears, SampledPlant};
pub use stiffness::{PiStiffness, StiffnessPoint};
pub use velocity_loop::{LoopPoint, Margins, VelocityLoop};

/// `n` frequencies log-spaced from `lo` to `hi` (rad/s), both included.
pub fn log_space(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let n = n.max(2);
    let (a, b) = (lo.ln(), hi.ln());
    (0..n)
        .map(|k| (a + (b - a) * k as f64 / (n - 1) as f64).exp())
        .collect()
}
