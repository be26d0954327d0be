//! One decoupled scalar-output filter (Eq 6.16–6.18).

use super::CovarianceForm;
use crate::error::{check_finite, check_nonneg, check_positive};
use crate::identify::OVERFLOW;
use crate::linalg::{axpy, cholesky_in_place, mat_vec, sym_downdate, symmetrize};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};
/// One decoupled scalar-output filter for one row of `A` (Eq 6.16–6.18):
/// `g = P x / (xᵀ P x + r)`, `θ ← θ + g (z − xᵀ θ)`, `P ← (I − g xᵀ) P`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowIdentifier<T: Real, const N: usize> {
    theta: SVector<T, N>,
    p: SMatrix<T, N, N>,
    r: T,
    retired: bool,
}

impl<T: Real, const N: usize> RowIdentifier<T, N> {
    /// A row filter with `θ̂(0) = 0`, `P(0) = p0 I` and measurement variance `r`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `p0` not finite and > 0 or `r` not finite and ≥ 0.
    pub fn new(p0: T, r: T) -> Result<Self> {
        check_positive("p0", p0)?;
        check_nonneg("r", r)?;
        Ok(Self { theta: SVector::zeros(), p: SMatrix::identity() * p0, r, retired: false })
    }

    /// A row filter with a prior mean `theta0` and a full prior covariance `p0`.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf; [`Error::Singular`] when `p0` is not symmetric
    /// positive definite; [`Error::InvalidArgument`] for a bad `r`.
    pub fn with_prior(theta0: SVector<T, N>, p0: SMatrix<T, N, N>, r: T) -> Result<Self> {
        check_finite("theta0", theta0.as_slice())?;
        check_finite("p0", p0.as_slice())?;
        check_nonneg("r", r)?;
        if (p0 - p0.transpose()).abs().max() > T::default_epsilon() * T::of(16.0) * p0.abs().max() {
            return Err(Error::Singular { what: "p0 (it must be symmetric positive definite)" });
        }
        let mut l = p0;
        if !cholesky_in_place(l.as_mut_slice(), N) {
            return Err(Error::Singular { what: "p0 (it must be symmetric positive definite)" });
        }
        let mut p = p0;
        symmetrize(&mut p);
        Ok(Self { theta: theta0, p, r, retired: false })
    }

    /// A filter from its state (no checks: the parts come from a valid filter).
    pub(crate) fn from_parts(theta: SVector<T, N>, p: SMatrix<T, N, N>, r: T, retired: bool) -> Self {
        Self { theta, p, r, retired }
    }

    /// Current estimate `θ̂_i` of the row.
    pub fn theta(&self) -> &SVector<T, N> {
        &self.theta
    }

    /// Current covariance `P_i`.
    pub fn p(&self) -> &SMatrix<T, N, N> {
        &self.p
    }

    /// Measurement variance `r_i` in use (doubled by each reinitialization).
    pub fn r(&self) -> T {
        self.r
    }

    /// `true` once the row has retired (stopped updating).
    pub fn retired(&self) -> bool {
        self.retired
    }

    /// One update with the derivative measurement `z` of this row (Eq 6.16–6.18); returns
    /// the innovation `z − xᵀ θ̂(k−1)`.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf input, [`Error::Singular`] when `xᵀ P x + r ≤ 0`
    /// (the covariance lost positive definiteness), an overflow error for values so large the
    /// update would not be finite. The filter is unchanged after an error.
    pub fn update(&mut self, x: &SVector<T, N>, z: T, form: CovarianceForm) -> Result<T> {
        if let Some(index) = x.iter().position(|v| !v.finite()) {
            return Err(Error::NonFinite { arg: "r_k", index });
        }
        if !z.finite() {
            return Err(Error::NonFinite { arg: "z_k", index: 0 });
        }
        let e = z - self.theta.dot(x);
        let mut px = SVector::zeros();
        let (c, d) = self.plan(x, e, &mut px)?;
        self.apply(x, &px, c, d, form);
        Ok(e)
    }

    /// Computes `P x` into `px` and returns `(c, d) = (e/s, 1/√s)` with `s = xᵀPx + r`, or
    /// `d = 0` when this row takes no step. Changes nothing.
    #[inline(always)]
    fn plan(&self, x: &SVector<T, N>, e: T, px: &mut SVector<T, N>) -> Result<(T, T)> {
        if self.retired {
            return Ok((T::zero(), T::zero()));
        }
        mat_vec(&self.p, x, px);
        let s = x.dot(px) + self.r;
        if !s.finite() {
            return Err(OVERFLOW);
        }
        if self.r == T::zero() {
            // Noise-free data and a covariance collapsed along x (xᵀPx at rounding level):
            // nothing is left to learn in that direction.
            let floor = T::default_epsilon() * T::of(4.0 * N as f64) * x.abs().sum() * px.abs().sum();
            if s <= floor {
                return Ok((T::zero(), T::zero()));
            }
        }
        if !(s > T::zero()) {
            return Err(Error::Singular {
                what: "the innovation variance xᵀPx + r (P lost positive definiteness: use the \
                       Joseph form, f64, or reinitialization)",
            });
        }
        let inv_s = T::one() / s;
        let c = e * inv_s;
        // The θ step is P x e / s; the covariance step u uᵀ (u = P x / √s) is bounded by the
        // largest eigenvalue of P, so it cannot overflow for a finite P.
        if !(px.abs().sum() * c.abs()).finite() {
            return Err(OVERFLOW);
        }
        Ok((c, inv_s.sqrt()))
    }

    /// Applies a planned update: `θ += P x c`, `P −= u uᵀ` with `u = P x d`.
    #[inline(always)]
    fn apply(&mut self, x: &SVector<T, N>, px: &SVector<T, N>, c: T, d: T, form: CovarianceForm) {
        if d == T::zero() {
            return;
        }
        axpy(&mut self.theta, c, px);
        match form {
            CovarianceForm::Standard => sym_downdate(&mut self.p, &(px * d)),
            CovarianceForm::Joseph => {
                let g = px * (d * d);
                let a = SMatrix::<T, N, N>::identity() - g * x.transpose();
                self.p = a * self.p * a.transpose() + g * g.transpose() * self.r;
                symmetrize(&mut self.p);
            }
        }
    }
}
