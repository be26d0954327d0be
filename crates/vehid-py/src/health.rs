//! `HealthMonitor` and `Event`: the core's [`health::HealthMonitor`] for the
//! quarter car, [`health::HalfHealthMonitor`] for the half car and
//! [`health::FullHealthMonitor`] for the full car. Conversion and validation
//! only; the core does every computation.

use crate::convert::{array, py_str, shape_str, Table};
use crate::guard::{borrow, borrow_mut, Interrupts};
use crate::model::{Kind, PyLinearModel};
use crate::{core_err, option, VehidError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};
use vehid_core::health::{self, HealthConfig, Reason, Status};
use vehid_core::identify::FitError;
use vehid_core::model::{FullCar, HalfConstant, CORNERS};
use vehid_core::sim::FullConstant;
use vehid_core::sim::SensorSet;

/// Samples between two looks at pending signals in `fit` (some 100 ns each).
const CHECK: usize = 1 << 16;

/// Version of a pickled monitor's state layout (raise it when the core's serialized form
/// changes in a way older readers cannot follow). 3: the full car's monitor names the
/// anti-roll bars (two more CUSUMs); the quarter and half car's states are those of 2.
pub const STATE_FORMAT: u32 = 3;

/// A detected change of one physical constant (reported by `HealthMonitor`).
///
/// `t` is when it was reported and `t_change` the estimated onset (s); `parameter` names the
/// constant ('b' damper, N s/m; 'k2' spring, N/m; 'M' body mass, kg); `before` and `after` are
/// its values, `low` .. `high` the interval of `after` (the monitor's `confidence`, 95 % by
/// default), `change` the relative change `after / before - 1`. `position`: for a full car's
/// 'M' event whose changes fit a point load, where it was set down, `(x, y)` m from the nominal
/// car's centre of mass (x forward, y to the left); else None.
#[pyclass(name = "Event", module = "vehid._vehid", frozen, eq)]
#[derive(Clone, PartialEq)]
pub struct PyEvent {
    /// When the event was reported, s (sample index × dt).
    #[pyo3(get)]
    t: f64,
    /// Estimated onset, s.
    #[pyo3(get)]
    t_change: f64,
    /// The constant: 'b', 'k2' or 'M' (quarter car); 'b_f', 'b_r', 'k2_f', 'k2_r' or 'M'
    /// (half car); 'k_fl' .. 'k_rr', 'b_fl' .. 'b_rr', 'M', 'arb_f' or 'arb_r' (full car; N m/rad for
    /// an anti-roll bar).
    #[pyo3(get)]
    parameter: &'static str,
    /// Its value before, in its unit (N s/m, N/m, kg).
    #[pyo3(get)]
    before: f64,
    /// Its value after.
    #[pyo3(get)]
    after: f64,
    /// Lower end of the interval of `after`.
    #[pyo3(get)]
    low: f64,
    /// Upper end of the interval of `after`.
    #[pyo3(get)]
    high: f64,
    /// The relative change after / before - 1.
    #[pyo3(get)]
    change: f64,
    /// Where a point load was set down, (x, y) m from the centre of mass, or None.
    #[pyo3(get)]
    position: Option<(f64, f64)>,
}

impl From<health::Event<f64, HalfConstant>> for PyEvent {
    fn from(e: health::Event<f64, HalfConstant>) -> Self {
        Self {
            t: e.t,
            t_change: e.t_change,
            parameter: e.parameter.as_str(),
            before: e.before,
            after: e.after,
            low: e.low,
            high: e.high,
            change: e.change,
            position: e.position.map(|[x, y]| (x, y)),
        }
    }
}

impl From<health::Event<f64, FullConstant>> for PyEvent {
    fn from(e: health::Event<f64, FullConstant>) -> Self {
        Self {
            t: e.t,
            t_change: e.t_change,
            parameter: e.parameter.as_str(),
            before: e.before,
            after: e.after,
            low: e.low,
            high: e.high,
            change: e.change,
            position: e.position.map(|[x, y]| (x, y)),
        }
    }
}

