//! Batch least squares (Eq 2.14, 3.4): `θ̂_i = (Xᵀ X)⁻¹ Xᵀ z_i` for each unknown row `i`,
//! with `X` the stacked measured states `r(k)ᵀ`.
//!
//! - [`BatchLeastSquares`] (std) stores every sample and solves with a column-pivoted QR
//!   factorization of `X` (faer): no squaring of the condition number, and a rank check
//!   that turns missing excitation into [`Error::RankDeficient`] instead of a NaN.
//!   Memory grows with the data (the thesis' objection: about 1 MB for its runs).
//! - [`LsAccumulator`] keeps only `Σ x xᵀ` and `Σ x z_i` (memory-bounded, no allocation) and
//!   solves the normal equations by Cholesky when asked.
//!
//! Unbiased when the state is measured without noise; biased (attenuated) by state noise
//! (Eq 2.20), which the thesis shows is devastating (Fig 3-5).

use super::{check_lengths, check_sample, rows_buffer, vector, Cost, Dims, Fixed, Flat, Identifier, Store};
use crate::linalg::{cholesky_in_place, cholesky_solve};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

/// Running normal equations `Σ x xᵀ`, `Σ x z_i` for the unknown rows; no allocation.
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct LsAccumulator<T: Real, const N: usize, S: Store<T, N> = Fixed<1>> {
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    rows: S::Rows,
    gram: SMatrix<T, N, N>,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    xz: S::Vecs,
    samples: u64,
}

impl<T: Real, const N: usize, S: Store<T, N>> LsAccumulator<T, N, S> {
    /// An empty accumulator for the given 0-based unknown rows.
    ///
    /// # Errors
    /// [`Error::BadRow`] / [`Error::Shape`] for bad rows.
    pub fn from_rows(rows: &[usize]) -> Result<Self> {
        let rows_buf: S::Rows = rows_buffer::<_, N>(rows)?;
        Ok(Self {
            rows: rows_buf,
            gram: SMatrix::zeros(),
            xz: S::Vecs::filled("unknown_rows", rows.len(), SVector::zeros())?,
            samples: 0,
        })
    }

    /// Adds one sample (measured state `x`, measured derivative `z`). No allocation.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf (the accumulator is then unchanged).
    pub fn push(&mut self, x: &SVector<T, N>, z: &SVector<T, N>) -> Result<()> {
        check_sample(x, z)?;
        let rows = self.rows.flat();
        let xz = self.xz.flat_mut();
        for (acc, &r) in xz.iter_mut().zip(rows) {
            *acc += x * z[r];
        }
        self.gram += x * x.transpose();
        self.samples += 1;
        Ok(())
    }

    /// Number of samples accumulated.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Arithmetic per accumulated sample (`x xᵀ`: N² mul and add; `x z_i`: K N mul and add)
    /// and size. The solve (a Cholesky factorization, once) is not included.
    pub fn cost(&self) -> Cost {
        let k = self.rows.flat().len();
        Cost {
            multiplications: N * N + k * N,
            additions: N * N + k * N,
            divisions: 0,
            square_roots: 0,
            bytes: core::mem::size_of_val(self) + self.xz.heap_bytes(),
        }
    }

    /// The unknown rows (0-based).
    pub fn rows(&self) -> &[usize] {
        self.rows.flat()
    }

