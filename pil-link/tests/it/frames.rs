//! Frame round trips, corruption, noise and sequence checks. Corruption must never panic the
//! decoder and must always be reported: the firmware latches its safe state on these errors.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use crate::common;

use pil_link::{
    Decoder, Frame, FrameKind, LinkError, MAX_FRAME, MAX_PAYLOAD, PROTOCOL_VERSION, SequenceCheck,
};
use proptest::prelude::*;

fn encode(frame: &Frame) -> Vec<u8> {
    let mut wire = [0_u8; MAX_FRAME];
    let n = frame.encode(&mut wire).unwrap();
    wire[..n].to_vec()
}

/// Feeds bytes and collects every completed frame or error.
fn decode_all(decoder: &mut Decoder, bytes: &[u8]) -> Vec<Result<Frame, LinkError>> {
    bytes
        .iter()
        .filter_map(|&b| decoder.push(b).transpose())
        .collect()
}

const KINDS: [FrameKind; 8] = [
    FrameKind::Hello,
    FrameKind::HelloAck,
    FrameKind::Config,
    FrameKind::ConfigAck,
    FrameKind::Sensors,
    FrameKind::Commands,
    FrameKind::Fault,
    FrameKind::Stop,
];

fn arb_frame() -> impl Strategy<Value = Frame> {
    (
        0..KINDS.len(),
        any::<u16>(),
        proptest::collection::vec(any::<u8>(), 0..=MAX_PAYLOAD),
    )
        .prop_map(|(k, seq, payload)| Frame::new(KINDS[k], seq, &payload).unwrap())
}

#[test]
fn wire_layout_is_as_documented() {
    let frame = Frame::new(FrameKind::Sensors, 0x1234, &[0xDE, 0xAD]).unwrap();
    let wire = encode(&frame);
    assert_eq!(
        &wire[..9],
        &[
            0xA5,
            0x5A,
            PROTOCOL_VERSION,
            0x05,
            0x34,
            0x12,
            2,
            0xDE,
            0xAD
        ]
    );
    let crc = pil_link::crc32(&wire[2..9]);
    assert_eq!(&wire[9..], &crc.to_le_bytes());
}

#[test]
fn oversized_payload_is_refused() {
    let big = [0_u8; MAX_PAYLOAD + 1];
    assert_eq!(
        Frame::new(FrameKind::Config, 0, &big),
        Err(LinkError::BufferTooSmall {
            needed: MAX_PAYLOAD + 1
        })
    );
}

#[test]
fn bad_length_byte_is_reported_and_decoder_resyncs() {
    let mut bytes = vec![0xA5, 0x5A, 1, 0x05, 0, 0, 0xFF];
    let good = Frame::new(FrameKind::Stop, 9, &[]).unwrap();
    bytes.extend(encode(&good));
    let mut d = Decoder::new();
    let out = decode_all(&mut d, &bytes);
    assert_eq!(out, vec![Err(LinkError::BadLength { len: 0xFF }), Ok(good)]);
}

#[test]
fn intact_frame_of_another_version_is_bad_version() {
    let mut wire = encode(&Frame::new(FrameKind::Hello, 0, &[1, 2, 3, 4]).unwrap());
    let other = PROTOCOL_VERSION.wrapping_add(1);
    wire[2] = other;
    let n = wire.len();
    let crc = pil_link::crc32(&wire[2..n - 4]);
    wire[n - 4..].copy_from_slice(&crc.to_le_bytes());
    let mut d = Decoder::new();
    assert_eq!(
        decode_all(&mut d, &wire),
        vec![Err(LinkError::BadVersion { received: other })]
    );
}

#[test]
fn intact_frame_of_unknown_kind_is_reported() {
    let mut wire = encode(&Frame::new(FrameKind::Hello, 0, &[]).unwrap());
    wire[3] = 0x42;
    let n = wire.len();
    let crc = pil_link::crc32(&wire[2..n - 4]);
    wire[n - 4..].copy_from_slice(&crc.to_le_bytes());
    let mut d = Decoder::new();
    assert_eq!(
        decode_all(&mut d, &wire),
        vec![Err(LinkError::UnknownKind { kind: 0x42 })]
    );
}

#[test]
fn sequence_gap_repeat_and_wrap() {
    let mut s = SequenceCheck::new(u16::MAX);
    assert_eq!(s.accept(u16::MAX), Ok(()));
    assert_eq!(s.accept(0), Ok(()), "sequence numbers wrap");
    assert_eq!(
        s.accept(2),
        Err(LinkError::OutOfSequence {
            expected: 1,
            received: 2
        }),
        "a dropped frame is a gap"
    );
    assert_eq!(s.accept(1), Ok(()));
    assert_eq!(
        s.accept(1),
        Err(LinkError::OutOfSequence {
            expected: 2,
            received: 1
        }),
        "a repeated frame is out of sequence"
    );
}

