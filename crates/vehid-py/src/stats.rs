//! `Identifier.stats(alpha)` → `vehid.Stats` (the core's `estimate_stats`), and the physical
//! constants with intervals from a `Stats` of a car's physical structure (the core's
//! `PhysicalStructure::constant`, delta method).

use crate::identify::{raise, PyIdentifier};
use crate::model::to_array2;
use crate::structure::{known_constants, CarKind, Origin, PyStructure};
use crate::{core_err, VehidError};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use vehid_core::identify::{estimate_stats, posterior_stats, EstimateStats};

/// An estimate and its uncertainty, as statsmodels names them (from `Identifier.stats`).
///
/// `names` (n_params,) the parameters; `params` θ̂; `bse` standard errors; `conf_int`
/// (n_params, 2) the 1 − `alpha` intervals (Student's t with `df` degrees of freedom);
/// `cov` (n_params, n_params) the covariance `s² P`; `sigma2` and `nobs` one residual
/// variance and one (effective) sample count per identified equation. `s²` is the weighted
/// residual variance of the parameters' group: the OLS `scale` for one equation.
#[pyclass(name = "Stats", module = "vehid._vehid", frozen)]
pub struct PyStats {
    pub(crate) s: EstimateStats,
    pub(crate) names: Vec<String>,
    pub(crate) structure: Option<Py<PyStructure>>,
}

#[pymethods]
impl PyStats {
    /// The parameter names.
    #[getter]
    fn names<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, &self.names)
    }

    /// θ̂, (n_params,).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.s.params.clone().into_pyarray(py)
    }

    /// Standard errors, (n_params,).
    #[getter]
    fn bse<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.s.bse.clone().into_pyarray(py)
    }

    /// The 1 − alpha confidence intervals, (n_params, 2).
    #[getter]
    fn conf_int<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let v = self.s.conf_int.iter().flat_map(|&(a, b)| [a, b]).collect();
        to_array2(py, self.s.params.len(), 2, v)
    }

    /// The covariance of θ̂, (n_params, n_params).
    #[getter]
    fn cov<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let n = self.s.params.len();
        to_array2(py, n, n, self.s.cov.clone())
    }

    /// One residual variance per identified equation.
    #[getter]
    fn sigma2<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.s.sigma2.clone().into_pyarray(py)
    }

    /// One (effective) number of observations per identified equation.
    #[getter]
    fn nobs<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.s.nobs.clone().into_pyarray(py)
    }

    /// Residual degrees of freedom behind each parameter's interval, (n_params,).
    #[getter]
    fn df<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.s.df.clone().into_pyarray(py)
    }

    /// The level of `conf_int`.
    #[getter]
    fn alpha(&self) -> f64 {
        self.s.alpha
    }

    /// The structure the estimate belongs to (None for a linear model's rows).
    #[getter]
    fn structure(&self, py: Python<'_>) -> Option<Py<PyStructure>> {
        self.structure.as_ref().map(|s| s.clone_ref(py))
    }

    fn __repr__(&self) -> String {
        let rows: Vec<String> = self
            .names
            .iter()
            .zip(&self.s.params)
            .zip(&self.s.bse)
            .map(|((n, p), b)| format!("{n}={p:.6e}±{b:.2e}"))
            .collect();
        format!("Stats({}, alpha={})", rows.join(", "), self.s.alpha)
    }
}

/// `Identifier.stats(alpha)`.
pub(crate) fn stats_of(py: Python<'_>, id: &PyIdentifier, alpha: f64) -> PyResult<PyStats> {
    let inner = &id.inner;
    let s = py.detach(|| estimate_stats(inner.as_ref(), alpha)).map_err(raise)?;
    Ok(named(py, id, s))
}

/// `JointEKF.stats(alpha)`: the covariance as the filter holds it (the core's
/// `posterior_stats`).
pub(crate) fn posterior_stats_of(py: Python<'_>, id: &PyIdentifier, alpha: f64) -> PyResult<PyStats> {
    let s = posterior_stats(id.inner.as_ref(), alpha).map_err(raise)?;
    Ok(named(py, id, s))
}

