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

use super::{CovarianceForm, KalmanOptions};
use crate::error::{check_finite, check_nonneg, check_positive};
use crate::identify::OVERFLOW;
use crate::linalg::{cholesky_in_place, mat_vec, symmetrize};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

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

/// `true` for a positive normal float (`v ≥` the smallest normal, `4 / max` in IEEE binary
/// formats) that is finite.
fn normal<T: Real>(v: T) -> bool {
    v >= T::of(4.0) / T::biggest() && v.finite()
}

/// The error for an exact start whose covariance would underflow: the sample is refused.
pub(crate) const SCALE: Error = Error::InvalidArgument {
    arg: "r_k",
    expected: "samples whose inverse squares are representable (values near 1e154 in f64, or 1e19 in f32, \
               make the exact start's covariance underflow): rescale the units",
};

/// Relative size below which a diagonal entry of the exact start's `R` counts as zero
/// (`√ε · d` for `d` parameters): the start ends when every direction is identified that well.
fn start_tol<T: Real>(d: usize) -> T {
    T::default_epsilon().sqrt() * T::of(d as f64)
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
            return Err(super::lanes::overflow_culprit(e, self.theta.dot(x)));
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

    /// The directional forgetting term of an update with innovation variance `s`: the
    /// covariance after the update is inflated along `x` only,
    /// `P⁺ + ((1 − λ)/λ) P⁺x xᵀP⁺ / xᵀP⁺x` (Kulhavý & Kárný 1984), which with
    /// `P⁺x = P x r/s` is `c (P x)(P x)ᵀ`, `c = ((1 − λ)/λ) r / (s (s − r))`. A sample that
    /// carries no information (`x = 0`, `s = r`) forgets nothing: no wind-up without
    /// excitation. 0 when forgetting is off.
    fn forget_coefficient(&self, s: T, r: T, track: bool) -> T {
        let xpx = s - r;
        if !track || !self.directional || self.lambda >= T::one() || !(xpx > T::zero()) {
            return T::zero();
        }
        (T::one() - self.lambda) / self.lambda * r / (s * xpx)
    }

    /// Exponential forgetting `P ← P / λ` (`D ← D / λ` in the square-root form).
    fn forget_exponentially(&mut self) {
        let inv = T::one() / self.lambda;
        match self.form {
            CovarianceForm::Sqrt => {
                for j in 0..N {
                    self.m[(j, j)] *= inv;
                }
            }
            _ => self.m *= inv,
        }
    }

    /// Random-walk drift `P ← P + q I`.
    fn add_drift(&mut self) {
        match self.form {
            CovarianceForm::Sqrt => {
                for i in 0..self.dim() {
                    let mut a = SVector::<T, N>::zeros();
                    a[i] = T::one();
                    ud_rank_one(&mut self.m, self.drift, a);
                }
            }
            _ => {
                for j in 0..self.dim() {
                    self.m[(j, j)] += self.drift;
                }
            }
        }
    }

    /// The covariance form's measurement update (standard or Joseph).
    fn step_p(&mut self, x: &SVector<T, N>, e: T, track: bool) -> Result<()> {
        let mut px = SVector::zeros();
        mat_vec(&self.m, x, &mut px);
        let s = x.dot(&px) + self.r;
        if !s.finite() {
            return Err(OVERFLOW);
        }
        if self.r == T::zero() {
            // Noise-free data and a covariance collapsed along x (xᵀPx at rounding level):
            // nothing is left to learn in that direction.
            let floor = collapse_floor::<T, N>(x.abs().sum(), px.abs().sum());
            if s <= floor {
                return Ok(());
            }
        }
        if !(s > T::zero()) {
            return Err(Error::Singular {
                what: "the innovation variance xᵀPx + r (P lost positive definiteness: reset_covariance(p0) restarts the identifier from its \
                       estimate; form='sqrt' cannot lose it)",
            });
        }
        let Some(r_eff) = self.screen(e, s) else {
            self.record_gated();
            return Ok(());
        };
        let s = s - self.r + r_eff;
        let inv_s = T::one() / s;
        let g = px * inv_s;
        self.theta += g * e;
        let fc = self.forget_coefficient(s, r_eff, track);
        match self.form {
            CovarianceForm::Joseph => {
                let a = SMatrix::<T, N, N>::identity() - g * x.transpose();
                let mut next = a * self.m * a.transpose() + g * g.transpose() * r_eff + px * px.transpose() * fc;
                symmetrize(&mut next);
                if r_eff > T::zero() && r_eff < risky::<T>() * s && !positive_definite(&next, self.dim()) {
                    return Err(LOST_DEFINITENESS);
                }
                self.m = next;
            }
            _ => {
                // P − (P x)(P x)ᵀ (1/s − c), the forgetting folded into the downdate. Entry
                // (a, b) and (b, a) subtract the same product: P stays exactly symmetric.
                let gk = px * (inv_s - fc);
                let mut next = self.m;
                for b in 0..N {
                    for a in 0..N {
                        next[(a, b)] -= px[a] * gk[b];
                    }
                }
                symmetrize(&mut next);
                if r_eff > T::zero() && r_eff < risky::<T>() * s && !positive_definite(&next, self.dim()) {
                    return Err(LOST_DEFINITENESS);
                }
                self.m = next;
            }
        }
        self.record(e, s);
        Ok(())
    }

    /// Bierman's square-root (`U D Uᵀ`) measurement update: `f = Uᵀx`, `v = D f`,
    /// `α_j = r + Σ_{i≤j} f_i v_i`; `D_j ← D_j α_{j−1} / α_j`; the gain accumulates in `b`
    /// while `U` is updated column by column (Bierman, *Factorization Methods for Discrete
    /// Sequential Estimation*, 1977, §V.3). `s = α_N`.
    fn step_ud(&mut self, x: &SVector<T, N>, e: T, track: bool) -> Result<()> {
        let m = &mut self.m;
        // f = Uᵀ x (U unit upper triangular: U_aa = 1).
        let mut f = SVector::<T, N>::zeros();
        for j in 0..N {
            let mut v = x[j];
            for i in 0..j {
                v += m[(i, j)] * x[i];
            }
            f[j] = v;
        }
        let mut v = SVector::<T, N>::zeros();
        for j in 0..N {
            v[j] = m[(j, j)] * f[j];
        }
        // The innovation variance first (s = r + Σ f_j v_j), for the outlier screen.
        let s = (0..N).fold(self.r, |a, j| a + f[j] * v[j]);
        if self.r == T::zero() {
            // Noise-free data and xᵀPx at rounding level against |x|₁ |P x|₁ (`P x = U v`): as
            // in the covariance forms, nothing is learned along x. (Taking such a sample would
            // collapse P along a direction x reaches only at rounding level, with the
            // estimate there made of rounding errors, for good.)
            let mut px = v;
            for i in 0..N {
                for j in (i + 1)..N {
                    px[i] += m[(i, j)] * v[j];
                }
            }
            if s <= collapse_floor::<T, N>(x.abs().sum(), px.abs().sum()) {
                return Ok(());
            }
        }
        let r_eff = if s > T::zero() && s.finite() {
            let (gate, huber, nobs, ssr, r) = (self.gate, self.huber, self.nobs, self.ssr, self.r);
            match screen(gate, huber, nobs, ssr, r, e, s, self.dim as usize) {
                Some(r_eff) => r_eff,
                None => {
                    self.record_gated();
                    return Ok(());
                }
            }
        } else {
            self.r
        };
        let m = &mut self.m;
        let mut alpha = r_eff;
        let mut b = SVector::<T, N>::zeros();
        for j in 0..N {
            let prev = alpha;
            alpha = prev + f[j] * v[j];
            if !alpha.finite() {
                return Err(OVERFLOW);
            }
            if !(alpha > T::zero()) {
                if alpha < T::zero() || f[j] != T::zero() {
                    return Err(Error::Singular {
                        what: "the innovation variance xᵀPx + r (the square-root factors are not positive)",
                    });
                }
                // r = 0 and no information along x yet (f_j = v_j = 0): column j is unchanged.
                continue;
            }
            m[(j, j)] *= prev / alpha;
            if prev > T::zero() {
                let p = -f[j] / prev;
                for i in 0..j {
                    let u = m[(i, j)];
                    m[(i, j)] = u + b[i] * p;
                    b[i] += u * v[j];
                }
            } else {
                // α_{j−1} = 0: every earlier b_i is 0, U's column keeps its values.
                for i in 0..j {
                    b[i] += m[(i, j)] * v[j];
                }
            }
            b[j] = v[j];
        }
        if !(alpha > T::zero()) {
            // r = 0 and x orthogonal to everything learned: nothing to learn (noise-free).
            return Ok(());
        }
        let s = alpha;
        let c = e / s;
        for a in 0..N {
            self.theta[a] += b[a] * c;
        }
        // Bierman's b is P x: directional forgetting is the rank-one update c (P x)(P x)ᵀ.
        let fc = self.forget_coefficient(s, r_eff, track);
        if fc > T::zero() {
            ud_rank_one(&mut self.m, fc, b);
        }
        self.record(e, s);
        Ok(())
    }

    /// The outlier screen of a sample with innovation `e` and variance `s`: `None` when the
    /// gate rejects it, else the variance to use (`r`, or `r` scaled up by the Huber weight).
    fn screen(&self, e: T, s: T) -> Option<T> {
        screen(self.gate, self.huber, self.nobs, self.ssr, self.r, e, s, self.dim())
    }

    /// Counts a gated sample and lets it inform the scale: its recursive residual enters
    /// `σ̂²` Winsorized at the gate, `κ² σ̂²` (see [`gated_scale`]).
    fn record_gated(&mut self) {
        (self.ssr, self.nobs) = gated_scale(self.gate, self.lambda, self.ssr, self.nobs, self.dim());
        self.gated += 1;
    }

    /// Accumulates the statistics of an accepted update with innovation `e`, variance `s`.
    fn record(&mut self, e: T, s: T) {
        let decay = self.lambda;
        self.ssr = self.ssr * decay + e * e * self.r / s;
        self.nobs = self.nobs * decay + T::one();
        self.s = s;
    }

    /// Exact start: one sample into the QR factorization `R` (in `m`), `Qᵀz` (in `θ`) by
    /// Givens rotations; the residual left over is the sample's recursive residual. When
    /// `R` identifies every direction, switches to filtering.
    fn absorb(&mut self, x: &SVector<T, N>, z: T) -> Result<()> {
        let mut next = *self;
        let d = next.dim();
        let (rm, c) = (&mut next.m, &mut next.theta);
        let mut row = *x;
        let mut rhs = z;
        for j in 0..N {
            if row[j] == T::zero() {
                continue;
            }
            let rho = hypot(rm[(j, j)], row[j]);
            if !(rho.finite() && rho > T::zero()) {
                return Err(OVERFLOW);
            }
            let (cs, sn) = (rm[(j, j)] / rho, row[j] / rho);
            rm[(j, j)] = rho;
            for b in (j + 1)..N {
                let (rv, xv) = (rm[(j, b)], row[b]);
                rm[(j, b)] = cs * rv + sn * xv;
                row[b] = cs * xv - sn * rv;
            }
            let cv = c[j];
            c[j] = cs * cv + sn * rhs;
            rhs = cs * rhs - sn * cv;
            row[j] = T::zero();
        }
        if !rm.iter().chain(c.iter()).all(|v| v.finite()) || !rhs.finite() {
            return Err(OVERFLOW);
        }
        next.ssr += rhs * rhs;
        next.nobs += T::one();
        // Identified: every diagonal entry of R clearly non-zero.
        let big = (0..d).fold(T::zero(), |a, j| a.max(rm[(j, j)].abs()));
        let tol = start_tol::<T>(d) * big;
        if big > T::zero() && (0..d).all(|j| rm[(j, j)].abs() > tol) {
            next.finish_start();
            // `P = r R⁻¹R⁻ᵀ` scales as 1/x²: with samples near 1e154 (f64) it underflows, and
            // the filter would go on with a covariance of zeros and subnormals (a confident
            // wrong estimate). Its diagonal (`D` in the square-root form) must be normal.
            if !(0..d).all(|j| normal(next.m[(j, j)])) {
                return Err(SCALE);
            }
        }
        *self = next;
        Ok(())
    }

    /// From `R`, `Qᵀz` to `θ̂ = R⁻¹ Qᵀz` and the chosen covariance form of `P = r R⁻¹R⁻ᵀ`.
    fn finish_start(&mut self) {
        // S = R⁻¹ (upper triangular), by back substitution column by column.
        let rm = self.m;
        let d = self.dim();
        let mut sm = SMatrix::<T, N, N>::zeros();
        for col in 0..d {
            for i in (0..=col).rev() {
                let mut v = if i == col { T::one() } else { T::zero() };
                for k in (i + 1)..=col {
                    v -= rm[(i, k)] * sm[(k, col)];
                }
                sm[(i, col)] = v / rm[(i, i)];
            }
        }
        self.theta = sm * self.theta;
        self.m = match self.form {
            // P = r S Sᵀ = U D Uᵀ with U = S diag(1/s_bb), D = r diag(s_bb²).
            CovarianceForm::Sqrt => {
                let mut ud = SMatrix::<T, N, N>::zeros();
                for b in 0..d {
                    let sbb = sm[(b, b)];
                    for a in 0..b {
                        ud[(a, b)] = sm[(a, b)] / sbb;
                    }
                    ud[(b, b)] = self.r * sbb * sbb;
                }
                ud
            }
            _ => {
                let mut p = sm * sm.transpose() * self.r;
                symmetrize(&mut p);
                p
            }
        };
        self.start = false;
        if self.cap == T::zero() && self.tracking() {
            self.cap = self.trace();
        }
    }
}

