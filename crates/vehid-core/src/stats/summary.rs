//! The OLS summary of one identified equation, as statsmodels' `OLSResults` names it.
//!
//! From the equation's estimate `params` (`k` values), its unscaled covariance `C = (XᵀX)⁻¹`
//! (or the prior-regularized `(XᵀX + P₀⁻¹)⁻¹` of a recursive identifier), the residual sum of
//! squares `ssr` and the number of observations `nobs` (an effective, possibly fractional
//! count under exponential forgetting), with `k` the number of parameters:
//!
//! | statsmodels | here | formula |
//! |---|---|---|
//! | `df_resid` | `df_resid` | `nobs − k` |
//! | `scale`, `mse_resid` | `sigma2` | `ssr / df_resid` |
//! | `normalized_cov_params` | `cov_unscaled` (input) | `(XᵀX)⁻¹` |
//! | `cov_params()` | `cov_params` | `sigma2 · C` |
//! | `bse` | `bse` | `√diag(cov_params)` |
//! | `tvalues` | `tvalues` | `params / bse` |
//! | `pvalues` | `pvalues` | `2 · t.sf(|tvalues|, df_resid)` |
//! | `conf_int(alpha)` | `conf_int` | `params ∓ t.ppf(1 − alpha/2, df_resid) · bse` |
//! | `condition_number` | `condition_number` | `√(λ_max(XᵀX) / λ_min(XᵀX))` |
//!
//! statsmodels' `condition_number` (`regression/linear_model.py`, `RegressionResults`) is the
//! square root of the ratio of the largest to the smallest eigenvalue of `XᵀX` (`eigenvals`, from
//! the singular values of the design), i.e. the ratio of the extreme singular values of `X`.
//! `(XᵀX)⁻¹` has the same eigenvectors and the reciprocal eigenvalues, so the ratio is the same
//! with `C`: `√(λ_max(C) / λ_min(C))`. For a prior-regularized `C` it is the condition number of
//! `XᵀX + P₀⁻¹`. The eigenvalues come from Jacobi rotations (relatively accurate for positive
//! definite matrices); like statsmodels' value it carries a relative error of order
//! `ε · condition_number²` from the data.

use super::dist::{t_ppf, t_sf};
use super::eigen::jacobi_eigenvalues;
use crate::error::{check_finite, check_nonneg};
use crate::{Error, Result};

/// The largest asymmetry accepted in `cov_unscaled`: `|c_ij − c_ji| ≤ SYMMETRY_TOLERANCE ·
/// √(c_ii c_jj)` (rounding in a covariance update is far below; a transposed or wrong matrix is
/// far above).
pub const SYMMETRY_TOLERANCE: f64 = 1e-8;

/// The scalar results of [`summary_into`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SummaryScalars {
    /// Residual variance `ssr / df_resid` (statsmodels `scale`, `mse_resid`), in the squared
    /// unit of the equation's regressand.
    pub sigma2: f64,
    /// Residual degrees of freedom `nobs − k` (statsmodels `df_resid`; fractional under forgetting).
    pub df_resid: f64,
    /// The number of observations as given (statsmodels `nobs`).
    pub nobs: f64,
    /// The significance level of `conf_int` (a `1 − alpha` interval).
    pub alpha: f64,
    /// The critical value `t.ppf(1 − alpha/2, df_resid)` that scales `bse` into `conf_int`.
    pub t_crit: f64,
    /// `√(λ_max / λ_min)` of `XᵀX` (statsmodels `condition_number`), dimensionless.
    pub condition_number: f64,
}

/// Caller buffers for [`summary_into`], one entry per parameter (`cov_params`: `k × k`).
#[derive(Debug)]
pub struct SummaryBuffers<'a> {
    /// Standard errors `√diag(cov_params)` (statsmodels `bse`), in the parameters' units.
    pub bse: &'a mut [f64],
    /// `params / bse` (statsmodels `tvalues`).
    pub tvalues: &'a mut [f64],
    /// Two-sided p-values `2 · t.sf(|tvalues|, df_resid)` (statsmodels `pvalues`).
    pub pvalues: &'a mut [f64],
    /// `[lower, upper]` per parameter: `params ∓ t_crit · bse` (statsmodels `conf_int(alpha)`).
    pub conf_int: &'a mut [[f64; 2]],
    /// `sigma2 · cov_unscaled`, row-major (statsmodels `cov_params()`). Also the scratch space
    /// of the condition number.
    pub cov_params: &'a mut [f64],
}

