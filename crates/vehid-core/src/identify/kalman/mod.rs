//! The Kalman-filter identifier (Eq 4.3–4.7): recursive weighted least squares on
//! `z(k) = H_r(k) θ + ε(k)`, `H = I ⊗ xᵀ` restricted to the unknown rows,
//! `R = R_v + B R_u Bᵀ` (the unmeasured road input is measurement noise on the rows it
//! enters), `P(0) = p0 I`, `θ̂(0) = 0` unless a prior is given.
//!
//! Three forms that the algebra makes equal where their assumptions hold:
//! - [`KalmanRows`] (`rows`): Eq 6.16–6.18, one scalar-output filter per unknown row
//!   ([`RowIdentifier`]), each with its own `p0` and `r`. Exactly the full filter when `R` is
//!   diagonal and `P(0)` block diagonal. Rows can retire once identified.
//! - [`KalmanShared`] (`shared`): one `N × N` matrix `Q` with `P_i = r_i Q` for every row,
//!   valid when `r_i / p0_i` is the same on every row. The cheapest form.
//! - [`KalmanFull`] (`full`): the stacked filter with a general (non-diagonal) `R`, its
//!   covariance kept as `K × K` blocks of `N × N`.
//!
//! After `k` samples the estimate is the least-squares solution with the prior as extra
//! rows: `θ̂_i = argmin Σ_k (z_i − xᵀθ)²/r_i + (θ − θ̂_i(0))ᵀ P_i(0)⁻¹ (θ − θ̂_i(0))`
//! (thesis-notes §8). So the estimate depends on `r_i / p0_i` only; the ratio decides
//! whether the prior or the data wins in weakly excited directions.
//!
//! **Reinitialization (Eq 4.35–4.36).** With `e(k) = z − H θ̂(k−1)` on the unknown rows, when
//! `10 Σ|e_i(k)| > Σ_j P_jj(k)` the diagonal of `P` is multiplied by 10 and `R` doubled.
//!
//! # Memory (Table I of the thesis: 352 bytes for the 4-state identifier, 2800 for the 8-state)
//! `size_of::<KalmanIdentifier<f32, 4, 2>>()` is 336 bytes and
//! `size_of::<KalmanIdentifier<f32, 8, 4>>()` is 1432 bytes (the rows side by side: θ, the
//! covariances as `N × N` lanes of which the upper triangle is used, `r`, the statistics and
//! tracking state per row (with the forgetting factor per lane, derived), plus the row
//! indices, options and counters; a sample is planned on the stack); the shared form needs 184 and 504 (with the outlier gate's statistics). Both are within the thesis' 352 and 2800
//! bytes. These figures are asserted in the tests.
//!
//! # Forms, exact start, tracking, statistics
//! [`CovarianceForm`]: the standard form (the thesis', the fastest), Joseph's, and Bierman's
//! square-root `U D Uᵀ` form (positive definite in any precision: the recommended online form
//! in `f32`). [`KalmanRows::exact`]: no prior; samples are absorbed exactly (Givens QR) until
//! they identify every parameter, then every estimate is least squares on all samples so far.
//! [`KalmanOptions::forgetting`] / [`KalmanOptions::drift`] track parameters that change,
//! bounded by [`KalmanOptions::max_trace`] against wind-up. Every row accumulates its squared
//! recursive residuals (see [`RowIdentifier`]) for the statistics.

/// Gives an identifier with an `#[inline(always)] fn step(&mut self, x, z, e) -> Result<()>`
/// its AVX2 copy `step_avx2` and `dispatch`, which runs that copy when `$wide` (a constant
/// expression of the identifier's parameters: where it measured faster) and the CPU has AVX2
/// (x86-64 with `std`), else the portable `step`. Both copies compute the same bits (no FMA,
/// fixed summation order; tested). `$wide` is tested in a `const` block, so that the AVX2
/// copy is not even compiled for the identifiers that never take it.
macro_rules! avx2_step {
    ($wide:expr) => {
        /// [`Self::step`] compiled for AVX2 (same arithmetic, wider registers).
        #[cfg(all(feature = "std", target_arch = "x86_64"))]
        #[target_feature(enable = "avx2")]
        fn step_avx2(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
            self.step(x, z, e)
        }

        /// Runs [`Self::step`] in its AVX2 copy when wide and the CPU has AVX2, else portable.
        #[inline(always)]
        fn dispatch(&mut self, x: &SVector<T, N>, z: &SVector<T, N>, e: &mut [T]) -> Result<()> {
            #[cfg(all(feature = "std", target_arch = "x86_64"))]
            if const { $wide } && crate::simd::avx2() {
                // SAFETY: the CPU supports AVX2 (checked at run time by `simd::avx2`).
                return unsafe { self.step_avx2(x, z, e) };
            }
            self.step(x, z, e)
        }
    };
}

#[cfg(feature = "alloc")]
mod build;
mod full;
mod guards;
pub(crate) mod lanes;
mod options;
mod row;
mod rows;
mod shared;
mod sums;
mod ud;
mod xlanes;

#[cfg(feature = "alloc")]
pub use build::{boxed_kalman, KalmanSpec, Prior};
#[cfg(feature = "alloc")]
pub use full::FullKalmanIdentifierVec;
pub use full::{FullKalmanIdentifier, KalmanFull};
pub(crate) use guards::check_reset;
pub use options::{CovarianceForm, KalmanOptions, Mode};
pub use row::RowIdentifier;
pub use rows::{KalmanIdentifier, KalmanRows};
#[cfg(feature = "alloc")]
pub use rows::{KalmanIdentifierVec, KalmanIdentifierVec2};
#[cfg(feature = "alloc")]
pub use shared::SharedKalmanIdentifierVec;
pub use shared::{KalmanShared, SharedKalmanIdentifier};
pub(crate) use xlanes::{XLanes, XPlan};

#[cfg(test)]
mod numerics_tests;
#[cfg(test)]
mod tests;