/// Samples behind `σ̂` before the outlier screen acts (beyond the `N` the estimate uses).
pub(crate) const SCREEN_WARMUP: f64 = 50.0;

/// The outlier screen ([`KalmanOptions::gate`], [`KalmanOptions::huber`]) of a sample with
/// innovation `e` and innovation variance `s`, given the row's statistics: `None` when gated,
/// else the variance `r` to use (scaled up by the Huber weight). The recursive residual is
/// `w² = e² r / s`; `σ̂² = ssr / (nobs − N)` estimates its variance.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn screen<T: Real>(gate: T, huber: T, nobs: T, ssr: T, r: T, e: T, s: T, params: usize) -> Option<T> {
    if (gate == T::zero() && huber == T::zero()) || nobs < T::of(params as f64 + SCREEN_WARMUP) {
        return Some(r);
    }
    let sigma2 = ssr / (nobs - T::of(params as f64));
    if !(sigma2 > T::zero()) {
        return Some(r); // noise-free so far: no scale to judge by
    }
    let z2 = e * e * r / s / sigma2;
    if gate > T::zero() && !(z2 <= gate * gate) {
        return None;
    }
    if huber > T::zero() && z2 > huber * huber {
        return Some(r * z2.sqrt() / huber);
    }
    Some(r)
}