proptest! {
    #[test]
    fn round_trip(frames in proptest::collection::vec(arb_frame(), 1..8)) {
        let mut wire = Vec::new();
        for f in &frames {
            wire.extend(encode(f));
        }
        let mut d = Decoder::new();
        let out = decode_all(&mut d, &wire);
        prop_assert_eq!(out, frames.into_iter().map(Ok).collect::<Vec<_>>());
        prop_assert!(d.is_idle());
    }

    /// Noise before a frame (that does not itself look like a frame start) is skipped.
    #[test]
    fn leading_noise_is_skipped(frame in arb_frame(),
                                noise in proptest::collection::vec(any::<u8>().prop_filter("no sync", |b| *b != 0xA5), 0..64)) {
        let mut wire = noise.clone();
        wire.extend(encode(&frame));
        let mut d = Decoder::new();
        prop_assert_eq!(decode_all(&mut d, &wire), vec![Ok(frame)]);
        prop_assert_eq!(d.skipped_bytes() as usize, noise.len());
    }

    /// Any error burst of up to 32 bits after the sync pair is detected: CRC-32 guarantees
    /// it, so this is an exact property, not a probabilistic one. (Bursts that hit the
    /// length byte may also surface as `BadLength` or leave the frame incomplete; in no case
    /// is a frame accepted.)
    #[test]
    fn burst_errors_are_always_detected(frame in arb_frame(), start in any::<prop::sample::Index>(),
                                        burst in 1_u64..=u64::from(u32::MAX), shift in 0_u32..8) {
        let wire = encode(&frame);
        let body_bits = (wire.len() - 2) * 8;
        let start_bit = 16 + start.index(body_bits);
        let mut corrupted = wire.clone();
        // The burst pattern starts and ends on a 1 bit; spread it over the bits after start.
        let pattern = (burst | 1) << shift;
        for i in 0..40 {
            if pattern >> i & 1 == 1 {
                let bit = start_bit + i;
                if bit / 8 < corrupted.len() && i < 32 + shift as usize {
                    corrupted[bit / 8] ^= 1 << (bit % 8);
                }
            }
        }
        prop_assume!(corrupted != wire);
        let mut d = Decoder::new();
        // Follow with enough zeros to complete any frame whose length grew.
        corrupted.extend([0_u8; MAX_FRAME]);
        let out = decode_all(&mut d, &corrupted);
        prop_assert!(!out.contains(&Ok(frame)), "corrupted frame accepted: {:?}", out);
        prop_assert!(out.iter().all(|r| r.is_err()), "a frame was accepted: {:?}", out);
    }

    /// Arbitrary corruption of any bytes (sync included) never panics and is never accepted;
    /// an accepted frame would need a CRC-32 collision (probability 2^-32 per case).
    #[test]
    fn random_corruption_never_panics_and_is_detected(frame in arb_frame(),
                                                      hits in proptest::collection::vec((any::<prop::sample::Index>(), 1_u8..=255), 1..6)) {
        let wire = encode(&frame);
        let mut corrupted = wire.clone();
        for (idx, mask) in &hits {
            let i = idx.index(corrupted.len());
            corrupted[i] ^= mask;
        }
        // Hits on one byte can cancel (the same mask twice): then nothing is corrupted.
        prop_assume!(corrupted != wire);
        corrupted.extend([0_u8; MAX_FRAME]);
        let mut d = Decoder::new();
        let out = decode_all(&mut d, &corrupted);
        prop_assert!(out.iter().all(|r| r.is_err()), "corruption accepted: {:?}", out);
    }

    /// Pure noise never panics the decoder.
    #[test]
    fn noise_never_panics(noise in proptest::collection::vec(any::<u8>(), 0..2048)) {
        let mut d = Decoder::new();
        let _ = decode_all(&mut d, &noise);
    }

    /// Truncation (a lost tail) yields no frame; the next good frame after it is found as
    /// soon as the truncated one's claimed length has run out.
    #[test]
    fn truncated_frame_is_not_accepted(frame in arb_frame(), cut in any::<prop::sample::Index>()) {
        let wire = encode(&frame);
        let keep = cut.index(wire.len());
        let mut d = Decoder::new();
        let out = decode_all(&mut d, &wire[..keep]);
        prop_assert!(out.is_empty());
    }
}

mod payloads {
    use super::common;
    use controller_core::foc::Dq;
    use controller_core::per_unit::{Counts, CountsErr, Pu, PuPerS};
    use controller_core::{
        CurrentInputs, CurrentOutputs, Fault, FilterConfig, PmsmInputs, PmsmOutputs, Setpoint,
        VelocityInputs, VelocityOutputs,
    };
    use pil_link::tick::{Applied, Commands, Sensors};
    use pil_link::wire::Writer;
    use pil_link::{LinkError, MAX_PAYLOAD, settings};
    use proptest::prelude::*;

