//! Seeded simulation of `ẋ = A x + B u` with every noise source of the thesis (Ch. III.C).
//!
//! Per sample `k` (time `t_k = k·dt`):
//! - the road input `u(k) ~ N(0, σ_u²)` per input, held over `[t_k, t_{k+1})` (Eq 4.25),
//!   plus any pulse active at `k`;
//! - the true state `x(k)` and derivative `ẋ(k) = A x(k) + B u(k)`;
//! - the measurements `r(k) = x(k) + w(k)`, `w ~ N(0, diag σ_w²)` and
//!   `z(k) = ẋ(k) + v(k)`, `v ~ N(0, diag σ_v²)`; in instrumentation mode (Eq 4.37–4.39) a
//!   kinematic row `ẋ_i = x_j` is read from the sensor of `x_j`, so `z_i = r_j`;
//! - then `x(k+1) = Φ x(k) + Γ u(k)` by RK4 ([`Method::Rk4`], sub-stepped) or the exact
//!   zero-order hold ([`Method::Exact`]).
//!
//! The initial state is `x(0) ~ N(0, σ_ic² I)`. Each noise source has its own random
//! stream derived from the seed, so changing one σ leaves the others' realizations alone
//! (a noise-free and a noisy run with the same seed see the same road). The generator is
//! Xoshiro256++ and the normal variates are drawn in `f64`, so a seed gives the same run on
//! every platform, in `f32` and `f64` alike (up to the `f32` rounding).

use crate::analysis::{auto_substeps, rk4_map, zoh};
use crate::error::{check_finite, check_nonneg, check_positive};
use crate::model::{broadcast, LinearModel};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};
use rand::rngs::Xoshiro256PlusPlus;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// How the state is advanced between samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// Classical fourth-order Runge–Kutta (the thesis' integrator) with sub-steps.
    #[default]
    Rk4,
    /// Exact zero-order-hold discretization (matrix exponential).
    Exact,
}

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

    fn validate(&self) -> Result<()> {
        check_positive("dt", self.dt)?;
        for &s in self.road_sigma.iter() {
            check_nonneg("road_sigma", s)?;
        }
        check_nonneg("ic_sigma", self.ic_sigma)?;
        for &s in self.state_noise.iter() {
            check_nonneg("state_noise", s)?;
        }
        for &s in self.deriv_noise.iter() {
            check_nonneg("deriv_noise", s)?;
        }
        Ok(())
    }
}

/// Sets a per-component vector from one value or one value per component.
///
/// # Errors
/// [`Error::Shape`] for other lengths, [`Error::InvalidArgument`] for negative values.
pub fn per_component<T: Real, const K: usize>(arg: &'static str, v: &[T]) -> Result<SVector<T, K>> {
    Ok(SVector::from(broadcast::<T, K>(arg, v)?))
}

/// One sample of a simulation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample<T: Real, const N: usize, const M: usize> {
    /// Sample index `k`.
    pub k: u64,
    /// Time `t_k = k·dt`, s.
    pub t: T,
    /// True state `x(k)`.
    pub x: SVector<T, N>,
    /// True derivative `ẋ(k) = A x(k) + B u(k)`.
    pub xdot: SVector<T, N>,
    /// Road input `u(k)`, held until the next sample, m.
    pub u: SVector<T, M>,
    /// Measured state `r(k) = x(k) + w(k)`.
    pub r: SVector<T, N>,
    /// Measured derivative `z(k) = ẋ(k) + v(k)`.
    pub z: SVector<T, N>,
}

/// A streaming simulator: one [`Sample`] per call, no allocation.
///
/// # Examples
/// ```
/// use vehid_core::model::QuarterCar;
/// use vehid_core::sim::{SimConfig, Simulator};
/// let car = QuarterCar::<f64>::thesis().model();
/// let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
/// let mut sim = Simulator::new(car, cfg, 1).unwrap();
/// let s = sim.next_sample();
/// assert_eq!(s.k, 0);
/// ```
#[derive(Debug, Clone)]
pub struct Simulator<T: Real, const N: usize, const M: usize> {
    model: LinearModel<T, N, M>,
    cfg: SimConfig<T, N, M>,
    phi: SMatrix<T, N, N>,
    gamma: SMatrix<T, N, M>,
    substeps: usize,
    kinematic: [Option<usize>; N],
    x: SVector<T, N>,
    k: u64,
    rng_road: Xoshiro256PlusPlus,
    rng_w: Xoshiro256PlusPlus,
    rng_v: Xoshiro256PlusPlus,
}

/// Seeds of the independent streams: initial condition, road, state noise, derivative noise.
fn streams(seed: u64) -> [Xoshiro256PlusPlus; 4] {
    let mut master = Xoshiro256PlusPlus::seed_from_u64(seed);
    [
        Xoshiro256PlusPlus::from_rng(&mut master),
        Xoshiro256PlusPlus::from_rng(&mut master),
        Xoshiro256PlusPlus::from_rng(&mut master),
        Xoshiro256PlusPlus::from_rng(&mut master),
    ]
}

/// The sensors of Ch. III.C: `r = x + w`, `z = ẋ + v` (one draw per component, `w` first),
/// and in instrumentation mode (Eq 4.37–4.39) a kinematic row read from its state's sensor.
fn measure<T: Real, const N: usize, const M: usize>(
    cfg: &SimConfig<T, N, M>,
    kinematic: &[Option<usize>; N],
    rng_w: &mut Xoshiro256PlusPlus,
    rng_v: &mut Xoshiro256PlusPlus,
    x: &SVector<T, N>,
    xdot: &SVector<T, N>,
) -> (SVector<T, N>, SVector<T, N>) {
    let mut r = *x;
    for i in 0..N {
        r[i] += normal::<T>(rng_w) * cfg.state_noise[i];
    }
    let mut z = *xdot;
    for i in 0..N {
        z[i] += normal::<T>(rng_v) * cfg.deriv_noise[i];
    }
    if cfg.instrumentation {
        for i in 0..N {
            if let Some(j) = kinematic[i] {
                z[i] = r[j];
            }
        }
    }
    (r, z)
}

