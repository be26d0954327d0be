//! The uncertainty of an identifier's current estimate, as a statistician reads it
//! (statsmodels' `params`, `bse`, `conf_int`, `scale`, `cov_params`, `nobs`), for any
//! [`Identifier`] that keeps a covariance and residual statistics.
//!
//! An identifier's `P` is the covariance of its estimate *if* each equation's noise variance
//! is the `r_i` it was told (Eq 4.7). The data say how far off that is: within a group `g` of
//! parameters (equations sharing parameters are one group; a linear model's rows are one
//! group each), the weighted residual variance
//!
//! `s_g² = Σ_{i ∈ g} (ssr_i / r_i) / (Σ_{i ∈ g} nobs_i − k_g)`
//!
//! estimates `σ²/r` (exactly `ssr/(n − k)/r` for one equation: the OLS `scale`), and the
//! covariance of the estimate is `s_g² P_g` (statsmodels' `cov_params()` for OLS, where `P/r =
//! (XᵀX)⁻¹` after an exact start; prior-regularized otherwise). `sigma2_i = s_g² r_i` is
//! equation `i`'s residual variance, `bse = √diag(cov)`, and the `1 − α` interval is
//! `θ̂ ± t_{1−α/2}(df_g) bse` with `df_g = Σ nobs_i − k_g` (Student's t: exact for Gaussian
//! noise and fixed regressors, as statsmodels' `conf_int`).

use super::Identifier;
use crate::{Error, Real, Result};
use alloc::vec;
use alloc::vec::Vec;

/// An estimate and its uncertainty (everything `f64`; vectors over parameters are in the
/// identifier's parameter order, over equations in its equation order).
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateStats {
    /// The estimate θ̂ (`params`).
    pub params: Vec<f64>,
    /// Its covariance `s_g² P` (`params × params`, row-major; 0 between groups).
    pub cov: Vec<f64>,
    /// Standard errors `√diag(cov)`.
    pub bse: Vec<f64>,
    /// The `1 − alpha` confidence interval of each parameter, `(low, high)`.
    pub conf_int: Vec<(f64, f64)>,
    /// Residual degrees of freedom of each parameter's group, `Σ nobs − k_g`.
    pub df: Vec<f64>,
    /// Each equation's residual variance `s_g² r_i` (the OLS `scale` for one equation).
    pub sigma2: Vec<f64>,
    /// Each equation's (effective) number of observations.
    pub nobs: Vec<f64>,
    /// The level the intervals were computed for.
    pub alpha: f64,
}

/// `alpha` checked, then `id`'s estimate, its covariance and its equations' noise covariance
/// (`params`, `params²`, `equations²` values): what both kinds of statistics read.
fn read_estimate<T: Real, I: Identifier<T> + ?Sized>(id: &I, alpha: f64) -> Result<(Vec<T>, Vec<T>, Vec<T>)> {
    if !(alpha > 0.0 && alpha < 1.0) {
        return Err(Error::InvalidArgument { arg: "alpha", expected: "a level in (0, 1), e.g. 0.05" });
    }
    let d = id.dims();
    let (np, ne) = (d.params, d.equations);
    let mut theta = vec![T::zero(); np];
    id.params_into(&mut theta)?;
    let mut p = vec![T::zero(); np * np];
    id.covariance_into(&mut p)?;
    let mut r = vec![T::zero(); ne * ne];
    id.noise_into(&mut r)?;
    Ok((theta, p, r))
}

