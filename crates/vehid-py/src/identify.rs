//! The Python identifier classes: one base class `Identifier` over the core's
//! [`DynIdentifier`], and the thin subclasses `KalmanIdentifier`, `StochasticGradient`,
//! `BatchLeastSquares` (and `TwoAxleIdentifier` in `two_axle.rs`), which only convert their
//! constructor arguments.
//!
//! The shared methods (`update`, `fit`, `theta`, `params`, `a_hat`, `samples`, …) are written
//! once, on the base class. `fit` reads float64 C-contiguous arrays in place (anything else is
//! converted once), validates while it updates (the core's update rejects a non-finite sample
//! and the core's `fit` rolls back), releases the GIL, and checks for Ctrl-C (`guard.rs`;
//! an interrupted `fit` changes nothing). Every method borrows its object through
//! `guard::borrow` / `guard::borrow_mut`: a call into an identifier that another thread is
//! fitting raises a `VehidError` saying so.

use crate::convert::{array, finite, p0_value, shape_str, size, values, Table};
use crate::guard::{borrow, borrow_mut, check_every, Interrupts};
use crate::model::{to_array2, PyLinearModel};
use crate::structure::{kalman_on_structure, refuse_for_structure, PyStructure};
use crate::{core_err, option, VehidError};
use numpy::ndarray::{Array1, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::exceptions::PyMemoryError;
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use vehid_core::identify::{
    CovarianceForm, DynIdentifier, FitError, FitOptions, Gain, GainKind, KalmanOptions, KalmanSpec, Mode, Prior,
    Refresh, Samples,
};
use vehid_core::Error;
use vehid_runtime::{build, ModelData};

/// `model` as a linear model, or an error naming the two kinds of model an identifier takes.
fn linear_model<'a, 'py>(model: &'a Bound<'py, PyAny>) -> PyResult<&'a Bound<'py, PyLinearModel>> {
    model.cast::<PyLinearModel>().map_err(|_| {
        VehidError::new_err("`model` must be a LinearModel (QuarterCar, HalfCar, ...) or a vehid.Structure")
    })
}

/// The measured inputs `u` of a batch of `rows` samples as a table of `m` columns (None when
/// the model has none and none were given).
fn input_table<'py>(u: Option<&Bound<'py, PyAny>>, m: usize, rows: usize) -> PyResult<Option<Table<'py>>> {
    match (u, m) {
        (None, 0) => Ok(None),
        (None, m) => {
            Err(VehidError::new_err(format!("`u` is needed: the model has {m} measured inputs (shape (samples, {m}))")))
        }
        (Some(u), m) => Ok(Some(Table::new(u, "u", Some(rows), m, "measured inputs")?)),
    }
}

/// Maps a core error to a Python exception: `MemoryError` for allocations that failed,
/// `KeyboardInterrupt` passes through, `VehidError` for everything else.
pub(crate) fn raise(e: Error) -> PyErr {
    match e {
        Error::OutOfMemory { .. } => PyMemoryError::new_err(e.to_string()),
        e => core_err(e),
    }
}

/// The message of a rejected `fit`: the sample and column for a non-finite value, the
/// sample and the reason otherwise.
pub(crate) fn fit_error(e: FitError, len: usize) -> PyErr {
    match (e.sample, &e.error) {
        (Some(i), Error::NonFinite { arg, index }) => {
            let name = arg.trim_end_matches("_k");
            VehidError::new_err(format!(
                "`{name}[{i}, {index}]` is not finite (NaN or inf): clean or drop that sample; the identifier is \
                 unchanged (none of the {len} samples were applied)"
            ))
        }
        (_, Error::OutOfMemory { .. }) => raise(e.error),
        (Some(i), err) => VehidError::new_err(format!(
            "sample {i} was rejected ({err}); the identifier is unchanged (none of the {len} samples were applied)"
        )),
        (None, err) => raise(err.clone()),
    }
}

/// The base class of every identifier: samples in (`update`, `fit`), estimates out.
///
/// Not constructed directly: use `KalmanIdentifier`, `StochasticGradient`,
/// `BatchLeastSquares` or `TwoAxleIdentifier`.
#[pyclass(name = "Identifier", module = "vehid._vehid", subclass)]
pub struct PyIdentifier {
    pub(crate) inner: Box<dyn DynIdentifier<f64>>,
    pub(crate) model: ModelData,
    /// The structure, for an identifier built on one (`model` then only records its sizes).
    pub(crate) structure: Option<Py<PyStructure>>,
}

impl PyIdentifier {
    pub(crate) fn new(inner: Box<dyn DynIdentifier<f64>>, model: ModelData) -> Self {
        Self { inner, model, structure: None }
    }

    /// An identifier on a structure.
    pub(crate) fn on_structure(inner: Box<dyn DynIdentifier<f64>>, s: &Bound<'_, PyStructure>) -> Self {
        let st = s.get();
        let (n, m) = (st.core.states(), st.core.inputs());
        let model = ModelData {
            n,
            m,
            a: vec![0.0; n * n],
            b: vec![0.0; n * m],
            rows: st.core.equation_states().collect(),
            zeros: vec![],
        };
        Self { inner, model, structure: Some(s.clone().unbind()) }
    }

    /// The shape of θ: (equations, states) for a linear model, (1, params) for a structure.
    fn shape(&self) -> (usize, usize) {
        if self.structure.is_some() {
            return (1, self.inner.dims().params);
        }
        (self.inner.dims().equations, self.model.n)
    }

    /// The covariance `P` (params × params, row-major).
    pub(crate) fn covariance_vec(&self) -> PyResult<Vec<f64>> {
        let p = self.inner.dims().params;
        let mut out = vec![0.0; p * p];
        self.inner.covariance_into(&mut out).map_err(raise)?;
        Ok(out)
    }

    /// The noise covariance `R` (equations × equations, row-major).
    pub(crate) fn noise_vec(&self) -> PyResult<Vec<f64>> {
        let k = self.inner.dims().equations;
        let mut out = vec![0.0; k * k];
        self.inner.noise_into(&mut out).map_err(raise)?;
        Ok(out)
    }
}

