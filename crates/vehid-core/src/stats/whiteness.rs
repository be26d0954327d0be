//! Whiteness of residuals: the Ljung–Box portmanteau test (statsmodels' `acorr_ljungbox`) and
//! the chi-square survival function it needs; the residuals' cross-correlation with a
//! regressor (statsmodels' `ccf`).
//!
//! An identifier's equation `z_i = θᵀφ + ε` is estimated without bias only when `ε` is white
//! and independent of `φ` (the thesis' road noise, Eq 4.25). A real road's height is a random
//! walk in distance: the wheel equation's residuals then follow the road and are strongly
//! autocorrelated. The Ljung–Box statistic over lags `1..=h`,
//! `Q = n (n + 2) Σ_{j=1}^{h} ρ̂_j² / (n − j)` (Ljung & Box 1978, *Biometrika* 65),
//! is `χ²(h)` for white residuals, so its p-value `P(χ²(h) > Q)` is uniform there and tiny
//! where the model is violated.

use crate::{Error, Result};

/// `P(χ²(df) > x)`, the chi-square survival function (scipy `stats.chi2.sf`): the regularized
/// upper incomplete gamma function `Q(df/2, x/2)`, by its series below `a + 1` and its continued
/// fraction (modified Lentz, shared with the incomplete beta) above (Press et al., *Numerical Recipes*, §6.2; relative error a few
/// 1e-15 against scipy in the tests).
///
/// # Errors
/// [`Error::InvalidArgument`] for `df` not finite and > 0, or `x` NaN or < 0.
pub fn chi2_sf(x: f64, df: f64) -> Result<f64> {
    if !(df.is_finite() && df > 0.0) {
        return Err(Error::InvalidArgument { arg: "df", expected: "finite and > 0" });
    }
    if x.is_nan() || x < 0.0 {
        return Err(Error::InvalidArgument { arg: "x", expected: "a value >= 0 (a chi-square statistic)" });
    }
    if x == f64::INFINITY {
        return Ok(0.0);
    }
    let (a, h) = (0.5 * df, 0.5 * x);
    if h == 0.0 {
        return Ok(1.0);
    }
    let log_front = a * libm::log(h) - h - libm::lgamma(a);
    if h < a + 1.0 {
        // P(a, h) = e^{-h} h^a / Γ(a) Σ_k h^k / (a (a+1) … (a+k))
        let (mut term, mut sum, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            ap += 1.0;
            term *= h / ap;
            sum += term;
            if libm::fabs(term) < libm::fabs(sum) * 1e-17 {
                break;
            }
        }
        return Ok((1.0 - sum * libm::exp(log_front)).max(0.0));
    }
    // Q(a, h) = e^{-h} h^a / Γ(a) / F, F = b₀ + a₁/(b₁ + …) with b_i = h + 1 − a + 2i,
    // a_i = −i (i − a) (Numerical Recipes §6.2).
    let f = super::beta::lentz(h + 1.0 - a, |i| (-i * (i - a), h + 1.0 - a + 2.0 * i));
    Ok(libm::exp(log_front) / f)
}

/// The Ljung–Box test of a series' whiteness (statsmodels `acorr_ljungbox(x, lags=[h])`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LjungBox {
    /// `Q = n (n + 2) Σ_{j=1}^{h} ρ̂_j² / (n − j)`, with `ρ̂_j` the lag-`j` sample
    /// autocorrelation about the mean (statsmodels' `lb_stat`).
    pub stat: f64,
    /// `P(χ²(h) > Q)` (statsmodels' `lb_pvalue`): small when the series is not white.
    pub pvalue: f64,
    /// The largest lag `h`.
    pub lags: usize,
    /// The lag-1 autocorrelation `ρ̂_1` (near 1 for residuals that follow a random walk).
    pub rho1: f64,
}

/// The Ljung–Box test of `x` over lags `1..=lags` (module docs). No allocation: two passes.
///
/// # Errors
/// [`Error::InvalidArgument`] for `lags` 0 or not below `x.len()`; [`Error::NonFinite`] for
/// NaN/inf in `x`; [`Error::Singular`] for a series without variance.
pub fn ljung_box(x: &[f64], lags: usize) -> Result<LjungBox> {
    let n = x.len();
    if lags == 0 || lags >= n {
        return Err(Error::InvalidArgument { arg: "lags", expected: "at least 1 and fewer than the samples" });
    }
    crate::error::check_finite("x", x)?;
    let mean = x.iter().sum::<f64>() / n as f64;
    let c0: f64 = x.iter().map(|v| (v - mean) * (v - mean)).sum();
    if !(c0 > 0.0 && c0.is_finite()) {
        return Err(Error::Singular { what: "the autocorrelation of a series without variance (all values equal)" });
    }
    let nf = n as f64;
    let (mut q, mut rho1) = (0.0, 0.0);
    for j in 1..=lags {
        let cj: f64 = x[j..].iter().zip(x).map(|(a, b)| (a - mean) * (b - mean)).sum();
        let r = cj / c0;
        if j == 1 {
            rho1 = r;
        }
        q += r * r / (nf - j as f64);
    }
    let stat = nf * (nf + 2.0) * q;
    Ok(LjungBox { stat, pvalue: chi2_sf(stat, lags as f64)?, lags, rho1 })
}

