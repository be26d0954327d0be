//! Joint state and parameter estimation: an extended Kalman filter on the augmented state
//! (the thesis' Ch. VII proposal for further study).
//!
//! The regression identifiers treat the measured state `r(k)` as the regressor, so noise on
//! it biases them (errors in variables, Ch. IV.D). Here the state is not a regressor but an
//! unknown: the filter estimates the model states `x`, the parameters `p` of a
//! [`Structure`] and the road input `u` of each sample together, from the measured states
//! and the measured derivatives, with every noise where it really enters (Ljung, "Asymptotic
//! behavior of the extended Kalman filter as a parameter estimator for linear systems",
//! *IEEE Trans. Automatic Control* 24(1), 1979; Jazwinski, *Stochastic Processes and Filtering
//! Theory*, 1970, §8.3 for the augmented state).
//!
//! # The model
//! Continuous-time dynamics, the structure's equations plus the road through its input
//! column `g` (the `B` of `ẋ = A x + B u`, given), the road held over each interval (zero-order
//! hold, as in the thesis' simulation, Ch. III.C) and white from sample to sample:
//!
//! ```text
//! ẋ(t) = f(x, p, u_m) + g u_k              t ∈ [t_k, t_k+1),  u_k ~ N(0, σ_u²)
//! p_k+1 = p_k + η_k                         η_k ~ N(0, q I)  (q = 0: constant parameters)
//! r_k = x_k + w_k                           w_k ~ N(0, Σ_w),  Σ_w diagonal
//! z_k = f(x_k, p_k, u_m) + g u_k + v_k      v_k ~ N(0, Σ_v),  Σ_v diagonal
//! ```
//!
//! `f` is [`Structure::derivative`] (every equation in dependency order, `der(·)` reading the
//! derivatives just computed: the quarter car's physical wheel equation reads the body's
//! acceleration); `u_m` are the structure's measured inputs (held too).
//!
//! # How the road enters (the one modelling choice)
//! The same `u_k` drives the state from `t_k` to `t_k+1` *and* appears in `z_k`: the process
//! noise and the derivative measurement's noise are correlated. Dropping `z`'s road rows
//! would waste the rows that carry the parameters; pretending the two are independent would
//! count the road twice. The filter instead carries `u_k` as one more component of the
//! augmented state `s = [x; p; u]` (dimension `D = n + params + 1`): at each sample `u_k`
//! enters with mean 0 and variance `σ_u²`, independent of everything before; the update
//! with `z_k` gives its posterior (correlated with `x` and `p`), and the prediction through
//! the interval uses it. This is the exact generative model of the samples, so no
//! correlation is lost or invented (it is the correlated-noise Kalman filter, Anderson &
//! Moore, *Optimal Filtering*, 1979, §5.5, written as an augmentation).
//!
//! # The steps (per sample)
//! 1. **Update** at the prior `ŝ`: the `2n` scalar measurements `r_k,i` (`h = e_i`, variance
//!    `Σ_w,ii`) and `z_k,i` (`h = ∂f_i/∂s` at `ŝ`, variance `Σ_v,ii`) are processed one at a
//!    time (exact for a diagonal noise covariance; the linearization stays at the prior, so
//!    the result is the batch EKF update): `s_i = hᵀ P h + R_i`, `k = P h / s_i`,
//!    `ŝ ← ŝ + k (y_i − ŷ_i − hᵀ δ)` (`δ` the correction so far), and the covariance in the
//!    Joseph form `P ← (I − k hᵀ) P (I − k hᵀ)ᵀ + k R_i kᵀ` (expanded to
//!    `P − k (Ph)ᵀ − (Ph) kᵀ + s_i k kᵀ`, `O(D²)`; second order in gain errors like the
//!    matrix form, and symmetric by construction: the upper triangle is mirrored).
//! 2. **Predict** through the interval with classical Runge–Kutta (RK4), `substeps` steps of
//!    `dt / substeps`, the road and the parameters held; the Jacobian `J = ∂x_k+1/∂s` is the
//!    exact derivative of that numerical map (the tangents ride along through every stage:
//!    forward-mode differentiation of the structure's terms). `P ← J P Jᵀ` on the state
//!    rows, `q` added on the parameters, and the road slot restarts at `(0, σ_u²)`.
//!
//! RK4 is the thesis' integrator: with the simulator's sub-step count the filter's model at
//! the true parameters *is* the simulated transition (to rounding). Against the exact
//! zero-order hold `e^{A dt}` its error per sample is `O((ρ dt / substeps)⁵)` relative
//! (`ρ` the fastest pole): for the thesis' quarter car at `dt = 0.05` s with the simulator's
//! automatic count (`h ρ ≤ 1/2`), `‖Φ_RK4 − e^{A dt}‖ / ‖e^{A dt}‖ ≈ 1e-4`. Euler would not
//! do: the quarter car's wheel mode is at `ρ dt ≈ 2`.
//!
//! # What the filter must be told
//! The noise model (`Σ_w`, `Σ_v`, `σ_u`, `g`: [`EkfNoise`]), `dt`, and a prior (a parameter
//! guess with its variance; the states start at 0 with a given variance). Like the thesis'
//! Kalman identifier (whose `R = R_v + B R_u Bᵀ`, Eq 4.7, uses the same `B`, `σ_u`, `σ_v`) it
//! does not learn them; a wrong `Σ_w` weights the two sensors wrongly (the estimate stays
//! consistent in the regression identifiers' sense only when the noise model is right).
//!
//! `B` known is the thesis' premise, and the filter leans on it: knowing `g`, the update
//! with `z_k` and the next `r_k+1` pin the road of each sample, which the regression
//! identifiers must treat as noise (variance 81 in the quarter car's wheel row). A `B` that
//! depends on an unknown parameter (the physical quarter car's `B = k1/m` with `k1`
//! estimated) cannot be left to the filter: the road state absorbs `k1 (u − z_w)/m` whole
//! and only `u`'s variance would tell `k1` apart, which an EKF does not use (tried during
//! development: ξ 0.01–3 at 40,000 samples). With the physical structure, then, `g` carries
//! `k1/m`, information the regression identifiers do not have.
//!
//! # Cost
//! `O(n D²)` for the update and the prediction and `O(terms · D)` per RK4 stage; no
//! allocation (everything is `SMatrix` on the stack). Measured (release, a shared 2-core
//! machine, `tests/joint_ekf.rs`'s `timing`): about 2.9 µs per sample for the quarter car
//! with 5 RK4 sub-steps, physical structure (`D = 9`) or full rows (`D = 13`) alike, most
//! of it in the sub-steps (0.9 µs with one); the thesis' Kalman rows identifier: 17 ns. Ljung (1979) shows that the plain EKF
//! ignores the dependence of its gain on `p` and can then converge to a biased estimate; with
//! a nearly measured state (the gain on `x` is set by `Σ_w`, not by `p`) the effect is small
//! here: see `tests/joint_ekf.rs` for the measured figures.

