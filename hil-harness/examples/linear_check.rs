//! Prints the linear model's stability prediction against the nonlinear loop on a grid.
use machine_workflows::linear::check::check_grid;
use machine_workflows::sweep::{default_observer_hz, designs};

fn main() -> sim_engine::Result<()> {
    let grid = sim_engine::config::sweep_grid()?;
    let designs: Vec<_> = designs(&grid, default_observer_hz())
        .into_iter()
        .step_by(6)
        .collect();
    let bws: Vec<f64> = grid.bandwidths_rad_s.iter().copied().step_by(2).collect();
    let pts = check_grid(&["table1", "dyno"], &bws, &designs);
    let agree = pts.iter().filter(|p| p.predicted == p.measured).count();
    for p in &pts {
        if p.predicted != p.measured {
            let o = &p.oscillation;
            println!(
                "{} {} {} rad/s: predicted {} measured {} (radius {:.4} / {:.4}, ζ {:.3}, chatter {:.3} pu; \
                 {:?} at {:.1} Hz, ±{:.3} pu, narrowband {:.2}, saturated {:.2}, tone {:.1} Hz)",
                p.plant, p.design, p.bandwidth_rad_s, p.predicted, p.measured, p.radius_engaged,
                p.radius_apart, p.damping_engaged, p.limit_cycle_torque_pu, o.kind, o.freq_hz,
                o.amplitude_pu, o.narrowband_fraction, o.saturated_fraction, o.tone_hz.unwrap_or(0.0)
            );
        }
    }
    println!("{agree} of {} agree", pts.len());
    let quiet = |p: &machine_workflows::linear::check::CheckPoint| {
        p.measured && p.limit_cycle_torque_pu < 0.1
    };
    let agree_q = pts.iter().filter(|p| p.predicted == quiet(p)).count();
    println!("{agree_q} of {} agree with stable-and-quiet", pts.len());
    let mut lc: Vec<(f64, bool)> = pts
        .iter()
        .filter(|p| p.measured)
        .map(|p| (p.limit_cycle_torque_pu, p.predicted))
        .collect();
    lc.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (c, pr) in lc.iter().rev().take(25) {
        println!("chatter {c:.3} predicted {pr}");
    }
    Ok(())
}
