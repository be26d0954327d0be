//! The Kalman-filter identifier (Eq 4.3–4.7): recursive weighted least squares on
//! `z(k) = H_r(k) θ + ε(k)`, `H = I ⊗ xᵀ` restricted to the unknown rows,
//! `R = R_v + B R_u Bᵀ` (the unmeasured road input is measurement noise on the rows it
//! enters), `P(0) = p0 I`, `θ̂(0) = 0` unless a prior is given.
//!
//! Three forms that the algebra makes equal where their assumptions hold:
//! - [`KalmanRows`] (`rows`): Eq 6.16–6.18, one scalar-output filter per unknown row
//!   ([`RowIdentifier`]), each with its own `p0` and `r`. Exactly the full filter when `R` is
//!   diagonal and `P(0)` block diagonal. Rows can retire once identified.
//! - [`KalmanShared`] (`shared`): one `N × N` matrix `Q` with `P_i = r_i Q` for every row,
//!   valid when `r_i / p0_i` is the same on every row. The cheapest form.
//! - [`KalmanFull`] (`full`): the stacked filter with a general (non-diagonal) `R`, its
//!   covariance kept as `K × K` blocks of `N × N`.
//!
//! After `k` samples the estimate is the least-squares solution with the prior as extra
//! rows: `θ̂_i = argmin Σ_k (z_i − xᵀθ)²/r_i + (θ − θ̂_i(0))ᵀ P_i(0)⁻¹ (θ − θ̂_i(0))`
//! (thesis-notes §8). So the estimate depends on `r_i / p0_i` only; the ratio decides
//! whether the prior or the data wins in weakly excited directions.
//!
//! **Reinitialization (Eq 4.35–4.36).** With `e(k) = z − H θ̂(k−1)` on the unknown rows, when
//! `10 Σ|e_i(k)| > Σ_j P_jj(k)` the diagonal of `P` is multiplied by 10 and `R` doubled.
//!
//! # Memory (Table I of the thesis: 352 bytes for the 4-state identifier, 2800 for the 8-state)
//! `size_of::<KalmanIdentifier<f32, 4, 2>>()` is 328 bytes and
//! `size_of::<KalmanIdentifier<f32, 8, 4>>()` is 1512 bytes (the rows side by side: θ, the
//! covariances as `N × N` lanes of which the upper triangle is used, `r`, room for the
//! planned step of one sample (the transactional update), plus the row indices, options
//! and counters); the shared form needs 144 and 456.
//! Both are within the thesis' 352 and 2800 bytes. These figures are asserted in the tests.

use super::lanes::{finite_probe, is_fin, lane_sum, tree_sum, RowGroup};
#[cfg(feature = "alloc")]
use super::Dynamic;
use super::{check_sample, per_row, rows_buffer, rows_into, Cost, Fixed, Flat, Store, OVERFLOW};
use crate::error::{check_finite, check_nonneg, check_positive};
use crate::linalg::{axpy, cholesky_in_place, cholesky_solve, mat_vec, sym_downdate, symmetrize};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

/// Gives an identifier with an `#[inline(always)] fn step(&mut self, x, z, e) -> Result<()>`
/// its AVX2 copy `step_avx2` and `dispatch`, which runs that copy when `wide` (where it
/// measured faster) and the CPU has AVX2 (x86-64 with `std`), else the portable `step`.
/// Both copies compute the same bits (no FMA, fixed summation order; tested).
macro_rules! avx2_step {
    () => {
        /// [`Self::step`] compiled for AVX2 (same arithmetic, wider registers).
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        #[target_feature(enable = "avx2")]
        fn step_avx2(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
            self.step(x, z, e)
        }

        /// Runs [`Self::step`] in its AVX2 copy when `wide` and the CPU has AVX2, else portable.
        #[inline(always)]
        fn dispatch(&mut self, wide: bool, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            if wide && crate::simd::avx2() {
                // SAFETY: the CPU supports AVX2 (checked at run time by `simd::avx2`).
                return unsafe { self.step_avx2(x, z, e) };
            }
            let _ = wide;
            self.step(x, z, e)
        }
    };
}

/// How the covariance is propagated after a measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CovarianceForm {
    /// `P ← P − P x xᵀ P / (xᵀ P x + r)` (Eq 4.6), kept exactly symmetric: [`KalmanRows`]
    /// and [`KalmanShared`] update only the upper triangle (`P_ab −= (Px)_a (Px)_b / s`,
    /// `a ≤ b`) and mirror it; [`RowIdentifier`] evaluates `P − u uᵀ` with `u = P x / √s`.
    #[default]
    Standard,
    /// Joseph's form `P ← (I − g xᵀ) P (I − g xᵀ)ᵀ + r g gᵀ`, positive semi-definite by
    /// construction (slower; for `f32` over very long runs).
    Joseph,
}

/// Options common to the Kalman identifiers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KalmanOptions<T> {
    /// Covariance update form.
    pub form: CovarianceForm,
    /// Apply the reinitialization rule of Eq 4.36.
    pub reinit: bool,
    /// `rows` form only: a row stops updating once `tr P_i` falls below this value
    /// (0 = never). A reinitialization brings retired rows back.
    pub retire_below: T,
}

