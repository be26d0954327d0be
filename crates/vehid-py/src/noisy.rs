//! Identifiers for noisy state sensors: `vehid.IVIdentifier` (recursive instrumental
//! variables, the core's `InstrumentalVariables`) and `vehid.BiasCompensated` (bias-compensated
//! least squares, the core's `BiasCompensated`). Both subclass `vehid.Identifier`; on a
//! linear model they identify its full unknown rows (`Structure::full_rows`), so `theta` and
//! `a_hat` read as for the Kalman identifier. This file only converts and dispatches.

use crate::convert::{array, finite, shape_str};
use crate::guard::borrow;
use crate::identify::PyIdentifier;
use crate::model::PyLinearModel;
use crate::structure::{PyStructure, StructuredP0};
use crate::{core_err, VehidError};
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use vehid_core::identify::{DynIdentifier, Refresh, RING_VALUES};
use vehid_core::structure::Structure;

use vehid_runtime::build::PREDICTOR;
use vehid_runtime::build::{self, ModelInstrumentSettings as ModelArgs};

/// The model's structure and, for a linear model, its data (for `theta`/`a_hat`).
enum Target<'py> {
    Model(Bound<'py, PyLinearModel>),
    Structure(Bound<'py, PyStructure>),
}

impl<'py> Target<'py> {
    fn of(model: &Bound<'py, PyAny>) -> PyResult<Self> {
        if let Ok(s) = model.cast::<PyStructure>() {
            return Ok(Target::Structure(s.clone()));
        }
        model.cast::<PyLinearModel>().map(|m| Target::Model(m.clone())).map_err(|_| {
            VehidError::new_err("`model` must be a LinearModel (QuarterCar, HalfCar, ...) or a vehid.Structure")
        })
    }

    fn structure(&self) -> PyResult<Structure<f64>> {
        match self {
            Target::Structure(s) => Ok(s.get().core),
            Target::Model(m) => {
                let d = &m.get().data;
                Structure::full_rows(d.n, &d.rows).map_err(core_err)
            }
        }
    }

    fn wrap(&self, inner: Box<dyn DynIdentifier<f64>>) -> PyIdentifier {
        match self {
            Target::Structure(s) => PyIdentifier::on_structure(inner, s),
            Target::Model(m) => PyIdentifier::new(inner, m.get().data.clone()),
        }
    }
}

/// `r`: a scalar or one per identified equation (default 1).
fn r_arg(r: Option<&Bound<'_, PyAny>>, ne: usize) -> PyResult<Vec<f64>> {
    let Some(r) = r else { return Ok(vec![vehid_runtime::defaults::NOISY_R]) };
    let a = array(r, "r")?;
    finite("r", &a.data)?;
    if !(a.shape.is_empty() || a.shape == [ne]) {
        return Err(VehidError::new_err(format!(
            "`r` must be a scalar or one variance per identified equation, shape ({ne},), got {}",
            shape_str(&a.shape)
        )));
    }
    Ok(a.data)
}

/// `delay` (≥ 1) and `lags` (default `vehid_runtime::defaults::iv_lags`) of the instruments on `s`, checked
/// against the predictor's and the ring's capacities.
fn instrument_args(s: &Structure<f64>, delay: i128, lags: Option<i128>) -> PyResult<(usize, usize)> {
    let delay = usize::try_from(delay)
        .ok()
        .filter(|&d| d >= 1)
        .ok_or_else(|| VehidError::new_err(format!("`delay` must be an integer >= 1 (samples), got {delay}")))?;
    let width = 2 * s.states() + s.inputs();
    let lags = match lags {
        None => vehid_runtime::defaults::iv_lags(width),
        Some(l) => {
            usize::try_from(l).map_err(|_| VehidError::new_err(format!("`lags` must be an integer >= 0, got {l}")))?
        }
    };
    if lags > 0 && lags.saturating_mul(width).saturating_add(1) > PREDICTOR {
        return Err(VehidError::new_err(format!(
            "`lags` = {lags} is too many for this model: lags × (2·{} states + {} inputs) + 1 must be at most \
             {PREDICTOR}, so at most {} (or 0 for the plain delayed regressors)",
            s.states(),
            s.inputs(),
            (PREDICTOR - 1) / width
        )));
    }
    let slots = delay.saturating_add(lags.saturating_sub(1));
    if slots.saturating_mul(width) > RING_VALUES {
        return Err(VehidError::new_err(format!(
            "`delay` = {delay} with `lags` = {lags} needs {slots} past samples of {width} values, more than the \
             {RING_VALUES} values the identifier keeps: at most delay + lags - 1 = {} here",
            RING_VALUES / width
        )));
    }
    Ok((delay, lags))
}

/// Recursive instrumental variables: consistent when the measured state is noisy (white
/// sensor noise), where the Kalman identifier (least squares) is biased.
///
/// `model`: a LinearModel (its full unknown rows: `theta` (k, n)) or a Structure.
/// Instruments: each equation's regressors computed `delay` samples earlier (`lags=0`), or
/// (the default) refined — the regressors of the current sample as a recursive linear
/// predictor forecasts them from the `lags` samples `delay`, `delay`+1, … back (an
/// auxiliary model; two-stage least squares for regressors linear in the state). The
/// default `lags` is 6 (fewer when `lags × (2n + m) + 1` would exceed 64). Valid while the
/// sensor noise is white from sample to sample; with coloured noise choose `delay` longer
/// than its correlation time. `p0`: "exact" (default: batch IV on the first samples, then
/// recursive), a scalar, one per equation/row, or the (n_params, n_params) matrix, with prior
/// mean `theta0`; `r`: one variance per equation (weighs equations that share parameters).
/// `instruments="model"` (a Structure with a measured input): the instruments are the
/// noise-free states of an auxiliary model — the structure with the current estimate,
/// integrated by `substeps` RK4 steps per sample interval `dt` (seconds, required) from the
/// measured inputs (held over each interval) — as in Young and Garnier's SRIVC; every `refresh`
/// samples the estimate becomes the auxiliary model if its linear part is stable (else the
/// previous model stays), and until the first one the delayed regressors serve (`lags` must
/// be 0 or None). A sample whose instruments make the step singular raises VehidError, the identifier
/// unchanged. `stats()` gives the IV sandwich covariance. Pickles (every protocol), copies
/// and deep-copies: a restored one continues bit for bit (the ring of past samples and the
/// predictor included).
/// Outliers: `gate` κ (default 6; 0: off, the identifier alone)
/// screens a sample — accepted, counted in `gated`, otherwise left out — whose prediction error on
/// an equation exceeds κ times its standard deviation estimated from the samples accepted so far
/// (active after N + 50 samples), or any of whose values (a state, a derivative, an input)
/// exceeds κ² times its root mean square so far; the first 16 samples are kept and judged
/// together against their median, the identifier restarted without an outlier found there, so
/// that an outlier at sample 0 does not spoil the start (`vehid_core::identify::Screened`).
#[pyclass(name = "IVIdentifier", module = "vehid._vehid", extends = PyIdentifier)]
pub struct PyIVIdentifier {
    delay: usize,
    lags: usize,
    model: Option<ModelArgs>,
    road: Option<crate::road::Road>,
    gate: f64,
}

#[pymethods]
impl PyIVIdentifier {
    #[new]
    #[pyo3(signature = (model, delay = 1, lags = None, p0 = None, r = None, *, theta0 = None,
                        instruments = "delayed", dt = None, refresh = 100, substeps = 1, road = "white",
                        road_cutoff = None, spacing = None, min_spacing = None, lift_off = None, gate = None))]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        model: &Bound<'_, PyAny>,
        delay: i128,
        lags: Option<i128>,
        p0: Option<&Bound<'_, PyAny>>,
        r: Option<&Bound<'_, PyAny>>,
        theta0: Option<&Bound<'_, PyAny>>,
        instruments: &str,
        dt: Option<f64>,
        refresh: i128,
        substeps: i128,
        road: &str,
        road_cutoff: Option<f64>,
        spacing: Option<&Bound<'_, PyAny>>,
        min_spacing: Option<f64>,
        lift_off: Option<(f64, f64)>,
        #[pyo3(from_py_with = crate::args::gate)] gate: Option<f64>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let gate = gate.unwrap_or(vehid_runtime::defaults::GATE);
        let target = Target::of(model)?;
        let s = target.structure()?;
        let road = crate::road::road_args(road, road_cutoff, spacing, min_spacing, lift_off)?;
        if road.is_some() && instruments == "model" {
            return Err(VehidError::new_err(
                "a coloured `road` takes instruments=\"delayed\" (the auxiliary model would be simulated from \
                 differenced inputs)",
            ));
        }
        let (np, ne) = (s.params(), s.equations());
        let model_args = match instruments {
            "delayed" => None,
            "model" => {
                if lags.is_some_and(|l| l != 0) {
                    return Err(VehidError::new_err(
                        "`lags` must be 0 or None with instruments='model' (the auxiliary model replaces the \
                         predictor)",
                    ));
                }
                let dt = dt.ok_or_else(|| {
                    VehidError::new_err("`dt` (the sample interval, seconds) is required with instruments='model'")
                })?;
                let refresh = usize::try_from(refresh).map_err(|_| {
                    VehidError::new_err(format!("`refresh` must be an integer >= 1 (samples), got {refresh}"))
                })?;
                let substeps = u32::try_from(substeps)
                    .map_err(|_| VehidError::new_err(format!("`substeps` must be an integer >= 1, got {substeps}")))?;
                Some(ModelArgs { dt, substeps, refresh })
            }
            other => {
                return Err(VehidError::new_err(format!(
                    "unknown `instruments` {other:?}: expected \"delayed\" (the regressors `delay` samples back, or \
                     with lags the predictor's) or \"model\" (an auxiliary model simulated from the measured input)"
                )))
            }
        };
        // On a coloured road the instruments are the delayed regressors unless `lags` says
        // otherwise: on a road that is smooth at the sample scale the predictor finds the part
        // of the road its past predicts, which is the error (road.rs, "Smooth roads").
        let lags = if model_args.is_some() || (road.is_some() && lags.is_none()) { Some(0) } else { lags };
        let (delay, lags) = instrument_args(&s, delay, lags)?;
        let is_model = matches!(target, Target::Model(_));
        let p0 = StructuredP0::read(p0, np, ne, if is_model { "unknown row" } else { "identified equation" })?;
        let theta0 = match theta0 {
            None => None,
            Some(t) => {
                let a = array(t, "theta0")?;
                finite("theta0", &a.data)?;
                if a.data.len() != np || a.shape.len() > 2 {
                    return Err(VehidError::new_err(format!(
                        "`theta0` must hold the {np} parameters (a linear model: its unknown rows, (k, n)), got shape {}",
                        shape_str(&a.shape)
                    )));
                }
                Some(a.data)
            }
        };
        let r = r_arg(r, ne)?;
        let p0 = p0.prior();
        let th = theta0.as_deref();
        let ma = model_args;
        let inner = build::iv(s, delay, lags, p0, th, &r, ma).map_err(core_err)?;
        // The screen judges the samples the IV step takes (on a coloured road: the differenced ones).
        // Magnitude test and held start only: a residual test would select samples by the
        // equation error the instruments must be uncorrelated with (`Refresh::Never`).
        let inner = build::screened(inner, &s, gate, Refresh::Never).map_err(core_err)?;
        let inner = match road {
            Some(road) => crate::road::wrap(inner, &s, road)?,
            None => inner,
        };
        Ok(PyClassInitializer::from(target.wrap(inner)).add_subclass(Self {
            delay,
            lags,
            model: model_args,
            road,
            gate,
        }))
    }

    /// The road model: "white" (the thesis' road noise: samples identified as they are),
    /// "random-walk" or "iso8608" (the samples quasi-differenced by the road's shaping filter
    /// in distance first; `vehid_core::identify::Differenced`).
    #[getter]
    fn road(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        let this = crate::guard::borrow(slf)?;
        Ok(this.road.map_or("white", |r| r.name()))
    }

    /// The ISO 8608 shaping filter's cutoff, cycles/m (None unless road="iso8608").
    #[getter]
    fn road_cutoff(slf: &Bound<'_, Self>) -> PyResult<Option<f64>> {
        let this = crate::guard::borrow(slf)?;
        Ok(this.road.and_then(|r| r.cutoff()))
    }

    /// The lift-off check's `(M, m)`, kg (None: no check).
    #[getter]
    fn lift_off(slf: &Bound<'_, Self>) -> PyResult<Option<(f64, f64)>> {
        let this = crate::guard::borrow(slf)?;
        Ok(this.road.and_then(|r| r.lift_off))
    }

    /// Samples counted off the ground, or about to leave it (0 without the check): a run with
    /// any has biased constants (the linear model does not hold in flight).
    #[getter]
    fn lifted(slf: &Bound<'_, Self>) -> PyResult<u64> {
        let base = crate::guard::borrow(slf.as_super())?;
        Ok(crate::road::lifted(base.inner.as_ref()).unwrap_or(0))
    }

    /// The least distance between two differenced samples, m (None on a white road).
    #[getter]
    fn min_spacing(slf: &Bound<'_, Self>) -> PyResult<Option<f64>> {
        let this = crate::guard::borrow(slf)?;
        Ok(this.road.map(|r| r.min_spacing))
    }

    /// Metres travelled per sample, or "odometer" (the last column of `u`); None on a white road.
    #[getter]
    fn spacing<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let this = crate::guard::borrow(slf)?;
        this.road.map(|r| r.spacing(py)).transpose()
    }

    /// "delayed" (the regressors `delay` samples back, or the predictor's with `lags`) or
    /// "model" (the auxiliary model's noise-free states).
    #[getter]
    fn instruments(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        let this = crate::guard::borrow(slf)?;
        Ok({
            if this.model.is_some() {
                "model"
            } else {
                "delayed"
            }
        })
    }

    /// The auxiliary model's sample interval, seconds (None: `instruments="delayed"`).
    #[getter]
    fn dt(slf: &Bound<'_, Self>) -> PyResult<Option<f64>> {
        let this = crate::guard::borrow(slf)?;
        Ok(this.model.map(|m| m.dt))
    }

    /// Samples between refreshes of the auxiliary model (100 when unused).
    #[getter]
    fn refresh(slf: &Bound<'_, Self>) -> PyResult<usize> {
        let this = crate::guard::borrow(slf)?;
        Ok(this.model.map_or(100, |m| m.refresh))
    }

    /// RK4 steps of the auxiliary model per sample (1 when unused).
    #[getter]
    fn substeps(slf: &Bound<'_, Self>) -> PyResult<u32> {
        let this = crate::guard::borrow(slf)?;
        Ok(this.model.map_or(1, |m| m.substeps))
    }

    /// The instruments' delay, samples.
    #[getter]
    fn delay(slf: &Bound<'_, Self>) -> PyResult<usize> {
        let this = crate::guard::borrow(slf)?;
        Ok(this.delay)
    }

    /// Past samples the refined instruments' predictor reads (0: the delayed regressors).
    #[getter]
    fn lags(slf: &Bound<'_, Self>) -> PyResult<usize> {
        let this = crate::guard::borrow(slf)?;
        Ok(this.lags)
    }

    /// A copy with its own core.
    fn __copy__(slf: &Bound<'_, Self>) -> PyResult<Py<Self>> {
        let py = slf.py();
        let (delay, lags, model, road, gate) = {
            let b = crate::guard::borrow(slf)?;
            (b.delay, b.lags, b.model, b.road, b.gate)
        };
        let base = copy_base(slf.as_super())?;
        Py::new(py, PyClassInitializer::from(base).add_subclass(Self { delay, lags, model, road, gate }))
    }

    /// The same as `__copy__`: the core shares nothing.
    fn __deepcopy__(slf: &Bound<'_, Self>, _memo: &Bound<'_, PyAny>) -> PyResult<Py<Self>> {
        Self::__copy__(slf)
    }

    /// What builds a fresh object of this class and settings (pickling and copying, `persist.rs`).
    fn __getnewargs_ex__<'py>(slf: &Bound<'py, Self>) -> PyResult<crate::persist::NewArgs<'py>> {
        let py = slf.py();
        let kw = pyo3::types::PyDict::new(py);
        for key in ["delay", "lags", "road", "road_cutoff", "spacing", "min_spacing", "lift_off"] {
            kw.set_item(key, slf.getattr(key)?)?;
        }
        if slf.getattr("instruments")?.extract::<String>()? == "model" {
            // Any valid auxiliary model's settings: the saved core (and its settings) replace it.
            kw.set_item("instruments", "model")?;
            for key in ["dt", "refresh", "substeps"] {
                kw.set_item(key, slf.getattr(key)?)?;
            }
        }
        kw.set_item("gate", crate::guard::borrow(slf)?.gate)?;
        crate::persist::new_args(py, crate::guard::borrow(slf)?.as_super(), kw)
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let slf = crate::guard::borrow(slf)?;
        let base = slf.as_super();
        Ok(format!(
            "IVIdentifier(delay={}, lags={}, unknown_rows={}, samples={}, instruments={})",
            slf.delay,
            slf.lags,
            crate::convert::py_tuple(base.inner.rows()),
            base.inner.samples(),
            crate::convert::py_str(if slf.model.is_some() { "model" } else { "delayed" })
        ))
    }
}

