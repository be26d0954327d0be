//! Two axles on one road: `TwoAxleIdentifier`, `AxleSampler`, and the road simulator behind
//! `Simulator(..., speed=, spacing=, road=)` (Ch. VI.D, issue 6). Thin wrappers of the core.

use crate::convert::{array, shape_str};
use crate::dispatch::{ModelData, SimDyn, SimParams, TooLarge};
use crate::model::{to_array2, Kind, PyLinearModel};
use crate::{core_err, VehidError};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use vehid_core::identify::{TwoAxleConfig, TwoAxleIdentifierVec, WheelMethod};
use vehid_core::nalgebra::SVector;
use vehid_core::sampler::{axle_delay, AxleSampler, Trigger};
use vehid_core::sim::{per_component, RoadConfig, RoadMode, RoadSimulator, Run, SimConfig};
use vehid_core::Result;

/// Road memory of the Python road simulator, in road points per wheelbase (+2).
pub const ROAD_CELLS: usize = 4096;
/// Ring capacity of the Python `AxleSampler`.
pub const SAMPLER_SLOTS: usize = 4096;

/// The wheelbase of a model: the half car's `l1 + l2`, or the one given.
fn wheelbase_of(model: &PyLinearModel, wheelbase: Option<f64>) -> PyResult<f64> {
    match (wheelbase, model.kind) {
        (Some(w), _) => Ok(w),
        (None, Kind::Half(car)) => Ok(car.wheelbase()),
        (None, _) => Err(VehidError::new_err(
            "`wheelbase` is needed for a model other than HalfCar (the distance between the axles, m)",
        )),
    }
}

fn half_dims(d: &ModelData, what: &str) -> PyResult<()> {
    if d.n != 8 || d.m != 2 {
        return Err(VehidError::new_err(format!(
            "{what} needs an 8-state model with 2 inputs (front and rear road), like HalfCar; got n={}, m={}",
            d.n, d.m
        )));
    }
    Ok(())
}

// ---- the road simulator behind Simulator(speed=...) ---------------------------------------

/// The speed profile: one value for every sample, or one per sample (zeros are stops).
#[derive(Debug, Clone)]
pub enum Speeds {
    Constant(f64),
    /// Entry `i` is the speed (m/s) over the road interval after the next sample; a zero is a
    /// stop of `stop` seconds on the road point reached, before its sample (no sample). `next` is the first unused entry.
    Profile {
        v: Vec<f64>,
        next: usize,
        stop: f64,
    },
}

/// `Simulator(..., speed=, spacing=, road=)`: a [`RoadSimulator`] of the half car.
pub struct RoadSim {
    sim: RoadSimulator<f64, 8, ROAD_CELLS>,
    speeds: Speeds,
}

impl RoadSim {
    /// Positive entries left in a profile (samples it can still produce); `None` = unbounded.
    pub fn samples_left(&self) -> Option<usize> {
        match &self.speeds {
            Speeds::Constant(_) => None,
            Speeds::Profile { v, next, .. } => Some(v[*next..].iter().filter(|x| **x > 0.0).count()),
        }
    }
}

impl SimDyn for RoadSim {
    fn run(&mut self, n: usize) -> core::result::Result<Run<f64>, TooLarge> {
        let mut out = Run::<f64> { n_states: 8, n_inputs: 2, ..Run::default() };
        let cap = |v: &mut Vec<f64>, w: usize| -> core::result::Result<(), TooLarge> {
            let len = n.checked_mul(w).ok_or(TooLarge)?;
            v.try_reserve_exact(len).map_err(|_| TooLarge)
        };
        cap(&mut out.t, 1)?;
        cap(&mut out.s, 1)?;
        for v in [&mut out.x, &mut out.xdot, &mut out.r, &mut out.z] {
            cap(v, 8)?;
        }
        cap(&mut out.u, 2)?;
        let mut done = 0;
        while done < n {
            let v = match &mut self.speeds {
                Speeds::Constant(v) => *v,
                Speeds::Profile { v, next, stop } => {
                    // Checked by the caller: enough positive entries remain.
                    let Some(&x) = v.get(*next) else { break };
                    *next += 1;
                    if x == 0.0 {
                        let _ = self.sim.wait(*stop);
                        continue;
                    }
                    x
                }
            };
            match self.sim.next_sample(v) {
                Ok(s) => out.push_road(&s),
                Err(_) => break, // validated speeds: unreachable
            }
            done += 1;
        }
        Ok(out)
    }

