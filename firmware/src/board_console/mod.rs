//! The board console image, whichever board runs it: the drive firmware as a board runs it,
//! the current and velocity loop interrupts started disabled and held at rest, with the
//! board console of `stiffdrive board` on the board's serial port (pil-link's board
//! frames, `pil_link::board`). The QEMU `board` image (`src/bin/board.rs`) and the STM32F4
//! image (`src/main.rs` with `board-stm32f4`) are this module bound to their board: each
//! binds [`current_loop`], [`velocity_loop`] and [`uart_rx`] to its interrupts and calls
//! [`run`] with its [`ConsoleBoard`] (the serial port, the settings sector, the loop
//! timers).
//!
//! At boot [`run`] reads the settings sector: a record that passes its checks
//! (`pil_link::board::store`) and `design` is the drive it runs; otherwise the baked
//! drive, and the boot log says why. `Save` writes the running settings there (refused
//! while the drive is enabled); `Reset` answers, then resets the system (`SCB::sys_reset`).
//!
//! Thread mode serves the console (`BoardSession`), records each fault latch in the fault
//! history, and while the scope runs sends the samples the current-loop interrupt tapped
//! from the trend buffer (`console::ScopeTap`), eight to a frame.
//!
//! On QEMU (`board-qemu`) the board has a rig: its virtual motor drives the baked machine
//! file's load through a shaft with lost motion (`crate::drive::coupling`), and `Identify`
//! (`pil_link::board::identify`) runs a measurement as its own enable: the current-loop
//! interrupt sets the rig's load torque on the virtual machine, runs the tick and records
//! it (`crate::identify::Recorder`, a ring); thread mode streams the record while it is
//! taken and, after its last tick, puts the running settings back. Should the link fall
//! a whole ring behind, the run ends there, the stream says so and the fault history
//! records a console-link fault: never a record with a gap. There the velocity tick runs in the current-loop
//! interrupt, after every `current_rate_hz / velocity_rate_hz`-th current tick (TIMER1
//! stays stopped): QEMU runs its timers on the host's clock, so two timers drift apart when
//! it runs late, and an overdue current tick would run before a pended velocity tick; one
//! tick source keeps the loops in step as a board's synchronous timers do, the velocity
//! tick reading the encoder the next current tick reads and running first, as the host
//! loop orders them. A late QEMU then loses whole ticks of both loops alike, and a
//! measurement is the same in tick time however the host is loaded. The STM32F4 image has
//! no rig and does not serve `Identify` (the session's default refusal).
//!
//! On QEMU a PMSM drive (the baked machine file's motor a PMSM) runs on the virtual
//! three-phase stage (`crate::rig::PmsmRig`), and `Calibrate` (`pil_link::board::calibrate`)
//! runs its motor calibration there: the current-loop interrupt runs the sequencer in
//! place of the drive's tick and records two samples a tick, streamed as an `Identify`
//! record is. Until the drive carries its calibration (`[drive.pmsm]`'s
//! `encoder_offset_elec_deg`, set over the console and saved with the rest), its app is
//! built at offset 0 and held: the session refuses `Enable` and `Identify`, naming the
//! command that calibrates. Saved settings for another motor than the baked machine's are
//! not run (the baked drive is).

use core::fmt::Write as _;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use controller_core::{ConfigError, DriveConfig, Setpoint};
use heapless::Deque;
#[cfg(feature = "board-qemu")]
use pil_link::board::calibrate::{self, CalibrateError, SAMPLES_PER_TICK};
use pil_link::board::faults::{FaultEntry, FaultHistory, LINK_FAULT_CODE};
#[cfg(feature = "board-qemu")]
use pil_link::board::identify::{IdentifyError, IdentifyRun, CHANNELS, EXCITATION_NAMES};
use pil_link::board::message::Origin;
use pil_link::board::scope::{ScopeChunk, ScopeInfo, ScopeSample, CHUNK_SAMPLES};
use pil_link::board::session::{settings_crc, BoardSession, Drive};
use pil_link::board::store::{SaveError, RECORD_LEN};
use pil_link::wire::Writer;
use pil_link::{Frame, FrameKind, MAX_FRAME};

