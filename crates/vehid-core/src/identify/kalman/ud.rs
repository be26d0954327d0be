//! Bierman's `U D Uᵀ` factors of a covariance (the square-root form): factoring, product,
//! trace and the Agee–Turner rank-one update.

use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

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
