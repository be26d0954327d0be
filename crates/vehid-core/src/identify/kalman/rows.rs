//! The decoupled (`rows`) form.

use super::lanes::{RowGroup, FORGET, GENERAL, PLAIN};
use super::sums::finite_probe;
use super::{CovarianceForm, KalmanOptions, RowIdentifier};
#[cfg(feature = "alloc")]
use crate::identify::Dynamic;
use crate::identify::{
    check_lengths, check_sample, fixed_theta, per_row, rows_buffer, vector, Cost, Dims, Fixed, Flat, Identifier, Store,
    OVERFLOW,
};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

mod identifier;
/// The decoupled (`rows`) Kalman-filter identifier over a [`Store`]; see [`KalmanIdentifier`]
/// for the allocation-free form.
///
/// The row filters are kept side by side in lanes (the private `lanes` module): one update treats all
/// rows at once with vector instructions, and only the upper triangle of each `P` is stored.
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(
        remote = "Self",
        bound(
            serialize = "T: serde::Serialize, S::Group: serde::Serialize",
            deserialize = "T: crate::Real, S::Group: serde::Deserialize<'de>"
        )
    )
)]
pub struct KalmanRows<T: Real, const N: usize, S: Store<T, N>> {
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    rows: S::Rows,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    pub(super) groups: S::Groups,
    /// The planned step of the sample being processed, one per group (used when the plan
    /// does not stay in registers).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::transient"))]
    pub(super) scratch: S::Scratches,
    /// The same for the square-root form (empty in the other forms).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::transient"))]
    sqrt_scratch: S::SqrtScratches,
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
            s.set_filter(i, &f)?;
        }
        Ok(s)
    }

    /// Builds the identifier with an exact start (no prior): every row absorbs samples
    /// exactly until they identify all `N` parameters, and from then on each row's estimate
    /// is least squares on all samples so far ([`RowIdentifier::exact`]). `r` (one or one per
    /// row, > 0) is the variance the covariance is expressed in; it does not change the
    /// estimate.
    ///
    /// # Errors
    /// As [`KalmanRows::from_slices`]; `r` must be > 0.
    pub fn exact(rows: &[usize], r: &[T], opts: KalmanOptions<T>) -> Result<Self> {
        opts.validate()?;
        let rows_buf: S::Rows = rows_buffer::<_, N>(rows)?;
        let k = rows.len();
        let mut s = Self::empty(rows_buf, opts)?;
        for i in 0..k {
            s.set_filter(i, &RowIdentifier::exact(per_row("r", r, k, i)?)?)?;
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
            sqrt_scratch: S::SqrtScratches::filled(
                "unknown_rows",
                if opts.form == CovarianceForm::Sqrt { n_groups } else { 0 },
                S::Group::sqrt_scratch(),
            )?,
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

    /// Puts the filter of unknown row `i`, in the identifier's form and with its tracking.
    fn set_filter(&mut self, i: usize, f: &RowIdentifier<T, N>) -> Result<()> {
        let f = f.configured(self.opts.form, &self.opts)?;
        let zrow = self.rows.flat()[i];
        let (g, k) = self.group_mut(i);
        g.set_lane(k, zrow, &f);
        Ok(())
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
            s.set_filter(i, f)?;
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
        if self.starting() {
            return Err(Error::RankDeficient { rank: self.filter(0).start_rank(), needed: N });
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
            bytes: core::mem::size_of_val(self)
                + self.groups.heap_bytes()
                + self.scratch.heap_bytes()
                + self.sqrt_scratch.heap_bytes(),
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
    pub(crate) fn update_vec(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        let k = self.rows.flat().len();
        if e.len() != k {
            return Err(Error::Shape { arg: "e", expected: k, got: e.len() });
        }
        self.dispatch(x, z, e)
    }

    // AVX2 pays only when a group of lanes fills a 256-bit register (four f64 rows); narrower
    // groups are faster in the portable build, which fits them exactly.
    avx2_step!(<S::Group as RowGroup<T, N>>::LANES * core::mem::size_of::<T>() >= 32);

    /// The update: plan every group, then apply (a failure anywhere changes nothing).
    #[inline(always)]
    fn step(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        // The standard form without options (or with exponential forgetting only) first,
        // without the tests for the others.
        let mode = match self.groups.flat() {
            [g] => g.mode(),
            groups => {
                let first = groups.first().map_or(GENERAL, |g| g.mode());
                if groups.iter().all(|g| g.mode() == first) {
                    first
                } else {
                    GENERAL
                }
            }
        };
        match mode {
            PLAIN => return self.step_standard::<PLAIN>(x, z, e),
            FORGET => return self.step_standard::<FORGET>(x, z, e),
            _ => {}
        }
        if self.groups.flat().first().is_some_and(|g| g.starting()) {
            return self.absorb(x, z, e);
        }
        if self.opts.form == CovarianceForm::Sqrt {
            return self.step_sqrt(x, z, e);
        }
        self.step_standard::<GENERAL>(x, z, e)
    }

    /// [`Self::step`] in the standard or Joseph form (`MODE`: that of every group, or
    /// [`GENERAL`]).
    #[inline(always)]
    fn step_standard<const MODE: u8>(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        let k = e.len();
        let lanes = <S::Group as RowGroup<T, N>>::LANES;
        let probe = finite_probe(x, z);
        let mut ok = probe == T::zero();
        let groups = self.groups.flat_mut();
        // One group (every Fixed<K> store, and up to DYNAMIC_LANES rows) plans on the stack;
        // several groups plan into their scratch, all before any applies.
        if let [grp] = &mut *groups {
            let mut sc = S::Group::scratch();
            ok &= grp.plan::<MODE>(x, z, e, &mut sc);
            if !ok {
                // Not `check(&sc)` here: any reference to the plan would keep it in memory.
                return self.settle(x, z, e);
            }
            grp.apply::<MODE>(x, &sc);
            let gated = const { MODE == GENERAL } && self.opts.reinit && S::Group::gates(&sc);
            return self.accepted(e, gated);
        }
        let scratch = self.scratch.flat_mut();
        for (g, (grp, sc)) in groups.iter().zip(scratch.iter_mut()).enumerate() {
            let lo = g * lanes;
            let hi = (lo + lanes).min(k);
            ok &= grp.plan::<MODE>(x, z, &mut e[lo..hi], sc);
        }
        if !ok {
            return self.settle(x, z, e);
        }
        for (grp, sc) in groups.iter_mut().zip(scratch.iter()) {
            grp.apply::<MODE>(x, sc);
        }
        let gated = const { MODE == GENERAL } && self.opts.reinit && scratch.iter().any(S::Group::gates);
        self.accepted(e, gated)
    }

    /// A sample the fast path of [`Self::step`] did not accept at once (the standard and
    /// Joseph forms): plans it again; applies it when every group accepts it after a closer
    /// look (its risky downdates stay positive definite), else names the error.
    #[cold]
    #[inline(never)]
    fn settle(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        check_sample(x, z)?;
        let k = e.len();
        let lanes = <S::Group as RowGroup<T, N>>::LANES;
        let groups = self.groups.flat_mut();
        if let [grp] = &mut *groups {
            let mut sc = S::Group::scratch();
            grp.plan::<GENERAL>(x, z, e, &mut sc);
            if !grp.accepts(x, &sc) {
                grp.check(x, &sc)?;
                return Err(OVERFLOW);
            }
            grp.apply::<GENERAL>(x, &sc);
            let gated = self.opts.reinit && S::Group::gates(&sc);
            return self.accepted(e, gated);
        }
        let scratch = self.scratch.flat_mut();
        for (g, (grp, sc)) in groups.iter().zip(scratch.iter_mut()).enumerate() {
            let lo = g * lanes;
            let hi = (lo + lanes).min(k);
            grp.plan::<GENERAL>(x, z, &mut e[lo..hi], sc);
        }
        if !groups.iter().zip(scratch.iter()).all(|(grp, sc)| grp.accepts(x, sc)) {
            for (grp, sc) in groups.iter().zip(scratch.iter()) {
                grp.check(x, sc)?;
            }
            return Err(OVERFLOW);
        }
        for (grp, sc) in groups.iter_mut().zip(scratch.iter()) {
            grp.apply::<GENERAL>(x, sc);
        }
        let gated = self.opts.reinit && scratch.iter().any(S::Group::gates);
        self.accepted(e, gated)
    }

    /// [`Self::step`] for the square-root form (a separate path with its own scratch, inlined
    /// into both the portable and the AVX2 copy of the update).
    #[inline(always)]
    fn step_sqrt(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        let k = e.len();
        let lanes = <S::Group as RowGroup<T, N>>::LANES;
        let probe = finite_probe(x, z);
        let mut ok = probe == T::zero();
        let groups = self.groups.flat_mut();
        // One group (every Fixed<K> store, and up to DYNAMIC_LANES rows) plans on the stack;
        // several groups plan into their scratch, all before any applies.
        if let [grp] = &mut *groups {
            let mut sc = S::Group::sqrt_scratch();
            ok &= grp.plan_sqrt(x, z, e, &mut sc);
            if !ok {
                // Not `check_sqrt(&sc)` here: any reference to the plan would keep it in memory.
                return self.refused_sqrt(x, z, e);
            }
            grp.apply_sqrt(&sc);
            let gated = self.opts.reinit && S::Group::gates_sqrt(&sc);
            return self.accepted(e, gated);
        }
        let scratch = self.sqrt_scratch.flat_mut();
        for (g, (grp, sc)) in groups.iter().zip(scratch.iter_mut()).enumerate() {
            let lo = g * lanes;
            let hi = (lo + lanes).min(k);
            ok &= grp.plan_sqrt(x, z, &mut e[lo..hi], sc);
        }
        if !ok {
            return self.refused_sqrt(x, z, e);
        }
        for (grp, sc) in groups.iter_mut().zip(scratch.iter()) {
            grp.apply_sqrt(sc);
        }
        let gated = self.opts.reinit && scratch.iter().any(S::Group::gates_sqrt);
        self.accepted(e, gated)
    }

    /// The error of a sample the square-root form refused: plans it again and names the cause.
    #[cold]
    #[inline(never)]
    fn refused_sqrt(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        check_sample(x, z)?;
        let k = e.len();
        let lanes = <S::Group as RowGroup<T, N>>::LANES;
        // Every group in order, as before: the first one names the error.
        for (g, grp) in self.groups.flat().iter().enumerate() {
            let lo = g * lanes;
            let hi = (lo + lanes).min(k);
            let mut sc = S::Group::sqrt_scratch();
            grp.plan_sqrt(x, z, &mut e[lo..hi], &mut sc);
            grp.check_sqrt(&sc)?;
        }
        Err(OVERFLOW)
    }

    /// Exact start: the sample into every group's factorization (all or nothing).
    #[cold]
    #[inline(never)]
    fn absorb(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        check_sample(x, z)?;
        let lanes = <S::Group as RowGroup<T, N>>::LANES;
        let k = e.len();
        let mut next = self.groups.clone();
        for (g, grp) in next.flat_mut().iter_mut().enumerate() {
            let lo = g * lanes;
            let hi = (lo + lanes).min(k);
            grp.absorb(x, z, &mut e[lo..hi])?;
        }
        self.groups = next;
        self.samples += 1;
        Ok(())
    }

    /// `true` while the identifier absorbs its exact start (no estimate yet).
    pub fn starting(&self) -> bool {
        self.groups.flat().first().is_some_and(|g| g.starting())
    }

    /// Counts an applied sample and runs retirement and reinitialization if enabled
    /// (`gated`: the outlier gate left the sample out of a row).
    #[inline(always)]
    fn accepted(&mut self, e: &[T], gated: bool) -> Result<()> {
        self.samples += 1;
        if self.opts.reinit || self.opts.retire_below > T::zero() {
            self.after_step(e, gated);
        }
        Ok(())
    }

    /// Retirement and the reinitialization rule (Eq 4.36) after an accepted sample. A sample
    /// the gate left out of a row reinitializes nothing (an outlier is not a change of the
    /// dynamics), as in modes shared and full.
    fn after_step(&mut self, e: &[T], gated: bool) {
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
        if self.opts.reinit && !gated && T::of(10.0) * abs_e > trace {
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

impl<T: Real, const N: usize, const K: usize> KalmanRows<T, N, Fixed<K>> {
    /// One sample (measured state `x`, measured derivative `z`); returns the innovations
    /// `e_i = z_row − xᵀ θ̂_i(k−1)` of the unknown rows. No allocation.
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