impl From<health::Event<f64>> for PyEvent {
    fn from(e: health::Event<f64>) -> Self {
        Self {
            t: e.t,
            t_change: e.t_change,
            parameter: e.parameter.as_str(),
            before: e.before,
            after: e.after,
            low: e.low,
            high: e.high,
            change: e.change,
            position: e.position.map(|[x, y]| (x, y)),
        }
    }
}

#[pymethods]
impl PyEvent {
    /// An event from its fields (what unpickling calls; the monitor makes them otherwise).
    #[new]
    #[pyo3(signature = (t, t_change, parameter, before, after, low, high, change, position = None))]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        t: f64,
        t_change: f64,
        parameter: &str,
        before: f64,
        after: f64,
        low: f64,
        high: f64,
        change: f64,
        position: Option<(f64, f64)>,
    ) -> PyResult<Self> {
        if position.is_some() && parameter != "M" {
            return Err(VehidError::new_err(format!(
                "`position` is where a load was set down: for parameter 'M' only, got {}",
                py_str(parameter)
            )));
        }
        let parameter = match parameter {
            "M" => "M",
            "k2" => "k2",
            "b" => "b",
            other => match (other.parse::<HalfConstant>(), other.parse::<FullConstant>()) {
                (Ok(c), _) if health::HALF_NAMED.contains(&c) => c.as_str(),
                (_, Ok(c)) if health::FULL_NAMED.contains(&c) => c.as_str(),
                _ => {
                    return Err(VehidError::new_err(format!(
                        "`parameter` must be 'M', 'k2' or 'b' (quarter car), 'k2_f', 'b_f', 'k2_r', 'b_r' (half \
                         car) or 'k_fl' .. 'k_rr', 'b_fl' .. 'b_rr', 'arb_f', 'arb_r' (full car), got {}",
                        py_str(other)
                    )))
                }
            },
        };
        Ok(Self { t, t_change, parameter, before, after, low, high, change, position })
    }

    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let e = slf.get();
        let args = (e.t, e.t_change, e.parameter, e.before, e.after, e.low, e.high, e.change, e.position);
        (slf.get_type(), args).into_pyobject(slf.py())
    }

    /// The event as a dict (JSON-ready): t, t_change, parameter, before, after, low, high, change,
    /// and load_x, load_y for an event with a `position`.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("t", self.t)?;
        d.set_item("t_change", self.t_change)?;
        d.set_item("parameter", self.parameter)?;
        for (k, v) in [
            ("before", self.before),
            ("after", self.after),
            ("low", self.low),
            ("high", self.high),
            ("change", self.change),
        ] {
            d.set_item(k, v)?;
        }
        if let Some((x, y)) = self.position {
            d.set_item("load_x", x)?;
            d.set_item("load_y", y)?;
        }
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let at = self.position.map_or(String::new(), |(x, y)| format!(", position=({x:?}, {y:?})"));
        format!(
            "Event(t={:?}, parameter={}, before={:?}, after={:?}, low={:?}, high={:?}, change={:?}{at})",
            self.t,
            py_str(self.parameter),
            self.before,
            self.after,
            self.low,
            self.high,
            self.change
        )
    }
}

