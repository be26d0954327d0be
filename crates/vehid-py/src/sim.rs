//! `Simulator` and `Run`.

use crate::convert::{size, speed_arg, uint, values};
use crate::drive::{DriveRun, DriveSim, Unused};
use crate::guard::{borrow, borrow_mut, Interrupts};
use crate::identify::raise;
use crate::model::{to_array2, PyLinearModel};
use crate::two_axle::{half_dims, wheelbase_of};
use crate::{core_err, option, VehidError};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use vehid_core::sim::{Method, Pulse, RoadConfig, RoadMode, RoadSimulator, Run, SimConfig, SpeedProfile};
use vehid_core::Result;
use vehid_runtime::sim::{reserve_run, sim_chunk, simulator, SimDyn, SimParams};

/// Road memory of the Python road simulator, in road points per wheelbase (+2).
pub const ROAD_CELLS: usize = 4096;

/// `Simulator(..., speed=, spacing=, road=)`: a [`RoadSimulator`] of the half car with its
/// speed profile (a constant, or one entry per sample with stops; the core runs it).
pub struct RoadSim {
    sim: RoadSimulator<f64, 8, ROAD_CELLS>,
    /// Per-sample speeds, m/s (empty: the constant `speed`).
    speeds: Vec<f64>,
    speed: f64,
    /// The first unused entry of `speeds`.
    next: usize,
    /// Length of a stop (a zero entry), s.
    stop: f64,
}

impl SimDyn for RoadSim {
    fn run(&mut self, n: usize, interrupt: &mut dyn FnMut() -> bool) -> Result<Run<f64>> {
        let mut profile = if self.speeds.is_empty() {
            SpeedProfile::Constant(self.speed)
        } else {
            SpeedProfile::PerSample { speeds: &self.speeds, next: self.next, stop: self.stop }
        };
        // Check before reserving: a profile that cannot produce `n` samples is an error (the
        // entries the run uses; the whole profile was checked when the simulator was made).
        profile.check_next(n)?;
        let mut out = reserve_run(n, 8, 2, true)?;
        // All or nothing: the road state (some 40 kB) is kept to undo a run that fails or is
        // interrupted part way.
        let start = self.sim.clone();
        let chunk = sim_chunk(8);
        let mut done = 0;
        let mut step = || -> Result<()> {
            while done < n {
                if done > 0 && interrupt() {
                    return Err(vehid_core::Error::Interrupted);
                }
                let m = chunk.min(n - done);
                self.sim.run_profile(m, &mut profile, |s| out.push_road(s))?;
                done += m;
            }
            Ok(())
        };
        if let Err(e) = step() {
            self.sim = start;
            return Err(e);
        }
        if let SpeedProfile::PerSample { next, .. } = profile {
            self.next = next;
        }
        Ok(out)
    }

    fn substeps(&self) -> usize {
        0
    }

    fn samples(&self) -> u64 {
        self.sim.k()
    }
}

/// Builds the road simulator for `Simulator(model, speed=..., spacing=..., road=...)`.
fn road_simulator(
    model: &PyLinearModel,
    p: &SimParams,
    speed: Option<&Bound<'_, PyAny>>,
    spacing: f64,
    road: RoadMode,
) -> PyResult<RoadSim> {
    half_dims(&model.data, "speed=/spacing=/road= (two axles on one road)")?;
    if !p.pulses.is_empty() {
        return Err(VehidError::new_err(
            "`pulses` are not supported with speed=/spacing=/road= (samples are by distance)",
        ));
    }
    let (speed, speeds) = speed_arg(speed, 6.0)?;
    let profile = if speeds.is_empty() {
        SpeedProfile::Constant(speed)
    } else {
        SpeedProfile::PerSample { speeds: &speeds, next: 0, stop: p.dt }
    };
    profile.validate().map_err(core_err)?;
    let wheelbase = wheelbase_of(model, None)?;
    let build = || -> Result<RoadSimulator<f64, 8, ROAD_CELLS>> {
        let cfg = SimConfig::<f64, 8, 2>::from_settings(&p.settings())?;
        RoadSimulator::new(model.data.model::<8, 2>()?, cfg, RoadConfig::new(spacing, wheelbase).mode(road), p.seed)
    };
    Ok(RoadSim { sim: build().map_err(core_err)?, speeds, speed, next: 0, stop: p.dt })
}

