//! `pil-comparison.json`: the PIL run against the host run of the same scenario, every
//! controller output and every trace value bit for bit.

use super::backend::TickLog;
use controller_core::words::{CURRENT_FIELDS, VELOCITY_FIELDS};
use controller_core::{CurrentOutputs, PmsmOutputs, VelocityOutputs};
use serde::{Deserialize, Serialize};
use sim_engine::engine::runner::RunOutput;
use std::collections::BTreeMap;

/// The PIL run against the host run, bit for bit.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Comparison {
    /// Scenario.
    pub scenario: String,
    /// Current ticks compared (both runs; a PMSM drive's `pmsm` ticks).
    pub current_ticks: usize,
    /// Velocity ticks compared (both runs).
    pub velocity_ticks: usize,
    /// Tick counts of the host run (current, velocity), to show nothing is missing.
    pub host_ticks: (usize, usize),
    /// Output values compared.
    pub values_compared: usize,
    /// Output values whose raw bits differ.
    pub mismatches: usize,
    /// Mismatches per output field.
    pub per_field: BTreeMap<String, usize>,
    /// The first differing value.
    pub first_mismatch: Option<Mismatch>,
    /// The controller inputs (encoder, current, setpoint) were identical at every tick.
    pub inputs_identical: bool,
    /// Every trace value (plant states included) identical to the last bit.
    pub trace_identical: bool,
    /// All of the above: the firmware binary controls the machine as the host build does.
    pub bit_identical: bool,
}

/// One differing output value.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Mismatch {
    /// `current`, `pmsm` (a PMSM drive's current loop) or `velocity` loop.
    pub tick_loop: String,
    /// Tick index within that loop.
    pub index: usize,
    /// Field name.
    pub field: String,
    /// Raw bits on the host.
    pub host_bits: i64,
    /// Raw bits from the firmware.
    pub pil_bits: i64,
}

/// Each output word of a tick with its name, as the signed value of its bits (the fault
/// word is its code): controller-core's one layout ([`controller_core::words`]).
fn named(names: &[&'static str], words: &[u32]) -> Vec<(&'static str, i64)> {
    names
        .iter()
        .zip(words)
        .map(|(n, w)| (*n, i64::from(*w as i32)))
        .collect()
}

fn current_fields(o: &CurrentOutputs) -> Vec<(&'static str, i64)> {
    named(CURRENT_FIELDS, &o.to_words())
}

fn velocity_fields(o: &VelocityOutputs) -> Vec<(&'static str, i64)> {
    named(VELOCITY_FIELDS, &o.to_words())
}

/// The name of each word of [`PmsmOutputs::to_words`] (`controller_core::words`' layout).
const PMSM_FIELDS: [&str; PmsmOutputs::WORDS] = [
    "duty_a",
    "duty_b",
    "duty_c",
    "enabled",
    "i_d",
    "i_q",
    "i_d_ref",
    "i_q_ref",
    "v_d",
    "v_q",
    "torque_ref_pu",
    "accel_fb_pu",
    "fault",
];

fn pmsm_fields(o: &PmsmOutputs) -> Vec<(&'static str, i64)> {
    named(&PMSM_FIELDS, &o.to_words())
}

/// The output-value tally of a comparison.
#[derive(Default)]
struct Tally {
    per_field: BTreeMap<String, usize>,
    first: Option<Mismatch>,
    compared: usize,
    mismatches: usize,
}

impl Tally {
    fn note(
        &mut self,
        tick_loop: &str,
        index: usize,
        host: &[(&'static str, i64)],
        pil: &[(&'static str, i64)],
    ) {
        for (&(name, h), &(_, p)) in host.iter().zip(pil) {
            self.compared += 1;
            if h == p {
                continue;
            }
            self.mismatches += 1;
            *self
                .per_field
                .entry(format!("{tick_loop}.{name}"))
                .or_insert(0) += 1;
            self.first.get_or_insert_with(|| Mismatch {
                tick_loop: tick_loop.to_string(),
                index,
                field: name.to_string(),
                host_bits: h,
                pil_bits: p,
            });
        }
    }
}

fn same_inputs<I: PartialEq, O>(a: &[(I, O)], b: &[(I, O)]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|((x, _), (y, _))| x == y)
}

fn same_trace(a: &RunOutput, b: &RunOutput) -> bool {
    a.trace.rows.len() == b.trace.rows.len()
        && a.trace.rows.iter().zip(&b.trace.rows).all(|(r, s)| {
            r.values()
                .iter()
                .zip(s.values().iter())
                .all(|(x, y)| x.to_bits() == y.to_bits())
        })
}

/// Compares every controller output of two runs bit for bit.
pub fn compare(
    scenario: &str,
    host: &TickLog,
    pil: &TickLog,
    host_run: &RunOutput,
    pil_run: &RunOutput,
) -> Comparison {
    let mut tally = Tally::default();
    for (i, ((_, h), (_, p))) in host.current.iter().zip(&pil.current).enumerate() {
        tally.note("current", i, &current_fields(h), &current_fields(p));
    }
    for (i, ((_, h), (_, p))) in host.pmsm.iter().zip(&pil.pmsm).enumerate() {
        tally.note("pmsm", i, &pmsm_fields(h), &pmsm_fields(p));
    }
    for (i, ((_, h), (_, p))) in host.velocity.iter().zip(&pil.velocity).enumerate() {
        tally.note("velocity", i, &velocity_fields(h), &velocity_fields(p));
    }
    let inputs_identical = same_inputs(&host.current, &pil.current)
        && same_inputs(&host.pmsm, &pil.pmsm)
        && same_inputs(&host.velocity, &pil.velocity);
    let trace_identical = same_trace(host_run, pil_run);
    let complete = host.current.len() == pil.current.len()
        && host.pmsm.len() == pil.pmsm.len()
        && host.velocity.len() == pil.velocity.len()
        && !(pil.current.is_empty() && pil.pmsm.is_empty());
    let current = |l: &TickLog| l.current.len() + l.pmsm.len();
    Comparison {
        scenario: scenario.to_string(),
        current_ticks: current(host).min(current(pil)),
        velocity_ticks: host.velocity.len().min(pil.velocity.len()),
        host_ticks: (current(host), host.velocity.len()),
        values_compared: tally.compared,
        mismatches: tally.mismatches,
        per_field: tally.per_field,
        first_mismatch: tally.first,
        inputs_identical,
        trace_identical,
        bit_identical: complete && tally.mismatches == 0 && inputs_identical && trace_identical,
    }
}
