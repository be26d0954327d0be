//! The stochastic-gradient identifier (Eq 2.56, 5.2–5.18):
//! `θ̂(k+l) = [I + R(k) Σ_N] θ̂(k) + R(k) H_rᵀ z̃(k) − R(k) E[Hᵀ v]`, `z̃ = z − H_r θ̂`.
//!
//! With `H = I ⊗ xᵀ` each unknown row `i` updates on its own:
//! `θ_i ← θ_i + γ(k) h_i ∘ (Σ_w θ_i + x e_i)`, `e_i = z_i − xᵀ θ_i`, where `Σ_N = I ⊗ Σ_w`
//! (`Σ_w` the state-measurement noise covariance) removes the attenuation bias that state
//! noise causes, and `E[Hᵀ v] = 0` for white derivative noise. The identifier uses every
//! `l`-th sample (`spacing`), so that successive regressors are nearly independent.
//!
//! Gains ([`Gain`]), with `h` the per-parameter weights (the thesis makes the wheel-row weights
//! one tenth of the body-row weights, Eq 5.10):
//! - Venter (Eq 5.8): `γ(k) = k^(−p)`, `1/2 < p ≤ 1`;
//! - Lyapunov / normalized (Eq 5.9): `γ(k) = 1 / Σ_{i,j} h_ij r_j(k)²` (depends on the data,
//!   hence biased);
//! - Ljung with forgetting (Eq 5.15–5.18): `λ(k) = λ₀ λ(k−1) + (1 − λ₀)`,
//!   `γ(k) = γ(k−1) / (γ(k−1) + λ(k))`, `γ(0) = 1`.
//!
//! Size: `size_of::<StochasticGradient<f32, 4, 2>>()` is 192 bytes (θ, `h`, `Σ_w` and the
//! gain state).

use super::{
    check_lengths, check_sample, fixed_theta, rows_buffer, rows_into, vector, Cost, Dims, Fixed, Flat, Identifier,
    Store, OVERFLOW,
};
use crate::error::{check_finite, check_nonneg, check_positive};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

/// The gain sequence `γ(k)` of the stochastic-gradient identifier.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Gain<T> {
    /// Venter's gain (Eq 5.8): `γ(k) = k^(−p)`, `1/2 < p ≤ 1` (thesis: 0.51, 0.95).
    Venter {
        /// The exponent `p`.
        p: T,
    },
    /// The normalized (Lyapunov) gain of Eq 5.9: `γ(k) = 1 / Σ h_ij r_j(k)²`.
    Lyapunov,
    /// Ljung's gain sequence with forgetting (Eq 5.15–5.18).
    Ljung {
        /// Forgetting-factor growth `λ₀` (thesis 0.99), in (0, 1].
        lambda0: T,
        /// Initial forgetting factor `λ(0)` (thesis 0.95), > 0.
        lambda_init: T,
    },
}

/// The name of a gain sequence, without its constants.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum GainKind {
    /// Venter's gain (Eq 5.8).
    #[default]
    Venter,
    /// The normalized (Lyapunov) gain (Eq 5.9).
    Lyapunov,
    /// Ljung's gain sequence with forgetting (Eq 5.15–5.18).
    Ljung,
}

option_names!(GainKind, "gain", { Venter => "venter", Lyapunov => "lyapunov", Ljung => "ljung" });

impl<T: Real> Gain<T> {
    /// The gain of the given kind with its constants (each kind uses the ones it needs):
    /// Venter's exponent `p`, Ljung's `lambda0` and `lambda_init`.
    pub fn of_kind(kind: GainKind, p: T, lambda0: T, lambda_init: T) -> Self {
        match kind {
            GainKind::Venter => Gain::Venter { p },
            GainKind::Lyapunov => Gain::Lyapunov,
            GainKind::Ljung => Gain::Ljung { lambda0, lambda_init },
        }
    }