    fn substeps(&self) -> usize {
        0
    }

    fn samples(&self) -> u64 {
        self.sim.k()
    }
}

/// Builds the road simulator for `Simulator(model, speed=..., spacing=..., road=...)`.
pub fn road_simulator(
    model: &PyLinearModel,
    p: &SimParams,
    speed: Option<&Bound<'_, PyAny>>,
    spacing: f64,
    road: &str,
) -> PyResult<RoadSim> {
    half_dims(&model.data, "speed=/spacing=/road= (two axles on one road)")?;
    let mode = match road {
        "white" => RoadMode::White,
        "independent" => RoadMode::Independent,
        other => {
            return Err(VehidError::new_err(format!(
                "unknown `road` {other:?}: expected one of \"white\", \"independent\""
            )))
        }
    };
    if !p.pulses.is_empty() {
        return Err(VehidError::new_err(
            "`pulses` are not supported with speed=/spacing=/road= (samples are by distance)",
        ));
    }
    let speeds =
        match speed {
            None => Speeds::Constant(6.0),
            Some(obj) => {
                let a = array(obj, "speed")?;
                if let Some(i) = a.data.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
                    return Err(VehidError::new_err(format!(
                        "`speed[{i}]` = {} is not a finite speed >= 0 (m/s)",
                        a.data[i]
                    )));
                }
                match a.shape[..] {
                    [] if a.data[0] > 0.0 => Speeds::Constant(a.data[0]),
                    [] => return Err(VehidError::new_err(
                        "`speed` = 0: a stopped vehicle produces no samples (give a speed > 0 or a per-sample array)",
                    )),
                    [_] => Speeds::Profile { v: a.data, next: 0, stop: p.dt },
                    _ => {
                        return Err(VehidError::new_err(format!(
                            "`speed` must be a scalar or a 1-D array (one speed per sample), got shape {}",
                            shape_str(&a.shape)
                        )))
                    }
                }
            }
        };
    let wheelbase = wheelbase_of(model, None)?;
    let build = || -> Result<RoadSimulator<f64, 8, ROAD_CELLS>> {
        let mut cfg = SimConfig::<f64, 8, 2>::new(p.dt);
        cfg.road_sigma = per_component("road_sigma", &p.road_sigma)?;
        cfg.ic_sigma = p.ic_sigma;
        cfg.state_noise = per_component("state_noise", &p.state_noise)?;
        cfg.deriv_noise = per_component("deriv_noise", &p.deriv_noise)?;
        cfg.substeps = p.substeps;
        cfg.method = p.method;
        cfg.instrumentation = p.instrumentation;
        RoadSimulator::new(model.data.model::<8, 2>()?, cfg, RoadConfig::new(spacing, wheelbase).mode(mode), p.seed)
    };
    Ok(RoadSim { sim: build().map_err(core_err)?, speeds })
}

// ---- TwoAxleIdentifier ---------------------------------------------------------------------

fn method_arg(method: &str) -> PyResult<WheelMethod> {
    match method {
        "none" => Ok(WheelMethod::None),
        "thesis" => Ok(WheelMethod::Thesis),
        "cancel" => Ok(WheelMethod::Cancel),
        other => Err(VehidError::new_err(format!(
            "unknown `method` {other:?}: expected one of \"none\", \"thesis\", \"cancel\""
        ))),
    }
}