/// Checks every input and returns `(k, df_resid)`.
fn check_inputs(params: &[f64], cov_unscaled: &[f64], ssr: f64, nobs: f64, alpha: f64) -> Result<(usize, f64)> {
    let k = params.len();
    if k == 0 {
        return Err(Error::InvalidArgument { arg: "params", expected: "at least one parameter" });
    }
    let kk =
        k.checked_mul(k).ok_or(Error::Shape { arg: "cov_unscaled", expected: usize::MAX, got: cov_unscaled.len() })?;
    if cov_unscaled.len() != kk {
        return Err(Error::Shape { arg: "cov_unscaled", expected: kk, got: cov_unscaled.len() });
    }
    check_finite("params", params)?;
    check_nonneg("ssr", ssr)?;
    if !nobs.is_finite() {
        return Err(Error::NonFinite { arg: "nobs", index: 0 });
    }
    // (`1 − alpha/2` must stay below 1 in f64: alpha > 2⁻⁵³.)
    if !(alpha > 0.0 && alpha < 1.0 && 1.0 - alpha / 2.0 < 1.0) {
        return Err(Error::InvalidArgument {
            arg: "alpha",
            expected: "a significance level in (0, 1) with 1 - alpha/2 < 1 in f64 (alpha > 1.2e-16), e.g. 0.05",
        });
    }
    let df_resid = nobs - k as f64;
    if !(df_resid > 0.0) {
        return Err(Error::InvalidArgument {
            arg: "nobs",
            expected: "more observations than parameters (nobs > k): with nobs <= k there are no residual \
                       degrees of freedom, so sigma2 = ssr / (nobs - k) is undefined",
        });
    }
    check_cov(cov_unscaled, k)?;
    Ok((k, df_resid))
}

const NOT_PD: &str = "`cov_unscaled`, the unscaled covariance (X'X)^-1,";

/// Checks that `cov_unscaled` (`k × k`) is finite, has a positive diagonal and is symmetric
/// to [`SYMMETRY_TOLERANCE`].
fn check_cov(cov_unscaled: &[f64], k: usize) -> Result<()> {
    check_finite("cov_unscaled", cov_unscaled)?;
    for i in 0..k {
        if !(cov_unscaled[i * k + i] > 0.0) {
            return Err(Error::Singular { what: NOT_PD });
        }
    }
    for i in 0..k {
        for j in 0..i {
            let (a, b) = (cov_unscaled[i * k + j], cov_unscaled[j * k + i]);
            let scale = libm::sqrt(cov_unscaled[i * k + i]) * libm::sqrt(cov_unscaled[j * k + j]);
            if !(libm::fabs(a - b) <= SYMMETRY_TOLERANCE * scale) {
                return Err(Error::InvalidArgument {
                    arg: "cov_unscaled",
                    expected: "a symmetric matrix (|c_ij - c_ji| <= 1e-8 sqrt(c_ii c_jj))",
                });
            }
        }
    }
    Ok(())
}

