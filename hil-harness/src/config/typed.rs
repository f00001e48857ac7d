//! One typed deserialization of a TOML value tree, with the dotted key of any error.

use crate::error::{HarnessError, Result};
use serde::de::DeserializeOwned;

/// Deserializes `value` into `T`. An error names the key where it happened, below
/// `prefix` (`drive`, or `""` for a whole file), with serde's message: an unknown key and
/// the allowed ones, a missing key, a value of the wrong type.
pub fn typed<T: DeserializeOwned>(prefix: &str, value: toml::Value) -> Result<T> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        let path = e.path().to_string();
        let key = match (prefix.is_empty(), path.as_str()) {
            (true, _) => path.clone(),
            (false, "" | ".") => prefix.to_string(),
            (false, p) => format!("{prefix}.{p}"),
        };
        HarnessError::config(key, e.inner().message().to_string())
    })
}
