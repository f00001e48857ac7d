//! A PMSM's motor calibration run on the board (`pil_link::board::calibrate`): the
//! current-loop interrupt runs controller-core's excitation sequencer
//! ([`Calibration`], the one the host's simulated calibration drives) on the three-phase
//! stage alone. Each tick it reads the encoder and the two phase currents, runs the
//! sequencer on the α current, turns its voltage into the three duties with the drive's
//! modulator (`[drive.pmsm]`'s bus and PWM period, [`duties_for_voltage`]), switches the
//! stage on and sets them, and returns the tick's row for the record. No current loop and
//! no encoder offset: an uncalibrated drive runs it. After the last tick the stage is off.
//!
//! The order within a tick is the host's (`machine-workflows/src/calibrate/record.rs`):
//! the samples of the tick's start, then the voltage, which acts over the next period.

use controller_core::foc::calibration::{Calibration, CalibrationState};
use controller_core::foc::{clarke, Svpwm};
use controller_core::{ConfigError, DriveConfig};
use pil_link::board::calibrate::CalibrationRow;

use crate::board::three_phase::{duties_for_voltage, PmsmLoopIo};

/// One calibration run: the sequence, its state and the drive's modulator.
#[derive(Clone, Copy, Debug)]
pub struct CalibrationRun {
    seq: Calibration,
    state: CalibrationState,
    svpwm: Svpwm,
}

/// Why a tick ended the run early.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TickEnd {
    /// Every tick of the sequence ran.
    Done,
    /// No current sample came, or the stage refused the duties or the enable.
    Stage,
}

impl CalibrationRun {
    /// The run of `seq` on the stage of the PMSM drive `cfg`.
    ///
    /// # Errors
    /// The drive's modulator refused (naming `pmsm.dc_bus_pu` or `pmsm.pwm_period_counts`);
    /// a drive without `[drive.pmsm]` is `ConfigError::Missing` of `pmsm`.
    pub fn new(cfg: &DriveConfig, seq: Calibration) -> Result<Self, ConfigError> {
        let p = cfg.pmsm.ok_or(ConfigError::Missing {
            param: "pmsm",
            measure: "a machine file whose [electrics] motor = \"pmsm\"",
        })?;
        Ok(Self {
            seq,
            state: CalibrationState::default(),
            svpwm: Svpwm::new(p.dc_bus_pu, p.pwm_period_counts)?,
        })
    }

    /// Ticks of the whole run.
    #[must_use]
    pub fn total_ticks(&self) -> u32 {
        self.seq.total_ticks()
    }

    /// The duties of 0 V (half the period on each phase).
    #[must_use]
    pub fn zero_duties(&self) -> [u16; 3] {
        [self.svpwm.period() / 2; 3]
    }

    /// One tick on `io`: the row it recorded, or why the run is over (the stage is then
    /// off: [`Self::stop`]).
    ///
    /// # Errors
    /// [`TickEnd`]: the sequence is over, or the stage failed.
    pub fn tick<I: PmsmLoopIo>(&mut self, io: &mut I) -> Result<CalibrationRow, TickEnd> {
        if self.state.tick >= self.seq.total_ticks() {
            self.stop(io);
            return Err(TickEnd::Done);
        }
        let count = io.encoder_count();
        let Some([i_a, i_b]) = io.phase_currents_pu() else {
            self.stop(io);
            return Err(TickEnd::Stage);
        };
        let t = self.seq.tick(&mut self.state, clarke(i_a, i_b).alpha);
        let duties = duties_for_voltage(&self.svpwm, t.voltage);
        // On first: the duties act from this tick, as on the host's plant.
        if !(io.set_enable(true) && io.set_duties(duties)) {
            self.stop(io);
            return Err(TickEnd::Stage);
        }
        Ok(CalibrationRow {
            stage: t.stage,
            v_alpha: t.voltage.alpha,
            v_beta: t.voltage.beta,
            phase: t.phase,
            i_a,
            i_b,
            count,
        })
    }

