//! The firmware in QEMU as a [`ControlBackend`], and a recorder of any backend's ticks.

use controller_core::{
    CurrentInputs, CurrentOutputs, Fault, PmsmInputs, PmsmOutputs, VelocityInputs, VelocityOutputs,
};
use pil_link::host::{HostError, HostLink, Stream};
use pil_link::tick::{Commands, Sensors};
use pil_link::wire::Writer;
use sim_engine::engine::runner::ControlBackend;

/// Every controller input and output of a run, in tick order (raw fixed-point values).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TickLog {
    /// Current ticks.
    pub current: Vec<(CurrentInputs, CurrentOutputs)>,
    /// Velocity ticks.
    pub velocity: Vec<(VelocityInputs, VelocityOutputs)>,
    /// Current ticks of a PMSM drive (in place of `current`).
    pub pmsm: Vec<(PmsmInputs, PmsmOutputs)>,
}

/// A backend that records every tick of another.
pub struct Recorder<B> {
    /// The backend recorded.
    pub inner: B,
    /// What it saw and answered.
    pub log: TickLog,
}

impl<B: ControlBackend> ControlBackend for Recorder<B> {
    fn halted(&self) -> bool {
        self.inner.halted()
    }

    fn excitation_pu(&self) -> f64 {
        self.inner.excitation_pu()
    }

    fn finished(&mut self) {
        self.inner.finished();
    }

    fn current_tick(&mut self, inputs: CurrentInputs) -> CurrentOutputs {
        let out = self.inner.current_tick(inputs);
        self.log.current.push((inputs, out));
        out
    }

    fn velocity_tick(&mut self, inputs: VelocityInputs) -> VelocityOutputs {
        let out = self.inner.velocity_tick(inputs);
        self.log.velocity.push((inputs, out));
        out
    }

    fn pmsm_tick(&mut self, inputs: PmsmInputs) -> sim_engine::error::Result<PmsmOutputs> {
        let out = self.inner.pmsm_tick(inputs)?;
        self.log.pmsm.push((inputs, out));
        Ok(out)
    }
}

/// The firmware in QEMU as a [`ControlBackend`]. After a link fault it stops talking to the
/// firmware, answers with the safe state (zero commands, fault set) and reports itself
/// halted, so the runner stops at the next tick; [`super::run_pil`] then cuts the trace exactly at
/// the fault.
pub struct PilBackend {
    pub(super) link: HostLink<Stream>,
    pub(super) log: TickLog,
    pub(super) current_ticks: u64,
    pub(super) fault: Option<(HostError, u64)>,
    /// The excitation sample the firmware reported with its last current tick (Q16.16).
    pub(super) excitation_bits: i32,
    /// The `Stop` sent when the run's last tick was done ([`ControlBackend::finished`]), and
    /// how it went; `None` before, or after a fault.
    pub(super) stopped: Option<Result<(), HostError>>,
}

impl PilBackend {
    /// A backend on an open, configured link.
    pub(super) fn new(link: HostLink<Stream>) -> Self {
        Self {
            link,
            log: TickLog::default(),
            current_ticks: 0,
            fault: None,
            excitation_bits: 0,
            stopped: None,
        }
    }

    /// Ends a run without a fault: the `Stop` sent at its last tick, or now if the runner
    /// did not say it finished.
    pub(super) fn stop(&mut self) -> Result<(), HostError> {
        match self.stopped.take() {
            Some(result) => result,
            None => self.link.stop(),
        }
    }

    /// Every tick the firmware answered so far.
    pub fn log(&self) -> &TickLog {
        &self.log
    }

    fn exchange(&mut self, sensors: Sensors) -> Option<Commands> {
        if self.fault.is_some() {
            return None;
        }
        let mut w = Writer::new();
        let result = sensors
            .encode(&mut w)
            .map_err(HostError::Link)
            .and_then(|()| self.link.tick(w.as_slice()))
            .and_then(|frame| Commands::decode(frame.payload()).map_err(HostError::Link));
        match result {
            Ok(c) => Some(c),
            Err(e) => {
                self.fault = Some((e, self.current_ticks));
                None
            }
        }
    }
}

const SAFE_CURRENT: CurrentOutputs = CurrentOutputs {
    voltage_cmd_pu: controller_core::Pu::ZERO,
    current_ref_pu: controller_core::Pu::ZERO,
    accel_fb_pu: controller_core::Pu::ZERO,
    fault: Some(Fault::External),
};

/// A PMSM tick's safe state: the switches open, the fault set.
fn safe_pmsm() -> PmsmOutputs {
    PmsmOutputs {
        enabled: false,
        fault: Some(Fault::External),
        ..PmsmOutputs::default()
    }
}

impl ControlBackend for PilBackend {
    fn halted(&self) -> bool {
        self.fault.is_some()
    }

    fn finished(&mut self) {
        if self.fault.is_none() && self.stopped.is_none() {
            self.stopped = Some(self.link.stop());
        }
    }

    fn excitation_pu(&self) -> f64 {
        sim_engine::engine::plant::f(controller_core::Pu::from_bits(self.excitation_bits))
    }

    fn current_tick(&mut self, inputs: CurrentInputs) -> CurrentOutputs {
        let out = match self.exchange(Sensors::Current(inputs)) {
            Some(Commands::Current(out, applied)) => {
                self.log.current.push((inputs, out));
                self.excitation_bits = applied.excitation_bits;
                out
            }
            Some(Commands::Velocity(_) | Commands::Pmsm(..)) => {
                self.fault = Some((wrong_reply(), self.current_ticks));
                SAFE_CURRENT
            }
            None => SAFE_CURRENT,
        };
        self.current_ticks += 1;
        out
    }

    fn pmsm_tick(&mut self, inputs: PmsmInputs) -> sim_engine::error::Result<PmsmOutputs> {
        let out = match self.exchange(Sensors::Pmsm(inputs)) {
            Some(Commands::Pmsm(out, applied)) => {
                self.log.pmsm.push((inputs, out));
                self.excitation_bits = applied.excitation_bits;
                out
            }
            Some(Commands::Current(..) | Commands::Velocity(_)) => {
                self.fault = Some((wrong_reply(), self.current_ticks));
                safe_pmsm()
            }
            None => safe_pmsm(),
        };
        self.current_ticks += 1;
        Ok(out)
    }

    fn velocity_tick(&mut self, inputs: VelocityInputs) -> VelocityOutputs {
        let safe = VelocityOutputs {
            fault: Some(Fault::External),
            ..VelocityOutputs::default()
        };
        match self.exchange(Sensors::Velocity(inputs)) {
            Some(Commands::Velocity(out)) => {
                self.log.velocity.push((inputs, out));
                out
            }
            Some(Commands::Current(..) | Commands::Pmsm(..)) => {
                self.fault = Some((wrong_reply(), self.current_ticks));
                safe
            }
            None => safe,
        }
    }
}

fn wrong_reply() -> HostError {
    HostError::Link(pil_link::LinkError::BadPayload {
        kind: pil_link::FrameKind::Commands as u8,
        len: 0,
    })
}
