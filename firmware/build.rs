//! Build script of the firmware.
//!
//! 1. Linker scripts for embedded builds: the QEMU board uses the root `memory.x`
//!    (mps2-an386) and `link/device-qemu.x`; the STM32F4 board uses
//!    `link/memory-stm32f407.x` (its `device.x` comes from the `stm32f4` PAC), the
//!    three-phase board (`board-stm32f4-3ph`, a NUCLEO-F446RE) `link/memory-stm32f446re.x`.
//!    A `board-check.x` assertion fails the link if the other board's layout got in; on
//!    the three-phase board `link/check-three-phase-vectors.x` fails the `firmware` image's
//!    link unless its current loop is on the ADC vector. A three-phase build refuses a
//!    drive that is not a PMSM or whose current loop is not a whole number of PWM periods.
//! 2. The loop-in-the-loop expectation: the recorded input sequence (`lil/inputs.csv`, or
//!    `lil/inputs-pmsm.csv` for a PMSM drive) is run through the HOST build of
//!    controller-core (this script is compiled for the host), and
//!    the inputs plus the expected output words are written to `$OUT_DIR/lil_data.rs` for the
//!    `fw-lil` image, which runs the same sequence on the target and compares bit for bit.
//! 3. The drive: the machine file named by `STIFFDRIVE_DRIVE` (a path; a relative one is
//!    taken from the workspace root), else `configs/machines/table1.toml`, composed by the one
//!    composer the harness uses (`machine_file::compose`: its `[drive]` table, with the
//!    machine keys it omits taken from the plant), validated by `design()` (a bad file fails
//!    the build naming the key) and encoded with pil-link's settings codec into
//!    `$OUT_DIR/drive_settings.bin`, which the image decodes at start-up
//!    (`firmware::drive::baked`). The file's path and a checksum of the settings go into
//!    `$OUT_DIR/drive_name.txt`, which the image logs at boot. No field of the drive is
//!    spelled out here.
//! 4. The machine behind the QEMU `board` image's virtual motor: the same file's `[plant]`
//!    as plant-host derives its constants (`MechanicsConfig::derived`: K, D, g, ω_b), with
//!    the motor inertia and the two viscous frictions, into `$OUT_DIR/virtual_machine.rs`
//!    (`firmware::drive::coupling`). Always the dead zone; the file's sensors' noise and
//!    the computational delay are not modelled there. For a PMSM file, its `[electrics]`
//!    into `$OUT_DIR/virtual_pmsm.rs` (`firmware::drive::pmsm_machine`): the QEMU images'
//!    virtual PMSM (`firmware::virtual_pmsm`), the motor's truth.
use std::{env, fs, path::PathBuf};

use controller_core::DriveConfig;

#[path = "src/lil/words.rs"]
#[allow(dead_code)]
mod words;

// The three-phase board's table and arithmetic: the build refuses a drive whose current
// loop is not a whole number of PWM periods there.
#[path = "src/board/three_phase.rs"]
#[allow(dead_code)]
mod three_phase;