/// The checks of a covariance reset: `p0` finite and > 0, and not during an exact start
/// (there is no estimate to keep yet).
pub(crate) fn check_reset<T: Real>(p0: T, starting: bool) -> Result<()> {
    if !(p0 > T::zero() && p0.finite()) {
        return Err(Error::InvalidArgument { arg: "p0", expected: "a finite covariance > 0 to restart from" });
    }
    if starting {
        return Err(Error::Unsupported {
            what: "reset_covariance during the exact start (no estimate yet: feed samples until it has one)",
        });
    }
    Ok(())
}

/// The residual statistics `(ssr, nobs)` after a gated sample: its recursive residual enters
/// Winsorized at the gate, `κ² σ̂²` with `σ̂² = ssr / (nobs − N)`, decayed by `λ` like an
/// accepted one. An isolated outlier then moves `σ̂²` by a factor `1 + (κ² − 1)/n` only (n the
/// statistics' memory: every sample so far, or `1/(1 − λ)` with forgetting), while a lasting
/// change of the dynamics, whose every residual lies beyond the gate, raises `σ̂` by that
/// factor per sample until its samples pass: within about `ln(z²/κ²) / ln(1 + (κ² − 1)/n)`
/// samples for residuals `z σ̂` (tens of samples at `κ = 6`, `λ = 0.995`), so a gate does not
/// stop the identifier from tracking a change.
#[inline(always)]
pub(crate) fn gated_scale<T: Real>(gate: T, lambda: T, ssr: T, nobs: T, params: usize) -> (T, T) {
    let sigma2 = ssr / (nobs - T::of(params as f64));
    (ssr * lambda + gate * gate * sigma2, nobs * lambda + T::one())
}