    /// Solves the normal equations; θ̂ row-major (`K × N`) into `out`.
    ///
    /// # Errors
    /// [`Error::RankDeficient`] when `Σ x xᵀ` is numerically singular (pivot below
    /// `N·ε` times the largest diagonal); [`Error::Shape`] for a wrong `out` length.
    pub fn solve_into(&self, out: &mut [T]) -> Result<()> {
        let k = self.rows.flat().len();
        if out.len() != k * N {
            return Err(Error::Shape { arg: "out", expected: k * N, got: out.len() });
        }
        let g = self.gram.map(|v| v.to_f64());
        let scale = (0..N).fold(0.0f64, |m, i| m.max(g[(i, i)]));
        let mut l = g;
        let ok = scale > 0.0 && cholesky_in_place(l.as_mut_slice(), N);
        // Pivots of the factor below the threshold mean a direction without excitation.
        let tol = (N as f64) * f64::EPSILON * scale;
        let rank = if ok { (0..N).filter(|&i| l[(i, i)] * l[(i, i)] > tol).count() } else { 0 };
        if !ok || rank < N {
            return Err(Error::RankDeficient { rank: rank.min(N - 1), needed: N });
        }
        // nalgebra is column-major: the in-place factor is used consistently as its transpose,
        // which for a symmetric matrix is the same factorization.
        for (i, xz) in self.xz.flat().iter().enumerate() {
            let mut b: [f64; N] = core::array::from_fn(|j| xz[j].to_f64());
            cholesky_solve(l.as_slice(), N, &mut b);
            for j in 0..N {
                out[i * N + j] = T::of(b[j]);
            }
        }
        Ok(())
    }
}

#[cfg(feature = "serde")]
impl<T: Real, const N: usize, S: Store<T, N>> LsAccumulator<T, N, S> {
    /// Checks a deserialized accumulator: valid rows, one `Σ x z_i` per row.
    pub(crate) fn restored(&mut self) -> Result<()> {
        let k = crate::model::RowSet::<N>::new(self.rows.flat())?.len();
        if self.xz.flat().len() != k {
            return Err(Error::Shape { arg: "xz", expected: k, got: self.xz.flat().len() });
        }
        Ok(())
    }
}

impl<T: Real, const N: usize, const K: usize> LsAccumulator<T, N, Fixed<K>> {
    /// An empty accumulator for `K` unknown rows.
    ///
    /// # Errors
    /// As [`LsAccumulator::from_rows`].
    pub fn new(rows: [usize; K]) -> Result<Self> {
        Self::from_rows(&rows)
    }

    /// Solves the normal equations (`K × N`).
    ///
    /// # Errors
    /// As [`LsAccumulator::solve_into`].
    pub fn solve(&self) -> Result<SMatrix<T, K, N>> {
        let mut out = SMatrix::<T, N, K>::zeros();
        self.solve_into(out.as_mut_slice())?;
        Ok(out.transpose())
    }
}

/// Batch least squares over stored samples, solved by column-pivoted QR (faer); requires
/// `std`. Works for any number of unknown rows (run-time sized).
///
/// # Examples
/// ```
/// use vehid_core::identify::BatchLeastSquares;
/// use vehid_core::model::QuarterCar;
/// use vehid_core::sim::{SimConfig, Simulator};
/// let car = QuarterCar::<f64>::thesis();
/// let mut sim = Simulator::new(car.model(), SimConfig::new(0.05).ic_sigma(0.1), 3)?;
/// let mut ls = BatchLeastSquares::<f64, 4>::new(&car.unknown_rows())?;
/// for _ in 0..4 {
///     let s = sim.next_sample();
///     ls.push(&s.r, &s.z)?;
/// }
/// let theta = ls.solve()?;   // 2 × 4, row-major: exact from n = 4 noise-free samples (Eq 2.8)
/// assert!((theta[0] - car.theta()[(0, 0)]).abs() < 1e-8 * 140.0);
/// # Ok::<(), vehid_core::Error>(())
/// ```
#[cfg(feature = "std")]
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct BatchLeastSquares<T: Real, const N: usize> {
    rows: std::vec::Vec<usize>,
    /// Stored measured states, row-major (`samples × N`).
    x: std::vec::Vec<T>,
    /// Stored derivative measurements of the unknown rows (`samples × K`).
    z: std::vec::Vec<T>,
}

#[cfg(feature = "std")]
impl<T: Real, const N: usize> BatchLeastSquares<T, N> {
    /// An empty batch for the given 0-based unknown rows.
    ///
    /// # Errors
    /// [`Error::BadRow`] / [`Error::InvalidArgument`] for bad rows.
    pub fn new(rows: &[usize]) -> Result<Self> {
        let rows: std::vec::Vec<usize> = rows_buffer::<_, N>(rows)?;
        Ok(Self { rows, x: std::vec::Vec::new(), z: std::vec::Vec::new() })
    }

