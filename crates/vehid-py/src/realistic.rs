//! `RealisticIdentifier`: the body equation from a body accelerometer and a deflection sensor
//! (the core's `StateFilterFit`).

use crate::convert::{array, shape_str};
use crate::guard::{borrow, borrow_mut};
use crate::stats::PyStats;
use crate::structure::PyStructure;
use crate::{core_err, VehidError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};
use vehid_core::identify::{StateFilterFit, DEFAULT_BANDWIDTH, DEFAULT_BLOCK};

/// Version of the pickled state's layout.
const STATE_FORMAT: u32 = 2;

/// Identifies the body equation of `QuarterCar.structure(known, sensors="realistic")` from the
/// realistic channels `[a_body, a_wheel, deflection]` (m/s², m/s², m; deflection `zb - zw`,
/// positive in extension), on any road: a state-variable filter `F(s) = λ²/(s + λ)²` on both
/// sides of `a_body = -(k2/M) d - (b/M) ḋ + offset` (Young 1981; CONTSID), so that no
/// deflection rate is needed, and intervals that are cluster-robust over blocks of `block`
/// seconds (the filtered residuals are coloured). `bandwidth` is `λ` in rad/s.
///
/// `stats()` gives the parameters with intervals (Student's t, blocks − 1 degrees of
/// freedom); `car.physical(stats)` the constants (k2 and b with M known); m and k1 are not
/// determined by these sensors (`structure.not_identifiable`).
#[pyclass(name = "RealisticIdentifier", module = "vehid._vehid")]
pub struct PyRealisticIdentifier {
    core: StateFilterFit,
    structure: Py<PyStructure>,
}

impl PyRealisticIdentifier {
    fn build(structure: &Bound<'_, PyStructure>, dt: f64, bandwidth: f64, block: f64) -> PyResult<Self> {
        let s = structure.get();
        if !s.realistic() {
            return Err(VehidError::new_err(
                "`structure` must be a car's structure for the realistic sensors: \
                 QuarterCar.structure(known=..., sensors=\"realistic\")",
            ));
        }
        let core = StateFilterFit::new(s.core, dt, bandwidth, block).map_err(core_err)?;
        Ok(Self { core, structure: structure.clone().unbind() })
    }
}

#[pymethods]
impl PyRealisticIdentifier {
    #[new]
    #[pyo3(signature = (structure, dt, bandwidth = DEFAULT_BANDWIDTH, block = DEFAULT_BLOCK))]
    fn new(structure: &Bound<'_, PyAny>, dt: f64, bandwidth: f64, block: f64) -> PyResult<Self> {
        let s = structure.cast::<PyStructure>().map_err(|_| {
            VehidError::new_err(
                "`structure` must be a vehid.Structure from QuarterCar.structure(known=..., sensors=\"realistic\")",
            )
        })?;
        Self::build(s, dt, bandwidth, block)
    }

    /// One sample `y_k` = `[a_body, a_wheel, deflection]`; a bad sample changes nothing.
    fn update(slf: &Bound<'_, Self>, y_k: &Bound<'_, PyAny>) -> PyResult<()> {
        let a = array(y_k, "y_k")?;
        if a.shape != [3] {
            return Err(VehidError::new_err(format!(
                "`y_k` must be one sample [a_body, a_wheel, deflection], shape (3,), got {}",
                shape_str(&a.shape)
            )));
        }
        borrow_mut(slf)?.core.update(&a.data).map_err(|e| VehidError::new_err(format!("`y_k`: {e}")))
    }

    /// Samples `y` (N, 3), one row `[a_body, a_wheel, deflection]` per sample, in time order
    /// without gaps (call `restart()` at a gap). Every value is checked first: a bad one
    /// changes nothing. Returns self.
    fn fit<'py>(slf: &Bound<'py, Self>, y: &Bound<'py, PyAny>) -> PyResult<Bound<'py, Self>> {
        let a = array(y, "y")?;
        if a.shape.len() != 2 || a.shape[1] != 3 {
            return Err(VehidError::new_err(format!(
                "`y` must have shape (samples, 3): columns a_body, a_wheel, deflection, got {}",
                shape_str(&a.shape)
            )));
        }
        let mut this = borrow_mut(slf)?;
        let core = &mut this.core;
        slf.py().detach(|| core.fit(&a.data)).map_err(|e| match e {
            vehid_core::Error::NonFinite { index, .. } => VehidError::new_err(format!(
                "`y` has a value that is not finite at row {}, column {} (drop the samples of a gap and call \
                 restart() there)",
                index / 3,
                index % 3
            )),
            e => core_err(e),
        })?;
        Ok(slf.clone())
    }

