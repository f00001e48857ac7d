//! Reading one owned TOML table: every key is checked against its spec, unknown keys are
//! rejected, and every error names `table.key` and its allowed range.

use crate::error::ConfigError;
use toml::{Table, Value};

/// The allowed closed range of a real-valued key, with its unit for messages.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RealSpec {
    pub name: &'static str,
    pub min: f64,
    pub max: f64,
    pub unit: &'static str,
}

impl RealSpec {
    fn allowed(&self) -> String {
        format!("a number in {}..={} {}", self.min, self.max, self.unit)
            .trim_end()
            .to_string()
    }
}

/// The allowed closed range of an integer key.
#[derive(Debug, Clone, Copy)]
pub(crate) struct IntSpec {
    pub name: &'static str,
    pub min: i64,
    pub max: i64,
    pub unit: &'static str,
}

impl IntSpec {
    fn allowed(&self) -> String {
        format!("an integer in {}..={} {}", self.min, self.max, self.unit)
            .trim_end()
            .to_string()
    }
}

/// One owned table being read. `finish` rejects keys that no getter asked for.
pub(crate) struct TableReader<'a> {
    table_name: &'static str,
    table: Option<&'a Table>,
    known: Vec<&'static str>,
}

impl<'a> TableReader<'a> {
    /// Reads table `name` from the document; `required` makes its absence an error.
    pub fn open(doc: &'a Table, name: &'static str, required: bool) -> Result<Self, ConfigError> {
        let table = match doc.get(name) {
            None if required => return Err(ConfigError::MissingTable { table: name }),
            None => None,
            Some(Value::Table(t)) => Some(t),
            Some(_) => return Err(ConfigError::NotATable { table: name }),
        };
        Ok(Self {
            table_name: name,
            table,
            known: Vec::new(),
        })
    }

    fn key(&self, name: &str) -> String {
        format!("{}.{}", self.table_name, name)
    }