impl<T: Real> Default for KalmanOptions<T> {
    fn default() -> Self {
        Self { form: CovarianceForm::Standard, reinit: false, retire_below: T::zero() }
    }
}

impl<T: Real> KalmanOptions<T> {
    fn validate(&self) -> Result<()> {
        check_nonneg("retire_below", self.retire_below)
    }
}

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

/// The decoupled (`rows`) Kalman-filter identifier over a [`Store`]; see [`KalmanIdentifier`]
/// for the allocation-free form.
///
/// The row filters are kept side by side in lanes ([`super::lanes`]): one update treats all
/// rows at once with vector instructions, and only the upper triangle of each `P` is stored.
#[derive(Debug, Clone)]
pub struct KalmanRows<T: Real, const N: usize, S: Store<T, N>> {
    rows: S::Rows,
    groups: S::Groups,
    /// The planned step of the sample being processed, one per group (used when the plan
    /// does not stay in registers).
    scratch: S::Scratches,
    opts: KalmanOptions<T>,
    reinit_count: u32,
    samples: u64,
}

/// The Kalman-filter identifier for `K` unknown rows of an `N`-state model, decoupled rows
/// (Eq 6.16–6.18), no allocation.
///
/// # Examples
/// ```
/// use vehid_core::identify::KalmanIdentifier;
/// use vehid_core::model::QuarterCar;
/// let car = QuarterCar::<f64>::thesis();
/// let r = car.model().row_noise_var::<2>(0.1, 0.005)?;
/// let mut id = KalmanIdentifier::<f64, 4, 2>::new(car.unknown_rows(), 1000.0, r)?;
/// let x = nalgebra::Vector4::new(0.01, 0.2, 0.02, -0.1);
/// let z = car.model().a() * x;
/// let e = id.update(&x, &z)?;          // innovations of rows 1 and 3
/// assert_eq!(e.len(), 2);
/// let theta = id.theta();              // SMatrix<f64, 2, 4>
/// # let _ = theta;
/// # Ok::<(), vehid_core::Error>(())
/// ```
pub type KalmanIdentifier<T, const N: usize, const K: usize> = KalmanRows<T, N, Fixed<K>>;

/// [`KalmanRows`] with heap storage, for a number of rows known only at run time.
#[cfg(feature = "alloc")]
pub type KalmanIdentifierVec<T, const N: usize> = KalmanRows<T, N, Dynamic>;

/// [`KalmanRows`] with heap storage in groups of two lanes: the faster form for one or two
/// unknown rows (see [`Dynamic`]).
#[cfg(feature = "alloc")]
pub type KalmanIdentifierVec2<T, const N: usize> = KalmanRows<T, N, Dynamic<2>>;

impl<T: Real, const N: usize, S: Store<T, N>> KalmanRows<T, N, S> {
    /// Builds the identifier for the given 0-based unknown rows, with `P_i(0) = p0_i I`
    /// (`p0`: one value or one per row) and measurement variances `r` (one or one per row).
    ///
    /// # Errors
    /// [`Error::BadRow`] for bad rows, [`Error::Shape`] for wrong lengths,
    /// [`Error::InvalidArgument`] for `p0 ≤ 0`, `r < 0`, non-finite values.
    pub fn from_slices(rows: &[usize], p0: &[T], r: &[T], opts: KalmanOptions<T>) -> Result<Self> {
        opts.validate()?;
        let rows_buf: S::Rows = rows_buffer::<_, N>(rows)?;
        let k = rows.len();
        let mut s = Self::empty(rows_buf, opts)?;
        for i in 0..k {
            let f = RowIdentifier::new(per_row("p0", p0, k, i)?, per_row("r", r, k, i)?)?;
            s.set_filter(i, &f);
        }
        Ok(s)
    }

    /// Rows set, every lane padding.
    fn empty(rows: S::Rows, opts: KalmanOptions<T>) -> Result<Self> {
        let k = rows.flat().len();
        let lanes = <S::Group as RowGroup<T, N>>::LANES;
        let n_groups = k.div_ceil(lanes);
        Ok(Self {
            rows,
            groups: S::Groups::filled("unknown_rows", n_groups, S::Group::padding())?,
            scratch: S::Scratches::filled("unknown_rows", n_groups, S::Group::scratch())?,
            opts,
            reinit_count: 0,
            samples: 0,
        })
    }

    /// The group holding unknown row `i`, and the row's lane in it.
    fn group(&self, i: usize) -> (&S::Group, usize) {
        let lanes = <S::Group as RowGroup<T, N>>::LANES;
        (&self.groups.flat()[i / lanes], i % lanes)
    }

    /// [`Self::group`], mutably.
    fn group_mut(&mut self, i: usize) -> (&mut S::Group, usize) {
        let lanes = <S::Group as RowGroup<T, N>>::LANES;
        (&mut self.groups.flat_mut()[i / lanes], i % lanes)
    }