    /// The unknown rows (0-based).
    pub fn rows(&self) -> &[usize] {
        &self.rows
    }

    /// Number of stored samples.
    pub fn samples(&self) -> usize {
        self.x.len() / N.max(1)
    }

    /// Bytes of sample storage in use (the thesis' objection to batch least squares).
    pub fn storage_bytes(&self) -> usize {
        (self.x.capacity() + self.z.capacity()) * core::mem::size_of::<T>()
    }

    /// Stores one sample.
    ///
    /// # Errors
    /// [`Error::NonFinite`] for NaN/inf (nothing is stored then).
    pub fn push(&mut self, x: &SVector<T, N>, z: &SVector<T, N>) -> Result<()> {
        check_sample(x, z)?;
        self.x.extend_from_slice(x.as_slice());
        self.z.extend(self.rows.iter().map(|&r| z[r]));
        Ok(())
    }

    /// Stores many samples at once: `x` and `z` row-major (`len × N`).
    ///
    /// # Errors
    /// [`Error::Shape`] when the lengths disagree; [`Error::NonFinite`] naming the first bad
    /// value (nothing is stored then).
    pub fn extend(&mut self, x: &[T], z: &[T]) -> Result<()> {
        if x.len() % N != 0 || x.len() != z.len() {
            return Err(Error::Shape { arg: "z", expected: x.len(), got: z.len() });
        }
        crate::error::check_finite("r", x)?;
        crate::error::check_finite("z", z)?;
        self.x.extend_from_slice(x);
        for sample in z.chunks_exact(N) {
            self.z.extend(self.rows.iter().map(|&r| sample[r]));
        }
        Ok(())
    }

    /// Solves Eq 2.14 by column-pivoted QR; θ̂ row-major (`K × N`).
    ///
    /// # Errors
    /// [`Error::RankDeficient`] when the stored states do not span all `N` directions
    /// (fewer than `N` samples, or an unexcited direction): the diagonal of `R` falls below
    /// `max(L, N)·ε·|R₀₀|`. [`Error::Dominated`] naming a sample more than `1e6` times the
    /// median state norm that makes the rank look deficient or, at full rank, decides a
    /// direction alone (leverage above 1/2): an outlier that would bend the estimate.
    pub fn solve(&self) -> Result<std::vec::Vec<T>> {
        use faer::linalg::solvers::SolveLstsq;
        let (l, k) = (self.samples(), self.rows.len());
        let qr = self.checked_qr()?;
        let zm = faer::Mat::<f64>::from_fn(l, k, |i, j| self.z[i * k + j].to_f64());
        let sol = qr.solve_lstsq(&zm);
        let mut out = std::vec![T::zero(); k * N];
        for i in 0..k {
            for j in 0..N {
                let v = sol[(j, i)];
                if !v.is_finite() {
                    return Err(Error::RankDeficient { rank: N - 1, needed: N });
                }
                out[i * N + j] = T::of(v);
            }
        }
        Ok(out)
    }

    /// The column-pivoted QR factorization `X Π = Q R` of the stored states, once the checks
    /// of [`Self::solve`] (its errors) have passed.
    fn checked_qr(&self) -> Result<faer::linalg::solvers::ColPivQr<f64>> {
        let l = self.samples();
        if l < N {
            return Err(Error::RankDeficient { rank: l, needed: N });
        }
        let xm = faer::Mat::<f64>::from_fn(l, N, |i, j| self.x[i * N + j].to_f64());
        let qr = xm.col_piv_qr();
        let r = qr.R();
        let r00 = r[(0, 0)].abs();
        let tol = (l.max(N) as f64) * f64::EPSILON * r00;
        let rank = (0..N).filter(|&i| r[(i, i)].abs() > tol).count();
        if r00 == 0.0 || rank < N {
            // One sample far larger than the rest makes the others look like rounding: say
            // which, rather than "not enough excitation" (more samples would not help).
            if let Some(sample) = self.dominating_sample() {
                return Err(Error::Dominated { sample });
            }
            return Err(Error::RankDeficient { rank, needed: N });
        }
        // Full rank, but one sample may still dominate: far larger than the rest and alone
        // deciding a direction (leverage above 1/2), it bends the estimate with no error to
        // show for it. Named, as above (remove() drops it).
        if let Some(sample) = self.dominating(true).filter(|&i| self.leverage(i) > 0.5) {
            return Err(Error::Dominated { sample });
        }
        Ok(qr)
    }

