//! The sampled system `x(k+1) = Φ x(k) + Γ u(k)` of a model: the exact zero-order hold and
//! the thesis' RK4 integrator as a discrete map (Ch. III.C).

use super::LinearModel;
use crate::linalg::{expm_with_integral, spectral_radius};
use crate::{Error, Real, Result};
use nalgebra::SMatrix;

/// The error for a transition matrix that overflows: `dt` is far too long for the model's
/// time constants (or `A` has entries near the floating-point limit).
const TRANSITION_OVERFLOW: Error = Error::InvalidArgument {
    arg: "dt",
    expected: "a sample interval short enough for the model that e^{A dt} stays finite \
               (check dt and the magnitude of A)",
};

/// Most RK4 sub-steps per sample accepted (the automatic count is capped at the same value).
pub const MAX_SUBSTEPS: usize = 100_000;

/// Zero-order-hold discretization over `dt` seconds (exact for an input held constant over
/// the interval): `x(k+1) = Φ x(k) + Γ u(k)`, `Φ = e^{A dt}`, `Γ = ∫₀^dt e^{Aτ} dτ B`.
///
/// # Errors
/// [`Error::InvalidArgument`] when `dt` is not finite and > 0.
pub fn zoh<T: Real, const N: usize, const M: usize>(
    model: &LinearModel<T, N, M>,
    dt: T,
) -> Result<(SMatrix<T, N, N>, SMatrix<T, N, M>)> {
    crate::error::check_positive("dt", dt)?;
    let a = model.a().map(|v| v.to_f64());
    let b = model.b().map(|v| v.to_f64());
    let (phi, psi) = expm_with_integral(&a, dt.to_f64());
    let gamma = psi * b;
    if phi.iter().chain(gamma.iter()).any(|v| !v.is_finite()) {
        return Err(TRANSITION_OVERFLOW);
    }
    Ok((phi.map(T::of), gamma.map(T::of)))
}

/// The discrete map of the classical fourth-order Runge–Kutta method (the thesis'
/// integrator, Ch. III.C) over `dt` seconds in `substeps` equal steps, with the input held.
///
/// For a linear system with a held input, one RK4 step of length `h` is exactly
/// `x ← R(hA) x + h S(hA) B u` with `R(Z) = I + Z + Z²/2 + Z³/6 + Z⁴/24` and
/// `S(Z) = I + Z/2 + Z²/6 + Z³/24`; composing `substeps` of them gives `(Φ, Γ)`. Applying
/// this map is RK4 (to rounding), at the cost of one matrix–vector product per sample.
///
/// # Errors
/// [`Error::InvalidArgument`] when `dt` is not finite and > 0 or `substeps == 0`.
pub fn rk4_map<T: Real, const N: usize, const M: usize>(
    model: &LinearModel<T, N, M>,
    dt: T,
    substeps: usize,
) -> Result<(SMatrix<T, N, N>, SMatrix<T, N, M>)> {
    crate::error::check_positive("dt", dt)?;
    if substeps == 0 || substeps > MAX_SUBSTEPS {
        return Err(Error::InvalidArgument {
            arg: "substeps",
            expected: "between 1 and 100000 (or None for automatic)",
        });
    }
    let a = model.a().map(|v| v.to_f64());
    let b = model.b().map(|v| v.to_f64());
    let h = dt.to_f64() / substeps as f64;
    let eye = SMatrix::<f64, N, N>::identity();
    let z = a * h;
    let z2 = z * z;
    let z3 = z2 * z;
    let r = eye + z + z2 * 0.5 + z3 * (1.0 / 6.0) + z3 * z * (1.0 / 24.0);
    let s = (eye + z * 0.5 + z2 * (1.0 / 6.0) + z3 * (1.0 / 24.0)) * h;
    let step_gamma = s * b;
    let mut phi = eye;
    let mut gamma = SMatrix::<f64, N, M>::zeros();
    for _ in 0..substeps {
        gamma = r * gamma + step_gamma;
        phi = r * phi;
    }
    if phi.iter().chain(gamma.iter()).any(|v| !v.is_finite()) {
        return Err(TRANSITION_OVERFLOW);
    }
    Ok((phi.map(T::of), gamma.map(T::of)))
}

/// The number of RK4 sub-steps per sample that vehid uses when none is given: enough that
/// `h ρ(A) ≤ 1/2` for the fastest pole `ρ(A)` (the thesis' half car at `dt = 0.05` s has
/// `dt ρ ≈ 3.3`, beyond RK4's stability limit of about 2.79 on the real axis).
pub fn auto_substeps<T: Real, const N: usize, const M: usize>(model: &LinearModel<T, N, M>, dt: T) -> usize {
    auto_substeps_of(model.a(), dt)
}

/// [`auto_substeps`] for the state matrix `a` alone (1/s; `dt` in s).
pub fn auto_substeps_of<T: Real, const N: usize>(a: &SMatrix<T, N, N>, dt: T) -> usize {
    let need = libm::ceil(spectral_radius(a) * dt.to_f64() / 0.5);
    if need.is_finite() && need >= 1.0 {
        (need as usize).min(MAX_SUBSTEPS)
    } else {
        1
    }
}
