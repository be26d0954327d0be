//! `Simulator(car, road="iso8608-C", speed=, changes=, sensors=)`: a quarter-car, half-car or
//! full-car drive on an ISO 8608 road with parameter changes and a sensor set, the core's
//! [`QuarterDrive`], [`HalfDrive`] and [`FullDrive`]. Conversion and validation only; the core simulates.

use crate::convert::{py_str, speed_arg};
use crate::model::{Kind, PyLinearModel};
use crate::{core_err, option, VehidError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use vehid_core::sim::{
    Change, DriveConfig, FullChange, FullDrive, FullDriveConfig, FullLoad, HalfChange, HalfDrive, HalfDriveConfig,
    QuarterDrive, RoadClass, SensorNoise, SensorSet, MAX_CHANGES,
};
use vehid_core::{Error, Result};

/// Samples simulated between two looks at pending signals.
const CHUNK: usize = 1 << 14;

/// The samples of one drive run, row-major.
pub struct DriveRun {
    pub t: Vec<f64>,
    pub s: Vec<f64>,
    pub x: Vec<f64>,
    pub xdot: Vec<f64>,
    pub u: Vec<f64>,
    pub y: Vec<f64>,
    /// The constants in effect per sample (quarter car `[M, m, k1, k2, b]`, half car
    /// `HalfCar::CONSTANTS`).
    pub constants: Vec<f64>,
    pub len: usize,
    pub channels: usize,
    /// States, inputs and constants per sample (4, 1, 5 or 8, 2, 12).
    pub dims: [usize; 3],
}

/// The drive of either car.
#[derive(Clone)]
pub enum AnyDrive {
    Quarter(Box<QuarterDrive<f64>>),
    Half(Box<HalfDrive<f64>>),
    Full(Box<FullDrive<f64>>),
}

/// A drive with its speed profile.
#[derive(Clone)]
pub struct DriveSim {
    pub drive: AnyDrive,
    /// Per-sample speeds, m/s (empty: the configured constant speed).
    speeds: Vec<f64>,
    next: usize,
}

/// Keyword arguments of the linear simulator that a drive does not use.
pub struct Unused<'a> {
    pub road_sigma: bool,
    pub ic_sigma: f64,
    pub substeps: bool,
    pub method: &'a str,
    pub pulses: bool,
    pub instrumentation: bool,
    pub spacing: bool,
}