    /// The leverage `h_i = x_iᵀ (XᵀX)⁻¹ x_i ∈ [0, 1]` of stored sample `i` (the share of its
    /// own fitted value that it decides; the leverages of `n` samples sum to `N`), computed as
    /// `a / (1 + a)` with `a = x_iᵀ G₋ᵢ⁻¹ x_i`, `G₋ᵢ` the Gram matrix of the other samples (so
    /// that a sample far larger than the rest does not swamp the others in `XᵀX`); 1 when the
    /// others leave a direction unexcited (`G₋ᵢ` numerically singular) or `i` is out of range.
    /// Meant for the largest sample (the one [`Self::dominating_sample`] names): for another,
    /// `G₋ᵢ` holds that one and may be too ill-conditioned to factor (then 1).
    pub(crate) fn leverage(&self, i: usize) -> f64 {
        let Some(xi) = self.x.chunks_exact(N.max(1)).nth(i) else { return 1.0 };
        let xi = SVector::<f64, N>::from_fn(|j, _| xi[j].to_f64());
        let mut g = SMatrix::<f64, N, N>::zeros();
        for (k, x) in self.x.chunks_exact(N.max(1)).enumerate() {
            if k != i {
                let v = SVector::<f64, N>::from_fn(|j, _| x[j].to_f64());
                g += v * v.transpose();
            }
        }
        let Some(chol) = g.cholesky() else { return 1.0 };
        let a = xi.dot(&chol.solve(&xi));
        if !(a.is_finite() && a >= 0.0) {
            return 1.0;
        }
        a / (1.0 + a)
    }

    /// The stored sample whose state is more than `1e6` times the median state norm, if one
    /// is (the largest): an outlier that dominates the regression.
    pub fn dominating_sample(&self) -> Option<usize> {
        self.dominating(false)
    }

    /// [`Self::dominating_sample`]; with `typical`, only when the median norm is > 0 (most
    /// samples excited: a sample among mostly zero ones is not an outlier for being larger).
    fn dominating(&self, typical: bool) -> Option<usize> {
        let norms: std::vec::Vec<f64> = self
            .x
            .chunks_exact(N.max(1))
            .map(|row| row.iter().map(|v| v.to_f64() * v.to_f64()).sum::<f64>().sqrt())
            .collect();
        if norms.is_empty() {
            return None;
        }
        let mut sorted = norms.clone();
        let mid = sorted.len() / 2;
        let median = *sorted.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1;
        let (i, max) = norms.iter().enumerate().fold((0, 0.0f64), |b, (i, v)| if *v > b.1 { (i, *v) } else { b });
        (max > 1e6 * median && (median > 0.0 || !typical)).then_some(i)
    }

    /// Removes stored sample `index` (0-based, in the order stored), e.g. an outlier that
    /// [`Error::Dominated`] named.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] (argument `index`) when there is no such sample.
    pub fn remove(&mut self, index: usize) -> Result<()> {
        if index >= self.samples() {
            return Err(Error::InvalidArgument { arg: "index", expected: "the index of a stored sample (0-based)" });
        }
        let k = self.rows.len();
        self.x.drain(index * N..(index + 1) * N);
        self.z.drain(index * k..(index + 1) * k);
        Ok(())
    }

    /// Drops the stored samples (keeps the rows).
    pub fn clear(&mut self) {
        self.x.clear();
        self.z.clear();
    }