/// The statistics with the parameters' names (a structure's, or `a[row,col]`).
fn named(py: Python<'_>, id: &PyIdentifier, s: EstimateStats) -> PyStats {
    let names = match &id.structure {
        Some(st) => st.get().params.clone(),
        None => {
            let n = id.model.n;
            id.model.rows.iter().flat_map(|&r| (0..n).map(move |c| format!("a[{r},{c}]"))).collect()
        }
    };
    PyStats { s, names, structure: id.structure.as_ref().map(|s| s.clone_ref(py)) }
}

/// `car.physical(stats, **known)`: every constant as `(value, low, high)`, the interval by the
/// delta method with the Student quantile of the smallest `df` (known constants: the value
/// three times).
pub(crate) fn physical_from_stats<'py>(
    py: Python<'py>,
    car: CarKind,
    st: &PyStats,
    known: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let consts = car.constants();
    // The structure the stats came from, or the one `known` describes.
    let realistic = st.structure.as_ref().is_some_and(|s| s.get().realistic());
    let known_k = match (known.filter(|k| !k.is_empty()), &st.structure) {
        (Some(k), _) => known_constants(car, Some(k.as_any()))?,
        (None, Some(s)) => match &s.get().origin {
            Origin::Physical { car: of, known, .. } if *of == car => known.clone(),
            Origin::Physical { car: of, .. } => {
                return Err(VehidError::new_err(format!(
                    "these stats come from a {} structure, not a {}",
                    of.name(),
                    car.name()
                )))
            }
            Origin::Text { .. } => vec![None; consts.len()],
        },
        (None, None) => {
            return Err(VehidError::new_err(
                "give the known constants (e.g. m=1.0), as when building car.structure(known=...)",
            ))
        }
    };
    let ph = PyStructure::physical_known(car, known_k, realistic)?;
    if ph.params != st.names {
        return Err(VehidError::new_err(format!(
            "these stats belong to parameters {:?}, but the structure with these known constants has {:?}: use \
             the same known constants as for car.structure(known=...)",
            st.names, ph.params
        )));
    }
    let Origin::Physical { physical, known: kn, .. } = &ph.origin else {
        return Err(VehidError::new_err("internal: not a physical structure"));
    };
    let q = vehid_core::stats::t_interval_factor(st.s.alpha, &st.s.df).map_err(core_err)?;
    let out = PyDict::new(py);
    for (c, name) in consts.iter().enumerate() {
        if let Some(v) = kn[c] {
            out.set_item(*name, (v, v, v))?;
            continue;
        }
        match physical.constant(c, &st.s.params, &st.s.cov) {
            Ok((v, se)) => out.set_item(*name, (v, v - q * se, v + q * se))?,
            Err(vehid_core::Error::NotIdentifiable { .. }) => {}
            Err(e) => return Err(core_err(e)),
        }
    }
    if out.len() == kn.iter().flatten().count() {
        return Err(VehidError::new_err(
            "no constant follows from these parameters: the equations fix only ratios; give a mass as known",
        ));
    }
    Ok(out)
}

/// The Ljung–Box test of the whiteness of `x` over lags 1..`lags` (statsmodels'
/// `acorr_ljungbox(x, lags=[lags])`): `(lb_stat, lb_pvalue)`, with
/// `Q = n (n + 2) Σ_j ρ̂_j² / (n − j)` and the p-value `P(χ²(lags) > Q)`. A small p-value says
/// the series is not white (Ljung & Box 1978).
#[pyfunction]
#[pyo3(signature = (x, lags = 10))]
pub fn ljung_box(py: Python<'_>, x: &Bound<'_, PyAny>, lags: i128) -> PyResult<(f64, f64)> {
    let a = crate::convert::array(x, "x")?;
    if a.shape.len() != 1 {
        return Err(VehidError::new_err(format!(
            "`x` must be one series (n,), got shape {}",
            crate::convert::shape_str(&a.shape)
        )));
    }
    let lags = crate::convert::size(lags, "lags")?;
    let lb = py.detach(|| vehid_core::stats::ljung_box(&a.data, lags)).map_err(core_err)?;
    Ok((lb.stat, lb.pvalue))
}

