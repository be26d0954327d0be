//! The shared-covariance (`shared`) form.

use super::guards::overflow_culprit;
use super::guards::{positive_definite, risky, SCREEN_WARMUP};
use super::sums::{finite_probe, is_fin, lane_sum, tree_sum};
use super::{CovarianceForm, KalmanOptions};
use crate::error::{check_finite, check_positive};
#[cfg(feature = "alloc")]
use crate::identify::Dynamic;
use crate::identify::{
    check_lengths, check_sample, fixed_theta, per_row, rows_buffer, rows_into, vector, Cost, Dims, Fixed, Flat,
    Identifier, Store, OVERFLOW,
};
use crate::linalg::symmetrize;
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

mod identifier;
/// Shared-covariance Kalman identifier over a [`Store`] (`P_i = r_i Q`); see
/// [`SharedKalmanIdentifier`].
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct KalmanShared<T: Real, const N: usize, S: Store<T, N>> {
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    rows: S::Rows,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    theta: S::Vecs,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    r: S::Scalars,
    q: SMatrix<T, N, N>,
    opts: KalmanOptions<T>,
    reinit_count: u32,
    samples: u64,
    /// The outlier gate's statistics (kept only while [`KalmanOptions::gate`] is on): per row
    /// the sum of the squared recursive residuals `Σ w_i²`, `w_i² = e_i² r_i / s_i = e_i² / s`
    /// (`s = 1 + xᵀQx`, so `s_i = r_i s`), in the row's units²; the samples behind them
    /// (accepted and gated); and the samples gated (left out by every row).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    ssr: S::Scalars,
    nobs: T,
    gated: u64,
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
    /// As [`KalmanRows::from_slices`](super::KalmanRows::from_slices), plus [`Error::InvalidArgument`] when `r_i / p0_i`
    /// differs between rows (the shared form would then be a different filter; use `rows`),
    /// or when every `r_i` is zero (the common ratio must be > 0) and `retire_below` is set.
    pub fn from_slices(rows: &[usize], p0: &[T], r: &[T], opts: KalmanOptions<T>) -> Result<Self> {
        opts.validate()?;
        if opts.retire_below > T::zero() {
            return Err(Error::InvalidArgument { arg: "retire_below", expected: "0: retiring rows needs mode='rows'" });
        }
        if opts.form == CovarianceForm::Sqrt {
            return Err(Error::InvalidArgument {
                arg: "form",
                expected: "'standard' or 'joseph' for mode='shared' (the square-root form needs mode='rows')",
            });
        }
        if opts.huber > T::zero() {
            return Err(Error::InvalidArgument {
                arg: "huber",
                expected: "0 for mode='shared' (Huber weighting needs mode='rows'; the outlier gate works here)",
            });
        }
        if opts.tracking() {
            return Err(Error::InvalidArgument {
                arg: "forgetting",
                expected: "no forgetting or drift for mode='shared' (tracking needs mode='rows')",
            });
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
        let ssr = S::Scalars::filled("unknown_rows", k, T::zero())?;
        Ok(Self {
            rows: rows_buf,
            theta,
            r: rv,
            q: SMatrix::identity() / c,
            opts,
            reinit_count: 0,
            samples: 0,
            ssr,
            nobs: T::zero(),
            gated: 0,
        })
    }

    /// Sets the prior mean `θ̂(0)` (`K·N` values, row-major); before the first sample.
    ///
    /// # Errors
    /// [`Error::Shape`] for a wrong length, [`Error::NonFinite`] for NaN/inf.
    pub fn set_theta(&mut self, theta0: &[T]) -> Result<()> {
        let k = self.rows.flat().len();
        if theta0.len() != k * N {
            return Err(Error::Shape { arg: "theta0", expected: k * N, got: theta0.len() });
        }
        check_finite("theta0", theta0)?;
        for (t, chunk) in self.theta.flat_mut().iter_mut().zip(theta0.chunks_exact(N)) {
            *t = SVector::from_column_slice(chunk);
        }
        Ok(())
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

    /// Number of samples accepted (those the outlier gate left out included, as in mode
    /// `rows`).
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Samples left out by the outlier gate ([`KalmanOptions::gate`]; every row leaves a gated
    /// sample out, since the rows share one covariance).
    pub fn gated(&self) -> u64 {
        self.gated
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
    /// As [`KalmanRows::update_into`]; [`Error::Singular`] for a sample informative far beyond
    /// its noise (`1/s < √ε`) whose downdate would leave `Q` indefinite. A sample the outlier
    /// gate leaves out is not an error (it is counted, [`KalmanShared::gated`]).
    pub(crate) fn update_vec(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
        let k = self.rows.flat().len();
        if e.len() != k {
            return Err(Error::Shape { arg: "e", expected: k, got: e.len() });
        }
        self.dispatch(x, z, e)
    }

    // AVX2 pays for the half car in f64 (two 256-bit registers per column); for the quarter
    // car the portable build is faster (measured: 18.8 against 20.5 ns).
    avx2_step!(N * core::mem::size_of::<T>() > 32);

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
        let theta = self.theta.flat();
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
        // Non-short-circuit: one branch on the fast path.
        let rare = !ok | (self.opts.gate > T::zero()) | (T::one() < risky::<T>() * s);
        if rare {
            // The rare paths (and every sample while the gate is on): errors, the gate, a
            // downdate that could lose positive definiteness. Nothing has changed yet. A tail
            // call, so that nothing on the fast path below lives across it.
            return self.screened_step(x, z, e, s, step, qx, g, abs_e);
        }
        // (The gate is off here: a gate on takes the rare path.)
        self.apply::<false>(x, e, qx, g, s, abs_e);
        Ok(())
    }

    /// [`Self::step`]'s rare path: screens the sample, then applies it unless it is refused
    /// or gated.
    #[cold]
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    fn screened_step(
        &mut self,
        x: &SVector<T, N>,
        z: &SVector<T, N>,
        e: &mut [T],
        s: T,
        step: T,
        qx: [T; N],
        g: [T; N],
        abs_e: T,
    ) -> Result<()> {
        match self.screen_sample(x, z, e, s, step, qx, g)? {
            // Taken and counted like any sample (as in mode rows), but not used; no
            // reinitialization on an outlier.
            Screened::Gated => {
                self.samples += 1;
                Ok(())
            }
            Screened::Accepted => {
                if self.opts.gate > T::zero() {
                    self.apply::<true>(x, e, qx, g, s, abs_e);
                } else {
                    self.apply::<false>(x, e, qx, g, s, abs_e);
                }
                Ok(())
            }
        }
    }

    /// Applies an accepted sample: `θ += g e`, the covariance downdate, the gate's statistics
    /// (`GATE`: the gate is on), the count, reinitialization.
    #[inline(always)]
    fn apply<const GATE: bool>(&mut self, x: &SVector<T, N>, e: &[T], qx: [T; N], g: [T; N], s: T, abs_e: T) {
        for (th, &ei) in self.theta.flat_mut().iter_mut().zip(e.iter()) {
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
            CovarianceForm::Joseph => self.q = self.joseph(x, g),
            // Refused by the constructor.
            CovarianceForm::Sqrt => {}
        }
        if GATE {
            self.record(e, s);
        }
        self.samples += 1;
        if self.opts.reinit && T::of(10.0) * abs_e > self.trace() {
            self.reinitialize();
        }
    }

    /// Joseph's form for the shared covariance: `Q ← (I − g xᵀ) Q (I − g xᵀ)ᵀ + g gᵀ`.
    #[inline(never)]
    fn joseph(&self, x: &SVector<T, N>, g: [T; N]) -> SMatrix<T, N, N> {
        let g = SVector::<T, N>::from_column_slice(&g);
        let a = SMatrix::<T, N, N>::identity() - g * x.transpose();
        let mut q = a * self.q * a.transpose() + g * g.transpose();
        symmetrize(&mut q);
        q
    }

    /// `Q` after the measurement update with `Q x` and gain `g = Q x / s` (the arithmetic of
    /// [`Self::step`]: the standard downdate from the upper triangle, or Joseph's form).
    fn downdated(&self, x: &SVector<T, N>, qx: [T; N], g: [T; N]) -> SMatrix<T, N, N> {
        if self.opts.form == CovarianceForm::Joseph {
            return self.joseph(x, g);
        }
        let mut q = self.q;
        for b in 0..N {
            for a in 0..N {
                let v = if a <= b { qx[a] * g[b] } else { qx[b] * g[a] };
                q[(a, b)] -= v;
            }
        }
        q
    }

    /// The checks of a sample that is not plainly acceptable (`ok` false), or of every sample
    /// while the outlier gate is on, or of one whose downdate is risky (`1/s` below `√ε`):
    /// the error it is rejected with; else whether the gate leaves it out (then counted, its
    /// residuals entering the gate's scale Winsorized at the gate) or it is accepted. The
    /// risky downdate must leave `Q` positive definite (checked by Cholesky), else the sample
    /// is refused ([`super::guards::LOST_DEFINITENESS_JOINT`]). Changes nothing unless gated.
    ///
    /// # Errors
    /// [`Error::NonFinite`], an overflow error naming `r_k` or `z_k`, [`Error::Singular`].
    #[cold]
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    fn screen_sample(
        &mut self,
        x: &SVector<T, N>,
        z: &SVector<T, N>,
        e: &[T],
        s: T,
        step: T,
        qx: [T; N],
        g: [T; N],
    ) -> Result<Screened> {
        check_sample(x, z)?;
        if !s.finite() {
            return Err(OVERFLOW);
        }
        if !(s > T::zero()) {
            return Err(Error::Singular {
                what: "the shared covariance (1 + xᵀQx ≤ 0: Q lost positive definiteness: reset_covariance(p0) \
                       restarts the identifier from its estimate; mode='rows' with form='sqrt' cannot lose it)",
            });
        }
        if self.gate_out(e, s) {
            return Ok(Screened::Gated);
        }
        if !is_fin(step) {
            // The largest innovation decides which argument overflowed.
            let (i, _) =
                e.iter().enumerate().fold((0, T::zero()), |b, (i, v)| if !(v.abs() <= b.1) { (i, v.abs()) } else { b });
            let xth = self.theta.flat()[i].dot(x);
            return Err(overflow_culprit(e[i], xth));
        }
        if T::one() < risky::<T>() * s && !positive_definite(&self.downdated(x, qx, g), N) {
            return Err(super::guards::LOST_DEFINITENESS_JOINT);
        }
        Ok(Screened::Accepted)
    }

    /// The outlier gate ([`KalmanOptions::gate`] `κ`) for mode `shared`: once `N + 50` samples
    /// are behind the scale, a sample is left out when any row's recursive residual
    /// `w_i = e_i / √s` exceeds `κ σ̂_i` (`σ̂_i² = Σ w_i² / (n − N)`), as in mode `rows`; the
    /// rows share one covariance, so every row leaves it out. Then counts it and lets it
    /// inform the scale: each row's `w_i²` enters Winsorized at `κ² σ̂_i²` (see
    /// [`super::guards::gated_scale`]). `true` when gated.
    fn gate_out(&mut self, e: &[T], s: T) -> bool {
        let gate = self.opts.gate;
        let params = T::of(N as f64);
        if !(gate > T::zero()) || self.nobs < params + T::of(SCREEN_WARMUP) {
            return false;
        }
        let n = self.nobs - params;
        let out = self.ssr.flat().iter().zip(e).any(|(&ssr, &ei)| {
            let sigma2 = ssr / n;
            sigma2 > T::zero() && !(ei * ei / s <= gate * gate * sigma2)
        });
        if out {
            for (ssr, &ei) in self.ssr.flat_mut().iter_mut().zip(e) {
                let cap = gate * gate * *ssr / n;
                let w2 = ei * ei / s;
                *ssr += if w2 <= cap { w2 } else { cap };
            }
            self.nobs += T::one();
            self.gated += 1;
        }
        out
    }

    /// The gate's statistics after an accepted sample: `Σ w_i² += e_i² / s`, one more sample.
    fn record(&mut self, e: &[T], s: T) {
        for (ssr, &ei) in self.ssr.flat_mut().iter_mut().zip(e) {
            *ssr += ei * ei / s;
        }
        self.nobs += T::one();
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

/// What the rare-path checks of a sample decided ([`KalmanShared::screen_sample`]).
enum Screened {
    /// Left out by the outlier gate (counted; nothing else changes).
    Gated,
    /// To be applied.
    Accepted,
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

impl<T: Real, const N: usize, const K: usize> KalmanShared<T, N, Fixed<K>> {
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
