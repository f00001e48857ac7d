//! The QEMU board's virtual PMSM (`firmware::virtual_pmsm`, f32, substeps) against
//! plant-host's `PmsmPlant` (f64, Taylor series to round-off) on the same inputs: the same
//! machine file, the same three duties every 250 µs tick (held for the computational delay
//! as sim-engine applies them), the same load torque.
//!
//! Criteria, fixed before the runs: at every tick
//! - i_d, i_q within 2 % of the run's peak current magnitude + 0.005 pu;
//! - the motor and load speeds within 1 % of the run's peak motor speed + 1e-4 pu;
//! - the encoder position within 0.1 % of the travel + 2 counts;
//! - the sampled phase currents a and b within 2 % of the peak + 2 ADC codes.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use firmware::virtual_motor::Coupling;
use firmware::virtual_pmsm::{PmsmMachine, VirtualPmsm, VirtualPmsmConfig};
use plant_host::{PlantConfig, PmsmPlant};

const PERIOD_S: f64 = 250e-6;
const PWM_COUNTS: u16 = 4200;
/// The PWM frequency of 4200 counts up and down at 168 MHz.
const PWM_HZ: f64 = 20e3;

fn plant_config(edit: impl Fn(String) -> String) -> PlantConfig {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../configs/machines/table1-pmsm.toml"
    );
    let text = edit(std::fs::read_to_string(path).unwrap());
    PlantConfig::from_machine_toml(&text).unwrap()
}

/// The machine file's motor, field by field (as `firmware/build.rs` writes it).
fn machine(p: &PlantConfig) -> PmsmMachine {
    let e = &p.electrics;
    PmsmMachine {
        pole_pairs: e.pole_pairs.unwrap(),
        resistance_pu: e.winding_resistance_pu as f32,
        d_inductance_pu_s: e.d_inductance_pu_s.unwrap() as f32,
        q_inductance_pu_s: e.q_inductance_pu_s.unwrap() as f32,
        flux_linkage_pu: e.flux_linkage_pu.unwrap_or(1.0) as f32,
        dc_bus_pu: e.dc_bus_pu.unwrap() as f32,
        encoder_offset_elec_deg: e.encoder_offset_elec_deg.unwrap() as f32,
        encoder_reversed: e.encoder_reversed.unwrap_or(false),
        computational_delay_s: e.computational_delay_s as f32,
        current_adc_bits: e.current_adc_bits,
        current_full_scale_pu: e.current_full_scale_pu as f32,
    }
}

/// The virtual PMSM of a plant config, with its two-inertia coupling.
fn virtual_of(p: &PlantConfig) -> VirtualPmsm {
    let m = &p.mechanics;
    let d = m.derived();
    let coupling = Coupling {
        load_inertia_s: m.load_inertia_s as f32,
        stiffness_pu_per_rad: d.stiffness_pu_per_rad as f32,
        damping_pu: d.damping_pu as f32,
        half_gap_rad: d.half_gap_rad as f32,
        base_speed_rad_s: d.base_speed_rad_s as f32,
        motor_viscous_pu: m.motor_viscous_pu as f32,
        load_viscous_pu: m.load_viscous_pu as f32,
    };
    let config = VirtualPmsmConfig {
        machine: machine(p),
        base_speed_rad_s: d.base_speed_rad_s as f32,
        counts_per_rev: p.counts_per_rev(),
        inertia_s: (m.motor_inertia_s + m.load_inertia_s) as f32,
        period_s: PERIOD_S as f32,
        pwm_period_counts: PWM_COUNTS,
        coupling: None,
    };
    VirtualPmsm::new(config.with_coupling(m.motor_inertia_s as f32, coupling))
}

/// The largest differences of a run, over the tolerances of the module docs (≤ 1 passes).
#[derive(Debug, Default)]
struct Worst {
    current: f64,
    speed: f64,
    position: f64,
    samples: f64,
    peak_current: f64,
    peak_speed: f64,
}

