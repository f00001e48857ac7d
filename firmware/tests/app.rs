//! The App's interrupt bodies on the host, with a mock board: enable logic, fault and
//! sensor-fault handling, dump requests through the trend buffer.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use controller_core::{Fault, Pu, Setpoint};
use firmware::app::{velocity_inputs, App, AppError, DEFAULT_TRACE};
use firmware::board::{CurrentLoopIo, VelocityLoopIo};
use firmware::trace::{TraceState, TriggerCause};

#[derive(Default)]
struct MockIo {
    encoder: u32,
    current: Option<Pu>,
    fault_input: bool,
    voltage: Pu,
    enabled: bool,
    refuse_pwm: bool,
}

impl CurrentLoopIo for MockIo {
    fn encoder_count(&mut self) -> u32 {
        self.encoder
    }
    fn current_pu(&mut self) -> Option<Pu> {
        self.current
    }
    fn set_voltage_pu(&mut self, voltage_pu: Pu) -> bool {
        self.voltage = voltage_pu;
        !self.refuse_pwm
    }
    fn set_enable(&mut self, enabled: bool) -> bool {
        self.enabled = enabled;
        true
    }
}

impl VelocityLoopIo for MockIo {
    fn encoder_count(&mut self) -> u32 {
        self.encoder
    }
    fn fault_input(&mut self) -> bool {
        self.fault_input
    }
}

fn app() -> App {
    let cfg = firmware::drive::baked().unwrap();
    App::new(&cfg, cfg.counter_bits, DEFAULT_TRACE).unwrap()
}

/// One 4 kHz period as the interrupts run it (velocity tick on odd periods).
fn period(app: &mut App, io: &mut MockIo, k: u32, setpoint: &mut Setpoint) {
    app.on_current_tick(io);
    if k % 2 == 1 {
        app.on_velocity_tick(velocity_inputs(io, setpoint));
    }
}

#[test]
fn rejects_a_board_with_the_wrong_counter_width() {
    let cfg = firmware::drive::baked().unwrap();
    assert_eq!(
        App::new(&cfg, 32, DEFAULT_TRACE).err(),
        Some(AppError::CounterBits {
            board: 32,
            config: 16
        })
    );
}

#[test]
fn stage_is_enabled_only_on_request_and_without_fault() {
    let mut app = app();
    let mut io = MockIo {
        current: Some(Pu::ZERO),
        ..MockIo::default()
    };
    // A held setpoint 100 counts ahead: the regulators command a voltage.
    let mut sp = Setpoint {
        position_counts: controller_core::Counts::from_num(100),
        ..Setpoint::default()
    };
    for k in 0..20 {
        period(&mut app, &mut io, k, &mut sp);
    }
    assert!(!io.enabled, "no enable request yet");
    assert_eq!(io.voltage, Pu::ZERO, "0 V while disabled");

    app.set_enable_request(true);
    for k in 20..40 {
        period(&mut app, &mut io, k, &mut sp);
    }
    assert!(io.enabled);
    assert_ne!(io.voltage, Pu::ZERO);

    io.fault_input = true;
    for k in 40..44 {
        period(&mut app, &mut io, k, &mut sp);
    }
    assert_eq!(app.fault(), Some(Fault::External));
    assert!(!io.enabled);
    assert_eq!(io.voltage, Pu::ZERO);
    // A fault triggers the trend buffer.
    assert!(matches!(
        app.trace().state(),
        TraceState::PostTrigger {
            cause: TriggerCause::Fault,
            ..
        }
    ));

    // Latched until reset, even with the input gone.
    io.fault_input = false;
    for k in 44..50 {
        period(&mut app, &mut io, k, &mut sp);
    }
    assert!(!io.enabled);
    app.reset();
    for k in 50..52 {
        period(&mut app, &mut io, k, &mut sp);
    }
    assert_eq!(app.fault(), None);
    assert!(io.enabled);
}

#[test]
fn a_failed_current_sample_latches_an_external_fault() {
    let mut app = app();
    app.set_enable_request(true);
    let mut io = MockIo {
        current: Some(Pu::ZERO),
        ..MockIo::default()
    };
    let mut sp = Setpoint::default();
    for k in 0..10 {
        period(&mut app, &mut io, k, &mut sp);
    }
    assert!(io.enabled);
    io.current = None; // the ADC produced no conversion
    period(&mut app, &mut io, 10, &mut sp);
    assert!(!io.enabled, "stage off in the same tick");
    period(&mut app, &mut io, 11, &mut sp);
    assert_eq!(app.fault(), Some(Fault::External));
    // The sensor recovering does not re-enable: the fault is latched.
    io.current = Some(Pu::ZERO);
    period(&mut app, &mut io, 12, &mut sp);
    assert!(!io.enabled);
}

