//! `vehid.JointEKF`: the core's `JointEkf` (states, parameters and each sample's road input
//! estimated together by an extended Kalman filter; the thesis' Ch. VII proposal). It
//! subclasses `vehid.Identifier`, so `update`, `fit` (GIL released), `params`, `theta`,
//! `a_hat`, pickling and copying are the base class's; this file converts the constructor's
//! arguments and dispatches the sizes.
//!
//! Sizes: the filter's augmented state has `D = n + params + 1` entries, a const generic of
//! the core, and every size is one more compiled copy of the filter. The binding builds the
//! 4-state ones with 3, 4 or 8 parameters (`D` = 8, 9, 13): every quarter-car structure
//! (`QuarterCar.structure` with one or two constants known has 3 or 4 parameters, its full
//! rows 8). The filter's road enters through one input column, so the half car on one road
//! (two correlated road inputs) is not a case for it.

use crate::convert::{array, finite, shape_str};
use crate::guard::borrow;
use crate::identify::PyIdentifier;
use crate::model::{to_array2, PyLinearModel};
use crate::structure::PyStructure;
use crate::{core_err, VehidError};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use vehid_core::identify::{joint_ekf_substeps, EkfNoise, MAX_EKF_SUBSTEPS};
use vehid_core::nalgebra::SVector;
use vehid_core::structure::{Basis, Structure, Term, Var};
use vehid_runtime::ModelData;

use vehid_runtime::build::{EKF_SIZES, EKF_STATES};

/// A linear model's complete structure: its unknown rows with every entry a parameter
/// (`Structure::full_rows`, named row-major as θ), then its known rows as parameter-free
/// equations (the filter predicts every state).
fn model_structure(d: &ModelData) -> vehid_core::Result<Structure<f64>> {
    let mut s = Structure::<f64>::full_rows(d.n, &d.rows)?;
    let mut terms = Vec::with_capacity(d.n);
    for row in (0..d.n).filter(|r| !d.rows.contains(r)) {
        terms.clear();
        for (j, &a) in d.a[row * d.n..(row + 1) * d.n].iter().enumerate() {
            if a != 0.0 {
                terms.push(Term { coef: a, param: None, basis: Basis::Var(Var::State(j as u8)) });
            }
        }
        s.push_equation(row, &terms)?;
    }
    Ok(s)
}

/// A scalar or one value per component (`len`), each finite and > 0 (`zero_ok`: ≥ 0).
fn per_component(obj: &Bound<'_, PyAny>, arg: &str, len: usize, what: &str) -> PyResult<Vec<f64>> {
    let a = array(obj, arg)?;
    finite(arg, &a.data)?;
    let v = match a.shape[..] {
        [] => vec![a.data[0]; len],
        [l] if l == len => a.data,
        _ => {
            return Err(VehidError::new_err(format!(
                "`{arg}` must be a scalar or one value per {what} ({len},), got shape {}",
                shape_str(&a.shape)
            )))
        }
    };
    if let Some(i) = v.iter().position(|&x| x <= 0.0) {
        return Err(VehidError::new_err(format!("`{arg}` must be > 0, got {} at index {i}", v[i])));
    }
    Ok(v)
}

/// A finite scalar ≥ 0 (`positive`: > 0).
fn scalar(v: f64, arg: &str, positive: bool) -> PyResult<f64> {
    if !v.is_finite() || v < 0.0 || (positive && v == 0.0) {
        let want = if positive { "a finite number > 0" } else { "a finite number >= 0" };
        return Err(VehidError::new_err(format!("`{arg}` must be {want}, got {v}")));
    }
    Ok(v)
}

use vehid_runtime::with_joint_ekf as with_ekf;

/// Joint state and parameter estimation: an extended Kalman filter on the states, the
/// parameters and each sample's road input together (the thesis' Ch. VII proposal; Ljung
/// 1979). The measured state is not a regressor here but a noisy measurement of the
/// estimated state, so white sensor noise on it does not bias the parameters.
///
/// `model`: a LinearModel (its unknown rows, every entry a parameter: `theta` (k, n); its
/// known rows are used as they are) or a complete Structure (an equation for every state,
/// e.g. `car.structure(known={"m": 1.0})`). Built for 4 states with 3, 4 or 8 parameters
/// (every quarter-car structure); other sizes raise VehidError.
/// `theta0`: the prior guess of the parameters (a linear model: its unknown rows (k, n));
/// the filter needs a rough one (within ×0.5–×1.5 of the truth: from a diffuse prior it can
/// diverge). `p0`: its variance, a scalar or one per parameter (default `theta0**2`: a
/// standard deviation of 100 %). The noise model, which the filter is told and does not
/// learn: `state_noise` (standard deviation of the measured state's noise, > 0, scalar or one
/// per state), `deriv_noise` (of the measured derivative's; default 0.005), `road_sigma` (of the
/// road input of one sample, held over the interval; default 0.1), `road_gain` (the road's input column of dx/dt,
/// (n,) or (n, 1): the model's B by default; needed with a Structure, e.g. `car.b`). `dt`:
/// the sample interval (s); `substeps`: RK4 steps per interval (default: the simulator's
/// rule, h ρ(A) ≤ 1/2, on the model's A or the structure's linearization at `theta0`);
/// `x0_var`: the initial states' variance; `drift`: the parameters' random-walk variance per
/// sample (0: constant). `stats()` gives the parameter block of the filter's covariance as it
/// is (a posterior under the told noise model; normal intervals). Pickles (every protocol),
/// copies and deep-copies: a restored one continues bit for bit. About 2–3 µs per sample.
#[pyclass(name = "JointEKF", module = "vehid._vehid", extends = PyIdentifier)]
pub struct PyJointEKF;

