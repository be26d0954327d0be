//! Instruments from an auxiliary model driven by the measured input: the SRIVC / RIVC idea
//! of Young and Garnier, recursive, for structures with a measured input.
//!
//! # The instruments
//! The optimal instruments of an equation `y_i = h_i(r, z, u)ᵀ p + ε_i` with white `ε` are
//! the regressors' noise-free part (Söderström & Stoica, *System Identification*, 1989,
//! §8.2). When the system is driven by a *measured* input `u`, that part is what the system
//! itself would do on `u`: the simple refined IV for continuous-time models (SRIVC) of Young
//! and Garnier obtains the instruments by simulating the current estimate of the
//! continuous-time model on the measured input, and iterates (P. C. Young, *Recursive
//! Estimation and Time-Series Analysis*, 2nd ed., 2011, Ch. 8, the RIVC/SRIVC algorithms;
//! H. Garnier & L. Wang (eds.), *Identification of Continuous-time Models from Sampled
//! Data*, 2008, Ch. 4, §4.4–4.5). Here the auxiliary model is the structure itself with the
//! auxiliary parameters `p̂_a`:
//!
//! ```text
//! x̂(k+1) = Φ_RK4(x̂(k), u(k); p̂_a, dt)      (u held over the interval: zero-order hold)
//! ẑ(k)   = f(x̂(k), u(k); p̂_a)              (Structure::derivative, for der(·) terms)
//! ζ_i(k) = h_i(x̂(k), ẑ(k), u(k))
//! ```
//!
//! `Φ_RK4` is [`Structure::simulate`]'s step: `substeps` classical Runge–Kutta steps of
//! `dt / substeps` each (any structure, `sign`/`pos`/`neg` included; for a linear one the
//! error against the exact zero-order-hold map `e^{A dt}` is `O((|λ| dt / substeps)⁵)`).
//! `x̂(k)` depends on the measured inputs and samples before `k` only, so `ζ(k)` is
//! independent of the sensor noise at `k` (white), which is what makes the estimate
//! consistent; it is noise-free, so it is as correlated with `h(k)` as any instrument can be.
//! The measured derivatives `z` play the part of SRIVC's prefiltered derivatives: they are
//! measured here, the equation error is white, and so no prefilter is needed (§8.2 again:
//! the optimal prefilter is the inverse noise model, here 1).
//!
//! # The recursion and the refresh rule
//! The estimate is the recursive IV of [`InstrumentalVariables`] (`iv_filter.rs`: exact start
//! or prior) fed these instruments. The auxiliary model is iterated as in SRIVC, recursively:
//! - Until it has parameters, the instruments are the delayed regressors (the plain
//!   identifier), which start the estimate.
//! - Every `refresh` samples, once the estimate exists, the current `θ̂` becomes the
//!   auxiliary parameters `p̂_a` — if its linear part is stable (below). On the first
//!   adoption the auxiliary state starts from the measured state of that sample,
//!   `x̂(k+1) = Φ_RK4(r(k), u(k))`, so its instruments are used from the next sample on (the
//!   noise of `r(k)` is then in the past of every sample it touches); later adoptions keep
//!   `x̂` and change the model it follows. `refresh = 0` never adopts: with a given `p̂_a`
//!   (`theta_aux`) the instruments are then those of one fixed model (the batch reference's).
//! - A candidate with an unstable linear part is **not** adopted: the previous auxiliary
//!   model stays (or the delayed regressors, before the first), the refusal is counted
//!   ([`ModelInstruments::refused`]) and the next candidate is tried `refresh` samples later.
//!   Stable means `‖Φ^(2^j)‖_∞ < 1/2` for some `j ≤ 40`, with `Φ` the one-sample map of the
//!   state's linear part (columns `Φ_RK4(e_j, 0) − Φ_RK4(0, 0)`): then the spectral radius
//!   `ρ(Φ) ≤ ‖Φ^K‖^{1/K} < 1` (a sufficient test, no eigenvalues; a model whose slowest mode
//!   needs more than 2⁴⁰ samples to halve counts as unstable).
//! - Should the simulated state still leave the range (overflow, or a value at or above the
//!   update's limit √(largest)/256, e.g. a nonlinear structure whose linear part is stable),
//!   the auxiliary state restarts from the measured one, as at the first adoption
//!   ([`ModelInstruments::restarts`]).
//!
//! The update is transactional: the step of `x̂` is computed before the filter's and kept
//! only when the filter accepts the sample; the refresh runs after, and cannot fail.

