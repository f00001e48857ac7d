//! paper-repro: the paper's reproduction. [`report::reproduce`] (what `cargo run --release`
//! does) runs every scenario, the sweep, the stiffness measurement, the Sec. II map and
//! `tune` on the shipped machines, and writes `REPORT.md`, one section per paper figure or
//! claim; [`sec2`] is the Sec. II map with the paper's own estimator.

pub mod report;
pub mod sec2;