    /// Puts the filter of unknown row `i`.
    fn set_filter(&mut self, i: usize, f: &RowIdentifier<T, N>) {
        let zrow = self.rows.flat()[i];
        let (g, k) = self.group_mut(i);
        g.set_lane(k, zrow, f);
    }

    /// Builds the identifier from prepared row filters (e.g. with full prior covariances
    /// from [`RowIdentifier::with_prior`]).
    ///
    /// # Errors
    /// [`Error::BadRow`] / [`Error::Shape`] when rows and filters do not match.
    pub fn from_filters(rows: &[usize], filters: &[RowIdentifier<T, N>], opts: KalmanOptions<T>) -> Result<Self> {
        opts.validate()?;
        if rows.len() != filters.len() {
            return Err(Error::Shape { arg: "filters", expected: rows.len(), got: filters.len() });
        }
        let rows_buf: S::Rows = rows_buffer::<_, N>(rows)?;
        let mut s = Self::empty(rows_buf, opts)?;
        for (i, f) in filters.iter().enumerate() {
            s.set_filter(i, f);
        }
        Ok(s)
    }

    /// The unknown rows (0-based), in the order of θ and of the innovations.
    pub fn rows(&self) -> &[usize] {
        self.rows.flat()
    }

    /// The filter of unknown row `i` (θ̂_i, P_i, r_i, retired), assembled from the lanes.
    ///
    /// # Panics
    /// When `i` is not below the number of unknown rows.
    pub fn filter(&self, i: usize) -> RowIdentifier<T, N> {
        let (g, k) = self.group(i);
        g.lane(k)
    }

    /// The options in use.
    pub fn options(&self) -> &KalmanOptions<T> {
        &self.opts
    }

    /// Number of reinitializations so far (Eq 4.36).
    pub fn reinit_count(&self) -> u32 {
        self.reinit_count
    }

    /// Number of samples accepted.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Estimate of unknown row `i` (in the order of [`KalmanRows::rows`]).
    ///
    /// # Panics
    /// When `i` is not below the number of unknown rows.
    pub fn theta_row(&self, i: usize) -> SVector<T, N> {
        let (g, k) = self.group(i);
        g.theta_lane(k)
    }

    /// Writes θ̂ row-major (`K × N`) into `out`.
    ///
    /// # Errors
    /// [`Error::Shape`] for a wrong length.
    pub fn theta_into(&self, out: &mut [T]) -> Result<()> {
        let k = self.rows.flat().len();
        if out.len() != k * N {
            return Err(Error::Shape { arg: "out", expected: k * N, got: out.len() });
        }
        for (i, chunk) in out.chunks_exact_mut(N).enumerate() {
            chunk.copy_from_slice(self.theta_row(i).as_slice());
        }
        Ok(())
    }

    /// `tr P_i` of unknown row `i`.
    fn trace_row(&self, i: usize) -> T {
        let (g, k) = self.group(i);
        g.trace_lane(k)
    }

    /// `tr P = Σ_i tr P_i`, the quantity Eq 4.36 compares with the innovations.
    pub fn trace(&self) -> T {
        (0..self.rows.flat().len()).fold(T::zero(), |acc, i| acc + self.trace_row(i))
    }

    /// Arithmetic per update (standard form, every row active) and size. Per row:
    /// `e = z − xᵀθ` (N mul, N add), `P x` (N² mul, N(N−1) add), `s = xᵀPx + r` (N mul,
    /// N add), `1/s`, `c = e/s` (1 mul), `g = Px/s` (N mul), `θ += c Px` (N mul, N add),
    /// the upper triangle of `P −= Px gᵀ` (N(N+1)/2 mul and add).
    pub fn cost(&self) -> Cost {
        let k = self.rows.flat().len();
        let tri = N * (N + 1) / 2;
        Cost {
            multiplications: k * (N * N + 4 * N + 1 + tri),
            additions: k * (N * N + 2 * N + tri),
            divisions: k,
            square_roots: 0,
            bytes: core::mem::size_of_val(self) + self.groups.heap_bytes() + self.scratch.heap_bytes(),
        }
    }

    /// Retires row `i` by hand (it stops updating until the next reinitialization).
    pub fn retire(&mut self, i: usize) {
        if i < self.rows.flat().len() {
            let (g, k) = self.group_mut(i);
            g.retire_lane(k);
        }
    }

    /// One sample: the measured state `x` (= `r(k)`) and derivative `z`; writes the
    /// innovations `e_i = z_row − xᵀ θ̂_i(k−1)` into `e` (one per row). No allocation.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf; [`Error::Singular`] when a row's covariance lost
    /// positive definiteness; [`Error::Shape`] for a wrong `e` length. The identifier is
    /// unchanged after any error.
    pub fn update_into(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        let k = self.rows.flat().len();
        if e.len() != k {
            return Err(Error::Shape { arg: "e", expected: k, got: e.len() });
        }
        // AVX2 pays only when a group of lanes fills a 256-bit register (four f64 rows);
        // narrower groups are faster in the portable build, which fits them exactly.
        let wide = <S::Group as RowGroup<T, N>>::LANES * core::mem::size_of::<T>() >= 32;
        self.dispatch(wide, x, z, e)
    }