use super::interface::Identifier;
use super::{Dims, Flat, InstrumentalVariables, IvFilter};
use crate::structure::{Structure, MAX_INPUTS, MAX_PARAMS, MAX_STATES};
use crate::{Error, Real, Result};

/// Most squarings of the stability test (a mode that halves within 2⁴⁰ samples is stable).
const SQUARINGS: usize = 40;

/// The auxiliary model's state: its parameters and simulated state (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub(crate) struct AuxModel<T> {
    /// `p̂_a` (the structure's parameter order).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    theta: [T; MAX_PARAMS],
    /// `x̂(k)` of the next sample.
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    x: [T; MAX_STATES],
    dt: T,
    substeps: u32,
    refresh: u32,
    /// Samples since the last refresh (or attempt).
    since: u32,
    /// `p̂_a` holds parameters; `x̂` holds a simulated state.
    model: bool,
    running: bool,
    adopted: u64,
    refused: u64,
    restarts: u64,
}

/// Recursive IV whose instruments are the noise-free states of an auxiliary model simulated
/// from the measured input (module docs): built by
/// [`InstrumentalVariables::with_model_instruments`].
///
/// With the feature `serde` it is serialized whole (the identifier and the auxiliary model)
/// and checked on load.
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct ModelInstruments<T: Real, const P: usize, F: Flat<IvFilter<T, P>>> {
    iv: InstrumentalVariables<T, P, F, 0>,
    aux: AuxModel<T>,
}

/// [`ModelInstruments`] with its `G` groups' filters in an array: no allocation.
pub type ModelIvIdentifier<T, const P: usize, const G: usize> = ModelInstruments<T, P, [IvFilter<T, P>; G]>;

/// [`ModelInstruments`] with its groups' filters in a `Vec` (requires `alloc`).
#[cfg(feature = "alloc")]
pub type ModelIvIdentifierVec<T, const P: usize> = ModelInstruments<T, P, alloc::vec::Vec<IvFilter<T, P>>>;

/// `true` when the linear part of `s` with parameters `p` is stable over one sample (module
/// docs: `‖Φ^(2^j)‖_∞ < 1/2` for some `j ≤ 40`). `false` when a simulation overflows.
pub(crate) fn stable<T: Real>(s: &Structure<T>, p: &[T], dt: T, substeps: u32) -> bool {
    let (n, m) = (s.states(), s.inputs());
    let u = [T::zero(); 2 * MAX_INPUTS];
    let mut out = [T::zero(); 2 * MAX_STATES];
    let mut x0 = [T::zero(); MAX_STATES];
    if s.simulate(p, &x0[..n], &u[..2 * m], dt, substeps, &mut out[..2 * n]).is_err() {
        return false;
    }
    let mut base = [T::zero(); MAX_STATES];
    base[..n].copy_from_slice(&out[n..2 * n]);
    // Φ, column j: the map of e_j less the map of 0 (an offset cancels).
    let mut phi = [[T::zero(); MAX_STATES]; MAX_STATES];
    for j in 0..n {
        x0[j] = T::one();
        let ok = s.simulate(p, &x0[..n], &u[..2 * m], dt, substeps, &mut out[..2 * n]).is_ok();
        x0[j] = T::zero();
        if !ok {
            return false;
        }
        for i in 0..n {
            phi[i][j] = out[n + i] - base[i];
        }
    }
    let norm = |a: &[[T; MAX_STATES]; MAX_STATES]| {
        (0..n).map(|i| a[i][..n].iter().fold(T::zero(), |acc, v| acc + v.abs())).fold(T::zero(), |a, b| a.max(b))
    };
    let half = T::of(0.5);
    let big = T::biggest().sqrt() / T::of(256.0);
    for _ in 0..=SQUARINGS {
        let nm = norm(&phi);
        if nm < half {
            return true;
        }
        if !(nm < big) {
            return false;
        }
        let mut sq = [[T::zero(); MAX_STATES]; MAX_STATES];
        for i in 0..n {
            for k in 0..n {
                let a = phi[i][k];
                for j in 0..n {
                    sq[i][j] += a * phi[k][j];
                }
            }
        }
        phi = sq;
    }
    false
}