    fn fault(k: u8) -> Option<Fault> {
        [
            None,
            Some(Fault::Overspeed),
            Some(Fault::FollowingError),
            Some(Fault::EncoderJump),
            Some(Fault::External),
        ][usize::from(k % 5)]
    }

    proptest! {
        #[test]
        fn sensors_round_trip(enc in any::<u32>(), i in any::<i32>(), pos in any::<i64>(),
                              v in any::<i32>(), a in any::<i32>(), fi in any::<bool>()) {
            for s in [
                Sensors::Current(CurrentInputs { encoder_count: enc, current_pu: Pu::from_bits(i) }),
                Sensors::Velocity(VelocityInputs {
                    encoder_count: enc,
                    setpoint: Setpoint {
                        position_counts: Counts::from_bits(pos),
                        velocity_pu: Pu::from_bits(v),
                        acceleration_pu_s: PuPerS::from_bits(a),
                    },
                    fault_input: fi,
                }),
                Sensors::Pmsm(PmsmInputs {
                    encoder_count: enc,
                    phase_current_pu: [Pu::from_bits(i), Pu::from_bits(v)],
                }),
            ] {
                let mut w = Writer::new();
                s.encode(&mut w).unwrap();
                prop_assert_eq!(Sensors::decode(w.as_slice()), Ok(s));
                // Any truncation is refused, never misread.
                for n in 0..w.as_slice().len() {
                    prop_assert!(Sensors::decode(&w.as_slice()[..n]).is_err());
                }
            }
        }

        #[test]
        fn commands_round_trip(x in proptest::array::uniform8(any::<i32>()), k in any::<u8>(),
                               en in any::<bool>(), t in any::<u32>()) {
            for c in [
                Commands::Current(
                    CurrentOutputs {
                        voltage_cmd_pu: Pu::from_bits(x[0]),
                        current_ref_pu: Pu::from_bits(x[1]),
                        accel_fb_pu: Pu::from_bits(x[2]),
                        fault: fault(k),
                    },
                    Applied { voltage_bits: x[3], enabled: en, isr_ticks: t, excitation_bits: x[7] },
                ),
                Commands::Velocity(VelocityOutputs {
                    current_ref_pu: Pu::from_bits(x[0]),
                    accel_fb_pu: Pu::from_bits(x[1]),
                    velocity_cmd_pu: Pu::from_bits(x[2]),
                    velocity_est_pu: Pu::from_bits(x[3]),
                    acceleration_est_pu_s: PuPerS::from_bits(x[4]),
                    position_error_counts: CountsErr::from_bits(x[5]),
                    disturbance_est_pu: Pu::from_bits(x[6]),
                    fault: fault(k),
                }),
                Commands::Pmsm(
                    PmsmOutputs {
                        duties: [x[0] as u16, (x[1] >> 16) as u16, x[2] as u16],
                        enabled: en,
                        current: Dq { d: Pu::from_bits(x[3]), q: Pu::from_bits(x[4]) },
                        current_ref: Dq { d: Pu::from_bits(x[5]), q: Pu::from_bits(x[6]) },
                        voltage: Dq { d: Pu::from_bits(x[7]), q: Pu::from_bits(x[0]) },
                        torque_ref_pu: Pu::from_bits(x[1]),
                        accel_fb_pu: Pu::from_bits(x[2]),
                        fault: fault(k),
                    },
                    Applied { voltage_bits: 0, enabled: en, isr_ticks: t, excitation_bits: x[7] },
                ),
            ] {
                let mut w = Writer::new();
                c.encode(&mut w).unwrap();
                prop_assert!(w.as_slice().len() <= MAX_PAYLOAD);
                prop_assert_eq!(Commands::decode(w.as_slice()), Ok(c));
            }
        }

        #[test]
        fn drive_config_round_trips_bit_for_bit(bits in proptest::array::uniform12(any::<u32>())) {
            let mut cfg = common::table1();
            cfg.motor_inertia_s = f32::from_bits(bits[0]);
            cfg.velocity_bandwidth_rad_s = f32::from_bits(bits[1]);
            cfg.velocity_filter = FilterConfig::FirstOrder { corner_hz: f32::from_bits(bits[2]) };
            cfg.accel_feedback.gain_fraction = f32::from_bits(bits[3]);
            cfg.faults.encoder_jump_margin = f32::from_bits(bits[4]);
            if bits[5] % 2 == 1 {
                cfg.velocity_pi_inertia = controller_core::PiInertia::TotalPlusAfb;
            }
            if bits[5] & 2 == 2 {
                cfg.observer.torque_input = controller_core::ObserverTorque::MeasuredCurrent;
            }
            if bits[5] & 4 == 4 {
                cfg.notch = Some(controller_core::NotchConfig {
                    centre_hz: f32::from_bits(bits[6]),
                    width_hz: f32::from_bits(bits[7]),
                    depth_db: f32::from_bits(bits[8]),
                });
            }
            let mut w = Writer::new();
            settings::encode(&cfg, &mut w).unwrap();
            prop_assert_eq!(w.as_slice().len(), settings::LEN);
            let back = settings::decode(w.as_slice()).unwrap();
            // Compare as bytes: NaN payloads must survive too.
            let mut w2 = Writer::new();
            settings::encode(&back, &mut w2).unwrap();
            prop_assert_eq!(w.as_slice(), w2.as_slice());
        }
    }

