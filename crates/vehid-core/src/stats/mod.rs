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
//! | Student's t and the normal: CDF, survival function, quantile (scipy `stats.t`, `stats.norm`) | [`t_cdf`], [`t_sf`], [`t_ppf`], [`normal_cdf`], [`normal_sf`], [`normal_ppf`] | `dist.rs` (`beta.rs`: incomplete beta) |
//! | OLS summary (statsmodels `OLSResults`) | [`summary_into`] with [`SummaryBuffers`] → [`SummaryScalars`], [`Summary`] (alloc), [`condition_number`], [`SYMMETRY_TOLERANCE`] | `summary.rs` (`eigen.rs`: Jacobi) |
//! | Ljung–Box whiteness test (statsmodels `acorr_ljungbox`), chi-square survival function (scipy `stats.chi2.sf`) | [`ljung_box`] → [`LjungBox`], [`chi2_sf`] | `whiteness.rs` |
//! | Cross-correlation of a residual with a regressor (statsmodels `ccf`) | [`ccf_into`] | `whiteness.rs` |
//! | Recursive residuals (statsmodels `RecursiveLSResults.resid_recursive`) | [`recursive_residuals`] (alloc) | `recursive.rs` |
//! | CUSUM and CUSUM of squares (statsmodels `RecursiveLSResults`) | [`cusum_into`], [`cusum_squares_into`], [`cusum_bound`], [`cusum_scalar`], [`cusum_squares_bounds`], [`cusum_squares_critical`], [`CUSUM_SCALARS`], [`CUSUM_SQUARES_SCALARS`], [`Cusum`] (alloc) | `cusum.rs` |
//!
//! Functions that return a `Vec` (the [`Summary`] and [`Cusum`] structs) need `alloc`; the
//! rest writes into caller buffers and works without it. Bad input (NaN or infinite values,
//! `df ≤ 0`, a probability outside `(0, 1)`, mismatched lengths, too few residuals) is an
//! [`crate::Error`], never a panic.
//!
//! The tests compare with scipy and statsmodels (and 50-digit mpmath where scipy is off), through
//! tables that `benches/stats_reference.py` generates; their tolerances are stated in `tests.rs`.

mod beta;
mod cusum;
mod dist;
mod eigen;
#[cfg(feature = "alloc")]
mod recursive;
mod summary;
mod whiteness;

#[cfg(test)]
mod tests;

#[cfg(feature = "alloc")]
pub use cusum::Cusum;
pub use cusum::{
    cusum_bound, cusum_into, cusum_scalar, cusum_squares_bounds, cusum_squares_critical, cusum_squares_into,
    CUSUM_SCALARS, CUSUM_SQUARES_SCALARS,
};
pub use dist::{normal_cdf, normal_ppf, normal_sf, t_cdf, t_interval_factor, t_ppf, t_sf};
#[cfg(feature = "alloc")]
pub use recursive::recursive_residuals;
#[cfg(feature = "alloc")]
pub use summary::Summary;
pub use summary::{condition_number, summary_into, SummaryBuffers, SummaryScalars, SYMMETRY_TOLERANCE};
pub use whiteness::{ccf_into, chi2_sf, ljung_box, LjungBox};