/// One stretch of a simulation: every field is a float64 array with the sample index first.
#[pyclass(name = "Run", module = "vehid._vehid", frozen)]
pub struct PyRun {
    /// Sample times t_k = k·dt, s, (N,).
    #[pyo3(get)]
    t: Py<PyArray1<f64>>,
    /// True state x(k), (N, n).
    #[pyo3(get)]
    x: Py<PyArray2<f64>>,
    /// True derivative ẋ(k) = A x(k) + B u(k), (N, n).
    #[pyo3(get)]
    xdot: Py<PyArray2<f64>>,
    /// Road input u(k), held until the next sample, (N, m).
    #[pyo3(get)]
    u: Py<PyArray2<f64>>,
    r: Option<Py<PyArray2<f64>>>,
    z: Option<Py<PyArray2<f64>>>,
    /// Distance travelled, m, (N,), when the simulator was given speed=/spacing=/road=; else None.
    #[pyo3(get)]
    s: Option<Py<PyArray1<f64>>>,
    y: Option<Py<PyArray2<f64>>>,
    channels: Option<Vec<&'static str>>,
    constants: Option<Py<PyArray2<f64>>>,
    len: usize,
    n_states: usize,
    n_inputs: usize,
}

#[pymethods]
impl PyRun {
    /// Measured state r(k) = x(k) + w(k), (N, n). A drive with sensors='realistic' measures
    /// no state: VehidError (its measurements are `y`).
    #[getter]
    fn r(&self, py: Python<'_>) -> PyResult<Py<PyArray2<f64>>> {
        self.r.as_ref().map(|a| a.clone_ref(py)).ok_or_else(|| no_state("r"))
    }

    /// Measured derivative z(k) = ẋ(k) + v(k), (N, n). A drive with sensors='realistic'
    /// measures no state: VehidError (its measurements are `y`).
    #[getter]
    fn z(&self, py: Python<'_>) -> PyResult<Py<PyArray2<f64>>> {
        self.z.as_ref().map(|a| a.clone_ref(py)).ok_or_else(|| no_state("z"))
    }

    /// A drive's sensor channels (N, len(channels)) in the order of `channels`. A run of the
    /// thesis' simulator has no `y`: VehidError (its measurements are `r` and `z`).
    #[getter]
    fn y(&self, py: Python<'_>) -> PyResult<Py<PyArray2<f64>>> {
        self.y.as_ref().map(|a| a.clone_ref(py)).ok_or_else(no_channels)
    }

    /// The names of a drive's sensor channels: ('a_body', 'a_wheel', 'deflection') (m/s²,
    /// m/s², m) with sensors='realistic', ('zw', 'vw', 'zb', 'vb', 'dzw', 'dvw', 'dzb', 'dvb')
    /// with sensors='state'. VehidError for a run of the thesis' simulator.
    #[getter]
    fn channels<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let c = self.channels.as_ref().ok_or_else(no_channels)?;
        PyTuple::new(py, c)
    }

    /// A drive's true constants per sample: a QuarterCar's (N, 5), columns M (kg), m (kg),
    /// k1 (N/m), k2 (N/m), b (N s/m); a HalfCar's (N, 12), columns M, J, k11, k21, k12, k22,
    /// b1, b2, m1, m2, l1, l2; moved by `changes`. None for a run of the thesis' simulator.
    #[getter]
    fn constants(&self, py: Python<'_>) -> Option<Py<PyArray2<f64>>> {
        self.constants.as_ref().map(|a| a.clone_ref(py))
    }

    /// Number of states n.
    #[getter]
    fn n_states(&self) -> usize {
        self.n_states
    }

    /// Number of inputs m.
    #[getter]
    fn n_inputs(&self) -> usize {
        self.n_inputs
    }

    fn __len__(&self) -> usize {
        self.len
    }

    fn __repr__(&self) -> String {
        format!("Run(samples={}, n_states={}, n_inputs={})", self.len, self.n_states, self.n_inputs)
    }
}

fn no_state(name: &str) -> PyErr {
    VehidError::new_err(format!(
        "run.{name}: a drive with sensors='realistic' measures no state; its measurements are run.y (channels \
         run.channels), the true state is run.x (or simulate with sensors='state')"
    ))
}

