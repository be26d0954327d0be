//! One recursive least-squares filter for one scalar equation `z = xᵀθ + ε`, `ε ~ (0, r)`:
//! the decoupled row of Eq 6.16–6.18, and the engine of every identifier with a full
//! covariance per equation.
//!
//! The filter keeps the estimate `θ̂` and its covariance in one of three forms
//! ([`CovarianceForm`]): the covariance `P` itself (the thesis' form, updated as
//! `P − P x xᵀ P / s`, or in Joseph's form), or its `U D Uᵀ` factors (Bierman's square-root
//! form: `U` unit upper triangular, `D` diagonal, updated without ever forming `P`, so `P`
//! stays positive definite in any precision). Before filtering it can absorb samples exactly
//! ([`RowIdentifier::exact`]): the regressors are triangularized by Givens rotations (a QR
//! factorization `R` of the stacked `xᵀ`, the right-hand side `Qᵀz` alongside) until `R` is
//! well conditioned; then `θ̂ = R⁻¹ Qᵀz` and `P = r (RᵀR)⁻¹`, and every estimate from then on
//! is least squares on all samples so far, with no prior at all.
//!
//! Tracking ([`KalmanOptions::forgetting`], [`KalmanOptions::drift`]): exponential forgetting
//! `P ← P / λ` after each update, or directional forgetting
//! ([`KalmanOptions::directional`], Kulhavý & Kárný 1984), which inflates the covariance only
//! along the direction the sample informed, `P⁺ + ((1 − λ)/λ) P⁺x xᵀP⁺ / xᵀP⁺x`, so old
//! information is discounted where new information replaces it and kept where none arrives;
//! and random-walk drift `P ← P + q I`. All act only while `tr P` is below a bound (by
//! default the trace when filtering starts: wind-up protection). Without excitation
//! (`x = 0`, so `P x = 0`) the estimate cannot move; exponential forgetting then lets `tr P`
//! grow back to the bound (the uncertainty the filter started with) and no further, while
//! directional forgetting keeps the covariance exactly as it was.
//!
//! Statistics: the filter accumulates the squared recursive residuals
//! `w² = e² r / s` (`e` the innovation, `s = xᵀPx + r` its variance): with an exact start their
//! sum is the residual sum of squares of least squares on all samples (Brown, Durbin & Evans
//! 1975), with a prior it is the minimum of the prior-regularized objective.

use super::guards::check_reset;
use super::ud::{ud_factor, ud_product, ud_trace};
use super::{CovarianceForm, KalmanOptions};
use crate::error::{check_finite, check_nonneg, check_positive};
use crate::linalg::{cholesky_in_place, symmetrize};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

pub(super) mod exact;
mod step;

use exact::start_tol;

/// One decoupled scalar-output filter for one row of `A` (Eq 6.16–6.18):
/// `g = P x / (xᵀ P x + r)`, `θ ← θ + g (z − xᵀ θ)`, `P ← (I − g xᵀ) P`.
///
/// The matrix `m` holds, by phase and form: the covariance `P` (standard and Joseph forms),
/// `U` above the diagonal and `D` on it (square-root form), or the triangular factor `R`
/// with `θ` holding `Qᵀz` (exact start, before the data identify every direction).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(deserialize = "T: crate::Real"))
)]
pub struct RowIdentifier<T: Real, const N: usize> {
    pub(super) theta: SVector<T, N>,
    pub(super) m: SMatrix<T, N, N>,
    pub(super) r: T,
    pub(super) form: CovarianceForm,
    /// Absorbing samples exactly (exact start) until identified.
    pub(super) start: bool,
    pub(super) retired: bool,
    /// Forgetting factor λ (directional or exponential), drift q, and the trace bound below
    /// which they act.
    pub(super) lambda: T,
    pub(super) directional: bool,
    pub(super) drift: T,
    pub(super) cap: T,
    /// Outlier gate κ and Huber constant c (0: off), and the samples gated so far.
    pub(super) gate: T,
    pub(super) huber: T,
    pub(super) gated: u64,
    /// Σ w² (decayed by λ), the effective number of samples, and the last `s`.
    pub(super) ssr: T,
    pub(super) nobs: T,
    pub(super) s: T,
    /// Parameters in use: the leading `dim ≤ N` (a structure's smaller groups share one `N`);
    /// the rest of `θ` and of the matrix stays 0.
    pub(super) dim: u8,
}