    /// The kind of this gain.
    pub fn kind(&self) -> GainKind {
        match self {
            Gain::Venter { .. } => GainKind::Venter,
            Gain::Lyapunov => GainKind::Lyapunov,
            Gain::Ljung { .. } => GainKind::Ljung,
        }
    }

    /// The gain `γ(k)` of gradient step `step` and the forgetting factor after it, from the
    /// previous `gamma` and `lambda`: Venter `k^(−p)` (Eq 5.8), Ljung's `λ(k) = λ₀ λ(k−1) +
    /// (1 − λ₀)`, `γ(k) = γ(k−1) / (γ(k−1) + λ(k))` (Eq 5.15–5.18), or the normalized
    /// `1 / norm()` (Eq 5.9; `norm` is evaluated for that gain only). `None` when the
    /// normalized gain has no direction to move in (`norm() ≤ 0`: zero regressors).
    #[inline(always)]
    pub(crate) fn next(&self, step: u64, gamma: T, lambda: T, norm: impl FnOnce() -> T) -> Option<(T, T)> {
        match *self {
            Gain::Venter { p } => Some((T::of(libm::pow(step as f64, -p.to_f64())), lambda)),
            Gain::Ljung { lambda0, .. } => {
                let lambda = lambda0 * lambda + (T::one() - lambda0);
                Some((gamma / (gamma + lambda), lambda))
            }
            Gain::Lyapunov => {
                let den = norm();
                (den > T::zero()).then(|| (T::one() / den, lambda))
            }
        }
    }

    pub(crate) fn validate(&self) -> Result<()> {
        match *self {
            Gain::Venter { p } => {
                if !(p.finite() && p > T::of(0.5) && p <= T::one()) {
                    return Err(Error::InvalidArgument { arg: "p", expected: "a value in (1/2, 1] (Eq 5.8)" });
                }
            }
            Gain::Lyapunov => {}
            Gain::Ljung { lambda0, lambda_init } => {
                if !(lambda0.finite() && lambda0 > T::zero() && lambda0 <= T::one()) {
                    return Err(Error::InvalidArgument { arg: "lambda0", expected: "a value in (0, 1]" });
                }
                check_positive("lambda_init", lambda_init)?;
            }
        }
        Ok(())
    }
}

/// The stochastic-gradient identifier over a [`Store`]; see [`StochasticGradient`].
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct GradientCore<T: Real, const N: usize, S: Store<T, N>> {
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    rows: S::Rows,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    theta: S::Vecs,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    h: S::Vecs,
    sigma_w: SMatrix<T, N, N>,
    gain: Gain<T>,
    spacing: u32,
    phase: u32,
    k: u64,
    gamma: T,
    lambda: T,
    samples: u64,
}

/// The stochastic-gradient identifier for `K` unknown rows of an `N`-state model, no
/// allocation.
pub type StochasticGradient<T, const N: usize, const K: usize> = GradientCore<T, N, Fixed<K>>;

/// [`GradientCore`] with heap storage.
#[cfg(feature = "alloc")]
pub type StochasticGradientVec<T, const N: usize> = GradientCore<T, N, super::Dynamic>;

