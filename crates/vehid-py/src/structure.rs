//! `vehid.Structure`: a model linear in its parameters, from names and equation texts (the
//! core's `StructureBuilder`) or from a car's physical constants (`QuarterCar.structure`,
//! `HalfCar.structure`: the core's `PhysicalStructure`); and the identifiers built on one.

use crate::convert::{array, finite, p0_value, py_str, py_str_list, shape_str};
use crate::{core_err, VehidError};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use vehid_core::identify::{DynIdentifier, Gain, KalmanOptions, StructuredPrior};
use vehid_core::model::{HalfCar, PhysicalStructure, QuarterCar};
use vehid_core::structure::{Structure, StructureBuilder};

/// Where a structure came from (what pickling rebuilds it from).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Origin {
    /// Equation texts: `(state, text)` identified, `(state, text)` known, declared parameters.
    Text { equations: Vec<(String, String)>, known: Vec<(String, String)>, parameters: Option<Vec<String>> },
    /// A car's physical structure with these constants known (in the car's constant order),
    /// for the state sensors or (`realistic`) the body equation the realistic sensors determine.
    Physical { car: CarKind, known: Vec<Option<f64>>, realistic: bool, physical: Box<PhysicalStructure<f64>> },
}

/// The cars with a physical structure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum CarKind {
    Quarter,
    Half,
}

impl CarKind {
    /// The car's constants, in the core's order.
    pub(crate) fn constants(self) -> &'static [&'static str] {
        match self {
            CarKind::Quarter => &QuarterCar::<f64>::CONSTANTS,
            CarKind::Half => &HalfCar::<f64>::CONSTANTS,
        }
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            CarKind::Quarter => "QuarterCar",
            CarKind::Half => "HalfCar",
        }
    }

    /// The physical structure with `known` constants (core order) fixed, for the state
    /// sensors or the realistic ones.
    pub(crate) fn physical(self, known: &[Option<f64>], realistic: bool) -> vehid_core::Result<PhysicalStructure<f64>> {
        match self {
            CarKind::Quarter => {
                let mut k = [None; 5];
                k.copy_from_slice(known);
                if realistic {
                    QuarterCar::realistic_structure(k)
                } else {
                    QuarterCar::structure(k)
                }
            }
            CarKind::Half if realistic => Err(vehid_core::Error::Unsupported {
                what: "the half car's structure for the realistic sensors (its two body-corner equations share \
                       the pitch inertia, which a Structure does not hold: fit them with RealisticIdentifier(half, dt) \
                       and read J, k12, k22, b1, b2 with HalfCar.physical(stats, M=...))",
            }),
            CarKind::Half => {
                let mut k = [None; 12];
                k.copy_from_slice(known);
                HalfCar::structure(k)
            }
        }
    }
}

/// A model linear in its parameters: `d(state)/dt = Σ parameter × term` for each identified
/// equation (see the README, "Models linear in their parameters").
///
/// `states` and `inputs` name the state variables and the measured inputs; `equations` maps
/// a state to the text of its derivative (identified), `known` a state to a parameter-free
/// text (used when simulating). Term grammar: `[number*]parameter[*term]` or
/// `number[*term]`, a term being a state or input name, `der(state)` (the measured
/// derivative of another state), or `sign(e)`, `pos(e)`, `neg(e)` of a linear combination
/// `e` of states and inputs; products are expanded (`k*(x - y)`). Any other name is a
/// parameter, in order of first appearance unless `parameters` declares them (then any other
/// name is an error). A parameter may appear in several equations (shared). Bad text, a
/// misspelled name, a product of two parameters, a parameter no equation uses or two that the
/// data can never tell apart raise VehidError naming the equation.
///
/// Limits, each checked before the work it bounds (VehidError naming the equation or the list
/// and the limit): at most 16 states, 8 inputs, 32 parameters and 16 equations; an equation
/// text of at most 10,000 bytes, nested at most 64 levels deep (parentheses, `sign(`/`pos(`/
/// `neg(` calls and unary minus signs each add one), and at most 96 terms in all once products
/// are expanded and like terms merged (`(1+1)*(1+1)*a*x` is one term); a product is sized
/// before it is expanded.
#[pyclass(name = "Structure", module = "vehid._vehid", frozen)]
pub struct PyStructure {
    pub(crate) core: Structure<f64>,
    pub(crate) states: Vec<String>,
    pub(crate) inputs: Vec<String>,
    pub(crate) params: Vec<String>,
    pub(crate) origin: Origin,
}