impl<T: Real, const N: usize> RowIdentifier<T, N> {
    fn raw(theta: SVector<T, N>, m: SMatrix<T, N, N>, r: T, start: bool) -> Self {
        Self {
            theta,
            m,
            r,
            form: CovarianceForm::Standard,
            start,
            retired: false,
            lambda: T::one(),
            directional: false,
            drift: T::zero(),
            cap: T::zero(),
            gate: T::zero(),
            huber: T::zero(),
            gated: 0,
            ssr: T::zero(),
            nobs: T::zero(),
            s: T::zero(),
            dim: N as u8,
        }
    }

    /// Parameters in use (`N` unless [`RowIdentifier::restricted`]).
    #[inline(always)]
    pub fn dim(&self) -> usize {
        self.dim as usize
    }

    /// The same filter on the leading `d` parameters only (`1 ≤ d ≤ N`): the others are
    /// fixed at 0 with no uncertainty, and regressors must be 0 there. Lets one `N` serve
    /// several smaller problems (the groups of a [`crate::structure::Structure`]).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `d` out of range.
    pub fn restricted(mut self, d: usize) -> Result<Self> {
        if d == 0 || d > N {
            return Err(Error::InvalidArgument { arg: "dim", expected: "between 1 and the filter's N parameters" });
        }
        for a in 0..N {
            for b in 0..N {
                if a >= d || b >= d {
                    self.m[(a, b)] = T::zero();
                }
            }
            if a >= d {
                self.theta[a] = T::zero();
            }
        }
        self.dim = d as u8;
        if self.cap != T::zero() && !self.start && self.tracking() {
            self.cap = self.trace();
        }
        Ok(self)
    }

    /// A row filter with `θ̂(0) = 0`, `P(0) = p0 I` and measurement variance `r`.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `p0` not finite and > 0 or `r` not finite and ≥ 0.
    pub fn new(p0: T, r: T) -> Result<Self> {
        check_positive("p0", p0)?;
        check_nonneg("r", r)?;
        Ok(Self::raw(SVector::zeros(), SMatrix::identity() * p0, r, false))
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
        Ok(Self::raw(theta0, p, r, false))
    }

    /// A row filter with no prior: samples are absorbed exactly until they identify every
    /// parameter, and from then on the estimate is least squares on all samples so far
    /// (the exact initialization of recursive least squares). `r > 0` is the measurement
    /// variance the covariance is expressed in (`P = r (XᵀX)⁻¹`); it does not change the
    /// estimate.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `r` not finite and > 0.
    pub fn exact(r: T) -> Result<Self> {
        check_positive("r", r)?;
        Ok(Self::raw(SVector::zeros(), SMatrix::zeros(), r, true))
    }