/// The suspension health monitor of a quarter car (Rust: `vehid_core::health`): tracks
/// `k2/M` and `b/M` from the car's sensors and reports which constant changed, when, and
/// to what, with an interval.
///
/// `car` is the nominal `QuarterCar` (its M, k2, b are the `before` of the first events);
/// `dt` the sample interval, s; `sensors` "realistic" (`y` rows `[a_body, a_wheel,
/// deflection]`, m/s², m/s², m) or "state" (`[zw, vw, zb, vb, dzw, dvw, dzb, dvb]`, the
/// thesis' measured state and derivative). `sensor_noise` (the Simulator's keys) designs the
/// kinematic filter; the other settings are those of `HealthConfig` (defaults: window 6 s,
/// warmup 20 s, settle 4 s, reacquire 2 s, min_change 0.05, judge_error 0.008, threshold 8,
/// confidence 0.95, systematic 0.005, stuck_samples 20).
///
/// Only `k2/M` and `b/M` are observable without a road measurement: a change of both by the
/// same factor is reported as the body mass. A NaN channel is a missing sample (a gap); the
/// monitor then cannot judge for a while and never reports meanwhile (`status`).
///
/// With a `HalfCar` (Rust `HalfHealthMonitor`): `y` rows `[a_body_f, a_body_r, a_wheel_f,
/// a_wheel_r, deflection_f, deflection_r]` (body accelerometers above each axle, wheel
/// accelerometers, suspension extensions) or the 16 state channels; events name 'k2_f',
/// 'b_f', 'k2_r', 'b_r' or 'M' (a body-mass event assumes J scales with M and moves both).
///
/// With a `FullCar` (Rust `FullHealthMonitor`): `y` rows the 12 channels `[a_body_fl,
/// a_body_fr, a_body_rl, a_body_rr, a_wheel_fl, .., a_wheel_rr, deflection_fl, ..,
/// deflection_rr]` (a body accelerometer above each wheel, wheel accelerometers, suspension
/// extensions) or the 28 state channels; events name the corner, 'k_fl' .. 'k_rr',
/// 'b_fl' .. 'b_rr', or 'M': a load, spread like the body's own mass (Jx and Jy scale with M)
/// or, when a point mass fits the changes better, set down where the event's `position` says
/// (its mass added to M, Jx and Jy about the nominal centre of mass).
#[pyclass(name = "HealthMonitor", module = "vehid._vehid")]
pub struct PyHealthMonitor {
    inner: Mon,
}

/// The monitor of either car.
#[derive(Clone)]
enum Mon {
    Quarter(Box<health::HealthMonitor<f64>>),
    Half(Box<health::HalfHealthMonitor<f64>>),
    Full(Box<health::FullHealthMonitor<f64>>),
}

impl Mon {
    fn channels(&self) -> usize {
        match self {
            Mon::Quarter(m) => m.config().channels(),
            Mon::Half(m) => m.config().channels(),
            Mon::Full(m) => m.config().channels(),
        }
    }

    fn sensors(&self) -> SensorSet {
        match self {
            Mon::Quarter(m) => m.config().sensors,
            Mon::Half(m) => m.config().sensors,
            Mon::Full(m) => m.config().sensors,
        }
    }

    fn dt(&self) -> f64 {
        match self {
            Mon::Quarter(m) => m.config().dt,
            Mon::Half(m) => m.config().dt,
            Mon::Full(m) => m.config().dt,
        }
    }

    fn status(&self) -> Status {
        match self {
            Mon::Quarter(m) => m.status(),
            Mon::Half(m) => m.status(),
            Mon::Full(m) => m.status(),
        }
    }

    fn samples(&self) -> u64 {
        match self {
            Mon::Quarter(m) => m.samples(),
            Mon::Half(m) => m.samples(),
            Mon::Full(m) => m.samples(),
        }
    }

    fn events(&self) -> u64 {
        match self {
            Mon::Quarter(m) => m.events(),
            Mon::Half(m) => m.events(),
            Mon::Full(m) => m.events(),
        }
    }

    /// The rows of `data` (`n` channels each) through the monitor, all or nothing
    /// (`health::fit_rows`), `interrupt` asked every [`CHECK`] samples.
    fn fit_rows(
        &mut self,
        data: &[f64],
        n: usize,
        interrupt: &mut dyn FnMut() -> bool,
    ) -> Result<Vec<PyEvent>, FitError> {
        fn run<M: health::Monitor<f64>>(
            m: &mut M,
            data: &[f64],
            n: usize,
            interrupt: &mut dyn FnMut() -> bool,
        ) -> Result<Vec<PyEvent>, FitError>
        where
            PyEvent: From<health::Event<f64, M::Constant>>,
        {
            let mut events = Vec::new();
            health::fit_rows(m, data, n, &mut events, CHECK, interrupt)?;
            Ok(events.into_iter().map(PyEvent::from).collect())
        }
        match self {
            Mon::Quarter(m) => run(&mut **m, data, n, interrupt),
            Mon::Half(m) => run(&mut **m, data, n, interrupt),
            Mon::Full(m) => run(&mut **m, data, n, interrupt),
        }
    }