/// The cross-correlation of `x` with `y` at lags `0..out.len()` into `out` (statsmodels
/// `ccf(x, y, adjusted=True)`): `ccf_k = c_k / (σ_x σ_y)`, `c_k = Σ_{t} (x_{t+k} − x̄)(y_t − ȳ)
/// / (n − k)` (`x` lags `y` by `k`), `σ` the standard deviations with `ddof = 0`. A residual
/// that is white and independent of a regressor has `ccf_k ≈ 0` within `±2/√n`; a road that
/// is not white leaves the wheel equation's residuals correlated with the wheel's position.
/// Two passes, no allocation.
///
/// # Errors
/// [`Error::Shape`] for `x` and `y` of different lengths; [`Error::InvalidArgument`] naming
/// `out` when it asks for `n` lags or more; [`Error::NonFinite`]; [`Error::Singular`] for a
/// series without variance.
pub fn ccf_into(x: &[f64], y: &[f64], out: &mut [f64]) -> Result<()> {
    let n = x.len();
    if y.len() != n {
        return Err(Error::Shape { arg: "y", expected: n, got: y.len() });
    }
    if out.len() > n {
        return Err(Error::InvalidArgument { arg: "nlags", expected: "at most the number of samples" });
    }
    crate::error::check_finite("x", x)?;
    crate::error::check_finite("y", y)?;
    let mx = x.iter().sum::<f64>() / n as f64;
    let my = y.iter().sum::<f64>() / n as f64;
    let vx = x.iter().map(|v| (v - mx) * (v - mx)).sum::<f64>() / n as f64;
    let vy = y.iter().map(|v| (v - my) * (v - my)).sum::<f64>() / n as f64;
    if !(vx > 0.0 && vy > 0.0) {
        return Err(Error::Singular { what: "the cross-correlation of a series without variance (all values equal)" });
    }
    let scale = libm::sqrt(vx) * libm::sqrt(vy);
    for (k, o) in out.iter_mut().enumerate() {
        let c: f64 = x[k..].iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
        *o = c / (n - k) as f64 / scale;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_sf_in_closed_form() {
        // df = 2: e^{-x/2}; df = 1: erfc(√(x/2)); df = 4: e^{-x/2}(1 + x/2).
        for &x in &[0.0, 1e-8, 0.3, 1.0, 2.5, 7.0, 30.0, 200.0, 1400.0] {
            let want2 = libm::exp(-x / 2.0);
            let want1 = libm::erfc(libm::sqrt(x / 2.0));
            let want4 = libm::exp(-x / 2.0) * (1.0 + x / 2.0);
            for (df, want) in [(2.0, want2), (1.0, want1), (4.0, want4)] {
                let got = chi2_sf(x, df).unwrap();
                let tol = 1e-13 * want.max(1e-300);
                assert!((got - want).abs() <= tol.max(1e-16), "df {df}, x {x}: {got} against {want}");
            }
        }
        assert_eq!(chi2_sf(f64::INFINITY, 3.0).unwrap(), 0.0);
        assert!(chi2_sf(-1.0, 3.0).is_err() && chi2_sf(f64::NAN, 3.0).is_err());
        assert!(chi2_sf(1.0, 0.0).is_err() && chi2_sf(1.0, f64::INFINITY).is_err());
    }

    #[test]
    fn ljung_box_by_its_formula_and_on_a_random_walk() {
        // x = (1, -1, 1, -1, 2): mean 0.4, lag-1 and lag-2 autocorrelations by hand.
        let x = [1.0, -1.0, 1.0, -1.0, 2.0];
        let d: [f64; 5] = x.map(|v| v - 0.4);
        let c0: f64 = d.iter().map(|v| v * v).sum();
        let r1 = (d[1] * d[0] + d[2] * d[1] + d[3] * d[2] + d[4] * d[3]) / c0;
        let r2 = (d[2] * d[0] + d[3] * d[1] + d[4] * d[2]) / c0;
        let q = 5.0 * 7.0 * (r1 * r1 / 4.0 + r2 * r2 / 3.0);
        let lb = ljung_box(&x, 2).unwrap();
        assert!((lb.stat - q).abs() < 1e-12 * q, "{} against {q}", lb.stat);
        assert!((lb.rho1 - r1).abs() < 1e-15);
        assert!((lb.pvalue - chi2_sf(q, 2.0).unwrap()).abs() < 1e-15);
        // A random walk is far from white.
        let mut w = [0.0; 500];
        let mut s = 0.0f64;
        for (k, v) in w.iter_mut().enumerate() {
            s += libm::sin(k as f64 * 12.9898).signum();
            *v = s;
        }
        let lb = ljung_box(&w, 10).unwrap();
        assert!(lb.pvalue < 1e-10 && lb.rho1 > 0.9, "{lb:?}");
        assert!(ljung_box(&x, 0).is_err() && ljung_box(&x, 5).is_err());
        assert!(matches!(ljung_box(&[1.0; 10], 2), Err(Error::Singular { .. })));
        assert!(matches!(ljung_box(&[1.0, f64::NAN, 2.0, 3.0], 1), Err(Error::NonFinite { .. })));
    }
}
