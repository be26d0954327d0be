//! `LinearModel`, `QuarterCar`, `HalfCar`: the Python model classes (`FullCar`: `full.rs`).

use crate::convert::{array, finite, matrix, shape_str, size, values};
use crate::{core_err, option, VehidError};
use numpy::ndarray::Array2;
use numpy::{Complex64, IntoPyArray, PyArray1, PyArray2};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::pyclass::CompareOp;
use pyo3::types::{PyDict, PyTuple};
use vehid_core::model::{FullCar, HalfCar, HalfCarParams, QuarterCar, QuarterKnown};
use vehid_core::nalgebra::SMatrix;
use vehid_runtime::sizes::{MAX_INPUTS, MAX_STATES};
use vehid_runtime::ModelData;

/// Which vehicle a model came from: decides what `physical()` can recover.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    Generic,
    Quarter(QuarterCar<f64>),
    Half(HalfCar<f64>),
    Full(FullCar<f64>),
}

/// A continuous-time linear model `ẋ = A x + B u` (Eq 2.1) with 1..16 states and 1..4 inputs,
/// and the rows of `A` to identify.
///
/// `a` is (n, n), `b` is (n, m) (a 1-D `b` of length n is one input), `unknown_rows` are
/// 0-based row indices. Entries of the unknown rows that are exactly zero in `a` are taken as
/// structurally zero (left out of ξ); `structural_zeros=[(row, col), ...]` overrides that.
#[pyclass(name = "LinearModel", module = "vehid._vehid", subclass, frozen)]
pub struct PyLinearModel {
    pub data: ModelData,
    pub kind: Kind,
}

fn to_array1<'py, T: numpy::Element>(py: Python<'py>, v: Vec<T>) -> Bound<'py, PyArray1<T>> {
    v.into_pyarray(py)
}

pub(crate) fn to_array2<'py>(
    py: Python<'py>,
    rows: usize,
    cols: usize,
    v: Vec<f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    Array2::from_shape_vec((rows, cols), v)
        .map(|a| a.into_pyarray(py))
        .map_err(|e| VehidError::new_err(format!("internal shape error: {e}")))
}

fn rows_arg(v: Vec<i128>, arg: &str) -> PyResult<Vec<usize>> {
    v.into_iter()
        .map(|r| {
            usize::try_from(r)
                .map_err(|_| VehidError::new_err(format!("`{arg}` names row {r}, but rows must be 0-based (>= 0)")))
        })
        .collect()
}

impl PyLinearModel {
    pub fn new_core(data: ModelData, kind: Kind) -> Self {
        Self { data, kind }
    }

    /// Eq 4.7 per-row variances for already converted noise levels.
    pub(crate) fn row_noise_var_vec(&self, road: &[f64], deriv: &[f64]) -> PyResult<Vec<f64>> {
        let d = &self.data;
        d.row_noise_var(road, deriv).map_err(core_err)
    }

    fn theta_hat_arg(&self, theta_hat: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
        let (k, n) = (self.data.rows.len(), self.data.n);
        let (_, _, v) = matrix(theta_hat, "theta_hat", Some(k), Some(n))?;
        finite("theta_hat", &v)?;
        Ok(v)
    }

    fn sampled_cov_vec(
        &self,
        py: Python<'_>,
        road_sigma: Option<&Bound<'_, PyAny>>,
        dt: f64,
        method: &str,
        substeps: Option<i128>,
    ) -> PyResult<Vec<f64>> {
        let road = values(road_sigma, "road_sigma", vehid_runtime::defaults::ROAD_SIGMA)?;
        let method: vehid_core::sim::Method = option(method)?;
        let substeps = substeps.map(|s| size(s, "substeps")).transpose()?;
        let d = &self.data;
        py.detach(|| d.sampled_cov(&road, dt, method, substeps)).map_err(core_err)
    }
}

