//! The command line: `run`, `linear`, `tune`, `identify`, `commission`, `sweep`, `stiffness`,
//! `sec2-map`, `reproduce`, `pil`, `board`, `schema`, `replay`, `flash`.

use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

/// Runs controller-core against plant-host with the real timing and reproduces the paper.
#[derive(Debug, Parser)]
#[command(name = "hil-harness", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run one scenario: writes DIR/trace.csv, DIR/summary.json and plots.
    Run(ScenarioArgs),
    /// The linear model of one scenario's loop: poles and damping (gears engaged and apart),
    /// margins of the velocity and acceleration loops, stiffness, quantization torque
    /// noise; writes DIR/linear.json and DIR/linear.md.
    Linear(ScenarioArgs),
    /// Design the acceleration feedback, estimator and velocity loop from the plant on the
    /// linear model, with margins, with AFB and without, and choose in the nonlinear loop by
    /// the load-step objective against the file's own drive (docs/tuning.md); writes
    /// DIR/drive.toml (the machine file with the chosen drive), DIR/runner-up.toml (the best
    /// of the other kind), DIR/tune.md (with DIR/tune-bode.png and DIR/tune-poles.png) and
    /// DIR/tune.json.
    Tune {
        /// Configuration (path, or name under configs/).
        #[arg(long)]
        config: String,
        /// The bandwidth and the constraints to design for.
        #[command(flatten)]
        design: DesignArgs,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
    },
    /// Measure the machine in the closed loop (PRBS on the torque reference, H1 with Welch
    /// averaging, lost-motion reversal test) and fit its two-inertia model; writes
    /// DIR/plant.toml, DIR/identify.json, DIR/identify.md and DIR/bode.png|svg. On a PMSM
    /// machine the motor is calibrated first (phase resistance, Ld, Lq, pole pairs,
    /// encoder direction and offset, in identify.json and identify.md). With
    /// `--board --qemu | --port PATH` the board runs the measurements in its own loops (on
    /// a PMSM machine the calibration too, which is then set and saved on the board).
    Identify {
        /// Configuration (path, or name under configs/); its optional `[identify]` table
        /// holds the measurement settings. With `--board` it is the board's machine file
        /// (default configs/machines/table1.toml, the image's baked one).
        #[arg(long, required_unless_present = "board")]
        config: Option<String>,
        /// Measure on the board (`--qemu` or `--port PATH`) instead of the simulated
        /// machine.
        #[command(flatten)]
        board: crate::board::IdentifyBoardArgs,
        /// Override `section.key=value` (repeatable), e.g. identify.amplitude_pu=0.2.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
    },
    /// Commission a machine: identify it, tune on the identified model (with AFB and
    /// without, the chosen one by the load-step objective; with a notch placed on an
    /// identified resonance the loop cannot damp), and verify both drives on the machine
    /// itself; writes DIR/identify/,
    /// DIR/identified.toml, DIR/notched.toml (with a notch), DIR/tune/, DIR/commission.md
    /// and .json, and DIR/drive.toml (with a PMSM's calibration in `[drive.pmsm]`).
    Commission {
        /// Configuration (path, or name under configs/): the machine to commission.
        #[arg(long)]
        config: String,
        /// Override `section.key=value` (repeatable) on the machine file.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// The bandwidth and the constraints to design for.
        #[command(flatten)]
        design: DesignArgs,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
    },
    /// Largest stable velocity bandwidth with and without acceleration feedback.
    Sweep {
        /// Output directory.
        #[arg(long, default_value = "out/sweep")]
        out: PathBuf,
    },
    /// Dynamic stiffness over frequency: Eq. 1 and measured in the loop (the dyno), or
    /// with --config on that machine's own plant and drive, AFB on and off.
    Stiffness {
        /// A machine file (path, or name under configs/): measure its stiffness instead of
        /// the dyno's.
        #[arg(long)]
        config: Option<String>,
        /// Override a setting of the machine file (`--config` only).
        #[arg(long = "set", value_name = "KEY=VALUE", requires = "config")]
        set: Vec<String>,
        /// Output directory.
        #[arg(long, default_value = "out/stiffness")]
        out: PathBuf,
    },
    /// The paper's Sec. II claim with its own estimator: fig6 with differentiated velocity
    /// and acceleration over a grid of filter corners, with and without AFB at the same gains.
    Sec2Map {
        /// Output directory.
        #[arg(long, default_value = "out/sec2")]
        out: PathBuf,
    },
    /// The paper's scenarios, the sweep, stiffness, the Sec. II map, `tune` on table1, the
    /// printing press and the dyno (out/tune/), and out/REPORT.md (what `cargo run --release`
    /// does).
    Reproduce {
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
    },
    /// Run one scenario through the firmware in QEMU (processor in the loop).
    Pil(crate::pil::PilArgs),
    /// The board's serial console: status, settings by machine-file key (get, set, save),
    /// reset, faults, enable/disable and the scope, on a board's port or the `board` image
    /// in QEMU; the actions run in order in one session.
    Board(crate::board::BoardArgs),
    /// Write the JSON Schema of a machine file (`configs/machines/*.toml`: the plant tables
    /// and `[drive]`, with every range), or with `--grids` of the grids file
    /// (`configs/grids.toml`), for an editor to complete and check it.
    Schema {
        /// The grids file's schema instead of the machine file's.
        #[arg(long)]
        grids: bool,
        /// Output file [default: configs/machine.schema.json, with `--grids`
        /// configs/grids.schema.json].
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Build the image of the board for a machine file's motor, carrying its drive (e.g. a
    /// `drive.toml` from `tune` or `commission`), and run it on the board through probe-rs:
    /// a DC motor on the STM32F4-Discovery, a PMSM on the NUCLEO-F446RE with X-NUCLEO-IHM08M1.
    Flash {
        /// Machine file (path, or name under configs/) whose `[drive]` the image carries.
        #[arg(long)]
        config: String,
        /// Build the image and print the probe-rs command, without running it.
        #[arg(long)]
        build_only: bool,
    },
    /// Drive the plant open-loop with a torque CSV (plant-host's replay).
    Replay {
        /// Configuration (path, or name under configs/).
        #[arg(long)]
        config: String,
        /// Input CSV of load/motor torque over time.
        #[arg(long)]
        torque: PathBuf,
        /// Output CSV.
        #[arg(long)]
        out: PathBuf,
    },
}

