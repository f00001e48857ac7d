//! One typed deserialization of a TOML value tree, with the dotted key of any error.

use crate::error::Result;
use serde::de::DeserializeOwned;

/// Deserializes `value` into `T` ([`machine_file::typed`]). An error names the key where it
/// happened, below `prefix` (`drive`, or `""` for a whole file), with serde's message: an
/// unknown key and the allowed ones, a missing key, a value of the wrong type.
pub fn typed<T: DeserializeOwned>(prefix: &str, value: toml::Value) -> Result<T> {
    Ok(machine_file::typed(prefix, value)?)
}