/// One value of a sample, as a 1-D float array of the given length.
fn vector(obj: Option<&Bound<'_, PyAny>>, arg: &str, len: usize) -> PyResult<Vec<f64>> {
    let Some(obj) = obj else {
        if len == 0 {
            return Ok(vec![]);
        }
        return Err(VehidError::new_err(format!("`{arg}` is needed: the model has {len} measured inputs")));
    };
    let a = array(obj, arg)?;
    if a.shape != [len] {
        return Err(VehidError::new_err(format!("`{arg}` must have shape ({len},), got {}", shape_str(&a.shape))));
    }
    Ok(a.data)
}

/// Measured samples for an identifier's equations, checked: the states `r`, derivatives `z`
/// and inputs `u` as tables of its structure's sizes (a linear model's rows as its full-row
/// structure), every value finite. What `residuals` and `regressors` read.
struct Measured<'py> {
    rows: usize,
    n: usize,
    m: usize,
    r: Table<'py>,
    z: Table<'py>,
    u: Option<Table<'py>>,
}

impl<'py> Measured<'py> {
    fn read(
        this: &PyIdentifier,
        r: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<(Equations, Self)> {
        let structure = match &this.structure {
            Some(st) => Equations::Structure(Box::new(st.get().core)),
            None => match vehid_core::structure::Structure::full_rows(this.model.n, &this.model.rows) {
                Ok(s) => Equations::Structure(Box::new(s)),
                // Rows no structure holds (the full car's seven of 14): the rows as they are.
                Err(vehid_core::Error::Capacity { .. } | vehid_core::Error::InvalidArgument { .. }) => {
                    Equations::Rows { n: this.model.n, rows: this.model.rows.clone() }
                }
                Err(e) => return Err(core_err(e)),
            },
        };
        let (n, m) = (structure.states(), structure.inputs());
        let rt = Table::new(r, "r", None, n, "measured states")?;
        let zt = Table::new(z, "z", Some(rt.rows), n, "measured derivatives, like `r`")?;
        let ut = input_table(u, m, rt.rows)?;
        finite("r", rt.data())?;
        finite("z", zt.data())?;
        finite("u", ut.as_ref().map_or(&[][..], |t| t.data()))?;
        Ok((structure, Self { rows: rt.rows, n, m, r: rt, z: zt, u: ut }))
    }

    /// The samples as plain slices (which may cross into a GIL-free closure).
    fn samples(&self) -> Rows<'_> {
        let u = self.u.as_ref().map_or(&[][..], |t| t.data());
        Rows { rows: self.rows, n: self.n, m: self.m, x: self.r.data(), z: self.z.data(), u }
    }
}

/// The equations `residuals` and `regressors` evaluate: a Structure's, or a linear model's
/// unknown rows `z_r = θ_r · x + (the road, unmeasured)` when no structure holds them.
enum Equations {
    Structure(Box<vehid_core::structure::Structure<f64>>),
    Rows { n: usize, rows: Vec<usize> },
}

impl Equations {
    fn states(&self) -> usize {
        match self {
            Self::Structure(s) => s.states(),
            Self::Rows { n, .. } => *n,
        }
    }

    fn inputs(&self) -> usize {
        match self {
            Self::Structure(s) => s.inputs(),
            Self::Rows { .. } => 0,
        }
    }

    fn equations(&self) -> usize {
        match self {
            Self::Structure(s) => s.equations(),
            Self::Rows { rows, .. } => rows.len(),
        }
    }

    fn params(&self) -> usize {
        match self {
            Self::Structure(s) => s.params(),
            Self::Rows { n, rows } => n * rows.len(),
        }
    }

    /// Equation `i`'s residual at `theta` (`Structure::residual`; for rows
    /// `vehid_core::model::row_residual`).
    fn residual(&self, i: usize, theta: &[f64], x: &[f64], z: &[f64], u: &[f64]) -> f64 {
        match self {
            Self::Structure(s) => s.residual(i, theta, x, z, u),
            Self::Rows { n, rows } => vehid_core::model::row_residual(&theta[i * n..(i + 1) * n], x, z[rows[i]]),
        }
    }

    /// Equation `i`'s regressors into `h` (all parameters), its left side returned
    /// (`Structure::regression`; for rows, `x` in row `i`'s block and `z_r`).
    fn regression(&self, i: usize, x: &[f64], z: &[f64], u: &[f64], h: &mut [f64]) -> f64 {
        match self {
            Self::Structure(s) => s.regression(i, x, z, u, h),
            Self::Rows { n, rows } => {
                h.fill(0.0);
                h[i * n..(i + 1) * n].copy_from_slice(x);
                z[rows[i]]
            }
        }
    }
}

/// Row-major samples of states, derivatives and inputs.
struct Rows<'a> {
    rows: usize,
    n: usize,
    m: usize,
    x: &'a [f64],
    z: &'a [f64],
    u: &'a [f64],
}

impl Rows<'_> {
    /// `f(k, x_k, z_k, u_k)` for every sample `k`.
    fn each(&self, mut f: impl FnMut(usize, &[f64], &[f64], &[f64])) {
        let (n, m) = (self.n, self.m);
        for k in 0..self.rows {
            f(k, &self.x[k * n..(k + 1) * n], &self.z[k * n..(k + 1) * n], &self.u[k * m..(k + 1) * m]);
        }
    }
}

/// A regression `(H, y)`: regressors (samples, parameters) and left sides (samples,).
type Regression<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, numpy::PyArray1<f64>>);

