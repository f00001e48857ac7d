//! The three-phase board layer's arithmetic (`firmware::board::three_phase`) against
//! independent f64 arithmetic from the table's physical values: the three duties of a
//! voltage vector, the phase currents of two ADC readings, the bus voltage, the offsets,
//! the current loop's PWM periods per tick and the dead-time code. Criteria: a duty within
//! 1 count of the f64 modulator, a current or voltage within 1e-4 pu of the f64 scaling.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use controller_core::foc::{AlphaBeta, Svpwm};
use controller_core::per_unit::Pu;
use firmware::board::three_phase::{
    bus_voltage_pu, current_offset, dead_time_dtg, duties_for_voltage, periods_per_tick,
    phase_currents_pu, repetition_counter, AdcScale, OffsetError, IHM08M1,
};

/// Min-max injection in f64: the duties of (α, β) on a bus `bus` over `period` counts.
fn duties_f64(alpha: f64, beta: f64, bus: f64, period: f64) -> [f64; 3] {
    let s = 3_f64.sqrt() / 2.0;
    let v = [alpha, -alpha / 2.0 + s * beta, -alpha / 2.0 - s * beta];
    let zero = -(v.iter().copied().fold(f64::MIN, f64::max)
        + v.iter().copied().fold(f64::MAX, f64::min))
        / 2.0;
    v.map(|x| (period * (0.5 + (x + zero) / bus)).clamp(0.0, period))
}

#[test]
fn three_duties_for_a_voltage_vector() {
    let m = Svpwm::new(2.0, 4200).unwrap();
    // α = 0.5 pu on a 2 pu bus: phases at +0.375, −0.375, −0.375 pu after the injection,
    // so 4200·(1/2 ± 0.1875) counts.
    let v = AlphaBeta {
        alpha: Pu::from_num(0.5),
        beta: Pu::ZERO,
    };
    assert_eq!(duties_for_voltage(&m, v), [2888, 1313, 1313]);
    assert_eq!(duties_for_voltage(&m, AlphaBeta::default()), [2100; 3]);
    // Vectors all round the linear circle (|v| ≤ 2/√3): within a count of f64, inside
    // [0, period], centred on half the period (the zero sequence).
    let radius = 2.0 / 3_f64.sqrt();
    for k in 0..720 {
        let angle = f64::from(k) * core::f64::consts::TAU / 720.0;
        let size = radius * f64::from(k % 10 + 1) / 10.0;
        let (alpha, beta) = (size * angle.cos(), size * angle.sin());
        let v = AlphaBeta {
            alpha: Pu::from_num(alpha),
            beta: Pu::from_num(beta),
        };
        let got = duties_for_voltage(&m, v);
        let want = duties_f64(alpha, beta, 2.0, 4200.0);
        for (g, w) in got.iter().zip(want) {
            assert!(
                (f64::from(*g) - w).abs() <= 1.0,
                "({alpha}, {beta}): {got:?} against {want:?}"
            );
            assert!(*g <= 4200);
        }
        let max = *got.iter().max().unwrap();
        let min = *got.iter().min().unwrap();
        assert!(
            (i32::from(max) + i32::from(min) - 4200).abs() <= 2,
            "{got:?} not centred"
        );
    }
}

#[test]
fn phase_currents_from_two_adc_readings() {
    let b = IHM08M1;
    let scale = AdcScale::current(&b);
    // f64: amperes per count = 3.3 V / 4096 / (10 mΩ · 5.18), a positive current lowers
    // the reading (low-side shunt), per unit of the 5 A base.
    let pu_per_count = 3.3 / 4096.0 / (0.010 * 5.18) / 5.0;
    let offset = [2050_u16, 2040];
    for (raw, want) in [
        ([2050_u16, 2040_u16], [0.0, 0.0]),
        (
            [2050 - 321, 2040 + 643],
            [321.0 * pu_per_count, -643.0 * pu_per_count],
        ),
        ([0, 4095], [2050.0 * pu_per_count, -2055.0 * pu_per_count]),
    ] {
        let got = phase_currents_pu(raw, offset, scale);
        for (g, w) in got.iter().zip(want) {
            assert!(
                (g.to_num::<f64>() - w).abs() < 1e-4,
                "{raw:?}: {got:?} against {want:?}"
            );
        }
    }
    // About one pu is 321.5 counts: 321 counts below the offset read just under 1 pu.
    let one = phase_currents_pu([2050 - 321, 2040], offset, scale)[0];
    assert!(one > Pu::from_num(0.99) && one < Pu::ONE, "{one}");
}

