//! hil-harness's integration tests, built as one test binary: each module is one workflow
//! (tune, identify, commission, the notch, the linear model) on the shipped machine files;
//! `common` holds their shared set-up.
//! `cargo test -p hil-harness --test it <module>::` runs one module.

mod common;

mod commission;
mod commission_notch;
mod identify;
mod linear_model;
mod notch;
mod tune;
mod tune_report;
mod tune_table1;