    /// The same filter with the covariance kept in `form` (converted now: `U D Uᵀ` factors for
    /// [`CovarianceForm::Sqrt`]) and the tracking options of `opts` (forgetting, drift, the
    /// trace bound).
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for tracking options out of their domain (see
    /// [`KalmanOptions`]); [`Error::Singular`] when the covariance cannot be factored.
    pub fn configured(mut self, form: CovarianceForm, opts: &KalmanOptions<T>) -> Result<Self> {
        opts.validate()?;
        if !self.start && form != self.form {
            let p = self.p();
            self.m = match form {
                CovarianceForm::Sqrt => ud_factor(&p, self.dim())?,
                _ => p,
            };
        }
        self.form = form;
        self.lambda = opts.forgetting;
        self.directional = opts.directional;
        self.drift = opts.drift;
        self.gate = opts.gate;
        self.huber = opts.huber;
        self.cap = opts.max_trace;
        if self.cap == T::zero() && !self.start && self.tracking() {
            self.cap = self.trace();
        }
        Ok(self)
    }

    fn tracking(&self) -> bool {
        self.lambda < T::one() || self.drift > T::zero()
    }

    /// `true` while the filter is still absorbing its exact start (before the data identify
    /// every parameter).
    pub fn starting(&self) -> bool {
        self.start
    }

    /// During an exact start, the number of directions the samples so far identify (the
    /// numerical rank of their regressors); [`RowIdentifier::dim`] otherwise.
    pub fn start_rank(&self) -> usize {
        let d = self.dim();
        if !self.start {
            return d;
        }
        let big = (0..d).fold(T::zero(), |a, j| a.max(self.m[(j, j)].abs()));
        let tol = start_tol::<T>(d) * big;
        (0..d).filter(|&j| big > T::zero() && self.m[(j, j)].abs() > tol).count()
    }

    /// During an exact start, whether parameter `j` is not yet identified: its column of the
    /// triangular factor adds nothing beyond the earlier columns (it is a combination of them
    /// in the data so far). `false` once filtering.
    pub fn unidentified(&self, j: usize) -> bool {
        let d = self.dim();
        if !self.start || j >= d {
            return false;
        }
        let big = (0..d).fold(T::zero(), |a, i| a.max(self.m[(i, i)].abs()));
        !(big > T::zero() && self.m[(j, j)].abs() > start_tol::<T>(d) * big)
    }

    /// Current estimate `θ̂` of the row. During an exact start, before every parameter is
    /// identified, there is none: NaN.
    pub fn theta(&self) -> SVector<T, N> {
        if self.start {
            return SVector::repeat(T::of(f64::NAN));
        }
        self.theta
    }

    /// Current covariance `P` (formed from the factors in the square-root form). During an
    /// exact start: infinite on the diagonal (no information yet in some direction).
    pub fn p(&self) -> SMatrix<T, N, N> {
        if self.start {
            return SMatrix::from_diagonal_element(T::of(f64::INFINITY));
        }
        match self.form {
            CovarianceForm::Sqrt => ud_product(&self.m),
            _ => self.m,
        }
    }

    /// `tr P` (infinite during an exact start).
    pub fn trace(&self) -> T {
        if self.start {
            return T::of(f64::INFINITY);
        }
        match self.form {
            CovarianceForm::Sqrt => ud_trace(&self.m),
            _ => self.m.trace(),
        }
    }

    /// The forgetting factor λ (1: none).
    pub fn forgetting(&self) -> T {
        self.lambda
    }

    /// Measurement variance `r` in use (doubled by each reinitialization).
    pub fn r(&self) -> T {
        self.r
    }

    /// The covariance form.
    pub fn form(&self) -> CovarianceForm {
        self.form
    }

    /// `true` once the row has retired (stopped updating).
    pub fn retired(&self) -> bool {
        self.retired
    }

    /// Sum of the squared recursive residuals `Σ e² r / s` (decayed by λ with forgetting): the
    /// residual sum of squares of least squares on all samples after an exact start.
    pub fn ssr(&self) -> T {
        self.ssr
    }

    /// Samples that entered the statistics (effective: decayed by λ with forgetting).
    pub fn nobs(&self) -> T {
        self.nobs
    }

    /// The innovation variance `s = xᵀPx + r` of the last update (0 before any, or during
    /// the exact start).
    pub fn innovation_var(&self) -> T {
        self.s
    }

    /// Samples this row gated as outliers ([`KalmanOptions::gate`]): not used, not counted in
    /// the statistics.
    pub fn gated(&self) -> u64 {
        self.gated
    }

    /// Stops updating (until the next [`RowIdentifier::reinitialize`]).
    pub fn retire(&mut self) {
        self.retired = true;
    }

    /// Covariance resetting ([`crate::identify::Identifier::reset_covariance`]): `P ← p0 I`
    /// on the parameters in use (in the square-root form `U = I`, `D = p0 I`: the same
    /// stored matrix), `θ̂` kept, and the row updates again if it was retired.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for `p0` not finite and > 0; [`Error::Unsupported`] during
    /// the exact start. Unchanged after an error.
    pub fn reset_covariance(&mut self, p0: T) -> Result<()> {
        check_reset(p0, self.start)?;
        let mut m = SMatrix::<T, N, N>::zeros();
        for a in 0..self.dim() {
            m[(a, a)] = p0;
        }
        self.m = m;
        self.retired = false;
        Ok(())
    }

    /// Eq 4.36: `P_aa ← 10 P_aa`, `r ← 2 r`, and the row updates again.
    pub fn reinitialize(&mut self) {
        if self.start {
            return;
        }
        let mut p = self.p();
        for a in 0..N {
            p[(a, a)] *= T::of(10.0);
        }
        self.m = match self.form {
            // P + 9 diag(P) is positive definite when P is: the factorization succeeds.
            CovarianceForm::Sqrt => ud_factor(&p, self.dim()).unwrap_or(self.m),
            _ => p,
        };
        self.r *= T::of(2.0);
        self.retired = false;
    }

    /// One update with the measurement `z` of this row (Eq 6.16–6.18); returns the
    /// innovation `z − xᵀ θ̂(k−1)` (NaN during an exact start, when there is no estimate).
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf input, [`Error::Singular`] when `xᵀ P x + r ≤ 0`
    /// (the covariance lost positive definiteness), an overflow error for values so large the
    /// update would not be finite. The filter is unchanged after an error.
    pub fn update(&mut self, x: &SVector<T, N>, z: T) -> Result<T> {
        if let Some(index) = x.iter().position(|v| !v.finite()) {
            return Err(Error::NonFinite { arg: "r_k", index });
        }
        if !z.finite() {
            return Err(Error::NonFinite { arg: "z_k", index: 0 });
        }
        if self.retired {
            return Ok(z - self.theta.dot(x));
        }
        if self.start {
            return self.absorb(x, z).map(|()| T::of(f64::NAN));
        }
        let mut next = *self;
        let e = z - self.theta.dot(x);
        // Tracking acts while tr P is below the bound (decided on the covariance before the
        // sample): directional forgetting inside the measurement update, drift after it.
        let track = self.tracking() && self.trace() < self.cap;
        match self.form {
            CovarianceForm::Sqrt => next.step_ud(x, e, track)?,
            _ => next.step_p(x, e, track)?,
        }
        // A gated sample leaves the row unchanged (`KalmanOptions::gate`): no forgetting, no
        // drift, as in the lanes of `KalmanRows` (only its count and statistics move).
        let track = track && next.gated == self.gated;
        if track && !self.directional && self.lambda < T::one() {
            next.forget_exponentially();
        }
        if track && self.drift > T::zero() {
            next.add_drift();
        }
        if !(next.theta.iter().all(|v| v.finite()) && next.m.iter().all(|v| v.finite())) {
            // Through the state (`xᵀθ`, the covariance) or through the derivative (`e`).
            return Err(super::guards::overflow_culprit(e, self.theta.dot(x)));
        }
        *self = next;
        Ok(e)
    }

    /// `true` when the next [`RowIdentifier::update`] is the plain step: the standard form
    /// after the start, not retired, no tracking, no outlier screen, `r > 0` (the step a
    /// structure's groups take side by side in lanes, `kalman::xlanes`).
    #[inline(always)]
    pub(crate) fn plain(&self) -> bool {
        (self.form == CovarianceForm::Standard)
            & !self.start
            & !self.retired
            & (self.lambda == T::one())
            & (self.drift == T::zero())
            & (self.gate == T::zero())
            & (self.huber == T::zero())
            & (self.r > T::zero())
    }
}
