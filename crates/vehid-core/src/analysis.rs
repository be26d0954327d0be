//! Analysis of a linear model under the thesis' road noise: stationary covariances and the
//! output standard deviations of Eq 4.27 (the discretizations it uses are
//! [`crate::model::zoh`] and [`crate::model::rk4_map`]).
//!
//! All functions are allocation-free and work for `f32` and `f64` (they compute in `f64`).

use crate::linalg::{discrete_lyapunov, expm_with_integral, integrate, spectral_radius};
use crate::model::{broadcast, LinearModel};
use crate::{Error, Real, Result};
use nalgebra::{SMatrix, SVector};

/// Stationary covariance of the sampled system `x(k+1) = Φ x(k) + Γ u(k)` with
/// `u(k) ~ N(0, diag(road_sigma²))`: the solution of `P = Φ P Φᵀ + Γ Σ_u Γᵀ`.
///
/// # Errors
/// [`Error::Unstable`] when `Φ` has a pole on or outside the unit circle;
/// [`Error::InvalidArgument`] / [`Error::Shape`] for bad `road_sigma`.
pub fn discrete_stationary_cov<T: Real, const N: usize, const M: usize>(
    phi: &SMatrix<T, N, N>,
    gamma: &SMatrix<T, N, M>,
    road_sigma: &[T],
) -> Result<SMatrix<T, N, N>> {
    let su = broadcast::<T, M>("road_sigma", road_sigma)?;
    let phi = phi.map(|v| v.to_f64());
    let g = gamma.map(|v| v.to_f64());
    let s = SMatrix::<f64, M, M>::from_fn(|i, j| {
        if i == j {
            {
                let s = su[i].to_f64();
                s * s
            }
        } else {
            0.0
        }
    });
    let c = g * s * g.transpose();
    discrete_lyapunov(&phi, &c).map(|p| p.map(T::of)).ok_or(Error::Unstable { what: "the stationary covariance" })
}

/// Largest `ρ(A) · hold` [`output_std`] accepts.
pub const MAX_HOLD_RHO: f64 = 1e6;

