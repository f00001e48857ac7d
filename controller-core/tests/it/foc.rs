//! The FOC current loop's blocks against f64 (`foc::`): sin/cos, Clarke/Park and the
//! space-vector modulator over 10⁶ random inputs each with stated error bounds, the duties
//! never outside `[0, period]`, the electrical angle, and the closed current loop on a d/q
//! motor model integrated in f64 (RK4) here: the q-current rise against the bandwidth, the
//! decoupling through a speed reversal, and the voltage circle without windup.
#![allow(
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    clippy::cast_possible_truncation
)]

use controller_core::foc::transforms::CosSin;
use controller_core::foc::{
    AlphaBeta, AngleCoefficients, Dq, FocCoefficients, FocInputs, FocSettings, Svpwm, clarke,
    inverse_park, park,
};
use controller_core::per_unit::Pu;
use std::f64::consts::{PI, TAU};

/// xorshift64*: a fixed, seeded sequence.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [lo, hi).
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

const N: usize = 1_000_000;
const Q31: f64 = 2_147_483_648.0;
const LSB: f64 = 1.0 / 65_536.0;

fn pu(x: f64) -> Pu {
    Pu::from_num(x)
}
fn f(x: Pu) -> f64 {
    x.to_num()
}
fn angle_of(phase: u32) -> f64 {
    f64::from(phase) / 4_294_967_296.0 * TAU
}

/// sin and cos: at most 2e-5 from f64 over 10⁶ random 32-bit phases. idsp states 9e-6 of
/// interpolation error; its output's full scale is also 2^31 − 0.85·2^15, not 2^31 (room
/// for the interpolation without overflow), a gain 1.3e-5 low, which adds to it here
/// (measured: 1.87e-5).
#[test]
fn cossin_is_within_2e_5_of_f64() {
    let mut rng = Rng(1);
    let mut worst = 0f64;
    for _ in 0..N {
        let phase = rng.next() as u32;
        let cs = CosSin::of(phase);
        let th = angle_of(phase);
        worst = worst
            .max((f64::from(cs.cos) / Q31 - th.cos()).abs())
            .max((f64::from(cs.sin) / Q31 - th.sin()).abs());
    }
    assert!(worst < 2e-5, "largest sin/cos error {worst:e}");
}

/// Clarke, Park and inverse Park: within 3e-5·|v| + 1 LSB of f64 (sin and cos's 2e-5) for |phase currents| ≤ 20
/// pu over 10⁶ random inputs; inverse Park after Park returns the vector within the same.
#[test]
fn clarke_and_park_are_within_their_stated_error() {
    let mut rng = Rng(2);
    let (mut worst_c, mut worst_p, mut worst_i) = (0f64, 0f64, 0f64);
    for _ in 0..N {
        let (a, b) = (rng.uniform(-20.0, 20.0), rng.uniform(-20.0, 20.0));
        let (qa, qb) = (pu(a), pu(b));
        let (a, b) = (f(qa), f(qb));
        let ab = clarke(qa, qb);
        let (alpha, beta) = (a, (a + 2.0 * b) / 3f64.sqrt());
        worst_c = worst_c
            .max((f(ab.beta) - beta).abs())
            .max((f(ab.alpha) - alpha).abs());
        let phase = rng.next() as u32;
        let th = angle_of(phase);
        let cs = CosSin::of(phase);
        let dq = park(ab, cs);
        let (al, be) = (f(ab.alpha), f(ab.beta));
        let len = al.hypot(be);
        let d = al * th.cos() + be * th.sin();
        let q = -al * th.sin() + be * th.cos();
        worst_p = worst_p.max(((f(dq.d) - d).abs().max((f(dq.q) - q).abs()) - LSB) / len.max(1e-9));
        let back = inverse_park(dq, cs);
        let al2 = f(dq.d) * th.cos() - f(dq.q) * th.sin();
        let be2 = f(dq.d) * th.sin() + f(dq.q) * th.cos();
        worst_i = worst_i.max(
            ((f(back.alpha) - al2).abs().max((f(back.beta) - be2).abs()) - LSB) / len.max(1e-9),
        );
    }
    assert!(worst_c <= LSB, "Clarke error {worst_c:e} pu");
    assert!(
        worst_p < 3e-5,
        "Park error beyond 1 LSB, relative to |v|: {worst_p:e}"
    );
    assert!(
        worst_i < 3e-5,
        "inverse Park error beyond 1 LSB, relative: {worst_i:e}"
    );
}

