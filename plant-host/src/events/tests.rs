//! The event search's guards, crossing times and peak bound.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
use super::*;
use crate::model::test_model as model;

/// Every linear part of every guard, in each mode of both laws, with the winding (so the
/// current is a state): its value is c·x + k and its rate the derivative of that value
/// along the mode's dynamics, c·(A·x + B·u), with every component of the state counting
/// (the current drives the motor speed, so it enters the rate of the clamped law's force).
#[test]
fn guard_values_and_rates_follow_the_mode_dynamics() {
    let x = Vec5::new(0.003, -1.2, 0.7, -0.4, 1.5);
    let u = Vec3::new(0.8, -0.3, 1.0);
    let close = |got: f64, want: f64| (got - want).abs() <= 1e-12 * (1.0 + want.abs());
    let mut parts = 0;
    for law in [BacklashModel::DeadZone, BacklashModel::Clamped] {
        let model = model(law);
        for contact in Contact::ALL {
            let (a, b) = model.matrices(contact);
            let dx = a * x + b * u;
            for guard in guard_list(contact, law, &model.shaft, &a, &b)
                .iter()
                .flatten()
            {
                for l in guard.lins() {
                    let c = Vec5::from(l.c);
                    let (value, rate) = (c.dot(&x) + l.k, c.dot(&dx));
                    assert!(close(l.value(&x), value), "{law:?} {contact:?} {c:?}");
                    assert!(close(l.rate(&x, &u), rate), "{law:?} {contact:?} {c:?}");
                    parts += 1;
                }
            }
        }
    }
    // Dead zone: 2 + 1 + 1 parts; clamped: 4 + 1 + 1.
    assert_eq!(parts, 10);
}

/// The guard's value at `x`: the smallest of its parts.
fn value(g: &Guard, x: &Vec5) -> f64 {
    g.lins()
        .iter()
        .map(|l| l.value(x))
        .fold(f64::INFINITY, f64::min)
}

/// From inside the gap, the motor 0.5 pu faster than the load and the twist 1 mrad from
/// the driving edge: under both laws the earliest crossing of the free mode's guards is
/// the driving edge's, and the time found is the first at which that guard is positive,
/// to within 1e-12 s (it is positive there, not positive 1e-12 s before, and nowhere
/// positive on a fine grid before that). Heading away from both edges (the speeds
/// equal), nothing is crossed within the step.
#[test]
fn first_crossing_is_the_earliest_time_a_guard_turns_positive() {
    let u = Vec3::new(0.5, 0.0, 1.0);
    let h = 2e-3;
    for law in [BacklashModel::DeadZone, BacklashModel::Clamped] {
        let m = model(law);
        let (a, b) = m.matrices(Contact::Free);
        let guards = Guards::new(Contact::Free, law, &m.shaft, &a, &b);
        let x0 = Vec5::new(0.003, 0.0, 1.0, 0.5, 0.2);
        let taylor = Taylor::new(&a, &b, &x0, &u, h);
        let (t, target) = guards.first_crossing(&taylor, h).expect("a crossing");
        assert_eq!(target, Contact::Driving, "{law:?}");
        assert!(t > 0.0 && t <= h, "{law:?}: {t}");
        let driving = guards.list[0].as_ref().unwrap();
        assert!(value(driving, &taylor.state(t)) > 0.0, "{law:?}: {t}");
        assert!(
            value(driving, &taylor.state(t - 1e-12)) <= 0.0,
            "{law:?}: {t}"
        );
        for j in 0..1000 {
            let tau = (t - 1e-12) * f64::from(j) / 1000.0;
            for g in guards.list.iter().flatten() {
                assert!(
                    value(g, &taylor.state(tau)) <= 0.0,
                    "{law:?}: {tau} before {t}"
                );
            }
        }
        // A twist of 1 mrad at 0.5 pu·300 rad/s is crossed in about 6.7 µs.
        assert!((t - 0.001 / 150.0).abs() < 1e-6, "{law:?}: {t}");
        let still = Vec5::new(0.0, 0.0, 1.0, 1.0, 0.0);
        let taylor = Taylor::new(&a, &b, &still, &Vec3::zeros(), h);
        assert_eq!(guards.first_crossing(&taylor, h), None, "{law:?}");
        // At rest with the twist exactly on the driving edge, nothing moving and no
        // current: the guard is zero all along the step, never positive, so no crossing.
        let edge = Vec5::new(m.shaft.g, 0.0, 0.0, 0.0, 0.0);
        let taylor = Taylor::new(&a, &b, &edge, &Vec3::zeros(), h);
        assert_eq!(value(driving, &taylor.state(h)), 0.0, "{law:?}");
        assert_eq!(guards.first_crossing(&taylor, h), None, "{law:?}");
    }
}

