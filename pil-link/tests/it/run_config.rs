//! The `Config` payload with the identification excitation (`run_config`): every field of
//! `ExcitationConfig` round-trips exactly (`f32` as raw bits, NaN payloads included), any
//! truncation or trailing byte is refused, and a bad tag or injection byte is a
//! `BadPayload` of the `Config` frame.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use crate::common;

use controller_core::excitation::{ExcitationConfig, Injection, Waveform};
use pil_link::wire::Writer;
use pil_link::{FrameKind, LinkError, run_config, settings};
use proptest::prelude::*;

fn payload(e: Option<&ExcitationConfig>) -> Vec<u8> {
    let mut w = Writer::new();
    run_config::encode(&common::table1(), e, &mut w).unwrap();
    w.as_slice().to_vec()
}

fn prbs() -> ExcitationConfig {
    ExcitationConfig {
        waveform: Waveform::Prbs {
            bits: 11,
            hold_ticks: 3,
            periods: 4,
        },
        amplitude_pu: 0.05,
        injection: Injection::TorqueReference,
    }
}

fn chirp() -> ExcitationConfig {
    ExcitationConfig {
        waveform: Waveform::Chirp {
            start_hz: 1.5,
            end_hz: 900.0,
            duration_s: 2.25,
        },
        amplitude_pu: 0.2,
        injection: Injection::VelocityReference,
    }
}

/// Bit-exact equality (`PartialEq` on f32 would call NaN unequal and -0 equal to +0).
fn bits(e: &ExcitationConfig) -> (u8, u32, [u32; 3]) {
    let inj = match e.injection {
        Injection::TorqueReference => 0,
        Injection::VelocityReference => 1,
    };
    let w = match e.waveform {
        Waveform::Prbs {
            bits,
            hold_ticks,
            periods,
        } => [u32::from(bits), u32::from(hold_ticks), u32::from(periods)],
        Waveform::Chirp {
            start_hz,
            end_hz,
            duration_s,
        } => [start_hz.to_bits(), end_hz.to_bits(), duration_s.to_bits()],
    };
    (inj, e.amplitude_pu.to_bits(), w)
}

#[test]
fn payload_lengths_and_the_no_excitation_section() {
    let none = payload(None);
    assert_eq!(none.len(), settings::LEN + 1);
    assert_eq!(none[settings::LEN], 0);
    assert_eq!(payload(Some(&prbs())).len(), settings::LEN + 11);
    assert_eq!(payload(Some(&chirp())).len(), run_config::MAX_LEN);
    assert_eq!(run_config::decode(&none).unwrap(), (common::table1(), None));
    // The settings bytes are those of `settings::encode`, unchanged.
    let mut w = Writer::new();
    settings::encode(&common::table1(), &mut w).unwrap();
    assert_eq!(&none[..settings::LEN], w.as_slice());
}

#[test]
fn both_waveforms_round_trip() {
    for e in [prbs(), chirp()] {
        let (drive, back) = run_config::decode(&payload(Some(&e))).unwrap();
        assert_eq!(drive, common::table1());
        assert_eq!(bits(&back.unwrap()), bits(&e));
    }
}

#[test]
fn every_truncation_and_a_trailing_byte_are_refused() {
    for e in [None, Some(prbs()), Some(chirp())] {
        let p = payload(e.as_ref());
        for n in 0..p.len() {
            assert!(
                run_config::decode(&p[..n]).is_err(),
                "{n} of {} bytes",
                p.len()
            );
        }
        let mut long = p.clone();
        long.push(0);
        assert!(run_config::decode(&long).is_err());
    }
}

#[test]
fn a_bad_tag_or_injection_byte_is_a_bad_config_payload() {
    let config = FrameKind::Config as u8;
    for (at, value) in [(0, 3_u8), (0, 0xFF), (1, 2), (1, 0xFF)] {
        let mut p = payload(Some(&prbs()));
        p[settings::LEN + at] = value;
        let len = u8::try_from(p.len()).unwrap();
        assert_eq!(
            run_config::decode(&p),
            Err(LinkError::BadPayload { kind: config, len }),
            "byte {at} = {value}"
        );
    }
    // A PRBS section relabelled as a chirp is short for one: refused, never misread.
    let mut p = payload(Some(&prbs()));
    p[settings::LEN] = 2;
    assert!(run_config::decode(&p).is_err());
}

proptest! {
    #[test]
    fn any_field_bits_round_trip(amp in any::<u32>(), f in proptest::array::uniform3(any::<u32>()),
                                 b in any::<u8>(), h in any::<u16>(), n in any::<u16>(),
                                 velocity in any::<bool>()) {
        let injection = if velocity { Injection::VelocityReference } else { Injection::TorqueReference };
        for waveform in [
            Waveform::Prbs { bits: b, hold_ticks: h, periods: n },
            Waveform::Chirp {
                start_hz: f32::from_bits(f[0]),
                end_hz: f32::from_bits(f[1]),
                duration_s: f32::from_bits(f[2]),
            },
        ] {
            let e = ExcitationConfig { waveform, amplitude_pu: f32::from_bits(amp), injection };
            let (_, back) = run_config::decode(&payload(Some(&e))).unwrap();
            prop_assert_eq!(bits(&back.unwrap()), bits(&e));
        }
    }
}