impl<T: Real, const P: usize, F: Flat<IvFilter<T, P>>> InstrumentalVariables<T, P, F, 0> {
    /// Instruments from the auxiliary model (`iv_model.rs`; SRIVC/RIVC): the structure with
    /// parameters `p̂_a` simulated from the measured input with the sample interval `dt`
    /// seconds (`substeps` RK4 steps per sample, inputs held), its state's regressors the
    /// instruments. `refresh` (samples, ≥ 0) is how often the current estimate replaces `p̂_a`
    /// when stable (0: never); `theta_aux` an initial `p̂_a` (`None`: the delayed regressors
    /// until the first refresh). The delay given at construction remains the fallback
    /// instruments' delay. Call before the first sample.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming `instruments` for a structure without a measured
    /// input (nothing to simulate the model from: use the delayed regressors or `lags`),
    /// `structure` for one that cannot be simulated (a state without an equation: add a known
    /// equation), `dt` (finite, > 0), `substeps` (≥ 1), `refresh` (0 with no `theta_aux`
    /// would never have instruments), `theta_aux` (not stable) or samples already seen;
    /// [`Error::Shape`] / [`Error::NonFinite`] naming `theta_aux`.
    pub fn with_model_instruments(
        self,
        dt: T,
        substeps: u32,
        refresh: usize,
        theta_aux: Option<&[T]>,
    ) -> Result<ModelInstruments<T, P, F>> {
        let s = self.structure();
        if self.samples() > 0 {
            return Err(Error::InvalidArgument { arg: "instruments", expected: "chosen before the first sample" });
        }
        if s.inputs() == 0 {
            return Err(Error::InvalidArgument {
                arg: "instruments",
                expected: "a structure with a measured input for instruments from the auxiliary model (it is \
                           simulated from the measured input; without one use the delayed regressors, or lags > 0 \
                           for the data-driven predictor)",
            });
        }
        if !s.complete() {
            return Err(Error::InvalidArgument {
                arg: "structure",
                expected: "an equation for every state, so that the auxiliary model can be simulated (add known \
                           equations, e.g. q = v)",
            });
        }
        if !(dt > T::zero() && dt.finite()) {
            return Err(Error::InvalidArgument { arg: "dt", expected: "the sample interval: finite and > 0 s" });
        }
        if substeps == 0 {
            return Err(Error::InvalidArgument { arg: "substeps", expected: "at least 1 RK4 step per sample" });
        }
        let refresh = u32::try_from(refresh)
            .map_err(|_| Error::InvalidArgument { arg: "refresh", expected: "at most 2³² − 1 samples" })?;
        let mut aux = AuxModel {
            theta: [T::zero(); MAX_PARAMS],
            x: [T::zero(); MAX_STATES],
            dt,
            substeps,
            refresh,
            since: 0,
            model: false,
            running: false,
            adopted: 0,
            refused: 0,
            restarts: 0,
        };
        match theta_aux {
            Some(t) => {
                if t.len() != s.params() {
                    return Err(Error::Shape { arg: "theta_aux", expected: s.params(), got: t.len() });
                }
                crate::error::check_finite("theta_aux", t)?;
                if !stable(s, t, dt, substeps) {
                    return Err(Error::InvalidArgument {
                        arg: "theta_aux",
                        expected: "an auxiliary model whose linear part is stable at this dt (its simulation would \
                                   diverge)",
                    });
                }
                aux.theta[..t.len()].copy_from_slice(t);
                aux.model = true;
            }
            None if refresh == 0 => {
                return Err(Error::InvalidArgument {
                    arg: "refresh",
                    expected: "≥ 1 sample when no theta_aux is given (with neither, the auxiliary model never gets \
                               parameters)",
                });
            }
            None => {}
        }
        Ok(ModelInstruments { iv: self, aux })
    }
}