/// (value, d/dτ) of a two-part guard's polynomial: the value is the smaller part's, as
/// the state the Taylor series gives makes it, and the derivative is that part's slope
/// (a central difference over ±1e-9 s, to 1e-6 relative), on both sides of the point
/// where the two parts swap.
#[test]
fn guard_poly_gives_the_smaller_part_and_its_slope() {
    let m = model(BacklashModel::Clamped);
    let (a, b) = m.matrices(Contact::Free);
    let guards = Guards::new(Contact::Free, BacklashModel::Clamped, &m.shaft, &a, &b);
    let driving = guards.list[0].as_ref().unwrap();
    // The force part is the smaller at the start (the motor 0.1 pu faster, 1 mrad
    // from the edge), the twist part once the twist has closed to about 0.77 mrad.
    let x0 = Vec5::new(0.003, 0.0, 0.6, 0.5, 0.2);
    let u = Vec3::new(0.5, -0.2, 1.0);
    let h = 1e-4;
    let taylor = Taylor::new(&a, &b, &x0, &u, h);
    let poly = GuardPoly::new(&taylor, driving);
    let mut which = [0, 0];
    for j in 0..=40 {
        let tau = h * f64::from(j) / 40.0;
        let x = taylor.state(tau);
        let parts: Vec<f64> = driving.lins().iter().map(|l| l.value(&x)).collect();
        let (value, slope) = poly.eval(tau);
        let want = parts[0].min(parts[1]);
        assert!(
            (value - want).abs() <= 1e-12 * (1.0 + want.abs()),
            "{tau}: {value} {want}"
        );
        let smaller = usize::from(parts[1] < parts[0]);
        which[smaller] += 1;
        let part = |t: f64| driving.lins()[smaller].value(&taylor.state(t));
        let dt = 1e-9;
        let diff = (part(tau + dt) - part(tau - dt)) / (2.0 * dt);
        assert!(
            (slope - diff).abs() <= 1e-6 * diff.abs().max(1.0),
            "{tau}: {slope} {diff}"
        );
    }
    // Both parts are the smaller one somewhere on the step.
    assert!(which[0] > 0 && which[1] > 0, "{which:?}");
}