#[pymethods]
impl PyLinearModel {
    #[new]
    #[pyo3(signature = (a, b, unknown_rows, structural_zeros = None))]
    fn py_new(
        a: &Bound<'_, PyAny>,
        b: &Bound<'_, PyAny>,
        unknown_rows: Vec<i128>,
        structural_zeros: Option<Vec<(i128, i128)>>,
    ) -> PyResult<Self> {
        let am = array(a, "a")?;
        let n = match am.shape[..] {
            [r, c] if r == c && (1..=MAX_STATES).contains(&r) => r,
            _ => {
                return Err(VehidError::new_err(format!(
                    "`a` must be a square (n, n) array with 1 <= n <= {MAX_STATES}, got shape {}",
                    shape_str(&am.shape)
                )))
            }
        };
        let bm = array(b, "b")?;
        let m = match bm.shape[..] {
            [r] if r == n => 1,
            [r, c] if r == n && (1..=MAX_INPUTS).contains(&c) => c,
            _ => {
                return Err(VehidError::new_err(format!(
                    "`b` must have shape ({n}, m) with 1 <= m <= {MAX_INPUTS} (or ({n},) for one input), got {}",
                    shape_str(&bm.shape)
                )))
            }
        };
        let rows = rows_arg(unknown_rows, "unknown_rows")?;
        let zeros = structural_zeros
            .map(|z| {
                z.into_iter()
                    .map(|(r, c)| Ok((size(r, "structural_zeros")?, size(c, "structural_zeros")?)))
                    .collect::<PyResult<Vec<_>>>()
            })
            .transpose()?;
        let data = ModelData::new(n, m, &am.data, &bm.data, &rows, zeros.as_deref()).map_err(core_err)?;
        Ok(Self::new_core(data, Kind::Generic))
    }

    /// Number of states n.
    #[getter]
    fn n_states(&self) -> usize {
        self.data.n
    }

    /// Number of inputs m.
    #[getter]
    fn n_inputs(&self) -> usize {
        self.data.m
    }

