//! Recursive least squares with exponential forgetting and a bound on the covariance, for
//! `N` regressors and `O` outputs that share them (no allocation).

use crate::Real;
use nalgebra::{SMatrix, SVector};

/// Recursive least squares for `yᵀ = φᵀΘ + eᵀ` with `N` parameters per output, `O` outputs
/// measured with the same regressors `φ` (so they share the covariance `P`), and forgetting
/// factor `λ` (Ljung & Söderström, *Theory and Practice of Recursive Identification*, 1983,
/// §2.6):
///
/// ```text
/// ε = y − Θᵀφ,  K = Pφ / (λ' + φᵀPφ),  Θ ← Θ + K εᵀ,  P ← (P − K (Pφ)ᵀ) / λ'
/// ```
///
/// with `λ' = λ`, except `λ' = 1` (no forgetting) while a diagonal entry of `P` exceeds its
/// cap: without excitation plain forgetting divides `P` by `λ` every sample and it grows
/// without bound ("covariance wind-up"); the cap keeps the estimate's uncertainty at most
/// what the monitor can still judge. With outputs whose noises have covariance `Σ` (`O × O`),
/// the estimates' covariance is `Σ ⊗ P` (column `o` of `Θ` has `Σ_oo P`).
///
/// Why not the crate's `KalmanIdentifier`: that filter identifies rows of a state-space `A`
/// from a measured state and derivative; here the regressors are the kinematic filters'
/// outputs plus a constant, and the monitor needs the `N × N` `P` of its equations per sample
/// at a few tens of nanoseconds, so a dedicated form is both simpler and cheaper. The quarter
/// car uses [`Rls3`] (`N = 3`, one output), the half car `Rls<T, 5, 2>` (one `P` for both
/// body-corner equations: a single covariance update per sample).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(bound(serialize = "T: serde::Serialize", deserialize = "T: crate::Real"))
)]
pub struct Rls<T: Real, const N: usize, const O: usize = 1> {
    theta: SMatrix<T, N, O>,
    p: SMatrix<T, N, N>,
    lambda: T,
    inv_lambda: T,
    #[cfg_attr(feature = "serde", serde(with = "crate::persist::array"))]
    cap: [T; N],
}

/// The quarter car's tracker: three parameters `[k2/M, b/M, c]`, one output.
pub type Rls3<T> = Rls<T, 3, 1>;

impl<T: Real, const N: usize, const O: usize> Rls<T, N, O> {
    /// Starts at `theta` (column `o`: output `o`'s parameters) with covariance `p` (made
    /// symmetric: `(p + pᵀ)/2`), forgetting factor `lambda` in `(0, 1]`, no cap.
    pub fn new(theta: SMatrix<T, N, O>, p: SMatrix<T, N, N>, lambda: T) -> Self {
        let half = T::of(0.5);
        let p = p * half + p.transpose() * half;
        Self { theta, p, lambda, inv_lambda: T::one() / lambda, cap: [T::biggest(); N] }
    }

    /// Sets the cap on the diagonal of `P` above which forgetting pauses.
    pub fn set_cap(&mut self, cap: [T; N]) {
        self.cap = cap;
    }

    /// Lets parameter `j` jump by an unknown amount: adds `q` to `P_jj` (the time update of
    /// a Kalman filter whose parameter `j` takes a random step of variance `q σ²`). The
    /// next samples learn its new value; the other parameters keep their estimates and, in
    /// the limit of a large `q`, lose only what they knew through parameter `j`.
    pub fn release(&mut self, j: usize, q: T) {
        self.p[(j, j)] += q;
    }

    /// The estimate `Θ` (`N × O`).
    pub fn theta(&self) -> &SMatrix<T, N, O> {
        &self.theta
    }

    /// The (unscaled) covariance `P`.
    pub fn p(&self) -> &SMatrix<T, N, N> {
        &self.p
    }

    /// The forgetting factor `λ`.
    pub fn lambda(&self) -> T {
        self.lambda
    }

    /// One sample of all outputs `y`; returns the a-priori residuals `ε = y − Θᵀφ`, or `None`
    /// (nothing changed) when the step would not be finite.
    #[inline]
    pub fn update_all(&mut self, phi: &SVector<T, N>, y: &SVector<T, O>) -> Option<SVector<T, O>> {
        let mut e = SVector::<T, O>::zeros();
        for o in 0..O {
            e[o] = y[o] - phi.dot(&self.theta.column(o));
        }
        let pphi = self.p * phi;
        let wound = (0..N).any(|i| self.p[(i, i)] > self.cap[i]);
        let (lam, inv_lam) = if wound { (T::one(), T::one()) } else { (self.lambda, self.inv_lambda) };
        let den = lam + phi.dot(&pphi);
        let k = pphi * (T::one() / den);
        let mut ok = den > T::zero();
        let mut theta = self.theta;
        for o in 0..O {
            for i in 0..N {
                let v = theta[(i, o)] + k[i] * e[o];
                theta[(i, o)] = v;
                ok &= v.finite();
            }
        }
        // The symmetric rank-1 update on the upper triangle, mirrored (P stays exactly
        // symmetric: `new` makes it so).
        let mut p = self.p;
        for i in 0..N {
            for j in i..N {
                let v = (self.p[(i, j)] - k[i] * pphi[j]) * inv_lam;
                p[(i, j)] = v;
                p[(j, i)] = v;
                ok &= v.finite();
            }
        }
        if !ok {
            return None;
        }
        self.theta = theta;
        self.p = p;
        Some(e)
    }
}

impl<T: Real, const N: usize> Rls<T, N, 1> {
    /// One sample of the single output `y`; returns the a-priori residual `ε = y − φᵀθ`, or
    /// `None` (nothing changed) when the step would not be finite.
    #[inline]
    pub fn update(&mut self, phi: &SVector<T, N>, y: T) -> Option<T> {
        self.update_all(phi, &SVector::<T, 1>::new(y)).map(|e| e[0])
    }
}
