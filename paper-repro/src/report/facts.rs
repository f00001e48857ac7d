//! The facts of a run that a heading or a plot title states, formatted from its typed
//! configuration, so that no title types a scenario's numbers itself.

use sim_engine::config::RunConfig;

/// The first load step of the scenario that is not zero \[pu\] (0 when there is none).
pub fn load_step_pu(cfg: &RunConfig) -> f64 {
    cfg.scenario
        .load
        .iter()
        .find(|l| l.torque_pu != 0.0)
        .map_or(0.0, |l| l.torque_pu)
}

/// The scenario's stability window, `a-b s`, as the metrics resolve it.
pub fn stable_window(cfg: &RunConfig) -> String {
    let (a, b) = cfg
        .scenario
        .metric_windows(f64::from(cfg.drive.torque_limit_pu))
        .stable_window_s;
    format!("{a}-{b} s")
}

/// `template` with its placeholders replaced by the run's facts:
/// - `{bw}`: the velocity bandwidth \[rad/s\];
/// - `{load}`: the first non-zero load step, as a whole percentage (`150 %`);
/// - `{accel_s}`: the profile's acceleration time \[s\];
/// - `{counts}`: the interpolated encoder counts per revolution;
/// - `{stable_window}`: the stability window of the metrics ([`stable_window`]).
pub fn fill(template: &str, cfg: &RunConfig) -> String {
    template
        .replace("{bw}", &cfg.drive.velocity_bandwidth_rad_s.to_string())
        .replace("{load}", &format!("{:.0} %", 100.0 * load_step_pu(cfg)))
        .replace("{accel_s}", &cfg.scenario.profile.accel_s.to_string())
        .replace("{counts}", &cfg.plant.counts_per_rev().to_string())
        .replace("{stable_window}", &stable_window(cfg))
}
