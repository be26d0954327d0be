//! Which constant changed: generalized least squares of relative deviations against the
//! patterns the constants leave (no allocation): on the half car's Kronecker-structured
//! covariance ([`fit_kron`]), and the dense form for any size `K` (tests only).

use crate::Real;
use nalgebra::SMatrix;
#[cfg(test)]
use nalgebra::SVector;

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
#[cfg(test)]
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
/// definite. The dense form, for any covariance: the half car's monitor uses [`fit_kron`] on
/// its covariance's structure, and its tests check the two against each other.
#[cfg(test)]
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

/// The half car's five fits ([`super::half`]: the spring and the damper of each axle, then
/// the body mass) on the structure of its covariance, without forming it. The relative
/// deviations `x_i = θ_i/θ_ref,i − 1` (`i = 4 o + j`: equation `o`, regressor `j`) have the
/// covariance `C = D (Σ ⊗ Q) D`, `D = diag(1/θ_ref)`, where `Σ` is the two equations' residual
/// covariance and `Q` the `4 × 4` covariance factor of the coefficients (tracked plus
/// reference: both share `Σ` and `D`). So `C⁻¹ = D⁻¹ (Σ⁻¹ ⊗ Q⁻¹) D⁻¹`, and with
/// `X̃ = Θ − Θ_ref` (`= D⁻¹ x`, `4 × 2`, a column per equation) and `Ũ = D⁻¹ u`:
/// `uᵀC⁻¹x = Σ_{o,o'} Σ⁻¹_oo' Ũ_oᵀ Q⁻¹ X̃_o'`, i.e. the sum of `Ũ ⊙ (Q⁻¹ X̃ Σ⁻¹)`. The patterns:
/// regressor `j` in both equations (`Ũ = e_j r_jᵀ`, `r_j` row `j` of `Θ_ref`), and all eight
/// (`Ũ = Θ_ref`). A `4 × 4` Cholesky factor instead of the dense form's `8 × 8`
/// ([`fit_patterns`], the same fits: `half_tests.rs` checks one against the other).
///
/// `dtheta` is `X̃`, `r` the reference `Θ_ref` (rows 0–3), `sigma_inv` `Σ⁻¹`, `q` the factor
/// `Q`; `None` when `Q` is not positive definite (`Σ` is, by the reference's check).
pub(crate) fn fit_kron<T: Real>(
    dtheta: &SMatrix<T, 4, 2>,
    r: &SMatrix<T, 4, 2>,
    sigma_inv: &SMatrix<T, 2, 2>,
    q: &SMatrix<T, 4, 4>,
) -> Option<[Fit<T>; 5]> {
    let mut l = *q;
    if !cholesky(&mut l) {
        return None;
    }
    // L⁻¹ (lower), then Q⁻¹ = L⁻ᵀ L⁻¹.
    let mut li = SMatrix::<T, 4, 4>::zeros();
    for j in 0..4 {
        li[(j, j)] = T::one() / l[(j, j)];
        for i in j + 1..4 {
            let mut v = T::zero();
            for k in j..i {
                v -= l[(i, k)] * li[(k, j)];
            }
            li[(i, j)] = v / l[(i, i)];
        }
    }
    let mut qi = SMatrix::<T, 4, 4>::zeros();
    for a in 0..4 {
        for b in a..4 {
            let mut v = T::zero();
            for k in b..4 {
                v += li[(k, a)] * li[(k, b)];
            }
            qi[(a, b)] = v;
            qi[(b, a)] = v;
        }
    }
    // Z = Q⁻¹ A Σ⁻¹ for A = X̃ and A = Θ_ref.
    let zx = (qi * dtheta) * sigma_inv;
    let zr = (qi * r) * sigma_inv;
    let xx = dtheta.dot(&zx);
    let fit = |ux: T, uu: T| Fit { value: ux / uu, var: T::one() / uu, ssr: xx - ux * ux / uu };
    let mut out = [Fit { value: T::zero(), var: T::zero(), ssr: T::zero() }; 5];
    for (j, o) in out.iter_mut().take(4).enumerate() {
        let (a, b) = (r[(j, 0)], r[(j, 1)]);
        let ux = a * zx[(j, 0)] + b * zx[(j, 1)];
        let rsr =
            a * a * sigma_inv[(0, 0)] + a * b * (sigma_inv[(0, 1)] + sigma_inv[(1, 0)]) + b * b * sigma_inv[(1, 1)];
        *o = fit(ux, rsr * qi[(j, j)]);
    }
    out[4] = fit(r.dot(&zx), r.dot(&zr));
    Some(out)
}

