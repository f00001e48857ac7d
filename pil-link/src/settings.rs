//! The `Config` payload: controller-core's [`DriveConfig`], field by field, `f32` as raw
//! IEEE bits. The firmware designs its gains from exactly the numbers the host used, so the
//! comparison also checks that `design` (the one place floats are used) gives the same
//! fixed-point coefficients on the Cortex-M4F as on the host.
//!
//! Layout ([`LEN`] bytes): the scalar fields in declaration order, each filter as
//! `tag u8 (0 none, 1 first order, 2 second order) | corner_hz f32 | q f32`, each enum as u8,
//! then the notch as `present u8 (0 none, 1 notch) | centre_hz f32 | width_hz f32 |
//! depth_db f32` (zeros without one), and last the PMSM current loop (`[drive.pmsm]`) as
//! `present u8 | pole_pairs u32 | d_inductance f32 | q_inductance f32 | flux_linkage f32 |
//! dc_bus f32 | offset_present u8 | offset_deg f32 | reversed u8 | angle_advance_ticks f32 |
//! pwm_period_counts u16 | commutation_min_speed f32 | commutation_trip_s f32` (zeros for a
//! DC drive).

use crate::wire::{Reader, Writer};
use crate::{FrameKind, LinkError};
use controller_core::foc::PmsmConfig;
use controller_core::{
    AccelFeedbackConfig, AfbFilterAtLimit, AfbMode, AfbRate, DriveConfig, Estimator, FaultLimits,
    FilterConfig, NotchConfig, ObserverConfig, ObserverInertia, ObserverTorque, PiInertia,
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
        notch,
        pmsm,
    } = *cfg;
    put_machine(
        w,
        &Machine {
            base_speed_rpm,
            encoder_cpr,
            counter_bits,
            current_rate_hz,
            velocity_rate_hz,
            motor_inertia_s,
            load_inertia_s,
        },
    )?;
    put_loops(
        w,
        &Loops {
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
        },
    )?;
    put_filter(w, velocity_filter)?;
    w.u8(estimator_byte(velocity_estimator))?;
    put_accel_feedback(w, accel_feedback)?;
    put_observer(w, observer)?;
    put_faults(w, faults)?;
    put_notch(w, notch)?;
    put_pmsm(w, pmsm)
}

/// Length of the payload [`encode`] writes, in bytes.
pub const LEN: usize = 168 + PMSM_LEN;

/// Bytes of the PMSM section, the last of the payload.
pub const PMSM_LEN: usize = 1 + 4 * 5 + 1 + 4 + 1 + 4 + 2 + 4 + 4;

/// Parses a `Config` payload.
pub fn decode(payload: &[u8]) -> Result<DriveConfig, LinkError> {
    let mut r = Reader::new(FrameKind::Config, payload);
    let bad = LinkError::BadPayload {
        kind: FrameKind::Config as u8,
        len: u8::try_from(payload.len()).unwrap_or(u8::MAX),
    };
    let Machine {
        base_speed_rpm,
        encoder_cpr,
        counter_bits,
        current_rate_hz,
        velocity_rate_hz,
        motor_inertia_s,
        load_inertia_s,
    } = get_machine(&mut r)?;
    let Loops {
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
    } = get_loops(&mut r, bad)?;
    let velocity_filter = get_filter(&mut r, bad)?;
    let velocity_estimator = get_estimator(&mut r, bad)?;
    let accel_feedback = get_accel_feedback(&mut r, bad)?;
    let observer = get_observer(&mut r, bad)?;
    let faults = get_faults(&mut r)?;
    let notch = get_notch(&mut r, bad)?;
    let pmsm = get_pmsm(&mut r, bad)?;
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
        accel_feedback,
        observer,
        faults,
        notch,
        pmsm,
    })
}

/// The machine group of [`DriveConfig`]: speed base, encoder, loop rates, inertias.
struct Machine {
    base_speed_rpm: f32,
    encoder_cpr: u32,
    counter_bits: u8,
    current_rate_hz: u32,
    velocity_rate_hz: u32,
    motor_inertia_s: f32,
    load_inertia_s: f32,
}

/// The loops group of [`DriveConfig`]: bandwidths, the current loop's winding model,
/// limits and feedforward gains.
struct Loops {
    position_bandwidth_rad_s: f32,
    velocity_bandwidth_rad_s: f32,
    velocity_damping: f32,
    velocity_pi_inertia: PiInertia,
    current_bandwidth_rad_s: f32,
    winding_resistance_pu: f32,
    winding_inductance_pu_s: f32,
    torque_limit_pu: f32,
    voltage_limit_pu: f32,
    velocity_ff_gain: f32,
    accel_ff_gain: f32,
}

fn put_machine(w: &mut Writer, m: &Machine) -> Result<(), LinkError> {
    w.u32(m.base_speed_rpm.to_bits())?
        .u32(m.encoder_cpr)?
        .u8(m.counter_bits)?
        .u32(m.current_rate_hz)?
        .u32(m.velocity_rate_hz)?
        .u32(m.motor_inertia_s.to_bits())?
        .u32(m.load_inertia_s.to_bits())?;
    Ok(())
}