    /// A gap in the record: the filter starts again at the next sample.
    fn restart(slf: &Bound<'_, Self>) -> PyResult<()> {
        borrow_mut(slf)?.core.restart();
        Ok(())
    }

    /// The estimate with cluster-robust standard errors and `1 - alpha` intervals.
    #[pyo3(signature = (alpha = 0.05))]
    fn stats(slf: &Bound<'_, Self>, alpha: f64) -> PyResult<PyStats> {
        let this = borrow(slf)?;
        let s = this.core.stats(alpha).map_err(core_err)?;
        let names = this.structure.get().params.clone();
        Ok(PyStats { s, names, structure: Some(this.structure.clone_ref(slf.py())) })
    }

    /// The structure fitted.
    #[getter]
    fn structure(slf: &Bound<'_, Self>) -> PyResult<Py<PyStructure>> {
        Ok(borrow(slf)?.structure.clone_ref(slf.py()))
    }

    /// Samples used (after each start's settling).
    #[getter]
    fn samples(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(borrow(slf)?.core.samples())
    }

    /// Sample interval, s.
    #[getter]
    fn dt(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.core.dt())
    }

    /// The filter's bandwidth λ, rad/s.
    #[getter]
    fn bandwidth(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.core.bandwidth())
    }

    /// The blocks' length, s.
    #[getter]
    fn block(slf: &Bound<'_, Self>) -> PyResult<f64> {
        let this = borrow(slf)?;
        Ok(this.core.block() as f64 * this.core.dt())
    }

    /// Samples left out after each start while the filter settles.
    #[getter]
    fn settling(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(borrow(slf)?.core.settling())
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let this = borrow(slf)?;
        Ok(format!(
            "RealisticIdentifier(dt={:?}, bandwidth={:?}, samples={})",
            this.core.dt(),
            this.core.bandwidth(),
            this.core.samples()
        ))
    }

    /// Pickling: `(RealisticIdentifier, (structure, dt, bandwidth, block), state)`, the state
    /// `(FORMAT, "vehid <version>", postcard bytes and their CRC-32)`; a restored one continues bit
    /// for bit.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let this = borrow(slf)?;
        let bytes = vehid_runtime::seal::seal(&this.core)
            .map_err(|e| VehidError::new_err(format!("the identifier cannot be saved: {e}")))?;
        let block = this.core.block() as f64 * this.core.dt();
        let args = (this.structure.clone_ref(py), this.core.dt(), this.core.bandwidth(), block);
        let state = (STATE_FORMAT, format!("vehid {}", env!("CARGO_PKG_VERSION")), PyBytes::new(py, &bytes));
        (slf.get_type(), args, state).into_pyobject(py)
    }

    /// Restores a pickled state (checked: a corrupt one is a VehidError and changes nothing).
    fn __setstate__(slf: &Bound<'_, Self>, state: &Bound<'_, PyAny>) -> PyResult<()> {
        let corrupt = |what: &str| {
            VehidError::new_err(format!(
                "cannot restore the RealisticIdentifier: {what} (the pickle is corrupt, or was not made by vehid)"
            ))
        };
        let Ok((format, version, payload)) = state.extract::<(u32, String, Vec<u8>)>() else {
            return Err(corrupt("its state is not a (format, version, bytes) tuple"));
        };
        if format != STATE_FORMAT {
            return Err(VehidError::new_err(format!(
                "cannot restore the RealisticIdentifier: it was pickled by {version} in state format {format}, and \
                 this vehid ({}) reads format {STATE_FORMAT} only",
                env!("CARGO_PKG_VERSION")
            )));
        }
        let core: StateFilterFit = vehid_runtime::seal::open(&payload)
            .map_err(|e| corrupt(&format!("its payload does not decode or fails its checksum ({e})")))?;
        let mut this = borrow_mut(slf)?;
        if core.structure() != this.core.structure() || !core.is_consistent() {
            return Err(corrupt("its payload does not match its structure and settings"));
        }
        this.core = core;
        Ok(())
    }

    fn __copy__(slf: &Bound<'_, Self>) -> PyResult<Self> {
        let this = borrow(slf)?;
        Ok(Self { core: this.core.clone(), structure: this.structure.clone_ref(slf.py()) })
    }

    fn __deepcopy__(slf: &Bound<'_, Self>, _memo: &Bound<'_, PyAny>) -> PyResult<Self> {
        Self::__copy__(slf)
    }
}