#[inline]
fn normal<T: Real>(rng: &mut Xoshiro256PlusPlus) -> T {
    let v: f64 = StandardNormal.sample(rng);
    T::of(v)
}

impl<T: Real, const N: usize, const M: usize> Simulator<T, N, M> {
    /// Builds a simulator; the initial state is drawn here.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `dt ≤ 0`, negative or non-finite σ, `substeps == 0`;
    /// [`Error::Unstable`] when explicit `substeps` make RK4 unstable for a stable model
    /// (the message's fix: more sub-steps, or `None`).
    pub fn new(model: LinearModel<T, N, M>, cfg: SimConfig<T, N, M>, seed: u64) -> Result<Self> {
        cfg.validate()?;
        let substeps = match (cfg.method, cfg.substeps) {
            (Method::Exact, _) => 0,
            (Method::Rk4, None) => auto_substeps(&model, cfg.dt),
            (Method::Rk4, Some(s)) => s,
        };
        let (phi, gamma) = match cfg.method {
            Method::Exact => zoh(&model, cfg.dt)?,
            Method::Rk4 => {
                let (p, g) = rk4_map(&model, cfg.dt, substeps)?;
                let (pe, _) = zoh(&model, cfg.dt)?;
                let rho_rk4 = crate::linalg::spectral_radius(&p);
                if rho_rk4 > 1.0 && crate::linalg::spectral_radius(&pe) < 1.0 {
                    return Err(Error::InvalidArgument {
                        arg: "substeps",
                        expected: "enough RK4 sub-steps for the fastest pole (RK4 diverges here); \
                                   pass None for an automatic count",
                    });
                }
                (p, g)
            }
        };
        check_finite("a", phi.as_slice())?;
        let mut kinematic = [None; N];
        for (i, kin) in kinematic.iter_mut().enumerate() {
            *kin = model.kinematic_source(i);
        }
        let [mut rng_ic, rng_road, rng_w, rng_v] = streams(seed);
        let x = SVector::<T, N>::from_fn(|_, _| normal::<T>(&mut rng_ic) * cfg.ic_sigma);
        Ok(Self { model, cfg, phi, gamma, substeps, kinematic, x, k: 0, rng_road, rng_w, rng_v })
    }

    /// The model simulated.
    pub fn model(&self) -> &LinearModel<T, N, M> {
        &self.model
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig<T, N, M> {
        &self.cfg
    }

    /// RK4 sub-steps per sample in use (0 for the exact method).
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// The discrete transition `(Φ, Γ)` in use: `x(k+1) = Φ x(k) + Γ u(k)`.
    pub fn transition(&self) -> (&SMatrix<T, N, N>, &SMatrix<T, N, M>) {
        (&self.phi, &self.gamma)
    }

    /// The true state about to be sampled.
    pub fn state(&self) -> &SVector<T, N> {
        &self.x
    }

    /// Index of the next sample.
    pub fn k(&self) -> u64 {
        self.k
    }

    fn pulse_at(&self, k: u64) -> T {
        let mut p = T::zero();
        for pulse in self.cfg.pulses() {
            if k >= pulse.start && k - pulse.start < pulse.width {
                p += pulse.amplitude;
            }
        }
        p
    }

    /// Draws the road input of sample `k` (noise plus pulses).
    fn next_input(&mut self) -> SVector<T, M> {
        let pulse = self.pulse_at(self.k);
        let mut u = SVector::<T, M>::zeros();
        for j in 0..M {
            u[j] = normal::<T>(&mut self.rng_road) * self.cfg.road_sigma[j] + pulse;
        }
        u
    }

    /// Produces sample `k` and advances the state to `k + 1`.
    pub fn next_sample(&mut self) -> Sample<T, N, M> {
        let u = self.next_input();
        self.sample_with_input(u)
    }

    /// As [`Simulator::next_sample`] but with the road input given by the caller (for road
    /// models outside the simulator, e.g. two axles on one road profile).
    ///
    /// # Errors
    /// [`Error::NonFinite`] when `u` holds NaN/inf (the simulator is then unchanged).
    pub fn next_sample_with(&mut self, u: &SVector<T, M>) -> Result<Sample<T, N, M>> {
        check_finite("u", u.as_slice())?;
        Ok(self.sample_with_input(*u))
    }

    fn sample_with_input(&mut self, u: SVector<T, M>) -> Sample<T, N, M> {
        let x = self.x;
        let xdot = self.model.a() * x + self.model.b() * u;
        let (r, z) = measure(&self.cfg, &self.kinematic, &mut self.rng_w, &mut self.rng_v, &x, &xdot);
        let t = T::of(self.k as f64 * self.cfg.dt.to_f64());
        let s = Sample { k: self.k, t, x, xdot, u, r, z };
        self.x = self.phi * x + self.gamma * u;
        self.k += 1;
        s
    }

    /// Runs `n` samples, calling `f` on each (allocation-free whole-run form).
    pub fn run_with(&mut self, n: usize, mut f: impl FnMut(&Sample<T, N, M>)) {
        for _ in 0..n {
            let s = self.next_sample();
            f(&s);
        }
    }

    /// Runs `n` samples into a [`Run`].
    #[cfg(feature = "alloc")]
    pub fn run(&mut self, n: usize) -> Run<T> {
        let mut out = Run::with_capacity(N, M, n);
        self.run_with(n, |s| out.push(s));
        out
    }
}

/// How the rear wheel's road relates to the front wheel's (Ch. VI.D).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RoadMode {
    /// One white road under both wheels: the rear wheel meets the front wheel's road one
    /// wheelbase later, `u2(s) = u1(s − L)` (Eq 6.9; Fig 6-8, 6-9).
    #[default]
    White,
    /// Independent white roads under the two wheels (Fig 6-7).
    Independent,
}