use super::checks::check_slices;
use super::{Dims, Identifier, OVERFLOW};
use crate::error::{check_finite, check_nonneg, check_positive};
use crate::structure::{Basis, Structure, Var, MAX_EQUATIONS};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

mod identifier;
mod noise;

pub use noise::EkfNoise;

/// Most RK4 sub-steps per sample the filter accepts.
pub const MAX_EKF_SUBSTEPS: u32 = 1000;

/// The RK4 sub-steps per sample of the filter's prediction when none is given: those the
/// simulator would choose ([`crate::model::auto_substeps`]: `h ρ(A) ≤ 1/2`, `dt` in s) for
/// the structure linearized at the parameters `params`, column `j` of `A` being
/// `f(e_j) − f(0)` with the inputs at 0 (exact for a linear structure; for `sign`, `pos`,
/// `neg` terms the slope on the positive side).
///
/// # Errors
/// [`Error::Shape`] for a structure without `N` states or `params` of another length than its
/// parameters; [`Error::Capacity`] over [`crate::structure::MAX_INPUTS`] inputs.
pub fn joint_ekf_substeps<T: Real, const N: usize>(structure: &Structure<T>, params: &[T], dt: T) -> Result<u32> {
    if structure.states() != N {
        return Err(Error::Shape { arg: "structure", expected: N, got: structure.states() });
    }
    if params.len() != structure.params() {
        return Err(Error::Shape { arg: "params", expected: structure.params(), got: params.len() });
    }
    let m = structure.inputs();
    if m > crate::structure::MAX_INPUTS {
        return Err(Error::Capacity { arg: "inputs", needed: m, capacity: crate::structure::MAX_INPUTS });
    }
    let u = [T::zero(); crate::structure::MAX_INPUTS];
    let (mut base, mut col, mut x) = ([T::zero(); N], [T::zero(); N], [T::zero(); N]);
    structure.derivative(params, &x, &u[..m], &mut base);
    let mut a = SMatrix::<T, N, N>::zeros();
    for j in 0..N {
        x[j] = T::one();
        structure.derivative(params, &x, &u[..m], &mut col);
        x[j] = T::zero();
        for i in 0..N {
            a[(i, j)] = col[i] - base[i];
        }
    }
    Ok(crate::model::auto_substeps_of(&a, dt) as u32)
}

