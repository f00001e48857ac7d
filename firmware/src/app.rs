//! The application: controller-core bound to the board layer. [`App`] holds the controller
//! and the trend buffer; [`App::on_current_tick`] is the body of the 4 kHz current-loop
//! interrupt and [`App::on_velocity_tick`] the controller part of the 2 kHz velocity-loop
//! interrupt. The velocity interrupt prepares its inputs (encoder, fault input, profile
//! setpoint: [`velocity_inputs`]) before it takes the controller, so only the core's
//! `velocity_tick` itself runs with the current loop held off (see `shared.rs`).
//!
//! The same functions serve the benchmark, the loop-in-the-loop replay and the
//! processor-in-the-loop image ([`App::step_current`], [`App::step_velocity`]): there is
//! one control path, whatever feeds it.
//!
//! A PMSM drive (`[drive.pmsm]`) is built with [`App::new_pmsm`]; its current-loop
//! interrupt calls [`App::on_pmsm_tick`] (two phase currents in, three duties out, through
//! [`PmsmLoopIo`]), or [`App::step_pmsm`] from sensor values, in place of
//! [`App::on_current_tick`]; the velocity tick is the DC drive's.

use controller_core::excitation::{ExcitationConfig, ExcitationParams};
use controller_core::per_unit::Pu;
use controller_core::{
    ConfigError, Controller, CurrentInputs, CurrentOutputs, DriveConfig, Fault, PmsmInputs,
    PmsmOutputs, Setpoint, VelocityInputs, VelocityOutputs,
};

use crate::board::three_phase::PmsmLoopIo;
use crate::board::{CurrentLoopIo, VelocityLoopIo};
use crate::trace::{
    SignalSnapshot, TraceBuffer, TraceConfig, TraceConfigError, TraceSignal, TriggerCause,
};

/// Samples in the trend buffer: 512 × (4 + 1) words = 10 KiB of RAM.
pub const TRACE_LEN: usize = 512;

/// The trend buffer the app keeps.
pub type AppTrace = TraceBuffer<TRACE_LEN>;

/// Default trend setup: encoder, current, current reference and voltage command every
/// 4th current tick (1 ms), 128 samples after the trigger.
pub const DEFAULT_TRACE: TraceConfig = TraceConfig {
    channels: [
        TraceSignal::EncoderCounts,
        TraceSignal::CurrentPu,
        TraceSignal::CurrentRefPu,
        TraceSignal::VoltageCmdPu,
    ],
    decimation: 4,
    post_trigger: 128,
};

/// Why the app could not be built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AppError {
    /// The drive settings are invalid (the core names the parameter and its range).
    Config(ConfigError),
    /// The trend-buffer settings are invalid.
    Trace(TraceConfigError),
    /// The baked drive settings ([`crate::drive::BAKED`]) do not decode, or name a motor
    /// the constructor does not drive (`LinkError::UnsupportedMotor`: a PMSM drive given to
    /// [`App::new`], a DC drive to [`App::new_pmsm`]).
    Settings(pil_link::LinkError),
    /// The board's encoder counter width differs from `DriveConfig::counter_bits`.
    CounterBits {
        /// Width the board delivers \[bits\].
        board: u8,
        /// Width the settings declare \[bits\].
        config: u8,
    },
}

/// A source of motion setpoints, one per velocity tick (controller-core's `Profile`).
pub trait SetpointSource {
    /// The setpoint for the next velocity tick.
    fn next_setpoint(&mut self) -> Setpoint;
}

impl SetpointSource for controller_core::Profile {
    fn next_setpoint(&mut self) -> Setpoint {
        self.next()
    }
}

/// A fixed setpoint (hold position / constant velocity).
impl SetpointSource for Setpoint {
    fn next_setpoint(&mut self) -> Setpoint {
        *self
    }
}

pub use controller_core::words::fault_code;