    /// The state matrix A, (n, n) (a copy).
    #[getter]
    fn a<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        to_array2(py, self.data.n, self.data.n, self.data.a.clone())
    }

    /// The input matrix B, (n, m) (a copy).
    #[getter]
    fn b<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        to_array2(py, self.data.n, self.data.m, self.data.b.clone())
    }

    /// The unknown rows of A (0-based, ascending).
    #[getter]
    fn unknown_rows<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, &self.data.rows)
    }

    /// The true unknown rows of A, (len(unknown_rows), n).
    #[getter]
    fn theta<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let d = &self.data;
        let v = d.theta().map_err(core_err)?;
        to_array2(py, d.rows.len(), d.n, v)
    }

    /// Which entries of the unknown rows are structurally zero, bool (len(unknown_rows), n).
    #[getter]
    fn structural_zeros<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<bool>>> {
        let d = &self.data;
        let v: Vec<bool> = d.rows.iter().flat_map(|&r| (0..d.n).map(move |c| d.zeros.contains(&(r, c)))).collect();
        Array2::from_shape_vec((d.rows.len(), d.n), v)
            .map(|a| a.into_pyarray(py))
            .map_err(|e| VehidError::new_err(format!("internal shape error: {e}")))
    }

    /// The poles (eigenvalues of A), (n,) complex128, sorted by real then imaginary part.
    fn poles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<Complex64>>> {
        let d = &self.data;
        let v = py.detach(|| d.poles()).map_err(core_err)?;
        Ok(to_array1(py, v.into_iter().map(|(re, im)| Complex64::new(re, im)).collect()))
    }

    /// Eq 4.27: standard deviation of each state (continuous time, every instant alike) under
    /// road noise of standard deviation `road_sigma` (scalar or one per input) held for
    /// `hold` seconds. (n,).
    #[pyo3(signature = (road_sigma = None, hold = 0.05), text_signature = "(self, road_sigma=1.0, hold=0.05)")]
    fn output_std<'py>(
        &self,
        py: Python<'py>,
        road_sigma: Option<&Bound<'py, PyAny>>,
        #[pyo3(from_py_with = crate::args::hold)] hold: f64,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let road = values(road_sigma, "road_sigma", 1.0)?;
        let d = &self.data;
        // A long hold on a large model takes seconds: GIL released.
        let v = py.detach(|| d.output_std(&road, hold)).map_err(core_err)?;
        Ok(to_array1(py, v))
    }

    /// Diagonal of R_v + B R_u Bᵀ on the unknown rows (Eq 4.7), (len(unknown_rows),).
    /// `road_sigma`: scalar or one per input; `deriv_noise`: scalar or one per state.
    #[pyo3(
        signature = (road_sigma = None, deriv_noise = None),
        text_signature = "(self, road_sigma=0.1, deriv_noise=0.005)"
    )]
    fn row_noise_var<'py>(
        &self,
        py: Python<'py>,
        road_sigma: Option<&Bound<'py, PyAny>>,
        deriv_noise: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let road = values(road_sigma, "road_sigma", vehid_runtime::defaults::ROAD_SIGMA)?;
        let deriv = values(deriv_noise, "deriv_noise", vehid_runtime::defaults::DERIV_NOISE)?;
        let d = &self.data;
        let v = py.detach(|| d.row_noise_var(&road, &deriv)).map_err(core_err)?;
        Ok(to_array1(py, v))
    }

    /// Stationary covariance (n, n) of the state at the sample instants of the discretized
    /// system `x(k+1) = Φ x(k) + Γ u(k)` that `Simulator` steps (`method` "rk4" or "exact",
    /// `substeps` as for `Simulator`).
    #[pyo3(
        signature = (road_sigma = None, dt = 0.05, method = "rk4", substeps = None),
        text_signature = "(self, road_sigma=0.1, dt=0.05, method='rk4', substeps=None)"
    )]
    fn sampled_cov<'py>(
        &self,
        py: Python<'py>,
        road_sigma: Option<&Bound<'py, PyAny>>,
        dt: f64,
        method: &str,
        substeps: Option<i128>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let v = self.sampled_cov_vec(py, road_sigma, dt, method, substeps)?;
        to_array2(py, self.data.n, self.data.n, v)
    }

    /// Standard deviation (n,) of each state at the sample instants (square root of the
    /// diagonal of `sampled_cov`): what a long simulation's `run.x.std(axis=0)` estimates.
    #[pyo3(
        signature = (road_sigma = None, dt = 0.05, method = "rk4", substeps = None),
        text_signature = "(self, road_sigma=0.1, dt=0.05, method='rk4', substeps=None)"
    )]
    fn sampled_std<'py>(
        &self,
        py: Python<'py>,
        road_sigma: Option<&Bound<'py, PyAny>>,
        dt: f64,
        method: &str,
        substeps: Option<i128>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let n = self.data.n;
        let v = self.sampled_cov_vec(py, road_sigma, dt, method, substeps)?;
        Ok(to_array1(py, (0..n).map(|i| v[i * n + i].max(0.0).sqrt()).collect()))
    }

    /// `Â`: A with its unknown rows replaced by `theta_hat` (len(unknown_rows), n). (n, n).
    fn a_hat<'py>(&self, py: Python<'py>, theta_hat: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let th = self.theta_hat_arg(theta_hat)?;
        let d = &self.data;
        let v = d.a_hat(&th).map_err(core_err)?;
        to_array2(py, d.n, d.n, v)
    }

    /// The car's physical structure as a `vehid.Structure`, with the constants in `known`
    /// (e.g. {"m": 1.0}) fixed: its parameters are the unknown constants and their ratios
    /// (QuarterCar with m known: "k2/M", "b/M", "M", "k1"; the body equation in ratio form,
    /// the wheel's in momentum form through der(x4)), states x1..xn. HalfCar needs l1 and l2
    /// known (they enter the pitch lever arms).
    ///
    /// `sensors="realistic"` (QuarterCar): the body equation the realistic sensors determine,
    /// `dvb/dt = -(k2/M) d - (b/M) v + offset`, states `d, v, vb` (deflection, its rate, the
    /// body's velocity): parameters k2/M, b/M, offset (k2, b, offset with M known); m and k1 are
    /// not determined (`not_identifiable` says why). Fit it with `RealisticIdentifier`.
    #[pyo3(signature = (known = None, sensors = "state"))]
    fn structure(&self, known: Option<&Bound<'_, PyAny>>, sensors: &str) -> PyResult<crate::structure::PyStructure> {
        use crate::structure::{CarKind, PyStructure};
        let car = match self.kind {
            Kind::Quarter(_) => CarKind::Quarter,
            Kind::Half(_) => CarKind::Half,
            Kind::Full(_) => {
                return Err(VehidError::new_err(
                    "the full car has no physical structure yet (its body equations need more terms than a \
                     vehid.Structure holds): identify its rows (model.unknown_rows; on a road that is not white, \
                     TwoAxleIdentifier(full, spacing=...)) and read the constants with FullCar.physical(theta_hat, \
                     m_fl=, m_fr=, m_rl=, m_rr=); from the realistic sensors, RealisticIdentifier(full, dt) and \
                     FullCar.physical(stats, M=...)",
                ))
            }
            Kind::Generic => {
                return Err(VehidError::new_err(
                    "a generic LinearModel has no physical structure: write one with vehid.Structure(...)",
                ))
            }
        };
        PyStructure::physical(car, known, crate::structure::sensors_arg(sensors)?)
    }

    /// Physical constants from identified rows `theta_hat` (len(unknown_rows), n).
    ///
    /// QuarterCar: one known mass, `m=` (wheel, the thesis' choice) or `M=` (body) ->
    /// {"M", "m", "k1", "k2", "b"}. HalfCar: `m1=` and `m2=` (wheel masses); the tyre
    /// stiffnesses come from the model's B -> all 12 constants. A generic LinearModel has no
    /// physical constants.
    ///
    /// Given a `Stats` (from an identifier on `car.structure(known=...)`) instead of rows:
    /// {constant: (value, low, high)} with the interval at the Stats' level by the delta
    /// method (exact when the constant is linear in the parameters); known constants appear
    /// as (value, value, value); `known` defaults to the structure's.
    #[pyo3(signature = (theta_hat, **known))]
    fn physical<'py>(
        &self,
        py: Python<'py>,
        theta_hat: &Bound<'py, PyAny>,
        known: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        if let (Ok(st), Kind::Full(car)) = (theta_hat.cast::<crate::stats::PyStats>(), self.kind) {
            return crate::full::physical_full_stats(py, &car, &self.data, st.get(), known);
        }
        if let (Ok(st), Kind::Half(car)) = (theta_hat.cast::<crate::stats::PyStats>(), self.kind) {
            if st.get().names == crate::realistic::corner_names(2) {
                return crate::realistic::physical_half_corners(py, &car, st.get(), known);
            }
        }
        if let (Ok(st), Kind::Quarter(_) | Kind::Half(_)) = (theta_hat.cast::<crate::stats::PyStats>(), self.kind) {
            let car = match self.kind {
                Kind::Quarter(_) => crate::structure::CarKind::Quarter,
                _ => crate::structure::CarKind::Half,
            };
            return crate::stats::physical_from_stats(py, car, st.get(), known);
        }
        let allowed: &[&str] = match self.kind {
            Kind::Generic => {
                return Err(VehidError::new_err(
                    "physical constants are undefined for a generic LinearModel: only QuarterCar and \
                     HalfCar know how their rows of A are made of masses, stiffnesses and dampings",
                ))
            }
            Kind::Quarter(_) => &["m", "M"],
            Kind::Half(_) => &["m1", "m2"],
            Kind::Full(_) => &crate::full::PHYSICAL_KEYS,
        };
        let mut given: Vec<(String, f64)> = Vec::new();
        if let Some(kw) = known {
            for (k, v) in kw.iter() {
                let key: String = k.extract()?;
                if !allowed.contains(&key.as_str()) {
                    return Err(PyTypeError::new_err(format!(
                        "physical() got an unexpected keyword argument '{key}' (known quantities: {})",
                        allowed.join(", ")
                    )));
                }
                let val: f64 =
                    v.extract().map_err(|_| VehidError::new_err(format!("`{key}` must be a number (a mass in kg)")))?;
                given.push((key, val));
            }
        }
        let th = self.theta_hat_arg(theta_hat)?;
        let get = |name: &str| given.iter().find(|(k, _)| k == name).map(|(_, v)| *v);
        let out = PyDict::new(py);
        match self.kind {
            Kind::Generic => {}
            Kind::Quarter(_) => {
                let known = match (get("m"), get("M")) {
                    (Some(m), None) => QuarterKnown::WheelMass(m),
                    (None, Some(mb)) => QuarterKnown::BodyMass(mb),
                    _ => {
                        return Err(VehidError::new_err(
                            "QuarterCar.physical() needs exactly one known mass: m= (wheel) or M= (body)",
                        ))
                    }
                };
                let theta = SMatrix::<f64, 2, 4>::from_fn(|i, j| th[i * 4 + j]);
                let car = QuarterCar::from_theta(&theta, known).map_err(core_err)?;
                for (k, v) in car.named() {
                    out.set_item(k, v)?;
                }
            }
            Kind::Half(_) => {
                let (Some(m1), Some(m2)) = (get("m1"), get("m2")) else {
                    return Err(VehidError::new_err(
                        "HalfCar.physical() needs both wheel masses: m1= (front) and m2= (rear)",
                    ));
                };
                let theta = SMatrix::<f64, 4, 8>::from_fn(|i, j| th[i * 8 + j]);
                let m = self.data.m;
                let (b21, b42) = (self.data.b[m], self.data.b[3 * m + 1]);
                let car = HalfCar::from_theta(&theta, m1, m2, b21, b42).map_err(core_err)?;
                half_params_into(&out, &car.params())?;
            }
            Kind::Full(car) => crate::full::physical_full(&car, &self.data, &th, &get, &out)?,
        }
        Ok(out)
    }

    /// Pickling (every protocol): the class and its constructor arguments (the physical
    /// constants of QuarterCar and HalfCar; A, B, the rows and the structural zeros otherwise).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let m = slf.get();
        let args = match m.kind {
            Kind::Full(c) => {
                let f = py.import("vehid._vehid")?.getattr("_full_car_from_constants")?;
                let list = crate::full::reduce_args(py, &c)?.to_list();
                return (f, (list,)).into_pyobject(py);
            }
            Kind::Quarter(c) => (c.m_body(), c.m_wheel(), c.k1(), c.k2(), c.b()).into_pyobject(py)?,
            Kind::Half(c) => {
                let p = c.params();
                let v = [p.k11, p.k21, p.k12, p.k22, p.b1, p.b2, p.m1, p.m2, p.m_body, p.j, p.l1, p.l2];
                PyTuple::new(py, v)?
            }
            Kind::Generic => {
                let d = &m.data;
                let rows = |v: &[f64], w: usize| v.chunks(w).map(<[f64]>::to_vec).collect::<Vec<_>>();
                (rows(&d.a, d.n), rows(&d.b, d.m), d.rows.clone(), d.zeros.clone()).into_pyobject(py)?
            }
        };
        (slf.get_type(), args).into_pyobject(py)
    }

    /// Models compare by value: the same class, matrices, unknown rows, structural zeros and
    /// (QuarterCar, HalfCar) physical constants.
    fn __richcmp__(slf: &Bound<'_, Self>, other: &Bound<'_, PyAny>, op: CompareOp) -> PyResult<Py<PyAny>> {
        let py = slf.py();
        let Ok(other) = other.cast::<Self>() else {
            return Ok(py.NotImplemented());
        };
        let same = slf.get_type().is(other.get_type()) && {
            let (a, b) = (slf.get(), other.get());
            a.data == b.data && a.kind == b.kind
        };
        match op {
            CompareOp::Eq => Ok(same.into_pyobject(py)?.to_owned().into_any().unbind()),
            CompareOp::Ne => Ok((!same).into_pyobject(py)?.to_owned().into_any().unbind()),
            _ => Ok(py.NotImplemented()),
        }
    }

    /// Consistent with `==` (-0.0 and 0.0 hash alike).
    fn __hash__(&self) -> u64 {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        let d = &self.data;
        (d.n, d.m, &d.rows, &d.zeros).hash(&mut h);
        for v in d.a.iter().chain(&d.b) {
            (v + 0.0).to_bits().hash(&mut h);
        }
        h.finish()
    }

    fn __repr__(&self) -> String {
        match &self.kind {
            Kind::Generic => format!(
                "LinearModel(n_states={}, n_inputs={}, unknown_rows={})",
                self.data.n,
                self.data.m,
                crate::convert::py_tuple(&self.data.rows)
            ),
            Kind::Quarter(c) => format!(
                "QuarterCar(M={:?}, m={:?}, k1={:?}, k2={:?}, b={:?})",
                c.m_body(),
                c.m_wheel(),
                c.k1(),
                c.k2(),
                c.b()
            ),
            Kind::Full(c) => crate::full::repr(c),
            Kind::Half(c) => {
                let p = c.params();
                format!(
                    "HalfCar(k11={:?}, k21={:?}, k12={:?}, k22={:?}, b1={:?}, b2={:?}, m1={:?}, m2={:?}, \
                     M={:?}, J={:?}, l1={:?}, l2={:?})",
                    p.k11, p.k21, p.k12, p.k22, p.b1, p.b2, p.m1, p.m2, p.m_body, p.j, p.l1, p.l2
                )
            }
        }
    }
}

