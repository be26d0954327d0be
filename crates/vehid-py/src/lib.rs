//! Python bindings for vehid-core: the `vehid._vehid` extension module.
//!
//! A thin layer: arguments are converted and checked for shape here, everything else
//! (domains, numerics) is the core's, and every core `Error` becomes a `VehidError` (a
//! `ValueError`) carrying the core's message, which names the argument. Sizes known only at
//! run time reach the const-generic core through the dispatch tables in [`dispatch`].

use pyo3::prelude::*;

mod args;
mod convert;
mod drive;
mod full;
mod guard;
mod health;
mod identify;
mod joint_ekf;
mod model;
mod noisy;
mod persist;
mod realistic;
mod reproduce;
mod road;
mod sim;
mod stats;
mod structure;
mod two_axle;

pyo3::create_exception!(
    vehid,
    VehidError,
    pyo3::exceptions::PyValueError,
    "A value passed to vehid is invalid (wrong shape, non-finite, out of its domain) or a \
     computation cannot be done on it (e.g. an unstable model has no stationary variance). \
     Subclass of ValueError; the message names the argument."
);

/// Maps a core error to `VehidError` with the core's message.
pub(crate) fn core_err(e: vehid_core::Error) -> PyErr {
    VehidError::new_err(e.to_string())
}

/// Parses an option string (`mode=`, `method=`, `gain=`, …) with the core's `FromStr`: the
/// message names the argument, lists the choices and repeats what was given.
pub(crate) fn option<T: core::str::FromStr<Err = vehid_core::Error>>(value: &str) -> PyResult<T> {
    value.parse::<T>().map_err(|e| VehidError::new_err(format!("{e} (got {value:?})")))
}

/// Eq 3.17 / 6.10: ξ = Σ ((θ − θ̂)/θ)² over the entries whose true value is non-zero.
/// `theta` and `theta_hat` are arrays of the same shape. A non-finite estimate gives inf.
#[pyfunction]
fn xi(theta: &Bound<'_, PyAny>, theta_hat: &Bound<'_, PyAny>) -> PyResult<f64> {
    let t = convert::array(theta, "theta")?;
    let h = convert::array(theta_hat, "theta_hat")?;
    if t.shape != h.shape {
        return Err(VehidError::new_err(format!(
            "`theta_hat` has shape {} but `theta` has shape {}: they must match",
            convert::shape_str(&h.shape),
            convert::shape_str(&t.shape)
        )));
    }
    vehid_core::metrics::xi(&t.data, &h.data).map_err(core_err)
}

/// Eq 4.31: signal-to-noise ratio 20 log10(signal_std / noise_std) in dB. Scalars give a
/// float; arrays (or an array and a scalar) give an array of the array's shape.
#[pyfunction]
fn snr_db<'py>(
    py: Python<'py>,
    signal_std: &Bound<'py, PyAny>,
    noise_std: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    use numpy::IntoPyArray;
    let s = convert::array(signal_std, "signal_std")?;
    let n = convert::array(noise_std, "noise_std")?;
    let shape = if s.shape == n.shape || n.shape.is_empty() {
        s.shape.clone()
    } else if s.shape.is_empty() {
        n.shape.clone()
    } else {
        return Err(VehidError::new_err(format!(
            "`noise_std` has shape {} but `signal_std` has shape {}: pass equal shapes or a scalar",
            convert::shape_str(&n.shape),
            convert::shape_str(&s.shape)
        )));
    };
    if s.data.is_empty() || n.data.is_empty() {
        // Empty arrays: an empty result of the array's shape.
        let arr = numpy::ndarray::ArrayD::<f64>::zeros(shape);
        return Ok(arr.into_pyarray(py).into_any());
    }
    let len = s.data.len().max(n.data.len());
    let pick = |v: &[f64], i: usize| if v.len() == 1 { v[0] } else { v[i] };
    let out = (0..len)
        .map(|i| vehid_core::metrics::snr_db(pick(&s.data, i), pick(&n.data, i)))
        .collect::<vehid_core::Result<Vec<f64>>>()
        .map_err(core_err)?;
    if shape.is_empty() {
        return Ok(out[0].into_pyobject(py)?.into_any());
    }
    let arr = numpy::ndarray::ArrayD::from_shape_vec(shape, out)
        .map_err(|e| VehidError::new_err(format!("internal shape error: {e}")))?;
    Ok(arr.into_pyarray(py).into_any())
}

/// vehid's compiled core: models, simulator, identifiers, metrics.
#[pymodule]
fn _vehid(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("VehidError", m.py().get_type::<VehidError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // What the classes use when a caller does not say (`vehid_runtime::defaults`), for the
    // command line's options to show and pass the same values.
    m.add("DEFAULT_ROAD_SIGMA", vehid_runtime::defaults::ROAD_SIGMA)?;
    m.add("DEFAULT_DERIV_NOISE", vehid_runtime::defaults::DERIV_NOISE)?;
    m.add("DEFAULT_GATE", vehid_runtime::defaults::GATE)?;
    m.add_class::<model::PyLinearModel>()?;
    m.add_class::<model::PyQuarterCar>()?;
    m.add_class::<model::PyHalfCar>()?;
    m.add_class::<full::PyFullCar>()?;
    m.add_function(wrap_pyfunction!(full::full_car_from_constants, m)?)?;
    m.add_class::<sim::PySimulator>()?;
    m.add_class::<sim::PyRun>()?;
    m.add_class::<identify::PyIdentifier>()?;
    m.add_class::<identify::PyKalmanIdentifier>()?;
    m.add_class::<identify::PyStochasticGradient>()?;
    m.add_class::<identify::PyBatchLeastSquares>()?;
    m.add_class::<two_axle::PyTwoAxleIdentifier>()?;
    m.add_class::<noisy::PyIVIdentifier>()?;
    m.add_class::<noisy::PyBiasCompensated>()?;
    m.add_class::<joint_ekf::PyJointEKF>()?;
    m.add_class::<two_axle::PyAxleSampler>()?;
    m.add_class::<structure::PyStructure>()?;
    m.add_class::<stats::PyStats>()?;
    m.add_class::<health::PyHealthMonitor>()?;
    m.add_class::<health::PyEvent>()?;
    m.add_class::<realistic::PyRealisticIdentifier>()?;
    m.add_function(wrap_pyfunction!(structure::_physical_structure, m)?)?;
    m.add_function(wrap_pyfunction!(structure::validate, m)?)?;
    m.add_function(wrap_pyfunction!(xi, m)?)?;
    m.add_function(wrap_pyfunction!(stats::ljung_box, m)?)?;
    m.add_function(wrap_pyfunction!(stats::ccf, m)?)?;
    m.add_function(wrap_pyfunction!(stats::recursive_residuals, m)?)?;
    m.add_function(wrap_pyfunction!(stats::cusum, m)?)?;
    m.add_function(wrap_pyfunction!(snr_db, m)?)?;
    m.add_function(wrap_pyfunction!(reproduce::reproduce_report, m)?)?;
    Ok(())
}