/// A fresh base object with a copy of `base`'s core and model.
fn copy_base(base: &Bound<'_, PyIdentifier>) -> PyResult<PyIdentifier> {
    let b = crate::guard::borrow(base)?;
    let inner = b.inner.clone_box();
    Ok(match &b.structure {
        Some(s) => PyIdentifier::on_structure(inner, s.bind(base.py())),
        None => PyIdentifier::new(inner, b.model.clone()),
    })
}

/// A noise covariance argument: a scalar (every component), one per state (n,), or (n, n).
fn noise_arg(v: Option<&Bound<'_, PyAny>>, arg: &str, n: usize) -> PyResult<Vec<f64>> {
    let Some(v) = v else { return Ok(vec![]) };
    let a = array(v, arg)?;
    finite(arg, &a.data)?;
    match a.shape[..] {
        [] => Ok(a.data),
        [len] if len == n => Ok(a.data),
        [r, c] if r == n && c == n => Ok(a.data),
        _ => Err(VehidError::new_err(format!(
            "`{arg}` must be a variance (scalar), one per state ({n},) or a ({n}, {n}) covariance, got {}",
            shape_str(&a.shape)
        ))),
    }
}

/// Bias-compensated least squares: `(XᵀX − N Σ_w)⁻¹ Xᵀz` for the full rows of a linear model,
/// and its generalization to a Structure whose terms are linear in the noisy variables
/// (states, `der(·)` with `deriv_noise_var`; inputs are taken as exact; sign/pos/neg of a noisy
/// variable is refused).
///
/// `state_noise_var`: Σ_w, the covariance of the state sensors' noise (state units²): a
/// scalar, one per state, or (n, n). Given, it must be right: too small leaves part of the
/// bias, too large makes the corrected matrix indefinite (VehidError when the estimate is
/// read). Or `"estimate"`: Σ_w diagonal (independent sensors), estimated from the same samples
/// (Zheng's bias-eliminating idea: the least-squares normal equations' residual at a
/// recursive instrumental-variable estimate run alongside, with instruments `delay` and
/// `lags` as IVIdentifier's, is linear in the variances; a weighted non-negative least-squares
/// fit gives them, `state_noise_var_estimate` reads them). Valid for white sensor noise; the
/// states no parameterized term reads are not estimated (NaN), and states that always enter
/// together are estimated only as that combination. `deriv_noise_var`: Σ_v of the derivative
/// sensors, needed only for structures whose regressors read `der(·)` (default 0). `r`: one
/// variance per equation (weighs equations that share parameters). The estimate is solved
/// when read (`theta`, `params`), from sums kept per sample (nothing stored); `update` returns
/// NaN innovations, as BatchLeastSquares. `stats()` is not available (use IVIdentifier for
/// standard errors). Pickles (every protocol), copies and deep-copies: a restored one
/// continues bit for bit.
/// Outliers: `gate` κ (default 6; 0: off, the identifier alone)
/// screens a sample — accepted, counted in `gated`, otherwise left out — whose prediction error on
/// an equation exceeds κ times its standard deviation estimated from the samples accepted so far
/// (active after N + 50 samples), or any of whose values (a state, a derivative, an input)
/// exceeds κ² times its root mean square so far; the first 16 samples are kept and judged
/// together against their median, the identifier restarted without an outlier found there, so
/// that an outlier at sample 0 does not spoil the start (`vehid_core::identify::Screened`).
#[pyclass(name = "BiasCompensated", module = "vehid._vehid", extends = PyIdentifier)]
pub struct PyBiasCompensated {
    gate: f64,
}