fn half_params_into(out: &Bound<'_, PyDict>, p: &HalfCarParams<f64>) -> PyResult<()> {
    for (k, v) in p.named() {
        out.set_item(k, v)?;
    }
    Ok(())
}

/// A model built from physical constants must come out finite: a tiny mass or a huge
/// stiffness overflows a ratio such as k/m without an error from the arithmetic. `mass_of`
/// names, for each acceleration row, the constant that divides it.
fn finite_model(d: &ModelData, mass_of: &[(usize, &str)]) -> PyResult<()> {
    let (n, m) = (d.n, d.m);
    for i in 0..n {
        if d.a[i * n..(i + 1) * n].iter().chain(&d.b[i * m..(i + 1) * m]).all(|v| v.is_finite()) {
            continue;
        }
        let mass = mass_of.iter().find(|(r, _)| *r == i).map_or("a mass", |(_, name)| *name);
        return Err(VehidError::new_err(format!(
            "row {i} of A or B overflows (inf): {mass} is too small for the stiffnesses and dampings that act on \
             it, or they are too large; physical constants in SI units (masses well above 1e-300, stiffnesses, \
             dampings and lengths well below 1e300)"
        )));
    }
    Ok(())
}

/// The quarter car of Eq 3.8–3.13: state [x1, ẋ1, x2, ẋ2] (wheel, body), one road input,
/// unknown rows (1, 3). Defaults are the thesis' values.
#[pyclass(name = "QuarterCar", module = "vehid._vehid", extends = PyLinearModel, frozen)]
pub struct PyQuarterCar;

