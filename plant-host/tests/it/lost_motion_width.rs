//! The lost motion is exactly as wide as the config says: from the middle of the gap, a
//! motor pushed by a small torque moves the load only once the twist reaches half the
//! total backlash (the dead-zone edge), not earlier and not later.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;

use plant_host::TwoInertiaPlant;

#[test]
fn the_gears_engage_at_half_the_backlash_from_the_centre() {
    let cfg = common::table1();
    let half_gap_rad = 0.5 * cfg.mechanics.backlash_deg.to_radians();
    assert!(half_gap_rad > 0.0);
    let mut plant = TwoInertiaPlant::torque_driven(&cfg);
    let dt = 1e-5;
    let mut engaged_at = None;
    for _ in 0..200_000 {
        let twist = plant.motor_pos_rad() - plant.load_pos_rad();
        plant.advance(dt, 0.01, 0.0);
        if plant.shaft_torque_pu().abs() > 0.0 {
            engaged_at = Some(twist);
            break;
        }
    }
    let twist = engaged_at.expect("the gears never engaged");
    // The step before contact: the twist is just below the edge (one step of motion).
    assert!(
        twist <= half_gap_rad && twist > 0.98 * half_gap_rad,
        "engaged at a twist of {twist} rad; the dead-zone edge is at {half_gap_rad} rad"
    );
}