fn get_machine(r: &mut Reader<'_>) -> Result<Machine, LinkError> {
    Ok(Machine {
        base_speed_rpm: f(r)?,
        encoder_cpr: r.u32()?,
        counter_bits: r.u8()?,
        current_rate_hz: r.u32()?,
        velocity_rate_hz: r.u32()?,
        motor_inertia_s: f(r)?,
        load_inertia_s: f(r)?,
    })
}

fn put_loops(w: &mut Writer, l: &Loops) -> Result<(), LinkError> {
    for x in [
        l.position_bandwidth_rad_s,
        l.velocity_bandwidth_rad_s,
        l.velocity_damping,
    ] {
        w.u32(x.to_bits())?;
    }
    w.u8(match l.velocity_pi_inertia {
        PiInertia::Total => 0,
        PiInertia::TotalPlusAfb => 1,
    })?;
    for x in [
        l.current_bandwidth_rad_s,
        l.winding_resistance_pu,
        l.winding_inductance_pu_s,
        l.torque_limit_pu,
        l.voltage_limit_pu,
        l.velocity_ff_gain,
        l.accel_ff_gain,
    ] {
        w.u32(x.to_bits())?;
    }
    Ok(())
}

fn get_loops(r: &mut Reader<'_>, bad: LinkError) -> Result<Loops, LinkError> {
    Ok(Loops {
        position_bandwidth_rad_s: f(r)?,
        velocity_bandwidth_rad_s: f(r)?,
        velocity_damping: f(r)?,
        velocity_pi_inertia: match r.u8()? {
            0 => PiInertia::Total,
            1 => PiInertia::TotalPlusAfb,
            _ => return Err(bad),
        },
        current_bandwidth_rad_s: f(r)?,
        winding_resistance_pu: f(r)?,
        winding_inductance_pu_s: f(r)?,
        torque_limit_pu: f(r)?,
        voltage_limit_pu: f(r)?,
        velocity_ff_gain: f(r)?,
        accel_ff_gain: f(r)?,
    })
}

fn put_accel_feedback(w: &mut Writer, afb: AccelFeedbackConfig) -> Result<(), LinkError> {
    let AccelFeedbackConfig {
        mode,
        gain_fraction,
        filter,
        rate,
        source,
        limit_headroom_fraction,
        filter_at_limit,
    } = afb;
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
    .u32(limit_headroom_fraction.to_bits())?
    .u8(match filter_at_limit {
        AfbFilterAtLimit::Track => 0,
        AfbFilterAtLimit::Hold => 1,
    })?;
    Ok(())
}

fn get_accel_feedback(
    r: &mut Reader<'_>,
    bad: LinkError,
) -> Result<AccelFeedbackConfig, LinkError> {
    let mode = match r.u8()? {
        0 => AfbMode::Off,
        1 => AfbMode::Plain,
        2 => AfbMode::Error,
        _ => return Err(bad),
    };
    let gain_fraction = f(r)?;
    let filter = get_filter(r, bad)?;
    let rate = match r.u8()? {
        0 => AfbRate::Current,
        1 => AfbRate::Velocity,
        _ => return Err(bad),
    };
    let source = get_estimator(r, bad)?;
    let limit_headroom_fraction = f(r)?;
    let filter_at_limit = match r.u8()? {
        0 => AfbFilterAtLimit::Track,
        1 => AfbFilterAtLimit::Hold,
        _ => return Err(bad),
    };
    Ok(AccelFeedbackConfig {
        mode,
        gain_fraction,
        filter,
        rate,
        source,
        limit_headroom_fraction,
        filter_at_limit,
    })
}

fn put_observer(w: &mut Writer, observer: ObserverConfig) -> Result<(), LinkError> {
    let ObserverConfig {
        bandwidth_hz,
        model_inertia,
        torque_input,
        count_interval_counts,
    } = observer;
    w.u32(bandwidth_hz.to_bits())?
        .u8(match model_inertia {
            ObserverInertia::Total => 0,
            ObserverInertia::Motor => 1,
        })?
        .u8(match torque_input {
            ObserverTorque::Command => 0,
            ObserverTorque::MeasuredCurrent => 1,
        })?
        .u32(count_interval_counts.to_bits())?;
    Ok(())
}

fn get_observer(r: &mut Reader<'_>, bad: LinkError) -> Result<ObserverConfig, LinkError> {
    let bandwidth_hz = f(r)?;
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
    let count_interval_counts = f(r)?;
    Ok(ObserverConfig {
        bandwidth_hz,
        model_inertia,
        torque_input,
        count_interval_counts,
    })
}