/// The reference PMSM drive (from the workspace root).
const REFERENCE_PMSM_PATH: &str = "configs/machines/table1-pmsm.toml";

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap_or_default());
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=../memory.x");
    println!("cargo:rerun-if-changed=link");
    println!("cargo:rerun-if-changed=lil/inputs.csv");
    println!("cargo:rerun-if-changed=lil/inputs-pmsm.csv");
    println!("cargo:rerun-if-changed=src/lil/words.rs");
    println!("cargo:rerun-if-changed=src/board/three_phase.rs");
    println!("cargo:rerun-if-env-changed=STIFFDRIVE_DRIVE");

    let root = manifest.join("..");
    let drive_file = match env::var_os("STIFFDRIVE_DRIVE") {
        Some(p) if !p.is_empty() => root.join(p),
        _ => root.join(machine_file::TABLE1_PATH),
    };
    println!("cargo:rerun-if-changed={}", drive_file.display());
    let three_phase = env::var_os("CARGO_FEATURE_BOARD_STM32F4_3PH").is_some();
    let cfg = match bake_drive(&drive_file, &root, &out, three_phase) {
        Ok(cfg) => cfg,
        Err(e) => {
            eprintln!("drive settings ({}): {e}", drive_file.display());
            std::process::exit(1);
        }
    };
    if let Err(e) = bake_reference_pmsm(&root, &out) {
        eprintln!("reference PMSM drive ({REFERENCE_PMSM_PATH}): {e}");
        std::process::exit(1);
    }
    if let Err(e) = write_lil_data(&cfg, &manifest.join("lil"), &out) {
        // A broken recording must fail the build, not produce an empty test.
        eprintln!("loop-in-the-loop data: {e}");
        std::process::exit(1);
    }

    let target = env::var("TARGET").unwrap_or_default();
    if !target.starts_with("thumb") {
        return;
    }
    let stm32 = env::var_os("CARGO_FEATURE_BOARD_STM32F4").is_some();
    // memory.x of the board (found through this -L path: link/lld.sh links from an empty
    // directory so the root memory.x in the working directory cannot shadow it), and a
    // check script that fails the link if the wrong layout got in anyway.
    let copies: &[(&str, &str)] = if three_phase {
        &[
            ("link/memory-stm32f446re.x", "memory.x"),
            ("link/check-stm32f446re.x", "board-check.x"),
            ("link/check-three-phase-vectors.x", "three-phase-vectors.x"),
        ]
    } else if stm32 {
        &[
            ("link/memory-stm32f407.x", "memory.x"),
            ("link/check-stm32f407.x", "board-check.x"),
        ]
    } else {
        &[
            ("../memory.x", "memory.x"),
            ("link/device-qemu.x", "device.x"),
            ("link/check-qemu.x", "board-check.x"),
        ]
    };
    for (from, to) in copies {
        if let Err(e) = fs::copy(manifest.join(from), out.join(to)) {
            eprintln!("cannot copy {from}: {e}");
            std::process::exit(1);
        }
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg=-Tboard-check.x");
    if three_phase {
        // The image's current loop must sit on the ADC vector (the other binaries of the
        // package keep the DC board's timers).
        println!("cargo:rustc-link-arg-bin=firmware=-Tthree-phase-vectors.x");
    }
}

/// The `[plant]` of the machine file as the virtual motor's coupling: a Rust expression
/// `(motor inertia, Coupling { .. })` for `include!`.
fn write_coupling(plant: &plant_host::PlantConfig, out: &std::path::Path) -> Result<(), String> {
    let m = &plant.mechanics;
    let d = m.derived();
    let fields = [
        ("load_inertia_s", m.load_inertia_s),
        ("stiffness_pu_per_rad", d.stiffness_pu_per_rad),
        ("damping_pu", d.damping_pu),
        ("half_gap_rad", d.half_gap_rad),
        ("base_speed_rad_s", d.base_speed_rad_s),
        ("motor_viscous_pu", m.motor_viscous_pu),
        ("load_viscous_pu", m.load_viscous_pu),
    ];
    let mut text = format!(
        "({:?}_f32, crate::virtual_motor::Coupling {{\n",
        m.motor_inertia_s as f32
    );
    for (name, v) in fields {
        text.push_str(&format!("    {name}: {:?}_f32,\n", v as f32));
    }
    text.push_str("})\n");
    fs::write(out.join("virtual_machine.rs"), text).map_err(|e| e.to_string())
}

/// The `[electrics]` of a PMSM machine file as the QEMU images' virtual PMSM: a Rust
/// expression `Option<PmsmMachine>` for `include!` (`None` for a DC motor), the file's
/// values as they are (`firmware::virtual_pmsm` works out the rest).
fn write_pmsm_machine(
    plant: &plant_host::PlantConfig,
    out: &std::path::Path,
) -> Result<(), String> {
    let e = &plant.electrics;
    let text = match (
        e.motor,
        e.pole_pairs,
        e.d_inductance_pu_s,
        e.q_inductance_pu_s,
        e.dc_bus_pu,
        e.encoder_offset_elec_deg,
    ) {
        (plant_host::MotorKind::Pmsm, Some(p), Some(ld), Some(lq), Some(bus), Some(offset)) => {
            let fields = [
                ("resistance_pu", e.winding_resistance_pu),
                ("d_inductance_pu_s", ld),
                ("q_inductance_pu_s", lq),
                ("flux_linkage_pu", e.flux_linkage_pu.unwrap_or(1.0)),
                ("dc_bus_pu", bus),
                ("encoder_offset_elec_deg", offset),
                ("computational_delay_s", e.computational_delay_s),
                ("current_full_scale_pu", e.current_full_scale_pu),
            ];
            let mut text = format!(
                "Some(crate::virtual_pmsm::PmsmMachine {{\n    pole_pairs: {p},\n    \
                 current_adc_bits: {},\n    encoder_reversed: {},\n",
                e.current_adc_bits,
                e.encoder_reversed.unwrap_or(false)
            );
            for (name, v) in fields {
                text.push_str(&format!("    {name}: {:?}_f32,\n", v as f32));
            }
            text.push_str("})\n");
            text
        }
        _ => "None\n".to_string(),
    };
    fs::write(out.join("virtual_pmsm.rs"), text).map_err(|e| e.to_string())
}