/// The joint extended Kalman filter on `s = [x; p; u]` (module docs): `N` states, `D =
/// N + params + 1` (checked at construction: Rust cannot yet compute it from the others).
///
/// On the [`Identifier`] interface: `update_into(r_k, z_k, u_m, e)` takes one sample and
/// writes, for each identified equation, the innovation of its measured derivative
/// (`z_i − f_i` at the prior); `params_into` gives `p̂`; `covariance_into` the parameters'
/// block of `P`. Transactional: a rejected sample (NaN, overflow, a covariance that lost
/// definiteness) changes nothing.
///
/// # Examples
/// ```
/// use nalgebra::SVector;
/// use vehid_core::identify::{EkfNoise, Identifier, JointEkf};
/// use vehid_core::model::QuarterCar;
/// use vehid_core::sim::{SimConfig, Simulator};
///
/// let car = QuarterCar::<f64>::thesis();
/// // m known: parameters k2/M, b/M, M, k1 (D = 4 + 4 + 1).
/// let ps = QuarterCar::structure([None, Some(1.0), None, None, None])?;
/// let cfg = SimConfig::new(0.05).road_sigma(0.1).deriv_noise(0.1).state_noise(0.008);
/// let mut sim = Simulator::new(car.model(), cfg, 7)?;
/// let noise = EkfNoise::from_sigmas(0.008, 0.1, SVector::from([0.0, 90.0, 0.0, 0.0]), 0.1);
/// let guess = [2.5, 6.0, 5.0, 135.0];
/// let var = guess.map(|g| g * g);
/// let mut ekf = JointEkf::<f64, 4, 9>::new(*ps.structure(), &guess, &var, 1.0, noise, 0.05, sim.substeps() as u32)?;
/// let mut e = [0.0; 2];
/// for _ in 0..3000 {
///     let s = sim.next_sample();
///     ekf.update_into(s.r.as_slice(), s.z.as_slice(), &[], &mut e)?;
/// }
/// let mut p = [0.0; 4];
/// ekf.params_into(&mut p)?;
/// assert!((p[0] - 5.0).abs() < 0.5 && (p[3] - 90.0).abs() < 20.0, "{p:?}");
/// # Ok::<(), vehid_core::Error>(())
/// ```
///
/// Persistence (feature `serde`): the whole filter (structure, noise model, `ŝ`, `P`, counter)
/// round-trips; a loaded one is checked (its structure rebuilt, sizes, evaluation order,
/// equation rows, noise model, `dt`, `substeps`, finite `ŝ` and `P`), so corrupt input is an
/// error, and a restored filter continues bit for bit.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct JointEkf<T: Real, const N: usize, const D: usize> {
    structure: Structure<T>,
    /// Equations (identified and known) in dependency order.
    order: [u8; MAX_EQUATIONS],
    rows: [usize; MAX_EQUATIONS],
    noise: EkfNoise<T, N>,
    dt: T,
    substeps: u32,
    /// `ŝ = [x̂; p̂; û]`: the prior of the next sample (`û` = 0 between samples).
    s: SVector<T, D>,
    /// Its covariance (the road slot: `σ_u²`, uncorrelated, between samples).
    p: SMatrix<T, D, D>,
    samples: u64,
}