impl<T: Real, const P: usize, F: Flat<IvFilter<T, P>>> ModelInstruments<T, P, F> {
    /// The recursive IV identifier inside.
    pub fn inner(&self) -> &InstrumentalVariables<T, P, F, 0> {
        &self.iv
    }

    /// The auxiliary parameters `p̂_a` (`None` before the first adoption with no `theta_aux`).
    pub fn theta_aux(&self) -> Option<&[T]> {
        self.aux.model.then(|| &self.aux.theta[..self.iv.structure().params()])
    }

    /// The auxiliary model's simulated state `x̂` for the next sample (`None` until it runs).
    pub fn state_aux(&self) -> Option<&[T]> {
        self.aux.running.then(|| &self.aux.x[..self.iv.structure().states()])
    }

    /// Candidates adopted as the auxiliary model.
    pub fn adopted(&self) -> u64 {
        self.aux.adopted
    }

    /// Candidates refused for an unstable linear part (the previous model kept).
    pub fn refused(&self) -> u64 {
        self.aux.refused
    }

    /// Restarts of the auxiliary state from the measured one after it left the range.
    pub fn restarts(&self) -> u64 {
        self.aux.restarts
    }

    /// The sample interval `dt`, seconds, the RK4 steps per sample and the refresh interval.
    pub fn settings(&self) -> (T, u32, usize) {
        (self.aux.dt, self.aux.substeps, self.aux.refresh as usize)
    }

    /// `Φ_RK4(x, u)` into `out` (`n` values), or `false` when it leaves the range.
    fn step(&self, x: &[T], u: &[T], out: &mut [T]) -> bool {
        let s = self.iv.structure();
        let (n, m, np) = (s.states(), s.inputs(), s.params());
        let mut uu = [T::zero(); 2 * MAX_INPUTS];
        uu[..m].copy_from_slice(&u[..m]);
        let mut both = [T::zero(); 2 * MAX_STATES];
        let a = &self.aux;
        let ok = s.simulate(&a.theta[..np], &x[..n], &uu[..2 * m], a.dt, a.substeps, &mut both[..2 * n]).is_ok();
        let limit = T::biggest().sqrt() / T::of(256.0);
        out[..n].copy_from_slice(&both[n..2 * n]);
        ok && out[..n].iter().all(|v| v.abs() < limit)
    }

    /// After an accepted sample `(x, u)`: the auxiliary state's step (planned as `next`:
    /// `Some` when it stayed in range), then the refresh (module docs).
    fn after(&mut self, x: &[T], u: &[T], next: Option<[T; MAX_STATES]>) {
        if self.aux.running {
            match next {
                Some(v) => self.aux.x = v,
                None => {
                    self.aux.restarts += 1;
                    self.restart(x, u);
                }
            }
        }
        if self.aux.refresh > 0 && !self.iv.starting() {
            self.aux.since += 1;
            if self.aux.since >= self.aux.refresh {
                self.aux.since = 0;
                let s = self.iv.structure();
                let np = s.params();
                let mut cand = [T::zero(); MAX_PARAMS];
                let ok = self.iv.params_into(&mut cand[..np]).is_ok()
                    && cand[..np].iter().all(|v| v.finite())
                    && stable(s, &cand[..np], self.aux.dt, self.aux.substeps);
                if ok {
                    self.aux.theta = cand;
                    self.aux.model = true;
                    self.aux.adopted += 1;
                } else {
                    self.aux.refused += 1;
                }
            }
        }
        if self.aux.model && !self.aux.running {
            self.restart(x, u);
        }
    }

