//! Small dense helpers on const-generic matrices that nalgebra does not give for generic
//! `N` without heavy trait bounds: matrix exponential with its integral, a spectral-radius
//! bound, and Gauss–Legendre quadrature. All are allocation-free.

use crate::Real;
use nalgebra::{SMatrix, SVector};

/// Infinity norm (largest absolute row sum) of a square matrix; NaN when any entry is NaN.
pub fn inf_norm<T: Real, const N: usize>(a: &SMatrix<T, N, N>) -> T {
    let mut best = T::zero();
    for i in 0..N {
        let mut s = T::zero();
        for j in 0..N {
            s += a[(i, j)].abs();
        }
        if !s.finite() {
            return s;
        }
        if s > best {
            best = s;
        }
    }
    best
}

/// `(e^{A t}, ∫₀ᵗ e^{A τ} dτ)` by scaling and squaring of the Taylor series.
///
/// The second matrix gives the zero-order-hold input matrix `Γ = (∫₀ᵗ e^{Aτ}dτ) B`. The
/// doubling rule `Ψ(2s) = (I + e^{As}) Ψ(s)` keeps the pair consistent; accuracy is a few
/// units of the scalar's epsilon times the condition of the exponential.
pub fn expm_with_integral<T: Real, const N: usize>(a: &SMatrix<T, N, N>, t: T) -> (SMatrix<T, N, N>, SMatrix<T, N, N>) {
    let norm = inf_norm(a).to_f64() * t.to_f64().abs();
    let mut squarings = 0u32;
    let mut scaled = norm;
    while scaled > 0.25 && squarings < 60 {
        scaled *= 0.5;
        squarings += 1;
    }
    let h = t / T::of(libm::pow(2.0, squarings as f64));
    let x = a * h;
    let eye = SMatrix::<T, N, N>::identity();
    // Horner form: Φ = I + X(I + X/2(I + X/3(...))), Ψ = h(I + X/2(I + X/3(...))).
    let terms = if core::mem::size_of::<T>() == 4 { 10 } else { 18 };
    let mut phi_tail = eye; // I + X/(k+1)(...) at the end of the loop
    for k in (1..=terms).rev() {
        phi_tail = eye + x * phi_tail * T::of(1.0 / (k as f64 + 1.0));
    }
    // phi_tail now is I + X/2 + X²/6 + ... = Σ X^k/(k+1)!
    let mut psi = phi_tail * h;
    let mut phi = eye + x * phi_tail;
    for _ in 0..squarings {
        psi += phi * psi;
        phi = phi * phi;
    }
    (phi, psi)
}

/// An estimate of the spectral radius `max |λ(A)|` by Gelfand's formula
/// `ρ = lim ‖A^k‖^{1/k}` with repeated normalized squaring (k = 2¹²).
///
/// Never below the true radius by more than about 0.1 % for the matrices vehid meets; used
/// to choose RK4 sub-steps without computing eigenvalues (works without `alloc`).
pub fn spectral_radius<T: Real, const N: usize>(a: &SMatrix<T, N, N>) -> f64 {
    let mut m: SMatrix<f64, N, N> = a.map(|v| v.to_f64());
    let mut log_rho = 0.0;
    let mut weight = 1.0;
    for _ in 0..12 {
        let norm = inf_norm(&m);
        if norm == 0.0 || !norm.is_finite() {
            return if norm == 0.0 { libm::exp(log_rho) * 0.0 } else { f64::INFINITY };
        }
        log_rho += weight * libm::log(norm);
        m /= norm;
        m = m * m;
        weight *= 0.5;
    }
    let norm = inf_norm(&m);
    if norm > 0.0 {
        log_rho += weight * libm::log(norm);
    } else {
        return 0.0;
    }
    libm::exp(log_rho)
}

/// 8-point Gauss–Legendre nodes on [-1, 1].
const GL8_X: [f64; 4] =
    [0.183_434_642_495_649_8, 0.525_532_409_916_329, 0.796_666_477_413_626_7, 0.960_289_856_497_536_3];