/// Compose, validate and encode the drive of `toml_path` into `drive_settings.bin`, and its
/// name (path below `root`, settings checksum) into `drive_name.txt`; the drive as the image
/// will decode it.
fn bake_drive(
    toml_path: &std::path::Path,
    root: &std::path::Path,
    out: &std::path::Path,
    three_phase: bool,
) -> Result<DriveConfig, String> {
    let machine = machine_file::load(toml_path).map_err(|e| e.to_string())?;
    if three_phase {
        check_three_phase(&machine.drive)?;
    }
    // A PMSM drive builds for every QEMU image: fw-lil and fw-bench run it (`App::new_pmsm`),
    // an image whose board drives one DC winding refuses it at start-up (`App::new`).
    write_coupling(&machine.plant, out)?;
    write_pmsm_machine(&machine.plant, out)?;
    let (back, bytes) = encode_drive(&machine.drive)?;
    let bytes = bytes.as_slice();
    fs::write(out.join("drive_settings.bin"), bytes).map_err(|e| e.to_string())?;
    let shown = toml_path
        .canonicalize()
        .ok()
        .and_then(|p| {
            let root = root.canonicalize().ok()?;
            p.strip_prefix(&root).ok().map(|p| p.to_path_buf())
        })
        .unwrap_or_else(|| toml_path.to_path_buf());
    let name = format!("{} (settings crc {:08x})", shown.display(), crc32(bytes));
    fs::write(out.join("drive_name.txt"), name).map_err(|e| e.to_string())?;
    Ok(back)
}

/// Validate `cfg` by `design()` and encode it with pil-link's settings codec: the drive as
/// the image decodes it (the reference runs use the decoded drive too) and the bytes.
fn encode_drive(cfg: &DriveConfig) -> Result<(DriveConfig, Vec<u8>), String> {
    controller_core::design(cfg).map_err(|e| format!("drive.{}: {e}", e.param()))?;
    let mut w = pil_link::wire::Writer::new();
    pil_link::settings::encode(cfg, &mut w).map_err(|e| format!("encode: {e}"))?;
    let bytes = w.as_slice().to_vec();
    let back = pil_link::settings::decode(&bytes).map_err(|e| format!("decode: {e:?}"))?;
    if back != *cfg {
        return Err("settings codec does not round-trip the drive".into());
    }
    Ok((back, bytes))
}

/// The reference PMSM drive, `configs/machines/table1-pmsm.toml` whatever `STIFFDRIVE_DRIVE`
/// names, into `pmsm_settings.bin` (`firmware::drive::reference_pmsm`): `fw-bench`'s second
/// drive and the host tests' PMSM.
fn bake_reference_pmsm(root: &std::path::Path, out: &std::path::Path) -> Result<(), String> {
    let path = root.join(REFERENCE_PMSM_PATH);
    println!("cargo:rerun-if-changed={}", path.display());
    let machine = machine_file::load(&path).map_err(|e| e.to_string())?;
    if machine.drive.pmsm.is_none() {
        return Err(format!("{REFERENCE_PMSM_PATH}: not a PMSM drive"));
    }
    let (_, bytes) = encode_drive(&machine.drive)?;
    fs::write(out.join("pmsm_settings.bin"), bytes).map_err(|e| e.to_string())
}

/// The three-phase image (`board-stm32f4-3ph`) runs a PMSM drive whose current loop takes a
/// whole number of PWM periods (`three_phase::drive_periods_per_tick`).
fn check_three_phase(cfg: &DriveConfig) -> Result<(), String> {
    three_phase::drive_periods_per_tick(cfg)
        .map(|_| ())
        .map_err(|e| format!("STIFFDRIVE_DRIVE (board-stm32f4-3ph): {e}"))
}