/// `√(λ_max(C) / λ_min(C))` of the symmetric positive definite `C` (`k × k`), with `scratch`
/// (`k × k`) as working space. Assumes the checks of [`check_inputs`].
fn condition_from(cov_unscaled: &[f64], k: usize, scratch: &mut [f64]) -> Result<f64> {
    // The symmetric part (the inputs may differ by rounding).
    for i in 0..k {
        for j in 0..k {
            scratch[i * k + j] = 0.5 * cov_unscaled[i * k + j] + 0.5 * cov_unscaled[j * k + i];
        }
    }
    if !jacobi_eigenvalues(scratch, k) {
        return Err(Error::Singular { what: NOT_PD });
    }
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for i in 0..k {
        let v = scratch[i * k + i];
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !(lo > 0.0) {
        return Err(Error::Singular { what: NOT_PD });
    }
    Ok(libm::sqrt(hi / lo))
}

/// statsmodels' `condition_number` of the design, from the unscaled covariance `(XᵀX)⁻¹`
/// (`k × k`, row-major): `√(λ_max / λ_min)` (module documentation). `scratch` holds `k × k`
/// values of working space.
///
/// # Errors
/// [`Error::Shape`] for lengths that are not `k × k`; [`Error::NonFinite`];
/// [`Error::InvalidArgument`] for an asymmetric matrix; [`Error::Singular`] when it is not
/// positive definite.
pub fn condition_number(cov_unscaled: &[f64], scratch: &mut [f64]) -> Result<f64> {
    let k = libm::sqrt(cov_unscaled.len() as f64) as usize;
    if k == 0 || k * k != cov_unscaled.len() {
        return Err(Error::Shape { arg: "cov_unscaled", expected: (k + 1) * (k + 1), got: cov_unscaled.len() });
    }
    if scratch.len() != k * k {
        return Err(Error::Shape { arg: "scratch", expected: k * k, got: scratch.len() });
    }
    check_cov(cov_unscaled, k)?;
    condition_from(cov_unscaled, k, scratch)
}

/// The OLS summary of one equation into caller buffers, allocation-free (module
/// documentation for the formulas and their statsmodels names).
///
/// - `params`: the estimate `θ̂` (`k` values);
/// - `cov_unscaled`: `(XᵀX)⁻¹` (`k × k`, row-major, symmetric positive definite);
/// - `ssr`: the residual sum of squares `Σ eᵢ²` (≥ 0, squared regressand units);
/// - `nobs`: the number of observations (`> k`; may be fractional);
/// - `alpha`: the significance level of `conf_int`, e.g. `0.05` for 95 % intervals.
///
/// With `ssr = 0` the standard errors are 0 and `tvalues` are `±∞` (NaN for a zero
/// parameter), as in statsmodels.
///
/// # Errors
/// [`Error::Shape`] for a buffer or `cov_unscaled` of the wrong length; [`Error::NonFinite`]
/// for NaN/inf in `params`, `cov_unscaled` or `nobs`; [`Error::InvalidArgument`] for a
/// negative `ssr`, `alpha` outside `(0, 1)`, `nobs ≤ k` (no residual degrees of freedom), an
/// asymmetric `cov_unscaled`; [`Error::Singular`] when `cov_unscaled` is not positive
/// definite. After an error the buffers' contents are unspecified.
///
/// # Examples
/// A straight line through (0, 0), (1, 1), (2, 3): `XᵀX = [[3, 3], [3, 5]]`.
/// ```
/// use vehid_core::stats::{summary_into, SummaryBuffers};
/// let (params, ssr) = ([-1.0 / 6.0, 1.5], 1.0 / 6.0); // intercept, slope; residuals 1/6, −1/3, 1/6
/// let cov_unscaled = [5.0 / 6.0, -0.5, -0.5, 0.5]; // (XᵀX)⁻¹
/// let (mut bse, mut t, mut p, mut ci, mut cov) = ([0.0; 2], [0.0; 2], [0.0; 2], [[0.0; 2]; 2], [0.0; 4]);
/// let out = SummaryBuffers { bse: &mut bse, tvalues: &mut t, pvalues: &mut p, conf_int: &mut ci, cov_params: &mut cov };
/// let s = summary_into(&params, &cov_unscaled, ssr, 3.0, 0.05, out)?;
/// assert!((s.sigma2 - 1.0 / 6.0).abs() < 1e-15); // ssr / (3 − 2)
/// assert!((bse[1] - (1.0f64 / 12.0).sqrt()).abs() < 1e-15); // √(σ² · ½)
/// # Ok::<(), vehid_core::Error>(())
/// ```
pub fn summary_into(
    params: &[f64],
    cov_unscaled: &[f64],
    ssr: f64,
    nobs: f64,
    alpha: f64,
    out: SummaryBuffers<'_>,
) -> Result<SummaryScalars> {
    let (k, df_resid) = check_inputs(params, cov_unscaled, ssr, nobs, alpha)?;
    for (arg, len) in [("bse", out.bse.len()), ("tvalues", out.tvalues.len()), ("pvalues", out.pvalues.len())] {
        if len != k {
            return Err(Error::Shape { arg, expected: k, got: len });
        }
    }
    if out.conf_int.len() != k {
        return Err(Error::Shape { arg: "conf_int", expected: k, got: out.conf_int.len() });
    }
    if out.cov_params.len() != k * k {
        return Err(Error::Shape { arg: "cov_params", expected: k * k, got: out.cov_params.len() });
    }
    let condition_number = condition_from(cov_unscaled, k, out.cov_params)?;
    let sigma2 = ssr / df_resid;
    let t_crit = t_ppf(1.0 - alpha / 2.0, df_resid)?;
    for (c, u) in out.cov_params.iter_mut().zip(cov_unscaled) {
        *c = u * sigma2;
    }
    for i in 0..k {
        let bse = libm::sqrt(out.cov_params[i * k + i]);
        let tv = params[i] / bse;
        out.bse[i] = bse;
        out.tvalues[i] = tv;
        out.pvalues[i] = if tv.is_nan() {
            f64::NAN // 0/0: a zero parameter with zero standard error, as statsmodels
        } else if tv.is_infinite() {
            0.0 // a perfect fit (ssr = 0), as statsmodels
        } else {
            2.0 * t_sf(libm::fabs(tv), df_resid)?
        };
        out.conf_int[i] = [params[i] - t_crit * bse, params[i] + t_crit * bse];
    }
    Ok(SummaryScalars { sigma2, df_resid, nobs, alpha, t_crit, condition_number })
}

/// The OLS summary of one equation (statsmodels' names; module documentation), owning its
/// arrays. Built by [`Summary::new`]; the allocation-free form is [`summary_into`].
#[cfg(feature = "alloc")]
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The estimate `θ̂` as given (statsmodels `params`).
    pub params: alloc::vec::Vec<f64>,
    /// Standard errors (statsmodels `bse`).
    pub bse: alloc::vec::Vec<f64>,
    /// `params / bse` (statsmodels `tvalues`).
    pub tvalues: alloc::vec::Vec<f64>,
    /// Two-sided p-values of `tvalues` under Student's t with `df_resid` (statsmodels `pvalues`).
    pub pvalues: alloc::vec::Vec<f64>,
    /// `[lower, upper]` per parameter, a `1 − alpha` interval (statsmodels `conf_int(alpha)`).
    pub conf_int: alloc::vec::Vec<[f64; 2]>,
    /// `sigma2 · (XᵀX)⁻¹`, `k × k` row-major (statsmodels `cov_params()`).
    pub cov_params: alloc::vec::Vec<f64>,
    /// Residual variance `ssr / df_resid` (statsmodels `scale`).
    pub sigma2: f64,
    /// Residual degrees of freedom `nobs − k` (statsmodels `df_resid`).
    pub df_resid: f64,
    /// Number of observations (statsmodels `nobs`).
    pub nobs: f64,
    /// Significance level of `conf_int`.
    pub alpha: f64,
    /// `t.ppf(1 − alpha/2, df_resid)`.
    pub t_crit: f64,
    /// `√(λ_max / λ_min)` of `XᵀX` (statsmodels `condition_number`).
    pub condition_number: f64,
}