use crate::app::{fault_code, App, AppError, DEFAULT_TRACE};
pub use crate::board::ConsoleBoard;
use crate::board::EncoderCounter;
use crate::boards::active as board;
use crate::console::{channel_names, ticks_to_ms, FaultTracker, ScopeTap};
use crate::isr::{Loops, Shared};
use crate::ring::ByteRing;
use crate::rt::exit;
use crate::trace::TraceState;

mod boot;
use boot::boot_settings;

#[cfg(feature = "board-qemu")]
use crate::calibrate::CalibrationRun;
#[cfg(feature = "board-qemu")]
use crate::identify::StreamEnd;
#[cfg(feature = "board-qemu")]
use crate::rig::{PmsmRig, Rig, PMSM_LOOPS, RECORD};
#[cfg(feature = "board-qemu")]
use controller_core::foc::calibration::Calibration;

/// The app and the loops' I/O (handed to `crate::rig` on QEMU).
static LOOPS: Loops<board::CurrentIoImpl, board::VelocityIoImpl, Setpoint> = Loops::new();
static RX: ByteRing = ByteRing::new();
/// Current-loop interrupts since boot: the clock of the fault history.
static BOOT_TICKS: AtomicU32 = AtomicU32::new(0);
static SCOPE_ON: AtomicBool = AtomicBool::new(false);
/// Scope samples from the current-loop interrupt to thread mode (a full queue drops
/// the sample, which the stream's counter then shows as a gap).
static SCOPE: Shared<(ScopeTap, Deque<(u32, ScopeSample), 256>)> = Shared::new();

/// The current-loop interrupt's body.
pub fn current_loop() {
    #[cfg(feature = "board-qemu")]
    if PmsmRig::active() {
        PmsmRig::tick();
    } else {
        let inputs = Rig::before_tick(&LOOPS);
        let out = LOOPS.current_isr();
        Rig::after_tick(&LOOPS, inputs, out);
    }
    #[cfg(not(feature = "board-qemu"))]
    let _ = LOOPS.current_isr();
    BOOT_TICKS.fetch_add(1, Ordering::Relaxed);
    if SCOPE_ON.load(Ordering::Relaxed) {
        let newest = with_app(|app| app.trace().newest()).flatten();
        critical_section::with(|cs| {
            SCOPE.with(cs, |(tap, queue)| {
                if let Some(item) = tap.offer(newest) {
                    let _ = queue.push_back(item);
                }
            })
        });
    }
}

/// The velocity-loop interrupt's body.
pub fn velocity_loop() {
    #[cfg(feature = "board-qemu")]
    if PmsmRig::active() {
        let _ = PMSM_LOOPS.velocity_isr();
        return;
    }
    let _ = LOOPS.velocity_isr();
}

/// Runs `f` on the drive's app (the DC loops', or on QEMU the PMSM rig's).
fn with_app<R>(f: impl FnOnce(&mut App) -> R) -> Option<R> {
    #[cfg(feature = "board-qemu")]
    if PmsmRig::active() {
        return PMSM_LOOPS.with_app(f);
    }
    LOOPS.with_app(f)
}

/// The app of `cfg`: a DC drive's; on QEMU a PMSM drive's, held at offset 0 until its
/// calibration is set (module docs: the session refuses to run it until then).
fn new_app(cfg: &DriveConfig) -> Result<App, AppError> {
    let bits = board::Encoder::COUNTER_BITS;
    #[cfg(feature = "board-qemu")]
    if let Some(mut p) = cfg.pmsm {
        let mut held = *cfg;
        p.encoder_offset_elec_deg = p.encoder_offset_elec_deg.or(Some(0.0));
        held.pmsm = Some(p);
        return App::new_pmsm(&held, bits, DEFAULT_TRACE);
    }
    App::new(cfg, bits, DEFAULT_TRACE)
}