    fn update(&mut self, y: &[f64]) -> vehid_core::Result<Option<PyEvent>> {
        Ok(match self {
            Mon::Quarter(m) => m.update(y)?.map(PyEvent::from),
            Mon::Half(m) => m.update(y)?.map(PyEvent::from),
            Mon::Full(m) => m.update(y)?.map(PyEvent::from),
        })
    }

    fn channel_names(&self) -> &'static [&'static str] {
        match self {
            Mon::Quarter(_) => self.sensors().channels(),
            Mon::Half(_) => self.sensors().half_channels(),
            Mon::Full(_) => self.sensors().full_channels(),
        }
    }
}

/// The half car's constants as the monitor names them (`HalfConstant`, then the lever arms).
const HALF_KEYS: [&str; 12] = ["M", "J", "k1_f", "k1_r", "k2_f", "k2_r", "b_f", "b_r", "m_f", "m_r", "l1", "l2"];

/// The status as a string: "warmup", "monitoring", "settling", or "cannot judge: <reason>".
fn status_str(s: Status) -> &'static str {
    match s {
        Status::Warmup => "warmup",
        Status::Monitoring => "monitoring",
        Status::Settling => "settling",
        Status::CannotJudge(r) => match r {
            Reason::LowExcitation => "cannot judge: low excitation",
            Reason::Missing => "cannot judge: missing samples",
            Reason::Stuck => "cannot judge: stuck sensor",
            Reason::Jump => "cannot judge: jump in the data",
            Reason::Reacquiring => "cannot judge: reacquiring",
            Reason::Sensors => "cannot judge: sensors disagree",
        },
    }
}

