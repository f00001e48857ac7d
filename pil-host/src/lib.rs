//! Processor in the loop: the same scenarios as `run`, with the controller replaced by the
//! firmware binary running in QEMU (mps2-an386, Cortex-M4F), one `pil-link` frame exchange
//! per controller tick in lock step, so QEMU's speed does not matter.
//!
//! * [`settings`]: one run's scenario and its firmware, QEMU and link settings, with their
//!   ranges;
//! * [`backend`]: the firmware as a control backend, and a tick recorder;
//! * [`session`]: QEMU, the link, the run, the fault handling and the files;
//! * [`image`]: building the firmware's `pil` image;
//! * [`compare`](mod@compare): the bit-for-bit comparison with the host run;
//! * [`comparison_markdown`]: its Markdown (`pil-comparison.md`), from the typed results;
//! * [`board`](mod@board), [`board_scope`]: `stiffdrive board`, the board console session (on a
//!   serial port, or the `board` image in QEMU) and its scope recording; [`board_identify`],
//!   [`board_calibrate`]: the records of the board's own measurements and calibration.
//!
//! Files in `--out` DIR: `trace.csv`, `summary.json`, `trace.svg/png` (as `run`), plus
//! `pil.json` (link statistics, fault), `pil-comparison.json` and `pil-comparison.md` (the
//! bit-for-bit comparison with the host run of the same scenario), `firmware.defmt` (the
//! firmware's defmt log) and `firmware.log` (decoded in-process by `fw-runner`'s defmt decoder).
//!
//! `summary.json`'s oscillation verdict follows the same rule as a host run's; a
//! `limit_cycle` is confirmed by rerunning the scenario with the encoder interpolated
//! (the rule's step 5) on the host build of controller-core, which the comparison checks
//! bit for bit against the firmware at the run's own encoder. A run cut at a link fault
//! keeps its verdict unconfirmed (`interpolated_amplitude_pu` is `null`).
//!
//! On a link fault (lost, corrupted or late frame, seen by either side) the run stops
//! driving the firmware at that tick, waits for the firmware to show its latched safe state,
//! writes the trace up to the fault and returns an error naming both sides' view.

pub mod backend;
pub mod board;
pub mod board_calibrate;
pub mod board_identify;
pub mod board_scope;
pub mod compare;
pub mod image;
pub mod session;
pub mod settings;

pub use backend::{PilBackend, Recorder, TickLog};
pub use compare::{compare, Comparison, Mismatch};
pub use image::{build_pil_image, build_pil_image_with, firmware_target_dir, with_all_images};
/// Where QEMU puts the firmware's UART ([`PilRun::port`]).
pub use pil_link::qemu::LinkPort;
pub use session::{run_pil, with_firmware, FirmwareFault, LinkFault, LinkReport, PilOutcome};
pub use settings::{PilRun, DEFAULT_REPLY_TIMEOUT_MS, DEFAULT_WATCHDOG_MS, REPLY_TIMEOUT_MS};

use sim_engine::error::{HarnessError, Result};

fn firmware_view(f: &LinkFault) -> String {
    f.firmware.as_ref().map_or_else(
        || "the firmware never reported a latched safe state".to_string(),
        |r| {
            format!(
                "firmware latched {}; its outputs are {} (torque bits {}, PWM voltage bits {}, \
                 enable pin {}, tick after the fault {})",
                r.code,
                if r.outputs_safe { "safe" } else { "NOT SAFE" },
                r.torque_cmd_bits,
                r.pwm_voltage_bits,
                if r.enable_pin { "high" } else { "low" },
                if r.current_tick_ran {
                    "ran"
                } else {
                    "did not run"
                }
            )
        },
    )
}

/// `hil-harness pil`: runs, writes DIR, returns the line to print; a link fault is an error
/// (after the trace up to it has been written).
pub fn pil_command(args: &PilRun) -> Result<String> {
    let o = run_pil(args)?;
    if let Some(f) = &o.link.fault {
        return Err(HarnessError::Backend(format!(
            "PIL link fault at t = {:.4} s (current tick {}): {}; {}; trace up to the fault \
             written to {}",
            f.t_s,
            f.at_current_tick,
            f.harness_error,
            firmware_view(f),
            o.out.display()
        )));
    }
    let cmp = match &o.comparison {
        None => "not compared".to_string(),
        Some(c) if c.bit_identical => format!(
            "bit-identical to the host run ({} current + {} velocity ticks)",
            c.current_ticks, c.velocity_ticks
        ),
        Some(c) => format!(
            "DIFFERS from the host run: {} mismatched values",
            c.mismatches
        ),
    };
    let message = format!(
        "{} (PIL, firmware in QEMU): {} frames, {:.0} µs per round trip, {:.2} s simulated in \
         {:.1} s; {cmp} -> {}",
        o.cfg.name,
        o.link.frames,
        o.link.round_trip_us,
        o.run.sim_time_s,
        o.link.wall_time_s,
        o.out.display()
    );
    match &o.comparison {
        Some(c) if !c.bit_identical => Err(HarnessError::Backend(message)),
        _ => Ok(message),
    }
}

