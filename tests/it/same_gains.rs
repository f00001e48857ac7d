//! "The same gains without acceleration feedback" means the same gains bit for bit: every
//! comparison run without AFB (the `*-no-afb` scenarios, the stiffness run without AFB)
//! builds its controller from its AFB run's designed gains with Ka = 0, never from a
//! design of its own.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use controller_core::Gains;
use sim_engine::config::borrow_gains;
use sim_engine::engine::runner::{controller, regulator_gains, same_regulator_gains};
use sim_engine::{resolve, RunConfig};

fn bits(g: &Gains) -> [u32; 7] {
    [
        g.kp_vel.to_bits(),
        g.ki_vel.to_bits(),
        g.kpp.to_bits(),
        g.k_pos_pu_per_count.to_bits(),
        g.kp_cur.to_bits(),
        g.ki_cur.to_bits(),
        g.j_loop_s.to_bits(),
    ]
}

fn check_pair(afb: &RunConfig, off: &RunConfig, sets: &[String]) {
    let g_afb = regulator_gains(afb).unwrap();
    let g_off = regulator_gains(off).unwrap();
    assert!(g_afb.ka > 0.0, "{}: AFB run without Ka", afb.name);
    assert_eq!(g_off.ka, 0.0, "{}", off.name);
    assert_eq!(
        bits(&g_off),
        bits(&g_afb),
        "{} vs {} {sets:?}",
        off.name,
        afb.name
    );
    assert!(same_regulator_gains(&g_off, &g_afb), "{}", off.name);
    // The controller that runs is built from exactly these gains.
    assert_eq!(controller(off).unwrap().gains(), &g_off, "{}", off.name);
}

/// Every scenario that names `[scenario.comparison] gains_of` runs at that scenario's
/// gains, with the PI sized either way (`velocity_pi_inertia`); the report's six
/// comparisons are among them.
#[test]
fn every_no_afb_scenario_runs_at_the_gains_of_its_afb_run() {
    let mut pairs = 0;
    for inertia in ["total", "total_plus_afb"] {
        let sets = vec![format!("drive.velocity_pi_inertia={inertia}")];
        for name in sim_engine::config::known_scenarios() {
            let off = resolve(&name, None, &sets).unwrap();
            let Some(of) = off.gains_of.clone() else {
                continue;
            };
            let afb = resolve(&of.source, None, &sets).unwrap();
            check_pair(&afb, &off, &sets);
            pairs += 1;
        }
    }
    assert!(
        pairs >= 2 * paper_repro::report::COMPARISONS.len(),
        "{pairs}"
    );
    for (afb, off) in paper_repro::report::COMPARISONS {
        let cfg = resolve(off, None, &[]).unwrap();
        assert_eq!(
            cfg.gains_of.map(|g| g.source).as_deref(),
            Some(afb),
            "{off}"
        );
    }
}

/// With the PI sized for J_total + Ka the AFB run's gains differ from what the drive
/// without AFB would design for itself; the comparison still uses the AFB run's.
#[test]
fn borrowed_gains_are_not_the_drives_own_design() {
    let sets = vec!["drive.velocity_pi_inertia=total_plus_afb".to_string()];
    let off = resolve("fig6-no-afb", None, &sets).unwrap();
    let own = controller_core::design(&off.drive).unwrap();
    let used = regulator_gains(&off).unwrap();
    let ka = controller_core::design(&resolve("fig6", None, &sets).unwrap().drive)
        .unwrap()
        .ka;
    assert!(ka > 0.0);
    assert_eq!(
        used.kp_vel,
        off.drive.velocity_bandwidth_rad_s * (off.drive.total_inertia_s() + ka)
    );
    assert!(used.kp_vel > own.kp_vel);
}

/// The stiffness measurement without AFB uses the default AFB design's gains.
#[test]
fn stiffness_without_afb_runs_at_the_afb_designs_gains() {
    let off = machine_workflows::stiffness::stiffness_config(None, &[]).unwrap();
    for source in [
        Some(controller_core::Estimator::Observer),
        Some(controller_core::Estimator::Differentiation),
    ] {
        let afb = machine_workflows::stiffness::stiffness_config(source, &[]).unwrap();
        check_pair(&afb, &off, &[]);
    }
}

/// A comparison must be the same drive: one that differs outside `[drive.accel_feedback]`,
/// or one with AFB on, is rejected with the key named.
#[test]
fn a_different_drive_cannot_borrow_the_gains() {
    let afb = resolve("fig6", None, &[]).unwrap();
    let mut off = resolve(
        "fig6-no-afb",
        None,
        &["drive.velocity_bandwidth_rad_s=50".to_string()],
    )
    .unwrap();
    let e = borrow_gains(&mut off, "fig6", &afb.drive)
        .unwrap_err()
        .to_string();
    assert!(e.contains("scenario.comparison.gains_of"), "{e}");
    let mut on = resolve("fig6", None, &[]).unwrap();
    let e = borrow_gains(&mut on, "fig6", &afb.drive)
        .unwrap_err()
        .to_string();
    assert!(e.contains("mode = \"off\""), "{e}");
    // And through the scenario file: AFB switched back on in the comparison run.
    let e = resolve(
        "fig6-no-afb",
        None,
        &["drive.accel_feedback.mode=error".to_string()],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("scenario.comparison.gains_of"), "{e}");
}

/// The run a comparison names must design its own gains: a chain or a cycle of
/// `gains_of` is an error naming the key, not a recursion.
#[test]
fn gains_of_must_name_a_run_that_designs_its_own_gains() {
    let e = resolve(
        "shock-50-no-afb",
        None,
        &["scenario.comparison.gains_of=fig6-no-afb".to_string()],
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("scenario.comparison.gains_of") && e.contains("itself borrows"),
        "{e}"
    );
    let e = resolve(
        "fig6-no-afb",
        None,
        &["scenario.comparison.gains_of=fig6-no-afb".to_string()],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("scenario.comparison.gains_of"), "{e}");
    // An AFB run without AFB has no gains to lend.
    let e = resolve(
        "shock-50-no-afb",
        None,
        &["scenario.comparison.gains_of=fig6-low-bw".to_string()],
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("no AFB gains to borrow") || e.contains("acceleration feedback off"),
        "{e}"
    );
}
