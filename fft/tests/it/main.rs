//! The transforms against their definition. An integration test, so that it links the
//! crate's one compiled planner instead of compiling rustfft's generic code again for a test
//! build of the library (`[lib] test = false` in `fft/Cargo.toml`).

use fft::{Complex, forward, inverse};

use std::f64::consts::PI;

#[test]
fn forward_is_the_sum_and_inverse_undoes_it() {
    let n = 12;
    let x: Vec<Complex<f64>> = (0..n)
        .map(|k| Complex::new((0.7 * k as f64).sin(), 0.1 * k as f64))
        .collect();
    let mut got = x.clone();
    forward(&mut got);
    for (k, g) in got.iter().enumerate() {
        let want: Complex<f64> = x
            .iter()
            .enumerate()
            .map(|(j, v)| v * Complex::from_polar(1.0, -2.0 * PI * (k * j) as f64 / n as f64))
            .sum();
        assert!((g - want).norm() < 1e-12, "bin {k}: {g} against {want}");
    }
    inverse(&mut got);
    for (g, v) in got.iter().zip(&x) {
        assert!((g / n as f64 - v).norm() < 1e-12);
    }
}
