//! The attenuation bias of noisy measured derivatives in a structure's regressors, and its
//! removal from a recursive least-squares filter's estimate on read (bias-compensated least
//! squares, Söderström 2007 §4.3; [`super::BiasCompensated`] accumulates the same sums itself).
//!
//! A `der(s)` term puts the derivative noise `v_s` (σ_v, white, the same on every component)
//! into the regressor `h` and, through known terms and the equation's own state, into the
//! output `y`. Least squares then converges to `(E[h hᵀ] + C)⁻¹ (E[h y] + c)` per sample,
//! `C = σ_v² Σ_s ∂h/∂z_s ∂h/∂z_sᵀ`, `c = σ_v² Σ_s ∂h/∂z_s ∂y/∂z_s`; subtracting `N C` and
//! `N c` from the normal equations removes the bias.

use super::RowIdentifier;
use crate::linalg::{cholesky_in_place, cholesky_solve};
use crate::structure::{Basis, Partition, Structure, Var, MAX_PARAMS, MAX_STATES};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

/// `true` when some identified equation reads a derivative inside `sign`/`pos`/`neg` (not
/// linear in the noise: not compensated).
pub(crate) fn nonlinear_deriv<T: Real>(s: &Structure<T>) -> bool {
    (0..s.equations()).any(|i| {
        s.terms(i).iter().any(|t| match t.basis {
            Basis::Sign { start, len } | Basis::Pos { start, len } | Basis::Neg { start, len } => {
                s.combination(start, len).iter().any(|(v, _)| matches!(v, Var::Deriv(_)))
            }
            _ => false,
        })
    })
}

/// `true` when some parameter multiplies a measured derivative (`der(·)`).
pub(crate) fn reads_noisy_deriv<T: Real>(s: &Structure<T>) -> bool {
    (0..s.equations())
        .any(|i| s.terms(i).iter().any(|t| t.param.is_some() && matches!(t.basis, Basis::Var(Var::Deriv(_)))))
}

/// Adds `f (Σ_s ∂h/∂z_s ∂h/∂z_sᵀ, Σ_s ∂h/∂z_s ∂y/∂z_s)` of identified equation `i` of `s` to
/// `(a, b)`, `h` in the local order of its group in `part`.
pub(crate) fn add_deriv_noise<T: Real, const P: usize>(
    s: &Structure<T>,
    part: &Partition,
    i: usize,
    f: T,
    a: &mut SMatrix<T, P, P>,
    b: &mut SVector<T, P>,
) {
    let mut jh = [SVector::<T, P>::zeros(); MAX_STATES];
    let mut jy = [T::zero(); MAX_STATES];
    jy[s.equation_state(i)] = T::one();
    for t in s.terms(i) {
        if let Basis::Var(Var::Deriv(v)) = t.basis {
            match t.param {
                Some(p) => jh[v as usize][part.local[p as usize] as usize] += t.coef,
                None => jy[v as usize] -= t.coef,
            }
        }
    }
    for v in 0..s.states() {
        *a += jh[v] * jh[v].transpose() * f;
        *b += jh[v] * (jy[v] * f);
    }
}

/// The estimate of filter `f` with the noise sums `C` (`c_mat`) and `c` (`c_vec`) removed:
/// `(XᵀX − C)⁻¹ (XᵀX θ̂ − c)` with `XᵀX = r P⁻¹` (exact after an exact start; with a prior
/// `P(0) = p0 I`, `r/p0` more on the diagonal), on the filter's leading `dim` parameters.
///
/// # Errors
/// [`Error::Singular`] when `P` or the corrected matrix is not positive definite (too few
/// samples for the noise, or a `σ_v` too large).
pub(crate) fn compensated<T: Real, const P: usize>(
    f: &RowIdentifier<T, P>,
    c_mat: &SMatrix<T, P, P>,
    c_vec: &SVector<T, P>,
) -> Result<SVector<T, P>> {
    let theta = f.theta();
    if c_mat.iter().all(|v| *v == T::zero()) && c_vec.iter().all(|v| *v == T::zero()) {
        return Ok(theta);
    }
    let bad = Error::Singular {
        what: "the bias-compensated estimate (the corrected normal equations are not positive definite: more \
               samples, or check deriv_noise)",
    };
    // Row-major d × d systems in the leading entries of P × P buffers (symmetric: Cholesky).
    let d = f.dim();
    let (p, r) = (f.p(), f.r());
    let (mut l, mut a) = (SMatrix::<T, P, P>::zeros(), SMatrix::<T, P, P>::zeros());
    let ls = l.as_mut_slice();
    for i in 0..d {
        for j in 0..d {
            ls[i * d + j] = p[(i, j)];
        }
    }
    if !cholesky_in_place(ls, d) {
        return Err(bad);
    }
    // a = XᵀX = r P⁻¹, column by column.
    let asl = a.as_mut_slice();
    let mut col = [T::zero(); MAX_PARAMS];
    for j in 0..d {
        col[..d].fill(T::zero());
        col[j] = T::one();
        cholesky_solve(ls, d, &mut col[..d]);
        for i in 0..d {
            asl[i * d + j] = col[i] * r;
        }
    }
    let mut b = [T::zero(); MAX_PARAMS];
    for i in 0..d {
        b[i] = (0..d).fold(T::zero(), |acc, j| acc + asl[i * d + j] * theta[j]) - c_vec[i];
        for j in 0..d {
            asl[i * d + j] -= c_mat[(i, j)];
        }
    }
    if !cholesky_in_place(asl, d) {
        return Err(bad);
    }
    cholesky_solve(asl, d, &mut b[..d]);
    let out = SVector::<T, P>::from_fn(|i, _| if i < d { b[i] } else { T::zero() });
    if out.iter().all(|v| v.finite()) {
        Ok(out)
    } else {
        Err(bad)
    }
}
