//! The uncertainty of an identified equation, named as statisticians name it: statsmodels'
//! `params`, `bse`, `conf_int`, `sigma2` (`scale`), `cov_params`, and the CUSUM tests of the
//! recursive residuals (Brown, Durbin & Evans 1975).
//!
//! Pure math in `f64`, from the raw ingredients an identifier keeps per equation: the
//! estimate, its unscaled covariance `(XᵀX)⁻¹`, the residual sum of squares, the (effective)
//! number of observations, and the recursive residuals.
//!
//! | concept | items | file |
//! |---|---|---|
//! | Student's t and the normal: CDF, survival function, quantile | [`t_cdf`], [`t_sf`], [`t_ppf`], [`normal_cdf`], [`normal_sf`], [`normal_ppf`] | `dist.rs` (`beta.rs`: incomplete beta) |
//! | OLS summary (`OLSResults`) | [`summary_into`], [`Summary`] (alloc), [`condition_number`] | `summary.rs` (`eigen.rs`: Jacobi) |
//! | CUSUM and CUSUM of squares (`RecursiveLSResults`) | [`cusum_into`], [`cusum_squares_into`], [`cusum_bound`], [`cusum_squares_bounds`], [`Cusum`] (alloc) | `cusum.rs` |
//!
//! Functions that return a `Vec` (the [`Summary`] and [`Cusum`] structs) need `alloc`; the
//! rest writes into caller buffers and works without it. Bad input is an [`crate::Error`],
//! never a panic.

mod beta;
mod cusum;
mod dist;
mod eigen;
mod summary;

#[cfg(test)]
mod tests;

#[cfg(feature = "alloc")]
pub use cusum::Cusum;
pub use cusum::{
    cusum_bound, cusum_into, cusum_scalar, cusum_squares_bounds, cusum_squares_critical, cusum_squares_into,
    CUSUM_SCALARS, CUSUM_SQUARES_SCALARS,
};
pub use dist::{normal_cdf, normal_ppf, normal_sf, t_cdf, t_ppf, t_sf};
#[cfg(feature = "alloc")]
pub use summary::Summary;
pub use summary::{condition_number, summary_into, SummaryBuffers, SummaryScalars, SYMMETRY_TOLERANCE};