/// What one tick applies: three duties (`None`: the switches open) and the load torque.
type Input = (Option<[u16; 3]>, f64);

/// Runs both plants `ticks` ticks, the inputs from `input(tick, host plant)`; returns the
/// worst differences against the criteria.
fn run(p: &PlantConfig, ticks: u32, input: impl Fn(u32, &PmsmPlant) -> Input) -> Worst {
    let mut host = PmsmPlant::new(p, PWM_HZ).unwrap();
    let mut virt = virtual_of(p);
    let lsb =
        p.electrics.current_full_scale_pu / f64::from(1_u32 << (p.electrics.current_adc_bits - 1));
    let counts_per_rad = f64::from(p.counts_per_rev()) / std::f64::consts::TAU;
    let mut diffs = Vec::new();
    // The command acting now (duties of 1/2 at rest: no voltage).
    let mut held = Some([0.5; 3]);
    for k in 0..ticks {
        let (duties, load) = input(k, &host);
        // As sim-engine: the held command for the delay, then the new one; `None` opens
        // the switches.
        let new = duties.map(|d| d.map(|x| f64::from(x) / f64::from(PWM_COUNTS)));
        let delay = host.computational_delay_s();
        for (dt, command) in [(delay, held), (PERIOD_S - delay, new)] {
            if host.enabled() != command.is_some() {
                host.set_enabled(command.is_some());
            }
            host.try_advance(dt, command.unwrap_or([0.5; 3]), load)
                .unwrap();
        }
        held = new;
        virt.set_load_torque_pu(load as f32);
        virt.step(duties);
        let host_pos = host.motor_pos_rad() * counts_per_rad;
        let host_samples = host.phase_current_samples();
        let virt_samples = virt.phase_current_samples_pu();
        diffs.push([
            (host.i_d_pu() - f64::from(virt.i_d_pu())).abs(),
            (host.i_q_pu() - f64::from(virt.i_q_pu())).abs(),
            (host.motor_vel_pu() - f64::from(virt.speed_pu())).abs(),
            (host.load_vel_pu() - f64::from(virt.load_speed_pu())).abs(),
            (host_pos - f64::from(virt.position_counts())).abs(),
            (host_samples[0] - f64::from(virt_samples[0])).abs(),
            (host_samples[1] - f64::from(virt_samples[1])).abs(),
            host.i_d_pu().hypot(host.i_q_pu()),
            host.motor_vel_pu().abs(),
            host_pos.abs(),
        ]);
    }
    let max = |j: usize| diffs.iter().map(|d| d[j]).fold(0.0, f64::max);
    let (peak_i, peak_w, travel) = (max(7), max(8), max(9));
    Worst {
        current: max(0).max(max(1)) / (0.02 * peak_i + 0.005),
        speed: max(2).max(max(3)) / (0.01 * peak_w + 1e-4),
        position: max(4) / (1e-3 * travel + 2.0),
        samples: max(5).max(max(6)) / (0.02 * peak_i + 2.0 * lsb),
        peak_current: peak_i,
        peak_speed: peak_w,
    }
}

fn assert_within(w: &Worst) {
    eprintln!("{w:?}");
    assert!(
        w.current <= 1.0 && w.speed <= 1.0 && w.position <= 1.0 && w.samples <= 1.0,
        "over the tolerance (ratios > 1 fail): {w:?}"
    );
}

/// The duties of a rotor-frame voltage at the host plant's true angle, advanced to the
/// middle of the time the duties act, quantized to timer counts.
fn duties_at(plant: &PmsmPlant, v_dq: [f64; 2]) -> [u16; 3] {
    let w = plant.motor().electrical_rad_s_per_pu * plant.motor_vel_pu();
    let delay = plant.computational_delay_s();
    let angle = plant.electrical_angle_rad() + w * (delay + 0.5 * PERIOD_S);
    let v_ab = plant_host::inverse_park(v_dq, angle);
    plant
        .inverter()
        .duties_for(v_ab)
        .map(|d| (d * f64::from(PWM_COUNTS)).round() as u16)
}