#[pymethods]
impl PyIdentifier {
    /// One sample: measured state `r_k` (n,) and derivative `z_k` (n,) (and the measured
    /// inputs `u_k` (m,) for a model that has them). Returns the innovations (one per
    /// identified equation: the prediction error before the update; NaN for batch least
    /// squares, which has no running estimate). A rejected sample (NaN, inf, a numerically
    /// singular step) raises VehidError and leaves the identifier unchanged.
    #[pyo3(signature = (r_k, z_k, u_k = None))]
    fn update<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
        r_k: &Bound<'py, PyAny>,
        z_k: &Bound<'py, PyAny>,
        u_k: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let mut this = borrow_mut(slf)?;
        let d = this.inner.dims();
        let x = vector(Some(r_k), "r_k", d.states)?;
        let z = vector(Some(z_k), "z_k", d.states)?;
        let u = vector(u_k, "u_k", d.inputs)?;
        let mut e = vec![0.0; d.equations];
        this.inner.update_into(&x, &z, &u, &mut e).map_err(raise)?;
        Ok(e.into_pyarray(py))
    }

    /// Runs every sample of `r`, `z` (samples, n) (and `u` (samples, m) for a model with
    /// measured inputs) with the GIL released. All or nothing: a rejected sample raises and
    /// leaves the identifier as it was; so does Ctrl-C (KeyboardInterrupt within some 20 ms
    /// of work, whatever a sample costs, when called from the main thread).
    /// Returns θ̂ recorded every `record_every` samples, shape (samples // record_every, k, n)
    /// (empty when 0; NaN rows while the estimate does not exist yet).
    #[pyo3(signature = (r, z, u = None, record_every = 0))]
    fn fit<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
        r: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
        #[pyo3(from_py_with = crate::args::record_every)] record_every: i128,
    ) -> PyResult<Bound<'py, PyAny>> {
        let every = size(record_every, "record_every")?;
        let mut this = borrow_mut(slf)?;
        let d = this.inner.dims();
        let rt = Table::new(r, "r", None, d.states, "measured states")?;
        let zt = Table::new(z, "z", Some(rt.rows), d.states, "measured derivatives, like `r`")?;
        let ut = input_table(u, d.inputs, rt.rows)?;
        let samples = Samples::new(d.states, d.inputs, rt.data(), zt.data(), ut.as_ref().map_or(&[][..], |t| t.data()))
            .map_err(raise)?;
        let len = samples.len();
        let opts = FitOptions { record_every: every, check_every: check_every(d.params) };
        let inner = &mut this.inner;
        let mut hist = Vec::new();
        let mut signals = Interrupts::new();
        let res = py.detach(|| inner.fit_dyn(&samples, opts, &mut hist, &mut || signals.check()));
        if let Err(e) = res {
            if let (Error::Interrupted, Some(err)) = (&e.error, signals.raise()) {
                return Err(err);
            }
            return Err(fit_error(e, len));
        }
        let (k, n) = this.shape();
        let rows = hist.len() / (k * n).max(1);
        if this.structure.is_some() {
            return Ok(to_array2(py, rows, n, hist)?.into_any());
        }
        Array3::from_shape_vec((rows, k, n), hist)
            .map(|a| a.into_pyarray(py).into_any())
            .map_err(|e| VehidError::new_err(format!("internal shape error: {e}")))
    }

    /// The estimated unknown rows of A, shape (k, n); for a structure the parameters
    /// (n_params,), like `params`.
    #[getter]
    pub(crate) fn theta<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let this = borrow(slf)?;
        if this.structure.is_some() {
            return Ok(this.params_vec(py)?.into_pyarray(py).into_any());
        }
        let (k, n) = this.shape();
        Ok(to_array2(py, k, n, this.params_vec(py)?)?.into_any())
    }

    /// The estimate's uncertainty (`vehid.Stats`: params, bse, conf_int at level `alpha`,
    /// cov, sigma2, nobs): the covariance P scaled by the residual variance the data show
    /// (statsmodels' OLS figures after an exact start). Needs an identifier that keeps P and
    /// its residuals (KalmanIdentifier in mode "rows" or on a Structure, BatchLeastSquares).
    #[pyo3(signature = (alpha = 0.05))]
    fn stats(slf: &Bound<'_, Self>, py: Python<'_>, alpha: f64) -> PyResult<crate::stats::PyStats> {
        crate::stats::stats_of(py, &*borrow(slf)?, alpha)
    }

    /// The structure the identifier was built on (None for a linear model).
    #[getter]
    fn structure(slf: &Bound<'_, Self>, py: Python<'_>) -> PyResult<Option<Py<PyStructure>>> {
        Ok(borrow(slf)?.structure.as_ref().map(|s| s.clone_ref(py)))
    }

    /// The estimated parameters, (n_params,); for a linear model the unknown rows of A,
    /// row-major.
    #[getter]
    fn params<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(borrow(slf)?.params_vec(py)?.into_pyarray(py))
    }

    /// Â: the model's A with the unknown rows replaced by the estimate, shape (n, n).
    #[getter]
    pub(crate) fn a_hat<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let this = borrow(slf)?;
        if this.structure.is_some() {
            return Err(VehidError::new_err(
                "an identifier on a Structure has no matrix A: read `params` (named by `structure.parameters`)",
            ));
        }
        let th = this.params_vec(py)?;
        let d = &this.model;
        let a = d.a_hat(&th).map_err(core_err)?;
        to_array2(py, d.n, d.n, a)
    }

    /// Number of samples accepted.
    #[getter]
    fn samples(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(borrow(slf)?.inner.samples())
    }

    /// The unknown rows (0-based), in the order of θ and of the innovations.
    #[getter]
    fn unknown_rows(slf: &Bound<'_, Self>) -> PyResult<Vec<usize>> {
        Ok(borrow(slf)?.inner.rows().to_vec())
    }

    /// Samples each identified equation left out as outliers (the gate), (k,) int.
    #[getter]
    fn gated<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<u64>>> {
        let this = borrow(slf)?;
        let mut out = vec![0u64; this.inner.dims().equations];
        this.inner.gated_into(&mut out).map_err(raise)?;
        Ok(out.into_pyarray(py))
    }

    /// What builds a fresh object of this class: only vehid's identifier classes say (each
    /// overrides this; pickling and copying use it).
    fn __getnewargs_ex__<'py>(slf: &Bound<'py, Self>) -> PyResult<crate::persist::NewArgs<'py>> {
        Err(VehidError::new_err(format!(
            "{} cannot be pickled or copied: only vehid's identifier classes can",
            slf.get_type().name()?
        )))
    }

    /// Pickling (every protocol): the class with its settings, and the core's state
    /// (`persist.rs`).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        crate::persist::reduce(slf)
    }

    /// Restores the state `__reduce__` saved (its format version is checked first).
    fn __setstate__(slf: &Bound<'_, Self>, state: &Bound<'_, PyAny>) -> PyResult<()> {
        crate::persist::set_state(slf, state)
    }

    /// The regression of identified equation `equation` at each sample: `(H, y)` with `H`
    /// (samples, n_params) the regressors and `y` (samples,) the left side less the known
    /// terms, so that `y = H @ params + residual` (the core's `Structure::regression`; a
    /// linear model's rows as its full-row structure). For `recursive_residuals`, `ccf`.
    #[pyo3(signature = (r, z, u = None, equation = 0))]
    fn regressors<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
        r: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
        equation: usize,
    ) -> PyResult<Regression<'py>> {
        let (structure, data) = Measured::read(&*borrow(slf)?, r, z, u)?;
        let (ne, np, rows) = (structure.equations(), structure.params(), data.rows);
        if equation >= ne {
            return Err(VehidError::new_err(format!(
                "`equation` must be below {ne} (the identified equations, in order), got {equation}"
            )));
        }
        let data = data.samples();
        let (h, y) = py.detach(|| {
            let (mut h, mut y) = (vec![0.0; rows * np], vec![0.0; rows]);
            data.each(|k, xk, zk, uk| {
                y[k] = structure.regression(equation, xk, zk, uk, &mut h[k * np..(k + 1) * np]);
            });
            (h, y)
        });
        Ok((to_array2(py, rows, np, h)?, numpy::IntoPyArray::into_pyarray(y, py)))
    }

    /// Each identified equation's residual at the current estimate, (samples, equations):
    /// `z_i − (known terms + hᵀθ̂)` for the equations as written (before any road
    /// differencing), in the order of `unknown_rows`. Model checks read them (whiteness:
    /// `vehid.ljung_box`). GIL released.
    #[pyo3(signature = (r, z, u = None))]
    fn residuals<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
        r: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let this = borrow(slf)?;
        let theta = this.params_vec(py)?;
        let (structure, data) = Measured::read(&this, r, z, u)?;
        if structure.params() != theta.len() {
            return Err(VehidError::new_err(
                "residuals need an identifier whose parameters are its model's unknown rows or its Structure's \
                 parameters",
            ));
        }
        let (ne, rows, data) = (structure.equations(), data.rows, data.samples());
        let out = py.detach(|| {
            let mut out = vec![0.0; rows * ne];
            data.each(|k, xk, zk, uk| {
                for i in 0..ne {
                    out[k * ne + i] = structure.residual(i, &theta, xk, zk, uk);
                }
            });
            out
        });
        to_array2(py, rows, ne, out)
    }

    /// A copy with its own core (the model is shared: models are immutable).
    fn __copy__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        crate::persist::copy(slf)
    }

    /// The same as `__copy__`: the core shares nothing.
    fn __deepcopy__<'py>(slf: &Bound<'py, Self>, _memo: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        crate::persist::copy(slf)
    }
}

