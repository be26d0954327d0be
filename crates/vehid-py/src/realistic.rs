//! `RealisticIdentifier`: the body equation from a body accelerometer and a deflection sensor
//! (the core's `StateFilterFit`), or the full car's four body-corner equations from a body
//! accelerometer and a deflection sensor at each corner (the core's `CornerFilterFit`).

use crate::convert::{array, shape_str};
use crate::guard::{borrow, borrow_mut};
use crate::model::{Kind, PyLinearModel};
use crate::stats::PyStats;
use crate::structure::PyStructure;
use crate::{core_err, VehidError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};
use vehid_core::identify::{CornerFilterFit, StateFilterFit, CORNER_BANDWIDTH, DEFAULT_BANDWIDTH, DEFAULT_BLOCK};
use vehid_core::model::CORNERS;

/// Version of the pickled state's layout. 3: the corner fits (full and half car) keep the
/// deflection noise's sums (its compensation); the quarter car's states are those of 2.
const STATE_FORMAT: u32 = 3;

/// The fit: the quarter car's body equation on its structure, or the full car's four corners
/// (the half car's two) with the car given.
enum Core {
    Quarter(Box<StateFilterFit>, Py<PyStructure>),
    Full(Box<CornerFilterFit>, Py<PyAny>),
}

/// Dispatches a method shared by both fits.
macro_rules! both {
    ($core:expr, $f:ident => $body:expr) => {
        match $core {
            Core::Quarter($f, _) => $body,
            Core::Full($f, _) => $body,
        }
    };
}

impl Core {
    fn channels(&self) -> (usize, &'static str) {
        match self {
            Core::Quarter(..) => (3, "a_body, a_wheel, deflection"),
            Core::Full(c, _) if c.corners() == 2 => {
                (6, "a_body_f, a_body_r, a_wheel_f, a_wheel_r, deflection_f, deflection_r (the half car's)")
            }
            Core::Full(..) => {
                (12, "a_body_fl..rr, a_wheel_fl..rr, deflection_fl..rr (the full car's realistic channels)")
            }
        }
    }
}

/// The names of the full car's 36 coefficients (the half car's 10: `corners` 2):
/// `a_<corner>:d_<corner>` (the extension's), `a_<corner>:rate_<corner>` and `a_<corner>:offset`,
/// equation by equation.
pub(crate) fn corner_names(corners: usize) -> Vec<String> {
    let names: &[&str] = if corners == 2 { &["f", "r"] } else { &CORNERS };
    let mut out = Vec::with_capacity(names.len() * (2 * names.len() + 1));
    for i in names {
        for j in names {
            out.push(format!("a_{i}:d_{j}"));
            out.push(format!("a_{i}:rate_{j}"));
        }
        out.push(format!("a_{i}:offset"));
    }
    out
}

