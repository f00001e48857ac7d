//! The `Config` payload: controller-core's [`DriveConfig`], field by field, `f32` as raw
//! IEEE bits. The firmware designs its gains from exactly the numbers the host used, so the
//! comparison also checks that `design` (the one place floats are used) gives the same
//! fixed-point coefficients on the Cortex-M4F as on the host.
//!
//! Layout (110 bytes): the scalar fields in declaration order, each filter as
//! `tag u8 (0 none, 1 first order, 2 second order) | corner_hz f32 | q f32`, each enum as u8.

use crate::wire::{Reader, Writer};
use crate::{FrameKind, LinkError};
use controller_core::{
    AccelFeedbackConfig, AfbMode, AfbRate, DriveConfig, Estimator, FaultLimits, FilterConfig,
    ObserverConfig, ObserverInertia, ObserverTorque, PiInertia,
};

/// Payload bytes of a [`DriveConfig`].
///
/// ```
/// use pil_link::{settings, wire::Writer};
/// # let cfg: controller_core::DriveConfig = toml::from_str(include_str!(concat!(
/// #     env!("CARGO_MANIFEST_DIR"), "/../controller-core/doc/example-drive.toml"))).unwrap();
/// let mut w = Writer::new();
/// settings::encode(&cfg, &mut w).unwrap();
/// assert_eq!(w.as_slice().len(), settings::LEN);
/// assert_eq!(settings::decode(w.as_slice()), Ok(cfg));
/// ```
pub fn encode(cfg: &DriveConfig, w: &mut Writer) -> Result<(), LinkError> {
    // Exhaustive destructuring: a field added to DriveConfig fails to compile here.
    let DriveConfig {
        base_speed_rpm,
        encoder_cpr,
        counter_bits,
        current_rate_hz,
        velocity_rate_hz,
        motor_inertia_s,
        load_inertia_s,
        position_bandwidth_rad_s,
        velocity_bandwidth_rad_s,
        velocity_damping,
        velocity_pi_inertia,
        current_bandwidth_rad_s,
        winding_resistance_pu,
        winding_inductance_pu_s,
        torque_limit_pu,
        voltage_limit_pu,
        velocity_ff_gain,
        accel_ff_gain,
        velocity_filter,
        velocity_estimator,
        accel_feedback,
        observer,
        faults,
    } = *cfg;
    let AccelFeedbackConfig {
        mode,
        gain_fraction,
        filter,
        rate,
        source,
    } = accel_feedback;
    let ObserverConfig {
        bandwidth_hz,
        model_inertia,
        torque_input,
    } = observer;
    let FaultLimits {
        overspeed_pu,
        following_error_counts,
        encoder_jump_margin,
    } = faults;
    w.u32(base_speed_rpm.to_bits())?
        .u32(encoder_cpr)?
        .u8(counter_bits)?
        .u32(current_rate_hz)?
        .u32(velocity_rate_hz)?;
    for x in [
        motor_inertia_s,
        load_inertia_s,
        position_bandwidth_rad_s,
        velocity_bandwidth_rad_s,
        velocity_damping,
    ] {
        w.u32(x.to_bits())?;
    }
    w.u8(match velocity_pi_inertia {
        PiInertia::Total => 0,
        PiInertia::TotalPlusAfb => 1,
    })?;
    for x in [
        current_bandwidth_rad_s,
        winding_resistance_pu,
        winding_inductance_pu_s,
        torque_limit_pu,
        voltage_limit_pu,
        velocity_ff_gain,
        accel_ff_gain,
    ] {
        w.u32(x.to_bits())?;
    }
    put_filter(w, velocity_filter)?;
    w.u8(estimator_byte(velocity_estimator))?;
    w.u8(match mode {
        AfbMode::Off => 0,
        AfbMode::Plain => 1,
        AfbMode::Error => 2,
    })?
    .u32(gain_fraction.to_bits())?;
    put_filter(w, filter)?;
    w.u8(match rate {
        AfbRate::Current => 0,
        AfbRate::Velocity => 1,
    })?
    .u8(estimator_byte(source))?
    .u32(bandwidth_hz.to_bits())?
    .u8(match model_inertia {
        ObserverInertia::Total => 0,
        ObserverInertia::Motor => 1,
    })?
    .u8(match torque_input {
        ObserverTorque::Command => 0,
        ObserverTorque::MeasuredCurrent => 1,
    })?
    .u32(overspeed_pu.to_bits())?
    .u32(following_error_counts.to_bits())?
    .u32(encoder_jump_margin.to_bits())?;
    Ok(())
}

/// Length of the payload [`encode`] writes, in bytes.
pub const LEN: usize = 110;