#[pymethods]
impl PyQuarterCar {
    #[new]
    #[pyo3(signature = (M = 10.0, m = 1.0, k1 = 90.0, k2 = 50.0, b = 40.0))]
    #[allow(non_snake_case)]
    fn py_new(
        #[pyo3(from_py_with = crate::args::mass_body)] M: f64,
        #[pyo3(from_py_with = crate::args::mass_wheel)] m: f64,
        #[pyo3(from_py_with = crate::args::k1)] k1: f64,
        #[pyo3(from_py_with = crate::args::k2)] k2: f64,
        #[pyo3(from_py_with = crate::args::b)] b: f64,
    ) -> PyResult<PyClassInitializer<Self>> {
        let car = QuarterCar::new(M, m, k1, k2, b).map_err(core_err)?;
        let data = ModelData::from_core(&car.model());
        finite_model(&data, &[(1, "`m` (the wheel mass)"), (3, "`M` (the body mass)")])?;
        let base = PyLinearModel::new_core(data, Kind::Quarter(car));
        Ok(PyClassInitializer::from(base).add_subclass(Self))
    }

    /// A typical passenger car's corner (Rust `QuarterCar::passenger()`): M = 320 kg,
    /// m = 40 kg, k1 = 200 kN/m, k2 = 22 kN/m, b = 1500 N s/m (body mode 1.32 Hz, wheel hop
    /// 11.9 Hz, body damping ratio 0.28).
    #[classmethod]
    fn passenger<'py>(cls: &Bound<'py, pyo3::types::PyType>) -> PyResult<Bound<'py, PyAny>> {
        let c = QuarterCar::<f64>::passenger();
        cls.call1((c.m_body(), c.m_wheel(), c.k1(), c.k2(), c.b()))
    }

    /// The physical constants {"M", "m", "k1", "k2", "b"}.
    #[getter]
    fn params<'py>(slf: PyRef<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        if let Kind::Quarter(c) = slf.as_super().kind {
            for (k, v) in c.named() {
                out.set_item(k, v)?;
            }
        }
        Ok(out)
    }
}