/// The error for a covariance that lost positive definiteness (a sample refused).
const INDEFINITE: Error = Error::Singular {
    what: "the joint EKF's covariance (it lost positive definiteness: reset_covariance, or check the noise model)",
};

impl<T: Real, const N: usize, const D: usize> JointEkf<T, N, D> {
    /// A filter for `structure` (`N` states, complete: every state has an equation, known
    /// ones such as `ż = v` included) with the parameters' prior mean `p0` (`params`
    /// values, parameter units) and variances `p0_var` (`params` values, parameter units²,
    /// independent), the states' prior
    /// `N(0, x0_var I)` (state units²), the noise model `noise`, the sample interval `dt` (s)
    /// and `substeps` RK4 steps per interval (1..=[`MAX_EKF_SUBSTEPS`]; the simulator's
    /// [`crate::model::auto_substeps`] is a good choice: `h ρ(A) ≤ 1/2`).
    ///
    /// The prior matters, as for any EKF (its linearization is local; Ljung 1979): a guess
    /// of each parameter's magnitude with a standard deviation of the same order is enough
    /// (the tests start at half or 1.5 times the truth with a standard deviation of 100 %).
    /// A diffuse prior (`θ = 0`, variance 10⁴, the thesis' Kalman start) lets the first
    /// samples move the parameters to an unstable model whose prediction overflows.
    ///
    /// # Errors
    /// [`Error::Shape`] naming `structure` (its states are not `N`), `D` (not
    /// `N + params + 1`), `p0` or `p0_var` (not `params` values); [`Error::InvalidArgument`] for an
    /// incomplete structure, a variance or `dt` out of range (naming it), `substeps` out of
    /// range; [`Error::NonFinite`] for a non-finite `p0`.
    pub fn new(
        structure: Structure<T>,
        p0: &[T],
        p0_var: &[T],
        x0_var: T,
        noise: EkfNoise<T, N>,
        dt: T,
        substeps: u32,
    ) -> Result<Self> {
        let np = structure.params();
        if structure.states() != N {
            return Err(Error::Shape { arg: "structure", expected: N, got: structure.states() });
        }
        if D != N + np + 1 {
            return Err(Error::Shape { arg: "D", expected: N + np + 1, got: D });
        }
        if p0.len() != np {
            return Err(Error::Shape { arg: "p0", expected: np, got: p0.len() });
        }
        if !structure.complete() {
            return Err(Error::InvalidArgument {
                arg: "structure",
                expected: "an equation for every state (add the known ones, e.g. q = v): the filter predicts them all",
            });
        }
        check_finite("p0", p0)?;
        if p0_var.len() != np {
            return Err(Error::Shape { arg: "p0_var", expected: np, got: p0_var.len() });
        }
        for &v in p0_var {
            check_positive("p0_var", v)?;
        }
        check_positive("x0_var", x0_var)?;
        check_positive("dt", dt)?;
        noise.check()?;
        if substeps == 0 || substeps > MAX_EKF_SUBSTEPS {
            return Err(Error::InvalidArgument {
                arg: "substeps",
                expected: "between 1 and 1000 RK4 steps per sample",
            });
        }
        let mut rows = [0usize; MAX_EQUATIONS];
        for (r, st) in rows.iter_mut().zip(structure.equation_states()) {
            *r = st;
        }
        let mut s = SVector::<T, D>::zeros();
        let mut p = SMatrix::<T, D, D>::zeros();
        for i in 0..N {
            p[(i, i)] = x0_var;
        }
        for j in 0..np {
            s[N + j] = p0[j];
            p[(N + j, N + j)] = p0_var[j];
        }
        p[(D - 1, D - 1)] = noise.road_var;
        Ok(Self { structure, order: evaluation_order(&structure)?, rows, noise, dt, substeps, s, p, samples: 0 })
    }