/// A search of one guard on many steps (random starts in the gap, speeds and inputs,
/// under both laws): where it finds a time t, the guard's polynomial is positive there
/// and not positive [`TIME_TOL_S`] before it, nor at any of 400 points before; where it
/// finds none, the polynomial is positive at none of 400 points of the step.
#[test]
fn first_crossing_closes_on_the_earliest_positive_time_to_its_tolerance() {
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = |lo: f64, hi: f64| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        lo + (hi - lo) * (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let h = 2e-3;
    let (mut found, mut none) = (0, 0);
    for law in [BacklashModel::DeadZone, BacklashModel::Clamped] {
        let m = model(law);
        let (a, b) = m.matrices(Contact::Free);
        let guards = Guards::new(Contact::Free, law, &m.shaft, &a, &b);
        for _ in 0..300 {
            let g = m.shaft.g;
            let x0 = Vec5::new(
                uniform(-g, g),
                0.0,
                uniform(-1.0, 1.0),
                uniform(-1.0, 1.0),
                uniform(-2.0, 2.0),
            );
            let u = Vec3::new(uniform(-1.0, 1.0), uniform(-1.0, 1.0), 1.0);
            let taylor = Taylor::new(&a, &b, &x0, &u, h);
            for guard in guards.list.iter().flatten() {
                let poly = GuardPoly::new(&taylor, guard);
                let before = |t: f64| (0..400).map(move |j| t * f64::from(j) / 400.0);
                match first_crossing(&taylor, guard, h) {
                    Some(t) => {
                        found += 1;
                        assert!(t > 0.0 && t <= h, "{t}");
                        assert!(poly.eval(t).0 > 0.0, "{law:?} {x0:?} {u:?}: {t}");
                        let early = t - TIME_TOL_S;
                        assert!(poly.eval(early).0 <= 0.0, "{law:?} {x0:?} {u:?}: {t}");
                        for tau in before(early) {
                            assert!(poly.eval(tau).0 <= 0.0, "{law:?} {x0:?}: {tau} < {t}");
                        }
                    }
                    None => {
                        none += 1;
                        for tau in before(h).chain([h]) {
                            assert!(poly.eval(tau).0 <= 0.0, "{law:?} {x0:?}: {tau}");
                        }
                    }
                }
            }
        }
    }
    // The draw gives both outcomes many times.
    assert!(found > 100 && none > 100, "{found} found, {none} none");
}

/// Each rule of the Newton search's next point, on brackets where the rules give
/// different points (all values exact in binary).
#[test]
fn next_point_takes_the_newton_step_inside_the_bracket_and_bisects_otherwise() {
    // The Newton step 0.5 + 0.125/0.5 = 0.75 lies inside (0.5, 2): taken.
    assert_eq!(next_point(0.5, -0.125, 0.5, 0.5, 2.0), 0.75);
    // Zero slope: the midpoint of the bracket, here −1 for (−3, 1).
    assert_eq!(next_point(-3.0, -0.125, 0.0, -3.0, 1.0), -1.0);
    // A step that lands below, on, or above the bracket's ends: the midpoint 1.25.
    assert_eq!(next_point(0.5, 0.5, 0.25, 0.5, 2.0), 1.25); // 0.5 − 2 = −1.5
    assert_eq!(next_point(1.0, 0.5, 1.0, 0.5, 2.0), 1.25); // lands on lo
    assert_eq!(next_point(1.0, -1.0, 1.0, 0.5, 2.0), 1.25); // lands on hi
    assert_eq!(next_point(0.5, -4.0, 1.0, 0.5, 2.0), 1.25); // 4.5, above
    // Converged (the step is below half the tolerance): one tolerance across the root, up
    // where the guard is not positive, down where it is.
    let tol = TIME_TOL_S;
    assert_eq!(next_point(0.5, -1e-20, 1.0, 0.5, 2.0), 0.5 + tol);
    assert_eq!(next_point(0.5, 0.0, 1.0, 0.5, 2.0), 0.5 + tol);
    assert_eq!(next_point(1.0, 1e-20, 1.0, 0.5, 1.0), 1.0 - tol);
    // A step of exactly half the tolerance is not converged: taken as it is.
    assert_eq!(next_point(0.0, -0.5 * tol, 1.0, 0.0, 1.0), 0.5 * tol);
}

/// The cheap test flags a step that crosses an edge and leaves alone one that stays in the
/// middle of the gap (both speeds equal, no current), under both laws: the clamped law's
/// guards have two parts and take the dense test.
#[test]
fn suspect_flags_a_crossing_step_and_not_a_step_in_the_middle_of_the_gap() {
    let h = 1e-4;
    for law in [BacklashModel::DeadZone, BacklashModel::Clamped] {
        let m = model(law);
        let (a, b) = m.matrices(Contact::Free);
        let guards = Guards::new(Contact::Free, law, &m.shaft, &a, &b);
        assert_eq!(guards.short.is_some(), law == BacklashModel::DeadZone);
        let u = Vec3::new(0.5, 0.0, 1.0);
        let middle = Vec5::new(0.0, 0.0, 0.5, 0.5, 0.0);
        let end = Taylor::new(&a, &b, &middle, &u, h).state(h);
        assert!(!guards.suspect(&middle, &end, &u, h), "{law:?}");
        let closing = Vec5::new(0.003, 0.0, 1.0, 0.5, 0.2);
        let end = Taylor::new(&a, &b, &closing, &u, h).state(h);
        assert!(guards.suspect(&closing, &end, &u, h), "{law:?}");
    }
}

/// Two guards crossed in one step, the later-listed one first (the braking edge, then
/// the driving edge after the twist turns round): the earlier time and its mode are
/// taken.
#[test]
fn guards_take_the_earlier_of_two_crossings() {
    for law in [BacklashModel::DeadZone, BacklashModel::Clamped] {
        let m = model(law);
        let (a, b) = m.matrices(Contact::Free);
        let guards = Guards::new(Contact::Free, law, &m.shaft, &a, &b);
        let h = 0.02;
        // 0.1 mrad from the braking edge, closing on it at 0.01 pu, the motor pushed
        // the other way by 0.7 pu of current (the voltage holds it at the start).
        let x0 = Vec5::new(-0.0039, 0.0, 0.0, 0.01, 0.7);
        let u = Vec3::new(0.035, 0.0, 1.0);
        let taylor = Taylor::new(&a, &b, &x0, &u, h);
        let [driving, braking] = [0, 1].map(|i| guards.list[i].as_ref().unwrap());
        let t_drive = first_crossing(&taylor, driving, h).expect("driving edge crossed");
        let t_brake = first_crossing(&taylor, braking, h).expect("braking edge crossed");
        assert!(t_brake < t_drive, "{law:?}: {t_brake} {t_drive}");
        assert_eq!(
            guards.first_crossing(&taylor, h),
            Some((t_brake, Contact::Braking))
        );
    }
}

/// The tangent-line bound of an interior maximum: the two end tangents meet at
/// t = (l1 − l0 − d1·h)/(d0 − d1), clamped to [0, h], at height l0 + d0·t, which must
/// exceed −½·min(|l0|, |l1|) for the step to be searched.
#[test]
fn peak_reaches_zero_takes_the_tangents_meeting_point_with_its_margin() {
    // Tangents meet at t = 0.5, height −1 + 4·0.5 = 1: above the margin.
    assert!(peak_reaches_zero(-1.0, -1.0, 4.0, -4.0, 1.0));
    // Height −1 + 0.5·0.5 = −0.75, below −0.5.
    assert!(!peak_reaches_zero(-1.0, -1.0, 0.5, -0.5, 1.0));
    // Height −1 + 1.5·0.5 = −0.25, above −0.5 though below zero.
    assert!(peak_reaches_zero(-1.0, -1.0, 1.5, -1.5, 1.0));
    // Exactly at the margin: −1 + 1·0.5 = −0.5 is not above it.
    assert!(!peak_reaches_zero(-1.0, -1.0, 1.0, -1.0, 1.0));
    // Unequal ends: t = (−2 + 1 + 1)/(1 + 1) = 0, height −1: the margin is ½·min(1, 2).
    assert!(!peak_reaches_zero(-1.0, -2.0, 1.0, -1.0, 1.0));
    // The step's length enters the meeting point: t = (0 + 3·h)/(1 + 3), so h = 0.5
    // gives t = 0.375 and the height −0.625, not above; h = 1 gives t = 0.75 and
    // −0.25, above.
    assert!(!peak_reaches_zero(-1.0, -1.0, 1.0, -3.0, 0.5));
    assert!(peak_reaches_zero(-1.0, -1.0, 1.0, -3.0, 1.0));
    // h = 2: t = 6/4 = 1.5 within the step, height 0.5.
    assert!(peak_reaches_zero(-1.0, -1.0, 1.0, -3.0, 2.0));
    // The margin scales with the ends: at −4 it is −2, and the height −4 + 5·0.5 = −1.5
    // is above it.
    assert!(peak_reaches_zero(-4.0, -4.0, 5.0, -5.0, 1.0));
}