fn method_name(m: WheelMethod) -> &'static str {
    match m {
        WheelMethod::None => "none",
        WheelMethod::Thesis => "thesis",
        WheelMethod::Cancel => "cancel",
    }
}

type Id = TwoAxleIdentifierVec<f64, 8, 16>;

/// Identifier of the unknown rows of a half car driven along one road (Ch. VI.D).
///
/// Samples must be taken every `spacing` metres (e.g. `Simulator(half, speed=..., spacing=...)`
/// or `AxleSampler`), so that the rear axle is over the road point of the sample
/// d = wheelbase / spacing samples earlier. `method`: "none" (plain Kalman rows, Eq 6.16–6.18;
/// the rear row is biased by the correlated input), "thesis" (Eq 6.12–6.14: the front row's
/// innovation d samples earlier subtracted from the rear row's), "cancel" (the joint regression
/// of z4(k) − (b42/b21) z2(k−d) on [x(k), −(b42/b21) x(k−d)], in which the road input cancels;
/// variance σ_v²(1 + (b42/b21)²), plus the direct front equation weighted by its own variance).
/// The body rows are plain Kalman rows. `road_sigma` (m) and `deriv_noise` give every
/// equation's variance; `p0` is P(0) on every row (`p0_body` overrides it on the body rows).
#[pyclass(name = "TwoAxleIdentifier", module = "vehid._vehid")]
pub struct PyTwoAxleIdentifier {
    inner: Id,
    model: Py<PyLinearModel>,
    spacing: f64,
    wheelbase: f64,
}

fn sample_vecs(r: &Bound<'_, PyAny>, z: &Bound<'_, PyAny>) -> PyResult<(SVector<f64, 8>, SVector<f64, 8>)> {
    let ra = array(r, "r_k")?;
    let za = array(z, "z_k")?;
    for (name, a) in [("r_k", &ra), ("z_k", &za)] {
        if a.shape != [8] {
            return Err(VehidError::new_err(format!("`{name}` must have shape (8,), got {}", shape_str(&a.shape))));
        }
    }
    Ok((SVector::from_column_slice(&ra.data), SVector::from_column_slice(&za.data)))
}