/// Gather the velocity tick's inputs: encoder and fault input from the board, the next
/// setpoint from the profile. Runs before the controller is taken.
#[inline]
pub fn velocity_inputs<I: VelocityLoopIo, S: SetpointSource>(
    io: &mut I,
    profile: &mut S,
) -> VelocityInputs {
    VelocityInputs {
        encoder_count: io.encoder_count(),
        setpoint: profile.next_setpoint(),
        fault_input: io.fault_input(),
    }
}

/// The controller, the trend buffer and the bookkeeping the two ticks share.
///
/// Laid out in this order (`repr(C)`): the small fields the ticks touch first, the
/// controller, the trend buffer last, so that the ticks reach every field within the
/// Cortex-M4's immediate load offsets whatever the sizes of the controller and the buffer.
#[repr(C)]
pub struct App {
    /// Current-loop ticks since start (wraps after 12 days at 4 kHz).
    tick: u32,
    /// The power stage may be switched on (operator enable).
    enable_request: bool,
    /// A sensor read failed since the last reset: forces the external fault.
    sensor_fault: bool,
    /// The external fault input as the last velocity tick read it.
    fault_input_active: bool,
    /// Disabled without a fault: the core's ticks are not run (no regulator winds up
    /// while the stage is off); the controller is reset on the next enable.
    held: bool,
    /// Last velocity-tick setpoint, for the trace.
    last_setpoint: Setpoint,
    /// The current tick at which the latched fault was first reported, for the log.
    fault_tick: Option<u32>,
    controller: Controller,
    trace: AppTrace,
}

impl App {
    /// Build the app for a DC drive and a board whose encoder counter is `counter_bits`
    /// wide (the current tick: [`App::on_current_tick`]).
    ///
    /// # Errors
    /// [`AppError`] naming the bad setting; `AppError::Settings(UnsupportedMotor)` for a
    /// PMSM drive (a DC board drives one winding: [`CurrentLoopIo`]).
    pub fn new(cfg: &DriveConfig, counter_bits: u8, trace: TraceConfig) -> Result<Self, AppError> {
        if cfg.pmsm.is_some() {
            return Err(AppError::Settings(pil_link::LinkError::UnsupportedMotor));
        }
        Self::build(cfg, counter_bits, trace)
    }

    /// Build the app for a PMSM drive (`[drive.pmsm]`) and a board whose encoder counter is
    /// `counter_bits` wide (the current tick: [`App::on_pmsm_tick`]).
    ///
    /// # Errors
    /// [`AppError`] naming the bad setting (a PMSM drive without its measured encoder
    /// offset is the core's `ConfigError::Missing`); `AppError::Settings(UnsupportedMotor)`
    /// for a DC drive.
    pub fn new_pmsm(
        cfg: &DriveConfig,
        counter_bits: u8,
        trace: TraceConfig,
    ) -> Result<Self, AppError> {
        if cfg.pmsm.is_none() {
            return Err(AppError::Settings(pil_link::LinkError::UnsupportedMotor));
        }
        Self::build(cfg, counter_bits, trace)
    }

    fn build(cfg: &DriveConfig, counter_bits: u8, trace: TraceConfig) -> Result<Self, AppError> {
        if counter_bits != cfg.counter_bits {
            return Err(AppError::CounterBits {
                board: counter_bits,
                config: cfg.counter_bits,
            });
        }
        Ok(Self {
            controller: Controller::new(cfg).map_err(AppError::Config)?,
            trace: TraceBuffer::new(trace).map_err(AppError::Trace)?,
            tick: 0,
            enable_request: false,
            sensor_fault: false,
            fault_input_active: false,
            held: true,
            last_setpoint: Setpoint::default(),
            fault_tick: None,
        })
    }