    #[test]
    fn bad_tags_are_refused() {
        assert!(matches!(
            Sensors::decode(&[9, 0, 0, 0, 0, 0, 0, 0, 0]),
            Err(LinkError::BadPayload { .. })
        ));
        let mut w = Writer::new();
        settings::encode(&common::table1(), &mut w).unwrap();
        let mut bytes = w.as_slice().to_vec();
        bytes[66] = 7; // velocity filter tag
        assert!(settings::decode(&bytes).is_err());
        let mut bytes = w.as_slice().to_vec();
        bytes[37] = 2; // velocity_pi_inertia
        assert!(settings::decode(&bytes).is_err());
        let mut bytes = w.as_slice().to_vec();
        bytes[N0 - 13] = 2; // the notch's present byte
        assert!(settings::decode(&bytes).is_err());
    }

    /// Where the notch's section ends: the PMSM section follows it.
    const N0: usize = settings::LEN - settings::PMSM_LEN;

    #[test]
    fn the_notch_travels_with_the_drive() {
        let mut cfg = common::table1();
        let mut w = Writer::new();
        settings::encode(&cfg, &mut w).unwrap();
        let without = w.as_slice().to_vec();
        // No notch: a zero present byte and zeros.
        assert_eq!(&without[N0 - 13..], &[0; 13 + settings::PMSM_LEN]);
        assert_eq!(settings::decode(&without).unwrap().notch, None);
        let n = controller_core::NotchConfig {
            centre_hz: 65.25,
            width_hz: 20.0,
            depth_db: 30.0,
        };
        cfg.notch = Some(n);
        let mut w = Writer::new();
        settings::encode(&cfg, &mut w).unwrap();
        let with = w.as_slice();
        assert_eq!(with.len(), settings::LEN);
        // Everything before the notch is the same bytes.
        assert_eq!(&with[..N0 - 13], &without[..N0 - 13]);
        assert_eq!(with[N0 - 13], 1);
        assert_eq!(&with[N0 - 12..N0 - 8], &65.25_f32.to_le_bytes());
        assert_eq!(settings::decode(with).unwrap(), cfg);
        // Any truncation is refused.
        for k in 0..with.len() {
            assert!(settings::decode(&with[..k]).is_err(), "{k} bytes");
        }
    }

    /// A PMSM drive's `[drive.pmsm]` travels whole, after the notch; a DC drive's section
    /// is zeros; a flag byte other than 0 or 1 is refused.
    #[test]
    fn the_pmsm_section_travels_with_the_drive() {
        let mut cfg = common::table1();
        let mut w = Writer::new();
        settings::encode(&cfg, &mut w).unwrap();
        let dc = w.as_slice().to_vec();
        assert_eq!(&dc[N0..], &[0; settings::PMSM_LEN]);
        for offset in [None, Some(-137.25_f32)] {
            cfg.pmsm = Some(controller_core::foc::PmsmConfig {
                pole_pairs: 7,
                d_inductance_pu_s: 3e-4,
                q_inductance_pu_s: 4.5e-4,
                flux_linkage_pu: 0.9,
                dc_bus_pu: 1.8,
                encoder_offset_elec_deg: offset,
                encoder_reversed: true,
                angle_advance_ticks: 1.25,
                pwm_period_counts: 4199,
                commutation_min_speed_pu: 0.07,
                commutation_trip_s: 0.03,
            });
            let mut w = Writer::new();
            settings::encode(&cfg, &mut w).unwrap();
            let bytes = w.as_slice();
            assert_eq!(bytes.len(), settings::LEN);
            assert_eq!(&bytes[..N0], &dc[..N0]);
            assert_eq!(bytes[N0], 1);
            assert_eq!(settings::decode(bytes).unwrap(), cfg);
            for flag in [N0, N0 + 21, N0 + 26] {
                let mut bad = bytes.to_vec();
                bad[flag] = 2;
                assert!(settings::decode(&bad).is_err(), "flag byte {flag}");
            }
        }
    }
}
