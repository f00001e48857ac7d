//! The configuration of a run, composed from the files: one TOML value tree per file,
//! `--set` applied to the tree, then one typed deserialization each for the scenario
//! ([`scenario::ScenarioSpec`]), the plant (`plant_host::PlantConfig`) and the drive
//! (`controller_core::DriveConfig`), each validated by its owner.
//!
//! * [`files`]: where the files are, reading them;
//! * [`overrides`]: `section.key=value` on a value tree;
//! * [`typed`]: a value tree into a type, with the dotted key of any error;
//! * [`mod@machine`]: a machine file into plant and drive;
//! * [`scenario`]: the scenario file's types and checks;
//! * [`grids`]: the search grids of `sweep` and `tune` (`configs/grids.toml`);
//! * [`mod@resolve`]: the run (and the comparison's borrowed gains);
//! * [`schema`]: the JSON Schema of a machine file and of the grids file.

pub mod files;
pub mod grids;
pub mod machine;
pub mod overrides;
pub mod resolve;
pub mod scenario;
pub mod schema;
pub mod typed;

pub use files::{config_path, configs_dir, known_scenarios, load_scenario, read_table};
pub use grids::{load_grids, sweep_grid, tune_grid, Grid, GridFilter, GridsFile};
pub use machine::machine;
pub use resolve::{borrow_gains, resolve, resolve_on_machine, GainsOf, RunConfig};