/// The road and its sampling: a white road of independent heights per `spacing` metres,
/// the wheelbase, and whether the wheels share the road.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoadConfig<T> {
    /// Length of one road point (cell) and distance between samples `Δ`, m (> 0).
    pub spacing: T,
    /// Wheelbase `L = l1 + l2`, m (> 0).
    pub wheelbase: T,
    /// Shared or independent road.
    pub mode: RoadMode,
}

impl<T: Real> RoadConfig<T> {
    /// A shared white road, `spacing` m per road point, axles `wheelbase` m apart.
    pub fn new(spacing: T, wheelbase: T) -> Self {
        Self { spacing, wheelbase, mode: RoadMode::White }
    }

    /// Selects the road mode.
    pub fn mode(mut self, mode: RoadMode) -> Self {
        self.mode = mode;
        self
    }
}

/// One sample of a [`RoadSimulator`]: a [`Sample`] plus the distance travelled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoadSample<T: Real, const N: usize> {
    /// Sample index `k`.
    pub k: u64,
    /// Time of the sample, s (irregular when the speed varies).
    pub t: T,
    /// Distance travelled by the front axle, m.
    pub s: T,
    /// True state `x(k)`.
    pub x: SVector<T, N>,
    /// True derivative `ẋ(k) = A x(k) + B u(k)`.
    pub xdot: SVector<T, N>,
    /// Road heights under the front and the rear wheel at the sample, m.
    pub u: SVector<T, 2>,
    /// Measured state `r(k) = x(k) + w(k)`.
    pub r: SVector<T, N>,
    /// Measured derivative `z(k) = ẋ(k) + v(k)`.
    pub z: SVector<T, N>,
}

impl<T: Real, const N: usize> RoadSample<T, N> {
    /// The same sample as a time-simulator [`Sample`] (without `s`).
    pub fn sample(&self) -> Sample<T, N, 2> {
        Sample { k: self.k, t: self.t, x: self.x, xdot: self.xdot, u: self.u, r: self.r, z: self.z }
    }
}

/// Cached transitions: the last two step lengths seen.
#[derive(Debug, Clone, Copy)]
struct Step<T: Real, const N: usize> {
    tau: f64,
    phi: SMatrix<T, N, N>,
    gamma: SMatrix<T, N, 2>,
}

/// A streaming simulator of a two-axle vehicle (the half car: `M = 2` inputs, front and
/// rear road) driven along one road at a speed profile (Ch. VI.D, Eq 6.9). No allocation.
///
/// **Road.** A white road: an independent height `h_j ~ N(0, σ_u²)` for each road point
/// (cell) `[jΔ, (j+1)Δ)` of `Δ = spacing` metres, *held over distance*: a wheel's input is
/// the height of the cell it is on, so in time it is held for `Δ / v` seconds — the thesis'
/// held white noise (Eq 4.25) when the speed is constant (`Δ / v = 0.05` s at 6 m/s and
/// 0.3 m), a longer pulse when slower. The front wheel is at distance `s`, the rear wheel at
/// `s − L`; cells behind the start (`s < 0`) exist. [`RoadMode::White`] puts both wheels on
/// the same road (σ_u from `road_sigma[0]`), [`RoadMode::Independent`] gives the rear wheel
/// its own road (`road_sigma[1]`).
///
/// **Sampling.** [`RoadSimulator::next_sample`] samples at the current point and then drives
/// to the next road point at the given speed, so samples fall every `Δ` metres, at times
/// that are irregular when the speed varies, and the rear input at sample `k` is the front
/// input at sample `k − d` when `L = d·Δ`. [`RoadSimulator::advance`] moves by time (speed
/// and duration, any speed ≥ 0, stops included: a stopped vehicle's state keeps evolving on
/// its held input and produces no sample) and [`RoadSimulator::sample_now`] samples wherever
/// the vehicle is, for odometry-driven sampling with [`crate::sampler::AxleSampler`].
///
/// **Integration.** Between events (samples, cell boundaries under either wheel) the input
/// is constant and the state advances by the exact or RK4 transition for that step length
/// (`SimConfig::method`; the RK4 sub-step count is at least the automatic one for each step
/// length, `SimConfig::substeps` acts as a minimum). Transitions are cached for the three
/// most recently used step lengths, so a constant speed computes them once. `SimConfig::dt` and pulses are not
/// used.
///
/// `C` is the road memory in cells: at least `d + 2` with `d = ⌊L / Δ⌋`.
///
/// # Examples
/// ```
/// use vehid_core::model::HalfCar;
/// use vehid_core::sim::{RoadConfig, RoadSimulator, SimConfig};
/// let car = HalfCar::<f64>::thesis();
/// let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
/// let mut sim = RoadSimulator::<f64, 8, 16>::new(car.model(), cfg, RoadConfig::new(0.3, 3.0), 1)?;
/// let first: Vec<_> = (0..30).map(|_| sim.next_sample(6.0).unwrap()).collect();
/// assert_eq!(first[25].u[1], first[15].u[0]);              // the rear meets the front's road
/// assert!((first[10].t - 0.5).abs() < 1e-12 && (first[10].s - 3.0).abs() < 1e-12);
/// # Ok::<(), vehid_core::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct RoadSimulator<T: Real, const N: usize, const C: usize> {
    model: LinearModel<T, N, 2>,
    cfg: SimConfig<T, N, 2>,
    road: RoadConfig<T>,
    /// `L = d·Δ + e`, `0 ≤ e < Δ` (`e = 0` when `L / Δ` is an integer to 1e-9).
    d: i64,
    e: T,
    kinematic: [Option<usize>; N],
    x: SVector<T, N>,
    t: f64,
    /// Front cell index and offset in it (m).
    j: i64,
    o: T,
    heights: [T; C],
    rear_h: T,
    steps: [Option<Step<T, N>>; 3],
    /// `ρ(A)`, for the RK4 sub-step count of each step length (as [`auto_substeps`]).
    rho: f64,
    k: u64,
    rng_road: Xoshiro256PlusPlus,
    rng_w: Xoshiro256PlusPlus,
    rng_v: Xoshiro256PlusPlus,
}