/// The modulator: duties always in [0, period] (any vector, even far outside the bus), and
/// inside the linear circle the line-to-line voltages they make are the f64 ones within one
/// timer count (each duty rounded by half a count) and the Q16.16 rounding of the phase
/// voltages (two LSBs of a pu, in counts).
#[test]
fn svpwm_duties_stay_in_range_and_make_the_voltage() {
    let mut rng = Rng(3);
    let mut worst = 0f64;
    for i in 0..N {
        let bus = rng.uniform(0.5, 3.0);
        let period = 100 + (rng.next() % 8000) as u16;
        let m = Svpwm::new(bus as f32, period).expect("valid modulator");
        let bus = f64::from(bus as f32);
        let (alpha, beta) = if i % 10 == 0 {
            (rng.uniform(-3e4, 3e4), rng.uniform(-3e4, 3e4))
        } else {
            let r = rng.uniform(0.0, 0.999 * bus / 3f64.sqrt());
            let th = rng.uniform(-PI, PI);
            (r * th.cos(), r * th.sin())
        };
        let v = AlphaBeta {
            alpha: pu(alpha),
            beta: pu(beta),
        };
        let d = m.duties(v);
        assert!(d.iter().all(|&x| x <= period), "duties {d:?} over {period}");
        if i % 10 != 0 {
            let (alpha, beta) = (f(v.alpha), f(v.beta));
            let va = alpha;
            let vb = -alpha / 2.0 + 3f64.sqrt() / 2.0 * beta;
            let counts = f64::from(period) / bus;
            let ab = (f64::from(d[0]) - f64::from(d[1])) - (va - vb) * counts;
            worst = worst.max(ab.abs() - 2.0 * LSB * counts);
        }
    }
    assert!(worst <= 1.0, "line-to-line error {worst} counts");
}

/// The electrical angle: offset + pole_pairs·2π·count/cpr (or minus, reversed) within 1e-6
/// turn for random machines and counts reached by random steps, and its advance by
/// ω_e·t_delay.
#[test]
fn the_electrical_angle_follows_the_count() {
    let mut rng = Rng(4);
    for _ in 0..2_000 {
        let cpr = 4 + (rng.next() % (1 << 24)) as u32;
        let pp = 1 + (rng.next() % u64::from(cpr.min(60) - 1)) as u32;
        let offset = rng.uniform(-720.0, 720.0) as f32;
        let reversed = rng.next().is_multiple_of(2);
        let a =
            AngleCoefficients::new(pp, cpr, offset, reversed, 3000.0, 1.5e-4).expect("valid angle");
        let start = (rng.next() % (1 << 40)) as i64 - (1 << 39);
        let mut st = a.state_at(start);
        let mut count = start;
        for _ in 0..50 {
            let step = (rng.next() % (2 * u64::from(cpr) + 1)) as i64 - i64::from(cpr);
            count += step;
            let phase = a.update(&mut st, step as i32);
            let sign = if reversed { -1.0 } else { 1.0 };
            let turns = f64::from(offset) / 360.0
                + sign * f64::from(pp) * count.rem_euclid(i64::from(cpr)) as f64 / f64::from(cpr);
            let want = turns.rem_euclid(1.0);
            let got = f64::from(phase) / 4_294_967_296.0;
            let err = (got - want).rem_euclid(1.0);
            assert!(err.min(1.0 - err) < 1e-6, "angle {got} against {want}");
        }
        let speed = rng.uniform(-2.0, 2.0);
        let adv = a.advanced(0, pu(speed));
        let want = (f64::from(pp) * 50.0 * f(pu(speed)) * 1.5e-4).rem_euclid(1.0);
        let err = (f64::from(adv) / 4_294_967_296.0 - want).rem_euclid(1.0);
        assert!(err.min(1.0 - err) < 1e-6, "advance {adv} against {want}");
    }
}

