//! The sensor sets of a quarter car and their noise: shared by the drive simulator
//! (`sim::drive`) and the health monitor (`health`), which must not depend on each other.

use crate::error::check_nonneg;
use crate::{Real, Result};

/// Channel names of [`SensorSet::Realistic`]: body and wheel acceleration (m/s²),
/// suspension deflection `zb − zw` (m).
pub const REALISTIC_CHANNELS: [&str; 3] = ["a_body", "a_wheel", "deflection"];

/// Channel names of [`SensorSet::State`]: the measured state `r` (wheel position m, wheel
/// velocity m/s, body position m, body velocity m/s) then the measured derivative `z`.
pub const STATE_CHANNELS: [&str; 8] = ["zw", "vw", "zb", "vb", "dzw", "dvw", "dzb", "dvb"];

/// Channel names of [`SensorSet::Realistic`] on the half car: body accelerometers above
/// the front and the rear axle (m/s²), front and rear wheel accelerometers (m/s²), front and
/// rear suspension deflection (extension, m: `zb + l1 φ − z1`, `zb − l2 φ − z2`).
pub const HALF_REALISTIC_CHANNELS: [&str; 6] =
    ["a_body_f", "a_body_r", "a_wheel_f", "a_wheel_r", "deflection_f", "deflection_r"];

/// Channel names of [`SensorSet::State`] on the half car: the measured state `r` (front
/// wheel, rear wheel, body heave: position m, velocity m/s; pitch rad, rad/s), then the
/// measured derivative `z`.
pub const HALF_STATE_CHANNELS: [&str; 16] =
    ["z1", "v1", "z2", "v2", "zb", "vb", "ph", "om", "dz1", "dv1", "dz2", "dv2", "dzb", "dvb", "dph", "dom"];

/// Channel names of [`SensorSet::Realistic`] on the full car: a body accelerometer above each
/// wheel (m/s², `z̈b + x_i θ̈ + y_i φ̈`, small angles), a wheel accelerometer per corner (m/s²)
/// and each corner's suspension extension (m, `zb + x_i θ + y_i φ − z_i`), corners in the
/// order `fl, fr, rl, rr`.
pub const FULL_REALISTIC_CHANNELS: [&str; 12] = [
    "a_body_fl",
    "a_body_fr",
    "a_body_rl",
    "a_body_rr",
    "a_wheel_fl",
    "a_wheel_fr",
    "a_wheel_rl",
    "a_wheel_rr",
    "deflection_fl",
    "deflection_fr",
    "deflection_rl",
    "deflection_rr",
];

/// Channel names of [`SensorSet::State`] on the full car: the measured state `r` (the names of
/// [`crate::model::FULL_STATE_NAMES`]) then the measured derivative `z` (each name with a `d`).
pub const FULL_STATE_CHANNELS: [&str; 28] = [
    "z_fl",
    "v_fl",
    "z_fr",
    "v_fr",
    "z_rl",
    "v_rl",
    "z_rr",
    "v_rr",
    "zb",
    "vb",
    "pitch",
    "pitch_rate",
    "roll",
    "roll_rate",
    "dz_fl",
    "dv_fl",
    "dz_fr",
    "dv_fr",
    "dz_rl",
    "dv_rl",
    "dz_rr",
    "dv_rr",
    "dzb",
    "dvb",
    "dpitch",
    "dpitch_rate",
    "droll",
    "droll_rate",
];

/// Which sensors a vehicle has: what a drive (`sim::QuarterDrive`) reports and what the
/// health monitor (`health::HealthMonitor`) reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum SensorSet {
    /// The thesis' measured state and derivative ([`STATE_CHANNELS`]).
    State,
    /// Accelerometers and a deflection sensor ([`REALISTIC_CHANNELS`]).
    #[default]
    Realistic,
}

option_names!(SensorSet, "sensors", { State => "state", Realistic => "realistic" });

impl SensorSet {
    /// The channel names of this set on the half car.
    pub fn half_channels(&self) -> &'static [&'static str] {
        match self {
            SensorSet::State => &HALF_STATE_CHANNELS,
            SensorSet::Realistic => &HALF_REALISTIC_CHANNELS,
        }
    }

    /// The channel names of this set on the full car.
    pub fn full_channels(&self) -> &'static [&'static str] {
        match self {
            SensorSet::State => &FULL_STATE_CHANNELS,
            SensorSet::Realistic => &FULL_REALISTIC_CHANNELS,
        }
    }

    /// The channel names of this set.
    pub fn channels(&self) -> &'static [&'static str] {
        match self {
            SensorSet::State => &STATE_CHANNELS,
            SensorSet::Realistic => &REALISTIC_CHANNELS,
        }
    }
}

/// Sensor noise levels (standard deviations per sample at the drive's rate).
///
/// Defaults, typical of automotive sensors sampled at 100–1000 Hz:
/// - body accelerometer: 0.02 m/s² white noise (a low-g MEMS part of ~150 µg/√Hz over a
///   100 Hz band: 150e-6 · 9.81 · √100 ≈ 0.015 m/s²), constant bias ~ N(0, 0.1²) m/s²
///   (zero-g offset ±10 mg after mounting);
/// - wheel accelerometer: 0.1 m/s² white noise (a high-g, ±50 g, MEMS part of
///   ~1 mg/√Hz), bias ~ N(0, 0.3²) m/s²;
/// - deflection (ride-height) sensor: 0.3 mm white noise (a Hall-effect angle sensor on
///   the control arm, 12 bits over ±100 mm of travel: 0.05 mm steps, ~0.3 mm noise);
/// - state set: no noise (set `state`, `deriv` for the thesis' σ_w, σ_v).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorNoise<T> {
    /// Body accelerometer white noise, m/s².
    pub a_body: T,
    /// Standard deviation of the body accelerometer's constant bias, m/s².
    pub a_body_bias: T,
    /// Wheel accelerometer white noise, m/s².
    pub a_wheel: T,
    /// Standard deviation of the wheel accelerometer's constant bias, m/s².
    pub a_wheel_bias: T,
    /// Deflection sensor white noise, m.
    pub deflection: T,
    /// State set: noise on every measured state (state units).
    pub state: T,
    /// State set: noise on every measured derivative (state units per second).
    pub deriv: T,
}

impl<T: Real> Default for SensorNoise<T> {
    fn default() -> Self {
        Self {
            a_body: T::of(0.02),
            a_body_bias: T::of(0.1),
            a_wheel: T::of(0.1),
            a_wheel_bias: T::of(0.3),
            deflection: T::of(0.3e-3),
            state: T::zero(),
            deriv: T::zero(),
        }
    }
}

impl<T: Real> SensorNoise<T> {
    /// Checks every level is finite and ≥ 0.
    ///
    /// # Errors
    /// [`crate::Error::InvalidArgument`] naming the level (`noise.a_body`, …).
    pub fn validate(&self) -> Result<()> {
        check_nonneg("noise.a_body", self.a_body)?;
        check_nonneg("noise.a_body_bias", self.a_body_bias)?;
        check_nonneg("noise.a_wheel", self.a_wheel)?;
        check_nonneg("noise.a_wheel_bias", self.a_wheel_bias)?;
        check_nonneg("noise.deflection", self.deflection)?;
        check_nonneg("noise.state", self.state)?;
        check_nonneg("noise.deriv", self.deriv)
    }
}