#[pymethods]
impl PyJointEKF {
    #[new]
    #[pyo3(signature = (model, theta0, p0 = None, *, state_noise, deriv_noise = None, road_sigma = None,
                        road_gain = None, dt = 0.05, substeps = None, x0_var = 1.0, drift = 0.0),
           text_signature = "(model, theta0, p0=None, *, state_noise, deriv_noise=None, road_sigma=0.1, \
                             road_gain=None, dt=0.05, substeps=None, x0_var=1.0, drift=0.0)")]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        model: &Bound<'_, PyAny>,
        theta0: &Bound<'_, PyAny>,
        p0: Option<&Bound<'_, PyAny>>,
        state_noise: &Bound<'_, PyAny>,
        deriv_noise: Option<&Bound<'_, PyAny>>,
        road_sigma: Option<f64>,
        road_gain: Option<&Bound<'_, PyAny>>,
        dt: f64,
        substeps: Option<i128>,
        x0_var: f64,
        drift: f64,
    ) -> PyResult<PyClassInitializer<Self>> {
        let (s, data, st) = if let Ok(st) = model.cast::<PyStructure>() {
            (st.get().core, None, Some(st.clone()))
        } else if let Ok(m) = model.cast::<PyLinearModel>() {
            let d = m.get().data.clone();
            (model_structure(&d).map_err(core_err)?, Some(d), None)
        } else {
            return Err(VehidError::new_err(
                "`model` must be a LinearModel (QuarterCar, ...) or a vehid.Structure with an equation for every state",
            ));
        };
        let (n, np) = (s.states(), s.params());
        let d = n + np + 1;
        if n != EKF_STATES || !EKF_SIZES.contains(&d) {
            return Err(VehidError::new_err(format!(
                "`model`: JointEKF is built for {EKF_STATES} states with 3, 4 or 8 parameters (the quarter car's \
                 structures and full rows); this one has {n} states and {np} parameters"
            )));
        }
        if !s.complete() {
            return Err(VehidError::new_err(
                "`model`: the Structure needs an equation for every state (give the kinematic ones as known, e.g. \
                 known={\"x1\": \"x2\"}): the filter predicts them all",
            ));
        }
        let t = array(theta0, "theta0")?;
        finite("theta0", &t.data)?;
        if t.data.len() != np || t.shape.len() > 2 {
            return Err(VehidError::new_err(format!(
                "`theta0` must hold the {np} parameters (a linear model: its unknown rows, ({}, {n})), got shape {}",
                np / n,
                shape_str(&t.shape)
            )));
        }
        let theta0 = t.data;
        let p0 = match p0 {
            Some(p) => per_component(p, "p0", np, "parameter")?,
            None => {
                if let Some(j) = theta0.iter().position(|&v| v == 0.0) {
                    return Err(VehidError::new_err(format!(
                        "`p0` is needed: the default theta0**2 is 0 for parameter {j} (give its variance)"
                    )));
                }
                theta0.iter().map(|v| v * v).collect()
            }
        };
        let sw = per_component(state_noise, "state_noise", n, "state")?;
        let sv = match deriv_noise {
            Some(v) => per_component(v, "deriv_noise", n, "state")?,
            None => vec![vehid_runtime::defaults::DERIV_NOISE; n],
        };
        let road_sigma = scalar(road_sigma.unwrap_or(vehid_runtime::defaults::ROAD_SIGMA), "road_sigma", false)?;
        let dt = scalar(dt, "dt", true)?;
        let x0_var = scalar(x0_var, "x0_var", true)?;
        let drift = scalar(drift, "drift", false)?;
        let gain = match (road_gain, &data) {
            (Some(g), _) => {
                let a = array(g, "road_gain")?;
                finite("road_gain", &a.data)?;
                if !(a.shape == [n] || a.shape == [n, 1]) {
                    return Err(VehidError::new_err(format!(
                        "`road_gain` must be the road's input column, shape ({n},) or ({n}, 1), got {}",
                        shape_str(&a.shape)
                    )));
                }
                a.data
            }
            (None, Some(d)) if d.m == 1 => d.b.clone(),
            (None, Some(d)) => {
                return Err(VehidError::new_err(format!(
                    "`road_gain` is needed: the model has {} inputs, and the filter's road enters through one column",
                    d.m
                )))
            }
            (None, None) => {
                return Err(VehidError::new_err(
                    "`road_gain` is needed with a Structure: the road's input column of dx/dt (the car's B, e.g. \
                     road_gain=car.b)",
                ))
            }
        };
        let substeps = match substeps {
            Some(k) => u32::try_from(k).ok().filter(|k| (1..=MAX_EKF_SUBSTEPS).contains(k)).ok_or_else(|| {
                VehidError::new_err(format!("`substeps` must be an integer in 1..={MAX_EKF_SUBSTEPS}, got {k}"))
            })?,
            // At the model's own rows (its A), or at theta0 on a structure.
            None => {
                let at: Vec<f64> = match &data {
                    Some(d) => d.rows.iter().flat_map(|&r| d.a[r * d.n..(r + 1) * d.n].iter().copied()).collect(),
                    None => theta0.clone(),
                };
                joint_ekf_substeps::<f64, EKF_STATES>(&s, &at, dt).map_err(core_err)?
            }
        };
        let sq = |v: &[f64]| SVector::<f64, EKF_STATES>::from_iterator(v.iter().map(|x| x * x));
        let noise = EkfNoise {
            state_var: sq(&sw),
            deriv_var: sq(&sv),
            road_gain: SVector::from_column_slice(&gain),
            road_var: road_sigma * road_sigma,
            param_walk_var: drift,
        };
        let inner = vehid_runtime::build::joint_ekf(s, &theta0, &p0, x0_var, noise, dt, substeps).map_err(core_err)?;
        let base = match (st, data) {
            (Some(st), _) => PyIdentifier::on_structure(inner, &st),
            (None, Some(d)) => PyIdentifier::new(inner, d),
            (None, None) => unreachable!("a model or a structure"),
        };
        Ok(PyClassInitializer::from(base).add_subclass(Self))
    }

    /// The state predicted for the next sample, x̂(k+1 | k), (n,).
    #[getter]
    fn state<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let this = borrow(slf)?;
        let x = with_ekf!(this.as_super().inner, |id| id.state().as_slice().to_vec());
        Ok(x.ok_or_else(not_ekf)?.into_pyarray(py))
    }

    /// The covariance of `state`, (n, n).
    #[getter]
    fn state_covariance<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let this = borrow(slf)?;
        let p = with_ekf!(this.as_super().inner, |id| id.state_covariance().transpose().as_slice().to_vec());
        to_array2(py, EKF_STATES, EKF_STATES, p.ok_or_else(not_ekf)?)
    }

    /// The sample interval, s.
    #[getter]
    fn dt(slf: &Bound<'_, Self>) -> PyResult<f64> {
        let this = borrow(slf)?;
        with_ekf!(this.as_super().inner, |id| id.dt()).ok_or_else(not_ekf)
    }

    /// RK4 sub-steps per sample.
    #[getter]
    fn substeps(slf: &Bound<'_, Self>) -> PyResult<u32> {
        let this = borrow(slf)?;
        with_ekf!(this.as_super().inner, |id| id.substeps()).ok_or_else(not_ekf)
    }

    /// The road's input column of dx/dt in use, (n,).
    #[getter]
    fn road_gain<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let this = borrow(slf)?;
        let g = with_ekf!(this.as_super().inner, |id| id.noise().road_gain.as_slice().to_vec());
        Ok(g.ok_or_else(not_ekf)?.into_pyarray(py))
    }

    /// The estimate's uncertainty: the parameter block of the filter's covariance as it is (a
    /// posterior under the noise model the filter was told; not scaled by the residuals),
    /// `bse` its square roots, normal intervals at level `alpha` (`df` = inf), `sigma2` each
    /// equation's variance under that noise model, `nobs` the samples.
    #[pyo3(signature = (alpha = 0.05))]
    fn stats(slf: &Bound<'_, Self>, py: Python<'_>, alpha: f64) -> PyResult<crate::stats::PyStats> {
        let this = borrow(slf)?;
        crate::stats::posterior_stats_of(py, this.as_super(), alpha)
    }

    /// What builds a fresh object of this class and settings (pickling and copying, `persist.rs`).
    /// (Any valid filter of the same sizes: the saved core replaces it.)
    fn __getnewargs_ex__<'py>(slf: &Bound<'py, Self>) -> PyResult<crate::persist::NewArgs<'py>> {
        let py = slf.py();
        let kw = pyo3::types::PyDict::new(py);
        let this = borrow(slf)?;
        let (n, np) = (this.as_super().model.n, this.as_super().inner.dims().params);
        kw.set_item("theta0", vec![0.0; np])?;
        kw.set_item("p0", 1.0)?;
        kw.set_item("state_noise", 1.0)?;
        kw.set_item("road_gain", vec![0.0; n])?;
        kw.set_item("substeps", 1)?;
        crate::persist::new_args(py, this.as_super(), kw)
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let this = borrow(slf)?;
        let base = this.as_super();
        let d = base.inner.dims();
        Ok(format!(
            "JointEKF(states={}, params={}, unknown_rows={}, samples={})",
            d.states,
            d.params,
            crate::convert::py_tuple(base.inner.rows()),
            base.inner.samples()
        ))
    }
}

fn not_ekf() -> PyErr {
    VehidError::new_err("internal: this JointEKF holds no joint EKF core")
}
