//! `Simulator(car, road="iso8608-C", speed=, changes=, sensors=)`: a quarter-car drive on an
//! ISO 8608 road with parameter changes and a sensor set (issue 17), the core's
//! [`QuarterDrive`]. Conversion and validation only; the core simulates.

use crate::convert::{py_str, speed_arg};
use crate::model::{Kind, PyLinearModel};
use crate::{core_err, option, VehidError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use vehid_core::model::QuarterCar;
use vehid_core::sim::{Change, DriveConfig, QuarterDrive, RoadClass, SensorNoise, SensorSet, MAX_CHANGES};
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
    /// The constants in effect per sample `[M, m, k1, k2, b]`.
    pub constants: Vec<f64>,
    pub len: usize,
    pub channels: usize,
}

/// A drive with its speed profile.
#[derive(Clone)]
pub struct DriveSim {
    pub drive: QuarterDrive<f64>,
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
        let car: QuarterCar<f64> =
            match model.kind {
                Kind::Quarter(c) => c,
                _ => return Err(VehidError::new_err(
                    "a drive (road='iso8608-A'..'iso8608-E', changes=, sensors=) simulates a vehid.QuarterCar; the \
                     half car runs on the thesis' road (speed=, spacing=, road='white' or 'independent')",
                )),
            };
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
        let mut cfg = DriveConfig::new(dt).road(road).speed(speed).sensors(sensors).noise(noise);
        for c in parse_changes(changes)? {
            cfg = cfg.with_change(c).map_err(core_err)?;
        }
        let drive = QuarterDrive::new(car, cfg, seed).map_err(core_err)?;
        Ok(Self { drive, speeds, next: 0 })
    }

    /// The sensor channel names.
    pub fn channels(&self) -> &'static [&'static str] {
        self.drive.channels()
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
        let bytes = n.checked_mul(1 + 1 + 4 + 4 + 1 + c + 5).and_then(|v| v.checked_mul(8));
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
        };
        for (v, w) in [
            (&mut out.t, 1),
            (&mut out.s, 1),
            (&mut out.x, 4),
            (&mut out.xdot, 4),
            (&mut out.u, 1),
            (&mut out.y, c),
            (&mut out.constants, 5),
        ] {
            v.try_reserve_exact(n * w).map_err(|_| oom.clone())?;
        }
        let start = self.clone();
        for k in 0..n {
            if k % CHUNK == 0 && k > 0 && interrupt() {
                *self = start;
                return Err(Error::Interrupted);
            }
            let sample = if self.speeds.is_empty() {
                self.drive.next_sample()
            } else {
                let v = self.speeds[self.next];
                self.next += 1;
                match self.drive.next_sample_at(v) {
                    Ok(s) => s,
                    Err(e) => {
                        *self = start;
                        return Err(e);
                    }
                }
            };
            out.t.push(sample.t);
            out.s.push(sample.s);
            out.x.extend_from_slice(sample.x.as_slice());
            out.xdot.extend_from_slice(sample.xdot.as_slice());
            out.u.push(sample.u);
            out.y.extend_from_slice(sample.y());
            out.constants.extend_from_slice(&sample.constants);
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

/// `changes=[(t, {"b": 1350.0}), (t, {"k2": 19800.0}, ramp_seconds), ...]`.
fn parse_changes(changes: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<Change<f64>>> {
    let Some(obj) = changes else { return Ok(vec![]) };
    let usage = "`changes` must be a list of (t, {name: value}) or (t, {name: value}, ramp) tuples, e.g. \
                 [(60.0, {'b': 1350.0})]: t and ramp in seconds, names 'M', 'm', 'k1', 'k2', 'b'";
    let mut out = Vec::new();
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
        for (k, v) in values.iter() {
            let name: String = k.extract().map_err(|_| VehidError::new_err(usage))?;
            let v: f64 = v.extract().map_err(|_| VehidError::new_err(usage))?;
            out.push(Change::ramp(t, &name, v, ramp).map_err(|e| VehidError::new_err(format!("`changes`: {e}")))?);
        }
    }
    if out.len() > MAX_CHANGES {
        return Err(VehidError::new_err(format!(
            "`changes` names {} constant changes; a drive holds at most {MAX_CHANGES}",
            out.len()
        )));
    }
    Ok(out)
}
