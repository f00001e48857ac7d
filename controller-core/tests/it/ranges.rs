//! The range arguments behind the plain (wrapping) adds of the tick path, checked against
//! the saturating arithmetic they replaced: inside the ranges the code states, the results
//! are the same bits. Outside them (hand-made states or coefficients) the last tests pin
//! what the code does instead: the first-order state limited to ±2^48, and the saturating
//! add for an α outside [0, 1].
#![allow(clippy::unwrap_used, clippy::indexing_slicing)]

use controller_core::filter::{LowPass, LowPassState};
use controller_core::observer::{Observer, ObserverState};
use controller_core::per_unit::{Coef, Gain, Pu, TickGain};
use proptest::prelude::*;

fn sat32(x: i64) -> i32 {
    x.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

/// The observer step with every add of the estimates saturating.
fn observer_reference(o: &Observer, s: &mut ObserverState, position: i64, torque: Pu) {
    let p_meas = position.wrapping_shl(32);
    let u = (i64::from(torque.to_bits()) * i64::from(o.k_u.to_bits())) >> 8;
    let acc = u.saturating_add(s.d);
    let p_pred = s.p.wrapping_add(s.v).wrapping_add(acc >> 1);
    let v_pred = s.v.saturating_add(acc);
    let e = sat32(p_meas.wrapping_sub(p_pred) >> 16);
    let corr = |l: Coef| (i64::from(e) * i64::from(l.to_bits())) >> 14;
    let dv = corr(o.l2);
    s.p = p_pred.wrapping_add(corr(o.l1));
    s.v = v_pred.saturating_add(dv);
    s.residual = s.d.saturating_add(dv);
    s.acc = u.saturating_add(s.residual);
    s.d = s.d.saturating_add(corr(o.l3));
}

/// The first-order filter step with saturating adds.
fn first_order_reference(alpha: Coef, s: &mut LowPassState, x: Pu) -> Pu {
    let y = s.y_q32.clamp(-(1 << 48), 1 << 48);
    let y16 = sat32(y >> 16);
    let h = (y << 14) - i64::from(y16) * i64::from(alpha.to_bits());
    let y46 = h.saturating_add(i64::from(x.to_bits()) * i64::from(alpha.to_bits()));
    s.y_q32 = y46 >> 14;
    Pu::from_bits(sat32(s.y_q32.saturating_add(1 << 15) >> 16))
}

const STATE: std::ops::Range<i64> = -(1 << 60)..(1 << 60);

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn observer_matches_saturating_arithmetic_inside_its_ranges(
        l in proptest::array::uniform3(0i32..=i32::MAX),
        k_u: i32, p: i64, v in STATE, d in STATE, position: i64, torque: i32,
        steps in proptest::collection::vec((any::<i64>(), any::<i32>()), 1..20),
    ) {
        let o = Observer {
            l1: Coef::from_bits(l[0]), l2: Coef::from_bits(l[1]), l3: Coef::from_bits(l[2]),
            k_u: TickGain::from_bits(k_u), k_vel: TickGain::ONE, k_acc: Gain::ONE,
            k_load: Gain::ONE,
            count_interval: controller_core::observer::CountInterval::PLAIN,
        };
        let mut s = ObserverState { p, v, d, primed: true, ..ObserverState::default() };
        let mut r = s;
        o.update(&mut s, position, Pu::from_bits(torque));
        observer_reference(&o, &mut r, position, Pu::from_bits(torque));
        prop_assert_eq!(s, r);
        // Further steps from there, while the states stay in range.
        for (position, torque) in steps {
            if !(STATE.contains(&s.v) && STATE.contains(&s.d)) {
                break;
            }
            o.update(&mut s, position, Pu::from_bits(torque));
            observer_reference(&o, &mut r, position, Pu::from_bits(torque));
            prop_assert_eq!(s, r);
        }
    }

    #[test]
    fn first_order_filter_matches_saturating_arithmetic_for_alpha_in_0_1(
        alpha in 0i32..=(1 << 30), y in -(3i64 << 47)..(3i64 << 47),
        xs in proptest::collection::vec(any::<i32>(), 1..20),
    ) {
        let f = LowPass::FirstOrder { alpha: Coef::from_bits(alpha) };
        let mut s = LowPassState { y_q32: y, ..LowPassState::default() };
        let mut r = s;
        for x in xs {
            let out = f.process(&mut s, Pu::from_bits(x));
            let reference = first_order_reference(Coef::from_bits(alpha), &mut r, Pu::from_bits(x));
            prop_assert_eq!(out, reference);
            prop_assert_eq!(s, r);
        }
    }
}

/// `begin` on a first-order state of `y_q32` (Q32.32).
fn first_order_h(f: &LowPass, y_q32: i64) -> i64 {
    f.begin(&LowPassState {
        y_q32,
        ..LowPassState::default()
    })
    .0
}

/// A first-order state beyond ±2^48 (which only a hand-set state or a hand-made α reaches)
/// steps as the state at ±2^48: `begin` limits it before it shifts it to Q.46, whatever its
/// low bits. At +2^48 the Q16.16 state is saturated (2^31 − 1), so h = 2^62 − α·(2^31 − 1).
#[test]
fn first_order_state_beyond_2_48_steps_as_the_state_at_2_48() {
    let f = LowPass::FirstOrder {
        alpha: Coef::from_num(0.5),
    };
    let top = first_order_h(&f, 1 << 48);
    assert_eq!(top, (1 << 62) - ((1 << 31) - 1) * (1 << 29));
    let bottom = first_order_h(&f, -(1 << 48));
    assert_eq!(bottom, -(1 << 62) + (1 << 31) * (1 << 29));
    // Beyond the limit by whole Q16.16 steps (low 16 bits zero), by odd amounts, and at
    // the ends of i64.
    for beyond in [
        1 << 16,
        1 << 46,
        (1 << 47) + (1 << 16),
        1,
        12_345,
        i64::MAX - (1 << 48),
    ] {
        assert_eq!(
            first_order_h(&f, (1 << 48) + beyond),
            top,
            "+2^48 + {beyond}"
        );
        assert_eq!(
            first_order_h(&f, -(1 << 48) - beyond),
            bottom,
            "-2^48 - {beyond}"
        );
    }
    assert_eq!(first_order_h(&f, i64::MIN), bottom);
}

/// A hand-made α outside [0, 1] takes the saturating add: where h + α·x leaves i64, the
/// output goes to the limit of the sum's sign instead of wrapping round to the other one.
/// α = −2 (raw i32::MIN) at the state +2^48 gives h = 2^63 − 2^31, and x = −32768 pu adds
/// α·x = 2^62 (Q.46); mirrored, the state −2^48 gives h = −2^63 and x = 32768 pu − 1 LSB
/// adds −2^62 + 2^31.
#[test]
fn first_order_with_alpha_outside_0_1_saturates_instead_of_wrapping() {
    let f = LowPass::FirstOrder {
        alpha: Coef::from_bits(i32::MIN),
    };
    for (y_q32, x, h, sum, out) in [
        (
            1i64 << 48,
            Pu::MIN,
            i64::MAX - (1 << 31) + 1,
            i64::MAX,
            Pu::MAX,
        ),
        (-(1i64 << 48), Pu::MAX, i64::MIN, i64::MIN, Pu::MIN),
    ] {
        let mut s = LowPassState {
            y_q32,
            ..LowPassState::default()
        };
        assert_eq!(first_order_h(&f, y_q32), h);
        assert_eq!(f.add_feedthrough(h, x), sum);
        assert_eq!(f.process(&mut s, x), out);
        assert_eq!(s.y_q32, sum >> 14);
    }
}
