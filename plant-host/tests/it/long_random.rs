//! A longer random run against the reference (~3 s): 20 s of random held torques at 4 kHz,
//! ~1500 edge crossings. `cargo test -p plant-host --test it long_random:: -- --nocapture`
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use crate::common;

use common::{RefParams, Reference};
use plant_host::{BacklashModel, TwoInertiaPlant};

#[test]
fn twenty_seconds_of_random_torques() {
    for clamped in [false, true] {
        let mut cfg = common::table1();
        if clamped {
            cfg.lost_motion.model = BacklashModel::Clamped;
        }
        let m = &cfg.mechanics;
        let mut p = TwoInertiaPlant::torque_driven(&cfg);
        let mut r = Reference::new(
            RefParams::from_raw(
                m.base_speed_rpm,
                m.motor_inertia_s,
                m.load_inertia_s,
                m.anti_resonance_hz,
                m.shaft_damping_ratio,
                m.backlash_deg,
                clamped,
                None,
            ),
            1e-6,
        );
        // xorshift for reproducible torques held 5–50 ms each.
        let mut s = 0x1234_5678_9abc_def0_u64;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut tm, mut tl, mut left) = (0.0, 0.0, 0);
        let (mut e_pos, mut e_vel) = (0.0_f64, 0.0_f64);
        for _ in 0..80_000 {
            if left == 0 {
                tm = 3.0 * (rnd() - 0.5);
                tl = 0.6 * (rnd() - 0.5);
                left = 20 + (rnd() * 180.0) as u32;
            }
            left -= 1;
            p.advance(250e-6, tm, tl);
            r.advance(250e-6, tm, tl);
            e_pos = e_pos
                .max((p.motor_pos_rad() - r.x[0]).abs())
                .max((p.load_pos_rad() - r.x[1]).abs());
            e_vel = e_vel
                .max((p.motor_vel_pu() - r.x[2]).abs())
                .max((p.load_vel_pu() - r.x[3]).abs());
        }
        println!(
            "clamped={clamped}: 20 s, {} crossings (reference {}), max position error {e_pos:.2e} rad, speed {e_vel:.2e} pu",
            p.mode_changes(),
            r.switches
        );
        assert!(e_pos < 1e-6 && e_vel < 1e-6);
    }
}
