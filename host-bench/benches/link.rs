//! Host cost of the link per frame: encoding, decoding (byte at a time, CRC-32 included) and
//! the firmware session's handling of a `Sensors` frame. Figures are reported in
//! `docs/benchmarks.md`, not asserted. `cargo bench -p host-bench --bench link`
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    missing_docs
)]

use controller_core::per_unit::{Counts, Pu, PuPerS};
use controller_core::{Setpoint, VelocityInputs};
use criterion::{Criterion, Throughput, black_box, criterion_group, criterion_main};
use pil_link::tick::Sensors;
use pil_link::wire::{Reader, Writer};
use pil_link::{
    Decoder, FaultCode, FirmwareSession, Frame, FrameKind, Hello, MAX_FRAME, SafeOutputs, Target,
};

fn sensors_frame(seq: u16) -> Frame {
    let s = Sensors::Velocity(VelocityInputs {
        encoder_count: 12_345,
        setpoint: Setpoint {
            position_counts: Counts::from_num(68_266),
            velocity_pu: Pu::from_num(1),
            acceleration_pu_s: PuPerS::from_num(1),
        },
        fault_input: false,
    });
    let mut w = Writer::new();
    s.encode(&mut w).unwrap();
    Frame::new(FrameKind::Sensors, seq, w.as_slice()).unwrap()
}

struct Echo;

impl Target for Echo {
    fn configure(&mut self, _: &[u8]) -> Result<(), FaultCode> {
        Ok(())
    }
    fn tick(&mut self, sensors: &[u8], out: &mut Writer) -> Result<(), FaultCode> {
        let x = Reader::new(FrameKind::Sensors, sensors)
            .u8()
            .map_err(|_| FaultCode::BadPayload)?;
        out.u8(x).map(|_| ()).map_err(|_| FaultCode::BadPayload)
    }
    fn enter_safe_state(&mut self) -> SafeOutputs {
        SafeOutputs {
            current_tick_ran: true,
            ..SafeOutputs::default()
        }
    }
}

fn bench(c: &mut Criterion) {
    let frame = sensors_frame(7);
    let mut wire = [0_u8; MAX_FRAME];
    let n = frame.encode(&mut wire).unwrap();
    let mut g = c.benchmark_group("pil_link");
    g.throughput(Throughput::Bytes(n as u64));
    g.bench_function("encode_velocity_sensors_frame", |b| {
        b.iter(|| black_box(&frame).encode(black_box(&mut wire)).unwrap())
    });
    g.bench_function("decode_velocity_sensors_frame", |b| {
        let mut d = Decoder::new();
        b.iter(|| {
            let mut out = None;
            for &byte in &wire[..n] {
                if let Ok(Some(f)) = d.push(byte) {
                    out = Some(f);
                }
            }
            black_box(out)
        })
    });
    g.bench_function("firmware_session_sensors_frame", |b| {
        let mut s = FirmwareSession::new(1);
        let mut t = Echo;
        let mut w = Writer::new();
        Hello {
            watchdog_ms: u32::MAX,
        }
        .encode(&mut w)
        .unwrap();
        let mut hello = [0_u8; MAX_FRAME];
        let hn = Frame::new(FrameKind::Hello, 0, w.as_slice())
            .unwrap()
            .encode(&mut hello)
            .unwrap();
        for &byte in &hello[..hn] {
            s.on_byte(byte, 0, &mut t);
        }
        let mut cfg = [0_u8; MAX_FRAME];
        let cn = Frame::new(FrameKind::Config, 1, &[0])
            .unwrap()
            .encode(&mut cfg)
            .unwrap();
        for &byte in &cfg[..cn] {
            s.on_byte(byte, 0, &mut t);
        }
        let mut seq = 2_u16;
        b.iter(|| {
            let f = sensors_frame(seq);
            seq = seq.wrapping_add(1);
            let mut buf = [0_u8; MAX_FRAME];
            let k = f.encode(&mut buf).unwrap();
            let mut reply = None;
            for &byte in &buf[..k] {
                if let Some(r) = s.on_byte(byte, 0, &mut t) {
                    reply = Some(r);
                }
            }
            black_box(reply.expect("a reply per frame"))
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