    avx2_step!();

    /// The update: plan every group, then apply (a failure anywhere changes nothing).
    #[inline(always)]
    fn step(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        let k = e.len();
        let lanes = <S::Group as RowGroup<T, N>>::LANES;
        let probe = finite_probe(x, z);
        let mut ok = probe == T::zero();
        let groups = self.groups.flat_mut();
        // One group (every Fixed<K> store, and up to DYNAMIC_LANES rows) of a small model
        // plans in registers, with no round trip through memory. With more covariance
        // entries than vector registers (N = 8: 36), planning through memory is faster: the
        // compiler would otherwise keep every entry loaded between plan and apply, and spill.
        let small = N * (N + 1) / 2 <= 12;
        if let ([grp], true) = (&mut *groups, small) {
            let mut sc = S::Group::scratch();
            ok &= grp.plan(x, z, e, &mut sc);
            if !ok {
                check_sample(x, z)?;
                let copy = sc; // a reference to `sc` itself would keep it in memory
                grp.check(&copy)?;
                return Err(OVERFLOW);
            }
            grp.apply(x, &sc, self.opts.form);
            return self.accepted(e);
        }
        let scratch = self.scratch.flat_mut();
        for (g, (grp, sc)) in groups.iter().zip(scratch.iter_mut()).enumerate() {
            let lo = g * lanes;
            let hi = (lo + lanes).min(k);
            ok &= grp.plan(x, z, &mut e[lo..hi], sc);
        }
        if !ok {
            check_sample(x, z)?;
            for (grp, sc) in groups.iter().zip(scratch.iter()) {
                grp.check(sc)?;
            }
            return Err(OVERFLOW);
        }
        for (grp, sc) in groups.iter_mut().zip(scratch.iter()) {
            grp.apply(x, sc, self.opts.form);
        }
        self.accepted(e)
    }

    /// Counts an applied sample and runs retirement and reinitialization if enabled.
    #[inline(always)]
    fn accepted(&mut self, e: &[T]) -> Result<()> {
        self.samples += 1;
        if self.opts.reinit || self.opts.retire_below > T::zero() {
            self.after_step(e);
        }
        Ok(())
    }

    /// Retirement and the reinitialization rule (Eq 4.36) after an accepted sample.
    fn after_step(&mut self, e: &[T]) {
        let mut trace = T::zero();
        let mut abs_e = T::zero();
        for (i, ei) in e.iter().enumerate() {
            let tr = self.trace_row(i);
            trace += tr;
            abs_e += ei.abs();
            if self.opts.retire_below > T::zero() && tr < self.opts.retire_below {
                self.retire(i);
            }
        }
        if self.opts.reinit && T::of(10.0) * abs_e > trace {
            for g in self.groups.flat_mut() {
                g.reinitialize();
            }
            self.reinit_count += 1;
        }
    }
}

impl<T: Real, const N: usize, const K: usize> KalmanRows<T, N, Fixed<K>> {
    /// The thesis' identifier: rows, `P(0) = p0 I` on every row, one `r` per row (Eq 4.7;
    /// see [`crate::model::LinearModel::row_noise_var`]).
    ///
    /// # Errors
    /// As [`KalmanRows::from_slices`].
    pub fn new(rows: [usize; K], p0: T, r: [T; K]) -> Result<Self> {
        Self::from_slices(&rows, &[p0], &r, KalmanOptions::default())
    }
}

/// Shared-covariance Kalman identifier over a [`Store`] (`P_i = r_i Q`); see
/// [`SharedKalmanIdentifier`].
#[derive(Debug, Clone)]
pub struct KalmanShared<T: Real, const N: usize, S: Store<T, N>> {
    rows: S::Rows,
    theta: S::Vecs,
    r: S::Scalars,
    q: SMatrix<T, N, N>,
    opts: KalmanOptions<T>,
    reinit_count: u32,
    samples: u64,
}

/// The shared-covariance form: one `N × N` matrix for all `K` rows, no allocation. Valid
/// (equal to the decoupled rows) when `r_i / p0_i` is the same on every row.
pub type SharedKalmanIdentifier<T, const N: usize, const K: usize> = KalmanShared<T, N, Fixed<K>>;

/// [`KalmanShared`] with heap storage.
#[cfg(feature = "alloc")]
pub type SharedKalmanIdentifierVec<T, const N: usize> = KalmanShared<T, N, Dynamic>;