    /// Checks a deserialized batch: valid rows, whole samples (`N` states, one derivative per
    /// row each).
    #[cfg(feature = "serde")]
    pub(crate) fn restored(&mut self) -> Result<()> {
        let k = crate::model::RowSet::<N>::new(&self.rows)?.len();
        if self.x.len() % N != 0 {
            return Err(Error::Shape { arg: "x", expected: self.x.len().div_ceil(N) * N, got: self.x.len() });
        }
        if self.z.len() != self.samples() * k {
            return Err(Error::Shape { arg: "z", expected: self.samples() * k, got: self.z.len() });
        }
        Ok(())
    }
}

super::persist_by_serde!([T: Real, const N: usize, S: Store<T, N>] LsAccumulator<T, N, S>);

impl<T: Real, const N: usize, S: Store<T, N>> Identifier<T> for LsAccumulator<T, N, S> {
    fn dims(&self) -> Dims {
        let k = self.rows.flat().len();
        Dims { states: N, inputs: 0, equations: k, params: k * N }
    }

    fn rows(&self) -> &[usize] {
        self.rows.flat()
    }

    /// Accumulates the sample. A batch estimator has no running estimate to predict with,
    /// so the innovations are NaN.
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        check_lengths(self.dims(), x, z, u, e)?;
        self.push(&vector(x), &vector(z))?;
        e.fill(T::of(f64::NAN));
        Ok(())
    }

    /// Solves the normal equations ([`LsAccumulator::solve_into`]).
    fn params_into(&self, out: &mut [T]) -> Result<()> {
        self.solve_into(out)
    }

    fn samples(&self) -> u64 {
        self.samples
    }
}

#[cfg(feature = "std")]
super::persist_by_serde!([T: Real, const N: usize] BatchLeastSquares<T, N>);

#[cfg(feature = "std")]
impl<T: Real, const N: usize> Identifier<T> for BatchLeastSquares<T, N> {
    fn dims(&self) -> Dims {
        let k = self.rows.len();
        Dims { states: N, inputs: 0, equations: k, params: k * N }
    }

    fn rows(&self) -> &[usize] {
        &self.rows
    }

    /// Stores the sample. A batch estimator has no running estimate to predict with, so the
    /// innovations are NaN.
    fn update_into(&mut self, x: &[T], z: &[T], u: &[T], e: &mut [T]) -> Result<()> {
        check_lengths(self.dims(), x, z, u, e)?;
        self.push(&vector(x), &vector(z))?;
        e.fill(T::of(f64::NAN));
        Ok(())
    }

    /// Solves Eq 2.14 by QR ([`BatchLeastSquares::solve`]) over every stored sample.
    fn params_into(&self, out: &mut [T]) -> Result<()> {
        let k = self.rows.len();
        if out.len() != k * N {
            return Err(Error::Shape { arg: "out", expected: k * N, got: out.len() });
        }
        out.copy_from_slice(&self.solve()?);
        Ok(())
    }

    fn samples(&self) -> u64 {
        BatchLeastSquares::samples(self) as u64
    }

    /// The residual sum of squares of each row's least-squares fit, and the sample count.
    fn residuals_into(&self, ssr: &mut [T], nobs: &mut [T]) -> Result<()> {
        let k = self.rows.len();
        if ssr.len() != k || nobs.len() != k {
            return Err(Error::Shape { arg: "ssr", expected: k, got: ssr.len().min(nobs.len()) });
        }
        let theta = self.solve()?;
        let mut acc = std::vec![0.0f64; k];
        for (x, z) in self.x.chunks_exact(N).zip(self.z.chunks_exact(k.max(1))) {
            for i in 0..k {
                let pred: f64 = (0..N).map(|j| x[j].to_f64() * theta[i * N + j].to_f64()).sum();
                let e = z[i].to_f64() - pred;
                acc[i] += e * e;
            }
        }
        for i in 0..k {
            ssr[i] = T::of(acc[i]);
            nobs[i] = T::of(self.samples() as f64);
        }
        Ok(())
    }

