//! `advance_fixed` is `try_advance` bit for bit: the same sub-steps and maps, through gap
//! crossings, with steps longer than one sub-step, both backlash laws, and other step lengths
//! interleaved so that the map cache reuses the fixed steps' slots.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use crate::common;

use plant_host::{BacklashModel, TwoInertiaPlant};

fn bits(p: &TwoInertiaPlant) -> [u64; 6] {
    [
        p.motor_pos_rad(),
        p.load_pos_rad(),
        p.motor_vel_pu(),
        p.load_vel_pu(),
        p.current_pu(),
        p.time_s(),
    ]
    .map(f64::to_bits)
}

fn same_run(clamped: bool, voltage: bool) {
    let mut cfg = common::table1();
    if clamped {
        cfg.lost_motion.model = BacklashModel::Clamped;
    }
    let new = |c| {
        if voltage {
            TwoInertiaPlant::voltage_driven(c)
        } else {
            TwoInertiaPlant::torque_driven(c)
        }
    };
    let (mut fixed, mut plain) = (new(&cfg), new(&cfg));
    let lengths = [180e-6, 70e-6, 3.0 * fixed.max_substep_s() + 1e-7, 0.0];
    let steps = lengths.map(|h| fixed.fixed_step(h).unwrap());
    for (step, h) in steps.iter().zip(lengths) {
        assert_eq!(step.dt_s(), h);
    }
    let mut s: u64 = 0x2545_F491_4F6C_DD1D;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut crossings_seen = 0;
    for k in 0..4000 {
        // Reversing inputs every few steps: the gears cross the lost motion many times.
        let sign = if (k / 7) % 2 == 0 { 1.0 } else { -1.0 };
        let input = sign * (0.2 + next()) * if voltage { 0.3 } else { 1.0 };
        let load = 0.2 * (next() - 0.5);
        let i = k % lengths.len();
        fixed.advance_fixed(&steps[i], input, load).unwrap();
        plain.try_advance(lengths[i], input, load).unwrap();
        if k % 50 == 49 {
            // Seven other lengths fill (and recycle) the six cache slots of both plants.
            for j in 1..=7 {
                let h = 1e-5 * f64::from(j) + 1e-7;
                fixed.try_advance(h, input, load).unwrap();
                plain.try_advance(h, input, load).unwrap();
            }
        }
        assert_eq!(bits(&fixed), bits(&plain), "step {k}");
        assert_eq!(fixed.contact(), plain.contact(), "step {k}");
        crossings_seen = fixed.mode_changes();
    }
    assert!(crossings_seen > 100, "{crossings_seen} crossings");
    // Every mode change was found by a search (a suspect step redone), and both plants
    // redid the same steps.
    assert!(fixed.crossing_searches() >= crossings_seen);
    assert_eq!(fixed.crossing_searches(), plain.crossing_searches());
    // The twist is the motor angle less the load angle.
    let twist = fixed.motor_pos_rad() - fixed.load_pos_rad();
    assert!(
        (fixed.twist_rad() - twist).abs() < 1e-12,
        "{}",
        fixed.twist_rad()
    );
}

#[test]
fn a_fixed_step_advances_as_try_advance_does_bit_for_bit() {
    for clamped in [false, true] {
        for voltage in [false, true] {
            same_run(clamped, voltage);
        }
    }
}

#[test]
fn bad_lengths_and_inputs_are_the_errors_of_try_advance() {
    let cfg = common::table1();
    let mut p = TwoInertiaPlant::voltage_driven(&cfg);
    let mut q = p.clone();
    for h in [-1e-6, f64::NAN, f64::INFINITY] {
        // As text: a NaN in the error is not equal to itself.
        let (a, b) = (p.fixed_step(h).err(), q.try_advance(h, 0.0, 0.0).err());
        assert!(a.is_some());
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
    }
    let step = p.fixed_step(1e-4).unwrap();
    for (v, l) in [
        (f64::NAN, 0.0),
        (0.0, f64::INFINITY),
        (f64::NEG_INFINITY, f64::NAN),
    ] {
        let (a, b) = (
            p.advance_fixed(&step, v, l).err(),
            q.try_advance(1e-4, v, l).err(),
        );
        assert!(a.is_some());
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
    }
    // Nothing moved.
    assert_eq!(bits(&p), bits(&q));
    assert_eq!(p.time_s(), 0.0);
}