impl<T: Real, const N: usize, const C: usize> RoadSimulator<T, N, C> {
    /// Builds the road simulator; the initial state and the road behind the start are drawn
    /// here. The random streams are the [`Simulator`]'s for the same seed.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for bad noise levels, `substeps = 0`, or a spacing or
    /// wheelbase not finite and > 0; [`Error::Capacity`] when `C < d + 2`.
    pub fn new(model: LinearModel<T, N, 2>, cfg: SimConfig<T, N, 2>, road: RoadConfig<T>, seed: u64) -> Result<Self> {
        cfg.validate()?;
        if cfg.substeps == Some(0) {
            return Err(Error::InvalidArgument { arg: "substeps", expected: "at least 1 (or None for automatic)" });
        }
        check_positive("spacing", road.spacing)?;
        check_positive("wheelbase", road.wheelbase)?;
        let ratio = (road.wheelbase / road.spacing).to_f64();
        if !(ratio < 1e9) {
            return Err(Error::InvalidArgument { arg: "spacing", expected: "at most 1e9 road points per wheelbase" });
        }
        let near = libm::round(ratio);
        let (d, e) = if libm::fabs(ratio - near) <= 1e-9 * near.max(1.0) {
            (near as i64, T::zero())
        } else {
            let d = libm::floor(ratio);
            let e = road.wheelbase - T::of(d) * road.spacing;
            (d as i64, if e > T::zero() && e < road.spacing { e } else { T::zero() })
        };
        let needed = d as usize + 2;
        if needed > C {
            return Err(Error::Capacity { arg: "RoadSimulator capacity C (road cells, d + 2)", needed, capacity: C });
        }
        let mut kinematic = [None; N];
        for (i, kin) in kinematic.iter_mut().enumerate() {
            *kin = model.kinematic_source(i);
        }
        let rho = crate::linalg::spectral_radius(model.a());
        let [mut rng_ic, mut rng_road, rng_w, rng_v] = streams(seed);
        let x = SVector::<T, N>::from_fn(|_, _| normal::<T>(&mut rng_ic) * cfg.ic_sigma);
        let mut heights = [T::zero(); C];
        let mut rear_h = T::zero();
        match road.mode {
            RoadMode::White => {
                for cell in -(d + 1)..=0 {
                    heights[cell.rem_euclid(C as i64) as usize] = normal::<T>(&mut rng_road) * cfg.road_sigma[0];
                }
            }
            RoadMode::Independent => {
                heights[0] = normal::<T>(&mut rng_road) * cfg.road_sigma[0];
                rear_h = normal::<T>(&mut rng_road) * cfg.road_sigma[1];
            }
        }
        Ok(Self {
            model,
            cfg,
            road,
            d,
            e,
            kinematic,
            x,
            t: 0.0,
            j: 0,
            o: T::zero(),
            heights,
            rear_h,
            steps: [None; 3],
            rho,
            k: 0,
            rng_road,
            rng_w,
            rng_v,
        })
    }

    /// The model simulated.
    pub fn model(&self) -> &LinearModel<T, N, 2> {
        &self.model
    }

    /// The road settings.
    pub fn road(&self) -> &RoadConfig<T> {
        &self.road
    }

    /// Road points between the axles, `⌊L / Δ⌋`.
    pub fn delay(&self) -> usize {
        self.d as usize
    }

    /// The true state now.
    pub fn state(&self) -> &SVector<T, N> {
        &self.x
    }

    /// Time now, s.
    pub fn time(&self) -> f64 {
        self.t
    }

    /// Distance travelled by the front axle, m.
    pub fn distance(&self) -> T {
        T::of(self.j as f64) * self.road.spacing + self.o
    }

    /// Index of the next sample.
    pub fn k(&self) -> u64 {
        self.k
    }

    /// Road heights under the front and the rear wheel now, m.
    pub fn input(&self) -> SVector<T, 2> {
        let front = self.heights[self.j.rem_euclid(C as i64) as usize];
        let rear = match self.road.mode {
            RoadMode::White => {
                let cell = self.j - self.d - if self.o < self.e { 1 } else { 0 };
                self.heights[cell.rem_euclid(C as i64) as usize]
            }
            RoadMode::Independent => self.rear_h,
        };
        SVector::<T, 2>::new(front, rear)
    }

