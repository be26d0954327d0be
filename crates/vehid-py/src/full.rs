//! `FullCar`: the Python class of the core's `model::FullCar` (the 7-DOF full car), and the
//! full car's arms of the `LinearModel` methods (`physical`, pickling, `repr`).

use crate::model::{Kind, PyLinearModel};
use crate::{core_err, VehidError};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use vehid_core::model::{FullCar, FULL_CONSTANTS};
use vehid_core::nalgebra::SMatrix;
use vehid_runtime::ModelData;

/// The full car (heave, pitch, roll of the body; four wheel hops): 14 states
/// `[z_fl, v_fl, z_fr, v_fr, z_rl, v_rl, z_rr, v_rr, zb, vb, pitch, pitch_rate, roll,
/// roll_rate]` (m, m/s, rad, rad/s; pitch nose up, roll left side up), inputs the road under
/// each wheel `[fl, fr, rl, rr]` (m), unknown rows (1, 3, ..., 13).
///
/// `FullCar(**constants)`: any of the 25 constants by name, the rest from the symmetric
/// default car (`FullCar()`): body `M` (kg), `Jx` (roll, kg m²), `Jy` (pitch, kg m²); per
/// corner (suffix `_fl`, `_fr`, `_rl`, `_rr`) `kt_` (tyre, N/m), `k_` (spring, N/m), `b_`
/// (damper, N s/m), `m_` (unsprung mass, kg); geometry `l_f`, `l_r` (centre of mass to the
/// front and rear axle, m), `track_f`, `track_r` (track widths, m); anti-roll bars `arb_f`,
/// `arb_r` (roll stiffness, N m/rad, 0 for none). Rust `vehid_core::model::FullCar`.
#[pyclass(name = "FullCar", module = "vehid._vehid", extends = PyLinearModel, frozen)]
pub struct PyFullCar;

/// The car with `constants` (a dict of names to numbers) over the default's.
fn car_from_kwargs(constants: Option<&Bound<'_, PyDict>>) -> PyResult<FullCar<f64>> {
    let mut c = FullCar::<f64>::default().constants();
    if let Some(kw) = constants {
        for (k, v) in kw.iter() {
            let key: String = k.extract().map_err(|_| PyTypeError::new_err("FullCar() keywords must be strings"))?;
            let Some(i) = FullCar::<f64>::CONSTANTS.iter().position(|n| *n == key) else {
                return Err(PyTypeError::new_err(format!(
                    "FullCar() got an unexpected keyword argument '{key}' (constants: {})",
                    FullCar::<f64>::CONSTANTS.join(", ")
                )));
            };
            c[i] = v.extract().map_err(|_| VehidError::new_err(format!("`{key}` must be a number")))?;
        }
    }
    FullCar::from_constants(c).map_err(core_err)
}

/// A `FullCar` Python object of `car`.
pub(crate) fn full_initializer(car: FullCar<f64>) -> PyResult<PyClassInitializer<PyFullCar>> {
    let data = ModelData::from_core(&car.model());
    if data.a.iter().chain(&data.b).any(|v| !v.is_finite()) {
        return Err(VehidError::new_err(
            "the constants give a non-finite A or B: a mass or inertia is too small for its springs",
        ));
    }
    Ok(PyClassInitializer::from(PyLinearModel::new_core(data, Kind::Full(car))).add_subclass(PyFullCar))
}

#[pymethods]
impl PyFullCar {
    #[new]
    #[pyo3(signature = (**constants))]
    fn py_new(constants: Option<&Bound<'_, PyDict>>) -> PyResult<PyClassInitializer<Self>> {
        full_initializer(car_from_kwargs(constants)?)
    }