/// 8-point Gauss–Legendre weights matching [`GL8_X`].
const GL8_W: [f64; 4] =
    [0.362_683_783_378_362, 0.313_706_645_877_887_3, 0.222_381_034_453_374_5, 0.101_228_536_290_376_3];

/// `∫₀^len f(s) ds` by composite 8-point Gauss–Legendre over `panels` equal panels.
pub fn integrate<T: Real, const R: usize, const C: usize>(
    len: T,
    panels: usize,
    mut f: impl FnMut(T) -> SMatrix<T, R, C>,
) -> SMatrix<T, R, C> {
    let panels = panels.max(1);
    let width = len / T::of(panels as f64);
    let half = width * T::of(0.5);
    let mut acc = SMatrix::<T, R, C>::zeros();
    for p in 0..panels {
        let mid = width * T::of(p as f64) + half;
        for (x, w) in GL8_X.iter().zip(GL8_W.iter()) {
            let dx = half * T::of(*x);
            acc += (f(mid - dx) + f(mid + dx)) * (half * T::of(*w));
        }
    }
    acc
}

/// `Σ_{k≥0} Φᵏ C Φᵏᵀ`, the solution `P` of the discrete Lyapunov equation `P = Φ P Φᵀ + C`,
/// by doubling (Smith's method). `None` when the series does not converge (ρ(Φ) ≥ 1).
pub fn discrete_lyapunov<T: Real, const N: usize>(
    phi: &SMatrix<T, N, N>,
    c: &SMatrix<T, N, N>,
) -> Option<SMatrix<T, N, N>> {
    let mut p = *c;
    let mut f = *phi;
    for _ in 0..64 {
        let add = f * p * f.transpose();
        p += add;
        f = f * f;
        let fnorm = inf_norm(&f).to_f64();
        if !fnorm.is_finite() {
            return None;
        }
        if fnorm < 1e-18 {
            let p = (p + p.transpose()) * T::of(0.5);
            return p.iter().all(|v| v.finite()).then_some(p);
        }
    }
    None
}

/// Solves `L Lᵀ = S` in place for a small symmetric positive definite `S` (row-major,
/// `k × k`, only the lower triangle is read) and returns `false` when `S` is not
/// numerically positive definite. Used by the stacked (`full`) Kalman identifier.
pub fn cholesky_in_place<T: Real>(s: &mut [T], k: usize) -> bool {
    for j in 0..k {
        let mut d = s[j * k + j];
        for p in 0..j {
            d -= s[j * k + p] * s[j * k + p];
        }
        if !(d > T::zero()) || !d.finite() {
            return false;
        }
        let d = d.sqrt();
        s[j * k + j] = d;
        for i in (j + 1)..k {
            let mut v = s[i * k + j];
            for p in 0..j {
                v -= s[i * k + p] * s[j * k + p];
            }
            s[i * k + j] = v / d;
        }
    }
    true
}

/// Solves `L Lᵀ y = b` in place given the factor from [`cholesky_in_place`].
pub fn cholesky_solve<T: Real>(l: &[T], k: usize, b: &mut [T]) {
    for i in 0..k {
        let mut v = b[i];
        for p in 0..i {
            v -= l[i * k + p] * b[p];
        }
        b[i] = v / l[i * k + i];
    }
    for i in (0..k).rev() {
        let mut v = b[i];
        for p in (i + 1)..k {
            v -= l[p * k + i] * b[p];
        }
        b[i] = v / l[i * k + i];
    }
}

/// `out = P x` for a column-major `N × N` matrix, as column sweeps (no bounds checks; the
/// compiler vectorizes the inner loop).
#[inline(always)]
pub fn mat_vec<T: Real, const N: usize>(p: &SMatrix<T, N, N>, x: &SVector<T, N>, out: &mut SVector<T, N>) {
    let o = out.as_mut_slice();
    o.iter_mut().for_each(|v| *v = T::zero());
    for (col, &xj) in p.as_slice().chunks_exact(N).zip(x.iter()) {
        for (oi, &pij) in o.iter_mut().zip(col) {
            *oi += pij * xj;
        }
    }
}