    /// The transition over `tau` seconds with the input held, cached.
    fn step(&mut self, tau: f64) -> Result<Step<T, N>> {
        for i in 0..self.steps.len() {
            if let Some(s) = self.steps[i] {
                if s.tau == tau {
                    // Most recently used first.
                    self.steps[..=i].rotate_right(1);
                    return Ok(s);
                }
            }
        }
        let dt = T::of(tau);
        let (phi, gamma) = match self.cfg.method {
            Method::Exact => zoh(&self.model, dt)?,
            Method::Rk4 => {
                // auto_substeps' rule with ρ(A) computed once.
                let need = libm::ceil(self.rho * tau / 0.5);
                let auto = if need.is_finite() && need >= 1.0 { (need as usize).min(100_000) } else { 1 };
                let sub = auto.max(self.cfg.substeps.unwrap_or(1));
                rk4_map(&self.model, dt, sub)?
            }
        };
        let s = Step { tau, phi, gamma };
        self.steps.rotate_right(1);
        self.steps[0] = Some(s);
        Ok(s)
    }

    fn integrate(&mut self, tau: f64) -> Result<()> {
        if tau > 0.0 {
            let u = self.input();
            let s = self.step(tau)?;
            self.x = s.phi * self.x + s.gamma * u;
            self.t += tau;
        }
        Ok(())
    }

    /// Distances (m) to the next cell boundary under the front and under the rear wheel.
    fn to_boundaries(&self) -> (T, T) {
        let to_front = self.road.spacing - self.o;
        let to_rear = if self.e > T::zero() {
            if self.o < self.e {
                self.e - self.o
            } else {
                to_front + self.e
            }
        } else {
            to_front
        };
        (to_front, to_rear)
    }

    /// Moves the wheels by `dist` m, which ends exactly on the nearest boundary; draws the
    /// heights of the cells entered.
    fn cross(&mut self, dist: T, to_front: T, to_rear: T) {
        let front = dist >= to_front;
        let rear = dist >= to_rear;
        if front {
            self.j += 1;
            self.o = T::zero();
            self.heights[self.j.rem_euclid(C as i64) as usize] =
                normal::<T>(&mut self.rng_road) * self.cfg.road_sigma[0];
        } else {
            self.o = self.e;
        }
        if rear && self.road.mode == RoadMode::Independent {
            self.rear_h = normal::<T>(&mut self.rng_road) * self.cfg.road_sigma[1];
        }
    }

    /// Drives at `speed` m/s for `duration` s: the state evolves on the held road inputs,
    /// changing at every cell boundary either wheel crosses. `speed = 0` is a stop (the
    /// vehicle stands on its current inputs). Produces no sample.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a negative or non-finite speed or duration (the
    /// simulator is then unchanged).
    pub fn advance(&mut self, speed: T, duration: T) -> Result<()> {
        check_nonneg("speed", speed)?;
        check_nonneg("duration", duration)?;
        let mut rem = duration.to_f64();
        if speed == T::zero() {
            return self.integrate(rem);
        }
        let v = speed.to_f64();
        while rem > 0.0 {
            let (to_front, to_rear) = self.to_boundaries();
            let next = if to_rear < to_front { to_rear } else { to_front };
            let tau = next.to_f64() / v;
            if tau <= rem {
                self.integrate(tau)?;
                rem -= tau;
                self.cross(next, to_front, to_rear);
            } else {
                self.integrate(rem)?;
                self.o += T::of(v * rem);
                rem = 0.0;
            }
        }
        Ok(())
    }

    /// A stop of `duration` s (`advance(0, duration)`).
    ///
    /// # Errors
    /// As [`RoadSimulator::advance`].
    pub fn wait(&mut self, duration: T) -> Result<()> {
        self.advance(T::zero(), duration)
    }

    /// Samples at the current position and time (no motion): measurements of the true state
    /// and derivative with the inputs the wheels are on now.
    pub fn sample_now(&mut self) -> RoadSample<T, N> {
        let u = self.input();
        let x = self.x;
        let xdot = self.model.a() * x + self.model.b() * u;
        let (r, z) = measure(&self.cfg, &self.kinematic, &mut self.rng_w, &mut self.rng_v, &x, &xdot);
        let s = RoadSample { k: self.k, t: T::of(self.t), s: self.distance(), x, xdot, u, r, z };
        self.k += 1;
        s
    }

    /// Samples at the current point, then drives to the next road point (`spacing` m on,
    /// measured from the start of the current cell) at `speed` m/s. Called repeatedly from
    /// the start this samples every `spacing` metres; the speed is the speed over the road
    /// interval following the sample.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] (argument `speed`) for a speed that is not finite and > 0:
    /// a stopped vehicle produces no new sample (use [`RoadSimulator::wait`]). The simulator
    /// is then unchanged.
    pub fn next_sample(&mut self, speed: T) -> Result<RoadSample<T, N>> {
        if !(speed.finite() && speed > T::zero()) {
            return Err(Error::InvalidArgument {
                arg: "speed",
                expected: "a finite speed > 0 to reach the next sample point (a stopped vehicle produces no new samples; use wait())",
            });
        }
        let s = self.sample_now();
        let v = speed.to_f64();
        loop {
            let (to_front, to_rear) = self.to_boundaries();
            let next = if to_rear < to_front { to_rear } else { to_front };
            let tau = if next == self.road.spacing { self.road.spacing.to_f64() / v } else { next.to_f64() / v };
            self.integrate(tau)?;
            self.cross(next, to_front, to_rear);
            if self.o == T::zero() {
                break;
            }
        }
        Ok(s)
    }