impl<T: Real, const N: usize, S: Store<T, N>> GradientCore<T, N, S> {
    /// Builds the identifier. `h` holds one value (all parameters), one per row, or one per
    /// parameter (`K·N`, row-major). `state_noise_var` is the diagonal of `Σ_w` (one value or
    /// one per state; 0 disables the bias elimination). `spacing` is `l ≥ 1`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `p ∉ (1/2, 1]`, `h ≤ 0`, negative variances,
    /// `spacing == 0`, bad Ljung constants; [`Error::Shape`] for wrong lengths;
    /// [`Error::BadRow`] for bad rows.
    pub fn from_slices(rows: &[usize], gain: Gain<T>, h: &[T], state_noise_var: &[T], spacing: u32) -> Result<Self> {
        gain.validate()?;
        if spacing == 0 {
            return Err(Error::InvalidArgument { arg: "spacing", expected: "at least 1 sample" });
        }
        let rows_buf: S::Rows = rows_buffer::<_, N>(rows)?;
        let k = rows.len();
        check_finite("h", h)?;
        let mut hb = S::Vecs::filled("unknown_rows", k, SVector::zeros())?;
        for (i, hi) in hb.flat_mut().iter_mut().enumerate() {
            for j in 0..N {
                let v = match h.len() {
                    1 => h[0],
                    l if l == k * N => h[i * N + j],
                    l if l == k => h[i],
                    l => return Err(Error::Shape { arg: "h", expected: k * N, got: l }),
                };
                check_positive("h", v)?;
                hi[j] = v;
            }
        }
        let sw = crate::model::broadcast::<T, N>("state_noise_var", state_noise_var)?;
        for v in sw.iter() {
            check_nonneg("state_noise_var", *v)?;
        }
        let (gamma, lambda) = match gain {
            Gain::Ljung { lambda_init, .. } => (T::one(), lambda_init),
            _ => (T::one(), T::one()),
        };
        Ok(Self {
            rows: rows_buf,
            theta: S::Vecs::filled("unknown_rows", k, SVector::zeros())?,
            h: hb,
            sigma_w: SMatrix::from_diagonal(&SVector::from(sw)),
            gain,
            spacing,
            phase: 0,
            k: 0,
            gamma,
            lambda,
            samples: 0,
        })
    }

    /// The unknown rows (0-based).
    pub fn rows(&self) -> &[usize] {
        self.rows.flat()
    }

    /// Estimate of unknown row `i`.
    pub fn theta_row(&self, i: usize) -> &SVector<T, N> {
        &self.theta.flat()[i]
    }

    /// Writes θ̂ row-major (`K × N`) into `out`.
    ///
    /// # Errors
    /// [`Error::Shape`] for a wrong length.
    pub fn theta_into(&self, out: &mut [T]) -> Result<()> {
        rows_into(self.theta.flat(), out)
    }

    /// Samples seen (including the ones skipped by the spacing).
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Gradient steps taken (`k` of Eq 5.8).
    pub fn steps(&self) -> u64 {
        self.k
    }

    /// Arithmetic per gradient step and size: per row `e_i` (N mul, N add), `Σ_w θ_i`
    /// (N² mul, N(N−1) add), the sum with `x e_i` (N mul, N add), `θ_i += γ h_i ∘ (...)`
    /// (2N mul, N add); plus the gain (`k^(−p)`: one power, counted as a division here).
    pub fn cost(&self) -> Cost {
        let k = self.rows.flat().len();
        Cost {
            multiplications: k * (N * N + 4 * N),
            additions: k * (N * N + 2 * N),
            divisions: 1,
            square_roots: 0,
            bytes: core::mem::size_of_val(self) + self.theta.heap_bytes() + self.h.heap_bytes(),
        }
    }

    /// The last gain value `γ(k)`.
    pub fn gamma(&self) -> T {
        self.gamma
    }

    /// One sample; innovations `e_i = z_row − xᵀ θ̂_i` into `e`. Samples between the
    /// `spacing` are counted but do not move θ̂. No allocation.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf, [`Error::Shape`] for a wrong `e` length, an overflow
    /// error when the step would not be finite. The identifier is unchanged after an error.
    ///
    /// Never inlined: the compiler inlined it into a caller's loop or not depending on how it
    /// partitioned the caller into codegen units, and inlined it took 38 more instructions
    /// per update (253 → 291, the estimates and the loop's state competing for registers).
    #[inline(never)]
    pub(crate) fn update_vec(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        check_sample(x, z)?;
        let rows = self.rows.flat();
        let k = rows.len();
        if e.len() != k {
            return Err(Error::Shape { arg: "e", expected: k, got: e.len() });
        }
        let theta = self.theta.flat_mut();
        for i in 0..k {
            e[i] = z[rows[i]] - theta[i].dot(x);
            if !e[i].finite() {
                return Err(OVERFLOW);
            }
        }
        let active = self.phase == 0;
        let next_phase = if self.phase + 1 >= self.spacing { 0 } else { self.phase + 1 };
        if !active {
            self.phase = next_phase;
            self.samples += 1;
            return Ok(());
        }
        let step = self.k + 1;
        let norm = || {
            let x2 = x.component_mul(x);
            self.h.flat().iter().fold(T::zero(), |a, h| a + h.dot(&x2))
        };
        let Some((gamma, lambda)) = self.gain.next(step, self.gamma, self.lambda, norm) else {
            // The normalized gain with x = 0: no direction to move in.
            self.phase = next_phase;
            self.samples += 1;
            return Ok(());
        };
        let h = self.h.flat();
        let mut new = [SVector::<T, N>::zeros(); N];
        for i in 0..k {
            let grad = self.sigma_w * theta[i] + x * e[i];
            new[i] = theta[i] + h[i].component_mul(&grad) * gamma;
            if !new[i].iter().all(|v| v.finite()) {
                return Err(OVERFLOW);
            }
        }
        theta.copy_from_slice(&new[..k]);
        self.gamma = gamma;
        self.lambda = lambda;
        self.k = step;
        self.phase = next_phase;
        self.samples += 1;
        Ok(())
    }
}