    /// A passenger car after Ikenaga, Lewis, Campos & Davis (American Control Conference
    /// 2000): M = 1500 kg, Jx = 460 kg m², Jy = 2160 kg m², l_f = 1.4 m, l_r = 1.7 m, springs
    /// 35 kN/m front and 38 kN/m rear, dampers 1000 N s/m, unsprung masses 59 kg, tyres
    /// 190 kN/m; tracks 1.5 m (ours); no anti-roll bars (Rust `FullCar::passenger()`).
    #[classmethod]
    fn passenger<'py>(cls: &Bound<'py, pyo3::types::PyType>) -> PyResult<Bound<'py, PyAny>> {
        let kwargs = PyDict::new(cls.py());
        for (k, v) in FullCar::<f64>::passenger().params().named() {
            kwargs.set_item(k, v)?;
        }
        cls.call((), Some(&kwargs))
    }

    /// The 25 physical constants by name (`FullCar.CONSTANTS` order).
    #[getter]
    fn params<'py>(slf: PyRef<'py, Self>, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        if let Kind::Full(c) = slf.as_super().kind {
            for (k, v) in c.params().named() {
                out.set_item(k, v)?;
            }
        }
        Ok(out)
    }

    /// Wheelbase l_f + l_r, m.
    #[getter]
    fn wheelbase(slf: PyRef<'_, Self>) -> f64 {
        match slf.as_super().kind {
            Kind::Full(c) => c.wheelbase(),
            _ => f64::NAN,
        }
    }

    /// The constants' names in order.
    #[classattr]
    #[allow(non_snake_case)]
    fn CONSTANTS() -> Vec<&'static str> {
        FullCar::<f64>::CONSTANTS.to_vec()
    }
}

/// `FullCar.physical(theta_hat, m_fl=, m_fr=, m_rl=, m_rr=)`: the constants from identified
/// rows (`FullCar::from_theta`; the tyres from the model's B, the geometry the model's).
pub(crate) fn physical_full(
    car: &FullCar<f64>,
    data: &ModelData,
    th: &[f64],
    get: &dyn Fn(&str) -> Option<f64>,
    out: &Bound<'_, PyDict>,
) -> PyResult<()> {
    let names = ["m_fl", "m_fr", "m_rl", "m_rr"];
    let mut m = [0.0; 4];
    for (mi, name) in m.iter_mut().zip(names) {
        *mi = get(name).ok_or_else(|| {
            VehidError::new_err("FullCar.physical() needs the four wheel masses: m_fl=, m_fr=, m_rl=, m_rr= (kg)")
        })?;
    }
    let theta = SMatrix::<f64, 7, 14>::from_fn(|i, j| th[i * 14 + j]);
    let b_in = [0, 1, 2, 3].map(|i| data.b[(2 * i + 1) * data.m + i]);
    let p = car.params();
    let est = FullCar::from_theta(&theta, m, b_in, [p.l_f, p.l_r, p.track_f, p.track_r]).map_err(core_err)?;
    for (k, v) in est.params().named() {
        out.set_item(k, v)?;
    }
    Ok(())
}

/// The keyword names `physical()` accepts for the full car.
pub(crate) const PHYSICAL_KEYS: [&str; 4] = ["m_fl", "m_fr", "m_rl", "m_rr"];

/// Pickling: `(FullCar._from_constants, (constants,))`.
pub(crate) fn reduce_args<'py>(py: Python<'py>, car: &FullCar<f64>) -> PyResult<Bound<'py, PyTuple>> {
    PyTuple::new(py, car.constants())
}

/// `FullCar(M=..., ...)` with every constant.
pub(crate) fn repr(car: &FullCar<f64>) -> String {
    let parts: Vec<String> = car.params().named().iter().map(|(k, v)| format!("{k}={v:?}")).collect();
    format!("FullCar({})", parts.join(", "))
}

/// The unpickler: a `FullCar` from its 25 constants in order.
#[pyfunction]
#[pyo3(name = "_full_car_from_constants")]
pub fn full_car_from_constants(py: Python<'_>, constants: Vec<f64>) -> PyResult<Py<PyFullCar>> {
    let c: [f64; FULL_CONSTANTS] =
        constants.try_into().map_err(|_| VehidError::new_err(format!("a FullCar has {FULL_CONSTANTS} constants")))?;
    let car = FullCar::from_constants(c).map_err(core_err)?;
    Py::new(py, full_initializer(car)?)
}

