//! Two axles on one road, sampled by distance (Ch. VI.D).

#[cfg(feature = "alloc")]
use super::Run;
use super::{measure, normal, streams, Method, Sample, SimConfig};
use crate::error::{check_finite, check_nonneg, check_positive};
use crate::model::LinearModel;
use crate::model::{rk4_map, zoh};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};
use rand::rngs::Xoshiro256PlusPlus;

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

option_names!(RoadMode, "road", { White => "white", Independent => "independent" });

/// The speed of a road simulation, sample by sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SpeedProfile<'a, T> {
    /// The same speed for every sample, m/s (> 0).
    Constant(T),
    /// One entry per road interval, used in order from `next`: entry `i` is the speed (m/s)
    /// over the road interval after the next sample; a zero entry is a stop of `stop`
    /// seconds on the road point reached, before its sample (no sample for that entry).
    PerSample {
        /// The speeds, m/s (each finite and ≥ 0).
        speeds: &'a [T],
        /// The first entry not used yet.
        next: usize,
        /// Length of a stop, s (≥ 0).
        stop: T,
    },
}

impl<T: Real> SpeedProfile<'_, T> {
    /// Samples the profile can still produce (its positive entries from `next` on); `None`
    /// for a constant speed (unbounded).
    pub fn samples_left(&self) -> Option<usize> {
        match self {
            SpeedProfile::Constant(_) => None,
            SpeedProfile::PerSample { speeds, next, .. } => {
                Some(speeds.get(*next..).map_or(0, |v| v.iter().filter(|x| **x > T::zero()).count()))
            }
        }
    }

    /// Checks what a run of `n` samples uses: a constant speed as [`SpeedProfile::validate`];
    /// of a per-sample profile, the stop and the entries from `next` up to the `n`-th positive
    /// one (finite and ≥ 0), so that the cost is that of the run, not of the whole profile
    /// (a run in pieces would otherwise check a long profile once per piece).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] (argument `n`) when fewer than `n` positive entries are
    /// left; as [`SpeedProfile::validate`] for a bad entry among those used (the index is the
    /// entry's in the whole profile).
    pub fn check_next(&self, n: usize) -> Result<()> {
        let SpeedProfile::PerSample { speeds, next, stop } = *self else {
            return self.validate();
        };
        check_nonneg("stop", stop)?;
        let mut found = 0;
        let mut i = next;
        while found < n {
            let Some(&v) = speeds.get(i) else {
                return Err(Error::InvalidArgument {
                    arg: "n",
                    expected: "at most as many samples as the `speed` profile has non-zero entries left",
                });
            };
            if !v.finite() {
                return Err(Error::NonFinite { arg: "speed", index: i });
            }
            if v < T::zero() {
                return Err(Error::InvalidArgument { arg: "speed", expected: "speeds >= 0, m/s" });
            }
            found += usize::from(v > T::zero());
            i += 1;
        }
        Ok(())
    }

    /// Checks every speed: finite and > 0 for a constant, finite and ≥ 0 per sample.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] (argument `speed`), [`Error::NonFinite`] naming the entry.
    pub fn validate(&self) -> Result<()> {
        match *self {
            SpeedProfile::Constant(v) => {
                if !(v.finite() && v > T::zero()) {
                    return Err(Error::InvalidArgument {
                        arg: "speed",
                        expected:
                            "a finite speed > 0, m/s (a stopped vehicle produces no samples: give a per-sample profile)",
                    });
                }
            }
            SpeedProfile::PerSample { speeds, stop, .. } => {
                check_finite("speed", speeds)?;
                if speeds.iter().any(|v| *v < T::zero()) {
                    return Err(Error::InvalidArgument { arg: "speed", expected: "speeds >= 0, m/s" });
                }
                check_nonneg("stop", stop)?;
            }
        }
        Ok(())
    }
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
    /// here. The random streams are the [`Simulator`](super::Simulator)'s for the same seed.
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
                // auto_substeps' rule with ρ(A) computed once. A step so long (a very low
                // speed) that RK4 would need more than MAX_SUBSTEPS sub-steps uses the exact
                // zero-order hold, to which RK4 converges.
                let need = libm::ceil(self.rho * tau / 0.5);
                if need > crate::model::MAX_SUBSTEPS as f64 {
                    zoh(&self.model, dt)?
                } else {
                    let auto = if need.is_finite() && need >= 1.0 { need as usize } else { 1 };
                    let sub = auto.max(self.cfg.substeps.unwrap_or(1));
                    rk4_map(&self.model, dt, sub)?
                }
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

impl<T: Real, const N: usize, const C: usize> RoadSimulator<T, N, C> {
    /// Runs `n` samples following `profile` (its cursor advances), calling `f` on each. A
    /// zero entry of a per-sample profile is a stop ([`RoadSimulator::wait`]) and produces no
    /// sample. No allocation.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] (argument `n`) when the profile has fewer than `n` samples
    /// left, and the checks of [`SpeedProfile::check_next`] (the entries this run uses);
    /// nothing is simulated then.
    pub fn run_profile(
        &mut self,
        n: usize,
        profile: &mut SpeedProfile<'_, T>,
        mut f: impl FnMut(&RoadSample<T, N>),
    ) -> Result<()> {
        profile.check_next(n)?;
        let mut done = 0;
        while done < n {
            let v = match profile {
                SpeedProfile::Constant(v) => *v,
                SpeedProfile::PerSample { speeds, next, stop } => {
                    let v = speeds[*next];
                    *next += 1;
                    if v == T::zero() {
                        self.wait(*stop)?;
                        continue;
                    }
                    v
                }
            };
            let s = self.next_sample(v)?;
            f(&s);
            done += 1;
        }
        Ok(())
    }
}