/// `(key, value)` string pairs of a dict, in order, naming the argument on a wrong type.
fn str_pairs(d: Option<&Bound<'_, PyAny>>, arg: &str) -> PyResult<Vec<(String, String)>> {
    let Some(d) = d else { return Ok(vec![]) };
    if d.is_none() {
        return Ok(vec![]);
    }
    let d = d.cast::<PyDict>().map_err(|_| {
        VehidError::new_err(format!("`{arg}` must be a dict mapping a state name to the text of its derivative"))
    })?;
    d.iter()
        .map(|(k, v)| {
            let k: String =
                k.extract().map_err(|_| VehidError::new_err(format!("`{arg}`: every key must be a state name")))?;
            let v: String = v
                .extract()
                .map_err(|_| VehidError::new_err(format!("`{arg}[{k:?}]` must be a string such as \"-a*x + b*u\"")))?;
            Ok((k, v))
        })
        .collect()
}

/// A list of names (a string alone is refused: `"xy"` is not `["x", "y"]`).
fn names(obj: Option<&Bound<'_, PyAny>>, arg: &str) -> PyResult<Vec<String>> {
    let Some(obj) = obj else { return Ok(vec![]) };
    if obj.is_none() {
        return Ok(vec![]);
    }
    if obj.is_instance_of::<pyo3::types::PyString>() {
        return Err(VehidError::new_err(format!(
            "`{arg}` must be a list of names, e.g. [\"q\", \"v\"], not one string"
        )));
    }
    obj.extract::<Vec<String>>().map_err(|_| VehidError::new_err(format!("`{arg}` must be a list of names (strings)")))
}

impl PyStructure {
    /// Builds from texts.
    pub(crate) fn from_text(
        states: Vec<String>,
        inputs: Vec<String>,
        equations: Vec<(String, String)>,
        known: Vec<(String, String)>,
        parameters: Option<Vec<String>>,
    ) -> PyResult<Self> {
        let mut b = StructureBuilder::new(&states, &inputs);
        if let Some(p) = &parameters {
            b = b.parameters(p);
        }
        for (s, t) in &equations {
            b = b.equation(s, t);
        }
        for (s, t) in &known {
            b = b.known(s, t);
        }
        let (core, n) = b.build::<f64>().map_err(|e| VehidError::new_err(e.to_string()))?;
        Ok(Self {
            core,
            states: n.states,
            inputs: n.inputs,
            params: n.params,
            origin: Origin::Text { equations, known, parameters },
        })
    }

    /// A car's physical structure; `known` maps constant names to values.
    pub(crate) fn physical(car: CarKind, known: Option<&Bound<'_, PyAny>>, realistic: bool) -> PyResult<Self> {
        Self::physical_known(car, known_constants(car, known)?, realistic)
    }

    /// A car's physical structure with constants `k` (one per [`CarKind::constants`]) known;
    /// the realistic sensors' states are named `d, v, vb` (deflection, its rate, the body's
    /// velocity), the state sensors' `x1..xn`.
    pub(crate) fn physical_known(car: CarKind, k: Vec<Option<f64>>, realistic: bool) -> PyResult<Self> {
        let ph = car.physical(&k, realistic).map_err(core_err)?;
        let n = ph.structure().states();
        let states = if realistic {
            ["d", "v", "vb"].iter().map(|s| s.to_string()).collect()
        } else {
            (1..=n).map(|i| format!("x{i}")).collect()
        };
        Ok(Self {
            core: *ph.structure(),
            states,
            inputs: vec![],
            params: ph.param_names().iter().map(|s| s.to_string()).collect(),
            origin: Origin::Physical { car, known: k, realistic, physical: Box::new(ph) },
        })
    }

    /// Whether this is a car's structure for the realistic sensors.
    pub(crate) fn realistic(&self) -> bool {
        matches!(self.origin, Origin::Physical { realistic: true, .. })
    }

