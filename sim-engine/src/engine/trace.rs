//! The time series a run records: one row per velocity tick (2 kHz for Table 1), every
//! signal the paper plots, in per-unit and encoder counts.

use crate::error::{HarnessError, Result};
use std::io::Write;
use std::path::Path;

/// Column names of `trace.csv`, in order. Units are in the names.
pub const COLUMNS: [&str; 18] = [
    "t_s",
    "pos_cmd_counts",
    "motor_pos_counts",
    "load_pos_counts",
    "cmd_minus_motor_counts",
    "motor_minus_load_counts",
    "vel_cmd_pu",
    "motor_vel_pu",
    "load_vel_pu",
    "vel_est_pu",
    "torque_cmd_pu",
    "current_pu",
    "accel_fb_pu",
    "shaft_torque_pu",
    "load_torque_pu",
    "voltage_pu",
    "accel_est_pu_s",
    "fault",
];

/// One sample of every recorded signal.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TraceRow {
    /// Simulated time of the velocity tick (s).
    pub t_s: f64,
    /// Commanded position, unwrapped (counts).
    pub pos_cmd_counts: f64,
    /// True motor position (counts, not quantized).
    pub motor_pos_counts: f64,
    /// True load position reflected to the motor side (counts).
    pub load_pos_counts: f64,
    /// Velocity command from the profile (pu of base speed).
    pub vel_cmd_pu: f64,
    /// True motor speed (pu).
    pub motor_vel_pu: f64,
    /// True load speed (pu).
    pub load_vel_pu: f64,
    /// The controller's velocity estimate (pu).
    pub vel_est_pu: f64,
    /// Torque (= current) reference from the velocity regulator, after limits (pu).
    pub torque_cmd_pu: f64,
    /// Measured winding current (pu), as the current regulator samples it.
    pub current_pu: f64,
    /// Acceleration-feedback signal subtracted from the torque command (pu).
    pub accel_fb_pu: f64,
    /// Torque transmitted through the coupling (pu): what a torque transducer reads.
    pub shaft_torque_pu: f64,
    /// Load torque disturbance on the load inertia (pu).
    pub load_torque_pu: f64,
    /// Voltage command applied to the winding (pu).
    pub voltage_pu: f64,
    /// The controller's acceleration estimate (pu/s).
    pub accel_est_pu_s: f64,
    /// The fault code the controller reports (`controller_core::Fault::code`; 0 = none).
    pub fault: f64,
}

impl TraceRow {
    /// The row's values in [`COLUMNS`] order; the two position differences are derived.
    pub fn values(&self) -> [f64; 18] {
        [
            self.t_s,
            self.pos_cmd_counts,
            self.motor_pos_counts,
            self.load_pos_counts,
            self.pos_cmd_counts - self.motor_pos_counts,
            self.motor_pos_counts - self.load_pos_counts,
            self.vel_cmd_pu,
            self.motor_vel_pu,
            self.load_vel_pu,
            self.vel_est_pu,
            self.torque_cmd_pu,
            self.current_pu,
            self.accel_fb_pu,
            self.shaft_torque_pu,
            self.load_torque_pu,
            self.voltage_pu,
            self.accel_est_pu_s,
            self.fault,
        ]
    }

    /// Command minus motor position (counts): the following error of Fig. 4.
    pub fn cmd_minus_motor_counts(&self) -> f64 {
        self.pos_cmd_counts - self.motor_pos_counts
    }

    /// Motor minus load position (counts): the twist including lost motion, Fig. 4.
    pub fn motor_minus_load_counts(&self) -> f64 {
        self.motor_pos_counts - self.load_pos_counts
    }
}

/// A recorded run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// Rows in time order.
    pub rows: Vec<TraceRow>,
}

impl Trace {
    /// Whether any row records a latched fault (the metrics' `faulted`).
    #[must_use]
    pub fn faulted(&self) -> bool {
        self.rows.iter().any(|r| r.fault != 0.0)
    }

    /// Writes the trace as CSV with a header of [`COLUMNS`].
    pub fn write_csv(&self, path: &Path) -> Result<()> {
        let file = std::fs::File::create(path).map_err(|e| HarnessError::io(path, e))?;
        let mut out = std::io::BufWriter::new(file);
        let io = |e: std::io::Error| HarnessError::io(path, e);
        writeln!(out, "{}", COLUMNS.join(",")).map_err(io)?;
        for row in &self.rows {
            let mut first = true;
            for v in row.values() {
                if !first {
                    out.write_all(b",").map_err(io)?;
                }
                first = false;
                // Shortest representation that round-trips, so the file is bit-exact.
                write!(out, "{v}").map_err(io)?;
            }
            out.write_all(b"\n").map_err(io)?;
        }
        out.flush().map_err(io)
    }

    /// One signal as a vector of (t_s, value) points, for plotting.
    pub fn series(&self, f: impl Fn(&TraceRow) -> f64) -> Vec<(f64, f64)> {
        self.rows.iter().map(|r| (r.t_s, f(r))).collect()
    }
}