/// Identifies the body equation of `QuarterCar.structure(known, sensors="realistic")` from the
/// realistic channels `[a_body, a_wheel, deflection]` (m/s², m/s², m; deflection `zb - zw`,
/// positive in extension), on any road: a state-variable filter `F(s) = λ²/(s + λ)²` on both
/// sides of `a_body = -(k2/M) d - (b/M) ḋ + offset` (Young 1981; CONTSID), so that no
/// deflection rate is needed, and intervals that are cluster-robust over blocks of `block`
/// seconds (the filtered residuals are coloured). `bandwidth` is `λ` in rad/s (default 10, the
/// half car's too; the full car's 30, `vehid_core::identify::CORNER_BANDWIDTH` says why).
///
/// `stats()` gives the parameters with intervals (Student's t, blocks − 1 degrees of
/// freedom); `car.physical(stats)` the constants (k2 and b with M known); m and k1 are not
/// determined by these sensors (`structure.not_identifiable`).
///
/// Given a `FullCar` instead of a structure (a `HalfCar`: the same with its two corners f, r,
/// `α_ij = 1/M + x_i x_j/J`, six channels, `half.physical(stats, M=...)` for J, k12, k22, b1,
/// b2): the four body-corner equations `a_i = Σ_j
/// Θ_2j,i (−d_j) + Θ_2j+1,i (−ḋ_j) + c_i` (`Θ_2j,i = (α K)_ij`, `Θ_2j+1,i = α_ij b_j`, `α_ij =
/// 1/M + x_i x_j/Jy + y_i y_j/Jx`) from the twelve realistic channels `[a_body_fl..rr,
/// a_wheel_fl..rr, deflection_fl..rr]`, the same filter on every signal, the covariance of all
/// 36 coefficients cluster-robust across the equations too; `full.physical(stats, M=...)` the
/// springs, dampers, inertias and anti-roll bars.
#[pyclass(name = "RealisticIdentifier", module = "vehid._vehid")]
pub struct PyRealisticIdentifier {
    core: Core,
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
        Ok(Self { core: Core::Quarter(Box::new(core), structure.clone().unbind()) })
    }

    fn build_corners(car: &Bound<'_, PyAny>, half: bool, dt: f64, bandwidth: f64, block: f64) -> PyResult<Self> {
        let core =
            if half { CornerFilterFit::half(dt, bandwidth, block) } else { CornerFilterFit::new(dt, bandwidth, block) }
                .map_err(core_err)?;
        Ok(Self { core: Core::Full(Box::new(core), car.clone().unbind()) })
    }

    fn copy(&self, py: Python<'_>) -> Self {
        Self {
            core: match &self.core {
                Core::Quarter(c, s) => Core::Quarter(c.clone(), s.clone_ref(py)),
                Core::Full(c, car) => Core::Full(c.clone(), car.clone_ref(py)),
            },
        }
    }
}

#[pymethods]
impl PyRealisticIdentifier {
    #[new]
    #[pyo3(signature = (structure, dt, bandwidth = None, block = DEFAULT_BLOCK))]
    fn new(structure: &Bound<'_, PyAny>, dt: f64, bandwidth: Option<f64>, block: f64) -> PyResult<Self> {
        if let Ok(model) = structure.cast::<PyLinearModel>() {
            if let Kind::Full(_) | Kind::Half(_) = model.get().kind {
                let half = matches!(model.get().kind, Kind::Half(_));
                let default = if half { DEFAULT_BANDWIDTH } else { CORNER_BANDWIDTH };
                return Self::build_corners(structure, half, dt, bandwidth.unwrap_or(default), block);
            }
        }
        let bandwidth = bandwidth.unwrap_or(DEFAULT_BANDWIDTH);
        let s = structure.cast::<PyStructure>().map_err(|_| {
            VehidError::new_err(
                "`structure` must be a vehid.Structure from QuarterCar.structure(known=..., sensors=\"realistic\"), \
                 a vehid.HalfCar or a vehid.FullCar",
            )
        })?;
        Self::build(s, dt, bandwidth, block)
    }

    /// One sample `y_k` (the quarter car's `[a_body, a_wheel, deflection]`, the full car's
    /// twelve realistic channels); a bad sample changes nothing.
    fn update(slf: &Bound<'_, Self>, y_k: &Bound<'_, PyAny>) -> PyResult<()> {
        let a = array(y_k, "y_k")?;
        let mut this = borrow_mut(slf)?;
        let (width, names) = this.core.channels();
        if a.shape != [width] {
            return Err(VehidError::new_err(format!(
                "`y_k` must be one sample [{names}], shape ({width},), got {}",
                shape_str(&a.shape)
            )));
        }
        both!(&mut this.core, c => c.update(&a.data)).map_err(|e| VehidError::new_err(format!("`y_k`: {e}")))
    }