    /// [`PyStructure::simulate`]'s work: the simulated states, row-major.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn simulate_vec(
        &self,
        py: Python<'_>,
        params: &Bound<'_, PyAny>,
        x0: &Bound<'_, PyAny>,
        u: Option<&Bound<'_, PyAny>>,
        dt: f64,
        samples: Option<usize>,
        substeps: u32,
    ) -> PyResult<Vec<f64>> {
        let (n, m) = (self.core.states(), self.core.inputs());
        let p = vec_arg(params, "params", self.core.params())?;
        let x0 = vec_arg(x0, "x0", n)?;
        let (u, len) = match (u, samples) {
            (Some(u), s) => {
                let a = array(u, "u")?;
                let ok = match a.shape[..] {
                    [rows, cols] => cols == m && s.is_none_or(|s| s == rows),
                    [rows] => m == 1 && s.is_none_or(|s| s == rows),
                    _ => false,
                };
                if !ok || m == 0 {
                    return Err(VehidError::new_err(format!(
                        "`u` must have shape (samples, {m}) (one row of measured inputs per sample){}, got {}",
                        if m == 0 { ": this structure has no inputs, give samples= instead" } else { "" },
                        shape_str(&a.shape)
                    )));
                }
                let rows = a.data.len() / m;
                (a.data, rows)
            }
            (None, Some(s)) if m == 0 => (vec![], s),
            (None, _) if m > 0 => {
                return Err(VehidError::new_err(format!("`u` is needed: the structure has {m} measured inputs")))
            }
            (None, _) => return Err(VehidError::new_err("give `samples=` (the structure has no inputs)")),
        };
        let mut out = Vec::new();
        out.try_reserve_exact(len.saturating_mul(n)).map_err(|_| {
            pyo3::exceptions::PyMemoryError::new_err(format!("cannot allocate {len} simulated samples"))
        })?;
        out.resize(len * n, 0.0);
        let core = &self.core;
        py.detach(|| core.simulate(&p, &x0, &u, dt, substeps, &mut out)).map_err(core_err)?;
        Ok(out)
    }

    /// The identified equations' state names, in order.
    pub(crate) fn equation_states(&self) -> Vec<String> {
        self.core.equation_states().map(|i| self.states[i].clone()).collect()
    }
}

#[pymethods]
impl PyStructure {
    #[new]
    #[pyo3(signature = (states, inputs = None, equations = None, known = None, parameters = None))]
    fn py_new(
        states: &Bound<'_, PyAny>,
        inputs: Option<&Bound<'_, PyAny>>,
        equations: Option<&Bound<'_, PyAny>>,
        known: Option<&Bound<'_, PyAny>>,
        parameters: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let states = names(Some(states), "states")?;
        let inputs = names(inputs, "inputs")?;
        let equations = str_pairs(equations, "equations")?;
        let known = str_pairs(known, "known")?;
        let parameters = match parameters {
            Some(p) if !p.is_none() => Some(names(Some(p), "parameters")?),
            _ => None,
        };
        Self::from_text(states, inputs, equations, known, parameters)
    }