impl PyIdentifier {
    /// The parameters (solving a batch estimator can take a while: GIL released).
    fn params_vec(&self, py: Python<'_>) -> PyResult<Vec<f64>> {
        let inner = &self.inner;
        let mut out = vec![0.0; inner.dims().params];
        py.detach(|| inner.params_into(&mut out)).map_err(raise)?;
        Ok(out)
    }
}

/// The Kalman-filter identifier (Eq 4.3–4.7, 6.16–6.18) of the unknown rows of A: recursive
/// (weighted) least squares.
///
/// `p0` is P(0): "exact" (the default: no prior; samples are absorbed exactly until they
/// identify every parameter, then every estimate is least squares on all samples so far), a
/// scalar, one value per unknown row, one (n, n) matrix per row (k, n, n), or the full
/// (k·n, k·n) matrix (mode "full", or block diagonal for mode "rows"); `theta0` the prior mean
/// (k, n). The regression-error variances come from `r` (scalar or one per unknown row;
/// optional with p0="exact", where it does not change the estimate) or from `road_sigma` and
/// `deriv_noise` (R = R_v + B R_u Bᵀ, Eq 4.7), not both. For mode "full", `r` may be a (k, k)
/// matrix. `form`: "standard" (the thesis', fastest), "joseph", "sqrt" (Bierman's U D Uᵀ
/// factors: P stays positive definite for any p0 and scaling; the recommended online form).
/// Tracking: `forgetting` λ in (0, 1] (memory about 1/(1 − λ) samples; `directional=True`
/// forgets only along excited directions), `drift` q (random walk: P += q I per sample), both
/// only while tr P < `max_trace` (default: the trace when filtering starts). Outliers: `gate`
/// κ (default 6 in every mode; 0 turns it off, as exact least-squares equivalence needs)
/// leaves out a sample whose recursive residual exceeds κ estimated standard deviations
/// (counted in `gated`; in modes "shared" and "full" a sample beyond the gate on one row is
/// left out by every row); the same κ screens every value of a sample against κ² times its
/// root mean square so far (a state far beyond the others, which the recursive residual cannot
/// judge) and keeps the first 16 samples to judge them together against their median, restarting
/// without an outlier found there (an outlier at sample 0 no longer spoils the exact start; the
/// screen of `vehid_core::identify::Screened`, residual test off); `huber` c (e.g. 1.345,
/// mode "rows") weights large residuals down (Huber).
/// `reinit=True` applies Eq 4.36 (a sample the gate left out reinitializes nothing). `mode`: "rows" (decoupled filters, Eq 6.16–6.18), "shared" (one covariance
/// for all rows; needs the same r/p0 on every row), "full" (the stacked filter, general R).
/// With a prior the estimate depends on r/p0 only (see the README on prior regimes).
#[pyclass(name = "KalmanIdentifier", module = "vehid._vehid", extends = PyIdentifier)]
pub struct PyKalmanIdentifier {
    mode: Mode,
    form: CovarianceForm,
    gate: f64,
}

/// Parses `p0` for a model with `k` unknown rows and `n` states (`None` or "exact": the
/// exact start).
fn p0_arg(p0: Option<&Bound<'_, PyAny>>, k: usize, n: usize) -> PyResult<Prior<f64>> {
    let Some(a) = p0_value(p0, "\"exact\", a number, one per unknown row, or a matrix")? else {
        return Ok(Prior::Exact);
    };
    Ok(match a.shape[..] {
        [] => Prior::PerRow(a.data),
        [len] if len == k => Prior::PerRow(a.data),
        [kk, r, c] if kk == k && r == n && c == n => Prior::RowMatrices(a.data),
        [r, c] if r == k * n && c == k * n => Prior::Full(a.data),
        _ => {
            return Err(VehidError::new_err(format!(
                "`p0` must be \"exact\", a scalar, shape ({k},), ({k}, {n}, {n}) or ({kn}, {kn}), got {}",
                shape_str(&a.shape),
                kn = k * n
            )))
        }
    })
}