    /// Runs `n` samples at the constant `speed`, calling `f` on each (allocation-free).
    ///
    /// # Errors
    /// As [`RoadSimulator::next_sample`].
    pub fn run_with(&mut self, n: usize, speed: T, mut f: impl FnMut(&RoadSample<T, N>)) -> Result<()> {
        for _ in 0..n {
            let s = self.next_sample(speed)?;
            f(&s);
        }
        Ok(())
    }

    /// Runs `n` samples at the constant `speed` into a [`Run`] (with `s`).
    ///
    /// # Errors
    /// As [`RoadSimulator::next_sample`].
    #[cfg(feature = "alloc")]
    pub fn run(&mut self, n: usize, speed: T) -> Result<Run<T>> {
        let mut out = Run::with_capacity(N, 2, n);
        self.run_with(n, speed, |s| out.push_road(s))?;
        Ok(out)
    }
}

/// A whole simulation, row-major per sample (requires `alloc`).
#[cfg(feature = "alloc")]
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Run<T> {
    /// Number of states `n`.
    pub n_states: usize,
    /// Number of inputs `m`.
    pub n_inputs: usize,
    /// Sample times, s (`len`).
    pub t: alloc::vec::Vec<T>,
    /// True states (`len × n`).
    pub x: alloc::vec::Vec<T>,
    /// True derivatives (`len × n`).
    pub xdot: alloc::vec::Vec<T>,
    /// Road inputs (`len × m`).
    pub u: alloc::vec::Vec<T>,
    /// Measured states (`len × n`).
    pub r: alloc::vec::Vec<T>,
    /// Measured derivatives (`len × n`).
    pub z: alloc::vec::Vec<T>,
    /// Distance travelled, m (`len`), for road simulations; empty otherwise.
    pub s: alloc::vec::Vec<T>,
}

#[cfg(feature = "alloc")]
impl<T: Real> Run<T> {
    /// An empty run with room for `len` samples.
    pub fn with_capacity(n: usize, m: usize, len: usize) -> Self {
        use alloc::vec::Vec;
        Self {
            n_states: n,
            n_inputs: m,
            t: Vec::with_capacity(len),
            x: Vec::with_capacity(len * n),
            xdot: Vec::with_capacity(len * n),
            u: Vec::with_capacity(len * m),
            r: Vec::with_capacity(len * n),
            z: Vec::with_capacity(len * n),
            s: Vec::new(),
        }
    }

    /// Appends one road sample (with its distance `s`).
    pub fn push_road<const N: usize>(&mut self, s: &RoadSample<T, N>) {
        self.push(&s.sample());
        self.s.push(s.s);
    }

    /// Appends one sample.
    pub fn push<const N: usize, const M: usize>(&mut self, s: &Sample<T, N, M>) {
        self.t.push(s.t);
        self.x.extend_from_slice(s.x.as_slice());
        self.xdot.extend_from_slice(s.xdot.as_slice());
        self.u.extend_from_slice(s.u.as_slice());
        self.r.extend_from_slice(s.r.as_slice());
        self.z.extend_from_slice(s.z.as_slice());
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// `true` when the run holds no sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{HalfCar, QuarterCar};

    fn quarter_sim(seed: u64, cfg: SimConfig<f64, 4, 1>) -> Simulator<f64, 4, 1> {
        Simulator::new(QuarterCar::thesis().model(), cfg, seed).unwrap()
    }

    #[test]
    fn same_seed_same_run_bit_for_bit() {
        let cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.2).state_noise(0.01).deriv_noise(0.005);
        let mut a = quarter_sim(7, cfg.clone());
        let mut b = quarter_sim(7, cfg.clone());
        let mut c = quarter_sim(8, cfg);
        let mut differs = false;
        for _ in 0..1000 {
            let (sa, sb, sc) = (a.next_sample(), b.next_sample(), c.next_sample());
            assert_eq!(sa, sb);
            differs |= sa.z != sc.z;
        }
        assert!(differs);
    }

    #[test]
    fn noise_streams_are_independent_of_other_sigmas() {
        // The road realization does not change when measurement noise is switched on.
        let quiet = SimConfig::new(0.05).road_sigma(0.1);
        let noisy = quiet.clone().state_noise(0.01).deriv_noise(0.005);
        let (mut a, mut b) = (quarter_sim(3, quiet), quarter_sim(3, noisy));
        for _ in 0..100 {
            let (sa, sb) = (a.next_sample(), b.next_sample());
            assert_eq!(sa.x, sb.x);
            assert_eq!(sa.u, sb.u);
            assert!(sa.r != sb.r);
        }
    }

    #[test]
    fn measurements_equal_truth_plus_noise_with_requested_std() {
        let cfg = SimConfig::new(0.05).road_sigma(0.1).state_noise(0.02).deriv_noise(0.005);
        let mut sim = quarter_sim(11, cfg);
        let n = 20_000;
        let (mut sw, mut sv, mut xd) = (0.0, 0.0, 0.0);
        for _ in 0..n {
            let s = sim.next_sample();
            let xdot = QuarterCar::<f64>::thesis().model().a() * s.x + QuarterCar::<f64>::thesis().model().b() * s.u;
            xd += (xdot - s.xdot).norm();
            sw += (s.r - s.x).norm_squared();
            sv += (s.z - s.xdot).norm_squared();
        }
        assert!(xd < 1e-9);
        // Sample variance of 4n normal draws: relative standard error sqrt(2/(4n)) ≈ 0.5 %.
        let vw = sw / (4 * n) as f64;
        let vv = sv / (4 * n) as f64;
        assert!((vw / 0.02f64.powi(2) - 1.0).abs() < 0.03, "{vw}");
        assert!((vv / 0.005f64.powi(2) - 1.0).abs() < 0.03, "{vv}");
    }