    /// The stage off, the duties of 0 V.
    pub fn stop<I: PmsmLoopIo>(&self, io: &mut I) {
        let _ = io.set_enable(false);
        let _ = io.set_duties(self.zero_duties());
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use controller_core::foc::calibration::{CalibrationSettings, Stage};
    use controller_core::per_unit::Pu;

    /// A stage that records what it was asked; its currents follow the α voltage.
    #[derive(Default)]
    struct Stage3 {
        enabled: bool,
        duties: Vec<[u16; 3]>,
        i: Pu,
        missing_after: Option<usize>,
    }

    impl PmsmLoopIo for Stage3 {
        fn encoder_count(&mut self) -> u32 {
            self.duties.len() as u32
        }
        fn phase_currents_pu(&mut self) -> Option<[Pu; 2]> {
            match self.missing_after {
                Some(n) if self.duties.len() >= n => None,
                _ => Some([self.i, Pu::ZERO]),
            }
        }
        fn set_duties(&mut self, d: [u16; 3]) -> bool {
            self.duties.push(d);
            // 1 pu of α voltage makes 10 pu of current at once (R = 0.1 pu).
            let mean = (i64::from(d[0]) + i64::from(d[1]) + i64::from(d[2])) / 3;
            self.i = Pu::from_num(10.0 * 2.0 * (i64::from(d[0]) - mean) as f64 / 4200.0 / 3.0);
            true
        }
        fn set_enable(&mut self, on: bool) -> bool {
            self.enabled = on;
            true
        }
        fn fault_input(&mut self) -> bool {
            false
        }
    }

    fn drive() -> DriveConfig {
        crate::drive::reference_pmsm().unwrap()
    }

    fn short() -> Calibration {
        Calibration::new(&CalibrationSettings {
            settle_s: 0.01,
            record_s: 0.01,
            square_s: 0.01,
            turns: 2,
            sweep_hz: 100.0,
            ..CalibrationSettings::default()
        })
        .unwrap()
    }

    #[test]
    fn the_run_sets_the_sequencers_voltages_then_switches_the_stage_off() {
        let cfg = drive();
        let seq = short();
        let mut run = CalibrationRun::new(&cfg, seq).unwrap();
        let mut io = Stage3::default();
        let (mut rows, mut st) = (Vec::new(), CalibrationState::default());
        let mut host = Vec::new();
        while let Ok(row) = run.tick(&mut io) {
            assert!(io.enabled);
            let t = seq.tick(&mut st, clarke(row.i_a, row.i_b).alpha);
            host.push((t.stage, t.voltage.alpha, t.voltage.beta, t.phase));
            rows.push(row);
        }
        assert_eq!(rows.len() as u32, seq.total_ticks());
        let board: Vec<_> = rows
            .iter()
            .map(|r| (r.stage, r.v_alpha, r.v_beta, r.phase))
            .collect();
        assert_eq!(board, host, "the sequencer's own voltages, stage by stage");
        assert!(rows.iter().any(|r| r.stage == Stage::Backward));
        let p = cfg.pmsm.unwrap();
        let svpwm = Svpwm::new(p.dc_bus_pu, p.pwm_period_counts).unwrap();
        for (row, d) in rows.iter().zip(&io.duties) {
            let v = controller_core::foc::AlphaBeta {
                alpha: row.v_alpha,
                beta: row.v_beta,
            };
            assert_eq!(*d, svpwm.duties(v));
        }
        assert!(!io.enabled, "off after the last tick");
        assert_eq!(io.duties.last(), Some(&run.zero_duties()));
        assert_eq!(run.tick(&mut io), Err(TickEnd::Done));
    }

    #[test]
    fn a_missing_current_sample_ends_the_run_with_the_stage_off() {
        let mut run = CalibrationRun::new(&drive(), short()).unwrap();
        let mut io = Stage3 {
            missing_after: Some(5),
            ..Stage3::default()
        };
        let ok = core::iter::from_fn(|| run.tick(&mut io).ok()).count();
        assert_eq!(ok, 5);
        assert!(!io.enabled);
        let mut dc = drive();
        dc.pmsm = None;
        assert!(CalibrationRun::new(&dc, short()).is_err());
    }
}
