//! The interrupt glue on the host (critical sections from the `std` implementation): the
//! handler bodies run the App exactly as direct calls do, the non-blocking cell refuses a
//! second borrower, and a frozen trend buffer dumps in order and re-arms.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use controller_core::{Profile, ProfileConfig, Setpoint};
use firmware::app::{velocity_inputs, App, DEFAULT_TRACE};
use firmware::isr::{Loops, TaskLocal};
use firmware::lil::words::LilInput;
use firmware::lil::ReplayIo;
use firmware::trace::{TraceState, TriggerCause};

fn app() -> App {
    let cfg = firmware::drive::baked().unwrap();
    let mut app = App::new(&cfg, cfg.counter_bits, DEFAULT_TRACE).unwrap();
    app.set_enable_request(true);
    app
}

fn profile() -> Profile {
    Profile::new(&ProfileConfig::fig6(), &firmware::drive::baked().unwrap()).unwrap()
}

fn record(k: u32) -> LilInput {
    LilInput {
        encoder_count: (k * k / 400) & 0xFFFF,
        current_pu: controller_core::Pu::from_bits(((k % 37) as i32 - 18) * 300),
        fault_input: false,
    }
}

#[test]
fn handler_bodies_match_direct_app_calls() {
    // The same records through Loops (as the interrupts run them) and through App calls.
    let loops: Loops<ReplayIo, ReplayIo, Profile> = Loops::new();
    loops.install(app(), ReplayIo::default(), ReplayIo::default(), profile());
    let mut direct = app();
    let mut direct_io = ReplayIo::default();
    let mut direct_profile = profile();
    for k in 0..2000 {
        let rec = record(k);
        direct_io.record = rec;
        let d = direct.on_current_tick(&mut direct_io);
        let l = loops_current(&loops, rec);
        assert_eq!(l, d, "current tick {k}");
        if k % 2 == 1 {
            let dv = direct.on_velocity_tick(velocity_inputs(&mut direct_io, &mut direct_profile));
            let lv = loops.velocity_isr().unwrap();
            assert_eq!(lv, dv, "velocity tick {k}");
        }
    }
    assert_eq!(loops.overruns(), 0);
    assert_eq!(loops.with_app(|a| a.ticks()), Some(2000));
}

/// Run the current handler body with `rec` as the board's sample.
fn loops_current(
    loops: &Loops<ReplayIo, ReplayIo, Profile>,
    rec: LilInput,
) -> controller_core::CurrentOutputs {
    loops.with_current_io(|io| io.record = rec).unwrap();
    loops.with_velocity_io(|io| io.record = rec).unwrap();
    loops.current_isr().unwrap()
}

#[test]
fn task_local_never_hands_out_two_borrows() {
    let cell: TaskLocal<u32> = TaskLocal::new();
    assert_eq!(cell.with(|v| *v), None, "empty");
    assert!(cell.install(5));
    let nested = cell.with(|v| {
        *v += 1;
        // A second borrower (an interrupt arriving now) is refused, not blocked.
        cell.with(|w| *w)
    });
    assert_eq!(nested, Some(None));
    assert_eq!(cell.with(|v| *v), Some(6));
}

#[test]
fn a_frozen_trace_dumps_oldest_first_and_rearms() {
    let loops: Loops<ReplayIo, ReplayIo, Setpoint> = Loops::new();
    loops.install(
        app(),
        ReplayIo::default(),
        ReplayIo::default(),
        Setpoint::default(),
    );
    assert_eq!(loops.dump_trace(|_, _| {}), None, "nothing frozen yet");
    for _ in 0..100 {
        loops.current_isr().unwrap();
    }
    loops.with_app(|a| a.request_dump()).unwrap();
    for _ in 0..1000 {
        loops.current_isr().unwrap();
    }
    let mut ticks = Vec::new();
    let state = loops.dump_trace(|i, s| {
        assert_eq!(i, ticks.len());
        ticks.push(s.tick);
    });
    assert_eq!(
        state,
        Some(TraceState::Frozen {
            cause: TriggerCause::Request,
            trigger_tick: 100
        })
    );
    assert_eq!(ticks.len(), 25 + 128);
    assert!(ticks.windows(2).all(|w| w[1] == w[0] + 4));
    assert_eq!(
        loops.with_app(|a| a.trace().state()),
        Some(TraceState::Armed)
    );
}