/// One 1-D float series from `obj`, named `arg` in errors.
fn series(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Vec<f64>> {
    let a = crate::convert::array(obj, arg)?;
    if a.shape.len() != 1 {
        return Err(VehidError::new_err(format!(
            "`{arg}` must be one series (n,), got shape {}",
            crate::convert::shape_str(&a.shape)
        )));
    }
    Ok(a.data)
}

/// The cross-correlation of `x` with `y` at lags 0..nlags-1 (statsmodels'
/// `ccf(x, y, adjusted=True)[:nlags]`): `ccf[k] = Σ_t (x[t+k] - x̄)(y[t] - ȳ) / (n - k) / (σx σy)`.
/// Residuals that are white and independent of a regressor stay within ±2/√n.
#[pyfunction]
#[pyo3(signature = (x, y, nlags = None))]
pub fn ccf<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    nlags: Option<i128>,
) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
    let (x, y) = (series(x, "x")?, series(y, "y")?);
    let lags = match nlags {
        Some(l) => crate::convert::size(l, "nlags")?,
        None => x.len(),
    };
    let out = py
        .detach(|| {
            let mut out = vec![0.0; lags];
            vehid_core::stats::ccf_into(&x, &y, &mut out).map(|_| out)
        })
        .map_err(core_err)?;
    Ok(numpy::IntoPyArray::into_pyarray(out, py))
}

/// The recursive residuals of the regression of `y` (n,) on `h` (n, p) (Brown, Durbin & Evans
/// 1975; statsmodels' `RecursiveLS(y, h).fit().resid_recursive[p:]`): n - p one-step forecast
/// errors, each scaled to the noise variance; independent N(0, σ²) under the model.
#[pyfunction]
pub fn recursive_residuals<'py>(
    py: Python<'py>,
    h: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
    let a = crate::convert::array(h, "h")?;
    let y = series(y, "y")?;
    let p = match a.shape[..] {
        [rows, p] if rows == y.len() && p > 0 => p,
        _ => {
            return Err(VehidError::new_err(format!(
                "`h` must have shape ({}, n_params): one row of regressors per value of `y`, got {}",
                y.len(),
                crate::convert::shape_str(&a.shape)
            )))
        }
    };
    let w = py.detach(|| vehid_core::stats::recursive_residuals(&a.data, &y, p)).map_err(core_err)?;
    Ok(numpy::IntoPyArray::into_pyarray(w, py))
}

/// The CUSUM and CUSUM-of-squares tests of recursive residuals `w` at level `alpha` (0.01,
/// 0.05 or 0.10; statsmodels' `RecursiveLSResults.cusum`, `cusum_squares` and their
/// significance bounds): a dict with `cusum` (m,), `cusum_bound` (m,; the lower bound is its
/// negative), `cusum_squares` (m,), `cusum_squares_bounds` (m, 2), `sigma`, `alpha`, and
/// `first_cusum_crossing` / `first_cusum_squares_crossing`: the first index outside its
/// bounds (evidence that the parameters or the noise changed), or None.
#[pyfunction]
#[pyo3(signature = (w, alpha = 0.05))]
pub fn cusum<'py>(py: Python<'py>, w: &Bound<'py, PyAny>, alpha: f64) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    let w = series(w, "w")?;
    let c = py.detach(|| vehid_core::stats::Cusum::new(&w, alpha)).map_err(core_err)?;
    let out = pyo3::types::PyDict::new(py);
    let bounds: Vec<f64> = c.cusum_squares_bounds.iter().flatten().copied().collect();
    out.set_item("first_cusum_crossing", c.first_cusum_crossing())?;
    out.set_item("first_cusum_squares_crossing", c.first_cusum_squares_crossing())?;
    out.set_item("sigma", c.sigma)?;
    out.set_item("alpha", c.alpha)?;
    let m = c.len();
    out.set_item("cusum", numpy::IntoPyArray::into_pyarray(c.cusum, py))?;
    out.set_item("cusum_bound", numpy::IntoPyArray::into_pyarray(c.cusum_bound, py))?;
    out.set_item("cusum_squares", numpy::IntoPyArray::into_pyarray(c.cusum_squares, py))?;
    out.set_item("cusum_squares_bounds", crate::model::to_array2(py, m, 2, bounds)?)?;
    Ok(out)
}
