//! The stacked (`full`) form with a general `R`.

use super::guards::overflow_culprit;
use super::guards::{risky, LOST_DEFINITENESS_JOINT, SCREEN_WARMUP};
use super::{CovarianceForm, KalmanOptions};
use crate::error::{check_finite, check_nonneg, check_positive};
#[cfg(feature = "alloc")]
use crate::identify::Dynamic;
use crate::identify::{
    check_lengths, check_sample, fixed_theta, per_row, rows_buffer, rows_into, vector, Cost, Dims, Fixed, Flat,
    Identifier, Store, OVERFLOW,
};
use crate::linalg::{cholesky_in_place, cholesky_solve, symmetrize};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

mod blocks;
mod identifier;

use blocks::{blocks_positive_definite, culprit, downdate_blocks, gate_out};
/// The stacked (`full`) Kalman identifier over a [`Store`], general `R`; see
/// [`FullKalmanIdentifier`].
#[derive(Debug, Clone)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(remote = "Self", bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct KalmanFull<T: Real, const N: usize, S: Store<T, N>> {
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    rows: S::Rows,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    theta: S::Vecs,
    /// Covariance blocks `P_ij` (`K × K` of `N × N`, row-major).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    p: S::Blocks,
    /// Measurement covariance `R` (`K × K`, row-major).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    r: S::PairScalars,
    /// Scratch: `c_ij = P_ij x`.
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    c: S::PairVecs,
    /// Scratch: gain columns `w_il` (block `i`, column `l`).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    w: S::PairVecs,
    /// Scratch: Cholesky factor of `S`.
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    s: S::PairScalars,
    /// Scratch: the covariance after a risky sample, factored to check that it stays
    /// positive definite (`K × K` blocks; used only then).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    pn: S::Blocks,
    opts: KalmanOptions<T>,
    reinit_count: u32,
    samples: u64,
    /// The outlier gate's statistics (kept only while [`KalmanOptions::gate`] is on): per row
    /// `Σ w_i²` with `w_i² = e_i² R_ii / S_ii` (the row's recursive residual, as in mode `rows`;
    /// the same when `R` is diagonal), in the row's units²; the samples behind them (accepted
    /// and gated); and the samples gated (left out by every row).
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::flat"))]
    ssr: S::Scalars,
    nobs: T,
    gated: u64,
}

/// The stacked Kalman identifier of Eq 4.3–4.7 with a general `K × K` measurement
/// covariance `R`, no allocation. Its covariance is `(K·N) × (K·N)`, kept as blocks.
pub type FullKalmanIdentifier<T, const N: usize, const K: usize> = KalmanFull<T, N, Fixed<K>>;

/// [`KalmanFull`] with heap storage.
#[cfg(feature = "alloc")]
pub type FullKalmanIdentifierVec<T, const N: usize> = KalmanFull<T, N, Dynamic>;