#[test]
fn bus_voltage_from_its_reading() {
    let scale = AdcScale::bus(&IHM08M1);
    // 24 V through 169 kΩ / 9.31 kΩ: 1.2531 V, 1555.4 counts; 2 pu of the 12 V base.
    let volts_per_count = 3.3 / 4096.0 * (169_000.0 + 9_310.0) / 9_310.0;
    for raw in [0_u16, 1555, 4095] {
        let want = f64::from(raw) * volts_per_count / 12.0;
        let got = bus_voltage_pu(raw, scale).to_num::<f64>();
        assert!((got - want).abs() < 1e-4, "{raw}: {got} against {want}");
    }
    assert!((bus_voltage_pu(1555, scale).to_num::<f64>() - 2.0).abs() < 0.002);
}

#[test]
fn offsets_are_averaged_and_checked() {
    assert_eq!(current_offset(0, 2048 * 64 + 40, 64, 12), Ok(2049));
    assert_eq!(
        current_offset(1, 1800 * 16, 16, 12),
        Err(OffsetError {
            phase: 1,
            counts: 1800
        }),
        "248 counts off mid-scale: no amplifier, or current flowing"
    );
    assert!(current_offset(0, 0, 0, 12).is_err(), "no readings");
}

#[test]
fn the_current_loop_runs_on_every_kth_pwm_period() {
    // 168 MHz, 4200 counts up and down: 20 kHz; a 4 kHz loop every 5th period.
    assert_eq!(periods_per_tick(168_000_000, 4200, 4000), Ok(5));
    assert_eq!(periods_per_tick(168_000_000, 4200, 20_000), Ok(1));
    assert_eq!(repetition_counter(5), 9);
    assert_eq!(repetition_counter(1), 1);
    // 20 kHz / 3 kHz is not whole; nor is a loop faster than the PWM; k = 160 > 128.
    let err = periods_per_tick(168_000_000, 4200, 3000).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("drive.current_rate_hz = 3000")
            && text.contains("20000 Hz")
            && text.contains("drive.pmsm.pwm_period_counts = 4200"),
        "{text}"
    );
    assert!(periods_per_tick(168_000_000, 4200, 40_000).is_err());
    assert!(periods_per_tick(168_000_000, 4200, 125).is_err());
    assert!(periods_per_tick(168_000_000, 0, 4000).is_err());
}

#[test]
fn dead_time_codes_are_never_shorter_than_asked() {
    let t = 1e9 / 168e6; // ns per clock
    let decode = |dtg: u8| -> f64 {
        let d = f64::from(dtg);
        match dtg {
            0..=0x7F => d * t,
            0x80..=0xBF => (64.0 + f64::from(dtg & 0x3F)) * 2.0 * t,
            0xC0..=0xDF => (32.0 + f64::from(dtg & 0x1F)) * 8.0 * t,
            _ => (32.0 + f64::from(dtg & 0x1F)) * 16.0 * t,
        }
    };
    assert_eq!(dead_time_dtg(500, 168_000_000), 84);
    for ns in (0..=5_900).step_by(7) {
        let dtg = dead_time_dtg(ns, 168_000_000);
        let got = decode(dtg);
        assert!(
            got >= f64::from(ns) - 1e-9,
            "{ns} ns: code {dtg:#x} gives {got}"
        );
        // The next shorter code of the same range would be too short (tightest step 16 t).
        assert!(
            got - f64::from(ns) < 16.0 * t,
            "{ns} ns: code {dtg:#x} gives {got}"
        );
    }
}