/// Parses `theta0`: (k, n) or (k·n,).
fn theta0_arg(theta0: Option<&Bound<'_, PyAny>>, k: usize, n: usize) -> PyResult<Option<Vec<f64>>> {
    let Some(t) = theta0 else { return Ok(None) };
    let a = array(t, "theta0")?;
    finite("theta0", &a.data)?;
    match a.shape[..] {
        [r, c] if r == k && c == n => Ok(Some(a.data)),
        [len] if len == k * n => Ok(Some(a.data)),
        _ => Err(VehidError::new_err(format!(
            "`theta0` must have shape ({k}, {n}) (the prior mean of the unknown rows) or ({},), got {}",
            k * n,
            shape_str(&a.shape)
        ))),
    }
}

/// The regression-error variances from `r=` or from `road_sigma=`/`deriv_noise=`.
fn r_arg(
    m: &PyLinearModel,
    mode: Mode,
    exact: bool,
    r: Option<&Bound<'_, PyAny>>,
    road_sigma: Option<&Bound<'_, PyAny>>,
    deriv_noise: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<f64>> {
    let k = m.data.rows.len();
    match (r, road_sigma, deriv_noise) {
        (Some(r), None, None) => {
            let a = array(r, "r")?;
            finite("r", &a.data)?;
            let ok = match a.shape[..] {
                [] => true,
                [len] => len == k,
                [rr, cc] => mode == Mode::Full && rr == k && cc == k,
                _ => false,
            };
            if !ok {
                return Err(VehidError::new_err(format!(
                    "`r` must be a scalar or one variance per unknown row, shape ({k},){}; got {}",
                    if mode == Mode::Full { format!(", or a ({k}, {k}) matrix") } else { String::new() },
                    shape_str(&a.shape)
                )));
            }
            Ok(a.data)
        }
        (None, rs, dn) if rs.is_some() || dn.is_some() => {
            let rs = values(rs, "road_sigma", 0.0)?;
            let dn = values(dn, "deriv_noise", 0.0)?;
            m.row_noise_var_vec(&rs, &dn)
        }
        (None, None, None) => vehid_runtime::defaults::kalman_r(exact).ok_or_else(|| {
            VehidError::new_err(
                "give the regression-error variances: `r=` (one per unknown row) or `road_sigma=` and `deriv_noise=` \
             to compute them from the model (Eq 4.7)",
            )
        }),
        _ => Err(VehidError::new_err("give either `r=` or `road_sigma=`/`deriv_noise=`, not both")),
    }
}

#[pymethods]
impl PyKalmanIdentifier {
    #[new]
    #[pyo3(signature = (model, p0 = None, r = None, *, theta0 = None, road_sigma = None, deriv_noise = None,
                        reinit = false, mode = "rows".into(), form = None, joseph = false, retire_below = 0.0,
                        forgetting = 1.0, drift = 0.0, directional = false, max_trace = None, gate = None,
                        huber = 0.0),
           text_signature = "(model, p0=None, r=None, *, theta0=None, road_sigma=None, deriv_noise=None, \
                             reinit=False, mode='rows', form=None, joseph=False, retire_below=0.0, \
                             forgetting=1.0, drift=0.0, directional=False, max_trace=None, gate=None, huber=0.0)")]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        model: &Bound<'_, PyAny>,
        p0: Option<&Bound<'_, PyAny>>,
        r: Option<&Bound<'_, PyAny>>,
        theta0: Option<&Bound<'_, PyAny>>,
        road_sigma: Option<&Bound<'_, PyAny>>,
        deriv_noise: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = crate::args::reinit)] reinit: bool,
        #[pyo3(from_py_with = crate::args::mode)] mode: String,
        #[pyo3(from_py_with = crate::args::form)] form: Option<String>,
        #[pyo3(from_py_with = crate::args::joseph)] joseph: bool,
        #[pyo3(from_py_with = crate::args::retire_below)] retire_below: f64,
        #[pyo3(from_py_with = crate::args::forgetting)] forgetting: f64,
        #[pyo3(from_py_with = crate::args::drift)] drift: f64,
        #[pyo3(from_py_with = crate::args::directional)] directional: bool,
        #[pyo3(from_py_with = crate::args::max_trace)] max_trace: Option<f64>,
        #[pyo3(from_py_with = crate::args::gate)] gate: Option<f64>,
        #[pyo3(from_py_with = crate::args::huber)] huber: f64,
    ) -> PyResult<PyClassInitializer<Self>> {
        let mode: Mode = option(&mode)?;
        let form = match (form.as_deref(), joseph) {
            (None, false) => CovarianceForm::Standard,
            (None, true) => CovarianceForm::Joseph,
            (Some(f), false) => option(f)?,
            (Some(_), true) => {
                return Err(VehidError::new_err("give `form=` or the older `joseph=True`, not both"));
            }
        };
        let opts = KalmanOptions {
            form,
            reinit,
            retire_below,
            forgetting,
            directional,
            drift,
            max_trace: max_trace.unwrap_or(0.0),
            // On by default for online use, in every mode.
            gate: gate.unwrap_or(vehid_runtime::defaults::GATE),
            huber,
        };
        if let Ok(st) = model.cast::<PyStructure>() {
            refuse_for_structure("road_sigma", road_sigma.is_some())?;
            refuse_for_structure("deriv_noise", deriv_noise.is_some())?;
            if mode != Mode::Rows {
                return Err(VehidError::new_err(
                    "`mode` applies to a LinearModel: a Structure is identified one parameter group at a time \
                     (equations sharing a parameter are filtered together)",
                ));
            }
            let inner = kalman_on_structure(st.get(), p0, r, theta0, opts)?;
            // Its own gate tests the residual; the screen adds the magnitude test and the held start.
            let inner = build::screened(inner, &st.get().core, opts.gate, Refresh::Never).map_err(core_err)?;
            return Ok(PyClassInitializer::from(PyIdentifier::on_structure(inner, st)).add_subclass(Self {
                mode,
                form,
                gate: opts.gate,
            }));
        }
        let model = linear_model(model)?;
        let m = model.get();
        let (n, k) = (m.data.n, m.data.rows.len());
        let p0 = p0_arg(p0, k, n)?;
        let theta0 = theta0_arg(theta0, k, n)?;
        let r = r_arg(m, mode, p0 == Prior::Exact, r, road_sigma, deriv_noise)?;
        let spec = KalmanSpec { rows: m.data.rows.clone(), p0, theta0, r, mode, opts };
        let inner = build::kalman(n, &spec).map_err(core_err)?;
        let inner = screen_rows(inner, &m.data, opts.gate, Refresh::Never)?;
        Ok(PyClassInitializer::from(PyIdentifier::new(inner, m.data.clone())).add_subclass(Self {
            mode,
            form,
            gate: opts.gate,
        }))
    }

    /// "standard", "joseph" or "sqrt".
    #[getter]
    fn form(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        Ok(borrow(slf)?.form.as_str())
    }

    /// The covariance: (k, n, n) per-row P_i for modes "rows" and "shared" (P_i = r_i Q),
    /// the full (k·n, k·n) matrix for mode "full".
    #[getter]
    fn covariance<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let slf = borrow(slf)?;
        let base = slf.as_super();
        let (k, n) = base.shape();
        let c = base.covariance_vec()?;
        if slf.mode == Mode::Full {
            return Ok(to_array2(py, k * n, k * n, c)?.into_any());
        }
        // The diagonal blocks of the block-diagonal covariance.
        let kn = k * n;
        let blocks: Vec<f64> = (0..k)
            .flat_map(|i| (0..n * n).map(move |ab| (i * n + ab / n) * kn + i * n + ab % n))
            .map(|j| c[j])
            .collect();
        Array3::from_shape_vec((k, n, n), blocks)
            .map(|a| a.into_pyarray(py).into_any())
            .map_err(|e| VehidError::new_err(format!("internal shape error: {e}")))
    }

    /// The regression-error variances in use (k,), or the (k, k) R of mode "full"; each
    /// reinitialization doubles them (Eq 4.36).
    #[getter]
    fn r<'py>(slf: &Bound<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let slf = borrow(slf)?;
        let base = slf.as_super();
        let k = base.inner.dims().equations;
        let r = base.noise_vec()?;
        if slf.mode == Mode::Full {
            return Ok(to_array2(py, k, k, r)?.into_any());
        }
        Ok(Array1::from_iter((0..k).map(|i| r[i * k + i])).into_pyarray(py).into_any())
    }

    /// tr P, the quantity Eq 4.36 compares with the innovations.
    #[getter]
    fn trace(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.as_super().inner.trace().unwrap_or(f64::NAN))
    }

    /// Number of reinitializations (Eq 4.36) so far.
    #[getter]
    fn reinit_count(slf: &Bound<'_, Self>) -> PyResult<u32> {
        Ok(borrow(slf)?.as_super().inner.reinit_count())
    }

    /// Covariance resetting (Goodwin & Sin 1984, §3.3): restarts P at `p0` I around the
    /// current estimate, which is kept, as are r, the residual statistics and the counts;
    /// retired rows update again. The way back for an identifier whose covariance lost
    /// positive definiteness (every sample refused), or to let it move after a sudden change.
    /// Mode "shared" keeps one r/p0 for all rows: the first row gets p0 I. Raises VehidError
    /// for `p0` not finite and > 0, or during the exact start (no estimate yet); the
    /// identifier is then unchanged.
    fn reset_covariance(slf: &Bound<'_, Self>, #[pyo3(from_py_with = crate::args::p0_reset)] p0: f64) -> PyResult<()> {
        let mut this = borrow_mut(slf)?;
        this.as_super().inner.reset_covariance(p0).map_err(raise)
    }

    /// "rows", "shared" or "full".
    #[getter]
    fn mode(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        Ok(borrow(slf)?.mode.as_str())
    }

    /// What builds a fresh object of this class and settings (pickling and copying, `persist.rs`).
    fn __getnewargs_ex__<'py>(slf: &Bound<'py, Self>) -> PyResult<crate::persist::NewArgs<'py>> {
        let py = slf.py();
        let kw = pyo3::types::PyDict::new(py);
        let this = borrow(slf)?;
        kw.set_item("p0", 1.0)?;
        if this.as_super().structure.is_none() {
            kw.set_item("r", 1.0)?;
        }
        kw.set_item("mode", this.mode.as_str())?;
        kw.set_item("form", this.form.as_str())?;
        kw.set_item("gate", this.gate)?;
        crate::persist::new_args(py, this.as_super(), kw)
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let slf = borrow(slf)?;
        let base = slf.as_super();
        Ok(format!(
            "KalmanIdentifier(mode={}, unknown_rows={}, samples={}, reinit_count={})",
            crate::convert::py_str(slf.mode.as_str()),
            crate::convert::py_tuple(base.inner.rows()),
            base.inner.samples(),
            base.inner.reinit_count()
        ))
    }
}

