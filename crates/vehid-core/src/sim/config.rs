//! Simulation settings: sample interval, noise levels, pulses, integration method.

use crate::error::{check_nonneg, check_positive};
use crate::model::broadcast;
use crate::{Error, Real, Result};
use nalgebra::SVector;

/// How the state is advanced between samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// Classical fourth-order Runge–Kutta (the thesis' integrator) with sub-steps.
    #[default]
    Rk4,
    /// Exact zero-order-hold discretization (matrix exponential).
    Exact,
}

option_names!(Method, "method", { Rk4 => "rk4", Exact => "exact" });

/// A rectangular input pulse added to every road input (Ch. III.C: a pulse of 1–4 sample
/// intervals, applied for the 8-state study at the ninth measurement cycle).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pulse<T> {
    /// First sample index at which the pulse is on.
    pub start: u64,
    /// Number of samples it stays on (≥ 1).
    pub width: u64,
    /// Height, m (added to the road input).
    pub amplitude: T,
}

/// Most pulses one simulation holds (fixed so the simulator needs no allocation).
pub const MAX_PULSES: usize = 8;

/// Settings of a simulation: the sample interval and the four noise levels of the thesis.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig<T, const N: usize, const M: usize> {
    /// Sample interval, s (thesis: 0.05).
    pub dt: T,
    /// Road input standard deviation σ_u per input, m.
    pub road_sigma: SVector<T, M>,
    /// Initial-state standard deviation σ_ic (state units).
    pub ic_sigma: T,
    /// State measurement noise σ_w per state component (state units).
    pub state_noise: SVector<T, N>,
    /// Derivative measurement noise σ_v per state component (state units per second).
    pub deriv_noise: SVector<T, N>,
    /// RK4 sub-steps per sample; `None` chooses from the fastest pole.
    pub substeps: Option<usize>,
    /// Integration method.
    pub method: Method,
    /// Read kinematic rows' derivatives from the velocity sensors (Eq 4.37–4.39).
    pub instrumentation: bool,
    pulses: [Option<Pulse<T>>; MAX_PULSES],
}

impl<T: Real, const N: usize, const M: usize> SimConfig<T, N, M> {
    /// A noise-free configuration with sample interval `dt` seconds.
    pub fn new(dt: T) -> Self {
        Self {
            dt,
            road_sigma: SVector::zeros(),
            ic_sigma: T::zero(),
            state_noise: SVector::zeros(),
            deriv_noise: SVector::zeros(),
            substeps: None,
            method: Method::Rk4,
            instrumentation: false,
            pulses: [None; MAX_PULSES],
        }
    }

    /// Sets the same road σ_u (m) on every input.
    pub fn road_sigma(mut self, sigma: T) -> Self {
        self.road_sigma = SVector::repeat(sigma);
        self
    }

    /// Sets σ_ic.
    pub fn ic_sigma(mut self, sigma: T) -> Self {
        self.ic_sigma = sigma;
        self
    }

    /// Sets the same state-measurement σ_w on every component.
    pub fn state_noise(mut self, sigma: T) -> Self {
        self.state_noise = SVector::repeat(sigma);
        self
    }

    /// Sets the same derivative-measurement σ_v on every component.
    pub fn deriv_noise(mut self, sigma: T) -> Self {
        self.deriv_noise = SVector::repeat(sigma);
        self
    }

    /// Adds a pulse input.
    ///
    /// # Errors
    /// [`Error::Capacity`] beyond [`MAX_PULSES`]; [`Error::InvalidArgument`] for a zero width
    /// or a non-finite amplitude.
    pub fn with_pulse(mut self, pulse: Pulse<T>) -> Result<Self> {
        if pulse.width == 0 {
            return Err(Error::InvalidArgument { arg: "pulses", expected: "a width of at least 1 sample" });
        }
        if !pulse.amplitude.finite() {
            return Err(Error::InvalidArgument { arg: "pulses", expected: "a finite amplitude" });
        }
        match self.pulses.iter_mut().find(|p| p.is_none()) {
            Some(slot) => *slot = Some(pulse),
            None => return Err(Error::Capacity { arg: "pulses", needed: MAX_PULSES + 1, capacity: MAX_PULSES }),
        }
        Ok(self)
    }