impl<T: Real, const N: usize, S: Store<T, N>> KalmanShared<T, N, S> {
    /// Builds the shared form from per-row `p0` and `r` (one value or one per row).
    ///
    /// # Errors
    /// As [`KalmanRows::from_slices`], plus [`Error::InvalidArgument`] when `r_i / p0_i`
    /// differs between rows (the shared form would then be a different filter; use `rows`),
    /// or when every `r_i` is zero (the common ratio must be > 0) and `retire_below` is set.
    pub fn from_slices(rows: &[usize], p0: &[T], r: &[T], opts: KalmanOptions<T>) -> Result<Self> {
        opts.validate()?;
        if opts.retire_below > T::zero() {
            return Err(Error::InvalidArgument { arg: "retire_below", expected: "0: retiring rows needs mode='rows'" });
        }
        let rows_buf: S::Rows = rows_buffer::<_, N>(rows)?;
        let k = rows.len();
        let mut rv = S::Scalars::filled("r", k, T::zero())?;
        let mut ratio = None;
        for i in 0..k {
            let p = per_row("p0", p0, k, i)?;
            let ri = per_row("r", r, k, i)?;
            check_positive("p0", p)?;
            check_positive("r", ri)?;
            let c = ri / p;
            match ratio {
                None => ratio = Some(c),
                Some(c0) if (c - c0).abs() <= T::of(1e-12) * c0 => {}
                Some(_) => {
                    return Err(Error::InvalidArgument {
                        arg: "r",
                        expected: "the same r/p0 on every row for mode='shared' (use mode='rows' otherwise)",
                    })
                }
            }
            rv.flat_mut()[i] = ri;
        }
        let c = ratio.unwrap_or(T::one());
        let theta = S::Vecs::filled("unknown_rows", k, SVector::zeros())?;
        Ok(Self { rows: rows_buf, theta, r: rv, q: SMatrix::identity() / c, opts, reinit_count: 0, samples: 0 })
    }

    /// The unknown rows (0-based).
    pub fn rows(&self) -> &[usize] {
        self.rows.flat()
    }

    /// The shared normalized covariance `Q` (`P_i = r_i Q`).
    pub fn q(&self) -> &SMatrix<T, N, N> {
        &self.q
    }

    /// Measurement variance of row `i`.
    pub fn r(&self, i: usize) -> T {
        self.r.flat()[i]
    }

    /// Covariance of row `i`: `r_i Q`.
    pub fn p(&self, i: usize) -> SMatrix<T, N, N> {
        self.q * self.r.flat()[i]
    }

    /// Estimate of unknown row `i`.
    pub fn theta_row(&self, i: usize) -> &SVector<T, N> {
        &self.theta.flat()[i]
    }

    /// Number of reinitializations so far.
    pub fn reinit_count(&self) -> u32 {
        self.reinit_count
    }

    /// Number of samples accepted.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// `tr P = Σ_i r_i tr Q`.
    pub fn trace(&self) -> T {
        self.q.trace() * self.r.flat().iter().fold(T::zero(), |a, r| a + *r)
    }

    /// Arithmetic per update (standard form) and size: `Q x` (N² mul, N(N−1) add),
    /// `s = 1 + xᵀQx` (N mul, N add), `1/s`, `g = Qx/s` (N mul), per row `e_i` and
    /// `θ_i += g e_i` (2N mul, 2N add), the upper triangle of `Q −= (Qx) gᵀ` (N(N+1)/2 mul
    /// and add).
    pub fn cost(&self) -> Cost {
        let k = self.rows.flat().len();
        let tri = N * (N + 1) / 2;
        Cost {
            multiplications: N * N + 2 * N + tri + k * 2 * N,
            additions: N * N + tri + k * 2 * N,
            divisions: 1,
            square_roots: 0,
            bytes: core::mem::size_of_val(self) + self.theta.heap_bytes(),
        }
    }

    /// Writes θ̂ row-major (`K × N`) into `out`.
    ///
    /// # Errors
    /// [`Error::Shape`] for a wrong length.
    pub fn theta_into(&self, out: &mut [T]) -> Result<()> {
        rows_into(self.theta.flat(), out)
    }

    /// One sample; innovations into `e`. No allocation.
    ///
    /// # Errors
    /// As [`KalmanRows::update_into`].
    pub fn update_into(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        let k = self.rows.flat().len();
        if e.len() != k {
            return Err(Error::Shape { arg: "e", expected: k, got: e.len() });
        }
        // AVX2 pays for the half car in f64 (two 256-bit registers per column); for the
        // quarter car the portable build is faster (measured: 18.8 against 20.5 ns).
        let wide = N * core::mem::size_of::<T>() > 32;
        self.dispatch(wide, x, z, e)
    }

    avx2_step!();

