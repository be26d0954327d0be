//! The exact start of [`RowIdentifier`]: samples absorbed by Givens rotations (a QR
//! factorization of the stacked regressors) until they identify every direction, then the
//! least-squares estimate and its covariance as the filter's starting point.

use super::super::CovarianceForm;
use super::RowIdentifier;
use crate::identify::OVERFLOW;
use crate::linalg::symmetrize;
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

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
pub(super) fn start_tol<T: Real>(d: usize) -> T {
    T::default_epsilon().sqrt() * T::of(d as f64)
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

impl<T: Real, const N: usize> RowIdentifier<T, N> {
    /// Exact start: one sample into the QR factorization `R` (in `m`), `Qᵀz` (in `θ`) by
    /// Givens rotations; the residual left over is the sample's recursive residual. When
    /// `R` identifies every direction, switches to filtering.
    pub(super) fn absorb(&mut self, x: &SVector<T, N>, z: T) -> Result<()> {
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
    pub(super) fn finish_start(&mut self) {
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
