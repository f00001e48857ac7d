//! The range arguments behind the plain (wrapping) adds of the tick path, checked against
//! the saturating arithmetic they replaced: inside the ranges the code states, the results
//! are the same bits. (Outside them only hand-made states or coefficients differ.)
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