/// Standard deviation of each state under road noise held over intervals of `hold` seconds
/// (Eq 4.27): `σ_i² = (T σ_u²/π) ∫₀^∞ |H_i(ω)|² sinc²(ωT/2) dω`, `H(s) = (sI − A)⁻¹ B`.
///
/// The held white noise has a triangular autocorrelation (Eq 4.25), the output of a moving
/// average of length `T` over white noise of intensity `σ_u² T`. The frequency integral is
/// evaluated in closed form in the time domain: with `Ψ(t) = ∫₀ᵗ e^{Aτ} dτ` and `Γ = Ψ(T) B`,
/// `Σ = (1/T) [∫₀ᵀ Ψ(t) B S Bᵀ Ψ(t)ᵀ dt + ∫₀^∞ e^{As} Γ S Γᵀ e^{Aᵀs} ds]`, `S = diag(σ_u²)`;
/// the first integral by Gauss–Legendre quadrature, the second by doubling.
///
/// Thesis (Eq 4.28), quarter car: `σ/σ_u = [0.386, 1.84, 0.402, 1.03]`. This is the
/// continuous-time (random-phase) standard deviation, not the variance at the sample
/// instants of the discretized system ([`discrete_stationary_cov`]).
///
/// # Errors
/// [`Error::Unstable`] for a model that is not asymptotically stable;
/// [`Error::InvalidArgument`] / [`Error::Shape`] for bad `road_sigma` or `hold`.
pub fn output_std<T: Real, const N: usize, const M: usize>(
    model: &LinearModel<T, N, M>,
    road_sigma: &[T],
    hold: T,
) -> Result<SVector<T, N>> {
    crate::error::check_positive("hold", hold)?;
    let su = broadcast::<T, M>("road_sigma", road_sigma)?;
    if su.iter().any(|s| !(s.to_f64() * s.to_f64() * 1e6).is_finite()) {
        return Err(Error::InvalidArgument {
            arg: "road_sigma",
            expected: "a road standard deviation whose variance is finite with room to spare (below about 1e150; \
                       rescale the units)",
        });
    }
    let a = model.a().map(|v| v.to_f64());
    let b = model.b().map(|v| v.to_f64());
    let t = hold.to_f64();
    if !(spectral_radius(&a) * t <= MAX_HOLD_RHO) {
        return Err(Error::InvalidArgument {
            arg: "hold",
            expected: "a hold time of at most 1e6 times the model's fastest time constant (the integrals over \
                       longer holds lose all accuracy; the held input is then effectively constant)",
        });
    }
    let s = SMatrix::<f64, M, M>::from_fn(|i, j| {
        if i == j {
            {
                let s = su[i].to_f64();
                s * s
            }
        } else {
            0.0
        }
    });
    let panels = 2 + libm::ceil(spectral_radius(&a) * t) as usize;
    let first = integrate(t, panels.min(10_000), |tau| {
        let g = expm_with_integral(&a, tau).1 * b;
        g * s * g.transpose()
    });
    let (phi_t, psi_t) = expm_with_integral(&a, t);
    let gamma = psi_t * b;
    let c = gamma * s * gamma.transpose();
    // ∫₀^∞ e^{As} C e^{Aᵀs} ds = Σ_k Φᵏ (∫₀ᵀ e^{As} C e^{Aᵀs} ds) Φᵏᵀ, Φ = e^{AT}.
    let piece = integrate(t, panels.min(10_000), |tau| {
        let e = expm_with_integral(&a, tau).0;
        e * c * e.transpose()
    });
    let tail = discrete_lyapunov(&phi_t, &piece).ok_or(Error::Unstable { what: "the output standard deviation" })?;
    let cov = (first + tail) / t;
    if cov.iter().any(|v| !v.is_finite()) {
        // A stable model (the Lyapunov sum converged) whose variance still overflows: the
        // input is too large for f64, not the model unstable.
        return Err(Error::InvalidArgument {
            arg: "road_sigma",
            expected: "a road standard deviation small enough that the state variance is finite (rescale the units)",
        });
    }
    Ok(SVector::<T, N>::from_fn(|i, _| T::of(libm::sqrt(cov[(i, i)].max(0.0)))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{auto_substeps, rk4_map, zoh, HalfCar, QuarterCar, MAX_SUBSTEPS};

    #[test]
    fn output_std_matches_eq_4_28() {
        let car = QuarterCar::<f64>::thesis().model();
        let sd = output_std(&car, &[1.0], 0.05).unwrap();
        for (got, printed) in sd.iter().zip([0.386, 1.84, 0.402, 1.03]) {
            assert!((got / printed - 1.0).abs() < 0.005, "{got} vs {printed}");
        }
        // Linear in σ_u.
        let sd2 = output_std(&car, &[0.1], 0.05).unwrap();
        assert!((sd2 - sd * 0.1).norm() < 1e-12);
    }

    #[test]
    fn output_std_equals_frequency_domain_integral() {
        // Independent evaluation of Eq 4.27 as printed: (T σ²/π) ∫ |H_i(jω)|² sinc²(ωT/2) dω,
        // with H from a complex solve at each frequency (trapezoid on a log grid + tail).
        let car = QuarterCar::<f64>::thesis().model();
        let t = 0.05;
        let a = nalgebra::Matrix4::from_fn(|i, j| nalgebra::Complex::new(car.a()[(i, j)], 0.0));
        let b = nalgebra::Vector4::from_fn(|i, _| nalgebra::Complex::new(car.b()[(i, 0)], 0.0));
        let h = |w: f64| {
            let m = nalgebra::Matrix4::<nalgebra::Complex<f64>>::identity() * nalgebra::Complex::new(0.0, w) - a;
            m.lu().solve(&b).unwrap()
        };
        let sinc2 = |w: f64| {
            let x = w * t / 2.0;
            if x == 0.0 {
                1.0
            } else {
                (x.sin() / x).powi(2)
            }
        };
        let mut acc = [0.0; 4];
        let (lo, hi, steps) = (1e-4f64, 1e5f64, 400_000);
        let mut prev_w = 0.0;
        let mut prev = {
            let v = h(0.0);
            [v[0].norm_sqr(), v[1].norm_sqr(), v[2].norm_sqr(), v[3].norm_sqr()]
        };
        for k in 0..=steps {
            let w = lo * (hi / lo).powf(k as f64 / steps as f64);
            let v = h(w);
            let cur = [v[0].norm_sqr(), v[1].norm_sqr(), v[2].norm_sqr(), v[3].norm_sqr()];
            for i in 0..4 {
                acc[i] += 0.5 * (prev[i] * sinc2(prev_w) + cur[i] * sinc2(w)) * (w - prev_w);
            }
            prev = cur;
            prev_w = w;
        }
        let sd = output_std(&car, &[1.0], t).unwrap();
        for i in 0..4 {
            let freq = (t / core::f64::consts::PI * acc[i]).sqrt();
            assert!((freq / sd[i] - 1.0).abs() < 2e-3, "state {i}: {freq} vs {}", sd[i]);
        }
    }

    #[test]
    fn rk4_map_equals_stagewise_rk4() {
        let car = HalfCar::<f64>::thesis().model();
        let (dt, sub) = (0.05, 7);
        let (phi, gamma) = rk4_map(&car, dt, sub).unwrap();
        let x0 = SVector::<f64, 8>::from_fn(|i, _| (i as f64 * 0.37).sin());
        let u = nalgebra::Vector2::new(0.3, -0.2);
        let f = |x: &SVector<f64, 8>| car.a() * x + car.b() * u;
        let h = dt / sub as f64;
        let mut x = x0;
        for _ in 0..sub {
            let k1 = f(&x);
            let k2 = f(&(x + k1 * (h / 2.0)));
            let k3 = f(&(x + k2 * (h / 2.0)));
            let k4 = f(&(x + k3 * h));
            x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        }
        assert!((phi * x0 + gamma * u - x).norm() < 1e-13);
    }

    #[test]
    fn rk4_converges_to_exact_zoh() {
        let car = HalfCar::<f64>::thesis().model();
        let (pe, ge) = zoh(&car, 0.05).unwrap();
        let (pr, gr) = rk4_map(&car, 0.05, 400).unwrap();
        assert!((pe - pr).abs().max() < 1e-8 && (ge - gr).abs().max() < 1e-8);
        // Plain RK4 at the thesis' step is unstable for the half car's fast poles.
        let car = HalfCar::<f64>::thesis().model();
        let (p1, _) = rk4_map(&car, 0.05, 1).unwrap();
        assert!(crate::linalg::spectral_radius(&p1) > 1.0);
        assert!(auto_substeps(&car, 0.05) >= 2);
    }

    #[test]
    fn overflowing_discretization_names_dt_and_substeps_are_capped() {
        let car = QuarterCar::<f64>::thesis().model();
        assert!(matches!(zoh(&car, 1e300), Err(Error::InvalidArgument { arg: "dt", .. })));
        assert!(matches!(rk4_map(&car, 1e300, 3), Err(Error::InvalidArgument { arg: "dt", .. })));
        assert!(matches!(rk4_map(&car, 0.05, MAX_SUBSTEPS + 1), Err(Error::InvalidArgument { arg: "substeps", .. })));
    }

    #[test]
    fn unstable_model_is_an_error() {
        let mut a = *QuarterCar::<f64>::thesis().model().a();
        a[(3, 3)] = 100.0;
        let m = crate::model::LinearModel::new(a, nalgebra::Vector4::new(0.0, 90.0, 0.0, 0.0), &[1, 3]).unwrap();
        assert!(matches!(output_std(&m, &[1.0], 0.05), Err(Error::Unstable { .. })));
        assert!(matches!(output_std(&m, &[1.0], 0.0), Err(Error::InvalidArgument { arg: "hold", .. })));
    }
}