    /// The constants of a car's structure that its data cannot determine, each with what
    /// would determine it: `{constant: "needs ..."}` (empty for a structure from text, and when
    /// every constant follows). `car.physical(stats)` leaves these out.
    #[getter]
    fn not_identifiable<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        if let Origin::Physical { car, physical, .. } = &self.origin {
            for (c, name) in car.constants().iter().enumerate() {
                if let Some(why) = physical.needs(c) {
                    out.set_item(*name, why)?;
                }
            }
        }
        Ok(out)
    }

    /// The parameter names, in the order of `params` and of every vector over parameters.
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, &self.params)
    }

    /// The state names.
    #[getter]
    fn states<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, &self.states)
    }

    /// The measured-input names.
    #[getter]
    fn inputs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, &self.inputs)
    }

    /// The states whose derivatives are identified, in the order of the innovations and of
    /// `sigma2`.
    #[getter]
    fn identified<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, self.equation_states())
    }

    /// Number of parameters.
    #[getter]
    fn n_params(&self) -> usize {
        self.core.params()
    }

    /// Number of states.
    #[getter]
    fn n_states(&self) -> usize {
        self.core.states()
    }

    /// Number of measured inputs.
    #[getter]
    fn n_inputs(&self) -> usize {
        self.core.inputs()
    }

    /// The groups of parameters that no equation couples (each is identified by its own
    /// filter), as tuples of parameter names.
    #[getter]
    fn groups<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let part = self.core.partition();
        let groups: Vec<Vec<String>> = (0..part.groups as usize)
            .map(|g| {
                (0..self.core.params())
                    .filter(|&j| part.group_of_param[j] as usize == g)
                    .map(|j| self.params[j].clone())
                    .collect()
            })
            .collect();
        PyTuple::new(py, groups.into_iter().map(|g| PyTuple::new(py, g)).collect::<PyResult<Vec<_>>>()?)
    }

    /// The derivative of every state for parameters `params` (n_params,), states `x` (n,) and
    /// inputs `u` (m,): the identified equations with these parameters, the known ones as
    /// given (a state with neither has derivative 0).
    #[pyo3(signature = (params, x, u = None))]
    fn derivative(
        &self,
        params: &Bound<'_, PyAny>,
        x: &Bound<'_, PyAny>,
        u: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Vec<f64>> {
        let p = vec_arg(params, "params", self.core.params())?;
        let x = vec_arg(x, "x", self.core.states())?;
        let u = match u {
            Some(u) => vec_arg(u, "u", self.core.inputs())?,
            None if self.core.inputs() == 0 => vec![],
            None => return Err(VehidError::new_err(format!("`u` is needed: {} measured inputs", self.core.inputs()))),
        };
        let mut out = vec![0.0; self.core.states()];
        self.core.derivative(&p, &x, &u, &mut out);
        Ok(out)
    }

    /// Free-run simulation with parameters `params` (n_params,) from `x0` (n,): the state at
    /// every sample, (samples, n), starting with `x0`. `u` (samples, m): measured inputs, held
    /// over each interval of `dt` seconds; without inputs give `samples`. Each interval is
    /// integrated by `substeps` RK4 steps. Every state needs an equation (identified or known).
    /// GIL released.
    #[pyo3(signature = (params, x0, u = None, *, dt, samples = None, substeps = 10))]
    #[allow(clippy::too_many_arguments)]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        params: &Bound<'py, PyAny>,
        x0: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
        dt: f64,
        samples: Option<usize>,
        substeps: u32,
    ) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let out = self.simulate_vec(py, params, x0, u, dt, samples, substeps)?;
        let n = self.core.states();
        crate::model::to_array2(py, out.len() / n, n, out)
    }

    fn __repr__(&self) -> String {
        match &self.origin {
            Origin::Text { equations, .. } => {
                let eqs: Vec<String> = equations.iter().map(|(s, t)| format!("{}: {}", py_str(s), py_str(t))).collect();
                format!(
                    "Structure(states={}, inputs={}, equations={{{}}}, parameters={})",
                    py_str_list(&self.states),
                    py_str_list(&self.inputs),
                    eqs.join(", "),
                    py_str_list(&self.params)
                )
            }
            Origin::Physical { car, known, realistic, .. } => {
                let k: Vec<String> = car
                    .constants()
                    .iter()
                    .zip(known)
                    .filter_map(|(c, v)| v.map(|v| format!("{}: {v:?}", py_str(c))))
                    .collect();
                format!(
                    "{}.structure(known={{{}}}{}) (parameters {})",
                    car.name(),
                    k.join(", "),
                    if *realistic { ", sensors='realistic'" } else { "" },
                    py_str_list(&self.params)
                )
            }
        }
    }

    /// Structures compare by how they were made.
    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other.cast::<Self>().is_ok_and(|o| o.get().origin == self.origin && o.get().states == self.states)
    }

    /// Pickling: rebuilt from its texts (or its car and known constants).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let s = slf.get();
        match &s.origin {
            Origin::Text { equations, known, parameters } => {
                let eq = PyDict::new(py);
                for (k, v) in equations {
                    eq.set_item(k, v)?;
                }
                let kn = PyDict::new(py);
                for (k, v) in known {
                    kn.set_item(k, v)?;
                }
                let args = (s.states.clone(), s.inputs.clone(), eq, kn, parameters.clone()).into_pyobject(py)?;
                (slf.get_type(), args).into_pyobject(py)
            }
            Origin::Physical { car, known, realistic, .. } => {
                let kn = PyDict::new(py);
                for (c, v) in car.constants().iter().zip(known) {
                    if let Some(v) = v {
                        kn.set_item(*c, *v)?;
                    }
                }
                let f = py.import("vehid._vehid")?.getattr("_physical_structure")?;
                let sensors = if *realistic { "realistic" } else { "state" };
                (f, (car.name(), kn, sensors).into_pyobject(py)?).into_pyobject(py)
            }
        }
    }
}