/// The instruments `(delay, lags)` of a noise-estimating core, after writing its variances
/// into `var` when given (`None`: the core is the plain bias-compensated one).
fn estimating(inner: &dyn DynIdentifier<f64>, var: Option<&mut [f64]>) -> Option<vehid_core::Result<(usize, usize)>> {
    vehid_runtime::build::noise_estimating_instruments(inner, var)
}

#[pymethods]
impl PyBiasCompensated {
    #[new]
    #[pyo3(signature = (model, state_noise_var, deriv_noise_var = None, r = None, *, delay = None, lags = None, gate = None))]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        model: &Bound<'_, PyAny>,
        state_noise_var: &Bound<'_, PyAny>,
        deriv_noise_var: Option<&Bound<'_, PyAny>>,
        r: Option<&Bound<'_, PyAny>>,
        delay: Option<i128>,
        lags: Option<i128>,
        #[pyo3(from_py_with = crate::args::gate)] gate: Option<f64>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let gate = gate.unwrap_or(vehid_runtime::defaults::GATE);
        let target = Target::of(model)?;
        let s = target.structure()?;
        let n = s.states();
        let sv = noise_arg(deriv_noise_var, "deriv_noise_var", n)?;
        let r = r_arg(r, s.equations())?;
        let estimate = match state_noise_var.extract::<String>() {
            Ok(text) if text == "estimate" => true,
            Ok(other) => {
                return Err(VehidError::new_err(format!(
                    "unknown `state_noise_var` {other:?}: expected \"estimate\" or the variances (a scalar, one per \
                     state, or ({n}, {n}))"
                )))
            }
            Err(_) => false,
        };
        let inner = if estimate {
            let (delay, lags) = instrument_args(&s, delay.unwrap_or(1), lags)?;
            build::noise_estimating(s, delay, lags, &sv, &r)
        } else {
            if delay.is_some() || lags.is_some() {
                return Err(VehidError::new_err(
                    "`delay` and `lags` set the instruments of state_noise_var=\"estimate\"; with the variances \
                     given there are none",
                ));
            }
            let sw = noise_arg(Some(state_noise_var), "state_noise_var", n)?;
            build::bias_compensated(s, &sw, &sv, &r)
        }
        .and_then(|inner| build::screened(inner, &s, gate, Refresh::Geometric))
        .map_err(core_err)?;
        Ok(PyClassInitializer::from(target.wrap(inner)).add_subclass(Self { gate }))
    }

    /// True when Σ_w is estimated from the data (`state_noise_var="estimate"`).
    #[getter]
    fn estimates_noise(slf: &Bound<'_, Self>) -> PyResult<bool> {
        let this = borrow(slf)?;
        Ok(estimating(this.as_super().inner.as_ref(), None).is_some())
    }

    /// The instruments' `(delay, lags)` of `state_noise_var="estimate"` (None with Σ_w given).
    #[getter]
    fn instruments(slf: &Bound<'_, Self>) -> PyResult<Option<(usize, usize)>> {
        let this = borrow(slf)?;
        estimating(this.as_super().inner.as_ref(), None).transpose().map_err(core_err)
    }

    /// The estimated state-noise variances σ̂_j² (state units², (n,), ≥ 0; NaN for the states no
    /// parameterized term reads), fitted now from the samples so far. VehidError with Σ_w given,
    /// and while the instrumental estimate is starting.
    fn state_noise_var_estimate<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let this = borrow(slf)?;
        let n = this.as_super().model.n;
        let mut out = vec![0.0; n];
        match estimating(this.as_super().inner.as_ref(), Some(&mut out)) {
            None => Err(VehidError::new_err(
                "this BiasCompensated was given state_noise_var; build it with state_noise_var=\"estimate\" to \
                 estimate the variances from the data",
            )),
            Some(r) => {
                r.map_err(core_err)?;
                Ok(out.into_pyarray(py))
            }
        }
    }

    /// A copy with its own core.
    fn __copy__(slf: &Bound<'_, Self>) -> PyResult<Py<Self>> {
        let base = copy_base(slf.as_super())?;
        let gate = crate::guard::borrow(slf)?.gate;
        Py::new(slf.py(), PyClassInitializer::from(base).add_subclass(Self { gate }))
    }

    /// The same as `__copy__`: the core shares nothing.
    fn __deepcopy__(slf: &Bound<'_, Self>, _memo: &Bound<'_, PyAny>) -> PyResult<Py<Self>> {
        Self::__copy__(slf)
    }

    /// What builds a fresh object of this class and settings (pickling and copying, `persist.rs`).
    fn __getnewargs_ex__<'py>(slf: &Bound<'py, Self>) -> PyResult<crate::persist::NewArgs<'py>> {
        let py = slf.py();
        let kw = pyo3::types::PyDict::new(py);
        match slf.getattr("instruments")?.extract::<Option<(usize, usize)>>()? {
            Some((delay, lags)) => {
                kw.set_item("state_noise_var", "estimate")?;
                kw.set_item("delay", delay)?;
                kw.set_item("lags", lags)?;
            }
            None => kw.set_item("state_noise_var", 0.0)?,
        }
        kw.set_item("gate", crate::guard::borrow(slf)?.gate)?;
        crate::persist::new_args(py, crate::guard::borrow(slf)?.as_super(), kw)
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let slf = crate::guard::borrow(slf)?;
        let base = slf.as_super();
        let noise = match estimating(base.inner.as_ref(), None) {
            Some(Ok((d, l))) => format!("state_noise_var='estimate', delay={d}, lags={l}, "),
            _ => String::new(),
        };
        Ok(format!(
            "BiasCompensated({noise}unknown_rows={}, samples={})",
            crate::convert::py_tuple(base.inner.rows()),
            base.inner.samples()
        ))
    }
}