/// The stochastic-gradient identifier (Eq 2.56, 5.2–5.18).
///
/// `gain`: "venter" (Eq 5.8, γ = k^(−p), 1/2 < p ≤ 1), "lyapunov" (Eq 5.9, normalized by the
/// data; biased) or "ljung" (Eq 5.15–5.18, forgetting with `lambda0`, `lambda_init`).
/// `h`: the per-parameter weights: a scalar, one per unknown row (k,), or one per parameter
/// (k·n,) / (k, n); the thesis makes the wheel-row weights a tenth of the body-row ones
/// (Eq 5.10). `spacing`: use every l-th sample. `state_noise_var`: the diagonal of Σ_w (a
/// scalar or one per state) for the `[I + R Σ_N]` bias elimination. Outliers: `gate` κ (default 6; 0: off, the identifier alone)
/// screens a sample — accepted, counted in `gated`, otherwise left out — whose prediction error on
/// an equation exceeds κ times its standard deviation estimated from the samples accepted so far
/// (active after N + 50 samples), or any of whose values (a state, a derivative, an input)
/// exceeds κ² times its root mean square so far; the first 16 samples are kept and judged
/// together against their median, the identifier restarted without an outlier found there, so
/// that an outlier at sample 0 does not spoil the start (`vehid_core::identify::Screened`).
#[pyclass(name = "StochasticGradient", module = "vehid._vehid", extends = PyIdentifier)]
pub struct PyStochasticGradient {
    gain: GainKind,
    gate: f64,
}