fn put_faults(w: &mut Writer, faults: FaultLimits) -> Result<(), LinkError> {
    let FaultLimits {
        overspeed_pu,
        following_error_rev,
        encoder_jump_margin,
        overcurrent_ratio,
        overcurrent_ticks,
        continuous_current_pu,
        overload_current_pu,
        overload_time_s,
        thermal_warning_fraction,
        stall_speed_pu,
        stall_torque_fraction,
        stall_time_s,
    } = faults;
    w.u32(overspeed_pu.to_bits())?
        .u32(following_error_rev.to_bits())?
        .u32(encoder_jump_margin.to_bits())?
        .u32(overcurrent_ratio.to_bits())?
        .u32(overcurrent_ticks)?
        .u32(continuous_current_pu.to_bits())?
        .u32(overload_current_pu.to_bits())?
        .u32(overload_time_s.to_bits())?
        .u32(thermal_warning_fraction.to_bits())?
        .u32(stall_speed_pu.to_bits())?
        .u32(stall_torque_fraction.to_bits())?
        .u32(stall_time_s.to_bits())?;
    Ok(())
}

fn get_faults(r: &mut Reader<'_>) -> Result<FaultLimits, LinkError> {
    Ok(FaultLimits {
        overspeed_pu: f(r)?,
        following_error_rev: f(r)?,
        encoder_jump_margin: f(r)?,
        overcurrent_ratio: f(r)?,
        overcurrent_ticks: r.u32()?,
        continuous_current_pu: f(r)?,
        overload_current_pu: f(r)?,
        overload_time_s: f(r)?,
        thermal_warning_fraction: f(r)?,
        stall_speed_pu: f(r)?,
        stall_torque_fraction: f(r)?,
        stall_time_s: f(r)?,
    })
}

fn put_notch(w: &mut Writer, notch: Option<NotchConfig>) -> Result<(), LinkError> {
    let (present, n) = match notch {
        Some(n) => (1, n),
        None => (
            0,
            NotchConfig {
                centre_hz: 0.0,
                width_hz: 0.0,
                depth_db: 0.0,
            },
        ),
    };
    let NotchConfig {
        centre_hz,
        width_hz,
        depth_db,
    } = n;
    w.u8(present)?
        .u32(centre_hz.to_bits())?
        .u32(width_hz.to_bits())?
        .u32(depth_db.to_bits())?;
    Ok(())
}

/// A flag byte: 0 or 1, anything else `bad`.
fn flag(r: &mut Reader<'_>, bad: LinkError) -> Result<bool, LinkError> {
    match r.u8()? {
        0 => Ok(false),
        1 => Ok(true),
        _ => Err(bad),
    }
}

fn get_notch(r: &mut Reader<'_>, bad: LinkError) -> Result<Option<NotchConfig>, LinkError> {
    let present = flag(r, bad)?;
    let n = NotchConfig {
        centre_hz: f(r)?,
        width_hz: f(r)?,
        depth_db: f(r)?,
    };
    Ok(present.then_some(n))
}

fn put_pmsm(w: &mut Writer, pmsm: Option<PmsmConfig>) -> Result<(), LinkError> {
    let Some(p) = pmsm else {
        return w.bytes(&[0; PMSM_LEN]).map(|_| ());
    };
    let PmsmConfig {
        pole_pairs,
        d_inductance_pu_s,
        q_inductance_pu_s,
        flux_linkage_pu,
        dc_bus_pu,
        encoder_offset_elec_deg,
        encoder_reversed,
        angle_advance_ticks,
        pwm_period_counts,
        commutation_min_speed_pu,
        commutation_trip_s,
    } = p;
    w.u8(1)?
        .u32(pole_pairs)?
        .u32(d_inductance_pu_s.to_bits())?
        .u32(q_inductance_pu_s.to_bits())?
        .u32(flux_linkage_pu.to_bits())?
        .u32(dc_bus_pu.to_bits())?
        .u8(u8::from(encoder_offset_elec_deg.is_some()))?
        .u32(encoder_offset_elec_deg.unwrap_or(0.0).to_bits())?
        .u8(u8::from(encoder_reversed))?
        .u32(angle_advance_ticks.to_bits())?
        .u16(pwm_period_counts)?
        .u32(commutation_min_speed_pu.to_bits())?
        .u32(commutation_trip_s.to_bits())?;
    Ok(())
}

fn get_pmsm(r: &mut Reader<'_>, bad: LinkError) -> Result<Option<PmsmConfig>, LinkError> {
    let present = flag(r, bad)?;
    let pole_pairs = r.u32()?;
    let d_inductance_pu_s = f(r)?;
    let q_inductance_pu_s = f(r)?;
    let flux_linkage_pu = f(r)?;
    let dc_bus_pu = f(r)?;
    let has_offset = flag(r, bad)?;
    let offset = f(r)?;
    let p = PmsmConfig {
        pole_pairs,
        d_inductance_pu_s,
        q_inductance_pu_s,
        flux_linkage_pu,
        dc_bus_pu,
        encoder_offset_elec_deg: has_offset.then_some(offset),
        encoder_reversed: flag(r, bad)?,
        angle_advance_ticks: f(r)?,
        pwm_period_counts: r.u16()?,
        commutation_min_speed_pu: f(r)?,
        commutation_trip_s: f(r)?,
    };
    Ok(present.then_some(p))
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
