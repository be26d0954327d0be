//! Which constant changed: generalized least squares of relative deviations against the
//! patterns the constants leave (no allocation, any size `K`).

use crate::Real;
use nalgebra::{SMatrix, SVector};

/// In-place Cholesky factor `C = L Lᵀ` (lower triangle of the result); `false` when `C` is
/// not positive definite (nothing useful is left in `c` then).
pub(crate) fn cholesky<T: Real, const K: usize>(c: &mut SMatrix<T, K, K>) -> bool {
    for j in 0..K {
        let mut d = c[(j, j)];
        for k in 0..j {
            d -= c[(j, k)] * c[(j, k)];
        }
        if !(d > T::zero()) || !d.finite() {
            return false;
        }
        let d = d.sqrt();
        c[(j, j)] = d;
        let inv = T::one() / d;
        for i in j + 1..K {
            let mut v = c[(i, j)];
            for k in 0..j {
                v -= c[(i, k)] * c[(j, k)];
            }
            c[(i, j)] = v * inv;
        }
    }
    true
}

/// `L⁻¹ b` for the lower-triangular factor of [`cholesky`].
pub(crate) fn forward<T: Real, const K: usize>(l: &SMatrix<T, K, K>, b: &SVector<T, K>) -> SVector<T, K> {
    let mut w = *b;
    for i in 0..K {
        let mut v = w[i];
        for k in 0..i {
            v -= l[(i, k)] * w[k];
        }
        w[i] = v / l[(i, i)];
    }
    w
}

/// The fit of one pattern `u` to deviations `x` with covariance `C`: the weighted
/// least-squares amplitude `x̂ = uᵀC⁻¹x / uᵀC⁻¹u`, its variance `1 / uᵀC⁻¹u` and the
/// weighted residual `xᵀC⁻¹x − (uᵀC⁻¹x)² / uᵀC⁻¹u`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Fit<T> {
    pub value: T,
    pub var: T,
    pub ssr: T,
}

/// Fits every pattern of `patterns` to `x` (covariance `c`); `None` when `c` is not positive
/// definite.
pub(crate) fn fit_patterns<T: Real, const K: usize, const P: usize>(
    x: &SVector<T, K>,
    c: &SMatrix<T, K, K>,
    patterns: &[SVector<T, K>; P],
) -> Option<[Fit<T>; P]> {
    let mut l = *c;
    if !cholesky(&mut l) {
        return None;
    }
    let wx = forward(&l, x);
    let xx = wx.dot(&wx);
    let mut out = [Fit { value: T::zero(), var: T::zero(), ssr: T::zero() }; P];
    for (o, u) in out.iter_mut().zip(patterns) {
        let wu = forward(&l, u);
        let uu = wu.dot(&wu);
        let ux = wu.dot(&wx);
        *o = Fit { value: ux / uu, var: T::one() / uu, ssr: xx - ux * ux / uu };
    }
    Some(out)
}