#[pymethods]
impl PyStochasticGradient {
    #[new]
    #[pyo3(signature = (model, gain = "venter".into(), h = None, p = 0.51, *, spacing = 1, state_noise_var = None, lambda0 = 0.99, lambda_init = 0.95, gate = None),
           text_signature = "(model, gain='venter', h=None, p=0.51, *, spacing=1, state_noise_var=None, lambda0=0.99, \
                             lambda_init=0.95, gate=None)")]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        model: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = crate::args::gain)] gain: String,
        h: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = crate::args::p)] p: f64,
        #[pyo3(from_py_with = crate::args::spacing_int)] spacing: i128,
        state_noise_var: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = crate::args::lambda0)] lambda0: f64,
        #[pyo3(from_py_with = crate::args::lambda_init)] lambda_init: f64,
        #[pyo3(from_py_with = crate::args::gate)] gate: Option<f64>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let kind: GainKind = option(&gain)?;
        let gate = gate.unwrap_or(vehid_runtime::defaults::GATE);
        if let Ok(st) = model.cast::<PyStructure>() {
            refuse_for_structure("state_noise_var", state_noise_var.is_some())?;
            let h = match h {
                None => vec![1.0],
                Some(h) => {
                    let a = array(h, "h")?;
                    finite("h", &a.data)?;
                    a.data
                }
            };
            let spacing = u32::try_from(spacing)
                .map_err(|_| VehidError::new_err(format!("`spacing` must be an integer >= 1, got {spacing}")))?;
            let g = Gain::of_kind(kind, p, lambda0, lambda_init);
            let inner = crate::structure::gradient_on_structure(st.get(), g, &h, spacing)?;
            // Magnitude test and held start only (`Refresh::Never`): see below.
            let inner = build::screened(inner, &st.get().core, gate, Refresh::Never).map_err(core_err)?;
            return Ok(
                PyClassInitializer::from(PyIdentifier::on_structure(inner, st)).add_subclass(Self { gain: kind, gate })
            );
        }
        let model = linear_model(model)?;
        let m = model.get();
        let h = match h {
            None => vec![1.0],
            Some(h) => {
                let a = array(h, "h")?;
                finite("h", &a.data)?;
                a.data
            }
        };
        let snv = values(state_noise_var, "state_noise_var", 0.0)?;
        let spacing = u32::try_from(spacing)
            .map_err(|_| VehidError::new_err(format!("`spacing` must be an integer >= 1, got {spacing}")))?;
        let g = Gain::of_kind(kind, p, lambda0, lambda_init);
        let inner = build::gradient(m.data.n, &m.data.rows, g, &h, &snv, spacing).map_err(core_err)?;
        // Magnitude test and held start only (`Refresh::Never`): the gradient's estimate converges
        // slowly (ξ about 5 after 10⁴ samples on the thesis car), its prediction errors are the
        // estimate's, not the noise's, and a residual screen would keep a wrong estimate.
        let inner = screen_rows(inner, &m.data, gate, Refresh::Never)?;
        Ok(PyClassInitializer::from(PyIdentifier::new(inner, m.data.clone())).add_subclass(Self { gain: kind, gate }))
    }

    /// The gain name.
    #[getter]
    fn gain(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        Ok(borrow(slf)?.gain.as_str())
    }

    /// What builds a fresh object of this class and settings (pickling and copying, `persist.rs`).
    fn __getnewargs_ex__<'py>(slf: &Bound<'py, Self>) -> PyResult<crate::persist::NewArgs<'py>> {
        let py = slf.py();
        let kw = pyo3::types::PyDict::new(py);
        let this = borrow(slf)?;
        kw.set_item("gain", this.gain.as_str())?;
        kw.set_item("gate", this.gate)?;
        crate::persist::new_args(py, this.as_super(), kw)
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let slf = borrow(slf)?;
        let base = slf.as_super();
        Ok(format!(
            "StochasticGradient(gain={}, unknown_rows={}, samples={})",
            crate::convert::py_str(slf.gain.as_str()),
            crate::convert::py_tuple(base.inner.rows()),
            base.inner.samples()
        ))
    }
}

/// Batch least squares (Eq 2.14): stores every sample and solves each unknown row by
/// column-pivoted QR when the estimate is read. With `keep_samples=False` (the memory-bounded
/// form, what `vehid identify --method ls` uses) nothing is stored: the same least-squares
/// estimate is computed recursively (Givens QR of the samples until they identify every
/// parameter, then recursive least squares with no prior and no outlier gate), equal to the
/// stored form's to rounding, with the same `stats()`; `remove()` needs the stored samples. On a
/// Structure: always the recursive form, storing nothing. Missing excitation raises VehidError (rank
/// deficiency), never NaN; so does (stored form) one sample that dominates the regression,
/// named with the `remove()` that drops it. `fit` stores the samples (all or nothing) and
/// returns the history like the recursive identifiers (θ̂ over every prefix, solved at each record). Outliers: `gate` κ (default 6; 0: off, the identifier alone)
/// screens a sample — accepted, counted in `gated`, otherwise left out — whose prediction error on
/// an equation exceeds κ times its standard deviation estimated from the samples accepted so far
/// (active after N + 50 samples), or any of whose values (a state, a derivative, an input)
/// exceeds κ² times its root mean square so far; the first 16 samples are kept and judged
/// together against their median, the identifier restarted without an outlier found there, so
/// that an outlier at sample 0 does not spoil the start (`vehid_core::identify::Screened`).
/// Screened samples are not stored (`remove()` indexes the stored ones).
#[pyclass(name = "BatchLeastSquares", module = "vehid._vehid", extends = PyIdentifier)]
pub struct PyBatchLeastSquares {
    keep_samples: bool,
    gate: f64,
}

/// The structure whose residuals screen a linear model's identifier: its unknown rows' full
/// rows (`Structure::full_rows`).
fn full_rows(m: &ModelData) -> Option<vehid_core::structure::Structure<f64>> {
    vehid_core::structure::Structure::full_rows(m.n, &m.rows).ok()
}