    /// Allow (or forbid) the power stage to switch on; it stays off while faulted.
    ///
    /// Disabling without a latched fault holds the regulators: the core's ticks stop (so
    /// nothing winds up while the stage is off). Enabling from the held state resets the
    /// controller first, so it starts from a clean state at the present position. A latched
    /// fault is never cleared here (that takes [`App::reset`]).
    pub fn set_enable_request(&mut self, enable: bool) {
        self.enable_request = enable;
        if enable && self.held {
            self.controller.reset();
            self.held = false;
        } else if !enable && self.controller.fault().is_none() {
            self.held = true;
        }
    }

    /// Clear a latched fault and the regulators' state (the operator's fault reset).
    pub fn reset(&mut self) {
        self.controller.reset();
        self.fault_tick = None;
        self.sensor_fault = false;
        self.held = !self.enable_request;
    }

    /// The latched fault, if any.
    #[must_use]
    pub fn fault(&self) -> Option<Fault> {
        self.controller.fault()
    }

    /// The latched fault and the current tick it latched at (when and why it tripped).
    #[must_use]
    pub fn fault_record(&self) -> Option<(Fault, u32)> {
        self.controller.fault().zip(self.fault_tick)
    }

    /// Whether the I²t model of the winding is at its warning level.
    #[must_use]
    pub fn thermal_warning(&self) -> bool {
        self.controller.thermal_warning()
    }

    /// The app with an identification excitation in its controller
    /// ([`Controller::with_excitation`]; none by default). Errors name `names`' fields.
    ///
    /// # Errors
    /// [`AppError::Config`] when the excitation is refused (range, Nyquist limit).
    pub fn with_excitation(
        mut self,
        cfg: &ExcitationConfig,
        names: ExcitationParams,
    ) -> Result<Self, AppError> {
        self.controller = self
            .controller
            .with_excitation(cfg, names)
            .map_err(AppError::Config)?;
        Ok(self)
    }

    /// The torque of the last PMSM tick's measured currents in the drive's motor model, in
    /// the counts' direction (`Controller::pmsm_measured_torque`).
    #[must_use]
    pub fn measured_torque_pu(&self) -> Pu {
        self.controller.pmsm_measured_torque()
    }

    /// A q-axis quantity of a PMSM drive's FOC frame signed by the counts' direction
    /// (`Controller::q_in_count_direction`).
    #[must_use]
    pub fn q_in_count_direction(&self, q: Pu) -> Pu {
        self.controller.q_in_count_direction(q)
    }

    /// The excitation's latest sample \[pu\] (zero without one).
    #[must_use]
    pub fn excitation_pu(&self) -> Pu {
        self.controller.excitation_pu()
    }

    /// Current-loop ticks run so far.
    #[must_use]
    pub const fn ticks(&self) -> u32 {
        self.tick
    }

    /// The trend buffer (to dump it once frozen).
    #[must_use]
    pub const fn trace(&self) -> &AppTrace {
        &self.trace
    }

    /// The trend buffer, mutable (to re-arm it after a dump).
    pub fn trace_mut(&mut self) -> &mut AppTrace {
        &mut self.trace
    }

    /// Ask for a trace dump: the trend buffer triggers now and freezes after its
    /// post-trigger samples.
    pub fn request_dump(&mut self) {
        self.trace.trigger(self.tick, TriggerCause::Request);
    }

    /// Whether the regulators are held in reset (disabled, no fault latched).
    #[must_use]
    pub const fn is_held(&self) -> bool {
        self.held
    }

