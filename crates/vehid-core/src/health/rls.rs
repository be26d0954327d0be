//! A three-parameter recursive least squares with exponential forgetting and a bound on
//! the covariance (no allocation).

use crate::Real;
use nalgebra::{SMatrix, SVector};

/// Recursive least squares for `y = φᵀθ + e` with three parameters and forgetting factor
/// `λ` (Ljung & Söderström, *Theory and Practice of Recursive Identification*, 1983,
/// §2.6):
///
/// ```text
/// ε = y − φᵀθ,  K = Pφ / (λ' + φᵀPφ),  θ ← θ + K ε,  P ← (P − K φᵀP) / λ'
/// ```
///
/// with `λ' = λ`, except `λ' = 1` (no forgetting) while a diagonal entry of `P` exceeds its
/// cap: without excitation plain forgetting divides `P` by `λ` every sample and it grows
/// without bound ("covariance wind-up"); the cap keeps the estimate's uncertainty at most
/// what the monitor can still judge.
///
/// Why not the crate's `KalmanIdentifier`: that filter identifies rows of a state-space `A`
/// from a measured state and derivative; here the regressors `[−d̂, −ḋ̂, 1]` are the
/// kinematic filter's outputs plus a constant, and the monitor needs the 3 × 3 `P` of one
/// equation per sample at a few tens of nanoseconds, so a dedicated 3-parameter form is
/// both simpler and cheaper.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(serialize = "T: serde::Serialize", deserialize = "T: serde::Deserialize<'de>"))
)]
pub struct Rls3<T: Real> {
    theta: SVector<T, 3>,
    p: SMatrix<T, 3, 3>,
    lambda: T,
    inv_lambda: T,
    cap: [T; 3],
}

impl<T: Real> Rls3<T> {
    /// Starts at `theta` with covariance `p`, forgetting factor `lambda` in `(0, 1]`, no cap.
    pub fn new(theta: SVector<T, 3>, p: SMatrix<T, 3, 3>, lambda: T) -> Self {
        Self { theta, p, lambda, inv_lambda: T::one() / lambda, cap: [T::biggest(); 3] }
    }

    /// Sets the cap on the diagonal of `P` above which forgetting pauses.
    pub fn set_cap(&mut self, cap: [T; 3]) {
        self.cap = cap;
    }

    /// The estimate `θ`.
    pub fn theta(&self) -> &SVector<T, 3> {
        &self.theta
    }

    /// The (unscaled) covariance `P`.
    pub fn p(&self) -> &SMatrix<T, 3, 3> {
        &self.p
    }

    /// The forgetting factor `λ`.
    pub fn lambda(&self) -> T {
        self.lambda
    }

    /// One sample; returns the a-priori residual `ε = y − φᵀθ`, or `None` (nothing
    /// changed) when the step would not be finite.
    #[inline]
    pub fn update(&mut self, phi: &SVector<T, 3>, y: T) -> Option<T> {
        let e = y - phi.dot(&self.theta);
        let pphi = self.p * phi;
        let wound = (0..3).any(|i| self.p[(i, i)] > self.cap[i]);
        let lam = if wound { T::one() } else { self.lambda };
        let den = lam + phi.dot(&pphi);
        let k = pphi * (T::one() / den);
        let theta = self.theta + k * e;
        let inv_lam = if wound { T::one() } else { self.inv_lambda };
        let mut p = (self.p - k * pphi.transpose()) * inv_lam;
        p = (p + p.transpose()) * T::of(0.5);
        if !(den > T::zero()) || theta.iter().chain(p.iter()).any(|v| !v.finite()) {
            return None;
        }
        self.theta = theta;
        self.p = p;
        Some(e)
    }
}