#[cfg(feature = "serde")]
impl<T: Real, const N: usize, S: Store<T, N>> GradientCore<T, N, S> {
    /// Checks a deserialized identifier: valid rows, gain and spacing, one `θ_i` and `h_i`
    /// per row.
    pub(crate) fn restored(&mut self) -> Result<()> {
        self.gain.validate()?;
        if self.spacing == 0 {
            return Err(Error::InvalidArgument { arg: "spacing", expected: "at least 1 sample" });
        }
        let k = crate::model::RowSet::<N>::new(self.rows.flat())?.len();
        for (arg, len) in [("theta", self.theta.flat().len()), ("h", self.h.flat().len())] {
            if len != k {
                return Err(Error::Shape { arg, expected: k, got: len });
            }
        }
        Ok(())
    }
}

impl<T: Real, const N: usize, const K: usize> GradientCore<T, N, Fixed<K>> {
    /// The identifier with one weight `h` for every parameter, no bias elimination,
    /// spacing 1.
    ///
    /// # Errors
    /// As [`GradientCore::from_slices`].
    pub fn new(rows: [usize; K], gain: Gain<T>, h: T) -> Result<Self> {
        Self::from_slices(&rows, gain, &[h], &[T::zero()], 1)
    }
}

impl<T: Real, const N: usize, const K: usize> GradientCore<T, N, Fixed<K>> {
    /// One sample; returns the innovations `e_i = z_row − xᵀ θ̂_i` of the unknown rows. No
    /// allocation.
    ///
    /// # Errors
    /// As [`Identifier::update_into`]; the identifier is unchanged after an error.
    #[inline]
    pub fn update(&mut self, x: &SVector<T, N>, z: &SVector<T, N>) -> Result<SVector<T, K>> {
        let mut e = SVector::<T, K>::zeros();
        self.update_vec(x, z, e.as_mut_slice())?;
        Ok(e)
    }

    /// The estimate θ̂ of the unknown rows (`K × N`).
    pub fn theta(&self) -> SMatrix<T, K, N> {
        fixed_theta(self)
    }
}

super::persist_by_serde!([T: Real, const N: usize, S: Store<T, N>] GradientCore<T, N, S>);

impl<T: Real, const N: usize, S: Store<T, N>> Identifier<T> for GradientCore<T, N, S> {
    fn dims(&self) -> Dims {
        let k = self.rows.flat().len();
        Dims { states: N, inputs: 0, equations: k, params: k * N }
    }

    fn rows(&self) -> &[usize] {
        self.rows.flat()
    }

    #[inline]
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        check_lengths(self.dims(), x, z, u, e)?;
        self.update_vec(&vector(x), &vector(z), e)
    }

    fn params_into(&self, out: &mut [T]) -> Result<()> {
        self.theta_into(out)
    }

    fn samples(&self) -> u64 {
        self.samples
    }
}