    /// The body of the current-loop interrupt: sample, run the core's current tick, drive
    /// the PWM and the enable output, record the trend buffer.
    ///
    /// While held (see [`App::set_enable_request`]) the core's ticks do not run: 0 V, enable
    /// low, the trend buffer still records the sensors. A latched fault keeps the ticks
    /// running (the core then commands zero torque) and the stage off until [`App::reset`].
    #[inline]
    pub fn on_current_tick<I: CurrentLoopIo>(&mut self, io: &mut I) -> CurrentOutputs {
        let encoder_count = io.encoder_count();
        let current_pu = match io.current_pu() {
            Some(i) => i,
            None => {
                // No valid sample: run the tick on zero current, latch a sensor fault that
                // the next velocity tick turns into the core's external fault.
                self.sensor_fault = true;
                Pu::ZERO
            }
        };
        let inputs = CurrentInputs {
            encoder_count,
            current_pu,
        };
        let out = if self.held {
            self.record_trace(&inputs, &CurrentOutputs::default());
            CurrentOutputs::default()
        } else {
            self.step_current(inputs)
        };
        // `held` implies no enable request.
        let run = out.fault.is_none()
            && !self.sensor_fault
            && !self.fault_input_active
            && self.enable_request;
        let applied = io.set_voltage_pu(if run { out.voltage_cmd_pu } else { Pu::ZERO });
        let enabled = io.set_enable(run);
        if !(applied && enabled) {
            self.sensor_fault = true;
        }
        out
    }

    /// The controller part of the velocity-loop interrupt: run the core's velocity tick on
    /// inputs gathered by [`velocity_inputs`]. A latched sensor fault forces the fault input.
    #[inline]
    pub fn on_velocity_tick(&mut self, inputs: VelocityInputs) -> VelocityOutputs {
        self.fault_input_active = inputs.fault_input;
        if self.held {
            self.last_setpoint = inputs.setpoint;
            return VelocityOutputs::default();
        }
        self.step_velocity(VelocityInputs {
            fault_input: inputs.fault_input || self.sensor_fault,
            ..inputs
        })
    }

    /// One current tick from sensor values, without a board: the code the current-loop
    /// interrupt runs between its board reads and writes (used by `on_current_tick`, the
    /// loop-in-the-loop replay and the PIL image). Returns the commands.
    #[inline]
    pub fn step_current(&mut self, inputs: CurrentInputs) -> CurrentOutputs {
        let out = self.controller.current_tick(inputs);
        if out.fault.is_some() {
            self.trace.trigger(self.tick, TriggerCause::Fault);
            if self.fault_tick.is_none() {
                self.fault_tick = Some(self.tick);
            }
        }
        self.record_trace(&inputs, &out);
        out
    }

    /// Offer this tick's signals to the trend buffer and count the tick.
    #[inline]
    fn record_trace(&mut self, inputs: &CurrentInputs, out: &CurrentOutputs) {
        let setpoint = &self.last_setpoint;
        self.trace.record_with(self.tick, || SignalSnapshot {
            encoder_counts: inputs.encoder_count,
            current_pu: inputs.current_pu.to_bits(),
            current_ref_pu: out.current_ref_pu.to_bits(),
            voltage_cmd_pu: out.voltage_cmd_pu.to_bits(),
            accel_fb_pu: out.accel_fb_pu.to_bits(),
            velocity_setpoint_pu: setpoint.velocity_pu.to_bits(),
            // Whole counts of the commanded position (saturated to i32 for the trace).
            position_setpoint_counts: saturate_counts(*setpoint),
            fault_code: i32::from(fault_code(out.fault)),
        });
        self.tick = self.tick.wrapping_add(1);
    }

    /// One velocity tick from its inputs, without a board (see [`App::step_current`]).
    #[inline]
    pub fn step_velocity(&mut self, inputs: VelocityInputs) -> VelocityOutputs {
        self.last_setpoint = inputs.setpoint;
        self.controller.velocity_tick(inputs)
    }
}

