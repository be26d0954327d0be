//! The simulator sampled at a fixed interval (Ch. III.C).

#[cfg(feature = "alloc")]
use super::Run;
use super::{measure, normal, streams, Method, SimConfig};
use crate::error::check_finite;
use crate::model::LinearModel;
use crate::model::{auto_substeps, rk4_map, zoh};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};
use rand::rngs::Xoshiro256PlusPlus;

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

    #[inline]
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
    #[inline]
    fn next_input(&mut self) -> SVector<T, M> {
        let pulse = self.pulse_at(self.k);
        let mut u = SVector::<T, M>::zeros();
        for j in 0..M {
            u[j] = normal::<T>(&mut self.rng_road) * self.cfg.road_sigma[j] + pulse;
        }
        u
    }

    /// Produces sample `k` and advances the state to `k + 1`.
    #[inline]
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

    #[inline]
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
