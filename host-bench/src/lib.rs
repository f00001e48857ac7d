//! Criterion benchmarks of stiffdrive's host cost, one per `benches/` file:
//!
//! | benchmark | measures | command |
//! |---|---|---|
//! | `period` | one 4 kHz period of `controller-core` (a current tick and half a velocity tick) | `cargo bench -p host-bench --bench period` |
//! | `plant` | `plant-host`'s plant per simulated second | `cargo bench -p host-bench --bench plant` |
//! | `link` | `pil-link`'s encoding, decoding and session per frame | `cargo bench -p host-bench --bench link` |
//! | `closed_loop` | `sim-engine`'s full closed loop per simulated millisecond | `cargo bench -p host-bench --bench closed_loop` |
//!
//! The figures are in `docs/benchmarks.md`. The library is empty: the benchmarks live in a
//! crate of their own so that `cargo test` never compiles criterion.
