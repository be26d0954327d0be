//! Simulators of linear models at run-time sizes, behind one object-safe interface
//! ([`SimDyn`]), built through the core's validation.

use crate::model::ModelData;
use crate::sizes::dispatch_nm;
use vehid_core::sim::{Method, Pulse, Run, SimConfig, SimSettings, Simulator};
use vehid_core::{Error, Result};

/// Everything a Python `Simulator(...)` was given, already converted.
#[derive(Debug, Clone)]
pub struct SimParams {
    pub dt: f64,
    pub road_sigma: Vec<f64>,
    pub ic_sigma: f64,
    pub state_noise: Vec<f64>,
    pub deriv_noise: Vec<f64>,
    pub substeps: Option<usize>,
    pub method: Method,
    pub pulses: Vec<Pulse<f64>>,
    pub instrumentation: bool,
    pub seed: u64,
}

impl SimParams {
    /// The core's run-time settings.
    pub fn settings(&self) -> SimSettings<'_, f64> {
        SimSettings {
            dt: self.dt,
            road_sigma: &self.road_sigma,
            ic_sigma: self.ic_sigma,
            state_noise: &self.state_noise,
            deriv_noise: &self.deriv_noise,
            substeps: self.substeps,
            method: self.method,
            instrumentation: self.instrumentation,
            pulses: &self.pulses,
        }
    }
}

/// A simulator of any size, behind one object-safe interface.
pub trait SimDyn: Send + Sync {
    /// Runs `n` more samples (the stream continues from the previous call), asking
    /// `interrupt()` between pieces of work (every [`sim_chunk`] samples; a run is simulated
    /// in these pieces, which gives the same samples as one piece). All or nothing: when
    /// `interrupt()` says stop, or on any error, the simulator is put back where it was.
    ///
    /// # Errors
    /// [`Error::OutOfMemory`] when the output does not fit; [`Error::Interrupted`]; the
    /// simulator's own errors.
    fn run(&mut self, n: usize, interrupt: &mut dyn FnMut() -> bool) -> Result<Run<f64>>;
    /// RK4 sub-steps per sample (0 for the exact method).
    fn substeps(&self) -> usize;
    /// Samples produced so far (index of the next sample).
    fn samples(&self) -> u64;
}

/// An empty run with room for `n` samples, reserved fallibly (a size that cannot be
/// allocated is an error, not an abort).
pub fn reserve_run(n: usize, states: usize, inputs: usize, distance: bool) -> Result<Run<f64>> {
    let mut out = Run::<f64> { n_states: states, n_inputs: inputs, ..Run::default() };
    let bytes = n.checked_mul(1 + 4 * states + inputs + usize::from(distance)).and_then(|v| v.checked_mul(8));
    let oom = Error::OutOfMemory { what: "the simulated run", bytes: bytes.unwrap_or(usize::MAX) };
    if bytes.is_none_or(|b| b > isize::MAX as usize) {
        return Err(oom);
    }
    let reserve = |v: &mut Vec<f64>, width: usize| v.try_reserve_exact(n * width).map_err(|_| oom.clone());
    reserve(&mut out.t, 1)?;
    for v in [&mut out.x, &mut out.xdot, &mut out.r, &mut out.z] {
        reserve(v, states)?;
    }
    reserve(&mut out.u, inputs)?;
    if distance {
        reserve(&mut out.s, 1)?;
    }
    Ok(out)
}

/// Samples simulated between two interrupt checks: some 10⁵ operations (a sample of an
/// `n`-state model costs a few n² of them: the step `Φ x + Γ u`, discretized once, and the
/// noise), at least one sample.
pub fn sim_chunk(n: usize) -> usize {
    ((1usize << 17) / (4 * n * n).max(1)).clamp(1, 1 << 16)
}

impl<const N: usize, const M: usize> SimDyn for Simulator<f64, N, M> {
    fn run(&mut self, n: usize, interrupt: &mut dyn FnMut() -> bool) -> Result<Run<f64>> {
        let mut out = reserve_run(n, N, M, false)?;
        let chunk = sim_chunk(N);
        if n <= chunk {
            self.run_with(n, |s| out.push(s));
            return Ok(out);
        }
        // Kept to undo an interrupted run (a few hundred bytes).
        let start = self.clone();
        let mut done = 0;
        while done < n {
            if done > 0 && interrupt() {
                *self = start;
                return Err(Error::Interrupted);
            }
            let m = chunk.min(n - done);
            self.run_with(m, |s| out.push(s));
            done += m;
        }
        Ok(out)
    }

    fn substeps(&self) -> usize {
        Simulator::substeps(self)
    }

    fn samples(&self) -> u64 {
        self.k()
    }
}

/// Builds a simulator through the core's validation.
fn simulator_nm<const N: usize, const M: usize>(d: &ModelData, p: &SimParams) -> Result<Box<dyn SimDyn>> {
    let cfg = SimConfig::<f64, N, M>::from_settings(&p.settings())?;
    Ok(Box::new(Simulator::new(d.model::<N, M>()?, cfg, p.seed)?))
}

/// A simulator of the model `d` with the settings `p` (the core's `SimConfig::from_settings`
/// and `Simulator::new`), any size.
///
/// # Errors
/// The core's settings and model errors.
pub fn simulator(d: &ModelData, p: &SimParams) -> Result<Box<dyn SimDyn>> {
    dispatch_nm!(d.n, d.m, simulator_nm(d, p))
}