    /// Checks a deserialized filter (feature `serde`; its structure checked itself): the sizes
    /// (`N` states, `D = N + params + 1`), a complete structure, the evaluation order and the
    /// equations' rows as the constructor computes them, the noise model, `dt`, `substeps`,
    /// a finite `ŝ` and `P`, and the road slot as a step leaves it (`ŝ_u = 0`, `P_uu = σ_u²`,
    /// no covariance with the rest).
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let corrupt = Error::InvalidArgument { arg: "state", expected: "a joint EKF's saved state" };
        let (np, ne) = (self.structure.params(), self.structure.equations());
        if self.structure.states() != N || D != N + np + 1 || !self.structure.complete() {
            return Err(corrupt);
        }
        if self.order != evaluation_order(&self.structure)? {
            return Err(corrupt);
        }
        if self.structure.equation_states().enumerate().any(|(i, s)| self.rows[i] != s)
            || self.rows[ne..].iter().any(|&r| r != 0)
        {
            return Err(corrupt);
        }
        self.noise.check()?;
        check_positive("dt", self.dt)?;
        if self.substeps == 0 || self.substeps > MAX_EKF_SUBSTEPS {
            return Err(corrupt);
        }
        check_finite("state", self.s.as_slice())?;
        check_finite("state", self.p.as_slice())?;
        // The road slot as every step leaves it (and the constructor starts it): estimate 0,
        // variance σ_u², uncorrelated with the states and parameters.
        let road = D - 1;
        if self.s[road] != T::zero()
            || self.p[(road, road)] != self.noise.road_var
            || (0..road).any(|j| self.p[(road, j)] != T::zero() || self.p[(j, road)] != T::zero())
        {
            return Err(corrupt);
        }
        Ok(())
    }

    /// The structure identified.
    pub fn structure(&self) -> &Structure<T> {
        &self.structure
    }

    /// The noise model in use.
    pub fn noise(&self) -> &EkfNoise<T, N> {
        &self.noise
    }

    /// The sample interval, s.
    pub fn dt(&self) -> T {
        self.dt
    }

    /// RK4 sub-steps per sample.
    pub fn substeps(&self) -> u32 {
        self.substeps
    }

    /// The predicted state `x̂(k+1 | k)` after the last sample (state units).
    pub fn state(&self) -> SVector<T, N> {
        self.s.fixed_rows::<N>(0).into_owned()
    }

    /// The covariance of [`JointEkf::state`] (state units²).
    pub fn state_covariance(&self) -> SMatrix<T, N, N> {
        self.p.fixed_view::<N, N>(0, 0).into_owned()
    }

    /// `f(x, p, u_m) + g u` and its tangent `∂/∂s` (column `i`: the gradient of `ẋ_i`) for
    /// a state `x` whose tangent is `tx` (column `l`: `∂x_l/∂s`); `p` and `u` from `s`.
    /// Forward-mode differentiation of [`Structure::derivative`]: the equations in
    /// dependency order, `der(l)` reading the value and tangent just computed. `sign` has no
    /// tangent; `pos`/`neg` at their kink (the combination exactly 0) take the flat side.
    fn eval(&self, s: &SVector<T, D>, x: &SVector<T, N>, tx: &SMatrix<T, D, N>, um: &[T]) -> Eval<T, N, D> {
        let road = s[D - 1];
        let mut f = self.noise.road_gain * road;
        let mut df = SMatrix::<T, D, N>::zeros();
        for i in 0..N {
            df[(D - 1, i)] = self.noise.road_gain[i];
        }
        let n_eq = self.structure.equations() + self.structure.known_equations();
        for &i in &self.order[..n_eq] {
            let i = i as usize;
            let st = self.structure.equation_state(i);
            let mut v = f[st];
            let mut dv = df.column(st).into_owned();
            for t in self.structure.terms(i) {
                let (w, j) = match t.param {
                    Some(j) => (s[N + j as usize], Some(N + j as usize)),
                    None => (T::one(), None),
                };
                let cw = t.coef * w;
                let value = |var: Var| match var {
                    Var::State(l) => x[l as usize],
                    Var::Deriv(l) => f[l as usize],
                    Var::Input(l) => um.get(l as usize).copied().unwrap_or_else(T::zero),
                };
                // dv += c · ∂var/∂s.
                let tangent = |dv: &mut SVector<T, D>, var: Var, c: T| match var {
                    Var::State(l) => dv.axpy(c, &tx.column(l as usize), T::one()),
                    Var::Deriv(l) => dv.axpy(c, &df.column(l as usize), T::one()),
                    Var::Input(_) => {}
                };
                let comb = |start: u8, len: u8| {
                    self.structure.combination(start, len).iter().fold(T::zero(), |a, &(var, c)| a + c * value(var))
                };
                let phi = match t.basis {
                    Basis::One => T::one(),
                    Basis::Var(var) => {
                        tangent(&mut dv, var, cw);
                        value(var)
                    }
                    Basis::Sign { start, len } => {
                        let e = comb(start, len);
                        // sign is flat almost everywhere: no tangent.
                        if e > T::zero() {
                            T::one()
                        } else if e < T::zero() {
                            -T::one()
                        } else {
                            T::zero()
                        }
                    }
                    Basis::Pos { start, len } | Basis::Neg { start, len } => {
                        let e = comb(start, len);
                        let active = if matches!(t.basis, Basis::Pos { .. }) { e > T::zero() } else { e < T::zero() };
                        if active {
                            for &(var, c) in self.structure.combination(start, len) {
                                tangent(&mut dv, var, cw * c);
                            }
                            e
                        } else {
                            T::zero()
                        }
                    }
                };
                v += cw * phi;
                if let Some(j) = j {
                    dv[j] += t.coef * phi;
                }
            }
            f[st] = v;
            df.set_column(st, &dv);
        }
        Eval { f, df }
    }

    /// One interval: RK4 from the state of `s` with its parameters and road held, measured
    /// inputs `um`; the next state and its tangent `∂x_k+1/∂s` (`D × N`).
    fn predict(&self, s: &SVector<T, D>, um: &[T]) -> (SVector<T, N>, SMatrix<T, D, N>) {
        let mut x: SVector<T, N> = s.fixed_rows::<N>(0).into_owned();
        let mut tx = SMatrix::<T, D, N>::zeros();
        for i in 0..N {
            tx[(i, i)] = T::one();
        }
        let h = self.dt / T::of(f64::from(self.substeps));
        let (half, sixth, two) = (h / T::of(2.0), h / T::of(6.0), T::of(2.0));
        for _ in 0..self.substeps {
            let k1 = self.eval(s, &x, &tx, um);
            let k2 = self.eval(s, &(x + k1.f * half), &(tx + k1.df * half), um);
            let k3 = self.eval(s, &(x + k2.f * half), &(tx + k2.df * half), um);
            let k4 = self.eval(s, &(x + k3.f * h), &(tx + k3.df * h), um);
            x += (k1.f + (k2.f + k3.f) * two + k4.f) * sixth;
            tx += (k1.df + (k2.df + k3.df) * two + k4.df) * sixth;
        }
        (x, tx)
    }

    /// The whole step on copies; `Ok((s, P, e))` to commit.
    #[allow(clippy::type_complexity)]
    fn step(&self, r: &[T], z: &[T], um: &[T]) -> Result<(SVector<T, D>, SMatrix<T, D, D>, [T; MAX_EQUATIONS])> {
        let mut post = self.s;
        let mut p = self.p;
        // r_k: linear in s (h = e_i), exact.
        for i in 0..N {
            let ph = p.column(i).into_owned();
            let sv = ph[i] + self.noise.state_var[i];
            let innov = r[i] - post[i];
            joseph(&mut p, &mut post, &ph, sv, innov)?;
        }
        // z_k: linearized once at the estimate updated with r_k (a scalar at a time is then
        // the batch update of the block: the innovations subtract hᵀδ, δ the block's
        // correction so far).
        let x: SVector<T, N> = post.fixed_rows::<N>(0).into_owned();
        let mut eye = SMatrix::<T, D, N>::zeros();
        for i in 0..N {
            eye[(i, i)] = T::one();
        }
        let m = self.eval(&post, &x, &eye, um);
        let mut e = [T::zero(); MAX_EQUATIONS];
        for (k, &st) in self.rows[..self.structure.equations()].iter().enumerate() {
            e[k] = z[st] - m.f[st];
        }
        let base = post;
        for j in 0..N {
            let h = m.df.column(j);
            let ph = p * h;
            let sv = h.dot(&ph) + self.noise.deriv_var[j];
            let innov = z[j] - m.f[j] - h.dot(&(post - base));
            joseph(&mut p, &mut post, &ph, sv, innov)?;
        }
        if (0..D).any(|i| !(p[(i, i)] > T::zero())) {
            return Err(INDEFINITE);
        }
        // Predict: x rows through J = txᵀ; parameters held (plus the walk); the road restarts.
        let (xn, tx) = self.predict(&post, um);
        let jp = tx.transpose() * p; // N × D
        let pxx = jp * tx;
        let mut next = SMatrix::<T, D, D>::zeros();
        let np = D - N - 1;
        for a in 0..N {
            for b in 0..N {
                next[(a, b)] = (pxx[(a, b)] + pxx[(b, a)]) / T::of(2.0);
            }
            for b in N..N + np {
                next[(a, b)] = jp[(a, b)];
                next[(b, a)] = jp[(a, b)];
            }
        }
        for a in N..N + np {
            for b in N..N + np {
                next[(a, b)] = p[(a, b)];
            }
            next[(a, a)] += self.noise.param_walk_var;
        }
        next[(D - 1, D - 1)] = self.noise.road_var;
        let mut s = post;
        s.fixed_rows_mut::<N>(0).copy_from(&xn);
        s[D - 1] = T::zero();
        if !(s.iter().chain(next.iter()).all(|v| v.finite())) {
            return Err(OVERFLOW);
        }
        Ok((s, next, e))
    }
}