/// The statistics of `id`'s current estimate at level `alpha` (module docs).
///
/// # Errors
/// [`Error::InvalidArgument`] for `alpha` outside (0, 1); [`Error::Unsupported`] for an
/// identifier without a covariance or residual statistics (the stochastic gradient, the
/// shared and full Kalman modes); [`Error::RankDeficient`] while the estimate does not exist
/// yet; [`Error::InvalidArgument`] naming `samples` when a group has no residual degrees of
/// freedom (no more observations than parameters), naming `r` for an equation declared
/// noise-free (`r_i = 0`: no scale to estimate).
pub fn estimate_stats<T: Real, I: Identifier<T> + ?Sized>(id: &I, alpha: f64) -> Result<EstimateStats> {
    let (theta, p, r) = read_estimate(id, alpha)?;
    let d = id.dims();
    let (np, ne) = (d.params, d.equations);
    let (mut ssr, mut nobs) = (vec![T::zero(); ne], vec![T::zero(); ne]);
    id.residuals_into(&mut ssr, &mut nobs)?;
    let (mut gp, mut ge) = (vec![0usize; np], vec![0usize; ne]);
    id.groups_into(&mut gp, &mut ge)?;
    let groups = gp.iter().chain(&ge).copied().max().map_or(0, |g| g + 1);
    let mut scale = vec![0.0f64; groups];
    let mut df = vec![0.0f64; groups];
    for g in 0..groups {
        let k = gp.iter().filter(|&&x| x == g).count() as f64;
        let (mut num, mut n) = (0.0, 0.0);
        for i in (0..ne).filter(|&i| ge[i] == g) {
            let ri = r[i * ne + i].to_f64();
            if ri <= 0.0 {
                return Err(Error::InvalidArgument {
                    arg: "r",
                    expected: "positive variances for statistics (an equation declared noise-free, r = 0, has no \
                               residual scale to estimate)",
                });
            }
            num += ssr[i].to_f64() / ri;
            n += nobs[i].to_f64();
        }
        df[g] = n - k;
        if df[g] <= 0.0 {
            return Err(Error::InvalidArgument {
                arg: "samples",
                expected: "more observations than parameters in every group for statistics (no residual degrees \
                           of freedom yet): feed more samples",
            });
        }
        scale[g] = num / df[g];
    }
    let cov: Vec<f64> = (0..np * np)
        .map(|ab| {
            let (a, b) = (ab / np, ab % np);
            if gp[a] == gp[b] {
                scale[gp[a]] * p[ab].to_f64()
            } else {
                0.0
            }
        })
        .collect();
    let bse: Vec<f64> = (0..np).map(|j| libm::sqrt(cov[j * np + j].max(0.0))).collect();
    let params: Vec<f64> = theta.iter().map(|v| v.to_f64()).collect();
    let mut conf_int = Vec::with_capacity(np);
    let mut dfp = Vec::with_capacity(np);
    for j in 0..np {
        let q = crate::stats::t_ppf(1.0 - alpha / 2.0, df[gp[j]])?;
        conf_int.push((params[j] - q * bse[j], params[j] + q * bse[j]));
        dfp.push(df[gp[j]]);
    }
    let sigma2 = (0..ne).map(|i| scale[ge[i]] * r[i * ne + i].to_f64()).collect();
    let nobs = nobs.iter().map(|v| v.to_f64()).collect();
    Ok(EstimateStats { params, cov, bse, conf_int, df: dfp, sigma2, nobs, alpha })
}

/// The statistics of an estimate whose covariance is a posterior, taken as it is (not scaled
/// by a residual variance): the joint EKF's parameter block of `P`
/// ([`super::JointEkf`], whose noise model is told, not estimated). `cov = P`, `bse =
/// √diag(P)`, the `1 − alpha` interval `θ̂ ± z_{1−α/2} bse` (normal: `df = ∞`), `sigma2` each
/// equation's variance under the noise model (the diagonal of its `R`), `nobs` the samples
/// taken.
///
/// # Errors
/// [`Error::InvalidArgument`] for `alpha` outside (0, 1); [`Error::Unsupported`] for an
/// identifier without a covariance or a noise covariance; the identifier's error while its
/// estimate does not exist.
pub fn posterior_stats<T: Real, I: Identifier<T> + ?Sized>(id: &I, alpha: f64) -> Result<EstimateStats> {
    let (theta, p, r) = read_estimate(id, alpha)?;
    let d = id.dims();
    let (np, ne) = (d.params, d.equations);
    let params: Vec<f64> = theta.iter().map(|v| v.to_f64()).collect();
    let cov: Vec<f64> = p.iter().map(|v| v.to_f64()).collect();
    let bse: Vec<f64> = (0..np).map(|j| libm::sqrt(cov[j * np + j].max(0.0))).collect();
    let q = crate::stats::t_ppf(1.0 - alpha / 2.0, f64::INFINITY)?;
    let conf_int = params.iter().zip(&bse).map(|(&v, &s)| (v - q * s, v + q * s)).collect();
    Ok(EstimateStats {
        params,
        cov,
        bse,
        conf_int,
        df: vec![f64::INFINITY; np],
        sigma2: (0..ne).map(|i| r[i * ne + i].to_f64()).collect(),
        nobs: vec![id.samples() as f64; ne],
        alpha,
    })
}