/// A linear model's identifier behind the screen at `gate` (`build::screened`), its residuals
/// those of the model's full rows; when those rows exceed a structure's capacity (more than 96
/// terms: e.g. the full car's seven rows of 14 states) the screen's magnitude test and held
/// start only (`build::screened_magnitudes`; the Kalman identifiers test residuals themselves).
fn screen_rows(
    inner: Box<dyn DynIdentifier<f64>>,
    m: &ModelData,
    gate: f64,
    refresh: Refresh,
) -> PyResult<Box<dyn DynIdentifier<f64>>> {
    match full_rows(m) {
        Some(s) => build::screened(inner, &s, gate, refresh).map_err(core_err),
        None => build::screened_magnitudes(inner, gate).map_err(core_err),
    }
}

/// Batch least squares for `m` in its form (`keep`: stored samples; else the memory-bounded
/// recursive one), behind the screen at `gate`.
fn batch_core(m: &ModelData, keep: bool, gate: f64) -> PyResult<Box<dyn DynIdentifier<f64>>> {
    let inner = if keep { build::batch(m.n, &m.rows) } else { build::batch_recursive(m.n, &m.rows) };
    let inner = inner.map_err(core_err)?;
    screen_rows(inner, m, gate, if keep { Refresh::Geometric } else { Refresh::Every })
}

/// Batch least squares on a Structure (the recursive form, exact start, no prior), behind the
/// screen at `gate`.
fn batch_on_structure(st: &PyStructure, gate: f64) -> PyResult<Box<dyn DynIdentifier<f64>>> {
    let inner = kalman_on_structure(st, None, None, None, KalmanOptions::default())?;
    build::screened(inner, &st.core, gate, Refresh::Every).map_err(core_err)
}

#[pymethods]
impl PyBatchLeastSquares {
    #[new]
    #[pyo3(signature = (model, keep_samples = true, *, gate = None))]
    fn py_new(
        model: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = crate::args::keep_samples)] keep_samples: bool,
        #[pyo3(from_py_with = crate::args::gate)] gate: Option<f64>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let gate = gate.unwrap_or(vehid_runtime::defaults::GATE);
        if let Ok(st) = model.cast::<PyStructure>() {
            // Least squares on all samples, solved recursively (exact start, no prior, no
            // Kalman gate: the screen's): the same estimate as the normal equations, without
            // storing samples.
            let inner = batch_on_structure(st.get(), gate)?;
            return Ok(PyClassInitializer::from(PyIdentifier::on_structure(inner, st))
                .add_subclass(Self { keep_samples: false, gate }));
        }
        let model = linear_model(model)?;
        let m = model.get();
        let inner = batch_core(&m.data, keep_samples, gate)?;
        Ok(PyClassInitializer::from(PyIdentifier::new(inner, m.data.clone())).add_subclass(Self { keep_samples, gate }))
    }

    /// Whether the samples are stored (QR solve, `remove()`), or none (the memory-bounded
    /// recursive form: `storage_bytes` stays 0).
    #[getter]
    fn keep_samples(slf: &Bound<'_, Self>) -> PyResult<bool> {
        Ok(borrow(slf)?.keep_samples)
    }

    /// Bytes of sample storage (the thesis' objection to batch least squares); 0 for the
    /// memory-bounded form (`keep_samples=False`) and on a Structure.
    #[getter]
    fn storage_bytes(slf: &Bound<'_, Self>) -> PyResult<usize> {
        let mut slf = borrow_mut(slf)?;
        let keep = slf.keep_samples;
        let base = slf.as_super();
        if base.structure.is_some() || !keep {
            return Ok(0);
        }
        build::batch_storage_bytes(base.inner.as_ref()).map_err(core_err)
    }

    /// Drops the stored samples (the memory-bounded form: starts its recursive solution anew)
    /// and starts the outlier screen anew (its held samples, scales and counts).
    fn clear(slf: &Bound<'_, Self>) -> PyResult<()> {
        let mut slf = borrow_mut(slf)?;
        let (keep, gate) = (slf.keep_samples, slf.gate);
        let base = slf.as_super();
        base.inner = match &base.structure {
            Some(st) => batch_on_structure(st.get(), gate)?,
            None => batch_core(&base.model, keep, gate)?,
        };
        Ok(())
    }

    /// Drops stored sample `index` (0-based, in the order the samples were given), e.g. the
    /// one a `VehidError` names as dominating the batch (an outlier). Later samples move up by
    /// one. An index out of range raises and changes nothing; so does the memory-bounded form
    /// (`keep_samples=False`), which has no samples to drop.
    fn remove(slf: &Bound<'_, Self>, index: i128) -> PyResult<()> {
        let mut slf = borrow_mut(slf)?;
        if !slf.keep_samples {
            return Err(VehidError::new_err(
                "`remove` needs the stored samples: this BatchLeastSquares keeps none (keep_samples=False: \
                 only its recursive solution); refit with BatchLeastSquares(model) to drop a sample",
            ));
        }
        let base = slf.as_super();
        let samples = base.inner.samples();
        let index = usize::try_from(index).ok().filter(|&i| (i as u64) < samples).ok_or_else(|| {
            VehidError::new_err(format!(
                "`index` must be the index of a stored sample, 0 to {}, got {index}",
                samples.saturating_sub(1)
            ))
        })?;
        build::batch_remove(&mut base.inner, index).map_err(raise)
    }

    /// What builds a fresh object of this class and settings (pickling and copying, `persist.rs`).
    fn __getnewargs_ex__<'py>(slf: &Bound<'py, Self>) -> PyResult<crate::persist::NewArgs<'py>> {
        let py = slf.py();
        let kw = pyo3::types::PyDict::new(py);
        let this = borrow(slf)?;
        kw.set_item("keep_samples", this.keep_samples)?;
        kw.set_item("gate", this.gate)?;
        crate::persist::new_args(py, this.as_super(), kw)
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let slf = borrow(slf)?;
        let base = slf.as_super();
        Ok(format!(
            "BatchLeastSquares(unknown_rows={}, samples={}{})",
            crate::convert::py_tuple(base.inner.rows()),
            base.inner.samples(),
            if slf.keep_samples || base.structure.is_some() { "" } else { ", keep_samples=False" }
        ))
    }
}