impl DriveSim {
    /// Builds the drive of `Simulator(car, dt, road="iso8608-X", speed, changes, sensors,
    /// sensor_noise, state_noise, deriv_noise, seed)`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        model: &PyLinearModel,
        dt: f64,
        road: &str,
        speed: Option<&Bound<'_, PyAny>>,
        changes: Option<&Bound<'_, PyAny>>,
        sensors: Option<&str>,
        sensor_noise: Option<&Bound<'_, PyDict>>,
        state_noise: Option<f64>,
        deriv_noise: Option<f64>,
        seed: u64,
        unused: Unused<'_>,
    ) -> PyResult<Self> {
        if !matches!(model.kind, Kind::Quarter(_) | Kind::Half(_) | Kind::Full(_)) {
            return Err(VehidError::new_err(
                "a drive (road='iso8608-A'..'iso8608-E', changes=, sensors=) simulates a vehid.QuarterCar, a \
                 vehid.HalfCar or a vehid.FullCar",
            ));
        }
        for (given, name) in [
            (unused.road_sigma, "road_sigma"),
            (unused.ic_sigma != 0.0, "ic_sigma"),
            (unused.substeps, "substeps"),
            (unused.method != "rk4", "method"),
            (unused.pulses, "pulses"),
            (unused.instrumentation, "instrumentation"),
            (unused.spacing, "spacing"),
        ] {
            if given {
                return Err(VehidError::new_err(format!(
                    "`{name}` does not apply to a drive on an ISO 8608 road (road={}): the road's roughness \
                     is its class, the integration is exact; leave `{name}` out",
                    py_str(road)
                )));
            }
        }
        let road: RoadClass = option(road)?;
        let sensors: SensorSet = option(sensors.unwrap_or("realistic"))?;
        let mut noise = sensor_noise_arg(sensor_noise)?;
        for (v, name, slot) in [(state_noise, "state_noise", 0), (deriv_noise, "deriv_noise", 1)] {
            let Some(v) = v else { continue };
            if sensors != SensorSet::State {
                return Err(VehidError::new_err(format!(
                    "`{name}` is the noise of the state sensors (sensors='state'); the realistic sensors' noise is \
                     set by sensor_noise={{'a_body': ..., 'a_wheel': ..., 'deflection': ...}}"
                )));
            }
            if slot == 0 {
                noise.state = v;
            } else {
                noise.deriv = v;
            }
        }
        let (speed, speeds) = speed_arg(speed, 15.0)?;
        if let Some(i) = speeds.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(VehidError::new_err(format!(
                "`speed[{i}]` is {}: speeds must be finite and >= 0 m/s",
                speeds[i]
            )));
        }
        let base = DriveConfig::new(dt).road(road).speed(speed).sensors(sensors).noise(noise);
        let (changes, loads) = parse_changes(changes)?;
        let bad = |e: vehid_core::Error| VehidError::new_err(format!("`changes`: {e}"));
        if !loads.is_empty() && !matches!(model.kind, Kind::Full(_)) {
            return Err(VehidError::new_err(
                "`changes`: a point load ('load' kg at 'load_x', 'load_y' m from the centre of mass) is set down on \
                 a vehid.FullCar; for this car change 'M' (a load spread like the body's mass)",
            ));
        }
        let drive = match model.kind {
            Kind::Half(car) => {
                let mut cfg = HalfDriveConfig::new(base);
                for (t, name, v, ramp) in changes {
                    cfg = cfg.with_change(HalfChange::ramp(t, &name, v, ramp).map_err(bad)?).map_err(core_err)?;
                }
                AnyDrive::Half(Box::new(HalfDrive::new(car, cfg, seed).map_err(core_err)?))
            }
            Kind::Full(car) => {
                let mut cfg = FullDriveConfig::new(base);
                for (t, name, v, ramp) in changes {
                    cfg = cfg.with_change(FullChange::ramp(t, &name, v, ramp).map_err(bad)?).map_err(core_err)?;
                }
                for (t, [m, x, y], ramp) in loads {
                    cfg = cfg.with_load(FullLoad::ramp(t, m, x, y, ramp).map_err(bad)?).map_err(bad)?;
                }
                AnyDrive::Full(Box::new(FullDrive::new(car, cfg, seed).map_err(core_err)?))
            }
            Kind::Quarter(car) => {
                let mut cfg = base;
                for (t, name, v, ramp) in changes {
                    cfg = cfg.with_change(Change::ramp(t, &name, v, ramp).map_err(bad)?).map_err(core_err)?;
                }
                AnyDrive::Quarter(Box::new(QuarterDrive::new(car, cfg, seed).map_err(core_err)?))
            }
            Kind::Generic => unreachable!("checked above"),
        };
        Ok(Self { drive, speeds, next: 0 })
    }

    /// Samples produced so far.
    pub fn k(&self) -> u64 {
        match &self.drive {
            AnyDrive::Quarter(d) => d.k(),
            AnyDrive::Half(d) => d.k(),
            AnyDrive::Full(d) => d.k(),
        }
    }

    /// The drive's settings (road, speed, sensors, noise).
    pub fn config(&self) -> &DriveConfig<f64> {
        match &self.drive {
            AnyDrive::Quarter(d) => d.config(),
            AnyDrive::Half(d) => &d.config().base,
            AnyDrive::Full(d) => &d.config().base,
        }
    }

    /// States, inputs and constants per sample.
    pub fn dims(&self) -> [usize; 3] {
        match &self.drive {
            AnyDrive::Quarter(_) => [4, 1, 5],
            AnyDrive::Half(_) => [8, 2, 12],
            AnyDrive::Full(_) => [14, 4, 25],
        }
    }

    /// The sensor channel names.
    pub fn channels(&self) -> &'static [&'static str] {
        match &self.drive {
            AnyDrive::Quarter(d) => d.channels(),
            AnyDrive::Half(d) => d.channels(),
            AnyDrive::Full(d) => d.channels(),
        }
    }

    /// Simulates `n` more samples, all or nothing (an error or an interrupt puts the drive
    /// back where it was).
    ///
    /// # Errors
    /// [`Error::OutOfMemory`], [`Error::Interrupted`], [`Error::InvalidArgument`] for a
    /// speed profile with fewer than `n` samples left.
    pub fn run(&mut self, n: usize, interrupt: &mut dyn FnMut() -> bool) -> Result<DriveRun> {
        if !self.speeds.is_empty() && n > self.speeds.len() - self.next {
            return Err(Error::InvalidArgument {
                arg: "n",
                expected: "at most as many samples as the `speed` array has entries left",
            });
        }
        let c = self.channels().len();
        let dims @ [ns, ni, nc] = self.dims();
        let bytes = n.checked_mul(1 + 1 + 2 * ns + ni + c + nc).and_then(|v| v.checked_mul(8));
        let oom = Error::OutOfMemory { what: "the simulated drive", bytes: bytes.unwrap_or(usize::MAX) };
        if bytes.is_none_or(|b| b > isize::MAX as usize) {
            return Err(oom);
        }
        let mut out = DriveRun {
            t: vec![],
            s: vec![],
            x: vec![],
            xdot: vec![],
            u: vec![],
            y: vec![],
            constants: vec![],
            len: n,
            channels: c,
            dims,
        };
        for (v, w) in [
            (&mut out.t, 1),
            (&mut out.s, 1),
            (&mut out.x, ns),
            (&mut out.xdot, ns),
            (&mut out.u, ni),
            (&mut out.y, c),
            (&mut out.constants, nc),
        ] {
            v.try_reserve_exact(n * w).map_err(|_| oom.clone())?;
        }
        let start = self.clone();
        for k in 0..n {
            if k % CHUNK == 0 && k > 0 && interrupt() {
                *self = start;
                return Err(Error::Interrupted);
            }
            let speed = if self.speeds.is_empty() {
                None
            } else {
                self.next += 1;
                Some(self.speeds[self.next - 1])
            };
            // One sample of either drive into `out` (their samples differ only in `u`'s width).
            macro_rules! record {
                ($d:expr, |$s:ident| $push_u:expr) => {{
                    let sample = match speed {
                        None => Ok($d.next_sample()),
                        Some(v) => $d.next_sample_at(v),
                    };
                    sample.map(|$s| {
                        out.t.push($s.t);
                        out.s.push($s.s);
                        out.x.extend_from_slice($s.x.as_slice());
                        out.xdot.extend_from_slice($s.xdot.as_slice());
                        $push_u;
                        out.y.extend_from_slice($s.y());
                        out.constants.extend_from_slice(&$s.constants);
                    })
                }};
            }
            let pushed = match &mut self.drive {
                AnyDrive::Quarter(d) => record!(d, |s| out.u.push(s.u)),
                AnyDrive::Half(d) => record!(d, |s| out.u.extend_from_slice(&s.u)),
                AnyDrive::Full(d) => record!(d, |s| out.u.extend_from_slice(&s.u)),
            };
            if let Err(e) = pushed {
                *self = start;
                return Err(e);
            }
        }
        Ok(out)
    }
}