#[pymethods]
impl PyTwoAxleIdentifier {
    #[new]
    #[pyo3(signature = (model, spacing = 0.3, method = "cancel", p0 = 1000.0, road_sigma = 0.1, deriv_noise = 0.005,
                        *, p0_body = None, wheelbase = None, direct_front = true))]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        model: Bound<'_, PyLinearModel>,
        spacing: f64,
        method: &str,
        p0: f64,
        road_sigma: f64,
        deriv_noise: f64,
        p0_body: Option<f64>,
        wheelbase: Option<f64>,
        direct_front: bool,
    ) -> PyResult<Self> {
        let m = model.get();
        half_dims(&m.data, "TwoAxleIdentifier")?;
        let wheelbase = wheelbase_of(m, wheelbase)?;
        let (d, residual) = axle_delay(wheelbase, spacing).map_err(core_err)?;
        if residual > 1e-9 * wheelbase {
            return Err(VehidError::new_err(format!(
                "`spacing` = {spacing} does not divide the wheelbase {wheelbase} m: the rear axle must be over an \
                 earlier sample point (use e.g. {:.6} m)",
                wheelbase / d as f64
            )));
        }
        let mut cfg = TwoAxleConfig::new(method_arg(method)?, p0, road_sigma, deriv_noise);
        cfg.p0_body = p0_body.unwrap_or(p0);
        cfg.direct_front = direct_front;
        let core = m.data.model::<8, 2>().map_err(core_err)?;
        let inner = Id::new(&core, d, cfg).map_err(core_err)?;
        Ok(Self { inner, model: model.unbind(), spacing, wheelbase })
    }

    /// One sample on the next road point: measured state `r_k` (8,) and derivative `z_k` (8,).
    /// Returns the innovations of the unknown rows (4,) (0 for a wheel row that took no step).
    /// A rejected sample raises VehidError and leaves the identifier unchanged.
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        r_k: &Bound<'py, PyAny>,
        z_k: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (x, z) = sample_vecs(r_k, z_k)?;
        let mut e = vec![0.0; 4];
        self.inner.update_into(&x, &z, None, &mut e).map_err(core_err)?;
        Ok(e.into_pyarray(py))
    }

    /// Runs every sample of `r`, `z` (samples, 8), one per road point, with the GIL released.
    /// All or nothing: a rejected sample raises and leaves the identifier unchanged.
    fn fit(&mut self, py: Python<'_>, r: &Bound<'_, PyAny>, z: &Bound<'_, PyAny>) -> PyResult<()> {
        let ra = array(r, "r")?;
        let za = array(z, "z")?;
        if ra.shape.len() != 2 || ra.shape[1] != 8 || za.shape != ra.shape {
            return Err(VehidError::new_err(format!(
                "`r` and `z` must both have shape (samples, 8), got {} and {}",
                shape_str(&ra.shape),
                shape_str(&za.shape)
            )));
        }
        let inner = &mut self.inner;
        let before = inner.clone();
        let res = py.detach(|| {
            let mut e = [0.0; 4];
            for (i, (x, zk)) in ra.data.chunks_exact(8).zip(za.data.chunks_exact(8)).enumerate() {
                inner
                    .update_into(&SVector::from_column_slice(x), &SVector::from_column_slice(zk), None, &mut e)
                    .map_err(|err| (i, err))?;
            }
            Ok::<(), (usize, vehid_core::Error)>(())
        });
        if let Err((i, err)) = res {
            self.inner = before;
            return Err(VehidError::new_err(format!("sample {i} was rejected ({err}); the identifier is unchanged")));
        }
        Ok(())
    }

    /// The estimated unknown rows of A (rows 1, 3, 5, 7), shape (4, 8).
    #[getter]
    fn theta<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let mut out = vec![0.0; 32];
        self.inner.theta_into(&mut out).map_err(core_err)?;
        to_array2(py, 4, 8, out)
    }

    /// Â: A with the unknown rows replaced by the estimate, shape (8, 8).
    #[getter]
    fn a_hat<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let a = self.inner.a_hat();
        to_array2(py, 8, 8, (0..64).map(|k| a[(k / 8, k % 8)]).collect())
    }

    /// "none", "thesis" or "cancel".
    #[getter]
    fn method(&self) -> &'static str {
        method_name(self.inner.config().method)
    }

    /// Samples (road points) between the axles, d = wheelbase / spacing.
    #[getter]
    fn delay(&self) -> usize {
        self.inner.delay()
    }

    /// Sample spacing, m.
    #[getter]
    fn spacing(&self) -> f64 {
        self.spacing
    }

    /// Wheelbase, m.
    #[getter]
    fn wheelbase(&self) -> f64 {
        self.wheelbase
    }

    /// Variances (front, rear, cancelled) of the wheel-row equations.
    #[getter]
    fn wheel_variances(&self) -> (f64, f64, f64) {
        self.inner.wheel_variances()
    }

    /// Samples accepted.
    #[getter]
    fn samples(&self) -> u64 {
        self.inner.samples()
    }

    /// Samples paired with the sample d road points earlier.
    #[getter]
    fn paired(&self) -> u64 {
        self.inner.paired()
    }

    /// The model.
    #[getter]
    fn model(&self, py: Python<'_>) -> Py<PyLinearModel> {
        self.model.clone_ref(py)
    }

    fn __repr__(&self) -> String {
        format!(
            "TwoAxleIdentifier(method='{}', spacing={:?}, delay={}, samples={})",
            self.method(),
            self.spacing,
            self.inner.delay(),
            self.inner.samples()
        )
    }
}

// ---- AxleSampler ----------------------------------------------------------------------------