    #[test]
    fn long_run_std_matches_discrete_lyapunov() {
        // The sampled state is a stationary AR(1) process with covariance P solving
        // P = Φ P Φᵀ + Γ σ² Γᵀ. The sample variance over n correlated samples has a standard
        // error of about σ² sqrt(2 τ / n) with τ the correlation time in samples
        // (1.4 s / 0.05 s = 28): sqrt(56/200000) ≈ 1.7 %; allow 4 standard errors (7 %) on
        // the variance, i.e. 3.5 % on the standard deviation.
        let cfg = SimConfig::new(0.05).road_sigma(0.1).method_exact();
        let mut sim = quarter_sim(5, cfg);
        let (phi, gamma) = (*sim.transition().0, *sim.transition().1);
        let p = crate::analysis::discrete_stationary_cov(&phi, &gamma, &[0.1]).unwrap();
        for _ in 0..2000 {
            sim.next_sample(); // burn-in from x(0) = 0
        }
        let n = 200_000;
        let mut acc = SVector::<f64, 4>::zeros();
        sim.run_with(n, |s| acc += s.x.component_mul(&s.x));
        for i in 0..4 {
            let sd = (acc[i] / n as f64).sqrt();
            let expect = p[(i, i)].sqrt();
            assert!((sd / expect - 1.0).abs() < 0.035, "state {i}: {sd} vs {expect}");
        }
        // ẋ1 at the sample instants: the thesis notes quote ≈ 2.09 σ_u (not Eq 4.28's 1.84).
        assert!((p[(1, 1)].sqrt() / 0.1 - 2.09).abs() < 0.01);
    }

    #[test]
    fn rk4_with_many_substeps_matches_exact() {
        let mk = |m: Method, s: Option<usize>| {
            let mut cfg = SimConfig::new(0.05).road_sigma(0.1).ic_sigma(0.3);
            cfg.method = m;
            cfg.substeps = s;
            Simulator::new(HalfCar::<f64>::thesis().model(), cfg, 9).unwrap()
        };
        let (mut a, mut b) = (mk(Method::Exact, None), mk(Method::Rk4, Some(400)));
        for _ in 0..2000 {
            let (sa, sb) = (a.next_sample(), b.next_sample());
            assert!((sa.x - sb.x).abs().max() < 1e-8);
        }
    }

    #[test]
    fn half_car_auto_substeps_is_stable_but_one_step_is_refused() {
        let model = HalfCar::<f64>::thesis().model();
        let cfg = SimConfig::new(0.05).road_sigma(0.1);
        let mut sim = Simulator::new(model.clone(), cfg.clone(), 1).unwrap();
        assert!(sim.substeps() >= 2);
        let mut big = 0.0f64;
        sim.run_with(5000, |s| big = big.max(s.x.abs().max()));
        assert!(big < 1.0);
        let mut one = cfg;
        one.substeps = Some(1);
        assert!(matches!(Simulator::new(model, one, 1), Err(Error::InvalidArgument { arg: "substeps", .. })));
    }

    #[test]
    fn instrumentation_reads_kinematic_rows_from_velocity_sensor() {
        let mut cfg = SimConfig::new(0.05).road_sigma(0.1).state_noise(0.01).deriv_noise(0.005);
        cfg.instrumentation = true;
        let mut sim = quarter_sim(2, cfg);
        for _ in 0..10 {
            let s = sim.next_sample();
            assert_eq!(s.z[0], s.r[1]);
            assert_eq!(s.z[2], s.r[3]);
            assert!(s.z[1] != s.xdot[1]);
        }
    }

    #[test]
    fn pulses_and_bad_configs() {
        let cfg = SimConfig::new(0.05).with_pulse(Pulse { start: 8, width: 2, amplitude: 0.5 }).unwrap();
        let mut sim = quarter_sim(1, cfg);
        let us: Vec<f64> = (0..12).map(|_| sim.next_sample().u[0]).collect();
        assert_eq!(&us[7..11], &[0.0, 0.5, 0.5, 0.0]);
        let model = QuarterCar::<f64>::thesis().model();
        let bad = |cfg: SimConfig<f64, 4, 1>| Simulator::new(model.clone(), cfg, 0).err().unwrap();
        assert!(matches!(bad(SimConfig::new(0.0)), Error::InvalidArgument { arg: "dt", .. }));
        assert!(matches!(bad(SimConfig::new(f64::NAN)), Error::InvalidArgument { arg: "dt", .. }));
        assert!(matches!(bad(SimConfig::new(0.05).road_sigma(-1.0)), Error::InvalidArgument { arg: "road_sigma", .. }));
        assert!(matches!(
            bad(SimConfig::new(0.05).ic_sigma(f64::INFINITY)),
            Error::InvalidArgument { arg: "ic_sigma", .. }
        ));
        assert!(matches!(
            bad(SimConfig::new(0.05).deriv_noise(-0.1)),
            Error::InvalidArgument { arg: "deriv_noise", .. }
        ));
        let mut zero_sub = SimConfig::new(0.05);
        zero_sub.substeps = Some(0);
        assert!(matches!(bad(zero_sub), Error::InvalidArgument { arg: "substeps", .. }));
        assert!(SimConfig::<f64, 4, 1>::new(0.05).with_pulse(Pulse { start: 0, width: 0, amplitude: 1.0 }).is_err());
        let mut full = SimConfig::<f64, 4, 1>::new(0.05);
        for _ in 0..MAX_PULSES {
            full = full.with_pulse(Pulse { start: 0, width: 1, amplitude: 1.0 }).unwrap();
        }
        assert!(matches!(full.with_pulse(Pulse { start: 0, width: 1, amplitude: 1.0 }), Err(Error::Capacity { .. })));
    }