/// The serial port's receive interrupt: every byte there into the ring thread mode reads.
pub fn uart_rx() {
    while let Some(b) = board::read_command() {
        RX.push(b);
    }
}

/// The drive behind the console: the app in `LOOPS`, the power stage, the settings
/// sector, the fault history, the scope.
struct BoardDrive<H> {
    hw: H,
    enabled: bool,
    /// Current and velocity loop rates the timers run at [Hz].
    rates_hz: (u32, u32),
    history: FaultHistory,
    tracker: FaultTracker,
    channels: heapless::String<128>,
    /// During a measurement: the running settings to put back after it.
    restore: Option<DriveConfig>,
    /// Samples of the record sent (the STM32F4 image records none).
    #[cfg_attr(not(feature = "board-qemu"), allow(dead_code))]
    record_sent: u32,
    /// A run's stream is not over yet.
    #[cfg_attr(not(feature = "board-qemu"), allow(dead_code))]
    record_open: bool,
    /// A motor calibration runs (the stage on for it).
    #[cfg_attr(not(feature = "board-qemu"), allow(dead_code))]
    calibrating: bool,
}

impl<H: ConsoleBoard> BoardDrive<H> {
    fn now_ms(&self) -> u32 {
        ticks_to_ms(
            u64::from(BOOT_TICKS.load(Ordering::Relaxed)),
            self.rates_hz.0,
        )
    }

    /// Thread mode, each pass: a new fault latch into the history; a trend buffer a
    /// fault froze armed again, so the scope goes on.
    fn poll(&mut self) {
        let record = with_app(|app| app.fault_record()).flatten();
        let now = self.now_ms();
        self.tracker.poll(record, now, &mut self.history);
        with_app(|app| {
            if matches!(app.trace().state(), TraceState::Frozen { .. }) {
                app.trace_mut().rearm();
            }
        });
        #[cfg(feature = "board-qemu")]
        if (self.restore.is_some() || self.calibrating) && !RECORD.active() {
            if RECORD.overran() {
                // The link fell a whole ring behind the record: the run stopped there.
                self.history.push(FaultEntry {
                    ms: now,
                    code: LINK_FAULT_CODE,
                });
                defmt::warn!(
                    "console: the link fell {=usize} samples behind the measurement: run ended",
                    crate::identify::RECORD_CAPACITY
                );
            }
            self.end_run();
        }
    }

    /// After a measurement (or to end it): the running settings' app back, disabled;
    /// the rig's load torque off.
    fn end_run(&mut self) {
        #[cfg(feature = "board-qemu")]
        {
            RECORD.abort();
            if core::mem::take(&mut self.calibrating) {
                PmsmRig::end_calibration();
            }
        }
        if let Some(cfg) = self.restore.take() {
            if let Ok(app) = new_app(&cfg) {
                with_app(|slot| *slot = app);
            }
            #[cfg(feature = "board-qemu")]
            if PmsmRig::active() {
                PmsmRig::set_load(0.0);
            } else {
                LOOPS.with_current_io(|io| io.pwm.motor_mut().set_load_torque_pu(0.0));
            }
        }
        self.enabled = false;
        defmt::info!("console: measurement over, running settings back");
    }

    /// Sends the record's samples written so far, up to eight frames a pass; after the
    /// last of a run cut short, the empty chunk that says so
    /// (`pil_link::board::identify::is_cut_end`).
    #[cfg(feature = "board-qemu")]
    fn send_record(&mut self, seq: &mut u16) {
        if !self.record_open {
            return;
        }
        for _ in 0..8 {
            let Some(chunk) = RECORD.chunk(self.record_sent) else {
                break;
            };
            self.record_sent = self.record_sent.wrapping_add(u32::from(chunk.len));
            self.send_chunk(&chunk, seq);
        }
        match RECORD.stream_end(self.record_sent) {
            StreamEnd::Open => {}
            StreamEnd::Whole => self.record_open = false,
            StreamEnd::Cut(recorded) => {
                self.send_chunk(&ScopeChunk::new(recorded), seq);
                self.record_open = false;
            }
        }
    }