/// Rebuilds `QuarterCar.structure(known, sensors)` / `HalfCar.structure(known)` when
/// unpickling.
#[pyfunction]
#[pyo3(signature = (car, known, sensors = "state"))]
pub(crate) fn _physical_structure(car: &str, known: &Bound<'_, PyAny>, sensors: &str) -> PyResult<PyStructure> {
    let kind = match car {
        "QuarterCar" => CarKind::Quarter,
        "HalfCar" => CarKind::Half,
        other => return Err(VehidError::new_err(format!("no physical structure for {other:?}"))),
    };
    PyStructure::physical(kind, Some(known), sensors_arg(sensors)?)
}

/// `sensors=`: `"state"` (false) or `"realistic"` (true).
pub(crate) fn sensors_arg(sensors: &str) -> PyResult<bool> {
    match sensors {
        "state" => Ok(false),
        "realistic" => Ok(true),
        other => Err(VehidError::new_err(format!(
            "`sensors` must be \"state\" (the measured state and derivative) or \"realistic\" \
             (accelerometers and a deflection sensor), got {}",
            py_str(other)
        ))),
    }
}

/// A 1-D float vector of exactly `len` values.
pub(crate) fn vec_arg(obj: &Bound<'_, PyAny>, arg: &str, len: usize) -> PyResult<Vec<f64>> {
    let a = array(obj, arg)?;
    if a.shape != [len] {
        return Err(VehidError::new_err(format!("`{arg}` must have shape ({len},), got {}", shape_str(&a.shape))));
    }
    finite(arg, &a.data)?;
    Ok(a.data)
}

/// `p0` for a structure of `np` parameters and `ne` equations (`per`: what an equation is to
/// the user, "identified equation" or "unknown row"): the exact start ("exact" or None), a
/// scalar, one per equation, or the (np, np) matrix.
pub(crate) enum StructuredP0 {
    Exact,
    Scalar(f64),
    PerEquation(Vec<f64>),
    Matrix(Vec<f64>),
}

impl StructuredP0 {
    pub(crate) fn read(p0: Option<&Bound<'_, PyAny>>, np: usize, ne: usize, per: &str) -> PyResult<Self> {
        let expected = format!("\"exact\", a number, one per {per}, or a ({np}, {np}) matrix");
        let Some(a) = p0_value(p0, &expected)? else { return Ok(Self::Exact) };
        match a.shape[..] {
            [] => Ok(Self::Scalar(a.data[0])),
            [len] if len == ne => Ok(Self::PerEquation(a.data)),
            [r, c] if r == np && c == np => Ok(Self::Matrix(a.data)),
            _ => Err(VehidError::new_err(format!(
                "`p0` must be \"exact\", a scalar, one per {per} ({ne},) or a ({np}, {np}) matrix, got {}",
                shape_str(&a.shape)
            ))),
        }
    }

    /// The core's view of it.
    pub(crate) fn prior(&self) -> StructuredPrior<'_, f64> {
        match self {
            Self::Exact => StructuredPrior::Exact,
            Self::Scalar(v) => StructuredPrior::Scalar(*v),
            Self::PerEquation(v) => StructuredPrior::PerEquation(v),
            Self::Matrix(v) => StructuredPrior::Matrix(v),
        }
    }
}

/// The recursive least-squares identifier of a structure: parses `p0`, `theta0` and `r` for
/// it and picks the filter size from the largest parameter group.
pub(crate) fn kalman_on_structure(
    s: &PyStructure,
    p0: Option<&Bound<'_, PyAny>>,
    r: Option<&Bound<'_, PyAny>>,
    theta0: Option<&Bound<'_, PyAny>>,
    opts: KalmanOptions<f64>,
) -> PyResult<Box<dyn DynIdentifier<f64>>> {
    let (np, ne) = (s.core.params(), s.core.equations());
    let p0 = StructuredP0::read(p0, np, ne, "identified equation")?;
    let p0 = p0.prior();
    let theta0 = match theta0 {
        Some(t) => Some(vec_arg(t, "theta0", np)?),
        None => None,
    };
    let r = match r {
        None => vec![1.0],
        Some(r) => {
            let a = array(r, "r")?;
            finite("r", &a.data)?;
            if !(a.shape.is_empty() || a.shape == [ne]) {
                return Err(VehidError::new_err(format!(
                    "`r` must be a scalar or one variance per identified equation, shape ({ne},), got {}",
                    shape_str(&a.shape)
                )));
            }
            a.data
        }
    };
    vehid_runtime::build::structured_kalman(s.core, p0, theta0.as_deref(), &r, opts).map_err(core_err)
}

