//! The ranges that `OutOfRangeGiven` errors from the controller's coefficients state (a
//! derived coefficient that does not fit its fixed-point format) are the true ranges: just
//! inside a stated bound the check that refused the value accepts it, and the bounds are
//! checked against the formulas of `controller/coefficients.rs`, worked out here on Table 1's
//! drive.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::float_cmp
)]

use crate::common;
use controller_core::{ConfigError, Controller, DriveConfig};

/// The error's key, value, range and whether the range's low end is exclusive.
fn given(cfg: &DriveConfig) -> (&'static str, f32, f32, f32, bool) {
    match Controller::new(cfg).map(|_| ()) {
        Err(ConfigError::OutOfRangeGiven {
            param,
            value,
            min,
            max,
            min_exclusive,
            ..
        }) => (param, value, min, max, min_exclusive),
        other => panic!("expected a range given the others: {other:?}"),
    }
}

/// Whether `cfg` passes the check that names `key` (accepted, or refused for another key).
fn passes(cfg: &DriveConfig, key: &str) -> bool {
    match Controller::new(cfg) {
        Ok(_) => true,
        Err(e) => e.param() != key,
    }
}

/// An observer bandwidth too small for its gains (Q2.30) names `observer.bandwidth_hz`,
/// with the range's top at the largest value below the current loop's Nyquist limit
/// (`current_rate_hz` / 2), the observer's own cap; the range's bottom is accepted.
#[test]
fn the_observer_bandwidth_range_tops_at_the_current_nyquist_limit() {
    let mut c = common::table1();
    c.observer.bandwidth_hz = 1e-3;
    let (key, value, min, max, min_exclusive) = given(&c);
    assert_eq!(key, "observer.bandwidth_hz");
    assert_eq!(value, 1e-3);
    assert!(!min_exclusive && min > 1e-3, "{min}");
    let nyquist = (c.current_rate_hz as f32 / 2.0).next_down();
    assert_eq!(max, nyquist);
    assert!(max > 1999.0 && max < 2000.0, "{max}");
    c.observer.bandwidth_hz = min * (1.0 + 1e-3);
    assert!(passes(&c, key), "{:?}", Controller::new(&c).err());
    c.observer.bandwidth_hz = max * (1.0 - 1e-3);
    assert!(passes(&c, key), "{:?}", Controller::new(&c).err());
}