/// Distance-triggered sampling for two axles on one road (Ch. VI.D).
///
/// Feed odometry (`feed(s)`, metres from the start, non-decreasing) or motion
/// (`advance(speed, dt)`); each call returns None, or a tuple `(sample, grid, position, pair)`
/// when a sample is to be taken now: its number, its grid point index (road point
/// grid·spacing), the odometry, and `pair` = `(sample, grid, error)` of the earlier sample whose
/// road point the rear axle is now over (|error| ≤ `tolerance` m), or None. A stopped vehicle
/// never triggers; odometry running backwards raises (use `reset(s)`); a jump over grid points
/// samples once and leaves the skipped points out. Default tolerance: 1 % of the spacing.
#[pyclass(name = "AxleSampler", module = "vehid._vehid")]
pub struct PyAxleSampler {
    inner: Box<AxleSampler<f64, SAMPLER_SLOTS>>,
}

type TriggerTuple = (u64, u64, f64, Option<(u64, u64, f64)>);

fn trigger_tuple(t: Option<Trigger<f64>>) -> Option<TriggerTuple> {
    t.map(|t| (t.sample, t.grid, t.position, t.pair.map(|p| (p.sample, p.grid, p.error))))
}

#[pymethods]
impl PyAxleSampler {
    #[new]
    #[pyo3(signature = (wheelbase = 3.0, spacing = 0.3, tolerance = None))]
    fn py_new(wheelbase: f64, spacing: f64, tolerance: Option<f64>) -> PyResult<Self> {
        let tol = tolerance.unwrap_or(0.01 * spacing);
        Ok(Self { inner: Box::new(AxleSampler::new(wheelbase, spacing, tol).map_err(core_err)?) })
    }

    /// Feeds an odometry reading (m).
    fn feed(&mut self, s: f64) -> PyResult<Option<TriggerTuple>> {
        Ok(trigger_tuple(self.inner.feed_distance(s).map_err(core_err)?))
    }

    /// Feeds motion: `speed` (m/s, ≥ 0) for `dt` seconds (≥ 0).
    fn advance(&mut self, speed: f64, dt: f64) -> PyResult<Option<TriggerTuple>> {
        Ok(trigger_tuple(self.inner.advance(speed, dt).map_err(core_err)?))
    }

    /// Time (s) to the next grid point at `speed`; None when stopped.
    fn time_to_next(&self, speed: f64) -> Option<f64> {
        self.inner.time_to_next(speed)
    }

    /// Distance (m) to the next grid point.
    #[getter]
    fn distance_to_next(&self) -> f64 {
        self.inner.distance_to_next()
    }

    /// Starts a new grid at odometry `s`, forgetting earlier samples.
    fn reset(&mut self, s: f64) -> PyResult<()> {
        self.inner.reset(s).map_err(core_err)
    }

    /// Samples between the axles, d.
    #[getter]
    fn delay(&self) -> usize {
        self.inner.delay()
    }

    /// Sample spacing, m.
    #[getter]
    fn spacing(&self) -> f64 {
        self.inner.spacing()
    }

    /// Wheelbase, m.
    #[getter]
    fn wheelbase(&self) -> f64 {
        self.inner.wheelbase()
    }

    /// Pairing tolerance, m.
    #[getter]
    fn tolerance(&self) -> f64 {
        self.inner.tolerance()
    }

    /// Last odometry reading, m.
    #[getter]
    fn position(&self) -> f64 {
        self.inner.position()
    }

    /// Samples triggered so far.
    #[getter]
    fn samples(&self) -> u64 {
        self.inner.samples()
    }

    fn __repr__(&self) -> String {
        format!(
            "AxleSampler(wheelbase={:?}, spacing={:?}, tolerance={:?}, delay={})",
            self.inner.wheelbase(),
            self.inner.spacing(),
            self.inner.tolerance(),
            self.inner.delay()
        )
    }
}