    fn send(&mut self, frame: &Frame) {
        let mut wire = [0_u8; MAX_FRAME];
        if let Ok(n) = frame.encode(&mut wire) {
            self.hw.send(wire.get(..n).unwrap_or(&[]));
        }
    }

    /// Sends the queued scope samples, [`CHUNK_SAMPLES`] to a frame, once that many wait.
    fn send_scope(&mut self, seq: &mut u16) {
        loop {
            let mut chunk: Option<ScopeChunk> = None;
            let ready = critical_section::with(|cs| {
                SCOPE.with(cs, |(_, queue)| queue.len() >= CHUNK_SAMPLES)
            });
            if ready != Some(true) {
                return;
            }
            for _ in 0..CHUNK_SAMPLES {
                let Some((n, s)) =
                    critical_section::with(|cs| SCOPE.with(cs, |(_, queue)| queue.pop_front()))
                        .flatten()
                else {
                    break;
                };
                let c = chunk.get_or_insert_with(|| ScopeChunk::new(n));
                // A gap (a dropped sample) ends the chunk; the next one starts after it.
                if n != c.first.wrapping_add(u32::from(c.len)) || !c.push(s) {
                    self.send_chunk(c, seq);
                    let mut next = ScopeChunk::new(n);
                    next.push(s);
                    chunk = Some(next);
                }
            }
            if let Some(c) = chunk {
                self.send_chunk(&c, seq);
            }
        }
    }

    fn send_chunk(&mut self, chunk: &ScopeChunk, seq: &mut u16) {
        let mut w = Writer::new();
        if chunk.encode(&mut w).is_ok() {
            if let Ok(frame) = Frame::new(FrameKind::ScopeData, *seq, w.as_slice()) {
                self.send(&frame);
            }
        }
        *seq = seq.wrapping_add(1);
    }
}

/// The board's refusal of settings `design` accepted, as the core's error.
fn app_error(e: AppError) -> ConfigError {
    match e {
        AppError::Config(e) => e,
        AppError::CounterBits { board, config } => ConfigError::OutOfRange {
            param: "counter_bits",
            value: f32::from(config),
            min: f32::from(board),
            max: f32::from(board),
            min_exclusive: false,
        },
        // Neither happens: the trace setup is the constant DEFAULT_TRACE and the settings
        // are already decoded. Named as the trace, should one ever.
        AppError::Trace(_) | AppError::Settings(_) => ConfigError::NotFinite { param: "trace" },
    }
}

impl<H: ConsoleBoard> Drive for BoardDrive<H> {
    fn apply(&mut self, cfg: &DriveConfig) -> Result<(), ConfigError> {
        let app = new_app(cfg).map_err(app_error)?;
        with_app(|slot| *slot = app);
        if (cfg.current_rate_hz, cfg.velocity_rate_hz) != self.rates_hz {
            self.hw
                .set_loop_rates(cfg.current_rate_hz, cfg.velocity_rate_hz);
            #[cfg(feature = "board-qemu")]
            {
                Rig::lock_velocity_to_current(cfg);
                // The machine stepped at the new period, at rest where it was.
                if PmsmRig::active() {
                    PmsmRig::rebuild_machine(cfg);
                } else {
                    LOOPS.with_current_io(|io| {
                        let counts = io.pwm.motor_mut().counts();
                        *io.pwm.motor_mut() = Rig::machine(cfg, counts);
                    });
                }
            }
        }
        self.rates_hz = (cfg.current_rate_hz, cfg.velocity_rate_hz);
        defmt::info!(
            "console: settings applied (settings crc {=u32:08x})",
            settings_crc(cfg)
        );
        Ok(())
    }

    fn enabled(&self) -> bool {
        self.enabled
    }