/// Parses a `Config` payload.
pub fn decode(payload: &[u8]) -> Result<DriveConfig, LinkError> {
    let mut r = Reader::new(FrameKind::Config, payload);
    let bad = LinkError::BadPayload {
        kind: FrameKind::Config as u8,
        len: u8::try_from(payload.len()).unwrap_or(u8::MAX),
    };
    let base_speed_rpm = f(&mut r)?;
    let encoder_cpr = r.u32()?;
    let counter_bits = r.u8()?;
    let current_rate_hz = r.u32()?;
    let velocity_rate_hz = r.u32()?;
    let motor_inertia_s = f(&mut r)?;
    let load_inertia_s = f(&mut r)?;
    let position_bandwidth_rad_s = f(&mut r)?;
    let velocity_bandwidth_rad_s = f(&mut r)?;
    let velocity_damping = f(&mut r)?;
    let velocity_pi_inertia = match r.u8()? {
        0 => PiInertia::Total,
        1 => PiInertia::TotalPlusAfb,
        _ => return Err(bad),
    };
    let current_bandwidth_rad_s = f(&mut r)?;
    let winding_resistance_pu = f(&mut r)?;
    let winding_inductance_pu_s = f(&mut r)?;
    let torque_limit_pu = f(&mut r)?;
    let voltage_limit_pu = f(&mut r)?;
    let velocity_ff_gain = f(&mut r)?;
    let accel_ff_gain = f(&mut r)?;
    let velocity_filter = get_filter(&mut r, bad)?;
    let velocity_estimator = get_estimator(&mut r, bad)?;
    let mode = match r.u8()? {
        0 => AfbMode::Off,
        1 => AfbMode::Plain,
        2 => AfbMode::Error,
        _ => return Err(bad),
    };
    let gain_fraction = f(&mut r)?;
    let filter = get_filter(&mut r, bad)?;
    let rate = match r.u8()? {
        0 => AfbRate::Current,
        1 => AfbRate::Velocity,
        _ => return Err(bad),
    };
    let source = get_estimator(&mut r, bad)?;
    let bandwidth_hz = f(&mut r)?;
    let model_inertia = match r.u8()? {
        0 => ObserverInertia::Total,
        1 => ObserverInertia::Motor,
        _ => return Err(bad),
    };
    let torque_input = match r.u8()? {
        0 => ObserverTorque::Command,
        1 => ObserverTorque::MeasuredCurrent,
        _ => return Err(bad),
    };
    let faults = FaultLimits {
        overspeed_pu: f(&mut r)?,
        following_error_counts: f(&mut r)?,
        encoder_jump_margin: f(&mut r)?,
    };
    r.finish()?;
    Ok(DriveConfig {
        base_speed_rpm,
        encoder_cpr,
        counter_bits,
        current_rate_hz,
        velocity_rate_hz,
        motor_inertia_s,
        load_inertia_s,
        position_bandwidth_rad_s,
        velocity_bandwidth_rad_s,
        velocity_damping,
        velocity_pi_inertia,
        current_bandwidth_rad_s,
        winding_resistance_pu,
        winding_inductance_pu_s,
        torque_limit_pu,
        voltage_limit_pu,
        velocity_ff_gain,
        accel_ff_gain,
        velocity_filter,
        velocity_estimator,
        accel_feedback: AccelFeedbackConfig {
            mode,
            gain_fraction,
            filter,
            rate,
            source,
        },
        observer: ObserverConfig {
            bandwidth_hz,
            model_inertia,
            torque_input,
        },
        faults,
    })
}

fn f(r: &mut Reader<'_>) -> Result<f32, LinkError> {
    r.u32().map(f32::from_bits)
}

const fn estimator_byte(e: Estimator) -> u8 {
    match e {
        Estimator::Differentiation => 0,
        Estimator::Observer => 1,
    }
}

fn get_estimator(r: &mut Reader<'_>, bad: LinkError) -> Result<Estimator, LinkError> {
    match r.u8()? {
        0 => Ok(Estimator::Differentiation),
        1 => Ok(Estimator::Observer),
        _ => Err(bad),
    }
}

fn put_filter(w: &mut Writer, filter: FilterConfig) -> Result<(), LinkError> {
    let (tag, corner_hz, q) = match filter {
        FilterConfig::None => (0, 0.0_f32, 0.0_f32),
        FilterConfig::FirstOrder { corner_hz } => (1, corner_hz, 0.0),
        FilterConfig::SecondOrder { corner_hz, q } => (2, corner_hz, q),
    };
    w.u8(tag)?.u32(corner_hz.to_bits())?.u32(q.to_bits())?;
    Ok(())
}

fn get_filter(r: &mut Reader<'_>, bad: LinkError) -> Result<FilterConfig, LinkError> {
    let tag = r.u8()?;
    let corner_hz = f(r)?;
    let q = f(r)?;
    match tag {
        0 => Ok(FilterConfig::None),
        1 => Ok(FilterConfig::FirstOrder { corner_hz }),
        2 => Ok(FilterConfig::SecondOrder { corner_hz, q }),
        _ => Err(bad),
    }
}