/// The rounding level of `xᵀPx` for a noise-free row (`r = 0`): `ε · 4N · |x|₁ · |P x|₁`
/// (`x_l1`, `px_l1`). At or below it the covariance has collapsed along `x` and the row takes
/// no step (every mode alike).
#[inline(always)]
pub(crate) fn collapse_floor<T: Real, const N: usize>(x_l1: T, px_l1: T) -> T {
    T::default_epsilon() * T::of(4.0 * N as f64) * x_l1 * px_l1
}

/// A sample is risky for the standard form when `r / s` is below this (`√ε`): it carries so
/// much information relative to its noise that the downdate `P − P x xᵀ P / s` cancels to
/// rounding level along `x`. The downdated covariance is then checked (Cholesky) before the
/// update is accepted. (Noise-free rows, `r = 0`, are exempt: their `P` becomes singular by
/// design, and directions already learned take no further step.)
pub(crate) fn risky<T: Real>() -> T {
    T::default_epsilon().sqrt()
}

/// The error of an update the standard or Joseph form cannot make without losing positive
/// definiteness (mode `rows`).
pub(crate) const LOST_DEFINITENESS: Error = Error::Singular {
    what: "the covariance after this sample (the update would lose positive definiteness: the sample is \
           informative far beyond its noise r; use form='sqrt', which cannot, or p0='exact' / a smaller p0)",
};