    /// The update: `g = Q x / s`, `s = 1 + xᵀQx`; `θ_i += g e_i`; `Q −= (Q x) gᵀ` with
    /// entry `(a, b)` taken from the upper triangle (so `Q` stays exactly symmetric).
    #[inline(always)]
    fn step(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        let probe = finite_probe(x, z);
        // Q x: column j scaled by x_j, the columns summed pairwise.
        let mut cols = [[T::zero(); N]; N];
        for (j, col) in cols.iter_mut().enumerate() {
            for a in 0..N {
                col[a] = self.q[(a, j)] * x[j];
            }
        }
        let qx = lane_sum(cols);
        let mut xqx = [T::zero(); N];
        for a in 0..N {
            xqx[a] = qx[a] * x[a];
        }
        let s = tree_sum(xqx) + T::one();
        let inv_s = T::one() / s;
        let rows = self.rows.flat();
        let theta = self.theta.flat_mut();
        let mut abs_e = T::zero();
        // Zipped (no bounds checks: they would split the loop the compiler vectorizes).
        for ((th, ei), &row) in theta.iter().zip(e.iter_mut()).zip(rows) {
            let mut xt = [T::zero(); N];
            for a in 0..N {
                xt[a] = th[a] * x[a];
            }
            *ei = z.as_slice().get(row).copied().unwrap_or_else(T::zero) - tree_sum(xt);
            abs_e += ei.abs();
        }
        let mut g = [T::zero(); N];
        let mut ag = [T::zero(); N];
        for a in 0..N {
            g[a] = qx[a] * inv_s;
            ag[a] = g[a].abs();
        }
        let step = tree_sum(ag) * abs_e;
        let ok = (probe == T::zero()) & (s > T::zero()) & (s <= T::biggest()) & is_fin(step);
        if !ok {
            check_sample(x, z)?;
            if !s.finite() {
                return Err(OVERFLOW);
            }
            if !(s > T::zero()) {
                return Err(Error::Singular { what: "the shared covariance (1 + xᵀQx ≤ 0)" });
            }
            return Err(OVERFLOW);
        }
        for (th, &ei) in theta.iter_mut().zip(e.iter()) {
            for a in 0..N {
                th[a] += g[a] * ei;
            }
        }
        match self.opts.form {
            CovarianceForm::Standard => {
                // Whole columns (vector stores that the next sample's loads can forward),
                // entry (a, b) and (b, a) both get Q_ab − (Qx)_min (g)_max: the same number.
                for b in 0..N {
                    for a in 0..N {
                        let v = if a <= b { qx[a] * g[b] } else { qx[b] * g[a] };
                        self.q[(a, b)] -= v;
                    }
                }
            }
            CovarianceForm::Joseph => self.joseph(x, g),
        }
        self.samples += 1;
        if self.opts.reinit && T::of(10.0) * abs_e > self.trace() {
            self.reinitialize();
        }
        Ok(())
    }

    /// Joseph's form for the shared covariance: `Q ← (I − g xᵀ) Q (I − g xᵀ)ᵀ + g gᵀ`.
    #[inline(never)]
    fn joseph(&mut self, x: &SVector<T, N>, g: [T; N]) {
        let g = SVector::<T, N>::from_column_slice(&g);
        let a = SMatrix::<T, N, N>::identity() - g * x.transpose();
        self.q = a * self.q * a.transpose() + g * g.transpose();
        symmetrize(&mut self.q);
    }

    /// Eq 4.36 for the shared form: `P_i' = P_i + 9 diag(P_i)`, `r_i' = 2 r_i`, so
    /// `Q' = (Q + 9 diag Q) / 2`.
    #[cold]
    fn reinitialize(&mut self) {
        for j in 0..N {
            self.q[(j, j)] *= T::of(10.0);
        }
        self.q *= T::of(0.5);
        for r in self.r.flat_mut() {
            *r *= T::of(2.0);
        }
        self.reinit_count += 1;
    }
}

impl<T: Real, const N: usize, const K: usize> KalmanShared<T, N, Fixed<K>> {
    /// The shared form with `P(0) = p0 I` on every row and one `r` per row (all `r_i / p0`
    /// equal, i.e. all `r_i` equal here).
    ///
    /// # Errors
    /// As [`KalmanShared::from_slices`].
    pub fn new(rows: [usize; K], p0: T, r: [T; K]) -> Result<Self> {
        Self::from_slices(&rows, &[p0], &r, KalmanOptions::default())
    }
}

/// The stacked (`full`) Kalman identifier over a [`Store`], general `R`; see
/// [`FullKalmanIdentifier`].
#[derive(Debug, Clone)]
pub struct KalmanFull<T: Real, const N: usize, S: Store<T, N>> {
    rows: S::Rows,
    theta: S::Vecs,
    /// Covariance blocks `P_ij` (`K × K` of `N × N`, row-major).
    p: S::Blocks,
    /// Measurement covariance `R` (`K × K`, row-major).
    r: S::PairScalars,
    /// Scratch: `c_ij = P_ij x`.
    c: S::PairVecs,
    /// Scratch: gain columns `w_il` (block `i`, column `l`).
    w: S::PairVecs,
    /// Scratch: Cholesky factor of `S`.
    s: S::PairScalars,
    opts: KalmanOptions<T>,
    reinit_count: u32,
    samples: u64,
}

/// The stacked Kalman identifier of Eq 4.3–4.7 with a general `K × K` measurement
/// covariance `R`, no allocation. Its covariance is `(K·N) × (K·N)`, kept as blocks.
pub type FullKalmanIdentifier<T, const N: usize, const K: usize> = KalmanFull<T, N, Fixed<K>>;

/// [`KalmanFull`] with heap storage.
#[cfg(feature = "alloc")]
pub type FullKalmanIdentifierVec<T, const N: usize> = KalmanFull<T, N, Dynamic>;