/// A q voltage ramped up over 0.4 s with a little negative d voltage, a load torque step at
/// 0.35 s, on table1-pmsm.toml (two-inertia coupling with lost motion).
fn ramp(k: u32, plant: &PmsmPlant) -> Input {
    let t = f64::from(k) * PERIOD_S;
    let v_q = 0.5 * (t / 0.4).min(1.0);
    let load = if t >= 0.35 { 0.3 } else { 0.0 };
    (Some(duties_at(plant, [-0.05, v_q])), load)
}

#[test]
fn field_oriented_voltage_ramp_with_a_load_step_matches_the_host_plant() {
    let p = plant_config(|t| t);
    let w = run(&p, 2400, ramp);
    assert!(w.peak_speed > 0.3 && w.peak_current > 0.5, "{w:?}");
    assert_within(&w);
}

#[test]
fn a_salient_motor_with_another_offset_and_pole_count_matches_the_host_plant() {
    let p = plant_config(|t| {
        t.replace("pole_pairs = 4 ", "pole_pairs = 3 ")
            .replace("d_inductance_pu_s = 5e-4", "d_inductance_pu_s = 4e-4")
            .replace("q_inductance_pu_s = 5e-4", "q_inductance_pu_s = 7e-4")
            .replace(
                "encoder_offset_elec_deg = 23.0   #",
                "encoder_offset_elec_deg = 137.0  #",
            )
    });
    assert_eq!(p.electrics.pole_pairs, Some(3));
    assert_eq!(p.electrics.encoder_offset_elec_deg, Some(137.0));
    // A negative d voltage: i_d ≠ 0, so the reluctance torque counts.
    let w = run(&p, 2400, |k, plant| {
        let t = f64::from(k) * PERIOD_S;
        (
            Some(duties_at(plant, [-0.3, 0.6 * (t / 0.4).min(1.0)])),
            0.0,
        )
    });
    assert!(w.peak_speed > 0.3, "{w:?}");
    assert_within(&w);
}

#[test]
fn the_bus_limit_and_the_open_inverter_match_the_host_plant() {
    let p = plant_config(|t| t);
    // Phase a high, b and c low (beyond the linear range: the hexagon's corner) for 20 ms,
    // then a voltage the field-oriented way, then the switches open while it coasts.
    let w = run(&p, 1600, |k, plant| match k {
        0..80 => (Some([PWM_COUNTS, 0, 0]), 0.0),
        80..1000 => (Some(duties_at(plant, [0.0, 0.4])), 0.0),
        _ => (None, 0.1),
    });
    assert!(w.peak_current > 1.0, "{w:?}");
    assert_within(&w);
}

#[test]
fn the_open_inverter_holds_the_currents_at_zero_and_the_counter_wraps() {
    let p = plant_config(|t| t);
    let mut m = virtual_of(&p).with_counts(u32::MAX - 2);
    for _ in 0..400 {
        m.step(Some([1000, 3200, 2100]));
    }
    assert!(m.i_d_pu().hypot(m.i_q_pu()) > 0.1);
    // The switches open: after the delay the currents are zero and stay there.
    m.step(None);
    assert_eq!((m.i_d_pu(), m.i_q_pu()), (0.0, 0.0));
    assert_eq!(m.phase_current_codes(), [0, 0]);
    // The preset near the wrap: the counter wraps, the angle follows the signed count.
    let before = m.counts();
    for _ in 0..2000 {
        m.step(Some([3000, 1600, 1700]));
    }
    let moved = m.counts().wrapping_sub(before) as i32;
    assert!(moved.unsigned_abs() > 10, "moved {moved}");
    let angle = m.electrical_angle_rad();
    let offset = 23_f32.to_radians();
    assert!((offset..offset + std::f32::consts::TAU).contains(&angle));
}