fn no_channels() -> PyErr {
    VehidError::new_err(
        "this run has no sensor channels (y, channels): the thesis' simulator measures run.r and run.z; give \
         road='iso8608-C' (and sensors=, changes=) for a drive with sensor channels",
    )
}

/// The `Run` of a drive: the state channels also fill `r` and `z`.
fn drive_run(py: Python<'_>, run: DriveRun, names: &'static [&'static str]) -> PyResult<PyRun> {
    let (len, c) = (run.len, run.channels);
    let [ns, ni, nc] = run.dims;
    let (r, z) = if c == 2 * ns {
        let (mut r, mut z) = (Vec::with_capacity(len * ns), Vec::with_capacity(len * ns));
        for row in run.y.chunks_exact(c) {
            r.extend_from_slice(&row[..ns]);
            z.extend_from_slice(&row[ns..]);
        }
        (Some(to_array2(py, len, ns, r)?.unbind()), Some(to_array2(py, len, ns, z)?.unbind()))
    } else {
        (None, None)
    };
    Ok(PyRun {
        t: run.t.into_pyarray(py).unbind(),
        s: Some(run.s.into_pyarray(py).unbind()),
        x: to_array2(py, len, ns, run.x)?.unbind(),
        xdot: to_array2(py, len, ns, run.xdot)?.unbind(),
        u: to_array2(py, len, ni, run.u)?.unbind(),
        r,
        z,
        y: Some(to_array2(py, len, c, run.y)?.unbind()),
        channels: Some(names.to_vec()),
        constants: Some(to_array2(py, len, nc, run.constants)?.unbind()),
        len,
        n_states: ns,
        n_inputs: ni,
    })
}

/// What a `Simulator` runs: the thesis' linear simulator or a quarter-car drive.
enum Engine {
    Linear(Box<dyn SimDyn>),
    Drive(Box<DriveSim>),
}

impl Engine {
    fn substeps(&self) -> usize {
        match self {
            Engine::Linear(s) => s.substeps(),
            Engine::Drive(_) => 0,
        }
    }

    fn samples(&self) -> u64 {
        match self {
            Engine::Linear(s) => s.samples(),
            Engine::Drive(d) => d.k(),
        }
    }
}

/// A seeded simulator of `ẋ = A x + B u` with the thesis' noise sources (Ch. III.C).
///
/// `road_sigma` (per input), `state_noise` and `deriv_noise` (per state) are scalars or one
/// value per component. `method` is "rk4" (sub-stepped, `substeps=None` chooses from the
/// fastest pole) or "exact" (zero-order hold). `pulses` is a list of
/// `(start_sample, width_samples, amplitude)`. `instrumentation=True` reads the derivative of
/// each kinematic row from the velocity sensor (Eq 4.37–4.39). `run(n)` continues the stream.
///
/// Two axles on one road (half car, Ch. VI.D): give `speed` (m/s: a scalar, or one value per
/// sample — the speed over the road interval after that sample; a 0 entry is a stop of `dt`
/// seconds on the road point reached, before its sample, and produces no sample), `spacing` (m between samples, default 0.3) and/or `road`
/// ("white": one road, the rear axle meets the front axle's road wheelbase/spacing samples
/// later; "independent": independent roads, Fig 6-7). Samples are then taken every `spacing`
/// metres (irregular in time when the speed varies), the road is a white height per `spacing`
/// metres held over distance, and `run.s` is the distance travelled.
///
/// A drive (a `QuarterCar`, `HalfCar` or `FullCar`): `road="iso8608-A"` .. `"iso8608-E"` (or `"flat"`)
/// is an ISO 8608 road profile by distance, `speed` m/s (a scalar, default 15, or one value
/// per sample), `changes=[(t, {"b": 1350.0}), (t, {"k2": 19800.0}, ramp), ...]` steps (or
/// ramps over `ramp` seconds) of the constants 'M', 'm', 'k1', 'k2', 'b' from `t` seconds,
/// `sensors="realistic"` (body and wheel accelerometers, m/s², with noise and a constant bias;
/// a deflection sensor, m) or `"state"` (the thesis' measured state and derivative, noise
/// `state_noise`, `deriv_noise`), `sensor_noise={"a_body": 0.02, "a_body_bias": 0.1,
/// "a_wheel": 0.1, "a_wheel_bias": 0.3, "deflection": 3e-4}` (standard deviations; these are
/// the defaults). `run.y` holds the channels named by `run.channels`, `run.x`/`run.xdot` the
/// true state, `run.u` the road height (m), `run.s` the distance (m), `run.constants` the
/// constants in effect. The integration is exact (zero-order hold of the road per sample).
/// A `HalfCar` drive: the rear wheel meets the front wheel's road a wheelbase later;
/// changes of 'M', 'J', 'k1_f', 'k1_r', 'k2_f', 'k2_r', 'b_f', 'b_r', 'm_f', 'm_r'; realistic
/// channels ('a_body_f', 'a_body_r', 'a_wheel_f', 'a_wheel_r', 'deflection_f', 'deflection_r')
/// or the 16 state channels; `run.u` (N, 2) the road under each wheel.
/// A `FullCar` drive: a left and a right track with the isotropic-road coherence, each rear
/// wheel on its front wheel's track a wheelbase later; changes of 'M', 'Jx', 'Jy' and the
/// corner constants ('b_fl', 'k_rr', ...; 'arb_f', 'arb_r'), and point loads:
/// `(t, {"load": 100.0, "load_x": -2.2, "load_y": 0.3})` sets 100 kg down on the body 2.2 m
/// behind and 0.3 m left of the centre of mass (`run.constants` then show M + 100, and Jx, Jy
/// about the initial centre of mass); realistic channels (a body
/// accelerometer above each wheel, four wheel accelerometers, four deflections, corners
/// fl, fr, rl, rr) or the 28 state channels; `run.u` (N, 4).
#[pyclass(name = "Simulator", module = "vehid._vehid")]
pub struct PySimulator {
    inner: Engine,
    road: Option<(f64, RoadMode)>,
    model: Py<PyLinearModel>,
    dt: f64,
    seed: u64,
    method: Method,
    n_states: usize,
    n_inputs: usize,
}

#[pymethods]
impl PySimulator {
    #[new]
    #[pyo3(signature = (model, dt = 0.05, road_sigma = None, ic_sigma = 0.0, state_noise = None,
                        deriv_noise = None, seed = 1, substeps = None, method = "rk4".into(), pulses = None,
                        instrumentation = false, speed = None, spacing = None, road = None, changes = None,
                        sensors = None, sensor_noise = None),
           text_signature = "(model, dt=0.05, road_sigma=0.1, ic_sigma=0.0, state_noise=0.0, \
                             deriv_noise=0.005, seed=1, substeps=None, method='rk4', pulses=None, \
                             instrumentation=False, speed=None, spacing=None, road=None, changes=None, \
                             sensors=None, sensor_noise=None)")]
    #[allow(clippy::too_many_arguments)]
    fn py_new(
        model: Bound<'_, PyLinearModel>,
        #[pyo3(from_py_with = crate::args::dt)] dt: f64,
        road_sigma: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = crate::args::ic_sigma)] ic_sigma: f64,
        state_noise: Option<&Bound<'_, PyAny>>,
        deriv_noise: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = crate::args::seed)] seed: i128,
        substeps: Option<i128>,
        #[pyo3(from_py_with = crate::args::method)] method: String,
        pulses: Option<Vec<(i128, i128, f64)>>,
        #[pyo3(from_py_with = crate::args::instrumentation)] instrumentation: bool,
        speed: Option<&Bound<'_, PyAny>>,
        spacing: Option<f64>,
        road: Option<&str>,
        changes: Option<&Bound<'_, PyAny>>,
        sensors: Option<&str>,
        sensor_noise: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let drive_road = road.filter(|r| !matches!(*r, "white" | "independent"));
        if drive_road.is_some() || changes.is_some() || sensors.is_some() || sensor_noise.is_some() {
            let Some(road) = drive_road else {
                return Err(VehidError::new_err(
                    "`changes`, `sensors` and `sensor_noise` are settings of a drive on an ISO 8608 road: give \
                     road='iso8608-A' .. 'iso8608-E' (e.g. road='iso8608-C', an average road)",
                ));
            };
            let scalar = |v: Option<&Bound<'_, PyAny>>, arg: &str| -> PyResult<Option<f64>> {
                v.map(|o| {
                    o.extract::<f64>().map_err(|_| {
                        VehidError::new_err(format!("`{arg}` of a drive is one standard deviation (a number)"))
                    })
                })
                .transpose()
            };
            let seed = uint(seed, "seed")?;
            let unused = Unused {
                road_sigma: road_sigma.is_some(),
                ic_sigma,
                substeps: substeps.is_some(),
                method: &method,
                pulses: pulses.is_some(),
                instrumentation,
                spacing: spacing.is_some(),
            };
            let drive = DriveSim::new(
                model.get(),
                dt,
                road,
                speed,
                changes,
                sensors,
                sensor_noise,
                scalar(state_noise, "state_noise")?,
                scalar(deriv_noise, "deriv_noise")?,
                seed,
                unused,
            )?;
            let [n_states, n_inputs, _] = drive.dims();
            return Ok(Self {
                inner: Engine::Drive(Box::new(drive)),
                road: None,
                dt,
                seed,
                method: Method::Exact,
                n_states,
                n_inputs,
                model: model.unbind(),
            });
        }
        let p = SimParams {
            dt,
            road_sigma: values(road_sigma, "road_sigma", vehid_runtime::defaults::ROAD_SIGMA)?,
            ic_sigma,
            state_noise: values(state_noise, "state_noise", 0.0)?,
            deriv_noise: values(deriv_noise, "deriv_noise", vehid_runtime::defaults::DERIV_NOISE)?,
            substeps: substeps.map(|s| size(s, "substeps")).transpose()?,
            method: option(&method)?,
            pulses: pulses
                .unwrap_or_default()
                .into_iter()
                .map(|(s, w, a)| Ok(Pulse { start: uint(s, "pulses")?, width: uint(w, "pulses")?, amplitude: a }))
                .collect::<PyResult<_>>()?,
            instrumentation,
            seed: uint(seed, "seed")?,
        };
        let d = &model.get().data;
        let (inner, road): (Box<dyn SimDyn>, _) = if speed.is_some() || spacing.is_some() || road.is_some() {
            let (spacing, road) = (spacing.unwrap_or(0.3), option::<RoadMode>(road.unwrap_or("white"))?);
            (Box::new(road_simulator(model.get(), &p, speed, spacing, road)?), Some((spacing, road)))
        } else {
            // Discretizing can take a while (explicit `substeps` are not capped): GIL released.
            (model.py().detach(|| simulator(d, &p)).map_err(core_err)?, None)
        };
        Ok(Self {
            inner: Engine::Linear(inner),
            road,
            dt,
            seed: p.seed,
            method: p.method,
            n_states: d.n,
            n_inputs: d.m,
            model: model.unbind(),
        })
    }

    /// Simulates `n` more samples (the GIL is released meanwhile) and returns them as a Run.
    /// A run too large for memory raises MemoryError; a speed profile with fewer than `n`
    /// samples left raises VehidError. Ctrl-C (from the main thread) raises
    /// KeyboardInterrupt within some 20 ms of work. Nothing is simulated when it raises: the
    /// next run starts where this one would have.
    fn run(slf: &Bound<'_, Self>, #[pyo3(from_py_with = crate::args::n)] n: i128) -> PyResult<PyRun> {
        let py = slf.py();
        let n = size(n, "n")?;
        let mut this = borrow_mut(slf)?;
        let mut signals = Interrupts::new();
        let inner = match &mut this.inner {
            Engine::Drive(d) => {
                let run = match py.detach(|| d.run(n, &mut || signals.check())) {
                    Ok(run) => run,
                    Err(e @ vehid_core::Error::Interrupted) => {
                        return Err(signals.raise().unwrap_or_else(|| core_err(e)))
                    }
                    Err(e) => return Err(raise(e)),
                };
                return drive_run(py, run, d.channels());
            }
            Engine::Linear(inner) => inner,
        };
        let run = match py.detach(|| inner.run(n, &mut || signals.check())) {
            Ok(run) => run,
            Err(e @ vehid_core::Error::Interrupted) => return Err(signals.raise().unwrap_or_else(|| core_err(e))),
            Err(e) => return Err(raise(e)),
        };
        let (len, ns, ni) = (run.len(), run.n_states, run.n_inputs);
        let s = this.road.is_some().then(|| run.s.into_pyarray(py).unbind());
        Ok(PyRun {
            s,
            t: run.t.into_pyarray(py).unbind(),
            x: to_array2(py, len, ns, run.x)?.unbind(),
            xdot: to_array2(py, len, ns, run.xdot)?.unbind(),
            u: to_array2(py, len, ni, run.u)?.unbind(),
            r: Some(to_array2(py, len, ns, run.r)?.unbind()),
            z: Some(to_array2(py, len, ns, run.z)?.unbind()),
            y: None,
            channels: None,
            constants: None,
            len,
            n_states: ns,
            n_inputs: ni,
        })
    }

    /// RK4 sub-steps per sample (0 for the exact method).
    #[getter]
    fn substeps(slf: &Bound<'_, Self>) -> PyResult<usize> {
        Ok(borrow(slf)?.inner.substeps())
    }

    /// Sample interval, s.
    #[getter]
    fn dt(slf: &Bound<'_, Self>) -> PyResult<f64> {
        Ok(borrow(slf)?.dt)
    }

    /// Sample spacing (m) for a road simulation (speed=/spacing=/road=), else None.
    #[getter]
    fn spacing(slf: &Bound<'_, Self>) -> PyResult<Option<f64>> {
        Ok(borrow(slf)?.road.map(|r| r.0))
    }

    /// "white" or "independent" for a road simulation, the ISO 8608 class ("iso8608-C") of a
    /// drive, else None.
    #[getter]
    fn road(slf: &Bound<'_, Self>) -> PyResult<Option<&'static str>> {
        let this = borrow(slf)?;
        if let Engine::Drive(d) = &this.inner {
            return Ok(Some(d.config().road.as_str()));
        }
        Ok(this.road.map(|r| r.1.as_str()))
    }

    /// The sensor channel names of a drive (as `Run.channels`), else None.
    #[getter]
    fn channels<'py>(slf: &Bound<'py, Self>) -> PyResult<Option<Bound<'py, PyTuple>>> {
        match &borrow(slf)?.inner {
            Engine::Drive(d) => Ok(Some(PyTuple::new(slf.py(), d.channels())?)),
            Engine::Linear(_) => Ok(None),
        }
    }

    /// "realistic" or "state" for a drive, else None.
    #[getter]
    fn sensors(slf: &Bound<'_, Self>) -> PyResult<Option<&'static str>> {
        match &borrow(slf)?.inner {
            Engine::Drive(d) => Ok(Some(d.config().sensors.as_str())),
            Engine::Linear(_) => Ok(None),
        }
    }

    /// The seed.
    #[getter]
    fn seed(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(borrow(slf)?.seed)
    }

    /// "rk4" or "exact".
    #[getter]
    fn method(slf: &Bound<'_, Self>) -> PyResult<&'static str> {
        Ok(borrow(slf)?.method.as_str())
    }

    /// The model simulated.
    #[getter]
    fn model(slf: &Bound<'_, Self>) -> PyResult<Py<PyLinearModel>> {
        Ok(borrow(slf)?.model.clone_ref(slf.py()))
    }

    /// Samples produced so far (the index of the next one).
    #[getter]
    fn samples(slf: &Bound<'_, Self>) -> PyResult<u64> {
        Ok(borrow(slf)?.inner.samples())
    }

    /// Number of states n.
    #[getter]
    fn n_states(slf: &Bound<'_, Self>) -> PyResult<usize> {
        Ok(borrow(slf)?.n_states)
    }

    /// Number of inputs m.
    #[getter]
    fn n_inputs(slf: &Bound<'_, Self>) -> PyResult<usize> {
        Ok(borrow(slf)?.n_inputs)
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        let this = borrow(slf)?;
        let model = this.model.bind(slf.py()).repr()?;
        Ok(format!(
            "Simulator({model}, dt={:?}, method='{}', substeps={}, seed={}, samples={})",
            this.dt,
            this.method.as_str(),
            this.inner.substeps(),
            this.seed,
            this.inner.samples()
        ))
    }
}
