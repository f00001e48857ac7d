//! `FilterConfig` from `{ kind = "none" }`, `{ kind = "first_order", corner_hz = .. }` or
//! `{ kind = "second_order", corner_hz = .., q = .. }` (`q` optional), keys in any order;
//! a key the kind does not have is an unknown-field error. No buffering, no alloc.
use super::{FilterConfig, defaults};
use core::fmt;
use serde::de::{self, MapAccess, Visitor};

#[derive(serde::Deserialize)]
#[serde(field_identifier, rename_all = "snake_case")]
enum Key {
    Kind,
    CornerHz,
    Q,
}

#[derive(serde::Deserialize)]
#[serde(rename_all = "snake_case")]
enum Kind {
    None,
    FirstOrder,
    SecondOrder,
}

struct FilterVisitor;

fn set<'de, A: MapAccess<'de>, T: serde::Deserialize<'de>>(
    slot: &mut Option<T>,
    map: &mut A,
    name: &'static str,
) -> Result<(), A::Error> {
    if slot.is_some() {
        return Err(de::Error::duplicate_field(name));
    }
    *slot = Some(map.next_value()?);
    Ok(())
}

impl<'de> Visitor<'de> for FilterVisitor {
    type Value = FilterConfig;
    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a filter table with `kind` = \"none\", \"first_order\" or \"second_order\"")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<FilterConfig, A::Error> {
        let (mut kind, mut corner, mut q) = (None, None, None);
        while let Some(key) = map.next_key::<Key>()? {
            match key {
                Key::Kind => set(&mut kind, &mut map, "kind")?,
                Key::CornerHz => set(&mut corner, &mut map, "corner_hz")?,
                Key::Q => set(&mut q, &mut map, "q")?,
            }
        }
        let unknown = |k: &str, allowed: &'static [&'static str]| -> A::Error {
            de::Error::unknown_field(k, allowed)
        };
        match kind.ok_or_else(|| de::Error::missing_field("kind"))? {
            Kind::None => match (corner, q) {
                (None, None) => Ok(FilterConfig::None),
                (Some(_), _) => Err(unknown("corner_hz", &["kind"])),
                (None, Some(_)) => Err(unknown("q", &["kind"])),
            },
            Kind::FirstOrder => match q {
                Some(_) => Err(unknown("q", &["kind", "corner_hz"])),
                None => Ok(FilterConfig::FirstOrder {
                    corner_hz: corner.ok_or_else(|| de::Error::missing_field("corner_hz"))?,
                }),
            },
            Kind::SecondOrder => Ok(FilterConfig::SecondOrder {
                corner_hz: corner.ok_or_else(|| de::Error::missing_field("corner_hz"))?,
                q: q.unwrap_or_else(defaults::butterworth_q),
            }),
        }
    }
}

impl<'de> serde::Deserialize<'de> for FilterConfig {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_map(FilterVisitor)
    }
}