    fn set_enabled(&mut self, on: bool) {
        if !on && (self.restore.is_some() || self.calibrating) {
            self.end_run();
            return;
        }
        with_app(|app| app.set_enable_request(on));
        self.enabled = on;
        defmt::info!(
            "console: drive {=str}",
            if on { "enabled" } else { "disabled" }
        );
    }

    fn fault_code(&self) -> u8 {
        with_app(|app| fault_code(app.fault())).unwrap_or(0)
    }

    fn save(&mut self, record: &[u8; RECORD_LEN]) -> Result<(), SaveError> {
        if self.enabled {
            return Err(SaveError::Enabled);
        }
        let result = self.hw.write_settings(record);
        if let Err(e) = result {
            defmt::warn!("console: save failed: {}", defmt::Display2Format(&e));
        }
        result
    }

    fn fault_history(&self) -> FaultHistory {
        self.history
    }

    fn scope(&mut self, on: bool) -> ScopeInfo<'_> {
        critical_section::with(|cs| {
            SCOPE.with_slot(cs, |slot| *slot = Some((ScopeTap::new(), Deque::new())))
        });
        SCOPE_ON.store(on, Ordering::Relaxed);
        ScopeInfo {
            rate_hz: self.rates_hz.0 / u32::from(DEFAULT_TRACE.decimation.max(1)),
            channels: self.channels.as_str(),
        }
    }

    #[cfg(feature = "board-qemu")]
    fn identify(
        &mut self,
        cfg: &DriveConfig,
        running: &DriveConfig,
        run: &IdentifyRun,
    ) -> Result<ScopeInfo<'_>, IdentifyError> {
        let refused = |e| IdentifyError::Config(app_error(e));
        let mut app = new_app(cfg).map_err(refused)?;
        if let Some(e) = run.excitation() {
            app = app.with_excitation(&e, EXCITATION_NAMES).map_err(refused)?;
        }
        app.set_enable_request(true);
        // One critical section: the run's first tick is the next one, on a machine at rest
        // (the rig's brake released), the excitation at its first sample.
        critical_section::with(|_| {
            RECORD.start(run)?;
            Rig::align_velocity();
            if PmsmRig::active() {
                PmsmRig::brake();
            } else {
                LOOPS.with_current_io(|io| io.pwm.brake());
            }
            with_app(|slot| *slot = app);
            Ok::<(), IdentifyError>(())
        })?;
        self.restore = Some(*running);
        self.record_sent = 0;
        self.record_open = true;
        self.enabled = true;
        defmt::info!("console: measurement of {=u32} ticks", run.ticks);
        Ok(ScopeInfo {
            rate_hz: self.rates_hz.0,
            channels: CHANNELS,
        })
    }

    #[cfg(feature = "board-qemu")]
    fn calibrate(
        &mut self,
        cfg: &DriveConfig,
        seq: &Calibration,
    ) -> Result<ScopeInfo<'_>, CalibrateError> {
        if !PmsmRig::active() {
            return Err(CalibrateError::NotPmsm);
        }
        let run = CalibrationRun::new(cfg, *seq).map_err(CalibrateError::Config)?;
        let samples = run.total_ticks().saturating_mul(SAMPLES_PER_TICK);
        // One critical section: the record armed, the run's first tick the next one.
        critical_section::with(|_| {
            RECORD
                .start_samples(samples)
                .map_err(|_| CalibrateError::Unsupported)?;
            PmsmRig::start_calibration(run);
            Ok::<(), CalibrateError>(())
        })?;
        self.calibrating = true;
        self.record_sent = 0;
        self.record_open = true;
        self.enabled = true;
        defmt::info!(
            "console: motor calibration of {=u32} ticks",
            run.total_ticks()
        );
        Ok(ScopeInfo {
            rate_hz: self.rates_hz.0,
            channels: calibrate::CHANNELS,
        })
    }

    fn enter_safe_state(&mut self) {
        self.set_enabled(false);
        let ms = self.now_ms();
        self.history.push(FaultEntry {
            ms,
            code: LINK_FAULT_CODE,
        });
        defmt::warn!("console: corrupt frame while enabled: drive disabled");
    }
}

