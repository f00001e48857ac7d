//! The machine workflows end to end, each module one workflow (tune, identify, commission,
//! the notch, the linear model) on the shipped machine files and on machines written for the
//! test (`common`). `cargo test --test it workflows::<module>::` runs one module.

mod common;

mod afb_only;
mod commission;
mod commission_notch;
mod commission_spindle;
mod drive_files;
mod identify;
mod linear_model;
mod notch;
mod pmsm_commission;
mod pmsm_identify;
mod pmsm_ipm;
mod tune;
mod tune_objective;
mod tune_report;
mod tune_table1;