    /// `(XᵀX)⁻¹` on each row's block (the same for every row): the covariance of the estimate
    /// for unit noise variance ([`Identifier::noise_into`] gives 1). From the factorization
    /// that solves (`X Π = Q R`): `(XᵀX)⁻¹ = Π R⁻¹ R⁻ᵀ Πᵀ`, without forming `XᵀX` (whose
    /// condition number is that of `X` squared), so it exists whenever the states give an
    /// estimate. Errors as [`BatchLeastSquares::solve`]'s on the states, and
    /// [`Error::InvalidArgument`] naming `r` when states so small (all below about `1e-154`)
    /// make `(XᵀX)⁻¹` overflow.
    fn covariance_into(&self, out: &mut [T]) -> Result<()> {
        let k = self.rows.len();
        let kn = k * N;
        if out.len() != kn * kn {
            return Err(Error::Shape { arg: "out", expected: kn * kn, got: out.len() });
        }
        let qr = self.checked_qr()?;
        type Square<const M: usize> = nalgebra::SMatrix<f64, M, M>;
        let r = Square::<N>::from_fn(|a, b| qr.R()[(a, b)]);
        // W = R⁻¹ (the checks keep R's diagonal away from 0).
        let w: Square<N> = r.solve_upper_triangular(&Square::<N>::identity()).unwrap_or(Square::<N>::repeat(f64::NAN));
        let cov = w * w.transpose(); // (Πᵀ XᵀX Π)⁻¹, in pivoted order
        if !cov.iter().all(|v| v.is_finite()) {
            return Err(Error::InvalidArgument {
                arg: "r",
                expected: "states large enough that (XᵀX)⁻¹ stays finite (rescale the units)",
            });
        }
        let (order, _) = qr.P().arrays(); // column a of X Π is column order[a] of X
        out.fill(T::zero());
        for i in 0..k {
            for a in 0..N {
                for b in 0..N {
                    out[(i * N + order[a]) * kn + i * N + order[b]] = T::of(cov[(a, b)]);
                }
            }
        }
        Ok(())
    }

    /// Unit variances: [`Identifier::covariance_into`] is `(XᵀX)⁻¹`.
    fn noise_into(&self, out: &mut [T]) -> Result<()> {
        crate::identify::checks::diagonal_into(out, self.rows.len(), |_| T::one())
    }

    /// Stores every sample; rolls back by truncating the stored samples (no copy of them).
    fn fit<F>(&mut self, data: &super::Samples<'_, T>, mut each: F) -> core::result::Result<(), super::FitError>
    where
        Self: Sized + Clone,
        F: FnMut(usize, &Self, &[T]) -> core::ops::ControlFlow<Error>,
    {
        use core::ops::ControlFlow;
        let dims = self.dims();
        data.check(dims).map_err(|error| super::FitError { sample: None, error })?;
        let (xl, zl) = (self.x.len(), self.z.len());
        let k = self.rows.len();
        let need = data.len().saturating_mul(N + k);
        if self.x.try_reserve(data.len().saturating_mul(N)).is_err()
            || self.z.try_reserve(data.len().saturating_mul(k)).is_err()
        {
            return Err(super::FitError {
                sample: None,
                error: Error::OutOfMemory {
                    what: "the stored samples of batch least squares",
                    bytes: need.saturating_mul(core::mem::size_of::<T>()),
                },
            });
        }
        let nan = std::vec![T::of(f64::NAN); k];
        for (i, (x, z, u)) in data.iter().enumerate() {
            let step = match check_lengths(Dims { equations: 0, ..dims }, x, z, u, &[])
                .and_then(|()| self.push(&vector(x), &vector(z)))
            {
                Ok(()) => each(i, self, &nan),
                Err(err) => ControlFlow::Break(err),
            };
            if let ControlFlow::Break(error) = step {
                self.x.truncate(xl);
                self.z.truncate(zl);
                return Err(super::FitError { sample: Some(i), error });
            }
        }
        Ok(())
    }
}