    /// Starts the auxiliary state from the measured sample: `x̂ = Φ_RK4(r(k), u(k))`, or the
    /// measured state itself should even that leave the range.
    fn restart(&mut self, x: &[T], u: &[T]) {
        let n = self.iv.structure().states();
        let mut next = [T::zero(); MAX_STATES];
        if !self.step(x, u, &mut next) {
            next[..n].copy_from_slice(&x[..n]);
        }
        self.aux.x = next;
        self.aux.running = true;
    }

    /// Checks a deserialized identifier (feature `serde`): the auxiliary model's settings
    /// (`dt` finite and > 0, `substeps` ≥ 1, a structure with an input that can be simulated),
    /// its parameters and state finite, below the update's limit and 0 beyond the
    /// structure's sizes, a running state only with parameters, and no parameters without a
    /// way to get them (`refresh` 0). Each failure names what is wrong.
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let corrupt = |expected| Err(Error::InvalidArgument { arg: "state", expected });
        let s = self.iv.structure();
        let (n, np) = (s.states(), s.params());
        let a = &self.aux;
        if s.inputs() == 0 || !s.complete() {
            return corrupt("model instruments on a structure with a measured input and an equation for every state");
        }
        if !(a.dt > T::zero() && a.dt.finite()) || a.substeps == 0 {
            return corrupt("model instruments with a sample interval dt > 0 and at least 1 RK4 step");
        }
        let limit = T::biggest().sqrt() / T::of(256.0);
        let fits = |v: &[T], k: usize| v[..k].iter().all(|x| x.abs() < limit) && v[k..].iter().all(|&x| x == T::zero());
        if !fits(&a.theta, np) || !fits(&a.x, n) {
            return corrupt("an auxiliary model's parameters and state finite and 0 beyond the structure's sizes");
        }
        if (!a.model && (a.running || a.refresh == 0)) || (!a.running && a.x.iter().any(|&v| v != T::zero())) {
            return corrupt("an auxiliary model running only with parameters, and with a way to get them");
        }
        Ok(())
    }
}

super::persist_by_serde!([T: Real, const P: usize, F: Flat<IvFilter<T, P>>] ModelInstruments<T, P, F>);

impl<T: Real, const P: usize, F: Flat<IvFilter<T, P>>> Identifier<T> for ModelInstruments<T, P, F> {
    fn dims(&self) -> Dims {
        self.iv.dims()
    }

    fn rows(&self) -> &[usize] {
        self.iv.rows()
    }

    /// One sample: with the auxiliary model running, the instruments' sample is
    /// `(x̂(k), f(x̂(k), u(k)), u(k))`; before, the delayed regressors'. Then the auxiliary
    /// state's step and the refresh (module docs). Transactional.
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        if !self.aux.running {
            self.iv.update_into(x, z, u, e)?;
            self.after(x, u, None);
            return Ok(());
        }
        let s = self.iv.structure();
        let (n, m, np) = (s.states(), s.inputs(), s.params());
        if x.len() != n || u.len() != m {
            // Refused by the identifier's own check, which names the argument.
            return self.iv.update_with(x, z, u, (x, z, u), e);
        }
        let mut az = [T::zero(); MAX_STATES];
        s.derivative(&self.aux.theta[..np], &self.aux.x[..n], u, &mut az[..n]);
        let mut next = [T::zero(); MAX_STATES];
        let ok = self.step(&self.aux.x, u, &mut next);
        let ax = self.aux.x;
        self.iv.update_with(x, z, u, (&ax[..n], &az[..n], u), e)?;
        self.after(x, u, ok.then_some(next));
        Ok(())
    }

    fn params_into(&self, out: &mut [T]) -> Result<()> {
        self.iv.params_into(out)
    }

    fn samples(&self) -> u64 {
        self.iv.samples()
    }

    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        self.iv.covariance_into(out)
    }

    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        self.iv.noise_into(out)
    }

    fn residuals_into(&self, ssr: &mut [T], nobs: &mut [T]) -> Result<()> {
        self.iv.residuals_into(ssr, nobs)
    }

    fn groups_into(&self, group_of_param: &mut [usize], group_of_eq: &mut [usize]) -> Result<()> {
        self.iv.groups_into(group_of_param, group_of_eq)
    }
}