/// `sensor_noise={"a_body": 0.02, ...}`: the defaults of [`SensorNoise`] with the given
/// standard deviations, each checked finite and ≥ 0 (shared by `Simulator` and
/// `HealthMonitor`).
pub fn sensor_noise_arg(sensor_noise: Option<&Bound<'_, PyDict>>) -> PyResult<SensorNoise<f64>> {
    let mut noise = SensorNoise::<f64>::default();
    let Some(d) = sensor_noise else { return Ok(noise) };
    for (k, v) in d.iter() {
        let key: String = k
            .extract()
            .map_err(|_| VehidError::new_err("`sensor_noise` keys must be strings such as 'a_body' or 'deflection'"))?;
        let v: f64 = v.extract().map_err(|_| {
            VehidError::new_err(format!("`sensor_noise[{}]` must be a number (a standard deviation)", py_str(&key)))
        })?;
        let slot = match key.as_str() {
            "a_body" => &mut noise.a_body,
            "a_body_bias" => &mut noise.a_body_bias,
            "a_wheel" => &mut noise.a_wheel,
            "a_wheel_bias" => &mut noise.a_wheel_bias,
            "deflection" => &mut noise.deflection,
            "state" => &mut noise.state,
            "deriv" => &mut noise.deriv,
            other => {
                return Err(VehidError::new_err(format!(
                    "`sensor_noise` has no entry {}: use 'a_body', 'a_body_bias', 'a_wheel', 'a_wheel_bias', \
                     'deflection' (realistic sensors) or 'state', 'deriv' (state sensors)",
                    py_str(other)
                )))
            }
        };
        *slot = v;
    }
    noise.validate().map_err(crate::core_err)?;
    Ok(noise)
}