#[cfg(feature = "alloc")]
impl Summary {
    /// The summary of one equation; arguments as [`summary_into`].
    ///
    /// # Errors
    /// As [`summary_into`], plus [`Error::OutOfMemory`].
    pub fn new(params: &[f64], cov_unscaled: &[f64], ssr: f64, nobs: f64, alpha: f64) -> Result<Self> {
        let (k, _) = check_inputs(params, cov_unscaled, ssr, nobs, alpha)?;
        let mut bse = zeros(k, "the standard errors")?;
        let mut tvalues = zeros(k, "the t values")?;
        let mut pvalues = zeros(k, "the p values")?;
        let mut cov_params = zeros(k * k, "the parameter covariance")?;
        let mut conf_int = alloc::vec::Vec::new();
        conf_int
            .try_reserve_exact(k)
            .map_err(|_| Error::OutOfMemory { what: "the confidence intervals", bytes: k * 16 })?;
        conf_int.resize(k, [0.0; 2]);
        let mut p = zeros(k, "the parameters")?;
        p.copy_from_slice(params);
        let out = SummaryBuffers {
            bse: &mut bse,
            tvalues: &mut tvalues,
            pvalues: &mut pvalues,
            conf_int: &mut conf_int,
            cov_params: &mut cov_params,
        };
        let s = summary_into(params, cov_unscaled, ssr, nobs, alpha, out)?;
        Ok(Self {
            params: p,
            bse,
            tvalues,
            pvalues,
            conf_int,
            cov_params,
            sigma2: s.sigma2,
            df_resid: s.df_resid,
            nobs: s.nobs,
            alpha: s.alpha,
            t_crit: s.t_crit,
            condition_number: s.condition_number,
        })
    }

    /// The number of parameters `k`.
    pub fn k(&self) -> usize {
        self.params.len()
    }
}

/// A zeroed `Vec` of `len` values, or [`Error::OutOfMemory`].
#[cfg(feature = "alloc")]
pub(crate) fn zeros(len: usize, what: &'static str) -> Result<alloc::vec::Vec<f64>> {
    let mut v = alloc::vec::Vec::new();
    v.try_reserve_exact(len).map_err(|_| Error::OutOfMemory { what, bytes: len.saturating_mul(8) })?;
    v.resize(len, 0.0);
    Ok(v)
}
