//! Field-oriented control (FOC) of a three-phase permanent-magnet synchronous motor (PMSM):
//! the blocks of one current tick, each in fixed point, each without a panic path.
//!
//! ```text
//!  count ─▶ angle ─▶ θe (+ ω·t_delay) ─▶ cossin ─┬──────────────────────────┐
//!  i_a, i_b ─▶ clarke ─▶ (iα, iβ) ─▶ park ─▶ (id, iq)                      │
//!  (id*, iq*) ─▶ d/q PI + decoupling ─▶ voltage circle ─▶ (vd, vq) ─▶ inverse park ─▶ svpwm ─▶ duties
//! ```
//!
//! Per-unit conventions (the voltage base makes the back-EMF at base speed 1 pu with the
//! rated flux):
//! - speed ω in pu of the mechanical base speed ω_b = 2π·base_speed_rpm/60; the electrical
//!   speed in rad/s is `pole_pairs · ω_b · ω`;
//! - inductances L in pu·s (`L·di/dt = v` with di/dt in pu/s), as the DC winding's;
//! - the d/q voltage equations:
//!   `L_d·di_d/dt = v_d − R·i_d + ω_e·L_q·i_q` and
//!   `L_q·di_q/dt = v_q − R·i_q − ω_e·L_d·i_d − ω·λ`, with ω_e in rad/s and λ in pu;
//! - torque `T = λ·i_q + ω_e,b·(L_d − L_q)·i_d·i_q` in pu, ω_e,b = pole_pairs·ω_b.
//!
//! The angle is a 32-bit phase: `0` is 0, `i32::MIN` (as `u32`, 2^31) is π, and the
//! arithmetic wraps modulo one electrical turn. sin and cos come from `idsp::cossin`
//! (a table with interpolation: at most 9e-6 error).

pub mod angle;
pub mod calibration;
pub mod commutation;
pub mod config;
pub mod current_loop;
pub mod mtpa;
pub mod svpwm;
pub mod transforms;
pub mod voltage_limit;

pub use angle::{AngleCoefficients, AngleState};
pub use commutation::{CommutationCheck, CommutationState};
pub use config::PmsmConfig;
pub use current_loop::{FocCoefficients, FocInputs, FocOutputs, FocSettings, FocState};
pub use svpwm::Svpwm;
pub use transforms::{AlphaBeta, CosSin, Dq, clarke, inverse_park, park};
pub use voltage_limit::VoltageCircle;