/// The PMSM drive's current tick (an app built by [`App::new_pmsm`]).
impl App {
    /// The body of a PMSM drive's current-loop interrupt: sample the encoder and two phase
    /// currents, run the core's `pmsm_tick`, set the three duties and the stage's enable,
    /// record the trend buffer (the q axis: `CurrentPu` is i_q, `CurrentRefPu` i_q*,
    /// `VoltageCmdPu` v_q).
    ///
    /// As [`App::on_current_tick`]: while held the core's ticks do not run (the duties of
    /// 0 V, the stage off); a missing sample runs the tick on zero currents and latches the
    /// sensor fault; the stage switches only while the core enables it, no fault is latched
    /// or input and the operator enabled it. On a DC drive's app the core commands nothing
    /// and the stage stays off.
    #[inline]
    pub fn on_pmsm_tick<I: PmsmLoopIo>(&mut self, io: &mut I) -> PmsmOutputs {
        let encoder_count = io.encoder_count();
        let phase_current_pu = match io.phase_currents_pu() {
            Some(i) => i,
            None => {
                self.sensor_fault = true;
                [Pu::ZERO; 2]
            }
        };
        let inputs = PmsmInputs {
            encoder_count,
            phase_current_pu,
        };
        let zero = self.zero_voltage_duties();
        let out = if self.held {
            // The electrical angle follows the shaft while held (see
            // `Controller::pmsm_track`).
            self.controller.pmsm_track(encoder_count);
            self.record_pmsm(encoder_count, &PmsmOutputs::default());
            PmsmOutputs {
                duties: zero,
                ..PmsmOutputs::default()
            }
        } else {
            self.step_pmsm(inputs)
        };
        let run = out.enabled
            && out.fault.is_none()
            && !self.sensor_fault
            && !self.fault_input_active
            && self.enable_request;
        let applied = io.set_duties(if run { out.duties } else { zero });
        let enabled = io.set_enable(run);
        if !(applied && enabled) {
            self.sensor_fault = true;
        }
        out
    }

    /// One PMSM current tick from sensor values, without a board: the code
    /// [`App::on_pmsm_tick`] runs between its board reads and writes (the loop-in-the-loop
    /// replay, the PIL image). Returns the core's outputs.
    #[inline]
    pub fn step_pmsm(&mut self, inputs: PmsmInputs) -> PmsmOutputs {
        let out = self.controller.pmsm_tick(inputs);
        if out.fault.is_some() {
            self.trace.trigger(self.tick, TriggerCause::Fault);
            if self.fault_tick.is_none() {
                self.fault_tick = Some(self.tick);
            }
        }
        self.record_pmsm(inputs.encoder_count, &out);
        out
    }

    /// The trend buffer's record of a PMSM tick: its q axis as the DC winding's current,
    /// reference and voltage.
    #[inline]
    fn record_pmsm(&mut self, encoder_count: u32, out: &PmsmOutputs) {
        // In the counts' direction, as the torque side's signals (`q_in_count_direction`).
        let (mut current, mut voltage, mut reference) =
            (out.current.q, out.voltage.q, out.current_ref.q);
        if self.controller.encoder_reversed() {
            current = current.saturating_neg();
            voltage = voltage.saturating_neg();
            reference = reference.saturating_neg();
        }
        self.record_trace(
            &CurrentInputs {
                encoder_count,
                current_pu: current,
            },
            &CurrentOutputs {
                voltage_cmd_pu: voltage,
                current_ref_pu: reference,
                accel_fb_pu: out.accel_fb_pu,
                fault: out.fault,
            },
        );
    }

    /// Whether the drive is a PMSM (its current tick is [`App::on_pmsm_tick`]).
    #[must_use]
    pub fn is_pmsm(&self) -> bool {
        self.controller.foc().is_some()
    }

    /// The duties of 0 V (each half the PWM period) of a PMSM drive; zeros on a DC drive.
    #[must_use]
    pub fn zero_voltage_duties(&self) -> [u16; 3] {
        [self.controller.foc().map_or(0, |f| f.svpwm.period() / 2); 3]
    }
}

fn saturate_counts(sp: Setpoint) -> i32 {
    let whole = sp.position_counts.to_bits() >> 16;
    i32::try_from(whole).unwrap_or(if whole < 0 { i32::MIN } else { i32::MAX })
}