/// The board console image's `main`: the settings, the app, the board and its loops, then
/// the console session for good.
pub fn run<H: ConsoleBoard>(mut hw: H) -> ! {
    let Some(mut core) = cortex_m::Peripherals::take() else {
        exit(false)
    };
    let Ok(baked) = crate::drive::baked() else {
        defmt::error!("baked drive settings do not decode");
        exit(false)
    };
    defmt::info!(
        "stiffdrive firmware {=str} on {=str}: board console on {=str} (board protocol {=u8})",
        env!("CARGO_PKG_VERSION"),
        board::NAME,
        H::PORT,
        pil_link::board::BOARD_VERSION
    );
    let (mut cfg, mut origin, mut note) = boot_settings(&mut hw, baked);
    let app = match new_app(&cfg) {
        Ok(app) => app,
        Err(e) => {
            defmt::warn!(
                "settings refused by the board ({}): baked drive",
                defmt::Debug2Format(&e)
            );
            (cfg, origin) = (baked, Origin::Baked);
            note.clear();
            let _ = write!(note, "baked (saved settings refused by the board)");
            match new_app(&cfg) {
                Ok(app) => app,
                Err(_) => exit(false),
            }
        }
    };
    #[cfg_attr(not(feature = "board-qemu"), allow(unused_mut))]
    let mut b = board::init(&mut core, &cfg);
    #[cfg(feature = "board-qemu")]
    {
        *b.current_io.pwm.motor_mut() = Rig::machine(&cfg, 0);
    }
    hw.booted(&note);
    #[cfg(feature = "board-qemu")]
    if cfg.pmsm.is_some() {
        // The baked file's PMSM behind the virtual three-phase stage.
        if !PmsmRig::install(app, &cfg, b.velocity_io) {
            defmt::error!("the drive is a PMSM and the baked machine's motor is not");
            exit(false)
        }
        defmt::info!("PMSM drive on the virtual three-phase stage");
    } else {
        LOOPS.install(app, b.current_io, b.velocity_io, Setpoint::default());
    }
    #[cfg(not(feature = "board-qemu"))]
    LOOPS.install(app, b.current_io, b.velocity_io, Setpoint::default());
    let mut drive = BoardDrive {
        hw,
        enabled: false,
        rates_hz: (cfg.current_rate_hz, cfg.velocity_rate_hz),
        history: FaultHistory::new(),
        tracker: FaultTracker::new(),
        channels: channel_names(&DEFAULT_TRACE),
        restore: None,
        record_sent: 0,
        record_open: false,
        calibrating: false,
    };
    let mut session = BoardSession::new(cfg, origin, crate::version(), crate::drive::NAME);
    board::start(&mut core.NVIC, cfg.current_rate_hz, cfg.velocity_rate_hz);
    #[cfg(feature = "board-qemu")]
    Rig::lock_velocity_to_current(&cfg);
    serve(&mut session, &mut drive)
}

fn serve<H: ConsoleBoard>(session: &mut BoardSession, drive: &mut BoardDrive<H>) -> ! {
    let mut scope_seq = 0_u16;
    loop {
        while let Some(byte) = RX.pop() {
            if let Some(frame) = session.on_byte(byte, drive) {
                drive.send(&frame);
            }
            if session.reset_requested() {
                defmt::info!("console: system reset");
                board::stop();
                cortex_m::peripheral::SCB::sys_reset();
            }
        }
        drive.poll();
        if SCOPE_ON.load(Ordering::Relaxed) {
            drive.send_scope(&mut scope_seq);
        }
        #[cfg(feature = "board-qemu")]
        drive.send_record(&mut scope_seq);
        cortex_m::interrupt::free(|_| {
            if RX.is_empty() {
                cortex_m::asm::wfi();
            }
        });
    }
}
