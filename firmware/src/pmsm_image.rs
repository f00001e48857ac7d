//! The PMSM drive on the three-phase STM32F4 board (`board-stm32f4-3ph`, the `firmware`
//! image; `cargo fw-build-stm32`): the baked drive's `Controller::pmsm_tick` in the
//! current-loop interrupt, which ADC1's injected end of conversion raises every k-th PWM
//! period (`boards::stm32f4::three_phase`), and its `velocity_tick` every
//! `current_rate_hz / velocity_rate_hz`-th current tick, pended by the current loop at a
//! lower priority: both loops are locked to the PWM.
//!
//! It boots with the stage off, holding nothing. Console bytes on USART2 (the Nucleo's
//! virtual COM port): `e` resets the controller and enables it, holding the position it
//! finds; `x` disables (the stage off, the regulators held); `r` clears a latched fault and
//! the break flag, disabled. A status line follows every second. The board console session
//! of `stiffdrive board` is the DC images' (`board_console`).

use core::cell::RefCell;
use core::fmt::Write as _;
use core::sync::atomic::{AtomicU32, Ordering};

use controller_core::per_unit::count_signed;
use controller_core::{Controller, Counts, Fault, PmsmInputs, Pu, Setpoint, VelocityInputs};
use critical_section::Mutex;

use crate::board::three_phase::{PmsmLoopIo, IHM08M1};
use crate::board::EncoderCounter;
use crate::boards::stm32f4::three_phase::{self as stage, InitError, ThreePhaseIo, Tim2Encoder};
use crate::boards::stm32f4::{read_command, Usart2};

/// The drive between interrupts.
struct Drive {
    controller: Controller,
    io: ThreePhaseIo,
    /// The position held since the last enable.
    hold: Setpoint,
    /// Enabled: the ticks run and the stage may switch.
    running: bool,
    /// A conversion was missing or the stage refused: the external fault until reset.
    sensor_fault: bool,
    /// Half the PWM period: the duties of 0 V.
    half: u16,
    counter_bits: u8,
}

static DRIVE: Mutex<RefCell<Option<Drive>>> = Mutex::new(RefCell::new(None));
/// Current ticks since boot.
static TICKS: AtomicU32 = AtomicU32::new(0);
/// Current ticks per velocity tick.
static VELOCITY_EVERY: AtomicU32 = AtomicU32::new(0);

/// Run `f` on the drive inside a critical section; nothing if it is not installed or
/// already borrowed (never a panic).
fn with_drive(f: impl FnOnce(&mut Drive)) {
    critical_section::with(|cs| {
        if let Ok(mut slot) = DRIVE.borrow(cs).try_borrow_mut() {
            if let Some(d) = slot.as_mut() {
                f(d);
            }
        }
    });
}

impl Drive {
    fn current_tick(&mut self) {
        let encoder_count = self.io.encoder_count();
        let currents = self.io.phase_currents_pu();
        self.sensor_fault |= currents.is_none();
        let out = if self.running {
            Some(self.controller.pmsm_tick(PmsmInputs {
                encoder_count,
                phase_current_pu: currents.unwrap_or([Pu::ZERO; 2]),
            }))
        } else {
            // Held: the electrical angle still follows the shaft, so that an enable
            // after the rotor turned starts at the right angle.
            self.controller.pmsm_track(encoder_count);
            None
        };
        let on = out.is_some_and(|o| o.enabled) && !self.sensor_fault;
        let duties = match out {
            Some(o) if on => o.duties,
            _ => [self.half; 3],
        };
        let applied = self.io.set_duties(duties);
        let enabled = self.io.set_enable(on);
        self.sensor_fault |= !(applied && enabled);
    }

    fn velocity_tick(&mut self, encoder_count: u32) {
        if self.running {
            let fault_input = self.io.fault_input() || self.sensor_fault;
            let _ = self.controller.velocity_tick(VelocityInputs {
                encoder_count,
                setpoint: self.hold,
                fault_input,
            });
        }
    }

    fn command(&mut self, byte: u8) {
        match byte {
            b'e' if !self.running => {
                self.controller.reset();
                let start = count_signed(Tim2Encoder.count(), self.counter_bits);
                self.hold = Setpoint {
                    position_counts: Counts::from_num(start),
                    ..Setpoint::default()
                };
                self.running = true;
            }
            b'x' => self.running = false,
            b'r' => {
                self.running = false;
                self.controller.reset();
                self.sensor_fault = false;
                stage::clear_break();
            }
            _ => {}
        }
    }
}