/// `Q⁻¹` of a symmetric positive definite `q` through its Cholesky factor (`None` when `q` is
/// not positive definite).
pub(crate) fn spd_inverse<T: Real, const K: usize>(q: &SMatrix<T, K, K>) -> Option<SMatrix<T, K, K>> {
    let mut l = *q;
    if !cholesky(&mut l) {
        return None;
    }
    // L⁻¹ (lower), then Q⁻¹ = L⁻ᵀ L⁻¹.
    let mut li = SMatrix::<T, K, K>::zeros();
    for j in 0..K {
        li[(j, j)] = T::one() / l[(j, j)];
        for i in j + 1..K {
            let mut v = T::zero();
            for k in j..i {
                v -= l[(i, k)] * li[(k, j)];
            }
            li[(i, j)] = v / l[(i, i)];
        }
    }
    let mut qi = SMatrix::<T, K, K>::zeros();
    for a in 0..K {
        for b in a..K {
            let mut v = T::zero();
            for k in b..K {
                v += li[(k, a)] * li[(k, b)];
            }
            qi[(a, b)] = v;
            qi[(b, a)] = v;
        }
    }
    Some(qi)
}

/// A constant's pattern in the coefficients' own units, `Ũ = ∂Θ/∂ ln c` (`N × O`: a row per
/// regressor, a column per equation), for [`fit_kron_patterns`]; `row` is its only non-zero
/// row when it has one (a spring or a damper without anti-roll bars: the fit then needs one
/// entry of `Q⁻¹`); `zero` when it has none (a constant the monitor does not judge: its fit
/// is skipped).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Pattern<T: Real, const N: usize, const O: usize> {
    pub u: SMatrix<T, N, O>,
    pub row: Option<usize>,
    pub zero: bool,
}

impl<T: Real, const N: usize, const O: usize> Pattern<T, N, O> {
    /// The pattern `u`, its single non-zero row found.
    pub(crate) fn new(u: SMatrix<T, N, O>) -> Self {
        let mut rows = (0..N).filter(|&r| (0..O).any(|o| u[(r, o)] != T::zero()));
        let (first, second) = (rows.next(), rows.next());
        let row = match (first, second) {
            (Some(r), None) => Some(r),
            _ => None,
        };
        Self { u, row, zero: first.is_none() }
    }
}

/// The fits of `P` patterns to the deviations `X̃ = Θ − Θ_ref` (`N × O`) of `O` equations that
/// share their `N` regressors: [`fit_kron`] for any size (the full car's monitor: `N = 8`,
/// `O = 4`). The relative deviations' covariance is `C = D (Σ ⊗ Q) D`, so with `Z = Q⁻¹ A Σ⁻¹`
/// `uᵀC⁻¹x = Σ Ũ ⊙ Z(X̃)` and `uᵀC⁻¹u = Σ Ũ ⊙ Z(Ũ)`; for a pattern with one non-zero row `r`
/// the latter is `Q⁻¹_rr ũ_r Σ⁻¹ ũ_rᵀ`. A zero pattern fits nothing: amplitude 0, variance
/// `∞`, the whole weighted residual. `None` when `Q` is not positive definite.
pub(crate) fn fit_kron_patterns<T: Real, const N: usize, const O: usize, const P: usize>(
    dtheta: &SMatrix<T, N, O>,
    patterns: &[Pattern<T, N, O>; P],
    sigma_inv: &SMatrix<T, O, O>,
    q: &SMatrix<T, N, N>,
) -> Option<[Fit<T>; P]> {
    let qi = spd_inverse(q)?;
    let zx = (qi * dtheta) * sigma_inv;
    let xx = dtheta.dot(&zx);
    let mut out = [Fit { value: T::zero(), var: T::zero(), ssr: T::zero() }; P];
    for (o, p) in out.iter_mut().zip(patterns) {
        if p.zero {
            *o = Fit { value: T::zero(), var: T::one() / T::zero(), ssr: xx };
            continue;
        }
        let ux = p.u.dot(&zx);
        let uu = match p.row {
            Some(r) => {
                let ur = p.u.row(r);
                qi[(r, r)] * (ur * sigma_inv).dot(&ur)
            }
            None => p.u.dot(&((qi * p.u) * sigma_inv)),
        };
        *o = Fit { value: ux / uu, var: T::one() / uu, ssr: xx - ux * ux / uu };
    }
    Some(out)
}