/// The Markdown of a run's comparison with its link statistics: `pil-comparison.md`, and
/// the section REPORT.md gives a PIL run.
pub fn comparison_markdown(c: &Comparison, l: &LinkReport) -> String {
    let scenario = &c.scenario;
    let verdict = if c.bit_identical {
        "**bit-identical**: the firmware binary on the Cortex-M4F controls the simulated \
         machine exactly as the host build of controller-core does"
    } else {
        "**NOT bit-identical**"
    };
    let mut text = format!(
        "## Processor in the loop: `{scenario}` through the firmware in QEMU\n\n\
         Command: `cargo run --release -- pil --scenario {scenario} --out DIR`.\n\
         The firmware's `pil` image (version {}) runs in QEMU mps2-an386 \
         (Cortex-M4F); every controller tick the harness sends the sampled encoder count \
         and current (or the velocity setpoint) in a CRC-32 framed `pil-link` frame over \
         UART0, the firmware pends its TIMER0/TIMER1 interrupt, whose handler runs the \
         drive's interrupt body, and returns the commands; the harness then advances the \
         plant. Lock step, so QEMU's speed does not matter.\n\n\
         | quantity | value |\n|---|---|\n\
         | current ticks compared | {} |\n\
         | velocity ticks compared | {} |\n\
         | output values compared (raw fixed-point bits) | {} |\n\
         | mismatches | {} |\n\
         | controller inputs identical | {} |\n\
         | trace (plant states included) identical | {} |\n\
         | link frames | {} |\n\
         | mean wall time per frame (QEMU round trip + plant step) | {:.0} µs |\n\
         | wall time of the closed loop | {:.1} s |\n\n\
         Verdict: {verdict}.\n",
        l.firmware_version,
        c.current_ticks,
        c.velocity_ticks,
        c.values_compared,
        c.mismatches,
        c.inputs_identical,
        c.trace_identical,
        l.frames,
        l.round_trip_us,
        l.wall_time_s,
    );
    if let Some(m) = &c.first_mismatch {
        text.push_str(&format!(
            "\nFirst mismatch: {} tick {}, `{}`: host bits {}, firmware bits {}\n",
            m.tick_loop, m.index, m.field, m.host_bits, m.pil_bits
        ));
    }
    text
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::backend::TickLog;
    use super::compare::compare;
    use super::session::cut_at;
    use controller_core::Pu;
    use controller_core::{
        CurrentInputs, CurrentOutputs, Fault, PmsmInputs, PmsmOutputs, VelocityInputs,
        VelocityOutputs,
    };
    use sim_engine::config::resolve;
    use sim_engine::engine::metrics::compute;
    use sim_engine::engine::runner::RunOutput;
    use sim_engine::engine::trace::{Trace, TraceRow};

    fn log(n: usize) -> TickLog {
        let mut l = TickLog::default();
        for k in 0..n {
            let i = CurrentInputs {
                encoder_count: k as u32,
                current_pu: Pu::from_bits(k as i32),
            };
            let o = CurrentOutputs {
                voltage_cmd_pu: Pu::from_bits(3 * k as i32),
                ..CurrentOutputs::default()
            };
            l.current.push((i, o));
            if k % 2 == 0 {
                l.velocity
                    .push((VelocityInputs::default(), VelocityOutputs::default()));
            }
        }
        l
    }

    fn run_of(rows: usize) -> RunOutput {
        let trace = Trace {
            rows: (0..rows)
                .map(|k| TraceRow {
                    t_s: k as f64 * 5e-4,
                    ..TraceRow::default()
                })
                .collect(),
        };
        let windows = resolve("fig6", None, &[])
            .unwrap()
            .scenario
            .metric_windows(2.0);
        let metrics = compute(&trace, &windows);
        RunOutput {
            trace,
            metrics,
            sim_time_s: 0.0,
            wall_time_s: 0.0,
            ticks: 0,
            fault: None,
            protection: Default::default(),
        }
    }

    #[test]
    fn identical_logs_compare_bit_identical() {
        let c = compare("t", &log(10), &log(10), &run_of(5), &run_of(5));
        assert!(c.bit_identical, "{c:?}");
        assert_eq!(c.values_compared, 10 * 4 + 5 * 8);
    }

    #[test]
    fn one_lsb_anywhere_is_a_mismatch() {
        let host = log(10);
        let mut pil = log(10);
        pil.current[7].1.voltage_cmd_pu =
            Pu::from_bits(pil.current[7].1.voltage_cmd_pu.to_bits() + 1);
        pil.velocity[3].1.fault = Some(Fault::External);
        let c = compare("t", &host, &pil, &run_of(5), &run_of(5));
        assert!(!c.bit_identical);
        assert_eq!(c.mismatches, 2);
        assert_eq!(c.per_field.get("current.voltage_cmd_pu"), Some(&1));
        assert_eq!(c.per_field.get("velocity.fault"), Some(&1));
        let m = c.first_mismatch.unwrap();
        assert_eq!((m.tick_loop.as_str(), m.index), ("current", 7));
    }

    #[test]
    fn missing_ticks_or_trace_rows_are_not_identical() {
        let c = compare("t", &log(10), &log(9), &run_of(5), &run_of(5));
        assert!(!c.bit_identical && !c.inputs_identical);
        let mut other = run_of(5);
        other.trace.rows[2].motor_vel_pu = 1e-300;
        let c = compare("t", &log(10), &log(10), &run_of(5), &other);
        assert!(!c.bit_identical && !c.trace_identical);
    }

    fn pmsm_log(n: u32) -> TickLog {
        let mut l = TickLog::default();
        for k in 0..n {
            let i = PmsmInputs {
                encoder_count: k,
                phase_current_pu: [Pu::from_bits(k as i32), Pu::from_bits(-(k as i32))],
            };
            let o = PmsmOutputs {
                duties: [2100, 2100 + k as u16, 2100],
                enabled: true,
                ..PmsmOutputs::default()
            };
            l.pmsm.push((i, o));
        }
        l
    }

    #[test]
    fn a_pmsm_drives_ticks_are_compared_word_by_word() {
        let host = pmsm_log(6);
        let c = compare("t", &host, &pmsm_log(6), &run_of(3), &run_of(3));
        assert!(c.bit_identical, "{c:?}");
        assert_eq!((c.current_ticks, c.values_compared), (6, 6 * 13));
        let mut pil = pmsm_log(6);
        pil.pmsm[4].1.duties[1] += 1;
        let c = compare("t", &host, &pil, &run_of(3), &run_of(3));
        assert!(!c.bit_identical);
        assert_eq!(c.per_field.get("pmsm.duty_b"), Some(&1));
        let m = c.first_mismatch.unwrap();
        assert_eq!((m.tick_loop.as_str(), m.index), ("pmsm", 4));
        // A tick missing, or a changed phase current sample: not identical.
        let c = compare("t", &host, &pmsm_log(5), &run_of(3), &run_of(3));
        assert!(!c.bit_identical);
        let mut pil = pmsm_log(6);
        pil.pmsm[2].0.phase_current_pu[1] = Pu::from_bits(7);
        let c = compare("t", &host, &pil, &run_of(3), &run_of(3));
        assert!(!c.bit_identical && !c.inputs_identical && c.mismatches == 0);
    }

    #[test]
    fn the_recorder_logs_a_pmsm_drives_current_ticks() {
        use sim_engine::engine::runner::{controller, ControlBackend};
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../configs/machines/table1-pmsm.toml"
        );
        let cfg = resolve("fig6", Some(path), &[]).unwrap();
        let mut alone = controller(&cfg).unwrap();
        let mut rec = super::Recorder {
            inner: controller(&cfg).unwrap(),
            log: TickLog::default(),
        };
        for k in 0..20_u32 {
            let i = PmsmInputs {
                encoder_count: 3 * k,
                phase_current_pu: [Pu::from_bits(100 * k as i32), Pu::ZERO],
            };
            let out = rec.pmsm_tick(i).unwrap();
            assert_eq!(out, alone.pmsm_tick(i));
            assert_eq!(rec.log.pmsm.last(), Some(&(i, out)));
        }
        assert_eq!((rec.log.pmsm.len(), rec.log.current.len()), (20, 0));
    }

    #[test]
    fn the_trace_is_cut_before_the_fault() {
        let cfg = resolve("fig6", None, &[]).unwrap();
        let mut run = run_of(100);
        cut_at(&mut run, &cfg, 0.01);
        assert_eq!(run.trace.rows.len(), 20);
        assert!(run.trace.rows.iter().all(|r| r.t_s < 0.01));
    }
}
