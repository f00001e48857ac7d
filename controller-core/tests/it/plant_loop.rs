//! The real fixed-point `Controller` closed around plant-host's `TwoInertiaPlant` (the paper's
//! Fig. 3 with lost motion, the RL winding with back-EMF, the 0.18 ms computational delay and the
//! current ADC; `plant-host/README.md`), with the judging of `accel_loop` and `afb_design`.
//! The linear model of the loop (`loop-model/`, used by `afb_loop`)
//! cannot run what these runs decide on: the lost motion's transitions, the encoder and ADC
//! quantization, the fixed-point clamps and the fault checks.
#![allow(
    dead_code,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use controller_core::{Controller, CurrentInputs, DriveConfig, Profile, Pu, VelocityInputs};
use plant_host::{PlantConfig, TwoInertiaPlant};

// The run's summary and the scenarios are the hand-written loop's (`sim`), so both plants
// are judged alike.
pub use super::sim::{RunSummary, Scenario};

/// The paper's Fig. 6 scenario: ramp to 1 pu in 1 s, hold; 50 % load step at 1.5 s.
/// Judged over [1.7 s, end). The plant's computational delay between sampling and applying.
pub fn run_fig6(cfg: &DriveConfig, plant: &PlantConfig, end_s: f64) -> RunSummary {
    let mut ctl = Controller::new(cfg).expect("config");
    run_scenario(&mut ctl, cfg, plant, &Scenario::fig6(end_s))
}

pub fn run_scenario(
    ctl: &mut Controller,
    cfg: &DriveConfig,
    plant: &PlantConfig,
    sc: &Scenario,
) -> RunSummary {
    let end_s = sc.end_s;
    let mut profile = Profile::new(&sc.profile, cfg).expect("profile");
    let ts = 1.0 / f64::from(cfg.current_rate_hz);
    let ratio = cfg.current_rate_hz / cfg.velocity_rate_hz;
    let mask: u64 = if cfg.counter_bits >= 32 {
        u64::from(u32::MAX)
    } else {
        (1u64 << cfg.counter_bits) - 1
    };
    // The encoder the drive is configured for (a test may change the drive's CPR).
    let mut plant = *plant;
    plant.mechanics.encoder_cpr = cfg.encoder_cpr;
    let mut x = TwoInertiaPlant::voltage_driven(&plant);
    let n_ticks = (end_s / ts) as u64;
    let judge_from = (sc.judge_from_s / ts) as u64;
    let limit = f64::from(cfg.torque_limit_pu);
    let (mut sq, mut n, mut at_limit) = (0.0f64, 0u64, 0u64);
    let (mut tmin, mut tmax) = (f64::MAX, f64::MIN);
    let mut faulted = false;
    let mut max_ls = 0.0f64;
    let mut v_cmd_now = 0.0f64;
    let avg_len = ((0.01 / ts) as usize).max(1);
    let mut hist: std::collections::VecDeque<f64> = std::collections::VecDeque::new();
    let mut hist_sum = 0.0f64;
    let (mut rip_sq, mut rip_n, mut lsq) = (0.0f64, 0u64, 0.0f64);
    let mut dip = 0.0f64;
    // Motor speed at the start of the last two current ticks (true mean accelerations).
    let (mut w_prev, mut w_prev2) = (0.0f64, 0.0f64);
    let (mut aerr_sq, mut aerr_n) = (0.0f64, 0u64);
    for k in 0..n_ticks {
        let t = k as f64 * ts;
        let counts = x.encoder_count();
        let raw = (counts as u64 & mask) as u32;
        if k % u64::from(ratio) == 0 {
            let sp = profile.next();
            v_cmd_now = sp.velocity_pu.to_num::<f64>();
            let out = ctl.velocity_tick(VelocityInputs {
                encoder_count: raw,
                setpoint: sp,
                fault_input: false,
            });
            faulted |= out.fault.is_some();
            // The velocity tick reads the observer of the last current tick (k − 1), whose
            // estimate covers the tick from k − 2 to k − 1.
            if k >= judge_from.max(2) {
                let a_true = (w_prev - w_prev2) / ts;
                let ea = out.acceleration_est_pu_s.to_num::<f64>() - a_true;
                aerr_sq += ea * ea;
                aerr_n += 1;
            }
        }
        w_prev2 = w_prev;
        w_prev = x.motor_vel_pu();
        let out = ctl.current_tick(CurrentInputs {
            encoder_count: raw,
            current_pu: Pu::saturating_from_num(x.current_sample()),
        });
        faulted |= out.fault.is_some();
        let v = out.voltage_cmd_pu.to_num::<f64>();
        let tl = if t >= sc.load_step_s { sc.load_pu } else { 0.0 };
        x.advance_period(ts, v, tl).expect("finite voltage");
        if t >= sc.load_step_s && t < sc.load_step_s + 0.3 {
            dip = dip.max((x.motor_vel_pu() - v_cmd_now).abs());
        }
        if k >= judge_from {
            let e = x.motor_vel_pu() - v_cmd_now;
            sq += e * e;
            n += 1;
            let iref = out.current_ref_pu.to_num::<f64>();
            tmin = tmin.min(iref);
            tmax = tmax.max(iref);
            if iref.abs() >= limit * 0.999 {
                at_limit += 1;
            }
            max_ls = max_ls.max((x.load_vel_pu() - x.motor_vel_pu()).abs());
            let el = x.load_vel_pu() - v_cmd_now;
            lsq += el * el;
            hist.push_back(iref);
            hist_sum += iref;
            if hist.len() > avg_len {
                hist_sum -= hist.pop_front().unwrap_or(0.0);
            }
            if hist.len() == avg_len {
                let r = iref - hist_sum / avg_len as f64;
                rip_sq += r * r;
                rip_n += 1;
            }
        }
    }
    let nf = n.max(1) as f64;
    RunSummary {
        speed_err_rms_pu: (sq / nf).sqrt(),
        torque_p2p_pu: tmax - tmin,
        limit_fraction: at_limit as f64 / nf,
        faulted,
        max_load_speed_err_pu: max_ls,
        torque_ripple_rms_pu: (rip_sq / rip_n.max(1) as f64).sqrt(),
        load_speed_err_rms_pu: (lsq / nf).sqrt(),
        speed_dip_pu: dip,
        accel_est_err_rms_pu_s: (aerr_sq / aerr_n.max(1) as f64).sqrt(),
    }
}
