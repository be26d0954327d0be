//! Two axles on one road: `TwoAxleIdentifier` and `AxleSampler` (Ch. VI.D). Thin wrappers
//! of the core.

use crate::dispatch::ModelData;
use crate::guard::borrow;
use crate::identify::PyIdentifier;
use crate::model::{Kind, PyLinearModel};
use crate::{core_err, option, VehidError};
use pyo3::exceptions::PyMemoryError;
use pyo3::prelude::*;
use vehid_core::identify::{TwoAxleConfig, TwoAxleIdentifierVec, WheelMethod};
use vehid_core::sampler::{axle_delay, AxleSampler, Trigger};

/// Ring capacity of the Python `AxleSampler`.
pub const SAMPLER_SLOTS: usize = 4096;

/// The wheelbase of a model: the half car's `l1 + l2`, or the one given.
pub(crate) fn wheelbase_of(model: &PyLinearModel, wheelbase: Option<f64>) -> PyResult<f64> {
    match (wheelbase, model.kind) {
        (Some(w), _) => Ok(w),
        (None, Kind::Half(car)) => Ok(car.wheelbase()),
        (None, _) => Err(VehidError::new_err(
            "`wheelbase` is needed for a model other than HalfCar (the distance between the axles, m)",
        )),
    }
}

pub(crate) fn half_dims(d: &ModelData, what: &str) -> PyResult<()> {
    if d.n != 8 || d.m != 2 {
        return Err(VehidError::new_err(format!(
            "{what} needs an 8-state model with 2 inputs (front and rear road), like HalfCar; got n={}, m={}",
            d.n, d.m
        )));
    }
    Ok(())
}

// ---- TwoAxleIdentifier ---------------------------------------------------------------------

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
/// `update` and `fit` take one sample per road point, in order.
#[pyclass(name = "TwoAxleIdentifier", module = "vehid._vehid", extends = PyIdentifier)]
pub struct PyTwoAxleIdentifier {
    model: Py<PyLinearModel>,
    spacing: f64,
    wheelbase: f64,
}

impl PyTwoAxleIdentifier {
    /// The core identifier behind the base class.
    fn core<'a>(slf: &'a PyRef<'_, Self>) -> &'a Id {
        let base: &PyIdentifier = slf.as_super();
        // Built by `py_new` with exactly this type; the base never replaces it.
        match base.inner.as_any().downcast_ref::<Id>() {
            Some(id) => id,
            None => unreachable!("TwoAxleIdentifier holds a TwoAxleIdentifierVec"),
        }
    }
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
    ) -> PyResult<PyClassInitializer<Self>> {
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
        let mut cfg = TwoAxleConfig::new(option::<WheelMethod>(method)?, p0, road_sigma, deriv_noise);
        cfg.p0_body = p0_body.unwrap_or(p0);
        cfg.direct_front = direct_front;
        let core = m.data.model::<8, 2>().map_err(core_err)?;
        let inner = Id::new(&core, d, cfg).map_err(|e| match e {
            // The ring of the last d samples is what grows as `spacing` shrinks.
            vehid_core::Error::OutOfMemory { bytes, .. } => PyMemoryError::new_err(format!(
                "`spacing` = {spacing} m puts d = {d} samples between the axles (wheelbase {wheelbase} m), and the \
                 identifier must keep the last d samples ({bytes} bytes, which cannot be allocated): use a larger \
                 `spacing` (the thesis samples every 0.3 m)"
            )),
            e => core_err(e),
        })?;
        let base = PyIdentifier::new(Box::new(inner), m.data.clone());
        Ok(PyClassInitializer::from(base).add_subclass(Self { model: model.unbind(), spacing, wheelbase }))
    }

    /// "none", "thesis" or "cancel".
    #[getter]
    fn method(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        Ok(Self::core(&borrow(slf)?).config().method.as_str())
    }

    /// Samples (road points) between the axles, d = wheelbase / spacing.
    #[getter]
    fn delay(slf: &Bound<'_, Self>) -> PyResult<usize> {
        Ok(Self::core(&borrow(slf)?).delay())
    }

    /// Sample spacing, m.
    #[getter]
    fn spacing(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.spacing)
    }

    /// Wheelbase, m.
    #[getter]
    fn wheelbase(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.wheelbase)
    }

    /// Variances (front, rear, cancelled) of the wheel-row equations.
    #[getter]
    fn wheel_variances(slf: &Bound<'_, Self>) -> PyResult<(f64, f64, f64)> {
        Ok(Self::core(&borrow(slf)?).wheel_variances())
    }

    /// Samples paired with the sample d road points earlier.
    #[getter]
    fn paired(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(Self::core(&borrow(slf)?).paired())
    }

    /// The model.
    #[getter]
    fn model(slf: &Bound<'_, Self>) -> PyResult<Py<PyLinearModel>> {
        Ok(borrow(slf)?.model.clone_ref(slf.py()))
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let slf = borrow(slf)?;
        let id = Self::core(&slf);
        Ok(format!(
            "TwoAxleIdentifier(method={}, spacing={:?}, delay={}, samples={})",
            crate::convert::py_str(id.config().method.as_str()),
            slf.spacing,
            id.delay(),
            id.samples()
        ))
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
        // The default follows `spacing`; for a bad spacing it is 0, so that the core names
        // `spacing`, not the tolerance derived from it.
        let tol = tolerance.unwrap_or(if spacing.is_finite() && spacing > 0.0 { 0.01 * spacing } else { 0.0 });
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
