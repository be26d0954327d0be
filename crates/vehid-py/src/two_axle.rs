//! Two axles on one road: `TwoAxleIdentifier` (the core's `TwoAxleIdentifier` on a model's
//! rows, or `TwoAxleStructured` on a Structure) and `AxleSampler` (Ch. VI.D). Thin wrappers
//! of the core.

use crate::guard::borrow;
use crate::identify::PyIdentifier;
use crate::model::{to_array2, Kind, PyLinearModel};
use crate::structure::PyStructure;
use crate::{core_err, option, VehidError};
use numpy::PyArray2;
use pyo3::exceptions::PyMemoryError;
use pyo3::prelude::*;
use vehid_core::identify::{Refresh, TwoAxleConfig, TwoAxleIdentifierVec, TwoAxleStructuredConfig, WheelMethod};
use vehid_core::sampler::{axle_delay, AxleSampler, Trigger};
use vehid_runtime::ModelData;

/// Ring capacity of the Python `AxleSampler`.
pub const SAMPLER_SLOTS: usize = 4096;

/// The wheelbase of a model: the half car's `l1 + l2`, the full car's `l_f + l_r`, or the
/// one given.
pub(crate) fn wheelbase_of(model: &PyLinearModel, wheelbase: Option<f64>) -> PyResult<f64> {
    match (wheelbase, model.kind) {
        (Some(w), _) => Ok(w),
        (None, Kind::Half(car)) => Ok(car.wheelbase()),
        (None, Kind::Full(car)) => Ok(car.wheelbase()),
        (None, _) => Err(VehidError::new_err(
            "`wheelbase` is needed for a model other than HalfCar or FullCar (the distance between the axles, m)",
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
/// The full car's: 14 states, 4 road inputs (two tracks).
type IdFull = TwoAxleIdentifierVec<f64, 14, 28, 4>;

use vehid_runtime::build::TWO_AXLE_SIZES as STRUCTURED_SIZES;

use vehid_runtime::with_two_axle_structured as with_structured;

/// What the getters report, from either core: method, delay, wheel variances, paired.
struct Info {
    method: &'static str,
    delay: usize,
    variances: (f64, f64, f64),
    paired: u64,
}

/// `p0=`: a number, "exact", or None (the default of the kind).
enum P0 {
    Default,
    Exact,
    Value(f64),
}

fn p0_arg(p0: Option<&Bound<'_, PyAny>>) -> PyResult<P0> {
    let Some(p0) = p0.filter(|p| !p.is_none()) else { return Ok(P0::Default) };
    if let Ok(text) = p0.extract::<String>() {
        return match text.as_str() {
            "exact" => Ok(P0::Exact),
            other => Err(VehidError::new_err(format!("unknown `p0` {other:?}: expected a number > 0 or \"exact\""))),
        };
    }
    p0.extract::<f64>()
        .map(P0::Value)
        .map_err(|_| VehidError::new_err("`p0` must be a number (P(0) on every parameter) or \"exact\""))
}

/// Identifier of the unknown rows of a half car (or a full car) driven along one road (Ch. VI.D).
///
/// Samples must be taken every `spacing` metres (e.g. `Simulator(half, speed=..., spacing=...)`
/// or `AxleSampler`), so that the rear axle is over the road point of the sample
/// d = wheelbase / spacing samples earlier. `method`: "none" (plain Kalman rows, Eq 6.16–6.18;
/// the rear row is biased by the correlated input), "thesis" (Eq 6.12–6.14: the front row's
/// innovation d samples earlier subtracted from the rear row's), "cancel" (the joint regression
/// of z4(k) − (b42/b21) z2(k−d) on [x(k), −(b42/b21) x(k−d)], in which the road input cancels;
/// variance σ_v²(1 + (b42/b21)²), plus the direct front equation weighted by its own variance).
/// The body rows are plain Kalman rows. A `FullCar` has two tracks: each rear wheel rolls on its
/// front wheel's track (left, right) a wheelbase later, and each track's pair of wheel rows
/// (rows 1 and 5, 3 and 7) is identified as above on its own (`wheel_variances`: the left
/// track's; its seven rows of 14 exceed what the outlier screen below holds in its structure:
/// the screen judges magnitudes and holds the start, and a sample whose recursive residual on
/// a filter exceeds κ times that filter's residual scale leaves the filter unchanged). `road_sigma` (m) and `deriv_noise` give every
/// equation's variance; `p0` is P(0) on every row (default 1000; `p0_body` overrides it on the
/// body rows), or "exact" (methods "none" and "cancel"): least squares on every sample once each
/// filter's parameters are determined, no prior (`theta` raises until then). `update` and `fit` take one sample per road point, in order.
///
/// On a Structure (`model=half.structure(known={"m1": 1.0, "m2": 1.0, "l1": 2.0, "l2": 1.0})`,
/// with `car=half`: the 8-state, 2-input model whose B gives the wheel rows and ρ = b42/b21,
/// and the wheelbase): road cancellation on the structure's parameters (method "cancel" only):
/// the rear wheel equation minus ρ times the front one d samples earlier, the other equations
/// as they are, one filter per parameter group. `p0`: "exact" (the default here: least squares
/// on every sample once identified) or a number; `compensate` (default True) removes the bias
/// that the derivative noise in `der(·)` regressors (the wheel equations read the body's
/// accelerations) leaves, from `deriv_noise`. `params` are the structure's parameters, `theta`
/// (k, n) the unknown rows of A they give (in the order of `unknown_rows`, the structure's
/// equations), `a_hat` the car's A with those rows; `fit`'s history holds `params`. No
/// `stats()` (no residual statistics are kept).
/// Outliers: `gate` κ (default 6; 0: off, the identifier alone)
/// screens a sample — accepted, counted in `gated`, otherwise left out — whose prediction error on
/// an equation exceeds κ times its standard deviation estimated from the samples accepted so far
/// (active after N + 50 samples), or any of whose values (a state, a derivative, an input)
/// exceeds κ² times its root mean square so far; the first 16 samples are kept and judged
/// together against their median, the identifier restarted without an outlier found there, so
/// that an outlier at sample 0 does not spoil the start (`vehid_core::identify::Screened`).
/// A screened sample's road point passes: the rear axle stays paired with the front axle's
/// sample one wheelbase earlier.
#[pyclass(name = "TwoAxleIdentifier", module = "vehid._vehid", extends = PyIdentifier)]
pub struct PyTwoAxleIdentifier {
    model: Py<PyLinearModel>,
    spacing: f64,
    wheelbase: f64,
    gate: f64,
}

impl PyTwoAxleIdentifier {
    /// The settings the getters report, from whichever core the base holds.
    fn info(slf: &PyRef<'_, Self>) -> PyResult<Info> {
        let base: &PyIdentifier = slf.as_super();
        let any = vehid_runtime::build::unscreened(base.inner.as_ref()).as_any();
        macro_rules! rows_info {
            ($id:expr) => {
                Info {
                    method: $id.config().method.as_str(),
                    delay: $id.delay(),
                    variances: $id.wheel_variances(),
                    paired: $id.paired(),
                }
            };
        }
        if let Some(id) = any.downcast_ref::<Id>() {
            return Ok(rows_info!(id));
        }
        if let Some(id) = any.downcast_ref::<IdFull>() {
            return Ok(rows_info!(id));
        }
        with_structured!(base.inner, |id| Info {
            method: WheelMethod::Cancel.as_str(),
            delay: id.delay(),
            variances: id.wheel_variances(),
            paired: id.paired(),
        })
        .ok_or_else(|| VehidError::new_err("internal: TwoAxleIdentifier holds no two-axle core"))
    }

    /// The unknown rows of A from a Structure's parameters (equations × n, row-major); `None`
    /// for the rows identifier.
    fn structured_rows(base: &PyIdentifier, py: Python<'_>) -> PyResult<Option<Vec<f64>>> {
        let inner = &base.inner;
        let d = inner.dims();
        let mut out = vec![0.0; d.equations * d.states];
        match py.detach(|| with_structured!(inner, |id| id.a_rows_into(&mut out))) {
            None => Ok(None),
            Some(r) => r.map(|()| Some(out)).map_err(crate::identify::raise),
        }
    }
}

#[pymethods]
impl PyTwoAxleIdentifier {
    #[new]
    #[pyo3(signature = (model, spacing = 0.3, method = "cancel", p0 = None, road_sigma = None, deriv_noise = None,
                        *, p0_body = None, wheelbase = None, direct_front = true, car = None, compensate = true,
                        gate = None),
           text_signature = "(model, spacing=0.3, method='cancel', p0=None, road_sigma=0.1, deriv_noise=0.005, *, \
                             p0_body=None, wheelbase=None, direct_front=True, car=None, compensate=True, gate=None)")]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        model: &Bound<'_, PyAny>,
        spacing: f64,
        method: &str,
        p0: Option<&Bound<'_, PyAny>>,
        road_sigma: Option<f64>,
        deriv_noise: Option<f64>,
        p0_body: Option<f64>,
        wheelbase: Option<f64>,
        direct_front: bool,
        car: Option<Bound<'_, PyLinearModel>>,
        compensate: bool,
        #[pyo3(from_py_with = crate::args::gate)] gate: Option<f64>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let gate = gate.unwrap_or(vehid_runtime::defaults::GATE);
        let road_sigma = road_sigma.unwrap_or(vehid_runtime::defaults::ROAD_SIGMA);
        let deriv_noise = deriv_noise.unwrap_or(vehid_runtime::defaults::DERIV_NOISE);
        let p0 = p0_arg(p0)?;
        let structure = model.cast::<PyStructure>().ok();
        let car =
            match (structure, model.cast::<PyLinearModel>(), car) {
                (Some(_), _, Some(car)) => car,
                (Some(_), _, None) => {
                    return Err(VehidError::new_err(
                        "`car` is needed with a Structure: the half car (an 8-state model with 2 road inputs) whose B \
                     gives the wheel rows and rho = b42/b21, e.g. TwoAxleIdentifier(half.structure(known=...), \
                     car=half)",
                    ))
                }
                (None, Ok(m), None) => m.clone(),
                (None, Ok(_), Some(_)) => {
                    return Err(VehidError::new_err(
                        "`car` is for a Structure only: with a model, the model itself gives B and the wheelbase",
                    ))
                }
                (None, Err(_), _) => return Err(VehidError::new_err(
                    "`model` must be a HalfCar (an 8-state LinearModel with 2 road inputs) or a vehid.Structure (with \
                     car=)",
                )),
            };
        let m = car.get();
        let full = structure.is_none() && matches!(m.kind, Kind::Full(_));
        if !full {
            half_dims(&m.data, if structure.is_some() { "`car`" } else { "TwoAxleIdentifier (or a FullCar)" })?;
        }
        let wheelbase = wheelbase_of(m, wheelbase)?;
        let (d, residual) = axle_delay(wheelbase, spacing).map_err(core_err)?;
        if residual > 1e-9 * wheelbase {
            return Err(VehidError::new_err(format!(
                "`spacing` = {spacing} does not divide the wheelbase {wheelbase} m: the rear axle must be over an \
                 earlier sample point (use e.g. {:.6} m)",
                wheelbase / d as f64
            )));
        }
        let method = option::<WheelMethod>(method)?;
        let memory = |e: vehid_core::Error| match e {
            // The ring of the last d samples is what grows as `spacing` shrinks.
            vehid_core::Error::OutOfMemory { bytes, .. } => PyMemoryError::new_err(format!(
                "`spacing` = {spacing} m puts d = {d} samples between the axles (wheelbase {wheelbase} m), and the \
                 identifier must keep the last d samples ({bytes} bytes, which cannot be allocated): use a larger \
                 `spacing` (the thesis samples every 0.3 m)"
            )),
            e => core_err(e),
        };
        let base = if let Some(st) = structure {
            if method != WheelMethod::Cancel {
                return Err(VehidError::new_err(format!(
                    "`method` {:?} is for the rows identifier: on a Structure the road is cancelled (method=\"cancel\")",
                    method.as_str()
                )));
            }
            if p0_body.is_some() {
                return Err(VehidError::new_err(
                    "`p0_body` is for the rows identifier: on a Structure `p0` applies to every parameter",
                ));
            }
            let s = st.get().core;
            let core = m.data.model::<8, 2>().map_err(core_err)?;
            let mut cfg = TwoAxleStructuredConfig::new(road_sigma, deriv_noise);
            cfg.p0 = match p0 {
                P0::Default | P0::Exact => None,
                P0::Value(v) => Some(v),
            };
            cfg.direct_front = direct_front;
            cfg.compensate = compensate;
            let built = vehid_runtime::build::two_axle_structured(s, &core, d, cfg);
            let inner = match built {
                Err(vehid_core::Error::Capacity { arg: "P", needed, .. }) => {
                    return Err(VehidError::new_err(format!(
                        "`model`: a parameter group of this Structure (the two wheel equations' groups merged) holds \
                         {needed} parameters, more than the {} TwoAxleIdentifier is built for",
                        STRUCTURED_SIZES[STRUCTURED_SIZES.len() - 1]
                    )))
                }
                other => other,
            }
            .map_err(memory)?;
            // The estimate is bias-compensated on read: re-read as the samples grow.
            let inner = vehid_runtime::build::screened(inner, &s, gate, Refresh::Geometric).map_err(core_err)?;
            PyIdentifier::on_structure(inner, st)
        } else {
            let (p0, exact) = match p0 {
                P0::Default => (1000.0, false),
                P0::Value(v) => (v, false),
                P0::Exact if p0_body.is_some() => {
                    return Err(VehidError::new_err(
                        "`p0_body` is for a prior: with p0=\"exact\" every row starts exactly (no prior)",
                    ))
                }
                P0::Exact if method == WheelMethod::Thesis => return Err(VehidError::new_err(
                    "`p0` = \"exact\" is for methods \"none\" and \"cancel\": the thesis' method subtracts the front \
                         row's innovation, which a row in its exact start does not have (give a number, e.g. 1000)",
                )),
                P0::Exact => (1000.0, true),
            };
            if !compensate {
                return Err(VehidError::new_err(
                    "`compensate` is for a Structure: the rows identifier's regressors read no measured derivative",
                ));
            }
            let mut cfg = TwoAxleConfig::new(method, p0, road_sigma, deriv_noise);
            cfg.p0_body = p0_body.unwrap_or(p0);
            cfg.direct_front = direct_front;
            cfg.exact = exact;
            // The outer screen's structure holds the model's full rows (the half car's); the full
            // car's seven rows of 14 (98 terms) exceed it: each filter gates its own residuals
            // behind the screen's magnitude test.
            let screen = vehid_core::structure::Structure::full_rows(m.data.n, &m.data.rows).ok();
            if screen.is_none() {
                cfg.gate = gate;
            }
            let inner: vehid_runtime::build::Boxed = if full {
                Box::new(IdFull::new(&m.data.model::<14, 4>().map_err(core_err)?, d, cfg).map_err(memory)?)
            } else {
                Box::new(Id::new(&m.data.model::<8, 2>().map_err(core_err)?, d, cfg).map_err(memory)?)
            };
            let inner = match screen {
                Some(rows) => vehid_runtime::build::screened(inner, &rows, gate, Refresh::Every).map_err(core_err)?,
                None => vehid_runtime::build::screened_magnitudes(inner, gate).map_err(core_err)?,
            };
            PyIdentifier::new(inner, m.data.clone())
        };
        Ok(PyClassInitializer::from(base).add_subclass(Self { model: car.unbind(), spacing, wheelbase, gate }))
    }

    /// "none", "thesis" or "cancel".
    #[getter]
    fn method(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        Ok(Self::info(&borrow(slf)?)?.method)
    }

    /// Samples (road points) between the axles, d = wheelbase / spacing.
    #[getter]
    fn delay(slf: &Bound<'_, Self>) -> PyResult<usize> {
        Ok(Self::info(&borrow(slf)?)?.delay)
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
        Ok(Self::info(&borrow(slf)?)?.variances)
    }

    /// Samples paired with the sample d road points earlier.
    #[getter]
    fn paired(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(Self::info(&borrow(slf)?)?.paired)
    }

    /// The model (on a Structure: the `car` given).
    #[getter]
    fn model(slf: &Bound<'_, Self>) -> PyResult<Py<PyLinearModel>> {
        Ok(borrow(slf)?.model.clone_ref(slf.py()))
    }

    /// Whether the derivative noise's bias is removed (a Structure's `compensate`; False for
    /// the rows identifier).
    #[getter]
    fn compensate(slf: &Bound<'_, Self>) -> PyResult<bool> {
        let this = borrow(slf)?;
        let base: &PyIdentifier = this.as_super();
        Ok(with_structured!(base.inner, |id| id.config().compensate).unwrap_or(false))
    }

    /// The estimated unknown rows of A, shape (k, n), in the order of `unknown_rows` (on a
    /// Structure: the rows its parameters give).
    #[getter]
    fn theta<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let this = borrow(slf)?;
        let base: &PyIdentifier = this.as_super();
        match Self::structured_rows(base, py)? {
            Some(rows) => Ok(to_array2(py, rows.len() / base.model.n, base.model.n, rows)?.into_any()),
            None => {
                drop(this);
                PyIdentifier::theta(slf.as_super(), py)
            }
        }
    }

    /// Â: the model's A with the unknown rows replaced by the estimate, shape (n, n).
    #[getter]
    fn a_hat<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let this = borrow(slf)?;
        let base: &PyIdentifier = this.as_super();
        match Self::structured_rows(base, py)? {
            Some(rows) => {
                let n = base.model.n;
                let mut a = this.model.bind(py).get().data.a.clone();
                for (i, &r) in base.inner.rows().iter().enumerate() {
                    a[r * n..(r + 1) * n].copy_from_slice(&rows[i * n..(i + 1) * n]);
                }
                to_array2(py, n, n, a)
            }
            None => {
                drop(this);
                PyIdentifier::a_hat(slf.as_super(), py)
            }
        }
    }

    /// What builds a fresh object of this class and settings (pickling and copying, `persist.rs`).
    fn __getnewargs_ex__<'py>(slf: &Bound<'py, Self>) -> PyResult<crate::persist::NewArgs<'py>> {
        let py = slf.py();
        let kw = pyo3::types::PyDict::new(py);
        for key in ["spacing", "method", "wheelbase"] {
            kw.set_item(key, slf.getattr(key)?)?;
        }
        let this = borrow(slf)?;
        kw.set_item("gate", this.gate)?;
        let model = match &this.as_super().structure {
            // On a Structure: the car gives B; `compensate` decides what the structure may hold.
            Some(st) => {
                kw.set_item("car", this.model.clone_ref(py))?;
                kw.set_item("compensate", slf.getattr("compensate")?)?;
                st.bind(py).clone().into_any()
            }
            None => this.model.bind(py).clone().into_any(),
        };
        Ok((pyo3::types::PyTuple::new(py, [model])?, kw))
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let slf = borrow(slf)?;
        let info = Self::info(&slf)?;
        let base: &PyIdentifier = slf.as_super();
        let on = if base.structure.is_some() { "structure, " } else { "" };
        Ok(format!(
            "TwoAxleIdentifier({on}method={}, spacing={:?}, delay={}, samples={})",
            crate::convert::py_str(info.method),
            slf.spacing,
            info.delay,
            base.inner.samples()
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