/// [`LOST_DEFINITENESS`] for modes `shared` and `full`, which have neither the square-root
/// form nor the exact start.
pub(crate) const LOST_DEFINITENESS_JOINT: Error = Error::Singular {
    what: "the covariance after this sample (the update would lose positive definiteness: the sample is \
           informative far beyond its noise r; use a smaller p0, or mode='rows' with form='sqrt', which cannot \
           lose it)",
};

/// `true` when the leading `d × d` block of the symmetric `p` is numerically positive
/// definite (its Cholesky factorization exists).
pub(crate) fn positive_definite<T: Real, const N: usize>(p: &SMatrix<T, N, N>, d: usize) -> bool {
    let mut l = SMatrix::<T, N, N>::zeros();
    let buf = l.as_mut_slice();
    for b in 0..d {
        for a in 0..d {
            buf[b * d + a] = p[(a, b)];
        }
    }
    cholesky_in_place(&mut buf[..d * d], d)
}

/// `√(a² + b²)` without overflow or underflow in the squares.
fn hypot<T: Real>(a: T, b: T) -> T {
    let (a, b) = (a.abs(), b.abs());
    let (big, small) = if a > b { (a, b) } else { (b, a) };
    if big == T::zero() {
        return T::zero();
    }
    let q = small / big;
    big * (T::one() + q * q).sqrt()
}

/// `U D Uᵀ` factors of the leading `d × d` block of a symmetric positive definite `P`
/// (packed: `U` above the diagonal, `D` on it; 0 beyond the block), by the backward recursion
/// of Bierman (1977, §III).
///
/// # Errors
/// [`Error::Singular`] when the block is not positive definite.
pub(crate) fn ud_factor<T: Real, const N: usize>(p: &SMatrix<T, N, N>, d: usize) -> Result<SMatrix<T, N, N>> {
    let mut p = *p;
    let mut ud = SMatrix::<T, N, N>::zeros();
    for j in (0..d).rev() {
        let d = p[(j, j)];
        if !(d > T::zero()) || !d.finite() {
            return Err(Error::Singular {
                what: "the covariance (it must be positive definite to be factored U D Uᵀ)",
            });
        }
        ud[(j, j)] = d;
        for i in 0..j {
            ud[(i, j)] = p[(i, j)] / d;
        }
        for i in 0..j {
            for k in 0..=i {
                let v = p[(k, i)] - ud[(k, j)] * d * ud[(i, j)];
                p[(k, i)] = v;
                p[(i, k)] = v;
            }
        }
    }
    Ok(ud)
}

/// `P = U D Uᵀ` from the packed factors.
pub(crate) fn ud_product<T: Real, const N: usize>(ud: &SMatrix<T, N, N>) -> SMatrix<T, N, N> {
    let mut p = SMatrix::<T, N, N>::zeros();
    for a in 0..N {
        for b in a..N {
            // P_ab = Σ_j U_aj D_j U_bj over j ≥ max(a, b) = b (U_jj = 1).
            let mut v = T::zero();
            for j in b..N {
                let ua = if a == j { T::one() } else { ud[(a, j)] };
                let ub = if b == j { T::one() } else { ud[(b, j)] };
                v += ua * ud[(j, j)] * ub;
            }
            p[(a, b)] = v;
            p[(b, a)] = v;
        }
    }
    p
}

/// `tr(U D Uᵀ) = Σ_j D_j (1 + Σ_{a<j} U_aj²)`.
pub(crate) fn ud_trace<T: Real, const N: usize>(ud: &SMatrix<T, N, N>) -> T {
    let mut t = T::zero();
    for j in 0..N {
        let mut col = T::one();
        for a in 0..j {
            col += ud[(a, j)] * ud[(a, j)];
        }
        t += ud[(j, j)] * col;
    }
    t
}

/// Agee–Turner rank-one update `U D Uᵀ ← U D Uᵀ + c a aᵀ` for `c > 0` (Bierman 1977, §III.3):
/// numerically stable, keeps `D > 0`.
pub(crate) fn ud_rank_one<T: Real, const N: usize>(ud: &mut SMatrix<T, N, N>, mut c: T, mut a: SVector<T, N>) {
    for j in (0..N).rev() {
        let d = ud[(j, j)];
        let dn = d + c * a[j] * a[j];
        if !(dn > T::zero()) {
            continue;
        }
        let b = c * a[j] / dn;
        c = c * d / dn;
        let aj = a[j];
        for k in 0..j {
            a[k] -= aj * ud[(k, j)];
            ud[(k, j)] += b * a[k];
        }
        ud[(j, j)] = dn;
    }
}
