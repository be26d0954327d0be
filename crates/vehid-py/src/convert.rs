//! Python → Rust argument conversion and validation. Nothing numerical happens here: values
//! are converted to `f64` (NumPy's `asarray(x, dtype=float)` semantics, so ints, lists and
//! non-contiguous arrays are accepted), shapes are checked, and every failure becomes a
//! `VehidError` that names the argument.

use crate::VehidError;
use numpy::{
    AllowTypeChange, PyArray2, PyArrayDescrMethods, PyArrayLikeDyn, PyArrayMethods, PyReadonlyArray2,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyMemoryError;
use pyo3::prelude::*;

/// A float64 array copied out of Python, row-major (C order) whatever its strides were.
pub struct Array {
    pub shape: Vec<usize>,
    pub data: Vec<f64>,
}

/// `"(2, 4)"`, the way NumPy prints a shape.
pub fn shape_str(shape: &[usize]) -> String {
    match shape {
        [one] => format!("({one},)"),
        _ => format!("({})", shape.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", ")),
    }
}

/// Refuses complex input (NumPy would silently drop the imaginary part).
fn not_complex(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<()> {
    let complex = if let Ok(a) = obj.cast::<numpy::PyUntypedArray>() {
        a.dtype().kind() == b'c'
    } else {
        obj.is_instance_of::<pyo3::types::PyComplex>()
            || obj.cast::<pyo3::types::PySequence>().is_ok_and(|s| {
                s.try_iter()
                    .is_ok_and(|mut it| it.any(|v| v.is_ok_and(|v| v.is_instance_of::<pyo3::types::PyComplex>())))
            })
    };
    if complex {
        return Err(VehidError::new_err(format!(
            "`{arg}` holds complex numbers: pass real values (e.g. `x.real`, if the imaginary part is negligible)"
        )));
    }
    Ok(())
}

/// Converts any array-like to float64, copying it in row-major order.
pub fn array(obj: &Bound<'_, PyAny>, arg: &str) -> PyResult<Array> {
    not_complex(obj, arg)?;
    let arr: PyArrayLikeDyn<'_, f64, AllowTypeChange> = obj.extract().map_err(|e: PyErr| {
        // NumPy's own MemoryError (converting a huge input) stays a MemoryError.
        if e.is_instance_of::<PyMemoryError>(obj.py()) {
            return e;
        }
        VehidError::new_err(format!("`{arg}` must be a float array or convertible to one: {e}"))
    })?;
    let shape = arr.shape().to_vec();
    // The copy is reserved fallibly: a huge input (e.g. a broadcast view, which takes no
    // memory itself) raises MemoryError instead of aborting the process.
    let len = arr.len();
    let mut data: Vec<f64> = Vec::new();
    data.try_reserve_exact(len).map_err(|_| {
        PyMemoryError::new_err(format!(
            "`{arg}` ({} values) cannot be copied: {} bytes cannot be allocated; pass a C-contiguous float64 array \
             (read in place), or fewer samples per call",
            len,
            len.saturating_mul(8)
        ))
    })?;
    // Contiguous C-order input (the common case) is one block copy; anything else is walked
    // in logical row-major order.
    // (`as_slice` also accepts Fortran order, whose memory order is not row-major: check.)
    match arr.as_slice() {
        Ok(slice) if arr.is_c_contiguous() => data.extend_from_slice(slice),
        _ => data.extend(arr.as_array().iter().copied()),
    }
    Ok(Array { shape, data })
}

/// Fails with a message naming `arg` when a value is NaN or infinite.
pub fn finite(arg: &str, data: &[f64]) -> PyResult<()> {
    match data.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(VehidError::new_err(format!(
            "`{arg}` holds a non-finite value (NaN or inf) at index {i}: pass finite numbers"
        ))),
        None => Ok(()),
    }
}

/// A 2-D array of the given shape (`None` accepts any size along that axis).
pub fn matrix(
    obj: &Bound<'_, PyAny>,
    arg: &str,
    rows: Option<usize>,
    cols: Option<usize>,
) -> PyResult<(usize, usize, Vec<f64>)> {
    let a = array(obj, arg)?;
    let ok = a.shape.len() == 2 && rows.is_none_or(|r| a.shape[0] == r) && cols.is_none_or(|c| a.shape[1] == c);
    if !ok {
        let want = |d: Option<usize>, name: &str| d.map_or(name.to_string(), |v| v.to_string());
        return Err(VehidError::new_err(format!(
            "`{arg}` must have shape ({}, {}), got {}",
            want(rows, "rows"),
            want(cols, "cols"),
            shape_str(&a.shape)
        )));
    }
    Ok((a.shape[0], a.shape[1], a.data))
}

/// A scalar or a 1-D sequence of values (one per component); the core checks the count and
/// the domain.
/// Reads a `p0` argument, the prior covariance of every identifier with a Kalman-type start:
/// `None` for the exact start (`None` or "exact"), else the finite array, whose shape the caller
/// matches; another text is refused with `expected` (the forms the caller takes, in words).
pub fn p0_value(p0: Option<&Bound<'_, PyAny>>, expected: &str) -> PyResult<Option<Array>> {
    let Some(p0) = p0 else { return Ok(None) };
    if let Ok(text) = p0.extract::<String>() {
        return match text.as_str() {
            "exact" => Ok(None),
            other => Err(VehidError::new_err(format!("unknown `p0` {other:?}: expected {expected}"))),
        };
    }
    let a = array(p0, "p0")?;
    finite("p0", &a.data)?;
    Ok(Some(a))
}