impl<T: Real, const N: usize, S: Store<T, N>> KalmanFull<T, N, S> {
    /// Builds the stacked filter: `P(0)` block diagonal with `p0_i I` (`p0`: one value or
    /// one per row) and `R` a full symmetric positive semi-definite `K × K` matrix
    /// (row-major, `K²` values).
    ///
    /// # Errors
    /// As [`KalmanRows::from_slices`], plus [`Error::Shape`] / [`Error::Singular`] for an `R`
    /// of the wrong size or not symmetric with a non-negative diagonal.
    pub fn from_slices(rows: &[usize], p0: &[T], r: &[T], opts: KalmanOptions<T>) -> Result<Self> {
        opts.validate()?;
        if opts.retire_below > T::zero() {
            return Err(Error::InvalidArgument { arg: "retire_below", expected: "0: retiring rows needs mode='rows'" });
        }
        let rows_buf: S::Rows = rows_buffer::<_, N>(rows)?;
        let k = rows.len();
        if r.len() != k * k {
            return Err(Error::Shape { arg: "r", expected: k * k, got: r.len() });
        }
        check_finite("r", r)?;
        for i in 0..k {
            check_nonneg("r", r[i * k + i])?;
            for j in 0..i {
                if (r[i * k + j] - r[j * k + i]).abs()
                    > T::default_epsilon() * T::of(16.0) * (r[i * k + i] + r[j * k + j])
                {
                    return Err(Error::Singular { what: "r (it must be a symmetric covariance matrix)" });
                }
            }
        }
        let mut p = S::Blocks::filled("p0", k * k, SMatrix::zeros())?;
        for i in 0..k {
            let v = per_row("p0", p0, k, i)?;
            check_positive("p0", v)?;
            p.flat_mut()[i * k + i] = SMatrix::identity() * v;
        }
        let mut rbuf = S::PairScalars::filled("r", k * k, T::zero())?;
        rbuf.flat_mut().copy_from_slice(r);
        Ok(Self {
            rows: rows_buf,
            theta: S::Vecs::filled("unknown_rows", k, SVector::zeros())?,
            p,
            r: rbuf,
            c: S::PairVecs::filled("unknown_rows", k * k, SVector::zeros())?,
            w: S::PairVecs::filled("unknown_rows", k * k, SVector::zeros())?,
            s: S::PairScalars::filled("unknown_rows", k * k, T::zero())?,
            opts,
            reinit_count: 0,
            samples: 0,
        })
    }

    /// Replaces the prior covariance by a full `(K·N) × (K·N)` matrix (row-major).
    ///
    /// # Errors
    /// [`Error::Shape`] for a wrong size; [`Error::Singular`] when it is not symmetric
    /// positive definite (checked by a Cholesky factorization).
    #[cfg(feature = "alloc")]
    pub fn set_p0(&mut self, p0: &[T]) -> Result<()> {
        let k = self.rows.flat().len();
        let kn = k * N;
        if p0.len() != kn * kn {
            return Err(Error::Shape { arg: "p0", expected: kn * kn, got: p0.len() });
        }
        check_finite("p0", p0)?;
        let mut l = alloc::vec::Vec::from(p0);
        for i in 0..kn {
            for j in 0..i {
                if (p0[i * kn + j] - p0[j * kn + i]).abs()
                    > T::default_epsilon() * T::of(16.0) * (p0[i * kn + i] + p0[j * kn + j])
                {
                    return Err(Error::Singular { what: "p0 (it must be symmetric positive definite)" });
                }
            }
        }
        if !cholesky_in_place(&mut l, kn) {
            return Err(Error::Singular { what: "p0 (it must be symmetric positive definite)" });
        }
        let p = self.p.flat_mut();
        for bi in 0..k {
            for bj in 0..k {
                p[bi * k + bj] = SMatrix::from_fn(|a, b| p0[(bi * N + a) * kn + bj * N + b]);
            }
        }
        Ok(())
    }

    /// The unknown rows (0-based).
    pub fn rows(&self) -> &[usize] {
        self.rows.flat()
    }

    /// Covariance block `P_ij`.
    pub fn p_block(&self, i: usize, j: usize) -> &SMatrix<T, N, N> {
        let k = self.rows.flat().len();
        &self.p.flat()[i * k + j]
    }

    /// Measurement covariance entry `R_ij`.
    pub fn r(&self, i: usize, j: usize) -> T {
        let k = self.rows.flat().len();
        self.r.flat()[i * k + j]
    }

    /// Estimate of unknown row `i`.
    pub fn theta_row(&self, i: usize) -> &SVector<T, N> {
        &self.theta.flat()[i]
    }

    /// Number of reinitializations so far.
    pub fn reinit_count(&self) -> u32 {
        self.reinit_count
    }

    /// Number of samples accepted.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// `tr P`.
    pub fn trace(&self) -> T {
        let k = self.rows.flat().len();
        (0..k).fold(T::zero(), |a, i| a + self.p.flat()[i * k + i].trace())
    }