    /// Samples `y` (N, 3) for the quarter car, one row `[a_body, a_wheel, deflection]` per
    /// sample, or (N, 12) for the full car, in time order without gaps (call `restart()` at a
    /// gap). Every value is checked first: a bad one changes nothing. Returns self.
    fn fit<'py>(slf: &Bound<'py, Self>, y: &Bound<'py, PyAny>) -> PyResult<Bound<'py, Self>> {
        let a = array(y, "y")?;
        let mut this = borrow_mut(slf)?;
        let (width, names) = this.core.channels();
        if a.shape.len() != 2 || a.shape[1] != width {
            return Err(VehidError::new_err(format!(
                "`y` must have shape (samples, {width}): columns {names}, got {}",
                shape_str(&a.shape)
            )));
        }
        let core = &mut this.core;
        slf.py().detach(|| both!(core, c => c.fit(&a.data))).map_err(|e| match e {
            vehid_core::Error::NonFinite { index, .. } => VehidError::new_err(format!(
                "`y` has a value that is not finite at row {}, column {} (drop the samples of a gap and call \
                 restart() there)",
                index / width,
                index % width
            )),
            e => core_err(e),
        })?;
        Ok(slf.clone())
    }

    /// A gap in the record: the filter starts again at the next sample.
    fn restart(slf: &Bound<'_, Self>) -> PyResult<()> {
        both!(&mut borrow_mut(slf)?.core, c => c.restart());
        Ok(())
    }

    /// The estimate with cluster-robust standard errors and `1 - alpha` intervals. The full
    /// car's: 36 coefficients named `a_fl:d_fl`, `a_fl:rate_fl`, …, `a_fl:offset`, … (1/s², 1/s,
    /// m/s²), equation by equation.
    #[pyo3(signature = (alpha = 0.05))]
    fn stats(slf: &Bound<'_, Self>, alpha: f64) -> PyResult<PyStats> {
        let this = borrow(slf)?;
        match &this.core {
            Core::Quarter(c, structure) => {
                let s = c.stats(alpha).map_err(core_err)?;
                let names = structure.get().params.clone();
                Ok(PyStats { s, names, structure: Some(structure.clone_ref(slf.py())) })
            }
            Core::Full(c, _) => {
                let s = c.stats(alpha).map_err(core_err)?;
                Ok(PyStats { s, names: corner_names(c.corners()), structure: None })
            }
        }
    }

    /// The structure fitted (the quarter car's; the full car's fit has none: `car`).
    #[getter]
    fn structure(slf: &Bound<'_, Self>) -> PyResult<Py<PyStructure>> {
        match &borrow(slf)?.core {
            Core::Quarter(_, s) => Ok(s.clone_ref(slf.py())),
            Core::Full(..) => Err(VehidError::new_err(
                "the full car's corner fit has no Structure: its car is `.car`, its coefficients `.stats().names`",
            )),
        }
    }

    /// The FullCar or HalfCar given (None for a structure's fit).
    #[getter]
    fn car(slf: &Bound<'_, Self>) -> PyResult<Option<Py<PyAny>>> {
        Ok(match &borrow(slf)?.core {
            Core::Quarter(..) => None,
            Core::Full(_, car) => Some(car.clone_ref(slf.py())),
        })
    }

    /// Samples used (after each start's settling).
    #[getter]
    fn samples(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(both!(&borrow(slf)?.core, c => c.samples()))
    }

    /// Sample interval, s.
    #[getter]
    fn dt(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(both!(&borrow(slf)?.core, c => c.dt()))
    }

    /// The filter's bandwidth λ, rad/s.
    #[getter]
    fn bandwidth(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(both!(&borrow(slf)?.core, c => c.bandwidth()))
    }

    /// The blocks' length, s.
    #[getter]
    fn block(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(both!(&borrow(slf)?.core, c => c.block() as f64 * c.dt()))
    }

    /// Samples left out after each start while the filter settles.
    #[getter]
    fn settling(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(both!(&borrow(slf)?.core, c => c.settling()))
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let this = borrow(slf)?;
        let (dt, bandwidth, samples) = both!(&this.core, c => (c.dt(), c.bandwidth(), c.samples()));
        let of = match &this.core {
            Core::Full(c, _) if c.corners() == 2 => "HalfCar, ",
            Core::Full(..) => "FullCar, ",
            Core::Quarter(..) => "",
        };
        Ok(format!("RealisticIdentifier({of}dt={dt:?}, bandwidth={bandwidth:?}, samples={samples})"))
    }