/// Forces exact symmetry: `P ← (P + Pᵀ)/2`.
#[inline]
pub fn symmetrize<T: Real, const N: usize>(p: &mut SMatrix<T, N, N>) {
    let half = T::of(0.5);
    for i in 0..N {
        for j in (i + 1)..N {
            let v = (p[(i, j)] + p[(j, i)]) * half;
            p[(i, j)] = v;
            p[(j, i)] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Matrix3};

    #[test]
    fn expm_of_rotation_generator_is_rotation() {
        // e^{[[0,w],[-w,0]] t} = [[cos wt, sin wt], [-sin wt, cos wt]]: closed form.
        let w = 3.0_f64;
        let a = Matrix2::new(0.0, w, -w, 0.0);
        let (phi, psi) = expm_with_integral(&a, 0.7);
        let (s, c) = (w * 0.7_f64).sin_cos();
        assert!((phi - Matrix2::new(c, s, -s, c)).norm() < 1e-13);
        // ∫₀ᵗ: [[sin wt / w, (1 - cos wt)/w], [-(1 - cos wt)/w, sin wt / w]]
        let expect = Matrix2::new(s / w, (1.0 - c) / w, -(1.0 - c) / w, s / w);
        assert!((psi - expect).norm() < 1e-13);
    }

    #[test]
    fn expm_of_diagonal_matches_scalar_exponentials() {
        let a = Matrix3::from_diagonal(&nalgebra::Vector3::new(-65.3, -0.5, 2.0));
        let (phi, psi) = expm_with_integral(&a, 0.05);
        for (i, l) in [-65.3_f64, -0.5, 2.0].iter().enumerate() {
            let e = (l * 0.05).exp();
            assert!((phi[(i, i)] - e).abs() < 1e-14 * e.max(1.0));
            assert!((psi[(i, i)] - (e - 1.0) / l).abs() < 1e-14);
        }
    }

    #[test]
    fn inf_norm_propagates_nan() {
        assert!(inf_norm(&Matrix2::new(1.0, f64::NAN, 0.0, 0.0)).is_nan());
    }

    #[test]
    fn spectral_radius_of_known_matrices() {
        let a = Matrix2::new(0.0, 3.0, -3.0, 0.0); // ±3j
        assert!((spectral_radius(&a) - 3.0).abs() < 3e-3);
        let b = Matrix2::new(-40.0, 1.0, 0.0, -2.0);
        assert!((spectral_radius(&b) - 40.0).abs() < 0.1);
    }

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        // ∫₀² s^7 ds = 2^8/8 = 32
        let v = integrate(2.0_f64, 1, |s| nalgebra::Matrix1::new(s.powi(7)));
        assert!((v[0] - 32.0).abs() < 1e-12);
    }

    #[test]
    fn discrete_lyapunov_scalar_closed_form() {
        // p = a² p + c  =>  p = c / (1 - a²)
        let phi = nalgebra::Matrix1::new(0.9_f64);
        let c = nalgebra::Matrix1::new(2.0);
        let p = discrete_lyapunov(&phi, &c).unwrap();
        assert!((p[0] - 2.0 / (1.0 - 0.81)).abs() < 1e-10);
        assert!(discrete_lyapunov(&nalgebra::Matrix1::new(1.0_f64), &c).is_none());
    }

    #[test]
    fn cholesky_solves_spd_system() {
        let mut s = [4.0_f64, 2.0, 2.0, 3.0];
        assert!(cholesky_in_place(&mut s, 2));
        let mut b = [2.0, 1.0];
        cholesky_solve(&s, 2, &mut b);
        // [[4,2],[2,3]] y = [2,1] => y = [0.5, 0]
        assert!((b[0] - 0.5).abs() < 1e-15 && b[1].abs() < 1e-15);
        let mut bad = [1.0_f64, 2.0, 2.0, 1.0];
        assert!(!cholesky_in_place(&mut bad, 2));
    }
}