/// The known constants of a car, one per [`CarKind::constants`], from a dict mapping constant
/// names to values (`None`: nothing known).
pub(crate) fn known_constants(car: CarKind, known: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<Option<f64>>> {
    let consts = car.constants();
    let mut k = vec![None; consts.len()];
    if let Some(d) = known.filter(|d| !d.is_none()) {
        let d = d.cast::<PyDict>().map_err(|_| {
            VehidError::new_err(format!("`known` must be a dict of known constants, e.g. {{\"{}\": 1.0}}", consts[1]))
        })?;
        for (key, v) in d.iter() {
            let key: String = key.extract().map_err(|_| VehidError::new_err("`known`: keys must be names"))?;
            let Some(c) = consts.iter().position(|c| *c == key) else {
                return Err(VehidError::new_err(format!(
                    "`known`: {} has no constant {key:?} (its constants: {})",
                    car.name(),
                    consts.join(", ")
                )));
            };
            let val: f64 =
                v.extract().map_err(|_| VehidError::new_err(format!("`known[{key:?}]` must be a number")))?;
            k[c] = Some(val);
        }
    }
    Ok(k)
}

/// Refuses keyword arguments that only make sense for a linear model.
pub(crate) fn refuse_for_structure(what: &str, given: bool) -> PyResult<()> {
    if given {
        return Err(PyTypeError::new_err(format!(
            "`{what}` applies to a LinearModel only: on a Structure give `r=` (one variance per identified equation)"
        )));
    }
    Ok(())
}

/// Validates identified parameters by free-run simulation on (held-out) data: simulates
/// `structure` with `params` from the first measured state `x[0]` over the measured inputs
/// `u` (samples, m) (or `samples = len(x)` without inputs), `dt` seconds apart, and compares
/// with the measured states `x` (samples, n). Returns {"x_sim": (samples, n), "fit": (n,)
/// percent, 100 (1 − ‖x − x̂‖/‖x − mean x‖), "rmse": (n,)} (Ljung 1999 §16.6).
#[pyfunction]
#[pyo3(signature = (structure, params, x, u = None, *, dt, substeps = 10))]
pub(crate) fn validate<'py>(
    py: Python<'py>,
    structure: &Bound<'py, PyStructure>,
    params: &Bound<'py, PyAny>,
    x: &Bound<'py, PyAny>,
    u: Option<&Bound<'py, PyAny>>,
    dt: f64,
    substeps: u32,
) -> PyResult<Bound<'py, PyDict>> {
    let s = structure.get();
    let n = s.core.states();
    let xa = array(x, "x")?;
    if xa.shape.len() != 2 || xa.shape[1] != n || xa.shape[0] == 0 {
        return Err(VehidError::new_err(format!(
            "`x` must have shape (samples, {n}) (the measured states), got {}",
            shape_str(&xa.shape)
        )));
    }
    finite("x", &xa.data)?;
    let len = xa.shape[0];
    let x0 = numpy::PyArray1::from_slice(py, &xa.data[..n]);
    let sim = s.simulate_vec(py, params, x0.as_any(), u, dt, Some(len), substeps)?;
    let (mut fit, mut rmse) = (vec![0.0; n], vec![0.0; n]);
    vehid_core::metrics::simulation_fit(&xa.data, &sim, n, &mut fit, &mut rmse).map_err(core_err)?;
    let out = PyDict::new(py);
    out.set_item("x_sim", crate::model::to_array2(py, len, n, sim)?)?;
    out.set_item("fit", numpy::PyArray1::from_vec(py, fit))?;
    out.set_item("rmse", numpy::PyArray1::from_vec(py, rmse))?;
    Ok(out)
}

/// The stochastic-gradient identifier of a structure (weights `h`: one, or one per parameter).
pub(crate) fn gradient_on_structure(
    s: &PyStructure,
    gain: Gain<f64>,
    h: &[f64],
    spacing: u32,
) -> PyResult<Box<dyn DynIdentifier<f64>>> {
    vehid_runtime::build::structured_gradient(s.core, gain, h, spacing).map_err(core_err)
}