/// One scenario, its config and overrides, and where to write.
#[derive(Clone, Debug, Args)]
pub struct ScenarioArgs {
    /// Scenario name (a file under configs/scenarios/).
    #[arg(long)]
    pub scenario: String,
    /// Configuration (path, or name under configs/); default: the scenario's.
    #[arg(long)]
    pub config: Option<String>,
    /// Override `section.key=value` (repeatable), e.g. drive.velocity_bandwidth_rad_s=50.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
}

/// What `tune` and `commission` design for: the bandwidth and the constraints.
#[derive(Args, Debug, Clone)]
pub struct DesignArgs {
    /// Velocity bandwidth to design for (rad/s). Without it, every bandwidth of the grid
    /// (`configs/grids.toml`) is searched too, as with `--max-bandwidth`.
    #[arg(long, conflicts_with = "max_bandwidth")]
    pub target_bandwidth: Option<f64>,
    /// Search the velocity bandwidth too (the default without `--target-bandwidth`): every
    /// bandwidth of the grid, chosen by the objective among those that meet the constraints.
    #[arg(long)]
    pub max_bandwidth: bool,
    /// Smallest damping ratio, gears engaged and apart.
    #[arg(long, default_value_t = 0.3)]
    pub min_damping: f64,
    /// Largest torque noise from encoder quantization (pu RMS).
    #[arg(long, default_value_t = 0.2)]
    pub max_noise_pu: f64,
    /// Largest motor-torque noise above the velocity bandwidth in the nonlinear `fig6` run
    /// (pu RMS; finite, > 0). Default: the larger of 2 x the machine file's own drive's and
    /// 0.01 pu.
    #[arg(long)]
    pub max_torque_noise_pu: Option<f64>,
}

impl DesignArgs {
    /// The design constraints these arguments set (the rest at their defaults).
    #[must_use]
    pub fn constraints(&self) -> machine_workflows::tune::Constraints {
        machine_workflows::tune::Constraints {
            min_damping: self.min_damping,
            max_noise_pu: self.max_noise_pu,
            max_torque_noise_pu: self.max_torque_noise_pu,
            ..machine_workflows::tune::Constraints::default()
        }
    }
}