#[test]
fn a_refused_pwm_write_is_a_fault_too() {
    let mut app = app();
    app.set_enable_request(true);
    let mut io = MockIo {
        current: Some(Pu::ZERO),
        refuse_pwm: true,
        ..MockIo::default()
    };
    let mut sp = Setpoint::default();
    for k in 0..4 {
        period(&mut app, &mut io, k, &mut sp);
    }
    assert_eq!(app.fault(), Some(Fault::External));
}

#[test]
fn a_dump_request_freezes_the_trace_after_its_post_trigger_samples() {
    let mut app = app();
    let mut io = MockIo {
        current: Some(Pu::from_num(0.25)),
        ..MockIo::default()
    };
    let mut sp = Setpoint::default();
    for k in 0..1000 {
        io.encoder = k / 8;
        period(&mut app, &mut io, k, &mut sp);
    }
    app.request_dump();
    let post = u32::from(DEFAULT_TRACE.post_trigger) * u32::from(DEFAULT_TRACE.decimation);
    for k in 1000..1000 + post + 100 {
        io.encoder = k / 8;
        period(&mut app, &mut io, k, &mut sp);
    }
    assert_eq!(
        app.trace().state(),
        TraceState::Frozen {
            cause: TriggerCause::Request,
            trigger_tick: 1000
        }
    );
    // 250 pre-trigger samples (every 4th of 1000 ticks) + 128 post-trigger ones.
    assert_eq!(app.trace().len(), 250 + 128);
    let last = app.trace().sample(app.trace().len() - 1).unwrap();
    assert_eq!(last.tick, 1000 + post - 1);
    // Channel 0 is the encoder count, channel 1 the current (Q16.16 bits).
    assert_eq!(last.values[0] as u32, last.tick / 8);
    assert_eq!(last.values[1], Pu::from_num(0.25).to_bits());
    app.trace_mut().rearm();
    assert_eq!(app.trace().state(), TraceState::Armed);
}

#[test]
fn nothing_winds_up_while_disabled() {
    // A: disabled for 0.25 s with the setpoint 500 counts away, then enabled.
    // B: a fresh app enabled at that moment. Same inputs from there on: same outputs.
    let mut a = app();
    let mut io_a = MockIo {
        current: Some(Pu::from_num(0.1)),
        encoder: 7,
        ..MockIo::default()
    };
    let mut far = Setpoint {
        position_counts: controller_core::Counts::from_num(500),
        ..Setpoint::default()
    };
    for k in 0..1000 {
        period(&mut a, &mut io_a, k, &mut far);
    }
    assert!(a.is_held());
    assert_eq!(io_a.voltage, Pu::ZERO);
    a.set_enable_request(true);
    assert!(!a.is_held());

    let mut b = app();
    b.set_enable_request(true);
    let mut io_b = MockIo {
        current: Some(Pu::from_num(0.1)),
        encoder: 7,
        ..MockIo::default()
    };
    let mut sp = Setpoint::default();
    for k in 0..200 {
        let (oa, ob) = (a.on_current_tick(&mut io_a), b.on_current_tick(&mut io_b));
        assert_eq!(oa, ob, "current tick {k}");
        if k % 2 == 1 {
            let va = a.on_velocity_tick(velocity_inputs(&mut io_a, &mut sp));
            let vb = b.on_velocity_tick(velocity_inputs(&mut io_b, &mut sp));
            assert_eq!(va, vb, "velocity tick {k}");
        }
    }
    assert!(io_a.enabled && io_b.enabled);
}

#[test]
fn disabling_never_clears_a_latched_fault() {
    let mut app = app();
    app.set_enable_request(true);
    let mut io = MockIo {
        current: Some(Pu::ZERO),
        fault_input: true,
        ..MockIo::default()
    };
    let mut sp = Setpoint::default();
    for k in 0..4 {
        period(&mut app, &mut io, k, &mut sp);
    }
    assert_eq!(app.fault(), Some(Fault::External));
    io.fault_input = false;
    app.set_enable_request(false);
    app.set_enable_request(true);
    for k in 4..8 {
        period(&mut app, &mut io, k, &mut sp);
    }
    assert_eq!(app.fault(), Some(Fault::External));
    assert!(!io.enabled);
}