/// `changes=[(t, {"b": 1350.0}), (t, {"k2": 19800.0}, ramp_seconds), ...]`: `(t, name,
/// value, ramp)` per constant (the names are checked by the core's change of the car).
/// A point load of a full-car drive: `(t, [mass, x, y], ramp)`.
type Load = (f64, [f64; 3], f64);

/// The constant changes `(t, name, value, ramp)` and the point loads of `changes`.
#[allow(clippy::type_complexity)]
fn parse_changes(changes: Option<&Bound<'_, PyAny>>) -> PyResult<(Vec<(f64, String, f64, f64)>, Vec<Load>)> {
    let Some(obj) = changes else { return Ok((vec![], vec![])) };
    let usage = "`changes` must be a list of (t, {name: value}) or (t, {name: value}, ramp) tuples, e.g. \
                 [(60.0, {'b': 1350.0})]: t and ramp in seconds, names 'M', 'm', 'k1', 'k2', 'b' (QuarterCar) or \
                 'M', 'J', 'k1_f', 'k1_r', 'k2_f', 'k2_r', 'b_f', 'b_r', 'm_f', 'm_r' (HalfCar) or 'M', 'Jx', 'Jy', \
                 'kt_fl' .. 'kt_rr', 'k_fl' .. 'k_rr', 'b_fl' .. 'b_rr', 'm_fl' .. 'm_rr', 'arb_f', 'arb_r', and a point \
                 load 'load' (kg) at 'load_x', 'load_y' (m forward and to the left of the centre of mass, default 0) \
                 (FullCar)";
    let mut out = Vec::new();
    let mut loads = Vec::new();
    for item in obj.try_iter().map_err(|_| VehidError::new_err(usage))? {
        let item = item?;
        let tuple = item.cast::<PyTuple>().map_err(|_| VehidError::new_err(usage))?;
        if !(2..=3).contains(&tuple.len()) {
            return Err(VehidError::new_err(usage));
        }
        let t: f64 = tuple.get_item(0)?.extract().map_err(|_| VehidError::new_err(usage))?;
        let ramp: f64 = match tuple.len() {
            3 => tuple.get_item(2)?.extract().map_err(|_| VehidError::new_err(usage))?,
            _ => 0.0,
        };
        let values = tuple.get_item(1)?;
        let values = values.cast::<PyDict>().map_err(|_| VehidError::new_err(usage))?;
        let mut load: [Option<f64>; 3] = [None; 3];
        for (k, v) in values.iter() {
            let name: String = k.extract().map_err(|_| VehidError::new_err(usage))?;
            let v: f64 = v.extract().map_err(|_| VehidError::new_err(usage))?;
            match ["load", "load_x", "load_y"].iter().position(|n| *n == name) {
                Some(i) => load[i] = Some(v),
                None => out.push((t, name, v, ramp)),
            }
        }
        match load {
            [None, None, None] => {}
            [Some(m), x, y] => loads.push((t, [m, x.unwrap_or(0.0), y.unwrap_or(0.0)], ramp)),
            [None, ..] => {
                return Err(VehidError::new_err(
                    "`changes`: 'load_x' and 'load_y' place a point load: give its mass too, e.g. {'load': 100.0, \
                     'load_x': -2.0}",
                ))
            }
        }
    }
    if out.len() > MAX_CHANGES {
        return Err(VehidError::new_err(format!(
            "`changes` names {} constant changes; a drive holds at most {MAX_CHANGES}",
            out.len()
        )));
    }
    Ok((out, loads))
}