pub fn values(obj: Option<&Bound<'_, PyAny>>, arg: &str, default: f64) -> PyResult<Vec<f64>> {
    let Some(obj) = obj else { return Ok(vec![default]) };
    let a = array(obj, arg)?;
    match a.shape.len() {
        0 | 1 => Ok(a.data),
        _ => Err(VehidError::new_err(format!(
            "`{arg}` must be a scalar or a 1-D sequence, got shape {}",
            shape_str(&a.shape)
        ))),
    }
}

/// `speed=`: a scalar (m/s) or a 1-D array of one speed per sample; `None` gives `default`.
/// Returns `(constant, per_sample)`, `per_sample` empty for a constant speed.
pub fn speed_arg(obj: Option<&Bound<'_, PyAny>>, default: f64) -> PyResult<(f64, Vec<f64>)> {
    let Some(obj) = obj else { return Ok((default, vec![])) };
    let a = array(obj, "speed")?;
    match a.shape[..] {
        [] => Ok((a.data[0], vec![])),
        [_] => Ok((0.0, a.data)),
        _ => Err(VehidError::new_err(format!(
            "`speed` must be a scalar or a 1-D array (one speed per sample, m/s), got shape {}",
            shape_str(&a.shape)
        ))),
    }
}

/// A non-negative integer that fits a `u64`.
pub fn uint(v: i128, arg: &str) -> PyResult<u64> {
    u64::try_from(v).map_err(|_| VehidError::new_err(format!("`{arg}` must be an integer in 0..2**64, got {v}")))
}

/// A non-negative integer that fits a `usize`.
pub fn size(v: i128, arg: &str) -> PyResult<usize> {
    usize::try_from(v).map_err(|_| VehidError::new_err(format!("`{arg}` must be a non-negative integer, got {v}")))
}

/// A 2-D float64 table of samples (`rows × cols`, row-major): read in place when the input
/// already is a C-contiguous float64 array (no copy, whatever its size), converted once
/// otherwise (ints, lists, strided views, Fortran order).
pub struct Table<'py> {
    borrowed: Option<PyReadonlyArray2<'py, f64>>,
    owned: Vec<f64>,
    /// Number of rows (samples).
    pub rows: usize,
}

impl<'py> Table<'py> {
    /// Reads `obj` as a `(rows, cols)` table; `rows` is checked when given. `what` describes
    /// the table in the shape error.
    pub fn new(obj: &Bound<'py, PyAny>, arg: &str, rows: Option<usize>, cols: usize, what: &str) -> PyResult<Self> {
        let shape_err = |got: &[usize]| {
            let want = match rows {
                Some(r) => format!("({r}, {cols})"),
                None => format!("(samples, {cols})"),
            };
            VehidError::new_err(format!("`{arg}` must have shape {want} ({what}), got {}", shape_str(got)))
        };
        if let Ok(a) = obj.cast::<PyArray2<f64>>() {
            let ro = a.try_readonly().map_err(|e| VehidError::new_err(format!("`{arg}` cannot be read: {e}")))?;
            let shape = ro.shape().to_vec();
            if shape[1] != cols || rows.is_some_and(|r| r != shape[0]) {
                return Err(shape_err(&shape));
            }
            if ro.is_c_contiguous() && ro.as_slice().is_ok() {
                return Ok(Self { rows: shape[0], borrowed: Some(ro), owned: Vec::new() });
            }
        }
        let a = array(obj, arg)?;
        if a.shape.len() != 2 || a.shape[1] != cols || rows.is_some_and(|r| r != a.shape[0]) {
            return Err(shape_err(&a.shape));
        }
        Ok(Self { rows: a.shape[0], borrowed: None, owned: a.data })
    }

    /// The values, row-major.
    pub fn data(&self) -> &[f64] {
        match &self.borrowed {
            Some(a) => a.as_slice().unwrap_or(&[]),
            None => &self.owned,
        }
    }
}

/// Python's repr of a tuple of row indices: `(1, 3)`, `(0,)`.
pub fn py_tuple(rows: &[usize]) -> String {
    match rows {
        [one] => format!("({one},)"),
        _ => format!("({})", rows.iter().map(|r| r.to_string()).collect::<Vec<_>>().join(", ")),
    }
}

/// Python's repr of a string: single quotes, `\\` and `'` escaped (`'rows'`).
pub fn py_str(s: &str) -> String {
    format!("'{}'", s.replace('\\', "\\\\").replace('\'', "\\'"))
}

/// Python's repr of a list of strings: `['x', 'v']`.
pub fn py_str_list(v: &[String]) -> String {
    format!("[{}]", v.iter().map(|s| py_str(s)).collect::<Vec<_>>().join(", "))
}