    #[test]
    fn f32_simulation_tracks_f64() {
        let cfg64 = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
        let cfg32 = SimConfig::<f32, 4, 1>::new(0.05).road_sigma(0.1).deriv_noise(0.005);
        let mut a = quarter_sim(4, cfg64);
        let mut b = Simulator::new(QuarterCar::<f32>::thesis().model(), cfg32, 4).unwrap();
        for _ in 0..500 {
            let (sa, sb) = (a.next_sample(), b.next_sample());
            for i in 0..4 {
                assert!((sa.x[i] - sb.x[i] as f64).abs() < 1e-4);
            }
        }
    }

    fn half_road(mode: RoadMode, spacing: f64, seed: u64) -> RoadSimulator<f64, 8, 16> {
        let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
        RoadSimulator::new(HalfCar::thesis().model(), cfg, RoadConfig::new(spacing, 3.0).mode(mode), seed).unwrap()
    }

    #[test]
    fn road_independent_at_constant_speed_is_the_time_simulator() {
        // 6 m/s over 0.3 m road points is the thesis' 0.05 s held input, and the streams are
        // the Simulator's: the same run.
        let mut road = half_road(RoadMode::Independent, 0.3, 4);
        let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.005);
        let mut time = Simulator::new(HalfCar::<f64>::thesis().model(), cfg, 4).unwrap();
        for k in 0..3000 {
            let (a, b) = (road.next_sample(6.0).unwrap(), time.next_sample());
            assert_eq!(a.u, b.u);
            assert!((a.x - b.x).abs().max() < 1e-9 * (1.0 + b.x.abs().max()), "k={k}");
            assert!((a.t - b.t).abs() < 1e-9 && (a.s - 0.3 * k as f64).abs() < 1e-9);
        }
    }

    #[test]
    fn road_white_rear_meets_front_road_d_samples_later_at_any_speed() {
        let mut sim = half_road(RoadMode::White, 0.3, 2);
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        let mut us = Vec::new();
        let mut t_prev = 0.0;
        for k in 0..500 {
            let v = 0.5 + 20.0 * rand::RngExt::random::<f64>(&mut rng);
            let s = sim.next_sample(v).unwrap();
            assert!((s.s - 0.3 * k as f64).abs() < 1e-9);
            if k > 0 {
                assert!(s.t > t_prev);
            }
            t_prev = s.t;
            us.push(s.u);
            if k >= 10 {
                assert_eq!(s.u[1], us[k - 10][0]);
            }
            if k % 50 == 0 {
                sim.wait(0.7).unwrap(); // a stop: time passes, no sample, no motion
            }
        }
        assert!(us.iter().all(|u| u[0] != 0.0));
    }

    #[test]
    fn road_non_integer_wheelbase_and_time_driving() {
        // Δ = 0.4 m, L = 3 m: d = 7, the rear axle is 0.2 m into a cell when the front is on a
        // boundary, so at sample k it is on the front's cell k − 8.
        let mut sim = half_road(RoadMode::White, 0.4, 5);
        let mut fronts = Vec::new();
        for k in 0..100 {
            let s = sim.next_sample(5.0).unwrap();
            fronts.push(s.u[0]);
            if k >= 8 {
                assert_eq!(s.u[1], fronts[k - 8]);
            }
        }
        // Driving by time: 2 s at 3 m/s is 6 m; a stop moves nothing.
        let s0 = sim.distance();
        sim.advance(3.0, 2.0).unwrap();
        assert!((sim.distance() - s0 - 6.0).abs() < 1e-9);
        let (x, k) = (*sim.state(), sim.k());
        sim.advance(0.0, 1.0).unwrap();
        assert_eq!(sim.k(), k);
        assert!(*sim.state() != x);
        let before = sim.clone();
        assert!(matches!(sim.next_sample(0.0), Err(Error::InvalidArgument { arg: "speed", .. })));
        assert!(matches!(sim.advance(-1.0, 1.0), Err(Error::InvalidArgument { arg: "speed", .. })));
        assert!(matches!(sim.advance(1.0, f64::NAN), Err(Error::InvalidArgument { arg: "duration", .. })));
        assert_eq!((before.state(), before.k(), before.distance()), (sim.state(), sim.k(), sim.distance()));
    }

    #[test]
    fn road_bad_configs() {
        let model = HalfCar::<f64>::thesis().model();
        let cfg = SimConfig::new(0.05).road_sigma(0.1);
        let mk = |spacing: f64, wheelbase: f64| {
            RoadSimulator::<f64, 8, 16>::new(model.clone(), cfg.clone(), RoadConfig::new(spacing, wheelbase), 1).err()
        };
        assert!(matches!(mk(0.1, 3.0), Some(Error::Capacity { needed: 32, capacity: 16, .. })));
        assert!(matches!(mk(0.0, 3.0), Some(Error::InvalidArgument { arg: "spacing", .. })));
        assert!(matches!(mk(0.3, f64::NAN), Some(Error::InvalidArgument { arg: "wheelbase", .. })));
        assert!(mk(0.3, 3.0).is_none());
    }
}

impl<T: Real, const N: usize, const M: usize> SimConfig<T, N, M> {
    /// Selects the exact zero-order-hold method.
    pub fn method_exact(mut self) -> Self {
        self.method = Method::Exact;
        self
    }
}