impl<T: Real, const N: usize, S: Store<T, N>> KalmanFull<T, N, S> {
    /// Builds the stacked filter: `P(0)` block diagonal with `p0_i I` (`p0`: one value or
    /// one per row) and `R` a symmetric positive semi-definite `K × K` matrix: the whole
    /// matrix (row-major, `K²` values), or its diagonal (one value per row, or one value).
    ///
    /// # Errors
    /// As [`KalmanRows::from_slices`](super::KalmanRows::from_slices), plus [`Error::Shape`] / [`Error::Singular`] for an `R`
    /// of the wrong size or not symmetric with a non-negative diagonal.
    pub fn from_slices(rows: &[usize], p0: &[T], r: &[T], opts: KalmanOptions<T>) -> Result<Self> {
        opts.validate()?;
        if opts.retire_below > T::zero() {
            return Err(Error::InvalidArgument { arg: "retire_below", expected: "0: retiring rows needs mode='rows'" });
        }
        if opts.form != CovarianceForm::Standard {
            return Err(Error::InvalidArgument {
                arg: "form",
                expected: "'standard' for mode='full' (the Joseph and square-root forms need mode='rows')",
            });
        }
        if opts.huber > T::zero() {
            return Err(Error::InvalidArgument {
                arg: "huber",
                expected: "0 for mode='full' (Huber weighting needs mode='rows'; the outlier gate works here)",
            });
        }
        if opts.tracking() {
            return Err(Error::InvalidArgument {
                arg: "forgetting",
                expected: "no forgetting or drift for mode='full' (tracking needs mode='rows')",
            });
        }
        let rows_buf: S::Rows = rows_buffer::<_, N>(rows)?;
        let k = rows.len();
        // R: one variance (every row), one per row (diagonal R), or the whole K × K matrix.
        let mut rbuf = S::PairScalars::filled("r", k * k, T::zero())?;
        check_finite("r", r)?;
        if r.len() == k * k {
            rbuf.flat_mut().copy_from_slice(r);
        } else if r.len() == 1 || r.len() == k {
            for i in 0..k {
                rbuf.flat_mut()[i * k + i] = per_row("r", r, k, i)?;
            }
        } else {
            return Err(Error::Shape { arg: "r", expected: k * k, got: r.len() });
        }
        let rm = rbuf.flat();
        for i in 0..k {
            check_nonneg("r", rm[i * k + i])?;
            for j in 0..i {
                if (rm[i * k + j] - rm[j * k + i]).abs()
                    > T::default_epsilon() * T::of(16.0) * (rm[i * k + i] + rm[j * k + j])
                {
                    return Err(Error::Singular { what: "r (it must be a symmetric covariance matrix)" });
                }
            }
        }
        // Positive semi-definite: R + ε tr(R) I must factor (a singular R, e.g. noise-free
        // data, is fine; a negative eigenvalue would make every later sample fail).
        let mut s_buf = S::PairScalars::filled("unknown_rows", k * k, T::zero())?;
        {
            let tr = (0..k).fold(T::zero(), |a, i| a + rm[i * k + i]);
            let sb = s_buf.flat_mut();
            sb.copy_from_slice(rm);
            for i in 0..k {
                sb[i * k + i] += T::default_epsilon() * T::of(64.0) * tr + T::of(1e-30);
            }
            if !cholesky_in_place(sb, k) {
                return Err(Error::Singular {
                    what: "r (it must be positive semi-definite: a covariance matrix has no negative eigenvalue)",
                });
            }
            sb.fill(T::zero());
        }
        let mut p = S::Blocks::filled("p0", k * k, SMatrix::zeros())?;
        for i in 0..k {
            let v = per_row("p0", p0, k, i)?;
            check_positive("p0", v)?;
            p.flat_mut()[i * k + i] = SMatrix::identity() * v;
        }
        Ok(Self {
            rows: rows_buf,
            theta: S::Vecs::filled("unknown_rows", k, SVector::zeros())?,
            p,
            r: rbuf,
            c: S::PairVecs::filled("unknown_rows", k * k, SVector::zeros())?,
            w: S::PairVecs::filled("unknown_rows", k * k, SVector::zeros())?,
            s: s_buf,
            pn: S::Blocks::filled("unknown_rows", k * k, SMatrix::zeros())?,
            opts,
            reinit_count: 0,
            samples: 0,
            ssr: S::Scalars::filled("unknown_rows", k, T::zero())?,
            nobs: T::zero(),
            gated: 0,
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

    /// Number of samples accepted (those the outlier gate left out included, as in mode
    /// `rows`).
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Samples left out by the outlier gate ([`KalmanOptions::gate`]; every row leaves a gated
    /// sample out, since the rows are filtered jointly).
    pub fn gated(&self) -> u64 {
        self.gated
    }

    /// `tr P`.
    pub fn trace(&self) -> T {
        let k = self.rows.flat().len();
        (0..k).fold(T::zero(), |a, i| a + self.p.flat()[i * k + i].trace())
    }

    /// Arithmetic per update and size: an operation count of one update for K
    /// rows and N states, on the path every sample takes (no outlier gate, no
    /// reinitialization, no definiteness check of a risky sample; the overflow bound on the
    /// step is a check, not counted), each formula counted as written: a sum of n terms is
    /// n − 1 additions, a subtraction is an addition.
    ///
    /// | step | multiplications | additions | divisions | square roots |
    /// |---|---|---|---|---|
    /// | `e_i = z_i − θ_iᵀx` | K N | K N | | |
    /// | `C_ij = P_ij x`, K² blocks | K² N² | K² N(N−1) | | |
    /// | `S_ij = xᵀC_ij + R_ij`, j ≤ i | K(K+1)/2 · N | K(K+1)/2 · N | | |
    /// | Cholesky of the K × K `S` | K(K²−1)/6 | K(K²−1)/6 | K(K−1)/2 | K |
    /// | `W = C S⁻¹`: K N solves with the factor | K²(K−1) N | K²(K−1) N | 2 K² N | |
    /// | `θ_i += Σ_l W_il e_l` | K² N | K² N | | |
    /// | `P_ij −= Σ_l W_il C_jlᵀ`, j ≥ i | K(K+1)/2 · K N² | K(K+1)/2 · K N² | | |
    /// | the diagonal blocks symmetrized, `(a + b)/2` | K N(N−1)/2 | K N(N−1)/2 | | |
    pub fn cost(&self) -> Cost {
        let k = self.rows.flat().len();
        let blocks = k * (k + 1) / 2;
        let chol = (k * k * k - k) / 6;
        let solves = (k * k * k - k * k) * N;
        let sym = k * (N * N - N) / 2;
        let common = k * N + blocks * N + chol + solves + k * k * N + blocks * k * N * N + sym;
        Cost {
            multiplications: common + k * k * N * N,
            additions: common + k * k * (N * N - N),
            divisions: (k * k - k) / 2 + 2 * k * k * N,
            square_roots: k,
            bytes: core::mem::size_of_val(self)
                + self.rows.heap_bytes()
                + self.theta.heap_bytes()
                + self.p.heap_bytes()
                + self.r.heap_bytes()
                + self.c.heap_bytes()
                + self.w.heap_bytes()
                + self.s.heap_bytes()
                + self.pn.heap_bytes()
                + self.ssr.heap_bytes(),
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
    /// A noise-free row (`R_mm = 0`) that has learned all `x` tells it is left out of the
    /// sample (as mode rows' row takes no step), instead of making `S` singular.
    ///
    /// # Errors
    /// As [`KalmanRows::update_into`]; [`Error::Singular`] when `S` is not positive definite,
    /// or for a sample informative far beyond its noise on some row (`R_ii / S_ii < √ε`) whose
    /// downdate would leave `P` indefinite (the whole `(K·N) × (K·N)` matrix is checked by
    /// Cholesky then). A sample the outlier gate leaves out is not an error (it is counted,
    /// [`KalmanFull::gated`]).
    pub(crate) fn update_vec(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
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
        if s.iter().any(|v| !v.finite()) {
            return Err(OVERFLOW);
        }
        if !abs_e.finite() {
            return Err(culprit(theta, x, e));
        }
        // A noise-free row (R_mm = 0, so R_ml = 0) whose block has collapsed along x
        // (xᵀ P_mm x at rounding level, the floor of mode rows) has nothing left to learn
        // there, and its zero S_mm would make S singular: the sample updates without it, as
        // mode rows' row takes no step. (P positive semi-definite and xᵀ P_mm x = 0 give
        // P_lm x = 0 for every l: column m of every C_l is zero, S is block diagonal.)
        for m in 0..k {
            if r[m * k + m] == T::zero() {
                let floor = super::guards::collapse_floor::<T, N>(x.abs().sum(), c[m * k + m].abs().sum());
                if s[m * k + m] <= floor {
                    for l in 0..k {
                        c[l * k + m] = SVector::zeros();
                        s[l * k + m] = T::zero();
                        s[m * k + l] = T::zero();
                    }
                    s[m * k + m] = T::one();
                }
            }
        }
        // Risky: a row informed far beyond its noise (R_ii / S_ii below √ε; noise-free rows,
        // R_ii = 0, are exempt as in mode rows): the downdate is checked before it is made.
        let rk = risky::<T>();
        let risky_sample = (0..k).any(|i| r[i * k + i] > T::zero() && r[i * k + i] < rk * s[i * k + i]);
        let gate = self.opts.gate > T::zero();
        if gate && gate_out::<T, N>(self.opts.gate, &mut self.nobs, self.ssr.flat_mut(), e, s, r) {
            // Taken and counted like any sample (as in mode rows), but not used; no
            // reinitialization on an outlier.
            self.gated += 1;
            self.samples += 1;
            return Ok(());
        }
        if !cholesky_in_place(s, k) {
            return Err(Error::Singular {
                what: "the innovation covariance H P Hᵀ + R (P lost positive definiteness: reset_covariance(p0) \
                       restarts the identifier from its estimate; mode='rows' with form='sqrt' cannot lose it)",
            });
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
            return Err(culprit(theta, x, e));
        }
        if risky_sample {
            // The downdate into the candidate, checked (the check factors it in place, so the
            // downdate is made again below).
            let pn = &mut self.pn.flat_mut()[..k * k];
            pn.copy_from_slice(&p[..k * k]);
            downdate_blocks(pn, w, c, k);
            if !blocks_positive_definite(pn, k) {
                return Err(LOST_DEFINITENESS_JOINT);
            }
        }
        // Apply: nothing above changed the identifier's state (but the gate's count).
        for i in 0..k {
            for l in 0..k {
                theta[i] += w[i * k + l] * e[l];
            }
        }
        downdate_blocks(p, w, c, k);
        if gate {
            // The recursive residuals w_i² = e_i² R_ii / S_ii (S_ii from C, as S was factored).
            for (i, ssr) in self.ssr.flat_mut().iter_mut().enumerate() {
                let sii = x.dot(&c[i * k + i]) + r[i * k + i];
                // A noise-free row carries no residual (and 0/0 when collapsed, above).
                if r[i * k + i] > T::zero() {
                    *ssr += e[i] * e[i] * r[i * k + i] / sii;
                }
            }
            self.nobs += T::one();
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

impl<T: Real, const N: usize, const K: usize> KalmanFull<T, N, Fixed<K>> {
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