/// One scalar measurement with `P h = ph`, `s = hᵀ P h + R` and innovation `innov`:
/// `ŝ += k innov`, `P ← P − k (Ph)ᵀ − (Ph) kᵀ + s k kᵀ` (the Joseph form expanded; upper
/// triangle computed, mirrored), `k = Ph / s`.
#[inline]
fn joseph<T: Real, const D: usize>(
    p: &mut SMatrix<T, D, D>,
    s: &mut SVector<T, D>,
    ph: &SVector<T, D>,
    sv: T,
    innov: T,
) -> Result<()> {
    if !(sv > T::zero()) || !sv.finite() {
        return Err(INDEFINITE);
    }
    let k = ph / sv;
    s.axpy(innov, &k, T::one());
    for b in 0..D {
        for a in 0..=b {
            let v = p[(a, b)] - k[a] * ph[b] - ph[a] * k[b] + sv * k[a] * k[b];
            p[(a, b)] = v;
            p[(b, a)] = v;
        }
    }
    Ok(())
}

/// `f` and its tangent (columns: states).
struct Eval<T: Real, const N: usize, const D: usize> {
    f: SVector<T, N>,
    df: SMatrix<T, D, N>,
}

/// The structure's equations (identified and known) in an order in which every `der(l)` a
/// term reads comes after the equation of `l` (Kahn's algorithm; the structure has checked
/// that there is no loop).
fn evaluation_order<T: Real>(s: &Structure<T>) -> Result<[u8; MAX_EQUATIONS]> {
    let n_eq = s.equations() + s.known_equations();
    let reads = |i: usize| {
        let bit = |v: Var| if let Var::Deriv(l) = v { 1u32 << l } else { 0 };
        s.terms(i).iter().fold(0u32, |acc, t| {
            acc | match t.basis {
                Basis::One => 0,
                Basis::Var(v) => bit(v),
                Basis::Sign { start, len } | Basis::Pos { start, len } | Basis::Neg { start, len } => {
                    s.combination(start, len).iter().fold(0, |a, &(v, _)| a | bit(v))
                }
            }
        })
    };
    let mut order = [0u8; MAX_EQUATIONS];
    let mut placed = [false; MAX_EQUATIONS];
    let mut done = 0u32;
    for slot in order.iter_mut().take(n_eq) {
        let i = (0..n_eq).find(|&i| !placed[i] && reads(i) & !done == 0).ok_or(Error::InvalidArgument {
            arg: "structure",
            expected: "derivatives that do not read each other in a loop",
        })?;
        placed[i] = true;
        *slot = i as u8;
        done |= 1 << s.equation_state(i);
    }
    Ok(order)
}

#[cfg(test)]
mod tangent_tests;