/// The current-loop interrupt's body (ADC1's JEOC).
pub fn current_loop() {
    with_drive(Drive::current_tick);
    let tick = TICKS.fetch_add(1, Ordering::Relaxed).wrapping_add(1);
    let every = VELOCITY_EVERY.load(Ordering::Relaxed);
    if every > 0 && tick.is_multiple_of(every) {
        stage::pend_velocity();
    }
}

/// The velocity-loop interrupt's body (pended by [`current_loop`]).
pub fn velocity_loop() {
    let count = Tim2Encoder.count();
    with_drive(|d| d.velocity_tick(count));
}

/// The console's receive interrupt: the command bytes.
pub fn command() {
    while let Some(b) = read_command() {
        with_drive(|d| d.command(b));
    }
}

/// Why the stage stayed off, for the console.
fn describe(e: &InitError, out: &mut Usart2) {
    let _ = match e {
        InitError::NotPmsm => write!(
            out,
            "the baked drive has no [drive.pmsm]: build with STIFFDRIVE_DRIVE naming a PMSM \
             machine file"
        ),
        InitError::Clock(source) => write!(out, "clock: {}", source.describe()),
        InitError::TickRatio(t) => write!(out, "{t}"),
        InitError::Offset(o) => write!(
            out,
            "phase {} current offset {} counts, not mid-scale: check the power board's \
             supply, and that no current flows at start",
            ["U", "V"].get(o.phase).unwrap_or(&"?"),
            o.counts
        ),
        InitError::NoConversion => write!(out, "no ADC conversion: TIM1 or the ADCs dead"),
    };
}

/// Stage off, say why on the console, and wait (the watchdog is not started).
fn halt(why: impl FnOnce(&mut Usart2)) -> ! {
    crate::boards::stm32f4::emergency_stop();
    let mut out = Usart2;
    let _ = write!(out, "stiffdrive three-phase image: stage off: ");
    why(&mut out);
    let _ = write!(out, "\r\n");
    loop {
        cortex_m::asm::wfi();
    }
}

/// The image's main: bring the board up, install the drive, start the loops, report.
pub fn run() -> ! {
    let Some(mut core) = cortex_m::Peripherals::take() else {
        crate::boards::exit(false)
    };
    let Ok(cfg) = crate::drive::baked() else {
        halt(|o| {
            let _ = write!(o, "the baked drive settings do not decode");
        })
    };
    let b = match stage::init(&cfg) {
        Ok(b) => b,
        Err(e) => halt(|o| describe(&e, o)),
    };
    if cfg.counter_bits != Tim2Encoder::COUNTER_BITS {
        halt(|o| {
            let _ = write!(
                o,
                "drive.counter_bits = {} but TIM2 counts 16",
                cfg.counter_bits
            );
        })
    }
    let controller = match Controller::new(&cfg) {
        Ok(c) => c,
        Err(e) => halt(|o| {
            let _ = write!(o, "drive.{}: {e}", e.param());
        }),
    };
    let half = cfg.pmsm.map_or(0, |p| p.pwm_period_counts / 2);
    VELOCITY_EVERY.store(
        (cfg.current_rate_hz / cfg.velocity_rate_hz.max(1)).max(1),
        Ordering::Relaxed,
    );
    let drive = Drive {
        controller,
        io: b.io,
        hold: Setpoint::default(),
        running: false,
        sensor_fault: false,
        half,
        counter_bits: cfg.counter_bits,
    };
    // Before the loop interrupts are unmasked: nothing else holds the cell (`try_`: no
    // panic path is linked).
    critical_section::with(|cs| {
        if let Ok(mut slot) = DRIVE.borrow(cs).try_borrow_mut() {
            *slot = Some(drive);
        }
    });
    let mut out = b.console;
    let _ = write!(
        out,
        "stiffdrive firmware {} on {}: drive {}; current loop every {} PWM periods \
         (ADC1 JEOC), offsets U {} V {} counts; e enable, x disable, r reset\r\n",
        env!("CARGO_PKG_VERSION"),
        IHM08M1.name,
        crate::drive::NAME,
        b.periods_per_tick,
        b.offsets[0],
        b.offsets[1]
    );
    stage::start(&mut core.NVIC);
    let mut last = 0_u32;
    loop {
        cortex_m::asm::wfi();
        let ticks = TICKS.load(Ordering::Relaxed);
        if ticks.wrapping_sub(last) >= cfg.current_rate_hz {
            last = ticks;
            let mut state: (bool, Option<Fault>) = (false, None);
            with_drive(|d| state = (d.running, d.controller.fault()));
            let _ = write!(
                out,
                "ticks {ticks} enabled {} fault {:?}\r\n",
                state.0, state.1
            );
        }
    }
}
