//! Loop-in-the-loop on the target (`cargo fw-lil`, QEMU): replays the recorded sensor
//! sequence through the firmware's tick code (`App::on_current_tick` /
//! `App::on_velocity_tick`, as the interrupts call them) on the Cortex-M4F and compares every
//! output word with the expectation the HOST build of controller-core computed at build
//! time (`build.rs`). Exits 0 only if all words match bit for bit and the run is complete.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use cortex_m_rt::entry;
    use firmware::lil;
    use firmware::rt::exit;

    #[entry]
    fn main() -> ! {
        let report = match lil::replay_embedded() {
            Ok(r) => r,
            Err(e) => {
                defmt::error!("fw-lil: bad settings: {}", defmt::Debug2Format(&e));
                exit(false)
            }
        };
        defmt::info!(
            "fw-lil: {=u32} periods, {=u32} output words compared with the host core, {=u32} mismatches, {=u32} missing, digest {=u32:#010x}, {=u32} ticks enabled, final fault code {=u8}",
            report.periods,
            report.words,
            report.mismatches,
            report.missing_words,
            report.digest,
            report.enabled_ticks,
            controller_core::words::fault_code(report.final_fault)
        );
        if let Some(m) = report.first_mismatch {
            defmt::error!(
                "first mismatch: period {=u32}, word {=u32}: host {=u32:#010x}, target {=u32:#010x}",
                m.period,
                m.word,
                m.expected,
                m.actual
            );
        }
        let pass = report.periods > 0 && report.mismatches == 0 && report.missing_words == 0;
        if pass {
            defmt::info!("fw-lil: PASS (bit-identical to the host build of controller-core)");
        } else {
            defmt::error!("fw-lil: FAIL");
        }
        exit(pass)
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "fw-lil: runs in QEMU: cargo fw-lil (the host comparison is `cargo test -p firmware`)"
    );
}
