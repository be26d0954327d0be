//! Eigenvalues of a small symmetric matrix by cyclic Jacobi rotations, in place and without
//! allocation (for the condition number of `(XᵀX)⁻¹`).
//!
//! Jacobi's method with the relative stopping rule `|a_pq| ≤ ε √|a_pp a_qq|` computes the
//! eigenvalues of a positive definite matrix to high relative accuracy, small ones included
//! (Demmel & Veselić, SIAM J. Matrix Anal. Appl. 13, 1992), which is what a condition number
//! needs. Rotation formulas as in Rutishauser (1966) / Numerical Recipes §11.1.

/// Sweeps before giving up (quadratic convergence needs well under 20 for `k ≤ 100`).
const MAX_SWEEPS: usize = 60;

/// Replaces the symmetric `k × k` row-major matrix `m` by a diagonal one with the same
/// eigenvalues (on the diagonal; off-diagonal entries end as zeros). Only the upper triangle
/// is read. Returns `false` when the sweeps ran out (not seen for finite input).
pub(crate) fn jacobi_eigenvalues(m: &mut [f64], k: usize) -> bool {
    debug_assert_eq!(m.len(), k * k);
    for i in 0..k {
        for j in 0..i {
            m[i * k + j] = m[j * k + i];
        }
    }
    for _ in 0..MAX_SWEEPS {
        let mut rotated = false;
        for p in 0..k {
            for q in p + 1..k {
                let apq = m[p * k + q];
                let (app, aqq) = (m[p * k + p], m[q * k + q]);
                // (√|app|·√|aqq| rather than √|app·aqq|: no overflow or underflow of the product.)
                if libm::fabs(apq) <= f64::EPSILON * libm::sqrt(libm::fabs(app)) * libm::sqrt(libm::fabs(aqq)) {
                    m[p * k + q] = 0.0;
                    m[q * k + p] = 0.0;
                    continue;
                }
                rotated = true;
                // tan of the rotation angle: the smaller root of t² + 2θt − 1 = 0.
                let theta = (aqq - app) / (2.0 * apq);
                let t = if libm::fabs(theta) > 1e150 {
                    0.5 / theta
                } else {
                    let t = 1.0 / (libm::fabs(theta) + libm::sqrt(theta * theta + 1.0));
                    if theta < 0.0 {
                        -t
                    } else {
                        t
                    }
                };
                let c = 1.0 / libm::sqrt(t * t + 1.0);
                let s = t * c;
                let tau = s / (1.0 + c);
                m[p * k + p] = app - t * apq;
                m[q * k + q] = aqq + t * apq;
                m[p * k + q] = 0.0;
                m[q * k + p] = 0.0;
                for r in 0..k {
                    if r == p || r == q {
                        continue;
                    }
                    let (grp, grq) = (m[r * k + p], m[r * k + q]);
                    let np = grp - s * (grq + tau * grp);
                    let nq = grq + s * (grp - tau * grq);
                    m[r * k + p] = np;
                    m[p * k + r] = np;
                    m[r * k + q] = nq;
                    m[q * k + r] = nq;
                }
            }
        }
        if !rotated {
            return true;
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_by_two_closed_form() {
        // [[2, 1], [1, 2]] has eigenvalues 1 and 3.
        let mut m = [2.0, 1.0, 1.0, 2.0];
        assert!(jacobi_eigenvalues(&mut m, 2));
        let (lo, hi) = (m[0].min(m[3]), m[0].max(m[3]));
        assert!((lo - 1.0).abs() < 1e-15 && (hi - 3.0).abs() < 4e-15);
        assert_eq!((m[1], m[2]), (0.0, 0.0));
    }

    #[test]
    fn graded_matrix_keeps_its_small_eigenvalue() {
        // [[1, 1e-7], [1e-7, 1e-12]]: det = 9.9e-13 exactly representable up to rounding, the
        // small eigenvalue det/λ_max ≈ 9.9e-13 must come out to full relative accuracy.
        let mut m = [1.0, 1e-7, 1e-7, 1e-12];
        let (tr, det) = (1.0 + 1e-12, 1e-12 - 1e-14);
        let big = 0.5 * (tr + libm::sqrt(tr * tr - 4.0 * det));
        let small = det / big;
        assert!(jacobi_eigenvalues(&mut m, 2));
        let (lo, hi) = (m[0].min(m[3]), m[0].max(m[3]));
        assert!((hi / big - 1.0).abs() < 1e-15);
        assert!((lo / small - 1.0).abs() < 1e-14, "{lo} vs {small}");
    }

    #[test]
    fn three_by_three_trace_and_determinant() {
        let mut m = [4.0, 1.0, 0.5, 1.0, 3.0, 0.25, 0.5, 0.25, 2.0];
        let det = 4.0 * (3.0 * 2.0 - 0.25 * 0.25) - 1.0 * (1.0 * 2.0 - 0.25 * 0.5) + 0.5 * (1.0 * 0.25 - 3.0 * 0.5);
        assert!(jacobi_eigenvalues(&mut m, 3));
        let ev = [m[0], m[4], m[8]];
        assert!((ev.iter().sum::<f64>() - 9.0).abs() < 1e-14);
        assert!((ev.iter().product::<f64>() / det - 1.0).abs() < 1e-14);
        for (i, v) in m.iter().enumerate() {
            if i % 4 != 0 {
                assert_eq!(*v, 0.0);
            }
        }
    }
}