/// A motor of the tests: 4 pole pairs, Ld ≠ Lq, on a 4096-count encoder, its speed
/// prescribed (the mechanics are not the question here).
fn settings() -> FocSettings {
    FocSettings {
        pole_pairs: 4,
        encoder_cpr: 4096,
        encoder_offset_elec_deg: 0.0,
        encoder_reversed: false,
        base_speed_rpm: 3000.0,
        resistance_pu: 0.05,
        d_inductance_pu_s: 0.0002,
        q_inductance_pu_s: 0.0003,
        flux_linkage_pu: 1.0,
        dc_bus_pu: 2.5,
        current_bandwidth_rad_s: 2000.0,
        current_rate_hz: 20_000.0,
        delay_ticks: 1.5,
        current_limit_pu: 2.0,
        pwm_period: 4200,
        commutation_min_speed_pu: 0.05,
        commutation_trip_s: 0.02,
    }
}

/// The d/q motor in f64 under the averaged inverter, with a prescribed speed: the duties of
/// one tick act, delayed by one tick (the next period), for one tick.
struct Motor {
    s: FocSettings,
    /// The machine's own pole pairs and electrical angle at count 0 \[rad\].
    pole_pairs: f64,
    offset: f64,
    /// With an inertia \[s\] the speed follows the motor's torque; without, `accel`.
    inertia_s: Option<f64>,
    /// Stationary-frame currents (α, β) \[pu\].
    i: [f64; 2],
    /// Mechanical angle \[rad\] and speed \[pu\].
    theta_m: f64,
    speed: f64,
    /// The duties that act in the coming tick.
    pending: [u16; 3],
}