/// The half car of Eq 6.1–6.8: state [x1, ẋ1, x2, ẋ2, x3, ẋ3, φ, φ̇] (front wheel, rear
/// wheel, body heave, pitch), inputs [u1, u2] (road under each wheel), unknown rows
/// (1, 3, 5, 7). Defaults are the thesis' values.
#[pyclass(name = "HalfCar", module = "vehid._vehid", extends = PyLinearModel, frozen)]
pub struct PyHalfCar;

#[pymethods]
impl PyHalfCar {
    #[new]
    #[pyo3(signature = (k11 = 100.0, k21 = 100.0, k12 = 40.0, k22 = 40.0, b1 = 60.0, b2 = 60.0,
                        m1 = 1.0, m2 = 1.0, M = 20.0, J = 60.0, l1 = 2.0, l2 = 1.0))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn py_new(
        #[pyo3(from_py_with = crate::args::k11)] k11: f64,
        #[pyo3(from_py_with = crate::args::k21)] k21: f64,
        #[pyo3(from_py_with = crate::args::k12)] k12: f64,
        #[pyo3(from_py_with = crate::args::k22)] k22: f64,
        #[pyo3(from_py_with = crate::args::b1)] b1: f64,
        #[pyo3(from_py_with = crate::args::b2)] b2: f64,
        #[pyo3(from_py_with = crate::args::m1)] m1: f64,
        #[pyo3(from_py_with = crate::args::m2)] m2: f64,
        #[pyo3(from_py_with = crate::args::mass_body)] M: f64,
        #[pyo3(from_py_with = crate::args::inertia)] J: f64,
        #[pyo3(from_py_with = crate::args::l1)] l1: f64,
        #[pyo3(from_py_with = crate::args::l2)] l2: f64,
    ) -> PyResult<PyClassInitializer<Self>> {
        let p = HalfCarParams { k11, k21, k12, k22, b1, b2, m1, m2, m_body: M, j: J, l1, l2 };
        let car = HalfCar::new(p).map_err(core_err)?;
        let data = ModelData::from_core(&car.model());
        let masses = [
            (1, "`m1` (the front wheel mass)"),
            (3, "`m2` (the rear wheel mass)"),
            (5, "`M` (the body mass)"),
            (7, "`J` (the pitch inertia)"),
        ];
        finite_model(&data, &masses)?;
        let base = PyLinearModel::new_core(data, Kind::Half(car));
        Ok(PyClassInitializer::from(base).add_subclass(Self))
    }

    /// A typical passenger car, one side of a mid-size sedan (Rust `HalfCar::passenger()`):
    /// M = 640 kg, J = 1040 kg m², l1 = 1.2 m, l2 = 1.5 m, k12 = 24 kN/m, k22 = 22 kN/m,
    /// b1 = 1600 N s/m, b2 = 1400 N s/m, m1 = 40 kg, m2 = 35 kg, k11 = k21 = 200 kN/m (typical
    /// values: corner bounce 1.31 / 1.40 Hz, damping ratios 0.27 / 0.28, dynamic index 0.90).
    #[classmethod]
    fn passenger<'py>(cls: &Bound<'py, pyo3::types::PyType>) -> PyResult<Bound<'py, PyAny>> {
        let kwargs = PyDict::new(cls.py());
        for (k, v) in HalfCar::<f64>::passenger().params().named() {
            kwargs.set_item(k, v)?;
        }
        cls.call((), Some(&kwargs))
    }

    /// The 12 physical constants.
    #[getter]
    fn params<'py>(slf: PyRef<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        if let Kind::Half(c) = slf.as_super().kind {
            half_params_into(&out, &c.params())?;
        }
        Ok(out)
    }

    /// Wheelbase l1 + l2, m.
    #[getter]
    fn wheelbase(slf: PyRef<'_, Self>) -> f64 {
        match slf.as_super().kind {
            Kind::Half(c) => c.wheelbase(),
            _ => f64::NAN,
        }
    }
}
