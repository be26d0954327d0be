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
//!
//! # Files
//! The forms: `rows.rs`, `shared.rs`, `full.rs` (each with its `Identifier` impl and
//! persistence in `rows/`, `shared/`, `full/identifier.rs`; `full/blocks.rs`: the stacked
//! covariance's block arithmetic). One row: `row.rs` ([`RowIdentifier`]; `row/step.rs`: its
//! update in each form, `row/exact.rs`: the exact start). The rows side by side: `lanes.rs`
//! (`lanes/group.rs`: the group interface, `lanes/standard.rs`: the standard and Joseph
//! downdates, `lanes/sqrt.rs`: the square-root form), `xlanes.rs` (a regressor per lane).
//! What all forms share: `guards.rs` (the outlier screen, definiteness checks, the errors of a
//! refused update), `sums.rs` (fixed-order lane sums, finiteness probes), `ud.rs` (Bierman's
//! `U D Uᵀ` arithmetic), `avx2.rs` (the AVX2 copy of an update), `options.rs`, `build.rs`
//! (run-time construction). Dependencies go one way: the shared files do not use the forms,
//! and `lanes` uses `row` (a lane is read and written as a [`RowIdentifier`]), never the
//! reverse.

#[macro_use]
mod avx2;

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