impl Motor {
    fn new(s: FocSettings) -> Self {
        let half = s.pwm_period / 2;
        Self {
            s,
            pole_pairs: f64::from(s.pole_pairs),
            offset: f64::from(s.encoder_offset_elec_deg).to_radians(),
            inertia_s: None,
            i: [0.0; 2],
            theta_m: 0.0,
            speed: 0.0,
            pending: [half; 3],
        }
    }
    fn w_base(&self) -> f64 {
        f64::from(self.s.base_speed_rpm) * TAU / 60.0
    }
    fn theta_e(&self) -> f64 {
        self.pole_pairs * self.theta_m + self.offset
    }
    /// (d, q) currents at the present angle.
    fn dq(&self) -> (f64, f64) {
        let th = self.theta_e();
        let [a, b] = self.i;
        (a * th.cos() + b * th.sin(), -a * th.sin() + b * th.cos())
    }
    /// Phase currents a and b.
    fn phases(&self) -> [f64; 2] {
        let [a, b] = self.i;
        [a, -a / 2.0 + 3f64.sqrt() / 2.0 * b]
    }
    fn count(&self) -> i64 {
        (self.theta_m / TAU * f64::from(self.s.encoder_cpr)).floor() as i64
    }
    /// One tick of `dt` with the pending duties, then `duties` become pending.
    fn step(&mut self, duties: [u16; 3], accel_pu_s: f64) {
        let dt = 1.0 / f64::from(self.s.current_rate_hz);
        let bus = f64::from(self.s.dc_bus_pu);
        let per = f64::from(self.s.pwm_period);
        let v: Vec<f64> = self
            .pending
            .iter()
            .map(|&d| f64::from(d) / per * bus)
            .collect();
        let mean = (v[0] + v[1] + v[2]) / 3.0;
        let (va, vb) = (v[0] - mean, v[1] - mean);
        let v_ab = [va, (va + 2.0 * vb) / 3f64.sqrt()];
        let (r, ld, lq, flux) = (
            f64::from(self.s.resistance_pu),
            f64::from(self.s.d_inductance_pu_s),
            f64::from(self.s.q_inductance_pu_s),
            f64::from(self.s.flux_linkage_pu),
        );
        let pp = self.pole_pairs;
        let offset = self.offset;
        let inertia = self.inertia_s;
        let wb = self.w_base();
        // State (iα, iβ, θm, ω); RK4 with 20 sub-steps.
        let deriv = |x: [f64; 4]| -> [f64; 4] {
            let th = pp * x[2] + offset;
            let (c, s) = (th.cos(), th.sin());
            let (id, iq) = (x[0] * c + x[1] * s, -x[0] * s + x[1] * c);
            let (vd, vq) = (v_ab[0] * c + v_ab[1] * s, -v_ab[0] * s + v_ab[1] * c);
            let we = pp * wb * x[3];
            let did = (vd - r * id + we * lq * iq) / ld;
            // In the rotating frame, plus the frame's own rotation back to (α, β).
            let diq = (vq - r * iq - we * ld * id - x[3] * flux) / lq;
            let dal = did * c - diq * s - we * (id * s + iq * c);
            let dbe = did * s + diq * c + we * (id * c - iq * s);
            let accel = inertia.map_or(accel_pu_s, |j| {
                (flux * iq + pp * wb * (ld - lq) * id * iq) / j
            });
            [dal, dbe, wb * x[3], accel]
        };
        let mut x = [self.i[0], self.i[1], self.theta_m, self.speed];
        let h = dt / 20.0;
        for _ in 0..20 {
            let add = |a: [f64; 4], b: [f64; 4], k: f64| -> [f64; 4] {
                [
                    a[0] + k * b[0],
                    a[1] + k * b[1],
                    a[2] + k * b[2],
                    a[3] + k * b[3],
                ]
            };
            let k1 = deriv(x);
            let k2 = deriv(add(x, k1, h / 2.0));
            let k3 = deriv(add(x, k2, h / 2.0));
            let k4 = deriv(add(x, k3, h));
            for j in 0..4 {
                x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
        }
        self.i = [x[0], x[1]];
        self.theta_m = x[2];
        self.speed = x[3];
        self.pending = duties;
    }
}

/// One tick of a run: the motor's (i_d, i_q), the drive's i_q* and v_q.
type Row = (f64, f64, f64, Pu);

/// Runs the loop for `ticks`; `torque(k)` and `accel(k)` give the torque reference and the
/// prescribed acceleration; returns (i_d, i_q, i_q*) of each tick from the motor itself.
fn run(
    s: FocSettings,
    speed0: f64,
    ticks: usize,
    torque: impl Fn(usize) -> f64,
    accel: impl Fn(usize) -> f64,
) -> Vec<Row> {
    run_on(s, Motor::new(s), speed0, ticks, torque, accel).0
}

/// [`run`] on the motor `m`, which may differ from the drive's settings; also returns the
/// first tick at which the commutation check latched.
fn run_on(
    s: FocSettings,
    mut m: Motor,
    speed0: f64,
    ticks: usize,
    torque: impl Fn(usize) -> f64,
    accel: impl Fn(usize) -> f64,
) -> (Vec<Row>, Option<usize>) {
    let c = FocCoefficients::new(&s).expect("valid FOC settings");
    let mut tripped = None;
    m.speed = speed0;
    let mut st = c.state_at(m.count());
    let mut last = m.count();
    let mut out = Vec::with_capacity(ticks);
    for k in 0..ticks {
        let count = m.count();
        let [a, b] = m.phases();
        let o = c.tick(
            &mut st,
            FocInputs {
                phase_current_pu: [pu(a), pu(b)],
                count_delta: (count - last) as i32,
                speed_pu: pu(m.speed),
                torque_ref_pu: pu(torque(k)),
            },
        );
        last = count;
        if o.commutation_off && tripped.is_none() {
            tripped = Some(k);
        }
        m.step(o.duties, accel(k));
        let (d, q) = m.dq();
        out.push((d, q, f(o.current_ref.q), o.voltage.q));
    }
    (out, tripped)
}

/// A q-current step at standstill rises as the set bandwidth asks: the time to 63 % of the
/// step is 1/ω_c within 10 % (the loop delay of 1.5 ticks included).
#[test]
fn the_q_current_rises_at_the_set_bandwidth() {
    let s = settings();
    let out = run(s, 0.0, 400, |_| 0.5, |_| 0.0);
    let dt = 1.0 / f64::from(s.current_rate_hz);
    let k63 = out
        .iter()
        .position(|&(_, q, _, _)| q >= 0.5 * (1.0 - (-1f64).exp()))
        .expect("the current reaches 63 %");
    let t63 = (k63 as f64 + 1.0) * dt;
    let want = 1.0 / f64::from(s.current_bandwidth_rad_s);
    eprintln!("q-current step: 63 % after {t63:e} s, 1/ω_c = {want:e} s");
    assert!(
        (t63 - want).abs() <= 0.1 * want,
        "63 % rise after {t63:e} s against 1/ω_c = {want:e} s"
    );
    let (_, q_end, _, _) = out[out.len() - 1];
    assert!((q_end - 0.5).abs() < 0.01, "settles at {q_end}");
}

/// A full-speed reversal (+1 pu to −1 pu in 0.1 s) with 1 pu torque: the decoupling holds
/// i_d within 0.05 pu of its reference (maximum torque per ampere's, since L_d < L_q: a
/// negative d current that the cross-coupling would push around as the speed reverses).
#[test]
fn the_decoupling_holds_i_d_through_a_full_speed_reversal() {
    let s = settings();
    let refs = FocCoefficients::new(&s)
        .expect("valid FOC settings")
        .mtpa
        .references(pu(1.0));
    let (d_ref, q_ref) = (f(refs.d), f(refs.q));
    assert!(
        d_ref < -0.1,
        "L_d < L_q asks for a negative d current: {d_ref}"
    );
    let ticks = 2_400;
    let out = run(
        s,
        1.0,
        ticks,
        |_| 1.0,
        |k| {
            if (200..2_200).contains(&k) {
                -20.0
            } else {
                0.0
            }
        },
    );
    let worst = out[100..]
        .iter()
        .map(|&(d, _, _, _)| (d - d_ref).abs())
        .fold(0.0, f64::max);
    eprintln!("reversal: |i_d − i_d*| ≤ {worst} pu (i_d* = {d_ref})");
    assert!(worst <= 0.05, "|i_d − i_d*| reached {worst} pu");
    let worst_q = out[100..]
        .iter()
        .map(|&(_, q, _, _)| (q - q_ref).abs())
        .fold(0.0, f64::max);
    assert!(worst_q <= 0.1, "|i_q − i_q*| reached {worst_q} pu");
}

/// At base speed with 1 pu torque on a 1.8 pu bus the voltage circle limits; when the
/// demand drops to 0.2 pu the q current follows without overshoot above 10 % of the step
/// (the integrator did not wind up while limited).
#[test]
fn the_voltage_circle_limits_without_windup() {
    let s = FocSettings {
        dc_bus_pu: 1.8,
        ..settings()
    };
    let drop_at = 1_000;
    let out = run(
        s,
        1.0,
        2_000,
        |k| if k < drop_at { 1.0 } else { 0.2 },
        |_| 0.0,
    );
    let vmax = 1.8 / 3f64.sqrt();
    let limited = out[500..drop_at]
        .iter()
        .any(|&(_, _, _, vq)| f(vq) >= vmax - 0.05);
    let (_, q_before, _, _) = out[drop_at - 1];
    assert!(
        limited && q_before < 0.95,
        "the circle must limit: i_q {q_before}"
    );
    let step = q_before - 0.2;
    let overshoot = out[drop_at..]
        .iter()
        .map(|&(_, q, _, _)| 0.2 - q)
        .fold(f64::MIN, f64::max);
    let (_, q_end, _, _) = out[out.len() - 1];
    eprintln!(
        "voltage circle: i_q {q_before} at the limit, {overshoot} pu past 0.2 pu after the drop"
    );
    assert!(
        overshoot <= 0.1 * step && (q_end - 0.2).abs() < 0.01,
        "after the drop from {q_before}: {overshoot} pu past 0.2 pu, ending at {q_end}"
    );
}

/// The commutation check stays quiet on the right angle: through a full-speed reversal at
/// 1 pu torque, and on a free inertia run up to the voltage limit and back.
#[test]
fn the_commutation_check_passes_the_right_angle() {
    let s = settings();
    let (_, tripped) = run_on(
        s,
        Motor::new(s),
        1.0,
        2_400,
        |_| 1.0,
        |k| {
            if (200..2_200).contains(&k) {
                -20.0
            } else {
                0.0
            }
        },
    );
    assert_eq!(tripped, None, "latched on the right angle in the reversal");
    let mut m = Motor::new(s);
    m.inertia_s = Some(0.05);
    let (out, tripped) = run_on(
        s,
        m,
        0.0,
        10_000,
        |k| if k < 5_000 { 1.0 } else { -1.0 },
        |_| 0.0,
    );
    assert_eq!(
        tripped, None,
        "latched on the right angle on a free inertia"
    );
    assert!(out.len() == 10_000);
}

/// An angle more than 30° off (a wrong encoder offset, or a wrong pole-pair count)
/// latches the commutation check within 0.5 s of a 0.5 pu torque step from standstill on a
/// free inertia; an offset 20° off does not.
#[test]
fn a_wrong_angle_latches_the_commutation_check() {
    let s = settings();
    let rate = f64::from(s.current_rate_hz);
    let ticks = (0.5 * rate) as usize;
    for (true_pp, offset_error_deg) in [
        (4.0, 40.0),
        (4.0, -40.0),
        (4.0, 60.0),
        (4.0, 120.0),
        (4.0, 180.0),
        (4.0, -150.0),
        (5.0, 0.0),
        (3.0, 0.0),
        (7.0, 25.0),
    ] {
        let mut m = Motor::new(s);
        m.inertia_s = Some(0.05);
        m.pole_pairs = true_pp;
        m.offset += f64::to_radians(offset_error_deg);
        let (_, tripped) = run_on(s, m, 0.0, ticks, |_| 0.5, |_| 0.0);
        let at = tripped.map(|k| k as f64 / rate);
        eprintln!(
            "pole pairs {true_pp} (drive 4), offset {offset_error_deg}° off: latched at {at:?} s"
        );
        assert!(
            at.is_some(),
            "pole pairs {true_pp}, offset {offset_error_deg}°: no latch in 0.5 s"
        );
    }
    let mut m = Motor::new(s);
    m.inertia_s = Some(0.05);
    m.offset += f64::to_radians(20.0);
    let (_, tripped) = run_on(s, m, 0.0, ticks, |_| 0.5, |_| 0.0);
    assert_eq!(tripped, None, "20° off latched");
}

/// Every bad setting is an error naming its key, never a panic.
#[test]
fn bad_foc_settings_name_their_key() {
    type Edit = fn(&mut FocSettings);
    let cases: [(Edit, &str); 5] = [
        (|s| s.pole_pairs = 0, "pmsm.pole_pairs"),
        (|s| s.dc_bus_pu = f32::NAN, "pmsm.dc_bus_pu"),
        (|s| s.d_inductance_pu_s = -1.0, "pmsm.d_inductance_pu_s"),
        (|s| s.flux_linkage_pu = f32::INFINITY, "flux_linkage_pu"),
        (
            |s| s.current_bandwidth_rad_s = 1e9,
            "current_bandwidth_rad_s",
        ),
    ];
    for (edit, key) in cases {
        let mut s = settings();
        edit(&mut s);
        let e = FocCoefficients::new(&s).expect_err("refused");
        assert!(format!("{e}").contains(key), "{e} names {key}");
    }
    let _ = Dq::default();
}