    /// Arithmetic per update and size: `c_ij = P_ij x` (K² N² mul), `S` (K(K+1)/2 · N),
    /// Cholesky of `S` and `K·N` triangular solves (about K³/3 + K²N mul), `θ` (K² N) and
    /// the upper blocks of `P` (K(K+1)/2 · K N² mul). Counted to leading order.
    pub fn cost(&self) -> Cost {
        let k = self.rows.flat().len();
        let mul = k * k * N * N
            + k * (k + 1) / 2 * N
            + k * k * k / 3
            + 2 * k * k * N
            + k * k * N
            + k * (k + 1) / 2 * k * N * N;
        Cost {
            multiplications: mul,
            additions: mul,
            divisions: k * N * 2 + k,
            square_roots: k,
            bytes: core::mem::size_of_val(self) + self.p.heap_bytes() + self.c.heap_bytes() + self.w.heap_bytes(),
        }
    }

    /// Writes θ̂ row-major (`K × N`) into `out`.
    ///
    /// # Errors
    /// [`Error::Shape`] for a wrong length.
    pub fn theta_into(&self, out: &mut [T]) -> Result<()> {
        rows_into(self.theta.flat(), out)
    }

    /// One sample of the stacked filter (Eq 4.3–4.6); innovations into `e`. No allocation.
    ///
    /// `S = H P Hᵀ + R` with `(H P Hᵀ)_ij = xᵀ P_ij x`; the gain block of row `i` is
    /// `W_i = C_i S⁻¹`, `C_i = [P_i1 x, …, P_iK x]`; `θ_i += W_i e`, `P_ij −= W_i C_jᵀ`.
    ///
    /// # Errors
    /// As [`KalmanRows::update_into`]; [`Error::Singular`] when `S` is not positive definite.
    pub fn update_into(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        check_sample(x, z)?;
        let rows = self.rows.flat();
        let k = rows.len();
        if e.len() != k {
            return Err(Error::Shape { arg: "e", expected: k, got: e.len() });
        }
        let theta = self.theta.flat_mut();
        let p = self.p.flat_mut();
        let c = self.c.flat_mut();
        let w = self.w.flat_mut();
        let s = self.s.flat_mut();
        let r = self.r.flat();
        let mut abs_e = T::zero();
        for i in 0..k {
            e[i] = z[rows[i]] - theta[i].dot(x);
            abs_e += e[i].abs();
        }
        for ij in 0..k * k {
            c[ij] = p[ij] * x;
        }
        for i in 0..k {
            for j in 0..=i {
                let v = x.dot(&c[i * k + j]) + r[i * k + j];
                s[i * k + j] = v;
                s[j * k + i] = v;
            }
        }
        if s.iter().any(|v| !v.finite()) || !abs_e.finite() {
            return Err(OVERFLOW);
        }
        if !cholesky_in_place(s, k) {
            return Err(Error::Singular { what: "the innovation covariance H P Hᵀ + R" });
        }
        // W_i = C_i S⁻¹, row by row of C_i: solve S w = (c_i1[a], …, c_iK[a]).
        let mut bound = T::zero();
        let mut col = [T::zero(); N];
        for i in 0..k {
            for a in 0..N {
                let buf = &mut col[..k.min(N)];
                for l in 0..k {
                    buf[l] = c[i * k + l][a];
                }
                cholesky_solve(s, k, buf);
                for l in 0..k {
                    w[i * k + l][a] = buf[l];
                    bound += buf[l].abs() * (abs_e + c[i * k + l][a].abs() * T::of(k as f64));
                }
            }
        }
        if !bound.finite() {
            return Err(OVERFLOW);
        }
        // Apply: nothing above changed the identifier's state.
        for i in 0..k {
            for l in 0..k {
                theta[i] += w[i * k + l] * e[l];
            }
        }
        for i in 0..k {
            for j in i..k {
                let mut d = SMatrix::<T, N, N>::zeros();
                for l in 0..k {
                    d += w[i * k + l] * c[j * k + l].transpose();
                }
                p[i * k + j] -= d;
                if i == j {
                    symmetrize(&mut p[i * k + i]);
                } else {
                    p[j * k + i] = p[i * k + j].transpose();
                }
            }
        }
        self.samples += 1;
        let trace = (0..k).fold(T::zero(), |a, i| a + p[i * k + i].trace());
        if self.opts.reinit && T::of(10.0) * abs_e > trace {
            for i in 0..k {
                for j in 0..N {
                    p[i * k + i][(j, j)] *= T::of(10.0);
                }
            }
            for v in self.r.flat_mut() {
                *v *= T::of(2.0);
            }
            self.reinit_count += 1;
        }
        Ok(())
    }
}

impl<T: Real, const N: usize, const K: usize> KalmanFull<T, N, Fixed<K>> {
    /// The stacked filter with `P(0) = p0 I` and a full `R` (`K × K`).
    ///
    /// # Errors
    /// As [`KalmanFull::from_slices`].
    pub fn new(rows: [usize; K], p0: T, r: SMatrix<T, K, K>) -> Result<Self> {
        Self::from_slices(&rows, &[p0], r.transpose().as_slice(), KalmanOptions::default())
    }
}

fixed_k_api!(KalmanRows);
fixed_k_api!(KalmanShared);
fixed_k_api!(KalmanFull);

#[cfg(test)]
mod tests;