    /// The pulses configured.
    pub fn pulses(&self) -> impl Iterator<Item = &Pulse<T>> {
        self.pulses.iter().flatten()
    }

    pub(crate) fn validate(&self) -> Result<()> {
        check_positive("dt", self.dt)?;
        for &s in self.road_sigma.iter() {
            check_sigma("road_sigma", s)?;
        }
        check_sigma("ic_sigma", self.ic_sigma)?;
        for &s in self.state_noise.iter() {
            check_sigma("state_noise", s)?;
        }
        for &s in self.deriv_noise.iter() {
            check_sigma("deriv_noise", s)?;
        }
        Ok(())
    }
}

/// Largest noise standard deviation a simulation accepts: larger values overflow once
/// squared or propagated through the model (the simulation would produce inf/NaN).
pub const MAX_SIGMA: f64 = 1e100;

/// A finite, non-negative standard deviation no larger than [`MAX_SIGMA`].
fn check_sigma<T: Real>(arg: &'static str, s: T) -> Result<()> {
    check_nonneg(arg, s)?;
    if s.to_f64() > MAX_SIGMA {
        return Err(Error::InvalidArgument {
            arg,
            expected: "a standard deviation of at most 1e100 (larger ones overflow in the simulation: rescale the \
                       units)",
        });
    }
    Ok(())
}

/// Sets a per-component vector from one value or one value per component.
///
/// # Errors
/// [`Error::Shape`] for other lengths, [`Error::InvalidArgument`] for negative values.
pub fn per_component<T: Real, const K: usize>(arg: &'static str, v: &[T]) -> Result<SVector<T, K>> {
    Ok(SVector::from(broadcast::<T, K>(arg, v)?))
}

impl<T: Real, const N: usize, const M: usize> SimConfig<T, N, M> {
    /// Selects the exact zero-order-hold method.
    pub fn method_exact(mut self) -> Self {
        self.method = Method::Exact;
        self
    }
}

/// The settings of a simulation as run-time data (sizes known only at run time, e.g. from
/// Python): [`SimConfig::from_settings`] turns them into the const-sized [`SimConfig`] of
/// either simulator, with every check in one place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimSettings<'a, T> {
    /// Sample interval, s (> 0).
    pub dt: T,
    /// Road input σ_u, m: one value (every input) or one per input.
    pub road_sigma: &'a [T],
    /// Initial-state σ_ic (state units).
    pub ic_sigma: T,
    /// State measurement σ_w: one value or one per state.
    pub state_noise: &'a [T],
    /// Derivative measurement σ_v: one value or one per state.
    pub deriv_noise: &'a [T],
    /// RK4 sub-steps per sample (`None`: automatic).
    pub substeps: Option<usize>,
    /// Integration method.
    pub method: Method,
    /// Read kinematic rows' derivatives from the velocity sensors (Eq 4.37–4.39).
    pub instrumentation: bool,
    /// Input pulses (at most [`MAX_PULSES`]).
    pub pulses: &'a [Pulse<T>],
}

impl<T: Real, const N: usize, const M: usize> SimConfig<T, N, M> {
    /// The configuration `s` describes.
    ///
    /// # Errors
    /// [`Error::Shape`] for a per-component value of the wrong length; the checks of
    /// [`SimConfig::with_pulse`] and of the simulators' constructors.
    pub fn from_settings(s: &SimSettings<'_, T>) -> Result<Self> {
        let mut cfg = SimConfig::<T, N, M>::new(s.dt);
        cfg.road_sigma = per_component("road_sigma", s.road_sigma)?;
        cfg.ic_sigma = s.ic_sigma;
        cfg.state_noise = per_component("state_noise", s.state_noise)?;
        cfg.deriv_noise = per_component("deriv_noise", s.deriv_noise)?;
        cfg.substeps = s.substeps;
        cfg.method = s.method;
        cfg.instrumentation = s.instrumentation;
        for p in s.pulses {
            cfg = cfg.with_pulse(*p)?;
        }
        cfg.validate()?;
        Ok(cfg)
    }
}
