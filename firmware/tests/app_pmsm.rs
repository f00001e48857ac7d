//! The App's PMSM current tick on the host, with a mock three-phase board: the reference
//! PMSM drive (`configs/machines/table1-pmsm.toml`, baked by `build.rs`), its enable logic,
//! a missing sample and a refused write, and that the interrupt body runs the very tick
//! `step_pmsm` runs.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use controller_core::{Fault, PmsmInputs, Pu, Setpoint};
use firmware::app::{velocity_inputs, App, AppError, DEFAULT_TRACE};
use firmware::board::three_phase::PmsmLoopIo;
use firmware::board::VelocityLoopIo;

#[derive(Default)]
struct MockStage {
    encoder: u32,
    currents: Option<[Pu; 2]>,
    fault_input: bool,
    duties: [u16; 3],
    enabled: bool,
    refuse: bool,
}

impl PmsmLoopIo for MockStage {
    fn encoder_count(&mut self) -> u32 {
        self.encoder
    }
    fn phase_currents_pu(&mut self) -> Option<[Pu; 2]> {
        self.currents
    }
    fn set_duties(&mut self, duties: [u16; 3]) -> bool {
        self.duties = duties;
        !self.refuse
    }
    fn set_enable(&mut self, enabled: bool) -> bool {
        self.enabled = enabled;
        true
    }
    fn fault_input(&mut self) -> bool {
        self.fault_input
    }
}

impl VelocityLoopIo for MockStage {
    fn encoder_count(&mut self) -> u32 {
        self.encoder
    }
    fn fault_input(&mut self) -> bool {
        self.fault_input
    }
}

fn pmsm_app() -> App {
    let cfg = firmware::drive::reference_pmsm().unwrap();
    App::new_pmsm(&cfg, cfg.counter_bits, DEFAULT_TRACE).unwrap()
}

/// Half the reference drive's PWM period: the duties of 0 V.
fn half() -> u16 {
    let cfg = firmware::drive::reference_pmsm().unwrap();
    cfg.pmsm.unwrap().pwm_period_counts / 2
}

fn period(app: &mut App, io: &mut MockStage, k: u32, sp: &mut Setpoint) {
    app.on_pmsm_tick(io);
    if k % 2 == 1 {
        app.on_velocity_tick(velocity_inputs(io, sp));
    }
}

#[test]
fn each_constructor_takes_its_own_motor_only() {
    let pmsm = firmware::drive::reference_pmsm().unwrap();
    let dc = firmware::drive::baked().unwrap();
    let unsupported = Some(AppError::Settings(pil_link::LinkError::UnsupportedMotor));
    if dc.pmsm.is_none() {
        assert_eq!(
            App::new_pmsm(&dc, dc.counter_bits, DEFAULT_TRACE).err(),
            unsupported
        );
        assert!(!App::new(&dc, dc.counter_bits, DEFAULT_TRACE)
            .unwrap()
            .is_pmsm());
    }
    assert_eq!(
        App::new(&pmsm, pmsm.counter_bits, DEFAULT_TRACE).err(),
        unsupported
    );
    let app = pmsm_app();
    assert!(app.is_pmsm());
    assert_eq!(app.zero_voltage_duties(), [half(); 3]);
    // The core's refusal of an unmeasured encoder offset reaches the caller.
    let mut unmeasured = pmsm;
    if let Some(p) = unmeasured.pmsm.as_mut() {
        p.encoder_offset_elec_deg = None;
    }
    assert!(matches!(
        App::new_pmsm(&unmeasured, unmeasured.counter_bits, DEFAULT_TRACE),
        Err(AppError::Config(_))
    ));
}

#[test]
fn the_stage_switches_only_on_request_and_runs_the_cores_pmsm_tick() {
    let mut app = pmsm_app();
    let mut twin = pmsm_app();
    let mut io = MockStage {
        currents: Some([Pu::from_num(0.1), Pu::from_num(-0.05)]),
        duties: [1; 3],
        ..MockStage::default()
    };
    let mut sp = Setpoint {
        position_counts: controller_core::Counts::from_num(100),
        ..Setpoint::default()
    };
    for k in 0..20 {
        period(&mut app, &mut io, k, &mut sp);
    }
    assert!(!io.enabled, "no enable request yet");
    assert_eq!(io.duties, [half(); 3], "0 V while held");
    assert!(app.is_held());

    app.set_enable_request(true);
    twin.set_enable_request(true);
    let mut moved = false;
    for k in 20..60 {
        io.encoder = k;
        let out = app.on_pmsm_tick(&mut io);
        // The interrupt body runs the board-less step's tick, bit for bit.
        let inputs = PmsmInputs {
            encoder_count: k,
            phase_current_pu: io.currents.unwrap(),
        };
        assert_eq!(out, twin.step_pmsm(inputs), "tick {k}");
        assert!(out.enabled && io.enabled);
        assert_eq!(io.duties, out.duties);
        moved |= out.duties != [half(); 3];
        if k % 2 == 1 {
            let a = app.on_velocity_tick(velocity_inputs(&mut io, &mut sp));
            let b = twin.step_velocity(velocity_inputs(&mut io, &mut sp));
            assert_eq!(a, b, "velocity tick {k}");
        }
    }
    assert!(moved, "the regulators commanded a voltage");

    io.fault_input = true;
    for k in 60..64 {
        period(&mut app, &mut io, k, &mut sp);
    }
    assert_eq!(app.fault(), Some(Fault::External));
    assert!(!io.enabled);
    assert_eq!(io.duties, [half(); 3]);
    assert!(app.fault_record().is_some());
}

#[test]
fn a_missing_sample_or_a_refused_write_turns_the_stage_off_and_latches() {
    for refuse in [false, true] {
        let mut app = pmsm_app();
        app.set_enable_request(true);
        let mut io = MockStage {
            currents: Some([Pu::ZERO; 2]),
            ..MockStage::default()
        };
        let mut sp = Setpoint::default();
        for k in 0..10 {
            period(&mut app, &mut io, k, &mut sp);
        }
        assert!(io.enabled);
        if refuse {
            io.refuse = true;
            period(&mut app, &mut io, 10, &mut sp);
            io.refuse = false;
        } else {
            io.currents = None;
            period(&mut app, &mut io, 10, &mut sp);
            assert!(!io.enabled, "stage off in the same tick");
            io.currents = Some([Pu::ZERO; 2]);
        }
        period(&mut app, &mut io, 11, &mut sp);
        assert_eq!(
            app.fault(),
            Some(Fault::External),
            "refused write: {refuse}"
        );
        period(&mut app, &mut io, 12, &mut sp);
        assert!(!io.enabled);
        assert_eq!(io.duties, [half(); 3]);
    }
}