#[pymethods]
impl PyHealthMonitor {
    #[new]
    #[pyo3(signature = (car, dt = 0.005, sensors = "realistic", sensor_noise = None, *, window = None, warmup = None,
                        settle = None, reacquire = None, min_change = None, judge_error = None, threshold = None,
                        confidence = None, systematic = None, stuck_samples = None))]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        car: &Bound<'_, PyLinearModel>,
        dt: f64,
        sensors: &str,
        sensor_noise: Option<&Bound<'_, PyDict>>,
        window: Option<f64>,
        warmup: Option<f64>,
        settle: Option<f64>,
        reacquire: Option<f64>,
        min_change: Option<f64>,
        judge_error: Option<f64>,
        threshold: Option<f64>,
        confidence: Option<f64>,
        systematic: Option<f64>,
        stuck_samples: Option<i128>,
    ) -> PyResult<Self> {
        let set: SensorSet = option(sensors)?;
        let noise = crate::drive::sensor_noise_arg(sensor_noise)?;
        macro_rules! settings {
            ($cfg:ident) => {
                for (v, slot) in [
                    (window, &mut $cfg.window),
                    (warmup, &mut $cfg.warmup),
                    (settle, &mut $cfg.settle),
                    (reacquire, &mut $cfg.reacquire),
                    (min_change, &mut $cfg.min_change),
                    (judge_error, &mut $cfg.judge_error),
                    (threshold, &mut $cfg.threshold),
                    (confidence, &mut $cfg.confidence),
                    (systematic, &mut $cfg.systematic),
                ] {
                    if let Some(v) = v {
                        *slot = v;
                    }
                }
                if let Some(n) = stuck_samples {
                    $cfg.stuck_samples = usize::try_from(n).map_err(|_| {
                        VehidError::new_err(format!("`stuck_samples` must be an integer between 2 and 64, got {n}"))
                    })?;
                }
            };
        }
        let inner = match car.get().kind {
            Kind::Quarter(c) => {
                let mut cfg = HealthConfig::new(dt, c).with_sensors(set, &noise);
                settings!(cfg);
                Mon::Quarter(Box::new(health::HealthMonitor::new(cfg).map_err(core_err)?))
            }
            Kind::Half(c) => {
                let mut cfg = HealthConfig::new(dt, c).with_sensors(set, &noise);
                settings!(cfg);
                Mon::Half(Box::new(health::HalfHealthMonitor::new(cfg).map_err(core_err)?))
            }
            Kind::Full(c) => {
                let mut cfg = HealthConfig::new(dt, c).with_sensors(set, &noise);
                settings!(cfg);
                Mon::Full(Box::new(health::FullHealthMonitor::new(cfg).map_err(core_err)?))
            }
            Kind::Generic => {
                return Err(VehidError::new_err("`car` must be a vehid.QuarterCar, a vehid.HalfCar or a vehid.FullCar"))
            }
        };
        Ok(Self { inner })
    }

    /// One sample `y_k` (its channels, as `sensors` says); returns the event it completes, as
    /// a list of 0 or 1 `Event`. ±inf is a VehidError (nothing changes); NaN marks a
    /// missing channel.
    fn update(slf: &Bound<'_, Self>, y_k: &Bound<'_, PyAny>) -> PyResult<Vec<PyEvent>> {
        let mut this = borrow_mut(slf)?;
        let n = this.inner.channels();
        let a = array(y_k, "y_k")?;
        if a.shape != [n] {
            return Err(VehidError::new_err(format!(
                "`y_k` must have shape ({n},) ({} per row), got {}",
                this.inner.channel_names().join(", "),
                shape_str(&a.shape)
            )));
        }
        let ev = this.inner.update(&a.data).map_err(|e| VehidError::new_err(format!("`y_k`: {e}")))?;
        Ok(ev.into_iter().collect())
    }

    /// Many samples `y` (N, channels), in order (the GIL is released); returns the events
    /// they complete. All or nothing: a row with ±inf is a VehidError naming it, and the
    /// monitor is unchanged. NaN marks missing channels (gaps in a log: rows of NaN).
    fn fit(slf: &Bound<'_, Self>, y: &Bound<'_, PyAny>) -> PyResult<Vec<PyEvent>> {
        let py = slf.py();
        let mut this = borrow_mut(slf)?;
        let n = this.inner.channels();
        let names = this.inner.channel_names().join(", ") + " per row";
        let table = Table::new(y, "y", None, n, &names)?;
        let data = table.data();
        if let Some(i) = data.iter().position(|v| v.is_infinite()) {
            return Err(VehidError::new_err(format!(
                "`y[{}, {}]` is infinite: drop that sample or mark it missing with NaN; the monitor is unchanged",
                i / n,
                i % n
            )));
        }
        let mut signals = Interrupts::new();
        let mon = &mut this.inner;
        // All or nothing (the core's `fit_rows`): a rejected sample or an interrupt leaves the
        // monitor as it was.
        match py.detach(|| mon.fit_rows(data, n, &mut || signals.check())) {
            Ok(events) => Ok(events),
            Err(FitError { error: vehid_core::Error::Interrupted, .. }) => {
                Err(signals.raise().unwrap_or_else(|| core_err(vehid_core::Error::Interrupted)))
            }
            Err(FitError { sample: Some(k), error }) => {
                Err(VehidError::new_err(format!("sample {k} was rejected ({error}); the monitor is unchanged")))
            }
            Err(FitError { sample: None, error }) => Err(core_err(error)),
        }
    }

    /// What the monitor is doing: "warmup", "monitoring", "settling", or "cannot judge:
    /// low excitation" / "missing samples" / "stuck sensor" / "jump in the data" /
    /// "reacquiring" / "sensors disagree".
    #[getter]
    fn status(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        Ok(status_str(borrow(slf)?.inner.status()))
    }

    /// Samples seen.
    #[getter]
    fn samples(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(borrow(slf)?.inner.samples())
    }

    /// Events reported so far.
    #[getter]
    fn events(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(borrow(slf)?.inner.events())
    }

    /// The current belief {"M": kg, "k2": N/m, "b": N s/m}: the nominal car's, moved by every
    /// event. Half car: {"M", "J", "k1_f", "k1_r", "k2_f", "k2_r", "b_f", "b_r", "m_f", "m_r",
    /// "l1", "l2"} (kg, kg m², N/m, N s/m, m). Full car: the 25 constants of
    /// `FullCar.CONSTANTS` (a body-mass event moves M, Jx and Jy).
    #[getter]
    fn constants<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(slf.py());
        match &borrow(slf)?.inner {
            Mon::Quarter(m) => {
                let [mb, k2, b] = m.constants();
                d.set_item("M", mb)?;
                d.set_item("k2", k2)?;
                d.set_item("b", b)?;
            }
            Mon::Half(m) => {
                for (k, v) in HALF_KEYS.iter().zip(m.constants()) {
                    d.set_item(*k, v)?;
                }
            }
            Mon::Full(m) => {
                for (k, v) in FullCar::<f64>::CONSTANTS.iter().zip(m.constants()) {
                    d.set_item(*k, v)?;
                }
            }
        }
        Ok(d)
    }

    /// The tracked ratios {"k2/M": (value, low, high) 1/s², "b/M": (...) 1/s, "c": (...) m/s²}
    /// with the `confidence` intervals. Half car: {"front": [...], "rear": [...]}, each the
    /// five coefficients of that body-corner equation `[α k2_f, α b_f, α k2_r, α b_r, c]` as
    /// (value, low, high) (the α of that corner: module docs of `vehid_core::health`). Full
    /// car: {"fl": [...], "fr": [...], "rl": [...], "rr": [...]}, each the nine coefficients
    /// of that corner's equation (the extension's and the rate's of fl, fr, rl, rr, then the
    /// offset c) as (value, low, high).
    #[getter]
    fn estimate<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(slf.py());
        match &borrow(slf)?.inner {
            Mon::Quarter(m) => {
                let e = m.estimate();
                for (j, name) in ["k2/M", "b/M", "c"].into_iter().enumerate() {
                    d.set_item(name, (e.value[j], e.low[j], e.high[j]))?;
                }
            }
            Mon::Half(m) => {
                let e = m.estimate();
                for (o, name) in ["front", "rear"].into_iter().enumerate() {
                    let row: Vec<(f64, f64, f64)> =
                        (0..5).map(|j| (e.value[o][j], e.low[o][j], e.high[o][j])).collect();
                    d.set_item(name, row)?;
                }
            }
            Mon::Full(m) => {
                let e = m.estimate();
                for (o, name) in CORNERS.into_iter().enumerate() {
                    let row: Vec<(f64, f64, f64)> =
                        (0..9).map(|j| (e.value[o][j], e.low[o][j], e.high[o][j])).collect();
                    d.set_item(name, row)?;
                }
            }
        }
        Ok(d)
    }

    /// The reference ratios {"k2/M": 1/s², "b/M": 1/s} the tracked ones are compared with
    /// (None during the warm-up). Half car: {"front": [5 coefficients], "rear": [...]}. Full
    /// car: {"fl": [9 coefficients], "fr", "rl", "rr"}.
    #[getter]
    fn reference<'py>(slf: &Bound<'py, Self>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let d = PyDict::new(slf.py());
        match &borrow(slf)?.inner {
            Mon::Quarter(m) => {
                let Some([k, b]) = m.reference() else { return Ok(None) };
                d.set_item("k2/M", k)?;
                d.set_item("b/M", b)?;
            }
            Mon::Half(m) => {
                let Some([f, r]) = m.reference() else { return Ok(None) };
                d.set_item("front", f.to_vec())?;
                d.set_item("rear", r.to_vec())?;
            }
            Mon::Full(m) => {
                let Some(rows) = m.reference() else { return Ok(None) };
                for (name, row) in CORNERS.into_iter().zip(rows) {
                    d.set_item(name, row.to_vec())?;
                }
            }
        }
        Ok(Some(d))
    }

    /// Sample interval, s.
    #[getter]
    fn dt(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.inner.dt())
    }

    /// "realistic" or "state".
    #[getter]
    fn sensors(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        Ok(borrow(slf)?.inner.sensors().as_str())
    }

    /// The channel names a sample holds, in order.
    #[getter]
    fn channels<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(slf.py(), borrow(slf)?.inner.channel_names())
    }

    /// Pickling: `(copyreg.__newobj__, (HealthMonitor, car, dt), state)`, the state
    /// `(FORMAT, "vehid <version>", postcard bytes of the core monitor)`; a restored monitor
    /// continues bit for bit.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let this = borrow(slf)?;
        let module = py.import("vehid._vehid")?;
        let (car, bytes) = match &this.inner {
            Mon::Quarter(m) => {
                let c = m.config().car;
                let car = module.getattr("QuarterCar")?.call1((c.m_body(), c.m_wheel(), c.k1(), c.k2(), c.b()))?;
                (car, vehid_runtime::seal::seal(m))
            }
            Mon::Half(m) => {
                let kwargs = PyDict::new(py);
                for (k, v) in m.config().car.params().named() {
                    kwargs.set_item(k, v)?;
                }
                (module.getattr("HalfCar")?.call((), Some(&kwargs))?, vehid_runtime::seal::seal(m))
            }
            Mon::Full(m) => {
                let kwargs = PyDict::new(py);
                for (k, v) in m.config().car.params().named() {
                    kwargs.set_item(k, v)?;
                }
                (module.getattr("FullCar")?.call((), Some(&kwargs))?, vehid_runtime::seal::seal(m))
            }
        };
        let bytes = bytes.map_err(|e| VehidError::new_err(format!("the monitor cannot be saved: {e}")))?;
        let state = (STATE_FORMAT, format!("vehid {}", env!("CARGO_PKG_VERSION")), PyBytes::new(py, &bytes));
        let newobj = py.import("copyreg")?.getattr("__newobj__")?;
        (newobj, (slf.get_type(), car, this.inner.dt()), state).into_pyobject(py)
    }

    /// Restores a pickled monitor's state (checked: a corrupt state is a VehidError).
    fn __setstate__(slf: &Bound<'_, Self>, state: &Bound<'_, PyAny>) -> PyResult<()> {
        let corrupt = |what: &str| {
            VehidError::new_err(format!(
                "cannot restore the health monitor: {what} (the pickle is corrupt, or was not made by vehid)"
            ))
        };
        let Ok((format, version, payload)) = state.extract::<(u32, String, Vec<u8>)>() else {
            return Err(corrupt("its state is not a (format, version, bytes) tuple"));
        };
        let mut this = borrow_mut(slf)?;
        // Format 2 states of the quarter and half car's monitors are those of 3.
        let readable = format == STATE_FORMAT || (format == 2 && !matches!(this.inner, Mon::Full(_)));
        if !readable {
            let oldest = if matches!(this.inner, Mon::Full(_)) { STATE_FORMAT } else { 2 };
            return Err(VehidError::new_err(format!(
                "cannot restore the health monitor: it was pickled by {version} in state format {format}, and \
                 this vehid ({}) reads this car's monitor in formats {oldest} to {STATE_FORMAT} only; run the monitor \
                 again from its log, or load it with the version that saved it",
                env!("CARGO_PKG_VERSION")
            )));
        }
        let decode = |e: vehid_runtime::seal::Error| {
            corrupt(&format!("its payload does not decode or fails its checksum ({e})"))
        };
        this.inner = match this.inner {
            Mon::Quarter(_) => Mon::Quarter(Box::new(vehid_runtime::seal::open(&payload).map_err(decode)?)),
            Mon::Half(_) => Mon::Half(Box::new(vehid_runtime::seal::open(&payload).map_err(decode)?)),
            Mon::Full(_) => Mon::Full(Box::new(vehid_runtime::seal::open(&payload).map_err(decode)?)),
        };
        Ok(())
    }

    fn __copy__(slf: &Bound<'_, Self>) -> PyResult<Self> {
        Ok(Self { inner: borrow(slf)?.inner.clone() })
    }

    fn __deepcopy__(slf: &Bound<'_, Self>, _memo: &Bound<'_, PyAny>) -> PyResult<Self> {
        Ok(Self { inner: borrow(slf)?.inner.clone() })
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let this = borrow(slf)?;
        Ok(format!(
            "HealthMonitor(dt={:?}, sensors={}, samples={}, events={}, status={})",
            this.inner.dt(),
            py_str(this.inner.sensors().as_str()),
            this.inner.samples(),
            this.inner.events(),
            py_str(status_str(this.inner.status()))
        ))
    }
}
