//! Scalar arguments converted with their name in the message.
//!
//! pyo3 reports a failed conversion (`dt="x"`, `n=2**200`) with the converter's message only
//! (`must be real number, not str`) and names the argument in the exception's `__notes__`,
//! which `str(e)` and most logs do not show; a too large integer raises `OverflowError`, which
//! is not a `ValueError`. The arguments below are extracted with `#[pyo3(from_py_with = …)]`
//! through [`named`]: a wrong type raises `TypeError("`name`: …")`, a value out of the Rust
//! type's range (or any other failed conversion) a `VehidError` (a `ValueError`) naming the
//! argument. Other exceptions (MemoryError, KeyboardInterrupt) pass through.

use crate::VehidError;
use pyo3::exceptions::{PyOverflowError, PyTypeError, PyValueError};
use pyo3::prelude::*;

/// `ob` extracted as `T`, a failed conversion reported with the argument's `name` in the
/// message (see the module documentation).
pub(crate) fn named<'a, 'py, T>(ob: &'a Bound<'py, PyAny>, name: &str) -> PyResult<T>
where
    T: FromPyObject<'a, 'py>,
    T::Error: Into<PyErr>,
{
    ob.extract::<T>().map_err(|e| {
        let e: PyErr = e.into();
        let py = ob.py();
        let msg = e.value(py).str().map(|s| s.to_string()).unwrap_or_default();
        if e.is_instance_of::<PyTypeError>(py) {
            PyTypeError::new_err(format!("`{name}`: {msg}"))
        } else if e.is_instance_of::<PyOverflowError>(py) {
            VehidError::new_err(format!("`{name}` is out of range: {msg}"))
        } else if e.is_instance_of::<PyValueError>(py) {
            VehidError::new_err(format!("`{name}`: {msg}"))
        } else {
            e
        }
    })
}

/// One extractor function per argument name and type, for `from_py_with`.
macro_rules! named_args {
    ($($f:ident: $t:ty = $name:literal;)*) => {
        $(
            #[doc = concat!("Argument `", $name, "` as `", stringify!($t), "` (see [`named`]).")]
            pub(crate) fn $f(ob: &Bound<'_, PyAny>) -> PyResult<$t> {
                named(ob, $name)
            }
        )*
    };
}

named_args! {
    // Simulator
    dt: f64 = "dt";
    ic_sigma: f64 = "ic_sigma";
    seed: i128 = "seed";
    method: String = "method";
    instrumentation: bool = "instrumentation";
    n: i128 = "n";
    // Identifier.fit
    record_every: i128 = "record_every";
    // KalmanIdentifier
    reinit: bool = "reinit";
    mode: String = "mode";
    form: Option<String> = "form";
    joseph: bool = "joseph";
    retire_below: f64 = "retire_below";
    forgetting: f64 = "forgetting";
    drift: f64 = "drift";
    directional: bool = "directional";
    max_trace: Option<f64> = "max_trace";
    gate: Option<f64> = "gate";
    huber: f64 = "huber";
    p0_reset: f64 = "p0";
    // StochasticGradient
    gain: String = "gain";
    p: f64 = "p";
    spacing_int: i128 = "spacing";
    lambda0: f64 = "lambda0";
    lambda_init: f64 = "lambda_init";
    // BatchLeastSquares
    keep_samples: bool = "keep_samples";
    // LinearModel.output_std
    hold: f64 = "hold";
    // QuarterCar, HalfCar
    mass_body: f64 = "M";
    mass_wheel: f64 = "m";
    k1: f64 = "k1";
    k2: f64 = "k2";
    b: f64 = "b";
    k11: f64 = "k11";
    k21: f64 = "k21";
    k12: f64 = "k12";
    k22: f64 = "k22";
    b1: f64 = "b1";
    b2: f64 = "b2";
    m1: f64 = "m1";
    m2: f64 = "m2";
    inertia: f64 = "J";
    l1: f64 = "l1";
    l2: f64 = "l2";
}