/// `FullCar.physical(stats, m_fl=, m_fr=, m_rl=, m_rr=)`: the constants with their intervals at
/// the Stats' level (`FullCar::from_theta_se`, the delta method on the rows' covariance; the
/// t quantile at the smallest residual degrees of freedom); known constants as
/// `(value, value, value)`.
pub(crate) fn physical_full_stats<'py>(
    py: Python<'py>,
    car: &FullCar<f64>,
    data: &ModelData,
    st: &crate::stats::PyStats,
    known: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    use vehid_core::model::FULL_STATES;
    if st.names == crate::realistic::corner_names(4) {
        return physical_corners(py, car, st, known);
    }
    let n = 7 * FULL_STATES;
    if st.s.params.len() != n || st.s.cov.len() != n * n {
        return Err(VehidError::new_err(format!(
            "these stats have {} parameters; FullCar.physical() reads the {n} entries of the seven identified rows \
             (stats of an identifier on the FullCar itself)",
            st.s.params.len()
        )));
    }
    let m = wheel_masses(known)?;
    let theta = SMatrix::<f64, 7, 14>::from_row_slice(&st.s.params);
    let b_in = [0, 1, 2, 3].map(|i| data.b[(2 * i + 1) * data.m + i]);
    let p = car.params();
    let (est, se) =
        FullCar::from_theta_se(&theta, &st.s.cov, m, b_in, [p.l_f, p.l_r, p.track_f, p.track_r]).map_err(core_err)?;
    let q = vehid_core::stats::t_interval_factor(st.s.alpha, &st.s.df).map_err(core_err)?;
    let out = PyDict::new(py);
    for ((k, v), s) in est.params().named().iter().zip(se) {
        out.set_item(*k, (*v, v - q * s, v + q * s))?;
    }
    Ok(out)
}

/// `FullCar.physical(stats, M=...)` on the stats of `RealisticIdentifier(full)`: the body mass
/// given, the constants the four body-corner equations determine (`model::CORNER_DETERMINED`:
/// inertias, springs, dampers, anti-roll bars) with intervals at the stats' level
/// (`FullCar::from_corner_coefficients`: a weighted fit, its sandwich covariance; a bar's
/// estimate as fitted, below 0 on a car without one when its scatter says so), and `M` as
/// (value, value, value); the tyres and the wheel masses are not determined by these sensors
/// and are left out.
fn physical_corners<'py>(
    py: Python<'py>,
    car: &FullCar<f64>,
    st: &crate::stats::PyStats,
    known: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let m_body = body_mass_keyword(known)?;
    let (_, values, se) = car.from_corner_coefficients(&st.s.params, &st.s.cov, m_body).map_err(core_err)?;
    let q = vehid_core::stats::t_interval_factor(st.s.alpha, &st.s.df).map_err(core_err)?;
    let out = PyDict::new(py);
    out.set_item("M", (m_body, m_body, m_body))?;
    for ((name, v), s) in vehid_core::model::CORNER_DETERMINED.iter().zip(values).zip(se) {
        out.set_item(*name, (v, v - q * s, v + q * s))?;
    }
    Ok(out)
}

/// The body mass `M=` of `physical()` on the corner equations' stats (the only keyword).
pub(crate) fn body_mass_keyword(known: Option<&Bound<'_, PyDict>>) -> PyResult<f64> {
    let mut m_body = None;
    if let Some(kw) = known {
        for (k, v) in kw.iter() {
            let key: String = k.extract()?;
            if key != "M" {
                return Err(PyTypeError::new_err(format!(
                    "physical() got an unexpected keyword argument '{key}' (the corner equations' stats take the \
                     body mass only: M=)"
                )));
            }
            m_body = Some(v.extract::<f64>().map_err(|_| VehidError::new_err("`M` must be a number (a mass in kg)"))?);
        }
    }
    m_body.ok_or_else(|| {
        VehidError::new_err(
            "physical() on the corner equations needs the body mass M= (kg): the realistic sensors determine the \
             springs, dampers and inertias only relative to it",
        )
    })
}

/// The four wheel masses from `physical()`'s keywords (each required; no other keyword).
fn wheel_masses(known: Option<&Bound<'_, PyDict>>) -> PyResult<[f64; 4]> {
    let mut m = [f64::NAN; 4];
    if let Some(kw) = known {
        for (k, v) in kw.iter() {
            let key: String = k.extract()?;
            let Some(i) = PHYSICAL_KEYS.iter().position(|n| *n == key) else {
                return Err(PyTypeError::new_err(format!(
                    "physical() got an unexpected keyword argument '{key}' (known quantities: {})",
                    PHYSICAL_KEYS.join(", ")
                )));
            };
            m[i] = v.extract().map_err(|_| VehidError::new_err(format!("`{key}` must be a number (a mass in kg)")))?;
        }
    }
    if m.iter().any(|v| v.is_nan()) {
        return Err(VehidError::new_err(
            "FullCar.physical() needs the four wheel masses: m_fl=, m_fr=, m_rl=, m_rr= (kg)",
        ));
    }
    Ok(m)
}