    fn raw(&mut self, name: &'static str) -> Option<&'a Value> {
        self.known.push(name);
        self.table.and_then(|t| t.get(name))
    }

    /// A required real key.
    pub fn real(&mut self, spec: RealSpec) -> Result<f64, ConfigError> {
        match self.real_opt(spec)? {
            Some(v) => Ok(v),
            None => Err(self.missing(spec.name, spec.allowed())),
        }
    }

    /// A real key with a default.
    pub fn real_or(&mut self, spec: RealSpec, default: f64) -> Result<f64, ConfigError> {
        Ok(self.real_opt(spec)?.unwrap_or(default))
    }

    fn real_opt(&mut self, spec: RealSpec) -> Result<Option<f64>, ConfigError> {
        let key = self.key(spec.name);
        let v = match self.raw(spec.name) {
            None => return Ok(None),
            // Integers are accepted for real keys: `base_speed_rpm = 1000` is natural.
            Some(Value::Integer(i)) => *i as f64,
            Some(Value::Float(x)) => *x,
            Some(_) => {
                return Err(ConfigError::WrongType {
                    key,
                    allowed: spec.allowed(),
                })
            }
        };
        if !v.is_finite() {
            return Err(ConfigError::NotFinite {
                key,
                allowed: spec.allowed(),
            });
        }
        if v < spec.min || v > spec.max {
            return Err(ConfigError::OutOfRange {
                key,
                value: format!("{v}"),
                allowed: spec.allowed(),
            });
        }
        Ok(Some(v))
    }

    /// A required integer key.
    pub fn int(&mut self, spec: IntSpec) -> Result<i64, ConfigError> {
        match self.int_opt(spec)? {
            Some(v) => Ok(v),
            None => Err(self.missing(spec.name, spec.allowed())),
        }
    }

    /// An integer key with a default.
    pub fn int_or(&mut self, spec: IntSpec, default: i64) -> Result<i64, ConfigError> {
        Ok(self.int_opt(spec)?.unwrap_or(default))
    }

    fn int_opt(&mut self, spec: IntSpec) -> Result<Option<i64>, ConfigError> {
        let key = self.key(spec.name);
        let v = match self.raw(spec.name) {
            None => return Ok(None),
            Some(Value::Integer(i)) => *i,
            Some(Value::Float(x)) if !x.is_finite() => {
                return Err(ConfigError::NotFinite {
                    key,
                    allowed: spec.allowed(),
                })
            }
            Some(_) => {
                return Err(ConfigError::WrongType {
                    key,
                    allowed: spec.allowed(),
                })
            }
        };
        if v < spec.min || v > spec.max {
            return Err(ConfigError::OutOfRange {
                key,
                value: format!("{v}"),
                allowed: spec.allowed(),
            });
        }
        Ok(Some(v))
    }

    /// A string key restricted to `choices`, with a default.
    pub fn choice_or(
        &mut self,
        name: &'static str,
        choices: &[&'static str],
        default: &'static str,
    ) -> Result<&'static str, ConfigError> {
        let key = self.key(name);
        let allowed = format!("one of {}", quoted(choices));
        match self.raw(name) {
            None => Ok(default),
            Some(Value::String(s)) => {
                choices
                    .iter()
                    .find(|c| **c == s.as_str())
                    .copied()
                    .ok_or(ConfigError::OutOfRange {
                        key,
                        value: format!("\"{s}\""),
                        allowed,
                    })
            }
            Some(_) => Err(ConfigError::WrongType { key, allowed }),
        }
    }

    /// A required key is absent. If the table holds a key that nothing reads and that is
    /// within two edits of it (a misspelling), that key is named first.
    fn missing(&self, name: &'static str, allowed: String) -> ConfigError {
        let near = self.table.and_then(|t| {
            t.keys()
                .find(|k| k.as_str() != name && edit_distance(k, name) <= 2)
        });
        match near {
            Some(k) => ConfigError::Misspelt {
                key: self.key(k),
                expected: self.key(name),
            },
            None => ConfigError::Missing {
                key: self.key(name),
                allowed,
            },
        }
    }

    /// Rejects any key of the table that no getter asked for.
    pub fn finish(self) -> Result<(), ConfigError> {
        let Some(table) = self.table else {
            return Ok(());
        };
        // Report the first unknown key in file order (toml keeps a sorted map: deterministic).
        if let Some(k) = table.keys().find(|k| !self.known.contains(&k.as_str())) {
            return Err(ConfigError::Unknown {
                key: self.key(k),
                allowed: self.known.join(", "),
            });
        }
        Ok(())
    }
}

/// Levenshtein distance of two short keys.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row.first().copied().unwrap_or(0);
        if let Some(first) = row.first_mut() {
            *first = i + 1;
        }
        for (j, cb) in b.iter().enumerate() {
            let up = row.get(j + 1).copied().unwrap_or(usize::MAX);
            let left = row.get(j).copied().unwrap_or(usize::MAX);
            let next = (diag + usize::from(ca != *cb)).min(up + 1).min(left + 1);
            diag = up;
            if let Some(cell) = row.get_mut(j + 1) {
                *cell = next;
            }
        }
    }
    row.last().copied().unwrap_or(0)
}

fn quoted(choices: &[&str]) -> String {
    choices
        .iter()
        .map(|c| format!("\"{c}\""))
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::edit_distance;

    #[test]
    fn edit_distance_counts_insertions_deletions_and_swaps() {
        assert_eq!(edit_distance("anti_resonance_hz", "anti_resonance_hz"), 0);
        assert_eq!(edit_distance("anti_resonance_hzx", "anti_resonance_hz"), 1);
        assert_eq!(edit_distance("encodr_cpr", "encoder_cpr"), 1);
        assert_eq!(edit_distance("motor_inertia_s", "load_inertia_s"), 4);
        assert_eq!(edit_distance("", "abc"), 3);
    }
}