/// Parse the recording of the drive's motor (`lil/inputs.csv`, or `lil/inputs-pmsm.csv` for
/// a PMSM drive), run the host core on it, write `lil_inputs.bin` and `lil_expected.bin`.
/// A missing recording gives empty files (the replay then fails loudly for having no
/// periods); a malformed one is an error.
fn write_lil_data(
    cfg: &DriveConfig,
    lil: &std::path::Path,
    out: &std::path::Path,
) -> Result<(), String> {
    // A PMSM drive without its calibration cannot run (the core refuses it): no
    // expectation, as for a missing recording. Its `board` image calibrates it
    // (`stiffdrive identify --board`).
    if cfg
        .pmsm
        .is_some_and(|p| p.encoder_offset_elec_deg.is_none())
    {
        for f in ["lil_inputs.bin", "lil_expected.bin"] {
            fs::write(out.join(f), []).map_err(|e| e.to_string())?;
        }
        return Ok(());
    }
    let csv = lil.join(if cfg.pmsm.is_some() {
        "inputs-pmsm.csv"
    } else {
        "inputs.csv"
    });
    let text = match fs::read_to_string(&csv) {
        Ok(t) => t,
        Err(_) => {
            println!(
                "cargo:warning=no {}: loop-in-the-loop data empty",
                csv.display()
            );
            String::new()
        }
    };
    let rows = csv_rows(&text)?;
    let mut input_bytes = Vec::new();
    let mut expected = Vec::new();
    let mut emit = |w: &[u32]| {
        for x in w {
            expected.extend_from_slice(&x.to_le_bytes());
        }
    };
    let run = if cfg.pmsm.is_some() {
        let inputs = pmsm_records(&rows)?;
        for rec in &inputs {
            input_bytes.extend_from_slice(&rec.to_bytes());
        }
        words::reference_run_pmsm(cfg, inputs.iter().copied(), &mut emit)
    } else {
        let inputs = dc_records(&rows)?;
        for rec in &inputs {
            input_bytes.extend_from_slice(&rec.to_bytes());
        }
        words::reference_run(cfg, inputs.iter().copied(), &mut emit)
    };
    run.map_err(|e| format!("host controller-core rejected the run's settings: {e}"))?;
    fs::write(out.join("lil_inputs.bin"), input_bytes).map_err(|e| e.to_string())?;
    fs::write(out.join("lil_expected.bin"), expected).map_err(|e| e.to_string())?;
    Ok(())
}

/// The recording's data lines (the period column dropped), with their line numbers.
fn csv_rows(text: &str) -> Result<Vec<(usize, Vec<&str>)>, String> {
    let mut rows = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with("period") {
            continue;
        }
        // The period column is dropped.
        let f: Vec<&str> = line.split(',').map(str::trim).skip(1).collect();
        if f.is_empty() {
            return Err(format!("line {}: expected a period and its inputs", n + 1));
        }
        rows.push((n + 1, f));
    }
    Ok(rows)
}

/// A field of line `n` parsed, or the error naming it.
fn field<T: std::str::FromStr>(n: usize, text: &str, what: &str) -> Result<T, String> {
    text.parse().map_err(|_| format!("line {n}: bad {what}"))
}

/// A fault-input field: 0 or 1.
fn flag(n: usize, text: &str) -> Result<bool, String> {
    match text {
        "0" => Ok(false),
        "1" => Ok(true),
        _ => Err(format!("line {n}: bad fault_input")),
    }
}

/// A DC drive's records: encoder_count, current_pu_bits, fault_input.
fn dc_records(rows: &[(usize, Vec<&str>)]) -> Result<Vec<words::LilInput>, String> {
    rows.iter()
        .map(|(n, f)| {
            let [enc, cur, flt] = f.as_slice() else {
                return Err(format!("line {n}: expected 4 fields, got {}", f.len() + 1));
            };
            Ok(words::LilInput {
                encoder_count: field(*n, enc, "encoder_count")?,
                current_pu: controller_core::Pu::from_bits(field(*n, cur, "current_pu_bits")?),
                fault_input: flag(*n, flt)?,
            })
        })
        .collect()
}

/// A PMSM drive's records: encoder_count, i_a_pu_bits, i_b_pu_bits, fault_input.
fn pmsm_records(rows: &[(usize, Vec<&str>)]) -> Result<Vec<words::PmsmLilInput>, String> {
    rows.iter()
        .map(|(n, f)| {
            let [enc, a, b, flt] = f.as_slice() else {
                return Err(format!("line {n}: expected 5 fields, got {}", f.len() + 1));
            };
            let pu = |t: &str, what: &str| field(*n, t, what).map(controller_core::Pu::from_bits);
            Ok(words::PmsmLilInput {
                encoder_count: field(*n, enc, "encoder_count")?,
                phase_current_pu: [pu(a, "i_a_pu_bits")?, pu(b, "i_b_pu_bits")?],
                fault_input: flag(*n, flt)?,
            })
        })
        .collect()
}

/// CRC-32 (IEEE 802.3, reflected, polynomial 0xEDB88320) of the baked settings: names the
/// drive in the boot log, so two images with the same file name but other settings differ.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}
