//! Replay refuses inputs it cannot honour in bounded time or with finite output, naming the
//! column and its range, before it simulates anything.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use crate::common;

use plant_host::{COLUMN_RANGES, MAX_SPAN_S, parse_torque_csv, simulate};
use std::path::Path;

fn csv(rows: &[&str]) -> String {
    let mut t = String::from("t_s,motor_torque_pu,load_torque_pu\n");
    for r in rows {
        t.push_str(r);
        t.push('\n');
    }
    t
}

fn error(rows: &[&str]) -> String {
    parse_torque_csv(&csv(rows), Path::new("in.csv"))
        .unwrap_err()
        .to_string()
}

#[test]
fn a_span_past_the_bound_is_refused_before_simulating() {
    let e = error(&["0,0,0", "1000,0,0"]);
    assert!(e.contains("bounded to 600 s"), "{e}");
    // A span that would take hours to simulate (t = 0 and t = 1e7 s): refused too.
    let e = error(&["0,0,0", "10000000,0,0"]);
    assert!(e.contains("t_s = 10000000 is outside"), "{e}");
    // Exactly the bound is fine.
    let ok = csv(&["0,0,0", &format!("{MAX_SPAN_S},0,0")]);
    assert!(parse_torque_csv(&ok, Path::new("in.csv")).is_ok());
}

#[test]
fn torques_and_times_outside_their_ranges_name_the_column_and_range() {
    for (row, column) in [
        ("0,1e308,0", "motor_torque_pu"),
        ("0,0,-1e308", "load_torque_pu"),
        ("0,1000.5,0", "motor_torque_pu"),
        ("2e6,0,0", "t_s"),
    ] {
        let e = error(&[row]);
        let (_, lo, hi) = COLUMN_RANGES
            .iter()
            .find(|(n, _, _)| *n == column)
            .copied()
            .unwrap();
        assert!(
            e.contains(column) && e.contains(&format!("[{lo}, {hi}]")),
            "{row}: {e}"
        );
    }
}

#[test]
fn the_largest_allowed_torque_over_the_longest_span_stays_finite() {
    let cfg = common::table1();
    let rows = parse_torque_csv(
        &csv(&[
            "0,1000,-1000",
            "300,-1000,1000",
            &format!("{MAX_SPAN_S},0,0"),
        ]),
        Path::new("in.csv"),
    )
    .unwrap();
    let (states, _) = simulate(&cfg, &rows);
    for s in &states {
        assert!(
            s.motor_pos_rad.is_finite()
                && s.motor_vel_pu.is_finite()
                && s.shaft_torque_pu.is_finite(),
            "{s:?}"
        );
    }
}