    /// Pickling: `(RealisticIdentifier, (structure or car, dt, bandwidth, block), state)`, the
    /// state `(FORMAT, "vehid <version>", postcard bytes and their CRC-32)`; a restored one
    /// continues bit for bit.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let this = borrow(slf)?;
        let saved = match &this.core {
            Core::Quarter(c, _) => vehid_runtime::seal::seal(c.as_ref()),
            Core::Full(c, _) => vehid_runtime::seal::seal(c.as_ref()),
        };
        let bytes = saved.map_err(|e| VehidError::new_err(format!("the identifier cannot be saved: {e}")))?;
        let (dt, bandwidth, block) = both!(&this.core, c => (c.dt(), c.bandwidth(), c.block() as f64 * c.dt()));
        let source = match &this.core {
            Core::Quarter(_, s) => s.clone_ref(py).into_any(),
            Core::Full(_, car) => car.clone_ref(py),
        };
        let args = (source, dt, bandwidth, block);
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
        let corners = matches!(borrow(slf)?.core, Core::Full(..));
        let oldest = if corners { STATE_FORMAT } else { 2 };
        if !(oldest..=STATE_FORMAT).contains(&format) {
            return Err(VehidError::new_err(format!(
                "cannot restore the RealisticIdentifier: it was pickled by {version} in state format {format}, and \
                 this vehid ({}) reads this fit in formats {oldest} to {STATE_FORMAT} only; fit it again, or load it \
                 with the version that saved it",
                env!("CARGO_PKG_VERSION")
            )));
        }
        let undecodable = |e: vehid_runtime::seal::Error| {
            corrupt(&format!("its payload does not decode or fails its checksum ({e})"))
        };
        let mismatch = || corrupt("its payload does not match its structure and settings");
        let mut this = borrow_mut(slf)?;
        match &mut this.core {
            Core::Quarter(now, _) => {
                let core: StateFilterFit = vehid_runtime::seal::open(&payload).map_err(undecodable)?;
                if core.structure() != now.structure() || !core.is_consistent() {
                    return Err(mismatch());
                }
                **now = core;
            }
            Core::Full(now, _) => {
                let core: CornerFilterFit = vehid_runtime::seal::open(&payload).map_err(undecodable)?;
                let settings = |c: &CornerFilterFit| (c.corners(), c.dt(), c.bandwidth(), c.block());
                if settings(&core) != settings(now) || !core.is_consistent() {
                    return Err(mismatch());
                }
                **now = core;
            }
        }
        Ok(())
    }

    fn __copy__(slf: &Bound<'_, Self>) -> PyResult<Self> {
        Ok(borrow(slf)?.copy(slf.py()))
    }

    fn __deepcopy__(slf: &Bound<'_, Self>, _memo: &Bound<'_, PyAny>) -> PyResult<Self> {
        Self::__copy__(slf)
    }
}

/// `HalfCar.physical(stats, M=...)` on the stats of `RealisticIdentifier(half)`: `M` given as
/// (value, value, value), then J, k12, k22, b1, b2 with intervals at the stats' level
/// (`HalfCar::from_corner_coefficients`); the tyres and the wheel masses are left out.
pub(crate) fn physical_half_corners<'py>(
    py: Python<'py>,
    car: &vehid_core::model::HalfCar<f64>,
    st: &PyStats,
    known: Option<&Bound<'py, pyo3::types::PyDict>>,
) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    let m_body = crate::full::body_mass_keyword(known)?;
    let (_, values, se) = car.from_corner_coefficients(&st.s.params, &st.s.cov, m_body).map_err(core_err)?;
    let q = vehid_core::stats::t_interval_factor(st.s.alpha, &st.s.df).map_err(core_err)?;
    let out = pyo3::types::PyDict::new(py);
    out.set_item("M", (m_body, m_body, m_body))?;
    for ((name, v), s) in vehid_core::model::HALF_CORNER_DETERMINED.iter().zip(values).zip(se) {
        out.set_item(*name, (v, v - q * s, v + q * s))?;
    }
    Ok(out)
}
